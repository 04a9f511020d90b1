//! Building a roadmap: the paper's samples joined to their nearest neighbours by valid edges,
//! isolated samples re-drawn, then (beyond the paper) a few cross-component edge tests and
//! visibility repair, and the bridging of components that share a free region.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::num::NonZeroUsize;
use std::sync::Arc;

use kiddo::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::bridge::bridge_components;
use super::buckets::Buckets;
use super::{BuildPhase, BuildStats, PrmParams, Roadmap, components, kd_tree};
use crate::cspace::{ConfigSpace, jitter};
use crate::error::BuildError;
use crate::search::{Csr, Edge};

/// How many rounds isolated samples are re-drawn before they are left alone.
const RESAMPLE_ROUNDS: usize = 32;

impl Roadmap {
    /// Builds the roadmap. As the paper: samples in free space (ridge-biased here), each joined
    /// to its nearest neighbours by valid straight edges no longer than d_max, isolated samples
    /// re-drawn. Beyond the paper, `repair_share` of the n samples go to visibility repair:
    /// a few extra edge tests between nearby components, then connector and guard samples.
    pub fn build(cspace: Arc<ConfigSpace>, params: &PrmParams) -> Result<Self, BuildError> {
        Self::build_until(cspace, params, &grid::Stop::never())
    }

    /// [`Roadmap::build`], polling `stop` every few dozen samples: [`BuildError::Stopped`]
    /// once it is requested.
    pub fn build_until(
        cspace: Arc<ConfigSpace>,
        params: &PrmParams,
        stop: &grid::Stop,
    ) -> Result<Self, BuildError> {
        Self::build_observed(cspace, params, stop, &mut |_| {})
    }

    /// [`Roadmap::build_until`], calling `phase_done` as each [`BuildPhase`] ends (the
    /// benchmark times the phases with it; the roadmap is the same).
    pub fn build_observed(
        cspace: Arc<ConfigSpace>,
        params: &PrmParams,
        stop: &grid::Stop,
        phase_done: &mut dyn FnMut(BuildPhase),
    ) -> Result<Self, BuildError> {
        params.validate()?;
        if cspace.free_cells().is_empty() {
            return Err(BuildError::NoFreeSpace {
                inflation_m: cspace.inflation().total_m(),
            });
        }
        // Most samples are the paper's random ones; the rest are spent where they join
        // components or cover unseen space (see `repair`).
        let repair_budget = ((params.samples as f64) * params.repair_share).floor() as usize;
        let random_count = (params.samples - repair_budget).max(1);
        let mut b = Building::sample(&cspace, params, random_count);
        phase_done(BuildPhase::Sampling);
        b.connect_neighbours(stop)?;
        phase_done(BuildPhase::Neighbours);
        let mut uf = b.union_find();
        b.cross_component_edges(&mut uf)?;
        phase_done(BuildPhase::Cross);
        b.repair(params.samples.saturating_sub(random_count), &mut uf);
        phase_done(BuildPhase::Repair);
        if params.repair_share > 0.0 {
            bridge_components(&cspace, &mut b.nodes, &mut b.adj, &mut uf, &mut b.stats);
        }
        phase_done(BuildPhase::Bridging);
        let built = b.finish()?;
        phase_done(BuildPhase::Graph);
        Ok(Self {
            cspace,
            params: params.clone(),
            nodes: built.nodes,
            graph: built.graph,
            component: built.component,
            tree: built.tree,
            stats: built.stats,
        })
    }
}

/// Cross-component edge tests per node after the k-nearest pass.
const CROSS_TESTS: usize = 3;
/// Candidate samples drawn per repair sample kept.
const REPAIR_TRIALS_PER_SAMPLE: usize = 4;
/// Visibility tests per repair candidate.
const REPAIR_TESTS: usize = 8;

/// Tested pairs ([`pair_key`]) -> edge length if valid.
type Tested = HashMap<u64, Option<f64>, BuildHasherDefault<PairHasher>>;

