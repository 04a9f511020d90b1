//! Nav2's classical path smoothing and tracking in the simulator: the Simple Smoother keeps
//! clearance and its end points and straightens corners; MPPI drives round an obstacle on its
//! path that only its laser sees.

use sim::kinematics::integrate;
use sim::smoother::{max_turning, total_turning};
use sim::{
    Action, Mppi, MppiParams, MppiWorld, PathTrack, Pose2, SmootherParams, World, smooth_path,
};

use crate::common::room;

/// A 10 m x 10 m room, its outer wall one cell thick.
fn world() -> std::sync::Arc<World> {
    World::build(room(10.0, 10.0)).expect("builds")
}

#[test]
fn the_smoother_keeps_the_ends_and_the_clearance_and_rounds_corners() {
    let w = world();
    // An L close to the walls: 0.6 m from the bottom wall and the right wall.
    let path = [(1.0, 0.6), (9.4, 0.6), (9.4, 9.0)];
    let p = SmootherParams::default();
    let smooth = smooth_path(&w, &path, &p);
    let dense = sim::smoother::densify(&path, w.resolution());
    assert_eq!(smooth.first(), Some(&(1.0, 0.6)));
    assert_eq!(smooth.last(), Some(&(9.4, 9.0)));
    assert_eq!(smooth.len(), dense.len());
    // Corners rounded: the sharpest turn between two points is far below the 90° corner, and
    // the total turning is still a quarter turn.
    assert!(max_turning(&dense) > 1.5);
    assert!(max_turning(&smooth) < 0.5, "{}", max_turning(&smooth));
    assert!((total_turning(&smooth) - std::f64::consts::FRAC_PI_2).abs() < 0.1);
    // The corner is cut, but never closer to a wall than the margin (or than the original).
    let corner = smooth
        .iter()
        .map(|q| (q.0 - 9.4).hypot(q.1 - 0.6))
        .fold(f64::INFINITY, f64::min);
    assert!(corner > 0.05, "{corner}");
    for (q, o) in smooth.iter().zip(&dense) {
        let floor = w.clearance(o.0, o.1).min(p.min_clearance_m);
        assert!(w.clearance(q.0, q.1) >= floor - 1e-9, "{q:?}");
    }
    // A path hugging the wall stays where it is: no point may go below its own clearance.
    let hug = [(1.0, 0.4), (5.0, 0.4), (5.0, 3.0)];
    let s = smooth_path(&w, &hug, &p);
    let d = sim::smoother::densify(&hug, w.resolution());
    for (q, o) in s.iter().zip(&d) {
        assert!(w.clearance(q.0, q.1) >= w.clearance(o.0, o.1).min(0.1) - 1e-9);
    }
}

#[test]
fn the_direct_smoother_lands_where_the_descent_converges() {
    let w = world();
    let p = SmootherParams::default();
    // Far from every wall: nothing stops the descent, and the direct solve is its limit.
    let open = [(2.0, 2.0), (5.0, 2.5), (6.0, 6.0), (3.0, 7.5), (8.0, 8.0)];
    let direct = smooth_path(&w, &open, &p);
    let descent = sim::smoother::smooth_path_by_descent(&w, &open, &p);
    assert_eq!(direct.len(), descent.len());
    let worst = direct
        .iter()
        .zip(&descent)
        .map(|(a, b)| (a.0 - b.0).hypot(a.1 - b.1))
        .fold(0.0, f64::max);
    assert!(worst < 1e-6, "{worst}");
    // The corners are really smoothed (the solve did not return the input).
    let dense = sim::smoother::densify(&open, w.resolution());
    assert!(max_turning(&direct) < 0.5 * max_turning(&dense));
    // Where the clearance stops points (here: no point may come closer to a wall than it
    // was, and rounding the apex of this V moves it towards the bottom wall), the answer is
    // the descent's, exactly, and no point lost clearance.
    let keep_all = SmootherParams {
        min_clearance_m: 100.0,
        ..p
    };
    let v = [(1.0, 0.6), (5.0, 3.0), (9.0, 0.6)];
    let stopped = smooth_path(&w, &v, &keep_all);
    assert_eq!(
        stopped,
        sim::smoother::smooth_path_by_descent(&w, &v, &keep_all)
    );
    let dense = sim::smoother::densify(&v, w.resolution());
    for (q, o) in stopped.iter().zip(&dense) {
        assert!(
            w.clearance(q.0, q.1) >= w.clearance(o.0, o.1) - 1e-9,
            "{q:?}"
        );
    }
    assert_ne!(stopped, smooth_path(&w, &v, &p));
}

#[test]
fn mppi_reaches_the_goal_round_an_obstacle_on_its_path() {
    let w = world();
    let path = sim::smoother::densify(&[(1.0, 5.0), (8.0, 5.0)], 0.05);
    let mut track = PathTrack::new(path);
    // Something the map does not know stands across the path's edge at x = 4.5 (a person,
    // 0.4 m wide, 0.1 m off the path's line): driving straight on would hit it.
    let unknown: Vec<(f64, f64)> = (0..=8).map(|k| (4.5, 5.1 + 0.05 * f64::from(k))).collect();
    assert!(
        unknown
            .iter()
            .any(|u| (u.1 - 5.0).abs() < w.spec().robot.footprint_radius)
    );
    let clearance = |x: f64, y: f64| w.clearance(x, y);
    let radius = w.spec().robot.footprint_radius;
    let view = MppiWorld {
        clearance: &clearance,
        unknown: &unknown,
        radius,
    };
    let mut mppi = Mppi::new(MppiParams::default(), 7);
    let mut pose = Pose2::new(1.0, 5.0, 0.0);
    let mut closest = f64::INFINITY;
    let mut costs = Vec::new();
    let mut steps = 0;
    while (pose.x - 8.0).hypot(pose.y - 5.0) > 0.25 && steps < 400 {
        let a = mppi.command(pose, &mut track, &view);
        assert!(
            a.linear <= 0.8 + 1e-9 && a.angular.abs() <= 0.5 + 1e-9,
            "{a:?}"
        );
        costs.push(mppi.last_cost());
        pose = integrate(pose, Action::new(a.linear, a.angular), 0.1);
        for u in &unknown {
            closest = closest.min((u.0 - pose.x).hypot(u.1 - pose.y) - radius);
        }
        steps += 1;
    }
    assert!(steps < 400, "did not arrive: {pose:?}");
    assert!(closest > 0.0, "touched the obstacle: {closest}");
    // A cost every cycle, finite: what the critics made of the chosen rollout.
    assert_eq!(costs.len(), steps);
    assert!(costs.iter().all(|c| c.is_finite()));
}
