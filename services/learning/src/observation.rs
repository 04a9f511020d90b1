//! How an observation of the simulator (or of a real robot) becomes the network's input, and
//! how the network's output becomes a velocity command. Training and every inference path use
//! these functions, and the exported policy's metadata records their constants, so a policy
//! behaves the same wherever it runs.

use serde::{Deserialize, Serialize};
use sim::{Action, Observation};

/// Which values the network reads besides the ranges.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InputLayout {
    /// The paper's §4.1.1: goal distance and goal angle / π. Policies exported before the
    /// layout was recorded have it.
    #[default]
    Paper,
    /// Goal distance, sin and cos of the goal angle, and the odometry velocity (linear /
    /// `linear_max`, angular / `angular_max`). The angle's sine and cosine have no jump behind
    /// the robot, where ±π meet; the velocity tells the network what it is already doing, which
    /// a single scan cannot.
    Extended,
}

impl InputLayout {
    /// Number of inputs after the ranges.
    pub fn extra_inputs(self) -> usize {
        match self {
            InputLayout::Paper => 2,
            InputLayout::Extended => 5,
        }
    }

    /// Names of the inputs after the ranges, in order.
    pub fn names(self) -> &'static [&'static str] {
        match self {
            InputLayout::Paper => &[
                "goal_distance / goal_distance_scale_m, clipped",
                "goal_angle / pi (counter-clockwise, robot frame)",
            ],
            InputLayout::Extended => &[
                "goal_distance / goal_distance_scale_m, clipped",
                "sin(goal_angle) (counter-clockwise, robot frame)",
                "cos(goal_angle)",
                "odometry linear speed / linear_max, clipped to [-1, 1]",
                "odometry angular speed / angular_max, clipped to [-1, 1]",
            ],
        }
    }
}

/// The constants of the input and output scaling.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scaling {
    /// Number of laser ranges in an observation (the paper: 23).
    pub beams: usize,
    /// Laser ranges are clipped to this distance and divided by it, metres.
    pub range_horizon_m: f32,
    /// The goal distance is divided by this and clipped to `goal_distance_clip`, metres.
    pub goal_distance_scale_m: f32,
    /// Largest scaled goal distance.
    pub goal_distance_clip: f32,
    /// The linear speed for a network output of 1 (the paper: 0.8 m/s; the output is a
    /// sigmoid in [0, 1]).
    pub linear_max: f32,
    /// The angular speed for a network output of ±1 (the paper: 0.5 rad/s; the output is a tanh
    /// in [-1, 1]).
    pub angular_max: f32,
    /// The inputs after the ranges (absent in files of older policies: the paper's).
    #[serde(default)]
    pub layout: InputLayout,
}

impl Default for Scaling {
    fn default() -> Self {
        Self {
            beams: 23,
            range_horizon_m: 5.0,
            goal_distance_scale_m: 10.0,
            goal_distance_clip: 2.0,
            linear_max: 0.8,
            angular_max: 0.5,
            layout: InputLayout::Extended,
        }
    }
}

/// Outputs of the network: linear speed in [0, 1], angular speed in [-1, 1].
pub const ACTION_DIM: usize = 2;

impl Scaling {
    /// Length of the network's input.
    pub fn input_len(&self) -> usize {
        self.beams + self.layout.extra_inputs()
    }

    /// Writes the network input for `obs` into `out` (of length [`Scaling::input_len`]).
    ///
    /// Ranges beyond the horizon (and non-finite ones: a laser that saw nothing) read as the
    /// horizon; the rest follows the [`InputLayout`]. Every input is bounded, whatever the
    /// sensor says.
    pub fn encode_into(&self, obs: &Observation, out: &mut [f32]) {
        debug_assert_eq!(out.len(), self.input_len());
        let h = self.range_horizon_m;
        for (o, r) in out.iter_mut().zip(&obs.ranges) {
            let r = if r.is_finite() { r.clamp(0.0, h) } else { h };
            *o = r / h;
        }
        let d = if obs.goal_distance.is_finite() {
            (obs.goal_distance / self.goal_distance_scale_m).clamp(0.0, self.goal_distance_clip)
        } else {
            self.goal_distance_clip
        };
        let angle = if obs.goal_angle.is_finite() {
            obs.goal_angle
        } else {
            0.0
        };
        let rest = &mut out[self.beams..];
        rest[0] = d;
        match self.layout {
            InputLayout::Paper => {
                rest[1] = (angle / std::f32::consts::PI).clamp(-1.0, 1.0);
            }
            InputLayout::Extended => {
                let ratio = |v: f32, max: f32| {
                    if v.is_finite() && max > 0.0 {
                        (v / max).clamp(-1.0, 1.0)
                    } else {
                        0.0
                    }
                };
                let (sin, cos) = angle.sin_cos();
                rest[1] = sin;
                rest[2] = cos;
                rest[3] = ratio(obs.velocity[0], self.linear_max);
                rest[4] = ratio(obs.velocity[1], self.angular_max);
            }
        }
    }

