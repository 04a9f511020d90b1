//! The fleet's job kinds, which the job engine (`queue`) runs and knows nothing of: `train`
//! (TD3 in the mental simulation of a floor, exported as a policy), `evaluate` (an exported
//! policy on a floor), `validate` (a plan tried in the mental simulation, through the same
//! [`planner::Planner`] as `POST /v1/plan`, its payload and result in the plan's wire form,
//! [`wire`]) and `roadmap` (a floor's policy-aware roadmap).
//!
//! - [`JobRequest`]: a kind and its typed payload, as `POST /v1/jobs` takes it;
//! - [`JobEnv`]: what the handlers share (the knowledge, the files, the planner the process
//!   assembled);
//! - [`source`], [`builds`], [`fleet`]: the planner's ports over the knowledge service (in
//!   process or over HTTP), the job database (roadmap builds) and the traffic schedule;
//! - [`service`]: runners for every kind, and the retention purge.
//!
//! Payloads are checked twice: when a job is created (so a client learns at once, with the
//! field named, that it asked for something impossible) and when it runs (a payload from
//! another process or an older version still fails cleanly, as a fatal error).

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod builds;
pub mod curves;
pub mod evaluate;
pub mod fleet;
pub mod request;
pub mod results;
pub mod roadmap;
pub mod service;
pub mod source;
pub mod train;
pub mod validate;

use std::path::PathBuf;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use serde_json::Value;

pub use builds::QueueRoadmapBuilds;
pub use evaluate::{EvaluateHandler, EvaluatePayload};
pub use fleet::QueueFleet;
pub use planner::{PolicyRoadmapKey, PolicyStore, RoadmapStore};
use queue::{JobError, Worker};
pub use request::JobRequest;
pub use results::{EvaluateResult, JobResult, RoadmapResult, TrainResult};
pub use roadmap::{RoadmapHandler, RoadmapPayload};
pub use source::{FloorDatabase, HttpKnowledge, InProcessKnowledge, KnowledgeSource, SourceError};
pub use train::{TrainHandler, TrainPayload};
pub use validate::{ValidateHandler, ValidatePayload};

/// The kinds of job this service runs. The queue stores a kind as its name (TEXT, so the
/// runner stays generic over handlers); the API accepts and shows the same names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobKind {
    /// TD3 in the mental simulation of a floor, exported as a policy.
    Train,
    /// An exported policy on a floor's held-out missions.
    Evaluate,
    /// A plan tried in the mental simulation.
    Validate,
    /// A floor's policy-aware roadmap: every roadmap edge driven by a policy (PRM-RL).
    Roadmap,
}

impl JobKind {
    /// Every kind, in the order error messages list them.
    pub const ALL: [JobKind; 4] = [
        JobKind::Train,
        JobKind::Evaluate,
        JobKind::Validate,
        JobKind::Roadmap,
    ];

    /// The name stored in the queue and used by the API.
    pub fn as_str(self) -> &'static str {
        match self {
            JobKind::Train => "train",
            JobKind::Evaluate => "evaluate",
            JobKind::Validate => "validate",
            JobKind::Roadmap => "roadmap",
        }
    }
}

impl std::fmt::Display for JobKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl From<JobKind> for String {
    fn from(kind: JobKind) -> String {
        kind.as_str().to_owned()
    }
}

impl std::str::FromStr for JobKind {
    type Err = UnknownKind;

    fn from_str(s: &str) -> Result<Self, UnknownKind> {
        JobKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| UnknownKind(s.to_owned()))
    }
}

/// A job kind this service does not have (the API answers 400).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown job kind {0:?}: expected one of {names}", names = kind_names())]
pub struct UnknownKind(pub String);

fn kind_names() -> String {
    JobKind::ALL.map(JobKind::as_str).join(", ")
}

