//! Fleet coordination: a plan among the other robots of its floor. Here the fit and the commit;
//! [`joining`]: the plan's way into the floor's schedule (standing at its start until planned,
//! routes around robots standing with no plan, the drive among the others, retries);
//! [`yielding`]: one of robots standing in each other's only way makes way.
//!
//! A plan among the fleet: the timed trajectory the rehearsal validated, checked against every
//! other robot's committed itinerary on the floor ([`traffic`]: footprints, each robot
//! anywhere within its time tolerance of its schedule), conflicts resolved by waiting, and the
//! result committed to the floor's schedule against the version it was checked against.
//!
//! How a conflict is resolved ([`fit`]): the robot waits at the last waypoint it reaches
//! before the conflict (the start first of all, which is a later start), one second more at a
//! time, until the conflict is gone or moves later. A conflict that happens while the robot
//! stands waiting at a waypoint (the waypoint is in the other robot's way) moves the wait to
//! the waypoint before it, down to the start (a conflict at the goal, where the robot is held
//! after arriving, moves the wait before the goal). So two robots sent down one corridor from its
//! two ends never meet in it: the second one waits before the corridor, or where the first
//! one's path leaves room. Where the robot, waiting at its start (or the first stop it may
//! still wait at), would stand in another robot's way, it leaves at once and waits at the next
//! stop instead. Where the waits would exceed `max_wait_s`, the plan is refused, naming the
//! robots in the way and the earliest later start that fits with no wait.
//!
//! Then the plan is driven again in the simulation with its waits, while every other robot
//! drives its committed itinerary in the same simulation ([`simulated_robots`]: footprints the
//! laser sees, moving along their schedules, as they do not react to this robot). A drive that
//! arrives but leaves the margin to another robot's schedule (people met at other times than in
//! the validating drive make it early or late after a wait) is fitted again on itself
//! ([`Basis`]): waits are added where the margin was lost. A plan that touches another robot
//! there, or does not arrive among them (blocked), is fitted again from a later start, and
//! refused (409, naming the robots) where no start within `max_wait_s` helps.
//! Nothing is committed that was not driven through among the plans it was fitted against.
//!
//! Plans on one floor are fitted and driven side by side, each against the schedule it read,
//! and committed one at a time against that version. Where plans were committed meanwhile, a
//! plan whose drive keeps the margin from each of them is committed without driving it again
//! ([`committed_since`]); one that does not is fitted and driven again against the new
//! schedule (after a few such losses, holding the floor's lock from its snapshot to its
//! commit, so that a busy floor still takes it).
//!
//! What is guaranteed: the committed itineraries keep the robots apart by the margin as long as
//! each stays within its tolerance of its schedule (progress reports shift a late robot's
//! schedule), and the robot, holding at its waypoints and setting off again under noise among
//! the others and the people, arrived in that drive.

pub(crate) mod improve;
pub(crate) mod joining;
pub(crate) mod yielding;

use std::future::Future;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};

use prm::Point2;
use sim::Pose2;
use traffic::{Conflict, Itinerary, Margins, Reserved, TimedPose};

use crate::{InvalidField, PlanFailure, PortError};

/// A boxed future of a [`FleetSchedule`] call.
pub type FleetFuture<'a, T> = Pin<Box<dyn Future<Output = Result<T, PortError>> + Send + 'a>>;

/// How a commit went.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Committed {
    /// Committed; the floor's new version.
    Yes(i64),
    /// Another plan was committed on the floor since the snapshot: check again.
    VersionChanged,
    /// The schedule refuses the itinerary (a value out of its range); why.
    Refused(String),
}

/// The fleet's schedule as the planner sees it (the `traffic` store in the job database).
pub trait FleetSchedule: Send + Sync {
    /// The floor's version and every unexpired itinerary on it.
    fn snapshot<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, (i64, Vec<Itinerary>)>;
    /// The floor's version alone (what a plan waiting for the floor to change reads).
    fn version<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, i64>;
    /// Commits `itinerary` (replacing its robot's previous one) if the floor is still at
    /// `expected_version`.
    fn commit(&self, itinerary: Itinerary, expected_version: i64) -> FleetFuture<'_, Committed>;
    /// Revises committed plans of one floor at once (each `plans[k]` replacing the plan of its
    /// `plan_id`, whose revision the schedule raises by one) if the floor is still at
    /// `expected_version`: all of them or none. Refused where one of their robots has set off
    /// or a plan is gone.
    fn revise(&self, plans: Vec<Itinerary>, expected_version: i64) -> FleetFuture<'_, Committed>;
    /// Now, milliseconds since the Unix epoch (the schedule's clock).
    fn now_ms(&self) -> i64;
    /// Every unexpired plan on the floor with what its robot reported (the passing order at
    /// the places plans meet needs who has passed). By default the snapshot's itineraries, as
    /// if no robot had reported yet.
    fn planned<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, Vec<traffic::Planned>> {
        Box::pin(async move {
            let (_, itineraries) = self.snapshot(floor).await?;
            Ok(itineraries
                .into_iter()
                .map(|itinerary| traffic::Planned {
                    itinerary,
                    acknowledged: 1,
                    progress_t_s: None,
                })
                .collect())
        })
    }
    /// Says where every process sharing the schedule sees it that a plan waits for robots
    /// standing in its way ([`traffic::Wait`], replacing what its robot's plan said before). By
    /// default nowhere: a schedule of one process's own, whose waits the planner holds itself.
    fn post_wait(&self, wait: traffic::Wait) -> FleetFuture<'_, ()> {
        drop(wait);
        Box::pin(async { Ok(()) })
    }
    /// `robot`'s plan no longer waits (see [`FleetSchedule::post_wait`]).
    fn clear_wait<'a>(&'a self, robot: &'a str) -> FleetFuture<'a, ()> {
        let _ = robot;
        Box::pin(async { Ok(()) })
    }
    /// The waits on `floor` every process sharing the schedule posted, not yet ended (by
    /// default none: see [`FleetSchedule::post_wait`]).
    fn waits<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, Vec<traffic::Wait>> {
        let _ = floor;
        Box::pin(async { Ok(Vec::new()) })
    }
}

