//! Local densification: when the roadmap does not join a query's start and goal although free
//! space does, a grid wavefront between the parts of the roadmap they reach supplies extra
//! nodes for that query; [`Roadmap::absorb`] keeps them for later queries.

use std::sync::Arc;

use super::shortcut::thin_line_of_sight;
use super::waves::{CellTables, neighbours4};
use super::{Plan, Roadmap, components, dist, kd_tree, segment_mins};
use crate::cspace::ConfigSpace;
use crate::error::QueryError;
use crate::search::{Csr, Edge, Search, SearchAlgorithm};

impl Roadmap {
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

    /// Local densification: a grid wavefront from the part of the roadmap the start reaches
    /// (or the start itself) to the part the goal reaches; the cells it crosses, thinned to
    /// straight-line-of-sight waypoints, become extra nodes for this query. Start and goal are
    /// in one free region here, so the wavefront always arrives.
    pub(super) fn densified_query(
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
        Ok(self.plan(
            &pts,
            &mins,
            super::query::polyline_cells(&pts),
            added,
            search.expanded,
        ))
    }
}

/// Largest radius (cells) of the disc an anchor claims in local densification.
const DISC_CAP: f64 = 8.0;

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
