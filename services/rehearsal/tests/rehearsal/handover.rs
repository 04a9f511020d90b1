//! The handover inside the policy controller, on a real world and roadmap: a policy that only
//! ever drives straight ahead stalls behind the shield wherever an edge needs a turn, and the
//! classical follower taking over near obstacles brings it to the waypoint; the report says
//! how much of the driving was the follower's.

use std::sync::Arc;

use learning::Policy;
use prm::{Point2, PrmParams};
use rehearsal::{
    AttemptOutcome, ClassicalFollower, Controller, DriveLimits, EdgeRolloutParams,
    PolicyController, RoadmapCache, drive, drive_edges,
};
use sim::{Action, Observation, Pose2};

/// A policy whose network ignores its input: full speed ahead (sigmoid(8) ≈ 1), no turning.
fn straight_ahead(dir: &std::path::Path) -> Arc<Policy> {
    constant(dir, 8.0)
}

/// A policy whose network ignores its input: linear output sigmoid(`linear`), no turning.
fn constant(dir: &std::path::Path, linear: f32) -> Arc<Policy> {
    let scaling = learning::Scaling::default();
    let inputs = scaling.input_len();
    let meta = learning::policy::PolicyMetadata::new(scaling, vec![2], serde_json::json!({}));
    let layers = [
        (vec![0.0f32; 2 * inputs], vec![0.0f32; 2]),
        (vec![0.0f32; 4], vec![linear, 0.0]),
    ];
    learning::policy::write_policy(dir, &meta, &layers).expect("written");
    Arc::new(Policy::load(dir).expect("loads"))
}

/// `c` attached to `world` with the default beams, its first attempt begun.
fn ready(mut c: PolicyController, world: &Arc<sim::World>) -> PolicyController {
    c.attach(world, learning::Scaling::default().beams);
    c.start_attempt(1);
    c
}

/// Nothing within 5 m, the waypoint 3 m straight ahead, the robot at rest.
fn open_space() -> Observation {
    Observation {
        ranges: vec![5.0; learning::Scaling::default().beams],
        goal_distance: 3.0,
        goal_angle: 0.0,
        velocity: [0.0; 2],
    }
}

#[test]
fn a_policy_that_makes_no_progress_hands_over_to_the_follower() {
    let tmp = tempfile::tempdir().expect("tmp");
    // Standing still in open space: nothing near, so no other rule hands over.
    let world = fixtures::worlds::walled_room();
    let mut c = ready(PolicyController::new(constant(tmp.path(), -12.0)), &world);
    let open = open_space();
    let here = Pose2::new(1.0, 1.0, 0.0);
    for _ in 0..rehearsal::POLICY_STALL_STEPS {
        let a = c.command(&open, here, (4.0, 1.0));
        assert!(!c.handed_over() && a.linear < 0.01, "{a:?}");
    }
    // No gain on the waypoint for 3 s: the follower drives to it, and keeps it however clear
    // the way is (the policy, not the way, was the trouble).
    let a = c.command(&open, here, (4.0, 1.0));
    assert!(c.handed_over() && a.linear > 0.0, "{a:?}");
    for _ in 0..(2 * rehearsal::HAND_BACK_STEPS) {
        c.command(&open, here, (4.0, 1.0));
        assert!(c.handed_over());
    }
    // A policy that gains on its waypoint keeps driving.
    let mut c = ready(PolicyController::new(straight_ahead(tmp.path())), &world);
    for k in 0..(2 * rehearsal::POLICY_STALL_STEPS) {
        let x = 1.0 + 0.03 * f64::from(k);
        c.command(&open, Pose2::new(x, 1.0, 0.0), (4.0, 1.0));
        assert!(!c.handed_over(), "step {k}");
    }
}