/// How a plan takes part in the fleet's schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FleetOptions {
    /// Commit the plan to the floor's schedule (default true); false only checks it.
    pub commit: bool,
    /// When the robot sets off, ms since the Unix epoch; `None`: now.
    pub start_unix_ms: Option<i64>,
    /// How early or late the robot may be on its schedule, seconds (default 2).
    pub tolerance_s: f64,
    /// Most waiting, in total, the plan may take to let other robots pass, seconds
    /// (default 120): beyond it the plan is refused with the earliest start that fits.
    pub max_wait_s: f64,
    /// How long the robot is held at its last goal after arriving, seconds (default 30).
    pub hold_s: f64,
    /// How long, at most, the plan waits (wall-clock) for robots standing in its way with no
    /// plan yet to get theirs, seconds (default [`STANDING_WAIT_S`]; 0: refuse
    /// at once, naming them, as a client asking one plan at a time and asking again later
    /// wants).
    pub standing_wait_s: f64,
}

impl Default for FleetOptions {
    fn default() -> Self {
        Self {
            commit: true,
            start_unix_ms: None,
            tolerance_s: 2.0,
            max_wait_s: 120.0,
            hold_s: 30.0,
            standing_wait_s: STANDING_WAIT_S,
        }
    }
}

/// Largest tolerance, wait and hold, seconds.
pub const MAX_FLEET_S: f64 = 3600.0;
/// Latest start a plan may ask for, ms since the Unix epoch (2100-01-01).
pub const MAX_START_UNIX_MS: i64 = 4_102_444_800_000;
/// Most other robots' plans a floor's schedule holds when a plan is checked against it: past
/// it, the plan is refused (a floor that busy needs traffic management this schedule does not
/// do).
pub const MAX_ROBOTS_PER_FLOOR: usize = 100;
/// Gap kept between two robots' footprints beyond their radii, metres: how close to a robot's
/// footprint another may pass before the first one's controller reacts to it. Regulated Pure
/// Pursuit slows for anything closer than Nav2's `cost_scaling_dist` (0.6 m from the centre of
/// Nav2's 0.22 m default robot: 0.38 m beyond its footprint, `sim::rpp`); a robot that slows for
/// another leaves its schedule, and the schedule holds only where nobody has to react.
pub const ROBOT_MARGIN_M: f64 = 0.6 - sim::rpp::NAV2_DEFAULT_ROBOT_RADIUS_M;
/// Gap kept from a robot standing still (waiting, parked at its goal, at its start before it
/// sets off), metres: the safety margin a plan keeps from any obstacle
/// (`PlanOptions::safety_margin_m`'s default). A robot standing still does not react, and the
/// one passing it does so in its drive among the fleet, which is what is committed.
pub const STILL_MARGIN_M: f64 = 0.1;
/// The margins between two robots' schedules: [`ROBOT_MARGIN_M`] while both move,
/// [`STILL_MARGIN_M`] where either stands still.
pub const MARGINS: Margins = Margins {
    moving: ROBOT_MARGIN_M,
    still: STILL_MARGIN_M,
};
/// Fresh draws of people and noise a plan's drive among the fleet is tried with when it did
/// not arrive and no other robot was involved (people or noise stopped it): as the rehearsal
/// re-samples, a person who happened to stand in the way is not a conflict of the schedule.
pub const FRESH_DRAWS: u32 = 2;
/// Time the fit adds to a plan's tolerance, seconds: the drive among the fleet deviates from
/// the fitted draft by about this much (braking before a wait and setting off after it take
/// about a second at the sample robot's limits; people slow it), and a fit that cleared another
/// robot by less would have its drive refused and fitted again from a later start.
pub const FIT_SLACK_S: f64 = 1.0;
/// How long, at most, a plan waits for a robot standing in its way with no plan yet (that
/// robot may be planning now; once its plan is committed, the schedule says when it leaves),
/// seconds of wall-clock time. Two robots each standing in the other's way wait this long, then
/// are refused.
pub const STANDING_WAIT_S: f64 = 10.0;
/// How long a plan waits for the plan of a robot standing in its route before its route is
/// rehearsed again around it, seconds of wall-clock time: a detour costs every robot that takes
/// it, while a robot asking for a plan at the same moment usually has one within this time.
pub const REROUTE_AFTER_S: f64 = 2.0;
/// Steps of waiting tried, seconds.
const WAIT_STEP_S: f64 = 1.0;

