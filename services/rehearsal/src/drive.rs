//! One simulated drive through waypoints: the controller, the waypoint timer, replanning, and
//! the recovery behaviours of a robot that stops making progress; what the drive measured.

use std::collections::VecDeque;
use std::sync::Arc;

use prm::Point2;
use sim::{Action, EnvConfig, NavEnv, Observation, Outcome, Pose2, StepResult, World};

use crate::controller::Controller;
use crate::error::{BlockedReason, Endpoint, PlanError, invalid};
use crate::recovery::{Active, RecoveryEvent, RecoveryKind, RecoveryParams};
use crate::social::{SocialMetrics, SocialTracker};
use crate::types::AttemptOutcome;

/// How the reason of a drive that ended touching a person begins.
pub const PERSON_COLLISION: &str = "collision with a person";

/// How the reason of a drive that ended touching another robot begins (the robot's name
/// follows).
pub const ROBOT_COLLISION: &str = "collision with robot";

/// Whether a drive's (or attempt's) `reason` says it ended touching a person.
pub fn hit_person(reason: &str) -> bool {
    reason.starts_with(PERSON_COLLISION)
}

/// The person nearest to the robot, in words (for a drive that ended touching one, or stuck):
/// how far and where relative to the robot's heading, how fast they walked and closed in, how
/// fast the robot drove, and whether the laser could see them (empty without people).
fn person_contact(env: &NavEnv, robot_linear: f32) -> String {
    let pose = env.pose();
    let gap = |q: &sim::Person| sim::norm(q.position.0 - pose.x, q.position.1 - pose.y) - q.radius;
    let Some(q) = env.people().iter().min_by(|a, b| gap(a).total_cmp(&gap(b))) else {
        return String::new();
    };
    let (dx, dy) = (q.position.0 - pose.x, q.position.1 - pose.y);
    let bearing = sim::kinematics::wrap_angle(dy.atan2(dx) - pose.yaw);
    let v = f64::from(robot_linear);
    let (rvx, rvy) = (v * pose.yaw.cos(), v * pose.yaw.sin());
    let dist = sim::norm(dx, dy).max(1e-9);
    let closing = -((q.velocity.0 - rvx) * dx + (q.velocity.1 - rvy) * dy) / dist;
    let view = env.beam_angles().iter().fold(0.0f64, |m, a| m.max(a.abs()));
    let gap = gap(q) - env.world().spec().robot.footprint_radius;
    let side = match bearing.to_degrees() {
        d if d.abs() <= 15.0 => "ahead".to_owned(),
        d if d.abs() >= 165.0 => "behind".to_owned(),
        d if d > 0.0 => format!("{d:.0}° left"),
        d => format!("{:.0}° right", -d),
    };
    let seen = if bearing.abs() > view {
        ", outside the laser's view"
    } else {
        ""
    };
    format!(
        "; the nearest person was {gap:.2} m away {side}{seen}, walking {:.2} m/s and closing \
         at {closing:.2} m/s, the robot driving {v:.2} m/s",
        sim::norm(q.velocity.0, q.velocity.1)
    )
}

/// Bounds of one simulated drive.
#[derive(Clone, Debug, PartialEq)]
pub struct DriveLimits {
    /// Simulated seconds per waypoint before replanning (or, without a replanner, failing).
    pub waypoint_timeout_s: f64,
    /// Replans allowed before the drive counts as stalled.
    pub max_replans: u32,
    /// Seed of the simulation's noise.
    pub sim_seed: u64,
    /// The robot's velocity at the start (zero: at rest), as a previous drive left it.
    pub initial_velocity: Action,
    /// Polled every few simulated steps: once requested, the drive ends with
    /// [`PlanError::Stopped`].
    pub stop: grid::Stop,
    /// Record the laser ranges the controller saw at every step ([`DriveRun::ranges`]).
    pub trace: bool,
    /// Recovery behaviours for a robot that stops making progress ([`crate::recovery`]);
    /// `None` for none.
    pub recoveries: Option<RecoveryParams>,
    /// Other robots moving along their schedules on the drive's clock (seconds since its
    /// start), seen by the laser; touching one ends the drive in a collision.
    pub others: Option<Arc<sim::OtherRobots>>,
    /// Waits: `holds[0]` is when the robot may leave its start, `holds[k]` when it may leave
    /// the k-th waypoint it reaches, seconds since the drive's start (missing or past: at
    /// once). The robot stands still until then; the waypoint timer and the progress checker
    /// wait with it.
    pub holds: Vec<f64>,
}

