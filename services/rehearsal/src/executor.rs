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

use std::sync::Arc;

use grid::seed::mix;
use learning::Policy;
use prm::{Point2, PrmParams, QueryOptions, Roadmap};
use sim::{Action, EnvConfig, NoiseConfig, Pose2, World};

use crate::cache::{RoadmapCache, SpaceEntry};
pub use crate::checks::check_request;
use crate::checks::{check_goals, start_entry};
use crate::controller::{ClassicalFollower, Controller, PolicyController, ShieldedFollower};
pub use crate::drive::{
    DriveLimits, DriveRun, PERSON_COLLISION, ROBOT_COLLISION, Replanner, drive, hit_person,
};
use crate::error::{PlanError, invalid};
pub use crate::paths::REROUTE_PENALTY_M;
use crate::paths::{LegPath, LegQuery, clear_of_standing, plan_leg, replan};
use crate::recovery::{RecoveryEvent, RecoveryParams};
use crate::social::SocialMetrics;
use crate::timed::TimedAmong;
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
pub(crate) const START_ESCAPE_M: f64 = 1.0;

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
pub(crate) struct Driver<'c> {
    pub(crate) controller: &'c mut dyn Controller,
    pub(crate) env: EnvConfig,
    max_segment_m: f64,
}

impl<'c> Driver<'c> {
    pub(crate) fn new(
        world: &Arc<World>,
        opts: &PlanOptions,
        controller: &'c mut dyn Controller,
    ) -> Result<Self, PlanError> {
        let beams = controller_beams(world, controller)?;
        controller.attach(world, beams);
        let mut env = env_config_for(world, beams, opts.noise);
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
    /// Whether the fallback (not the primary controller) validated it.
    by_fallback: bool,
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
    validate_detailed(
        world,
        roadmaps,
        map_version,
        request,
        controller,
        fallback,
        policy_roadmap,
    )
    .result
}

/// What an attempt measured beyond its [`AttemptReport`]: the social metrics and the
/// recoveries tried ([`validate_detailed`]).
#[derive(Clone, Debug, PartialEq)]
pub struct AttemptDetails {
    /// Intrusions into people's space and time standing still.
    pub social: SocialMetrics,
    /// The recovery behaviours tried, in order.
    pub recoveries: Vec<RecoveryEvent>,
}

/// A validation with what each attempt measured beyond its report.
#[derive(Debug)]
pub struct Detailed {
    /// What [`validate_with_fallback`] returns.
    pub result: Result<PlanReport, PlanError>,
    /// One entry per attempt driven, in the order of the attempts (of the report, or of
    /// [`PlanError::NotValidated`]).
    pub attempts: Vec<AttemptDetails>,
}

/// [`validate_with_fallback`], also returning each attempt's [`AttemptDetails`] (the
/// benchmarks' social metrics and recoveries).
pub fn validate_detailed(
    world: &Arc<World>,
    roadmaps: &RoadmapCache,
    map_version: &str,
    request: &PlanRequest,
    controller: &mut dyn Controller,
    fallback: Option<&mut dyn Controller>,
    policy_roadmap: Option<&Arc<Roadmap>>,
) -> Detailed {
    let floor = Floor {
        world,
        roadmaps,
        map_version,
    };
    match Validation::new(floor, request, controller, fallback, policy_roadmap) {
        Ok(validation) => validation.run(),
        Err(e) => Detailed {
            result: Err(e),
            attempts: Vec::new(),
        },
    }
}

/// Where a validation plans: the world, and the roadmap cache with the world's map version.
#[derive(Clone, Copy)]
struct Floor<'v> {
    world: &'v Arc<World>,
    roadmaps: &'v RoadmapCache,
    map_version: &'v str,
}

/// A validation under way ([`validate_with_fallback`]): what every leg shares, and what the
/// legs validated so far gave.
struct Validation<'v, 'c> {
    floor: Floor<'v>,
    request: &'v PlanRequest,
    /// The policy-aware roadmap the primary controller plans on, unless the request asks for
    /// the geometric roadmap.
    policy_roadmap: Option<&'v Arc<Roadmap>>,
    /// The primary controller's kind and description, as the report names it.
    primary: ControllerKind,
    description: String,
    /// The primary controller, then the fallback if there is one.
    drivers: Vec<Driver<'c>>,
    space: Arc<SpaceEntry>,
    inflation: prm::Inflation,
    /// The start's way out of the safety margin, if it needs one.
    entry: Option<Point2>,
    /// Samples of each geometric roadmap.
    samples: usize,
    /// Where the robot stands when the next leg sets off.
    pose: Pose2,
    /// Every attempt driven so far, in order, and what each measured beyond its report.
    attempts: Vec<AttemptReport>,
    details: Vec<AttemptDetails>,
    validated: Vec<ValidatedLeg>,
}