impl FleetOptions {
    /// The options, or which one is out of range.
    pub fn check(&self) -> Result<(), InvalidField> {
        for (name, v) in [
            ("tolerance_s", self.tolerance_s),
            ("max_wait_s", self.max_wait_s),
            ("hold_s", self.hold_s),
            ("standing_wait_s", self.standing_wait_s),
        ] {
            if !(v.is_finite() && (0.0..=MAX_FLEET_S).contains(&v)) {
                return Err(InvalidField::new(
                    format!("options.{name}"),
                    format!("`options.{name}` must lie in [0, {MAX_FLEET_S}] seconds, got {v}"),
                ));
            }
        }
        if let Some(t) = self.start_unix_ms
            && !(0..=MAX_START_UNIX_MS).contains(&t)
        {
            return Err(InvalidField::new(
                "options.start_time_ms",
                format!(
                    "`options.start_time_ms` must lie in [0, {MAX_START_UNIX_MS}] ms since the Unix epoch, got {t}"
                ),
            ));
        }
        Ok(())
    }
}

/// A wait the plan carries so that another robot can pass.
#[derive(Debug, Clone, PartialEq)]
pub struct Wait {
    /// The waypoint (an index of the plan's waypoints) waited at; `None`: the start (a later
    /// start).
    pub waypoint: Option<usize>,
    /// Seconds waited.
    pub wait_s: f64,
    /// When the robot may go on, ms since the Unix epoch.
    pub not_before_unix_ms: i64,
    /// The robots it lets pass.
    pub for_robots: Vec<String>,
}

/// A plan as it takes part in the floor's schedule.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetOutcome {
    /// The itinerary checked (and committed, unless `options.commit` was false).
    pub itinerary: Itinerary,
    /// When the robot reaches each waypoint, ms since the Unix epoch (waits included).
    pub waypoint_times_unix_ms: Vec<i64>,
    /// The waits that let other robots pass, in order.
    pub waits: Vec<Wait>,
    /// The plan driven again with its waits among the other robots' committed plans (`None`
    /// when there were none).
    pub among: Option<rehearsal::AmongReport>,
    /// Other robots' itineraries it was checked against.
    pub others: usize,
    /// Drives among the other robots' plans it took (those refused included; 0 when alone on
    /// the floor with nothing to wait for, where the validating drive is the one).
    pub drives: u32,
    /// The floor's version after the commit; `None` when not committed.
    pub version: Option<i64>,
    /// Where the plan meets another plan that passes there first (in the schedule's order),
    /// along the plan: the robot goes no further than the first one not yet passed.
    pub passes_after: Vec<traffic::Passing>,
}

/// The other robots' itineraries as robots of a simulation whose clock starts at
/// `start_unix_ms` (seconds after it), as the schedule places them: along their trajectories
/// (with their delays), held at their last pose until they expire, absent before they start.
/// An itinerary the simulation refuses (the schedule checked it when it was committed) is an
/// internal failure.
pub fn simulated_robots(
    others: &[Itinerary],
    start_unix_ms: i64,
) -> Result<sim::OtherRobots, PlanFailure> {
    let seconds = |unix_ms: i64| (unix_ms - start_unix_ms) as f64 / 1000.0;
    sim::OtherRobots::new(
        others
            .iter()
            .map(|it| {
                let origin = seconds(it.start_unix_ms) + it.delay_s;
                let mut track: Vec<(f64, f64, f64)> = it
                    .trajectory
                    .iter()
                    .map(|p| (origin + p.t_s, p.x, p.y))
                    .collect();
                if let Some(&(t, x, y)) = track.last() {
                    track.push((seconds(it.expires_unix_ms).max(t), x, y));
                }
                sim::OtherRobot {
                    name: it.robot.clone(),
                    radius: it.radius_m,
                    track,
                }
            })
            .collect(),
    )
    .map_err(|e| PlanFailure::internal(format!("the other robots' itineraries: {e}")))
}

/// A plan alone on its floor with nothing to wait for, as its drive among the fleet: the
/// validating drive itself, step for step (`rehearsal::drive_among` drives each leg with its
/// validating attempt's noise).
pub fn validated_alone(report: &rehearsal::PlanReport) -> rehearsal::AmongReport {
    rehearsal::AmongReport {
        outcome: rehearsal::AttemptOutcome::Reached,
        reason: "every goal reached, no other robot on the floor".to_owned(),
        time_s: report.simulated_time_s,
        min_robot_clearance_m: None,
        robots: 0,
        steps: report.steps.clone(),
        control_period_s: report.control_period_s,
        people_draw: 0,
    }
}

