//! The schedule's writes: [`Schedule::commit`], [`Schedule::cancel`],
//! [`Schedule::progress`] and [`Schedule::revise`], each one transaction under the write lock
//! (see the parent module).

use super::rows::{COLUMNS, ItineraryRow, trajectory_text};
use super::{LOCK_CLASS, Schedule, on_pool};
use crate::change::{Change, Removal};
use crate::error::TrafficError;
use crate::itinerary::{Itinerary, MAX_HORIZON_S, add_seconds};
use crate::progress::match_progress;
use crate::revision::Planned;

/// The advisory lock's object id for writes (migrations use 0).
const WRITE_LOCK: i32 = 1;

/// Deletes itineraries expired before `$1`. An expired itinerary is already absent from every
/// snapshot, so its floor's version does not change.
const PURGE: &str = "DELETE FROM traffic_itineraries WHERE expires_ms < $1";
/// Gives floor `$1` its row (version 0) if it has none.
const ENSURE_FLOOR: &str =
    "INSERT INTO traffic_floors (floor, version) VALUES ($1, 0) ON CONFLICT (floor) DO NOTHING";
/// Bumps floor `$1`'s version if it is still `$2`.
const BUMP_IF: &str = "UPDATE traffic_floors SET version = version + 1 \
                       WHERE floor = $1 AND version = $2 RETURNING version";
/// Bumps floor `$1`'s version (creating its row at version 1).
const BUMP: &str = "INSERT INTO traffic_floors (floor, version) VALUES ($1, 1) \
                    ON CONFLICT (floor) DO UPDATE SET version = traffic_floors.version + 1 \
                    RETURNING version";
const VERSION: &str = "SELECT version FROM traffic_floors WHERE floor = $1";

/// Begins a write transaction in an [`on_pool!`] arm: SQLite's `BEGIN IMMEDIATE`, or
/// PostgreSQL's transaction with the schedule's advisory lock; then purges what expired.
macro_rules! begin_write {
    ($schedule:expr, $pool:ident, $pg:ident, $now:expr) => {{
        let err = |e| $schedule.db_err(e);
        let mut tx = if $pg {
            $pool.begin().await.map_err(err)?
        } else {
            $pool.begin_with("BEGIN IMMEDIATE").await.map_err(err)?
        };
        if $pg {
            sqlx::query("SELECT pg_advisory_xact_lock($1, $2)")
                .bind(LOCK_CLASS)
                .bind(WRITE_LOCK)
                .execute(&mut *tx)
                .await
                .map_err(err)?;
        }
        sqlx::query(PURGE)
            .bind($now)
            .execute(&mut *tx)
            .await
            .map_err(err)?;
        tx
    }};
}

