//! TD3 (Fujimoto et al. 2018) as the paper's Algorithm 1: an actor and twin critics with target
//! networks, target policy smoothing with clipped noise (Eq. 14), clipped double-Q targets
//! (Eq. 15–17), delayed policy updates with the regularised objective of Eq. 18, and Polyak
//! averaging of the targets.
//!
//! Adam is written here rather than taken from tch: libtorch's optimiser state cannot be read
//! out through tch, and a checkpoint must hold it for a resumed run to continue exactly.

use std::path::Path;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use tch::nn::{self, Module};
use tch::{Device, Kind, Tensor};

use crate::config::Td3Config;
use crate::observation::{ACTION_DIM, Residual, Scaling};
use crate::replay::Batch;

/// Why the learner failed.
#[derive(Debug, thiserror::Error)]
pub enum LearnerError {
    /// libtorch refused an operation.
    #[error("libtorch: {0}")]
    Torch(#[from] tch::TchError),
    /// A checkpoint does not fit this learner.
    #[error("learner checkpoint: {0}")]
    Checkpoint(String),
}

/// A multi-layer perceptron with ReLU between layers, its linear layers named `layers.{i}`.
#[derive(Debug)]
struct Mlp {
    layers: Vec<nn::Linear>,
}

impl Mlp {
    fn new(path: &nn::Path<'_>, inputs: usize, hidden: &[usize], outputs: usize) -> Mlp {
        let mut widths = vec![inputs];
        widths.extend(hidden);
        widths.push(outputs);
        let layers = widths
            .windows(2)
            .enumerate()
            .map(|(i, w)| {
                nn::linear(
                    path / "layers" / i,
                    to_i64(w[0]),
                    to_i64(w[1]),
                    nn::LinearConfig::default(),
                )
            })
            .collect();
        Mlp { layers }
    }

    fn forward(&self, x: &Tensor) -> Tensor {
        let mut h = self.layers[0].forward(x);
        for layer in &self.layers[1..] {
            h = layer.forward(&h.relu());
        }
        h
    }
}

#[allow(clippy::cast_possible_wrap, reason = "layer widths are small")]
fn to_i64(v: usize) -> i64 {
    v as i64
}

/// The actor's squashing: sigmoid for the linear speed, tanh for the angular one.
fn squash(raw: &Tensor) -> Tensor {
    Tensor::cat(
        &[raw.narrow(1, 0, 1).sigmoid(), raw.narrow(1, 1, 1).tanh()],
        1,
    )
}

/// Adam with bias correction, its state kept as tensors a checkpoint can hold.
#[derive(Debug)]
struct Adam {
    params: Vec<Tensor>,
    m: Vec<Tensor>,
    v: Vec<Tensor>,
    step: u64,
    lr: f64,
    beta1: f64,
    beta2: f64,
    eps: f64,
}

impl Adam {
    fn new(params: Vec<Tensor>, lr: f64) -> Adam {
        let m = params.iter().map(Tensor::zeros_like).collect();
        let v = params.iter().map(Tensor::zeros_like).collect();
        Adam {
            params,
            m,
            v,
            step: 0,
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        }
    }

    fn zero_grad(&mut self) {
        for p in &mut self.params {
            let mut g = p.grad();
            if g.defined() {
                let _ = g.detach_().zero_();
            }
        }
    }

    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_possible_wrap,
        reason = "step counts fit"
    )]
    fn step(&mut self) {
        self.step += 1;
        let t = self.step.min(i32::MAX as u64) as i32;
        let bc1 = 1.0 - self.beta1.powi(t);
        let bc2 = 1.0 - self.beta2.powi(t);
        let step_size = self.lr / bc1;
        let bc2_sqrt = bc2.sqrt();
        tch::no_grad(|| {
            for ((p, m), v) in self.params.iter_mut().zip(&mut self.m).zip(&mut self.v) {
                let g = p.grad();
                if !g.defined() {
                    continue;
                }
                let _ = m.lerp_(&g, 1.0 - self.beta1);
                *v *= self.beta2;
                let _ = v.addcmul_(&(&g * (1.0 - self.beta2)), &g);
                let denom = (v.sqrt() / bc2_sqrt) + self.eps;
                let _ = p.addcdiv_(&(&*m * -step_size), &denom);
            }
        });
    }
}

/// Statistics of one gradient step.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct UpdateStats {
    /// Sum of both critics' mean squared errors.
    pub critic_loss: f64,
    /// The actor's loss (negated Eq. 18), when this step updated the actor.
    pub actor_loss: Option<f64>,
    /// Mean of Q1 over the batch.
    pub q_mean: f64,
}

