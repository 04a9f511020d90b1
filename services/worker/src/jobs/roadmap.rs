//! `roadmap`: the policy-aware roadmap of a floor (PRM-RL): every edge of the floor's geometric
//! roadmap driven by a policy in the mental simulation, K times per direction, and the per-edge
//! report persisted under (floor state, policy weights, roadmap parameters), so that
//! `POST /v1/plan` uses it from then on, in this process or any other sharing the data
//! directory.
//!
//! The geometric roadmap itself is not stored: it is rebuilt deterministically (same floor
//! state, margin, sample count and seed give the same nodes and edges) and checked against a
//! fingerprint of its nodes before the stored report is applied to it.
//!
//! A `roadmap` job is enqueued when a training job exports a policy, and when a plan asks for a
//! floor state (a floor that changed is a new state) and policy that have none. A floor that
//! changes while its roadmap is built makes that build stale: it is not stored, and the job is
//! retried against the new state.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rehearsal::{EdgeReport, EdgeRolloutParams, EdgeStat};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use sim::World;

use super::{JobEnv, PayloadError};
use crate::runner::{JobContext, JobError, JobHandler};

/// Most rollouts per edge direction a job may ask for.
pub const MAX_ROLLOUTS: u32 = 100;
/// Largest safety margin a job may ask for, metres.
pub const MAX_MARGIN_M: f64 = 1.0;

/// What a `roadmap` job is asked.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RoadmapPayload {
    /// The policy's id (see `GET /v1/policies`).
    pub policy: String,
    /// A floor, or a place on one (IRI or identifier).
    pub place: String,
    /// The robot [default: the one the policy was trained for].
    #[serde(default)]
    pub robot: Option<String>,
    /// Clearance kept from obstacles by the roadmap, metres [default: the plan endpoint's].
    #[serde(default)]
    pub safety_margin_m: Option<f64>,
    /// Rollouts per edge direction [default: 10].
    #[serde(default)]
    pub rollouts: Option<u32>,
    /// Success rate an edge direction needs to be kept [default: 0.9].
    #[serde(default)]
    pub keep_threshold: Option<f64>,
}

impl RoadmapPayload {
    /// Values in range.
    pub fn check(&self) -> Result<(), PayloadError> {
        if !super::policies::valid_id(&self.policy) {
            return Err(PayloadError::NotFound(format!(
                "payload.policy: no policy has id {:?}",
                self.policy
            )));
        }
        if let Some(m) = self.safety_margin_m
            && !(m.is_finite() && (0.0..=MAX_MARGIN_M).contains(&m))
        {
            return Err(PayloadError::Invalid(format!(
                "payload.safety_margin_m: must be in [0, {MAX_MARGIN_M}] metres, got {m}"
            )));
        }
        if let Some(k) = self.rollouts
            && !(1..=MAX_ROLLOUTS).contains(&k)
        {
            return Err(PayloadError::Invalid(format!(
                "payload.rollouts: must be in 1..={MAX_ROLLOUTS}, got {k}"
            )));
        }
        if let Some(t) = self.keep_threshold
            && !(t.is_finite() && t > 0.0 && t <= 1.0)
        {
            return Err(PayloadError::Invalid(format!(
                "payload.keep_threshold: must be in (0, 1], got {t}"
            )));
        }
        Ok(())
    }

    /// The rollout parameters asked for.
    pub fn rollout_params(&self) -> EdgeRolloutParams {
        let d = EdgeRolloutParams::default();
        EdgeRolloutParams {
            rollouts: self.rollouts.unwrap_or(d.rollouts),
            keep_threshold: self.keep_threshold.unwrap_or(d.keep_threshold),
            ..d
        }
    }

    /// The safety margin asked for.
    pub fn margin(&self) -> f64 {
        self.safety_margin_m
            .unwrap_or(rehearsal::PlanOptions::default().safety_margin_m)
    }
}

/// Which stored roadmap: the floor state, the policy's weights (by content), and the
/// parameters it was built with. Equal keys mean interchangeable roadmaps.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct RoadmapKey {
    /// The floor database's version (floor, robot, knowledge state).
    pub floor_state: String,
    /// The policy's id.
    pub policy: String,
    /// FNV-1a of the policy's weights file.
    pub weights: u64,
    /// The safety margin's bits.
    pub margin_bits: u64,
    /// Rollouts per edge direction.
    pub rollouts: u32,
    /// The keep threshold's bits.
    pub keep_bits: u64,
}

