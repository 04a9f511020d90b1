//! A validated plan driven again among the fleet: the same legs, controllers and waypoints,
//! with the waits the fleet's schedule gave it, while the other robots drive their own
//! committed plans in the same simulation ([`sim::OtherRobots`]: footprints the laser sees,
//! moving along their schedules) and the people walk about as in the rehearsal.
//!
//! This checks what the schedule's geometry cannot: that the robot, holding at its waypoints
//! and setting off again under noise, with its controller reacting to what its laser sees,
//! still arrives without touching another robot.
//!
//! Each leg is driven with the noise, people and controller state of the attempt that
//! validated it, so a plan with no other robot on its floor and nothing to wait for drives
//! exactly as it was validated ([`PlanReport::drives_again_alike`]): the planner then commits
//! the validating drive without driving it again, and a joint run of the committed plans
//! starts every robot on the drive it was committed with.
//!
//! People are drawn at random, so a drive that stalled beside a person who happened to stand
//! in the way says nothing about the fleet's schedule: the planner may drive the plan again
//! among a fresh draw of people and noise (`draw` ≥ 1), as the rehearsal re-samples, and the
//! drive it commits names its draw ([`AmongReport::people_draw`]) so it can be driven again.

use std::sync::Arc;

use grid::seed::mix;
use sim::{Action, OtherRobots, World};

use crate::controller::Controller;
use crate::drive::{DriveLimits, drive};
use crate::error::PlanError;
use crate::executor::{Driver, leg_seed, recoveries_for};
use crate::types::{AttemptOutcome, PlanReport, PlanRequest};

/// Mixed into a fresh draw's seeds, so they differ from every rehearsal attempt's.
const FRESH_DRAW: u64 = 0xf1ee_7d4a_0000_0000;

/// How a plan fared driven among the other robots.
#[derive(Clone, Debug, PartialEq)]
pub struct AmongReport {
    /// How the drive ended.
    pub outcome: AttemptOutcome,
    /// Why, in words (a contact names the robot).
    pub reason: String,
    /// Simulated time from the start to the end of the drive, waits included, seconds.
    pub time_s: f64,
    /// Closest approach of the footprint to another robot, metres (`None` when no other
    /// robot was on the floor during the drive).
    pub min_robot_clearance_m: Option<f64>,
    /// Other robots in the simulation.
    pub robots: usize,
    /// Where the robot was at every control period from the start (waits included), as far
    /// as it drove.
    pub steps: Vec<sim::Pose2>,
    /// Seconds between two of `steps`.
    pub control_period_s: f64,
    /// The draw of people and noise it was driven among: 0 the validating attempts', `k` the
    /// `k`-th fresh one.
    pub people_draw: u32,
}

impl AmongReport {
    /// The robot the drive ended touching, if it did.
    pub fn met_robot(&self) -> Option<&str> {
        if self.outcome != AttemptOutcome::Collision {
            return None;
        }
        let at = self.reason.find(crate::drive::ROBOT_COLLISION)?;
        let rest = &self.reason[at + crate::drive::ROBOT_COLLISION.len()..];
        rest.trim_start().split(" at (").next()
    }
}

/// Drives `report` (validated for `request`) again from its start, leg by leg with the
/// controller that validated each leg (`primary`, or `fallback` where the follower did),
/// holding at the start until `holds[0]` and at waypoint `k` of `report.waypoints` until
/// `holds[k + 1]` (seconds since the start), among `others` on the plan's clock. `draw` 0
/// drives each leg among its validating attempt's people and noise; `draw` k ≥ 1 among the
/// k-th fresh draw (seeds no attempt or people draw of the rehearsal used).
#[allow(clippy::too_many_arguments)]
pub fn drive_among(
    world: &Arc<World>,
    request: &PlanRequest,
    report: &PlanReport,
    primary: &mut dyn Controller,
    mut fallback: Option<&mut dyn Controller>,
    others: &OtherRobots,
    holds: &[f64],
    draw: u32,
) -> Result<AmongReport, PlanError> {
    let opts = &request.options;
    let mut primary = Driver::new(world, opts, primary)?;
    let mut fallback = match fallback.take() {
        Some(f) => Some(Driver::new(world, opts, f)?),
        None => None,
    };
    let mut pose = request.start;
    let (mut clock_s, mut first) = (0.0, 0usize);
    let mut closest: Option<f64> = None;
    let mut steps: Vec<sim::Pose2> = Vec::new();
    let dt = primary.env.control_period;
    for (leg, leg_report) in report.legs.iter().enumerate() {
        let Some(&last) = report.goal_indices.get(leg) else {
            break;
        };
        let waypoints = report
            .waypoints
            .get(first..=last)
            .unwrap_or_default()
            .to_vec();
        // The controller that validated the leg: the fallback only where it did (a follower
        // behind RPP or MPPI is as `Classical` as they are).
        let driver = match &mut fallback {
            Some(f) if leg_report.by_fallback => f,
            _ => &mut primary,
        };
        // The validating attempt's noise, people and controller state (see the module).
        let attempt = match draw {
            0 => report.validating_attempt(leg),
            k => opts.max_attempts + opts.people_draws + k,
        };
        driver.controller.start_attempt(attempt);
        // This leg's clock starts at 0: the other robots and the holds move with it.
        let shifted = Arc::new(others.shifted(-clock_s));
        let leg_holds: Vec<f64> = (first..=last + 1)
            .map(|k| holds.get(k).map_or(0.0, |h| h - clock_s))
            .collect();
        let run = drive(
            world,
            &driver.env,
            pose,
            std::slice::from_ref(&waypoints),
            &mut *driver.controller,
            DriveLimits {
                waypoint_timeout_s: opts.waypoint_timeout_s,
                max_replans: 0,
                sim_seed: match draw {
                    0 => leg_seed(opts.seed, attempt, leg),
                    k => mix(leg_seed(opts.seed, attempt, leg), FRESH_DRAW ^ u64::from(k)),
                },
                initial_velocity: Action::default(),
                stop: request.stop.clone(),
                trace: false,
                recoveries: recoveries_for(opts),
                others: Some(shifted),
                holds: leg_holds,
            },
            None,
        )?;
        if let Some(c) = run.min_robot_clearance_m {
            closest = Some(closest.map_or(c, |m: f64| m.min(c)));
        }
        clock_s += run.time_s;
        // Each leg's trajectory starts where the last one ended: keep that pose once.
        let skip = usize::from(!steps.is_empty());
        steps.extend(run.trajectory.iter().skip(skip).copied());
        if run.outcome != AttemptOutcome::Reached {
            return Ok(AmongReport {
                outcome: run.outcome,
                reason: format!("leg {}: {}", leg + 1, run.reason),
                time_s: clock_s,
                min_robot_clearance_m: closest,
                robots: others.robots().len(),
                steps,
                control_period_s: dt,
                people_draw: draw,
            });
        }
        pose = run.end_pose;
        first = last + 1;
    }
    Ok(AmongReport {
        outcome: AttemptOutcome::Reached,
        reason: "every goal reached among the other robots".to_owned(),
        time_s: clock_s,
        min_robot_clearance_m: closest,
        robots: others.robots().len(),
        steps,
        control_period_s: dt,
        people_draw: draw,
    })
}
