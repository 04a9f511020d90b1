//! The job kinds: `train` (TD3 in the mental simulation of a floor, exported as a policy),
//! `evaluate` (an exported policy on a floor) and `validate` (a plan tried in the mental
//! simulation; its executor plugs in through [`PlanValidator`]).
//!
//! Payloads are checked twice: when a job is created (so a client learns at once, with the
//! field named, that it asked for something impossible) and when it runs (a payload from
//! another process or an older version still fails cleanly, as a fatal error).

pub mod evaluate;
pub mod policies;
pub mod source;
pub mod train;
pub mod validate;

use std::path::PathBuf;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::runner::{JobError, Worker};
pub use evaluate::{EvaluateHandler, EvaluatePayload};
pub use policies::{PolicyStore, PolicySummary};
pub use source::{FloorDatabase, HttpKnowledge, InProcessKnowledge, KnowledgeSource, SourceError};
pub use train::{TrainHandler, TrainPayload};
pub use validate::{PlanValidator, ValidateHandler, ValidatePayload};

/// The `train` kind.
pub const TRAIN: &str = "train";
/// The `evaluate` kind.
pub const EVALUATE: &str = "evaluate";
/// The `validate` kind.
pub const VALIDATE: &str = "validate";
/// Every kind, in the order error messages list them.
pub const KINDS: [&str; 3] = [TRAIN, EVALUATE, VALIDATE];

/// What the handlers share: where worlds come from and where files go.
#[derive(Clone)]
pub struct JobEnv {
    /// The knowledge service (in process, or over HTTP).
    pub knowledge: Arc<dyn KnowledgeSource>,
    /// Checkpoints of running trainings: `<checkpoints_dir>/<job id>/`.
    pub checkpoints_dir: PathBuf,
    /// Exported policies.
    pub policies: PolicyStore,
    /// The plan validator behind `validate` jobs, when this build has one.
    pub validator: Option<Arc<dyn PlanValidator>>,
}

impl std::fmt::Debug for JobEnv {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JobEnv")
            .field("checkpoints_dir", &self.checkpoints_dir)
            .field("policies", &self.policies)
            .field("validator", &self.validator.is_some())
            .finish_non_exhaustive()
    }
}

impl JobEnv {
    /// Registers the handlers of every kind on `worker`.
    pub fn register(self: &Arc<Self>, worker: Worker) -> Worker {
        worker
            .register(TRAIN, TrainHandler::new(self.clone()))
            .register(EVALUATE, EvaluateHandler::new(self.clone()))
            .register(VALIDATE, ValidateHandler::new(self.clone()))
    }

    /// Checks a job about to be created: the kind exists, the payload has the kind's shape and
    /// values in range, and what it names (robot, place, policy) exists. Returns the payload
    /// as it will be stored.
    pub async fn check_new(&self, kind: &str, payload: &Value) -> Result<Value, PayloadError> {
        match kind {
            TRAIN => {
                let p: TrainPayload = parse(payload)?;
                p.check()?;
                self.check_floor(&p.place, &p.robot).await?;
            }
            EVALUATE => {
                let p: EvaluatePayload = parse(payload)?;
                p.check()?;
                let robot = evaluate::policy_robot(&self.policies, &p)?;
                self.check_floor(&p.place, &robot).await?;
            }
            VALIDATE => {
                let p: ValidatePayload = parse(payload)?;
                let Some(validator) = &self.validator else {
                    return Err(PayloadError::Unprocessable(
                        "validate jobs are not available yet: this build has no plan validator"
                            .to_owned(),
                    ));
                };
                validator.check(payload).map_err(PayloadError::Invalid)?;
                self.check_floor(&p.place, &p.robot).await?;
            }
            other => {
                return Err(PayloadError::UnknownKind(format!(
                    "unknown job kind {other:?}: expected one of {}",
                    KINDS.join(", ")
                )));
            }
        }
        Ok(payload.clone())
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
    /// The payload is malformed or a value is out of range; the message names the field (422).
    #[error("{0}")]
    Invalid(String),
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

impl From<PayloadError> for JobError {
    fn from(e: PayloadError) -> Self {
        match e {
            PayloadError::Unavailable(m) => JobError::Retryable(m),
            other => JobError::Fatal(other.to_string()),
        }
    }
}

impl From<SourceError> for JobError {
    fn from(e: SourceError) -> Self {
        match e {
            SourceError::Unavailable(m) => JobError::Retryable(m),
            other => JobError::Fatal(other.to_string()),
        }
    }
}

/// The payload as `T`; serde's message names the field (`missing field `place``).
pub fn parse<T: for<'de> Deserialize<'de>>(payload: &Value) -> Result<T, PayloadError> {
    if !payload.is_object() {
        return Err(PayloadError::Invalid(
            "payload: must be a JSON object".to_owned(),
        ));
    }
    serde_json::from_value(payload.clone())
        .map_err(|e| PayloadError::Invalid(format!("payload: {e}")))
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
    fn rfc3339_formats_known_instants() {
        assert_eq!(rfc3339(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(rfc3339(951_782_400_123), "2000-02-29T00:00:00.123Z");
        assert_eq!(rfc3339(1_767_225_599_999), "2025-12-31T23:59:59.999Z");
    }
}
