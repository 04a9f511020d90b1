//! Every hyperparameter of training, with documented defaults.
//!
//! The TD3 defaults are the TD3 authors' current reference implementation (Fujimoto et al.,
//! `TD3.py`): 256-256 hidden units, learning rate 3e-4, batch 256, γ 0.99, τ 0.005, policy noise
//! 0.2 clipped at 0.5, policy delay 2, exploration N(0, 0.1). The regularisers β1, β2 are the
//! paper's Eq. 18 (its §5.2 compares 0, 1 and 5). Noise scales are in the network's action
//! space (linear in [0, 1], angular in [-1, 1]).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Why a training configuration file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigFileError {
    /// The file could not be read.
    #[error("cannot read the training configuration {}: {error}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why (in the message, not a `source`, so that it is printed once).
        error: std::io::Error,
    },
    /// It is not JSON, or a key is unknown or of the wrong type (the message names it).
    #[error("invalid training configuration {}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// The TD3 learner.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Td3Config {
    /// Hidden layer widths of the actor and of each critic.
    pub hidden: Vec<usize>,
    /// Adam learning rate of the actor.
    pub actor_lr: f64,
    /// Adam learning rate of the critics.
    pub critic_lr: f64,
    /// Transitions per gradient step.
    pub batch_size: usize,
    /// Discount γ.
    pub gamma: f64,
    /// Polyak rate τ of the target networks.
    pub tau: f64,
    /// Standard deviation of the target policy smoothing noise (Eq. 14's σ).
    pub policy_noise: f64,
    /// Clip of the target policy smoothing noise (Eq. 14's ε_max).
    pub noise_clip: f64,
    /// Critic updates per actor (and target) update.
    pub policy_delay: u32,
    /// Standard deviation of the exploration noise added to the actor's output.
    pub exploration_noise: f64,
    /// Eq. 18's β1: pushes the linear speed towards its maximum.
    pub beta1: f64,
    /// Eq. 18's β2: pushes the angular speed towards zero.
    pub beta2: f64,
    /// Rewards are multiplied by this before the critics see them (Eq. 1's ±100 would give
    /// targets in the hundreds; the optimal policy is unchanged). Eq. 18's β terms are
    /// multiplied by it too, so that β keeps the paper's meaning relative to unscaled returns:
    /// without that, β = 1 with rewards scaled by 0.1 acts like β = 10 and the actor learns to
    /// drive straight at full speed into walls.
    pub reward_scale: f64,
    /// TD3+BC's α (Fujimoto & Gu 2021): when positive, the actor maximises
    /// `α·Q / mean|Q| − (π(s) − a*)²`, `a*` the classical follower's action in `s`, so the
    /// policy improves on the demonstrator where the critic says so and stays near it
    /// elsewhere. 0 is the paper's actor objective (Eq. 18).
    pub bc_alpha: f64,
    /// Whether the actor learns a correction to the classical follower steering at the goal
    /// ([`crate::observation::Residual`]) rather than the whole command: it starts as the
    /// follower drives, and the exported policy carries the base in its metadata.
    pub residual: bool,
    /// The classical controller a residual actor corrects: the follower (rotate-then-go), or
    /// Regulated Pure Pursuit steering at the goal (arcs instead of turns on the spot).
    pub residual_base: ResidualBase,
}

/// The base of a residual actor ([`Td3Config::residual_base`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ResidualBase {
    /// [`crate::observation::Residual::follower`] of the follower's defaults.
    #[default]
    Follower,
    /// [`crate::observation::Residual::rpp`] of Nav2's defaults for the paper's robot.
    Rpp,
}

impl ResidualBase {
    /// The base.
    pub fn residual(self) -> crate::observation::Residual {
        match self {
            ResidualBase::Follower => {
                crate::observation::Residual::follower(&sim::follower::FollowerParams::default())
            }
            ResidualBase::Rpp => crate::observation::Residual::rpp(&sim::RppParams::default()),
        }
    }
}

