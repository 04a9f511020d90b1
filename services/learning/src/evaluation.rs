//! Evaluation of a policy on a fixed set of missions: success rate, collision rate and mean
//! time to goal. Works with any [`BatchActor`]: the tch learner during training, the pure-Rust
//! [`Policy`] after export.

use std::sync::Arc;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use sim::{EnvConfig, EnvError, NavEnv, Outcome, Pose2, World};

use crate::observation::{ACTION_DIM, Scaling};
use crate::policy::Policy;

/// Something that maps a batch of scaled inputs to network outputs.
pub trait BatchActor {
    /// Outputs (`n × 2`, linear in [0, 1], angular in [-1, 1]) for `n` inputs laid out
    /// row-major in `inputs`.
    fn act_batch(&self, inputs: &[f32], n: usize, out: &mut Vec<f32>);
}

impl BatchActor for Policy {
    fn act_batch(&self, inputs: &[f32], n: usize, out: &mut Vec<f32>) {
        out.clear();
        let dim = self.scaling().input_len();
        for row in inputs.chunks_exact(dim).take(n) {
            // The input length is the policy's by construction.
            let y = self.forward(row).unwrap_or([0.0; ACTION_DIM]);
            out.extend_from_slice(&y);
        }
    }
}

/// A mission of the evaluation set.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Mission {
    /// Start pose.
    pub start: Pose2,
    /// Goal position.
    pub goal: (f64, f64),
}

/// `count` random missions in the world's largest free region, goals within the configured
/// distance range, drawn from `seed` alone: the same seed gives the same set.
pub fn mission_set(
    world: &Arc<World>,
    env: &EnvConfig,
    count: usize,
    seed: u64,
) -> Result<Vec<Mission>, EnvError> {
    let mut sampler = NavEnv::new(Arc::clone(world), env.clone(), seed)?;
    (0..count)
        .map(|_| {
            sampler
                .sample_start_goal()
                .map(|(start, goal)| Mission { start, goal })
        })
        .collect()
}

/// How a policy did on a mission set.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// Share of missions that reached the goal.
    pub success_rate: f64,
    /// Share that ended in a collision.
    pub collision_rate: f64,
    /// Share that ran out of steps.
    pub timeout_rate: f64,
    /// Missions run.
    pub episodes: usize,
    /// Environment steps taken.
    pub env_steps: u64,
    /// Mean simulated time to goal over successes, seconds (0 without successes).
    pub mean_time_to_goal_s: f64,
    /// Mean undiscounted return.
    pub mean_return: f64,
    /// Wall-clock time of the evaluation, seconds.
    pub wall_s: f64,
    /// Success by how far the shortest path is longer than the straight line (only from
    /// [`evaluate_held_out`]): a policy that sees only its laser finds detours hardest.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub by_detour: Vec<DetourBucket>,
    /// Whether the commands went through the collision shield (`sim::shield`), as a policy
    /// trained behind it is evaluated: it drives that way in every validation.
    #[serde(default)]
    pub shielded: bool,
}

/// Missions whose shortest path is between `min` and `max` times the straight distance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DetourBucket {
    /// Lower bound of path / straight distance.
    pub min: f64,
    /// Upper bound (exclusive; infinite for the last bucket).
    pub max: f64,
    /// Missions in the bucket.
    pub missions: usize,
    /// Share of them that reached the goal.
    pub success_rate: f64,
}

/// Time limit of held-out missions, steps (60 s at the paper's 0.1 s control period): a 10 m
/// goal behind a wall can need a 30 m path.
pub const HELD_OUT_MAX_STEPS: u32 = 600;

/// The held-out evaluation `mentalsim train` ends with and `mentalsim eval` runs: `episodes`
/// random missions with goals 2–10 m away in the world's free region, drawn from `seed`, with a
/// 60-second limit, run by `policy`; successes are also broken down by detour. With `in_view`,
/// only goals the robot can reach in a straight line (a roadmap edge's waypoints); otherwise
/// also goals behind walls.
pub fn evaluate_held_out(
    policy: &Policy,
    world: &Arc<World>,
    episodes: usize,
    seed: u64,
    in_view: bool,
) -> Result<EvalReport, EnvError> {
    let env = EnvConfig {
        beams: policy.scaling().beams,
        goal_distance: (2.0, 10.0),
        goals_in_view: in_view,
        max_steps: HELD_OUT_MAX_STEPS,
        ..EnvConfig::default()
    };
    let missions = mission_set(world, &env, episodes, seed)?;
    // A policy trained behind the shield is measured behind it, as it will drive.
    let trained_shielded = policy.metadata().training["config"]["shielded"] == true;
    let shield = trained_shielded
        .then(|| sim::shield::Shield::new(world, policy.scaling().beams))
        .flatten();
    let (mut report, outcomes) = run(
        policy,
        world,
        &env,
        policy.scaling(),
        &missions,
        seed,
        shield.as_ref(),
    )?;
    let bounds = [1.0, 1.1, 1.5, 2.0, f64::INFINITY];
    let mut counts = vec![(0usize, 0usize); bounds.len() - 1];
    for (m, o) in missions.iter().zip(&outcomes) {
        let straight = (m.goal.0 - m.start.x).hypot(m.goal.1 - m.start.y).max(1e-9);
        let field = sim::PathField::new(world, m.goal, 0.1);
        let ratio = field.distance(m.start.x, m.start.y).unwrap_or(straight) / straight;
        let k = bounds
            .windows(2)
            .position(|w| ratio < w[1])
            .unwrap_or(bounds.len() - 2);
        counts[k].0 += 1;
        counts[k].1 += usize::from(*o == Outcome::ReachedGoal);
    }
    {
        report.by_detour = counts
            .iter()
            .zip(bounds.windows(2))
            .map(|(&(n, ok), w)| DetourBucket {
                min: w[0],
                max: w[1],
                missions: n,
                success_rate: if n == 0 { 0.0 } else { ok as f64 / n as f64 },
            })
            .collect();
    }
    Ok(report)
}

