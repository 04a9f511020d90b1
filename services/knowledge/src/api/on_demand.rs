//! On-demand databases: the subset of the graph a mission needs (`POST /v1/on-demand`), and the
//! whole floor a place is on for one robot (`GET /v1/places/{id}/on-demand`, revalidated by
//! `ETag`), as Turtle, N-Triples or JSON-LD.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, ErrorBody, ErrorCode, RobotCaller};
use oxigraph::io::{RdfFormat, RdfSerializer};
use serde::Deserialize;
use utoipa::ToSchema;

use super::task::blocking;
use crate::on_demand::{self, Mission, OnDemandError, Waypoint};
use crate::service::Knowledge;

/// A waypoint: a place (IRI or identifier), or a point on a floor. The OpenAPI document
/// describes it as [`WaypointDoc`]: one of the two forms.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaypointInput {
    /// A place's IRI or identifier.
    #[serde(default)]
    place: Option<String>,
    /// x in metres (with `y`).
    #[serde(default)]
    x: Option<f64>,
    /// y in metres (with `x`).
    #[serde(default)]
    y: Option<f64>,
    /// The floor the point is on; needed only when floors overlap.
    #[serde(default)]
    floor: Option<String>,
}

/// [`WaypointInput`] as the OpenAPI document describes it: one of its two forms. Documentation
/// only: the handler reads [`WaypointInput`] and answers 400 to any other combination.
#[derive(ToSchema)]
#[serde(untagged)]
#[schema(
    as = WaypointInput,
    description = "A waypoint: a place (IRI or identifier), or a point on a floor (`x` and `y`, with an optional `floor`); never both."
)]
#[allow(
    dead_code,
    reason = "documentation only: the handler reads `WaypointInput`"
)]
pub(super) enum WaypointDoc {
    /// A place (room, corridor, hall, floor...): the waypoint is in it.
    #[serde(deny_unknown_fields)]
    Place {
        /// The place's IRI or identifier.
        place: String,
        /// Ignored with `place`.
        floor: Option<String>,
    },
    /// A point on a floor, in the floor frame.
    #[serde(deny_unknown_fields)]
    Point {
        /// x in metres.
        x: f64,
        /// y in metres.
        y: f64,
        /// The floor the point is on (IRI or identifier); needed only when floors overlap
        /// there.
        floor: Option<String>,
    },
}

/// A mission for which to build an on-demand database.
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct OnDemandRequest {
    /// The robot's IRI or identifier.
    robot: String,
    /// Where the robot starts.
    #[schema(value_type = WaypointDoc)]
    start: WaypointInput,
    /// Where it must go, in order (at least one).
    #[schema(value_type = Vec<WaypointDoc>, min_items = 1)]
    goals: Vec<WaypointInput>,
}

fn waypoint(which: &str, w: WaypointInput) -> Result<Waypoint, ApiError> {
    match (w.place, w.x, w.y) {
        (Some(place), None, None) => Ok(Waypoint::Place(place)),
        (None, Some(x), Some(y)) => Ok(Waypoint::Point {
            x,
            y,
            floor: w.floor,
        }),
        _ => Err(ApiError::bad_request(format!(
            "{which}: give either `place`, or `x` and `y` (with an optional `floor`)"
        ))),
    }
}

impl From<OnDemandError> for ApiError {
    fn from(e: OnDemandError) -> Self {
        if let OnDemandError::Store(e) = e {
            return ApiError::from(e);
        }
        match &e {
            OnDemandError::NoGoals | OnDemandError::NotFinite { .. } => {
                ApiError::bad_request(e.to_string())
            }
            OnDemandError::UnknownRobot(_) | OnDemandError::UnknownPlace { .. } => {
                ApiError::not_found(e.to_string())
            }
            OnDemandError::OutsideEveryPlace { .. }
            | OnDemandError::NoFloor(_)
            | OnDemandError::AmbiguousFloor { .. }
            | OnDemandError::NotConnected { .. }
            | OnDemandError::Cycle { .. }
            | OnDemandError::UnreadablePlace { .. } => {
                ApiError::new(ErrorCode::Unprocessable, e.to_string())
            }
            OnDemandError::Stopped => ApiError::new(ErrorCode::Timeout, e.to_string()),
            OnDemandError::Store(_) => ApiError::internal(e),
        }
    }
}

