//! `mentalsim train` and `mentalsim eval`: a navigation policy trained in the mental simulation
//! of a ROS map, and an exported policy evaluated on any map. The command line's side only —
//! arguments, the worlds from the maps, the progress bar; the run itself (training, curves,
//! export, held-out evaluation, `eval.json`) is `learning::run`.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use learning::run::TrainRun;
use learning::{Policy, TrainConfig, TrainSummary};
use sim::World;

/// The bundled robot, as the knowledge service loads it.
pub const ROBOT_IRI: &str = "https://mentalsim.dev/data/robots/differential-robot";

/// The bundled robot's TOSM description (Turtle).
pub fn bundled_robot_ttl() -> &'static str {
    knowledge::bundled::BUNDLED
        .iter()
        .find(|b| b.file.starts_with("robots/"))
        .map_or("", |b| b.turtle)
}

/// The mental simulation of a ROS map with the bundled robot.
pub fn load_world(map: &Path, objects: usize, seed: u64) -> anyhow::Result<Arc<World>> {
    if !map.is_file() {
        anyhow::bail!(
            "the map {} does not exist (give a ROS map_server YAML file)",
            map.display()
        );
    }
    Ok(bench::sim::world_from_map(
        map,
        bundled_robot_ttl().as_bytes(),
        ROBOT_IRI,
        objects,
        seed,
    )?)
}

/// What `mentalsim train` was asked.
#[derive(Debug, clap::Args)]
pub struct TrainArgs {
    /// The ROS map_server YAML of the place to train in (and evaluate on).
    #[arg(long)]
    pub map: PathBuf,
    /// Further maps whose simulations share the training environments (repeatable): one policy
    /// for several buildings. Evaluation stays on `--map`.
    #[arg(long = "extra-map")]
    pub extra_maps: Vec<PathBuf>,
    /// Wall-clock budget in minutes (counting earlier sessions of a resumed run).
    #[arg(long, default_value_t = 10.0)]
    pub minutes: f64,
    /// Where the exported policy, curves, checkpoint and eval.json go.
    #[arg(long)]
    pub out: PathBuf,
    /// Training configuration (JSON; any subset of the keys, the preset's values for the rest).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The values the configuration file starts from.
    #[arg(long, value_enum, default_value_t = Preset::Fast)]
    pub preset: Preset,
    /// Seed of the run.
    #[arg(long)]
    pub seed: Option<u64>,
    /// β1 = β2 of Eq. 18.
    #[arg(long)]
    pub beta: Option<f64>,
    /// Start from scratch even if --out holds a checkpoint.
    #[arg(long)]
    pub fresh: bool,
    /// Held-out missions of the final evaluation.
    #[arg(long, default_value_t = 200)]
    pub eval_episodes: usize,
    /// Which held-out goals `eval.json`'s headline figures are about (the other kind is
    /// reported beside them).
    #[arg(long, value_enum, default_value_t = Goals::InView)]
    pub goals: Goals,
    /// Show a progress bar (the command line always does).
    #[arg(skip = true)]
    pub progress: bool,
}

/// Where a training configuration starts.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Preset {
    /// Tuned for the 10-minute target on a 2-core CPU (`TrainConfig::fast`).
    Fast,
    /// The TD3 authors' reference hyperparameters (`TrainConfig::default`).
    Reference,
}

impl Preset {
    fn config(self) -> TrainConfig {
        match self {
            Preset::Fast => TrainConfig::fast(),
            Preset::Reference => TrainConfig::default(),
        }
    }
}

/// Reads the configuration file over the preset and applies the command line's overrides.
pub fn train_config(args: &TrainArgs) -> anyhow::Result<TrainConfig> {
    let preset = args.preset.config();
    let mut config: TrainConfig = match &args.config {
        Some(path) => preset.with_json_file(path)?,
        None => preset,
    };
    if let Some(seed) = args.seed {
        config.seed = seed;
    }
    if let Some(beta) = args.beta {
        config.td3.beta1 = beta;
        config.td3.beta2 = beta;
    }
    config
        .validate()
        .map_err(|e| anyhow::anyhow!("invalid training configuration: {e}"))?;
    Ok(config)
}

