//! A plan among the fleet: [`Planner::among_the_fleet`] fits the rehearsed plan among the
//! floor's schedule, drives it again among the other robots' plans and commits it (the rules
//! are [`crate::fleet`]'s).

use std::sync::Arc;

use sim::World;

use crate::fleet::{self, FleetOptions, FleetOutcome, FleetSchedule, NoFit, yielding};
use crate::replay::Replay;

mod attempt;
use crate::{FloorDatabase, InvalidField, PlanFailure, Planner, Unavailable, Unusable};
use attempt::{Joining, Next};

/// How committing the first clear of several itineraries went.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Cleared {
    /// One was committed.
    Committed,
    /// None: the robot the last one came too near (empty where none was tried or the full
    /// floor took none).
    TooNear(String),
}

/// Commits a plan may lose to other plans committed on its floor meanwhile (each time it is
/// fitted again against the new schedule) before it answers 503. Fitting it again from a later
/// start is bounded by `options.max_wait_s` instead.
const COMMIT_ATTEMPTS: usize = 16;
/// Commits a plan may lose while fitted and driven beside the floor's other plans; after
/// that it holds the floor's lock from its snapshot to its commit. On the plant with 20 robots
/// among people (`bench fleet`, three runs each), p95 latency 2.1–2.5 s with 3, 3.1–3.9 s with
/// 1 (plans queue for the lock sooner), 2.2–2.7 s with 16 (plans redriven more often).
const OPTIMISTIC_COMMITS: usize = 3;

/// Times a plan is fitted again on its own drive among the fleet ([`fleet::Basis`]) before a
/// drive that arrived too close to another robot's schedule sends it to a later start.
const REFITS_ON_DRIVE: u32 = 3;

/// How often the floor's schedule is read while waiting for it to change, milliseconds.
const POLL_MS: u64 = 25;
/// How long a plan's wait outlasts its deadline in the schedule, ms: a poll's worth and more,
/// so that a plan still waiting is never taken for gone by another process.
const WAIT_SLACK_MS: i64 = 2_000;

/// Logs a failure to tell the schedule `what` of `robot`'s plan: the plan goes on (waits of
/// other processes are a help in finding cycles, and a wait ends by itself).
fn tell(told: Result<(), crate::PortError>, robot: &str, what: &str) {
    if let Err(e) = told {
        tracing::warn!(%robot, error = %e, "the schedule could not be told {what}");
    }
}

/// A plan's place in its floor's schedule before it is rehearsed: its id and the start asked
/// for, the robot standing there in the schedule meanwhile ([`Planner::enter_the_fleet`]).
#[derive(Debug, Clone)]
pub(crate) struct FleetEntry {
    plan_id: String,
    requested_unix_ms: i64,
    options: FleetOptions,
    /// The plan's place in line for the cores ([`crate::gate::CpuGate`]); the caller's to set.
    pub(crate) ticket: u64,
}

/// Longest wait at one node a route timed among the fleet's plans takes, seconds: beyond it,
/// the route goes another way (the fit may still make it wait longer).
const ROUTE_NODE_WAIT_S: f64 = 60.0;

impl FleetEntry {
    /// How long the robot stands in the schedule before its plan replaces it: until it sets
    /// off at the latest, late by its tolerance.
    fn stand_for_s(&self) -> f64 {
        self.options.max_wait_s + self.options.tolerance_s + 1.0
    }

    /// The committed plans of `moving` as reservations a route is timed among, on the clock of
    /// this plan's start (`None` where there are none, or their tracks are unusable).
    pub(crate) fn reserved(&self, moving: &[traffic::Itinerary]) -> Option<rehearsal::Reserved> {
        if moving.is_empty() {
            return None;
        }
        let robots = fleet::simulated_robots(moving, self.requested_unix_ms).ok()?;
        Some(rehearsal::Reserved {
            robots,
            gap_m: fleet::ROBOT_MARGIN_M,
            slack_s: self.options.tolerance_s + fleet::FIT_SLACK_S,
            max_wait_s: self.options.max_wait_s.min(ROUTE_NODE_WAIT_S),
        })
    }
}

