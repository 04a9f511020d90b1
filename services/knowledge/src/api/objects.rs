//! Perceived objects (`POST /v1/places/{id}/objects`): what robots report seeing in a place,
//! kept in the perceived graph and included in the next on-demand databases through it.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use edge::{ApiError, ErrorBody, ErrorCode, RobotCaller, Role};
use oxigraph::model::{NamedNode, Quad};
use serde::{Deserialize, Serialize};
use tosm::{Place, PlaceKind};
use utoipa::ToSchema;

use super::places::find_place;
use super::task::blocking;
use crate::graphs::PERCEIVED_GRAPH;
use crate::on_demand;
use crate::service::Knowledge;

/// A pose as reported by a robot, in the floor frame.
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseInput {
    /// x, metres.
    x: f64,
    /// y, metres.
    y: f64,
    /// Height of the object's centre above the floor, metres [default: half its height].
    #[serde(default)]
    z: Option<f64>,
    /// Heading, radians, counter-clockwise from +x [default: 0].
    #[serde(default)]
    yaw: f64,
}

/// A shape and its size, metres.
#[derive(Deserialize, ToSchema)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum ShapeInput {
    /// A box.
    // Every property is required, so `max_properties` (with `type`) is the schema's
    // `deny_unknown_fields`.
    #[schema(max_properties = 4)]
    Box {
        /// Extent along x, > 0.
        #[schema(exclusive_minimum = 0)]
        length: f64,
        /// Extent along y, > 0.
        #[schema(exclusive_minimum = 0)]
        width: f64,
        /// Extent along z, > 0.
        #[schema(exclusive_minimum = 0)]
        height: f64,
    },
    /// An upright cylinder.
    #[schema(max_properties = 3)]
    Cylinder {
        /// Diameter, > 0.
        #[schema(exclusive_minimum = 0)]
        diameter: f64,
        /// Height, > 0.
        #[schema(exclusive_minimum = 0)]
        height: f64,
    },
    /// A sphere.
    #[schema(max_properties = 2)]
    Sphere {
        /// Diameter, > 0.
        #[schema(exclusive_minimum = 0)]
        diameter: f64,
    },
}

/// A colour, components in [0, 1].
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ColourInput {
    /// Red, in [0, 1].
    #[schema(minimum = 0, maximum = 1)]
    r: f64,
    /// Green, in [0, 1].
    #[schema(minimum = 0, maximum = 1)]
    g: f64,
    /// Blue, in [0, 1].
    #[schema(minimum = 0, maximum = 1)]
    b: f64,
    /// Opacity, in [0, 1] [default: 1].
    #[serde(default = "one")]
    #[schema(minimum = 0, maximum = 1, default = 1.0)]
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
    /// 1-64 lower-case letters, digits, `-`, `_` (400 otherwise). Generated when absent.
    #[serde(default)]
    #[schema(pattern = "^[a-z0-9_-]{1,64}$")]
    id: Option<String>,
    /// The TOSM class: an object class's local name (`Door`, `Table`, `Chair`, `Shelf`,
    /// `Cabinet`, `Sofa`, `Bin`, `VendingMachine` or `Object`) or its full IRI, or the IRI of
    /// a class from another vocabulary (stated a `tosm:Object` too). The pattern admits
    /// such IRIs without query, fragment or percent-escapes; the service takes any valid IRI
    /// that names no other TOSM term.
    #[schema(
        pattern = "^(?:(?:https://mentalsim\\.dev/ontology/tosm#)?(?:Door|Table|Chair|Shelf|Cabinet|Sofa|Bin|VendingMachine|Object)|[a-z][a-z0-9+.-]*://[A-Za-z0-9._~-]+(?:/[A-Za-z0-9._~!$&'()*+,;=:@-]*)*)$"
    )]
    class: String,
    /// A name for people, not blank [default: the class and the id].
    #[serde(default)]
    #[schema(pattern = "[^\\s\\u0085]")]
    name: Option<String>,
    /// Where it is. `z` defaults to resting on the floor.
    pose: PoseInput,
    /// Its shape and size.
    shape: ShapeInput,
    /// Its colour, when seen.
    #[serde(default)]
    colour: Option<ColourInput>,
    /// Mass in kg, > 0, when known.
    #[serde(default)]
    #[schema(exclusive_minimum = 0)]
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

