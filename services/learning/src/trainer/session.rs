//! One training session, [`Trainer::run`]: the loop of Algorithm 1 (act, step, store, reset
//! finished episodes, gradient steps) with its evaluations and checkpoints.

use std::time::Instant;

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use sim::Outcome;

use super::{Budget, EpisodeRecord, Progress, TrainError, Trainer, outcome_name};
use crate::observation::ACTION_DIM;
use crate::replay::Batch;

/// The wall clock of one [`Trainer::run`]: the training seconds of earlier sessions plus this
/// session's.
struct SessionClock {
    start: Instant,
    wall_before: f64,
}

impl SessionClock {
    /// Training wall-clock seconds now, over all sessions.
    fn wall_s(&self) -> f64 {
        self.wall_before + self.start.elapsed().as_secs_f64()
    }
}

/// What one [`Trainer::run`] reuses from step to step: the actions, the demonstrator's labels,
/// an encoded next observation and a sampled batch.
struct StepScratch {
    /// Length of one encoded observation.
    dim: usize,
    /// Every environment's action, `ACTION_DIM` values each.
    actions: Vec<f32>,
    /// One environment's next observation, encoded.
    next: Vec<f32>,
    /// The demonstrator's action in every environment's state.
    experts: Vec<f32>,
    /// The follower that demonstrates when the actor has no Regulated Pure Pursuit base.
    follower: sim::FollowerParams,
    /// The residual actor's Regulated Pure Pursuit base, which then demonstrates instead.
    rpp_base: Option<crate::observation::Residual>,
    batch: Batch,
}

impl StepScratch {
    fn new(trainer: &Trainer) -> StepScratch {
        let dim = trainer.options.scaling.input_len();
        let n = trainer.envs.len();
        StepScratch {
            dim,
            actions: vec![0.0f32; n * ACTION_DIM],
            next: vec![0.0f32; dim],
            experts: vec![0.0f32; n * ACTION_DIM],
            follower: sim::FollowerParams::default(),
            rpp_base: trainer
                .learner
                .residual()
                .filter(|r| matches!(r, crate::observation::Residual::Rpp(_))),
            batch: Batch::default(),
        }
    }
}

/// Writes `base` plus Gaussian noise of standard deviation `sigma` to `actions`, clamped to
/// the action box (speed in [0, 1], turn rate in [-1, 1]), drawing one normal per value.
fn noisy_actions(actions: &mut [f32], base: &[f32], sigma: f64, rng: &mut ChaCha8Rng) {
    #[allow(clippy::cast_possible_truncation, reason = "noise is f32")]
    for (k, (a, b)) in actions.iter_mut().zip(base).enumerate() {
        let z: f64 = rng.sample(StandardNormal);
        let v = b + (z * sigma) as f32;
        *a = if k % 2 == 0 {
            v.clamp(0.0, 1.0)
        } else {
            v.clamp(-1.0, 1.0)
        };
    }
}