impl Schedule {
    /// Commits `itinerary` if its floor's version is still `expected_version` (the version of
    /// the snapshot it was planned against); returns the floor's new version.
    ///
    /// In one transaction: the floor's version is checked and bumped, the robot's previous
    /// itinerary (on any floor) is removed (its floor's version bumped too; a removal reported
    /// unless it is the same plan on the same floor, committed again), the new one inserted, and
    /// what expired purged. Errors: [`TrafficError::Invalid`] (see
    /// [`Itinerary::check`]; also an itinerary already expired, or a negative version),
    /// [`TrafficError::VersionChanged`], [`TrafficError::PlanIdTaken`] (the plan id is another
    /// robot's).
    pub async fn commit(
        &self,
        itinerary: Itinerary,
        expected_version: i64,
    ) -> Result<i64, TrafficError> {
        itinerary.check()?;
        let now = self.now_ms();
        if itinerary.expires_unix_ms < now {
            return Err(TrafficError::Invalid(format!(
                "expires_unix_ms ({}) is already past (now {now})",
                itinerary.expires_unix_ms
            )));
        }
        if expected_version < 0 {
            return Err(TrafficError::Invalid(format!(
                "expected_version is {expected_version}; versions start at 0"
            )));
        }
        let trajectory = trajectory_text(&itinerary.trajectory)?;
        let err = |e| self.db_err(e);
        let it = &itinerary;
        let (version, replaced) = on_pool!(self, |pool, pg| {
            let mut tx = begin_write!(self, pool, pg, now);
            let holder: Option<String> =
                sqlx::query_scalar("SELECT robot FROM traffic_itineraries WHERE plan_id = $1")
                    .bind(&it.plan_id)
                    .fetch_optional(&mut *tx)
                    .await
                    .map_err(err)?;
            if let Some(owner) = holder.filter(|owner| *owner != it.robot) {
                return Err(TrafficError::PlanIdTaken {
                    plan_id: it.plan_id.clone(),
                    owner,
                });
            }
            sqlx::query(ENSURE_FLOOR)
                .bind(&it.floor)
                .execute(&mut *tx)
                .await
                .map_err(err)?;
            let bumped: Option<i64> = sqlx::query_scalar(BUMP_IF)
                .bind(&it.floor)
                .bind(expected_version)
                .fetch_optional(&mut *tx)
                .await
                .map_err(err)?;
            let Some(version) = bumped else {
                let current: i64 = sqlx::query_scalar(VERSION)
                    .bind(&it.floor)
                    .fetch_one(&mut *tx)
                    .await
                    .map_err(err)?;
                return Err(TrafficError::VersionChanged {
                    floor: it.floor.clone(),
                    expected: expected_version,
                    now: current,
                });
            };
            let previous: Vec<(String, String)> = sqlx::query_as(
                "DELETE FROM traffic_itineraries WHERE robot = $1 RETURNING plan_id, floor",
            )
            .bind(&it.robot)
            .fetch_all(&mut *tx)
            .await
            .map_err(err)?;
            let mut replaced = Vec::with_capacity(previous.len());
            // The same plan committed again (where its robot stood while it was planned, then
            // the plan): its `committed` change says all.
            for (plan_id, floor) in previous
                .into_iter()
                .filter(|(id, floor)| !(*id == it.plan_id && *floor == it.floor))
            {
                let floor_version = if floor == it.floor {
                    version
                } else {
                    sqlx::query_scalar(BUMP)
                        .bind(&floor)
                        .fetch_one(&mut *tx)
                        .await
                        .map_err(err)?
                };
                replaced.push(Change::Removed {
                    floor,
                    version: floor_version,
                    plan_id,
                    robot: it.robot.clone(),
                    reason: Removal::Replaced,
                });
            }
            sqlx::query(
                "INSERT INTO traffic_itineraries (plan_id, floor, robot, start_ms, expires_ms, \
                 delay_s, tolerance_s, radius_m, progress_t_s, trajectory, committed_ms, updated_ms) \
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, NULL, $9, $10, $10)",
            )
            .bind(&it.plan_id)
            .bind(&it.floor)
            .bind(&it.robot)
            .bind(it.start_unix_ms)
            .bind(it.expires_unix_ms)
            .bind(it.delay_s)
            .bind(it.tolerance_s)
            .bind(it.radius_m)
            .bind(&trajectory)
            .bind(now)
            .execute(&mut *tx)
            .await
            .map_err(err)?;
            tx.commit().await.map_err(err)?;
            (version, replaced)
        });
        tracing::debug!(
            plan_id = %itinerary.plan_id,
            robot = %itinerary.robot,
            floor = %itinerary.floor,
            version,
            "itinerary committed"
        );
        let mut changes = replaced;
        changes.push(Change::Committed { version, itinerary });
        self.publish(changes);
        Ok(version)
    }

