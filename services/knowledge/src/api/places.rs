//! Places: browse them (`/v1/places`, `/v1/places/{id}`), a floor's map as a PNG, and the SDF
//! world of a floor generated from the graph by the simulation parser.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use edge::{ApiError, Caller, ErrorBody, ErrorCode};
use oxigraph::model::Graph;
use serde::{Deserialize, Serialize};
use tosm::{Place, PlaceKind};
use utoipa::ToSchema;

use super::task::blocking;
use crate::on_demand;
use crate::service::Knowledge;

/// A place as robots and operators browse it.
#[derive(Serialize, ToSchema)]
pub struct PlaceView {
    /// The place's IRI.
    iri: String,
    /// `tosm:identifier`, usable as `{id}` in paths.
    id: Option<String>,
    /// `tosm:name`.
    name: String,
    /// building, floor, corridor, room, hall or place.
    kind: String,
    /// The place it is directly inside of.
    parent: Option<String>,
    /// Places reachable directly from it.
    connected: Vec<String>,
    /// Occupied share of its area, in [0, 1].
    complexity: Option<f64>,
    /// Boundary polygon in the floor frame, metres.
    boundary: Vec<[f64; 2]>,
    /// For floors: the map's size in cells, resolution in m/cell and free area in m².
    map: Option<MapView>,
}

/// Summary of a floor's metric map.
#[derive(Serialize, ToSchema)]
pub struct MapView {
    width: usize,
    height: usize,
    resolution: f64,
    origin: [f64; 3],
    free_area_m2: f64,
}

fn kind_name(kind: PlaceKind) -> &'static str {
    match kind {
        PlaceKind::Building => "building",
        PlaceKind::Floor => "floor",
        PlaceKind::Corridor => "corridor",
        PlaceKind::Room => "room",
        PlaceKind::Hall => "hall",
        PlaceKind::Other => "place",
    }
}

impl From<&Place> for PlaceView {
    fn from(p: &Place) -> Self {
        Self {
            iri: p.iri.clone(),
            id: p.symbol.identifier.clone(),
            name: p.symbol.name.clone(),
            kind: kind_name(p.kind).to_owned(),
            parent: p.parent.clone(),
            connected: p.connected.clone(),
            complexity: p.complexity,
            boundary: p.boundary.iter().map(|&(x, y)| [x, y]).collect(),
            map: p.map.as_ref().map(|m| MapView {
                width: m.grid.width,
                height: m.grid.height,
                resolution: m.resolution,
                origin: [m.origin.x, m.origin.y, m.origin.yaw],
                free_area_m2: m.grid.free_area_m2(),
            }),
        }
    }
}

/// The index of the place with IRI or identifier `id`; 404 when there is none.
pub(super) fn find_place(places: &[Place], id: &str) -> Result<usize, ApiError> {
    places
        .iter()
        .position(|p| p.iri == id || p.symbol.identifier.as_deref() == Some(id))
        .ok_or_else(|| ApiError::not_found(format!("no place has IRI or identifier {id:?}")))
}

/// Every place, buildings to rooms.
#[utoipa::path(get, path = "/v1/places", responses(
    (status = 200, body = [PlaceView]),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn list_places(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
) -> Result<Json<Vec<PlaceView>>, ApiError> {
    blocking(move || {
        let store = k.store()?;
        let places = on_demand::all_places(&store)?;
        Ok(Json(places.iter().map(PlaceView::from).collect()))
    })
    .await
}

/// One place, by IRI (percent-encoded) or identifier.
#[utoipa::path(get, path = "/v1/places/{id}", params(("id" = String, Path, min_length = 1, description = "IRI or tosm:identifier")), responses(
    (status = 200, body = PlaceView),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No place has this IRI or identifier.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn get_place(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Json<PlaceView>, ApiError> {
    blocking(move || {
        let store = k.store()?;
        let places = on_demand::all_places(&store)?;
        let i = find_place(&places, &id)?;
        Ok(Json(PlaceView::from(&places[i])))
    })
    .await
}

/// A floor's occupancy grid as a PNG (free 254, occupied 0, unknown 205; top row first).
#[utoipa::path(get, path = "/v1/places/{id}/map.png", params(("id" = String, Path, min_length = 1, description = "A floor: IRI or tosm:identifier.")), responses(
    (status = 200, content_type = "image/png", body = Vec<u8>),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No place has this IRI or identifier, or it has no metric map (only floors do).", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn place_map(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let png = blocking(move || {
        let store = k.store()?;
        let places = on_demand::all_places(&store)?;
        let place = &places[find_place(&places, &id)?];
        place.map.as_ref().map(|m| m.png.clone()).ok_or_else(|| {
            ApiError::not_found(format!(
                "place {} has no metric map (only floors do)",
                place.iri
            ))
        })
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "image/png")], png).into_response())
}

