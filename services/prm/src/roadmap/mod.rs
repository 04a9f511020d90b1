//! The probabilistic roadmap (paper §4.2.1): built once per (map, robot, parameters), then
//! queried many times; local densification when a query falls between its components.
//!
//! - `build`: sampling, k-nearest edges, re-sampling of isolated nodes and visibility repair;
//! - `bridge`: joining components that share a free region over the coarse grid;
//! - `query`: lazy start and goal links and the search, with the plan's clearance;
//! - `densify`: query-time densification by a grid wavefront, and keeping what it learnt;
//! - `shortcut`: line-of-sight thinning of plans and of chains of cells;
//! - `waves`: the per-thread cell tables and neighbourhoods the grid waves share.

use std::sync::Arc;

use kiddo::ImmutableKdTree;

use crate::cspace::{ConfigSpace, Inflation};
use crate::error::BuildError;
use crate::map::Point2;
use crate::search::{Csr, SearchAlgorithm};

mod bridge;
mod buckets;
mod build;
mod densify;
mod query;
mod shortcut;
mod waves;

pub use query::Reservations;

/// The paper's optimal number of samples (Eq. 19): `ceil(0.05 · free area in m² + 84)`.
pub fn optimal_samples(free_area_m2: f64) -> usize {
    let n = (0.05 * free_area_m2.max(0.0) + 84.0).ceil();
    if n.is_finite() { n as usize } else { 84 }
}

/// Parameters of a roadmap. Two roadmaps built from the same configuration space with equal
/// parameters are identical.
#[derive(Debug, Clone, PartialEq)]
pub struct PrmParams {
    /// n: number of samples.
    pub samples: usize,
    /// k: valid edges each sample tries to get to its nearest neighbours.
    pub neighbours: usize,
    /// d_max: longest edge, in metres.
    pub max_edge_m: f64,
    /// How many nearest neighbours a sample tests, in order, while it has fewer than k valid edges.
    pub max_tests_per_node: usize,
    /// Share of samples drawn on the distance field's ridges (the rest uniformly in free space):
    /// the clearance preference that keeps waypoints away from walls and finds doors.
    pub skeleton_share: f64,
    /// Share of the n samples spent on visibility repair (connectors and guards) instead of
    /// plain draws. With both shares 0 the roadmap is the paper's plain PRM.
    pub repair_share: f64,
    /// Seed of the sample sequence.
    pub seed: u64,
}

impl PrmParams {
    /// Defaults with the paper's n* for a map whose free area (uninflated) is `free_area_m2`.
    pub fn for_free_area(free_area_m2: f64) -> Self {
        Self {
            samples: optimal_samples(free_area_m2),
            ..Self::default()
        }
    }

    /// Checks the parameters; the same check runs inside [`Roadmap::build`].
    pub fn validate(&self) -> Result<(), BuildError> {
        if self.samples == 0 {
            return Err(BuildError::ZeroSamples);
        }
        if self.samples > MAX_SAMPLES {
            return Err(BuildError::TooManySamples(self.samples));
        }
        if self.neighbours == 0 {
            return Err(BuildError::ZeroNeighbours);
        }
        if !(self.max_edge_m.is_finite() && self.max_edge_m > 0.0) {
            return Err(BuildError::BadMaxEdge(self.max_edge_m));
        }
        if !(0.0..=1.0).contains(&self.skeleton_share) {
            return Err(BuildError::BadSkeletonShare(self.skeleton_share));
        }
        if !(0.0..=1.0).contains(&self.repair_share) {
            return Err(BuildError::BadRepairShare(self.repair_share));
        }
        Ok(())
    }
}

impl Default for PrmParams {
    /// n = 200, k = 10 (OMPL's default too), d_max = 15 m, the k nearest tested (as OMPL), half
    /// the samples on ridges, 30% spent on repair.
    fn default() -> Self {
        Self {
            samples: 200,
            neighbours: 10,
            max_edge_m: 15.0,
            max_tests_per_node: 10,
            skeleton_share: 0.5,
            repair_share: 0.3,
            seed: 0,
        }
    }
}