/// The refusal of a plan whose drive among `robots` (`among`) did not arrive, naming the
/// robots near where it ended.
pub fn did_not_arrive(
    robots: &sim::OtherRobots,
    among: &rehearsal::AmongReport,
    radius_m: f64,
) -> NoFit {
    NoFit {
        robots: robots_near_the_end(robots, among, radius_m),
        earliest_start_unix_ms: None,
        message: format!(
            "driven again with its waits among the {} other robots' committed plans, the robot did not arrive: {}",
            among.robots, among.reason
        ),
    }
}

/// The other robots within a metre of the footprint where `among`'s drive ended, when it
/// ended (those that blocked it, when it stalled), closest first.
pub fn robots_near_the_end(
    robots: &sim::OtherRobots,
    among: &rehearsal::AmongReport,
    radius_m: f64,
) -> Vec<String> {
    let Some(end) = among.steps.last() else {
        return Vec::new();
    };
    let mut near: Vec<(f64, &str)> = robots
        .at(among.time_s)
        .into_iter()
        .filter_map(|(k, (x, y), r)| {
            let gap = (x - end.x).hypot(y - end.y) - r - radius_m;
            let name = robots.robots().get(k)?.name.as_str();
            (gap < 1.0).then_some((gap, name))
        })
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    near.into_iter().map(|(_, n)| n.to_owned()).collect()
}

/// When the robot may leave each point of its route, seconds after `start_unix_ms`: `[0]` the
/// start, `[k + 1]` waypoint `k` of `waypoints`; 0 where it does not wait.
pub fn holds(waits: &[Wait], start_unix_ms: i64, waypoints: usize) -> Vec<f64> {
    let mut holds = vec![0.0; waypoints + 1];
    for w in waits {
        let at = w.waypoint.map_or(0, |k| k + 1);
        if let Some(h) = holds.get_mut(at) {
            *h = f64::max(*h, (w.not_before_unix_ms - start_unix_ms) as f64 / 1000.0);
        }
    }
    holds
}

/// The waits of a plan fitted on a drive among the fleet (a [`Basis`]) that already held at
/// `old`'s points: each old wait later by the `new` waits at or before the step it holds at
/// (`at_steps[j]` for waypoint `j`, 0 for the start), and a new wait at the same point as an
/// old one merged with it (their seconds added, the later time, both robots' lists). In the
/// order of the route.
pub fn merge_waits(old: &[Wait], new: Vec<Wait>, at_steps: &[usize]) -> Vec<Wait> {
    let step_of = |w: &Wait| {
        w.waypoint
            .map_or(0, |j| at_steps.get(j).copied().unwrap_or(0))
    };
    let mut merged: Vec<Wait> = old
        .iter()
        .map(|w| {
            let at = step_of(w);
            let shift: f64 = new
                .iter()
                .filter(|n| step_of(n) <= at)
                .map(|n| n.wait_s)
                .sum();
            Wait {
                not_before_unix_ms: w.not_before_unix_ms + (shift * 1000.0).round() as i64,
                ..w.clone()
            }
        })
        .collect();
    for w in new {
        match merged.iter_mut().find(|m| m.waypoint == w.waypoint) {
            Some(m) => {
                m.wait_s += w.wait_s;
                m.not_before_unix_ms = m.not_before_unix_ms.max(w.not_before_unix_ms);
                m.for_robots = dedup(m.for_robots.iter().chain(&w.for_robots).cloned().collect());
            }
            None => merged.push(w),
        }
    }
    merged.sort_by_key(|w| w.waypoint.map_or(0, |j| j + 1));
    merged
}

/// What a plan is fitted on after its drive among the fleet arrived but left the margin to
/// another robot's schedule: that drive (its holds included) and its waits. The drive differs
/// from the validating one after each wait (the people have moved on meanwhile, so a robot
/// that a person slowed there before may now pass at once): fitted on the validating drive
/// again, from a later start, the same difference meets the same robot. Fitted on the drive,
/// the waits added keep the margin where it was lost, and the next drive is the same as this
/// one up to the first of them.
#[derive(Debug, Clone)]
pub struct Basis {
    /// The drive among the fleet, every control period from the start.
    pub steps: Vec<Pose2>,
    /// The waits it was driven with.
    pub waits: Vec<Wait>,
}

impl Basis {
    /// Seconds waited in all.
    pub fn waited_s(&self) -> f64 {
        self.waits.iter().map(|w| w.wait_s).sum()
    }
}

/// Why no schedule fits.
#[derive(Debug, Clone, PartialEq)]
pub struct NoFit {
    /// The robots in the way.
    pub robots: Vec<String>,
    /// The earliest start that fits with no wait, ms since the Unix epoch, if one was found
    /// before every other robot's itinerary expires.
    pub earliest_start_unix_ms: Option<i64>,
    /// In words.
    pub message: String,
}

/// Whether `it` never moves: a robot standing where it is with no plan (yet), as a robot
/// asking for a plan is recorded until its plan is committed. When it sets off is not known, so
/// no wait resolves a conflict with it: its plan, once committed, will say.
pub fn stands_only(it: &Itinerary) -> bool {
    let Some(first) = it.trajectory.first() else {
        return true;
    };
    it.trajectory
        .iter()
        .all(|p| (p.x - first.x).hypot(p.y - first.y) < 0.01)
}

