//! Roadmap edges driven in the mental simulation (PRM-RL) with real worlds and roadmaps: the
//! report, the kept edges, and a policy-aware roadmap that plans only over kept edges.

use std::sync::Arc;

use prm::{Point2, PrmParams, QueryOptions};
use rehearsal::{
    ClassicalFollower, Controller, ControllerKind, EdgeRolloutParams, PlanError, RoadmapCache,
    drive_edges,
};
use sim::{Action, Observation, Pose2, World};

fn room() -> Arc<World> {
    fixtures::worlds::walled_room()
}

fn roadmap(world: &Arc<World>, cache: &RoadmapCache) -> Arc<prm::Roadmap> {
    let space = rehearsal::config_space(world, cache, "room-v1", 0.1).expect("space");
    let params = PrmParams {
        samples: 60,
        seed: 3,
        ..PrmParams::default()
    };
    cache
        .roadmap("room-v1", &space, &params)
        .expect("roadmap")
        .0
}

/// The follower, except on edges that end left of the inner wall (x < 4.9): there it drives
/// straight ahead, which from most headings ends against a wall.
struct BadOnTheLeft(ClassicalFollower);

impl Controller for BadOnTheLeft {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        if waypoint.0 < 4.9 {
            Action::new(0.8, 0.0)
        } else {
            self.0.command(obs, pose, waypoint)
        }
    }
    fn kind(&self) -> ControllerKind {
        ControllerKind::Policy
    }
    fn description(&self) -> String {
        "bad on the left".into()
    }
    fn attach(&mut self, world: &Arc<World>, beams: usize) {
        self.0.attach(world, beams);
    }
}

#[test]
fn the_follower_drives_the_edges_and_a_bad_controller_loses_them() {
    let world = room();
    let cache = RoadmapCache::default();
    let map = roadmap(&world, &cache);
    let undirected = map.edges().count();
    assert!(undirected > 20, "{undirected} edges");
    let params = EdgeRolloutParams {
        rollouts: 4,
        seed: 5,
        ..EdgeRolloutParams::default()
    };
    let good = drive_edges(&world, &map, ClassicalFollower::default, &params).expect("driven");
    assert_eq!(good.edges.len(), 2 * undirected);
    assert!(good.edges.iter().all(|e| e.rollouts == 4));
    assert!(
        good.edge_success_rate() > 0.95,
        "the follower drives {:.3} of its rollouts",
        good.edge_success_rate()
    );
    assert!(good.steps > 0);
    assert!(good.mean_edge_time_s().is_some_and(|t| t > 0.0));
    // The same parameters give the same report.
    let again = drive_edges(&world, &map, ClassicalFollower::default, &params).expect("driven");
    assert_eq!(again, good);
    // Odd rollouts start moving, as the executor hands a waypoint over: all from rest differs.
    let from_rest = EdgeRolloutParams {
        arrival_speed_share: 0.0,
        ..params
    };
    let rest = drive_edges(&world, &map, ClassicalFollower::default, &from_rest).expect("driven");
    assert_ne!(rest.mean_edge_time_s(), good.mean_edge_time_s());

    let bad = drive_edges(
        &world,
        &map,
        || BadOnTheLeft(ClassicalFollower::default()),
        &params,
    )
    .expect("driven");
    let nodes: Vec<Point2> = map.nodes().collect();
    let left = |i: usize| nodes[i].x < 4.9;
    let dropped_left = bad.dropped().filter(|e| left(e.to)).count();
    let dropped_right = bad.dropped().filter(|e| !left(e.to)).count();
    let good_dropped_right = good.dropped().filter(|e| !left(e.to)).count();
    assert!(dropped_left > 0, "no edge into the left part was dropped");
    // On the right it is the follower: it loses what the follower loses, give or take noise.
    assert!(
        dropped_right <= good_dropped_right + 2,
        "{dropped_right} dropped on the right (the follower: {good_dropped_right})"
    );
    // Costs: a kept direction costs at least its length, a dropped one has none.
    for e in &bad.edges {
        match bad.cost(e.from, e.to, 10.0) {
            Some(c) => assert!(c >= e.length_m && e.success_rate() >= 0.9, "{e:?}"),
            None => assert!(e.success_rate() < 0.9, "{e:?}"),
        }
    }
    // The complete policy-aware roadmap prices every direction: the unkept ones at the
    // penalty more, so a route takes them only where no kept route joins start and goal.
    for e in &bad.edges {
        let c = bad
            .cost_with_unkept(e.from, e.to, 10.0)
            .expect("every direction");
        match bad.cost(e.from, e.to, 10.0) {
            Some(kept) => assert!((c - kept).abs() < 1e-9, "{e:?}"),
            None => assert!(c >= e.length_m + rehearsal::UNKEPT_PENALTY_M, "{e:?}"),
        }
    }
    let kept_only = rehearsal::reweight(&map, &bad).expect("reweighted");
    let complete = rehearsal::reweight_with_unkept(&map, &bad).expect("reweighted");
    let opts = QueryOptions {
        no_densify: true,
        ..QueryOptions::default()
    };
    // Deep in the left part, where every edge in is unkept: only the complete roadmap goes.
    let (start, goal) = (Point2::new(8.0, 2.0), Point2::new(1.5, 2.0));
    let into_left = complete.query(start, goal, opts);
    assert!(into_left.is_ok(), "{into_left:?}");
    let kept_route = kept_only.query(start, goal, opts);
    if let Ok(route) = kept_route {
        // Where kept edges do join them, the complete roadmap plans the same route.
        assert_eq!(into_left.unwrap().waypoints, route.waypoints);
    }
    // On the right, where everything is kept, both plan the same route.
    let (a, b) = (Point2::new(6.0, 2.0), Point2::new(8.0, 6.5));
    assert_eq!(
        kept_only.query(a, b, opts).expect("kept route").waypoints,
        complete.query(a, b, opts).expect("route").waypoints
    );
}

