//! Perceived objects (`POST /v1/places/{id}/objects`): what robots report seeing in a place,
//! kept in the perceived graph and included in the next on-demand databases through it.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, ErrorBody, ErrorCode, Role};
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

/// Adds or updates an object a robot perceived; the next on-demand database of a mission
/// through this place includes it. Robots and engineers.
#[utoipa::path(post, path = "/v1/places/{id}/objects", params(("id" = String, Path)), request_body = ObjectReport, responses((status = 201, body = ReportedObject), (status = 200, body = ReportedObject), (status = 404, body = ErrorBody), (status = 422, body = ErrorBody)))]
pub(super) async fn report_object(
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
