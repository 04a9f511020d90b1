//! One simulated drive through waypoints: the controller, the waypoint timer, replanning, and
//! the recovery behaviours of a robot that stops making progress; what the drive measured.

use std::collections::VecDeque;
use std::sync::Arc;

use prm::Point2;
use sim::{Action, EnvConfig, NavEnv, Outcome, Pose2, World};

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
    mut replanner: Option<&mut Replanner<'_>>,
) -> Result<DriveRun, PlanError> {
    // (waypoint, goal index when it ends a leg)
    let mut queue: VecDeque<(Point2, Option<usize>)> = legs
        .iter()
        .enumerate()
        .flat_map(|(i, leg)| {
            let last = leg.len().saturating_sub(1);
            leg.iter()
                .enumerate()
                .map(move |(k, &p)| (p, (k == last).then_some(i)))
        })
        .collect();
    let Some(mut current) = queue.pop_front() else {
        return Err(invalid("goals", "must hold at least one goal"));
    };
    let mut env = NavEnv::new(Arc::clone(world), env_config.clone(), limits.sim_seed)
        .map_err(|e| invalid("policy", e.to_string()))?;
    env.set_other_robots(limits.others.clone());
    let mut obs = env
        .reset(start, (current.0.x, current.0.y))
        .map_err(|e| env_error(Endpoint::Start, e))?;
    if limits.initial_velocity != Action::default() {
        obs = env.set_velocity(limits.initial_velocity);
    }
    controller.start_path(start, &rest_of_leg(current, &queue));
    let dt = env_config.control_period;
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "the timeout is checked to lie in (0, 600] s"
    )]
    let timer_steps = ((limits.waypoint_timeout_s / dt).ceil() as u64).max(1);
    let radius = world.spec().robot.footprint_radius;
    let angular_max = env_config.limits.angular_max;
    let mut steps_on_waypoint = 0u64;
    // The current waypoint, and the closest the robot has come to it since its timer last
    // restarted.
    let mut approach = (Point2::new(f64::NAN, f64::NAN), f64::INFINITY);
    let (mut steps, mut handover_steps) = (0u64, 0u64);
    let mut min_clearance = world.clearance(start.x, start.y);
    let mut min_person = (!env.people().is_empty()).then_some(f64::INFINITY);
    let mut min_robot = env.other_robots().map(|_| f64::INFINITY);
    let mut hold_until = limits.holds.first().copied().unwrap_or(0.0);
    let mut replans = 0u32;
    let mut reached = Vec::new();
    let mut goal_indices = Vec::new();
    let mut time_s;
    let mut ranges = Vec::new();
    let mut social = SocialTracker::default();
    let mut recoveries: Vec<RecoveryEvent> = Vec::new();
    let mut recovering: Option<Active> = None;
    // The progress checker: where the robot last stood when it had moved far enough, and when.
    let mut anchor = (start, 0u64);
    if limits.trace {
        ranges.push(obs.ranges.clone());
    }
    let (outcome, reason) = loop {
        if steps_on_waypoint.is_multiple_of(64) && limits.stop.requested() {
            return Err(PlanError::Stopped);
        }
        let pose = env.pose();
        // A robot told to wait stands still; a recovery under way drives instead of the
        // controller.
        #[allow(clippy::cast_precision_loss, reason = "step counts are far below 2^52")]
        let holding = (steps as f64) * dt + 1e-9 < hold_until;
        let mut action = holding.then(Action::default);
        if !holding && let (Some(active), Some(params)) = (&mut recovering, &limits.recoveries) {
            match active.command(
                params,
                pose,
                (world, &|x, y| env.moving_clearance_at(x, y)),
                angular_max,
                dt,
            ) {
                Ok(a) => action = Some(a),
                Err(why) => {
                    if let Some(e) = recoveries.last_mut() {
                        e.outcome = why.to_owned();
                    }
                    recovering = None;
                    anchor = (pose, steps);
                    steps_on_waypoint = 0;
                    controller.start_path(pose, &rest_of_leg(current, &queue));
                }
            }
        }
        let in_recovery = action.is_some() && !holding;
        let action = match action {
            Some(a) => a,
            None => {
                let a = controller.command(&obs, pose, (current.0.x, current.0.y));
                if controller.handed_over() {
                    handover_steps += 1;
                }
                a
            }
        };
        steps += 1;
        let step = env.step(action);
        if limits.trace {
            ranges.push(step.observation.ranges.clone());
        }
        time_s = step.info.time_s;
        if step.info.min_clearance.is_finite() {
            min_clearance = min_clearance.min(step.info.min_clearance);
        }
        if let Some(m) = &mut min_person {
            *m = m.min(step.info.person_clearance);
        }
        if let Some(m) = &mut min_robot {
            *m = m.min(step.info.robot_clearance);
        }
        let people: Vec<((f64, f64), f64)> = env
            .people()
            .iter()
            .map(|q| (q.position, q.radius))
            .collect();
        social.moved(
            (step.info.pose.x - pose.x).hypot(step.info.pose.y - pose.y),
            sim::kinematics::wrap_angle(step.info.pose.yaw - pose.yaw),
            (env_config.limits.linear_max, angular_max),
        );
        social.step(
            (step.info.pose.x, step.info.pose.y),
            radius,
            step.info.executed.linear,
            dt,
            &people,
        );
        if !in_recovery && !holding {
            steps_on_waypoint += 1;
            // Among people (where the drive has recoveries), the waypoint's timer runs from
            // the robot's last approach to it, as Nav2's progress checker counts progress: a
            // robot creeping behind a person walking slowly the same way gets there, and one
            // that no longer comes closer (blocked, or circling) times out as before.
            if let Some(params) = &limits.recoveries {
                if approach.0 != current.0 {
                    approach = (current.0, f64::INFINITY);
                }
                let p = step.info.pose;
                let d = (p.x - current.0.x).hypot(p.y - current.0.y);
                if d < approach.1 - params.required_movement_m {
                    approach.1 = d;
                    steps_on_waypoint = 0;
                }
            }
        }
        let mut outcome = step.info.outcome;
        // A waypoint the controller drove past counts as reached (never a leg's goal).
        if outcome == Outcome::Running
            && !in_recovery
            && !holding
            && current.1.is_none()
            && controller.passed(step.info.pose, current.0)
        {
            outcome = Outcome::ReachedGoal;
        }
        match outcome {
            Outcome::Collision => {
                let p = step.info.pose;
                let robot = step
                    .info
                    .nearest_robot
                    .filter(|_| step.info.robot_clearance < env_config.collision_clearance)
                    .and_then(|i| env.other_robots().map(|o| o.robots()[i].name.clone()));
                let with = if step.info.person_clearance < env_config.collision_clearance {
                    PERSON_COLLISION.to_owned()
                } else if let Some(name) = robot {
                    format!("{ROBOT_COLLISION} {name}")
                } else {
                    "collision".to_owned()
                };
                let mut contact = if with == PERSON_COLLISION {
                    person_contact(&env, step.observation.velocity[0])
                } else {
                    String::new()
                };
                if in_recovery {
                    if let Some(e) = recoveries.last_mut() {
                        e.outcome = "collided".to_owned();
                        contact.push_str(&format!(", during the {} recovery", e.kind.as_str()));
                    }
                } else if controller.handed_over() {
                    contact.push_str(", the fallback driving");
                }
                break (
                    AttemptOutcome::Collision,
                    format!(
                        "{with} at ({:.2}, {:.2}) after {:.1} s, driving to waypoint {} ({:.2}, {:.2}){contact}",
                        p.x,
                        p.y,
                        time_s,
                        reached.len() + 1,
                        current.0.x,
                        current.0.y
                    ),
                );
            }
            Outcome::ReachedGoal => {
                reached.push(current.0);
                // Holds are times since the start: a waypoint reached while the robot still
                // stands waiting (one within reach of its start) does not end that wait.
                hold_until =
                    hold_until.max(limits.holds.get(reached.len()).copied().unwrap_or(0.0));
                if current.1.is_some() {
                    goal_indices.push(reached.len() - 1);
                }
                if recovering.take().is_some()
                    && let Some(e) = recoveries.last_mut()
                {
                    e.outcome = "the waypoint was reached".to_owned();
                }
                match queue.pop_front() {
                    None => break (AttemptOutcome::Reached, "every goal reached".to_owned()),
                    Some(next) => {
                        let new_leg = current.1.is_some();
                        current = next;
                        obs = env
                            .set_goal((current.0.x, current.0.y))
                            .map_err(|e| env_error(Endpoint::Waypoint, e))?;
                        steps_on_waypoint = 0;
                        if new_leg {
                            controller.start_path(env.pose(), &rest_of_leg(current, &queue));
                        }
                    }
                }
            }
            Outcome::TimeLimit | Outcome::Running => {
                obs = step.observation;
                let p = env.pose();
                if holding {
                    anchor = (p, steps);
                    continue;
                }
                // The progress checker, and a recovery when the robot is stuck.
                if (p.x - anchor.0.x).hypot(p.y - anchor.0.y)
                    > limits
                        .recoveries
                        .as_ref()
                        .map_or(f64::INFINITY, |r| r.required_movement_m)
                {
                    anchor = (p, steps);
                }
                if let Some(params) = &limits.recoveries
                    && recovering.is_none()
                    && (steps - anchor.1) as f64 * dt >= params.movement_time_allowance_s
                    && recoveries.len()
                        < usize::try_from(params.max_recoveries).unwrap_or(usize::MAX)
                    && !params.sequence.is_empty()
                {
                    let kind = params.sequence[recoveries.len() % params.sequence.len()];
                    let mut event = RecoveryEvent {
                        kind,
                        at_s: time_s,
                        position: Point2::new(p.x, p.y),
                        outcome: "done".to_owned(),
                    };
                    anchor = (p, steps);
                    steps_on_waypoint = 0;
                    if kind == RecoveryKind::Reroute {
                        let blocked = Point2::new(
                            p.x + (radius + 0.5) * p.yaw.cos(),
                            p.y + (radius + 0.5) * p.yaw.sin(),
                        );
                        let goal = leg_goal(current, &queue);
                        match (replanner.as_mut(), goal) {
                            (Some(replan), Some((goal, goal_index))) => {
                                match replan(Point2::new(p.x, p.y), goal, Some(blocked)) {
                                    Ok(fresh) => {
                                        // The junction: the route goes on from here.
                                        reached.push(Point2::new(p.x, p.y));
                                        drop_rest_of_leg(&mut current, &mut queue);
                                        push_path(&mut queue, &fresh, goal_index);
                                        if let Some(next) = queue.pop_front() {
                                            current = next;
                                            obs = env
                                                .set_goal((current.0.x, current.0.y))
                                                .map_err(|e| env_error(Endpoint::Waypoint, e))?;
                                        }
                                        controller.start_path(p, &rest_of_leg(current, &queue));
                                    }
                                    Err(why) => event.outcome = why,
                                }
                            }
                            _ => event.outcome = "no roadmap to re-route on".to_owned(),
                        }
                    } else {
                        let bearing = f64::from(obs.goal_angle);
                        recovering = Some(Active::start(kind, params, p, bearing, angular_max, dt));
                    }
                    recoveries.push(event);
                    continue;
                }
                if steps_on_waypoint < timer_steps {
                    continue;
                }
                let late = format!(
                    "waypoint {} ({:.2}, {:.2}) not reached within {} s from ({:.2}, {:.2}){}",
                    reached.len() + 1,
                    current.0.x,
                    current.0.y,
                    limits.waypoint_timeout_s,
                    p.x,
                    p.y,
                    person_contact(&env, obs.velocity[0])
                );
                let Some(replan) = replanner.as_mut() else {
                    break (AttemptOutcome::Stalled, late);
                };
                if replans >= limits.max_replans {
                    break (
                        AttemptOutcome::Stalled,
                        format!("{late}; {replans} replans already spent"),
                    );
                }
                replans += 1;
                let Some((goal, goal_index)) = leg_goal(current, &queue) else {
                    break (AttemptOutcome::Stalled, late);
                };
                let fresh = match replan(Point2::new(p.x, p.y), goal, None) {
                    Ok(w) => w,
                    Err(why) => break (AttemptOutcome::Stalled, format!("{late}; {why}")),
                };
                reached.push(Point2::new(p.x, p.y));
                drop_rest_of_leg(&mut current, &mut queue);
                push_path(&mut queue, &fresh, goal_index);
                let Some(next) = queue.pop_front() else {
                    break (AttemptOutcome::Stalled, late);
                };
                current = next;
                obs = env
                    .set_goal((current.0.x, current.0.y))
                    .map_err(|e| env_error(Endpoint::Waypoint, e))?;
                steps_on_waypoint = 0;
                controller.start_path(p, &rest_of_leg(current, &queue));
            }
        }
    };
    let reason = if recoveries.is_empty() {
        reason
    } else {
        format!(
            "{reason}; recoveries: {}",
            crate::recovery::describe(&recoveries)
        )
    };
    let trajectory = env.trajectory().to_vec();
    let distance_m = trajectory
        .windows(2)
        .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
        .sum();
    Ok(DriveRun {
        outcome,
        reason,
        time_s,
        distance_m,
        min_clearance_m: min_clearance,
        replans,
        reached,
        goal_indices,
        end_pose: env.pose(),
        trajectory,
        ranges,
        steps,
        handover_steps,
        min_robot_clearance_m: min_robot,
        min_person_clearance_m: min_person,
        social: social.metrics(),
        recoveries,
    })
}