impl Planner {
    /// Checks the start asked for and, for a plan to be committed by a robot the floor's
    /// schedule does not hold yet, puts it there standing at `start` from that time until its
    /// plan replaces it, at the latest `max_wait_s` later: so the plans of other robots, checked
    /// meanwhile, keep clear of where it stands. A robot whose plan is refused still stands
    /// there until then: it has not moved. A robot the schedule holds keeps its itinerary until
    /// its new plan is committed.
    /// Nothing is recorded for a start the robot does not fit at (`fits_there`: the rehearsal
    /// refuses it).
    pub(crate) async fn enter_the_fleet(
        &self,
        schedule: &dyn FleetSchedule,
        db: &FloorDatabase,
        radius_m: f64,
        start: sim::Pose2,
        options: &FleetOptions,
        fits_there: bool,
    ) -> Result<FleetEntry, PlanFailure> {
        let now = schedule.now_ms();
        let requested = options.start_unix_ms.unwrap_or(now);
        let slack_ms = (options.tolerance_s * 1000.0).round() as i64;
        if requested < now - slack_ms {
            return Err(PlanFailure::Unprocessable(Unusable::Field(
                InvalidField::new(
                    "options.start_time_ms",
                    format!(
                        "`options.start_time_ms` {requested} is {:.1} s in the past, beyond the plan's tolerance of {} s: a schedule cannot start before it is made",
                        (now - requested) as f64 / 1000.0,
                        options.tolerance_s
                    ),
                ),
            )));
        }
        let entry = FleetEntry {
            plan_id: fleet::plan_id(&db.robot, now),
            requested_unix_ms: requested,
            options: *options,
            ticket: 0,
        };
        // A start the robot does not fit at is the rehearsal's to refuse (422).
        if !options.commit || !fits_there {
            return Ok(entry);
        }
        let standing = standing_at(
            &entry.plan_id,
            db,
            radius_m,
            start,
            requested,
            entry.stand_for_s(),
        );
        // A robot with an itinerary on the floor keeps it until its new plan is committed (a
        // refused plan changes nothing).
        // A full floor is refused with the plan.
        record_standing(schedule, &standing, false).await?;
        Ok(entry)
    }

    /// Records that `robot` stands at `at` on the floor of `place` with no plan, from `from_ms`
    /// (default now) for `for_s` seconds, replacing its itinerary: plans keep clear of it (as a
    /// fleet adapter reports an idle robot). Refused (422) where the robot does not fit or the
    /// values are out of range, (409) inside the footprint another robot's schedule reserves
    /// there then.
    pub async fn stand(
        &self,
        robot: &str,
        place: &str,
        at: sim::Pose2,
        from_ms: Option<i64>,
        for_s: f64,
    ) -> Result<traffic::Itinerary, PlanFailure> {
        let Some(schedule) = &self.fleet else {
            return Err(PlanFailure::Unavailable(Unavailable::NoSchedule));
        };
        if !(for_s.is_finite() && for_s > 0.0 && for_s <= fleet::MAX_FLEET_S) {
            return Err(unusable_field(
                "for_s",
                format!(
                    "`for_s` must lie in (0, {}] seconds, got {for_s}",
                    fleet::MAX_FLEET_S
                ),
            ));
        }
        if !(at.x.is_finite() && at.y.is_finite() && at.yaw.is_finite()) {
            return Err(unusable_field(
                "x",
                "`x`, `y` and `yaw` must be finite numbers",
            ));
        }
        let now = schedule.now_ms();
        let from = from_ms.unwrap_or(now);
        if !(0..=fleet::MAX_START_UNIX_MS).contains(&from) {
            return Err(unusable_field(
                "time_ms",
                format!(
                    "`time_ms` must lie in [0, {}], got {from}",
                    fleet::MAX_START_UNIX_MS
                ),
            ));
        }
        let db = self.knowledge.floor_database(place, robot).await?;
        let db2 = Arc::clone(&db);
        let world = self.blocking(move || db2.world()).await??;
        if world.clearance(at.x, at.y) <= 0.0 {
            return Err(PlanFailure::Unprocessable(Unusable::DoesNotFit {
                x: at.x,
                y: at.y,
            }));
        }
        let radius = world.spec().robot.footprint_radius;
        let standing = standing_at(
            &fleet::plan_id(&db.robot, now),
            &db,
            radius,
            at,
            from,
            for_s,
        );
        let (_, all) = schedule.snapshot(&db.floor).await?;
        let others: Vec<&traffic::Itinerary> = all.iter().filter(|o| o.robot != db.robot).collect();
        outside_others(&others, (at.x, at.y), radius, from, "")?;
        if !record_standing(schedule.as_ref(), &standing, true).await? {
            return Err(PlanFailure::Unprocessable(Unusable::ScheduleFull(
                fleet::MAX_ROBOTS_PER_FLOOR,
            )));
        }
        Ok(standing)
    }