/// Replans from the robot's position (first point) to a goal (second): the remaining waypoints
/// of the leg, or why not. With a third point, the route must avoid the roadmap edges passing
/// near that blocked spot (a re-route recovery).
pub type Replanner<'a> =
    dyn FnMut(Point2, Point2, Option<Point2>) -> Result<Vec<Point2>, String> + 'a;

/// One simulated drive through waypoint legs.
#[derive(Clone, Debug, PartialEq)]
pub struct DriveRun {
    /// How it ended.
    pub outcome: AttemptOutcome,
    /// Why, in words.
    pub reason: String,
    /// Simulated time, seconds.
    pub time_s: f64,
    /// Distance driven, metres.
    pub distance_m: f64,
    /// Smallest footprint clearance, metres.
    pub min_clearance_m: f64,
    /// Timer expiries that led to a replan.
    pub replans: u32,
    /// Waypoints reached, in order, with where the robot stood when a replan or a re-route
    /// took over (the junction of the two routes): driven again, or by the robot the plan is
    /// for, consecutive ones are joined by the route that was driven, never across a corner
    /// the replan went round.
    pub reached: Vec<Point2>,
    /// Index into `reached` of each goal reached.
    pub goal_indices: Vec<usize>,
    /// Every pose of the drive.
    pub trajectory: Vec<Pose2>,
    /// The laser ranges the controller saw at every pose of `trajectory`, when
    /// [`DriveLimits::trace`] asked for them (else empty).
    pub ranges: Vec<Vec<f32>>,
    /// Where the robot ended.
    pub end_pose: Pose2,
    /// Control steps driven.
    pub steps: u64,
    /// Of those, the steps a fallback inside the controller drove ([`Controller::handed_over`]).
    pub handover_steps: u64,
    /// Closest approach of the footprint to a person, metres (`None` without people).
    pub min_person_clearance_m: Option<f64>,
    /// Closest approach of the footprint to another robot, metres (`None` without others).
    pub min_robot_clearance_m: Option<f64>,
    /// Intrusions into people's space and time standing still ([`crate::social`]).
    pub social: SocialMetrics,
    /// The recoveries tried, in order.
    pub recoveries: Vec<RecoveryEvent>,
}

impl DriveRun {
    /// The share of control steps a fallback inside the controller drove (0 without steps).
    pub fn handover_share(&self) -> f64 {
        if self.steps == 0 {
            0.0
        } else {
            #[allow(clippy::cast_precision_loss, reason = "step counts are far below 2^52")]
            {
                self.handover_steps as f64 / self.steps as f64
            }
        }
    }
}

/// Drives the simulated robot from `start` through `legs` (each leg ends at its goal) with
/// `controller`, one waypoint at a time under the waypoint timer. When the timer runs out the
/// `replanner` (if any) replaces the rest of the current leg by a path from where the robot is;
/// without one, or past `max_replans`, the drive is stalled.
///
/// The controller is told the rest of the leg at the start, after each goal and after each
/// replan ([`Controller::start_path`]); an intermediate waypoint it has driven past
/// ([`Controller::passed`]) counts as reached, so path trackers need not stop at the roadmap's
/// vertices. With [`DriveLimits::recoveries`], a robot that stops making progress tries the
/// recovery behaviours in turn ([`crate::recovery`]); the waypoint timer waits while they run.
///
/// Pure RL is this with one leg holding only the final goal and no replanner.
pub fn drive(
    world: &Arc<World>,
    env_config: &EnvConfig,
    start: Pose2,
    legs: &[Vec<Point2>],
    controller: &mut dyn Controller,
    limits: DriveLimits,
    replanner: Option<&mut Replanner<'_>>,
) -> Result<DriveRun, PlanError> {
    let mut drive = Drive::start(
        world, env_config, start, legs, controller, limits, replanner,
    )?;
    loop {
        if let Some(ended) = drive.step()? {
            return Ok(drive.finish(ended));
        }
    }
}

