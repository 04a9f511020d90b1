//! Stored policy-aware roadmaps (PRM-RL): every edge of a floor's geometric roadmap driven by a
//! policy, K times per direction, persisted under (floor state, policy weights, roadmap
//! parameters) so that plans use them in this process or any other sharing the data directory.
//!
//! The geometric roadmap itself is not stored: it is rebuilt deterministically (same floor
//! state, margin, sample count and seed give the same nodes and edges) and checked against a
//! fingerprint of its nodes before the stored report is applied to it.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::controllers::ControllerTrial;
use rehearsal::{EdgeReport, EdgeRolloutParams, EdgeStat};
use serde::{Deserialize, Serialize};
use sim::World;

/// Which stored roadmap: the floor state, the policy's weights (by content), and the
/// parameters it was built with. Equal keys mean interchangeable roadmaps.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PolicyRoadmapKey {
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

impl PolicyRoadmapKey {
    /// The key the plan endpoint looks up: `policy` (whose weights hash to `weights`) on
    /// `floor_state` with `margin` and the default rollout parameters.
    pub fn for_plans(floor_state: &str, policy: &str, weights: u64, margin: f64) -> Self {
        Self::with_params(
            floor_state,
            policy,
            weights,
            margin,
            &EdgeRolloutParams::default(),
        )
    }

    /// The key of `policy_dir`'s weights on `floor_state` with these parameters; `None` when
    /// the weights cannot be read.
    pub fn new(
        floor_state: &str,
        policy: &str,
        policy_dir: &Path,
        margin: f64,
        params: &EdgeRolloutParams,
    ) -> Option<PolicyRoadmapKey> {
        let bytes = std::fs::read(policy_dir.join(learning::policy::WEIGHTS_FILE)).ok()?;
        let weights = grid::hash::fnv1a(&bytes);
        Some(Self::with_params(
            floor_state,
            policy,
            weights,
            margin,
            params,
        ))
    }

    fn with_params(
        floor_state: &str,
        policy: &str,
        weights: u64,
        margin: f64,
        params: &EdgeRolloutParams,
    ) -> Self {
        Self {
            floor_state: floor_state.to_owned(),
            policy: policy.to_owned(),
            weights,
            margin_bits: margin.to_bits(),
            rollouts: params.rollouts,
            keep_bits: params.keep_threshold.to_bits(),
        }
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
    pub key: PolicyRoadmapKey,
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
    /// The controllers driven over the same missions of this floor state, from which
    /// `options.controller: auto` picks ([`crate::controllers`]); `None` in a roadmap stored
    /// before trials were measured, or built without one.
    #[serde(default)]
    pub trial: Option<ControllerTrial>,
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
pub fn nodes_fingerprint(roadmap: &prm::Roadmap) -> u64 {
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
    pub fn get(&self, key: &PolicyRoadmapKey) -> Option<StoredRoadmap> {
        let bytes = std::fs::read(self.dir.join(key.file_name())).ok()?;
        let stored: StoredRoadmap = serde_json::from_slice(&bytes).ok()?;
        (stored.key == *key).then_some(stored)
    }

    /// Whether a roadmap is stored under `key`.
    pub fn contains(&self, key: &PolicyRoadmapKey) -> bool {
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
) -> Result<Arc<prm::Roadmap>, rehearsal::PlanError> {
    let space = rehearsal::config_space(world, roadmaps, floor_state, margin)?;
    let params = prm::PrmParams {
        samples: prm::optimal_samples(space.free_area_m2),
        seed: 0,
        ..prm::PrmParams::default()
    };
    roadmaps
        .roadmap(floor_state, &space, &params)
        .map(|(r, _)| r)
}

/// Why a stored policy-aware roadmap cannot be applied.
#[derive(Debug, thiserror::Error)]
pub enum StoredRoadmapError {
    /// The geometric roadmap it applies to could not be made, or the stored one not applied.
    #[error("the stored policy-aware roadmap: {0}")]
    Roadmap(#[from] rehearsal::PlanError),
    /// It was built over another geometric roadmap.
    #[error("the stored policy-aware roadmap was built over another geometric roadmap")]
    OtherGeometric,
}

/// A stored policy-aware roadmap applied to its floor's geometric roadmap, with the trial of
/// controllers stored beside it.
#[derive(Debug, Clone)]
pub struct AppliedRoadmap {
    /// The policy-aware roadmap.
    pub roadmap: Arc<prm::Roadmap>,
    /// The controllers measured on the floor state, when they were.
    pub trial: Option<Arc<ControllerTrial>>,
}

/// The stored roadmap of `key` applied to the geometric roadmap of `world`: `Ok(None)` when
/// none is stored, an error when the stored one does not fit (another geometric roadmap).
/// `with_unkept`: the complete policy-aware roadmap ([`rehearsal::reweight_with_unkept`], what
/// `options.roadmap: auto` plans on), else only the kept directions (`policy`).
pub fn load_policy_roadmap(
    store: &RoadmapStore,
    key: &PolicyRoadmapKey,
    world: &Arc<World>,
    roadmaps: &rehearsal::RoadmapCache,
    with_unkept: bool,
) -> Result<Option<AppliedRoadmap>, StoredRoadmapError> {
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
        return Err(StoredRoadmapError::OtherGeometric);
    }
    let report = stored.report();
    if with_unkept {
        rehearsal::reweight_with_unkept(&geometric, &report)
    } else {
        rehearsal::reweight(&geometric, &report)
    }
    .map(|roadmap| {
        Some(AppliedRoadmap {
            roadmap,
            trial: stored.trial.map(Arc::new),
        })
    })
    .map_err(StoredRoadmapError::from)
}
