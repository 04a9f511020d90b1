//! Bridging: joins every roadmap component to the largest one of its free region by waves over
//! the coarse grid, so that most queries need no densification.

use std::collections::HashMap;

use super::build::UnionFind;
use super::shortcut::thin_line_of_sight;
use super::waves::CellTables;
use super::{BuildStats, dist};
use crate::cspace::{CoarseGrid, ConfigSpace};

/// Cells the bridging flood may visit per build; it bounds the build time on large cluttered
/// maps at the price of leaving the longest gaps to query-time densification.
const FLOOD_CELL_BUDGET: usize = 4_000_000;

/// Joins every roadmap component to the largest one of its free region: waves grow over the
/// coarse grid from the other components' nodes until they touch another component; each
/// meeting becomes a chain of blocks, thinned to straight segments, whose corners are added as
/// nodes. Components are grouped by the coarse region (4-connected free blocks) of their
/// nodes' blocks, which is all a wave can cross: per coarse region, the component with the
/// most nodes waits and the others radiate, and a wave stops growing once its component has
/// joined the waiting one. So the flood stays local to the gaps it closes, and it ends as soon
/// as every component that can be joined is, rather than filling the region looking for
/// components no wave can reach (those behind gaps narrower than a block are left to
/// query-time densification).
pub(super) fn bridge_components(
    cs: &ConfigSpace,
    nodes: &mut Vec<[f64; 2]>,
    adj: &mut Vec<Vec<(u32, f64)>>,
    uf: &mut UnionFind,
    stats: &mut BuildStats,
) {
    // The flood runs on the coarse grid (factor² fewer cells). A block is entirely free, so a
    // node reaches its block's centre in a straight line and 4-adjacent block centres see each
    // other. Gaps narrower than a block are left to query-time densification.
    let g = &cs.coarse;
    let Some(mut waves) = Waves::plan(g, nodes, uf) else {
        return;
    };
    let chains = CellTables::with(g.width * g.height, |t| waves.flood(t, uf, stats));
    add_chains(cs, chains, nodes, adj, uf, stats);
}

/// The [`CellTables`] table of a block's label: the node whose wave reached it, plus 1.
const LABEL: usize = 0;
/// The table of a block's parent: the block the wave came from, plus 1 (itself for a seed).
const PARENT: usize = 2;

/// The bridging flood over the coarse grid: where each node is and which component its wave
/// waits for.
struct Waves<'g> {
    g: &'g CoarseGrid,
    /// Per node, its block when that block is free.
    blocks: Vec<Option<usize>>,
    /// Per node, a node of the component its coarse region's flood waits for (u32::MAX when
    /// its region has nothing to join).
    waits_for: Vec<u32>,
    /// Joins still to make: every component of a coarse region but its waiting one.
    remaining: usize,
}

/// Where two components met.
enum Meeting {
    /// Both have a node in one free block: the block's first node and the other component's.
    InBlock { block: usize, node: u32 },
    /// Their waves touched between the 4-adjacent blocks `from` and `to`.
    Waves { from: usize, to: usize },
}

/// A bridge to add: the blocks from a node of one component to a node of another.
struct Chain {
    from: u32,
    to: u32,
    blocks: Vec<usize>,
}

impl<'g> Waves<'g> {
    /// Groups the components by coarse region and picks the one each region's flood waits
    /// for; `None` when no region holds two components.
    fn plan(g: &'g CoarseGrid, nodes: &[[f64; 2]], uf: &mut UnionFind) -> Option<Self> {
        let n = nodes.len();
        let f = g.factor;
        let block_of = |p: [f64; 2]| {
            let (bx, by) = ((p[0] / f as f64) as usize, (p[1] / f as f64) as usize);
            (bx < g.width && by < g.height && g.free[by * g.width + bx])
                .then_some(by * g.width + bx)
        };
        let blocks: Vec<Option<usize>> = nodes.iter().map(|&p| block_of(p)).collect();
        // Per coarse region: node count per component root.
        let mut sizes: HashMap<(u32, u32), usize> = HashMap::new();
        for i in 0..n as u32 {
            if let Some(b) = blocks[i as usize] {
                *sizes.entry((g.region[b], uf.find(i))).or_default() += 1;
            }
        }
        // Coarse region -> (size, root) of the component that waits.
        let mut largest: HashMap<u32, (usize, u32)> = HashMap::new();
        let mut roots_in: HashMap<u32, usize> = HashMap::new();
        for (&(region, root), &size) in &sizes {
            *roots_in.entry(region).or_default() += 1;
            let e = largest.entry(region).or_insert((size, root));
            // Ties broken on the root id: HashMap order must not decide.
            if (size, std::cmp::Reverse(root)) > (e.0, std::cmp::Reverse(e.1)) {
                *e = (size, root);
            }
        }
        let remaining: usize = roots_in.values().map(|&k| k - 1).sum();
        if remaining == 0 {
            return None;
        }
        let waits_for: Vec<u32> = blocks
            .iter()
            .map(|b| {
                b.map(|b| g.region[b])
                    .filter(|r| roots_in.get(r).copied().unwrap_or(0) >= 2)
                    .and_then(|r| largest.get(&r))
                    .map_or(u32::MAX, |&(_, root)| root)
            })
            .collect();
        Some(Self {
            g,
            blocks,
            waits_for,
            remaining,
        })
    }

