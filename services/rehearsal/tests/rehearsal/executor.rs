//! The plan executor with real components: worlds built by `sim`, roadmaps by `planning`, the
//! pure-Rust policy runtime of `learning`. What the plan endpoint makes of the results (wire
//! types, error reasons and codes) is tested in `api`'s `tests/api/plan.rs`.

use std::path::Path;
use std::sync::Arc;

use learning::Policy;
use learning::policy::write_goal_seeking_policy;
use prm::Point2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rehearsal::{
    AttemptOutcome, BlockedReason, ClassicalFollower, Controller, ControllerKind, Endpoint,
    PlanError, PlanOptions, PlanReport, PlanRequest, RoadmapCache, validate, validate_with,
    validate_with_fallback,
};
use sim::{Action, FloorMap, Observation, OccupancyGrid, Pose2, RobotSpec, World, WorldSpec};

/// The environment's collision clearance (sim's default).
const COLLISION_CLEARANCE: f64 = 0.02;
/// The environment's goal tolerance (sim's default).
const GOAL_TOLERANCE: f64 = 0.3;

fn room() -> Arc<World> {
    fixtures::worlds::walled_room()
}

fn request(goals: &[(f64, f64)]) -> PlanRequest {
    PlanRequest {
        start: Pose2::new(2.0, 2.0, 0.0),
        goals: goals.iter().map(|&(x, y)| Point2::new(x, y)).collect(),
        options: PlanOptions::default(),
        stop: rehearsal::Stop::default(),
    }
}

/// The report's run really happened without a collision and ended at the last goal.
fn assert_sound(world: &World, report: &PlanReport, goals: &[Point2]) {
    assert!(report.min_clearance_m >= COLLISION_CLEARANCE, "{report:?}");
    for p in &report.trajectory {
        assert!(
            world.clearance(p.x, p.y) >= COLLISION_CLEARANCE,
            "pose ({}, {}) is in collision",
            p.x,
            p.y
        );
    }
    // The waypoints answered, from the start, are joined by straight stretches the robot's
    // body fits along: a robot driving them meets no wall.
    let start = report.trajectory.first().expect("a trajectory");
    let mut from = (start.x, start.y);
    for w in &report.waypoints {
        let n = ((w.x - from.0).hypot(w.y - from.1) / 0.02).ceil().max(1.0) as usize;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let (x, y) = (from.0 + (w.x - from.0) * t, from.1 + (w.y - from.1) * t);
            assert!(
                world.clearance(x, y) > 0.0,
                "the stretch ({:.2}, {:.2}) → ({:.2}, {:.2}) runs into a wall at ({x:.2}, {y:.2})",
                from.0,
                from.1,
                w.x,
                w.y
            );
        }
        from = (w.x, w.y);
    }
    let end = report.trajectory.last().expect("a trajectory");
    let last = goals.last().expect("a goal");
    assert!(
        (end.x - last.x).hypot(end.y - last.y) <= GOAL_TOLERANCE + 1e-9,
        "ends at ({}, {}), goal ({}, {})",
        end.x,
        end.y,
        last.x,
        last.y
    );
    assert_eq!(report.goal_indices.len(), goals.len());
    for (gi, g) in report.goal_indices.iter().zip(goals) {
        assert_eq!(report.waypoints[*gi], *g);
    }
    assert!(report.distance_m >= report.waypoint_path_length_m * 0.9);
    assert!(report.simulated_time_s > 0.0 && report.prm_path_length_m > 0.0);
    assert_eq!(
        report.attempts.last().map(|a| a.outcome),
        Some(AttemptOutcome::Reached)
    );
}

#[test]
fn the_classical_follower_validates_a_multi_goal_plan() {
    let world = room();
    let cache = RoadmapCache::default();
    let req = request(&[(7.0, 2.0), (12.0, 6.0), (8.0, 1.0)]);
    let report = validate(&world, &cache, "room-v1", &req, None).expect("validated");
    assert_eq!(report.controller, ControllerKind::Classical);
    assert_eq!(report.controller.as_str(), "classical");
    assert!(report.controller_description.contains("rotate-then-go"));
    assert_sound(&world, &report, &req.goals);
    // Around the inner wall: longer than the straight line to the first goal.
    assert!(report.prm_path_length_m > 5.0 + 4.0 + 5.0);
    // The same request again plans on the cached roadmap and gives the same report.
    let again = validate(&world, &cache, "room-v1", &req, None).expect("validated");
    assert!(again.roadmap.cached);
    assert_eq!(again.waypoints, report.waypoints);
    assert_eq!(again.trajectory, report.trajectory);
    assert!(cache.stats().hits >= 1);
}

