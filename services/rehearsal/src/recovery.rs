//! Recovery behaviours, as Nav2's behaviour server has them and its default behaviour tree
//! (`navigate_to_pose_w_replanning_and_recovery.xml`) tries them, for a robot that stalls
//! (beside a person standing still, most often): a progress checker (Nav2's
//! `SimpleProgressChecker`: the robot must move `required_movement_radius` within
//! `movement_time_allowance`) declares the controller stuck, and the drive tries the next
//! recovery in turn (round robin): wait, back up, spin, and re-route around the blocked edge
//! (a replan on the roadmap without the edges that pass the blocked spot), at most
//! `max_recoveries` times per drive (Nav2's `number_of_retries`). Nav2's costmap clearing has
//! nothing to clear here: the shield and the controllers keep no memory of old scans.
//!
//! Each recovery is recorded ([`RecoveryEvent`]) and the drive's report says what was tried.

use prm::Point2;
use sim::{Action, Pose2, World};

/// One recovery behaviour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RecoveryKind {
    /// Stand still for a while (Nav2 `Wait`): people walk round a robot that stands still.
    Wait,
    /// Drive backwards a little, straight (Nav2 `BackUp`), stopping where the map says the
    /// footprint would come too close to a wall (the laser sees only ahead).
    BackUp,
    /// Turn on the spot (Nav2 `Spin`), towards the side of the waypoint.
    Spin,
    /// Replan around the blocked spot ahead of the robot.
    Reroute,
}

impl RecoveryKind {
    /// `wait`, `back_up`, `spin` or `reroute`.
    pub fn as_str(self) -> &'static str {
        match self {
            RecoveryKind::Wait => "wait",
            RecoveryKind::BackUp => "back_up",
            RecoveryKind::Spin => "spin",
            RecoveryKind::Reroute => "reroute",
        }
    }
}

/// Settings of the recoveries; [`RecoveryParams::default`] gives Nav2's defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct RecoveryParams {
    /// The robot must move this far… (Nav2 `required_movement_radius`, default 0.5 m)
    pub required_movement_m: f64,
    /// …within this long, else it is stuck (Nav2 `movement_time_allowance`, default 10 s).
    pub movement_time_allowance_s: f64,
    /// The recoveries, tried in turn.
    pub sequence: Vec<RecoveryKind>,
    /// How long to wait, s (Nav2 default tree: `Wait wait_duration="5.0"`).
    pub wait_s: f64,
    /// How far to back up, m (Nav2 default tree: `BackUp backup_dist="0.30"`).
    pub backup_m: f64,
    /// How fast, m/s (Nav2 default tree: `backup_speed="0.15"`).
    pub backup_speed: f64,
    /// How far to spin, rad (Nav2 default tree: `Spin spin_dist="1.57"`).
    pub spin_rad: f64,
    /// Most recoveries per drive (Nav2 default tree: `number_of_retries="6"`).
    pub max_recoveries: u32,
    /// Around the blocked spot, edges passing closer than this are avoided by a re-route, m.
    pub reroute_radius_m: f64,
}

impl Default for RecoveryParams {
    fn default() -> Self {
        Self {
            required_movement_m: 0.5,
            movement_time_allowance_s: 10.0,
            sequence: vec![
                RecoveryKind::Wait,
                RecoveryKind::BackUp,
                RecoveryKind::Spin,
                RecoveryKind::Reroute,
            ],
            wait_s: 5.0,
            backup_m: 0.30,
            backup_speed: 0.15,
            spin_rad: 1.57,
            max_recoveries: 6,
            reroute_radius_m: 0.8,
        }
    }
}

/// One recovery tried in a drive.
#[derive(Clone, Debug, PartialEq)]
pub struct RecoveryEvent {
    /// Which.
    pub kind: RecoveryKind,
    /// Simulated time it started, s.
    pub at_s: f64,
    /// Where the robot stood.
    pub position: Point2,
    /// How it ended, in words (`done`, or why it stopped early).
    pub outcome: String,
}