/// A plan id: unique in practice (time, a process counter and the robot, mixed).
pub fn plan_id(robot: &str, now_ms: i64) -> String {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    let h = grid::seed::mix(
        grid::seed::mix(now_ms as u64, u64::from(nanos) ^ (n << 32)),
        grid::hash::fnv1a(robot.as_bytes()),
    );
    format!("plan-{h:016x}")
}

/// The step of `steps` at which each waypoint is reached: the first local minimum of the
/// distance to it within 1 m after the previous waypoint's step, else the closest step.
pub fn waypoint_steps(steps: &[Pose2], waypoints: &[Point2]) -> Vec<usize> {
    let mut out = Vec::with_capacity(waypoints.len());
    let mut from = 0;
    for w in waypoints {
        let d = |k: usize| (steps[k].x - w.x).hypot(steps[k].y - w.y);
        let mut best = from.min(steps.len().saturating_sub(1));
        for k in from..steps.len() {
            if d(k) < d(best) {
                best = k;
            }
            // Past a close approach and moving away: that was the pass.
            if d(best) < 1.0 && d(k) > d(best) + 0.5 {
                break;
            }
        }
        out.push(best);
        from = best;
    }
    out
}

/// A candidate schedule: the rehearsed steps with waits inserted at some of them.
struct Draft<'a> {
    steps: &'a [Pose2],
    dt: f64,
    /// (step index, seconds), by step.
    waits: Vec<(usize, f64)>,
}

impl Draft<'_> {
    fn itinerary(&self, template: &Itinerary) -> Itinerary {
        let mut trajectory = Vec::with_capacity(self.steps.len() + self.waits.len());
        let mut shift = 0.0;
        for (k, p) in self.steps.iter().enumerate() {
            let t = k as f64 * self.dt + shift;
            trajectory.push(TimedPose {
                t_s: t,
                x: p.x,
                y: p.y,
                yaw: p.yaw,
            });
            let waited: f64 = self
                .waits
                .iter()
                .filter(|(i, _)| *i == k)
                .map(|(_, s)| s)
                .sum();
            if waited > 0.0 {
                shift += waited;
                trajectory.push(TimedPose {
                    t_s: t + waited,
                    x: p.x,
                    y: p.y,
                    yaw: p.yaw,
                });
            }
        }
        let duration_s = trajectory.last().map_or(0.0, |p| p.t_s);
        Itinerary {
            trajectory,
            expires_unix_ms: template.start_unix_ms
                + ((duration_s + template.tolerance_s) * 1000.0).ceil() as i64
                + (template.expires_unix_ms - template.start_unix_ms),
            ..template.clone()
        }
    }

    /// Schedule time of step `k`, seconds (after the waits at earlier steps).
    fn time_of(&self, k: usize) -> f64 {
        k as f64 * self.dt
            + self
                .waits
                .iter()
                .filter(|(i, _)| *i < k)
                .map(|(_, s)| s)
                .sum::<f64>()
    }

    fn total_wait(&self) -> f64 {
        self.waits.iter().map(|(_, s)| s).sum()
    }

    /// The robot standing at step `k` while it waits there, as an itinerary of its own.
    fn standing(&self, k: usize, template: &Itinerary) -> Itinerary {
        let p = self
            .steps
            .get(k)
            .or(self.steps.last())
            .copied()
            .unwrap_or(Pose2::new(0.0, 0.0, 0.0));
        let (from, to) = (self.time_of(k), self.time_of(k) + self.wait_at(k));
        let pose = |t_s: f64| TimedPose {
            t_s,
            x: p.x,
            y: p.y,
            yaw: p.yaw,
        };
        Itinerary {
            trajectory: vec![pose(from), pose(to)],
            expires_unix_ms: template.start_unix_ms + (to * 1000.0).ceil() as i64,
            ..template.clone()
        }
    }

    /// Seconds waited at step `at`.
    fn wait_at(&self, at: usize) -> f64 {
        self.waits
            .iter()
            .filter(|(i, _)| *i == at)
            .map(|(_, s)| s)
            .sum()
    }

    /// Waits exactly `s` seconds at step `at` (none when `s` is 0).
    fn set_wait(&mut self, at: usize, s: f64) {
        self.waits.retain(|(i, _)| *i != at);
        if s > 0.0 {
            self.add_wait(at, s);
        }
    }

    fn add_wait(&mut self, at: usize, s: f64) {
        match self.waits.iter_mut().find(|(i, _)| *i == at) {
            Some(w) => w.1 += s,
            None => {
                self.waits.push((at, s));
                self.waits.sort_by_key(|w| w.0);
            }
        }
    }
}

/// The first conflict of `itinerary` with `others` (footprints closer than
/// [`ROBOT_MARGIN_M`], each robot anywhere within its tolerance of its schedule).
pub fn first_conflict(itinerary: &Itinerary, others: &[Itinerary]) -> Option<Conflict> {
    first(itinerary, &Reserved::new(others, itinerary.start_unix_ms))
}

