//! Answering a query: start and goal checked and linked lazily to their nearest nodes, the
//! search, and the plan with its clearance.

use std::num::NonZeroUsize;

use kiddo::SquaredEuclidean;

use super::{Plan, QueryOptions, Roadmap, dist, segment_mins};
use crate::cspace::RegionId;
use crate::error::{Endpoint, QueryError};
use crate::map::Point2;
use crate::search::{Search, SearchAlgorithm};

/// Other robots' reservations a route is timed among (their plans in a fleet's schedule).
pub trait Reservations {
    /// How long a robot that reached `a` `t_s` seconds after setting off must wait there
    /// before it can drive straight to `b` without coming near any reservation, seconds;
    /// `None` where no wait it may take there lets it (or waiting there is in the way).
    fn wait_before(&self, a: Point2, b: Point2, t_s: f64) -> Option<f64>;
    /// The speed the robot covers a route at, turns included, m/s (positive).
    fn speed_m_s(&self) -> f64;
}

impl Roadmap {
    /// Shortest roadmap path from `start` to `goal`, densifying locally when the roadmap does
    /// not join them although free space does.
    pub fn query(
        &self,
        start: Point2,
        goal: Point2,
        opts: QueryOptions,
    ) -> Result<Plan, QueryError> {
        self.query_among(start, goal, opts, None)
    }

    /// [`Roadmap::query`] timed among `reserved`: the roadmap route that arrives first,
    /// waiting at its nodes where a reservation is in the way (the plan's length is still its
    /// length, not its time). Where the start and goal see each other, or the roadmap must be
    /// densified to join them, the route is the shortest one.
    pub fn query_among(
        &self,
        start: Point2,
        goal: Point2,
        opts: QueryOptions,
        reserved: Option<&dyn Reservations>,
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
        if let Some(plan) = self.lazy_search(gs, gg, opts.algorithm, reserved) {
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
    fn lazy_search(
        &self,
        gs: [f64; 2],
        gg: [f64; 2],
        algorithm: SearchAlgorithm,
        reserved: Option<&dyn Reservations>,
    ) -> Option<Plan> {
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
        // Costs are in cells: a second waited costs what the robot covers in it.
        let n = self.nodes.len() as u32;
        let res = self.cspace.resolution();
        let at = |i: u32| match i {
            i if i < n => self.cspace.to_world(self.nodes[i as usize]),
            i if i == n => self.cspace.to_world(gs),
            _ => self.cspace.to_world(gg),
        };
        let timing = reserved.map(|r| {
            let cells_per_s = r.speed_m_s() / res;
            move |u: u32, v: u32, g_u: f64| {
                r.wait_before(at(u), at(v), g_u / cells_per_s)
                    .map_or(f64::INFINITY, |w| w * cells_per_s)
            }
        });
        let delay = timing.as_ref().map(|t| t as &dyn Fn(u32, u32, f64) -> f64);
        let mut start_free = |i: u32| {
            let known = start_known.borrow().iter().find(|v| v.0 == i).map(|v| v.1);
            known.unwrap_or_else(|| {
                let free = self.cspace.segment_free_grid(gs, self.nodes[i as usize]);
                start_known.borrow_mut().push((i, free));
                free
            })
        };
        let mut search = Search::timed(&self.graph, &sl, &gl, algorithm, h, delay);
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
                search = Search::timed(&self.graph, &beyond, &gl, algorithm, h, delay);
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
                // The path's length, not its cost: a reweighted roadmap's weights are costs.
                return Some(self.plan(&pts, &mins, polyline_cells(&pts), 0, expanded));
            }
            gl.retain(|l| l.0 != last);
            if gl.is_empty() {
                // None of the k nearest in sight of the goal: check farther nodes eagerly.
                gl = self.links_beyond(gg, k);
                g_ok.extend(gl.iter().map(|l| l.0));
                expanded += search.expanded;
                let sl_now = search.start_links().to_vec();
                search = Search::timed(&self.graph, &sl_now, &gl, algorithm, h, delay);
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

    pub(super) fn region(&self, g: [f64; 2]) -> RegionId {
        self.cspace
            .cell_index(g)
            .map_or(0, |i| self.cspace.region[i])
    }

    /// Up to k valid edges from a query point to its nearest roadmap nodes within d_max.
    pub(super) fn links(&self, g: [f64; 2]) -> Vec<(u32, f64)> {
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
    pub(super) fn points(
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
    pub(super) fn plan(
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
}

/// Length of a polyline in grid units.
pub(super) fn polyline_cells(pts: &[[f64; 2]]) -> f64 {
    pts.windows(2).map(|w| dist(w[0], w[1])).sum()
}
