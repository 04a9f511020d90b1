//! Model Predictive Path Integral control (Williams, Aldrich, Theodorou, "Model Predictive Path
//! Integral Control: From Theory to Parallel Computation", JGCD 2017; Williams et al.,
//! "Information Theoretic MPC for Model-Based Reinforcement Learning", ICRA 2017) with the
//! critics of Nav2's `nav2_mppi_controller`, written from the papers and Nav2's parameter page
//! (docs.nav2.org "Model Predictive Path Integral Controller"), not from its code.
//!
//! Each control cycle: `batch_size` control sequences of `time_steps` steps are sampled around
//! the current optimal sequence (Gaussian noise, `vx_std`, `wz_std`), clamped to the robot's
//! limits and rolled out with the differential-drive model; every rollout is scored by the
//! critics (obstacles, path align, path follow, path angle, goal, prefer forward) plus the
//! information-theoretic control cost (`gamma`); the new optimal sequence is the softmax-weighted
//! mean of the samples (`temperature`); its first command is sent and the sequence shifted by
//! one step for the next cycle (warm start).
//!
//! Obstacles come from a map (the footprint clearance the simulation's world knows, Nav2's
//! static layer and inflation) and from points the laser sees that the map does not explain
//! (the obstacle layer): people.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use crate::kinematics::{integrate, wrap_angle};
use crate::track::PathTrack;
use crate::{Action, Pose2};

/// Settings of MPPI. [`MppiParams::for_robot`] gives Nav2's defaults scaled to a robot and the
/// simulator's control rate; each field names its source.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MppiParams {
    /// Step of the prediction model, s: the simulator's control period (Nav2 `model_dt`,
    /// default 0.05 for its 20 Hz controller: the controller's period).
    pub model_dt: f64,
    /// Steps of a rollout (Nav2 `time_steps`, default 56 × 0.05 s = 2.8 s: the same horizon at
    /// `model_dt`).
    pub time_steps: usize,
    /// Rollouts per cycle (Nav2 `batch_size`, default 1000).
    pub batch_size: usize,
    /// Linear sampling noise, m/s (Nav2 `vx_std`, default 0.2).
    pub vx_std: f64,
    /// Angular sampling noise, rad/s (Nav2 `wz_std`, default 0.4).
    pub wz_std: f64,
    /// Top forward speed, m/s (Nav2 `vx_max`, default 0.5: the robot's).
    pub vx_max: f64,
    /// Top reverse speed, m/s, negative (Nav2 `vx_min`, default -0.35 for `vx_max` 0.5: scaled).
    pub vx_min: f64,
    /// Angular limit, rad/s (Nav2 `wz_max`, default 1.9: the robot's).
    pub wz_max: f64,
    /// Softmax temperature λ (Nav2 `temperature`, default 0.3).
    pub temperature: f64,
    /// Weight of the control cost (Nav2 `gamma`, default 0.015).
    pub gamma: f64,
    /// Obstacles: weight near collision (Nav2 ObstaclesCritic `critical_weight`, default 20).
    pub critical_weight: f64,
    /// Obstacles: weight of the repulsion (Nav2 `repulsion_weight`, default 1.5).
    pub repulsion_weight: f64,
    /// Obstacles: cost of a rollout that collides (Nav2 `collision_cost`, default 100000).
    pub collision_cost: f64,
    /// Obstacles: footprint clearance under which the critical term applies, m (Nav2
    /// `collision_margin_distance`, default 0.1).
    pub collision_margin_distance: f64,
    /// Obstacles: footprint clearance under which repulsion applies, m (Nav2 costmap
    /// `inflation_radius` 0.55 for its 0.22 m robot: 0.33 m beyond the footprint).
    pub inflation_beyond_footprint: f64,
    /// Obstacles: within this of the goal only the collision terms apply, m (Nav2
    /// `near_goal_distance`, default 0.5).
    pub near_goal_distance: f64,
    /// Path align weight (Nav2 PathAlignCritic `cost_weight`, default 10).
    pub path_align_weight: f64,
    /// Path align: rollouts reaching fewer path points ahead than this are not judged (Nav2
    /// `offset_from_furthest`, default 20).
    pub path_align_offset: usize,
    /// Path align: every n-th rollout point is compared with the path (Nav2
    /// `trajectory_point_step`, default 4).
    pub path_align_point_step: usize,
    /// Path align: off when more than this share of the path ahead is blocked by what the map
    /// does not know (Nav2 `max_path_occupancy_ratio`, default 0.07).
    pub max_path_occupancy_ratio: f64,
    /// Path align, angle and prefer-forward are off within this of the goal, m (Nav2
    /// `threshold_to_consider`, default 0.5).
    pub near_goal_threshold: f64,
    /// Path follow weight (Nav2 PathFollowCritic `cost_weight`, default 5).
    pub path_follow_weight: f64,
    /// Path follow: target this many points beyond the furthest reached (Nav2
    /// `offset_from_furthest`, default 6).
    pub path_follow_offset: usize,
    /// Path follow off, goal critic on, within this of the goal, m (Nav2 PathFollowCritic and
    /// GoalCritic `threshold_to_consider`, default 1.4).
    pub goal_threshold: f64,
    /// Path angle weight (Nav2 PathAngleCritic `cost_weight`, default 2).
    pub path_angle_weight: f64,
    /// Path angle: target this many points beyond the furthest reached (default 4).
    pub path_angle_offset: usize,
    /// Path angle applies when the robot faces farther off than this, rad (Nav2
    /// `max_angle_to_furthest`, default 0.785).
    pub max_angle_to_furthest: f64,
    /// Goal weight (Nav2 GoalCritic `cost_weight`, default 5).
    pub goal_weight: f64,
    /// Prefer-forward weight (Nav2 PreferForwardCritic `cost_weight`, default 5).
    pub prefer_forward_weight: f64,
    /// How far ahead along the path the robot's closest point is searched for, m (the local
    /// costmap's half width, 1.5 m for Nav2's default 3 m).
    pub search_m: f64,
}