/// A roadmap being built: its samples, their edges so far, and the pairs already tested.
struct Building<'a> {
    cs: &'a ConfigSpace,
    params: &'a PrmParams,
    rng: ChaCha8Rng,
    stats: BuildStats,
    /// Node positions in grid units (cells).
    nodes: Vec<[f64; 2]>,
    /// Per node: its neighbours and the edges' lengths, in cells.
    adj: Vec<Vec<(u32, f64)>>,
    /// Pair results; cleared for nodes that get re-drawn.
    tested: Tested,
    /// d_max squared, in cells².
    dmax2: f64,
    /// Nearest neighbours a node asks the k-d tree for (itself among them).
    tests: NonZeroUsize,
}

/// What a finished build hands the [`Roadmap`].
struct Built {
    nodes: Vec<[f64; 2]>,
    graph: Csr,
    component: Vec<u32>,
    tree: ImmutableKdTree<f64, 2>,
    stats: BuildStats,
}

impl<'a> Building<'a> {
    /// The paper's `random_count` random samples, with no edges yet.
    fn sample(cs: &'a ConfigSpace, params: &'a PrmParams, random_count: usize) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
        let mut stats = BuildStats::default();
        let nodes: Vec<[f64; 2]> = (0..random_count)
            .map(|_| draw(cs, params, &mut rng))
            .collect();
        stats.samples_drawn = nodes.len();
        let dmax = params.max_edge_m / cs.resolution();
        let tests = NonZeroUsize::new(params.max_tests_per_node.max(params.neighbours) + 1)
            .unwrap_or(NonZeroUsize::MIN);
        Self {
            cs,
            params,
            rng,
            stats,
            adj: vec![Vec::new(); nodes.len()],
            nodes,
            tested: HashMap::default(),
            dmax2: dmax * dmax,
            tests,
        }
    }

    /// The paper's neighbour pass: each sample joined to its nearest neighbours by valid edges
    /// no longer than d_max, then isolated samples re-drawn and joined again, for up to
    /// [`RESAMPLE_ROUNDS`] rounds. Polls `stop` every 32 samples.
    fn connect_neighbours(&mut self, stop: &grid::Stop) -> Result<(), BuildError> {
        let mut pending: Vec<u32> = (0..self.nodes.len() as u32).collect();
        for round in 0..=RESAMPLE_ROUNDS {
            let tree = kd_tree(&self.nodes)?;
            for (n, &i) in pending.iter().enumerate() {
                if n.is_multiple_of(32) && stop.requested() {
                    return Err(BuildError::Stopped);
                }
                self.connect_to_nearest(&tree, i);
            }
            pending = (0..self.nodes.len() as u32)
                .filter(|&i| self.adj[i as usize].is_empty())
                .collect();
            if pending.is_empty() || round == RESAMPLE_ROUNDS {
                break;
            }
            self.redraw(&pending);
        }
        Ok(())
    }

    /// Tests node `i`'s nearest neighbours in order (within d_max, pairs tested before taken
    /// from `tested`) until it has k valid edges or runs out of candidates.
    fn connect_to_nearest(&mut self, tree: &ImmutableKdTree<f64, 2>, i: u32) {
        let p = self.nodes[i as usize];
        let near = tree
            .query(&p)
            .nearest_n::<SquaredEuclidean<f64>>(self.tests)
            .within(self.dmax2)
            .execute();
        let mut valid = 0usize;
        for nb in near {
            let j = nb.item;
            if j == i {
                continue;
            }
            let key = pair_key(i, j);
            let len = match self.tested.get(&key) {
                Some(r) => *r,
                None => {
                    self.stats.edge_checks += 1;
                    let q = self.nodes[j as usize];
                    let r = self.cs.segment_free_grid(p, q).then(|| nb.distance.sqrt());
                    self.tested.insert(key, r);
                    if let Some(len) = r {
                        self.adj[i as usize].push((j, len));
                        self.adj[j as usize].push((i, len));
                    }
                    r
                }
            };
            if len.is_some() {
                valid += 1;
                if valid >= self.params.neighbours {
                    break;
                }
            }
        }
    }

    /// Re-draws the isolated samples `pending` (the paper's rule); their old pair results no
    /// longer hold.
    fn redraw(&mut self, pending: &[u32]) {
        let adj = &self.adj;
        self.tested.retain(|&key, _| {
            let (a, b) = ((key >> 32) as u32, key as u32);
            !(adj[a as usize].is_empty() || adj[b as usize].is_empty())
        });
        for &i in pending {
            self.nodes[i as usize] = draw(self.cs, self.params, &mut self.rng);
            self.stats.samples_drawn += 1;
        }
    }

    /// The components of the edges so far.
    fn union_find(&self) -> UnionFind {
        let mut uf = UnionFind::new(self.nodes.len());
        for (i, list) in self.adj.iter().enumerate() {
            for &(j, _) in list {
                uf.union(i as u32, j);
            }
        }
        uf
    }

    /// Joins components that are close: each node tests a few more of its neighbours lying in
    /// other components. Part of the repair, so that `repair_share` = 0 is exactly the paper's
    /// PRM.
    fn cross_component_edges(&mut self, uf: &mut UnionFind) -> Result<(), BuildError> {
        let wide = NonZeroUsize::new(3 * self.tests.get()).unwrap_or(NonZeroUsize::MIN);
        let tree = kd_tree(&self.nodes)?;
        let cross_nodes = if self.params.repair_share > 0.0 {
            self.nodes.len() as u32
        } else {
            0
        };
        for i in 0..cross_nodes {
            let p = self.nodes[i as usize];
            let near = tree
                .query(&p)
                .nearest_n::<SquaredEuclidean<f64>>(wide)
                .within(self.dmax2)
                .execute();
            let mut tries = 0;
            for nb in near {
                let j = nb.item;
                if j == i || uf.find(i) == uf.find(j) || self.tested.contains_key(&pair_key(i, j)) {
                    continue;
                }
                tries += 1;
                self.stats.edge_checks += 1;
                let r = self
                    .cs
                    .segment_free_grid(p, self.nodes[j as usize])
                    .then(|| nb.distance.sqrt());
                self.tested.insert(pair_key(i, j), r);
                if let Some(len) = r {
                    self.adj[i as usize].push((j, len));
                    self.adj[j as usize].push((i, len));
                    uf.union(i, j);
                }
                if tries >= CROSS_TESTS {
                    break;
                }
            }
        }
        Ok(())
    }

    /// Visibility-based repair (after Siméon, Laumond and Nissoux's Visibility-PRM): spends
    /// `budget` samples on candidates that see two or more components (connectors, which join
    /// them) or see no node at all (guards, which cover space no query could otherwise reach).
    /// Candidates that only see one component add nothing and are dropped. When the trials run
    /// out, the rest of the budget becomes ordinary samples so the roadmap always has n nodes.
    fn repair(&mut self, budget: usize, uf: &mut UnionFind) {
        let (cs, params) = (self.cs, self.params);
        let dmax = params.max_edge_m / cs.resolution();
        let dmax2 = dmax * dmax;
        let mut added = 0usize;
        let mut trials = 0usize;
        let mut near: Vec<(f64, u32)> = Vec::new();
        let mut seen: Vec<(u32, u32, f64)> = Vec::new(); // (component root, node, length)
        if budget == 0 {
            return;
        }
        let mut buckets = Buckets::new(
            cs.width,
            cs.height,
            cs.free_cells().len(),
            self.nodes.len() + budget,
        );
        for (j, &q) in self.nodes.iter().enumerate() {
            buckets.insert(j as u32, q);
        }
        while added < budget {
            let exhausted = trials >= budget * REPAIR_TRIALS_PER_SAMPLE;
            trials += 1;
            let p = draw(cs, params, &mut self.rng);
            self.stats.samples_drawn += 1;
            // The node set grows one by one here: buckets rather than a k-d tree.
            self.stats.repair_distances +=
                buckets.nearest(&self.nodes, p, params.max_tests_per_node, dmax2, &mut near);
            seen.clear();
            let mut tests = 0;
            for &(d2, j) in &near {
                let root = uf.find(j);
                if seen.iter().any(|s| s.0 == root) {
                    continue;
                }
                if tests >= REPAIR_TESTS && !exhausted {
                    break;
                }
                tests += 1;
                self.stats.edge_checks += 1;
                if cs.segment_free_grid(p, self.nodes[j as usize]) {
                    seen.push((root, j, d2.sqrt()));
                }
            }
            let keep = exhausted || seen.len() != 1;
            if !keep {
                continue;
            }
            let id = self.nodes.len() as u32;
            self.nodes.push(p);
            buckets.insert(id, p);
            self.adj.push(Vec::new());
            uf.push();
            for &(_, j, len) in &seen {
                self.adj[id as usize].push((j, len));
                self.adj[j as usize].push((id, len));
                uf.union(id, j);
            }
            added += 1;
        }
    }

    /// The graph of the edges found, its components and the nodes' k-d tree.
    fn finish(self) -> Result<Built, BuildError> {
        let Building {
            nodes,
            adj,
            mut stats,
            ..
        } = self;
        stats.isolated = adj.iter().filter(|a| a.is_empty()).count();
        // An edge's clearance is left unknown (NaN): a query traces it only for the edges its
        // plan uses (a handful), where tracing every edge here cost more than the rest of the
        // graph. The plan's clearance is the same either way.
        let mut edges: Vec<Edge> = Vec::with_capacity(adj.iter().map(Vec::len).sum::<usize>() / 2);
        for (i, list) in adj.iter().enumerate() {
            for &(j, len) in list {
                if (i as u32) < j {
                    edges.push((i as u32, j, len, f32::NAN));
                }
            }
        }
        stats.edges = edges.len();
        let graph = Csr::from_edges(nodes.len(), &edges);
        let component = components(&graph);
        stats.components = component
            .iter()
            .copied()
            .max()
            .map_or(0, |m| m as usize + 1);
        let tree = kd_tree(&nodes)?;
        Ok(Built {
            nodes,
            graph,
            component,
            tree,
            stats,
        })
    }
}