impl RoadmapKey {
    /// The key the plan endpoint looks up: `policy` (whose weights hash to `weights`) on
    /// `floor_state` with `margin` and the default rollout parameters.
    pub fn for_plans(floor_state: &str, policy: &str, weights: u64, margin: f64) -> Self {
        let params = EdgeRolloutParams::default();
        Self {
            floor_state: floor_state.to_owned(),
            policy: policy.to_owned(),
            weights,
            margin_bits: margin.to_bits(),
            rollouts: params.rollouts,
            keep_bits: params.keep_threshold.to_bits(),
        }
    }

    /// The key of `policy_dir`'s weights on `floor_state` with these parameters; `None` when
    /// the weights cannot be read.
    pub fn new(
        floor_state: &str,
        policy: &str,
        policy_dir: &Path,
        margin: f64,
        params: &EdgeRolloutParams,
    ) -> Option<RoadmapKey> {
        let bytes = std::fs::read(policy_dir.join(learning::policy::WEIGHTS_FILE)).ok()?;
        Some(RoadmapKey {
            floor_state: floor_state.to_owned(),
            policy: policy.to_owned(),
            weights: grid::hash::fnv1a(&bytes),
            margin_bits: margin.to_bits(),
            rollouts: params.rollouts,
            keep_bits: params.keep_threshold.to_bits(),
        })
    }

    fn file_name(&self) -> String {
        // The controller's revision names the file too: a roadmap driven by an older policy
        // controller is never served, and is rebuilt.
        let text = format!(
            "{}\u{1f}{}\u{1f}{}\u{1f}{:x}\u{1f}{:x}\u{1f}{}\u{1f}{:x}",
            rehearsal::POLICY_CONTROLLER_REVISION,
            self.floor_state,
            self.policy,
            self.weights,
            self.margin_bits,
            self.rollouts,
            self.keep_bits
        );
        format!("{:016x}.json", grid::hash::fnv1a(text.as_bytes()))
    }
}

/// One driven edge direction, as stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredEdge {
    /// Node index it started at.
    pub from: usize,
    /// Node index it drove to.
    pub to: usize,
    /// Length, metres.
    pub length_m: f64,
    /// Rollouts that arrived.
    pub successes: u32,
    /// Rollouts that collided.
    pub collisions: u32,
    /// Rollouts driven.
    pub rollouts: u32,
    /// Mean simulated time of the arrivals, seconds.
    pub mean_time_s: Option<f64>,
    /// Smallest clearance over the rollouts, metres.
    pub min_clearance_m: f64,
    /// Rollouts closer than 10 cm to an obstacle.
    pub near_misses: u32,
}

impl From<&EdgeStat> for StoredEdge {
    fn from(e: &EdgeStat) -> Self {
        let EdgeStat {
            from,
            to,
            length_m,
            successes,
            collisions,
            rollouts,
            mean_time_s,
            min_clearance_m,
            near_misses,
        } = *e;
        StoredEdge {
            from,
            to,
            length_m,
            successes,
            collisions,
            rollouts,
            mean_time_s,
            min_clearance_m,
            near_misses,
        }
    }
}

impl From<&StoredEdge> for EdgeStat {
    fn from(e: &StoredEdge) -> Self {
        let StoredEdge {
            from,
            to,
            length_m,
            successes,
            collisions,
            rollouts,
            mean_time_s,
            min_clearance_m,
            near_misses,
        } = *e;
        EdgeStat {
            from,
            to,
            length_m,
            successes,
            collisions,
            rollouts,
            mean_time_s,
            min_clearance_m,
            near_misses,
        }
    }
}

/// A stored policy-aware roadmap: its key, the fingerprint of the geometric roadmap's nodes it
/// applies to, and every edge direction's rollouts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StoredRoadmap {
    /// What it was built for.
    pub key: RoadmapKey,
    /// Nodes of the geometric roadmap.
    pub nodes: usize,
    /// FNV-1a of the nodes' coordinates.
    pub nodes_fingerprint: u64,
    /// Seed of the rollouts.
    pub seed: u64,
    /// Seconds the build took.
    pub wall_s: f64,
    /// Every edge direction.
    pub edges: Vec<StoredEdge>,
}