impl Default for Td3Config {
    fn default() -> Self {
        Self {
            hidden: vec![256, 256],
            actor_lr: 3e-4,
            critic_lr: 3e-4,
            batch_size: 256,
            gamma: 0.99,
            tau: 0.005,
            policy_noise: 0.2,
            noise_clip: 0.5,
            policy_delay: 2,
            exploration_noise: 0.1,
            beta1: 1.0,
            beta2: 1.0,
            reward_scale: 0.1,
            bc_alpha: 0.0,
            residual: false,
            residual_base: ResidualBase::Follower,
        }
    }
}

/// The training loop around the learner.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// The learner.
    pub td3: Td3Config,
    /// Seed of everything random: networks, environments, replay sampling, noise.
    pub seed: u64,
    /// Environments stepped together (one batched actor call per step).
    pub envs: usize,
    /// Replay buffer capacity, transitions.
    pub buffer_capacity: usize,
    /// Environment steps with uniformly random actions before the actor takes over.
    pub random_steps: u64,
    /// Gradient steps per environment step (summed over the batch of environments).
    pub updates_per_step: f64,
    /// Environment steps between evaluations.
    pub eval_every: u64,
    /// Start/goal pairs of the fixed evaluation set.
    pub eval_episodes: usize,
    /// Seed of the evaluation set (kept apart from the training seed, so that policies trained
    /// with different seeds are evaluated on the same missions).
    pub eval_seed: u64,
    /// Seconds between checkpoints (0: only at the end).
    pub checkpoint_every_s: f64,
    /// libtorch intra-op threads (0: libtorch's default). One is fastest for these small
    /// networks: with more, OpenMP threads wait on each other at every operation, and on a busy
    /// machine a training ran 7x slower with two threads than with one.
    pub threads: usize,
    /// Goal distances of training episodes, metres (min, max). Below the evaluation's 2 m too:
    /// a plan's waypoints can be half a metre apart.
    pub goal_distance: (f64, f64),
    /// Steps per episode before it is cut off (a truncation: the value is bootstrapped).
    pub max_episode_steps: u32,
    /// Pay Eq. 1's r_closer in proportion to the progress made (see
    /// `sim::RewardConfig::progress`); false is the paper's constant r_closer.
    pub progress_reward: bool,
    /// Charge Eq. 1's r_time per step instead of only on arrival (see
    /// `sim::RewardConfig::time_per_step`).
    pub time_per_step_reward: bool,
    /// Start with goals at most 2 m beyond the minimum distance and widen the range by 1 m
    /// whenever 60% of the last 100 training episodes reached their goal, up to
    /// `goal_distance`. Evaluation always uses the full range.
    pub curriculum: bool,
    /// People walking about in training, at most this many per 100 m² of free region (0:
    /// none). A curriculum on density: none at first; once the goal curriculum has reached its
    /// full range, a quarter of this more whenever 60% of the last 100 episodes reached their
    /// goal. The policy sees people only through its laser.
    pub people_density: f64,
    /// Weight of the heading term of the progress reward (`sim::RewardConfig::heading`).
    pub heading_reward: f64,
    /// Measure progress along the shortest path through the free region rather than in a
    /// straight line (`sim::RewardConfig::geodesic`).
    pub geodesic_reward: bool,
    /// Charge per second spent within 15 cm of an obstacle, at contact
    /// (`sim::RewardConfig::clearance`); 0: none. Measured with the fast preset (10 minutes
    /// each, side by side, `mentalsim bench edges` on the 11 shared maps): 2.0 gave 98.83% of
    /// edge rollouts with 4.51% near misses against 98.98% and 4.13% without, so it stays 0.
    pub clearance_reward: f64,
    /// Probability that an episode which reached its goal is followed by one from the same pose
    /// and velocity with a new goal (`sim::NavEnv::continue_random`), as when a plan's next
    /// waypoint is handed over; otherwise the next episode starts from rest somewhere else.
    pub chain_goals: f64,
    /// Eq. 1's r_time, per simulated second (`sim::RewardConfig::time`). Higher makes waiting
    /// near obstacles cost more than the collision it avoids, so a policy keeps moving.
    pub time_cost: f64,
    /// Environment steps at the start of the run driven by the classical follower with
    /// Gaussian noise of `demo_noise` on its actions (the executed, noisy action is stored, as
    /// in DART, so the buffer shows recoveries), before `random_steps` and the actor.
    pub demo_steps: u64,
    /// Standard deviation of that noise, in the network's action units.
    pub demo_noise: f64,
    /// Behaviour-cloning gradient steps of the actor on the demonstrations when they end
    /// ([`crate::td3::Learner::clone_step`]): the warm start.
    pub bc_steps: u64,
    /// Gradient steps of the critics alone after the warm start, before the actor moves.
    pub critic_warmup_steps: u64,
    /// Export the actor of the best periodic evaluation (success rate, then mean time) rather
    /// than the last one: TD3's policy can get worse with more training, and a longer run must
    /// not export a worse policy than it had. Snapshots live in memory: a resumed run chooses
    /// among those of its last session and its final actor.
    pub export_best: bool,
    /// Drive every training step behind the rehearsal's collision shield (`sim::shield`): the
    /// environment applies the shielded command, the buffer keeps the actor's own, so the
    /// policy learns what the shield will do to it in a validation (slowed or stopped when it
    /// skims walls) instead of meeting it first there.
    pub shielded: bool,
    /// Train only on goals the robot can drive to in a straight line (`sim::EnvConfig::
    /// goals_in_view`): the waypoints of a roadmap plan, which is what the policy drives
    /// between. False also draws goals behind walls, reachable only by detours the laser
    /// cannot show: a policy then learns to hesitate (spinning on the spot), and 10 minutes
    /// of training reached 69% of held-out goals in view against 96% with this on.
    pub goals_in_view: bool,
    /// In every other training environment the policy sees the point this far along the
    /// shortest path to its goal instead of the goal (`sim::EnvConfig::carrot_m`), as
    /// `hybrid_path` plans show it the carrot on their path, with goals anywhere in the free
    /// region: it learns to take corners at speed. 0: the goal everywhere.
    pub carrot_m: f64,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            td3: Td3Config::default(),
            seed: 1,
            envs: 8,
            buffer_capacity: 1_000_000,
            random_steps: 10_000,
            updates_per_step: 0.5,
            eval_every: 20_000,
            eval_episodes: 100,
            eval_seed: 20_261_122,
            checkpoint_every_s: 60.0,
            threads: 1,
            goal_distance: (0.5, 10.0),
            max_episode_steps: 400,
            progress_reward: true,
            time_per_step_reward: true,
            curriculum: true,
            people_density: 0.0,
            heading_reward: 0.5,
            geodesic_reward: true,
            clearance_reward: 0.0,
            chain_goals: 0.5,
            time_cost: 1.0,
            goals_in_view: true,
            carrot_m: 0.0,
            demo_steps: 0,
            demo_noise: 0.3,
            bc_steps: 0,
            critic_warmup_steps: 0,
            export_best: false,
            shielded: false,
        }
    }
}