    /// Runs the flood on the tables `t`: seeds, then waves grown until every component that
    /// can be is joined (or the cell budget is spent); the chains of blocks to add.
    fn flood(
        &mut self,
        t: &mut CellTables,
        uf: &mut UnionFind,
        stats: &mut BuildStats,
    ) -> Vec<Chain> {
        // Breadth-first, level by level: a plain vector read from the front.
        let mut queue: Vec<u32> = Vec::new();
        let mut meetings = Vec::new();
        self.seed(t, uf, &mut queue, &mut meetings);
        let head = self.grow(t, uf, &mut queue, &mut meetings);
        stats.flood_blocks += head;
        chains(t, meetings)
    }

    /// Labels every node's block with the node (the first one, when several share it), and
    /// queues the blocks of the components that do not wait; two components in one block are
    /// joined there directly.
    fn seed(
        &mut self,
        t: &mut CellTables,
        uf: &mut UnionFind,
        queue: &mut Vec<u32>,
        meetings: &mut Vec<Meeting>,
    ) {
        for i in 0..self.blocks.len() as u32 {
            let (Some(b), w) = (self.blocks[i as usize], self.waits_for[i as usize]) else {
                continue;
            };
            if w == u32::MAX {
                continue;
            }
            let label = t.get(LABEL, b);
            if label == 0 {
                t.set(LABEL, b, i + 1);
                t.set(PARENT, b, b as u32 + 1);
                // The region's largest component waits for the others to reach it.
                if uf.find(i) != uf.find(w) {
                    queue.push(b as u32);
                }
            } else if uf.find(label - 1) != uf.find(i) {
                // Two components in one free block: the block joins them directly.
                uf.union(label - 1, i);
                meetings.push(Meeting::InBlock { block: b, node: i });
                self.remaining -= 1;
            }
        }
    }

    /// Grows the waves breadth-first from `queue`, joining components where they touch; a
    /// wave stops once its component has joined the one it waits for. Returns how many blocks
    /// it expanded.
    fn grow(
        &mut self,
        t: &mut CellTables,
        uf: &mut UnionFind,
        queue: &mut Vec<u32>,
        meetings: &mut Vec<Meeting>,
    ) -> usize {
        let g = self.g;
        let gw = g.width;
        let mut head = 0;
        'flood: while head < queue.len() && self.remaining > 0 {
            if head >= FLOOD_CELL_BUDGET {
                // Gaps still open are left to local densification at query time.
                break;
            }
            let c = queue[head] as usize;
            head += 1;
            let lc = t.get(LABEL, c);
            let mut root = uf.find(lc - 1);
            let waiting = self.waits_for[lc as usize - 1];
            if root == uf.find(waiting) {
                // Joined to the waiting component: its wave has done its work.
                continue;
            }
            // Free blocks are never on the grid's border: all four neighbours exist.
            for nc in [c - 1, c + 1, c - gw, c + gw] {
                if !g.free[nc] {
                    continue;
                }
                let ln = t.get(LABEL, nc);
                if ln == 0 {
                    t.set(LABEL, nc, lc);
                    t.set(PARENT, nc, c as u32 + 1);
                    queue.push(nc as u32);
                } else if ln != lc && root != uf.find(ln - 1) {
                    // (Most labelled neighbours belong to the same wave: the cheap test first.)
                    uf.union(lc - 1, ln - 1);
                    meetings.push(Meeting::Waves { from: c, to: nc });
                    self.remaining -= 1;
                    if self.remaining == 0 {
                        break 'flood;
                    }
                    root = uf.find(lc - 1);
                    // Joined to the waiting component: grow no further.
                    if root == uf.find(waiting) {
                        continue 'flood;
                    }
                }
            }
        }
        head
    }
}

/// The chains of blocks the meetings stand for: through the shared block, or back along both
/// waves to their seeds.
fn chains(t: &CellTables, meetings: Vec<Meeting>) -> Vec<Chain> {
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
        .map(|m| match m {
            // Both nodes in the block: through its centre.
            Meeting::InBlock { block, node } => Chain {
                from: t.get(LABEL, block) - 1,
                to: node,
                blocks: vec![block],
            },
            Meeting::Waves { from, to } => {
                let mut blocks = back(from);
                blocks.reverse();
                blocks.extend(back(to));
                Chain {
                    from: t.get(LABEL, from) - 1,
                    to: t.get(LABEL, to) - 1,
                    blocks,
                }
            }
        })
        .collect()
}

/// Adds each chain to the roadmap: thinned to straight segments, its corners become nodes
/// joined in a path from one end node to the other.
fn add_chains(
    cs: &ConfigSpace,
    chains: Vec<Chain>,
    nodes: &mut Vec<[f64; 2]>,
    adj: &mut Vec<Vec<(u32, f64)>>,
    uf: &mut UnionFind,
    stats: &mut BuildStats,
) {
    let g = &cs.coarse;
    let f = g.factor;
    // The centre of the block's middle cell, not of the block: for even factors the block
    // centre lies on a grid line, where converting to metres and back can move a horizontal
    // segment into the neighbouring row of cells.
    let centre = |b: usize| {
        [
            ((b % g.width) * f + f / 2) as f64 + 0.5,
            ((b / g.width) * f + f / 2) as f64 + 0.5,
        ]
    };
    for Chain {
        from: a,
        to: b,
        blocks: path,
    } in chains
    {
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
