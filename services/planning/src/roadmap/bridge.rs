//! Bridging: joins every roadmap component to the largest one of its free region by waves over
//! the coarse grid, so that most queries need no densification.

use std::collections::HashMap;

use super::build::UnionFind;
use super::shortcut::thin_line_of_sight;
use super::waves::{CellTables, neighbours4};
use super::{BuildStats, dist};
use crate::cspace::ConfigSpace;

/// Cells the bridging flood may visit per build; it bounds the build time on large cluttered
/// maps at the price of leaving the longest gaps to query-time densification.
const FLOOD_CELL_BUDGET: usize = 4_000_000;

/// Joins every roadmap component to the largest one of its free region: waves grow over the
/// coarse grid from the other components' nodes until they touch another component; each
/// meeting becomes a chain of blocks, thinned to straight segments, whose corners are added as
/// nodes. Only the smaller components radiate, so the flood stays local to the gaps; the
/// region's largest component waits for them.
pub(super) fn bridge_components(
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
