//! Line-of-sight thinning: plans without detours ([`Roadmap::shortcut`]) and chains of cells
//! reduced to the corners a straight segment cannot cut.

use super::{Plan, Roadmap, dist};
use crate::cspace::ConfigSpace;

impl Roadmap {
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
}

/// Thins a chain of points whose consecutive segments are free into fewer points whose
/// consecutive segments are still free: from each kept point, gallop then bisect to a far
/// point in straight sight.
pub(super) fn thin_line_of_sight(cs: &ConfigSpace, chain: &[[f64; 2]]) -> Vec<[f64; 2]> {
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