/// Adds or updates an object a robot perceived; the next on-demand database of a mission
/// through this place includes it. Robots and engineers.
#[utoipa::path(post, path = "/v1/places/{id}/objects",
    params(("id" = String, Path, min_length = 1, description = "The place: a floor, room, corridor or hall (IRI or tosm:identifier).")),
    request_body = ObjectReport,
    responses(
        (status = 201, description = "A new object was stored.", body = ReportedObject),
        (status = 200, description = "An earlier report of the same id was replaced.", body = ReportedObject),
        (status = 400, description = "The body is not JSON, or the object id breaks its rule.", body = ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, response = edge::error::responses::Forbidden),
        (status = 404, description = "No place has this IRI or identifier.", body = ErrorBody),
        (status = 413, response = edge::error::responses::PayloadTooLarge),
        (status = 415, response = edge::error::responses::UnsupportedMediaType),
        (status = 422, description = "The body does not fit the schema (a missing or unknown field, a wrong type), the place is a building, the class is no object class, or a value is out of range.", body = ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
        (status = 507, response = edge::error::responses::StorageFull),
    ))]
pub(super) async fn report_object(
    State(k): State<Arc<Knowledge>>,
    RobotCaller(principal): RobotCaller,
    Path(id): Path<String>,
    Json(report): Json<ObjectReport>,
) -> Result<Response, ApiError> {
    let is_robot = principal.role == Role::Robot;
    k.check_space(0)?;
    if is_robot && let Err(wait_s) = k.take_report(&principal.name) {
        return Ok(super::too_many_requests(
            format!(
                "{} sent more than {} object reports in a burst ({} per second on average); retry in {wait_s:.1} s",
                principal.name,
                crate::service::REPORT_BURST,
                crate::service::REPORTS_PER_SECOND
            ),
            wait_s,
        ));
    }
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
        if is_robot {
            check_robot_report(&store, &object)?;
        }
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

/// What a robot may not do with a report: change an object another agent reported, or type it
/// with a class the ontology does not know as an object class.
fn check_robot_report(
    store: &crate::KnowledgeStore,
    object: &tosm::Object,
) -> Result<(), ApiError> {
    // Every IRI below goes into a query: each must be one (no `>` or space can break out).
    let iri = |text: &str, what: &str| {
        NamedNode::new(text)
            .map_err(|e| ApiError::new(ErrorCode::Unprocessable, format!("{what} <{text}>: {e}")))
    };
    let reporter = iri(
        object.reported_by.as_deref().unwrap_or_default(),
        "reporter",
    )?;
    let subject = iri(&object.iri, "object")?;
    let taken = store.ask(&format!(
        "ASK {{ GRAPH <{PERCEIVED_GRAPH}> {{ {subject} {} ?by FILTER(?by != {reporter}) }} }}",
        tosm::vocab::REPORTED_BY,
    ))?;
    if taken {
        return Err(ApiError::new(
            ErrorCode::Forbidden,
            format!(
                "{} was reported by another agent: a robot changes only the objects it reported \
                 (choose another id, or ask an engineer)",
                object.iri
            ),
        ));
    }
    if object.class == tosm::ObjectClass::Other && object.class_iri != tosm::vocab::OBJECT.as_str()
    {
        let class = iri(&object.class_iri, "class")?;
        let known = store.ask(&format!(
            "ASK {{ GRAPH ?g {{ {class} <http://www.w3.org/2000/01/rdf-schema#subClassOf>+ {} }} }}",
            tosm::vocab::OBJECT
        ))?;
        if !known {
            return Err(ApiError::new(
                ErrorCode::Unprocessable,
                format!(
                    "class <{}> is not an object class of the ontology: robots report TOSM \
                     classes or classes an engineer declared a subclass of tosm:Object",
                    object.class_iri
                ),
            ));
        }
    }
    Ok(())
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
