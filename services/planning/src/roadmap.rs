//! The probabilistic roadmap (paper §4.2.1): built once per (map, robot, parameters), then
//! queried many times; local densification when a query falls between its components.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::num::NonZeroUsize;
use std::sync::Arc;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::cspace::{ConfigSpace, Inflation, RegionId, jitter};
use crate::error::{BuildError, Endpoint, QueryError};
use crate::grid::Point2;
use crate::search::{Csr, Edge, Search, SearchAlgorithm};

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
    /// The caller's map version (or [`crate::GridMap::fingerprint`]).
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
    /// Skip local densification and fail with [`QueryError::NotConnected`] instead.
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

/// How many rounds isolated samples are re-drawn before they are left alone.
const RESAMPLE_ROUNDS: usize = 32;

impl Roadmap {
    /// Builds the roadmap. As the paper: samples in free space (ridge-biased here), each joined
    /// to its nearest neighbours by valid straight edges no longer than d_max, isolated samples
    /// re-drawn. Beyond the paper, `repair_share` of the n samples go to visibility repair:
    /// a few extra edge tests between nearby components, then connector and guard samples.
    pub fn build(cspace: Arc<ConfigSpace>, params: &PrmParams) -> Result<Self, BuildError> {
        params.validate()?;
        if cspace.free_cells().is_empty() {
            return Err(BuildError::NoFreeSpace {
                inflation_m: cspace.inflation().total_m(),
            });
        }
        let cs = &*cspace;
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
        let mut stats = BuildStats::default();
        // Most samples are the paper's random ones; the rest are spent where they join
        // components or cover unseen space (see `repair`).
        let repair_budget = ((params.samples as f64) * params.repair_share).floor() as usize;
        let random_count = (params.samples - repair_budget).max(1);
        let mut nodes: Vec<[f64; 2]> = (0..random_count)
            .map(|_| draw(cs, params, &mut rng))
            .collect();
        stats.samples_drawn = nodes.len();
        let dmax = params.max_edge_m / cs.resolution();
        let dmax2 = dmax * dmax;
        let k = params.neighbours;
        let tests =
            NonZeroUsize::new(params.max_tests_per_node.max(k) + 1).unwrap_or(NonZeroUsize::MIN);

        // Tested pairs (lo, hi) -> edge length if valid. Cleared for nodes that get re-drawn.
        let mut tested: HashMap<u64, Option<f64>, BuildHasherDefault<PairHasher>> =
            HashMap::default();
        let mut adj: Vec<Vec<(u32, f64)>> = vec![Vec::new(); nodes.len()];
        let mut pending: Vec<u32> = (0..nodes.len() as u32).collect();
        for round in 0..=RESAMPLE_ROUNDS {
            let tree = kd_tree(&nodes)?;
            for &i in &pending {
                let p = nodes[i as usize];
                let near = tree
                    .query(&p)
                    .nearest_n::<SquaredEuclidean<f64>>(tests)
                    .within(dmax2)
                    .execute();
                let mut valid = 0usize;
                for nb in near {
                    let j = nb.item;
                    if j == i {
                        continue;
                    }
                    let key = pair_key(i, j);
                    let len = match tested.get(&key) {
                        Some(r) => *r,
                        None => {
                            stats.edge_checks += 1;
                            let q = nodes[j as usize];
                            let r = cs.segment_free_grid(p, q).then(|| nb.distance.sqrt());
                            tested.insert(key, r);
                            if let Some(len) = r {
                                adj[i as usize].push((j, len));
                                adj[j as usize].push((i, len));
                            }
                            r
                        }
                    };
                    if len.is_some() {
                        valid += 1;
                        if valid >= k {
                            break;
                        }
                    }
                }
            }
            pending = (0..nodes.len() as u32)
                .filter(|&i| adj[i as usize].is_empty())
                .collect();
            if pending.is_empty() || round == RESAMPLE_ROUNDS {
                break;
            }
            // Re-draw isolated samples (the paper's rule); their old pair results no longer hold.
            tested.retain(|&key, _| {
                let (a, b) = ((key >> 32) as u32, key as u32);
                !(adj[a as usize].is_empty() || adj[b as usize].is_empty())
            });
            for &i in &pending {
                nodes[i as usize] = draw(cs, params, &mut rng);
                stats.samples_drawn += 1;
            }
        }
        let mut uf = UnionFind::new(nodes.len());
        for (i, list) in adj.iter().enumerate() {
            for &(j, _) in list {
                uf.union(i as u32, j);
            }
        }
        // Join components that are close: test a few more neighbours lying in other components.
        // Part of the repair, so that repair_share = 0 is exactly the paper's PRM.
        let wide = NonZeroUsize::new(3 * tests.get()).unwrap_or(NonZeroUsize::MIN);
        let tree = kd_tree(&nodes)?;
        let cross_nodes = if params.repair_share > 0.0 {
            nodes.len() as u32
        } else {
            0
        };
        for i in 0..cross_nodes {
            let p = nodes[i as usize];
            let near = tree
                .query(&p)
                .nearest_n::<SquaredEuclidean<f64>>(wide)
                .within(dmax2)
                .execute();
            let mut tries = 0;
            for nb in near {
                let j = nb.item;
                if j == i || uf.find(i) == uf.find(j) || tested.contains_key(&pair_key(i, j)) {
                    continue;
                }
                tries += 1;
                stats.edge_checks += 1;
                let r = cs
                    .segment_free_grid(p, nodes[j as usize])
                    .then(|| nb.distance.sqrt());
                tested.insert(pair_key(i, j), r);
                if let Some(len) = r {
                    adj[i as usize].push((j, len));
                    adj[j as usize].push((i, len));
                    uf.union(i, j);
                }
                if tries >= CROSS_TESTS {
                    break;
                }
            }
        }
        let budget = params.samples.saturating_sub(random_count);
        repair(
            cs, params, &mut rng, budget, &mut nodes, &mut adj, &mut uf, &mut stats,
        );
        if params.repair_share > 0.0 {
            bridge_components(cs, &mut nodes, &mut adj, &mut uf, &mut stats);
        }
        stats.isolated = adj.iter().filter(|a| a.is_empty()).count();

        // Each edge's clearance is computed once here, so a query reads it for the roadmap part
        // of its path and traces only the segments it adds (start and goal links).
        let mut edges: Vec<Edge> = Vec::with_capacity(adj.iter().map(Vec::len).sum::<usize>() / 2);
        for (i, list) in adj.iter().enumerate() {
            for &(j, len) in list {
                if (i as u32) < j {
                    let min = cs.segment_min_dist(nodes[i], nodes[j as usize]) as f32;
                    edges.push((i as u32, j, len, min));
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
        Ok(Self {
            cspace,
            params: params.clone(),
            nodes,
            graph,
            component,
            tree,
            stats,
        })
    }

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

    /// Shortest roadmap path from `start` to `goal`, densifying locally when the roadmap does
    /// not join them although free space does.
    pub fn query(
        &self,
        start: Point2,
        goal: Point2,
        opts: QueryOptions,
    ) -> Result<Plan, QueryError> {
        let cs = &*self.cspace;
        let gs = cs.check_endpoint(Endpoint::Start, start)?;
        let gg = cs.check_endpoint(Endpoint::Goal, goal)?;
        let (rs, rg) = (self.region(gs), self.region(gg));
        if rs != rg {
            return Err(QueryError::Unreachable {
                start_region: rs,
                goal_region: rg,
            });
        }
        let dmax = self.params.max_edge_m / cs.resolution();
        let direct = dist(gs, gg);
        if direct <= dmax && cs.segment_free_grid(gs, gg) {
            return Ok(self.plan(&[gs, gg], &[f32::NAN], direct, 0, 0));
        }
        if let Some(plan) = self.lazy_search(gs, gg, opts.algorithm) {
            return Ok(plan);
        }
        if opts.no_densify {
            return Err(QueryError::NotConnected);
        }
        let start_links = self.links(gs);
        let goal_links = self.links(gg);
        self.densified_query(gs, gg, &start_links, &goal_links, opts.algorithm)
    }

    /// Shortest path with the start and goal joined to their k nearest nodes lazily: the search
    /// assumes every such link is free and checks a link only when it would use it. A start
    /// link is checked when the search is about to expand its node through it; the goal link
    /// when a path ends with it. A blocked link is withdrawn and the search resumes, redoing
    /// only the one label derived from it. The answer is the same as checking all 2k links
    /// first (the final path is shortest in a graph that contains every valid link), with
    /// fewer segment checks, which dominate a query.
    fn lazy_search(&self, gs: [f64; 2], gg: [f64; 2], algorithm: SearchAlgorithm) -> Option<Plan> {
        let k = self.params.neighbours;
        // Verdicts on start links (node, free), so that no link is checked twice; the eager
        // fallbacks' links are free by construction.
        let start_known = std::cell::RefCell::new(Vec::<(u32, bool)>::new());
        let mut g_ok = Vec::new();
        let mut sl = self.candidates(gs);
        if sl.is_empty() {
            sl = self.links_beyond(gs, k);
            start_known
                .borrow_mut()
                .extend(sl.iter().map(|l| (l.0, true)));
        }
        let mut gl = self.candidates(gg);
        if gl.is_empty() {
            gl = self.links_beyond(gg, k);
            g_ok.extend(gl.iter().map(|l| l.0));
        }
        let h = |i: u32| dist(self.nodes[i as usize], gg);
        let mut start_free = |i: u32| {
            let known = start_known.borrow().iter().find(|v| v.0 == i).map(|v| v.1);
            known.unwrap_or_else(|| {
                let free = self.cspace.segment_free_grid(gs, self.nodes[i as usize]);
                start_known.borrow_mut().push((i, free));
                free
            })
        };
        let mut search = Search::new(&self.graph, &sl, &gl, algorithm, h);
        let mut found = search.run(&mut start_free);
        let mut expanded = 0;
        if found.is_none() && search.start_links_left() == 0 {
            // None of the k nearest is in sight of the start: check farther nodes eagerly.
            let beyond = self.links_beyond(gs, k);
            if !beyond.is_empty() {
                expanded += search.expanded;
                start_known
                    .borrow_mut()
                    .extend(beyond.iter().map(|l| (l.0, true)));
                search = Search::new(&self.graph, &beyond, &gl, algorithm, h);
                found = search.run(&mut start_free);
            }
        }
        loop {
            let path = found?;
            let last = path.nodes[path.nodes.len() - 2];
            if g_ok.contains(&last) || self.cspace.segment_free_grid(self.nodes[last as usize], gg)
            {
                let pts = self.points(&path.nodes, &self.nodes, gs, gg);
                let mins = segment_mins(&self.graph, &path.nodes);
                let expanded = expanded + search.expanded;
                return Some(self.plan(&pts, &mins, path.length, 0, expanded));
            }
            gl.retain(|l| l.0 != last);
            if gl.is_empty() {
                // None of the k nearest in sight of the goal: check farther nodes eagerly.
                gl = self.links_beyond(gg, k);
                g_ok.extend(gl.iter().map(|l| l.0));
                expanded += search.expanded;
                let sl_now = search.start_links().to_vec();
                search = Search::new(&self.graph, &sl_now, &gl, algorithm, h);
            } else {
                search.withdraw_goal(last);
            }
            found = search.run(&mut start_free);
        }
    }

    /// Nodes a query endpoint may test when none of its k nearest is in sight: a query that
    /// starts in a cluttered corner should still reach the roadmap without densifying.
    fn query_tests(&self) -> usize {
        (3 * self.params.neighbours).max(self.params.max_tests_per_node)
    }

    /// The k nearest roadmap nodes within d_max, unchecked.
    fn candidates(&self, g: [f64; 2]) -> Vec<(u32, f64)> {
        let dmax = self.params.max_edge_m / self.cspace.resolution();
        let Some(k) = NonZeroUsize::new(self.params.neighbours) else {
            return Vec::new();
        };
        self.tree
            .query(&g)
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .within(dmax * dmax)
            .execute()
            .into_iter()
            .map(|nb| (nb.item, nb.distance.sqrt()))
            .collect()
    }

    /// Valid links to the nearest nodes after the first `skip`, up to `max_tests_per_node`
    /// tested, stopping at the first in sight.
    fn links_beyond(&self, g: [f64; 2], skip: usize) -> Vec<(u32, f64)> {
        let dmax = self.params.max_edge_m / self.cspace.resolution();
        let Some(tests) = NonZeroUsize::new(self.query_tests().max(skip + 1)) else {
            return Vec::new();
        };
        self.tree
            .query(&g)
            .nearest_n::<SquaredEuclidean<f64>>(tests)
            .within(dmax * dmax)
            .execute()
            .into_iter()
            .skip(skip)
            .find(|nb| {
                self.cspace
                    .segment_free_grid(g, self.nodes[nb.item as usize])
            })
            .map(|nb| vec![(nb.item, nb.distance.sqrt())])
            .unwrap_or_default()
    }

    /// Keeps what a densified query learnt: the plan's waypoints become nodes and its segments
    /// edges, so later queries through the same gap need no densification. Returns the number
    /// of nodes added. For the cache owner, between queries (it needs `&mut`); plans from other
    /// roadmaps or with blocked segments are ignored.
    pub fn absorb(&mut self, plan: &Plan) -> usize {
        let cs = Arc::clone(&self.cspace);
        let pts: Vec<[f64; 2]> = plan.waypoints.iter().map(|&p| cs.to_grid(p)).collect();
        let valid = pts.len() >= 2
            && pts
                .iter()
                .all(|&g| cs.cell_index(g).is_some_and(|i| cs.free[i]))
            && pts.windows(2).all(|w| cs.segment_free_grid(w[0], w[1]));
        if plan.densified_nodes == 0 || !valid {
            return 0;
        }
        let mut edges: Vec<Edge> = Vec::with_capacity(self.stats.edges + pts.len());
        edges.extend(self.graph.edges());
        // Existing nodes are matched exactly: waypoints that are roadmap nodes carry their bits.
        let mut ids = Vec::with_capacity(pts.len());
        let mut added = 0;
        for &p in &pts {
            let id = match self.nodes.iter().position(|&q| q == p) {
                Some(i) => i as u32,
                None => {
                    self.nodes.push(p);
                    added += 1;
                    self.nodes.len() as u32 - 1
                }
            };
            ids.push(id);
        }
        for (w, pair) in pts.windows(2).zip(ids.windows(2)) {
            if pair[0] != pair[1] {
                let min = cs.segment_min_dist(w[0], w[1]) as f32;
                edges.push((pair[0], pair[1], dist(w[0], w[1]), min));
            }
        }
        let Ok(tree) = kd_tree(&self.nodes) else {
            // Only past MAX_SAMPLES nodes; keep the roadmap as it was.
            self.nodes.truncate(self.nodes.len() - added);
            return 0;
        };
        self.graph = Csr::from_edges(self.nodes.len(), &edges);
        self.component = components(&self.graph);
        self.tree = tree;
        self.stats.edges = edges.len();
        self.stats.components = self
            .component
            .iter()
            .copied()
            .max()
            .map_or(0, |m| m as usize + 1);
        added
    }

    /// Removes detours: each waypoint is joined to the farthest later one in straight sight.
    /// Reported apart from the raw roadmap path, as the paper's planner does not do this.
    pub fn shortcut(&self, plan: &Plan) -> Plan {
        let cs = &*self.cspace;
        let g: Vec<[f64; 2]> = plan.waypoints.iter().map(|&p| cs.to_grid(p)).collect();
        if g.len() <= 2 {
            return plan.clone();
        }
        let mut out = vec![g[0]];
        let mut i = 0;
        while i + 1 < g.len() {
            let mut j = g.len() - 1;
            while j > i + 1 && !cs.segment_free_grid(g[i], g[j]) {
                j -= 1;
            }
            out.push(g[j]);
            i = j;
        }
        let len = out.windows(2).map(|w| dist(w[0], w[1])).sum();
        let mins = vec![f32::NAN; out.len() - 1];
        self.plan(&out, &mins, len, plan.densified_nodes, plan.expanded)
    }

    fn region(&self, g: [f64; 2]) -> RegionId {
        self.cspace
            .cell_index(g)
            .map_or(0, |i| self.cspace.region[i])
    }

    /// Up to k valid edges from a query point to its nearest roadmap nodes within d_max.
    fn links(&self, g: [f64; 2]) -> Vec<(u32, f64)> {
        let dmax = self.params.max_edge_m / self.cspace.resolution();
        let tests = NonZeroUsize::new(self.query_tests()).unwrap_or(NonZeroUsize::MIN);
        let near = self
            .tree
            .query(&g)
            .nearest_n::<SquaredEuclidean<f64>>(tests)
            .within(dmax * dmax)
            .execute();
        // As the paper: the k nearest nodes, those in sight. Farther ones are tried only while
        // none of the k is in sight, so a query in a cluttered corner still finds the roadmap.
        let mut out = Vec::with_capacity(self.params.neighbours);
        for (tested, nb) in near.into_iter().enumerate() {
            if tested >= self.params.neighbours && !out.is_empty() {
                break;
            }
            if self
                .cspace
                .segment_free_grid(g, self.nodes[nb.item as usize])
            {
                out.push((nb.item, nb.distance.sqrt()));
            }
        }
        out
    }

    /// Maps a search result (virtual start n, goal n+1) to grid points.
    fn points(
        &self,
        ids: &[u32],
        positions: &[[f64; 2]],
        gs: [f64; 2],
        gg: [f64; 2],
    ) -> Vec<[f64; 2]> {
        let n = positions.len() as u32;
        ids.iter()
            .map(|&id| {
                if id == n {
                    gs
                } else if id == n + 1 {
                    gg
                } else {
                    positions[id as usize]
                }
            })
            .collect()
    }

    /// A plan through `pts`. `mins[k]` is the obstacle distance (cells) along segment k when
    /// already known (a roadmap edge's, computed at build), NaN when it must be traced here.
    fn plan(
        &self,
        pts: &[[f64; 2]],
        mins: &[f32],
        length_cells: f64,
        densified: usize,
        expanded: usize,
    ) -> Plan {
        let cs = &*self.cspace;
        debug_assert_eq!(mins.len() + 1, pts.len().max(1));
        let mut min = f64::INFINITY;
        for (w, &known) in pts.windows(2).zip(mins) {
            let d = if known.is_nan() {
                cs.segment_min_dist(w[0], w[1])
            } else {
                f64::from(known)
            };
            min = min.min(d);
        }
        if pts.len() == 1
            && let Some(i) = cs.cell_index(pts[0])
        {
            min = f64::from(cs.dist[i]);
        }
        Plan {
            waypoints: pts.iter().map(|&g| cs.to_world(g)).collect(),
            length_m: length_cells * cs.resolution(),
            min_clearance_m: ((min - 0.5) * cs.resolution()).max(0.0),
            densified_nodes: densified,
            expanded,
        }
    }

    /// Local densification: a grid wavefront from the part of the roadmap the start reaches
    /// (or the start itself) to the part the goal reaches; the cells it crosses, thinned to
    /// straight-line-of-sight waypoints, become extra nodes for this query. Start and goal are
    /// in one free region here, so the wavefront always arrives.
    fn densified_query(
        &self,
        gs: [f64; 2],
        gg: [f64; 2],
        start_links: &[(u32, f64)],
        goal_links: &[(u32, f64)],
        algorithm: SearchAlgorithm,
    ) -> Result<Plan, QueryError> {
        let cs = &*self.cspace;
        let n = self.nodes.len() as u32;
        // Placeholder ids for the terminals while the chain is assembled (node ids stay far below).
        let (virtual_start, virtual_goal) = (u32::MAX - 1, u32::MAX);
        // Anchors: cells from which the wavefront starts (start side) or which end it (goal side).
        let side = |g: [f64; 2], links: &[(u32, f64)], terminal: u32| -> Vec<(usize, u32)> {
            if links.is_empty() {
                return cs
                    .cell_index(g)
                    .map(|c| vec![(c, terminal)])
                    .unwrap_or_default();
            }
            let comps: Vec<u32> = links
                .iter()
                .map(|&(j, _)| self.component[j as usize])
                .collect();
            (0..n)
                .filter(|&i| comps.contains(&self.component[i as usize]))
                .filter_map(|i| cs.cell_index(self.nodes[i as usize]).map(|c| (c, i)))
                .collect()
        };
        // The start and goal cells themselves always take part, so the search cannot miss.
        let mut sources = side(gs, &[], virtual_start);
        sources.extend(
            side(gs, start_links, virtual_start)
                .into_iter()
                .filter(|&(_, id)| id != virtual_start),
        );
        let mut targets = side(gg, &[], virtual_goal);
        targets.extend(
            side(gg, goal_links, virtual_goal)
                .into_iter()
                .filter(|&(_, id)| id != virtual_goal),
        );
        // Each anchor claims the disc of cells it sees for certain (distance field), so the wave
        // stops as soon as it touches one instead of having to hit the anchor's own cell.
        let anchor_at = |id: u32| match id {
            id if id == virtual_start => gs,
            id if id == virtual_goal => gg,
            id => self.nodes[id as usize],
        };
        // Grow the wave from the side with fewer anchors: every anchor radiates, so starting
        // from a lone terminal rather than from a whole component explores far fewer cells.
        let found = if sources.len() <= targets.len() {
            wavefront(cs, &sources, &targets, anchor_at)
        } else {
            wavefront(cs, &targets, &sources, anchor_at).map(|(mut cells, to, from)| {
                cells.reverse();
                (cells, from, to)
            })
        };
        let Some((cells, from, to)) = found else {
            // Unreachable in a 4-connected region cannot happen; answer honestly if it does.
            return Err(QueryError::NotConnected);
        };
        let anchor = anchor_at;
        let mut chain: Vec<[f64; 2]> = Vec::with_capacity(cells.len() + 2);
        chain.push(anchor(from));
        chain.extend(
            cells
                .iter()
                .map(|&c| [(c % cs.width) as f64 + 0.5, (c / cs.width) as f64 + 0.5]),
        );
        chain.push(anchor(to));
        let thin = thin_line_of_sight(cs, &chain);
        // New nodes: the thinned chain without its two anchors.
        let mut positions = self.nodes.clone();
        let first_new = positions.len() as u32;
        positions.extend_from_slice(&thin[1..thin.len() - 1]);
        let added = thin.len() - 2;
        let ids: Vec<u32> = std::iter::once(from)
            .chain(first_new..first_new + added as u32)
            .chain(std::iter::once(to))
            .collect();
        let m = positions.len() as u32;
        let mut edges: Vec<Edge> = Vec::with_capacity(self.stats.edges + added + 1);
        edges.extend(self.graph.edges());
        let mut sl = start_links.to_vec();
        let mut gl = goal_links.to_vec();
        for (w, pair) in thin.windows(2).zip(ids.windows(2)) {
            let len = dist(w[0], w[1]);
            let (a, b) = (pair[0], pair[1]);
            match (a == virtual_start, b == virtual_goal) {
                (true, true) => return Ok(self.plan(&[gs, gg], &[f32::NAN], len, 0, 0)),
                (true, false) => sl.push((b, len)),
                (false, true) => gl.push((a, len)),
                // Traced in `plan` only if the path uses it.
                (false, false) => edges.push((a, b, len, f32::NAN)),
            }
        }
        let graph = Csr::from_edges(m as usize, &edges);
        let h = |i: u32| dist(positions[i as usize], gg);
        let mut search = Search::new(&graph, &sl, &gl, algorithm, h);
        let found = search.run(|_| true).ok_or(QueryError::NotConnected)?;
        let pts = self.points(&found.nodes, &positions, gs, gg);
        let mins = segment_mins(&graph, &found.nodes);
        Ok(self.plan(&pts, &mins, found.length, added, search.expanded))
    }
}

/// Cross-component edge tests per node after the k-nearest pass.
const CROSS_TESTS: usize = 3;
/// Candidate samples drawn per repair sample kept.
const REPAIR_TRIALS_PER_SAMPLE: usize = 4;
/// Visibility tests per repair candidate.
const REPAIR_TESTS: usize = 8;

/// Visibility-based repair (after Siméon, Laumond and Nissoux's Visibility-PRM): spends `budget`
/// samples on candidates that see two or more components (connectors, which join them) or see
/// no node at all (guards, which cover space no query could otherwise reach). Candidates that
/// only see one component add nothing and are dropped. When the trials run out, the rest of the
/// budget becomes ordinary samples so the roadmap always has n nodes.
#[allow(clippy::too_many_arguments)]
fn repair(
    cs: &ConfigSpace,
    params: &PrmParams,
    rng: &mut ChaCha8Rng,
    budget: usize,
    nodes: &mut Vec<[f64; 2]>,
    adj: &mut Vec<Vec<(u32, f64)>>,
    uf: &mut UnionFind,
    stats: &mut BuildStats,
) {
    let dmax = params.max_edge_m / cs.resolution();
    let dmax2 = dmax * dmax;
    let mut added = 0usize;
    let mut trials = 0usize;
    let mut near: Vec<(f64, u32)> = Vec::new();
    let mut seen: Vec<(u32, u32, f64)> = Vec::new(); // (component root, node, length)
    while added < budget {
        let exhausted = trials >= budget * REPAIR_TRIALS_PER_SAMPLE;
        trials += 1;
        let p = draw(cs, params, rng);
        stats.samples_drawn += 1;
        // Brute-force neighbours: the node set grows one by one here, and n is small.
        near.clear();
        near.extend(nodes.iter().enumerate().filter_map(|(j, q)| {
            let d2 = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2);
            (d2 <= dmax2).then_some((d2, j as u32))
        }));
        let m = params.max_tests_per_node.min(near.len());
        if m < near.len() {
            near.select_nth_unstable_by(m, |a, b| a.0.total_cmp(&b.0));
            near.truncate(m);
        }
        near.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
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
            stats.edge_checks += 1;
            if cs.segment_free_grid(p, nodes[j as usize]) {
                seen.push((root, j, d2.sqrt()));
            }
        }
        let keep = exhausted || seen.len() != 1;
        if !keep {
            continue;
        }
        let id = nodes.len() as u32;
        nodes.push(p);
        adj.push(Vec::new());
        uf.push();
        for &(_, j, len) in &seen {
            adj[id as usize].push((j, len));
            adj[j as usize].push((id, len));
            uf.union(id, j);
        }
        added += 1;
    }
}

/// Joins every roadmap component to the largest one of its free region: waves grow over the
/// coarse grid from the other components' nodes until they touch another component; each
/// meeting becomes a chain of blocks, thinned to straight segments, whose corners are added as
/// nodes. Only the smaller components radiate, so the flood stays local to the gaps; the
/// region's largest component waits for them.
fn bridge_components(
    cs: &ConfigSpace,
    nodes: &mut Vec<[f64; 2]>,
    adj: &mut Vec<Vec<(u32, f64)>>,
    uf: &mut UnionFind,
    stats: &mut BuildStats,
) {
    let n = nodes.len();
    let cells: Vec<usize> = nodes
        .iter()
        .map(|&p| cs.cell_index(p).unwrap_or(0))
        .collect();
    // Per region: node count per component root.
    let mut sizes: HashMap<(u32, u32), usize> = HashMap::new();
    for i in 0..n as u32 {
        let region = cs.region[cells[i as usize]];
        *sizes.entry((region, uf.find(i))).or_default() += 1;
    }
    let mut largest: HashMap<u32, (usize, u32)> = HashMap::new(); // region -> (size, root)
    let mut roots_in: HashMap<u32, usize> = HashMap::new();
    for (&(region, root), &size) in &sizes {
        *roots_in.entry(region).or_default() += 1;
        let e = largest.entry(region).or_insert((size, root));
        // Ties broken on the root id: HashMap order must not decide.
        if (size, std::cmp::Reverse(root)) > (e.0, std::cmp::Reverse(e.1)) {
            *e = (size, root);
        }
    }
    let mut remaining: usize = roots_in.values().map(|&k| k - 1).sum();
    if remaining == 0 {
        return;
    }
    // The flood runs on the coarse grid (factor² fewer cells). A block is entirely free, so a
    // node reaches its block's centre in a straight line and 4-adjacent block centres see each
    // other. Gaps narrower than a block are left to query-time densification.
    let g = &cs.coarse;
    let f = g.factor;
    let block_of = |p: [f64; 2]| {
        let (bx, by) = ((p[0] / f as f64) as usize, (p[1] / f as f64) as usize);
        (bx < g.width && by < g.height && g.free[by * g.width + bx]).then_some(by * g.width + bx)
    };
    const LABEL: usize = 0; // seed node + 1
    const PARENT: usize = 2; // parent block + 1
    let chains: Vec<(u32, u32, Vec<usize>)> = CellTables::with(g.width * g.height, |t| {
        let mut queue = std::collections::VecDeque::new();
        for i in 0..n as u32 {
            let region = cs.region[cells[i as usize]];
            if roots_in.get(&region).copied().unwrap_or(0) < 2 {
                continue;
            }
            let Some(b) = block_of(nodes[i as usize]) else {
                continue;
            };
            if t.get(LABEL, b) == 0 {
                t.set(LABEL, b, i + 1);
                t.set(PARENT, b, b as u32 + 1);
                // The region's largest component waits for the others to reach it.
                if largest.get(&region).is_none_or(|&(_, r)| r != uf.find(i)) {
                    queue.push_back(b);
                }
            }
        }
        let mut meetings = Vec::new();
        let mut budget = FLOOD_CELL_BUDGET;
        'flood: while let Some(c) = queue.pop_front() {
            budget = budget.saturating_sub(1);
            if budget == 0 {
                // Gaps still open are left to local densification at query time.
                break;
            }
            let lc = t.get(LABEL, c);
            for nc in neighbours4(c, g.width, g.height) {
                if !g.free[nc] {
                    continue;
                }
                let ln = t.get(LABEL, nc);
                if ln == 0 {
                    t.set(LABEL, nc, lc);
                    t.set(PARENT, nc, c as u32 + 1);
                    queue.push_back(nc);
                } else if ln != lc && uf.find(lc - 1) != uf.find(ln - 1) {
                    // (Most labelled neighbours belong to the same wave: the cheap test first.)
                    uf.union(lc - 1, ln - 1);
                    meetings.push((c, nc));
                    remaining -= 1;
                    if remaining == 0 {
                        break 'flood;
                    }
                }
            }
        }
        let back = |mut c: usize| {
            let mut out = vec![c];
            while t.get(PARENT, c) as usize - 1 != c {
                c = t.get(PARENT, c) as usize - 1;
                out.push(c);
            }
            out
        };
        meetings
            .into_iter()
            .map(|(c1, c2)| {
                let mut cells = back(c1);
                cells.reverse();
                cells.extend(back(c2));
                (t.get(LABEL, c1) - 1, t.get(LABEL, c2) - 1, cells)
            })
            .collect()
    });
    // The centre of the block's middle cell, not of the block: for even factors the block
    // centre lies on a grid line, where converting to metres and back can move a horizontal
    // segment into the neighbouring row of cells.
    let centre = |b: usize| {
        [
            ((b % g.width) * f + f / 2) as f64 + 0.5,
            ((b / g.width) * f + f / 2) as f64 + 0.5,
        ]
    };
    for (a, b, path) in chains {
        let mut chain = Vec::with_capacity(path.len() + 2);
        chain.push(nodes[a as usize]);
        chain.extend(path.into_iter().map(centre));
        chain.push(nodes[b as usize]);
        let thin = thin_line_of_sight(cs, &chain);
        let mut prev = a;
        for (k, &p) in thin.iter().enumerate().skip(1) {
            let id = if k + 1 == thin.len() {
                b
            } else {
                nodes.push(p);
                adj.push(Vec::new());
                uf.push();
                stats.bridge_nodes += 1;
                nodes.len() as u32 - 1
            };
            let len = dist(nodes[prev as usize], nodes[id as usize]);
            adj[prev as usize].push((id, len));
            adj[id as usize].push((prev, len));
            uf.union(prev, id);
            prev = id;
        }
    }
}

