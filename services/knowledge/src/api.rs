//! The knowledge service's REST API for robots and operators: browse places and robots, fetch
//! a floor's map, import maps, report perceived objects, and get on-demand databases.
//!
//! Wire types live here and are converted from the core types on purpose.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::{Multipart, Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use edge::{ApiError, ErrorCode};
use oxigraph::io::{RdfFormat, RdfSerializer};
use oxigraph::model::{Graph, NamedNode, Quad};
use serde::{Deserialize, Serialize};
use tosm::{Place, PlaceKind};
use utoipa::{OpenApi, ToSchema};

use crate::auth::Role;
use crate::maps::{self, ImportError};
use crate::on_demand::{self, Mission, OnDemandError, Waypoint};
use crate::service::Knowledge;

/// The OpenAPI document of the REST API, generated from the handlers below.
#[derive(OpenApi)]
#[openapi(
    info(title = "Mentalsim knowledge service", description = "TOSM knowledge for robot fleets: places, robots, maps, perceived objects and on-demand databases. SPARQL 1.1 Protocol at /sparql and Graph Store Protocol at /store are described by their W3C specifications."),
    paths(list_places, get_place, place_map, world_sdf, list_robots, get_robot, robot_urdf, import_map, report_object, on_demand_database, floor_on_demand_database),
    components(schemas(PlaceView, RobotView, ImportedMap, ObjectReport, PoseInput, ShapeInput, ColourInput, ReportedObject, OnDemandRequest, WaypointInput, ErrorBody, ErrorDetail)),
    modifiers(&BearerAuth),
    security(("bearer" = []))
)]
pub struct KnowledgeApi;

/// Declares the bearer-token scheme the `security` entries of our OpenAPI documents name.
#[derive(Debug)]
pub struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}

/// The error body every endpoint answers with.
#[derive(Serialize, ToSchema)]
pub struct ErrorBody {
    error: ErrorDetail,
}

/// An error's code and message.
#[derive(Serialize, ToSchema)]
pub struct ErrorDetail {
    /// Stable machine-readable code, e.g. `bad_request`, `not_found`, `unprocessable`.
    code: String,
    /// What is wrong, for people.
    message: String,
}

/// The REST routes under `/v1`.
pub fn router(knowledge: Arc<Knowledge>) -> Router {
    Router::new()
        .route("/v1/places", get(list_places))
        .route("/v1/places/{id}", get(get_place))
        .route("/v1/places/{id}/map.png", get(place_map))
        .route("/v1/places/{id}/objects", post(report_object))
        .route("/v1/places/{id}/world.sdf", get(world_sdf))
        .route("/v1/robots/{id}/robot.urdf", get(robot_urdf))
        .route("/v1/robots", get(list_robots))
        .route("/v1/robots/{id}", get(get_robot))
        .route("/v1/maps", post(import_map))
        .route("/v1/on-demand", post(on_demand_database))
        .route("/v1/places/{id}/on-demand", get(floor_on_demand_database))
        .with_state(knowledge)
}

async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(ApiError::internal)?
}

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

fn find_place(places: &[Place], id: &str) -> Result<usize, ApiError> {
    places
        .iter()
        .position(|p| p.iri == id || p.symbol.identifier.as_deref() == Some(id))
        .ok_or_else(|| ApiError::not_found(format!("no place has IRI or identifier {id:?}")))
}

/// Every place, buildings to rooms.
#[utoipa::path(get, path = "/v1/places", responses((status = 200, body = [PlaceView]), (status = 401, body = ErrorBody)))]
async fn list_places(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
) -> Result<Json<Vec<PlaceView>>, ApiError> {
    k.tokens.authenticate(&headers)?;
    blocking(move || {
        let store = k.store()?;
        let places = on_demand::all_places(&store)?;
        Ok(Json(places.iter().map(PlaceView::from).collect()))
    })
    .await
}

