//! Robots: browse the robot models (`/v1/robots`, `/v1/robots/{id}`), and a robot's URDF, its
//! gz-sim model (SDF) and its `ros_gz_bridge` configuration, generated from its TOSM
//! description.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use edge::{ApiError, Caller, ErrorBody, ErrorCode};
use oxigraph::model::Graph;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::task::blocking;
use crate::graphs::INFERRED_GRAPH;
use crate::service::Knowledge;
use crate::store::KnowledgeStore;

/// The simulated robot `id` (IRI or identifier) names, as the simulation parser makes it.
fn robot_spec(k: &Knowledge, id: &str) -> Result<sim::RobotSpec, ApiError> {
    let store = k.store()?;
    let graph = union_graph(&store)?;
    let robots = tosm::read_robots(&graph)
        .map_err(|p| ApiError::internal(format!("stored robots do not validate: {p}")))?;
    let robot = find_robot(&robots, id)?;
    sim::parse_robot(&graph, &robot.iri).map_err(|p| {
        ApiError::new(
            ErrorCode::Unprocessable,
            format!("the robot's description does not make a simulated robot: {p}"),
        )
    })
}

/// The URDF of a robot, generated from its TOSM description: REP-105 frames
/// (`base_footprint` → `base_link` → parts, wheels and sensors, the laser's link named after
/// the robot's laser), and gz-sim extensions: the laser a `gpu_lidar`, cameras `camera` or
/// `rgbd_camera` sensors, the DiffDrive and JointStatePublisher systems on the topics
/// `bridge.yaml` bridges. `check_urdf`, ROS and gz-sim load it as it is.
#[utoipa::path(get, path = "/v1/robots/{id}/robot.urdf", params(("id" = String, Path, min_length = 1, description = "IRI or tosm:identifier")), responses(
    (status = 200, content_type = "application/xml", body = String),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No robot has this IRI or identifier.", body = ErrorBody),
    (status = 422, description = "The robot's description does not make a simulated robot.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn robot_urdf(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let urdf = blocking(move || Ok(sim::export::robot_urdf(&robot_spec(&k, &id)?))).await?;
    Ok(([(header::CONTENT_TYPE, "application/xml")], urdf).into_response())
}

/// The robot as an SDF 1.9 model for gz-sim (`ros_gz_sim create -file robot.sdf`): the links
/// and joints of `robot.urdf`, the laser a `gpu_lidar` sensor, cameras `camera` or
/// `rgbd_camera` sensors, and the DiffDrive and JointStatePublisher systems on the topics
/// `bridge.yaml` bridges. The world must run gz-sim's sensors system (`world.sdf` does).
#[utoipa::path(get, path = "/v1/robots/{id}/robot.sdf", params(("id" = String, Path, min_length = 1, description = "IRI or tosm:identifier")), responses(
    (status = 200, content_type = "application/xml", body = String),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No robot has this IRI or identifier.", body = ErrorBody),
    (status = 422, description = "The robot's description does not make a simulated robot.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn robot_sdf(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let sdf = blocking(move || Ok(sim::export::robot_sdf(&robot_spec(&k, &id)?))).await?;
    Ok(([(header::CONTENT_TYPE, "application/xml")], sdf).into_response())
}

/// Which world's clock the bridge forwards.
#[derive(Deserialize, utoipa::IntoParams)]
pub struct BridgeQuery {
    /// The gz-sim world's name (the `<world name>` of `world.sdf`): the clock is bridged from
    /// `/world/<world>/clock` [default: gz-sim's global `/clock`]. Letters, digits, `_`, `-`
    /// and `.`.
    #[param(nullable = false, min_length = 1)]
    world: Option<String>,
}

/// The `ros_gz_bridge` configuration for the robot in gz-sim (`ros2 run ros_gz_bridge
/// parameter_bridge --ros-args -p config_file:=bridge.yaml`): `/cmd_vel` to the drive;
/// `/odom`, `/scan`, `/tf` (`odom` → `base_footprint`), `/joint_states` and `/clock` from
/// Gazebo; each camera's `/<camera>/image` and `camera_info` (an RGB-D camera's also
/// `depth_image` and `points`). The Gazebo topics are those `robot.sdf` and `robot.urdf` use.
#[utoipa::path(get, path = "/v1/robots/{id}/bridge.yaml", params(("id" = String, Path, min_length = 1, description = "IRI or tosm:identifier"), BridgeQuery), responses(
    (status = 200, content_type = "application/yaml", body = [BridgeEntry]),
    (status = 400, description = "The `world` is empty or holds other characters than letters, digits, `_`, `-` and `.`.", body = ErrorBody),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No robot has this IRI or identifier.", body = ErrorBody),
    (status = 422, description = "The robot's description does not make a simulated robot.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn bridge_yaml(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
    axum::extract::Query(query): axum::extract::Query<BridgeQuery>,
) -> Result<Response, ApiError> {
    if let Some(world) = &query.world {
        let valid = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.');
        if world.is_empty() || !world.chars().all(valid) {
            return Err(ApiError::bad_request(format!(
                "world {world:?} is no gz-sim world name: letters, digits, `_`, `-` and `.` only"
            )));
        }
    }
    let yaml = blocking(move || {
        let spec = robot_spec(&k, &id)?;
        Ok(sim::export::ros_gz_bridge_yaml(
            &spec,
            query.world.as_deref(),
        ))
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "application/yaml")], yaml).into_response())
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
    _caller: Caller,
) -> Result<Json<Vec<RobotView>>, ApiError> {
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
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Json<RobotView>, ApiError> {
    blocking(move || {
        let robots = read_robots(&k.store()?)?;
        Ok(Json(RobotView::from(find_robot(&robots, &id)?)))
    })
    .await
}

/// One topic of the `ros_gz_bridge` configuration `GET /v1/robots/{id}/bridge.yaml` writes (a
/// YAML list of these). Documentation only: [`sim::export::ros_gz_bridge_yaml`] writes it.
#[derive(utoipa::ToSchema)]
#[allow(dead_code, reason = "read by the OpenAPI document, never built")]
pub struct BridgeEntry {
    /// The ROS 2 topic.
    ros_topic_name: String,
    /// The Gazebo Transport topic.
    gz_topic_name: String,
    /// The ROS 2 message type, e.g. `sensor_msgs/msg/LaserScan`.
    ros_type_name: String,
    /// The Gazebo message type, e.g. `gz.msgs.LaserScan`.
    gz_type_name: String,
    /// `GZ_TO_ROS` or `ROS_TO_GZ`.
    direction: String,
}
