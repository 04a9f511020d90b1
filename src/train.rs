//! `mentalsim train` and `mentalsim eval`: a navigation policy trained in the mental simulation
//! of a ROS map, and an exported policy evaluated on any map.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use learning::trainer::{Budget, TrainOptions, Trainer};
use learning::{Policy, Scaling, TrainConfig};
use sim::{EnvConfig, World};

/// The bundled robot, as the knowledge service loads it.
const ROBOT_IRI: &str = "https://mentalsim.dev/data/robots/differential-robot";

fn bundled_robot_ttl() -> &'static str {
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
        Some(path) => {
            let text = std::fs::read_to_string(path).with_context(|| {
                format!("cannot read the training configuration {}", path.display())
            })?;
            let top: serde_json::Value = serde_json::from_str(&text)
                .with_context(|| format!("invalid training configuration {}", path.display()))?;
            preset.with_json(top).map_err(|e| {
                anyhow::anyhow!("invalid training configuration {}: {e}", path.display())
            })?
        }
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

/// Trains, exports the policy into `out`, writes the curves and `eval.json`; returns the JSON.
pub fn train(args: &TrainArgs, stop: &AtomicBool) -> anyhow::Result<serde_json::Value> {
    if !(args.minutes.is_finite() && args.minutes > 0.0) {
        anyhow::bail!("--minutes must be a positive number, got {}", args.minutes);
    }
    if args.eval_episodes == 0 {
        anyhow::bail!("--eval-episodes must be at least 1");
    }
    let config = train_config(args)?;
    let config_seed = config.seed;
    let world = load_world(&args.map, 0, config.seed)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let options = TrainOptions {
        config,
        env: EnvConfig::default(),
        scaling: Scaling::default(),
        out_dir: args.out.clone(),
    };
    let extra = args
        .extra_maps
        .iter()
        .map(|m| load_world(m, 0, config_seed))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let trainer = if !args.fresh && Trainer::has_checkpoint(&args.out) {
        eprintln!("resuming the run checkpointed in {}", args.out.display());
        Trainer::resume(Arc::clone(&world), options)?
    } else {
        Trainer::new(Arc::clone(&world), options)?
    };
    let mut trainer = trainer.with_extra_worlds(extra)?;
    let budget = Budget {
        wall_s: Some(args.minutes * 60.0),
        env_steps: None,
    };
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
        let eval = p
            .last_eval
            .as_ref()
            .map(|e| format!(" eval {:.0}%", e.report.success_rate * 100.0))
            .unwrap_or_default();
        let line = format!(
            "steps {} episodes {} grad steps {} success {:.0}% reward {:.1}{eval}",
            p.counters.env_steps,
            p.counters.episodes,
            p.counters.grad_steps,
            p.success_rate_100 * 100.0,
            p.mean_reward_100,
        );
        if plain && last_line.elapsed() >= Duration::from_secs(15) {
            last_line = std::time::Instant::now();
            eprintln!("[{:>6.0} s] {line}", p.counters.wall_s);
        }
        bar.set_message(line);
        !stop.load(Ordering::Relaxed)
    };
    trainer.run(budget, &mut on_progress)?;
    bar.finish_and_clear();
    let interrupted = stop.load(Ordering::Relaxed);
    let counters = trainer.counters().clone();

    // Curves.
    let episodes = trainer.episodes();
    std::fs::write(
        args.out.join("curves.csv"),
        learning::curves::curves_csv(episodes),
    )?;
    let title = format!(
        "TD3 in the mental simulation of {} (β1 = β2 = {})",
        map_name(&args.map),
        trainer.options().config.td3.beta1
    );
    learning::curves::plot_curves(
        &args.out.join("curves.png"),
        &title,
        &[("reward".into(), learning::curves::smooth(episodes))],
    )?;
    let mut evals_csv = String::from(
        "env_steps,wall_s,success_rate,collision_rate,timeout_rate,mean_time_to_goal_s,mean_return\n",
    );
    for e in trainer.evals() {
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
    std::fs::write(args.out.join("evals.csv"), evals_csv)?;

    // Export, then evaluate the exported policy (the pure-Rust runtime robots embed) on
    // held-out missions drawn from a seed training never used.
    trainer.export(
        &args.out,
        serde_json::json!({ "map": args.map.display().to_string() }),
    )?;
    let policy = Policy::load(&args.out)?;
    let held_out_seed = trainer.options().config.eval_seed.wrapping_add(1);
    let (report, other) = held_out(
        &policy,
        &world,
        args.eval_episodes,
        held_out_seed,
        args.goals,
    )?;
    let json = serde_json::json!({
        "goals": args.goals.name(),
        "success_rate": report.success_rate,
        "collision_rate": report.collision_rate,
        "timeout_rate": report.timeout_rate,
        "mean_time_to_goal_s": report.mean_time_to_goal_s,
        "eval_episodes": report.episodes,
        args.goals.other().key(): other,
        "episodes": counters.episodes,
        "env_steps": counters.env_steps,
        "grad_steps": counters.grad_steps,
        "wall_s": counters.wall_s,
        "sessions": counters.sessions,
        "interrupted": interrupted,
        "map": args.map.display().to_string(),
        "extra_maps": args.extra_maps.iter().map(|m| m.display().to_string()).collect::<Vec<_>>(),
        "seed": trainer.options().config.seed,
        "beta": trainer.options().config.td3.beta1,
        "evaluation": report,
        "config": trainer.options().config,
    });
    std::fs::write(
        args.out.join("eval.json"),
        format!("{}\n", serde_json::to_string_pretty(&json)?),
    )?;
    Ok(json)
}

