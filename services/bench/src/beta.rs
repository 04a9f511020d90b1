//! The paper's §5.2 experiment (`mentalsim bench beta`): one TD3 training per value of the
//! Eq. 18 regulariser β1 = β2 and per seed, each a full run of [`learning::run`] (its own
//! directory `beta-<β>/seed-<seed>/` with the policy, curves and `eval.json`; a run already
//! there is resumed), then
//!
//! - `beta.md`: one row per run — held-out success on goals in view (the headline), collision
//!   rate, success on goals anywhere, episodes, environment steps, wall time — and per β the
//!   mean success over seeds with its spread;
//! - `beta.png`: reward curves per β, the mean over seeds ± their standard deviation.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use learning::curves::{CurvePoint, PlotError, plot_curves};
use learning::run::{RunError, TrainRun, map_name};
use learning::trainer::Progress;
use learning::{ConfigFileError, Goals, TrainConfig, TrainSummary};
use sim::World;

use crate::error::BenchError;

/// What to run.
#[derive(Clone, Debug)]
pub struct BetaOptions {
    /// ROS map_server YAML of the place.
    pub map: PathBuf,
    /// The robot's TOSM description (Turtle), as the knowledge service holds it.
    pub robot_ttl: Vec<u8>,
    /// The robot's IRI in it.
    pub robot_iri: String,
    /// Minutes per training.
    pub minutes: f64,
    /// Values of β1 = β2.
    pub betas: Vec<f64>,
    /// Seeds per value.
    pub seeds: Vec<u64>,
    /// Output directory: one run per (β, seed), the table and the plot.
    pub out: PathBuf,
    /// Training configuration shared by all runs (JSON over `TrainConfig::fast`).
    pub config: Option<PathBuf>,
    /// Held-out missions of each final evaluation.
    pub eval_episodes: usize,
}