/// The on-demand database for a mission (thesis §3.4): the route's places with their maps and
/// boundaries, the objects in them, and the robot — as Turtle (default), N-Triples or JSON-LD
/// by `Accept`. `X-Triple-Count` gives its size; `X-Route` the places crossed.
#[utoipa::path(post, path = "/v1/on-demand", request_body = OnDemandRequest, responses(
    (status = 200, description = "The subset, in the format `Accept` asks for (Turtle by default).",
        content((String = "text/turtle"), (String = "application/n-triples"), (serde_json::Value = "application/ld+json")),
        headers(
            ("x-triple-count" = u64, description = "Triples in the subset."),
            ("x-route" = String, description = "The IRIs of the places the route crosses, in order, separated by spaces."))),
    (status = 400, description = "The body is not JSON, a waypoint gives neither `place` nor `x` and `y` (or both), or there is no goal.", body = ErrorBody),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 403, response = edge::error::responses::Forbidden),
    (status = 404, description = "No robot, place or floor has the IRI or identifier given.", body = ErrorBody),
    (status = 406, description = "`Accept` names none of `text/turtle`, `application/n-triples`, `application/ld+json` (or `application/json`).", body = ErrorBody),
    (status = 413, response = edge::error::responses::PayloadTooLarge),
    (status = 415, response = edge::error::responses::UnsupportedMediaType),
    (status = 422, description = "The body does not fit the schema (a missing or unknown field, a wrong type), or the mission is impossible: a point outside every place or on several overlapping floors, a place on no floor, places not connected.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn on_demand_database(
    State(k): State<Arc<Knowledge>>,
    _caller: RobotCaller,
    headers: HeaderMap,
    Json(request): Json<OnDemandRequest>,
) -> Result<Response, ApiError> {
    let format = graph_format(headers.get(header::ACCEPT).and_then(|v| v.to_str().ok()))?;
    let mut goals = Vec::new();
    for (i, g) in request.goals.into_iter().enumerate() {
        goals.push(waypoint(&format!("goals[{i}]"), g)?);
    }
    let mission = Mission {
        robot: request.robot,
        start: waypoint("start", request.start)?,
        goals,
    };
    // Dropped with this future when the client hangs up or the request times out: the
    // blocking work then stops at its next waypoint, leg or place.
    let stop = grid::Stop::new();
    let _stop_on_drop = grid::StopOnDrop(stop.clone());
    blocking(move || {
        let store = k.store()?;
        let db = on_demand::build_until(&store, &mission, &stop)?;
        let body = serialize(&db.triples, format)?;
        let mut response = ([(header::CONTENT_TYPE, format.media_type())], body).into_response();
        response
            .headers_mut()
            .insert("x-triple-count", HeaderValue::from(db.triples.len()));
        if let Ok(v) = HeaderValue::from_str(&db.route.join(" ")) {
            response.headers_mut().insert("x-route", v);
        }
        Ok(response)
    })
    .await
}

/// Which robot a floor's database is for.
#[derive(serde::Deserialize, utoipa::IntoParams)]
pub struct FloorRobotQuery {
    /// The robot's IRI or identifier [default: the first robot in the store]. An unknown one
    /// (an empty one included) is 404.
    #[param(nullable = false)]
    robot: Option<String>,
}