/// The current waypoint and the rest of its leg, through the leg's goal.
fn rest_of_leg(
    current: (Point2, Option<usize>),
    queue: &VecDeque<(Point2, Option<usize>)>,
) -> Vec<Point2> {
    let mut out = vec![current.0];
    if current.1.is_none() {
        for &(p, g) in queue {
            out.push(p);
            if g.is_some() {
                break;
            }
        }
    }
    out
}

/// The goal of the current leg and its index: the current waypoint or a later one.
fn leg_goal(
    current: (Point2, Option<usize>),
    queue: &VecDeque<(Point2, Option<usize>)>,
) -> Option<(Point2, usize)> {
    match current.1 {
        Some(i) => Some((current.0, i)),
        None => queue.iter().find_map(|&(q, gi)| gi.map(|i| (q, i))),
    }
}

/// Drops the waypoints after `current` up to and including the leg's goal (a replanned path
/// takes their place; the current waypoint is replaced by the caller).
fn drop_rest_of_leg(
    current: &mut (Point2, Option<usize>),
    queue: &mut VecDeque<(Point2, Option<usize>)>,
) {
    if current.1.is_none() {
        while let Some((_, gi)) = queue.pop_front() {
            if gi.is_some() {
                break;
            }
        }
    }
}

/// Puts `fresh` in front of the queue, its last point the goal `goal_index`.
fn push_path(queue: &mut VecDeque<(Point2, Option<usize>)>, fresh: &[Point2], goal_index: usize) {
    let last = fresh.len().saturating_sub(1);
    for (k, &w) in fresh.iter().enumerate().rev() {
        queue.push_front((w, (k == last).then_some(goal_index)));
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