/// When `it`'s robot sets off, seconds after `start_unix_ms`: the end of its first stay at
/// its first pose (0 where it moves at once).
pub fn set_off_s(it: &Itinerary, start_unix_ms: i64) -> f64 {
    let origin = (it.start_unix_ms - start_unix_ms) as f64 / 1000.0;
    let Some(first) = it.trajectory.first() else {
        return origin.max(0.0);
    };
    let stays = it
        .trajectory
        .iter()
        .take_while(|p| (p.x - first.x).hypot(p.y - first.y) < 1e-6)
        .last()
        .map_or(0.0, |p| p.t_s);
    (origin + stays).max(0.0)
}

/// The itineraries of `now` that are not in `checked` (committed, replaced or moved by a
/// progress report since `checked` was read): what a plan driven among `checked` has not met.
/// A plan whose drive keeps [`ROBOT_MARGIN_M`] from all of them ([`first_conflict`]) is
/// committed among `now` without driving it again: the margin is where a controller starts
/// reacting to another robot, so they are at most seen by its laser, and people do not react to
/// other robots. `bench fleet`'s joint run drives every committed plan among all the others.
pub fn committed_since(checked: &[Itinerary], now: &[Itinerary]) -> Vec<Itinerary> {
    now.iter()
        .filter(|i| !checked.contains(i))
        .cloned()
        .collect()
}

/// How [`commit_among`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum CommitEnd {
    /// Committed; the floor's new version.
    Yes(i64),
    /// A plan committed since conflicts with it: fit and drive it again.
    Refit,
    /// The floor kept changing: `max_rechecks` used up.
    Exhausted,
}

/// Commits `itinerary`, driven among `checked` (the floor at `version`). Where the floor changed
/// meanwhile, it is committed against the new version when it keeps the margin from every plan
/// committed since ([`committed_since`]), and sent back to be fitted again otherwise. Each such
/// check counts in `rechecks`, up to `max_rechecks`.
pub(crate) async fn commit_among(
    schedule: &dyn FleetSchedule,
    itinerary: &Itinerary,
    mut version: i64,
    mut checked: Vec<Itinerary>,
    rechecks: &mut usize,
    max_rechecks: usize,
) -> Result<CommitEnd, PlanFailure> {
    loop {
        match schedule.commit(itinerary.clone(), version).await? {
            Committed::Yes(v) => return Ok(CommitEnd::Yes(v)),
            Committed::Refused(m) => {
                return Err(PlanFailure::Unprocessable(crate::Unusable::Refused(m)));
            }
            Committed::VersionChanged => {}
        }
        *rechecks += 1;
        if *rechecks >= max_rechecks {
            return Ok(CommitEnd::Exhausted);
        }
        let (now_version, now) = schedule.snapshot(&itinerary.floor).await?;
        let now: Vec<Itinerary> = now
            .into_iter()
            .filter(|i| i.robot != itinerary.robot)
            .collect();
        if now.len() >= MAX_ROBOTS_PER_FLOOR
            || first_conflict(itinerary, &committed_since(&checked, &now)).is_some()
        {
            return Ok(CommitEnd::Refit);
        }
        (version, checked) = (now_version, now);
    }
}

/// `fitted` with the trajectory the robot drove (`steps` every `dt` seconds from
/// `start_unix_ms`, waits included, a later start as standing at the start): standing still,
/// only the first and last pose of each stop are kept; the hold at the goal is as fitted.
pub fn driven(fitted: &Itinerary, start_unix_ms: i64, steps: &[Pose2], dt: f64) -> Itinerary {
    let still = |a: &Pose2, b: &Pose2| (a.x - b.x).hypot(a.y - b.y) < 1e-6;
    let mut trajectory: Vec<TimedPose> = Vec::with_capacity(steps.len());
    for (k, p) in steps.iter().enumerate() {
        let keep =
            k == 0 || k + 1 == steps.len() || !still(p, &steps[k - 1]) || !still(p, &steps[k + 1]);
        if keep {
            trajectory.push(TimedPose {
                t_s: k as f64 * dt,
                x: p.x,
                y: p.y,
                yaw: p.yaw,
            });
        }
    }
    let hold_ms = fitted.expires_unix_ms - fitted.end_unix_ms();
    let mut out = Itinerary {
        trajectory,
        start_unix_ms,
        ..fitted.clone()
    };
    out.expires_unix_ms = out.end_unix_ms() + hold_ms.max(0);
    out
}

fn first(itinerary: &Itinerary, others: &Reserved<'_>) -> Option<Conflict> {
    others.first_with(itinerary, MARGINS)
}

/// A fitted plan.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// Its itinerary, waits included.
    pub itinerary: Itinerary,
    /// The step of the rehearsal each waypoint is reached at.
    pub waypoint_steps: Vec<usize>,
    /// Each wait, in the order of the steps it is at.
    pub waits: Vec<FitWait>,
}