impl TrainConfig {
    /// The configuration tuned for the 10-minute target on a 2-core CPU (`mentalsim train`'s
    /// default preset): the TD3 reference but 64-64 networks at learning rate 1e-3, one gradient
    /// step per environment step, exploration noise 0.3 and β1 = β2 = 0, warm-started from the
    /// classical follower: 50,000 steps of noisy demonstrations, 10,000 behaviour-cloning steps,
    /// 5,000 critic-only steps, then TD3. Small networks make more gradient steps per second,
    /// and on this machine more steps beat wider layers; β = 0 won the 12-minute comparison.
    /// Measured on every roadmap edge of the 11 shared maps after 10 minutes on 24 generated
    /// floors (`mentalsim bench edges`, one seed): the warm start 95.9% of edge rollouts, TD3
    /// from scratch 94.3%; TD3+BC (α = 2.5) 89.5%, because it keeps the follower's slowness
    /// and runs out of time on long edges, so `bc_alpha` stays 0 here. The actor is residual
    /// over the follower steering at the goal (`td3.residual`): 97.17% of edge rollouts
    /// against 95.96% without (30% fewer failures, the same 6.58 s mean edge time; the
    /// follower 99.63% at 9.15 s), and residual with TD3+BC (α = 2.5) 92.2%. Training behind
    /// the rehearsal's collision shield (`shielded`), as the policy is validated, then takes
    /// the residual policy from 97.17% to 99.44% at 6.40 s (near misses 3.5% → 7.0%).
    /// Plans drive the policy to the carrot on their path, so half the environments show it
    /// one (`carrot_m`, 1.2 m as `rehearsal::POLICY_CARROT_M`), over Regulated Pure Pursuit's
    /// steering (`td3.residual_base`), the base that drives those plans' handovers: one seed
    /// each, `mentalsim bench navigation` on the 11 shared maps in the empty building, 5.8%
    /// faster run by run than the same recipe without the carrot (standard error 1.4%), 4.0%
    /// faster than RPP where its twin was 2.8% slower (docs/benchmarks.md).
    pub fn fast() -> Self {
        Self {
            td3: Td3Config {
                hidden: vec![64, 64],
                residual: true,
                residual_base: ResidualBase::Rpp,
                actor_lr: 1e-3,
                critic_lr: 1e-3,
                exploration_noise: 0.3,
                beta1: 0.0,
                beta2: 0.0,
                ..Td3Config::default()
            },
            updates_per_step: 1.0,
            random_steps: 0,
            demo_steps: 50_000,
            demo_noise: 0.3,
            bc_steps: 10_000,
            critic_warmup_steps: 5_000,
            export_best: true,
            shielded: true,
            carrot_m: 1.2,
            ..Self::default()
        }
    }

