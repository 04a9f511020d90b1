//! The hybrid PRM-RL executor of the paper's §4.2.2, run in the mental simulation to validate a
//! plan before the robot moves.
//!
//! 1. The roadmap (cached per map version, robot and parameters) gives waypoints from the start
//!    through every goal.
//! 2. A [`Controller`] drives the simulated robot to the waypoints one at a time; each waypoint
//!    starts a timer of `waypoint_timeout_s` simulated seconds, and when it runs out the planner
//!    replans from the robot's current position to the goal of the current leg.
//! 3. A collision, or a robot that keeps stalling, fails the attempt: the roadmap is re-sampled
//!    with the next seed and the plan tried again (the paper's §5.3: "the roadmap can be
//!    re-sampled and a new path generated"), at most `max_attempts` times.
//!
//! No IO, no async: the caller runs this on a blocking thread.

use std::collections::VecDeque;
use std::sync::Arc;

use grid::seed::mix;
use learning::Policy;
use planning::{ConfigSpace, Point2, PrmParams, QueryError, QueryOptions, Roadmap};
use sim::{Action, EnvConfig, NavEnv, NoiseConfig, Outcome, Pose2, World};

use crate::cache::{RoadmapCache, SpaceEntry};
use crate::controller::{ClassicalFollower, Controller, PolicyController, ShieldedFollower};
use crate::error::{BlockedReason, Endpoint, PlanError, invalid};
use crate::types::{
    AttemptOutcome, AttemptReport, AttemptTrace, ControllerKind, DrawsReport, LaserTrace,
    LegReport, PlanOptions, PlanReport, PlanRequest, RoadmapChoice, RoadmapInfo, RoadmapKind,
};

/// Most goals one request may carry.
pub const MAX_GOALS: usize = 1000;
/// Most attempts one request may ask for.
pub const MAX_ATTEMPTS: u32 = 50;

/// Most draws of people a validated plan is driven again among ([`PlanOptions::people_draws`]).
pub const MAX_PEOPLE_DRAWS: u32 = 20;
/// Longest waypoint timer, simulated seconds.
pub const MAX_WAYPOINT_TIMEOUT_S: f64 = 600.0;
/// Farthest the start may be from free configuration space and still be driven out of it
/// straight (a robot parked closer to a wall than the safety margin), metres.
const START_ESCAPE_M: f64 = 1.0;

/// Validates the plan of `request` in `world`: with `policy` (hybrid PRM-RL) when given, with
/// the [`ClassicalFollower`] otherwise. A leg the policy validates in no attempt is validated
/// with the follower (robots carry both), so a plan is never worse than the follower's; the
/// report says which controller validated each leg. Among people the follower runs behind the
/// collision shield ([`follower_for`]).
///
/// `map_version` identifies the world's map for the roadmap cache: equal strings must mean equal
/// maps (and objects).
pub fn validate(
    world: &Arc<World>,
    roadmaps: &RoadmapCache,
    map_version: &str,
    request: &PlanRequest,
    policy: Option<Arc<Policy>>,
) -> Result<PlanReport, PlanError> {
    let mut follower = follower_for(&request.options);
    match policy {
        Some(p) => validate_with_fallback(
            world,
            roadmaps,
            map_version,
            request,
            &mut PolicyController::new(p),
            Some(&mut *follower),
            None,
        ),
        None => validate_with(world, roadmaps, map_version, request, &mut *follower),
    }
}

/// The classical follower a plan falls back on: the bare follower in an empty building; behind
/// the collision shield ([`ShieldedFollower`]) among people, whom the bare follower cannot see
/// (robots run a collision monitor under their path follower for that).
pub fn follower_for(options: &PlanOptions) -> Box<dyn Controller> {
    if options.people.any() {
        Box::new(ShieldedFollower::default())
    } else {
        Box::new(ClassicalFollower::default())
    }
}

/// [`validate`] with any controller and no fallback: a leg no attempt validates fails the plan.
pub fn validate_with(
    world: &Arc<World>,
    roadmaps: &RoadmapCache,
    map_version: &str,
    request: &PlanRequest,
    controller: &mut dyn Controller,
) -> Result<PlanReport, PlanError> {
    validate_with_fallback(
        world,
        roadmaps,
        map_version,
        request,
        controller,
        None,
        None,
    )
}

/// A controller ready to drive one world: attached, with the simulation settings it needs.
struct Driver<'c> {
    controller: &'c mut dyn Controller,
    env: EnvConfig,
    max_segment_m: f64,
}

impl<'c> Driver<'c> {
    fn new(
        world: &Arc<World>,
        opts: &PlanOptions,
        controller: &'c mut dyn Controller,
    ) -> Result<Self, PlanError> {
        let beams = controller_beams(world, controller)?;
        controller.attach(world, beams);
        let mut env = env_config(beams, opts.noise);
        env.people = opts.people.clone();
        if let Some(t) = controller.goal_tolerance() {
            env.goal_tolerance = t;
        }
        let max_segment_m = max_segment(&env, opts);
        Ok(Self {
            controller,
            env,
            max_segment_m,
        })
    }
}