impl StoredRoadmap {
    /// The report [`rehearsal::reweight`] applies.
    pub fn report(&self) -> EdgeReport {
        EdgeReport {
            edges: self.edges.iter().map(EdgeStat::from).collect(),
            params: EdgeRolloutParams {
                rollouts: self.key.rollouts,
                keep_threshold: f64::from_bits(self.key.keep_bits),
                seed: self.seed,
                ..EdgeRolloutParams::default()
            },
            steps: 0,
            handover_steps: 0,
        }
    }
}

/// FNV-1a of a roadmap's node coordinates.
pub fn nodes_fingerprint(roadmap: &planning::Roadmap) -> u64 {
    let mut bytes = Vec::new();
    for p in roadmap.nodes() {
        bytes.extend_from_slice(&p.x.to_le_bytes());
        bytes.extend_from_slice(&p.y.to_le_bytes());
    }
    grid::hash::fnv1a(&bytes)
}

/// Stored policy-aware roadmaps: one JSON file per key in a directory, written atomically.
#[derive(Debug, Clone)]
pub struct RoadmapStore {
    dir: PathBuf,
}

impl RoadmapStore {
    /// Files in `dir` (created when the first roadmap is stored).
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: dir.into() }
    }

    /// The roadmap stored under `key`, if any (a file for another key, or one that does not
    /// parse, is none).
    pub fn get(&self, key: &RoadmapKey) -> Option<StoredRoadmap> {
        let bytes = std::fs::read(self.dir.join(key.file_name())).ok()?;
        let stored: StoredRoadmap = serde_json::from_slice(&bytes).ok()?;
        (stored.key == *key).then_some(stored)
    }

    /// Whether a roadmap is stored under `key`.
    pub fn contains(&self, key: &RoadmapKey) -> bool {
        self.dir.join(key.file_name()).is_file()
    }

    /// Stores `roadmap` under its key, replacing any earlier one atomically.
    pub fn put(&self, roadmap: &StoredRoadmap) -> std::io::Result<PathBuf> {
        std::fs::create_dir_all(&self.dir)?;
        let path = self.dir.join(roadmap.key.file_name());
        let json = serde_json::to_vec(roadmap).map_err(std::io::Error::other)?;
        learning::policy::write_atomic(&path, &json)?;
        Ok(path)
    }
}

/// The geometric roadmap the plan endpoint's first attempt uses on `world` (n* samples, seed
/// 0, inflated by `margin`): the one a policy-aware roadmap is built over.
pub fn geometric_roadmap(
    world: &Arc<World>,
    roadmaps: &rehearsal::RoadmapCache,
    floor_state: &str,
    margin: f64,
) -> Result<Arc<planning::Roadmap>, String> {
    let space =
        rehearsal::config_space(world, roadmaps, floor_state, margin).map_err(|e| e.to_string())?;
    let params = planning::PrmParams {
        samples: planning::optimal_samples(space.free_area_m2),
        seed: 0,
        ..planning::PrmParams::default()
    };
    roadmaps
        .roadmap(floor_state, &space, &params)
        .map(|(r, _)| r)
        .map_err(|e| e.to_string())
}

/// The stored roadmap of `key` applied to the geometric roadmap of `world`: `Ok(None)` when
/// none is stored, an error when the stored one does not fit (another geometric roadmap).
/// `with_unkept`: the complete policy-aware roadmap ([`rehearsal::reweight_with_unkept`], what
/// `options.roadmap: auto` plans on), else only the kept directions (`policy`).
pub fn load_policy_roadmap(
    store: &RoadmapStore,
    key: &RoadmapKey,
    world: &Arc<World>,
    roadmaps: &rehearsal::RoadmapCache,
    with_unkept: bool,
) -> Result<Option<Arc<planning::Roadmap>>, String> {
    let Some(stored) = store.get(key) else {
        return Ok(None);
    };
    let geometric = geometric_roadmap(
        world,
        roadmaps,
        &key.floor_state,
        f64::from_bits(key.margin_bits),
    )?;
    if geometric.nodes().count() != stored.nodes
        || nodes_fingerprint(&geometric) != stored.nodes_fingerprint
    {
        return Err(
            "the stored policy-aware roadmap was built over another geometric roadmap".into(),
        );
    }
    let report = stored.report();
    if with_unkept {
        rehearsal::reweight_with_unkept(&geometric, &report)
    } else {
        rehearsal::reweight(&geometric, &report)
    }
    .map(Some)
    .map_err(|e| e.to_string())
}

/// The payload of the roadmap job for `policy` on `place` (the plan endpoint's and an export's).
pub fn payload(policy: &str, place: &str, robot: &str, margin: f64) -> Value {
    json!({"policy": policy, "place": place, "robot": robot, "safety_margin_m": margin})
}