/// How a drive ended, and why in words.
struct Ended {
    outcome: AttemptOutcome,
    reason: String,
}

impl Ended {
    fn stalled(reason: String) -> Self {
        Self {
            outcome: AttemptOutcome::Stalled,
            reason,
        }
    }
}

/// A waypoint of a drive, and the index of the goal it is when it ends a leg.
#[derive(Clone, Copy, Debug)]
struct Waypoint {
    at: Point2,
    goal: Option<usize>,
}

/// The waypoints a drive has yet to reach: the one it drives to, and those after it, leg after
/// leg.
struct Route {
    current: Waypoint,
    queue: VecDeque<Waypoint>,
}

impl Route {
    /// The waypoints of `legs` in order, each leg's last one its goal; `None` without any.
    fn new(legs: &[Vec<Point2>]) -> Option<Self> {
        let mut queue: VecDeque<Waypoint> = legs
            .iter()
            .enumerate()
            .flat_map(|(i, leg)| {
                let last = leg.len().saturating_sub(1);
                leg.iter().enumerate().map(move |(k, &at)| Waypoint {
                    at,
                    goal: (k == last).then_some(i),
                })
            })
            .collect();
        let current = queue.pop_front()?;
        Some(Self { current, queue })
    }

    /// The current waypoint as the simulation takes a goal.
    fn target(&self) -> (f64, f64) {
        (self.current.at.x, self.current.at.y)
    }

    /// The current waypoint and the rest of its leg, through the leg's goal.
    fn rest_of_leg(&self) -> Vec<Point2> {
        let mut out = vec![self.current.at];
        if self.current.goal.is_none() {
            for w in &self.queue {
                out.push(w.at);
                if w.goal.is_some() {
                    break;
                }
            }
        }
        out
    }

    /// The goal of the current leg and its index: the current waypoint or a later one.
    fn leg_goal(&self) -> Option<(Point2, usize)> {
        match self.current.goal {
            Some(i) => Some((self.current.at, i)),
            None => self.queue.iter().find_map(|w| w.goal.map(|i| (w.at, i))),
        }
    }

    /// Moves on to the next waypoint; `false` when there is none (the current one stays).
    fn advance(&mut self) -> bool {
        match self.queue.pop_front() {
            Some(next) => {
                self.current = next;
                true
            }
            None => false,
        }
    }

    /// Replaces the rest of the current leg by `fresh` (a replanned path, its last point the
    /// goal `goal_index`) and moves on to its first point: `false` when there is none (the
    /// current waypoint then stays).
    fn replace_rest_of_leg(&mut self, fresh: &[Point2], goal_index: usize) -> bool {
        // The waypoints after the current one up to and including the leg's goal; the current
        // one is replaced by the fresh path's first point below.
        if self.current.goal.is_none() {
            while let Some(w) = self.queue.pop_front() {
                if w.goal.is_some() {
                    break;
                }
            }
        }
        let last = fresh.len().saturating_sub(1);
        for (k, &at) in fresh.iter().enumerate().rev() {
            self.queue.push_front(Waypoint {
                at,
                goal: (k == last).then_some(goal_index),
            });
        }
        self.advance()
    }
}

/// The waypoint timer: control steps driven towards the current waypoint since the timer last
/// restarted.
struct WaypointTimer {
    steps: u64,
    /// Steps it allows.
    limit: u64,
    /// The waypoint the robot drove to at the last step counted, and the closest it has come
    /// to it since the timer last restarted.
    approach: (Point2, f64),
}

