//! A batch of environments stepped in parallel across cores with rayon, each with its own seed,
//! so a batch gives exactly the results of stepping its environments one after another.

use std::sync::Arc;

use rayon::prelude::*;

use crate::env::{EnvConfig, EnvError, NavEnv, Observation, StepResult};
use crate::kinematics::Action;
use crate::world::World;

/// Environments sharing one world.
#[derive(Clone, Debug)]
pub struct EnvBatch {
    envs: Vec<NavEnv>,
    auto_reset: bool,
}

/// The seed of environment `index` in a batch seeded with `seed`: the `index`-th SplitMix64
/// output from `seed` ([`grid::seed::nth`]), so neighbouring environments get unrelated streams.
pub fn env_seed(seed: u64, index: usize) -> u64 {
    grid::seed::nth(seed, index as u64)
}

impl EnvBatch {
    /// `count` environments; environment `i` is seeded with [`env_seed`]`(seed, i)`. With
    /// `auto_reset`, an environment whose episode ends starts a random one at once (see
    /// [`StepResult::reset_observation`]).
    pub fn new(
        world: Arc<World>,
        config: EnvConfig,
        count: usize,
        seed: u64,
        auto_reset: bool,
    ) -> Result<EnvBatch, EnvError> {
        let envs = (0..count)
            .map(|i| NavEnv::new(Arc::clone(&world), config.clone(), env_seed(seed, i)))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(EnvBatch { envs, auto_reset })
    }

    /// Number of environments.
    pub fn len(&self) -> usize {
        self.envs.len()
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.envs.is_empty()
    }

    /// The environments.
    pub fn envs(&self) -> &[NavEnv] {
        &self.envs
    }

    /// The environments, to reset one with a chosen start and goal.
    pub fn envs_mut(&mut self) -> &mut [NavEnv] {
        &mut self.envs
    }

    /// Resets every environment to a random start and goal, in parallel.
    pub fn reset_random(&mut self) -> Result<Vec<Observation>, EnvError> {
        self.envs.par_iter_mut().map(NavEnv::reset_random).collect()
    }

    /// Steps every environment with its action, in parallel. `actions` must hold one action per
    /// environment.
    pub fn step(&mut self, actions: &[Action]) -> Result<Vec<StepResult>, EnvError> {
        if actions.len() != self.envs.len() {
            return Err(EnvError::Config {
                field: "actions",
                message: format!(
                    "{} actions for {} environments",
                    actions.len(),
                    self.envs.len()
                ),
            });
        }
        let auto = self.auto_reset;
        self.envs
            .par_iter_mut()
            .zip(actions.par_iter())
            .map(|(env, a)| {
                let mut r = env.step(*a);
                if auto && r.done {
                    r.reset_observation = Some(env.reset_random()?);
                }
                Ok(r)
            })
            .collect()
    }
}
