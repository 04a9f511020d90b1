//! Exported policies: the listing (newest first, with each one's training summary), one
//! policy's summary and metadata, and its files for download.

use std::sync::Arc;

use axum::Json;
use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, Caller, ErrorBody};
use planner::PolicyEntry;
use planner::policies::{METADATA, WEIGHTS};
use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use axum::Router;
use axum::routing::get;
use edge::{TokenSource, Tokens};
use planner::PolicyStore;

/// The state of the policy routes.
#[derive(Debug)]
pub struct PolicyRoutes {
    /// Who may do what.
    pub tokens: Tokens,
    /// The exported policies.
    pub policies: PolicyStore,
}

impl TokenSource for PolicyRoutes {
    fn tokens(&self) -> &Tokens {
        &self.tokens
    }
}

/// The routes of exported policies.
pub fn router(state: Arc<PolicyRoutes>) -> Router {
    Router::new()
        .route("/v1/policies", get(list_policies))
        .route("/v1/policies/{id}", get(get_policy))
        .route("/v1/policies/{id}/policy.safetensors", get(policy_weights))
        .route("/v1/policies/{id}/policy.json", get(policy_metadata))
        .with_state(state)
}

/// A policy in a listing: its id and its training's summary, in the wire types.
#[derive(Debug, Clone, Serialize, ToSchema)]
#[schema(as = PolicySummary)]
pub struct PolicyView {
    /// The policy's id (the id of the job that trained it).
    pub id: String,
    /// The robot's IRI.
    pub robot: Option<String>,
    /// The place the job named.
    pub place: Option<String>,
    /// The floor's IRI.
    pub floor: Option<String>,
    /// The training job.
    pub job_id: Option<String>,
    /// When it was exported (RFC 3339, UTC).
    pub created: Option<String>,
    /// The held-out evaluation of the exported policy: success, collision and timeout rates,
    /// missions run.
    #[schema(value_type = Object)]
    pub eval: Value,
}

impl From<&PolicyEntry> for PolicyView {
    fn from(p: &PolicyEntry) -> Self {
        let s = &p.summary;
        Self {
            id: p.id.clone(),
            robot: s.robot.clone(),
            place: s.place.clone(),
            floor: s.floor.clone(),
            job_id: s.job_id.clone(),
            created: (s.created_ms > 0).then(|| jobs::rfc3339(s.created_ms)),
            eval: s
                .eval
                .as_ref()
                .and_then(|e| serde_json::to_value(e).ok())
                .unwrap_or(Value::Null),
        }
    }
}

fn policy_path(api: &PolicyRoutes, id: &str) -> Result<std::path::PathBuf, ApiError> {
    api.policies
        .path(id)
        .filter(|p| p.join(WEIGHTS).is_file())
        .ok_or_else(|| ApiError::not_found(format!("no policy has id {id:?}")))
}

/// Exported policies, newest first: id, robot, place, creation time and evaluation summary.
#[utoipa::path(get, path = "/v1/policies", responses(
    (status = 200, body = [PolicyView]),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(crate) async fn list_policies(
    State(api): State<Arc<PolicyRoutes>>,
    _caller: Caller,
) -> Result<Json<Vec<PolicyView>>, ApiError> {
    let store = api.policies.clone();
    let list = tokio::task::spawn_blocking(move || store.list())
        .await
        .map_err(ApiError::internal)?;
    Ok(Json(list.iter().map(PolicyView::from).collect()))
}

/// One policy: its summary and its full metadata (`policy.json`: scaling, network, training).
#[utoipa::path(get, path = "/v1/policies/{id}", params(("id" = String, Path, pattern = "^[A-Za-z0-9_-]{1,128}$", description = "The policy's id: 1-128 letters, digits, `-` and `_` (anything else is 404).")), responses(
    (status = 200, body = Object),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No policy has this id.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(crate) async fn get_policy(
    State(api): State<Arc<PolicyRoutes>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    policy_path(&api, &id)?;
    let meta = api
        .policies
        .metadata(&id)
        .ok_or_else(|| ApiError::not_found(format!("no policy has id {id:?}")))?;
    let entry = PolicyEntry {
        id: id.clone(),
        summary: planner::policies::summary_of(&meta),
    };
    let mut view = serde_json::to_value(PolicyView::from(&entry)).map_err(ApiError::internal)?;
    view["metadata"] = meta;
    view["files"] = serde_json::json!({
        "policy.safetensors": format!("/v1/policies/{id}/policy.safetensors"),
        "policy.json": format!("/v1/policies/{id}/policy.json"),
    });
    Ok(Json(view))
}

async fn download(
    api: &PolicyRoutes,
    id: &str,
    file: &str,
    media: &'static str,
) -> Result<Response, ApiError> {
    let path = policy_path(api, id)?.join(file);
    let bytes = tokio::fs::read(&path)
        .await
        .map_err(|_| ApiError::not_found(format!("policy {id:?} has no {file}")))?;
    let disposition = format!("attachment; filename=\"{file}\"");
    Ok((
        [
            (header::CONTENT_TYPE, HeaderValue::from_static(media)),
            (
                header::CONTENT_DISPOSITION,
                HeaderValue::from_str(&disposition).map_err(ApiError::internal)?,
            ),
        ],
        Body::from(bytes),
    )
        .into_response())
}

/// The policy's weights (safetensors).
#[utoipa::path(get, path = "/v1/policies/{id}/policy.safetensors", params(("id" = String, Path, pattern = "^[A-Za-z0-9_-]{1,128}$", description = "The policy's id: 1-128 letters, digits, `-` and `_` (anything else is 404).")), responses(
    (status = 200, content_type = "application/octet-stream", body = Vec<u8>),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No policy has this id.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(crate) async fn policy_weights(
    State(api): State<Arc<PolicyRoutes>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    download(&api, &id, WEIGHTS, "application/octet-stream").await
}

/// The policy's metadata file (`learning::Policy::from_bytes` takes it with the weights).
#[utoipa::path(get, path = "/v1/policies/{id}/policy.json", params(("id" = String, Path, pattern = "^[A-Za-z0-9_-]{1,128}$", description = "The policy's id: 1-128 letters, digits, `-` and `_` (anything else is 404).")), responses(
    (status = 200, content_type = "application/json", body = Object),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No policy has this id.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(crate) async fn policy_metadata(
    State(api): State<Arc<PolicyRoutes>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    download(&api, &id, METADATA, "application/json").await
}
