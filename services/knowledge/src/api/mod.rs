//! The knowledge service's REST API for robots and operators: browse places and robots, fetch
//! a floor's map, import maps, report perceived objects and people counts, and get on-demand
//! databases. One module per resource; this one assembles their routes and the OpenAPI
//! document.
//!
//! Wire types live here and are converted from the core types on purpose.

mod maps;
mod objects;
mod on_demand;
mod people;
mod places;
mod robots;
mod task;

use std::sync::Arc;

use axum::Router;
use axum::routing::{get, post};
use edge::{BearerAuth, ErrorBody, ErrorDetail};
use utoipa::OpenApi;

// The handlers' OpenAPI descriptions, named without their module: utoipa makes a handler's
// module path its tag, and the document has none.
use self::maps::{__path_import_map, ImportedMap, MapUpload};
use self::objects::{
    __path_report_object, ColourInput, ObjectReport, PoseInput, ReportedObject, ShapeInput,
};
use self::on_demand::{
    __path_floor_on_demand_database, __path_on_demand_database, OnDemandRequest, WaypointDoc,
};
use self::people::{
    __path_report_people_observations, EstimateView, PeopleEstimates, PeopleObservation,
    PeopleObservations,
};
use self::places::{
    __path_get_place, __path_list_objects, __path_list_places, __path_place_map,
    __path_place_map_pgm, __path_place_map_yaml, __path_world_sdf, MapServerYaml, ObjectPose,
    ObjectView, PlaceView,
};
use self::robots::{
    __path_bridge_yaml, __path_get_robot, __path_list_robots, __path_robot_sdf, __path_robot_urdf,
    BridgeEntry, RobotView,
};
use crate::service::Knowledge;

/// The OpenAPI document of the REST API, generated from the handlers of the resource modules.
#[derive(OpenApi)]
#[openapi(
    info(title = "Mentalsim knowledge service", description = "TOSM knowledge for robot fleets: places, robots, maps, perceived objects, people counts and on-demand databases. SPARQL 1.1 Protocol at /sparql and Graph Store Protocol at /store are described by their W3C specifications."),
    paths(me, list_places, get_place, place_map, place_map_yaml, place_map_pgm, world_sdf, list_objects, list_robots, get_robot, robot_urdf, robot_sdf, bridge_yaml, import_map, report_object, report_people_observations, on_demand_database, floor_on_demand_database),
    components(
        schemas(Me, PlaceView, ObjectView, ObjectPose, MapServerYaml, BridgeEntry, RobotView, ImportedMap, MapUpload, ObjectReport, PoseInput, ShapeInput, ColourInput, ReportedObject, PeopleObservations, PeopleObservation, PeopleEstimates, EstimateView, OnDemandRequest, WaypointDoc, ErrorBody, ErrorDetail, edge::ErrorCode),
        responses(edge::error::responses::Unauthorized, edge::error::responses::Forbidden, edge::error::responses::StorageFull, edge::error::responses::PayloadTooLarge, edge::error::responses::UnsupportedMediaType, edge::error::responses::ServiceUnavailable)
    ),
    modifiers(&BearerAuth),
    security(("bearer" = []))
)]
pub struct KnowledgeApi;

/// The REST routes under `/v1`.
pub fn router(knowledge: Arc<Knowledge>) -> Router {
    Router::new()
        .route("/v1/places", get(places::list_places))
        .route("/v1/places/{id}", get(places::get_place))
        .route("/v1/places/{id}/map.png", get(places::place_map))
        .route("/v1/places/{id}/map.yaml", get(places::place_map_yaml))
        .route("/v1/places/{id}/map.pgm", get(places::place_map_pgm))
        .route(
            "/v1/places/{id}/objects",
            get(places::list_objects).post(objects::report_object),
        )
        .route(
            "/v1/places/{id}/observations",
            post(people::report_people_observations),
        )
        .route("/v1/me", get(me))
        .route("/v1/places/{id}/world.sdf", get(places::world_sdf))
        .route("/v1/robots/{id}/robot.urdf", get(robots::robot_urdf))
        .route("/v1/robots/{id}/robot.sdf", get(robots::robot_sdf))
        .route("/v1/robots/{id}/bridge.yaml", get(robots::bridge_yaml))
        .route("/v1/robots", get(robots::list_robots))
        .route("/v1/robots/{id}", get(robots::get_robot))
        .route("/v1/maps", post(maps::import_map))
        .route("/v1/on-demand", post(on_demand::on_demand_database))
        .route(
            "/v1/places/{id}/on-demand",
            get(on_demand::floor_on_demand_database),
        )
        .with_state(knowledge)
}

/// 429 `too_many_requests` saying `message`, with `Retry-After` the whole seconds of `wait_s`
/// rounded up (at least 1).
fn too_many_requests(message: String, wait_s: f64) -> axum::response::Response {
    use axum::response::IntoResponse;
    let mut response =
        edge::ApiError::new(edge::ErrorCode::TooManyRequests, message).into_response();
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a wait of at most a few seconds, rounded up"
    )]
    let retry = wait_s.ceil().max(1.0) as u64;
    response
        .headers_mut()
        .insert(axum::http::header::RETRY_AFTER, retry.into());
    response
}

/// Who a token belongs to.
#[derive(serde::Serialize, utoipa::ToSchema)]
pub struct Me {
    /// The token holder's name (a robot's id, a person's name).
    name: String,
    /// `engineer` (reads and writes everything) or `robot` (reads, plans, reports objects and
    /// people counts).
    role: &'static str,
}

/// The token's holder and role: what the console offers follows it.
#[utoipa::path(get, path = "/v1/me", responses(
    (status = 200, body = Me),
    (status = 401, response = edge::error::responses::Unauthorized)))]
async fn me(edge::Caller(principal): edge::Caller) -> Result<axum::Json<Me>, edge::ApiError> {
    Ok(axum::Json(Me {
        name: principal.name,
        role: match principal.role {
            edge::Role::Engineer => "engineer",
            edge::Role::Robot => "robot",
        },
    }))
}