/// The validating run of one leg, with the roadmap and controller it was driven with.
struct ValidatedLeg {
    run: DriveRun,
    controller: ControllerKind,
    prm_path_length_m: f64,
    roadmap: RoadmapInfo,
}

/// The plan of §4.2.2, validated leg by leg (start → goal 0 → goal 1 → …). Each leg gets up to
/// `max_attempts` simulated runs with `controller`, each on a roadmap re-sampled with the next
/// seed; a leg none of them validates gets as many runs with `fallback` (the plan endpoint
/// gives the classical follower behind a policy: a plan is never worse than the follower's),
/// and the report says which controller validated each leg. Each leg starts where the previous
/// one's validating run ended. The roadmap seeds (`seed`, `seed + 1`, …) and simulation seeds
/// are the same for every leg and controller, so a report is reproducible.
///
/// With `policy_roadmap` (a roadmap whose edges `controller` was seen to drive, built by
/// [`crate::edges`] on the map's geometric roadmap), `controller` plans on it in every attempt
/// (attempts then differ in the simulation's noise only) and never densifies it; the fallback
/// plans on the geometric roadmaps. The report says which roadmap validated each leg.
pub fn validate_with_fallback(
    world: &Arc<World>,
    roadmaps: &RoadmapCache,
    map_version: &str,
    request: &PlanRequest,
    controller: &mut dyn Controller,
    fallback: Option<&mut dyn Controller>,
    policy_roadmap: Option<&Arc<Roadmap>>,
) -> Result<PlanReport, PlanError> {
    let opts = &request.options;
    check_request(request)?;
    let policy_roadmap = policy_roadmap.filter(|_| opts.roadmap != RoadmapChoice::Geometric);
    let primary_kind = controller.kind();
    let controller_description = controller.description();
    let mut drivers = vec![Driver::new(world, opts, controller)?];
    if let Some(f) = fallback {
        drivers.push(Driver::new(world, opts, f)?);
    }
    let inflation = planning::Inflation {
        robot_radius_m: world.spec().robot.footprint_radius,
        safety_margin_m: opts.safety_margin_m,
    };
    let space = roadmaps.config_space(map_version, world, inflation)?;
    let cs = &*space.cspace;
    let start = request.start;
    let clearance = drivers
        .iter()
        .map(|d| d.env.collision_clearance)
        .fold(0.0, f64::max);
    let entry = start_entry(world, cs, start, clearance)?;
    let goals = &request.goals;
    check_goals(cs, entry.unwrap_or(Point2::new(start.x, start.y)), goals)?;
    let samples = opts
        .samples
        .unwrap_or_else(|| planning::optimal_samples(space.free_area_m2));

    let n_drivers = drivers.len();
    let mut attempts = Vec::new();
    let mut validated: Vec<ValidatedLeg> = Vec::with_capacity(goals.len());
    let mut pose = start;
    for (leg, &goal) in goals.iter().enumerate() {
        // Where the roadmap path of this leg starts: the start (or its way out of the margin),
        // then the previous goal; the robot itself starts where the last leg left it.
        let (from, leg_entry) = if leg == 0 {
            (None, entry)
        } else {
            (Some(goals[leg - 1]), None)
        };
        let mut done = None;
        'drivers: for (d, driver) in drivers.iter_mut().enumerate() {
            let on_policy_roadmap = d == 0 && policy_roadmap.is_some();
            // On the policy-aware roadmap only driven edges join the roadmap's nodes. `policy`
            // never densifies; `auto` densifies where they join no route (a start or goal that
            // no node within reach sees in a straight line, a gap the build left), as the
            // start and goal links, which no rollout drove either.
            let query = QueryOptions {
                no_densify: on_policy_roadmap && opts.roadmap == RoadmapChoice::Policy,
                ..QueryOptions::default()
            };
            for attempt in 1..=opts.max_attempts {
                if request.stop.requested() {
                    return Err(PlanError::Stopped);
                }
                let (roadmap, cached, seed, kind) = match policy_roadmap.filter(|_| d == 0) {
                    Some(r) => (Arc::clone(r), true, r.params().seed, RoadmapKind::Policy),
                    None => {
                        let seed = opts.seed.wrapping_add(u64::from(attempt - 1));
                        let params = PrmParams {
                            samples,
                            seed,
                            ..PrmParams::default()
                        };
                        let (r, cached) =
                            roadmaps.roadmap_until(map_version, &space, &params, &request.stop)?;
                        (r, cached, seed, RoadmapKind::Geometric)
                    }
                };
                let legs = plan_leg(
                    &roadmap,
                    opts,
                    LegQuery {
                        robot: pose,
                        from,
                        entry: leg_entry,
                        goal,
                        goal_index: leg,
                        query,
                    },
                    driver.max_segment_m,
                );
                let legs = match legs {
                    Ok(l) => l,
                    // No kept edge of the policy-aware roadmap joins the leg: the fallback
                    // plans it on the geometric roadmap; without one it is the answer.
                    Err(PlanError::Unreachable { .. })
                        if on_policy_roadmap
                            && n_drivers > 1
                            && opts.roadmap == RoadmapChoice::Auto =>
                    {
                        continue 'drivers;
                    }
                    Err(e) => return Err(e),
                };
                driver.controller.start_attempt(attempt);
                let max_segment_m = driver.max_segment_m;
                let replanner: &mut Replanner<'_> = &mut |p: Point2, g: Point2| {
                    replan(&roadmap, opts, world, (p, g), max_segment_m, query)
                };
                let run = drive(
                    world,
                    &driver.env,
                    pose,
                    std::slice::from_ref(&legs.waypoints),
                    &mut *driver.controller,
                    DriveLimits {
                        waypoint_timeout_s: opts.waypoint_timeout_s,
                        max_replans: opts.max_replans,
                        sim_seed: leg_seed(opts.seed, attempt, leg),
                        initial_velocity: Action::default(),
                        stop: request.stop.clone(),
                        trace: opts.trace,
                    },
                    Some(replanner),
                )?;
                // A leg's run knows only its own goal: number it in the plan.
                let goals_reached = if run.outcome == AttemptOutcome::Reached {
                    leg + 1
                } else {
                    leg
                };
                attempts.push(AttemptReport {
                    attempt,
                    leg,
                    controller: driver.controller.kind(),
                    roadmap_seed: seed,
                    outcome: run.outcome,
                    reason: run.reason.clone(),
                    simulated_time_s: run.time_s,
                    distance_m: run.distance_m,
                    min_clearance_m: run.min_clearance_m,
                    replans: run.replans,
                    waypoints_reached: validated.iter().map(|v| v.run.reached.len()).sum::<usize>()
                        + run.reached.len(),
                    goals_reached,
                    prm_path_length_m: legs.length_m,
                    end_pose: run.end_pose,
                    handover_share: run.handover_share(),
                    min_person_clearance_m: run.min_person_clearance_m,
                    trace: opts.trace.then(|| {
                        attempt_trace(&run, &legs.waypoints, driver.env.control_period, opts)
                    }),
                });
                if run.outcome == AttemptOutcome::Reached {
                    done = Some(ValidatedLeg {
                        run,
                        controller: driver.controller.kind(),
                        prm_path_length_m: legs.length_m,
                        roadmap: RoadmapInfo {
                            samples: roadmap.params().samples,
                            nodes: roadmap.nodes().count(),
                            seed,
                            inflation_m: inflation.total_m(),
                            cached,
                            kind,
                        },
                    });
                    break 'drivers;
                }
            }
        }
        let Some(leg_run) = done else {
            return Err(PlanError::NotValidated { attempts });
        };
        pose = leg_run.run.end_pose;
        validated.push(leg_run);
    }
    let draws = if opts.people_draws > 0 && opts.people.any() {
        Some(drive_draws(
            world,
            &mut drivers,
            start,
            &validated,
            request,
        )?)
    } else {
        None
    };
    let roadmap = validated[0].roadmap.clone();
    let mut report = assemble(
        start,
        primary_kind,
        controller_description,
        opts,
        validated,
        attempts,
        roadmap,
    );
    report.people_draws = draws;
    if opts.trace {
        let laser = &world.spec().robot.laser;
        report.laser = Some(LaserTrace {
            angles_rad: laser
                .beam_angles(drivers[0].env.beams)
                .unwrap_or_default()
                .into_iter()
                .map(|a| a + laser.mount.yaw)
                .collect(),
            max_range_m: laser.range_max,
            control_period_s: drivers[0].env.control_period,
        });
    }
    Ok(report)
}

