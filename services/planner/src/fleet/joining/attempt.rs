//! One attempt of a plan to join its floor's schedule ([`Joining::attempt`]): fit, drive among
//! the others, judge, commit; and the state attempts carry from one to the next.

use std::sync::Arc;

use sim::World;

use super::Among;
use super::{
    COMMIT_ATTEMPTS, FleetEntry, LATER_WITHOUT_ROBOTS_S, REFITS_ON_DRIVE, Standing, View,
    later_start, outside_others, stands,
};
use crate::fleet::{self, FleetOptions, FleetOutcome, FleetSchedule, NoFit};
use crate::replay::Replay;
use crate::{FloorDatabase, PlanFailure, Planner, Unusable};

/// A fit already driven among the fleet and refused there: the drive is deterministic, so the
/// same fit among the same plans (the floor's version) is not driven twice.
pub(super) struct RefusedFit {
    itinerary: traffic::Itinerary,
    version: i64,
    why: NoFit,
}

/// What one attempt to join the floor's schedule came to.
pub(super) enum Next {
    /// Try again (the schedule changed, a later start, a fit on the drive, a lost commit).
    Again,
    /// The answer.
    Answer(Among),
    /// The commit lost to other plans too often.
    Exhausted,
}

/// A fit's waits on the clock, and when the robot reaches each waypoint.
struct Timed {
    waits: Vec<fleet::Wait>,
    waypoint_times_unix_ms: Vec<i64>,
}

/// One plan's attempts to join its floor's schedule: what [`Planner::among_the_fleet`] works
/// with, and the state its attempts carry from one to the next.
pub(super) struct Joining<'a> {
    pub(super) planner: &'a Planner,
    pub(super) schedule: &'a dyn FleetSchedule,
    pub(super) db: &'a FloorDatabase,
    pub(super) world: &'a Arc<World>,
    pub(super) report: &'a rehearsal::PlanReport,
    pub(super) replay: &'a Arc<Replay>,
    pub(super) entry: &'a FleetEntry,
    pub(super) avoided: Option<&'a [String]>,
    pub(super) make_way: Option<f64>,
    /// The rehearsed route, as points 0.2 m apart.
    pub(super) route: Vec<(f64, f64)>,
    /// A plan refused because a robot with no plan yet stands in its way waits for the floor's
    /// schedule to change (that robot's plan), up to `options.standing_wait_s` from here.
    pub(super) waiting_since: std::time::Instant,
    /// A plan the drive among the fleet refuses is fitted again from a later start (the robot
    /// standing at its start until then, [`later_start_after`]), within `max_wait_s`.
    pub(super) later_s: f64,
    pub(super) refused_fits: Vec<RefusedFit>,
    /// Drives among the fleet so far.
    pub(super) drives: u32,
    /// After a drive among the fleet that arrived but left the margin to another robot's
    /// schedule, the fit starts from that drive ([`fleet::Basis`]), a few times.
    pub(super) basis: Option<fleet::Basis>,
    pub(super) refits_on_drive: u32,
    /// The robots drives were refused for, in the order met.
    pub(super) in_the_way: Vec<String>,
    pub(super) lost_commits: usize,
    pub(super) rechecks: usize,
}