/// One place, by IRI (percent-encoded) or identifier.
#[utoipa::path(get, path = "/v1/places/{id}", params(("id" = String, Path, description = "IRI or tosm:identifier")), responses((status = 200, body = PlaceView), (status = 404, body = ErrorBody)))]
async fn get_place(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Json<PlaceView>, ApiError> {
    k.tokens.authenticate(&headers)?;
    blocking(move || {
        let store = k.store()?;
        let places = on_demand::all_places(&store)?;
        let i = find_place(&places, &id)?;
        Ok(Json(PlaceView::from(&places[i])))
    })
    .await
}

/// A floor's occupancy grid as a PNG (free 254, occupied 0, unknown 205; top row first).
#[utoipa::path(get, path = "/v1/places/{id}/map.png", params(("id" = String, Path)), responses((status = 200, content_type = "image/png", body = Vec<u8>), (status = 404, body = ErrorBody)))]
async fn place_map(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    k.tokens.authenticate(&headers)?;
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

/// Which robot to place in an exported world.
#[derive(Deserialize, utoipa::IntoParams)]
pub struct WorldQuery {
    /// The robot's IRI or identifier [default: the first robot in the store].
    robot: Option<String>,
}

/// The SDF 1.9 world of a floor (or of the floor a place is on), generated from the graph alone
/// by the simulation parser: walls from the metric map, library models, and placeholders of
/// their stated shape and colour. Gazebo loads it as it is.
#[utoipa::path(get, path = "/v1/places/{id}/world.sdf", params(("id" = String, Path), WorldQuery), responses((status = 200, content_type = "application/xml", body = String), (status = 404, body = ErrorBody), (status = 422, body = ErrorBody)))]
async fn world_sdf(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    Path(id): Path<String>,
    axum::extract::Query(query): axum::extract::Query<WorldQuery>,
) -> Result<Response, ApiError> {
    k.tokens.authenticate(&headers)?;
    let sdf = blocking(move || {
        let store = k.store()?;
        let places = on_demand::all_places(&store)?;
        let place = &places[find_place(&places, &id)?];
        let mut floor = Some(place);
        while let Some(p) = floor {
            if p.kind == PlaceKind::Floor {
                break;
            }
            floor = p
                .parent
                .as_deref()
                .and_then(|parent| places.iter().find(|q| q.iri == parent));
        }
        let floor = floor.ok_or_else(|| {
            ApiError::new(
                ErrorCode::Unprocessable,
                format!(
                    "{} is on no floor: only floors and the places on them have a world",
                    place.iri
                ),
            )
        })?;
        let db = on_demand::floor_database(&store, &floor.iri, query.robot.as_deref())?;
        let graph: Graph = db.triples.into_iter().collect();
        let spec = sim::parse_floor(&graph, &db.robot, &floor.iri).map_err(|p| {
            ApiError::new(
                ErrorCode::Unprocessable,
                format!("the stored knowledge does not make a world: {p}"),
            )
        })?;
        Ok(sim::export::world_sdf(&spec))
    })
    .await?;
    Ok(([(header::CONTENT_TYPE, "application/xml")], sdf).into_response())
}

/// The URDF of a robot, generated from its TOSM description: links, joints, wheels, laser
/// and camera sensors. `check_urdf` and ROS load it as it is.
#[utoipa::path(get, path = "/v1/robots/{id}/robot.urdf", params(("id" = String, Path)), responses((status = 200, content_type = "application/xml", body = String), (status = 404, body = ErrorBody), (status = 422, body = ErrorBody)))]
async fn robot_urdf(
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

fn read_robots(store: &crate::KnowledgeStore) -> Result<Vec<tosm::Robot>, ApiError> {
    let graph = union_graph(store)?;
    tosm::read_robots(&graph)
        .map_err(|p| ApiError::internal(format!("stored robots do not validate: {p}")))
}

/// Every asserted triple (not the entailments), as one graph.
fn union_graph(store: &crate::KnowledgeStore) -> Result<Graph, ApiError> {
    let mut graph = Graph::new();
    for quad in store.snapshot()?.iter() {
        let quad = quad.map_err(ApiError::internal)?;
        if quad.graph_name.as_ref()
            != oxigraph::model::GraphNameRef::NamedNode(crate::inference::INFERRED_GRAPH)
        {
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
#[utoipa::path(get, path = "/v1/robots", responses((status = 200, body = [RobotView])))]
async fn list_robots(
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
#[utoipa::path(get, path = "/v1/robots/{id}", params(("id" = String, Path)), responses((status = 200, body = RobotView), (status = 404, body = ErrorBody)))]
async fn get_robot(
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
            e if e.is_client_error() => ApiError::new(ErrorCode::Unprocessable, e.to_string()),
            e => ApiError::internal(e),
        }
    }
}

/// Imports a ROS map_server map as a floor. Multipart form: `yaml` (the map's YAML), `image`
/// (its PGM or PNG), `name` (lower-case letters, digits, `-`, `_`). Engineers only.
#[utoipa::path(post, path = "/v1/maps", request_body(content_type = "multipart/form-data", content = String, description = "fields: name, yaml, image"), responses((status = 201, body = ImportedMap), (status = 400, body = ErrorBody), (status = 422, body = ErrorBody)))]
async fn import_map(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    mut form: Multipart,
) -> Result<Response, ApiError> {
    k.tokens.require(&headers, Role::Engineer)?;
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

/// A pose as reported by a robot, in the floor frame.
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseInput {
    x: f64,
    y: f64,
    #[serde(default)]
    z: Option<f64>,
    #[serde(default)]
    yaw: f64,
}

/// A shape and its size, metres.
#[derive(Deserialize, ToSchema)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum ShapeInput {
    /// A box.
    Box {
        /// Extent along x.
        length: f64,
        /// Extent along y.
        width: f64,
        /// Extent along z.
        height: f64,
    },
    /// An upright cylinder.
    Cylinder {
        /// Diameter.
        diameter: f64,
        /// Height.
        height: f64,
    },
    /// A sphere.
    Sphere {
        /// Diameter.
        diameter: f64,
    },
}

/// A colour, components in [0, 1].
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ColourInput {
    r: f64,
    g: f64,
    b: f64,
    #[serde(default = "one")]
    a: f64,
}

fn one() -> f64 {
    1.0
}

/// An object a robot perceived in a place.
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ObjectReport {
    /// A stable id for the object within the place; reporting the same id again updates it.
    /// Lower-case letters, digits, `-`, `_`. Generated when absent.
    #[serde(default)]
    id: Option<String>,
    /// The TOSM class: a local name such as `VendingMachine`, `Table`, or a full class IRI.
    class: String,
    /// A name for people.
    #[serde(default)]
    name: Option<String>,
    /// Where it is. `z` defaults to resting on the floor.
    pose: PoseInput,
    /// Its shape and size.
    shape: ShapeInput,
    /// Its colour, when seen.
    #[serde(default)]
    colour: Option<ColourInput>,
    /// Mass in kg, when known.
    #[serde(default)]
    mass_kg: Option<f64>,
}

/// What was stored for a report.
#[derive(Serialize, ToSchema)]
pub struct ReportedObject {
    /// The object's IRI.
    iri: String,
    /// The place it was reported in.
    place: String,
    /// Who reported it.
    reported_by: String,
    /// When (`xsd:dateTime`).
    reported_at: String,
    /// Whether an earlier report of the same id was replaced.
    updated: bool,
}

/// The named graph robots' reports live in.
pub const PERCEIVED_GRAPH: &str = "https://mentalsim.dev/graph/perceived";

/// Adds or updates an object a robot perceived; the next on-demand database of a mission
/// through this place includes it. Robots and engineers.
#[utoipa::path(post, path = "/v1/places/{id}/objects", params(("id" = String, Path)), request_body = ObjectReport, responses((status = 201, body = ReportedObject), (status = 200, body = ReportedObject), (status = 404, body = ErrorBody), (status = 422, body = ErrorBody)))]
async fn report_object(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    Path(id): Path<String>,
    Json(report): Json<ObjectReport>,
) -> Result<Response, ApiError> {
    let principal = k.tokens.require(&headers, Role::Robot)?;
    blocking(move || {
        let store = k.store()?;
        let places = on_demand::all_places(&store)?;
        let place = places[find_place(&places, &id)?].clone();
        if matches!(place.kind, PlaceKind::Building) {
            return Err(ApiError::new(
                ErrorCode::Unprocessable,
                format!(
                    "{} is a building: report objects in a floor, room, corridor or hall",
                    place.iri
                ),
            ));
        }
        let slug = match &report.id {
            Some(s)
                if !s.is_empty()
                    && s.len() <= 64
                    && s.chars().all(|c| {
                        c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '_'
                    }) =>
            {
                s.clone()
            }
            Some(s) => {
                return Err(ApiError::bad_request(format!(
                    "object id {s:?} must be 1-64 characters of a-z, 0-9, '-' and '_'"
                )));
            }
            None => uuid_slug(),
        };
        let object = to_object(&place, &slug, &report, &principal.name)?;
        let triples = tosm::object_to_triples(&object).map_err(|p| {
            ApiError::new(ErrorCode::Unprocessable, p.to_string())
                .with_details(serde_json::json!({ "problems": p.to_string() }))
        })?;
        let graph = NamedNode::new_unchecked(PERCEIVED_GRAPH);
        let owned = [
            NamedNode::new_unchecked(object.iri.clone()),
            NamedNode::new_unchecked(format!("{}/pose", object.iri)),
            NamedNode::new_unchecked(format!("{}/shape", object.iri)),
        ];
        let quads: Vec<Quad> = triples
            .into_iter()
            .map(|t| t.in_graph(graph.clone()))
            .collect();
        let updated = store.replace_subjects(graph.as_ref(), &owned, &quads)?;
        k.after_write()?;
        let status = if updated {
            StatusCode::OK
        } else {
            StatusCode::CREATED
        };
        Ok((
            status,
            Json(ReportedObject {
                iri: object.iri,
                place: place.iri,
                reported_by: principal.name,
                reported_at: object.reported_at.unwrap_or_default(),
                updated,
            }),
        )
            .into_response())
    })
    .await
}

fn uuid_slug() -> String {
    uuid::Uuid::now_v7().simple().to_string()
}

fn to_object(
    place: &Place,
    slug: &str,
    report: &ObjectReport,
    reporter: &str,
) -> Result<tosm::Object, ApiError> {
    let class_iri = if report.class.contains("://") {
        report.class.clone()
    } else {
        format!("{}{}", tosm::vocab::NS, report.class)
    };
    let class = tosm::vocab::ALL
        .iter()
        .find(|(_, iri)| iri.as_str() == class_iri)
        .map(|(local, _)| *local);
    let class = match class {
        Some("Door") => tosm::ObjectClass::Door,
        Some("Table") => tosm::ObjectClass::Table,
        Some("Chair") => tosm::ObjectClass::Chair,
        Some("Shelf") => tosm::ObjectClass::Shelf,
        Some("Cabinet") => tosm::ObjectClass::Cabinet,
        Some("Sofa") => tosm::ObjectClass::Sofa,
        Some("Bin") => tosm::ObjectClass::Bin,
        Some("VendingMachine") => tosm::ObjectClass::VendingMachine,
        Some("Object") => tosm::ObjectClass::Other,
        Some(other) => {
            return Err(ApiError::new(
                ErrorCode::Unprocessable,
                format!("class {other} is not an object class"),
            ));
        }
        None if report.class.contains("://") => tosm::ObjectClass::Other,
        None => {
            return Err(ApiError::new(
                ErrorCode::Unprocessable,
                format!(
                    "unknown object class {:?}: use a TOSM class name such as VendingMachine or Table, or a full IRI",
                    report.class
                ),
            ));
        }
    };
    let shape = match report.shape {
        ShapeInput::Box {
            length,
            width,
            height,
        } => tosm::Shape::Box {
            length,
            width,
            height,
        },
        ShapeInput::Cylinder { diameter, height } => tosm::Shape::Cylinder { diameter, height },
        ShapeInput::Sphere { diameter } => tosm::Shape::Sphere { diameter },
    };
    let z = report.pose.z.unwrap_or(shape.size()[2] / 2.0);
    let now = oxsdatatypes::DateTime::now().to_string();
    Ok(tosm::Object {
        iri: format!("{}/objects/{slug}", place.iri),
        class_iri,
        class,
        symbol: tosm::Symbol {
            name: report
                .name
                .clone()
                .unwrap_or_else(|| format!("{} {slug}", report.class)),
            identifier: Some(slug.to_owned()),
            description: None,
        },
        pose: tosm::Pose3::new(report.pose.x, report.pose.y, z, report.pose.yaw),
        shape,
        colour: report.colour.as_ref().map(|c| tosm::Colour {
            r: c.r,
            g: c.g,
            b: c.b,
            a: c.a,
        }),
        colour_name: None,
        physical: tosm::Physical {
            mass_kg: report.mass_kg,
            material: None,
            friction: None,
        },
        inside_of: place.iri.clone(),
        relations: Vec::new(),
        is_open: None,
        reported_by: Some(if reporter.contains("://") {
            reporter.to_owned()
        } else {
            format!("https://mentalsim.dev/data/agents/{reporter}")
        }),
        reported_at: Some(now),
    })
}

/// A waypoint: a place (IRI or identifier), or a point on a floor.
#[derive(Deserialize, ToSchema)]
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

/// A mission for which to build an on-demand database.
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct OnDemandRequest {
    /// The robot's IRI or identifier.
    robot: String,
    /// Where the robot starts.
    start: WaypointInput,
    /// Where it must go, in order (at least one).
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
            | OnDemandError::NotConnected { .. } => {
                ApiError::new(ErrorCode::Unprocessable, e.to_string())
            }
            OnDemandError::Store(_) => ApiError::internal(e),
        }
    }
}

/// The on-demand database for a mission (thesis §3.4): the route's places with their maps and
/// boundaries, the objects in them, and the robot — as Turtle (default), N-Triples or JSON-LD
/// by `Accept`. `X-Triple-Count` gives its size; `X-Route` the places crossed.
#[utoipa::path(post, path = "/v1/on-demand", request_body = OnDemandRequest, responses(
    (status = 200, description = "the subset", content_type = "text/turtle", body = String),
    (status = 400, body = ErrorBody), (status = 404, body = ErrorBody), (status = 406, body = ErrorBody), (status = 422, body = ErrorBody)))]
