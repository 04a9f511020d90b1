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
}

impl Csr {
    /// Builds from an undirected edge list over `n` nodes (each edge stored in both directions).
    pub fn from_edges(n: usize, edges: &[(u32, u32, f64)]) -> Self {
        let mut degree = vec![0u32; n + 1];
        for &(a, b, _) in edges {
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
        for &(a, b, w) in edges {
            for (from, to) in [(a, b), (b, a)] {
                let slot = &mut fill[from as usize];
                targets[*slot as usize] = to;
                weights[*slot as usize] = w;
                *slot += 1;
            }
        }
        Self {
            offsets,
            targets,
            weights,
        }
    }

    pub fn node_count(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn neighbours(&self, i: u32) -> impl Iterator<Item = (u32, f64)> + '_ {
        let (lo, hi) = (
            self.offsets[i as usize] as usize,
            self.offsets[i as usize + 1] as usize,
        );
        self.targets[lo..hi]
            .iter()
            .copied()
            .zip(self.weights[lo..hi].iter().copied())
    }
}

#[derive(Clone, Copy, PartialEq)]
struct Entry {
    f: f64,
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
    }
}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// The query's extra nodes: a virtual start S (id n) and goal G (id n+1) joined to roadmap nodes.
pub(crate) struct Terminals<'a> {
    pub start_links: &'a [(u32, f64)],
    pub goal_links: &'a [(u32, f64)],
}

/// Result of one search: node sequence from S to G (both virtual ids included) and its length.
pub(crate) struct Found {
    pub nodes: Vec<u32>,
    pub length: f64,
    pub expanded: usize,
}

/// Shortest path from the virtual start to the virtual goal; `h(i)` is the heuristic of node i
/// (ignored for Dijkstra).
pub(crate) fn shortest_path(
    g: &Csr,
    t: &Terminals<'_>,
    algorithm: SearchAlgorithm,
    h: impl Fn(u32) -> f64,
) -> Option<Found> {
    let n = g.node_count();
    let (s, goal) = (n as u32, n as u32 + 1);
    let mut dist = vec![f64::INFINITY; n + 2];
    let mut prev = vec![u32::MAX; n + 2];
    let mut closed = vec![false; n + 2];
    // Goal links indexed by node for O(1) lookup while expanding.
    let mut goal_cost = vec![f64::INFINITY; n];
    for &(j, w) in t.goal_links {
        goal_cost[j as usize] = goal_cost[j as usize].min(w);
    }
    let heur = |i: u32| match algorithm {
        SearchAlgorithm::Dijkstra => 0.0,
        SearchAlgorithm::AStar if i >= s => 0.0,
        SearchAlgorithm::AStar => h(i),
    };
    let mut heap = BinaryHeap::with_capacity(64);
    dist[s as usize] = 0.0;
    heap.push(Entry { f: 0.0, node: s });
    let mut expanded = 0usize;
    while let Some(Entry { node: u, .. }) = heap.pop() {
        if closed[u as usize] {
            continue;
        }
        closed[u as usize] = true;
        expanded += 1;
        if u == goal {
            let mut nodes = vec![goal];
            let mut cur = goal;
            while cur != s {
                cur = prev[cur as usize];
                nodes.push(cur);
            }
            nodes.reverse();
            return Some(Found {
                nodes,
                length: dist[goal as usize],
                expanded,
            });
        }
        let du = dist[u as usize];
        let mut relax = |v: u32, w: f64, heap: &mut BinaryHeap<Entry>| {
            let nd = du + w;
            if nd < dist[v as usize] {
                dist[v as usize] = nd;
                prev[v as usize] = u;
                heap.push(Entry {
                    f: nd + heur(v),
                    node: v,
                });
            }
        };
        if u == s {
            for &(j, w) in t.start_links {
                relax(j, w, &mut heap);
            }
            continue;
        }
        for (v, w) in g.neighbours(u) {
            if !closed[v as usize] {
                relax(v, w, &mut heap);
            }
        }
        let gc = goal_cost[u as usize];
        if gc.is_finite() {
            relax(goal, gc, &mut heap);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dijkstra_and_astar_agree_on_a_small_graph() {
        // 0 - 1 - 2 with a costly shortcut 0 - 2.
        let g = Csr::from_edges(3, &[(0, 1, 1.0), (1, 2, 1.0), (0, 2, 5.0)]);
        let t = Terminals {
            start_links: &[(0, 0.5)],
            goal_links: &[(2, 0.5)],
        };
        for alg in [SearchAlgorithm::Dijkstra, SearchAlgorithm::AStar] {
            let found = shortest_path(&g, &t, alg, |_| 0.0).expect("path");
            assert_eq!(found.nodes, vec![3, 0, 1, 2, 4]);
            assert!((found.length - 3.0).abs() < 1e-12);
        }
    }

    #[test]
    fn disconnected_graph_has_no_path() {
        let g = Csr::from_edges(2, &[]);
        let t = Terminals {
            start_links: &[(0, 1.0)],
            goal_links: &[(1, 1.0)],
        };
        assert!(shortest_path(&g, &t, SearchAlgorithm::AStar, |_| 0.0).is_none());
    }
}