impl WaypointTimer {
    fn new(limits: &DriveLimits, dt: f64) -> Self {
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "the timeout is checked to lie in (0, 600] s"
        )]
        let limit = ((limits.waypoint_timeout_s / dt).ceil() as u64).max(1);
        Self {
            steps: 0,
            limit,
            approach: (Point2::new(f64::NAN, f64::NAN), f64::INFINITY),
        }
    }

    fn restart(&mut self) {
        self.steps = 0;
    }

    fn expired(&self) -> bool {
        self.steps >= self.limit
    }

    /// Counts a step driven towards `waypoint` that ended at `pose`.
    fn count(&mut self, pose: Pose2, waypoint: Point2, recoveries: Option<&RecoveryParams>) {
        self.steps += 1;
        // Among people (where the drive has recoveries), the waypoint's timer runs from the
        // robot's last approach to it, as Nav2's progress checker counts progress: a robot
        // creeping behind a person walking slowly the same way gets there, and one that no
        // longer comes closer (blocked, or circling) times out as before.
        if let Some(params) = recoveries {
            if self.approach.0 != waypoint {
                self.approach = (waypoint, f64::INFINITY);
            }
            let d = (pose.x - waypoint.x).hypot(pose.y - waypoint.y);
            if d < self.approach.1 - params.required_movement_m {
                self.approach.1 = d;
                self.steps = 0;
            }
        }
    }
}

/// The progress checker's anchor: where the robot last stood when it had moved far enough,
/// and at which step.
#[derive(Clone, Copy)]
struct Anchor {
    pose: Pose2,
    step: u64,
}

/// What a drive measures as it goes.
struct Measured {
    /// Control steps driven.
    steps: u64,
    /// Of those, the steps a fallback inside the controller drove.
    handover_steps: u64,
    /// Simulated time at the last step, seconds.
    time_s: f64,
    min_clearance: f64,
    min_person: Option<f64>,
    min_robot: Option<f64>,
    /// The laser ranges at every pose, when traced.
    ranges: Vec<Vec<f32>>,
    social: SocialTracker,
}

/// One drive under way: the simulation, the waypoints left, the timers and recoveries, and
/// what it measured so far. [`drive`] steps it until it ends.
struct Drive<'d, 'r> {
    world: &'d Arc<World>,
    env_config: &'d EnvConfig,
    limits: DriveLimits,
    controller: &'d mut dyn Controller,
    replanner: Option<&'d mut Replanner<'r>>,
    env: NavEnv,
    /// What the controller sees at the next step.
    obs: Observation,
    route: Route,
    /// The control period, seconds.
    dt: f64,
    timer: WaypointTimer,
    anchor: Anchor,
    /// When the robot may set off again, seconds since the start ([`DriveLimits::holds`]).
    hold_until: f64,
    /// The recovery under way, if one is.
    recovering: Option<Active>,
    /// The recoveries tried, in order.
    recoveries: Vec<RecoveryEvent>,
    replans: u32,
    /// Waypoints reached, and the junctions of replanned routes ([`DriveRun::reached`]).
    reached: Vec<Point2>,
    goal_indices: Vec<usize>,
    measured: Measured,
    /// The controller's [`Controller::short_stops`] when the drive began.
    short_stops_before: u32,
}

impl<'d, 'r> Drive<'d, 'r> {
    /// The simulation reset at `start`, heading for the first waypoint; the controller told
    /// the first leg.
    fn start(
        world: &'d Arc<World>,
        env_config: &'d EnvConfig,
        start: Pose2,
        legs: &[Vec<Point2>],
        controller: &'d mut dyn Controller,
        limits: DriveLimits,
        replanner: Option<&'d mut Replanner<'r>>,
    ) -> Result<Self, PlanError> {
        let Some(route) = Route::new(legs) else {
            return Err(invalid("goals", "must hold at least one goal"));
        };
        let controller_short_stops = controller.short_stops();
        let mut env = NavEnv::new(Arc::clone(world), env_config.clone(), limits.sim_seed)
            .map_err(|e| invalid("policy", e.to_string()))?;
        env.set_other_robots(limits.others.clone());
        let mut obs = env
            .reset(start, route.target())
            .map_err(|e| env_error(Endpoint::Start, e))?;
        if limits.initial_velocity != Action::default() {
            obs = env.set_velocity(limits.initial_velocity);
        }
        controller.start_path(start, &route.rest_of_leg());
        let dt = env_config.control_period;
        let measured = Measured {
            steps: 0,
            handover_steps: 0,
            time_s: 0.0,
            min_clearance: world.clearance(start.x, start.y),
            min_person: (!env.people().is_empty()).then_some(f64::INFINITY),
            min_robot: env.other_robots().map(|_| f64::INFINITY),
            ranges: if limits.trace {
                vec![obs.ranges.clone()]
            } else {
                Vec::new()
            },
            social: SocialTracker::starting_at(limits.initial_velocity.linear),
        };
        Ok(Self {
            world,
            env_config,
            timer: WaypointTimer::new(&limits, dt),
            hold_until: limits.holds.first().copied().unwrap_or(0.0),
            limits,
            controller,
            replanner,
            env,
            obs,
            route,
            dt,
            anchor: Anchor {
                pose: start,
                step: 0,
            },
            recovering: None,
            recoveries: Vec::new(),
            replans: 0,
            reached: Vec::new(),
            goal_indices: Vec::new(),
            measured,
            short_stops_before: controller_short_stops,
        })
    }