/// An attempt's drive as [`PlanOptions::trace`] reports it, thinned by the trajectory stride.
fn attempt_trace(
    run: &DriveRun,
    path: &[Point2],
    control_period_s: f64,
    opts: &PlanOptions,
) -> AttemptTrace {
    let kept = stride_indices(run.trajectory.len(), opts.trajectory_stride.max(1));
    AttemptTrace {
        path: path.to_vec(),
        times_s: kept.iter().map(|&i| i as f64 * control_period_s).collect(),
        poses: kept.iter().map(|&i| run.trajectory[i]).collect(),
        ranges: kept
            .iter()
            .filter_map(|&i| run.ranges.get(i).cloned())
            .collect(),
    }
}

/// Drives the validated legs again, each with the controller that validated it through the
/// waypoints it reached, among `options.people_draws` fresh draws of people (no replanning:
/// a waypoint not reached within the timer fails the draw).
fn drive_draws(
    world: &Arc<World>,
    drivers: &mut [Driver<'_>],
    start: Pose2,
    validated: &[ValidatedLeg],
    request: &PlanRequest,
) -> Result<DrawsReport, PlanError> {
    let opts = &request.options;
    let mut report = DrawsReport {
        draws: opts.people_draws,
        reached: 0,
        hit_person: 0,
        near_miss: 0,
        min_person_clearance_m: None,
        failures: Vec::new(),
    };
    for draw in 1..=opts.people_draws {
        let mut pose = start;
        let mut closest = f64::INFINITY;
        let mut failure = None;
        for (leg, v) in validated.iter().enumerate() {
            let Some(driver) = drivers
                .iter_mut()
                .find(|d| d.controller.kind() == v.controller)
            else {
                continue;
            };
            driver.controller.start_attempt(opts.max_attempts + draw);
            let run = drive(
                world,
                &driver.env,
                pose,
                std::slice::from_ref(&v.run.reached),
                &mut *driver.controller,
                DriveLimits {
                    waypoint_timeout_s: opts.waypoint_timeout_s,
                    max_replans: 0,
                    sim_seed: mix(leg_seed(opts.seed, 0, leg), u64::from(draw)),
                    initial_velocity: Action::default(),
                    stop: request.stop.clone(),
                    trace: false,
                },
                None,
            )?;
            closest = closest.min(run.min_person_clearance_m.unwrap_or(f64::INFINITY));
            if run.outcome != AttemptOutcome::Reached {
                failure = Some((leg, run.reason));
                break;
            }
            pose = run.end_pose;
        }
        if closest.is_finite() {
            report.min_person_clearance_m = Some(
                report
                    .min_person_clearance_m
                    .map_or(closest, |m| m.min(closest)),
            );
        }
        let hit = failure
            .as_ref()
            .is_some_and(|(_, reason)| hit_person(reason));
        if hit {
            report.hit_person += 1;
        } else if closest < crate::NEAR_MISS_M {
            report.near_miss += 1;
        }
        match failure {
            None => report.reached += 1,
            Some((leg, reason)) => report
                .failures
                .push(format!("draw {draw}, leg {leg}: {reason}")),
        }
    }
    Ok(report)
}

/// The simulation seed of one attempt on one leg: the first leg's are those of a one-leg plan.
fn leg_seed(seed: u64, attempt: u32, leg: usize) -> u64 {
    let s = mix(seed, u64::from(attempt));
    if leg == 0 { s } else { mix(s, leg as u64) }
}

/// The plan's report from its validated legs.
fn assemble(
    start: Pose2,
    controller: ControllerKind,
    controller_description: String,
    opts: &PlanOptions,
    legs: Vec<ValidatedLeg>,
    attempts: Vec<AttemptReport>,
    roadmap: RoadmapInfo,
) -> PlanReport {
    let mut waypoints = Vec::new();
    let mut goal_indices = Vec::new();
    let mut trajectory: Vec<Pose2> = Vec::new();
    let mut leg_reports = Vec::with_capacity(legs.len());
    let (mut time_s, mut distance_m, mut prm_m) = (0.0, 0.0, 0.0);
    let mut min_clearance_m = f64::INFINITY;
    let mut replans = 0;
    for (i, leg) in legs.into_iter().enumerate() {
        let run = leg.run;
        let offset = waypoints.len();
        goal_indices.extend(run.goal_indices.iter().map(|g| g + offset));
        waypoints.extend(run.reached);
        // Each leg's trajectory starts where the last one ended: keep that pose once.
        let skip = usize::from(!trajectory.is_empty());
        trajectory.extend(run.trajectory.into_iter().skip(skip));
        time_s += run.time_s;
        distance_m += run.distance_m;
        prm_m += leg.prm_path_length_m;
        min_clearance_m = min_clearance_m.min(run.min_clearance_m);
        replans += run.replans;
        leg_reports.push(LegReport {
            goal_index: i,
            controller: leg.controller,
            roadmap: leg.roadmap.kind,
            attempts: attempts.iter().filter(|a| a.leg == i).count(),
            roadmap_seed: leg.roadmap.seed,
            simulated_time_s: run.time_s,
            distance_m: run.distance_m,
            min_clearance_m: run.min_clearance_m,
            replans: run.replans,
        });
    }
    let waypoint_path_length_m = polyline_length(start, &waypoints);
    PlanReport {
        waypoints,
        goal_indices,
        controller,
        controller_description,
        simulated_time_s: time_s,
        distance_m,
        min_clearance_m,
        prm_path_length_m: prm_m,
        waypoint_path_length_m,
        replans,
        trajectory: stride(&trajectory, opts.trajectory_stride),
        roadmap,
        legs: leg_reports,
        attempts,
        laser: None,
        people_draws: None,
    }
}

/// The beam count the controller needs, checked against the robot's laser.
fn controller_beams(world: &World, controller: &dyn Controller) -> Result<usize, PlanError> {
    let beams = controller.beams().unwrap_or(EnvConfig::default().beams);
    let laser = &world.spec().robot.laser;
    if laser.beam_angles(beams).is_none() {
        return Err(invalid(
            "policy",
            format!(
                "the policy reads {beams} laser beams but the robot's laser ({} samples) cannot give them",
                laser.samples
            ),
        ));
    }
    Ok(beams)
}

/// The simulation settings of a validation: the environment's defaults (control period, limits
/// 0.8 m/s and 0.5 rad/s, goal tolerance, collision clearance), the trajectory recorded, no step
/// limit (the executor's timers bound the run).
pub fn env_config(beams: usize, noise: bool) -> EnvConfig {
    EnvConfig {
        beams,
        noise: if noise {
            NoiseConfig::default()
        } else {
            NoiseConfig::none()
        },
        max_steps: u32::MAX,
        record_trajectory: true,
        ..EnvConfig::default()
    }
}

/// Checks a request's values before any work: finite poses, 1 to [`MAX_GOALS`] goals, options
/// within their bounds. `Err` is [`PlanError::InvalidInput`] naming the field.
pub fn check_request(request: &PlanRequest) -> Result<(), PlanError> {
    let s = request.start;
    for (field, v) in [("start.x", s.x), ("start.y", s.y), ("start.yaw", s.yaw)] {
        if !v.is_finite() {
            return Err(invalid(field, format!("must be a finite number, got {v}")));
        }
    }
    if request.goals.is_empty() {
        return Err(invalid("goals", "must hold at least one goal"));
    }
    if request.goals.len() > MAX_GOALS {
        return Err(invalid(
            "goals",
            format!(
                "holds {} goals; at most {MAX_GOALS} are taken",
                request.goals.len()
            ),
        ));
    }
    for (i, g) in request.goals.iter().enumerate() {
        if !(g.x.is_finite() && g.y.is_finite()) {
            let field = if g.x.is_finite() { "y" } else { "x" };
            return Err(invalid(
                format!("goals[{i}].{field}"),
                format!("must be a finite number, got ({}, {})", g.x, g.y),
            ));
        }
    }
    check_options(&request.options)
}

fn check_options(o: &PlanOptions) -> Result<(), PlanError> {
    if let Some((field, message)) = o.people.problem() {
        return Err(invalid(format!("options.{field}"), message));
    }
    if o.people_draws > MAX_PEOPLE_DRAWS {
        return Err(invalid(
            "options.people_draws",
            format!(
                "must lie in [0, {MAX_PEOPLE_DRAWS}], got {}",
                o.people_draws
            ),
        ));
    }
    if o.max_attempts == 0 || o.max_attempts > MAX_ATTEMPTS {
        return Err(invalid(
            "options.max_attempts",
            format!("must lie in [1, {MAX_ATTEMPTS}], got {}", o.max_attempts),
        ));
    }
    if !(o.waypoint_timeout_s.is_finite()
        && o.waypoint_timeout_s > 0.0
        && o.waypoint_timeout_s <= MAX_WAYPOINT_TIMEOUT_S)
    {
        return Err(invalid(
            "options.waypoint_timeout_s",
            format!(
                "must lie in (0, {MAX_WAYPOINT_TIMEOUT_S}] simulated seconds, got {}",
                o.waypoint_timeout_s
            ),
        ));
    }
    if !(o.safety_margin_m.is_finite() && (0.0..=5.0).contains(&o.safety_margin_m)) {
        return Err(invalid(
            "options.safety_margin_m",
            format!("must lie in [0, 5] metres, got {}", o.safety_margin_m),
        ));
    }
    if let Some(n) = o.samples
        && !(1..=planning::MAX_SAMPLES).contains(&n)
    {
        return Err(invalid(
            "options.samples",
            format!("must lie in [1, {}], got {n}", planning::MAX_SAMPLES),
        ));
    }
    if o.max_replans > 1000 {
        return Err(invalid(
            "options.max_replans",
            format!("must be at most 1000, got {}", o.max_replans),
        ));
    }
    Ok(())
}

/// Where the roadmap path starts: `None` when the start is free configuration space, or the
/// nearest free point when the robot fits at the start but stands closer to an obstacle than the
/// safety margin and can drive there straight.
fn start_entry(
    world: &World,
    cs: &ConfigSpace,
    start: Pose2,
    collision_clearance: f64,
) -> Result<Option<Point2>, PlanError> {
    let p = Point2::new(start.x, start.y);
    match cs.validate_endpoint(planning::Endpoint::Start, p) {
        Ok(()) => Ok(None),
        Err(e @ QueryError::InObstacle { .. }) => {
            let escape = cs.nearest_free(p).filter(|&q| {
                q.distance(p) <= START_ESCAPE_M
                    && segment_clear(world, p, q, collision_clearance + 0.02)
            });
            match escape {
                Some(q) => Ok(Some(q)),
                None => Err(blocked_error(Endpoint::Start, e)),
            }
        }
        Err(e) => Err(blocked_error(Endpoint::Start, e)),
    }
}

/// Every goal must be free and in the same free region as the point before it.
fn check_goals(cs: &ConfigSpace, from: Point2, goals: &[Point2]) -> Result<(), PlanError> {
    for (i, &g) in goals.iter().enumerate() {
        cs.validate_endpoint(planning::Endpoint::Goal, g)
            .map_err(|e| blocked_error(Endpoint::Goal(i), e))?;
    }
    let mut prev = (from, Endpoint::Start);
    for (i, &g) in goals.iter().enumerate() {
        if cs.region_of(prev.0) != cs.region_of(g) {
            return Err(PlanError::Unreachable {
                goal_index: i,
                goal: g,
                from: prev.1,
            });
        }
        prev = (g, Endpoint::Goal(i));
    }
    Ok(())
}

/// A planner endpoint error as the request's own error, naming the point.
fn blocked_error(which: Endpoint, e: QueryError) -> PlanError {
    match e {
        QueryError::NonFinite { x, y, .. } => invalid(
            which.to_string(),
            format!("must be a finite point, got ({x}, {y})"),
        ),
        QueryError::OutsideMap {
            point,
            nearest_free,
            ..
        } => PlanError::Blocked {
            endpoint: which,
            point,
            reason: BlockedReason::OutsideMap,
            clearance_m: None,
            required_m: 0.0,
            nearest_free,
        },
        QueryError::InObstacle {
            point,
            clearance_m,
            required_m,
            nearest_free,
            ..
        } => PlanError::Blocked {
            endpoint: which,
            point,
            reason: BlockedReason::InObstacle,
            clearance_m: Some(clearance_m),
            required_m,
            nearest_free,
        },
        other @ (QueryError::Unreachable { .. } | QueryError::NotConnected) => {
            PlanError::Map(format!("{which}: {other}"))
        }
    }
}

/// Whether the robot's footprint keeps `min_clearance` along the straight segment `a`–`b`.
fn segment_clear(world: &World, a: Point2, b: Point2, min_clearance: f64) -> bool {
    let step = (world.resolution() / 2.0).max(1e-3);
    let len = a.distance(b);
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a short segment: a small positive count"
    )]
    let n = ((len / step).ceil() as usize).max(1);
    (0..=n).all(|k| {
        let t = k as f64 / n as f64;
        world.clearance(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)) >= min_clearance
    })
}

