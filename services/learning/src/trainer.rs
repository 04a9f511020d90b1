//! The training loop: environments in the mental simulation of a place, a replay buffer, the
//! TD3 learner, periodic evaluation on a fixed mission set, checkpoints a run resumes from, and
//! the exported policy at the end.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use sim::{EnvConfig, EnvError, NavEnv, Outcome, World};

use crate::config::TrainConfig;
use crate::evaluation::{BatchActor, EvalReport, Mission, evaluate_shielded, mission_set};
use crate::observation::Scaling;
use crate::policy::{PolicyError, PolicyMetadata, write_atomic, write_policy};
use crate::replay::ReplayBuffer;
use crate::td3::{Learner, LearnerError};

mod session;

/// Name of the checkpoint directory inside a run's output directory.
pub const CHECKPOINT_DIR: &str = "checkpoint";

/// Why training stopped or could not start.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A setting is out of range.
    #[error("invalid training configuration: {0}")]
    Config(String),
    /// The environment refused a setting or the world has no room.
    #[error("environment: {0}")]
    Env(#[from] EnvError),
    /// The learner failed.
    #[error(transparent)]
    Learner(#[from] LearnerError),
    /// Writing or reading the policy or buffer failed.
    #[error(transparent)]
    Policy(#[from] PolicyError),
    /// Memory the training needs could not be allocated.
    #[error("out of memory: {0}")]
    OutOfMemory(String),
    /// A checkpoint could not be written or read.
    #[error("checkpoint {path}: {message}")]
    Checkpoint {
        /// The checkpoint directory.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

impl BatchActor for Learner {
    fn act_batch(&self, inputs: &[f32], n: usize, out: &mut Vec<f32>) {
        self.act(inputs, n, out);
    }
}

/// What training needs besides the world.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainOptions {
    /// Hyperparameters.
    pub config: TrainConfig,
    /// The environment (beam count, limits, noise, reward); `goal_distance` and `max_steps` are
    /// taken from `config`.
    pub env: EnvConfig,
    /// Input and output scaling (its beam count must equal `env.beams`).
    pub scaling: Scaling,
    /// Where checkpoints, curves and the exported policy go.
    pub out_dir: PathBuf,
}

impl TrainOptions {
    /// Options with defaults for everything but the output directory.
    pub fn new(out_dir: impl Into<PathBuf>) -> TrainOptions {
        TrainOptions {
            config: TrainConfig::default(),
            env: EnvConfig::default(),
            scaling: Scaling::default(),
            out_dir: out_dir.into(),
        }
    }

    fn env_config(&self) -> EnvConfig {
        EnvConfig {
            goal_distance: self.config.goal_distance,
            goals_in_view: self.config.goals_in_view,
            max_steps: self.config.max_episode_steps,
            reward: sim::RewardConfig {
                progress: self.config.progress_reward,
                time_per_step: self.config.time_per_step_reward,
                heading: self.config.heading_reward,
                geodesic: self.config.geodesic_reward,
                clearance: self.config.clearance_reward,
                time: self.config.time_cost,
                ..self.env.reward
            },
            ..self.env.clone()
        }
    }
}

/// When a call to [`Trainer::run`] ends.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct Budget {
    /// Total wall-clock seconds of training, counting earlier sessions of a resumed run.
    pub wall_s: Option<f64>,
    /// Total environment steps.
    pub env_steps: Option<u64>,
}

/// One finished training episode, for the curves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EpisodeRecord {
    /// Index, from 1.
    pub episode: u64,
    /// Environment steps of the run when it ended.
    pub env_steps: u64,
    /// Training wall-clock seconds when it ended.
    pub wall_s: f64,
    /// Undiscounted return.
    pub reward: f64,
    /// `goal`, `collision` or `timeout`.
    pub outcome: String,
    /// Steps in the episode.
    pub steps: u32,
}

/// One evaluation during training.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalRecord {
    /// Environment steps when it ran.
    pub env_steps: u64,
    /// Training wall-clock seconds when it ran.
    pub wall_s: f64,
    /// The result.
    pub report: EvalReport,
}