    /// One control step: the action, the simulation's step, what it measured, and what the
    /// drive does about how the step ended; the end of the drive when it ended.
    fn step(&mut self) -> Result<Option<Ended>, PlanError> {
        if self.timer.steps.is_multiple_of(64) && self.limits.stop.requested() {
            return Err(PlanError::Stopped);
        }
        let pose = self.env.pose();
        let holding = self.holding();
        let (action, in_recovery) = self.action(pose, holding);
        let step = self.simulate(action, pose);
        if !in_recovery && !holding {
            self.timer.count(
                step.info.pose,
                self.route.current.at,
                self.limits.recoveries.as_ref(),
            );
        }
        match self.outcome(&step, in_recovery, holding) {
            Outcome::Collision => Ok(Some(self.collision(&step, in_recovery))),
            Outcome::ReachedGoal => self.reach_waypoint(),
            Outcome::TimeLimit | Outcome::Running => {
                self.obs = step.observation;
                self.drive_on(holding)
            }
        }
    }

    /// Whether the robot is told to wait (it stands still, and the waypoint timer and the
    /// progress checker wait with it).
    fn holding(&self) -> bool {
        #[allow(clippy::cast_precision_loss, reason = "step counts are far below 2^52")]
        let now = (self.measured.steps as f64) * self.dt;
        now + 1e-9 < self.hold_until
    }

    /// What the robot does at this step, and whether a recovery commands it: it stands still
    /// when told to wait; a recovery under way drives instead of the controller.
    fn action(&mut self, pose: Pose2, holding: bool) -> (Action, bool) {
        if holding {
            return (Action::default(), false);
        }
        if let Some(a) = self.recovery_command(pose) {
            return (a, true);
        }
        let a = self
            .controller
            .command(&self.obs, pose, self.route.target());
        if self.controller.handed_over() {
            self.measured.handover_steps += 1;
        }
        (a, false)
    }

    /// The command of the recovery under way; `None` without one, or when it has just ended
    /// (the controller then drives on from where the robot stands).
    fn recovery_command(&mut self, pose: Pose2) -> Option<Action> {
        let (Some(active), Some(params)) = (&mut self.recovering, &self.limits.recoveries) else {
            return None;
        };
        let env = &self.env;
        match active.command(
            params,
            pose,
            (self.world, &|x, y| env.moving_clearance_at(x, y)),
            self.env_config.limits.angular_max,
            self.dt,
        ) {
            Ok(a) => Some(a),
            Err(why) => {
                if let Some(e) = self.recoveries.last_mut() {
                    e.outcome = why.to_owned();
                }
                self.recovering = None;
                self.anchor = Anchor {
                    pose,
                    step: self.measured.steps,
                };
                self.timer.restart();
                self.controller.start_path(pose, &self.route.rest_of_leg());
                None
            }
        }
    }

