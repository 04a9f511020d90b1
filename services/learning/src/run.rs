//! A training run into a directory, the way `mentalsim train` and `mentalsim bench beta` make
//! one: train (resuming the run checkpointed there unless told not to) until the wall-clock
//! budget is spent or the caller stops it, write the curves (`curves.csv`, `curves.png`,
//! `evals.csv`), export the policy, evaluate the exported policy — the pure-Rust runtime robots
//! embed — on held-out missions drawn from a seed training never used, and write that
//! [`TrainSummary`] as `eval.json`.
//!
//! The caller builds the worlds (from maps, through the simulation parser) and shows progress.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use sim::{EnvConfig, EnvError, World};

use crate::config::TrainConfig;
use crate::curves::{self, PlotError};
use crate::observation::Scaling;
use crate::policy::{Policy, PolicyError};
use crate::summary::{Goals, HeldOut, TrainSummary, held_out};
use crate::trainer::{Budget, Progress, TrainError, TrainOptions, Trainer};

/// What to run.
#[derive(Clone, Debug)]
pub struct TrainRun {
    /// The world trained in and evaluated on.
    pub world: Arc<World>,
    /// Further worlds that share the training environments (one policy for several places).
    pub extra_worlds: Vec<Arc<World>>,
    /// Train in `extra_worlds` only: `world` is held out, seen only by the evaluations.
    pub hold_out: bool,
    /// The map `world` was built from (recorded in `eval.json` and the policy, and named in
    /// the plot's title).
    pub map: PathBuf,
    /// The maps of `extra_worlds`.
    pub extra_maps: Vec<PathBuf>,
    /// The training configuration (validated by the trainer).
    pub config: TrainConfig,
    /// Where the checkpoint, curves, exported policy and `eval.json` go.
    pub out: PathBuf,
    /// Wall-clock budget in minutes, counting earlier sessions of a resumed run.
    pub minutes: f64,
    /// Start from scratch even if `out` holds a checkpoint.
    pub fresh: bool,
    /// Held-out missions of the final evaluation (of each kind of goals).
    pub eval_episodes: usize,
    /// Which held-out goals the headline figures are about.
    pub goals: Goals,
    /// Learners trained side by side, one per core, each with its own seed, replay buffer and
    /// checkpoint (`out/learners/<k>/`); the one whose exported policy does best on selection
    /// missions (drawn from a seed neither training nor the held-out evaluation uses) is the
    /// run's policy. 1: a single learner in `out`.
    pub learners: usize,
    /// How learners are compared: by default their success (then time) on selection
    /// missions; a caller that can drive roadmaps passes a better measure (per-edge success on
    /// the held-out world, which in-view missions saturate before).
    pub selector: Option<Selector>,
}

/// Scores a learner's exported policy (higher is better) on the held-out world.
pub type ScoreFn = dyn Fn(&Policy, &Arc<World>) -> Result<f64, String> + Send + Sync;

/// A score of a learner's exported policy (higher is better) on `world`, the held-out world.
#[derive(Clone)]
pub struct Selector(pub Arc<ScoreFn>);

impl std::fmt::Debug for Selector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Selector(..)")
    }
}

/// Most learners a run trains side by side.
pub const MAX_LEARNERS: usize = 16;

impl TrainRun {
    /// Whether the run continues the one checkpointed in `out`.
    pub fn resumes(&self) -> bool {
        !self.fresh && Trainer::has_checkpoint(&self.learner_dir(0))
    }

    /// Where learner `k` keeps its checkpoint, curves and exported policy: `out` itself for a
    /// single learner.
    pub fn learner_dir(&self, k: usize) -> PathBuf {
        if self.learners <= 1 {
            self.out.clone()
        } else {
            self.out.join("learners").join(k.to_string())
        }
    }
}

/// The files of a learner's directory that make the run's policy and curves.
const CHOSEN_FILES: [&str; 5] = [
    crate::policy::WEIGHTS_FILE,
    crate::policy::METADATA_FILE,
    "curves.csv",
    "curves.png",
    "evals.csv",
];

