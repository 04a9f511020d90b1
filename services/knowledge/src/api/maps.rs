//! Map import (`POST /v1/maps`): a ROS map_server map, uploaded as a multipart form, becomes a
//! floor in a named graph of its own. Engineers only.

use std::sync::Arc;

use axum::Json;
use axum::body::Bytes;
use axum::extract::{Multipart, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, EngineerCaller, ErrorBody, ErrorCode};
use serde::Serialize;
use utoipa::ToSchema;

use super::task::blocking;
use crate::maps::{self, ImportError};
use crate::service::Knowledge;

/// The result of a map import.
#[derive(Serialize, ToSchema)]
pub struct ImportedMap {
    /// The new floor's IRI.
    floor: String,
    /// The named graph it lives in.
    graph: String,
    /// Size in cells.
    width: usize,
    /// Size in cells.
    height: usize,
    /// Metres per cell.
    resolution: f64,
    /// Free area, m².
    free_area_m2: f64,
    /// Triples written.
    triples: usize,
}

impl From<ImportError> for ApiError {
    fn from(e: ImportError) -> Self {
        match e {
            ImportError::Store(e) => ApiError::from(e),
            e @ ImportError::Map {
                source: tosm::RosMapError::TooManyPixels { .. },
                ..
            } => ApiError::new(ErrorCode::PayloadTooLarge, e.to_string()),
            e if e.is_client_error() => ApiError::new(ErrorCode::Unprocessable, e.to_string()),
            e => ApiError::internal(e),
        }
    }
}

/// The multipart form of a map import as the OpenAPI document describes it. Documentation
/// only: [`import_map`] reads the parts itself.
#[derive(ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(description = "A ROS map_server map: these three parts, and no other.")]
#[allow(
    dead_code,
    reason = "documentation only: the handler reads the multipart parts itself"
)]
pub(super) struct MapUpload {
    /// The floor's name: its `tosm:identifier` and the last segment of its IRI and of its
    /// graph's. 1-64 characters of a-z, 0-9, `-` and `_`; importing a name again replaces
    /// that floor.
    #[schema(pattern = "^[a-z0-9_-]{1,64}$")]
    name: String,
    /// The map_server YAML, UTF-8: `resolution`, `origin`, `occupied_thresh`, `free_thresh`,
    /// `negate` and `image` (the image is the `image` part, whatever name the YAML gives it).
    yaml: String,
    /// The image: a PGM or PNG of at most 64 megapixels, with at least one free cell under
    /// the YAML's thresholds.
    #[schema(value_type = String, format = Binary)]
    image: Vec<u8>,
}

/// Imports a ROS map_server map as a floor. Multipart form: `yaml` (the map's YAML), `image`
/// (its PGM or PNG), `name` (lower-case letters, digits, `-`, `_`). Engineers only.
#[utoipa::path(post, path = "/v1/maps",
    request_body(content_type = "multipart/form-data", content = MapUpload, description = "The parts `name`, `yaml` and `image`; any other part is refused (400)."),
    responses(
        (status = 201, body = ImportedMap, headers(("location" = String, description = "The new floor's IRI."))),
        (status = 400, description = "The body is not a multipart form, a part is missing or unknown, or `yaml` is not UTF-8.", body = ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, response = edge::error::responses::Forbidden),
        (status = 413, description = "The body is larger than an engineer's map import may be (`body_limit_bytes`, 64 MiB by default; a robot's token gets 403 or this at its smaller limit), or the image declares more pixels than a map may have (64 megapixels), refused before decoding.", body = ErrorBody),
        (status = 422, description = "The name breaks its rule, or the map does not make a floor: the YAML does not parse or has values out of range, the image does not decode or has no free cell.", body = ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
        (status = 507, response = edge::error::responses::StorageFull),
    ))]
pub(super) async fn import_map(
    State(k): State<Arc<Knowledge>>,
    _caller: EngineerCaller,
    mut form: Multipart,
) -> Result<Response, ApiError> {
    let (mut name, mut yaml, mut image): (Option<String>, Option<String>, Option<Bytes>) =
        (None, None, None);
    while let Some(field) = form
        .next_field()
        .await
        .map_err(|e| ApiError::bad_request(format!("malformed multipart body: {e}")))?
    {
        let field_name = field.name().unwrap_or("").to_owned();
        let data = field
            .bytes()
            .await
            .map_err(|e| ApiError::bad_request(format!("field {field_name}: {e}")))?;
        match field_name.as_str() {
            "name" => name = Some(String::from_utf8_lossy(&data).trim().to_owned()),
            "yaml" => {
                yaml = Some(
                    String::from_utf8(data.to_vec())
                        .map_err(|_| ApiError::bad_request("field yaml is not UTF-8 text"))?,
                )
            }
            "image" => image = Some(data),
            other => {
                return Err(ApiError::bad_request(format!(
                    "unexpected form field {other:?}: expected name, yaml, image"
                )));
            }
        }
    }
    let yaml = yaml
        .ok_or_else(|| ApiError::bad_request("missing form field `yaml` (the map_server YAML)"))?;
    let image = image.ok_or_else(|| {
        ApiError::bad_request("missing form field `image` (the PGM or PNG the YAML names)")
    })?;
    let name = name.ok_or_else(|| ApiError::bad_request("missing form field `name`"))?;
    // Checked once the body is read (it is bounded): a client still sending would see a
    // dropped connection instead of this answer.
    k.check_space((yaml.len() + image.len()) as u64)?;
    let imported =
        blocking(move || maps::import(&k, &name, &yaml, &image).map_err(ApiError::from)).await?;
    let floor = imported.floor_iri.clone();
    let mut response = (
        StatusCode::CREATED,
        Json(ImportedMap {
            floor: imported.floor_iri,
            graph: imported.graph_iri,
            width: imported.size.0,
            height: imported.size.1,
            resolution: imported.resolution,
            free_area_m2: imported.free_area_m2,
            triples: imported.triples,
        }),
    )
        .into_response();
    if let Ok(v) = HeaderValue::from_str(&floor) {
        response.headers_mut().insert(header::LOCATION, v);
    }
    Ok(response)
}