/// Longest straight stretch between two waypoints: half of what the robot covers at top speed
/// within the waypoint timer, so turning and slowing never make a waypoint miss its timer (the
/// roadmap's edges reach 15 m, which 0.8 m/s does not cover in 15 s). Longer segments get
/// intermediate waypoints on the segment itself (free, as the segment is).
fn max_segment(env: &EnvConfig, opts: &PlanOptions) -> f64 {
    (0.5 * env.limits.linear_max * opts.waypoint_timeout_s).max(0.5)
}

/// `points` after `from`, with evenly spaced points inserted in every segment longer than
/// `max_m`.
pub(crate) fn subdivide(from: Point2, points: Vec<Point2>, max_m: f64) -> Vec<Point2> {
    let mut out = Vec::with_capacity(points.len());
    let mut prev = from;
    for p in points {
        let d = prev.distance(p);
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a map-sized distance over at least 0.5 m: a small positive count"
        )]
        let pieces = (d / max_m).ceil().max(1.0) as usize;
        for k in 1..pieces {
            let t = k as f64 / pieces as f64;
            out.push(Point2::new(
                prev.x + t * (p.x - prev.x),
                prev.y + t * (p.y - prev.y),
            ));
        }
        out.push(p);
        prev = p;
    }
    out
}

/// What one leg plans from and to.
struct LegQuery {
    /// Where the robot stands.
    robot: Pose2,
    /// The previous goal, for every leg but the first (the robot stands within the goal
    /// tolerance of it): the roadmap path starts there.
    from: Option<Point2>,
    /// For the first leg, the start's way out of the safety margin, if it needs one.
    entry: Option<Point2>,
    goal: Point2,
    goal_index: usize,
    /// How to search (a policy-aware roadmap is not densified: new edges would be undriven).
    query: QueryOptions,
}