    /// The other robots on `floor`: those standing with no plan yet ([`fleet::stands_only`])
    /// and those with one.
    pub(crate) async fn others_on_the_floor(
        &self,
        schedule: &dyn FleetSchedule,
        db: &FloorDatabase,
    ) -> Result<(Vec<traffic::Itinerary>, Vec<traffic::Itinerary>), PlanFailure> {
        let (_, all) = schedule.snapshot(&db.floor).await?;
        Ok(all
            .into_iter()
            .filter(|i| i.robot != db.robot)
            .partition(fleet::stands_only))
    }

    /// The validated plan among the other robots' committed plans on its floor: fitted with
    /// waits ([`fleet::fit`]) and committed against the version it was checked against (a
    /// commit that lost the race is checked again, a few times). `avoided`: the robots standing
    /// with no plan that the rehearsed route keeps clear of (`None`: it did not try); another
    /// one in its way sends it back to be rehearsed again ([`Among::Reroute`]).
    ///
    /// Each turn of the loop is one [`Joining::attempt`]: fit, drive among the others, judge,
    /// commit.
    pub(crate) async fn among_the_fleet(
        &self,
        schedule: &dyn FleetSchedule,
        db: &FloorDatabase,
        (world, report, replay): (&Arc<World>, &rehearsal::PlanReport, &Arc<Replay>),
        entry: &FleetEntry,
        avoided: Option<&[String]>,
        make_way: Option<f64>,
    ) -> Result<Among, PlanFailure> {
        let robot_lock = self.fleet_lock(format!("robot {}", db.robot));
        let _one_plan_per_robot = robot_lock.lock().await;
        // Plans on one floor are fitted and driven side by side, each against the schedule as
        // it was (optimistically), and committed one at a time under the floor's lock. A plan
        // that lost its commit OPTIMISTIC_COMMITS times holds the lock from its snapshot to its
        // commit, so a busy floor still takes it.
        let floor_lock = self.fleet_lock(format!("floor {}", db.floor));
        let mut joining = Joining {
            planner: self,
            schedule,
            db,
            world,
            report,
            replay,
            entry,
            avoided,
            make_way,
            route: yielding::route_points(&report.steps, 0.2),
            waiting_since: std::time::Instant::now(),
            later_s: 0.0,
            refused_fits: Vec::new(),
            drives: 0,
            basis: None,
            refits_on_drive: 0,
            in_the_way: Vec::new(),
            lost_commits: 0,
            rechecks: 0,
        };
        while joining.lost_commits < COMMIT_ATTEMPTS {
            let held_throughout = if joining.lost_commits >= OPTIMISTIC_COMMITS {
                Some(floor_lock.lock().await)
            } else {
                None
            };
            let floor_lock = held_throughout.is_none().then_some(&*floor_lock);
            match joining.attempt(floor_lock).await? {
                Next::Again => {}
                Next::Answer(among) => return Ok(among),
                Next::Exhausted => break,
            }
        }
        Err(PlanFailure::Unavailable(Unavailable::ScheduleBusy(
            "this plan was committed",
        )))
    }

    /// Commits the first leg of a plan making way (to its first goal, the place it makes way
    /// at, [`yielding::prefix`]) under the floor's lock, unless it would come within the
    /// margins of another robot's schedule; whether it was.
    pub(crate) async fn commit_first_leg(
        &self,
        schedule: &dyn FleetSchedule,
        db: &FloorDatabase,
        radius_m: f64,
        report: &rehearsal::PlanReport,
        entry: &FleetEntry,
    ) -> Result<bool, PlanFailure> {
        let Some(&goal) = report.goal_indices.first() else {
            return Ok(false);
        };
        let Some(&at_step) = fleet::waypoint_steps(&report.steps, &report.waypoints).get(goal)
        else {
            return Ok(false);
        };
        let template = traffic::Itinerary {
            plan_id: entry.plan_id.clone(),
            robot: db.robot.clone(),
            floor: db.floor.clone(),
            start_unix_ms: entry.requested_unix_ms,
            trajectory: Vec::new(),
            radius_m,
            tolerance_s: entry.options.tolerance_s,
            expires_unix_ms: entry.requested_unix_ms,
            delay_s: 0.0,
            revision: 1,
        };
        let candidates = yielding::SET_OFF_DELAYS_S.map(|delay| {
            yielding::prefix(
                &template,
                &report.steps,
                at_step,
                report.control_period_s,
                delay,
                entry.stand_for_s(),
            )
        });
        Ok(self.commit_first_clear(schedule, db, candidates).await? == Cleared::Committed)
    }