#[test]
fn the_follower_takes_over_where_the_policy_would_press_on_a_wall() {
    let tmp = tempfile::tempdir().expect("tmp");
    let policy = straight_ahead(tmp.path());
    let world = fixtures::worlds::walled_room();
    let cache = RoadmapCache::default();
    let space = rehearsal::config_space(&world, &cache, "room-v1", 0.1).expect("space");
    let params = PrmParams {
        samples: 60,
        seed: 3,
        ..PrmParams::default()
    };
    let (map, _) = cache.roadmap("room-v1", &space, &params).expect("roadmap");
    let rollouts = EdgeRolloutParams {
        rollouts: 4,
        seed: 5,
        ..EdgeRolloutParams::default()
    };
    let alone = drive_edges(
        &world,
        &map,
        || PolicyController::without_handover(Arc::clone(&policy)),
        &rollouts,
    )
    .expect("driven");
    let handed = drive_edges(
        &world,
        &map,
        || PolicyController::new(Arc::clone(&policy)),
        &rollouts,
    )
    .expect("driven");
    let follower = drive_edges(&world, &map, ClassicalFollower::default, &rollouts).expect("ok");
    // Straight ahead behind the shield alone: it loses the edges that need a turn.
    assert!(
        alone.edge_success_rate() < 0.8,
        "alone: {:.3}",
        alone.edge_success_rate()
    );
    assert_eq!(alone.handover_steps, 0);
    // With the handover it drives most of those (not all: where an edge leads away from
    // every wall, straight ahead never comes near one and never reaches the waypoint), and the
    // follower drove part of it.
    assert!(
        handed.edge_success_rate() > alone.edge_success_rate() + 0.15,
        "handover {:.3}, alone {:.3}, follower {:.3}",
        handed.edge_success_rate(),
        alone.edge_success_rate(),
        follower.edge_success_rate()
    );
    assert!(
        handed.handover_steps > 0 && handed.handover_steps < handed.steps,
        "{} of {} steps",
        handed.handover_steps,
        handed.steps
    );
    assert!((0.0..1.0).contains(&handed.handover_share()));
    assert_eq!(follower.handover_share(), 0.0);
}

#[test]
fn the_handover_lasts_until_the_policy_keeps_the_margin_or_the_next_waypoint() {
    let tmp = tempfile::tempdir().expect("tmp");
    let world = fixtures::worlds::walled_room();
    let mut c = ready(PolicyController::new(straight_ahead(tmp.path())), &world);
    let beams = learning::Scaling::default().beams;
    let open = open_space();
    let here = Pose2::new(1.0, 1.0, 0.0);
    // Open space: the policy's own command, full speed ahead.
    let a = c.command(&open, here, (4.0, 1.0));
    assert!(!c.handed_over() && a.linear > 0.7, "{a:?}");
    // A wall 0.5 m ahead: the footprint would come within the margin, the follower drives.
    let mut wall = open.clone();
    wall.ranges[beams / 2] = 0.5;
    c.command(&wall, here, (4.0, 1.0));
    assert!(c.handed_over());
    // It keeps driving while the laser sees open space again, for a second...
    for k in 1..rehearsal::HAND_BACK_STEPS {
        c.command(&open, here, (4.0, 1.0));
        assert!(c.handed_over(), "step {k}");
    }
    // ...after which the policy, its own command clear all that time, drives again.
    let a = c.command(&open, here, (4.0, 1.0));
    assert!(!c.handed_over() && a.linear > 0.7, "{a:?}");
    // A wall seen again within that second starts the count afresh.
    c.command(&wall, here, (4.0, 1.0));
    for _ in 0..(rehearsal::HAND_BACK_STEPS - 1) {
        c.command(&open, here, (4.0, 1.0));
    }
    c.command(&wall, here, (4.0, 1.0));
    for _ in 0..(rehearsal::HAND_BACK_STEPS - 1) {
        c.command(&open, here, (4.0, 1.0));
    }
    assert!(c.handed_over());
    // A person within personal space (a return the map does not know, 1 m away ahead to the
    // left, clear of the policy's way): the follower keeps the wheel.
    let mut person = open.clone();
    person.ranges[beams * 3 / 4] = 1.0;
    for _ in 0..(2 * rehearsal::HAND_BACK_STEPS) {
        c.command(&person, here, (4.0, 1.0));
        assert!(c.handed_over());
    }
    // The next waypoint is the policy's at once.
    let a = c.command(&open, Pose2::new(4.0, 1.0, 0.0), (7.0, 1.0));
    assert!(!c.handed_over() && a.linear > 0.7, "{a:?}");
    // A new attempt starts with the policy.
    c.command(&wall, here, (4.0, 1.0));
    assert!(c.handed_over());
    c.start_attempt(2);
    c.command(&open, here, (4.0, 1.0));
    assert!(!c.handed_over());
    // Without the handover the shield alone answers.
    let mut alone = PolicyController::without_handover(straight_ahead(tmp.path()));
    alone.attach(&world, beams);
    alone.command(&wall, here, (4.0, 1.0));
    assert!(!alone.handed_over());
}

/// The goal-seeking hand-made policy: it turns towards its goal and drives once facing it.
fn goal_seeking(dir: &std::path::Path) -> Arc<Policy> {
    let beams = learning::Scaling::default().beams;
    learning::policy::write_goal_seeking_policy(dir, beams, serde_json::json!({})).expect("ok");
    Arc::new(Policy::load(dir).expect("loads"))
}

