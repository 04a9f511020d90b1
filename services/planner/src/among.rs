//! A plan among the fleet: [`Planner::among_the_fleet`] fits the rehearsed plan among the
//! floor's schedule, drives it again among the other robots' plans and commits it (the rules
//! are [`crate::fleet`]'s).

use std::sync::Arc;

use sim::World;

use crate::fleet::{self, FleetOptions, FleetOutcome, FleetSchedule, NoFit};
use crate::replay::Replay;
use crate::{FloorDatabase, PlanFailure, Planner};

/// Commits a plan may lose to other plans committed on its floor meanwhile (each time it is
/// fitted again against the new schedule) before it answers 503. Fitting it again from a later
/// start is bounded by `options.max_wait_s` instead.
const COMMIT_ATTEMPTS: usize = 16;
/// Commits a plan may lose while fitted and driven beside the floor's other plans; after
/// that it holds the floor's lock from its snapshot to its commit. On the plant with 20 robots
/// among people (`bench fleet`, three runs each), p95 latency 2.1–2.5 s with 3, 3.1–3.9 s with
/// 1 (plans queue for the lock sooner), 2.2–2.7 s with 16 (plans redriven more often).
const OPTIMISTIC_COMMITS: usize = 3;

impl Planner {
    /// The validated plan among the other robots' committed plans on its floor: fitted with
    /// waits ([`fleet::fit`]) and committed against the version it was checked against (a
    /// commit that lost the race is checked again, a few times).
    pub(crate) async fn among_the_fleet(
        &self,
        schedule: &dyn FleetSchedule,
        db: &FloorDatabase,
        world: &Arc<World>,
        report: &rehearsal::PlanReport,
        replay: &Arc<Replay>,
        options: &FleetOptions,
    ) -> Result<FleetOutcome, PlanFailure> {
        let now = schedule.now_ms();
        let start = options.start_unix_ms.unwrap_or(now);
        let slack_ms = (options.tolerance_s * 1000.0).round() as i64;
        if start < now - slack_ms {
            return Err(PlanFailure::Unprocessable(format!(
                "`options.start_time_ms` {start} is {:.1} s in the past, beyond the plan's tolerance of {} s: a schedule cannot start before it is made",
                (now - start) as f64 / 1000.0,
                options.tolerance_s
            )));
        }
        let plan_id = fleet::plan_id(&db.robot, now);
        let requested = start;
        // A plan the drive among the fleet refuses is fitted again from a later start: 2 s,
        // then twice as late each time, within `max_wait_s`.
        let mut later_s = 0.0f64;
        let mut in_the_way: Vec<String> = Vec::new();
        let robot_lock = self.fleet_lock(format!("robot {}", db.robot));
        let _one_plan_per_robot = robot_lock.lock().await;
        // Plans on one floor are fitted and driven side by side, each against the schedule as
        // it was (optimistically), and committed one at a time under the floor's lock. A plan
        // that lost its commit OPTIMISTIC_COMMITS times holds the lock from its snapshot to its
        // commit, so a busy floor still takes it.
        let floor_lock = self.fleet_lock(format!("floor {}", db.floor));
        let (mut lost_commits, mut rechecks) = (0, 0);
        'attempts: while lost_commits < COMMIT_ATTEMPTS {
            let held_throughout = if lost_commits >= OPTIMISTIC_COMMITS {
                Some(floor_lock.lock().await)
            } else {
                None
            };
            let start = requested + (later_s * 1000.0).round() as i64;
            let template = traffic::Itinerary {
                plan_id: plan_id.clone(),
                robot: db.robot.clone(),
                floor: db.floor.clone(),
                start_unix_ms: start,
                trajectory: Vec::new(),
                radius_m: world.spec().robot.footprint_radius,
                // The fit leaves the drive room to deviate from the draft (braking before a
                // wait, setting off after it, people in the way): what is committed is the
                // drive, checked with the plan's own tolerance.
                tolerance_s: options.tolerance_s + fleet::FIT_SLACK_S,
                expires_unix_ms: start + (options.hold_s * 1000.0).round() as i64,
                delay_s: 0.0,
            };
            let (version, committed) = schedule
                .snapshot(&db.floor)
                .await
                .map_err(PlanFailure::Unavailable)?;
            let others: Vec<traffic::Itinerary> = committed
                .into_iter()
                .filter(|i| i.robot != db.robot)
                .collect();
            // A start inside another robot's reserved footprint cannot be waited out: the
            // robot is already there.
            if let Some(here) = report.steps.first()
                && let Some(other) = others.iter().find(|o| {
                    o.pose_at(requested).is_some_and(|(x, y)| {
                        (x - here.x).hypot(y - here.y)
                            < o.radius_m + world.spec().robot.footprint_radius
                    })
                })
            {
                return Err(PlanFailure::FleetConflict(NoFit {
                    robots: vec![other.robot.clone()],
                    earliest_start_unix_ms: None,
                    message: format!(
                        "the start ({:.2}, {:.2}) lies in the footprint the schedule reserves for {} at that time",
                        here.x, here.y, other.robot
                    ),
                }));
            }
            if others.len() >= fleet::MAX_ROBOTS_PER_FLOOR {
                return Err(PlanFailure::Unprocessable(format!(
                    "the floor's traffic schedule holds {} other robots' plans, the most it takes ({}); cancel some or wait for them to expire",
                    others.len(),
                    fleet::MAX_ROBOTS_PER_FLOOR
                )));
            }
            let (itinerary, at_steps, waits) = fleet::fit(
                &template,
                &report.steps,
                report.control_period_s,
                &report.waypoints,
                &others,
                options.max_wait_s,
            )
            .map_err(PlanFailure::FleetConflict)?;
            let time_at = |k: usize| {
                let waited: f64 = waits
                    .iter()
                    .filter(|(i, _, _)| *i < k)
                    .map(|(_, s, _)| s)
                    .sum();
                start + ((k as f64 * report.control_period_s + waited) * 1000.0).round() as i64
            };
            let mut waits: Vec<fleet::Wait> = waits
                .iter()
                .map(|(k, s, robots)| fleet::Wait {
                    waypoint: at_steps.iter().position(|a| a == k).filter(|_| *k > 0),
                    wait_s: *s,
                    not_before_unix_ms: time_at(*k) + (s * 1000.0).round() as i64,
                    for_robots: robots.clone(),
                })
                .collect();
            if later_s > 0.0 {
                waits.insert(
                    0,
                    fleet::Wait {
                        waypoint: None,
                        wait_s: later_s,
                        not_before_unix_ms: start,
                        for_robots: in_the_way.clone(),
                    },
                );
            }
            let mut waypoint_times_unix_ms: Vec<i64> =
                at_steps.iter().map(|&k| time_at(k)).collect();
            // Driven again with its waits while the others drive theirs: a plan that meets
            // another robot there is not committed. What is committed is that drive, waits
            // included, so the schedule holds where the robot will be as it waits and sets off.
            // Alone on the floor with nothing to wait for, that drive is the validating one,
            // step for step (`rehearsal::drive_among` drives each leg with its validating
            // attempt's noise): it is committed as it is.
            let robots =
                Arc::new(fleet::simulated_robots(&others, start).map_err(PlanFailure::Internal)?);
            let among = if others.is_empty() && waits.is_empty() && report.drives_again_alike() {
                fleet::validated_alone(report)
            } else {
                let holds = fleet::holds(&waits, start, report.waypoints.len());
                let (replay2, world2, report2, robots2) = (
                    Arc::clone(replay),
                    Arc::clone(world),
                    report.clone(),
                    Arc::clone(&robots),
                );
                let radius = world.spec().robot.footprint_radius;
                self.blocking(move || {
                    replay2.among_fresh_draws(&world2, &report2, &robots2, &holds, radius)
                })
                .await??
            };
            let refused = |robot: String, message: String| {
                PlanFailure::FleetConflict(NoFit {
                    robots: vec![robot],
                    earliest_start_unix_ms: None,
                    message,
                })
            };
            let (itinerary, refusal) = if let Some(robot) = among.met_robot() {
                let why = format!(
                    "driven again with its waits among the {} other robots' committed plans, the robot did not arrive: {}",
                    among.robots, among.reason
                );
                (itinerary, Some(refused(robot.to_owned(), why)))
            } else if among.outcome == rehearsal::AttemptOutcome::Reached {
                let driven = traffic::Itinerary {
                    tolerance_s: options.tolerance_s,
                    ..fleet::driven(&itinerary, start, &among.steps, among.control_period_s)
                };
                match fleet::first_conflict(&driven, &others) {
                    Some(c) => {
                        let why = format!(
                            "driven with its waits, the robot would come within {} m of {} {:.1} s after its start",
                            fleet::ROBOT_MARGIN_M,
                            c.b_robot,
                            (c.at_unix_ms - start) as f64 / 1000.0
                        );
                        (driven, Some(refused(c.b_robot.clone(), why)))
                    }
                    None => (driven, None),
                }
            } else if others.is_empty() {
                // Alone on the floor, the drive differs from the validated one only by its
                // noise: the validated trajectory is what is committed.
                (itinerary, None)
            } else {
                // Blocked (or out of time) among the others: not committed as it stands.
                let radius = world.spec().robot.footprint_radius;
                let no_fit = fleet::did_not_arrive(&robots, &among, radius);
                (itinerary, Some(PlanFailure::FleetConflict(no_fit)))
            };
            let itinerary = traffic::Itinerary {
                tolerance_s: options.tolerance_s,
                ..itinerary
            };
            if let Some(PlanFailure::FleetConflict(no_fit)) = refusal {
                let next = if later_s == 0.0 { 2.0 } else { 2.0 * later_s };
                for r in &no_fit.robots {
                    if !in_the_way.contains(r) {
                        in_the_way.push(r.clone());
                    }
                }
                if next > options.max_wait_s {
                    return Err(PlanFailure::FleetConflict(NoFit {
                        message: format!(
                            "{}; starting up to {later_s} s later did not help within `options.max_wait_s` ({} s)",
                            no_fit.message, options.max_wait_s
                        ),
                        ..no_fit
                    }));
                }
                later_s = next;
                continue;
            }
            // The times the robot reaches its waypoints are those of the drive committed.
            if among.outcome == rehearsal::AttemptOutcome::Reached {
                waypoint_times_unix_ms = fleet::waypoint_steps(&among.steps, &report.waypoints)
                    .iter()
                    .map(|&k| start + (k as f64 * among.control_period_s * 1000.0).round() as i64)
                    .collect();
            }
            let among = (!others.is_empty()).then_some(among);
            let version = if options.commit {
                let _one_commit_per_floor = if held_throughout.is_none() {
                    Some(floor_lock.lock().await)
                } else {
                    None
                };
                // Plans committed since the snapshot (here, or by another process) that this
                // drive keeps the margin from do not send it back to be fitted and driven again.
                match fleet::commit_among(
                    schedule,
                    &itinerary,
                    version,
                    others.clone(),
                    &mut rechecks,
                    COMMIT_ATTEMPTS,
                )
                .await?
                {
                    fleet::CommitEnd::Yes(v) => Some(v),
                    fleet::CommitEnd::Refit => {
                        lost_commits += 1;
                        continue 'attempts;
                    }
                    fleet::CommitEnd::Exhausted => break 'attempts,
                }
            } else {
                None
            };
            return Ok(FleetOutcome {
                itinerary,
                waypoint_times_unix_ms,
                among,
                waits,
                others: others.len(),
                version,
            });
        }
        Err(PlanFailure::Unavailable(
            "the floor's traffic schedule kept changing while this plan was committed; retry"
                .to_owned(),
        ))
    }
}