/// Why the experiment stopped.
#[derive(Debug, thiserror::Error)]
pub enum BetaError {
    /// An option is out of range (the message names the command line's flag).
    #[error("{0}")]
    Invalid(String),
    /// The training configuration file is unreadable or invalid.
    #[error(transparent)]
    Config(#[from] ConfigFileError),
    /// The map could not be turned into a mental simulation.
    #[error(transparent)]
    Map(#[from] BenchError),
    /// A run failed.
    #[error(transparent)]
    Run(#[from] RunError),
    /// The plot could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// A file could not be read or written.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        error: std::io::Error,
    },
    /// `stop` was set between runs.
    #[error("stopped")]
    Stopped,
}

/// Trains one policy per (β, seed), then writes `beta.md` (final success per β: mean, spread
/// over seeds) and `beta.png`; returns the Markdown. `stop` (set by SIGINT or SIGTERM) ends
/// the run under way with a checkpoint and its evaluation, then the experiment.
pub fn run_beta_experiment(options: &BetaOptions, stop: &AtomicBool) -> Result<String, BetaError> {
    if options.betas.is_empty() || options.seeds.is_empty() {
        return Err(BetaError::Invalid(
            "give at least one --betas value and one --seeds value".into(),
        ));
    }
    if let Some(b) = options
        .betas
        .iter()
        .find(|b| !(b.is_finite() && **b >= 0.0))
    {
        return Err(BetaError::Invalid(format!(
            "--betas values must be finite and not negative, got {b}"
        )));
    }
    if !(options.minutes.is_finite() && options.minutes > 0.0) {
        return Err(BetaError::Invalid(format!(
            "--minutes must be a positive number, got {}",
            options.minutes
        )));
    }
    if options.eval_episodes == 0 {
        return Err(BetaError::Invalid(
            "--eval-episodes must be at least 1".into(),
        ));
    }
    let mut table = String::from(
        "| β1 = β2 | seed | success, goals in view | collision | success, goals anywhere | episodes | env steps | wall s |\n|---|---|---|---|---|---|---|---|\n",
    );
    let mut summary = String::from(
        "\n| β1 = β2 | mean success, goals in view | min | max | mean success, goals anywhere | seeds |\n|---|---|---|---|---|---|\n",
    );
    let mut series = Vec::new();
    for &beta in &options.betas {
        let mut rates = Vec::new();
        let mut anywhere = Vec::new();
        let mut curves: Vec<Vec<CurvePoint>> = Vec::new();
        for &seed in &options.seeds {
            if stop.load(Ordering::Relaxed) {
                return Err(BetaError::Stopped);
            }
            let out = options
                .out
                .join(format!("beta-{beta}"))
                .join(format!("seed-{seed}"));
            eprintln!(
                "training β = {beta}, seed {seed} for {} min into {}",
                options.minutes,
                out.display()
            );
            let run = train_one(options, beta, seed, &out, stop)?;
            let rate = run.success_rate_on(Goals::InView);
            let detours = run.success_rate_on(Goals::Anywhere);
            rates.push(rate);
            anywhere.push(detours);
            table.push_str(&format!(
                "| {beta} | {seed} | {:.1}% | {:.1}% | {:.1}% | {} | {} | {:.0} |\n",
                rate * 100.0,
                run.collision_rate * 100.0,
                detours * 100.0,
                run.episodes,
                run.env_steps,
                run.wall_s,
            ));
            let csv = out.join("curves.csv");
            let text = std::fs::read_to_string(&csv).map_err(|error| BetaError::Io {
                path: csv.clone(),
                error,
            })?;
            curves.push(read_curve(&text));
        }
        let mean = rates.iter().sum::<f64>() / rates.len() as f64;
        let lo = rates.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = rates.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mean_anywhere = anywhere.iter().sum::<f64>() / anywhere.len() as f64;
        summary.push_str(&format!(
            "| {beta} | {:.1}% | {:.1}% | {:.1}% | {:.1}% | {} |\n",
            mean * 100.0,
            lo * 100.0,
            hi * 100.0,
            mean_anywhere * 100.0,
            rates.len()
        ));
        series.push((format!("β1 = β2 = {beta}"), mean_curve(&curves)));
    }
    plot_curves(
        &options.out.join("beta.png"),
        &format!(
            "Eq. 18 regulariser, {} (mean over seeds ± spread)",
            map_name(&options.map)
        ),
        &series,
    )?;
    let text = format!(
        "# β experiment (paper §5.2) on {}\n\n{} minutes per run; success on held-out missions (goals 2–10 m) with the exported policy: goals in view (reachable in a straight line, the waypoints a roadmap hands the policy) and, beside them, goals anywhere (a third behind walls).\n\n{table}{summary}",
        map_name(&options.map),
        options.minutes
    );
    let md = options.out.join("beta.md");
    std::fs::write(&md, &text).map_err(|error| BetaError::Io { path: md, error })?;
    Ok(text)
}

/// One run: the shared configuration with this seed and β, trained into `out`.
fn train_one(
    options: &BetaOptions,
    beta: f64,
    seed: u64,
    out: &Path,
    stop: &AtomicBool,
) -> Result<TrainSummary, BetaError> {
    let mut config = match &options.config {
        Some(path) => TrainConfig::fast().with_json_file(path)?,
        None => TrainConfig::fast(),
    };
    config.seed = seed;
    config.td3.beta1 = beta;
    config.td3.beta2 = beta;
    config
        .validate()
        .map_err(|e| BetaError::Invalid(format!("invalid training configuration: {e}")))?;
    let run = TrainRun {
        world: load_world(options, seed)?,
        extra_worlds: Vec::new(),
        hold_out: false,
        map: options.map.clone(),
        extra_maps: Vec::new(),
        config,
        out: out.to_owned(),
        minutes: options.minutes,
        fresh: false,
        eval_episodes: options.eval_episodes,
        goals: Goals::InView,
        // One learner per (β, seed): the study is about the seeds.
        learners: 1,
        selector: None,
    };
    if run.resumes() {
        eprintln!("resuming the run checkpointed in {}", out.display());
    }
    // Without a terminal (a log file) a line now and then; with one, quiet.
    let plain = !std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut last_line = Instant::now();
    let mut on_progress = |p: &Progress| {
        if plain && last_line.elapsed() >= Duration::from_secs(15) {
            last_line = Instant::now();
            eprintln!("[{:>6.0} s] {p}", p.counters.wall_s);
        }
        !stop.load(Ordering::Relaxed)
    };
    Ok(learning::run::run(run, &mut on_progress)?)
}

/// The mental simulation of the map with the robot, no furniture.
fn load_world(options: &BetaOptions, seed: u64) -> Result<Arc<World>, BetaError> {
    if !options.map.is_file() {
        return Err(BetaError::Invalid(format!(
            "the map {} does not exist (give a ROS map_server YAML file)",
            options.map.display()
        )));
    }
    Ok(crate::sim::world_from_map(
        &options.map,
        &options.robot_ttl,
        &options.robot_iri,
        0,
        seed,
    )?)
}

/// The mean over seeds of their smoothed curves, the band their spread, as long as the
/// shortest.
fn mean_curve(curves: &[Vec<CurvePoint>]) -> Vec<CurvePoint> {
    let len = curves.iter().map(Vec::len).min().unwrap_or(0);
    (0..len)
        .map(|i| {
            let vals: Vec<f64> = curves.iter().map(|c| c[i].mean).collect();
            let n = vals.len() as f64;
            let m = vals.iter().sum::<f64>() / n;
            let sd = (vals.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n).sqrt();
            CurvePoint {
                mean: m,
                std: sd,
                ..curves[0][i]
            }
        })
        .collect()
}

/// The smoothed curve of a run's `curves.csv`.
fn read_curve(csv: &str) -> Vec<CurvePoint> {
    csv.lines()
        .skip(1)
        .filter_map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            Some(CurvePoint {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curves_are_read_back_and_averaged_over_seeds() {
        let csv = "episode,env_steps,wall_s,reward,outcome,steps,mean,std,success\n\
                   1,10,0.5,1,goal,10,2.0,0.5,1\n\
                   2,20,1.0,1,goal,10,4.0,0.5,1\n";
        let a = read_curve(csv);
        assert_eq!(a.len(), 2);
        assert_eq!((a[1].episode, a[1].env_steps), (2, 20));
        let mut b = a.clone();
        for p in &mut b {
            p.mean += 2.0;
        }
        b.pop();
        let m = mean_curve(&[a, b]);
        assert_eq!(m.len(), 1, "as long as the shortest");
        assert!((m[0].mean - 3.0).abs() < 1e-12 && (m[0].std - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_options_are_refused_naming_the_flag() {
        let options = BetaOptions {
            map: PathBuf::from("/nonexistent/map.yaml"),
            robot_ttl: Vec::new(),
            robot_iri: String::new(),
            minutes: 1.0,
            betas: vec![-1.0],
            seeds: vec![1],
            out: std::env::temp_dir().join("never-written"),
            config: None,
            eval_episodes: 10,
        };
        let stop = AtomicBool::new(false);
        let e = run_beta_experiment(&options, &stop).unwrap_err();
        assert!(e.to_string().contains("--betas"), "{e}");
        let e = run_beta_experiment(
            &BetaOptions {
                betas: vec![0.0],
                ..options
            },
            &stop,
        )
        .unwrap_err();
        assert!(e.to_string().contains("does not exist"), "{e}");
    }
}