impl MppiParams {
    /// Nav2's defaults for a robot of top speeds `linear_max` (m/s) and `angular_max` (rad/s)
    /// controlled every `dt` seconds.
    pub fn for_robot(linear_max: f64, angular_max: f64, dt: f64) -> Self {
        let vx_scale = linear_max / 0.5;
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a horizon of a few seconds over a positive period: a small count"
        )]
        let time_steps = ((56.0 * 0.05 / dt).round() as usize).max(2);
        Self {
            model_dt: dt,
            time_steps,
            batch_size: 1000,
            vx_std: 0.2,
            wz_std: 0.4,
            vx_max: linear_max,
            vx_min: -0.35 * vx_scale,
            wz_max: angular_max,
            temperature: 0.3,
            gamma: 0.015,
            critical_weight: 20.0,
            repulsion_weight: 1.5,
            collision_cost: 100_000.0,
            collision_margin_distance: 0.1,
            inflation_beyond_footprint: 0.55 - crate::rpp::NAV2_DEFAULT_ROBOT_RADIUS_M,
            near_goal_distance: 0.5,
            path_align_weight: 10.0,
            path_align_offset: 20,
            path_align_point_step: 4,
            max_path_occupancy_ratio: 0.07,
            near_goal_threshold: 0.5,
            path_follow_weight: 5.0,
            path_follow_offset: 6,
            goal_threshold: 1.4,
            path_angle_weight: 2.0,
            path_angle_offset: 4,
            max_angle_to_furthest: 0.785,
            goal_weight: 5.0,
            prefer_forward_weight: 5.0,
            search_m: 1.5,
        }
    }
}

impl Default for MppiParams {
    /// The paper's robot (0.8 m/s, 0.5 rad/s) at the simulator's 0.1 s control period.
    fn default() -> Self {
        Self::for_robot(0.8, 0.5, 0.1)
    }
}

/// What the world looks like to MPPI in one cycle.
pub struct MppiWorld<'a> {
    /// Footprint clearance at a point from what the map knows, metres.
    pub clearance: &'a (dyn Fn(f64, f64) -> f64 + Sync),
    /// Points the laser sees that the map does not explain (people), world frame.
    pub unknown: &'a [(f64, f64)],
    /// The footprint's radius, metres.
    pub radius: f64,
}

/// The MPPI optimiser: the warm-started control sequence and its noise generator.
#[derive(Clone, Debug)]
pub struct Mppi {
    params: MppiParams,
    /// The optimal sequence: (linear, angular) per step.
    sequence: Vec<(f64, f64)>,
    rng: ChaCha8Rng,
    /// The last cycle's optimal-rollout cost.
    last_cost: f64,
}

/// One rollout's cost and whether it collides.
#[derive(Clone, Copy, Debug)]
struct Scored {
    cost: f64,
}