/// Trains, exports the policy into `out`, writes the curves and `eval.json`; returns what
/// `eval.json` says. `stop` (set by Ctrl-C or SIGTERM) ends training early with a checkpoint;
/// the policy learned so far is still exported and evaluated.
pub fn train(args: &TrainArgs, stop: &AtomicBool) -> anyhow::Result<TrainSummary> {
    if !(args.minutes.is_finite() && args.minutes > 0.0) {
        anyhow::bail!("--minutes must be a positive number, got {}", args.minutes);
    }
    if args.eval_episodes == 0 {
        anyhow::bail!("--eval-episodes must be at least 1");
    }
    let config = train_config(args)?;
    let world = load_world(&args.map, 0, config.seed)?;
    let extra_worlds = args
        .extra_maps
        .iter()
        .map(|m| load_world(m, 0, config.seed))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let run = TrainRun {
        world,
        extra_worlds,
        map: args.map.clone(),
        extra_maps: args.extra_maps.clone(),
        config,
        out: args.out.clone(),
        minutes: args.minutes,
        fresh: args.fresh,
        eval_episodes: args.eval_episodes,
        goals: args.goals.into(),
    };
    if run.resumes() {
        eprintln!("resuming the run checkpointed in {}", args.out.display());
    }
    let bar = if args.progress {
        let bar = ProgressBar::new(1000);
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% ETA {eta} {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.enable_steady_tick(Duration::from_millis(250));
        bar
    } else {
        ProgressBar::hidden()
    };
    // Without a terminal (a log file, a job) the bar is hidden: print a line now and then.
    let plain = !std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut last_line = std::time::Instant::now();
    let mut on_progress = |p: &learning::trainer::Progress| {
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a permille"
        )]
        bar.set_position((p.fraction_done.unwrap_or(0.0) * 1000.0) as u64);
        let line = p.to_string();
        if plain && last_line.elapsed() >= Duration::from_secs(15) {
            last_line = std::time::Instant::now();
            eprintln!("[{:>6.0} s] {line}", p.counters.wall_s);
        }
        bar.set_message(line);
        !stop.load(Ordering::Relaxed)
    };
    let summary = learning::run::run(run, &mut on_progress);
    bar.finish_and_clear();
    Ok(summary?)
}

/// Which held-out goals the headline figures of `eval.json` are about.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Goals {
    /// Goals 2–10 m away that the robot can reach in a straight line: the waypoints of a
    /// roadmap plan, which is what the policy drives between.
    InView,
    /// Goals 2–10 m away anywhere in the free region, also behind walls, where only a detour
    /// the laser cannot show reaches them.
    Anywhere,
}

impl From<Goals> for learning::Goals {
    fn from(goals: Goals) -> Self {
        match goals {
            Goals::InView => learning::Goals::InView,
            Goals::Anywhere => learning::Goals::Anywhere,
        }
    }
}

/// `mentalsim eval`: an exported policy on a map, written as JSON.
pub fn eval(
    policy_dir: &Path,
    map: &Path,
    episodes: usize,
    seed: u64,
    goals: EvalGoals,
    rollouts: u32,
) -> anyhow::Result<serde_json::Value> {
    if episodes == 0 {
        anyhow::bail!("--episodes must be at least 1");
    }
    let policy = Policy::load(policy_dir)
        .with_context(|| format!("cannot load the policy in {}", policy_dir.display()))?;
    let world = load_world(map, 0, seed)?;
    let edges = match goals {
        EvalGoals::Edges => Some(edge_eval(&world, &policy, seed, rollouts)?),
        EvalGoals::InView | EvalGoals::Anywhere => None,
    };
    let goals = match goals {
        EvalGoals::InView | EvalGoals::Edges => learning::Goals::InView,
        EvalGoals::Anywhere => learning::Goals::Anywhere,
    };
    let learning::HeldOut { report, other, .. } =
        learning::held_out(&policy, &world, episodes, seed, goals)?;
    // Time per control command of the pure-Rust runtime: encode + forward + scale.
    let obs = sim::Observation {
        ranges: vec![3.0; policy.scaling().beams],
        goal_distance: 4.0,
        goal_angle: 0.3,
        velocity: [0.5, 0.1],
    };
    let reps = 2000u32;
    let t = std::time::Instant::now();
    for _ in 0..reps {
        std::hint::black_box(policy.act(std::hint::black_box(&obs))?);
    }
    let per_command_us = t.elapsed().as_secs_f64() * 1e6 / f64::from(reps);
    let mut json = serde_json::json!({
        "goals": goals.name(),
        "success_rate": report.success_rate,
        "collision_rate": report.collision_rate,
        "timeout_rate": report.timeout_rate,
        "mean_time_to_goal_s": report.mean_time_to_goal_s,
        "episodes": report.episodes,
        "env_steps": report.env_steps,
        "wall_s": report.wall_s,
        "control_command_us": per_command_us,
        "by_detour": report.by_detour,
        goals.other().key(): other,
        "map": map.display().to_string(),
        "policy": policy_dir.display().to_string(),
        "seed": seed,
    });
    if let (Some(edges), Some(out)) = (edges, json.as_object_mut()) {
        out.extend(edges);
    }
    Ok(json)
}