    /// Commits the first of `candidates` (itineraries of `db`'s robot) that keeps the margins
    /// from every other robot's schedule, under the floor's lock: [`Cleared::Committed`] once
    /// one is recorded, else [`Cleared::TooNear`] naming the robot the last one came too near
    /// (empty where none was tried or the full floor took none).
    async fn commit_first_clear(
        &self,
        schedule: &dyn FleetSchedule,
        db: &FloorDatabase,
        candidates: impl IntoIterator<Item = traffic::Itinerary>,
    ) -> Result<Cleared, PlanFailure> {
        let floor_lock = self.fleet_lock(format!("floor {}", db.floor));
        let _one_commit_per_floor = floor_lock.lock().await;
        let (_, all) = schedule.snapshot(&db.floor).await?;
        let others: Vec<traffic::Itinerary> =
            all.into_iter().filter(|i| i.robot != db.robot).collect();
        let mut near = String::new();
        for it in candidates {
            match fleet::first_conflict(&it, &others) {
                Some(c) => near = c.b_robot,
                None if record_standing(schedule, &it, true).await? => {
                    return Ok(Cleared::Committed);
                }
                None => break,
            }
        }
        Ok(Cleared::TooNear(near))
    }

    /// A plan that made way refused after its first leg was committed: the robot stands at
    /// `start` again in the schedule, as it did before, unless a plan committed meanwhile was
    /// fitted through it there (then the first leg stays, and a warning is logged: that plan
    /// counts on this robot having gone).
    pub(crate) async fn stand_again(
        &self,
        schedule: &dyn FleetSchedule,
        db: &FloorDatabase,
        radius_m: f64,
        start: sim::Pose2,
        entry: &FleetEntry,
    ) {
        let standing = standing_at(
            &entry.plan_id,
            db,
            radius_m,
            start,
            entry.requested_unix_ms,
            entry.stand_for_s(),
        );
        match self.commit_first_clear(schedule, db, [standing]).await {
            Ok(Cleared::Committed) => {}
            Ok(Cleared::TooNear(other)) => {
                tracing::warn!(robot = %db.robot, %other, "a plan that made way was refused after another was fitted through where it stood, or the floor was full");
            }
            Err(e) => {
                tracing::warn!(robot = %db.robot, error = %e, "the robot could not be stood again");
            }
        }
    }

    /// Where `view`'s robot is the one of a cycle of plans waiting for each other's robots to
    /// make way ([`yielding::Waits::turn_to_make_way`]): where, and for whom; a robot
    /// that finds no place says so, and another of the cycle takes its turn.
    async fn make_way(&self, view: &View<'_>) -> Option<Standing> {
        let margin = view.make_way?;
        let shared = match view.schedule.waits(view.floor).await {
            Ok(shared) => shared,
            Err(e) => {
                tracing::warn!(robot = %view.me, error = %e, "the floor's waits could not be read: only this process's are seen");
                Vec::new()
            }
        };
        let (mut routes, for_robots) = self.waits.turn_to_make_way(view.me, &shared)?;
        routes.extend(
            view.others
                .iter()
                .filter(|o| !fleet::stands_only(o))
                .map(|o| {
                    (
                        o.trajectory.iter().map(|p| (p.x, p.y)).collect(),
                        o.radius_m,
                    )
                }),
        );
        let here = view.route.first().copied()?;
        let standing: Vec<((f64, f64), f64)> = view
            .others
            .iter()
            .filter(|o| fleet::stands_only(o))
            .filter_map(|o| o.trajectory.first().map(|p| ((p.x, p.y), o.radius_m)))
            .collect();
        let world = view.world;
        let at = yielding::spot_off_routes(
            here,
            view.radius_m,
            |x, y| world.clearance(x, y) - margin,
            &routes,
            &standing,
        );
        match at {
            Some(at) => Some(Standing::MakeWay(at, for_robots)),
            None => {
                if let Some(wait) = self.waits.cannot_make_way(view.me) {
                    let told = view.schedule.post_wait(wait).await;
                    tell(told, view.me, "that it cannot make way");
                }
                None
            }
        }
    }