/// The waypoints of one leg after the robot's position, the last one its goal.
struct LegPath {
    waypoints: Vec<Point2>,
    length_m: f64,
}

fn plan_leg(
    roadmap: &Roadmap,
    opts: &PlanOptions,
    q: LegQuery,
    max_segment_m: f64,
) -> Result<LegPath, PlanError> {
    let s = Point2::new(q.robot.x, q.robot.y);
    let origin = q.from.or(q.entry).unwrap_or(s);
    let which = match q.goal_index {
        0 => Endpoint::Start,
        i => Endpoint::Goal(i - 1),
    };
    let mut plan = roadmap
        .query(origin, q.goal, q.query)
        .map_err(|e| match e {
            QueryError::Unreachable { .. } | QueryError::NotConnected => PlanError::Unreachable {
                goal_index: q.goal_index,
                goal: q.goal,
                from: which,
            },
            other => blocked_error(Endpoint::Goal(q.goal_index), other),
        })?;
    if opts.shortcut {
        plan = roadmap.shortcut(&plan);
    }
    let length_m = q.entry.map_or(0.0, |e| e.distance(s)) + plan.length_m;
    let mut leg: Vec<Point2> = plan.waypoints.into_iter().skip(1).collect();
    if let Some(e) = q.entry {
        leg.insert(0, e);
    }
    if leg.is_empty() {
        // Start and goal coincide: the goal is still a waypoint to reach.
        leg.push(q.goal);
    }
    Ok(LegPath {
        waypoints: subdivide(q.from.unwrap_or(s), leg, max_segment_m),
        length_m,
    })
}