impl Joining<'_> {
    fn options(&self) -> &FleetOptions {
        &self.entry.options
    }

    fn start_ms(&self) -> i64 {
        self.entry.requested_unix_ms
    }

    fn radius_m(&self) -> f64 {
        self.world.spec().robot.footprint_radius
    }

    /// One attempt: fit among the schedule as it is now, drive the fit among the others,
    /// judge the drive, commit it. `floor_lock`: the floor's lock to take for the commit
    /// (`None`: held throughout already).
    pub(super) async fn attempt(
        &mut self,
        floor_lock: Option<&tokio::sync::Mutex<()>>,
    ) -> Result<Next, PlanFailure> {
        // The core first, then the schedule: the plan is fitted and driven against the
        // schedule as it is when it runs, not as it was when it began to wait.
        let mut core = Some(self.planner.cpu.acquire(self.entry.ticket).await);
        let (version, others) = self.others_now().await?;
        let fitted = match self.fit(&others) {
            Ok(f) => f,
            Err(e) => {
                drop(core.take());
                let view = self.view(version, &others);
                return Ok(next_after(self.planner.wait_for_standing(&view, e).await?));
            }
        };
        // A fit already driven and refused among the same plans: a later start at once.
        if let Some(no_fit) = self
            .refused_fits
            .iter()
            .find(|r| r.itinerary == fitted.itinerary && r.version == version)
            .map(|r| r.why.clone())
        {
            drop(core.take());
            self.basis = None;
            self.later_s = later_start(
                self.later_s,
                &fitted.itinerary,
                self.start_ms(),
                self.options(),
                no_fit,
            )?;
            return Ok(Next::Again);
        }
        let mut timed = self.timed(&fitted);
        // Driven again with its waits while the others drive theirs: a plan that meets
        // another robot there is not committed. What is committed is that drive, waits
        // included, so the schedule holds where the robot will be as it waits and sets off.
        let robots = Arc::new(fleet::simulated_robots(&others, self.start_ms())?);
        let among = self
            .drive(core.take(), &others, &timed.waits, &robots)
            .await?;
        // Waiting for others, or for the floor's lock to commit, holds no core.
        drop(core);
        let (itinerary, refusal) = self.judge(&fitted.itinerary, &among, &others, &robots);
        if let Some(no_fit) = refusal {
            return self
                .after_refusal(
                    no_fit,
                    version,
                    &others,
                    &among,
                    &fitted.itinerary,
                    timed.waits,
                )
                .await;
        }
        let itinerary = traffic::Itinerary {
            tolerance_s: self.options().tolerance_s,
            ..itinerary
        };
        // The times the robot reaches its waypoints are those of the drive committed.
        if among.outcome == rehearsal::AttemptOutcome::Reached {
            let start = self.start_ms();
            timed.waypoint_times_unix_ms =
                fleet::waypoint_steps(&among.steps, &self.report.waypoints)
                    .iter()
                    .map(|&k| start + (k as f64 * among.control_period_s * 1000.0).round() as i64)
                    .collect();
        }
        let version = if self.options().commit {
            match self
                .commit(&itinerary, version, &others, floor_lock)
                .await?
            {
                fleet::CommitEnd::Yes(v) => Some(v),
                fleet::CommitEnd::Refit => {
                    self.lost_commits += 1;
                    return Ok(Next::Again);
                }
                fleet::CommitEnd::Exhausted => return Ok(Next::Exhausted),
            }
        } else {
            None
        };
        // The order at the places it meets others, with who has passed them by now.
        let on_floor = self.schedule.planned(&self.db.floor).await?;
        let passes_after = traffic::passings(&itinerary, &on_floor, fleet::ROBOT_MARGIN_M);
        Ok(Next::Answer(Among::Fitted(Box::new(FleetOutcome {
            passes_after,
            itinerary,
            waypoint_times_unix_ms: timed.waypoint_times_unix_ms,
            among: (!others.is_empty()).then_some(among),
            waits: timed.waits,
            others: others.len(),
            drives: self.drives,
            version,
        }))))
    }

    /// The floor's version and the other robots' itineraries on it now; refused where the
    /// start is inside another robot's reserved footprint (that cannot be waited out: the
    /// robot is already there) or the floor is full.
    async fn others_now(&self) -> Result<(i64, Vec<traffic::Itinerary>), PlanFailure> {
        let (version, committed) = self.schedule.snapshot(&self.db.floor).await?;
        let others: Vec<traffic::Itinerary> = committed
            .into_iter()
            .filter(|i| i.robot != self.db.robot)
            .collect();
        if let Some(here) = self.report.steps.first() {
            outside_others(
                &others.iter().collect::<Vec<_>>(),
                (here.x, here.y),
                self.radius_m(),
                self.start_ms(),
                "the start ",
            )?;
        }
        if others.len() >= fleet::MAX_ROBOTS_PER_FLOOR {
            return Err(PlanFailure::Unprocessable(Unusable::ScheduleFull(
                fleet::MAX_ROBOTS_PER_FLOOR,
            )));
        }
        Ok((version, others))
    }

    /// The plan fitted among `others` with waits: on the rehearsal from the latest later
    /// start, or on the last drive among the fleet ([`fleet::Basis`]).
    fn fit(&self, others: &[traffic::Itinerary]) -> Result<fleet::Fitted, NoFit> {
        let (options, start, db) = (self.options(), self.start_ms(), self.db);
        let template = traffic::Itinerary {
            plan_id: self.entry.plan_id.clone(),
            robot: db.robot.clone(),
            floor: db.floor.clone(),
            start_unix_ms: start,
            trajectory: Vec::new(),
            radius_m: self.radius_m(),
            // The fit leaves the drive room to deviate from the draft (braking before a
            // wait, setting off after it, people in the way): what is committed is the
            // drive, checked with the plan's own tolerance.
            tolerance_s: options.tolerance_s + fleet::FIT_SLACK_S,
            expires_unix_ms: start + (options.hold_s * 1000.0).round() as i64,
            delay_s: 0.0,
            revision: 1,
        };
        let (steps, start_wait_s, max_wait_s) = match &self.basis {
            Some(b) => (&b.steps, 0.0, options.max_wait_s - b.waited_s()),
            None => (&self.report.steps, self.later_s, options.max_wait_s),
        };
        fleet::fit(
            &template,
            steps,
            self.report.control_period_s,
            &self.report.waypoints,
            others,
            max_wait_s.max(0.0),
            start_wait_s,
        )
    }

    /// The fit's waits on the clock (merged into the drive's where it was fitted on one), and
    /// when it reaches each waypoint.
    fn timed(&self, fitted: &fleet::Fitted) -> Timed {
        let (mut waits, waypoint_times_unix_ms) =
            fleet::on_the_clock(fitted, self.start_ms(), self.report.control_period_s);
        // A later start lets pass the robots the drives were refused for as well.
        if self.later_s > 0.0 {
            let at_start = waits
                .iter_mut()
                .zip(&fitted.waits)
                .filter(|(_, f)| f.step == 0);
            for (w, _) in at_start {
                w.for_robots = fleet::dedup(
                    self.in_the_way
                        .iter()
                        .chain(&w.for_robots)
                        .cloned()
                        .collect(),
                );
            }
        }
        let waits = match &self.basis {
            Some(b) => fleet::merge_waits(&b.waits, waits, &fitted.waypoint_steps),
            None => waits,
        };
        Timed {
            waits,
            waypoint_times_unix_ms,
        }
    }

    /// The plan driven with `waits` among `robots` (the others' plans). Alone on the floor
    /// with nothing to wait for, that drive is the validating one, step for step
    /// (`rehearsal::drive_among` drives each leg with its validating attempt's noise): it is
    /// not driven again.
    async fn drive(
        &mut self,
        core: Option<crate::gate::Permit>,
        others: &[traffic::Itinerary],
        waits: &[fleet::Wait],
        robots: &Arc<sim::OtherRobots>,
    ) -> Result<rehearsal::AmongReport, PlanFailure> {
        let report = self.report;
        if others.is_empty() && waits.is_empty() && report.drives_again_alike() {
            return Ok(fleet::validated_alone(report));
        }
        let holds = fleet::holds(waits, self.start_ms(), report.waypoints.len());
        let (replay, world, report, robots) = (
            Arc::clone(self.replay),
            Arc::clone(self.world),
            report.clone(),
            Arc::clone(robots),
        );
        let radius = self.radius_m();
        self.drives += 1;
        self.planner
            .simulating(self.entry.ticket, core, move || {
                replay.among_fresh_draws(&world, &report, &robots, &holds, radius)
            })
            .await?
    }

    /// What is committed of the drive `among` of the fit `fitted`, and why not when it is
    /// not: it met a robot, or arrived within the margin of another's schedule, or was
    /// blocked among the others.
    fn judge(
        &self,
        fitted: &traffic::Itinerary,
        among: &rehearsal::AmongReport,
        others: &[traffic::Itinerary],
        robots: &sim::OtherRobots,
    ) -> (traffic::Itinerary, Option<NoFit>) {
        let refused = |robot: String, message: String| NoFit {
            robots: vec![robot],
            earliest_start_unix_ms: None,
            message,
        };
        let start = self.start_ms();
        if let Some(robot) = among.met_robot() {
            let why = format!(
                "driven again with its waits among the {} other robots' committed plans, the robot did not arrive: {}",
                among.robots, among.reason
            );
            (fitted.clone(), Some(refused(robot.to_owned(), why)))
        } else if among.outcome == rehearsal::AttemptOutcome::Reached {
            let driven = traffic::Itinerary {
                tolerance_s: self.options().tolerance_s,
                ..fleet::driven(fitted, start, &among.steps, among.control_period_s)
            };
            match fleet::first_conflict(&driven, others) {
                Some(c) => {
                    let why = format!(
                        "driven with its waits, the robot would come within {} m of {} (moving; {} m standing still) {:.1} s after its start",
                        fleet::ROBOT_MARGIN_M,
                        c.b_robot,
                        fleet::STILL_MARGIN_M,
                        (c.at_unix_ms - start) as f64 / 1000.0
                    );
                    (driven, Some(refused(c.b_robot.clone(), why)))
                }
                None => (driven, None),
            }
        } else if others.is_empty() {
            // Alone on the floor, the drive differs from the validated one only by its
            // noise: the validated trajectory is what is committed.
            (fitted.clone(), None)
        } else {
            // Blocked (or out of time) among the others: not committed as it stands.
            let no_fit = fleet::did_not_arrive(robots, among, self.radius_m());
            (fitted.clone(), Some(no_fit))
        }
    }

    /// After a drive refused as `no_fit`: wait for a robot standing in the way to get a plan,
    /// fit again on the drive, or try a later start.
    async fn after_refusal(
        &mut self,
        no_fit: NoFit,
        version: i64,
        others: &[traffic::Itinerary],
        among: &rehearsal::AmongReport,
        fitted: &traffic::Itinerary,
        waits: Vec<fleet::Wait>,
    ) -> Result<Next, PlanFailure> {
        // A robot with no plan yet in the way: no later start helps until it has one.
        let view = self.view(version, others);
        let standing = self.planner.wait_for_standing(&view, no_fit).await;
        drop(view);
        let no_fit = match standing {
            Ok(standing) => return Ok(next_after(standing)),
            Err(PlanFailure::FleetConflict(n)) if n.robots.iter().all(|r| !stands(others, r)) => n,
            Err(e) => return Err(e),
        };
        for r in &no_fit.robots {
            if !self.in_the_way.contains(r) {
                self.in_the_way.push(r.clone());
            }
        }
        // Nobody was where the drive ended: people (or its noise) stopped it, which a later
        // start changes little. A few are tried, not `max_wait_s` worth of drives that take
        // the cores from every other plan.
        if self.in_the_way.is_empty() && self.later_s >= LATER_WITHOUT_ROBOTS_S {
            return Err(PlanFailure::FleetConflict(NoFit {
                message: format!(
                    "{}; no robot was where it stopped, and starting up to {} s later did not help",
                    no_fit.message, self.later_s
                ),
                ..no_fit
            }));
        }
        // Arrived, but leaving the margin to a robot's schedule: fitted again on this drive, a
        // few times, before a later start.
        if among.outcome == rehearsal::AttemptOutcome::Reached
            && among.met_robot().is_none()
            && self.refits_on_drive < REFITS_ON_DRIVE
        {
            self.refits_on_drive += 1;
            self.basis = Some(fleet::Basis {
                steps: among.steps.clone(),
                waits,
            });
            return Ok(Next::Again);
        }
        self.basis = None;
        self.refused_fits.push(RefusedFit {
            itinerary: fitted.clone(),
            version,
            why: no_fit.clone(),
        });
        self.later_s = later_start(
            self.later_s,
            fitted,
            self.start_ms(),
            self.options(),
            no_fit,
        )?;
        Ok(Next::Again)
    }

    /// Commits `itinerary` against the version it was checked at, under the floor's lock
    /// (`floor_lock`; `None`: held already). Plans committed since the snapshot (here, or by
    /// another process) that this drive keeps the margin from do not send it back to be
    /// fitted and driven again.
    async fn commit(
        &mut self,
        itinerary: &traffic::Itinerary,
        version: i64,
        others: &[traffic::Itinerary],
        floor_lock: Option<&tokio::sync::Mutex<()>>,
    ) -> Result<fleet::CommitEnd, PlanFailure> {
        let _one_commit_per_floor = match floor_lock {
            Some(lock) => Some(lock.lock().await),
            None => None,
        };
        fleet::commit_among(
            self.schedule,
            itinerary,
            version,
            others.to_vec(),
            &mut self.rechecks,
            COMMIT_ATTEMPTS,
        )
        .await
    }

    /// The floor as this plan sees it at `version`, among `others`.
    fn view<'v>(&'v self, version: i64, others: &[traffic::Itinerary]) -> View<'v> {
        View {
            schedule: self.schedule,
            floor: &self.db.floor,
            version,
            others: others.to_vec(),
            since: self.waiting_since,
            standing_wait_s: self.options().standing_wait_s,
            avoided: self.avoided,
            me: &self.db.robot,
            route: &self.route,
            radius_m: self.radius_m(),
            world: self.world,
            make_way: self.make_way,
        }
    }
}

/// What follows a wait for robots standing in the way.
fn next_after(standing: Standing) -> Next {
    match standing {
        Standing::Changed => Next::Again,
        Standing::Reroute => Next::Answer(Among::Reroute),
        Standing::MakeWay(at, robots) => Next::Answer(Among::MakeWay(at, robots)),
    }
}