    /// Where one of the robots `refused` names stands in the way with no plan yet (in
    /// `others`, read at `version`), waits until the floor's schedule changes (and answers
    /// `Ok`: fit again), up to `standing_wait_s` after `since`; else the refusal, saying who
    /// stands where.
    async fn wait_for_standing(
        &self,
        view: &View<'_>,
        refused: NoFit,
    ) -> Result<Standing, PlanFailure> {
        let standing: Vec<&traffic::Itinerary> = view
            .others
            .iter()
            .filter(|o| refused.robots.contains(&o.robot) && fleet::stands_only(o))
            .collect();
        if standing.is_empty() {
            return Err(PlanFailure::FleetConflict(refused));
        }
        // A robot the route did not keep clear of: its plan is waited for a little (it may
        // be planning now, and leave), then the route goes around it.
        let reroute = view
            .avoided
            .is_some_and(|avoided| standing.iter().any(|o| !avoided.contains(&o.robot)));
        let limit = if reroute {
            fleet::REROUTE_AFTER_S.min(view.standing_wait_s)
        } else {
            view.standing_wait_s
        };
        let deadline = view.since + std::time::Duration::from_secs_f64(limit);
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        let wait = traffic::Wait {
            robot: view.me.to_owned(),
            floor: view.floor.to_owned(),
            by: standing.iter().map(|o| o.robot.clone()).collect(),
            route: view.route.to_vec(),
            radius_m: view.radius_m,
            cannot_make_way: view.make_way.is_none() || reroute,
            // Past its deadline and a poll's worth of slack, the wait is over even if its
            // process died without saying so.
            until_unix_ms: view.schedule.now_ms()
                + i64::try_from(left.as_millis()).unwrap_or(i64::MAX / 2)
                + WAIT_SLACK_MS,
        };
        let _waiting = self.waits.enter(wait.clone());
        tell(
            view.schedule.post_wait(wait).await,
            view.me,
            "that it waits",
        );
        let waited = async {
            while std::time::Instant::now() < deadline {
                // Only where no route keeps clear of the robots standing: a route around them
                // is tried first.
                if !reroute && let Some(at) = self.make_way(view).await {
                    return Ok(Some(at));
                }
                let now = view.schedule.version(view.floor).await?;
                if now != view.version {
                    return Ok(Some(Standing::Changed));
                }
                tokio::time::sleep(std::time::Duration::from_millis(POLL_MS)).await;
            }
            Ok::<_, PlanFailure>(None)
        }
        .await;
        tell(
            view.schedule.clear_wait(view.me).await,
            view.me,
            "that it no longer waits",
        );
        if let Some(standing) = waited? {
            return Ok(standing);
        }
        if reroute {
            return Ok(Standing::Reroute);
        }
        let at = standing
            .iter()
            .filter_map(|o| {
                let p = o.trajectory.first()?;
                Some(format!("{} at ({:.2}, {:.2})", o.robot, p.x, p.y))
            })
            .collect::<Vec<_>>()
            .join(", ");
        Err(PlanFailure::FleetConflict(NoFit {
            message: format!(
                "{}; {at} stands in the way with no plan, and none came within {} s",
                refused.message, view.standing_wait_s
            ),
            ..refused
        }))
    }
}

/// `Ok` unless a robot of `radius_m` at `xy` at `at_ms` is inside the footprint the schedule
/// reserves for one of `others` then (409, naming it; the message starts with `what`).
fn outside_others(
    others: &[&traffic::Itinerary],
    xy: (f64, f64),
    radius_m: f64,
    at_ms: i64,
    what: &str,
) -> Result<(), PlanFailure> {
    let inside = others.iter().find(|o| {
        o.pose_at(at_ms)
            .is_some_and(|(x, y)| (x - xy.0).hypot(y - xy.1) < o.radius_m + radius_m)
    });
    match inside {
        None => Ok(()),
        Some(other) => Err(PlanFailure::FleetConflict(NoFit {
            robots: vec![other.robot.clone()],
            earliest_start_unix_ms: None,
            message: format!(
                "{what}({:.2}, {:.2}) lies in the footprint the schedule reserves for {} at that time",
                xy.0, xy.1, other.robot
            ),
        })),
    }
}