/// A fresh roadmap path from where the robot stands to `goal`, or why there is none.
fn replan(
    roadmap: &Roadmap,
    opts: &PlanOptions,
    world: &World,
    (from, goal): (Point2, Point2),
    max_segment_m: f64,
    query: QueryOptions,
) -> Result<Vec<Point2>, String> {
    let cs = roadmap.cspace();
    // A robot pushed closer to a wall than the margin first drives back into free space.
    let entry = if cs.is_free(from) {
        None
    } else {
        let q = cs
            .nearest_free(from)
            .filter(|&q| q.distance(from) <= START_ESCAPE_M && segment_clear(world, from, q, 0.0))
            .ok_or_else(|| {
                format!(
                    "no free space within {START_ESCAPE_M} m of ({:.2}, {:.2}) to replan from",
                    from.x, from.y
                )
            })?;
        Some(q)
    };
    let mut plan = roadmap
        .query(entry.unwrap_or(from), goal, query)
        .map_err(|e| format!("replanning failed: {e}"))?;
    if opts.shortcut {
        plan = roadmap.shortcut(&plan);
    }
    let mut out: Vec<Point2> = entry.into_iter().collect();
    out.extend(plan.waypoints.into_iter().skip(1));
    if out.is_empty() {
        out.push(goal);
    }
    Ok(subdivide(from, out, max_segment_m))
}

