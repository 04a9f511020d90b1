//! Robots: browse the robot models (`/v1/robots`, `/v1/robots/{id}`) and a robot's URDF
//! generated from its TOSM description.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, ErrorBody, ErrorCode};
use oxigraph::model::Graph;
use serde::Serialize;
use utoipa::ToSchema;

use super::task::blocking;
use crate::graphs::INFERRED_GRAPH;
use crate::service::Knowledge;
use crate::store::KnowledgeStore;

/// The URDF of a robot, generated from its TOSM description: links, joints, wheels, laser
/// and camera sensors. `check_urdf` and ROS load it as it is.
#[utoipa::path(get, path = "/v1/robots/{id}/robot.urdf", params(("id" = String, Path, min_length = 1, description = "IRI or tosm:identifier")), responses(
    (status = 200, content_type = "application/xml", body = String),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No robot has this IRI or identifier.", body = ErrorBody),
    (status = 422, description = "The robot's description does not make a simulated robot.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn robot_urdf(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    k.tokens.authenticate(&headers)?;
    let urdf = blocking(move || {
        let store = k.store()?;
        let graph = union_graph(&store)?;
        let robots = tosm::read_robots(&graph)
            .map_err(|p| ApiError::internal(format!("stored robots do not validate: {p}")))?;
        let robot = find_robot(&robots, &id)?;
        let spec = sim::parse_robot(&graph, &robot.iri).map_err(|p| {
            ApiError::new(
                ErrorCode::Unprocessable,
                format!("the robot's description does not make a simulated robot: {p}"),
            )
        })?;
        Ok(sim::export::robot_urdf(&spec))
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "application/xml")], urdf).into_response())
}

/// A robot as described in TOSM.
#[derive(Serialize, ToSchema)]
pub struct RobotView {
    /// The robot's IRI.
    iri: String,
    /// `tosm:identifier`.
    id: Option<String>,
    /// `tosm:name`.
    name: String,
    /// Footprint length and width, metres.
    footprint: Option<[f64; 2]>,
    /// Distance between the active wheels, metres.
    wheel_separation: Option<f64>,
    /// Number of wheels, joints, lasers and cameras.
    wheels: usize,
    /// Joints.
    joints: usize,
    /// Laser range finders.
    lasers: usize,
    /// Cameras.
    cameras: usize,
}

fn find_robot<'a>(robots: &'a [tosm::Robot], id: &str) -> Result<&'a tosm::Robot, ApiError> {
    robots
        .iter()
        .find(|r| r.iri == id || r.symbol.identifier.as_deref() == Some(id))
        .ok_or_else(|| ApiError::not_found(format!("no robot has IRI or identifier {id:?}")))
}

fn read_robots(store: &KnowledgeStore) -> Result<Vec<tosm::Robot>, ApiError> {
    let graph = union_graph(store)?;
    tosm::read_robots(&graph)
        .map_err(|p| ApiError::internal(format!("stored robots do not validate: {p}")))
}

/// Every asserted triple (not the entailments), as one graph.
fn union_graph(store: &KnowledgeStore) -> Result<Graph, ApiError> {
    let mut graph = Graph::new();
    for quad in store.snapshot()?.iter() {
        let quad = quad.map_err(ApiError::internal)?;
        if quad.graph_name.as_ref() != oxigraph::model::GraphNameRef::NamedNode(INFERRED_GRAPH) {
            graph.insert(&oxigraph::model::Triple::from(quad));
        }
    }
    Ok(graph)
}

impl From<&tosm::Robot> for RobotView {
    fn from(r: &tosm::Robot) -> Self {
        Self {
            iri: r.iri.clone(),
            id: r.symbol.identifier.clone(),
            name: r.symbol.name.clone(),
            footprint: r.footprint().map(|(l, w)| [l, w]),
            wheel_separation: r.wheel_separation(),
            wheels: r.wheels.len(),
            joints: r.joints.len(),
            lasers: r.lasers.len(),
            cameras: r.cameras.len(),
        }
    }
}

/// Every robot model.
#[utoipa::path(get, path = "/v1/robots", responses(
    (status = 200, body = [RobotView]),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn list_robots(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
) -> Result<Json<Vec<RobotView>>, ApiError> {
    k.tokens.authenticate(&headers)?;
    blocking(move || {
        let robots = read_robots(&k.store()?)?;
        Ok(Json(robots.iter().map(RobotView::from).collect()))
    })
    .await
}

/// One robot, by IRI or identifier.
#[utoipa::path(get, path = "/v1/robots/{id}", params(("id" = String, Path, min_length = 1, description = "IRI or tosm:identifier")), responses(
    (status = 200, body = RobotView),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No robot has this IRI or identifier.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn get_robot(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Json<RobotView>, ApiError> {
    k.tokens.authenticate(&headers)?;
    blocking(move || {
        let robots = read_robots(&k.store()?)?;
        Ok(Json(RobotView::from(find_robot(&robots, &id)?)))
    })
    .await
}