/// What the handlers share: where worlds come from, where files go, and the planner. The
/// process assembles it ([`JobEnv::new`] over a planner it built).
#[derive(Clone)]
pub struct JobEnv {
    /// The knowledge service (in process, or over HTTP).
    pub knowledge: Arc<dyn KnowledgeSource>,
    /// Checkpoints of running trainings: `<checkpoints_dir>/<job id>/`.
    pub checkpoints_dir: PathBuf,
    /// Exported policies (the planner's).
    pub policies: PolicyStore,
    /// Geometric roadmaps by floor state, shared by plans and roadmap jobs in this process
    /// (the planner's).
    pub roadmaps: Arc<rehearsal::RoadmapCache>,
    /// Stored policy-aware roadmaps (the planner's).
    pub policy_roadmaps: RoadmapStore,
    /// The plan use case: `validate` jobs and `POST /v1/plan` call it alike.
    pub planner: Arc<planner::Planner>,
    /// The free-space reserve of the disk checkpoints and policies go to: a training whose
    /// disk has less stops at once and goes back to the queue until there is room.
    pub disk: Option<edge::disk::DiskWatch>,
}

/// Where the jobs and the planner keep their files.
#[derive(Debug, Clone)]
pub struct JobDirs {
    /// Checkpoints of running trainings.
    pub checkpoints: PathBuf,
    /// Exported policies.
    pub policies: PathBuf,
    /// Stored policy-aware roadmaps.
    pub roadmaps: PathBuf,
}

impl std::fmt::Debug for JobEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JobEnv")
            .field("checkpoints_dir", &self.checkpoints_dir)
            .field("policies", &self.policies)
            .finish_non_exhaustive()
    }
}

impl JobEnv {
    /// The jobs' environment over `knowledge`, with `planner` (whose stores the jobs share)
    /// and checkpoints under `checkpoints_dir`.
    pub fn new(
        knowledge: Arc<dyn KnowledgeSource>,
        planner: Arc<planner::Planner>,
        checkpoints_dir: PathBuf,
        disk: Option<edge::disk::DiskWatch>,
    ) -> Self {
        Self {
            knowledge,
            checkpoints_dir,
            policies: planner.policies().clone(),
            roadmaps: Arc::clone(planner.roadmaps()),
            policy_roadmaps: planner.policy_roadmaps().clone(),
            planner,
            disk,
        }
    }

    /// Registers the handlers of every kind on `worker`.
    pub fn register(self: &Arc<Self>, worker: Worker) -> Worker {
        JobKind::ALL
            .into_iter()
            .fold(worker, |worker, kind| match kind {
                JobKind::Train => worker.register(kind, TrainHandler::new(self.clone())),
                JobKind::Evaluate => worker.register(kind, EvaluateHandler::new(self.clone())),
                JobKind::Validate => worker.register(kind, ValidateHandler::new(self.clone())),
                JobKind::Roadmap => worker.register(kind, RoadmapHandler::new(self.clone())),
            })
    }

    /// Checks a job about to be created: its payload's values are in range, and what it names
    /// (robot, place, policy) exists. (Its shape is [`JobRequest::parse`]'s.)
    pub async fn check_new(&self, request: &JobRequest) -> Result<(), PayloadError> {
        match request {
            JobRequest::Train(p) => {
                p.check()?;
                self.check_floor(&p.place, &p.robot).await
            }
            JobRequest::Evaluate(p) => {
                p.check()?;
                let robot = evaluate::policy_robot(&self.policies, p)?;
                self.check_floor(&p.place, &robot).await
            }
            JobRequest::Validate(p) => {
                let q = validate::check(self, p)?;
                self.check_floor(&q.place, &q.robot).await
            }
            JobRequest::Roadmap(p) => {
                p.check()?;
                let robot = roadmap::roadmap_robot(self, p)?;
                self.check_floor(&p.place, &robot).await
            }
        }
    }