    /// Cancels plan `plan_id`: removes its itinerary and bumps its floor's version. Returns the
    /// itinerary, or `None` when no unexpired itinerary has that id.
    pub async fn cancel(&self, plan_id: &str) -> Result<Option<Itinerary>, TrafficError> {
        let now = self.now_ms();
        let err = |e| self.db_err(e);
        let delete =
            format!("DELETE FROM traffic_itineraries WHERE plan_id = $1 RETURNING {COLUMNS}");
        let removed: Option<(ItineraryRow, i64)> = on_pool!(self, |pool, pg| {
            let mut tx = begin_write!(self, pool, pg, now);
            let row: Option<ItineraryRow> = sqlx::query_as(&delete)
                .bind(plan_id)
                .fetch_optional(&mut *tx)
                .await
                .map_err(err)?;
            let removed = match row {
                Some(row) => {
                    let version: i64 = sqlx::query_scalar(BUMP)
                        .bind(&row.floor)
                        .fetch_one(&mut *tx)
                        .await
                        .map_err(err)?;
                    Some((row, version))
                }
                None => None,
            };
            tx.commit().await.map_err(err)?;
            removed
        });
        let Some((row, version)) = removed else {
            return Ok(None);
        };
        let itinerary = row.into_itinerary()?;
        tracing::debug!(plan_id, floor = %itinerary.floor, version, "itinerary cancelled");
        self.publish(vec![Change::Removed {
            floor: itinerary.floor.clone(),
            version,
            plan_id: itinerary.plan_id.clone(),
            robot: itinerary.robot.clone(),
            reason: Removal::Cancelled,
        }]);
        Ok(Some(itinerary))
    }

    /// Records that `robot` was at `(x, y)` at `at_unix_ms` on plan `plan_id`: the delay
    /// becomes the report's time minus the time the schedule put the robot closest to that
    /// position (searched forward from the last report; see the `progress` module), which
    /// shifts the rest of the itinerary; its expiry moves by the change in delay. Bumps the
    /// floor's version and returns the updated itinerary.
    ///
    /// `acknowledged`: the revision the robot drives (it learnt of it); the plan's
    /// `acknowledged` becomes it (never lower than before).
    ///
    /// Errors: [`TrafficError::NotFound`] (unknown, cancelled or expired),
    /// [`TrafficError::NotYourPlan`] (another robot's plan), [`TrafficError::Invalid`] (a
    /// position that is not finite), [`TrafficError::UnknownRevision`] (an acknowledged
    /// revision the plan never had).
    pub async fn progress(
        &self,
        plan_id: &str,
        robot: &str,
        at_unix_ms: i64,
        (x, y): (f64, f64),
        acknowledged: Option<u32>,
    ) -> Result<Planned, TrafficError> {
        if !(x.is_finite() && y.is_finite()) {
            return Err(TrafficError::Invalid(format!(
                "the reported position ({x}, {y}) is not finite"
            )));
        }
        let now = self.now_ms();
        let err = |e| self.db_err(e);
        let select = format!("SELECT {COLUMNS} FROM traffic_itineraries WHERE plan_id = $1");
        let (planned, version) = on_pool!(self, |pool, pg| {
            let mut tx = begin_write!(self, pool, pg, now);
            let row: Option<ItineraryRow> = sqlx::query_as(&select)
                .bind(plan_id)
                .fetch_optional(&mut *tx)
                .await
                .map_err(err)?;
            let Some(row) = row else {
                return Err(TrafficError::NotFound {
                    plan_id: plan_id.to_owned(),
                });
            };
            if row.robot != robot {
                return Err(TrafficError::NotYourPlan {
                    plan_id: plan_id.to_owned(),
                    robot: robot.to_owned(),
                    owner: row.robot,
                });
            }
            let Planned {
                mut itinerary,
                acknowledged: before,
                progress_t_s: last_match,
            } = row.into_planned()?;
            let acknowledged = match acknowledged {
                Some(a) if a > itinerary.revision || a == 0 => {
                    return Err(TrafficError::UnknownRevision {
                        plan_id: plan_id.to_owned(),
                        acknowledged: a,
                        current: itinerary.revision,
                    });
                }
                Some(a) => a.max(before),
                None => before,
            };
            let matched =
                match_progress(&itinerary, last_match, at_unix_ms, x, y).ok_or_else(|| {
                    TrafficError::Corrupt {
                        plan_id: plan_id.to_owned(),
                        message: "empty trajectory".to_owned(),
                    }
                })?;
            let delay = matched.delay_s.clamp(-MAX_HORIZON_S, MAX_HORIZON_S);
            itinerary.expires_unix_ms =
                add_seconds(itinerary.expires_unix_ms, delay - itinerary.delay_s);
            itinerary.delay_s = delay;
            sqlx::query(
                "UPDATE traffic_itineraries SET delay_s = $2, progress_t_s = $3, \
                 expires_ms = $4, updated_ms = $5, acknowledged = $6 WHERE plan_id = $1",
            )
            .bind(plan_id)
            .bind(delay)
            .bind(matched.t_s)
            .bind(itinerary.expires_unix_ms)
            .bind(now)
            .bind(i64::from(acknowledged))
            .execute(&mut *tx)
            .await
            .map_err(err)?;
            let version: i64 = sqlx::query_scalar(BUMP)
                .bind(&itinerary.floor)
                .fetch_one(&mut *tx)
                .await
                .map_err(err)?;
            tx.commit().await.map_err(err)?;
            let planned = Planned {
                itinerary,
                acknowledged,
                progress_t_s: Some(matched.t_s),
            };
            (planned, version)
        });
        tracing::debug!(
            plan_id,
            robot,
            delay_s = planned.itinerary.delay_s,
            acknowledged = planned.acknowledged,
            version,
            "itinerary progressed"
        );
        self.publish(vec![Change::Progressed {
            version,
            itinerary: planned.itinerary.clone(),
        }]);
        Ok(planned)
    }

