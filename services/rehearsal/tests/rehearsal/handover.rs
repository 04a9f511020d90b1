//! The handover inside the policy controller, on a real world and roadmap: a policy that only
//! ever drives straight ahead stalls behind the shield wherever an edge needs a turn, and the
//! classical follower taking over near obstacles brings it to the waypoint; the report says
//! how much of the driving was the follower's.

use std::sync::Arc;

use learning::Policy;
use planning::PrmParams;
use rehearsal::{
    ClassicalFollower, Controller, EdgeRolloutParams, PolicyController, RoadmapCache, drive_edges,
};
use sim::{Observation, Pose2};

/// A policy whose network ignores its input: full speed ahead (sigmoid(8) ≈ 1), no turning.
fn straight_ahead(dir: &std::path::Path) -> Arc<Policy> {
    let scaling = learning::Scaling::default();
    let inputs = scaling.input_len();
    let meta = learning::policy::PolicyMetadata::new(scaling, vec![2], serde_json::json!({}));
    let layers = [
        (vec![0.0f32; 2 * inputs], vec![0.0f32; 2]),
        (vec![0.0f32; 4], vec![8.0f32, 0.0]),
    ];
    learning::policy::write_policy(dir, &meta, &layers).expect("written");
    Arc::new(Policy::load(dir).expect("loads"))
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
fn the_handover_lasts_until_the_next_waypoint() {
    let tmp = tempfile::tempdir().expect("tmp");
    let world = fixtures::worlds::walled_room();
    let mut c = PolicyController::new(straight_ahead(tmp.path()));
    let beams = learning::Scaling::default().beams;
    c.attach(&world, beams);
    c.start_attempt(1);
    let open = Observation {
        ranges: vec![5.0; beams],
        goal_distance: 3.0,
        goal_angle: 0.0,
        velocity: [0.0; 2],
    };
    let here = Pose2::new(1.0, 1.0, 0.0);
    // Open space: the policy's own command, full speed ahead.
    let a = c.command(&open, here, (4.0, 1.0));
    assert!(!c.handed_over() && a.linear > 0.7, "{a:?}");
    // A wall 0.5 m ahead: the footprint would come within the margin, the follower drives.
    let mut wall = open.clone();
    wall.ranges[beams / 2] = 0.5;
    c.command(&wall, here, (4.0, 1.0));
    assert!(c.handed_over());
    // It keeps driving to that waypoint even where the laser sees open space again...
    c.command(&open, here, (4.0, 1.0));
    assert!(c.handed_over());
    // ...and the policy gets the next one.
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