/// The TD3 learner: networks, targets, optimisers.
#[derive(Debug)]
pub struct Learner {
    config: Td3Config,
    obs_dim: usize,
    device: Device,
    actor_vs: nn::VarStore,
    actor: Mlp,
    actor_target_vs: nn::VarStore,
    actor_target: Mlp,
    critic_vs: nn::VarStore,
    q1: Mlp,
    q2: Mlp,
    critic_target_vs: nn::VarStore,
    q1_target: Mlp,
    q2_target: Mlp,
    actor_opt: Adam,
    critic_opt: Adam,
    polyak: Vec<(Tensor, Tensor)>,
    critic_params: Vec<Tensor>,
    action_low: Tensor,
    action_high: Tensor,
    updates: u64,
    /// The base a residual actor's outputs are added to, with the scaling its inputs have.
    residual: Option<(Residual, Scaling)>,
}

fn paired(target: &nn::VarStore, source: &nn::VarStore) -> Vec<(Tensor, Tensor)> {
    let src = source.variables();
    let mut pairs: Vec<(String, Tensor, Tensor)> = target
        .variables()
        .into_iter()
        .filter_map(|(name, t)| src.get(&name).map(|s| (name, t, s.shallow_clone())))
        .collect();
    pairs.sort_by(|a, b| a.0.cmp(&b.0));
    pairs.into_iter().map(|(_, t, s)| (t, s)).collect()
}

/// Variables of a store in name order (the order optimiser state is saved in).
fn sorted_variables(vs: &nn::VarStore) -> Vec<(String, Tensor)> {
    let mut v: Vec<_> = vs.variables().into_iter().collect();
    v.sort_by(|a, b| a.0.cmp(&b.0));
    v
}

impl Learner {
    /// A learner for observations of `obs_dim` values, its weights initialised from `seed`.
    pub fn new(config: Td3Config, obs_dim: usize, device: Device, seed: u64) -> Learner {
        #[allow(clippy::cast_possible_wrap, reason = "any bit pattern is a seed")]
        tch::manual_seed(seed as i64);
        let hidden = config.hidden.clone();
        let actor_vs = nn::VarStore::new(device);
        let actor = Mlp::new(&(actor_vs.root() / "actor"), obs_dim, &hidden, ACTION_DIM);
        let critic_vs = nn::VarStore::new(device);
        let q1 = Mlp::new(&(critic_vs.root() / "q1"), obs_dim + ACTION_DIM, &hidden, 1);
        let q2 = Mlp::new(&(critic_vs.root() / "q2"), obs_dim + ACTION_DIM, &hidden, 1);
        let mut actor_target_vs = nn::VarStore::new(device);
        let actor_target = Mlp::new(
            &(actor_target_vs.root() / "actor"),
            obs_dim,
            &hidden,
            ACTION_DIM,
        );
        let mut critic_target_vs = nn::VarStore::new(device);
        let q1_target = Mlp::new(
            &(critic_target_vs.root() / "q1"),
            obs_dim + ACTION_DIM,
            &hidden,
            1,
        );
        let q2_target = Mlp::new(
            &(critic_target_vs.root() / "q2"),
            obs_dim + ACTION_DIM,
            &hidden,
            1,
        );
        // Algorithm 1, line 2: the targets start as copies. Same names, so `copy` cannot fail.
        let _ = actor_target_vs.copy(&actor_vs);
        let _ = critic_target_vs.copy(&critic_vs);
        actor_target_vs.freeze();
        critic_target_vs.freeze();
        let mut polyak = paired(&actor_target_vs, &actor_vs);
        polyak.extend(paired(&critic_target_vs, &critic_vs));
        let actor_opt = Adam::new(
            sorted_variables(&actor_vs)
                .into_iter()
                .map(|(_, t)| t)
                .collect(),
            config.actor_lr,
        );
        let critic_params: Vec<Tensor> = sorted_variables(&critic_vs)
            .into_iter()
            .map(|(_, t)| t)
            .collect();
        let critic_opt = Adam::new(
            critic_params.iter().map(Tensor::shallow_clone).collect(),
            config.critic_lr,
        );
        let opts = (Kind::Float, device);
        Learner {
            obs_dim,
            device,
            actor_vs,
            actor,
            actor_target_vs,
            actor_target,
            critic_vs,
            q1,
            q2,
            critic_target_vs,
            q1_target,
            q2_target,
            actor_opt,
            critic_opt,
            polyak,
            critic_params,
            action_low: Tensor::from_slice(&[0.0f32, -1.0])
                .view([1, 2])
                .to_kind(opts.0)
                .to_device(device),
            action_high: Tensor::from_slice(&[1.0f32, 1.0])
                .view([1, 2])
                .to_device(device),
            updates: 0,
            residual: None,
            config,
        }
    }