/// One learner's training, exported into its directory.
struct Learned {
    counters: crate::trainer::Counters,
    config: TrainConfig,
    interrupted: bool,
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A setting is out of range.
    #[error("{0}")]
    Invalid(String),
    /// Training failed.
    #[error(transparent)]
    Train(#[from] TrainError),
    /// The exported policy could not be read back.
    #[error(transparent)]
    Policy(#[from] PolicyError),
    /// The held-out evaluation could not set up its missions.
    #[error("held-out evaluation: {0}")]
    Evaluation(#[from] EnvError),
    /// A plot could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// A file could not be written.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What failed (in the message, not a `source`, so that it is printed once).
        error: std::io::Error,
    },
}

fn write(path: PathBuf, contents: impl AsRef<[u8]>) -> Result<(), RunError> {
    std::fs::write(&path, contents).map_err(|error| RunError::Io { path, error })
}

/// A short name of a map for titles: its folder's name (ROS maps live one per folder), else
/// its file's stem.
pub fn map_name(map: &Path) -> String {
    map.parent()
        .and_then(|p| p.file_name())
        .or_else(|| map.file_stem())
        .map_or_else(|| "map".into(), |s| s.to_string_lossy().into_owned())
}

/// Trains, writes the curves, exports the policy into `run.out`, evaluates it on held-out
/// missions and writes `eval.json`; returns what `eval.json` says. `on_progress` is called a
/// few times a second (with the first learner's progress); returning false stops the run early,
/// with a checkpoint, and the policy learned so far is still exported and evaluated
/// (`interrupted` says so).
pub fn run(
    run: TrainRun,
    on_progress: &mut dyn FnMut(&Progress) -> bool,
) -> Result<TrainSummary, RunError> {
    if !(run.minutes.is_finite() && run.minutes > 0.0) {
        return Err(RunError::Invalid(format!(
            "the budget must be a positive number of minutes, got {}",
            run.minutes
        )));
    }
    if run.eval_episodes == 0 {
        return Err(RunError::Invalid(
            "at least one held-out mission is needed".into(),
        ));
    }
    if !(1..=MAX_LEARNERS).contains(&run.learners) {
        return Err(RunError::Invalid(format!(
            "learners must be between 1 and {MAX_LEARNERS}, got {}",
            run.learners
        )));
    }
    let stop = std::sync::atomic::AtomicBool::new(false);
    let results: Vec<Result<Learned, RunError>> = std::thread::scope(|scope| {
        let others: Vec<_> = (1..run.learners)
            .map(|k| {
                let (run, stop) = (&run, &stop);
                scope.spawn(move || {
                    train_one(run, k, &mut |_| {
                        !stop.load(std::sync::atomic::Ordering::Relaxed)
                    })
                })
            })
            .collect();
        let first = train_one(&run, 0, &mut |p| {
            let go_on = on_progress(p);
            if !go_on {
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
            }
            go_on
        });
        // Should the first learner fail, the others stop too.
        if first.is_err() {
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
        }
        let mut all = vec![first];
        all.extend(others.into_iter().map(|h| {
            h.join()
                .unwrap_or_else(|_| Err(RunError::Invalid("a learner's thread panicked".into())))
        }));
        all
    });
    let learned: Vec<Learned> = results.into_iter().collect::<Result<_, _>>()?;
    // The run's policy: the only learner's, or the one that does best on selection missions
    // (success, then time), from a seed that neither training nor the held-out report uses.
    let eval_seed = learned[0].config.eval_seed;
    let (chosen, selection) = if learned.len() == 1 {
        (0, Vec::new())
    } else {
        let mut scores = Vec::new();
        for k in 0..learned.len() {
            let policy = Policy::load(&run.learner_dir(k))?;
            let h = held_out(
                &policy,
                &run.world,
                run.eval_episodes,
                eval_seed.wrapping_add(2),
                run.goals,
            )?;
            let score = match &run.selector {
                Some(Selector(score)) => score(&policy, &run.world).map_err(RunError::Invalid)?,
                None => h.report.success_rate,
            };
            scores.push((score, h.report.mean_time_to_goal_s));
        }
        let best = (0..scores.len())
            .max_by(|&a, &b| {
                scores[a]
                    .0
                    .total_cmp(&scores[b].0)
                    .then(scores[b].1.total_cmp(&scores[a].1))
                    .then(b.cmp(&a))
            })
            .unwrap_or(0);
        for name in CHOSEN_FILES {
            let from = run.learner_dir(best).join(name);
            let to = run.out.join(name);
            std::fs::copy(&from, &to).map_err(|error| RunError::Io { path: to, error })?;
        }
        (best, scores)
    };
    let counters = learned[chosen].counters.clone();
    let config = learned[chosen].config.clone();
    let interrupted = learned.iter().any(|l| l.interrupted);
    let policy = Policy::load(&run.out)?;
    let evaluation = evaluate(&policy, &run.world, &config, run.eval_episodes, run.goals)?;
    let summary = TrainSummary {
        episodes: counters.episodes,
        env_steps: counters.env_steps,
        grad_steps: counters.grad_steps,
        wall_s: counters.wall_s,
        sessions: counters.sessions,
        interrupted,
        map: run.map.display().to_string(),
        extra_maps: run
            .extra_maps
            .iter()
            .map(|m| m.display().to_string())
            .collect(),
        learners: learned.len(),
        chosen_learner: (learned.len() > 1).then_some(chosen),
        learner_selection: selection
            .iter()
            .map(
                |&(score, mean_time_to_goal_s)| crate::summary::LearnerScore {
                    score,
                    mean_time_to_goal_s,
                },
            )
            .collect(),
        ..TrainSummary::new(evaluation, config)
    };
    // Through `Value`, whose keys are sorted: the file reads the same run after run.
    let json = serde_json::to_value(&summary).and_then(|v| serde_json::to_string_pretty(&v));
    let json = json.map_err(|e| RunError::Io {
        path: run.out.join("eval.json"),
        error: e.into(),
    })?;
    write(run.out.join("eval.json"), format!("{json}\n"))?;
    Ok(summary)
}

/// Learner `k` of `run`: trains (resuming its checkpoint unless the run is fresh), writes its
/// curves and exports its policy into [`TrainRun::learner_dir`]. Learner `k` has the seed
/// `config.seed + k`.
fn train_one(
    run: &TrainRun,
    k: usize,
    on_progress: &mut dyn FnMut(&Progress) -> bool,
) -> Result<Learned, RunError> {
    let dir = run.learner_dir(k);
    std::fs::create_dir_all(&dir).map_err(|error| RunError::Io {
        path: dir.clone(),
        error,
    })?;
    let mut config = run.config.clone();
    config.seed = config.seed.wrapping_add(k as u64);
    let mut learner = Learner::open(LearnerSpec {
        world: Arc::clone(&run.world),
        extra_worlds: run.extra_worlds.clone(),
        hold_out: run.hold_out,
        options: TrainOptions {
            config,
            env: EnvConfig::default(),
            scaling: Scaling::default(),
            out_dir: dir.clone(),
        },
        resume: if run.fresh {
            Resume::Never
        } else {
            Resume::Checkpoint
        },
    })?;
    learner.train(run.minutes * 60.0, on_progress)?;
    let title = format!(
        "TD3 in the mental simulation of {} (β1 = β2 = {})",
        map_name(&run.map),
        learner.trainer().options().config.td3.beta1
    );
    learner.export(
        &dir,
        &title,
        serde_json::json!({ "map": run.map.display().to_string() }),
    )?;
    Ok(Learned {
        counters: learner.trainer().counters().clone(),
        config: learner.trainer().options().config.clone(),
        interrupted: learner.interrupted(),
    })
}

/// Whether [`Learner::open`] continues the checkpoint in the options' directory.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Resume {
    /// Start from scratch.
    Never,
    /// Resume the checkpoint when there is one; one that cannot be resumed is an error.
    Checkpoint,
    /// Resume the checkpoint when there is one and it can be resumed, else start from scratch
    /// (a job that must make progress whatever an earlier attempt left).
    CheckpointOrFresh,
}

/// What [`Learner::open`] trains.
pub struct LearnerSpec {
    /// The world evaluated on (and trained in unless `hold_out`).
    pub world: Arc<World>,
    /// Further worlds sharing the training environments.
    pub extra_worlds: Vec<Arc<World>>,
    /// Train in `extra_worlds` only (when there are any).
    pub hold_out: bool,
    /// Configuration, environment, scaling and the checkpoint directory.
    pub options: TrainOptions,
    /// Whether to continue a checkpoint.
    pub resume: Resume,
}

/// One learner's training, the pipeline `mentalsim train` (once per learner) and the `train`
/// job share: open (start, or resume a checkpoint), [`train`](Self::train) for a wall-clock
/// budget, [`export`](Self::export) the curves and the policy, then evaluate the exported
/// policy on held-out missions ([`evaluate`]).
pub struct Learner {
    trainer: Trainer,
    resumed: bool,
    discarded: Option<String>,
    interrupted: bool,
}

impl Learner {
    /// Starts or resumes, as `spec.resume` says.
    pub fn open(spec: LearnerSpec) -> Result<Self, RunError> {
        let LearnerSpec {
            world,
            extra_worlds,
            hold_out,
            options,
            resume,
        } = spec;
        let checkpointed = resume != Resume::Never && Trainer::has_checkpoint(&options.out_dir);
        let mut discarded = None;
        let (trainer, resumed) = if checkpointed {
            match Trainer::resume(Arc::clone(&world), options.clone()) {
                Ok(t) => (t, true),
                Err(e) if resume == Resume::CheckpointOrFresh => {
                    discarded = Some(e.to_string());
                    (Trainer::new(world, options)?, false)
                }
                Err(e) => return Err(e.into()),
            }
        } else {
            (Trainer::new(world, options)?, false)
        };
        let trainer = if hold_out && !extra_worlds.is_empty() {
            trainer.with_training_worlds(extra_worlds)?
        } else {
            trainer.with_extra_worlds(extra_worlds)?
        };
        Ok(Self {
            trainer,
            resumed,
            discarded,
            interrupted: false,
        })
    }