fn map_name(map: &Path) -> String {
    map.parent()
        .and_then(|p| p.file_name())
        .or_else(|| map.file_stem())
        .map_or_else(|| "map".into(), |s| s.to_string_lossy().into_owned())
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

impl Goals {
    fn name(self) -> &'static str {
        match self {
            Goals::InView => "in-view",
            Goals::Anywhere => "anywhere",
        }
    }

    /// The key under which `eval.json` reports this kind when it is not the headline.
    fn key(self) -> &'static str {
        match self {
            Goals::InView => "goals_in_view",
            Goals::Anywhere => "goals_anywhere",
        }
    }

    fn other(self) -> Goals {
        match self {
            Goals::InView => Goals::Anywhere,
            Goals::Anywhere => Goals::InView,
        }
    }
}

/// The held-out evaluation on `goals`, and a summary of the same on the other kind of goals
/// (drawn from the same seed), so that `eval.json` always shows both.
fn held_out(
    policy: &Policy,
    world: &Arc<World>,
    episodes: usize,
    seed: u64,
    goals: Goals,
) -> anyhow::Result<(learning::EvalReport, serde_json::Value)> {
    let report =
        learning::evaluate_held_out(policy, world, episodes, seed, goals == Goals::InView)?;
    let other = learning::evaluate_held_out(
        policy,
        world,
        episodes,
        seed,
        goals.other() == Goals::InView,
    )?;
    let summary = serde_json::json!({
        "success_rate": other.success_rate,
        "collision_rate": other.collision_rate,
        "timeout_rate": other.timeout_rate,
        "mean_time_to_goal_s": other.mean_time_to_goal_s,
        "episodes": other.episodes,
        "by_detour": other.by_detour,
    });
    Ok((report, summary))
}

/// `mentalsim eval`: an exported policy on a map, written as JSON.
pub fn eval(
    policy_dir: &Path,
    map: &Path,
    episodes: usize,
    seed: u64,
    goals: Goals,
) -> anyhow::Result<serde_json::Value> {
    if episodes == 0 {
        anyhow::bail!("--episodes must be at least 1");
    }
    let policy = Policy::load(policy_dir)
        .with_context(|| format!("cannot load the policy in {}", policy_dir.display()))?;
    let world = load_world(map, 0, seed)?;
    let (report, other) = held_out(&policy, &world, episodes, seed, goals)?;
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
    Ok(serde_json::json!({
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
    }))
}

/// What `mentalsim bench beta` was asked: the paper's §5.2 experiment.
#[derive(Debug)]
pub struct BetaArgs {
    /// ROS map_server YAML of the place.
    pub map: PathBuf,
    /// Minutes per training.
    pub minutes: f64,
    /// Values of β1 = β2.
    pub betas: Vec<f64>,
    /// Seeds per value.
    pub seeds: Vec<u64>,
    /// Output directory: one run per (β, seed), the table and the plot.
    pub out: PathBuf,
    /// Training configuration shared by all runs.
    pub config: Option<PathBuf>,
    /// Held-out missions of each final evaluation.
    pub eval_episodes: usize,
}