    /// Makes the actor a residual one over `residual` (for inputs scaled by `scaling`): its
    /// raw outputs are added to the base's pre-activations, and its last layer is shrunk to
    /// nearly zero (the targets copied) so that it starts as the base drives. Call before
    /// training or loading a checkpoint.
    pub fn set_residual(&mut self, residual: Residual, scaling: Scaling) {
        self.residual = Some((residual, scaling));
        if let Some(last) = self.actor.layers.last_mut() {
            tch::no_grad(|| {
                let _ = last.ws.f_mul_scalar_(0.01);
                if let Some(bs) = &mut last.bs {
                    let _ = bs.zero_();
                }
            });
        }
        tch::no_grad(|| {
            for (t, s) in &mut self.polyak {
                t.copy_(s);
            }
        });
    }

    /// The residual base of the actor, if it has one.
    pub fn residual(&self) -> Option<Residual> {
        self.residual.map(|(r, _)| r)
    }

    /// An actor's squashed outputs for the tensor `x` of the rows `rows`.
    fn actor_out(&self, net: &Mlp, x: &Tensor, rows: &[f32]) -> Tensor {
        let raw = net.forward(x);
        match &self.residual {
            None => squash(&raw),
            Some((residual, scaling)) => {
                let base = residual.preactivations(scaling, rows, self.obs_dim);
                squash(&(raw + self.tensor(&base, ACTION_DIM)))
            }
        }
    }

    /// The configuration.
    pub fn config(&self) -> &Td3Config {
        &self.config
    }

    /// Gradient steps taken.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// The actor's outputs (linear in [0, 1], angular in [-1, 1]) for `n` inputs laid out
    /// row-major in `inputs`, written to `out` (`n × 2`). No gradient is recorded.
    pub fn act(&self, inputs: &[f32], n: usize, out: &mut Vec<f32>) {
        out.clear();
        if n == 0 {
            return;
        }
        let x = Tensor::from_slice(inputs)
            .view([to_i64(n), to_i64(self.obs_dim)])
            .to_device(self.device);
        let y = tch::no_grad(|| self.actor_out(&self.actor, &x, &inputs[..n * self.obs_dim]));
        let y = y.to_device(Device::Cpu).contiguous().view([-1]);
        out.extend(Vec::<f32>::try_from(&y).unwrap_or_else(|_| vec![0.0; n * ACTION_DIM]));
    }

    fn tensor(&self, v: &[f32], cols: usize) -> Tensor {
        Tensor::from_slice(v)
            .view([-1, to_i64(cols)])
            .to_device(self.device)
    }

    /// One gradient step on `batch` (Algorithm 1, lines 8–17). `rng` draws the target policy
    /// smoothing noise, so the whole step is reproducible from the trainer's random state.
    pub fn update(&mut self, batch: &Batch, rng: &mut ChaCha8Rng) -> UpdateStats {
        self.step(batch, rng, true)
    }

    /// A gradient step of the critics alone (the actor and the targets stay): after a warm
    /// start, so that the critics learn the cloned policy's values before they steer it.
    pub fn critic_update(&mut self, batch: &Batch, rng: &mut ChaCha8Rng) -> UpdateStats {
        self.step(batch, rng, false)
    }