impl Mppi {
    /// An optimiser with `params`, its noise seeded with `seed`.
    pub fn new(params: MppiParams, seed: u64) -> Self {
        Self {
            params,
            sequence: vec![(0.0, 0.0); params.time_steps],
            rng: ChaCha8Rng::seed_from_u64(seed),
            last_cost: 0.0,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &MppiParams {
        &self.params
    }

    /// Forgets the optimal sequence (a new drive), reseeding the noise.
    pub fn reset(&mut self, seed: u64) {
        self.sequence = vec![(0.0, 0.0); self.params.time_steps];
        self.rng = ChaCha8Rng::seed_from_u64(seed);
    }

    /// The cost of the optimal sequence's rollout in the last cycle (the critics' sum).
    pub fn last_cost(&self) -> f64 {
        self.last_cost
    }

    /// One control cycle for a robot at `pose` on `track` (whose progress this updates): the
    /// command to send now.
    pub fn command(&mut self, pose: Pose2, track: &mut PathTrack, world: &MppiWorld<'_>) -> Action {
        let p = self.params;
        track.update(pose, p.search_m);
        let Some(goal) = track.end() else {
            return Action::default();
        };
        let t_steps = p.time_steps;
        let k = p.batch_size.max(1);
        // The path ahead that rollouts can reach, and what of it is blocked.
        let reach = p.vx_max * p.model_dt * t_steps as f64 + 1.0;
        let start = track.progress();
        let mut end = start;
        while end + 1 < track.points().len()
            && track.remaining_from(start) - track.remaining_from(end + 1) <= reach
        {
            end += 1;
        }
        let window = track.window(start, end);
        let blocked = window
            .iter()
            .filter(|q| {
                world
                    .unknown
                    .iter()
                    .any(|u| crate::norm(u.0 - q.0, u.1 - q.1) < world.radius)
            })
            .count();
        let occupancy = blocked as f64 / window.len().max(1) as f64;
        let to_goal = crate::norm(goal.0 - pose.x, goal.1 - pose.y);

        // Samples: noise around the optimal sequence, clamped.
        let nv = Normal::new(0.0, p.vx_std.max(1e-9)).ok();
        let nw = Normal::new(0.0, p.wz_std.max(1e-9)).ok();
        let mut samples: Vec<Vec<(f64, f64)>> = Vec::with_capacity(k);
        for s in 0..k {
            // The first sample is the optimal sequence itself (no noise), so a good plan
            // survives a bad draw.
            let seq = self
                .sequence
                .iter()
                .map(|&(v, w)| {
                    let (ev, ew) = if s == 0 {
                        (0.0, 0.0)
                    } else {
                        (
                            nv.map_or(0.0, |n| n.sample(&mut self.rng)),
                            nw.map_or(0.0, |n| n.sample(&mut self.rng)),
                        )
                    };
                    (
                        (v + ev).clamp(p.vx_min, p.vx_max),
                        (w + ew).clamp(-p.wz_max, p.wz_max),
                    )
                })
                .collect();
            samples.push(seq);
        }
        let previous = self.sequence.clone();
        let ctx = Ctx {
            p: &p,
            world,
            window,
            goal,
            to_goal,
            occupancy,
            pose,
            sequence: &previous,
        };
        // The furthest path point any rollout reaches (Nav2's furthest reached path point).
        let rollouts: Vec<Vec<Pose2>> = samples
            .iter()
            .map(|seq| {
                let mut q = pose;
                seq.iter()
                    .map(|&(v, w)| {
                        q = integrate(q, Action::new(v, w), p.model_dt);
                        q
                    })
                    .collect()
            })
            .collect();
        let furthest = rollouts
            .iter()
            .filter_map(|r| r.last())
            .map(|e| nearest_index(window, (e.x, e.y)))
            .max()
            .unwrap_or(0);
        let scores: Vec<Scored> = samples
            .iter()
            .zip(&rollouts)
            .map(|(seq, r)| ctx.score(seq, r, furthest))
            .collect();
        let best = scores.iter().map(|s| s.cost).fold(f64::INFINITY, f64::min);
        let weights: Vec<f64> = scores
            .iter()
            .map(|s| (-(s.cost - best) / p.temperature).exp())
            .collect();
        let total: f64 = weights.iter().sum();
        if total > 0.0 && total.is_finite() {
            for t in 0..t_steps {
                let (mut v, mut w) = (0.0, 0.0);
                for (seq, wt) in samples.iter().zip(&weights) {
                    v += wt * seq[t].0;
                    w += wt * seq[t].1;
                }
                self.sequence[t] = (v / total, w / total);
            }
        }
        // The optimal sequence's own cost, for reports.
        let mut q = pose;
        let optimal: Vec<Pose2> = self
            .sequence
            .iter()
            .map(|&(v, w)| {
                q = integrate(q, Action::new(v, w), p.model_dt);
                q
            })
            .collect();
        self.last_cost = ctx.score(&self.sequence, &optimal, furthest).cost;
        let first = self.sequence[0];
        // Warm start: shift by one step, repeating the last.
        self.sequence.rotate_left(1);
        let repeat = self.sequence[t_steps.saturating_sub(2)];
        if let Some(last) = self.sequence.last_mut() {
            *last = repeat;
        }
        Action::new(first.0, first.1)
    }
}

/// What scoring a rollout needs.
struct Ctx<'a> {
    p: &'a MppiParams,
    world: &'a MppiWorld<'a>,
    window: &'a [(f64, f64)],
    goal: (f64, f64),
    to_goal: f64,
    occupancy: f64,
    pose: Pose2,
    sequence: &'a [(f64, f64)],
}

impl Ctx<'_> {
    fn score(&self, seq: &[(f64, f64)], rollout: &[Pose2], furthest: usize) -> Scored {
        let p = self.p;
        let n = rollout.len().max(1) as f64;
        let mut cost = 0.0;
        // Control cost: γ u·ε / σ² (the information-theoretic term).
        for ((v, w), (u, uw)) in seq.iter().zip(self.sequence) {
            cost += p.gamma
                * (u * (v - u) / (p.vx_std * p.vx_std) + uw * (w - uw) / (p.wz_std * p.wz_std));
        }
        // Obstacles.
        let near_goal = self.to_goal < p.near_goal_distance;
        let (mut critical, mut repulsive) = (0.0, 0.0);
        for q in rollout {
            let mut c = (self.world.clearance)(q.x, q.y);
            for u in self.world.unknown {
                c = c.min(crate::norm(u.0 - q.x, u.1 - q.y) - self.world.radius);
            }
            if c < 0.0 {
                return Scored {
                    cost: cost + p.collision_cost,
                };
            }
            if c < p.collision_margin_distance {
                critical += p.collision_margin_distance - c;
            }
            if !near_goal && c < p.inflation_beyond_footprint {
                repulsive += p.inflation_beyond_footprint - c;
            }
        }
        cost += p.critical_weight * critical + p.repulsion_weight * repulsive / n;
        // Goal.
        if self.to_goal < p.goal_threshold {
            let d: f64 = rollout
                .iter()
                .map(|q| crate::norm(q.x - self.goal.0, q.y - self.goal.1))
                .sum();
            cost += p.goal_weight * d / n;
        }
        // Prefer forward.
        if self.to_goal >= p.near_goal_threshold {
            let back: f64 = seq.iter().map(|(v, _)| (-v).max(0.0) * p.model_dt).sum();
            cost += p.prefer_forward_weight * back;
        }
        if self.window.is_empty() {
            return Scored { cost };
        }
        let last = self.window.len() - 1;
        // Path follow: the rollout's end towards the point beyond the furthest reached.
        if self.to_goal >= p.goal_threshold
            && let Some(end) = rollout.last()
        {
            let target = self.window[(furthest + p.path_follow_offset).min(last)];
            cost += p.path_follow_weight * crate::norm(end.x - target.0, end.y - target.1);
        }
        // Path align: distance of the rollout's points to the path, once on it.
        if self.to_goal >= p.near_goal_threshold
            && furthest >= p.path_align_offset.min(last)
            && self.occupancy <= p.max_path_occupancy_ratio
        {
            let upto = &self.window[..=furthest.min(last)];
            let (mut sum, mut count) = (0.0, 0usize);
            for q in rollout.iter().step_by(p.path_align_point_step.max(1)) {
                let d = upto
                    .iter()
                    .map(|w| crate::norm(w.0 - q.x, w.1 - q.y))
                    .fold(f64::INFINITY, f64::min);
                sum += d;
                count += 1;
            }
            if count > 0 {
                cost += p.path_align_weight * sum / count as f64;
            }
        }
        // Path angle: face the path ahead when the robot does not.
        if self.to_goal >= p.near_goal_threshold {
            let target = self.window[(furthest + p.path_angle_offset).min(last)];
            let now =
                wrap_angle((target.1 - self.pose.y).atan2(target.0 - self.pose.x) - self.pose.yaw);
            if now.abs() > p.max_angle_to_furthest {
                let a: f64 = rollout
                    .iter()
                    .map(|q| wrap_angle((target.1 - q.y).atan2(target.0 - q.x) - q.yaw).abs())
                    .sum();
                cost += p.path_angle_weight * a / n;
            }
        }
        Scored { cost }
    }
}

/// Index of the point of `path` closest to `p`.
fn nearest_index(path: &[(f64, f64)], p: (f64, f64)) -> usize {
    path.iter()
        .enumerate()
        .min_by(|a, b| {
            let da = crate::norm(a.1.0 - p.0, a.1.1 - p.1);
            let db = crate::norm(b.1.0 - p.0, b.1.1 - p.1);
            da.total_cmp(&db)
        })
        .map_or(0, |(i, _)| i)
}