    /// Why a checkpoint was there but not resumed ([`Resume::CheckpointOrFresh`]).
    pub fn discarded_checkpoint(&self) -> Option<&str> {
        self.discarded.as_deref()
    }

    /// Whether it continued a checkpoint.
    pub fn resumed(&self) -> bool {
        self.resumed
    }

    /// Whether a progress callback stopped training early.
    pub fn interrupted(&self) -> bool {
        self.interrupted
    }

    /// The trainer (counters, evaluations, episodes, options).
    pub fn trainer(&self) -> &Trainer {
        &self.trainer
    }

    /// The trainer, e.g. to set an install guard on its checkpoints.
    pub fn trainer_mut(&mut self) -> &mut Trainer {
        &mut self.trainer
    }

    /// Trains until `budget_s` of wall-clock time (counting earlier sessions) is spent or
    /// `on_progress` returns false (then with a checkpoint).
    pub fn train(
        &mut self,
        budget_s: f64,
        on_progress: &mut dyn FnMut(&Progress) -> bool,
    ) -> Result<(), RunError> {
        let budget = Budget {
            wall_s: Some(budget_s),
            env_steps: None,
        };
        let interrupted = &mut self.interrupted;
        self.trainer.run(budget, &mut |p| {
            let go_on = on_progress(p);
            *interrupted |= !go_on;
            go_on
        })?;
        Ok(())
    }