    /// The network input for `obs`, or `None` if it has the wrong number of ranges.
    pub fn encode(&self, obs: &Observation) -> Option<Vec<f32>> {
        if obs.ranges.len() != self.beams {
            return None;
        }
        let mut v = vec![0.0; self.input_len()];
        self.encode_into(obs, &mut v);
        Some(v)
    }

    /// The velocity command for a network output (linear in [0, 1], angular in [-1, 1]).
    pub fn command(&self, output: [f32; ACTION_DIM]) -> Action {
        Action {
            linear: f64::from(output[0].clamp(0.0, 1.0) * self.linear_max),
            angular: f64::from(output[1].clamp(-1.0, 1.0) * self.angular_max),
        }
    }

    /// The observation an input row encodes, as far as the encoding keeps it: ranges beyond
    /// the horizon read as the horizon, the goal distance as clipped. What a monitor that
    /// reads observations (the collision shield) needs in training, where only inputs are kept.
    pub fn decode(&self, input: &[f32]) -> Observation {
        let beams = self.beams.min(input.len());
        let rest = &input[beams..];
        let at = |i: usize| rest.get(i).copied().unwrap_or(0.0);
        let (goal_angle, velocity) = match self.layout {
            InputLayout::Paper => (at(1) * std::f32::consts::PI, [0.0, 0.0]),
            InputLayout::Extended => (
                at(1).atan2(at(2)),
                [at(3) * self.linear_max, at(4) * self.angular_max],
            ),
        };
        Observation {
            ranges: input[..beams]
                .iter()
                .map(|r| r * self.range_horizon_m)
                .collect(),
            goal_distance: at(0) * self.goal_distance_scale_m,
            goal_angle,
            velocity,
        }
    }

    /// The network output that [`Scaling::command`] turns into `action` (clamped to the
    /// limits): how a demonstrator's command is written in the actor's units.
    #[allow(clippy::cast_possible_truncation, reason = "network outputs are f32")]
    pub fn output_of(&self, action: Action) -> [f32; ACTION_DIM] {
        [
            ((action.linear / f64::from(self.linear_max)) as f32).clamp(0.0, 1.0),
            ((action.angular / f64::from(self.angular_max)) as f32).clamp(-1.0, 1.0),
        ]
    }
}

/// A residual policy's base: a classical controller steering straight at the goal. The
/// network's two raw outputs are added to this base's command written as pre-activations
/// (the logit of the linear output, the inverse tanh of the angular one), so a network whose
/// last layer is near zero drives as the base does, and learning only has to find where to do
/// better (residual policy learning: Silver et al. 2018; Johannink et al. 2019). It reads only
/// the network's input, so every runtime can compute it. A policy file names its base by its
/// fields: the follower's, or Regulated Pure Pursuit's (Nav2's names).
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Residual {
    /// The classical follower: rotate-then-go, slowing down near the goal.
    Follower(FollowerBase),
    /// Nav2's Regulated Pure Pursuit on the straight line to the goal.
    Rpp(RppBase),
}

/// [`Residual::Follower`]: the classical follower's settings ([`sim::follower::follow`]).
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FollowerBase {
    /// The follower's top linear speed, m/s.
    pub linear_max: f64,
    /// Its top angular speed, rad/s.
    pub angular_max: f64,
    /// Heading error beyond which it turns on the spot, radians.
    pub rotate_threshold: f64,
    /// Its steering gain, (rad/s) per rad.
    pub heading_gain: f64,
    /// Its slowest forward speed while driving, m/s.
    pub linear_min: f64,
    /// Within this distance of the goal its speed falls in proportion, metres.
    pub slow_down_m: f64,
}

