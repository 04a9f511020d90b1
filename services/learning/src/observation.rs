//! How an observation of the simulator (or of a real robot) becomes the network's input, and
//! how the network's output becomes a velocity command. Training and every inference path use
//! these functions, and the exported policy's metadata records their constants, so a policy
//! behaves the same wherever it runs.

use serde::{Deserialize, Serialize};
use sim::{Action, Observation};

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
        }
    }
}

/// Inputs of the network: the ranges, then the goal distance, then the goal angle.
pub const GOAL_INPUTS: usize = 2;
/// Outputs of the network: linear speed in [0, 1], angular speed in [-1, 1].
pub const ACTION_DIM: usize = 2;

impl Scaling {
    /// Length of the network's input.
    pub fn input_len(&self) -> usize {
        self.beams + GOAL_INPUTS
    }

    /// Writes the network input for `obs` into `out` (of length [`Scaling::input_len`]).
    ///
    /// Ranges beyond the horizon (and non-finite ones: a laser that saw nothing) read as the
    /// horizon; the angle is divided by π.
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
        let a = if obs.goal_angle.is_finite() {
            obs.goal_angle / std::f32::consts::PI
        } else {
            0.0
        };
        out[self.beams] = d;
        out[self.beams + 1] = a.clamp(-1.0, 1.0);
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_are_bounded_whatever_the_sensor_says() {
        let s = Scaling {
            beams: 3,
            ..Scaling::default()
        };
        let obs = Observation {
            ranges: vec![f32::INFINITY, -1.0, 2.5],
            goal_distance: f32::NAN,
            goal_angle: 7.0,
        };
        let v = s.encode(&obs).expect("three ranges");
        assert_eq!(v, vec![1.0, 0.0, 0.5, 2.0, 1.0]);
        assert!(
            s.encode(&Observation {
                ranges: vec![1.0],
                ..obs
            })
            .is_none()
        );
    }

    #[test]
    fn commands_are_scaled_and_clamped() {
        let s = Scaling::default();
        let a = s.command([1.0, -1.0]);
        assert!((a.linear - 0.8).abs() < 1e-6 && (a.angular + 0.5).abs() < 1e-6);
        let a = s.command([2.0, 0.5]);
        assert!((a.linear - 0.8).abs() < 1e-6 && (a.angular - 0.25).abs() < 1e-6);
    }
}
