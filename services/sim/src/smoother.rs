//! A path smoother for roadmap paths, after Nav2's Simple Smoother (`nav2_smoother`,
//! `SimpleSmoother`; parameters from its configuration page, docs.nav2.org
//! "Simple Smoother"): the path is densified to the map's resolution, then each interior point
//! is moved, by gradient descent, towards the original path (`w_data`) and towards the
//! midpoint of its neighbours (`w_smooth`) until the total change of an iteration falls under
//! `tolerance` or `max_its` iterations ran. Where Nav2 checks the costmap and refuses a point in
//! collision, this checks the world's footprint clearance: a point may not move where the
//! footprint would keep less clearance than `min_clearance_m` (or than the original point
//! kept, where that was less), so smoothing never takes a path closer to a wall than the
//! roadmap allowed. The end points stay fixed. Nav2's `do_refinement` (smoothing the smoothed
//! path again, `refinement_num` times) is kept.
//!
//! Written from the documented behaviour and parameters, not from Nav2's code.

use crate::World;

/// Settings of the smoother; [`SmootherParams::default`] gives Nav2's defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmootherParams {
    /// Weight pulling each point back to the original path (Nav2 `w_data`, default 0.2).
    pub w_data: f64,
    /// Weight pulling each point to its neighbours' midpoint (Nav2 `w_smooth`, default 0.3).
    pub w_smooth: f64,
    /// Stop when an iteration moves the points by less than this in total (Nav2
    /// `tolerance`, default 1e-10).
    pub tolerance: f64,
    /// Most iterations per pass (Nav2 `max_its`, default 1000).
    pub max_its: usize,
    /// Further passes over the smoothed path (Nav2 `do_refinement: true`, `refinement_num: 2`).
    pub refinement_num: usize,
    /// Spacing of the densified path, metres: Nav2 smooths the planner's path, one point per
    /// costmap cell; 0 takes the world's resolution.
    pub spacing_m: f64,
    /// Footprint clearance a moved point must keep, metres (the roadmap's safety margin: the
    /// smoothed path keeps what the roadmap kept).
    pub min_clearance_m: f64,
}

impl Default for SmootherParams {
    fn default() -> Self {
        Self {
            w_data: 0.2,
            w_smooth: 0.3,
            tolerance: 1e-10,
            max_its: 1000,
            refinement_num: 2,
            spacing_m: 0.0,
            min_clearance_m: 0.1,
        }
    }
}

/// `path` with points inserted so no two consecutive ones are more than `spacing` apart.
pub fn densify(path: &[(f64, f64)], spacing: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(path.len());
    let Some(&first) = path.first() else {
        return out;
    };
    out.push(first);
    for w in path.windows(2) {
        let (a, b) = (w[0], w[1]);
        let d = crate::norm(b.0 - a.0, b.1 - a.1);
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a map-sized distance over a positive spacing: a small positive count"
        )]
        let n = ((d / spacing.max(1e-3)).ceil() as usize).max(1);
        for k in 1..=n {
            let t = k as f64 / n as f64;
            out.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
        }
    }
    out
}

/// The smoothed, densified path through `path` in `world` (see the module docs). Paths of
/// fewer than three points after densifying come back densified only.
pub fn smooth_path(world: &World, path: &[(f64, f64)], p: &SmootherParams) -> Vec<(f64, f64)> {
    let spacing = if p.spacing_m > 0.0 {
        p.spacing_m
    } else {
        world.resolution()
    };
    let original = densify(path, spacing);
    if original.len() < 3 {
        return original;
    }
    // A lower bound on each point's clearance where it stands (see `smooth_pass`), and what
    // each point may not go below: the margin, or what the original point had.
    let mut bound: Vec<f64> = original.iter().map(|q| world.clearance(q.0, q.1)).collect();
    let floor: Vec<f64> = bound.iter().map(|c| c.min(p.min_clearance_m)).collect();
    let mut current = original.clone();
    let slack = world.resolution();
    for _ in 0..=p.refinement_num {
        let reference = current.clone();
        smooth_pass(
            world,
            &reference,
            &mut current,
            &floor,
            &mut bound,
            slack,
            p,
        );
    }
    current
}

/// One pass of the gradient descent of `current` towards `reference` and towards smoothness.
///
/// Clearance changes by at most the distance moved (it is a distance to the nearest obstacle),
/// so a point whose lower bound `bound[i]` stays above its floor after a move of `d` needs no
/// query: its bound becomes `bound[i] - d`. Only a point whose bound would come within `slack`
/// (one map cell: the grid's distance is exact to within it) of its floor is queried. The
/// result is the exhaustive check's, at a fraction of the queries: most of a roadmap path runs
/// well clear of walls.
fn smooth_pass(
    world: &World,
    reference: &[(f64, f64)],
    current: &mut [(f64, f64)],
    floor: &[f64],
    bound: &mut [f64],
    slack: f64,
    p: &SmootherParams,
) {
    let n = current.len();
    for _ in 0..p.max_its {
        let mut change = 0.0;
        for i in 1..n - 1 {
            let (x, y) = current[i];
            let (px, py) = current[i - 1];
            let (nx, ny) = current[i + 1];
            let (ox, oy) = reference[i];
            let x2 = x + p.w_data * (ox - x) + p.w_smooth * (px + nx - 2.0 * x);
            let y2 = y + p.w_data * (oy - y) + p.w_smooth * (py + ny - 2.0 * y);
            let (dx, dy) = (x2 - x, y2 - y);
            let moved = (dx * dx + dy * dy).sqrt();
            let kept = bound[i] - moved;
            if kept >= floor[i] + slack {
                bound[i] = kept;
            } else {
                let c = world.clearance(x2, y2);
                if c < floor[i] {
                    continue;
                }
                bound[i] = c;
            }
            change += dx.abs() + dy.abs();
            current[i] = (x2, y2);
        }
        if change < p.tolerance {
            break;
        }
    }
}

/// Sum of the absolute turning angles along `path`, radians (a measure of how curved it is).
pub fn total_turning(path: &[(f64, f64)]) -> f64 {
    path.windows(3)
        .map(|w| {
            let a = (w[1].1 - w[0].1).atan2(w[1].0 - w[0].0);
            let b = (w[2].1 - w[1].1).atan2(w[2].0 - w[1].0);
            crate::kinematics::wrap_angle(b - a).abs()
        })
        .sum()
}

/// Largest turning angle between consecutive segments of `path`, radians.
pub fn max_turning(path: &[(f64, f64)]) -> f64 {
    path.windows(3)
        .map(|w| {
            let a = (w[1].1 - w[0].1).atan2(w[1].0 - w[0].0);
            let b = (w[2].1 - w[1].1).atan2(w[2].0 - w[1].0);
            crate::kinematics::wrap_angle(b - a).abs()
        })
        .fold(0.0, f64::max)
}