/// [`Residual::Rpp`]: Regulated Pure Pursuit's settings ([`sim::rpp_command`]), its look-ahead
/// the one it uses at cruise speed. It drives arcs instead of turning on the spot below
/// `rotate_to_heading_min_angle`, and slows only on tight arcs and near the goal.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RppBase {
    /// Cruise speed, m/s.
    pub desired_linear_vel: f64,
    /// The robot's angular limit, rad/s.
    pub angular_max: f64,
    /// Look-ahead distance, m.
    pub lookahead_dist: f64,
    /// Turn-in-place speed, rad/s.
    pub rotate_to_heading_angular_vel: f64,
    /// Heading error beyond which it turns on the spot, rad.
    pub rotate_to_heading_min_angle: f64,
    /// Radius below which curvature regulation slows the robot, m.
    pub regulated_linear_scaling_min_radius: f64,
    /// Slowest regulated speed, m/s.
    pub regulated_linear_scaling_min_speed: f64,
    /// Distance to the goal under which the robot slows to arrive, m.
    pub approach_velocity_scaling_dist: f64,
    /// Slowest approach speed, m/s.
    pub min_approach_linear_velocity: f64,
}

/// How far from 0 and 1 (linear) or ±1 (angular) the base is kept, so that its
/// pre-activation is finite and the network can still move it both ways.
const RESIDUAL_MARGIN: f32 = 0.02;

impl Residual {
    /// The base of the classical follower's settings.
    pub fn follower(p: &sim::follower::FollowerParams) -> Self {
        Self::Follower(FollowerBase {
            linear_max: p.linear_max,
            angular_max: p.angular_max,
            rotate_threshold: p.rotate_threshold,
            heading_gain: p.heading_gain,
            linear_min: p.linear_min,
            slow_down_m: p.slow_down_m,
        })
    }

    /// The base of Regulated Pure Pursuit's settings, at its look-ahead for cruise speed.
    pub fn rpp(p: &sim::RppParams) -> Self {
        Self::Rpp(RppBase {
            desired_linear_vel: p.desired_linear_vel,
            angular_max: p.angular_max,
            lookahead_dist: (p.desired_linear_vel * p.lookahead_time)
                .clamp(p.min_lookahead_dist, p.max_lookahead_dist),
            rotate_to_heading_angular_vel: p.rotate_to_heading_angular_vel,
            rotate_to_heading_min_angle: p.rotate_to_heading_min_angle,
            regulated_linear_scaling_min_radius: p.regulated_linear_scaling_min_radius,
            regulated_linear_scaling_min_speed: p.regulated_linear_scaling_min_speed,
            approach_velocity_scaling_dist: p.approach_velocity_scaling_dist,
            min_approach_linear_velocity: p.min_approach_linear_velocity,
        })
    }

    /// The base's command for a goal at `goal` in the robot frame (x ahead, y left).
    pub fn command(&self, goal: (f64, f64)) -> Action {
        match self {
            Residual::Follower(b) => {
                let params = sim::follower::FollowerParams {
                    linear_max: b.linear_max,
                    angular_max: b.angular_max,
                    rotate_threshold: b.rotate_threshold,
                    heading_gain: b.heading_gain,
                    linear_min: b.linear_min,
                    slow_down_m: b.slow_down_m,
                    ..sim::follower::FollowerParams::default()
                };
                sim::follower::follow(&params, (0.0, 0.0), goal, sim::Pose2::new(0.0, 0.0, 0.0))
            }
            Residual::Rpp(b) => {
                let params = sim::RppParams {
                    desired_linear_vel: b.desired_linear_vel,
                    angular_max: b.angular_max,
                    rotate_to_heading_angular_vel: b.rotate_to_heading_angular_vel,
                    rotate_to_heading_min_angle: b.rotate_to_heading_min_angle,
                    regulated_linear_scaling_min_radius: b.regulated_linear_scaling_min_radius,
                    regulated_linear_scaling_min_speed: b.regulated_linear_scaling_min_speed,
                    approach_velocity_scaling_dist: b.approach_velocity_scaling_dist,
                    min_approach_linear_velocity: b.min_approach_linear_velocity,
                    // Obstacles are the shield's and the network's to see.
                    cost_scaling_dist: 0.0,
                    ..sim::RppParams::default()
                };
                // The carrot: on the straight line to the goal, the look-ahead away (the goal
                // itself when nearer).
                let d = goal.0.hypot(goal.1);
                let carrot = if d > b.lookahead_dist {
                    let k = b.lookahead_dist / d;
                    (goal.0 * k, goal.1 * k)
                } else {
                    goal
                };
                sim::rpp_command(&params, carrot, d, f64::INFINITY).0
            }
        }
    }

