//! What a run reports: [`TrainSummary`], the figures of `eval.json` (the exported policy on
//! held-out missions, and the run's counters and settings), and [`held_out`], the held-out
//! evaluation on one kind of [`Goals`] with the other kind's figures ([`GoalsSummary`]) beside
//! it, so that every report shows both.
//!
//! Pure Rust: `mentalsim eval` and anything else that holds an exported [`Policy`] use it
//! without libtorch.

use std::sync::Arc;

use serde::{Deserialize, Serialize};
use sim::{EnvError, World};

use crate::config::TrainConfig;
use crate::evaluation::{DetourBucket, EvalReport, evaluate_held_out};
use crate::policy::Policy;

/// Which held-out goals a report's headline figures are about.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Goals {
    /// Goals 2–10 m away that the robot can reach in a straight line: the waypoints of a
    /// roadmap plan, which is what the policy drives between.
    InView,
    /// Goals 2–10 m away anywhere in the free region, also behind walls, where only a detour
    /// the laser cannot show reaches them.
    Anywhere,
}

impl Goals {
    /// The name reports use (`in-view`, `anywhere`).
    pub fn name(self) -> &'static str {
        match self {
            Goals::InView => "in-view",
            Goals::Anywhere => "anywhere",
        }
    }

    /// The key under which a report shows this kind when it is not the headline
    /// (`goals_in_view`, `goals_anywhere`).
    pub fn key(self) -> &'static str {
        match self {
            Goals::InView => "goals_in_view",
            Goals::Anywhere => "goals_anywhere",
        }
    }

    /// The other kind.
    pub fn other(self) -> Goals {
        match self {
            Goals::InView => Goals::Anywhere,
            Goals::Anywhere => Goals::InView,
        }
    }

    /// Whether goals are reachable in a straight line.
    pub fn in_view(self) -> bool {
        self == Goals::InView
    }
}

/// A held-out evaluation's figures on the kind of goals that is not the headline.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GoalsSummary {
    /// Share of missions that reached the goal.
    pub success_rate: f64,
    /// Share that ended in a collision.
    pub collision_rate: f64,
    /// Share that ran out of steps.
    pub timeout_rate: f64,
    /// Mean simulated time to goal over successes, seconds.
    pub mean_time_to_goal_s: f64,
    /// Missions run.
    pub episodes: usize,
    /// Success by detour ratio.
    pub by_detour: Vec<DetourBucket>,
}

impl From<&EvalReport> for GoalsSummary {
    fn from(r: &EvalReport) -> Self {
        Self {
            success_rate: r.success_rate,
            collision_rate: r.collision_rate,
            timeout_rate: r.timeout_rate,
            mean_time_to_goal_s: r.mean_time_to_goal_s,
            episodes: r.episodes,
            by_detour: r.by_detour.clone(),
        }
    }
}

/// The held-out evaluation of a policy on one kind of goals, with the other kind beside it.
#[derive(Clone, Debug, PartialEq)]
pub struct HeldOut {
    /// The headline kind.
    pub goals: Goals,
    /// The evaluation on it.
    pub report: EvalReport,
    /// The same number of missions, from the same seed, on the other kind.
    pub other: GoalsSummary,
}

/// Evaluates `policy` on `episodes` held-out missions from `seed` on `goals`, and on the
/// other kind of goals (see [`evaluate_held_out`]).
pub fn held_out(
    policy: &Policy,
    world: &Arc<World>,
    episodes: usize,
    seed: u64,
    goals: Goals,
) -> Result<HeldOut, EnvError> {
    let report = evaluate_held_out(policy, world, episodes, seed, goals.in_view())?;
    let other = evaluate_held_out(policy, world, episodes, seed, goals.other().in_view())?;
    Ok(HeldOut {
        goals,
        report,
        other: GoalsSummary::from(&other),
    })
}

/// A training run's report, written as `eval.json` beside the exported policy: the held-out
/// evaluation of the exported policy (headline kind of goals, the other kind under its key),
/// the run's counters and its settings.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrainSummary {
    /// The headline kind of goals.
    pub goals: Goals,
    /// Headline: share of held-out missions that reached the goal.
    pub success_rate: f64,
    /// Headline: share that ended in a collision.
    pub collision_rate: f64,
    /// Headline: share that ran out of steps.
    pub timeout_rate: f64,
    /// Headline: mean simulated time to goal over successes, seconds.
    pub mean_time_to_goal_s: f64,
    /// Held-out missions run (of each kind).
    pub eval_episodes: usize,
    /// Goals in view, when the headline is goals anywhere.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub goals_in_view: Option<GoalsSummary>,
    /// Goals anywhere, when the headline is goals in view.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub goals_anywhere: Option<GoalsSummary>,
    /// Training episodes, over all sessions.
    pub episodes: u64,
    /// Environment steps, over all sessions.
    pub env_steps: u64,
    /// Gradient steps, over all sessions.
    pub grad_steps: u64,
    /// Wall-clock seconds of training, over all sessions.
    pub wall_s: f64,
    /// Sessions of the run (1 + resumes).
    pub sessions: u32,
    /// The run was stopped before its budget was spent.
    pub interrupted: bool,
    /// The map trained and evaluated on.
    pub map: String,
    /// Further maps that shared the training.
    pub extra_maps: Vec<String>,
    /// The run's seed.
    pub seed: u64,
    /// β1 = β2 of Eq. 18.
    pub beta: f64,
    /// The headline evaluation in full.
    pub evaluation: EvalReport,
    /// The training configuration (of the chosen learner: its seed).
    pub config: TrainConfig,
    /// Learners trained side by side (one per core).
    pub learners: usize,
    /// Which of them made the policy, when there were several.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chosen_learner: Option<usize>,
    /// Each learner's exported policy on the selection missions, when there were several.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub learner_selection: Vec<LearnerScore>,
}