#[test]
fn on_the_smoothed_path_the_policy_turns_before_a_vertex_and_passes_it() {
    let tmp = tempfile::tempdir().expect("tmp");
    let policy = goal_seeking(tmp.path());
    let world = fixtures::worlds::walled_room();
    let beams = policy.scaling().beams;
    // An L: east 2 m, then north 3.5 m.
    let start = Pose2::new(1.5, 1.5, 0.0);
    let corner = Point2::new(3.5, 1.5);
    let path = [corner, Point2::new(3.5, 5.0)];
    let at = |x: f64, y: f64, yaw: f64, goal: Point2| {
        let (dx, dy) = (goal.x - x, goal.y - y);
        Observation {
            ranges: vec![5.0; beams],
            goal_distance: sim::norm(dx, dy) as f32,
            goal_angle: sim::kinematics::wrap_angle(dy.atan2(dx) - yaw) as f32,
            velocity: [0.8, 0.0],
        }
    };
    let mut vertex = PolicyController::with_rpp_handover(Arc::clone(&policy));
    let mut carrot = PolicyController::on_smoothed_path(Arc::clone(&policy));
    let mut last = [Action::default(); 2];
    for (i, c) in [&mut vertex, &mut carrot].into_iter().enumerate() {
        c.attach(&world, beams);
        c.start_attempt(1);
        c.start_path(start, &path);
        // Driving east towards the corner, 0.6 m before it.
        for x in [1.5, 2.0, 2.5, 2.9] {
            last[i] = c.command(
                &at(x, 1.5, 0.0, corner),
                Pose2::new(x, 1.5, 0.0),
                (3.5, 1.5),
            );
        }
        assert!(!c.handed_over(), "open space: the policy drives");
    }
    // Towards the vertex, the vertex straight ahead; towards the carrot, already turning left.
    assert!(last[0].angular.abs() < 0.05, "{:?}", last[0]);
    assert!(last[1].angular > 0.2, "{:?}", last[1]);
    // Past the corner, 0.4 m from the vertex and heading north: only the carrot's controller
    // counts the vertex as passed (the other's policy has not reached it).
    let past = Pose2::new(3.5, 1.9, std::f64::consts::FRAC_PI_2);
    for (i, c) in [&mut vertex, &mut carrot].into_iter().enumerate() {
        c.command(&at(3.5, 1.9, past.yaw, corner), past, (3.5, 1.5));
        assert_eq!(c.passed(past, corner), i == 1);
    }
}

#[test]
fn where_the_path_doubles_back_the_policy_drives_to_the_vertex_ahead() {
    let tmp = tempfile::tempdir().expect("tmp");
    let policy = goal_seeking(tmp.path());
    let world = fixtures::worlds::walled_room();
    let beams = policy.scaling().beams;
    // East 1.1 m, then back west past the start: the carrot 1.2 m on is behind the robot.
    let start = Pose2::new(1.5, 1.5, 0.0);
    let tip = Point2::new(2.6, 1.5);
    let mut c = PolicyController::on_smoothed_path(Arc::clone(&policy));
    c.attach(&world, beams);
    c.start_attempt(1);
    c.start_path(start, &[tip, Point2::new(0.6, 1.6)]);
    let obs = Observation {
        ranges: vec![5.0; beams],
        goal_distance: 1.1,
        goal_angle: 0.0,
        velocity: [0.0, 0.0],
    };
    let a = c.command(&obs, start, (tip.x, tip.y));
    // Towards the vertex ahead, not turning on the spot towards the carrot behind.
    assert!(a.linear > 0.3 && a.angular.abs() < 0.2, "{a:?}");
}

#[test]
fn on_the_smoothed_path_the_policy_drives_an_l_sooner() {
    let tmp = tempfile::tempdir().expect("tmp");
    let policy = goal_seeking(tmp.path());
    let world = fixtures::worlds::walled_room();
    let env = rehearsal::env_config(policy.scaling().beams, true);
    let legs = [vec![
        Point2::new(3.5, 1.5),
        Point2::new(3.5, 4.5),
        Point2::new(1.5, 4.5),
    ]];
    let times: Vec<f64> = [
        PolicyController::with_rpp_handover(Arc::clone(&policy)),
        PolicyController::on_smoothed_path(Arc::clone(&policy)),
    ]
    .into_iter()
    .map(|mut c| {
        c.attach(&world, policy.scaling().beams);
        c.start_attempt(1);
        let limits = DriveLimits {
            waypoint_timeout_s: 15.0,
            max_replans: 0,
            sim_seed: 11,
            initial_velocity: Action::default(),
            stop: rehearsal::Stop::default(),
            trace: false,
            recoveries: None,
            others: None,
            holds: Vec::new(),
        };
        let run = drive(
            &world,
            &env,
            Pose2::new(1.5, 1.5, 0.0),
            &legs,
            &mut c,
            limits,
            None,
        )
        .expect("driven");
        assert_eq!(run.outcome, AttemptOutcome::Reached, "{}", run.reason);
        run.time_s
    })
    .collect();
    // Two right-angle turns: stopping to turn at each vertex costs seconds.
    assert!(times[1] < times[0] - 1.0, "{times:?}");
}