/// Runs every mission once with `actor` (no exploration noise; the environment's own sensor and
/// actuation noise stays on, as on a real robot), all missions stepped together so the actor is
/// called once per step for the whole batch.
pub fn evaluate(
    actor: &dyn BatchActor,
    world: &Arc<World>,
    env: &EnvConfig,
    scaling: &Scaling,
    missions: &[Mission],
    seed: u64,
) -> Result<EvalReport, EnvError> {
    run(actor, world, env, scaling, missions, seed, None).map(|(report, _)| report)
}

/// [`evaluate`] with every command passed through `shield` first.
pub fn evaluate_shielded(
    actor: &dyn BatchActor,
    world: &Arc<World>,
    env: &EnvConfig,
    scaling: &Scaling,
    missions: &[Mission],
    seed: u64,
    shield: Option<&sim::shield::Shield>,
) -> Result<EvalReport, EnvError> {
    run(actor, world, env, scaling, missions, seed, shield).map(|(report, _)| report)
}

/// [`evaluate`], with each mission's outcome.
fn run(
    actor: &dyn BatchActor,
    world: &Arc<World>,
    env: &EnvConfig,
    scaling: &Scaling,
    missions: &[Mission],
    seed: u64,
    shield: Option<&sim::shield::Shield>,
) -> Result<(EvalReport, Vec<Outcome>), EnvError> {
    let started = Instant::now();
    let dim = scaling.input_len();
    let mut envs = Vec::with_capacity(missions.len());
    let mut inputs = vec![0.0f32; missions.len() * dim];
    for (i, m) in missions.iter().enumerate() {
        let mut e = NavEnv::new(Arc::clone(world), env.clone(), sim::env_seed(seed, i))?;
        let obs = e.reset(m.start, m.goal)?;
        scaling.encode_into(&obs, &mut inputs[i * dim..(i + 1) * dim]);
        envs.push(e);
    }
    let mut running: Vec<usize> = (0..missions.len()).collect();
    let mut outcome = vec![Outcome::Running; missions.len()];
    let mut time_s = vec![0.0; missions.len()];
    let mut returns = vec![0.0; missions.len()];
    let mut steps = 0u64;
    let mut batch = Vec::new();
    let mut out = Vec::new();
    while !running.is_empty() {
        batch.clear();
        for &i in &running {
            batch.extend_from_slice(&inputs[i * dim..(i + 1) * dim]);
        }
        actor.act_batch(&batch, running.len(), &mut out);
        let mut still = Vec::with_capacity(running.len());
        for (k, &i) in running.iter().enumerate() {
            let y = [out[k * 2], out[k * 2 + 1]];
            let mut command = scaling.command(y);
            if let Some(shield) = shield {
                let seen = scaling.decode(&inputs[i * dim..(i + 1) * dim]);
                command = shield.filter(command, &seen, f64::from(scaling.angular_max));
            }
            let r = envs[i].step(command);
            steps += 1;
            returns[i] += r.reward;
            scaling.encode_into(&r.observation, &mut inputs[i * dim..(i + 1) * dim]);
            if r.done {
                outcome[i] = r.info.outcome;
                time_s[i] = r.info.time_s;
            } else {
                still.push(i);
            }
        }
        running = still;
    }
    let n = missions.len().max(1);
    let share = |o: Outcome| outcome.iter().filter(|&&x| x == o).count() as f64 / n as f64;
    let successes: Vec<f64> = outcome
        .iter()
        .zip(&time_s)
        .filter(|(o, _)| **o == Outcome::ReachedGoal)
        .map(|(_, t)| *t)
        .collect();
    let mean = |v: &[f64]| {
        if v.is_empty() {
            0.0
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let report = EvalReport {
        success_rate: share(Outcome::ReachedGoal),
        collision_rate: share(Outcome::Collision),
        timeout_rate: share(Outcome::TimeLimit),
        episodes: missions.len(),
        env_steps: steps,
        mean_time_to_goal_s: mean(&successes),
        mean_return: mean(&returns),
        wall_s: started.elapsed().as_secs_f64(),
        by_detour: Vec::new(),
        shielded: shield.is_some(),
    };
    Ok((report, outcome))
}