impl Trainer {
    /// Trains until the budget is spent or `on_progress` (called a few times a second) returns
    /// false. Checkpoints every `checkpoint_every_s` seconds and when it returns.
    pub fn run(
        &mut self,
        budget: Budget,
        on_progress: &mut dyn FnMut(&Progress) -> bool,
    ) -> Result<(), TrainError> {
        let clock = SessionClock {
            start: Instant::now(),
            wall_before: self.counters.wall_s,
        };
        let mut last_report = Instant::now();
        let mut last_checkpoint = Instant::now();
        let mut scratch = StepScratch::new(self);
        loop {
            self.counters.wall_s = clock.wall_s();
            if self.budget_spent(&budget) {
                break;
            }
            if last_report.elapsed().as_secs_f64() >= 0.25 {
                last_report = Instant::now();
                if !on_progress(&self.progress(&budget)) {
                    break;
                }
            }
            self.label_experts(&mut scratch);
            let demonstrating = self.counters.env_steps < self.options.config.demo_steps;
            // Algorithm 1, line 4: act.
            self.choose_actions(demonstrating, &mut scratch);
            // Lines 5–7: step, store, reset finished episodes.
            self.step_envs(&mut scratch, &clock)?;
            if demonstrating {
                // No gradient steps while demonstrating: the demonstrations are data for the
                // warm start, gathered at the simulator's speed.
                continue;
            }
            let c = &self.options.config;
            if !self.counters.warm_started && c.demo_steps > 0 && c.bc_steps > 0 {
                self.warm_start(&mut scratch.batch);
            }
            // Lines 8–17: gradient steps.
            self.gradient_steps(&mut scratch.batch);
            if self.counters.env_steps >= self.counters.next_eval {
                self.counters.next_eval += self.options.config.eval_every;
                self.evaluate_and_record(clock.wall_s())?;
            }
            let every = self.options.config.checkpoint_every_s;
            if every > 0.0 && last_checkpoint.elapsed().as_secs_f64() >= every {
                self.counters.wall_s = clock.wall_s();
                self.checkpoint()?;
                last_checkpoint = Instant::now();
            }
        }
        self.counters.wall_s = clock.wall_s();
        self.checkpoint()?;
        let _ = on_progress(&self.progress(&budget));
        Ok(())
    }

    /// Whether the run has spent its wall-clock or environment-step budget.
    fn budget_spent(&self, budget: &Budget) -> bool {
        budget.wall_s.is_some_and(|w| self.counters.wall_s >= w)
            || budget
                .env_steps
                .is_some_and(|s| self.counters.env_steps >= s)
    }

    /// The demonstrator's action in every environment's state (labels for the
    /// behaviour-cloning term): the classical follower on the straight segment to the goal, or
    /// a Regulated Pure Pursuit base's command, so that the warm start begins where the
    /// residual actor's base is.
    fn label_experts(&self, scratch: &mut StepScratch) {
        let dim = scratch.dim;
        for (i, (e, env)) in scratch
            .experts
            .chunks_exact_mut(ACTION_DIM)
            .zip(&self.envs)
            .enumerate()
        {
            e.copy_from_slice(&match &scratch.rpp_base {
                Some(r) => r.output(&self.options.scaling, &self.inputs[i * dim..][..dim]),
                None => self
                    .options
                    .scaling
                    .output_of(env.demonstration(&scratch.follower)),
            });
        }
    }

    /// Algorithm 1, line 4: every environment's action, from the noisy demonstrator first
    /// (when configured), then uniformly at random while the buffer warms up, then the actor
    /// with exploration noise.
    fn choose_actions(&mut self, demonstrating: bool, scratch: &mut StepScratch) {
        let c = &self.options.config;
        if demonstrating {
            noisy_actions(
                &mut scratch.actions,
                &scratch.experts,
                c.demo_noise,
                &mut self.rng,
            );
        } else if self.counters.env_steps < c.demo_steps + c.random_steps {
            for a in scratch.actions.chunks_exact_mut(ACTION_DIM) {
                a[0] = self.rng.random::<f32>();
                a[1] = self.rng.random::<f32>() * 2.0 - 1.0;
            }
        } else {
            let n = self.envs.len();
            let mut out = Vec::with_capacity(n * ACTION_DIM);
            self.learner.act(&self.inputs, n, &mut out);
            noisy_actions(
                &mut scratch.actions,
                &out,
                c.td3.exploration_noise,
                &mut self.rng,
            );
        }
    }