/// Identifies a roadmap for caching: equal keys mean interchangeable roadmaps. Floats are kept
/// as their bit patterns so the key can be hashed and compared exactly.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct RoadmapKey {
    /// The caller's map version (or [`crate::PlanningGrid::fingerprint`]).
    pub map_version: u64,
    robot_radius_bits: u64,
    safety_margin_bits: u64,
    samples: usize,
    neighbours: usize,
    max_edge_bits: u64,
    max_tests: usize,
    skeleton_bits: u64,
    repair_bits: u64,
    seed: u64,
}

impl RoadmapKey {
    /// The key of the roadmap for this map version, robot and parameters.
    pub fn new(map_version: u64, inflation: Inflation, params: &PrmParams) -> Self {
        Self {
            map_version,
            robot_radius_bits: inflation.robot_radius_m.to_bits(),
            safety_margin_bits: inflation.safety_margin_m.to_bits(),
            samples: params.samples,
            neighbours: params.neighbours,
            max_edge_bits: params.max_edge_m.to_bits(),
            max_tests: params.max_tests_per_node,
            skeleton_bits: params.skeleton_share.to_bits(),
            repair_bits: params.repair_share.to_bits(),
            seed: params.seed,
        }
    }
}

/// What building a roadmap took.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct BuildStats {
    /// Samples drawn, re-samples of isolated nodes included.
    pub samples_drawn: usize,
    /// Segment checks run for edges.
    pub edge_checks: usize,
    /// Edges in the final graph.
    pub edges: usize,
    /// Nodes still without an edge after the re-sampling rounds.
    pub isolated: usize,
    /// Connected components of the graph.
    pub components: usize,
    /// Nodes added beyond n to bridge components that share a free region.
    pub bridge_nodes: usize,
    /// Node distances computed by visibility repair's nearest-node queries: its share of the
    /// build's work, which must grow like n (a scan of every node per candidate made it n²).
    pub repair_distances: usize,
    /// Coarse blocks the bridging flood expanded: it grows with the gaps it closes, not with n.
    pub flood_blocks: usize,
}

/// The phases of [`Roadmap::build_observed`], in the order they end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BuildPhase {
    /// The random samples drawn.
    Sampling,
    /// k-nearest edges with their segment checks, and the re-sampling rounds of isolated nodes.
    Neighbours,
    /// Extra edge tests between nearby components.
    Cross,
    /// Visibility repair (connectors and guards).
    Repair,
    /// Bridging of components that share a free region.
    Bridging,
    /// The graph: each edge's clearance, the adjacency, components and the k-d tree.
    Graph,
}

impl BuildPhase {
    /// Number of phases.
    pub const COUNT: usize = 6;
    /// Every phase, in order.
    pub const ALL: [BuildPhase; Self::COUNT] = [
        Self::Sampling,
        Self::Neighbours,
        Self::Cross,
        Self::Repair,
        Self::Bridging,
        Self::Graph,
    ];
    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Sampling => "sampling",
            Self::Neighbours => "k-NN",
            Self::Cross => "cross",
            Self::Repair => "repair",
            Self::Bridging => "bridging",
            Self::Graph => "graph",
        }
    }
}

/// A query's answer: waypoints from start to goal through free space.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Start, roadmap waypoints, goal (map frame, metres).
    pub waypoints: Vec<Point2>,
    /// Total length in metres.
    pub length_m: f64,
    /// Smallest clearance along the path, in metres (distance to the nearest blocked cell's edge).
    pub min_clearance_m: f64,
    /// Nodes added by local densification for this query (0 when the roadmap sufficed).
    pub densified_nodes: usize,
    /// Graph nodes the search expanded.
    pub expanded: usize,
}

/// How a query is answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QueryOptions {
    /// Dijkstra (as the paper) or A*.
    pub algorithm: SearchAlgorithm,
    /// Skip local densification and fail with [`crate::QueryError::NotConnected`] instead.
    pub no_densify: bool,
}

/// A probabilistic roadmap over one configuration space.
#[derive(Debug)]
pub struct Roadmap {
    cspace: Arc<ConfigSpace>,
    params: PrmParams,
    /// Node positions in grid units (cells).
    nodes: Vec<[f64; 2]>,
    graph: Csr,
    component: Vec<u32>,
    tree: ImmutableKdTree<f64, 2>,
    stats: BuildStats,
}