    /// Steps the simulation from `from` with `action` and records what the step measured:
    /// time, clearances, the laser (when traced) and the social metrics.
    fn simulate(&mut self, action: Action, from: Pose2) -> StepResult {
        let m = &mut self.measured;
        m.steps += 1;
        let step = self.env.step(action);
        if self.limits.trace {
            m.ranges.push(step.observation.ranges.clone());
        }
        m.time_s = step.info.time_s;
        if step.info.min_clearance.is_finite() {
            m.min_clearance = m.min_clearance.min(step.info.min_clearance);
        }
        if let Some(c) = &mut m.min_person {
            *c = c.min(step.info.person_clearance);
        }
        if let Some(c) = &mut m.min_robot {
            *c = c.min(step.info.robot_clearance);
        }
        let people: Vec<((f64, f64), f64)> = self
            .env
            .people()
            .iter()
            .map(|q| (q.position, q.radius))
            .collect();
        let limits = &self.env_config.limits;
        m.social.moved(
            (step.info.pose.x - from.x).hypot(step.info.pose.y - from.y),
            sim::kinematics::wrap_angle(step.info.pose.yaw - from.yaw),
            crate::LineLimits::of(
                &self.world.spec().robot.drive,
                limits.linear_max,
                limits.angular_max,
            ),
        );
        m.social.step(
            (step.info.pose.x, step.info.pose.y),
            self.world.spec().robot.footprint_radius,
            step.info.executed.linear,
            self.dt,
            &people,
        );
        step
    }

    /// How the step ended for the drive: the simulation's outcome, except that a waypoint the
    /// controller drove past counts as reached (never a leg's goal).
    fn outcome(&self, step: &StepResult, in_recovery: bool, holding: bool) -> Outcome {
        let outcome = step.info.outcome;
        if outcome == Outcome::Running
            && !in_recovery
            && !holding
            && self.route.current.goal.is_none()
            && self
                .controller
                .passed(step.info.pose, self.route.current.at)
        {
            Outcome::ReachedGoal
        } else {
            outcome
        }
    }

    /// The end of a drive that touched something: what, where and when, and who was driving.
    fn collision(&mut self, step: &StepResult, in_recovery: bool) -> Ended {
        let p = step.info.pose;
        let touching = self.env_config.collision_clearance;
        let robot = step
            .info
            .nearest_robot
            .filter(|_| step.info.robot_clearance < touching)
            .and_then(|i| self.env.other_robots().map(|o| o.robots()[i].name.clone()));
        let with = if step.info.person_clearance < touching {
            PERSON_COLLISION.to_owned()
        } else if let Some(name) = robot {
            format!("{ROBOT_COLLISION} {name}")
        } else {
            "collision".to_owned()
        };
        let mut contact = if with == PERSON_COLLISION {
            person_contact(&self.env, step.observation.velocity[0])
        } else {
            String::new()
        };
        if in_recovery {
            if let Some(e) = self.recoveries.last_mut() {
                e.outcome = "collided".to_owned();
                contact.push_str(&format!(", during the {} recovery", e.kind.as_str()));
            }
        } else if self.controller.handed_over() {
            contact.push_str(", the fallback driving");
        }
        let short = self
            .controller
            .short_stops()
            .saturating_sub(self.short_stops_before);
        if short > 0 {
            contact.push_str(&format!(
                "; the shield found the robot too fast to stop short of what it saw {short} time(s) in this drive (it brakes no harder than the robot's deceleration)"
            ));
        }
        let w = self.route.current.at;
        Ended {
            outcome: AttemptOutcome::Collision,
            reason: format!(
                "{with} at ({:.2}, {:.2}) after {:.1} s, driving to waypoint {} ({:.2}, {:.2}){contact}",
                p.x,
                p.y,
                self.measured.time_s,
                self.reached.len() + 1,
                w.x,
                w.y
            ),
        }
    }

    /// The current waypoint reached: on to the next one (the controller told the next leg
    /// after a goal), or the end of the drive after the last.
    fn reach_waypoint(&mut self) -> Result<Option<Ended>, PlanError> {
        self.reached.push(self.route.current.at);
        // Holds are times since the start: a waypoint reached while the robot still stands
        // waiting (one within reach of its start) does not end that wait.
        let hold = self.limits.holds.get(self.reached.len()).copied();
        self.hold_until = self.hold_until.max(hold.unwrap_or(0.0));
        let new_leg = self.route.current.goal.is_some();
        if new_leg {
            self.goal_indices.push(self.reached.len() - 1);
        }
        if self.recovering.take().is_some()
            && let Some(e) = self.recoveries.last_mut()
        {
            e.outcome = "the waypoint was reached".to_owned();
        }
        if !self.route.advance() {
            return Ok(Some(Ended {
                outcome: AttemptOutcome::Reached,
                reason: "every goal reached".to_owned(),
            }));
        }
        self.head_for_current()?;
        self.timer.restart();
        if new_leg {
            self.controller
                .start_path(self.env.pose(), &self.route.rest_of_leg());
        }
        Ok(None)
    }