/// The roadmap of one attempt, as the report names it.
struct AttemptRoadmap {
    /// Without the edges passing robots standing on the floor ([`clear_of_standing`]).
    roadmap: Arc<Roadmap>,
    cached: bool,
    seed: u64,
    kind: RoadmapKind,
}

impl<'v, 'c> Validation<'v, 'c> {
    /// The checks before any driving (the request's values, the start and every goal in the
    /// floor's configuration space) and the controllers attached to the world.
    // The two controllers may be borrowed for different lifetimes: the fallback's borrow is
    // shortened to `'c` where `Driver::new` takes it (inside an `Option` it would not be).
    fn new<'f: 'c>(
        floor: Floor<'v>,
        request: &'v PlanRequest,
        controller: &'c mut dyn Controller,
        fallback: Option<&'f mut dyn Controller>,
        policy_roadmap: Option<&'v Arc<Roadmap>>,
    ) -> Result<Self, PlanError> {
        let Floor {
            world,
            roadmaps,
            map_version,
        } = floor;
        let opts = &request.options;
        check_request(request)?;
        let policy_roadmap = policy_roadmap.filter(|_| opts.roadmap != RoadmapChoice::Geometric);
        let primary = controller.kind();
        let mut drivers = vec![Driver::new(world, opts, controller)?];
        // Described once attached: a controller scales itself to the robot it drives.
        let description = drivers[0].controller.description();
        if let Some(f) = fallback {
            drivers.push(Driver::new(world, opts, f)?);
        }
        let inflation = prm::Inflation {
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
        check_goals(
            cs,
            entry.unwrap_or(Point2::new(start.x, start.y)),
            &request.goals,
        )?;
        // Around robots standing on the floor the roadmap loses the edges that pass them and may
        // not densify: a denser one keeps the ways between them.
        let samples = opts
            .samples
            .unwrap_or_else(|| prm::optimal_samples(space.free_area_m2))
            * if opts.standing.is_empty() {
                1
            } else {
                STANDING_DENSITY
            };
        Ok(Self {
            floor,
            request,
            policy_roadmap,
            primary,
            description,
            drivers,
            space,
            inflation,
            entry,
            samples,
            pose: start,
            attempts: Vec::new(),
            details: Vec::new(),
            validated: Vec::with_capacity(request.goals.len()),
        })
    }

    /// Validates every leg in turn, then reports the plan.
    fn run(mut self) -> Detailed {
        let legs = self.validate_legs();
        let attempts = std::mem::take(&mut self.details);
        Detailed {
            result: legs.and_then(|()| self.report()),
            attempts,
        }
    }

    /// Each leg validated from where the previous one's validating run ended.
    fn validate_legs(&mut self) -> Result<(), PlanError> {
        for leg in 0..self.request.goals.len() {
            let validated = self.validate_leg(leg)?;
            self.pose = validated.run.end_pose;
            self.validated.push(validated);
        }
        Ok(())
    }

    /// The first attempt that validates `leg`: the primary controller's attempts, then the
    /// fallback's.
    fn validate_leg(&mut self, leg: usize) -> Result<ValidatedLeg, PlanError> {
        for d in 0..self.drivers.len() {
            if let Some(validated) = self.attempts_of(d, leg)? {
                return Ok(validated);
            }
        }
        Err(PlanError::NotValidated {
            attempts: std::mem::take(&mut self.attempts),
        })
    }

    /// Whether driver `d` plans on the policy-aware roadmap.
    fn on_policy_roadmap(&self, d: usize) -> bool {
        d == 0 && self.policy_roadmap.is_some()
    }

    /// Up to `max_attempts` attempts of driver `d` at `leg`: the validating run, or `None`
    /// when none validated it (or, on the policy-aware roadmap, no route joins the leg and
    /// the fallback is to plan it).
    fn attempts_of(&mut self, d: usize, leg: usize) -> Result<Option<ValidatedLeg>, PlanError> {
        let request = self.request;
        let opts = &request.options;
        // On the policy-aware roadmap only driven edges join the roadmap's nodes. `policy`
        // never densifies; `auto` densifies where they join no route (a start or goal that
        // no node within reach sees in a straight line, a gap the build left), as the
        // start and goal links, which no rollout drove either.
        // Nor where robots stand on the floor: new edges would not know to keep clear of them.
        let query = QueryOptions {
            no_densify: (self.on_policy_roadmap(d) && opts.roadmap == RoadmapChoice::Policy)
                || !opts.standing.is_empty(),
            ..QueryOptions::default()
        };
        for attempt in 1..=opts.max_attempts {
            if request.stop.requested() {
                return Err(PlanError::Stopped);
            }
            let roadmap = self.attempt_roadmap(d, attempt)?;
            let Some(path) = self.plan(d, leg, &roadmap.roadmap, query)? else {
                return Ok(None);
            };
            let run = self.drive_attempt(d, leg, attempt, &roadmap.roadmap, &path, query)?;
            self.record(d, leg, attempt, &roadmap, &path, &run);
            if run.outcome == AttemptOutcome::Reached {
                return Ok(Some(self.validated_leg(d, &roadmap, &path, run)));
            }
        }
        Ok(None)
    }

    /// The roadmap of driver `d`'s `attempt`: the policy-aware roadmap, or the geometric one
    /// of the attempt's seed (from the cache, or built); clear of robots standing on the floor.
    fn attempt_roadmap(&self, d: usize, attempt: u32) -> Result<AttemptRoadmap, PlanError> {
        let opts = &self.request.options;
        let (roadmap, cached, seed, kind) = match self.policy_roadmap.filter(|_| d == 0) {
            Some(r) => (Arc::clone(r), true, r.params().seed, RoadmapKind::Policy),
            None => {
                let seed = opts.seed.wrapping_add(u64::from(attempt - 1)) ^ opts.roadmap_salt;
                let params = PrmParams {
                    samples: self.samples,
                    seed,
                    ..PrmParams::default()
                };
                let (r, cached) = self.floor.roadmaps.roadmap_until(
                    self.floor.map_version,
                    &self.space,
                    &params,
                    &self.request.stop,
                )?;
                (r, cached, seed, RoadmapKind::Geometric)
            }
        };
        Ok(AttemptRoadmap {
            roadmap: clear_of_standing(roadmap, opts, self.floor.world)?,
            cached,
            seed,
            kind,
        })
    }

    /// The roadmap path of `leg` for driver `d` on `roadmap`, timed among the fleet's plans
    /// when there are any; `None` when no kept edge of the policy-aware roadmap joins the leg
    /// and the fallback is to plan it on the geometric roadmap (without one, that is the
    /// answer).
    fn plan(
        &self,
        d: usize,
        leg: usize,
        roadmap: &Roadmap,
        query: QueryOptions,
    ) -> Result<Option<LegPath>, PlanError> {
        let opts = &self.request.options;
        let driver = &self.drivers[d];
        // Among the fleet's plans, the route that arrives first, timed from when the leg sets
        // off.
        let timed = opts.reserved.as_deref().map(|reserved| TimedAmong {
            reserved,
            radius_m: self.floor.world.spec().robot.footprint_radius,
            speed_m_s: ROUTE_SPEED_SHARE * driver.env.limits.linear_max.abs().max(0.1),
            t0_s: self.validated.iter().map(|v| v.run.time_s).sum(),
        });
        // Where the roadmap path of this leg starts: the start (or its way out of the margin),
        // then the previous goal; the robot itself starts where the last leg left it.
        let goals = &self.request.goals;
        let (from, entry) = if leg == 0 {
            (None, self.entry)
        } else {
            (Some(goals[leg - 1]), None)
        };
        let planned = plan_leg(
            roadmap,
            opts,
            timed.as_ref().map(|t| t as &dyn prm::Reservations),
            LegQuery {
                robot: self.pose,
                from,
                entry,
                goal: goals[leg],
                goal_index: leg,
                query,
            },
            driver.max_segment_m,
        );
        match planned {
            Ok(path) => Ok(Some(path)),
            Err(PlanError::Unreachable { .. })
                if self.on_policy_roadmap(d)
                    && self.drivers.len() > 1
                    && opts.roadmap == RoadmapChoice::Auto =>
            {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// Driver `d`'s `attempt` at `leg`: `path` driven from where the robot stands, replanned on
    /// `roadmap` when a waypoint's timer runs out.
    fn drive_attempt(
        &mut self,
        d: usize,
        leg: usize,
        attempt: u32,
        roadmap: &Roadmap,
        path: &LegPath,
        query: QueryOptions,
    ) -> Result<DriveRun, PlanError> {
        let (world, request) = (self.floor.world, self.request);
        let opts = &request.options;
        let driver = &mut self.drivers[d];
        driver.controller.start_attempt(attempt);
        let max_segment_m = driver.max_segment_m;
        let replanner: &mut Replanner<'_> = &mut |p: Point2, g: Point2, blocked: Option<Point2>| {
            replan(roadmap, opts, world, (p, g), blocked, max_segment_m, query)
        };
        drive(
            world,
            &driver.env,
            self.pose,
            std::slice::from_ref(&path.waypoints),
            &mut *driver.controller,
            DriveLimits {
                waypoint_timeout_s: opts.waypoint_timeout_s,
                max_replans: opts.max_replans,
                sim_seed: leg_seed(opts.seed, attempt, leg),
                initial_velocity: Action::default(),
                stop: request.stop.clone(),
                trace: opts.trace,
                recoveries: recoveries_for(opts),
                others: None,
                holds: Vec::new(),
            },
            Some(replanner),
        )
    }

    /// The report of an attempt, and what it measured beyond it.
    fn record(
        &mut self,
        d: usize,
        leg: usize,
        attempt: u32,
        roadmap: &AttemptRoadmap,
        path: &LegPath,
        run: &DriveRun,
    ) {
        let opts = &self.request.options;
        let driver = &self.drivers[d];
        // A leg's run knows only its own goal: number it in the plan.
        let goals_reached = if run.outcome == AttemptOutcome::Reached {
            leg + 1
        } else {
            leg
        };
        self.details.push(AttemptDetails {
            social: run.social,
            recoveries: run.recoveries.clone(),
        });
        self.attempts.push(AttemptReport {
            attempt,
            leg,
            controller: driver.controller.kind(),
            roadmap_seed: roadmap.seed,
            outcome: run.outcome,
            reason: run.reason.clone(),
            simulated_time_s: run.time_s,
            distance_m: run.distance_m,
            min_clearance_m: run.min_clearance_m,
            replans: run.replans,
            waypoints_reached: self
                .validated
                .iter()
                .map(|v| v.run.reached.len())
                .sum::<usize>()
                + run.reached.len(),
            goals_reached,
            prm_path_length_m: path.length_m,
            end_pose: run.end_pose,
            handover_share: run.handover_share(),
            min_person_clearance_m: run.min_person_clearance_m,
            trace: opts
                .trace
                .then(|| attempt_trace(run, &path.waypoints, driver.env.control_period, opts)),
        });
    }

    /// The validating `run` of driver `d`, with the roadmap it was planned on.
    fn validated_leg(
        &self,
        d: usize,
        roadmap: &AttemptRoadmap,
        path: &LegPath,
        run: DriveRun,
    ) -> ValidatedLeg {
        ValidatedLeg {
            run,
            controller: self.drivers[d].controller.kind(),
            by_fallback: d > 0,
            prm_path_length_m: path.length_m,
            roadmap: RoadmapInfo {
                samples: roadmap.roadmap.params().samples,
                nodes: roadmap.roadmap.nodes().count(),
                seed: roadmap.seed,
                inflation_m: self.inflation.total_m(),
                cached: roadmap.cached,
                kind: roadmap.kind,
            },
        }
    }

    /// The plan's report once every leg is validated: the validated legs driven again among
    /// fresh draws of people when asked, and the laser's geometry when traced.
    fn report(mut self) -> Result<PlanReport, PlanError> {
        let (world, request) = (self.floor.world, self.request);
        let opts = &request.options;
        let draws = if opts.people_draws > 0 && opts.people.any() {
            Some(drive_draws(
                world,
                &mut self.drivers,
                request.start,
                &self.validated,
                request,
            )?)
        } else {
            None
        };
        let roadmap = self.validated[0].roadmap.clone();
        let mut report = assemble(
            request.start,
            self.primary,
            self.description,
            opts,
            self.validated,
            self.attempts,
            roadmap,
        );
        let env = &self.drivers[0].env;
        report.control_period_s = env.control_period;
        report.people_draws = draws;
        if opts.trace {
            report.laser = Some(laser_trace(world, env));
        }
        Ok(report)
    }
}

/// The laser as a traced report shows it: the beams `env` reads, in the robot's frame.
fn laser_trace(world: &World, env: &EnvConfig) -> LaserTrace {
    let laser = &world.spec().robot.laser;
    LaserTrace {
        angles_rad: laser
            .beam_angles(env.beams)
            .unwrap_or_default()
            .into_iter()
            .map(|a| a + laser.mount.yaw)
            .collect(),
        max_range_m: laser.range_max,
        control_period_s: env.control_period,
    }
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
            // The one that validated the leg: the fallback is the second driver.
            let Some(driver) = drivers.get_mut(usize::from(v.by_fallback)) else {
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
                    recoveries: recoveries_for(opts),
                    others: None,
                    holds: Vec::new(),
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
pub(crate) fn leg_seed(seed: u64, attempt: u32, leg: usize) -> u64 {
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
            by_fallback: leg.by_fallback,
            roadmap: leg.roadmap.kind,
            attempts: attempts.iter().filter(|a| a.leg == i).count(),
            roadmap_seed: leg.roadmap.seed,
            simulated_time_s: run.time_s,
            distance_m: run.distance_m,
            min_clearance_m: run.min_clearance_m,
            replans: run.replans,
            rerouted: run
                .recoveries
                .iter()
                .any(|r| r.kind == crate::recovery::RecoveryKind::Reroute),
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
        steps: trajectory,
        control_period_s: EnvConfig::default().control_period,
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
/// 0.8 m/s and 0.5 rad/s, goal tolerance, collision clearance) except that the robot may
/// reverse (at up to MPPI's reverse speed, which backing up as a recovery stays well within; the
/// policy and the follower never command it), the trajectory recorded, no step limit (the
/// executor's timers bound the run).
pub fn env_config(beams: usize, noise: bool) -> EnvConfig {
    env_config_with(sim::CommandLimits::default(), beams, noise)
}

/// The command limits of the robot of `world`: its model's top speeds, the simulation's
/// defaults (the paper's robot's 0.8 m/s and 0.5 rad/s) where its model gives none.
pub fn command_limits(world: &World) -> sim::CommandLimits {
    let d = &world.spec().robot.drive;
    let defaults = sim::CommandLimits::default();
    sim::CommandLimits {
        linear_max: d.max_linear_speed.unwrap_or(defaults.linear_max),
        angular_max: d.max_angular_speed.unwrap_or(defaults.angular_max),
        ..defaults
    }
}

/// [`env_config`] for the robot of `world`, at its own top speeds ([`command_limits`]).
pub fn env_config_for(world: &World, beams: usize, noise: bool) -> EnvConfig {
    env_config_with(command_limits(world), beams, noise)
}

fn env_config_with(limits: sim::CommandLimits, beams: usize, noise: bool) -> EnvConfig {
    EnvConfig {
        limits: sim::CommandLimits {
            linear_min: sim::MppiParams::default().vx_min,
            ..limits
        },
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

/// Longest straight stretch between two waypoints: half of what the robot covers at top speed
/// within the waypoint timer, so turning and slowing never make a waypoint miss its timer (the
/// roadmap's edges reach 15 m, which 0.8 m/s does not cover in 15 s). Longer segments get
/// intermediate waypoints on the segment itself (free, as the segment is).
fn max_segment(env: &EnvConfig, opts: &PlanOptions) -> f64 {
    (0.5 * env.limits.linear_max * opts.waypoint_timeout_s).max(0.5)
}

/// The checks a rehearsal of `request` makes before it drives, alone: the robot fits at its
/// start (or escapes to free space nearby), every goal is free and reachable from the one
/// before. Cheap once the floor's configuration space is in `roadmaps`. The error is the one the
/// rehearsal would answer.
pub fn check_endpoints(
    world: &World,
    roadmaps: &RoadmapCache,
    map_version: &str,
    request: &PlanRequest,
) -> Result<(), PlanError> {
    let inflation = prm::Inflation {
        robot_radius_m: world.spec().robot.footprint_radius,
        safety_margin_m: request.options.safety_margin_m,
    };
    let space = roadmaps.config_space(map_version, world, inflation)?;
    let cs = &*space.cspace;
    let start = request.start;
    let clearance = EnvConfig::default().collision_clearance;
    let entry = start_entry(world, cs, start, clearance)?;
    check_goals(
        cs,
        entry.unwrap_or(Point2::new(start.x, start.y)),
        &request.goals,
    )
}

/// The share of its top speed a robot is taken to cover a roadmap route at, turns and
/// accelerations included, when the route is timed among other robots' plans (the controllers
/// slow for turns, near walls and at the goal). An estimate: the fit of the driven plan among
/// the fleet sets the times that are committed.
const ROUTE_SPEED_SHARE: f64 = 0.75;

/// How many times the roadmap's samples a route keeping clear of standing robots is planned
/// on.
pub const STANDING_DENSITY: usize = 4;

/// The recoveries of a validation's drives: Nav2's ([`RecoveryParams::default`]) among people,
/// where robots stall beside people standing still; none in an empty building, where the
/// controllers' stalls are the waypoint timer's and the replanner's to resolve.
pub fn recoveries_for(opts: &PlanOptions) -> Option<RecoveryParams> {
    opts.people.any().then(RecoveryParams::default)
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
        prm::Inflation {
            robot_radius_m: world.spec().robot.footprint_radius,
            safety_margin_m,
        },
    )
}
