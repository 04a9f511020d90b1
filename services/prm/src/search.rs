//! Shortest paths on a roadmap: Dijkstra and A* over a compressed adjacency (CSR) graph.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Which shortest-path algorithm a query uses. Both return a shortest roadmap path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum SearchAlgorithm {
    /// Dijkstra's algorithm, as in the paper.
    Dijkstra,
    /// A* with the straight-line distance to the goal (admissible, so still optimal).
    #[default]
    AStar,
}

/// An undirected weighted graph in compressed sparse row form.
#[derive(Debug, Clone, Default)]
pub(crate) struct Csr {
    /// `targets[offsets[i]..offsets[i+1]]` are the neighbours of i.
    pub offsets: Vec<u32>,
    pub targets: Vec<u32>,
    pub weights: Vec<f64>,
    /// Per edge slot: the smallest centre-to-centre obstacle distance (cells) over the cells the
    /// edge's segment touches, or NaN when not computed (edges made for one query only).
    pub min_dist: Vec<f32>,
}

/// An undirected edge: ends, length (cells) and smallest obstacle distance along it (cells;
/// NaN when unknown).
pub(crate) type Edge = (u32, u32, f64, f32);

impl Csr {
    /// Builds from an undirected edge list over `n` nodes (each edge stored in both directions).
    pub fn from_edges(n: usize, edges: &[Edge]) -> Self {
        let mut degree = vec![0u32; n + 1];
        for &(a, b, _, _) in edges {
            degree[a as usize] += 1;
            degree[b as usize] += 1;
        }
        let mut offsets = Vec::with_capacity(n + 1);
        let mut acc = 0u32;
        for d in &degree[..n] {
            offsets.push(acc);
            acc += d;
        }
        offsets.push(acc);
        let mut fill: Vec<u32> = offsets[..n].to_vec();
        let mut targets = vec![0u32; acc as usize];
        let mut weights = vec![0f64; acc as usize];
        let mut min_dist = vec![f32::NAN; acc as usize];
        for &(a, b, w, c) in edges {
            for (from, to) in [(a, b), (b, a)] {
                let slot = &mut fill[from as usize];
                targets[*slot as usize] = to;
                weights[*slot as usize] = w;
                min_dist[*slot as usize] = c;
                *slot += 1;
            }
        }
        Self {
            offsets,
            targets,
            weights,
            min_dist,
        }
    }

    pub fn node_count(&self) -> usize {
        self.offsets.len() - 1
    }

    fn slots(&self, i: u32) -> std::ops::Range<usize> {
        self.offsets[i as usize] as usize..self.offsets[i as usize + 1] as usize
    }

    pub fn neighbours(&self, i: u32) -> impl Iterator<Item = (u32, f64)> + '_ {
        let r = self.slots(i);
        self.targets[r.clone()]
            .iter()
            .copied()
            .zip(self.weights[r].iter().copied())
    }

    /// Every edge once (lower id first), with its length and obstacle distance.
    pub fn edges(&self) -> impl Iterator<Item = Edge> + '_ {
        (0..self.node_count() as u32).flat_map(move |i| {
            self.slots(i)
                .filter(move |&k| i < self.targets[k])
                .map(move |k| (i, self.targets[k], self.weights[k], self.min_dist[k]))
        })
    }

    /// The undirected graph with an edge wherever either direction has one (for connectivity:
    /// a reweighted roadmap may keep an edge one way only).
    pub fn symmetric_closure(&self) -> Csr {
        let mut pairs: Vec<Edge> = (0..self.node_count() as u32)
            .flat_map(|i| {
                self.slots(i).map(move |k| {
                    let j = self.targets[k];
                    (i.min(j), i.max(j), self.weights[k], self.min_dist[k])
                })
            })
            .collect();
        pairs.sort_by_key(|e| (e.0, e.1));
        pairs.dedup_by_key(|e| (e.0, e.1));
        Csr::from_edges(self.node_count(), &pairs)
    }

    /// The stored obstacle distance of edge a–b; NaN when unknown or when there is no such edge.
    pub fn edge_min_dist(&self, a: u32, b: u32) -> f32 {
        if a as usize >= self.node_count() || b as usize >= self.node_count() {
            return f32::NAN;
        }
        self.slots(a)
            .find(|&k| self.targets[k] == b)
            .map_or(f32::NAN, |k| self.min_dist[k])
    }
}