/// Which robot the exported world is made for, and where to put it.
#[derive(Deserialize, utoipa::IntoParams)]
pub struct WorldQuery {
    /// The robot's IRI or identifier [default: the first robot in the store]. An unknown one
    /// (an empty one included) is 404.
    #[param(nullable = false)]
    pub(super) robot: Option<String>,
    /// With `y`: the world includes the robot's gz-sim model (as `robot.sdf`) standing at
    /// (`x`, `y`) in the map frame, metres. Without both, the world has no robot
    /// (`ros_gz_sim create` spawns one).
    #[param(nullable = false)]
    pub(super) x: Option<f64>,
    /// See `x`.
    #[param(nullable = false)]
    pub(super) y: Option<f64>,
    /// The robot's heading with `x` and `y`, radians [default: 0].
    #[param(nullable = false)]
    pub(super) yaw: Option<f64>,
}

impl WorldQuery {
    /// Where to put the robot, if anywhere; 400 for half a position or a non-finite number.
    fn robot_pose(&self) -> Result<Option<sim::Pose2>, ApiError> {
        let pose = match (self.x, self.y) {
            (None, None) if self.yaw.is_none() => return Ok(None),
            (Some(x), Some(y)) => sim::Pose2::new(x, y, self.yaw.unwrap_or(0.0)),
            _ => {
                return Err(ApiError::bad_request(
                    "x, y: give both to place the robot in the world (and yaw only with them)",
                ));
            }
        };
        if [pose.x, pose.y, pose.yaw].iter().all(|v| v.is_finite()) {
            Ok(Some(pose))
        } else {
            Err(ApiError::bad_request("x, y, yaw: must be finite numbers"))
        }
    }
}

/// The SDF 1.9 world of a floor (or of the floor a place is on), generated from the graph alone
/// by the simulation parser: walls from the metric map, library models, and placeholders of
/// their stated shape and colour, with the systems gz-sim needs to run a robot (physics, user
/// commands, scene broadcaster, sensors on ogre2), and the robot itself where `x` and `y` put
/// it. gz-sim loads it as it is.
#[utoipa::path(get, path = "/v1/places/{id}/world.sdf", params(("id" = String, Path, min_length = 1, description = "A floor or a place on one: IRI or tosm:identifier."), WorldQuery), responses(
    (status = 200, content_type = "application/xml", body = String),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 400, description = "Half a robot position (`x` without `y`, or `yaw` alone), or a non-finite one.", body = ErrorBody),
    (status = 404, description = "No place has this IRI or identifier, or it is on no floor (a building, or a place outside every floor: only floors and the places on them have a world), or no robot the `robot` given (or none at all).", body = ErrorBody),
    (status = 422, description = "The stored knowledge does not make a world.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn world_sdf(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
    axum::extract::Query(query): axum::extract::Query<WorldQuery>,
) -> Result<Response, ApiError> {
    let at = query.robot_pose()?;
    let sdf = blocking(move || {
        let spec = floor_spec(&k, &id, query.robot.as_deref())?;
        Ok(match at {
            Some(start) => sim::export::world_sdf_with_robot(&spec, start),
            None => sim::export::world_sdf(&spec),
        })
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "application/xml")], sdf).into_response())
}

/// The world the simulation parser makes of the floor `id` is on (or is), with `robot` in it.
fn floor_spec(k: &Knowledge, id: &str, robot: Option<&str>) -> Result<sim::WorldSpec, ApiError> {
    let store = k.store()?;
    let places = on_demand::all_places(&store)?;
    let place = &places[find_place(&places, id)?];
    let floor = on_demand::containers(|iri| places.iter().find(|q| q.iri == iri), place)?
        .into_iter()
        .find(|p| p.kind == PlaceKind::Floor);
    let floor = floor.ok_or_else(|| {
        ApiError::not_found(format!(
            "{} is on no floor: only floors and the places on them have a world",
            place.iri
        ))
    })?;
    let db = on_demand::floor_database(&store, &floor.iri, robot)?;
    let graph: Graph = db.triples.into_iter().collect();
    sim::parse_floor(&graph, &db.robot, &floor.iri).map_err(|p| {
        ApiError::new(
            ErrorCode::Unprocessable,
            format!("the stored knowledge does not make a world: {p}"),
        )
    })
}

/// An object as the simulation sees it: what the console draws on a floor's map.
#[derive(Serialize, ToSchema)]
pub struct ObjectView {
    /// The object's IRI.
    iri: String,
    /// Its TOSM class (local name or IRI), when stated.
    class: Option<String>,
    /// `box`, `cylinder` or `sphere`.
    shape: &'static str,
    /// Bounding-box extents along the object's x, y and z axes, metres.
    size: [f64; 3],
    /// Pose of the bounding-box centre in the floor frame: x, y, z in metres, yaw in radians.
    pose: ObjectPose,
    /// Colour as `#rrggbb`.
    colour: String,
    /// Whether the simulation stands in a placeholder of the object's own shape (no library
    /// model for its class).
    placeholder: bool,
    /// For doors: whether the leaf is open.
    open: bool,
}