/// The on-demand database of the whole floor a place is on (the place itself when it is a
/// floor), for one robot: everything a mental simulation of that floor needs — the floor, its
/// ancestors, the places on it with their maps and boundaries, the objects in them, and the
/// robot. Training and evaluation workers fetch their worlds here. Turtle (default),
/// N-Triples or JSON-LD by `Accept`; `X-Floor` and `X-Robot` give the IRIs of the floor and
/// the robot, `X-Triple-Count` its size. The `ETag` names the graph's state: a request with
/// `If-None-Match` set to it is answered 304 without a body while nothing was written since.
#[utoipa::path(get, path = "/v1/places/{id}/on-demand", params(
        ("id" = String, Path, min_length = 1, description = "A floor or a place on one: IRI or tosm:identifier."),
        FloorRobotQuery,
        ("If-None-Match" = Option<String>, Header, nullable = false, description = "An `ETag` of an earlier answer: 304 while the graph is unchanged.")),
    responses(
    (status = 200, description = "The floor's database, in the format `Accept` asks for (Turtle by default).",
        content((String = "text/turtle"), (String = "application/n-triples"), (serde_json::Value = "application/ld+json")),
        headers(
            ("etag" = String, description = "The graph's state and the format; absent when the graph changed while it was read."),
            ("x-triple-count" = u64, description = "Triples in the database."),
            ("x-floor" = String, description = "The floor's IRI."),
            ("x-robot" = String, description = "The robot's IRI."))),
    (status = 304, description = "Unchanged since the `If-None-Match` tag.", headers(("etag" = String))),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 403, response = edge::error::responses::Forbidden),
    (status = 404, description = "No place has this IRI or identifier, or no robot the `robot` given (or none at all).", body = ErrorBody),
    (status = 406, description = "`Accept` names none of `text/turtle`, `application/n-triples`, `application/ld+json` (or `application/json`).", body = ErrorBody),
    (status = 422, description = "The place is on no floor (a building, or a place outside every floor): only floors and the places on them have a database.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn floor_on_demand_database(
    State(k): State<Arc<Knowledge>>,
    _caller: RobotCaller,
    headers: HeaderMap,
    Path(id): Path<String>,
    axum::extract::Query(query): axum::extract::Query<FloorRobotQuery>,
) -> Result<Response, ApiError> {
    let format = graph_format(headers.get(header::ACCEPT).and_then(|v| v.to_str().ok()))?;
    let if_none_match = headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .map(str::to_owned);
    blocking(move || {
        let store = k.store()?;
        let tag = store.state_tag().map_err(ApiError::internal)?;
        let etag = format!("\"{tag}-{}\"", format.media_type());
        let matches = if_none_match
            .as_deref()
            .is_some_and(|v| v.split(',').any(|t| t.trim() == etag));
        if matches {
            let mut response = StatusCode::NOT_MODIFIED.into_response();
            if let Ok(v) = HeaderValue::from_str(&etag) {
                response.headers_mut().insert(header::ETAG, v);
            }
            return Ok(response);
        }
        let db = on_demand::floor_database_of_place(&store, &id, query.robot.as_deref())?;
        let body = serialize(&db.triples, format)?;
        let mut response = ([(header::CONTENT_TYPE, format.media_type())], body).into_response();
        let h = response.headers_mut();
        h.insert("x-triple-count", HeaderValue::from(db.triples.len()));
        // Only a state that did not change while the database was read may be named.
        if store.state_tag().ok().as_deref() == Some(tag.as_str())
            && let Ok(v) = HeaderValue::from_str(&etag)
        {
            h.insert(header::ETAG, v);
        }
        for (name, value) in [("x-floor", db.floors.first()), ("x-robot", Some(&db.robot))] {
            if let Some(v) = value.and_then(|v| HeaderValue::from_str(v).ok()) {
                h.insert(name, v);
            }
        }
        Ok(response)
    })
    .await
}

/// The graph formats the on-demand endpoint writes, by `Accept`.
fn graph_format(accept: Option<&str>) -> Result<RdfFormat, ApiError> {
    let Some(accept) = accept else {
        return Ok(RdfFormat::Turtle);
    };
    let mut best: Option<(f32, RdfFormat)> = None;
    for part in accept.split(',') {
        let mut pieces = part.split(';');
        let media = pieces.next().unwrap_or("").trim().to_ascii_lowercase();
        let q = pieces
            .filter_map(|p| p.trim().strip_prefix("q="))
            .find_map(|q| q.parse::<f32>().ok())
            .unwrap_or(1.0);
        let format = match media.as_str() {
            "text/turtle" | "*/*" | "text/*" => RdfFormat::Turtle,
            "application/n-triples" => RdfFormat::NTriples,
            "application/ld+json" | "application/json" => RdfFormat::JsonLd {
                profile: Default::default(),
            },
            _ => continue,
        };
        if q > 0.0 && best.as_ref().is_none_or(|(bq, _)| q > *bq) {
            best = Some((q, format));
        }
    }
    best.map(|(_, f)| f).ok_or_else(|| {
        ApiError::new(ErrorCode::NotAcceptable, format!("cannot answer {accept:?}: on-demand databases come as text/turtle, application/n-triples or application/ld+json"))
    })
}

fn serialize(triples: &[oxigraph::model::Triple], format: RdfFormat) -> Result<Vec<u8>, ApiError> {
    let mut serializer = RdfSerializer::from_format(format);
    if format == RdfFormat::Turtle {
        for (prefix, iri) in [
            ("tosm", tosm::vocab::NS),
            ("rdf", "http://www.w3.org/1999/02/22-rdf-syntax-ns#"),
            ("owl", "http://www.w3.org/2002/07/owl#"),
            ("xsd", "http://www.w3.org/2001/XMLSchema#"),
        ] {
            serializer = serializer
                .with_prefix(prefix, iri)
                .map_err(ApiError::internal)?;
        }
    }
    let mut writer = serializer.for_writer(Vec::new());
    for t in triples {
        writer.serialize_triple(t).map_err(ApiError::internal)?;
    }
    writer.finish().map_err(ApiError::internal)
}