    /// Points the simulation's goal at the current waypoint.
    fn head_for_current(&mut self) -> Result<(), PlanError> {
        self.obs = self
            .env
            .set_goal(self.route.target())
            .map_err(|e| env_error(Endpoint::Waypoint, e))?;
        Ok(())
    }

    /// A step that ended on the way: the progress checker (a recovery when the robot is
    /// stuck), then the waypoint timer (a replan when it ran out).
    fn drive_on(&mut self, holding: bool) -> Result<Option<Ended>, PlanError> {
        let p = self.env.pose();
        let here = Anchor {
            pose: p,
            step: self.measured.steps,
        };
        if holding {
            self.anchor = here;
            return Ok(None);
        }
        let required_m = self
            .limits
            .recoveries
            .as_ref()
            .map_or(f64::INFINITY, |r| r.required_movement_m);
        if (p.x - self.anchor.pose.x).hypot(p.y - self.anchor.pose.y) > required_m {
            self.anchor = here;
        }
        if let Some(kind) = self.recovery_due() {
            self.start_recovery(kind, p)?;
            return Ok(None);
        }
        if !self.timer.expired() {
            return Ok(None);
        }
        self.replan_late(p)
    }

    /// The recovery to try next, when the robot has not moved far enough for long enough, no
    /// recovery is under way and the drive may try one more.
    fn recovery_due(&self) -> Option<RecoveryKind> {
        let params = self.limits.recoveries.as_ref()?;
        #[allow(clippy::cast_precision_loss, reason = "step counts are far below 2^52")]
        let still_s = (self.measured.steps - self.anchor.step) as f64 * self.dt;
        let due = self.recovering.is_none()
            && still_s >= params.movement_time_allowance_s
            && self.recoveries.len() < usize::try_from(params.max_recoveries).unwrap_or(usize::MAX)
            && !params.sequence.is_empty();
        due.then(|| params.sequence[self.recoveries.len() % params.sequence.len()])
    }

    /// Starts the recovery `kind` where the robot stands at `p`: a re-route at once, the
    /// others over the next steps.
    fn start_recovery(&mut self, kind: RecoveryKind, p: Pose2) -> Result<(), PlanError> {
        let mut event = RecoveryEvent {
            kind,
            at_s: self.measured.time_s,
            position: Point2::new(p.x, p.y),
            outcome: "done".to_owned(),
        };
        self.anchor = Anchor {
            pose: p,
            step: self.measured.steps,
        };
        self.timer.restart();
        if kind == RecoveryKind::Reroute {
            event.outcome = self.reroute(p)?;
        } else if let Some(params) = &self.limits.recoveries {
            let bearing = f64::from(self.obs.goal_angle);
            let angular_max = self.env_config.limits.angular_max;
            self.recovering = Some(Active::start(
                kind,
                params,
                p,
                bearing,
                angular_max,
                self.dt,
            ));
        }
        self.recoveries.push(event);
        Ok(())
    }

    /// The re-route recovery: the rest of the leg replanned from `p` avoiding the roadmap's
    /// edges past the spot just ahead of the robot. Its outcome in words.
    fn reroute(&mut self, p: Pose2) -> Result<String, PlanError> {
        let ahead = self.world.spec().robot.footprint_radius + 0.5;
        let blocked = Point2::new(p.x + ahead * p.yaw.cos(), p.y + ahead * p.yaw.sin());
        let (Some(replan), Some((goal, goal_index))) =
            (self.replanner.as_mut(), self.route.leg_goal())
        else {
            return Ok("no roadmap to re-route on".to_owned());
        };
        let fresh = match replan(Point2::new(p.x, p.y), goal, Some(blocked)) {
            Ok(fresh) => fresh,
            Err(why) => return Ok(why),
        };
        // The junction: the route goes on from here.
        self.reached.push(Point2::new(p.x, p.y));
        if self.route.replace_rest_of_leg(&fresh, goal_index) {
            self.head_for_current()?;
        }
        self.controller.start_path(p, &self.route.rest_of_leg());
        Ok("done".to_owned())
    }