#[derive(Clone, Copy, PartialEq)]
struct Entry {
    f: f64,
    /// The label the node had when pushed: an entry whose label is no longer the node's is stale.
    g: f64,
    node: u32,
}
impl Eq for Entry {}
impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        // Min-heap on f; ties broken on the node id so results never depend on heap internals.
        other
            .f
            .total_cmp(&self.f)
            .then_with(|| other.node.cmp(&self.node))
            .then_with(|| other.g.total_cmp(&self.g))
    }
}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Result of one search: node sequence from S to G (both virtual ids included) and its cost (its
/// length on a geometric roadmap; plans measure their length from the points).
pub(crate) struct Found {
    pub nodes: Vec<u32>,
    #[cfg_attr(
        not(test),
        allow(dead_code, reason = "the tests check optimality with it")
    )]
    pub length: f64,
}

/// Shortest path from a virtual start S (id n) to a virtual goal G (id n+1) joined to graph nodes
/// by links, as Dijkstra or A*. A query checks the links lazily, so a link may turn out blocked
/// during or after the search; it is withdrawn at a moment when only one label derives from it
/// (a start link before its node is expanded, a goal link after the path ending with it is
/// found), and the search resumes instead of starting over. The buffers are allocated once
/// per query and reused across resumptions.
pub(crate) struct Search<'g, H> {
    g: &'g Csr,
    h: H,
    astar: bool,
    start_links: Vec<(u32, f64)>,
    /// Cheapest goal link per node (infinite where none), and the nodes that have one.
    goal_cost: Vec<f64>,
    goal_nodes: Vec<u32>,
    dist: Vec<f64>,
    prev: Vec<u32>,
    closed: Vec<bool>,
    heap: BinaryHeap<Entry>,
    /// The extra cost of an edge for the label it leaves from: `delay(u, v, g_u)`, infinite
    /// where the edge cannot be taken then (a route timed among others' reservations).
    delay: Option<Delay<'g>>,
    /// Nodes expanded so far, over every resumption.
    pub expanded: usize,
}

/// What an edge `u → v` costs beyond its weight when `u` is reached at cost `g_u` (the start is
/// node `n`, the goal `n + 1`): waiting there for the way to clear, as a cost.
pub(crate) type Delay<'g> = &'g dyn Fn(u32, u32, f64) -> f64;

impl<'g, H: Fn(u32) -> f64> Search<'g, H> {
    /// A search over `g`; `h(i)` is the heuristic of node i (ignored for Dijkstra), which must be
    /// consistent for A* (the straight-line distance to the goal is).
    pub fn new(
        g: &'g Csr,
        start_links: &[(u32, f64)],
        goal_links: &[(u32, f64)],
        algorithm: SearchAlgorithm,
        h: H,
    ) -> Self {
        Self::timed(g, start_links, goal_links, algorithm, h, None)
    }

    /// [`Search::new`] with each edge's cost raised by `delay` for the label it leaves from.
    /// The delays must not let a later label arrive sooner (waiting is allowed, so leaving
    /// later never arrives earlier), and the result is the route that arrives first.
    pub fn timed(
        g: &'g Csr,
        start_links: &[(u32, f64)],
        goal_links: &[(u32, f64)],
        algorithm: SearchAlgorithm,
        h: H,
        delay: Option<Delay<'g>>,
    ) -> Self {
        let n = g.node_count();
        let mut goal_cost = vec![f64::INFINITY; n];
        let mut goal_nodes = Vec::with_capacity(goal_links.len());
        for &(j, w) in goal_links {
            if goal_cost[j as usize].is_infinite() {
                goal_nodes.push(j);
            }
            goal_cost[j as usize] = goal_cost[j as usize].min(w);
        }
        let mut s = Self {
            g,
            h,
            astar: algorithm == SearchAlgorithm::AStar,
            start_links: start_links.to_vec(),
            goal_cost,
            goal_nodes,
            dist: vec![f64::INFINITY; n + 2],
            prev: vec![u32::MAX; n + 2],
            closed: vec![false; n + 2],
            heap: BinaryHeap::with_capacity(64),
            delay,
            expanded: 0,
        };
        let start = n as u32;
        s.dist[n] = 0.0;
        s.closed[n] = true;
        s.expanded = 1;
        for k in 0..s.start_links.len() {
            let (j, w) = s.start_links[k];
            s.relax(start, j, w);
        }
        s
    }

    /// The start links not withdrawn.
    pub fn start_links(&self) -> &[(u32, f64)] {
        &self.start_links
    }
    /// How many start links are not withdrawn.
    pub fn start_links_left(&self) -> usize {
        self.start_links.len()
    }

    fn start(&self) -> u32 {
        self.g.node_count() as u32
    }
    fn goal(&self) -> u32 {
        self.g.node_count() as u32 + 1
    }

    fn heuristic(&self, i: u32) -> f64 {
        if self.astar && i < self.start() {
            (self.h)(i)
        } else {
            0.0
        }
    }