async fn on_demand_database(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    Json(request): Json<OnDemandRequest>,
) -> Result<Response, ApiError> {
    k.tokens.require(&headers, Role::Robot)?;
    let format = graph_format(headers.get(header::ACCEPT).and_then(|v| v.to_str().ok()))?;
    let mut goals = Vec::new();
    for (i, g) in request.goals.into_iter().enumerate() {
        goals.push(waypoint(&format!("goal {}", i + 1), g)?);
    }
    let mission = Mission {
        robot: request.robot,
        start: waypoint("start", request.start)?,
        goals,
    };
    blocking(move || {
        let store = k.store()?;
        let db = on_demand::build(&store, &mission)?;
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

/// The on-demand database of the whole floor a place is on (the place itself when it is a
/// floor), for one robot: everything a mental simulation of that floor needs — the floor, its
/// ancestors, the places on it with their maps and boundaries, the objects in them, and the
/// robot. Training and evaluation workers fetch their worlds here. Turtle (default),
/// N-Triples or JSON-LD by `Accept`; `X-Floor` and `X-Robot` give the IRIs of the floor and
/// the robot, `X-Triple-Count` its size. The `ETag` names the graph's state: a request with
/// `If-None-Match` set to it is answered 304 without a body while nothing was written since.
#[utoipa::path(get, path = "/v1/places/{id}/on-demand", params(("id" = String, Path, description = "a floor or a place on one: IRI or tosm:identifier"), WorldQuery), responses(
    (status = 200, description = "the subset", content_type = "text/turtle", body = String),
    (status = 304, description = "unchanged since the `If-None-Match` tag"),
    (status = 404, body = ErrorBody), (status = 406, body = ErrorBody), (status = 422, body = ErrorBody)))]
async fn floor_on_demand_database(
    State(k): State<Arc<Knowledge>>,
    headers: HeaderMap,
    Path(id): Path<String>,
    axum::extract::Query(query): axum::extract::Query<WorldQuery>,
) -> Result<Response, ApiError> {
    k.tokens.require(&headers, Role::Robot)?;
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