/// Where an object stands.
#[derive(Serialize, ToSchema)]
pub struct ObjectPose {
    x: f64,
    y: f64,
    z: f64,
    yaw: f64,
}

/// Every object on the floor a place is on (or of that floor), as the simulation parser builds
/// it from the on-demand database: shape, size, pose, colour, and whether it is a placeholder.
#[utoipa::path(get, path = "/v1/places/{id}/objects", params(("id" = String, Path, min_length = 1, description = "A floor or a place on one: IRI or tosm:identifier.")), responses(
    (status = 200, body = [ObjectView]),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No place has this IRI or identifier, or it is on no floor, or there is no robot to make a world with.", body = ErrorBody),
    (status = 422, description = "The stored knowledge does not make a world.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn list_objects(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Json<Vec<ObjectView>>, ApiError> {
    blocking(move || {
        let spec = floor_spec(&k, &id, None)?;
        Ok(Json(
            spec.objects
                .iter()
                .map(|o| ObjectView {
                    iri: o.id.clone(),
                    class: o.class.clone(),
                    shape: o.shape.name(),
                    size: [o.size.x, o.size.y, o.size.z],
                    pose: ObjectPose {
                        x: o.pose.x,
                        y: o.pose.y,
                        z: o.pose.z,
                        yaw: o.pose.yaw,
                    },
                    colour: o.colour.to_hex(),
                    placeholder: sim::library::model_for(o) == sim::library::Model::Placeholder,
                    open: o.open,
                })
                .collect(),
        ))
    })
    .await
}

/// The occupancy grid of the floor the place `id` is on (or is); 404 naming the place when it
/// is on no floor or its floor has no map.
fn floor_grid(k: &Knowledge, id: &str) -> Result<tosm::OccupancyGrid, ApiError> {
    let store = k.store()?;
    let places = on_demand::all_places(&store)?;
    let place = &places[find_place(&places, id)?];
    let floor = on_demand::containers(|iri| places.iter().find(|q| q.iri == iri), place)?
        .into_iter()
        .find(|p| p.kind == PlaceKind::Floor)
        .ok_or_else(|| {
            ApiError::not_found(format!(
                "{} is on no floor: only a floor and the places on it have a map",
                place.iri
            ))
        })?;
    floor
        .map
        .as_ref()
        .map(|m| m.grid.clone())
        .ok_or_else(|| ApiError::not_found(format!("floor {} has no metric map", floor.iri)))
}

/// The YAML `map_server` reads, as `GET /v1/places/{id}/map.yaml` writes it. Documentation
/// only: the handler writes [`tosm::RosMapMeta::to_yaml`].
#[derive(ToSchema)]
#[allow(dead_code, reason = "read by the OpenAPI document, never built")]
pub struct MapServerYaml {
    /// The image file, beside the YAML: `map.pgm`.
    image: String,
    /// Metres per cell.
    resolution: f64,
    /// The lower-left cell's corner in the map frame: x, y (metres), yaw (radians).
    origin: [f64; 3],
    /// 0: black is occupied.
    negate: u8,
    /// Occupancy probability above which a cell is occupied (0.65).
    occupied_thresh: f64,
    /// Occupancy probability below which a cell is free (0.196).
    free_thresh: f64,
    /// `trinary`.
    mode: String,
}

/// The floor a place is on as nav2's `map_server` loads it: this YAML (trinary, thresholds
/// 0.65 / 0.196, `image: map.pgm`) beside `map.pgm`. Importing the two (`POST /v1/maps`) gives
/// the same grid back.
#[utoipa::path(get, path = "/v1/places/{id}/map.yaml", params(("id" = String, Path, min_length = 1, description = "A floor or a place on one: IRI or tosm:identifier.")), responses(
    (status = 200, content_type = "application/yaml", body = MapServerYaml),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No place has this IRI or identifier, or it is on no floor with a map.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn place_map_yaml(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let yaml = blocking(move || {
        let grid = floor_grid(&k, &id)?;
        Ok(tosm::RosMapMeta::for_grid_png("map.pgm", grid.resolution, grid.origin).to_yaml())
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "application/yaml")], yaml).into_response())
}

/// The floor a place is on as a binary PGM (free 254, occupied 0, unknown 205, top row first),
/// the image `map.yaml` names.
#[utoipa::path(get, path = "/v1/places/{id}/map.pgm", params(("id" = String, Path, min_length = 1, description = "A floor or a place on one: IRI or tosm:identifier.")), responses(
    (status = 200, content_type = "image/x-portable-graymap", body = Vec<u8>),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No place has this IRI or identifier, or it is on no floor with a map.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub(super) async fn place_map_pgm(
    State(k): State<Arc<Knowledge>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let pgm = blocking(move || Ok(floor_grid(&k, &id)?.to_pgm())).await?;
    Ok(([(header::CONTENT_TYPE, "image/x-portable-graymap")], pgm).into_response())
}