#[test]
fn each_bad_input_has_its_own_error() {
    let world = room();
    let cache = RoadmapCache::default();
    let run = |goals: &[(f64, f64)]| validate(&world, &cache, "room-v1", &request(goals), None);

    let e = run(&[(5.0, 3.0)]).expect_err("in the wall");
    let PlanError::Blocked {
        endpoint: Endpoint::Goal(0),
        reason: BlockedReason::InObstacle,
        nearest_free,
        ..
    } = &e
    else {
        panic!("{e:?}")
    };
    let near = nearest_free.expect("a nearest free point");
    assert!(
        (near.x - 5.0).abs() < 1.0 && (near.y - 3.0).abs() < 0.5,
        "{near:?}"
    );
    assert!(
        e.to_string()
            .starts_with("goals[0] (5.000, 3.000) is inside an obstacle")
    );
    assert!(e.to_string().contains("nearest free point"), "{e}");

    let e = run(&[(7.0, 2.0), (20.0, 3.0)]).expect_err("outside");
    assert!(
        matches!(
            e,
            PlanError::Blocked {
                endpoint: Endpoint::Goal(1),
                reason: BlockedReason::OutsideMap,
                ..
            }
        ),
        "{e:?}"
    );

    let e = run(&[(7.0, 2.0), (11.5, 2.5)]).expect_err("sealed box");
    let PlanError::Unreachable {
        goal_index, from, ..
    } = &e
    else {
        panic!("{e:?}")
    };
    assert_eq!((*goal_index, *from), (1, Endpoint::Goal(0)));
    assert!(e.to_string().ends_with("not connected to goals[0]"), "{e}");
    let e = run(&[(11.5, 2.5)]).expect_err("sealed box");
    assert!(e.to_string().ends_with("not connected to the start"), "{e}");

    let e = run(&[(f64::NAN, 3.0)]).expect_err("NaN");
    assert!(
        matches!(&e, PlanError::InvalidInput { field, .. } if field == "goals[0].x"),
        "{e:?}"
    );

    let e = run(&[]).expect_err("no goals");
    assert!(
        matches!(&e, PlanError::InvalidInput { field, .. } if field == "goals"),
        "{e:?}"
    );

    let mut req = request(&[(7.0, 2.0)]);
    req.start = Pose2::new(5.0, 1.0, 0.0);
    let e = validate(&world, &cache, "room-v1", &req, None).expect_err("start in the wall");
    assert!(
        matches!(
            e,
            PlanError::Blocked {
                endpoint: Endpoint::Start,
                reason: BlockedReason::InObstacle,
                ..
            }
        ),
        "{e:?}"
    );

    let mut req = request(&[(7.0, 2.0)]);
    req.options.max_attempts = 0;
    let e = validate(&world, &cache, "room-v1", &req, None).expect_err("no attempts");
    assert!(e.to_string().contains("options.max_attempts"), "{e}");
}

/// Drives straight ahead on its first attempt (into the inner wall), then follows the path.
struct RecklessFirst {
    attempt: u32,
    follower: ClassicalFollower,
}

impl Controller for RecklessFirst {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        if self.attempt == 1 {
            Action::new(0.8, 0.0)
        } else {
            self.follower.command(obs, pose, waypoint)
        }
    }
    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }
    fn description(&self) -> String {
        "reckless on the first attempt".into()
    }
    fn start_attempt(&mut self, attempt: u32) {
        self.attempt = attempt;
    }
}

#[test]
fn a_collision_resamples_the_roadmap_and_tries_again() {
    let world = room();
    let cache = RoadmapCache::default();
    let mut req = request(&[(7.0, 2.0)]);
    req.options.seed = 40;
    let mut c = RecklessFirst {
        attempt: 0,
        follower: ClassicalFollower::default(),
    };
    let report = validate_with(&world, &cache, "room-v1", &req, &mut c).expect("validated");
    assert_eq!(report.attempts.len(), 2, "{:?}", report.attempts);
    let first = &report.attempts[0];
    assert_eq!(first.outcome, AttemptOutcome::Collision);
    assert!(first.reason.contains("collision"), "{}", first.reason);
    assert_eq!(report.attempts[1].roadmap_seed, 41);
    assert_eq!(report.roadmap.seed, 41);
    assert_sound(&world, &report, &req.goals);
}

/// Reckless on every attempt.
struct Always(RecklessFirst);

impl Controller for Always {
    fn command(&mut self, o: &Observation, p: Pose2, w: (f64, f64)) -> Action {
        self.0.attempt = 1;
        self.0.command(o, p, w)
    }
    fn kind(&self) -> ControllerKind {
        self.0.kind()
    }
    fn description(&self) -> String {
        self.0.description()
    }
}