/// How the reason of a drive that ended touching a person begins.
pub const PERSON_COLLISION: &str = "collision with a person";

/// Whether a drive's (or attempt's) `reason` says it ended touching a person.
pub fn hit_person(reason: &str) -> bool {
    reason.starts_with(PERSON_COLLISION)
}

/// The person nearest to the robot, in words (for a drive that ended touching one, or stuck):
/// how far and where relative to the robot's heading, how fast they walked and closed in, how
/// fast the robot drove, and whether the laser could see them (empty without people).
fn person_contact(env: &NavEnv, robot_linear: f32) -> String {
    let pose = env.pose();
    let gap = |q: &sim::Person| (q.position.0 - pose.x).hypot(q.position.1 - pose.y) - q.radius;
    let Some(q) = env.people().iter().min_by(|a, b| gap(a).total_cmp(&gap(b))) else {
        return String::new();
    };
    let (dx, dy) = (q.position.0 - pose.x, q.position.1 - pose.y);
    let bearing = sim::kinematics::wrap_angle(dy.atan2(dx) - pose.yaw);
    let v = f64::from(robot_linear);
    let (rvx, rvy) = (v * pose.yaw.cos(), v * pose.yaw.sin());
    let dist = dx.hypot(dy).max(1e-9);
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
        q.velocity.0.hypot(q.velocity.1)
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
}