    /// Revises plans of one floor whose robots have not set off, in one transaction, if the
    /// floor is still at `expected_version`: each itinerary of `revised` replaces the one
    /// committed under its plan id (same robot, same floor, starting where it stood), with the
    /// revision one more, no delay and no progress matched yet. Returns the floor's new version
    /// and the revised itineraries. The schedule holds the old plans or all the new ones, never
    /// a mix.
    ///
    /// Errors: [`TrafficError::Invalid`] (an itinerary that fails [`Itinerary::check`], none,
    /// two for one plan, plans of several floors, another robot or floor than the plan's, or a
    /// start away from where the robot stands), [`TrafficError::NotFound`],
    /// [`TrafficError::SetOff`] (see [`Planned::set_off`]),
    /// [`TrafficError::VersionChanged`].
    pub async fn revise(
        &self,
        revised: Vec<Itinerary>,
        expected_version: i64,
    ) -> Result<(i64, Vec<Itinerary>), TrafficError> {
        let floor = check_revisions(&revised)?;
        let now = self.now_ms();
        let err = |e| self.db_err(e);
        let select = format!("SELECT {COLUMNS} FROM traffic_itineraries WHERE plan_id = $1");
        let texts = revised
            .iter()
            .map(|it| trajectory_text(&it.trajectory))
            .collect::<Result<Vec<_>, _>>()?;
        let (version, out) = on_pool!(self, |pool, pg| {
            let mut tx = begin_write!(self, pool, pg, now);
            let mut out = Vec::with_capacity(revised.len());
            for (new, text) in revised.iter().zip(&texts) {
                let row: Option<ItineraryRow> = sqlx::query_as(&select)
                    .bind(&new.plan_id)
                    .fetch_optional(&mut *tx)
                    .await
                    .map_err(err)?;
                let Some(row) = row else {
                    return Err(TrafficError::NotFound {
                        plan_id: new.plan_id.clone(),
                    });
                };
                let old = row.into_planned()?;
                check_revisable(&old, new, now)?;
                let revision = old.itinerary.revision.saturating_add(1);
                sqlx::query(
                    "UPDATE traffic_itineraries SET start_ms = $2, expires_ms = $3, delay_s = 0, \
                     tolerance_s = $4, radius_m = $5, progress_t_s = NULL, trajectory = $6, \
                     revision = $7, updated_ms = $8 WHERE plan_id = $1",
                )
                .bind(&new.plan_id)
                .bind(new.start_unix_ms)
                .bind(new.expires_unix_ms)
                .bind(new.tolerance_s)
                .bind(new.radius_m)
                .bind(text)
                .bind(i64::from(revision))
                .bind(now)
                .execute(&mut *tx)
                .await
                .map_err(err)?;
                out.push(Itinerary {
                    delay_s: 0.0,
                    revision,
                    ..new.clone()
                });
            }
            let bumped: Option<i64> = sqlx::query_scalar(BUMP_IF)
                .bind(floor)
                .bind(expected_version)
                .fetch_optional(&mut *tx)
                .await
                .map_err(err)?;
            let Some(version) = bumped else {
                let current: Option<i64> = sqlx::query_scalar(VERSION)
                    .bind(floor)
                    .fetch_optional(&mut *tx)
                    .await
                    .map_err(err)?;
                return Err(TrafficError::VersionChanged {
                    floor: floor.to_owned(),
                    expected: expected_version,
                    now: current.unwrap_or(0),
                });
            };
            tx.commit().await.map_err(err)?;
            (version, out)
        });
        tracing::info!(
            floor,
            version,
            plans = ?out.iter().map(|it| (&it.plan_id, it.revision)).collect::<Vec<_>>(),
            "plans revised"
        );
        self.publish(
            out.iter()
                .map(|itinerary| Change::Revised {
                    version,
                    itinerary: itinerary.clone(),
                })
                .collect(),
        );
        Ok((version, out))
    }
}