/// Counters of a run, carried across resumes.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Counters {
    /// Environment steps.
    pub env_steps: u64,
    /// Finished episodes.
    pub episodes: u64,
    /// Gradient steps.
    pub grad_steps: u64,
    /// Wall-clock seconds spent training, over all sessions.
    pub wall_s: f64,
    /// Sessions of this run (1 + resumes).
    pub sessions: u32,
    /// Fractional gradient steps owed (updates_per_step is not an integer in general).
    pub update_debt: f64,
    /// Environment steps at which the next evaluation runs.
    pub next_eval: u64,
    /// The curriculum's current largest goal distance, metres (0: no curriculum yet).
    #[serde(default)]
    pub goal_max: f64,
    /// Episodes finished when the curriculum last widened.
    #[serde(default)]
    pub curriculum_mark: u64,
    /// The people curriculum's current density, people per 100 m² (0: nobody yet).
    #[serde(default)]
    pub people_density: f64,
    /// Whether the behaviour-cloning warm start has run.
    #[serde(default)]
    pub warm_started: bool,
    /// Final loss of the warm start (mean squared action error against the follower).
    #[serde(default)]
    pub bc_loss: Option<f64>,
}

/// A snapshot for progress bars and job progress.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Progress {
    /// Counters.
    pub counters: Counters,
    /// Success rate over the last 100 training episodes (exploration noise on).
    pub success_rate_100: f64,
    /// Mean return over the last 100 training episodes.
    pub mean_reward_100: f64,
    /// The latest evaluation.
    pub last_eval: Option<EvalRecord>,
    /// Share of the budget used, in [0, 1], when the budget is bounded.
    pub fraction_done: Option<f64>,
    /// Checkpoints this trainer has written since it was created or resumed (a job notices a
    /// new checkpoint by this count changing).
    pub checkpoints_written: u64,
}

impl std::fmt::Display for Progress {
    /// One line for a progress bar's message or a log: steps, episodes, gradient steps, the
    /// success rate and mean reward of the last 100 episodes, and the latest evaluation.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "steps {} episodes {} grad steps {} success {:.0}% reward {:.1}",
            self.counters.env_steps,
            self.counters.episodes,
            self.counters.grad_steps,
            self.success_rate_100 * 100.0,
            self.mean_reward_100,
        )?;
        if let Some(e) = &self.last_eval {
            write!(f, " eval {:.0}%", e.report.success_rate * 100.0)?;
        }
        Ok(())
    }
}

/// The random generator's position, to continue the same stream after a resume.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct RngState {
    seed: [u8; 32],
    stream: u64,
    word_pos: u128,
}

impl RngState {
    fn of(rng: &ChaCha8Rng) -> RngState {
        RngState {
            seed: rng.get_seed(),
            stream: rng.get_stream(),
            word_pos: rng.get_word_pos(),
        }
    }

    fn restore(&self) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::from_seed(self.seed);
        rng.set_stream(self.stream);
        rng.set_word_pos(self.word_pos);
        rng
    }
}

/// What `state.json` of a checkpoint holds besides the tensors.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct TrainerState {
    config: TrainConfig,
    scaling: Scaling,
    counters: Counters,
    rng: RngState,
    episodes: Vec<EpisodeRecord>,
    evals: Vec<EvalRecord>,
}

/// A training run.
pub struct Trainer {
    options: TrainOptions,
    env_config: EnvConfig,
    world: Arc<World>,
    /// The worlds training episodes run in (by default `world` alone; evaluation stays in
    /// `world`). With more worlds than environments, an environment moves to a world drawn at
    /// random whenever it starts an episode from rest.
    train_worlds: Vec<Arc<World>>,
    /// Episodes started from rest, for the seeds of environments moved to another world.
    moves: u64,
    learner: Learner,
    buffer: ReplayBuffer,
    envs: Vec<NavEnv>,
    inputs: Vec<f32>,
    returns: Vec<f64>,
    rng: ChaCha8Rng,
    counters: Counters,
    episodes: Vec<EpisodeRecord>,
    evals: Vec<EvalRecord>,
    missions: Vec<Mission>,
    checkpoints_written: u64,
    /// The actor of the best periodic evaluation of this session: (success rate, mean time to
    /// goal, env steps, layers).
    best: Option<BestActor>,
    /// Asked right before a written checkpoint replaces the previous one; an error leaves the
    /// previous one in place (a job that lost its lease must not overwrite its successor's).
    install_guard: Option<InstallGuard>,
    /// The collision shield every step is driven behind (`shielded`).
    shield: Option<sim::shield::Shield>,
}

