//! `GET /v1/roadmaps`: the roadmap a plan on a floor starts on, as nodes and edges for the
//! console and for robots that draw it: the geometric roadmap of the robot's configuration
//! space, and, with a policy whose policy-aware roadmap is stored, each edge's measured success
//! probability and time and whether the policy keeps it.

use std::sync::Arc;

use axum::Json;
use axum::extract::State;
use edge::{ApiError, ErrorCode, RobotCaller};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use crate::plan::{PlanErrorResponse, PlanRoutes};
use planner::roadmaps::{geometric_roadmap, nodes_fingerprint};

/// Which roadmap.
#[derive(Debug, Deserialize, IntoParams)]
pub struct RoadmapQuery {
    /// A floor or a place on one: identifier or IRI.
    pub place: String,
    /// The robot whose footprint inflates the free space: identifier or IRI.
    pub robot: String,
    /// A policy: its policy-aware roadmap's measurements, where stored.
    #[param(nullable = false)]
    pub policy: Option<String>,
    /// Clearance kept beyond the robot's radius, metres [default: the plan endpoint's, 0.1].
    #[param(nullable = false)]
    pub safety_margin_m: Option<f64>,
}

/// A roadmap as nodes and undirected edges in the floor frame.
#[derive(Debug, Serialize, ToSchema)]
pub struct RoadmapView {
    /// `geometric`, or `policy` when the edges carry a stored policy-aware roadmap's
    /// measurements.
    pub kind: &'static str,
    /// The floor's IRI.
    pub floor: String,
    /// The ROS frame the node positions are in (the floor map's `tosm:frameId`).
    pub frame_id: String,
    /// The policy whose measurements the edges carry.
    pub policy: Option<String>,
    /// Why there are none, when a policy was named.
    pub note: Option<String>,
    /// Samples n (Eq. 19).
    pub samples: usize,
    /// The roadmap's seed (a plan's first attempt plans on seed 0).
    pub seed: u64,
    /// Robot radius plus safety margin the free space was inflated by, metres.
    pub inflation_m: f64,
    /// Node positions `[x, y]`, metres.
    pub nodes: Vec<[f64; 2]>,
    /// Edges between node indices.
    pub edges: Vec<EdgeView>,
}

/// One edge.
#[derive(Debug, Serialize, ToSchema)]
pub struct EdgeView {
    /// One end (index into `nodes`).
    pub a: usize,
    /// The other end.
    pub b: usize,
    /// Length, metres.
    pub length_m: f64,
    /// The policy's measured success rate, the worse of the two directions.
    pub success: Option<f64>,
    /// Mean simulated time of the successful rollouts, both directions, seconds.
    pub mean_time_s: Option<f64>,
    /// Whether the policy-aware roadmap keeps both directions (success at or above the keep
    /// threshold); `null` without measurements.
    pub kept: Option<bool>,
}