/// Several recoveries in words: `wait at 12.3 s (done), back up at 20.1 s (done)`.
pub fn describe(events: &[RecoveryEvent]) -> String {
    events
        .iter()
        .map(|e| format!("{} at {:.1} s ({})", e.kind.as_str(), e.at_s, e.outcome))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A recovery under way.
#[derive(Clone, Debug)]
pub(crate) struct Active {
    pub(crate) kind: RecoveryKind,
    /// Control steps left before it ends anyway.
    pub(crate) steps_left: u64,
    /// Where it started.
    pub(crate) from: Pose2,
    /// Yaw turned so far (spin), rad.
    pub(crate) turned: f64,
    /// Turning direction (spin): +1 left, -1 right.
    pub(crate) direction: f64,
}

/// A footprint's clearance at a point, metres.
type Clearance<'a> = dyn Fn(f64, f64) -> f64 + 'a;

/// The closest the footprint may come to anything while backing up, metres (the shield's last-
/// moment guard, [`sim::shield::WALL_GUARD_M`]).
const BACKUP_GUARD_M: f64 = sim::shield::WALL_GUARD_M;

impl Active {
    /// The recovery `kind` starting at `pose`, its length in control steps of `dt` at most.
    pub(crate) fn start(
        kind: RecoveryKind,
        p: &RecoveryParams,
        pose: Pose2,
        bearing: f64,
        angular_max: f64,
        dt: f64,
    ) -> Self {
        let secs = match kind {
            RecoveryKind::Wait => p.wait_s,
            RecoveryKind::BackUp => p.backup_m / p.backup_speed.max(1e-3) + 1.0,
            RecoveryKind::Spin => p.spin_rad / angular_max.max(1e-3) + 1.0,
            RecoveryKind::Reroute => 0.0,
        };
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a few seconds over a positive period: a small count"
        )]
        let steps_left = (secs / dt.max(1e-3)).ceil().max(0.0) as u64;
        Self {
            kind,
            steps_left,
            from: pose,
            turned: 0.0,
            direction: if bearing < 0.0 { -1.0 } else { 1.0 },
        }
    }

    /// The command for this step at `pose`, or why the recovery ends (`Err("done")` when it
    /// did what it set out to do).
    /// `moving(x, y)`: the footprint's clearance there now to what moves (people, other
    /// robots): backing up keeps clear of them as of the map, as Nav2's `BackUp` checks its
    /// footprint against the costmap, which holds both.
    pub(crate) fn command(
        &mut self,
        p: &RecoveryParams,
        pose: Pose2,
        (world, moving): (&World, &Clearance<'_>),
        angular_max: f64,
        dt: f64,
    ) -> Result<Action, &'static str> {
        if self.steps_left == 0 {
            return Err(match self.kind {
                RecoveryKind::Wait => "done",
                _ => "out of time",
            });
        }
        self.steps_left -= 1;
        match self.kind {
            RecoveryKind::Wait | RecoveryKind::Reroute => Ok(Action::default()),
            RecoveryKind::BackUp => {
                let backed = (pose.x - self.from.x).hypot(pose.y - self.from.y);
                if backed >= p.backup_m {
                    return Err("done");
                }
                let command = Action::new(-p.backup_speed, 0.0);
                // The map's last moment, as the shield's wall guard: a step and a half ahead.
                let ahead = sim::kinematics::integrate(pose, command, 1.5 * dt);
                let walls = |x: f64, y: f64| world.clearance(x, y);
                let guards: [(&str, &Clearance<'_>); 2] = [
                    ("stopped short of a wall behind", &walls),
                    ("stopped short of a person or robot behind", moving),
                ];
                for (what, clearance) in guards {
                    let (now, then) = (clearance(pose.x, pose.y), clearance(ahead.x, ahead.y));
                    if then < BACKUP_GUARD_M + 0.02 && then < now {
                        return Err(what);
                    }
                }
                Ok(command)
            }
            RecoveryKind::Spin => {
                if self.turned >= p.spin_rad {
                    return Err("done");
                }
                self.turned += angular_max * dt;
                Ok(Action::new(0.0, self.direction * angular_max))
            }
        }
    }
}