    /// The waypoint timer ran out with the robot at `p`: the rest of the leg replanned from
    /// there, or the end of a stalled drive (no replanner, no replans left, no way).
    fn replan_late(&mut self, p: Pose2) -> Result<Option<Ended>, PlanError> {
        let w = self.route.current.at;
        let late = format!(
            "waypoint {} ({:.2}, {:.2}) not reached within {} s from ({:.2}, {:.2}){}",
            self.reached.len() + 1,
            w.x,
            w.y,
            self.limits.waypoint_timeout_s,
            p.x,
            p.y,
            person_contact(&self.env, self.obs.velocity[0])
        );
        let Some(replan) = self.replanner.as_mut() else {
            return Ok(Some(Ended::stalled(late)));
        };
        if self.replans >= self.limits.max_replans {
            let spent = self.replans;
            return Ok(Some(Ended::stalled(format!(
                "{late}; {spent} replans already spent"
            ))));
        }
        self.replans += 1;
        let Some((goal, goal_index)) = self.route.leg_goal() else {
            return Ok(Some(Ended::stalled(late)));
        };
        let fresh = match replan(Point2::new(p.x, p.y), goal, None) {
            Ok(w) => w,
            Err(why) => return Ok(Some(Ended::stalled(format!("{late}; {why}")))),
        };
        self.reached.push(Point2::new(p.x, p.y));
        if !self.route.replace_rest_of_leg(&fresh, goal_index) {
            return Ok(Some(Ended::stalled(late)));
        }
        self.head_for_current()?;
        self.timer.restart();
        self.controller.start_path(p, &self.route.rest_of_leg());
        Ok(None)
    }

    /// What the drive measured, once it has `ended`.
    fn finish(self, ended: Ended) -> DriveRun {
        let reason = if self.recoveries.is_empty() {
            ended.reason
        } else {
            format!(
                "{}; recoveries: {}",
                ended.reason,
                crate::recovery::describe(&self.recoveries)
            )
        };
        let trajectory = self.env.trajectory().to_vec();
        let distance_m = trajectory
            .windows(2)
            .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
            .sum();
        let m = self.measured;
        DriveRun {
            outcome: ended.outcome,
            reason,
            time_s: m.time_s,
            distance_m,
            min_clearance_m: m.min_clearance,
            replans: self.replans,
            reached: self.reached,
            goal_indices: self.goal_indices,
            end_pose: self.env.pose(),
            trajectory,
            ranges: m.ranges,
            steps: m.steps,
            handover_steps: m.handover_steps,
            min_robot_clearance_m: m.min_robot,
            min_person_clearance_m: m.min_person,
            social: {
                // The drive itself drove the line within the limits, so the line's limit time
                // is never more than its time: the simulated drive changes speed at step
                // boundaries, up to half a step ahead of the continuous profile per change.
                let social = m.social.metrics();
                SocialMetrics {
                    limit_time_s: social.limit_time_s.min(m.time_s),
                    ..social
                }
            },
            recoveries: self.recoveries,
        }
    }
}

/// An environment refusal during a drive (the executor's checks make these unreachable in
/// practice: starts and waypoints come from free configuration space).
pub(crate) fn env_error(which: Endpoint, e: sim::EnvError) -> PlanError {
    match e {
        sim::EnvError::StartBlocked {
            x, y, nearest_free, ..
        }
        | sim::EnvError::GoalBlocked { x, y, nearest_free } => PlanError::Blocked {
            endpoint: which,
            point: Point2::new(x, y),
            reason: BlockedReason::InObstacle,
            clearance_m: None,
            required_m: 0.0,
            nearest_free: nearest_free.map(|(x, y)| Point2::new(x, y)),
        },
        other => PlanError::Map(other.to_string()),
    }
}