#[test]
fn no_attempt_validating_is_its_own_error_with_every_reason() {
    let world = room();
    let cache = RoadmapCache::default();
    let mut req = request(&[(7.0, 2.0)]);
    req.options.max_attempts = 3;
    let mut c = Always(RecklessFirst {
        attempt: 1,
        follower: ClassicalFollower::default(),
    });
    let e = validate_with(&world, &cache, "room-v1", &req, &mut c).expect_err("fails");
    let PlanError::NotValidated { attempts } = &e else {
        panic!("{e:?}")
    };
    assert_eq!(attempts.len(), 3);
    assert!(
        attempts
            .iter()
            .all(|a| a.outcome == AttemptOutcome::Collision)
    );
    // Each attempt on its own roadmap, and the message names every one.
    let seeds: Vec<u64> = attempts.iter().map(|a| a.roadmap_seed).collect();
    assert_eq!(seeds, [0, 1, 2]);
    for a in attempts {
        assert!(
            e.to_string().contains(&format!("#{} collision", a.attempt)),
            "{e}"
        );
    }
}

/// A "policy" that follows the path on its very first attempt and drives straight ahead on
/// every later one: it validates the first leg and fails the second.
struct FirstLegOnly {
    attempts: u32,
    follower: ClassicalFollower,
}

impl Controller for FirstLegOnly {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        if self.attempts == 1 {
            self.follower.command(obs, pose, waypoint)
        } else {
            Action::new(0.8, 0.0)
        }
    }
    fn kind(&self) -> ControllerKind {
        ControllerKind::Policy
    }
    fn description(&self) -> String {
        "good for one leg".into()
    }
    fn start_attempt(&mut self, _attempt: u32) {
        self.attempts += 1;
    }
}

#[test]
fn a_leg_the_policy_cannot_validate_is_validated_with_the_follower() {
    let world = room();
    let cache = RoadmapCache::default();
    let mut req = request(&[(7.0, 2.0), (3.0, 6.5)]);
    req.options.max_attempts = 3;
    let mut primary = FirstLegOnly {
        attempts: 0,
        follower: ClassicalFollower::default(),
    };
    let mut follower = ClassicalFollower::default();
    let report = validate_with_fallback(
        &world,
        &cache,
        "room-v1",
        &req,
        &mut primary,
        Some(&mut follower),
        None,
    )
    .expect("validated with the fallback");
    assert_eq!(report.controller, ControllerKind::Policy);
    let by: Vec<ControllerKind> = report.legs.iter().map(|l| l.controller).collect();
    assert_eq!(by, [ControllerKind::Policy, ControllerKind::Classical]);
    assert_eq!(report.legs[0].attempts, 1);
    // Every policy attempt on the second leg failed before the follower drove it.
    let second: Vec<_> = report.attempts.iter().filter(|a| a.leg == 1).collect();
    assert_eq!(second.len(), report.legs[1].attempts);
    assert!(second.len() > 3, "{second:?}");
    for a in &second[..3] {
        assert_eq!(a.controller, ControllerKind::Policy);
        assert_ne!(a.outcome, AttemptOutcome::Reached, "{a:?}");
    }
    let last = second.last().expect("an attempt");
    assert_eq!(
        (last.controller, last.outcome),
        (ControllerKind::Classical, AttemptOutcome::Reached)
    );
    assert_eq!(last.goals_reached, 2);
    assert_eq!(report.goal_indices.len(), 2);
    assert_sound(&world, &report, &req.goals);

    // Without a fallback the same plan is not validated, and the error names the leg's attempts.
    let mut primary = FirstLegOnly {
        attempts: 0,
        follower: ClassicalFollower::default(),
    };
    let e = validate_with(&world, &cache, "room-v1", &req, &mut primary).expect_err("fails");
    let PlanError::NotValidated { attempts } = &e else {
        panic!("{e:?}")
    };
    assert_eq!(attempts.iter().filter(|a| a.leg == 1).count(), 3);
}

/// Stands still for the first 16 s of its first attempt, then follows.
struct LateStarter {
    steps: u32,
    follower: ClassicalFollower,
}

impl Controller for LateStarter {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        self.steps += 1;
        if self.steps <= 160 {
            Action::default()
        } else {
            self.follower.command(obs, pose, waypoint)
        }
    }
    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }
    fn description(&self) -> String {
        "late".into()
    }
}

