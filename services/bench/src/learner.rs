//! Learner throughput: TD3 gradient steps per second of our tch learner beside Stable-Baselines3's
//! TD3 (PyPI), same network sizes, batch size, observation and action sizes and libtorch thread
//! count, measured one after the other in one run on a buffer of random transitions (the
//! learner's speed does not depend on what the transitions mean).

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use learning::replay::{Batch, ReplayBuffer};
use learning::td3::Learner;
use learning::{Td3Config, observation::ACTION_DIM};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::error::BenchError;

/// What to measure.
#[derive(Debug, Clone)]
pub struct LearnerBenchOptions {
    /// Network input size (23 ranges + goal distance and angle).
    pub obs_dim: usize,
    /// Hidden layers of actor and critics.
    pub hidden: Vec<usize>,
    /// Batch size.
    pub batch_size: usize,
    /// Timed gradient steps (after `warmup` untimed ones).
    pub steps: u64,
    /// Untimed gradient steps first.
    pub warmup: u64,
    /// Random transitions in the buffer.
    pub buffer: usize,
    /// libtorch intra-op threads for both (0: libtorch's default).
    pub threads: usize,
    /// Python with `stable-baselines3` installed; `None` skips SB3.
    pub python: Option<PathBuf>,
    /// The SB3 script (`services/bench/scripts/sb3_td3_bench.py`).
    pub script: PathBuf,
}

impl Default for LearnerBenchOptions {
    fn default() -> Self {
        Self {
            obs_dim: 25,
            hidden: vec![256, 256],
            batch_size: 256,
            steps: 2000,
            warmup: 100,
            buffer: 100_000,
            threads: 1,
            python: None,
            script: crate::bench_dir().join("scripts/sb3_td3_bench.py"),
        }
    }
}

/// The figures.
#[derive(Debug, Clone, Serialize)]
pub struct LearnerBenchReport {
    /// Our gradient steps per second.
    pub grad_steps_per_s_ours: f64,
    /// Stable-Baselines3's, if it ran.
    pub grad_steps_per_s_sb3: Option<f64>,
    /// Ours / SB3's.
    pub ratio: Option<f64>,
    /// Why SB3 did not run, or its version.
    pub sb3_status: String,
    /// Timed steps of each.
    pub steps: u64,
    /// Batch size.
    pub batch_size: usize,
    /// Hidden layers.
    pub hidden: Vec<usize>,
    /// Network input size.
    pub obs_dim: usize,
    /// libtorch threads.
    pub threads: usize,
    /// Time of one of our gradient steps, milliseconds.
    pub ms_per_step_ours: f64,
}

/// Runs ours, then SB3.
pub fn run_learner_bench(opts: &LearnerBenchOptions) -> Result<LearnerBenchReport, BenchError> {
    if opts.steps == 0 || opts.batch_size == 0 || opts.buffer < opts.batch_size {
        return Err(BenchError::BadOption(
            "steps and batch size must be positive and the buffer must hold a batch".into(),
        ));
    }
    if opts.threads > 0 {
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_possible_wrap,
            reason = "small"
        )]
        learning::set_torch_threads(opts.threads as i32);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut buffer = ReplayBuffer::new(opts.obs_dim, opts.buffer);
    let mut s = vec![0.0f32; opts.obs_dim];
    let mut s2 = vec![0.0f32; opts.obs_dim];
    for _ in 0..opts.buffer {
        s.iter_mut().for_each(|v| *v = rng.random());
        s2.iter_mut().for_each(|v| *v = rng.random());
        let a: [f32; ACTION_DIM] = [rng.random(), rng.random::<f32>() * 2.0 - 1.0];
        buffer.push(
            &s,
            a,
            a,
            rng.random::<f32>() - 0.5,
            &s2,
            rng.random::<f32>() < 0.02,
        );
    }
    let config = Td3Config {
        hidden: opts.hidden.clone(),
        batch_size: opts.batch_size,
        ..Td3Config::default()
    };
    let mut learner = Learner::new(config, opts.obs_dim, learning::Device::Cpu, 1);
    let mut batch = Batch::default();
    // Sampling is part of a gradient step, as it is in SB3's `train`.
    let mut step = |learner: &mut Learner, rng: &mut ChaCha8Rng| {
        buffer.sample_into(rng, opts.batch_size, &mut batch);
        learner.update(&batch, rng)
    };
    for _ in 0..opts.warmup {
        step(&mut learner, &mut rng);
    }
    let t = Instant::now();
    for _ in 0..opts.steps {
        step(&mut learner, &mut rng);
    }
    let ours_s = t.elapsed().as_secs_f64();
    let ours = opts.steps as f64 / ours_s;

    let (sb3, status) = match &opts.python {
        None => (None, "not run (no Python given)".to_owned()),
        Some(python) => match run_sb3(python, opts) {
            Ok((rate, version)) => (Some(rate), format!("stable-baselines3 {version}")),
            Err(e) => (None, format!("not run: {e}")),
        },
    };
    Ok(LearnerBenchReport {
        grad_steps_per_s_ours: ours,
        grad_steps_per_s_sb3: sb3,
        ratio: sb3.map(|b| ours / b),
        sb3_status: status,
        steps: opts.steps,
        batch_size: opts.batch_size,
        hidden: opts.hidden.clone(),
        obs_dim: opts.obs_dim,
        threads: opts.threads,
        ms_per_step_ours: 1000.0 * ours_s / opts.steps as f64,
    })
}

fn run_sb3(python: &PathBuf, opts: &LearnerBenchOptions) -> Result<(f64, String), String> {
    let hidden = opts
        .hidden
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(",");
    let out = Command::new(python)
        .arg(&opts.script)
        .args(["--obs-dim", &opts.obs_dim.to_string()])
        .args(["--hidden", &hidden])
        .args(["--batch-size", &opts.batch_size.to_string()])
        .args(["--steps", &opts.steps.to_string()])
        .args(["--warmup", &opts.warmup.to_string()])
        .args(["--buffer", &opts.buffer.to_string()])
        .args(["--threads", &opts.threads.to_string()])
        .output()
        .map_err(|e| format!("cannot run {}: {e}", python.display()))?;
    if !out.status.success() {
        return Err(format!(
            "the SB3 script failed: {}",
            String::from_utf8_lossy(&out.stderr)
                .lines()
                .last()
                .unwrap_or("")
        ));
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)
        .map_err(|e| format!("the SB3 script printed no JSON: {e}"))?;
    let rate = v["grad_steps_per_s"]
        .as_f64()
        .ok_or("the SB3 script reported no grad_steps_per_s")?;
    Ok((rate, v["version"].as_str().unwrap_or("?").to_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_run_reports_our_rate() {
        let r = run_learner_bench(&LearnerBenchOptions {
            steps: 20,
            warmup: 2,
            buffer: 512,
            hidden: vec![32, 32],
            ..LearnerBenchOptions::default()
        })
        .expect("runs");
        assert!(r.grad_steps_per_s_ours > 0.0);
        assert!(r.ratio.is_none());
        assert!(
            run_learner_bench(&LearnerBenchOptions {
                steps: 0,
                ..LearnerBenchOptions::default()
            })
            .is_err()
        );
    }
}
