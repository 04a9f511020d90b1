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
    match prepare(world, path, p) {
        Err(short) => short,
        Ok((original, bound, floor)) => match solve_direct(world, &original, &floor, p) {
            Some(solved) => solved,
            None => descend(world, original, bound, &floor, p),
        },
    }
}

/// [`smooth_path`] by the gradient descent alone, never solved directly: what it falls back to
/// where a point's clearance stops the smoothing (public so tests and benchmarks can compare).
pub fn smooth_path_by_descent(
    world: &World,
    path: &[(f64, f64)],
    p: &SmootherParams,
) -> Vec<(f64, f64)> {
    match prepare(world, path, p) {
        Err(short) => short,
        Ok((original, bound, floor)) => descend(world, original, bound, &floor, p),
    }
}

/// A smoothed path's inputs: the densified path, a lower bound on each point's clearance where
/// it stands (see `smooth_pass`), and what each point may not go below (the margin, or what
/// the original point had). `Err` with the densified path when it has fewer than three points.
#[allow(
    clippy::type_complexity,
    reason = "a private triple, named in the docs"
)]
fn prepare(
    world: &World,
    path: &[(f64, f64)],
    p: &SmootherParams,
) -> Result<(Vec<(f64, f64)>, Vec<f64>, Vec<f64>), Vec<(f64, f64)>> {
    let spacing = if p.spacing_m > 0.0 {
        p.spacing_m
    } else {
        world.resolution()
    };
    let original = densify(path, spacing);
    if original.len() < 3 {
        return Err(original);
    }
    let bound: Vec<f64> = original.iter().map(|q| world.clearance(q.0, q.1)).collect();
    let floor: Vec<f64> = bound.iter().map(|c| c.min(p.min_clearance_m)).collect();
    Ok((original, bound, floor))
}

/// The descent's passes from the densified `original`.
fn descend(
    world: &World,
    original: Vec<(f64, f64)>,
    mut bound: Vec<f64>,
    floor: &[f64],
    p: &SmootherParams,
) -> Vec<(f64, f64)> {
    let mut current = original;
    let slack = world.resolution();
    for _ in 0..=p.refinement_num {
        let reference = current.clone();
        smooth_pass(world, &reference, &mut current, floor, &mut bound, slack, p);
    }
    current
}

/// Where the descent converges, solved directly, when no point's clearance stops it.
///
/// Without the clearance check, a pass of the descent converges to the solution of a
/// tridiagonal system (each interior point where the pull back to the reference and the pull to
/// its neighbours' midpoint cancel: `w_data (o_i - x_i) + w_smooth (x_{i-1} + x_{i+1} - 2 x_i)
/// = 0`, the end points fixed), which the Thomas algorithm solves in one sweep each way instead
/// of a hundred or so descent iterations. When every point of the result keeps its clearance
/// floor, that is the smoothed path (it differs from the descent's by less than the descent's
/// tolerance); otherwise `None`, and the descent with its per-point refusals runs. Only for
/// weights with which the descent converges (`w_data > 0`, `w_data + 2 w_smooth <= 1`) and
/// enough iterations to get there (`max_its >= 100`).
fn solve_direct(
    world: &World,
    original: &[(f64, f64)],
    floor: &[f64],
    p: &SmootherParams,
) -> Option<Vec<(f64, f64)>> {
    let (d, s) = (p.w_data, p.w_smooth);
    if !(d > 0.0 && s >= 0.0 && d + 2.0 * s <= 1.0 && p.max_its >= 100) {
        return None;
    }
    let n = original.len();
    // The matrix is the same for every pass and both coordinates: factorise once.
    // Interior unknowns 1..n-1: sub- and super-diagonal -s, diagonal d + 2s.
    let diag = d + 2.0 * s;
    let mut c_prime = vec![0.0; n];
    let mut m_inv = vec![0.0; n];
    let mut prev_c = 0.0;
    for i in 1..n - 1 {
        let m = diag + s * prev_c;
        m_inv[i] = 1.0 / m;
        prev_c = -s * m_inv[i];
        c_prime[i] = prev_c;
    }
    let mut current = original.to_vec();
    let mut rhs = vec![(0.0, 0.0); n];
    for _ in 0..=p.refinement_num {
        let (first, last) = (current[0], current[n - 1]);
        // Forward sweep: rhs holds d'_i.
        let mut prev = (0.0, 0.0);
        for i in 1..n - 1 {
            let mut r = (d * current[i].0, d * current[i].1);
            if i == 1 {
                r = (r.0 + s * first.0, r.1 + s * first.1);
            }
            if i == n - 2 {
                r = (r.0 + s * last.0, r.1 + s * last.1);
            }
            prev = ((r.0 + s * prev.0) * m_inv[i], (r.1 + s * prev.1) * m_inv[i]);
            rhs[i] = prev;
        }
        // Back substitution (the last interior point has no successor: `next` starts at 0).
        let mut next = (0.0, 0.0);
        for i in (1..n - 1).rev() {
            next = (
                rhs[i].0 - c_prime[i] * next.0,
                rhs[i].1 - c_prime[i] * next.1,
            );
            current[i] = next;
        }
    }
    let keeps = current
        .iter()
        .zip(floor)
        .skip(1)
        .take(n - 2)
        .all(|(q, f)| world.clearance(q.0, q.1) >= *f);
    keeps.then_some(current)
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