    /// This configuration with every key of `json` put over it, recursing into objects (a
    /// file naming only `td3.beta1` keeps the other `td3` values). Unknown keys are errors.
    pub fn with_json(&self, json: serde_json::Value) -> Result<TrainConfig, String> {
        fn overlay(base: &mut serde_json::Value, top: serde_json::Value) {
            match (base, top) {
                (serde_json::Value::Object(b), serde_json::Value::Object(t)) => {
                    for (k, v) in t {
                        match b.get_mut(&k) {
                            Some(slot) => overlay(slot, v),
                            None => {
                                b.insert(k, v);
                            }
                        }
                    }
                }
                (slot, v) => *slot = v,
            }
        }
        if !json.is_object() {
            return Err("expected a JSON object".into());
        }
        let mut merged = serde_json::to_value(self).map_err(|e| e.to_string())?;
        overlay(&mut merged, json);
        serde_json::from_value(merged).map_err(|e| e.to_string())
    }

    /// This configuration with the JSON file at `path` put over it ([`TrainConfig::with_json`]).
    pub fn with_json_file(&self, path: &Path) -> Result<TrainConfig, ConfigFileError> {
        let invalid = |message: String| ConfigFileError::Invalid {
            path: path.to_owned(),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|error| ConfigFileError::Read {
            path: path.to_owned(),
            error,
        })?;
        let top: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| invalid(e.to_string()))?;
        self.with_json(top).map_err(invalid)
    }

    /// The first setting out of range, named.
    pub fn validate(&self) -> Result<(), String> {
        let t = &self.td3;
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let nonneg = |v: f64| v.is_finite() && v >= 0.0;
        let checks: [(bool, &str); 24] = [
            (
                !t.hidden.is_empty() && !t.hidden.contains(&0),
                "td3.hidden: at least one layer, no zero width",
            ),
            (pos(t.actor_lr), "td3.actor_lr must be positive"),
            (pos(t.critic_lr), "td3.critic_lr must be positive"),
            (t.batch_size > 0, "td3.batch_size must be at least 1"),
            (
                (0.0..=1.0).contains(&t.gamma),
                "td3.gamma must be in [0, 1]",
            ),
            (t.tau > 0.0 && t.tau <= 1.0, "td3.tau must be in (0, 1]"),
            (
                nonneg(t.policy_noise) && nonneg(t.noise_clip),
                "td3.policy_noise and td3.noise_clip must not be negative",
            ),
            (t.policy_delay > 0, "td3.policy_delay must be at least 1"),
            (
                nonneg(t.exploration_noise),
                "td3.exploration_noise must not be negative",
            ),
            (
                nonneg(t.beta1) && nonneg(t.beta2),
                "td3.beta1 and td3.beta2 must not be negative",
            ),
            (self.envs > 0, "envs must be at least 1"),
            (
                self.buffer_capacity >= t.batch_size,
                "buffer_capacity must hold at least one batch",
            ),
            (
                pos(self.updates_per_step),
                "updates_per_step must be positive",
            ),
            (
                self.eval_every > 0 && self.eval_episodes > 0,
                "eval_every and eval_episodes must be at least 1",
            ),
            (
                nonneg(self.checkpoint_every_s),
                "checkpoint_every_s must not be negative",
            ),
            (
                nonneg(self.goal_distance.0)
                    && self.goal_distance.1.is_finite()
                    && self.goal_distance.0 <= self.goal_distance.1
                    && self.goal_distance.1 > 0.0,
                "goal_distance must be (min, max) with 0 <= min <= max, max > 0",
            ),
            (
                self.max_episode_steps > 0,
                "max_episode_steps must be at least 1",
            ),
            (pos(t.reward_scale), "td3.reward_scale must be positive"),
            (nonneg(self.time_cost), "time_cost must not be negative"),
            (
                (0.0..=1.0).contains(&self.chain_goals),
                "chain_goals must be a probability in [0, 1]",
            ),
            (nonneg(t.bc_alpha), "td3.bc_alpha must not be negative"),
            (nonneg(self.demo_noise), "demo_noise must not be negative"),
            (
                nonneg(self.carrot_m)
                    && self.carrot_m <= 100.0
                    && (self.carrot_m == 0.0 || (self.progress_reward && self.geodesic_reward)),
                "carrot_m must lie in [0, 100] m, and needs progress_reward and geodesic_reward",
            ),
            (
                nonneg(self.people_density) && self.people_density <= 50.0,
                "people_density must lie in [0, 50] people per 100 m²",
            ),
        ];
        if let Some((_, msg)) = checks.iter().find(|(ok, _)| !ok) {
            return Err((*msg).to_owned());
        }
        self.check_upper_bounds()
    }

    /// Every count and size below a bound, so that a configuration cannot ask for more memory
    /// or time than a machine has (a job's configuration comes from a client).
    fn check_upper_bounds(&self) -> Result<(), String> {
        let t = &self.td3;
        let counts: [(&str, u64, u64); 13] = [
            ("td3.hidden (layers)", t.hidden.len() as u64, 8),
            (
                "td3.hidden (width)",
                t.hidden.iter().copied().max().unwrap_or(0) as u64,
                4096,
            ),
            ("td3.batch_size", t.batch_size as u64, 65_536),
            ("td3.policy_delay", u64::from(t.policy_delay), 1000),
            ("envs", self.envs as u64, 1024),
            ("buffer_capacity", self.buffer_capacity as u64, 10_000_000),
            ("random_steps", self.random_steps, 100_000_000),
            ("eval_every", self.eval_every, 100_000_000),
            ("eval_episodes", self.eval_episodes as u64, 10_000),
            ("threads", self.threads as u64, 256),
            (
                "max_episode_steps",
                u64::from(self.max_episode_steps),
                1_000_000,
            ),
            ("demo_steps", self.demo_steps, 100_000_000),
            (
                "bc_steps + critic_warmup_steps",
                self.bc_steps.saturating_add(self.critic_warmup_steps),
                10_000_000,
            ),
        ];
        if let Some((name, value, max)) = counts.iter().find(|(_, v, max)| v > max) {
            return Err(format!("{name} must be at most {max}, got {value}"));
        }
        let reals: [(&str, f64, f64); 11] = [
            ("td3.actor_lr", t.actor_lr, 1.0),
            ("td3.critic_lr", t.critic_lr, 1.0),
            ("td3.policy_noise", t.policy_noise, 10.0),
            ("td3.noise_clip", t.noise_clip, 10.0),
            ("td3.exploration_noise", t.exploration_noise, 10.0),
            ("td3.beta1", t.beta1, 1e6),
            ("td3.beta2", t.beta2, 1e6),
            ("td3.reward_scale", t.reward_scale, 1e6),
            ("td3.bc_alpha", t.bc_alpha, 1e6),
            ("updates_per_step", self.updates_per_step, 64.0),
            ("goal_distance (max)", self.goal_distance.1, 1000.0),
        ];
        if let Some((name, value, max)) = reals.iter().find(|(_, v, max)| *v > *max) {
            return Err(format!("{name} must be at most {max}, got {value}"));
        }
        let more: [(&str, f64, f64); 5] = [
            ("clearance_reward", self.clearance_reward.abs(), 1e6),
            ("checkpoint_every_s", self.checkpoint_every_s, 86_400.0),
            ("time_cost", self.time_cost, 1e6),
            ("heading_reward", self.heading_reward.abs(), 1e6),
            ("demo_noise", self.demo_noise, 10.0),
        ];
        match more
            .iter()
            .find(|(_, v, max)| !(v.is_finite() && *v <= *max))
        {
            Some((name, value, max)) => Err(format!("{name} must be at most {max}, got {value}")),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_values_are_named() {
        assert_eq!(TrainConfig::default().validate(), Ok(()));
        let mut c = TrainConfig::default();
        c.td3.tau = 0.0;
        assert!(c.validate().unwrap_err().contains("td3.tau"));
        let c = TrainConfig {
            envs: 0,
            ..TrainConfig::default()
        };
        assert!(c.validate().unwrap_err().contains("envs"));
        let parsed: Result<TrainConfig, _> = serde_json::from_str(r#"{"td3": {"gama": 0.9}}"#);
        assert!(parsed.unwrap_err().to_string().contains("gama"));
        let fast = TrainConfig::fast();
        assert_eq!(fast.validate(), Ok(()));
        let over = fast
            .with_json(serde_json::json!({"td3": {"beta1": 5.0}, "seed": 7}))
            .expect("a subset of the keys");
        assert_eq!((over.td3.beta1, over.seed), (5.0, 7));
        assert_eq!(
            over.td3.hidden,
            vec![64, 64],
            "the preset's other td3 values stay"
        );
        for (json, field) in [
            (serde_json::json!({"envs": 1_000_000_000u64}), "envs"),
            (
                serde_json::json!({"buffer_capacity": 1u64 << 40}),
                "buffer_capacity",
            ),
            (
                serde_json::json!({"td3": {"hidden": [1_000_000]}}),
                "td3.hidden",
            ),
            (
                serde_json::json!({"td3": {"batch_size": 100_000}}),
                "td3.batch_size",
            ),
            (
                serde_json::json!({"updates_per_step": 1e9}),
                "updates_per_step",
            ),
            (
                serde_json::json!({"heading_reward": 1e300}),
                "heading_reward",
            ),
        ] {
            let c = fast.with_json(json).expect("parses");
            let err = c.validate().unwrap_err();
            assert!(err.contains(field) && err.contains("at most"), "{err}");
        }
        let err = fast
            .with_json(serde_json::json!({"td3": {"gama": 0.9}}))
            .unwrap_err();
        assert!(err.contains("gama"), "{err}");
        assert!(fast.with_json(serde_json::json!([1])).is_err());
    }
}
