//! The collision shield: a monitor between a controller and the motors that keeps a round
//! differential robot from driving into what its laser sees. The rehearsal executor runs the
//! policy behind it, and training can run behind it too, so that a policy learns what the
//! shield will do to its commands.

use crate::{Action, Observation, World};

/// Closest the shield lets the footprint come to a laser return, metres (the simulation counts
/// a collision below 0.02 m).
pub const SHIELD_MARGIN_M: f64 = 0.06;
/// How far ahead the shield looks, seconds of the commanded motion.
pub const SHIELD_HORIZON_S: f64 = 1.5;
/// Forward speeds the shield tries, as shares of the wanted one, fastest first.
const SHIELD_SCALES: [f64; 6] = [1.0, 0.7, 0.45, 0.25, 0.1, 0.0];
/// Time step of the shield's look-ahead, seconds.
const SHIELD_STEP_S: f64 = 0.1;

/// A collision monitor for a differential robot with a round footprint: it rolls the wanted
/// command forward for [`SHIELD_HORIZON_S`] against the current laser returns and keeps the
/// fastest share of its forward speed that never brings the footprint closer than
/// [`SHIELD_MARGIN_M`] to a return it is approaching (moving along a wall, or away from it,
/// stays allowed). When even a crawl is unsafe the robot stops and turns on the spot (a
/// round robot cannot hit anything turning in place): towards the waypoint when it is off to
/// one side, else towards the side the laser sees more room on.
#[derive(Clone, Debug)]
pub struct Shield {
    /// The laser's origin in the robot frame, metres.
    origin: (f64, f64),
    /// Unit directions of the beams in the robot frame.
    dirs: Vec<(f64, f64)>,
    /// Returns at or beyond this range hit nothing.
    range_max: f64,
    /// The footprint's radius, metres.
    radius: f64,
}

impl Shield {
    /// The shield for the robot of `world` reading `beams` beams; `None` when its laser cannot
    /// give them.
    pub fn new(world: &World, beams: usize) -> Option<Self> {
        let robot = &world.spec().robot;
        let laser = &robot.laser;
        let dirs = laser
            .beam_angles(beams)?
            .into_iter()
            .map(|a| ((a + laser.mount.yaw).cos(), (a + laser.mount.yaw).sin()))
            .collect();
        Some(Self {
            origin: (laser.mount.x, laser.mount.y),
            dirs,
            range_max: laser.range_max,
            radius: robot.footprint_radius,
        })
    }

    /// The laser returns in the robot frame.
    fn returns(&self, obs: &Observation) -> Vec<(f64, f64)> {
        obs.ranges
            .iter()
            .zip(&self.dirs)
            .filter(|(r, _)| f64::from(**r) < self.range_max - 1e-3)
            .map(|(r, (c, s))| {
                let r = f64::from(*r);
                (self.origin.0 + r * c, self.origin.1 + r * s)
            })
            .collect()
    }

    /// Whether driving `command` for the horizon keeps the footprint clear of `points`.
    fn safe(&self, command: Action, points: &[(f64, f64)]) -> bool {
        self.keeps(command, points, SHIELD_MARGIN_M)
    }

    /// Whether driving `command` for the horizon keeps the footprint `margin` clear of what
    /// the laser sees (returns it is not approaching excepted), as the shield checks its own
    /// margin.
    pub fn keeps_margin(&self, command: Action, obs: &Observation, margin: f64) -> bool {
        let points = self.returns(obs);
        points.is_empty() || self.keeps(command, &points, margin)
    }

    fn keeps(&self, command: Action, points: &[(f64, f64)], margin: f64) -> bool {
        let gap = |x: f64, y: f64| {
            points
                .iter()
                .map(|(px, py)| (px - x).hypot(py - y))
                .fold(f64::INFINITY, f64::min)
                - self.radius
        };
        let now = gap(0.0, 0.0);
        let (mut x, mut y, mut yaw) = (0.0_f64, 0.0_f64, 0.0_f64);
        let mut t = 0.0;
        while t < SHIELD_HORIZON_S {
            x += command.linear * yaw.cos() * SHIELD_STEP_S;
            y += command.linear * yaw.sin() * SHIELD_STEP_S;
            yaw += command.angular * SHIELD_STEP_S;
            t += SHIELD_STEP_S;
            let g = gap(x, y);
            if g < margin && g < now - 1e-3 {
                return false;
            }
        }
        true
    }

