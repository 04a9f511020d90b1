//! [`JobRequest`]: a job of one kind with its typed payload, the form `POST /v1/jobs` takes,
//! the queue stores (`kind` and `payload`) and the OpenAPI documents describe. Each kind's
//! result is [`JobResult`](crate::JobResult)'s variant of the same name.

use queue::NewJob;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::{
    EvaluatePayload, JobKind, PayloadError, RoadmapPayload, TrainPayload, ValidatePayload, parse,
};

/// A job to run: its kind and that kind's payload.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(tag = "kind", content = "payload", rename_all = "lowercase")]
pub enum JobRequest {
    /// Trains a policy for a robot on a floor.
    Train(TrainPayload),
    /// Evaluates a policy on a floor.
    Evaluate(EvaluatePayload),
    /// Validates a plan in the mental simulation: the payload is a `POST /v1/plan` request
    /// (its schema is `PlanApiRequest`'s, which the plan's wire types document).
    Validate(Box<ValidatePayload>),
    /// Builds the policy-aware roadmap of a floor and a policy.
    Roadmap(RoadmapPayload),
}

impl JobRequest {
    /// The request of kind `kind` (its name) with `payload`: an unknown kind, or a payload
    /// that is not that kind's, is an error naming the field (`payload`, `kind`).
    pub fn parse(kind: &str, payload: &Value) -> Result<Self, PayloadError> {
        Ok(match kind.parse::<JobKind>()? {
            JobKind::Train => JobRequest::Train(parse(payload)?),
            JobKind::Evaluate => JobRequest::Evaluate(parse(payload)?),
            JobKind::Validate => JobRequest::Validate(Box::new(parse(payload)?)),
            JobKind::Roadmap => JobRequest::Roadmap(parse(payload)?),
        })
    }

    /// Its kind.
    pub fn kind(&self) -> JobKind {
        match self {
            JobRequest::Train(_) => JobKind::Train,
            JobRequest::Evaluate(_) => JobKind::Evaluate,
            JobRequest::Validate(_) => JobKind::Validate,
            JobRequest::Roadmap(_) => JobKind::Roadmap,
        }
    }

    /// The payload as the queue stores it (serialising our own types cannot fail).
    pub fn payload(&self) -> Value {
        match self {
            JobRequest::Train(p) => crate::to_json(p),
            JobRequest::Evaluate(p) => crate::to_json(p),
            JobRequest::Validate(p) => crate::to_json(p),
            JobRequest::Roadmap(p) => crate::to_json(p),
        }
    }

    /// The job to enqueue (default priority and attempts).
    pub fn to_job(&self) -> NewJob {
        NewJob::new(self.kind(), self.payload())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The form is the queue's: `kind` beside `payload`, and a payload read back is the one
    /// written.
    #[test]
    fn a_request_is_its_kind_beside_its_payload() {
        let payload = serde_json::json!({"policy": "p1", "place": "F1", "safety_margin_m": 0.2});
        let request = JobRequest::parse("roadmap", &payload).expect("a roadmap payload");
        assert_eq!(request.kind(), JobKind::Roadmap);
        assert_eq!(request.payload()["policy"], "p1");
        let json = serde_json::to_value(&request).expect("serialises");
        assert_eq!(json["kind"], "roadmap");
        assert_eq!(json["payload"]["safety_margin_m"], 0.2);
        let back: JobRequest = serde_json::from_value(json).expect("reads back");
        assert_eq!(back.payload(), request.payload());
    }

    #[test]
    fn an_unknown_kind_or_a_payload_of_another_kind_is_named() {
        let unknown = JobRequest::parse("dance", &serde_json::json!({})).unwrap_err();
        assert!(matches!(unknown, PayloadError::UnknownKind(_)), "{unknown}");
        let payload = serde_json::json!({"policy": "p1", "place": "F1"});
        match JobRequest::parse("train", &payload).unwrap_err() {
            PayloadError::Invalid { field, message } => {
                assert_eq!(field, "payload");
                assert!(message.contains("policy"), "{message}");
            }
            other => panic!("{other}"),
        }
    }
}