/// `db`'s robot standing at `at` from `from_ms` for `for_s` seconds, as an itinerary.
fn standing_at(
    plan_id: &str,
    db: &FloorDatabase,
    radius_m: f64,
    at: sim::Pose2,
    from_ms: i64,
    for_s: f64,
) -> traffic::Itinerary {
    traffic::Itinerary {
        plan_id: plan_id.to_owned(),
        robot: db.robot.clone(),
        floor: db.floor.clone(),
        start_unix_ms: from_ms,
        trajectory: vec![traffic::TimedPose {
            t_s: 0.0,
            x: at.x,
            y: at.y,
            yaw: at.yaw,
        }],
        radius_m,
        tolerance_s: 0.0,
        expires_unix_ms: from_ms + (for_s * 1000.0).round() as i64,
        delay_s: 0.0,
        revision: 1,
    }
}

/// Commits `standing` (a robot with no plan), replacing its robot's itinerary only where
/// `replace` (else a robot the floor's schedule holds already keeps its itinerary). Whether it
/// was recorded: not on a floor holding [`fleet::MAX_ROBOTS_PER_FLOOR`] other robots.
pub(crate) async fn record_standing(
    schedule: &dyn FleetSchedule,
    standing: &traffic::Itinerary,
    replace: bool,
) -> Result<bool, PlanFailure> {
    for _ in 0..COMMIT_ATTEMPTS {
        let (version, all) = schedule.snapshot(&standing.floor).await?;
        let known = all.iter().any(|i| i.robot == standing.robot);
        if (known && !replace) || all.len() >= fleet::MAX_ROBOTS_PER_FLOOR + usize::from(known) {
            return Ok(false);
        }
        match schedule.commit(standing.clone(), version).await? {
            fleet::Committed::Yes(_) => return Ok(true),
            fleet::Committed::Refused(m) => {
                return Err(PlanFailure::Unprocessable(Unusable::Refused(m)));
            }
            fleet::Committed::VersionChanged => {}
        }
    }
    Err(PlanFailure::Unavailable(Unavailable::ScheduleBusy(
        "the robot's place on it was recorded",
    )))
}

/// The later start tried after the drive among the fleet of `fitted` (asked to start at
/// `start_unix_ms`, `later_s` seconds later) was refused (`no_fit`): the next in
/// [`later_start_after`]'s series, and past the start `fitted` already had (a fit that waited
/// at its start longer than asked would be fitted the same again); the refusal where that is
/// beyond `options.max_wait_s`.
fn later_start(
    later_s: f64,
    fitted: &traffic::Itinerary,
    start_unix_ms: i64,
    options: &FleetOptions,
    no_fit: NoFit,
) -> Result<f64, PlanFailure> {
    let next = later_start_after(later_s).max(fleet::set_off_s(fitted, start_unix_ms) + 1.0);
    if next > options.max_wait_s {
        return Err(PlanFailure::FleetConflict(NoFit {
            message: format!(
                "{}; starting up to {later_s} s later did not help within `options.max_wait_s` ({} s)",
                no_fit.message, options.max_wait_s
            ),
            ..no_fit
        }));
    }
    Ok(next)
}

/// The next later start tried after a drive among the fleet refused one `later_s` seconds late:
/// 2 s, then twice as late up to [`LATER_STEP_S`], then that much later each time (doubling
/// further overshoots: every second a robot stands at its start is a second of its makespan,
/// and of every robot that waits for it).
fn later_start_after(later_s: f64) -> f64 {
    if later_s <= 0.0 {
        2.0
    } else {
        (2.0 * later_s).min(later_s + LATER_STEP_S)
    }
}

/// The largest step between two later starts tried, seconds.
const LATER_STEP_S: f64 = 16.0;

/// The latest start tried for a plan whose drives among the fleet end with no robot near
/// (2, 4 and 8 s later).
const LATER_WITHOUT_ROBOTS_S: f64 = 8.0;