    async fn check_floor(&self, place: &str, robot: &str) -> Result<(), PayloadError> {
        match self.knowledge.floor_database(place, robot).await {
            Ok(_) => Ok(()),
            Err(SourceError::NotFound(m)) => Err(PayloadError::NotFound(m)),
            Err(SourceError::Unprocessable(m)) => Err(PayloadError::Unprocessable(m)),
            Err(SourceError::Unavailable(m)) => Err(PayloadError::Unavailable(m)),
        }
    }
}

/// Why a job was refused at creation.
#[derive(Debug, Clone, thiserror::Error)]
pub enum PayloadError {
    /// No such kind (400).
    #[error("{0}")]
    UnknownKind(String),
    /// The payload is malformed or a value is out of range (422).
    #[error("{field}: {message}")]
    Invalid {
        /// The field at fault, as a dotted path into the job request (`payload.episodes`).
        field: String,
        /// What is wrong with it.
        message: String,
    },
    /// A robot, place or policy it names does not exist (404).
    #[error("{0}")]
    NotFound(String),
    /// It names things that exist but cannot be used so (422).
    #[error("{0}")]
    Unprocessable(String),
    /// The knowledge service cannot answer now (503).
    #[error("{0}")]
    Unavailable(String),
}

impl PayloadError {
    /// [`PayloadError::Invalid`]: `field` (a dotted path, `payload.episodes`) and what is wrong.
    pub fn invalid(field: &str, message: String) -> Self {
        PayloadError::Invalid {
            field: field.to_owned(),
            message,
        }
    }
}

impl From<UnknownKind> for PayloadError {
    fn from(e: UnknownKind) -> Self {
        PayloadError::UnknownKind(e.to_string())
    }
}

impl From<PayloadError> for JobError {
    fn from(e: PayloadError) -> Self {
        match e {
            PayloadError::Unavailable(m) => JobError::Retryable(m),
            other => JobError::Fatal(other.to_string()),
        }
    }
}

/// A knowledge source's refusal as a job's error: retried while the service is unavailable.
pub fn source_error(e: SourceError) -> JobError {
    match e {
        SourceError::Unavailable(m) => JobError::Retryable(m),
        other => JobError::Fatal(other.to_string()),
    }
}

/// The payload as `T`; serde's message names the field (`missing field `place``).
pub fn parse<T: for<'de> Deserialize<'de>>(payload: &Value) -> Result<T, PayloadError> {
    if !payload.is_object() {
        return Err(PayloadError::invalid(
            "payload",
            "must be a JSON object".to_owned(),
        ));
    }
    serde_json::from_value(payload.clone())
        .map_err(|e| PayloadError::invalid("payload", e.to_string()))
}

/// A handler's result or progress as JSON (serialising our own types cannot fail).
pub(crate) fn to_json<T: Serialize>(value: &T) -> Value {
    serde_json::to_value(value).unwrap_or(Value::Null)
}

/// Unix milliseconds as RFC 3339 UTC (`2026-01-31T12:00:00.000Z`).
pub fn rfc3339(ms: i64) -> String {
    let secs = ms.div_euclid(1000);
    let millis = ms.rem_euclid(1000);
    let days = secs.div_euclid(86_400);
    let rem = secs.rem_euclid(86_400);
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{millis:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_round_trip_through_their_names_and_serde() {
        for kind in JobKind::ALL {
            assert_eq!(kind.as_str().parse::<JobKind>(), Ok(kind));
            assert_eq!(serde_json::to_value(kind).unwrap(), kind.as_str());
            assert_eq!(String::from(kind), kind.to_string());
        }
        let e = "dance".parse::<JobKind>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown job kind \"dance\": expected one of train, evaluate, validate, roadmap"
        );
    }

    #[test]
    fn rfc3339_formats_known_instants() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(rfc3339(951_782_400_123), "2000-02-29T00:00:00.123Z");
        assert_eq!(rfc3339(1_767_225_599_999), "2025-12-31T23:59:59.999Z");
    }
}