    /// The base's command for one network input row, in output units (linear in [0, 1],
    /// angular in [-1, 1]).
    pub fn output(&self, scaling: &Scaling, input: &[f32]) -> [f32; ACTION_DIM] {
        let rest = &input[scaling.beams.min(input.len())..];
        let distance = f64::from(rest.first().copied().unwrap_or(0.0))
            * f64::from(scaling.goal_distance_scale_m);
        let angle = match scaling.layout {
            InputLayout::Paper => {
                f64::from(rest.get(1).copied().unwrap_or(0.0)) * std::f64::consts::PI
            }
            InputLayout::Extended => f64::from(rest.get(1).copied().unwrap_or(0.0))
                .atan2(f64::from(rest.get(2).copied().unwrap_or(1.0))),
        };
        let goal = (distance * angle.cos(), distance * angle.sin());
        scaling.output_of(self.command(goal))
    }

    /// [`Residual::output`] as the pre-activations the network's raw outputs are added to.
    pub fn preactivation(&self, scaling: &Scaling, input: &[f32]) -> [f32; ACTION_DIM] {
        let [linear, angular] = self.output(scaling, input);
        let m = RESIDUAL_MARGIN;
        let linear = linear.clamp(m, 1.0 - m);
        let angular = angular.clamp(-1.0 + m, 1.0 - m);
        [(linear / (1.0 - linear)).ln(), angular.atanh()]
    }

    /// [`Residual::preactivation`] of `rows` inputs of `width` values laid out row-major.
    pub fn preactivations(&self, scaling: &Scaling, inputs: &[f32], width: usize) -> Vec<f32> {
        inputs
            .chunks_exact(width.max(1))
            .flat_map(|row| self.preactivation(scaling, row))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_are_bounded_whatever_the_sensor_says() {
        let s = Scaling {
            beams: 3,
            layout: InputLayout::Paper,
            ..Scaling::default()
        };
        let obs = Observation {
            ranges: vec![f32::INFINITY, -1.0, 2.5],
            goal_distance: f32::NAN,
            goal_angle: 7.0,
            velocity: [f32::NAN, -9.0],
        };
        let v = s.encode(&obs).expect("three ranges");
        assert_eq!(v, vec![1.0, 0.0, 0.5, 2.0, 1.0]);
        let extended = Scaling {
            layout: InputLayout::Extended,
            ..s
        };
        let v = extended.encode(&obs).expect("three ranges");
        assert_eq!(v.len(), 8);
        assert_eq!(&v[..4], &[1.0, 0.0, 0.5, 2.0]);
        assert!((v[4] - 7.0f32.sin()).abs() < 1e-6 && (v[5] - 7.0f32.cos()).abs() < 1e-6);
        assert_eq!(&v[6..], &[0.0, -1.0]);
        assert!(
            s.encode(&Observation {
                ranges: vec![1.0],
                ..obs
            })
            .is_none()
        );
    }

    #[test]
    fn files_without_a_layout_are_read_as_the_papers() {
        let old = r#"{"beams":23,"range_horizon_m":5.0,"goal_distance_scale_m":10.0,
            "goal_distance_clip":2.0,"linear_max":0.8,"angular_max":0.5}"#;
        let s: Scaling = serde_json::from_str(old).expect("an old policy's scaling");
        assert_eq!(s.layout, InputLayout::Paper);
        assert_eq!(s.input_len(), 25);
        assert_eq!(Scaling::default().input_len(), 28);
    }

    #[test]
    fn commands_are_scaled_and_clamped() {
        let s = Scaling::default();
        let a = s.command([1.0, -1.0]);
        assert!((a.linear - 0.8).abs() < 1e-6 && (a.angular + 0.5).abs() < 1e-6);
        let a = s.command([2.0, 0.5]);
        assert!((a.linear - 0.8).abs() < 1e-6 && (a.angular - 0.25).abs() < 1e-6);
        assert_eq!(s.output_of(a), [1.0, 0.5]);
        assert_eq!(s.output_of(Action::new(-1.0, 9.0)), [0.0, 1.0]);
    }