    /// Algorithm 1, lines 5–7: steps every environment with its action (behind the shield,
    /// if any), stores the transitions, and resets the environments whose episode ended.
    fn step_envs(
        &mut self,
        scratch: &mut StepScratch,
        clock: &SessionClock,
    ) -> Result<(), TrainError> {
        let dim = scratch.dim;
        for i in 0..self.envs.len() {
            let a = [scratch.actions[i * 2], scratch.actions[i * 2 + 1]];
            let mut command = self.options.scaling.command(a);
            if let Some(shield) = &self.shield {
                let seen = self
                    .options
                    .scaling
                    .decode(&self.inputs[i * dim..(i + 1) * dim]);
                let angular_max = f64::from(self.options.scaling.angular_max);
                command = shield.filter(command, &seen, angular_max);
            }
            let r = self.envs[i].step(command);
            self.options
                .scaling
                .encode_into(&r.observation, &mut scratch.next);
            let terminal = matches!(r.info.outcome, Outcome::ReachedGoal | Outcome::Collision);
            #[allow(
                clippy::cast_possible_truncation,
                reason = "rewards are f32 in the buffer"
            )]
            self.buffer.push(
                &self.inputs[i * dim..(i + 1) * dim],
                a,
                [scratch.experts[i * 2], scratch.experts[i * 2 + 1]],
                (r.reward * self.options.config.td3.reward_scale) as f32,
                &scratch.next,
                terminal,
            );
            self.returns[i] += r.reward;
            self.counters.env_steps += 1;
            if r.done {
                self.finish_episode(i, &r, clock)?;
            } else {
                self.inputs[i * dim..(i + 1) * dim].copy_from_slice(&scratch.next);
            }
        }
        Ok(())
    }

    /// Records environment `i`'s finished episode, widens the curriculum if it is time, and
    /// starts its next episode: chained from where it stopped after a goal (sometimes), else
    /// from rest, perhaps in another world.
    fn finish_episode(
        &mut self,
        i: usize,
        r: &sim::StepResult,
        clock: &SessionClock,
    ) -> Result<(), TrainError> {
        let dim = self.options.scaling.input_len();
        self.counters.episodes += 1;
        self.episodes.push(EpisodeRecord {
            episode: self.counters.episodes,
            env_steps: self.counters.env_steps,
            wall_s: clock.wall_s(),
            reward: self.returns[i],
            outcome: outcome_name(r.info.outcome).into(),
            steps: r.info.steps,
        });
        self.returns[i] = 0.0;
        self.advance_curriculum()?;
        let chain = r.info.outcome == Outcome::ReachedGoal
            && self.rng.random::<f64>() < self.options.config.chain_goals;
        let obs = if chain {
            self.envs[i].continue_random()?
        } else {
            self.move_env(i)?;
            self.envs[i].reset_random()?
        };
        self.options
            .scaling
            .encode_into(&obs, &mut self.inputs[i * dim..(i + 1) * dim]);
        Ok(())
    }

    /// Algorithm 1, lines 8–17: the gradient steps owed once the buffer holds a batch
    /// (`updates_per_step` per environment step; critic-only steps right after the warm start).
    fn gradient_steps(&mut self, batch: &mut Batch) {
        let c = &self.options.config;
        if self.buffer.len() < c.td3.batch_size {
            return;
        }
        self.counters.update_debt += self.envs.len() as f64 * c.updates_per_step;
        while self.counters.update_debt >= 1.0 {
            self.buffer
                .sample_into(&mut self.rng, c.td3.batch_size, batch);
            if self.counters.grad_steps < c.critic_warmup_steps && self.counters.warm_started {
                let _ = self.learner.critic_update(batch, &mut self.rng);
            } else {
                let _ = self.learner.update(batch, &mut self.rng);
            }
            self.counters.grad_steps += 1;
            self.counters.update_debt -= 1.0;
        }
    }

    /// The warm start: `bc_steps` behaviour-cloning steps of the actor on the buffer (the
    /// demonstrations so far), then the targets copied from the networks.
    fn warm_start(&mut self, batch: &mut Batch) {
        let c = &self.options.config;
        let mut loss = None;
        if self.buffer.len() >= c.td3.batch_size {
            for _ in 0..c.bc_steps {
                self.buffer
                    .sample_into(&mut self.rng, c.td3.batch_size, batch);
                loss = Some(self.learner.clone_step(batch));
            }
            self.learner.sync_targets();
        }
        self.counters.bc_loss = loss;
        self.counters.warm_started = true;
    }
}