    fn relax(&mut self, u: u32, v: u32, w: f64) {
        let from = self.dist[u as usize];
        let nd = from + w + self.delay.map_or(0.0, |d| d(u, v, from));
        if nd < self.dist[v as usize] {
            self.dist[v as usize] = nd;
            self.prev[v as usize] = u;
            self.heap.push(Entry {
                f: nd + self.heuristic(v),
                g: nd,
                node: v,
            });
        }
    }

    /// Continues the search to the goal: the shortest path over the links not withdrawn, or
    /// `None` when the goal cannot be reached through them.
    ///
    /// `start_link_free(i)` is asked about the start link to node i when i is about to be
    /// expanded with that link as its label: a blocked link is withdrawn there, before anything
    /// was derived from it, so only i's own label is redone. Goal links are left to the caller
    /// (see [`Search::withdraw_goal`]): only the one the path ends with needs checking.
    pub fn run(&mut self, mut start_link_free: impl FnMut(u32) -> bool) -> Option<Found> {
        let (start, goal) = (self.start(), self.goal());
        while !self.closed[goal as usize] {
            let Entry { node: u, g, .. } = self.heap.pop()?;
            if self.closed[u as usize] || g != self.dist[u as usize] {
                continue; // Superseded or withdrawn label.
            }
            if self.prev[u as usize] == start && !start_link_free(u) {
                self.start_links.retain(|l| l.0 != u);
                self.relabel(u);
                continue;
            }
            self.closed[u as usize] = true;
            self.expanded += 1;
            if u == goal {
                break;
            }
            let (lo, hi) = (
                self.g.offsets[u as usize] as usize,
                self.g.offsets[u as usize + 1] as usize,
            );
            for k in lo..hi {
                let v = self.g.targets[k];
                if !self.closed[v as usize] {
                    self.relax(u, v, self.g.weights[k]);
                }
            }
            let gc = self.goal_cost[u as usize];
            if gc.is_finite() {
                self.relax(u, goal, gc);
            }
        }
        let mut nodes = vec![goal];
        let mut cur = goal;
        while cur != start {
            cur = self.prev[cur as usize];
            nodes.push(cur);
        }
        nodes.reverse();
        Some(Found {
            nodes,
            length: self.dist[goal as usize],
        })
    }

    /// Withdraws the goal link from node `j` after [`Search::run`] returned a path ending with
    /// it. The goal is the only label derived from it; it is redone from the settled nodes with
    /// a goal link, and the next `run` resumes with the same answer as a fresh search without
    /// that link.
    pub fn withdraw_goal(&mut self, j: u32) {
        self.goal_cost[j as usize] = f64::INFINITY;
        self.goal_nodes.retain(|&x| x != j);
        let goal = self.goal();
        if self.prev[goal as usize] == j {
            self.closed[goal as usize] = false;
            self.relabel(goal);
        }
    }

