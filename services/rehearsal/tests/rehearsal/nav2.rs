//! Nav2's controllers and recoveries in the rehearsal, driven in real worlds.

use std::sync::Arc;

use prm::Point2;
use rehearsal::{
    ClassicalFollower, Controller, ControllerKind, DriveLimits, DriveRun, MppiController,
    RecoveryKind, RecoveryParams, RppController, env_config,
};
use sim::{
    Action, FloorMap, Observation, Occupancy, OccupancyGrid, Pose2, RobotSpec, World, WorldSpec,
};

/// An empty `w` x `h` metre room with a one-cell wall round it.
fn open_room(w: f64, h: f64) -> Arc<World> {
    let res = 0.05;
    let (cols, rows) = ((w / res).round() as usize, (h / res).round() as usize);
    let mut g = OccupancyGrid::filled(cols, rows, res, Pose2::new(0.0, 0.0, 0.0), Occupancy::Free);
    for r in 0..rows {
        for c in 0..cols {
            if r == 0 || c == 0 || r == rows - 1 || c == cols - 1 {
                g.cells[r * cols + c] = Occupancy::Occupied;
            }
        }
    }
    World::build(WorldSpec {
        id: "open-room".into(),
        floor: Some(FloorMap {
            id: "room".into(),
            grid: g,
            wall_height: 2.5,
            frame_id: "map".into(),
        }),
        walls: vec![],
        objects: vec![],
        robot: RobotSpec::example_differential(),
        people: Default::default(),
        notes: vec![],
    })
    .expect("the room builds")
}

fn limits(recoveries: Option<RecoveryParams>) -> DriveLimits {
    DriveLimits {
        waypoint_timeout_s: 15.0,
        max_replans: 0,
        sim_seed: 3,
        initial_velocity: Action::default(),
        stop: rehearsal::Stop::default(),
        trace: false,
        recoveries,
        others: None,
        holds: Vec::new(),
    }
}

fn run(
    world: &Arc<World>,
    controller: &mut dyn Controller,
    start: Pose2,
    leg: &[(f64, f64)],
    recoveries: Option<RecoveryParams>,
) -> DriveRun {
    run_among(world, controller, start, leg, limits(recoveries))
}

/// [`run`] with its limits given (other robots, holds).
fn run_among(
    world: &Arc<World>,
    controller: &mut dyn Controller,
    start: Pose2,
    leg: &[(f64, f64)],
    limits: DriveLimits,
) -> DriveRun {
    let mut env = env_config(23, false);
    if let Some(t) = controller.goal_tolerance() {
        env.goal_tolerance = t;
    }
    controller.attach(world, 23);
    controller.start_attempt(1);
    let leg: Vec<Point2> = leg.iter().map(|&(x, y)| Point2::new(x, y)).collect();
    rehearsal::drive(world, &env, start, &[leg], controller, limits, None).expect("drives")
}

/// Speeds between consecutive poses of a drive, m/s, with where each was.
fn speeds(run: &DriveRun) -> Vec<((f64, f64), f64)> {
    run.trajectory
        .windows(2)
        .map(|w| {
            (
                (w[1].x, w[1].y),
                (w[1].x - w[0].x).hypot(w[1].y - w[0].y) / 0.1,
            )
        })
        .collect()
}

#[test]
fn rpp_follows_a_straight_and_an_l_path_through_its_vertices_without_stopping() {
    let world = open_room(20.0, 12.0);
    // Straight, with a vertex half way: it keeps its cruise speed through it.
    let mut rpp = RppController::new();
    let straight = run(
        &world,
        &mut rpp,
        Pose2::new(3.0, 3.0, 0.0),
        &[(8.0, 3.0), (14.0, 3.0)],
        None,
    );
    assert_eq!(
        straight.outcome,
        rehearsal::AttemptOutcome::Reached,
        "{}",
        straight.reason
    );
    assert_eq!(straight.reached.len(), 2);
    let near_vertex: Vec<f64> = speeds(&straight)
        .into_iter()
        .filter(|(p, _)| (p.0 - 8.0).abs() < 1.0)
        .map(|(_, v)| v)
        .collect();
    assert!(!near_vertex.is_empty());
    assert!(
        near_vertex.iter().all(|&v| v > 0.7),
        "slowed at the vertex: {near_vertex:?}"
    );
    // An L: it turns while driving, never standing still before the goal, and beats the
    // rotate-then-go follower that stops at the corner.
    let mut rpp = RppController::new();
    let l = run(
        &world,
        &mut rpp,
        Pose2::new(3.0, 3.0, 0.0),
        &[(10.0, 3.0), (10.0, 9.0)],
        None,
    );
    assert_eq!(
        l.outcome,
        rehearsal::AttemptOutcome::Reached,
        "{}",
        l.reason
    );
    let v = speeds(&l);
    let moving_until_the_end = &v[..v.len() - 5];
    let slowest = moving_until_the_end
        .iter()
        .filter(|(p, _)| (p.0 - 10.0).hypot(p.1 - 3.0) < 1.5)
        .map(|(_, v)| *v)
        .fold(f64::INFINITY, f64::min);
    assert!(
        slowest > 0.1,
        "stopped at the corner: {slowest} {:?}",
        v.iter()
            .filter(|(p, _)| (p.0 - 10.0).hypot(p.1 - 3.0) < 1.5)
            .map(|(p, v)| format!("({:.2},{:.2}) {v:.2}", p.0, p.1))
            .collect::<Vec<_>>()
    );
    let mut follower = ClassicalFollower::default();
    let f = run(
        &world,
        &mut follower,
        Pose2::new(3.0, 3.0, 0.0),
        &[(10.0, 3.0), (10.0, 9.0)],
        None,
    );
    assert_eq!(
        f.outcome,
        rehearsal::AttemptOutcome::Reached,
        "{}",
        f.reason
    );
    assert!(
        l.time_s < f.time_s,
        "RPP {} s, follower {} s",
        l.time_s,
        f.time_s
    );
    assert_eq!(rpp.kind(), ControllerKind::Classical);
    assert!(rpp.description().contains("Regulated Pure Pursuit"));
}