/// Disjoint sets over node ids, with path halving.
pub(super) struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    pub(super) fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
        }
    }
    pub(super) fn push(&mut self) {
        self.parent.push(self.parent.len() as u32);
    }
    pub(super) fn find(&mut self, mut a: u32) -> u32 {
        while self.parent[a as usize] != a {
            let grand = self.parent[self.parent[a as usize] as usize];
            self.parent[a as usize] = grand;
            a = grand;
        }
        a
    }
    pub(super) fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            // Smaller id as root keeps the structure deterministic.
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi as usize] = lo;
        }
    }
}

/// A fresh sample: on a ridge cell with probability `skeleton_share`, else uniform in free space.
fn draw(cs: &ConfigSpace, params: &PrmParams, rng: &mut ChaCha8Rng) -> [f64; 2] {
    let ridge = &cs.skeleton_cells;
    let cells = if !ridge.is_empty() && rng.random::<f64>() < params.skeleton_share {
        ridge.as_slice()
    } else {
        cs.free_cells()
    };
    let idx = cells[rng.random_range(0..cells.len())] as usize;
    jitter(idx, cs.width, rng)
}

fn pair_key(a: u32, b: u32) -> u64 {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    (u64::from(lo) << 32) | u64::from(hi)
}

/// Multiplicative hash for u64 pair keys: SipHash would be a tenth of the build time here.
#[derive(Default)]
struct PairHasher(u64);

impl Hasher for PairHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(5) ^ u64::from(b)).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}