    /// Recomputes the label of open node v, none of whose descendants has a label, from the
    /// settled nodes: the start's links, closed neighbours and, for the goal, closed nodes with
    /// a goal link. Entries left in the heap for its old label are skipped as stale.
    fn relabel(&mut self, v: u32) {
        self.dist[v as usize] = f64::INFINITY;
        self.prev[v as usize] = u32::MAX;
        let (start, goal) = (self.start(), self.goal());
        if v == goal {
            for k in 0..self.goal_nodes.len() {
                let j = self.goal_nodes[k];
                if self.closed[j as usize] {
                    self.relax(j, goal, self.goal_cost[j as usize]);
                }
            }
            return;
        }
        for k in 0..self.start_links.len() {
            let (j, w) = self.start_links[k];
            if j == v {
                self.relax(start, v, w);
            }
        }
        let (lo, hi) = (
            self.g.offsets[v as usize] as usize,
            self.g.offsets[v as usize + 1] as usize,
        );
        for k in lo..hi {
            let u = self.g.targets[k];
            if self.closed[u as usize] {
                self.relax(u, v, self.g.weights[k]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shortest(
        g: &Csr,
        sl: &[(u32, f64)],
        gl: &[(u32, f64)],
        alg: SearchAlgorithm,
        h: impl Fn(u32) -> f64,
    ) -> Option<Found> {
        Search::new(g, sl, gl, alg, h).run(|_| true)
    }

    #[test]
    fn dijkstra_and_astar_agree_on_a_small_graph() {
        // 0 - 1 - 2 with a costly shortcut 0 - 2.
        let g = Csr::from_edges(
            3,
            &[
                (0, 1, 1.0, f32::NAN),
                (1, 2, 1.0, f32::NAN),
                (0, 2, 5.0, f32::NAN),
            ],
        );
        for alg in [SearchAlgorithm::Dijkstra, SearchAlgorithm::AStar] {
            let found = shortest(&g, &[(0, 0.5)], &[(2, 0.5)], alg, |_| 0.0).expect("path");
            assert_eq!(found.nodes, vec![3, 0, 1, 2, 4]);
            assert!((found.length - 3.0).abs() < 1e-12);
        }
    }

    #[test]
    fn disconnected_graph_has_no_path() {
        let g = Csr::from_edges(2, &[]);
        assert!(
            shortest(&g, &[(0, 1.0)], &[(1, 1.0)], SearchAlgorithm::AStar, |_| {
                0.0
            })
            .is_none()
        );
    }

    #[test]
    fn edges_keep_their_obstacle_distance_both_ways() {
        let g = Csr::from_edges(3, &[(0, 1, 1.0, 2.5), (1, 2, 1.0, f32::NAN)]);
        assert_eq!(g.edge_min_dist(0, 1), 2.5);
        assert_eq!(g.edge_min_dist(1, 0), 2.5);
        assert!(g.edge_min_dist(1, 2).is_nan());
        assert!(g.edge_min_dist(0, 2).is_nan());
        assert!(g.edge_min_dist(0, 7).is_nan());
        let edges: Vec<_> = g.edges().map(|e| (e.0, e.1)).collect();
        assert_eq!(edges, vec![(0, 1), (1, 2)]);
    }

    /// Start links refused when their node is expanded, and goal links withdrawn after each
    /// path, give at every step the length a fresh search over the remaining links gives: the
    /// lazy query relies on it.
    #[test]
    fn resuming_after_withdrawals_equals_searching_afresh() {
        let mut state = 99u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state >> 33
        };
        let (mut refused, mut withdrawn) = (0, 0);
        for trial in 0..400 {
            let n = 5 + (next() % 60) as usize;
            let pos: Vec<[f64; 2]> = (0..n)
                .map(|_| [(next() % 1000) as f64 / 10.0, (next() % 1000) as f64 / 10.0])
                .collect();
            let d =
                |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
            let mut edges = Vec::new();
            for a in 0..n as u32 {
                for _ in 0..3 {
                    let b = (next() % n as u64) as u32;
                    if a != b {
                        edges.push((a, b, d(pos[a as usize], pos[b as usize]), f32::NAN));
                    }
                }
            }
            let g = Csr::from_edges(n, &edges);
            let (s, t) = ([50.0, 0.0], [50.0, 100.0]);
            let links = |p: [f64; 2], k: u64| -> Vec<(u32, f64)> {
                let mut v: Vec<u32> = (0..n as u32).collect();
                v.sort_by(|&a, &b| d(pos[a as usize], p).total_cmp(&d(pos[b as usize], p)));
                v.truncate(k as usize);
                v.into_iter().map(|j| (j, d(pos[j as usize], p))).collect()
            };
            let sl = links(s, 1 + next() % 8);
            let mut gl = links(t, 1 + next() % 8);
            // Each start link blocked with probability 1/3.
            let blocked: Vec<u32> = sl.iter().map(|l| l.0).filter(|_| next() % 3 == 0).collect();
            let free_sl: Vec<(u32, f64)> = sl
                .iter()
                .copied()
                .filter(|l| !blocked.contains(&l.0))
                .collect();
            let alg = if trial % 2 == 0 {
                SearchAlgorithm::AStar
            } else {
                SearchAlgorithm::Dijkstra
            };
            let h = |i: u32| d(pos[i as usize], t);
            let mut search = Search::new(&g, &sl, &gl, alg, h);
            loop {
                let fresh = shortest(&g, &free_sl, &gl, alg, h);
                let resumed = search.run(|i| {
                    let ok = !blocked.contains(&i);
                    refused += usize::from(!ok);
                    ok
                });
                assert_eq!(
                    fresh.as_ref().map(|f| f.length),
                    resumed.as_ref().map(|f| f.length),
                    "trial {trial}"
                );
                let Some(found) = resumed else { break };
                assert!(!blocked.contains(&found.nodes[1]), "trial {trial}");
                let len: f64 = found
                    .nodes
                    .windows(2)
                    .map(|w| match (w[0] as usize, w[1] as usize) {
                        (a, b) if a == n => d(s, pos[b]),
                        (a, b) if b == n + 1 => d(pos[a], t),
                        (a, b) => d(pos[a], pos[b]),
                    })
                    .sum();
                assert!((len - found.length).abs() < 1e-9, "trial {trial}");
                let last = found.nodes[found.nodes.len() - 2];
                gl.retain(|l| l.0 != last);
                if gl.is_empty() {
                    break;
                }
                search.withdraw_goal(last);
                withdrawn += 1;
            }
        }
        assert!(refused > 100 && withdrawn > 300, "{refused} {withdrawn}");
    }
}
