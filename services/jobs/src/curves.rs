//! A training job's learning curves: the files beside its exported policy once it succeeded,
//! else the episodes of its latest checkpoint (a run in progress), as CSV or drawn as a PNG.
//! `GET /v1/jobs/{id}/curves.csv` and `.png` translate and call these.

use std::path::PathBuf;

use queue::Job;

use crate::{JobEnv, JobKind, TrainResult};

/// Why a job has no curves to show.
#[derive(Debug, thiserror::Error)]
pub enum CurvesError {
    /// The job is of another kind (404).
    #[error("job {id} is a `{kind}` job: only `train` jobs have learning curves")]
    NotTraining {
        /// The job.
        id: uuid::Uuid,
        /// Its kind.
        kind: String,
    },
    /// No checkpoint or exported policy holds a point yet (404).
    #[error(
        "job {0} has no learning curve yet: its first checkpoint (or its exported policy) holds the first points; its progress events have the running figures"
    )]
    NoPointYet(uuid::Uuid),
    /// The curves' files could not be read or drawn (500).
    #[error("the curves of job {id}: {cause}")]
    Unreadable {
        /// The job.
        id: uuid::Uuid,
        /// What failed.
        #[source]
        cause: std::io::Error,
    },
}

/// Where a training job's curves come from.
enum Source {
    /// Written beside the exported policy.
    Files(PathBuf),
    /// The episodes of the job's latest checkpoint.
    Episodes(Vec<learning::trainer::EpisodeRecord>),
}

fn source(env: &JobEnv, job: &Job) -> Result<Source, CurvesError> {
    if job.kind.parse::<JobKind>() != Ok(JobKind::Train) {
        return Err(CurvesError::NotTraining {
            id: job.id,
            kind: job.kind.clone(),
        });
    }
    let policy_dir = job
        .result
        .clone()
        .and_then(|r| serde_json::from_value::<TrainResult>(r).ok())
        .and_then(|r| env.policies.path(&r.policy_id));
    if let Some(dir) = policy_dir.filter(|d| d.join(learning::curves::CSV_FILE).is_file()) {
        return Ok(Source::Files(dir));
    }
    let checkpoint_dir =
        crate::train::checkpoint_dir(job.checkpoint.as_ref(), job.id, &env.checkpoints_dir);
    match learning::trainer::Trainer::checkpointed_episodes(&checkpoint_dir) {
        Some(e) if !e.is_empty() => Ok(Source::Episodes(e)),
        _ => Err(CurvesError::NoPointYet(job.id)),
    }
}

/// The curves of training job `job` as CSV: one row per episode with its reward, outcome and
/// the moving mean, standard deviation and success rate over 100 episodes. Blocks.
pub fn curves_csv(env: &JobEnv, job: &Job) -> Result<String, CurvesError> {
    let unreadable = |cause| CurvesError::Unreadable { id: job.id, cause };
    match source(env, job)? {
        Source::Files(dir) => {
            std::fs::read_to_string(dir.join(learning::curves::CSV_FILE)).map_err(unreadable)
        }
        Source::Episodes(episodes) => Ok(learning::curves::curves_csv(&episodes)),
    }
}

/// The reward curve of training job `job` as a PNG (moving mean ± one standard deviation over
/// 100 episodes, like the paper's Figure 10). Blocks.
pub fn curves_png(env: &JobEnv, job: &Job) -> Result<Vec<u8>, CurvesError> {
    let unreadable = |cause| CurvesError::Unreadable { id: job.id, cause };
    match source(env, job)? {
        Source::Files(dir) => {
            std::fs::read(dir.join(learning::curves::PNG_FILE)).map_err(unreadable)
        }
        Source::Episodes(episodes) => {
            let tmp = tempfile::tempdir().map_err(unreadable)?;
            let path = tmp.path().join(learning::curves::PNG_FILE);
            learning::curves::plot_curves(
                &path,
                &crate::train::curves_title(job.id),
                &[("reward".into(), learning::curves::smooth(&episodes))],
            )
            .map_err(|e| unreadable(std::io::Error::other(e.to_string())))?;
            std::fs::read(&path).map_err(unreadable)
        }
    }
}