/// The floor of a batch of revisions, after checking each itinerary and that the batch holds
/// at least one, one per plan, all on one floor.
fn check_revisions(revised: &[Itinerary]) -> Result<&str, TrafficError> {
    let invalid = |m: String| Err(TrafficError::Invalid(m));
    let Some(first) = revised.first() else {
        return invalid("a revision needs at least one itinerary".to_owned());
    };
    for (i, it) in revised.iter().enumerate() {
        it.check()?;
        if it.floor != first.floor {
            return invalid(format!(
                "one revision is of one floor: plan {:?} is on {:?}, plan {:?} on {:?}",
                first.plan_id, first.floor, it.plan_id, it.floor
            ));
        }
        if revised[..i].iter().any(|o| o.plan_id == it.plan_id) {
            return invalid(format!("plan {:?} is revised twice at once", it.plan_id));
        }
    }
    Ok(&first.floor)
}

/// Whether `new` may replace `old` now: the same robot and floor, a robot that has not set
/// off, and a start where the robot stands (within its radius).
fn check_revisable(old: &Planned, new: &Itinerary, now: i64) -> Result<(), TrafficError> {
    let it = &old.itinerary;
    if it.robot != new.robot || it.floor != new.floor {
        return Err(TrafficError::Invalid(format!(
            "plan {:?} is {:?}'s on {:?}: a revision cannot give it to {:?} on {:?}",
            it.plan_id, it.robot, it.floor, new.robot, new.floor
        )));
    }
    if old.set_off(now) {
        return Err(TrafficError::SetOff {
            plan_id: it.plan_id.clone(),
            robot: it.robot.clone(),
            departs_unix_ms: it.departs_unix_ms(),
        });
    }
    let (Some(a), Some(b)) = (it.trajectory.first(), new.trajectory.first()) else {
        return Ok(());
    };
    if (a.x - b.x).hypot(a.y - b.y) > it.radius_m {
        return Err(TrafficError::Invalid(format!(
            "the revision of plan {:?} starts at ({:.2}, {:.2}), but its robot stands at ({:.2}, {:.2})",
            it.plan_id, b.x, b.y, a.x, a.y
        )));
    }
    if new.expires_unix_ms < now {
        return Err(TrafficError::Invalid(format!(
            "the revision of plan {:?} expires at {} ms, already past (now {now})",
            it.plan_id, new.expires_unix_ms
        )));
    }
    Ok(())
}