/// A learner's exported policy on the selection missions.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LearnerScore {
    /// What the learners were compared by: the run's selector's score (`mentalsim train`:
    /// per-edge success on the held-out world's roadmap), else the share of selection missions
    /// that reached the goal.
    pub score: f64,
    /// Mean simulated time to goal on the selection missions over successes, seconds.
    pub mean_time_to_goal_s: f64,
}

impl TrainSummary {
    /// A summary of `held_out` with everything else at zero or empty, for the caller to fill
    /// in (counters, maps, settings).
    pub fn new(held_out: HeldOut, config: TrainConfig) -> Self {
        let HeldOut {
            goals,
            report,
            other,
        } = held_out;
        let (goals_in_view, goals_anywhere) = match goals {
            Goals::InView => (None, Some(other)),
            Goals::Anywhere => (Some(other), None),
        };
        Self {
            goals,
            success_rate: report.success_rate,
            collision_rate: report.collision_rate,
            timeout_rate: report.timeout_rate,
            mean_time_to_goal_s: report.mean_time_to_goal_s,
            eval_episodes: report.episodes,
            goals_in_view,
            goals_anywhere,
            episodes: 0,
            env_steps: 0,
            grad_steps: 0,
            wall_s: 0.0,
            sessions: 0,
            interrupted: false,
            map: String::new(),
            extra_maps: Vec::new(),
            seed: config.seed,
            beta: config.td3.beta1,
            evaluation: report,
            config,
            learners: 1,
            chosen_learner: None,
            learner_selection: Vec::new(),
        }
    }

    /// The success rate on `goals`: the headline's, or the other kind's.
    pub fn success_rate_on(&self, goals: Goals) -> f64 {
        if goals == self.goals {
            return self.success_rate;
        }
        let other = match goals {
            Goals::InView => &self.goals_in_view,
            Goals::Anywhere => &self.goals_anywhere,
        };
        other.as_ref().map_or(0.0, |o| o.success_rate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(success_rate: f64, episodes: usize) -> EvalReport {
        EvalReport {
            success_rate,
            collision_rate: 1.0 - success_rate,
            timeout_rate: 0.0,
            episodes,
            env_steps: 100,
            mean_time_to_goal_s: 4.0,
            mean_return: 1.0,
            wall_s: 0.5,
            by_detour: vec![DetourBucket {
                min: 1.0,
                max: 1.1,
                missions: episodes,
                success_rate,
            }],
            shielded: false,
        }
    }

    #[test]
    fn the_other_kind_of_goals_goes_under_its_own_key() {
        let held_out = HeldOut {
            goals: Goals::InView,
            report: report(0.75, 8),
            other: GoalsSummary::from(&report(0.25, 8)),
        };
        let mut summary = TrainSummary::new(held_out, TrainConfig::fast());
        summary.map = "m.yaml".into();
        assert_eq!(summary.success_rate_on(Goals::InView), 0.75);
        assert_eq!(summary.success_rate_on(Goals::Anywhere), 0.25);
        let json = serde_json::to_value(&summary).unwrap();
        assert_eq!(json["goals"], "in-view");
        assert_eq!(json["success_rate"], 0.75);
        assert_eq!(json["eval_episodes"], 8);
        assert_eq!(json["goals_anywhere"]["success_rate"], 0.25);
        assert_eq!(json["goals_anywhere"]["episodes"], 8);
        assert!(json.get("goals_in_view").is_none(), "{json}");
        assert_eq!(json["evaluation"]["success_rate"], 0.75);
        assert_eq!(json["seed"], TrainConfig::fast().seed);
        for key in [
            "collision_rate",
            "timeout_rate",
            "mean_time_to_goal_s",
            "episodes",
            "env_steps",
            "grad_steps",
            "wall_s",
            "sessions",
            "interrupted",
            "map",
            "extra_maps",
            "beta",
            "config",
        ] {
            assert!(json.get(key).is_some(), "{key} missing from {json}");
        }
    }
}