/// See [`Trainer::set_install_guard`].
pub type InstallGuard = Box<dyn FnMut() -> Result<(), String> + Send>;

/// A name for this process's and trainer's staging directories, so two writers of one
/// checkpoint directory never share one.
fn writer_tag() -> String {
    static WRITERS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = WRITERS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    format!("{}-{n}", std::process::id())
}

/// The newest complete checkpoint set aside by an install that did not finish
/// (`checkpoint.old-<writer>`), if any.
fn previous_checkpoint(out_dir: &Path) -> Option<PathBuf> {
    std::fs::read_dir(out_dir)
        .ok()?
        .filter_map(Result::ok)
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with("checkpoint.old")
        })
        .map(|e| e.path())
        .filter(|d| d.join("state.json").is_file())
        .max_by_key(|d| {
            std::fs::metadata(d.join("state.json"))
                .and_then(|m| m.modified())
                .ok()
        })
}

use crate::policy::sync_path;

/// A snapshot of the actor at an evaluation.
#[derive(Clone, Debug)]
struct BestActor {
    success_rate: f64,
    mean_time_s: f64,
    env_steps: u64,
    layers: Vec<(Vec<f32>, Vec<f32>)>,
}

impl BestActor {
    /// Whether an evaluation with these figures beats this snapshot.
    fn beaten_by(&self, success_rate: f64, mean_time_s: f64) -> bool {
        success_rate > self.success_rate
            || (success_rate == self.success_rate && mean_time_s < self.mean_time_s)
    }

    /// Whether this snapshot beats an evaluation with these figures.
    fn beats(&self, success_rate: f64, mean_time_s: f64) -> bool {
        self.success_rate > success_rate
            || (self.success_rate == success_rate && self.mean_time_s < mean_time_s)
    }
}

impl std::fmt::Debug for Trainer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Trainer")
            .field("out_dir", &self.options.out_dir)
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

fn outcome_name(o: Outcome) -> &'static str {
    match o {
        Outcome::ReachedGoal => "goal",
        Outcome::Collision => "collision",
        Outcome::TimeLimit | Outcome::Running => "timeout",
    }
}