#[test]
fn mppi_drives_round_a_wall_and_reports_its_cost_per_cycle() {
    // The room with the inner wall at x = 5 up to y = 6: round its end to the other side.
    let world = fixtures::worlds::walled_room();
    let mut mppi = MppiController::new(1);
    let r = run(
        &world,
        &mut mppi,
        Pose2::new(2.0, 2.0, 1.57),
        &[(2.5, 6.9), (7.5, 6.9), (8.0, 2.0)],
        None,
    );
    assert_eq!(
        r.outcome,
        rehearsal::AttemptOutcome::Reached,
        "{}",
        r.reason
    );
    assert!(r.min_clearance_m > 0.02);
    let c = mppi.cycles();
    assert!(c.cycles as f64 >= r.time_s / 0.1 - 1.0, "{c:?}");
    assert!(c.mean_ms() > 0.0 && c.max_s >= c.total_s / c.cycles as f64);
    assert!(c.mean_cost().is_finite() && c.mean_cost() > 0.0, "{c:?}");
    assert_eq!((c.batch_size, c.time_steps), (1000, 28));
}

/// A controller that will not move until a recovery has run (the executor hands it the path
/// again after one), then drives as the classical follower: a robot stuck until helped.
struct Balker {
    follower: ClassicalFollower,
    paths: u32,
}

impl Controller for Balker {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        if self.paths < 2 {
            Action::default()
        } else {
            self.follower.command(obs, pose, waypoint)
        }
    }
    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }
    fn description(&self) -> String {
        "balks until a recovery".into()
    }
    fn start_path(&mut self, _pose: Pose2, _path: &[Point2]) {
        self.paths += 1;
    }
}

#[test]
fn a_stalled_robot_waits_then_backs_up_and_reaches() {
    let world = open_room(12.0, 8.0);
    let balker = || Balker {
        follower: ClassicalFollower::default(),
        paths: 0,
    };
    // Without recoveries the timer runs out.
    let stuck = run(
        &world,
        &mut balker(),
        Pose2::new(3.0, 4.0, 0.0),
        &[(8.0, 4.0)],
        None,
    );
    assert_eq!(stuck.outcome, rehearsal::AttemptOutcome::Stalled);
    assert!(stuck.recoveries.is_empty());
    // With them: after 10 s without progress it waits 5 s, then drives on and arrives.
    let helped = run(
        &world,
        &mut balker(),
        Pose2::new(3.0, 4.0, 0.0),
        &[(8.0, 4.0)],
        Some(RecoveryParams::default()),
    );
    assert_eq!(
        helped.outcome,
        rehearsal::AttemptOutcome::Reached,
        "{}",
        helped.reason
    );
    assert_eq!(helped.recoveries.len(), 1, "{:?}", helped.recoveries);
    let e = &helped.recoveries[0];
    assert_eq!((e.kind, e.outcome.as_str()), (RecoveryKind::Wait, "done"));
    assert!((e.at_s - 10.0).abs() < 0.2, "{e:?}");
    assert!(helped.time_s > 15.0);
    assert!(
        helped.reason.contains("recoveries: wait at"),
        "{}",
        helped.reason
    );
    // Backing up first: the robot ends up behind its start before it drives on.
    let backed = run(
        &world,
        &mut balker(),
        Pose2::new(3.0, 4.0, 0.0),
        &[(8.0, 4.0)],
        Some(RecoveryParams {
            sequence: vec![RecoveryKind::BackUp],
            ..RecoveryParams::default()
        }),
    );
    assert_eq!(
        backed.outcome,
        rehearsal::AttemptOutcome::Reached,
        "{}",
        backed.reason
    );
    assert_eq!(backed.recoveries[0].kind, RecoveryKind::BackUp);
    let least_x = backed
        .trajectory
        .iter()
        .map(|p| p.x)
        .fold(f64::INFINITY, f64::min);
    assert!(
        (2.65..2.75).contains(&least_x),
        "backed up to x = {least_x}"
    );
    // Backing up stops short of a wall behind the robot.
    let walled = run(
        &world,
        &mut balker(),
        Pose2::new(0.55, 4.0, 0.0),
        &[(8.0, 4.0)],
        Some(RecoveryParams {
            sequence: vec![RecoveryKind::BackUp],
            ..RecoveryParams::default()
        }),
    );
    assert!(walled.min_clearance_m > 0.02, "{}", walled.reason);
    assert_eq!(
        walled.recoveries[0].outcome, "stopped short of a wall behind",
        "{:?}",
        walled.recoveries
    );
    // And short of another robot standing behind it (as Nav2's `BackUp` checks the costmap,
    // which holds what the sensors see): 0.15 m behind, where backing up 0.3 m would hit it.
    let radius = world.spec().robot.footprint_radius;
    let behind = sim::OtherRobots::new(vec![sim::OtherRobot {
        name: "behind".to_owned(),
        radius: 0.3,
        track: vec![
            (0.0, 3.0 - radius - 0.3 - 0.15, 4.0),
            (1000.0, 3.0 - radius - 0.45, 4.0),
        ],
    }])
    .expect("a robot behind");
    let robot_behind = run_among(
        &world,
        &mut balker(),
        Pose2::new(3.0, 4.0, 0.0),
        &[(8.0, 4.0)],
        DriveLimits {
            others: Some(Arc::new(behind)),
            ..limits(Some(RecoveryParams {
                sequence: vec![RecoveryKind::BackUp],
                ..RecoveryParams::default()
            }))
        },
    );
    assert_eq!(
        robot_behind.recoveries[0].outcome, "stopped short of a person or robot behind",
        "{}",
        robot_behind.reason
    );
    assert_ne!(
        robot_behind.outcome,
        rehearsal::AttemptOutcome::Collision,
        "{}",
        robot_behind.reason
    );
}