/// Runs `roadmap` jobs.
#[derive(Debug, Clone)]
pub struct RoadmapHandler {
    env: Arc<JobEnv>,
}

impl RoadmapHandler {
    /// A handler using `env`.
    pub fn new(env: Arc<JobEnv>) -> Self {
        Self { env }
    }
}

/// The robot a roadmap job drives: the payload's, else the one the policy was trained for.
pub fn roadmap_robot(env: &JobEnv, p: &RoadmapPayload) -> Result<String, PayloadError> {
    super::evaluate::policy_robot(
        &env.policies,
        &super::EvaluatePayload {
            policy: p.policy.clone(),
            place: p.place.clone(),
            robot: p.robot.clone(),
            episodes: None,
            seed: None,
            goals_in_view: None,
        },
    )
}

impl JobHandler for RoadmapHandler {
    async fn run(&self, ctx: JobContext) -> Result<Value, JobError> {
        let payload: RoadmapPayload = ctx.payload_as()?;
        payload.check()?;
        let robot = roadmap_robot(&self.env, &payload)?;
        let dir =
            self.env.policies.path(&payload.policy).ok_or_else(|| {
                JobError::Fatal(format!("invalid policy id {:?}", payload.policy))
            })?;
        let db = self
            .env
            .knowledge
            .floor_database(&payload.place, &robot)
            .await?;
        if ctx.is_stopping() {
            return Err(ctx.stopped());
        }
        let params = payload.rollout_params();
        let margin = payload.margin();
        let key = RoadmapKey::new(&db.version, &payload.policy, &dir, margin, &params)
            .ok_or_else(|| JobError::Fatal("the policy's weights cannot be read".into()))?;
        let roadmaps = Arc::clone(&self.env.roadmaps);
        let version = db.version.clone();
        let built = tokio::task::spawn_blocking(move || -> Result<StoredRoadmap, JobError> {
            let policy = Arc::new(
                learning::Policy::load(&dir)
                    .map_err(|e| JobError::Fatal(format!("the policy does not load: {e}")))?,
            );
            let world = db.world().map_err(JobError::Fatal)?;
            let geometric =
                geometric_roadmap(&world, &roadmaps, &version, margin).map_err(JobError::Fatal)?;
            let started = std::time::Instant::now();
            let report = rehearsal::drive_edges(
                &world,
                &geometric,
                || rehearsal::PolicyController::new(Arc::clone(&policy)),
                &params,
            )
            .map_err(|e| JobError::Fatal(e.to_string()))?;
            Ok(StoredRoadmap {
                nodes: geometric.nodes().count(),
                nodes_fingerprint: nodes_fingerprint(&geometric),
                seed: params.seed,
                wall_s: started.elapsed().as_secs_f64(),
                edges: report.edges.iter().map(StoredEdge::from).collect(),
                key,
            })
        })
        .await
        .map_err(JobError::retryable)??;
        // A floor that changed while the roadmap was built: the build is stale. Never stored
        // (it is keyed by the old state, which plans no longer ask for); built again.
        let now = self
            .env
            .knowledge
            .floor_database(&payload.place, &robot)
            .await?;
        if now.version != built.key.floor_state {
            return Err(JobError::Retryable(
                "the floor changed while its policy-aware roadmap was built; building it again for the new state".into(),
            ));
        }
        let path = self
            .env
            .policy_roadmaps
            .put(&built)
            .map_err(|e| JobError::Retryable(format!("storing the roadmap: {e}")))?;
        let report = built.report();
        let _ = ctx
            .report_progress(&json!({"fraction_done": 1.0, "edges": built.edges.len()}))
            .await;
        Ok(json!({
            "policy": payload.policy,
            "robot": robot,
            "place": payload.place,
            "floor": now.floor,
            "floor_state": built.key.floor_state,
            "nodes": built.nodes,
            "edge_directions": built.edges.len(),
            "edge_directions_kept": report.kept().count(),
            "edge_success_rate": report.edge_success_rate(),
            "mean_edge_time_s": report.mean_edge_time_s(),
            "near_miss_rate": report.near_miss_rate(),
            "rollouts": built.key.rollouts,
            "keep_threshold": f64::from_bits(built.key.keep_bits),
            "safety_margin_m": margin,
            "wall_s": built.wall_s,
            "file": path.file_name().map(|f| f.to_string_lossy().into_owned()),
        }))
    }
}