/// The roadmap of a floor for a robot, and a policy's measurements of its edges.
#[utoipa::path(get, path = "/v1/roadmaps", params(RoadmapQuery), responses(
    (status = 200, body = RoadmapView),
    (status = 400, description = "A query parameter is missing or malformed.", body = edge::ErrorBody),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No such place, robot or policy.", body = edge::ErrorBody),
    (status = 422, description = "The place is on no floor, the knowledge does not make a world, or the margin is out of range.", body = edge::ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub async fn get_roadmap(
    State(api): State<Arc<PlanRoutes>>,
    _caller: RobotCaller,
    axum::extract::Query(query): axum::extract::Query<RoadmapQuery>,
) -> Result<Json<RoadmapView>, ApiError> {
    roadmap_view(api, query, false).await.map(Json)
}

/// Which robot's route graph.
#[derive(Debug, Deserialize, IntoParams)]
pub struct RouteGraphQuery {
    /// The robot whose footprint inflates the free space: identifier or IRI.
    pub robot: String,
    /// A policy: its policy-aware roadmap's measurements, where stored [default: the robot's
    /// newest policy, as `POST /v1/plan` drives with].
    #[param(nullable = false)]
    pub policy: Option<String>,
}

/// The floor's roadmap (the one `GET /v1/roadmaps` answers, with the measurements of the
/// robot's newest policy's policy-aware roadmap when one is stored) as a route graph for Nav2's
/// Route Server (`nav2_route`'s GeoJSON graph): a `FeatureCollection` of `Point` nodes (`id`,
/// `frame`: the floor map's `tosm:frameId`) and one `MultiLineString` edge per direction (`id`,
/// `startid`, `endid`, `cost` in metres; `metadata.success_probability` and
/// `metadata.mean_time_s` where a policy's rollouts measured them). Node and edge ids are unique
/// together, as the Route Server requires.
#[utoipa::path(get, path = "/v1/places/{id}/route-graph.geojson", params(("id" = String, Path, min_length = 1, description = "A floor or a place on one: IRI or tosm:identifier."), RouteGraphQuery), responses(
    (status = 200, content_type = "application/geo+json", body = Object),
    (status = 400, description = "A query parameter is missing or malformed.", body = edge::ErrorBody),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No such place, robot or policy.", body = edge::ErrorBody),
    (status = 422, description = "The place is on no floor, or the knowledge does not make a world.", body = edge::ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
pub async fn route_graph(
    State(api): State<Arc<PlanRoutes>>,
    _caller: RobotCaller,
    axum::extract::Path(place): axum::extract::Path<String>,
    axum::extract::Query(query): axum::extract::Query<RouteGraphQuery>,
) -> Result<axum::response::Response, ApiError> {
    use axum::response::IntoResponse;
    let view = roadmap_view(
        api,
        RoadmapQuery {
            place,
            robot: query.robot,
            policy: query.policy,
            safety_margin_m: None,
        },
        true,
    )
    .await?;
    Ok((
        [(axum::http::header::CONTENT_TYPE, "application/geo+json")],
        Json(geojson(&view)),
    )
        .into_response())
}

/// `view` in the Route Server's GeoJSON graph format.
pub fn geojson(view: &RoadmapView) -> serde_json::Value {
    use serde_json::json;
    let frame = view.frame_id.as_str();
    let mut features: Vec<serde_json::Value> = view
        .nodes
        .iter()
        .enumerate()
        .map(|(i, p)| {
            json!({
                "type": "Feature",
                "properties": {"id": i, "frame": frame},
                "geometry": {"type": "Point", "coordinates": [p[0], p[1]]}
            })
        })
        .collect();
    let mut next_id = view.nodes.len();
    for e in &view.edges {
        for (from, to) in [(e.a, e.b), (e.b, e.a)] {
            let mut metadata = serde_json::Map::new();
            if let Some(p) = e.success {
                metadata.insert("success_probability".into(), json!(p));
            }
            if let Some(t) = e.mean_time_s {
                metadata.insert("mean_time_s".into(), json!(t));
            }
            if let Some(k) = e.kept {
                metadata.insert("kept".into(), json!(k));
            }
            features.push(json!({
                "type": "Feature",
                "properties": {
                    "id": next_id,
                    "startid": from,
                    "endid": to,
                    "cost": e.length_m,
                    "metadata": metadata
                },
                "geometry": {
                    "type": "MultiLineString",
                    "coordinates": [[view.nodes[from], view.nodes[to]]]
                }
            }));
            next_id += 1;
        }
    }
    json!({"type": "FeatureCollection", "name": "graph", "features": features})
}

/// The roadmap `query` names, as `GET /v1/roadmaps` answers it; without a policy named, with
/// `newest_policy` the robot's newest one's measurements.
async fn roadmap_view(
    api: Arc<PlanRoutes>,
    mut query: RoadmapQuery,
    newest_policy: bool,
) -> Result<RoadmapView, ApiError> {
    let margin = query
        .safety_margin_m
        .unwrap_or(rehearsal::PlanOptions::default().safety_margin_m);
    if !(0.0..=5.0).contains(&margin) {
        return Err(ApiError::new(
            ErrorCode::Unprocessable,
            format!("safety_margin_m must be within 0–5 m, not {margin}"),
        )
        .with_details(serde_json::json!({"field": "safety_margin_m"})));
    }
    let planner = Arc::clone(&api.planner);
    let db = planner
        .floor(&query.place, &query.robot)
        .await
        .map_err(super::plan_failure)?;
    if newest_policy && query.policy.is_none() {
        query.policy = planner.policies().newest_for(&db.robot);
    }
    let key = match &query.policy {
        None => None,
        Some(id) => Some(
            planner
                .roadmap_key(&db, id, margin)
                .await
                .map_err(super::plan_failure)?,
        ),
    };
    tokio::task::spawn_blocking(move || -> Result<RoadmapView, ApiError> {
        let world = db
            .world()
            .map_err(|e| ApiError::new(ErrorCode::Unprocessable, e.to_string()))?;
        let roadmap = geometric_roadmap(&world, planner.roadmaps(), &db.version, margin)
            .map_err(|e| e.to_api_error())?;
        let stored = key
            .as_ref()
            .and_then(|k| planner.policy_roadmaps().get(k))
            .filter(|s| {
                s.nodes == roadmap.nodes().count()
                    && s.nodes_fingerprint == nodes_fingerprint(&roadmap)
            });
        let note = match (&key, &stored) {
            (Some(_), None) => Some(
                "no policy-aware roadmap of this floor state and policy is stored yet (a plan \
                 with the policy enqueues its `roadmap` job): the edges carry no measurements"
                    .to_owned(),
            ),
            _ => None,
        };
        // The edges as the stored roadmap measured them, by the keep rule it was built with.
        let report = stored.as_ref().map(|s| s.report());
        let index = report.as_ref().map(rehearsal::EdgeReport::index);
        let nodes: Vec<[f64; 2]> = roadmap.nodes().map(|p| [p.x, p.y]).collect();
        let edges = roadmap
            .edges()
            .map(|(a, b)| {
                let summary = index.as_ref().map(|i| i.summary(a, b));
                EdgeView {
                    a,
                    b,
                    length_m: (nodes[a][0] - nodes[b][0]).hypot(nodes[a][1] - nodes[b][1]),
                    success: summary.and_then(|s| s.success),
                    mean_time_s: summary.and_then(|s| s.mean_time_s),
                    kept: summary.and_then(|s| s.kept),
                }
            })
            .collect();
        let params = roadmap.params();
        Ok(RoadmapView {
            kind: if stored.is_some() {
                "policy"
            } else {
                "geometric"
            },
            floor: db.floor.clone(),
            frame_id: world.spec().map_frame().to_owned(),
            policy: query.policy.clone(),
            note,
            samples: params.samples,
            seed: params.seed,
            inflation_m: roadmap.cspace().inflation().total_m(),
            nodes,
            edges,
        })
    })
    .await
    .map_err(|e| ApiError::internal(format!("roadmap task failed: {e}")))?
}