    #[test]
    fn an_untrained_residual_policy_drives_as_the_follower() {
        let s = Scaling::default();
        let r = Residual::follower(&sim::follower::FollowerParams::default());
        let obs = |d: f32, angle: f32| Observation {
            ranges: vec![5.0; s.beams],
            goal_distance: d,
            goal_angle: angle,
            velocity: [0.0, 0.0],
        };
        // Goal ahead, far: full speed, no turn (within the margin).
        let input = s.encode(&obs(5.0, 0.0)).unwrap();
        let [l, a] = r.output(&s, &input);
        assert!((l - 1.0).abs() < 1e-6 && a.abs() < 1e-6, "{l} {a}");
        let [pl, pa] = r.preactivation(&s, &input);
        assert!((1.0 / (1.0 + (-pl).exp()) - 0.98).abs() < 1e-4 && pa.abs() < 1e-6);
        // Goal to the left, behind the threshold: turn left on the spot.
        let input = s.encode(&obs(3.0, 1.5)).unwrap();
        let [l, a] = r.output(&s, &input);
        assert!(l == 0.0 && (a - 1.0).abs() < 1e-6, "{l} {a}");
        // The same as the follower's own law for the goal's point.
        let input = s.encode(&obs(0.5, 0.2)).unwrap();
        let p = sim::follower::FollowerParams::default();
        let g = (0.5 * 0.2f64.cos(), 0.5 * 0.2f64.sin());
        let want = s.output_of(sim::follower::follow(
            &p,
            (0.0, 0.0),
            g,
            sim::Pose2::new(0.0, 0.0, 0.0),
        ));
        let got = r.output(&s, &input);
        assert!(
            (got[0] - want[0]).abs() < 1e-4 && (got[1] - want[1]).abs() < 1e-4,
            "{got:?} {want:?}"
        );
        assert_eq!(
            r.preactivations(&s, &[input.clone(), input].concat(), s.input_len())
                .len(),
            4
        );
    }

    #[test]
    fn an_untrained_rpp_residual_policy_drives_arcs_where_the_follower_turns_on_the_spot() {
        let s = Scaling::default();
        let r = Residual::rpp(&sim::RppParams::default());
        let out = |d: f32, angle: f32| {
            let input = s
                .encode(&Observation {
                    ranges: vec![5.0; s.beams],
                    goal_distance: d,
                    goal_angle: angle,
                    velocity: [0.0, 0.0],
                })
                .unwrap();
            r.output(&s, &input)
        };
        // Ahead, far: full speed.
        let [l, a] = out(5.0, 0.0);
        assert!((l - 1.0).abs() < 1e-6 && a.abs() < 1e-6, "{l} {a}");
        // 0.5 rad left, beyond the follower's 0.35 rad: an arc through the carrot 0.9 m away
        // (curvature 2 · 0.9 sin 0.5 / 0.81 ≈ 1.065 /m) at the speed the angular limit
        // allows, 0.5 / 1.065 ≈ 0.469 m/s.
        let [l, a] = out(5.0, 0.5);
        let k = 2.0 * 0.9 * 0.5f64.sin() / 0.81;
        assert!(
            (f64::from(l) * 0.8 - 0.5 / k).abs() < 1e-4 && (a - 1.0).abs() < 1e-6,
            "{l} {a}"
        );
        // Beyond 0.785 rad: on the spot.
        let [l, a] = out(3.0, -1.0);
        assert!(l == 0.0 && (a + 1.0).abs() < 1e-6, "{l} {a}");
        // 0.3 m ahead: the approach, 0.8 · 0.3 / 0.6 = 0.4 m/s.
        let [l, _] = out(0.3, 0.0);
        assert!((f64::from(l) * 0.8 - 0.4).abs() < 1e-4, "{l}");
        // Files name the base by its fields.
        let json = serde_json::to_string(&r).unwrap();
        assert!(json.contains("desired_linear_vel"), "{json}");
        assert_eq!(serde_json::from_str::<Residual>(&json).unwrap(), r);
        let f = Residual::follower(&sim::follower::FollowerParams::default());
        let json = serde_json::to_string(&f).unwrap();
        assert_eq!(serde_json::from_str::<Residual>(&json).unwrap(), f);
        assert!(serde_json::from_str::<Residual>(&json.replace("}", r#","x":1}"#)).is_err());
    }

    #[test]
    fn an_input_decodes_to_what_it_encodes() {
        let s = Scaling::default();
        let obs = Observation {
            ranges: (0..s.beams).map(|i| 0.3 + 0.2 * i as f32).collect(),
            goal_distance: 3.5,
            goal_angle: -2.0,
            velocity: [0.4, -0.2],
        };
        let back = s.decode(&s.encode(&obs).unwrap());
        for (a, b) in obs.ranges.iter().zip(&back.ranges) {
            assert!((a.min(s.range_horizon_m) - b).abs() < 1e-5, "{a} {b}");
        }
        assert!((back.goal_distance - 3.5).abs() < 1e-5);
        assert!((back.goal_angle + 2.0).abs() < 1e-5);
        assert!((back.velocity[0] - 0.4).abs() < 1e-5 && (back.velocity[1] + 0.2).abs() < 1e-5);
    }
}