impl Trainer {
    /// A fresh run in `world`.
    pub fn new(world: Arc<World>, options: TrainOptions) -> Result<Trainer, TrainError> {
        options.config.validate().map_err(TrainError::Config)?;
        if options.scaling.beams != options.env.beams {
            return Err(TrainError::Config(format!(
                "the scaling has {} beams, the environment {}",
                options.scaling.beams, options.env.beams
            )));
        }
        let c = &options.config;
        if c.threads > 0 {
            #[allow(
                clippy::cast_possible_truncation,
                clippy::cast_possible_wrap,
                reason = "thread counts are small"
            )]
            tch::set_num_threads(c.threads as i32);
        }
        let env_config = options.env_config();
        let dim = options.scaling.input_len();
        let mut learner = Learner::new(c.td3.clone(), dim, crate::training_device(), c.seed);
        if c.td3.residual {
            learner.set_residual(c.td3.residual_base.residual(), options.scaling);
        }
        let missions = mission_set(&world, &env_config, c.eval_episodes, c.eval_seed)?;
        let mut trainer = Trainer {
            buffer: ReplayBuffer::try_with_capacity(dim, c.buffer_capacity)
                .map_err(TrainError::OutOfMemory)?,
            envs: Vec::new(),
            inputs: vec![0.0; c.envs * dim],
            returns: vec![0.0; c.envs],
            rng: ChaCha8Rng::seed_from_u64(c.seed),
            counters: Counters {
                sessions: 1,
                next_eval: c.eval_every,
                ..Counters::default()
            },
            episodes: Vec::new(),
            evals: Vec::new(),
            missions,
            checkpoints_written: 0,
            install_guard: None,
            shield: c
                .shielded
                .then(|| sim::shield::Shield::new(&world, options.scaling.beams))
                .flatten(),
            best: None,
            learner,
            env_config,
            train_worlds: vec![Arc::clone(&world)],
            moves: 0,
            world,
            options,
        };
        trainer.start_envs()?;
        Ok(trainer)
    }

    /// Spreads the training environments over `world` and `extra` (environment `i` runs in
    /// world `i mod (1 + extra.len())`), so that one policy learns several buildings; the
    /// evaluations stay in the run's own world. Not part of the checkpoint: pass the same
    /// worlds again after [`Trainer::resume`].
    pub fn with_extra_worlds(self, extra: Vec<Arc<World>>) -> Result<Trainer, TrainError> {
        let mut worlds = vec![Arc::clone(&self.world)];
        worlds.extend(extra);
        self.with_training_worlds(worlds)
    }

    /// Trains in `worlds` only (the run's own world, where evaluations run, is then held out
    /// unless it is among them). Not part of the checkpoint: pass the same worlds again after
    /// [`Trainer::resume`].
    pub fn with_training_worlds(mut self, worlds: Vec<Arc<World>>) -> Result<Trainer, TrainError> {
        if worlds.is_empty() {
            return Err(TrainError::Config("no world to train in".into()));
        }
        self.train_worlds = worlds;
        self.start_envs()?;
        Ok(self)
    }

    /// Whether `out_dir` holds a checkpoint to resume from.
    pub fn has_checkpoint(out_dir: &Path) -> bool {
        out_dir.join(CHECKPOINT_DIR).join("state.json").is_file()
            || previous_checkpoint(out_dir).is_some()
    }

    /// The episodes recorded in `out_dir`'s checkpoint, for the curves of a run in progress;
    /// `None` without a readable checkpoint.
    pub fn checkpointed_episodes(out_dir: &Path) -> Option<Vec<EpisodeRecord>> {
        #[derive(Deserialize)]
        struct Episodes {
            episodes: Vec<EpisodeRecord>,
        }
        let mut dir = out_dir.join(CHECKPOINT_DIR);
        if !dir.join("state.json").is_file() {
            dir = previous_checkpoint(out_dir)?;
        }
        let bytes = std::fs::read(dir.join("state.json")).ok()?;
        serde_json::from_slice::<Episodes>(&bytes)
            .ok()
            .map(|e| e.episodes)
    }

    /// Continues the run checkpointed in `options.out_dir`. Its configuration comes from the
    /// checkpoint; `options.config` must equal it (a changed configuration is refused, named).
    pub fn resume(world: Arc<World>, options: TrainOptions) -> Result<Trainer, TrainError> {
        let mut dir = options.out_dir.join(CHECKPOINT_DIR);
        if !dir.join("state.json").is_file() {
            // A crash between the two renames of `checkpoint` leaves the previous one aside.
            if let Some(previous) = previous_checkpoint(&options.out_dir) {
                dir = previous;
            }
        }
        let bad = |message: String| TrainError::Checkpoint {
            path: dir.clone(),
            message,
        };
        let state_bytes = std::fs::read(dir.join("state.json")).map_err(|e| bad(e.to_string()))?;
        let state: TrainerState =
            serde_json::from_slice(&state_bytes).map_err(|e| bad(format!("state.json: {e}")))?;
        if state.config != options.config {
            return Err(bad(
                "the checkpoint was written with another training configuration".into(),
            ));
        }
        if state.scaling != options.scaling {
            return Err(bad("the checkpoint was written with another scaling".into()));
        }
        let mut trainer = Trainer::new(world, options)?;
        trainer.learner.load(&dir.join("learner.safetensors"))?;
        trainer.buffer = ReplayBuffer::load(&dir.join("replay.safetensors"))?;
        trainer.rng = state.rng.restore();
        trainer.counters = state.counters;
        trainer.counters.sessions += 1;
        trainer.episodes = state.episodes;
        trainer.evals = state.evals;
        // Episodes that were under way when the run stopped start afresh, from new seeds.
        trainer.start_envs()?;
        Ok(trainer)
    }

    fn start_envs(&mut self) -> Result<(), TrainError> {
        let c = &self.options.config;
        let dim = self.options.scaling.input_len();
        let base = c.seed ^ (u64::from(self.counters.sessions) << 32);
        let worlds = &self.train_worlds;
        // With a carrot, every other environment shows it on the way to goals anywhere in
        // the free region (what a plan's policy sees on its path); the rest keep the goals
        // as configured (a roadmap edge's far vertex, as edge rollouts and vertex plans show).
        let carrot = |i: usize| {
            let mut config = self.env_config.clone();
            if c.carrot_m > 0.0 && i % 2 == 1 {
                config.carrot_m = Some(c.carrot_m);
                config.goals_in_view = false;
            }
            config
        };
        self.envs = (0..c.envs)
            .map(|i| {
                NavEnv::new(
                    Arc::clone(&worlds[i % worlds.len()]),
                    carrot(i),
                    sim::env_seed(base, i),
                )
            })
            .collect::<Result<_, _>>()?;
        if c.curriculum && self.counters.goal_max <= 0.0 {
            self.counters.goal_max = (c.goal_distance.0 + 2.0).min(c.goal_distance.1);
        }
        let range = self.training_range();
        let people = self.training_people();
        for (i, env) in self.envs.iter_mut().enumerate() {
            env.set_goal_distance(range)?;
            env.set_people(people.clone())?;
            let obs = env.reset_random()?;
            self.options
                .scaling
                .encode_into(&obs, &mut self.inputs[i * dim..(i + 1) * dim]);
            self.returns[i] = 0.0;
        }
        Ok(())
    }

    /// Goal distances of training episodes now: the curriculum's range, or the configured one.
    fn training_range(&self) -> (f64, f64) {
        let (lo, hi) = self.options.config.goal_distance;
        if self.options.config.curriculum && self.counters.goal_max > 0.0 {
            (lo, self.counters.goal_max.clamp(lo, hi))
        } else {
            (lo, hi)
        }
    }

    /// People in training episodes now: the people curriculum's density.
    fn training_people(&self) -> sim::PeopleConfig {
        sim::PeopleConfig {
            density: self.counters.people_density,
            ..self.env_config.people.clone()
        }
    }

    /// Widens the curriculum when the last 100 episodes mostly succeeded: the goal range
    /// first, then the people's density.
    fn advance_curriculum(&mut self) -> Result<(), TrainError> {
        let c = &self.options.config;
        let goals_done = !c.curriculum || self.counters.goal_max >= c.goal_distance.1;
        let people_done = self.counters.people_density >= c.people_density;
        if (goals_done && people_done)
            || self.counters.episodes < self.counters.curriculum_mark + 100
        {
            return Ok(());
        }
        let last = &self.episodes[self.episodes.len().saturating_sub(100)..];
        let successes = last.iter().filter(|e| e.outcome == "goal").count();
        if successes * 10 < last.len() * 6 {
            return Ok(());
        }
        self.counters.curriculum_mark = self.counters.episodes;
        if !goals_done {
            self.counters.goal_max = (self.counters.goal_max + 1.0).min(c.goal_distance.1);
            let range = self.training_range();
            for env in &mut self.envs {
                env.set_goal_distance(range)?;
            }
        } else {
            self.counters.people_density =
                (self.counters.people_density + c.people_density / 4.0).min(c.people_density);
            let people = self.training_people();
            for env in &mut self.envs {
                env.set_people(people.clone())?;
            }
        }
        Ok(())
    }

    /// The counters.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// The learner.
    pub fn learner(&self) -> &Learner {
        &self.learner
    }

    /// Finished training episodes.
    pub fn episodes(&self) -> &[EpisodeRecord] {
        &self.episodes
    }

    /// Evaluations so far.
    pub fn evals(&self) -> &[EvalRecord] {
        &self.evals
    }

    /// The options.
    pub fn options(&self) -> &TrainOptions {
        &self.options
    }

    /// The progress snapshot.
    pub fn progress(&self, budget: &Budget) -> Progress {
        let last: Vec<&EpisodeRecord> = self.episodes.iter().rev().take(100).collect();
        let n = last.len().max(1) as f64;
        let success = last.iter().filter(|e| e.outcome == "goal").count();
        let fraction = match (budget.wall_s, budget.env_steps) {
            (Some(w), _) if w > 0.0 => Some((self.counters.wall_s / w).min(1.0)),
            (_, Some(s)) if s > 0 => Some((self.counters.env_steps as f64 / s as f64).min(1.0)),
            _ => None,
        };
        let success_rate_100 = success as f64 / n;
        Progress {
            counters: self.counters.clone(),
            success_rate_100,
            mean_reward_100: last.iter().map(|e| e.reward).sum::<f64>() / n,
            last_eval: self.evals.last().cloned(),
            fraction_done: fraction,
            checkpoints_written: self.checkpoints_written,
        }
    }

    /// With more training worlds than environments, moves environment `i` to a world drawn at
    /// random before it starts an episode from rest.
    fn move_env(&mut self, i: usize) -> Result<(), TrainError> {
        let worlds = self.train_worlds.len();
        if worlds <= self.envs.len() {
            return Ok(());
        }
        let k = self.rng.random_range(0..worlds);
        if Arc::ptr_eq(self.envs[i].world(), &self.train_worlds[k]) {
            return Ok(());
        }
        self.moves += 1;
        let base =
            self.options.config.seed ^ (u64::from(self.counters.sessions) << 32) ^ 0x6d6f_7665;
        #[allow(
            clippy::cast_possible_truncation,
            reason = "a seed index wraps harmlessly"
        )]
        let index = (self.moves as usize)
            .wrapping_mul(self.envs.len())
            .wrapping_add(i);
        let mut env = NavEnv::new(
            Arc::clone(&self.train_worlds[k]),
            self.env_config.clone(),
            sim::env_seed(base, index),
        )?;
        env.set_goal_distance(self.training_range())?;
        env.set_people(self.training_people())?;
        self.envs[i] = env;
        Ok(())
    }

    /// Evaluates the current actor on the fixed mission set and records the result.
    pub fn evaluate_and_record(&mut self, wall_s: f64) -> Result<EvalReport, TrainError> {
        let report = self.evaluate(&self.missions)?;
        let time = if report.mean_time_to_goal_s.is_finite() {
            report.mean_time_to_goal_s
        } else {
            f64::INFINITY
        };
        if self.options.config.export_best
            && self
                .best
                .as_ref()
                .is_none_or(|b| b.beaten_by(report.success_rate, time))
        {
            self.best = Some(BestActor {
                success_rate: report.success_rate,
                mean_time_s: time,
                env_steps: self.counters.env_steps,
                layers: self.learner.actor_layers(),
            });
        }
        self.evals.push(EvalRecord {
            env_steps: self.counters.env_steps,
            wall_s,
            report: report.clone(),
        });
        Ok(report)
    }

    /// Evaluates the current actor on `missions` in the training world (behind the shield
    /// when it trains behind it: the best actor is chosen as it will drive).
    pub fn evaluate(&self, missions: &[Mission]) -> Result<EvalReport, TrainError> {
        Ok(evaluate_shielded(
            &self.learner,
            &self.world,
            &self.env_config,
            &self.options.scaling,
            missions,
            self.options.config.eval_seed,
            self.shield.as_ref(),
        )?)
    }

    /// Writes a checkpoint: networks, targets and optimiser moments, the replay buffer, the
    /// counters, the random state and the logs. The directory is replaced as a whole, so a crash
    /// leaves the previous checkpoint or the new one.
    pub fn checkpoint(&mut self) -> Result<(), TrainError> {
        let out = &self.options.out_dir.clone();
        let final_dir = out.join(CHECKPOINT_DIR);
        let tag = writer_tag();
        let new_dir = out.join(format!("checkpoint.new-{tag}"));
        let old_dir = out.join(format!("checkpoint.old-{tag}"));
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |e: std::io::Error| TrainError::Checkpoint {
                path,
                message: e.to_string(),
            }
        };
        if new_dir.exists() {
            std::fs::remove_dir_all(&new_dir).map_err(io(&new_dir))?;
        }
        // A write that fails (a full disk) leaves no half-written directory behind.
        let staged = (|| -> Result<(), TrainError> {
            std::fs::create_dir_all(&new_dir).map_err(io(&new_dir))?;
            self.learner.save(&new_dir.join("learner.safetensors"))?;
            self.buffer.save(&new_dir.join("replay.safetensors"))?;
            let state = TrainerState {
                config: self.options.config.clone(),
                scaling: self.options.scaling,
                counters: self.counters.clone(),
                rng: RngState::of(&self.rng),
                episodes: self.episodes.clone(),
                evals: self.evals.clone(),
            };
            let json = serde_json::to_vec(&state).map_err(|e| TrainError::Checkpoint {
                path: new_dir.clone(),
                message: e.to_string(),
            })?;
            write_atomic(&new_dir.join("state.json"), &json).map_err(io(&new_dir))?;
            // Durable before it is installed: every file, then the directory's entries.
            for file in ["learner.safetensors", "replay.safetensors", "state.json"] {
                sync_path(&new_dir.join(file)).map_err(io(&new_dir))?;
            }
            sync_path(&new_dir).map_err(io(&new_dir))?;
            Ok(())
        })();
        if let Err(e) = staged {
            let _ = std::fs::remove_dir_all(&new_dir);
            return Err(e);
        }
        if let Some(guard) = self.install_guard.as_mut()
            && let Err(why) = guard()
        {
            let _ = std::fs::remove_dir_all(&new_dir);
            return Err(TrainError::Checkpoint {
                path: final_dir,
                message: format!("not installed: {why}"),
            });
        }
        if final_dir.exists() {
            std::fs::rename(&final_dir, &old_dir).map_err(io(&final_dir))?;
        }
        std::fs::rename(&new_dir, &final_dir).map_err(io(&final_dir))?;
        sync_path(out).map_err(io(out))?;
        if old_dir.exists() {
            std::fs::remove_dir_all(&old_dir).map_err(io(&old_dir))?;
        }
        self.checkpoints_written += 1;
        Ok(())
    }

    /// Sets what is asked right before each checkpoint replaces the previous one (a job's
    /// lease check); its error keeps the previous checkpoint and fails the checkpoint.
    pub fn set_install_guard(&mut self, guard: InstallGuard) {
        self.install_guard = Some(guard);
    }

    /// Writes the exported policy (`policy.safetensors`, `policy.json`) into `dir`, with a
    /// training summary in its metadata.
    pub fn export(&self, dir: &Path, summary: serde_json::Value) -> Result<(), TrainError> {
        // The final actor competes with the best snapshot on the same missions.
        let (layers, exported) = match &self.best {
            Some(best) => {
                let last = self.evaluate(&self.missions)?;
                let last_time = if last.mean_time_to_goal_s.is_finite() {
                    last.mean_time_to_goal_s
                } else {
                    f64::INFINITY
                };
                if !best.beats(last.success_rate, last_time) || best.layers.is_empty() {
                    (
                        self.learner.actor_layers(),
                        serde_json::json!({"actor": "final"}),
                    )
                } else {
                    (
                        best.layers.clone(),
                        serde_json::json!({
                            "actor": "best evaluation",
                            "env_steps": best.env_steps,
                            "success_rate": best.success_rate,
                            "final_success_rate": last.success_rate,
                        }),
                    )
                }
            }
            None => (
                self.learner.actor_layers(),
                serde_json::json!({"actor": "final"}),
            ),
        };
        let mut meta = PolicyMetadata::new(
            self.options.scaling,
            self.options.config.td3.hidden.clone(),
            serde_json::json!({
                "algorithm": "TD3 (Fujimoto et al. 2018) with the regularised actor objective of Eq. 18",
                "config": self.options.config,
                "counters": self.counters,
                "last_eval": self.evals.last(),
                "exported": exported,
                "summary": summary,
            }),
        );
        meta.residual = self.learner.residual();
        write_policy(dir, &meta, &layers)?;
        Ok(())
    }
}