/// Most samples a roadmap takes; far beyond any useful roadmap, well within u32 node ids.
pub const MAX_SAMPLES: usize = 10_000_000;

impl Roadmap {
    /// The configuration space the roadmap lives in.
    pub fn cspace(&self) -> &Arc<ConfigSpace> {
        &self.cspace
    }
    /// The parameters it was built with.
    pub fn params(&self) -> &PrmParams {
        &self.params
    }
    /// What the build did.
    pub fn stats(&self) -> &BuildStats {
        &self.stats
    }
    /// Node positions in metres.
    pub fn nodes(&self) -> impl Iterator<Item = Point2> + '_ {
        self.nodes.iter().map(|&g| self.cspace.to_world(g))
    }
    /// Edges as pairs of node indices (each once).
    pub fn edges(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.graph.edges().map(|e| (e.0 as usize, e.1 as usize))
    }

    /// The same nodes with each edge direction costing what `cost(from, to, length_m)` says, in
    /// metres, and without the directions it answers `None` for: a policy-aware roadmap
    /// (PRM-RL), whose edges are the ones a controller was seen to drive. A cost below the
    /// length counts as the length, so A*'s straight-line heuristic stays admissible. Queries
    /// on it should not densify (`QueryOptions::no_densify`): new edges would be undriven.
    ///
    /// # Errors
    /// None in practice: the nodes are the ones this roadmap was built on.
    pub fn reweighted(
        &self,
        mut cost: impl FnMut(usize, usize, f64) -> Option<f64>,
    ) -> Result<Roadmap, BuildError> {
        let res = self.cspace.resolution();
        let n = self.graph.node_count();
        let mut graph = Csr {
            offsets: Vec::with_capacity(n + 1),
            ..Csr::default()
        };
        graph.offsets.push(0);
        for u in 0..n {
            let slots = self.graph.offsets[u] as usize..self.graph.offsets[u + 1] as usize;
            for slot in slots {
                let v = self.graph.targets[slot];
                let w = self.graph.weights[slot];
                if let Some(c) = cost(u, v as usize, w * res) {
                    graph.targets.push(v);
                    graph.weights.push((c / res).max(w));
                    graph.min_dist.push(self.graph.min_dist[slot]);
                }
            }
            #[allow(
                clippy::cast_possible_truncation,
                reason = "a subset of the original slots, whose count fits in u32"
            )]
            graph.offsets.push(graph.targets.len() as u32);
        }
        let component = components(&graph.symmetric_closure());
        Ok(Roadmap {
            cspace: Arc::clone(&self.cspace),
            params: self.params.clone(),
            nodes: self.nodes.clone(),
            component,
            tree: kd_tree(&self.nodes)?,
            stats: BuildStats {
                edges: graph.edges().count(),
                ..self.stats.clone()
            },
            graph,
        })
    }
}

/// A k-d tree over node positions (grid units).
fn kd_tree(nodes: &[[f64; 2]]) -> Result<ImmutableKdTree<f64, 2>, BuildError> {
    // Only fails when item indices overflow u32, which `PrmParams::validate` rules out.
    ImmutableKdTree::new_from_slice(nodes).map_err(|_| BuildError::TooManySamples(nodes.len()))
}

/// Euclidean distance between two grid points, in cells.
fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    // Not `hypot`: its overflow care costs several times a square root, and grid coordinates
    // are far from overflowing.
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// The stored obstacle distance of each segment of a search result (NaN for the start and goal
/// links and for edges without one).
fn segment_mins(graph: &Csr, ids: &[u32]) -> Vec<f32> {
    ids.windows(2)
        .map(|w| graph.edge_min_dist(w[0], w[1]))
        .collect()
}

/// Connected component id per node.
fn components(g: &Csr) -> Vec<u32> {
    let n = g.node_count();
    let mut comp = vec![u32::MAX; n];
    let mut next = 0u32;
    let mut stack = Vec::new();
    for s in 0..n as u32 {
        if comp[s as usize] != u32::MAX {
            continue;
        }
        comp[s as usize] = next;
        stack.push(s);
        while let Some(u) = stack.pop() {
            for (v, _) in g.neighbours(u) {
                if comp[v as usize] == u32::MAX {
                    comp[v as usize] = next;
                    stack.push(v);
                }
            }
        }
        next += 1;
    }
    comp
}