/// A wait of a fitted plan.
#[derive(Debug, Clone, PartialEq)]
pub struct FitWait {
    /// The step of the rehearsal it is at (0: the start).
    pub step: usize,
    /// How long, seconds.
    pub wait_s: f64,
    /// The robots it lets pass.
    pub for_robots: Vec<String>,
}

/// Fits a rehearsed plan (`steps` every `dt` seconds from the start, reaching `waypoints`)
/// among `others`, as the module docs describe, the robot standing at its start for at least
/// `start_wait_s`. `template` carries the robot, floor, plan id, radius, tolerance and start;
/// its `expires_unix_ms - start_unix_ms` is the hold after the last goal. A robot that sets
/// off later is at its start meanwhile, and the itinerary says so: another robot's plan
/// through its start while it stands there is a conflict that no later start resolves.
pub fn fit(
    template: &Itinerary,
    steps: &[Pose2],
    dt: f64,
    waypoints: &[Point2],
    others: &[Itinerary],
    max_wait_s: f64,
    start_wait_s: f64,
) -> Result<Fitted, NoFit> {
    let at_waypoint = waypoint_steps(steps, waypoints);
    // Where the robot may wait: the start, then each waypoint's step.
    let stops: Vec<usize> = std::iter::once(0)
        .chain(at_waypoint.iter().copied())
        .collect();
    let mut draft = Draft {
        steps,
        dt,
        waits: Vec::new(),
    };
    draft.set_wait(0, start_wait_s);
    // The others are cut into pieces once for every candidate checked below.
    let committed = Reserved::new(others, template.start_unix_ms);
    // Waits go to stops[floor..ceiling]: the floor rises past a stop the robot must leave
    // early, the ceiling falls below one it must not stand at.
    let (mut floor, mut ceiling) = (0, stops.len());
    let mut blockers: Vec<(usize, Vec<String>)> = Vec::new();
    let mut in_the_way: Vec<String> = Vec::new();
    loop {
        let itinerary = draft.itinerary(template);
        let Some(c) = first(&itinerary, &committed) else {
            return Ok(fitted(itinerary, at_waypoint, &draft.waits, &blockers));
        };
        if let Some(b) = others
            .iter()
            .find(|o| o.robot == c.b_robot && stands_only(o))
        {
            return Err(NoFit {
                robots: vec![b.robot.clone()],
                earliest_start_unix_ms: None,
                message: format!(
                    "{} stands in the plan's way at ({:.2}, {:.2}) with no plan of its own yet",
                    b.robot, c.b_xy[0], c.b_xy[1]
                ),
            });
        }
        if !in_the_way.contains(&c.b_robot) {
            in_the_way.push(c.b_robot.clone());
        }
        if draft.total_wait() + WAIT_STEP_S > max_wait_s + 1e-9 {
            let refused = no_fit(
                template,
                &draft,
                others,
                &committed,
                in_the_way.clone(),
                max_wait_s,
            );
            // Waits along the way did not fit in the budget; standing at the start until a
            // later start within it may (the robot is there meanwhile: the schedule holds it).
            if let Some(t) = refused.earliest_start_unix_ms {
                let wait = ((t - template.start_unix_ms) as f64 / 1000.0).max(start_wait_s);
                let itinerary = Draft {
                    steps,
                    dt,
                    waits: vec![(0, wait)],
                }
                .itinerary(template);
                if wait <= max_wait_s + 1e-9 && first(&itinerary, &committed).is_none() {
                    return Ok(Fitted {
                        itinerary,
                        waypoint_steps: at_waypoint,
                        waits: vec![FitWait {
                            step: 0,
                            wait_s: wait,
                            for_robots: dedup(in_the_way),
                        }],
                    });
                }
            }
            return Err(refused);
        }
        let t_c = (c.at_unix_ms - template.start_unix_ms) as f64 / 1000.0;
        // The conflict happens while the robot waits at the first stop it may wait at (the
        // start first of all: another robot's plan passes through it): waiting there longer
        // does not help, and there is no stop before it. The robot leaves it as it would have
        // without that wait and waits at the next stop instead.
        let k = stops[floor];
        let required = if k == 0 { start_wait_s } else { 0.0 };
        let extra = draft.wait_at(k) - required;
        if extra > 1e-9
            && floor + 1 < ceiling
            && first(&draft.standing(k, template), &committed).is_some()
        {
            draft.set_wait(k, required);
            floor += 1;
            draft.add_wait(stops[floor], extra.max(WAIT_STEP_S));
            blockers.push((stops[floor], vec![c.b_robot.clone()]));
            continue;
        }
        // Waiting at a stop the conflict happens at (or while standing there) does not help:
        // the wait moves to the stop before.
        // The last stop is the goal, where the robot stays until its itinerary expires.
        let last = steps.len().saturating_sub(1);
        let standing = stops[..ceiling].iter().enumerate().position(|(i, &k)| {
            let (from, to) = (draft.time_of(k), draft.time_of(k + 1));
            let until = if k == last { f64::INFINITY } else { to };
            t_c >= from - 1e-9
                && t_c <= until + template.tolerance_s
                && i > floor
                // Passing the stop within the tolerance is not standing in the way there.
                && (k == last || first(&draft.standing(k, template), &committed).is_some())
        });
        if let Some(i) = standing {
            let moved: f64 = draft
                .waits
                .iter()
                .filter(|(k, _)| stops[i..].contains(k))
                .map(|(_, s)| s)
                .sum();
            draft.waits.retain(|(k, _)| !stops[i..].contains(k));
            ceiling = i;
            let before = stops[ceiling - 1];
            draft.add_wait(before, moved.max(WAIT_STEP_S));
            blockers.push((before, vec![c.b_robot.clone()]));
            continue;
        }
        // The last stop reached before the conflict, within the floor and the ceiling.
        let at = stops[floor..ceiling]
            .iter()
            .rev()
            .copied()
            .find(|&k| draft.time_of(k) < t_c - template.tolerance_s)
            .unwrap_or(stops[floor]);
        draft.add_wait(at, WAIT_STEP_S);
        blockers.push((at, vec![c.b_robot.clone()]));
    }
}