#[test]
fn among_people_a_drive_counts_intrusions_and_time_not_moving() {
    // Among people every drive counts intrusions into their space and the time not moving.
    let world = open_room(12.0, 8.0);
    let mut env = env_config(23, true);
    env.people = sim::PeopleConfig {
        count: Some(6),
        ..sim::PeopleConfig::default()
    };
    let mut rpp = RppController::new();
    rpp.attach(&world, 23);
    rpp.start_attempt(1);
    let r = rehearsal::drive(
        &world,
        &env,
        Pose2::new(1.0, 1.0, 0.0),
        &[vec![
            Point2::new(11.0, 7.0),
            Point2::new(1.0, 7.0),
            Point2::new(11.0, 1.0),
        ]],
        &mut rpp,
        limits(Some(RecoveryParams::default())),
        None,
    )
    .expect("drives");
    assert!(r.min_person_clearance_m.is_some());
    // Six people in 96 m² of room: the robot passes within 1.2 m of someone on a 34 m drive.
    assert!(
        r.social.personal_intrusions > 0,
        "{:?} {}",
        r.social,
        r.reason
    );
    assert!(r.social.time_not_moving_s <= r.time_s + 1e-9);
}

/// The classical follower held to a crawl, as a robot behind a person walking slowly its way.
struct Creeper(ClassicalFollower);

impl Controller for Creeper {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        let a = self.0.command(obs, pose, waypoint);
        Action {
            linear: a.linear.min(0.15),
            ..a
        }
    }
    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }
    fn description(&self) -> String {
        "creeps".into()
    }
}

/// Among people (with recoveries), a waypoint's timer runs from the robot's last approach to
/// it, as Nav2's progress checker counts progress: a robot crawling 6 m at 0.15 m/s (40 s, the
/// timer is 15 s) arrives, with no recovery; without recoveries the timer runs out as before.
#[test]
fn a_robot_crawling_towards_its_waypoint_is_not_timed_out_among_people() {
    let world = open_room(12.0, 8.0);
    let (start, leg) = (Pose2::new(3.0, 4.0, 0.0), [(9.0, 4.0)]);
    let timed_out = run(
        &world,
        &mut Creeper(ClassicalFollower::default()),
        start,
        &leg,
        None,
    );
    assert_eq!(timed_out.outcome, rehearsal::AttemptOutcome::Stalled);
    assert!(
        timed_out.reason.contains("not reached within 15 s"),
        "{}",
        timed_out.reason
    );
    let arrived = run(
        &world,
        &mut Creeper(ClassicalFollower::default()),
        start,
        &leg,
        Some(RecoveryParams::default()),
    );
    assert_eq!(
        arrived.outcome,
        rehearsal::AttemptOutcome::Reached,
        "{}",
        arrived.reason
    );
    assert!(arrived.time_s > 35.0, "{}", arrived.time_s);
    assert!(arrived.recoveries.is_empty(), "{:?}", arrived.recoveries);
}