    fn step(&mut self, batch: &Batch, rng: &mut ChaCha8Rng, with_actor: bool) -> UpdateStats {
        let c = &self.config;
        let s = self.tensor(&batch.obs, self.obs_dim);
        let a = self.tensor(&batch.actions, ACTION_DIM);
        let r = self.tensor(&batch.rewards, 1);
        let s2 = self.tensor(&batch.next_obs, self.obs_dim);
        let d = self.tensor(&batch.dones, 1);
        #[allow(clippy::cast_possible_truncation, reason = "noise is f32")]
        let noise: Vec<f32> = (0..batch.size * ACTION_DIM)
            .map(|_| {
                let z: f64 = rng.sample(StandardNormal);
                (z * c.policy_noise).clamp(-c.noise_clip, c.noise_clip) as f32
            })
            .collect();
        let noise = self.tensor(&noise, ACTION_DIM);

        // Lines 9–10: smoothed target actions (Eq. 14) and the clipped double-Q target (Eq. 15).
        let y = tch::no_grad(|| {
            let a2 = (self.actor_out(&self.actor_target, &s2, &batch.next_obs) + &noise)
                .maximum(&self.action_low)
                .minimum(&self.action_high);
            let sa2 = Tensor::cat(&[&s2, &a2], 1);
            let q = self
                .q1_target
                .forward(&sa2)
                .minimum(&self.q2_target.forward(&sa2));
            r + (1.0 - d) * q * c.gamma
        });
        // Lines 11–12: both critics regress on it (Eq. 16, 17).
        let sa = Tensor::cat(&[&s, &a], 1);
        let q1 = self.q1.forward(&sa);
        let q2 = self.q2.forward(&sa);
        let critic_loss =
            (&q1 - &y).square().mean(Kind::Float) + (&q2 - &y).square().mean(Kind::Float);
        self.critic_opt.zero_grad();
        critic_loss.backward();
        self.critic_opt.step();
        self.updates += 1;
        let mut stats = UpdateStats {
            critic_loss: critic_loss.double_value(&[]),
            actor_loss: None,
            q_mean: q1.mean(Kind::Float).double_value(&[]),
        };

        // Lines 13–16: every `policy_delay` steps, the actor ascends Eq. 18 and the targets move.
        if with_actor && self.updates.is_multiple_of(u64::from(c.policy_delay)) {
            for p in &self.critic_params {
                let _ = p.set_requires_grad(false);
            }
            let pi = self.actor_out(&self.actor, &s, &batch.obs);
            let q = self.q1.forward(&Tensor::cat(&[&s, &pi], 1));
            let linear = pi.narrow(1, 0, 1);
            let angular = pi.narrow(1, 1, 1);
            let regulariser = (linear - 1.0).square().mean(Kind::Float)
                * (c.beta1 * c.reward_scale)
                + angular.square().mean(Kind::Float) * (c.beta2 * c.reward_scale);
            let objective = if c.bc_alpha > 0.0 {
                // TD3+BC (Fujimoto & Gu 2021): λ·Q with λ = α / mean|Q| (so α means the same
                // whatever the scale of the returns), minus the squared distance to the
                // demonstrator's action in the same state.
                let lambda =
                    c.bc_alpha / (q.abs().mean(Kind::Float).detach().double_value(&[]) + 1e-6);
                let experts = self.tensor(&batch.experts, ACTION_DIM);
                q.mean(Kind::Float) * lambda
                    - (&pi - experts).square().mean(Kind::Float)
                    - regulariser
            } else {
                q.mean(Kind::Float) - regulariser
            };
            let actor_loss = -objective;
            self.actor_opt.zero_grad();
            actor_loss.backward();
            self.actor_opt.step();
            for p in &self.critic_params {
                let _ = p.set_requires_grad(true);
            }
            stats.actor_loss = Some(actor_loss.double_value(&[]));
            let tau = c.tau;
            tch::no_grad(|| {
                for (t, s) in &mut self.polyak {
                    let _ = t.lerp_(s, tau);
                }
            });
        }
        stats
    }

    /// One behaviour-cloning step of the actor alone: Adam on the mean squared distance between
    /// its actions and the demonstrator's (`batch.experts`). Returns the loss. Used to warm-start
    /// a policy from the classical follower before TD3 takes over.
    pub fn clone_step(&mut self, batch: &Batch) -> f64 {
        let s = self.tensor(&batch.obs, self.obs_dim);
        let experts = self.tensor(&batch.experts, ACTION_DIM);
        let pi = self.actor_out(&self.actor, &s, &batch.obs);
        let loss = (pi - experts).square().mean(Kind::Float);
        self.actor_opt.zero_grad();
        loss.backward();
        self.actor_opt.step();
        loss.double_value(&[])
    }

    /// Makes the target networks copies of the networks (after a warm start, so that the
    /// critics' targets use the cloned policy rather than the random initial one).
    pub fn sync_targets(&mut self) {
        tch::no_grad(|| {
            for (t, s) in &mut self.polyak {
                let _ = t.lerp_(s, 1.0);
            }
        });
    }

    /// The actor's linear layers as `(weight [out, in] row-major, bias)`, input layer first.
    pub fn actor_layers(&self) -> Vec<(Vec<f32>, Vec<f32>)> {
        self.actor
            .layers
            .iter()
            .map(|l| {
                let w = l.ws.to_device(Device::Cpu).contiguous().view([-1]);
                let w = Vec::<f32>::try_from(&w).unwrap_or_default();
                let b =
                    l.bs.as_ref()
                        .map(|b| {
                            Vec::<f32>::try_from(&b.to_device(Device::Cpu).contiguous())
                                .unwrap_or_default()
                        })
                        .unwrap_or_default();
                (w, b)
            })
            .collect()
    }