/// Disjoint sets over node ids, with path halving.
struct UnionFind {
    parent: Vec<u32>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n as u32).collect(),
        }
    }
    fn push(&mut self) {
        self.parent.push(self.parent.len() as u32);
    }
    fn find(&mut self, mut a: u32) -> u32 {
        while self.parent[a as usize] != a {
            let grand = self.parent[self.parent[a as usize] as usize];
            self.parent[a as usize] = grand;
            a = grand;
        }
        a
    }
    fn union(&mut self, a: u32, b: u32) {
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

fn kd_tree(nodes: &[[f64; 2]]) -> Result<ImmutableKdTree<f64, 2>, BuildError> {
    // Only fails when item indices overflow u32, which `PrmParams::validate` rules out.
    ImmutableKdTree::new_from_slice(nodes).map_err(|_| BuildError::TooManySamples(nodes.len()))
}

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

/// Per-cell tables for the grid waves, kept per thread and reset in O(1) by a generation stamp:
/// a fresh zeroed table per wave costs a memset of the whole map (megabytes) each time.
struct CellTables {
    /// Per cell: [generation stamp, table 0, table 1, table 2], interleaved so that one cell's
    /// entries share a cache line.
    cells: Vec<[u32; 4]>,
    generation: u32,
}

impl CellTables {
    /// Runs `f` with tables for `cells` cells, all reading 0.
    fn with<R>(cells: usize, f: impl FnOnce(&mut CellTables) -> R) -> R {
        thread_local! {
            static TABLES: std::cell::RefCell<CellTables> = const {
                std::cell::RefCell::new(CellTables { cells: Vec::new(), generation: 0 })
            };
        }
        TABLES.with(|t| {
            let mut t = t.borrow_mut();
            if t.cells.len() < cells || t.generation == u32::MAX {
                t.cells = vec![[0; 4]; cells];
                t.generation = 0;
            }
            t.generation += 1;
            f(&mut t)
        })
    }
    fn get(&self, table: usize, c: usize) -> u32 {
        let e = &self.cells[c];
        if e[0] == self.generation {
            e[table + 1]
        } else {
            0
        }
    }
    fn set(&mut self, table: usize, c: usize, v: u32) {
        let generation = self.generation;
        let e = &mut self.cells[c];
        if e[0] != generation {
            *e = [generation, 0, 0, 0];
        }
        e[table + 1] = v;
    }
}

/// The 4-neighbours of cell `c` inside a `w` × `h` grid. Waves use 4-connectivity: half the
/// work of 8, no corner rule, and the thinning straightens the staircases afterwards.
fn neighbours4(c: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (c % w, c / w);
    // Out-of-grid neighbours map to `usize::MAX` and are filtered, which compiles to a simple
    // unrolled loop (an array of Options did not).
    let n = [
        if x > 0 { c - 1 } else { usize::MAX },
        if x + 1 < w { c + 1 } else { usize::MAX },
        if y > 0 { c - w } else { usize::MAX },
        if y + 1 < h { c + w } else { usize::MAX },
    ];
    n.into_iter().filter(|&v| v != usize::MAX)
}

/// Largest radius (cells) of the disc an anchor claims in local densification.
const DISC_CAP: f64 = 8.0;
/// Cells the bridging flood may visit per build; it bounds the build time on large cluttered
/// maps at the price of leaving the longest gaps to query-time densification.
const FLOOD_CELL_BUDGET: usize = 4_000_000;

/// Calls `f` on every cell an anchor at `p` (in cell `cell`) sees for certain: a cell whose
/// centre is within d - need - 1.5 of the anchor cell's centre (d its obstacle distance) is
/// joined to the anchor by a segment inside the free disc of radius d - need.
fn visible_disc(cs: &ConfigSpace, cell: usize, cap: f64, mut f: impl FnMut(usize)) {
    f(cell);
    let need = cs.inflation().total_m() / cs.resolution() + 0.5;
    let r = (f64::from(cs.dist[cell]) - need - 1.5).min(cap);
    if r < 1.0 {
        return;
    }
    let (cx, cy) = ((cell % cs.width) as i64, (cell / cs.width) as i64);
    let ri = r as i64;
    for y in (cy - ri).max(0)..=(cy + ri).min(cs.height as i64 - 1) {
        for x in (cx - ri).max(0)..=(cx + ri).min(cs.width as i64 - 1) {
            let (dx, dy) = ((x - cx) as f64, (y - cy) as f64);
            if dx * dx + dy * dy <= r * r {
                f(y as usize * cs.width + x as usize);
            }
        }
    }
}

/// Breadth-first wavefront over free cells (4-connected) from the source
/// anchors to the first cell claimed by a target anchor. Each anchor claims the disc of cells
/// it sees for certain, so the wave stops when it touches that disc rather than the anchor's
/// own cell. Breadth-first rather than A*: the targets (every node of the goal's part of the
/// roadmap, and the goal) are usually spread around, and the nearest ends the search soonest.
/// Returns the cells crossed (first and last in the anchors' discs) and the two anchor ids.
fn wavefront(
    cs: &ConfigSpace,
    sources: &[(usize, u32)],
    targets: &[(usize, u32)],
    at: impl Fn(u32) -> [f64; 2],
) -> Option<(Vec<usize>, u32, u32)> {
    let (w, h) = (cs.width, cs.height);
    // Tables: 0 = target index + 1, 1 = source index + 1, 2 = parent cell + 1 (0 = unvisited).
    const TARGET: usize = 0;
    const SOURCE: usize = 1;
    const PARENT: usize = 2;
    CellTables::with(w * h, |t| {
        let mut queue = std::collections::VecDeque::new();
        for (k, &(cell, id)) in targets.iter().enumerate() {
            debug_assert_eq!(cs.cell_index(at(id)), Some(cell));
            visible_disc(cs, cell, DISC_CAP, |c| {
                if t.get(TARGET, c) == 0 {
                    t.set(TARGET, c, k as u32 + 1);
                }
            });
        }
        for (k, &(cell, id)) in sources.iter().enumerate() {
            debug_assert_eq!(cs.cell_index(at(id)), Some(cell));
            visible_disc(cs, cell, DISC_CAP, |c| {
                if t.get(PARENT, c) == 0 {
                    t.set(PARENT, c, c as u32 + 1);
                    t.set(SOURCE, c, k as u32 + 1);
                    queue.push_back(c);
                }
            });
        }
        while let Some(c) = queue.pop_front() {
            let target = t.get(TARGET, c);
            if target != 0 {
                let mut cells = vec![c];
                let mut cur = c;
                while t.get(PARENT, cur) as usize - 1 != cur {
                    cur = t.get(PARENT, cur) as usize - 1;
                    cells.push(cur);
                }
                cells.reverse();
                let from = sources[t.get(SOURCE, cur) as usize - 1].1;
                let to = targets[target as usize - 1].1;
                return Some((cells, from, to));
            }
            for nc in neighbours4(c, w, h) {
                if t.get(PARENT, nc) != 0 || !cs.free[nc] {
                    continue;
                }
                t.set(PARENT, nc, c as u32 + 1);
                queue.push_back(nc);
            }
        }
        None
    })
}

/// Thins a chain of points whose consecutive segments are free into fewer points whose
/// consecutive segments are still free: from each kept point, gallop then bisect to a far
/// point in straight sight.
fn thin_line_of_sight(cs: &ConfigSpace, chain: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut out = vec![chain[0]];
    let last = chain.len() - 1;
    let mut i = 0;
    while i < last {
        let mut good = i + 1;
        let mut step = 1;
        let mut bad = None;
        while good + step <= last {
            let j = good + step;
            if cs.segment_free_grid(chain[i], chain[j]) {
                good = j;
                step *= 2;
            } else {
                bad = Some(j);
                break;
            }
        }
        if let Some(mut hi) = bad {
            // Invariant: good visible, hi not; bisect between them.
            while hi - good > 1 {
                let mid = (good + hi) / 2;
                if cs.segment_free_grid(chain[i], chain[mid]) {
                    good = mid;
                } else {
                    hi = mid;
                }
            }
        } else if good < last && cs.segment_free_grid(chain[i], chain[last]) {
            good = last;
        }
        out.push(chain[good]);
        i = good;
    }
    out
}