    /// The command to send instead of `wanted`, given the observation and the angular limit.
    pub fn filter(&self, wanted: Action, obs: &Observation, angular_max: f64) -> Action {
        if wanted.linear <= 0.0 {
            return wanted;
        }
        let points = self.returns(obs);
        if points.is_empty() {
            return wanted;
        }
        for scale in SHIELD_SCALES {
            let command = Action {
                linear: wanted.linear * scale,
                angular: wanted.angular,
            };
            if scale > 0.0 && self.safe(command, &points) {
                return command;
            }
        }
        // Blocked: turn in place, towards the waypoint when it is to one side, else towards
        // the side with more room.
        let bearing = f64::from(obs.goal_angle);
        let side = if bearing.abs() > 0.2 {
            bearing.signum()
        } else {
            let room = |left: bool| -> f64 {
                obs.ranges
                    .iter()
                    .zip(&self.dirs)
                    .filter(|(_, (_, s))| (*s > 0.0) == left)
                    .map(|(r, _)| f64::from(*r))
                    .sum()
            };
            if room(true) >= room(false) { 1.0 } else { -1.0 }
        };
        Action {
            linear: 0.0,
            angular: side * angular_max,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn obs() -> Observation {
        Observation {
            ranges: vec![5.0; 23],
            goal_distance: 1.0,
            goal_angle: 0.0,
            velocity: [0.0; 2],
        }
    }

    /// A shield for a 0.2 m robot with 23 beams over the front half, laser at the centre.
    fn shield() -> Shield {
        Shield {
            origin: (0.0, 0.0),
            dirs: (0..23)
                .map(|i| {
                    let a = -PI / 2.0 + PI * f64::from(i) / 22.0;
                    (a.cos(), a.sin())
                })
                .collect(),
            range_max: 10.0,
            radius: 0.2,
        }
    }

    /// The ranges a laser at the origin sees with a wall `ahead` metres in front (x = ahead)
    /// and one `left` metres to the left (y = left), each `None` for no wall.
    #[allow(clippy::cast_possible_truncation, reason = "test ranges are small")]
    fn scan(s: &Shield, ahead: Option<f64>, left: Option<f64>) -> Observation {
        let ranges = s
            .dirs
            .iter()
            .map(|&(c, sn)| {
                let hit_ahead = ahead.filter(|_| c > 1e-9).map(|d| d / c);
                let hit_left = left.filter(|_| sn > 1e-9).map(|d| d / sn);
                [hit_ahead, hit_left]
                    .into_iter()
                    .flatten()
                    .fold(10.0_f64, f64::min) as f32
            })
            .collect();
        Observation { ranges, ..obs() }
    }

    #[test]
    fn the_shield_slows_and_stops_before_a_wall_but_not_along_one() {
        let s = shield();
        let go = Action::new(0.8, 0.0);
        // Open space: unchanged.
        assert_eq!(s.filter(go, &scan(&s, None, None), 0.5), go);
        // A wall 3 m ahead: 0.8 m/s for 1.5 s stays 1.6 m short of it.
        assert_eq!(s.filter(go, &scan(&s, Some(3.0), None), 0.5), go);
        // 1 m ahead: slower, still forward.
        let slowed = s.filter(go, &scan(&s, Some(1.0), None), 0.5);
        assert!(slowed.linear > 0.0 && slowed.linear < 0.8, "{slowed:?}");
        // 0.25 m ahead (5 cm from the footprint): stop and turn in place.
        let stopped = s.filter(go, &scan(&s, Some(0.25), None), 0.5);
        assert_eq!(stopped.linear, 0.0);
        assert_eq!(stopped.angular.abs(), 0.5);
        // Along a wall 4 cm from the footprint: driving parallel does not approach it.
        assert_eq!(s.filter(go, &scan(&s, None, Some(0.24)), 0.5), go);
        // Turning in place and reversing pass untouched.
        let turn = Action::new(0.0, 0.5);
        assert_eq!(s.filter(turn, &scan(&s, Some(0.25), None), 0.5), turn);
        // Blocked with the waypoint to the right: turns right.
        let right = Observation {
            goal_angle: -1.0,
            ..scan(&s, Some(0.25), None)
        };
        assert_eq!(s.filter(go, &right, 0.5).angular, -0.5);
    }
}