/// Which missions `mentalsim eval` measures.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EvalGoals {
    /// Held-out goals 2–10 m away in straight sight (the headline figures; `anywhere` beside).
    InView,
    /// Held-out goals 2–10 m away anywhere in the free region.
    Anywhere,
    /// Every edge of the map's roadmap, both directions, driven by the shielded policy as the
    /// executor would (PRM-RL): `edge_success_rate`, `edges`, `edges_kept`,
    /// `mean_edge_time_s`, beside the in-view figures.
    Edges,
}

/// The policy on every edge of the map's geometric roadmap (n* samples, the plan endpoint's
/// safety margin), as the policy-aware roadmap drives them.
fn edge_eval(
    world: &Arc<World>,
    policy: &Policy,
    seed: u64,
    rollouts: u32,
) -> anyhow::Result<serde_json::Map<String, serde_json::Value>> {
    let cache = rehearsal::RoadmapCache::default();
    let opts = rehearsal::PlanOptions::default();
    let space = rehearsal::config_space(world, &cache, "eval", opts.safety_margin_m)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let params = planning::PrmParams {
        samples: planning::optimal_samples(space.free_area_m2),
        seed,
        ..planning::PrmParams::default()
    };
    let (roadmap, _) = cache
        .roadmap("eval", &space, &params)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let rollout = rehearsal::EdgeRolloutParams {
        rollouts,
        seed,
        ..rehearsal::EdgeRolloutParams::default()
    };
    let policy = Arc::new(policy.clone());
    let t = std::time::Instant::now();
    let (_, report) = rehearsal::policy_roadmap(world, &roadmap, &policy, &rollout)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let wall_s = t.elapsed().as_secs_f64();
    let undirected = report.edges.len() / 2;
    // An edge is kept when the policy drives it in both directions.
    let kept = report
        .edges
        .chunks(2)
        .filter(|pair| {
            pair.iter()
                .all(|e| e.success_rate() >= rollout.keep_threshold)
        })
        .count();
    let worst: Vec<serde_json::Value> = {
        let mut dropped: Vec<&rehearsal::EdgeStat> = report.dropped().collect();
        dropped.sort_by(|a, b| a.success_rate().total_cmp(&b.success_rate()));
        dropped
            .iter()
            .take(20)
            .map(|e| {
                serde_json::json!({
                    "from": e.from, "to": e.to, "length_m": e.length_m,
                    "success_rate": e.success_rate(), "collisions": e.collisions,
                })
            })
            .collect()
    };
    let mut out = serde_json::Map::new();
    for (k, v) in [
        (
            "edge_success_rate",
            serde_json::json!(report.edge_success_rate()),
        ),
        ("edges", serde_json::json!(undirected)),
        ("edges_kept", serde_json::json!(kept)),
        (
            "edge_directions_kept",
            serde_json::json!(report.kept().count()),
        ),
        (
            "mean_edge_time_s",
            serde_json::json!(report.mean_edge_time_s()),
        ),
        ("edge_rollouts", serde_json::json!(rollouts)),
        (
            "edge_keep_threshold",
            serde_json::json!(rollout.keep_threshold),
        ),
        ("edge_steps", serde_json::json!(report.steps)),
        ("edge_wall_s", serde_json::json!(wall_s)),
        ("roadmap_nodes", serde_json::json!(roadmap.nodes().count())),
        ("edges_dropped_worst", serde_json::Value::Array(worst)),
    ] {
        out.insert(k.to_owned(), v);
    }
    Ok(out)
}