    /// Writes the curves (`curves.csv`, `curves.png` titled `title`, `evals.csv`) and the
    /// exported policy, with `summary` in its metadata, into `dir`; returns the policy as
    /// robots load it.
    pub fn export(
        &self,
        dir: &Path,
        title: &str,
        summary: serde_json::Value,
    ) -> Result<Policy, RunError> {
        std::fs::create_dir_all(dir).map_err(|error| RunError::Io {
            path: dir.to_path_buf(),
            error,
        })?;
        curves::write_curves(dir, title, self.trainer.episodes())?;
        let mut evals_csv = String::from(
            "env_steps,wall_s,success_rate,collision_rate,timeout_rate,mean_time_to_goal_s,mean_return\n",
        );
        for e in self.trainer.evals() {
            evals_csv.push_str(&format!(
                "{},{:.1},{:.4},{:.4},{:.4},{:.2},{:.2}\n",
                e.env_steps,
                e.wall_s,
                e.report.success_rate,
                e.report.collision_rate,
                e.report.timeout_rate,
                e.report.mean_time_to_goal_s,
                e.report.mean_return
            ));
        }
        write(dir.join("evals.csv"), evals_csv)?;
        self.trainer.export(dir, summary)?;
        Ok(Policy::load(dir)?)
    }
}

/// The held-out evaluation of an exported policy trained with `config`: `episodes` missions
/// from a seed training never used, on `goals` and on the other kind beside them.
pub fn evaluate(
    policy: &Policy,
    world: &Arc<World>,
    config: &TrainConfig,
    episodes: usize,
    goals: Goals,
) -> Result<HeldOut, RunError> {
    Ok(held_out(
        policy,
        world,
        episodes,
        held_out_seed(config),
        goals,
    )?)
}

/// The seed of the held-out evaluation: one neither training nor learner selection uses.
pub fn held_out_seed(config: &TrainConfig) -> u64 {
    config.eval_seed.wrapping_add(1)
}