/// A fit's waits on the clock of its plan starting at `start_unix_ms` (steps `dt` seconds
/// apart), and when the robot reaches each waypoint, ms since the Unix epoch.
pub(crate) fn on_the_clock(fitted: &Fitted, start_unix_ms: i64, dt: f64) -> (Vec<Wait>, Vec<i64>) {
    let time_at = |k: usize| {
        let waited: f64 = fitted
            .waits
            .iter()
            .filter(|w| w.step < k)
            .map(|w| w.wait_s)
            .sum();
        start_unix_ms + ((k as f64 * dt + waited) * 1000.0).round() as i64
    };
    let at_steps = &fitted.waypoint_steps;
    let waits = fitted
        .waits
        .iter()
        .map(|w| Wait {
            waypoint: at_steps
                .iter()
                .position(|a| *a == w.step)
                .filter(|_| w.step > 0),
            wait_s: w.wait_s,
            not_before_unix_ms: time_at(w.step) + (w.wait_s * 1000.0).round() as i64,
            for_robots: w.for_robots.clone(),
        })
        .collect();
    (waits, at_steps.iter().map(|&k| time_at(k)).collect())
}

/// The fit of `itinerary`, with `waits` (step, seconds) letting pass the robots `blockers`
/// names at their steps.
fn fitted(
    itinerary: Itinerary,
    waypoint_steps: Vec<usize>,
    waits: &[(usize, f64)],
    blockers: &[(usize, Vec<String>)],
) -> Fitted {
    let waits = waits
        .iter()
        .map(|&(step, wait_s)| {
            let robots = blockers
                .iter()
                .filter(|(at, _)| *at == step)
                .flat_map(|(_, r)| r.clone())
                .collect::<Vec<_>>();
            FitWait {
                step,
                wait_s,
                for_robots: dedup(robots),
            }
        })
        .collect();
    Fitted {
        itinerary,
        waypoint_steps,
        waits,
    }
}

/// `v` without repeats, in order.
pub(crate) fn dedup(mut v: Vec<String>) -> Vec<String> {
    let mut seen = Vec::new();
    v.retain(|r| {
        let new = !seen.contains(r);
        if new {
            seen.push(r.clone());
        }
        new
    });
    v
}

/// The refusal: the robots in the way and the earliest later start that fits without waits
/// (searched second by second until every other itinerary has expired, tolerances included).
fn no_fit(
    template: &Itinerary,
    draft: &Draft<'_>,
    others: &[Itinerary],
    committed: &Reserved<'_>,
    robots: Vec<String>,
    max_wait_s: f64,
) -> NoFit {
    // Once every other itinerary has expired, and both tolerances have passed, any start fits.
    let horizon = others
        .iter()
        .map(|o| o.expires_unix_ms + (o.tolerance_s * 1000.0).ceil() as i64)
        .max()
        .unwrap_or(template.start_unix_ms)
        + (template.tolerance_s * 1000.0).ceil() as i64;
    // A later start: standing at the start until then, then off without waits.
    let mut earliest = None;
    let mut delay_ms = 1000_i64;
    while template.start_unix_ms + delay_ms <= horizon + 1000 {
        let later = Draft {
            steps: draft.steps,
            dt: draft.dt,
            waits: vec![(0, delay_ms as f64 / 1000.0)],
        };
        if first(&later.itinerary(template), committed).is_none() {
            earliest = Some(template.start_unix_ms + delay_ms);
            break;
        }
        // Standing at the start already meets another robot: no later start helps.
        if first(&later.standing(0, template), committed).is_some() {
            break;
        }
        delay_ms += 1000;
    }
    let message = format!(
        "the plan conflicts with the committed plans of {} on this floor, and waiting up to {max_wait_s} s (`options.max_wait_s`) does not resolve it{}",
        robots.join(", "),
        match earliest {
            Some(t) => format!(
                "; the earliest start that fits is {} s later (unix ms {t})",
                (t - template.start_unix_ms) / 1000
            ),
            None => String::new(),
        }
    );
    NoFit {
        robots,
        earliest_start_unix_ms: earliest,
        message,
    }
}

#[cfg(test)]
mod tests;