#[test]
fn a_policy_aware_roadmap_plans_only_over_kept_edges() {
    let world = room();
    let cache = RoadmapCache::default();
    let map = roadmap(&world, &cache);
    let nodes: Vec<Point2> = map.nodes().collect();
    // Keep only the edges whose both ends lie above y = 4: a path from the lower left to the
    // lower right must then climb over the inner wall by the upper edges.
    let upper = |i: usize| nodes[i].y > 4.0;
    let policy_map = map
        .reweighted(|a, b, len| (upper(a) && upper(b)).then_some(len * 1.5))
        .expect("reweighted");
    let opts = QueryOptions {
        no_densify: true,
        ..QueryOptions::default()
    };
    let start = Point2::new(2.0, 6.5);
    let goal = Point2::new(8.0, 6.5);
    let plan = policy_map.query(start, goal, opts).expect("a path");
    // Interior waypoints are roadmap nodes above y = 4.
    for w in &plan.waypoints[1..plan.waypoints.len() - 1] {
        assert!(w.y > 4.0, "{w:?}");
    }
    // The plan's length is its length, not its cost.
    let polyline: f64 = plan.waypoints.windows(2).map(|w| w[0].distance(w[1])).sum();
    assert!(
        (plan.length_m - polyline).abs() < 1e-6,
        "{} vs {polyline}",
        plan.length_m
    );

    // No kept edge at all: nothing joins two points the straight line does not.
    let empty = map.reweighted(|_, _, _| None).expect("reweighted");
    let far = empty.query(Point2::new(2.0, 2.0), Point2::new(8.0, 2.0), opts);
    assert!(far.is_err(), "{far:?}");
}

#[test]
fn bad_rollout_parameters_are_refused_by_name() {
    let world = room();
    let cache = RoadmapCache::default();
    let map = roadmap(&world, &cache);
    for (params, field) in [
        (
            EdgeRolloutParams {
                rollouts: 0,
                ..EdgeRolloutParams::default()
            },
            "rollouts",
        ),
        (
            EdgeRolloutParams {
                keep_threshold: 1.5,
                ..EdgeRolloutParams::default()
            },
            "keep_threshold",
        ),
        (
            EdgeRolloutParams {
                waypoint_timeout_s: f64::NAN,
                ..EdgeRolloutParams::default()
            },
            "waypoint_timeout_s",
        ),
        (
            EdgeRolloutParams {
                arrival_speed_share: 1.5,
                ..EdgeRolloutParams::default()
            },
            "arrival_speed_share",
        ),
    ] {
        let e =
            drive_edges(&world, &map, ClassicalFollower::default, &params).expect_err("refused");
        assert!(matches!(e, PlanError::InvalidInput { .. }), "{e:?}");
        assert!(e.to_string().contains(field), "{e}");
    }
}