    /// Every network and target with the prefix its variables are saved under.
    fn networks(&self) -> [(&'static str, &nn::VarStore); 4] {
        [
            ("actor", &self.actor_vs),
            ("critic", &self.critic_vs),
            ("actor_target", &self.actor_target_vs),
            ("critic_target", &self.critic_target_vs),
        ]
    }

    /// Writes every network, target and optimiser moment to one safetensors file.
    pub fn save(&self, path: &Path) -> Result<(), LearnerError> {
        let mut named: Vec<(String, Tensor)> = Vec::new();
        for (prefix, vs) in self.networks() {
            for (name, t) in sorted_variables(vs) {
                named.push((format!("{prefix}/{name}"), t));
            }
        }
        for (prefix, opt) in [
            ("adam_actor", &self.actor_opt),
            ("adam_critic", &self.critic_opt),
        ] {
            for (i, (m, v)) in opt.m.iter().zip(&opt.v).enumerate() {
                named.push((format!("{prefix}/m/{i}"), m.shallow_clone()));
                named.push((format!("{prefix}/v/{i}"), v.shallow_clone()));
            }
            #[allow(clippy::cast_possible_wrap, reason = "step counts fit in i64")]
            named.push((
                format!("{prefix}/step"),
                Tensor::from_slice(&[opt.step as i64]),
            ));
        }
        #[allow(clippy::cast_possible_wrap, reason = "update counts fit in i64")]
        named.push(("updates".into(), Tensor::from_slice(&[self.updates as i64])));
        let tmp = path.with_extension("tmp");
        Tensor::write_safetensors(&named, &tmp)?;
        std::fs::rename(&tmp, path)
            .map_err(|e| LearnerError::Checkpoint(format!("{}: {e}", path.display())))?;
        Ok(())
    }

    /// Restores what [`Learner::save`] wrote into a learner built with the same configuration.
    pub fn load(&mut self, path: &Path) -> Result<(), LearnerError> {
        let tensors: std::collections::HashMap<String, Tensor> =
            Tensor::read_safetensors(path)?.into_iter().collect();
        let get = |name: &str| {
            tensors.get(name).ok_or_else(|| {
                LearnerError::Checkpoint(format!("{} has no `{name}`", path.display()))
            })
        };
        let restore = |dst: &Tensor, src: &Tensor, name: &str| -> Result<(), LearnerError> {
            if dst.size() != src.size() {
                return Err(LearnerError::Checkpoint(format!(
                    "`{name}` has shape {:?}, this learner {:?}: trained with other layer sizes",
                    src.size(),
                    dst.size()
                )));
            }
            tch::no_grad(|| dst.shallow_clone().copy_(&src.to_device(dst.device())));
            Ok(())
        };
        for (prefix, vs) in self.networks() {
            for (name, t) in sorted_variables(vs) {
                let key = format!("{prefix}/{name}");
                restore(&t, get(&key)?, &key)?;
            }
        }
        let scalar = |t: &Tensor| t.int64_value(&[0]);
        for (prefix, opt) in [
            ("adam_actor", &mut self.actor_opt),
            ("adam_critic", &mut self.critic_opt),
        ] {
            for i in 0..opt.m.len() {
                let (mk, vk) = (format!("{prefix}/m/{i}"), format!("{prefix}/v/{i}"));
                restore(&opt.m[i], get(&mk)?, &mk)?;
                restore(&opt.v[i], get(&vk)?, &vk)?;
            }
            #[allow(clippy::cast_sign_loss, reason = "saved from a u64")]
            {
                opt.step = scalar(get(&format!("{prefix}/step"))?) as u64;
            }
        }
        #[allow(clippy::cast_sign_loss, reason = "saved from a u64")]
        {
            self.updates = scalar(get("updates")?) as u64;
        }
        Ok(())
    }

    /// Every trainable parameter with its gradient after one update, for tests: `(name,
    /// gradient defined and non-zero)`.
    pub fn gradient_report(&mut self, batch: &Batch, rng: &mut ChaCha8Rng) -> Vec<(String, bool)> {
        // Make sure this step updates the actor too.
        let delay = u64::from(self.config.policy_delay);
        self.updates = (self.updates / delay + 1) * delay - 1;
        let _ = self.update(batch, rng);
        let mut out = Vec::new();
        for (prefix, vs) in [("actor", &self.actor_vs), ("critic", &self.critic_vs)] {
            for (name, t) in sorted_variables(vs) {
                let g = t.grad();
                let ok = g.defined() && g.abs().sum(Kind::Float).double_value(&[]) > 0.0;
                out.push((format!("{prefix}/{name}"), ok));
            }
        }
        out
    }
}