/// Replans from the robot's position to a goal: the remaining waypoints of the leg, or why not.
pub type Replanner<'a> = dyn FnMut(Point2, Point2) -> Result<Vec<Point2>, String> + 'a;

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
    /// Waypoints reached, in order.
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
    let mut obs = env
        .reset(start, (current.0.x, current.0.y))
        .map_err(|e| env_error(Endpoint::Start, e))?;
    if limits.initial_velocity != Action::default() {
        obs = env.set_velocity(limits.initial_velocity);
    }
    let dt = env_config.control_period;
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "the timeout is checked to lie in (0, 600] s"
    )]
    let timer_steps = ((limits.waypoint_timeout_s / dt).ceil() as u64).max(1);
    let mut steps_on_waypoint = 0u64;
    let (mut steps, mut handover_steps) = (0u64, 0u64);
    let mut min_clearance = world.clearance(start.x, start.y);
    let mut min_person = (!env.people().is_empty()).then_some(f64::INFINITY);
    let mut replans = 0u32;
    let mut reached = Vec::new();
    let mut goal_indices = Vec::new();
    let mut time_s;
    let mut ranges = Vec::new();
    if limits.trace {
        ranges.push(obs.ranges.clone());
    }
    let (outcome, reason) = loop {
        if steps_on_waypoint.is_multiple_of(64) && limits.stop.requested() {
            return Err(PlanError::Stopped);
        }
        let action = controller.command(&obs, env.pose(), (current.0.x, current.0.y));
        steps += 1;
        if controller.handed_over() {
            handover_steps += 1;
        }
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
        steps_on_waypoint += 1;
        match step.info.outcome {
            Outcome::Collision => {
                let p = step.info.pose;
                let with = if step.info.person_clearance < env_config.collision_clearance {
                    PERSON_COLLISION
                } else {
                    "collision"
                };
                let mut contact = if with == PERSON_COLLISION {
                    person_contact(&env, step.observation.velocity[0])
                } else {
                    String::new()
                };
                if controller.handed_over() {
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
                if current.1.is_some() {
                    goal_indices.push(reached.len() - 1);
                }
                match queue.pop_front() {
                    None => break (AttemptOutcome::Reached, "every goal reached".to_owned()),
                    Some(next) => {
                        current = next;
                        obs = env
                            .set_goal((current.0.x, current.0.y))
                            .map_err(|e| env_error(Endpoint::Waypoint, e))?;
                        steps_on_waypoint = 0;
                    }
                }
            }
            Outcome::TimeLimit | Outcome::Running => {
                obs = step.observation;
                if steps_on_waypoint < timer_steps {
                    continue;
                }
                let p = env.pose();
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
                // The goal of the current leg: the current waypoint or a later one.
                let (goal, goal_index) = match current.1 {
                    Some(i) => (current.0, i),
                    None => match queue.iter().find_map(|&(q, gi)| gi.map(|i| (q, i))) {
                        Some(found) => found,
                        None => break (AttemptOutcome::Stalled, late),
                    },
                };
                let fresh = match replan(Point2::new(p.x, p.y), goal) {
                    Ok(w) => w,
                    Err(why) => break (AttemptOutcome::Stalled, format!("{late}; {why}")),
                };
                // Drop the rest of the leg, then put the new path in front.
                if current.1.is_none() {
                    while let Some((_, gi)) = queue.pop_front() {
                        if gi.is_some() {
                            break;
                        }
                    }
                }
                let last = fresh.len().saturating_sub(1);
                for (k, &w) in fresh.iter().enumerate().rev() {
                    queue.push_front((w, (k == last).then_some(goal_index)));
                }
                let Some(next) = queue.pop_front() else {
                    break (AttemptOutcome::Stalled, late);
                };
                current = next;
                obs = env
                    .set_goal((current.0.x, current.0.y))
                    .map_err(|e| env_error(Endpoint::Waypoint, e))?;
                steps_on_waypoint = 0;
            }
        }
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
        min_person_clearance_m: min_person,
    })
}

/// An environment refusal during a drive (the executor's checks make these unreachable in
/// practice: starts and waypoints come from free configuration space).
fn env_error(which: Endpoint, e: sim::EnvError) -> PlanError {
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

fn polyline_length(start: Pose2, points: &[Point2]) -> f64 {
    let mut prev = Point2::new(start.x, start.y);
    let mut total = 0.0;
    for &p in points {
        total += prev.distance(p);
        prev = p;
    }
    total
}

/// Every `n`-th pose and the last; none for `n == 0`.
fn stride(poses: &[Pose2], n: u32) -> Vec<Pose2> {
    stride_indices(poses.len(), n)
        .into_iter()
        .map(|i| poses[i])
        .collect()
}

/// Every `n`-th index below `len` and the last one (none for `n` = 0).
fn stride_indices(len: usize, n: u32) -> Vec<usize> {
    if n == 0 || len == 0 {
        return Vec::new();
    }
    let n = n as usize;
    let mut out: Vec<usize> = (0..len).step_by(n).collect();
    if !(len - 1).is_multiple_of(n) {
        out.push(len - 1);
    }
    out
}

/// The configuration space the executor plans on for `world`, `map_version` and a safety
/// margin (for callers choosing missions, such as the navigation benchmark).
pub fn config_space(
    world: &World,
    roadmaps: &RoadmapCache,
    map_version: &str,
    safety_margin_m: f64,
) -> Result<Arc<SpaceEntry>, PlanError> {
    roadmaps.config_space(
        map_version,
        world,
        planning::Inflation {
            robot_radius_m: world.spec().robot.footprint_radius,
            safety_margin_m,
        },
    )
}