#[test]
fn the_waypoint_timer_replans_from_where_the_robot_is() {
    let world = room();
    let cache = RoadmapCache::default();
    let req = request(&[(7.0, 2.0), (3.0, 6.5)]);
    let mut c = LateStarter {
        steps: 0,
        follower: ClassicalFollower::default(),
    };
    let report = validate_with(&world, &cache, "room-v1", &req, &mut c).expect("validated");
    // One attempt per leg: the timer replanned, nothing failed.
    assert_eq!(report.attempts.len(), 2);
    assert!(
        report.legs.iter().all(|l| l.attempts == 1),
        "{:?}",
        report.legs
    );
    assert_eq!(report.replans, 1);
    assert!(report.simulated_time_s > 15.0);
    // The robot goes on from where it stood when the timer replanned (here its start): that
    // junction is a waypoint, so the route answered is the one driven.
    let first = report.waypoints[0];
    assert!(
        first.distance(Point2::new(2.0, 2.0)) < 0.1,
        "the first waypoint {first:?} is not where the replan took over"
    );
    assert_sound(&world, &report, &req.goals);
}

/// The goal-seeking hand-made policy (`learning::policy::write_goal_seeking_policy`).
fn steering_policy(dir: &Path, beams: usize) -> Arc<Policy> {
    write_goal_seeking_policy(dir, beams, serde_json::json!({"test": true})).expect("written");
    Arc::new(Policy::load(dir).expect("loads"))
}

#[test]
fn a_policy_drives_the_hybrid_planner() {
    let world = room();
    let cache = RoadmapCache::default();
    let dir = tempfile::tempdir().expect("tmp");
    let policy = steering_policy(dir.path(), 23);
    let req = request(&[(7.0, 2.0), (12.0, 6.0)]);
    let report = validate(&world, &cache, "room-v1", &req, Some(policy)).expect("validated");
    assert_eq!(report.controller, ControllerKind::Policy);
    assert!(report.controller_description.contains("TD3 actor"));
    assert_sound(&world, &report, &req.goals);

    // A policy whose input the robot's laser cannot give is a bad request.
    let dir = tempfile::tempdir().expect("tmp");
    let odd = steering_policy(dir.path(), 100_000);
    let e = validate(&world, &cache, "room-v1", &req, Some(odd)).expect_err("beams");
    assert!(
        matches!(&e, PlanError::InvalidInput { field, .. } if field == "policy"),
        "{e:?}"
    );
    assert!(e.to_string().contains("`policy`"), "{e}");
}

/// A real shared map: three goals far apart in the largest free region.
#[test]
fn a_real_map_validates_a_multi_goal_plan() {
    let Some(yaml) = fixtures::shared_fixture(
        "maps/ros/aws_small_house/map.yaml",
        "the shared map (the shared maps live beside the project)",
    ) else {
        return;
    };
    let text = std::fs::read_to_string(&yaml).expect("yaml");
    let meta = tosm::RosMapMeta::parse_yaml(&text).expect("yaml");
    let image = std::fs::read(yaml.with_file_name(&meta.image)).expect("image");
    let grid = OccupancyGrid::from_ros_map_server(&meta, &image).expect("grid");
    let world = World::build(WorldSpec {
        id: "aws_small_house".into(),
        floor: Some(FloorMap {
            id: "aws_small_house".into(),
            grid,
            wall_height: 2.5,
            frame_id: "map".into(),
        }),
        walls: vec![],
        objects: vec![],
        robot: RobotSpec::example_differential(),
        people: Default::default(),
        notes: vec![],
    })
    .expect("world");
    let cache = RoadmapCache::default();
    let space = rehearsal::config_space(&world, &cache, "aws_small_house", 0.1).expect("cs");
    let cs = &space.cspace;
    let region = cs.largest_region().expect("free space");
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut points = vec![cs.sample_free(&mut rng, Some(region)).expect("a point")];
    while points.len() < 4 {
        let p = cs.sample_free(&mut rng, Some(region)).expect("a point");
        if points.iter().all(|q| q.distance(p) > 3.0) {
            points.push(p);
        }
    }
    let req = PlanRequest {
        start: Pose2::new(points[0].x, points[0].y, 1.0),
        goals: points[1..].to_vec(),
        options: PlanOptions::default(),
        stop: rehearsal::Stop::default(),
    };
    let report = validate(&world, &cache, "aws_small_house", &req, None).expect("validated");
    assert_sound(&world, &report, &req.goals);
    eprintln!(
        "aws_small_house: {} waypoints, PRM path {:.1} m, driven {:.1} m in {:.1} s, min clearance {:.3} m, {} attempts",
        report.waypoints.len(),
        report.prm_path_length_m,
        report.distance_m,
        report.simulated_time_s,
        report.min_clearance_m,
        report.attempts.len()
    );
}