/// What a plan among the fleet came to.
pub(crate) enum Among {
    /// Fitted (and committed, unless only checked).
    Fitted(Box<FleetOutcome>),
    /// A robot with no plan yet stands in its route, and the route was not planned around it:
    /// rehearse again, keeping clear of every robot standing now.
    Reroute,
    /// Robots standing with no plan wait for each other's plans, this one among them: it
    /// makes way at the place given for the robots named ([`crate::yielding`]).
    MakeWay(prm::Point2, Vec<String>),
}

/// What a plan refused by a robot standing in its way does.
enum Standing {
    /// The floor's schedule changed: fit again.
    Changed,
    /// The robot was not avoided by the route: rehearse around it.
    Reroute,
    /// Robots standing in each other's way wait for each other's plans: this one makes way
    /// at `at` for `for_robots`.
    MakeWay(prm::Point2, Vec<String>),
}

/// The floor as a plan saw it when it was refused.
struct View<'a> {
    schedule: &'a dyn FleetSchedule,
    floor: &'a str,
    version: i64,
    others: Vec<traffic::Itinerary>,
    since: std::time::Instant,
    standing_wait_s: f64,
    /// The standing robots the route keeps clear of; `None`: it did not try.
    avoided: Option<&'a [String]>,
    /// The robot waiting, its route and radius, and its world: where it may make way
    /// ([`crate::yielding`]; `make_way`: the margin its routes keep from walls and objects),
    /// the place it makes way at is found there.
    me: &'a str,
    route: &'a [(f64, f64)],
    radius_m: f64,
    world: &'a World,
    make_way: Option<f64>,
}

/// Whether `robot` stands with no plan in `others`.
fn stands(others: &[traffic::Itinerary], robot: &str) -> bool {
    others
        .iter()
        .any(|o| o.robot == robot && fleet::stands_only(o))
}

/// A well-formed value that cannot be used (422), naming its field.
fn unusable_field(field: &str, message: impl Into<String>) -> PlanFailure {
    PlanFailure::Unprocessable(Unusable::Field(InvalidField::new(field, message)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(start_ms: i64) -> FleetEntry {
        FleetEntry {
            plan_id: "p-a".to_owned(),
            requested_unix_ms: start_ms,
            options: FleetOptions::default(),
            ticket: 0,
        }
    }

    fn moving(robot: &str, start_ms: i64) -> traffic::Itinerary {
        let pose = |t_s: f64, x: f64| traffic::TimedPose {
            t_s,
            x,
            y: 0.0,
            yaw: 0.0,
        };
        traffic::Itinerary {
            plan_id: format!("p-{robot}"),
            robot: robot.to_owned(),
            floor: "F".to_owned(),
            start_unix_ms: start_ms,
            trajectory: vec![pose(0.0, 0.0), pose(10.0, 5.0)],
            radius_m: 0.3,
            tolerance_s: 2.0,
            expires_unix_ms: start_ms + 40_000,
            delay_s: 0.0,
            revision: 1,
        }
    }

    /// The plans a route is timed among are the committed ones on the clock of the plan's
    /// start, kept apart by the fleet's margin and the fit's slack, and none without them.
    #[test]
    fn a_route_is_timed_among_the_committed_plans_on_its_own_clock() {
        let e = entry(100_000);
        assert!(e.reserved(&[]).is_none());
        // Committed 5 s after this plan starts: at its 5 s it sets off, at 15 s it is at x = 5,
        // and it is held there until it expires.
        let r = e.reserved(&[moving("b", 105_000)]).expect("reserved");
        let b = &r.robots.robots()[0];
        assert_eq!(b.position_at(4.9), None);
        assert_eq!(b.position_at(5.0), Some((0.0, 0.0)));
        assert_eq!(b.position_at(15.0), Some((5.0, 0.0)));
        assert_eq!(b.position_at(44.0), Some((5.0, 0.0)));
        assert_eq!(r.gap_m, fleet::ROBOT_MARGIN_M);
        let o = FleetOptions::default();
        assert_eq!(r.slack_s, o.tolerance_s + fleet::FIT_SLACK_S);
        assert_eq!(r.max_wait_s, o.max_wait_s.min(ROUTE_NODE_WAIT_S));
    }
}