/// Trains one policy per (β, seed), then writes `beta.md` (final success per β: mean, spread
/// over seeds) and `beta.png` (reward curves, mean over seeds ± their standard deviation).
pub fn beta_experiment(args: &BetaArgs, stop: &AtomicBool) -> anyhow::Result<String> {
    use learning::curves::{CurvePoint, plot_curves};
    if args.betas.is_empty() || args.seeds.is_empty() {
        anyhow::bail!("give at least one --betas value and one --seeds value");
    }
    if let Some(b) = args.betas.iter().find(|b| !(b.is_finite() && **b >= 0.0)) {
        anyhow::bail!("--betas values must be finite and not negative, got {b}");
    }
    let mut table = String::from(
        "| β1 = β2 | seed | success, goals in view | collision | success, goals anywhere | episodes | env steps | wall s |\n|---|---|---|---|---|---|---|---|\n",
    );
    let mut summary = String::from(
        "\n| β1 = β2 | mean success, goals in view | min | max | mean success, goals anywhere | seeds |\n|---|---|---|---|---|---|\n",
    );
    let mut series = Vec::new();
    for &beta in &args.betas {
        let mut rates = Vec::new();
        let mut anywhere = Vec::new();
        let mut curves: Vec<Vec<CurvePoint>> = Vec::new();
        for &seed in &args.seeds {
            if stop.load(Ordering::Relaxed) {
                anyhow::bail!("stopped");
            }
            let out = args
                .out
                .join(format!("beta-{beta}"))
                .join(format!("seed-{seed}"));
            eprintln!(
                "training β = {beta}, seed {seed} for {} min into {}",
                args.minutes,
                out.display()
            );
            let run = TrainArgs {
                map: args.map.clone(),
                extra_maps: Vec::new(),
                minutes: args.minutes,
                out: out.clone(),
                config: args.config.clone(),
                preset: Preset::Fast,
                seed: Some(seed),
                beta: Some(beta),
                fresh: false,
                eval_episodes: args.eval_episodes,
                goals: Goals::InView,
                progress: false,
            };
            let json = train(&run, stop)?;
            let rate = json["success_rate"].as_f64().unwrap_or(0.0);
            rates.push(rate);
            let detours = json["goals_anywhere"]["success_rate"]
                .as_f64()
                .unwrap_or(0.0);
            anywhere.push(detours);
            table.push_str(&format!(
                "| {beta} | {seed} | {:.1}% | {:.1}% | {:.1}% | {} | {} | {:.0} |\n",
                rate * 100.0,
                json["collision_rate"].as_f64().unwrap_or(0.0) * 100.0,
                detours * 100.0,
                json["episodes"],
                json["env_steps"],
                json["wall_s"].as_f64().unwrap_or(0.0),
            ));
            let state = std::fs::read_to_string(out.join("curves.csv"))?;
            curves.push(read_curve(&state));
        }
        #[allow(clippy::cast_precision_loss, reason = "a few seeds")]
        let mean = rates.iter().sum::<f64>() / rates.len() as f64;
        let lo = rates.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = rates.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        #[allow(clippy::cast_precision_loss, reason = "a few seeds")]
        let mean_anywhere = anywhere.iter().sum::<f64>() / anywhere.len() as f64;
        summary.push_str(&format!(
            "| {beta} | {:.1}% | {:.1}% | {:.1}% | {:.1}% | {} |\n",
            mean * 100.0,
            lo * 100.0,
            hi * 100.0,
            mean_anywhere * 100.0,
            rates.len()
        ));
        // Mean over seeds of the moving average, band = spread over seeds.
        let len = curves.iter().map(Vec::len).min().unwrap_or(0);
        let points: Vec<CurvePoint> = (0..len)
            .map(|i| {
                let vals: Vec<f64> = curves.iter().map(|c| c[i].mean).collect();
                #[allow(clippy::cast_precision_loss, reason = "a few seeds")]
                let n = vals.len() as f64;
                let m = vals.iter().sum::<f64>() / n;
                let sd = (vals.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n).sqrt();
                CurvePoint {
                    mean: m,
                    std: sd,
                    ..curves[0][i]
                }
            })
            .collect();
        series.push((format!("β1 = β2 = {beta}"), points));
    }
    plot_curves(
        &args.out.join("beta.png"),
        &format!(
            "Eq. 18 regulariser, {} (mean over seeds ± spread)",
            map_name(&args.map)
        ),
        &series,
    )?;
    let text = format!(
        "# β experiment (paper §5.2) on {}\n\n{} minutes per run; success on held-out missions (goals 2–10 m) with the exported policy: goals in view (reachable in a straight line, the waypoints a roadmap hands the policy) and, beside them, goals anywhere (a third behind walls).\n\n{table}{summary}",
        map_name(&args.map),
        args.minutes
    );
    std::fs::write(args.out.join("beta.md"), &text)?;
    Ok(text)
}

/// The smoothed curve of a run's `curves.csv`.
fn read_curve(csv: &str) -> Vec<learning::curves::CurvePoint> {
    csv.lines()
        .skip(1)
        .filter_map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            Some(learning::curves::CurvePoint {
                episode: f.first()?.parse().ok()?,
                env_steps: f.get(1)?.parse().ok()?,
                wall_s: f.get(2)?.parse().ok()?,
                mean: f.get(6)?.parse().ok()?,
                std: f.get(7)?.parse().ok()?,
                success: f.get(8)?.parse().ok()?,
            })
        })
        .collect()
}
