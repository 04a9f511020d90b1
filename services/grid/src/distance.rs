//! Exact Euclidean distance transforms of a binary grid: for every cell, the blocked cell whose
//! centre is nearest to its centre (a feature transform), or the squared distance to it.
//!
//! One algorithm serves both: Felzenszwalb and Huttenlocher's two passes ("Distance transforms
//! of sampled functions", 2012), linear in the number of cells. Pass 1 finds, in every column,
//! the nearest blocked row of each cell; pass 2 takes, along every row, the lower envelope of
//! the parabolas `(x - x')² + dy(x')²` rooted at those rows. Rows of pass 2 run in parallel on
//! rayon's pool. Every quantity is an integer below 2⁵³, so the result is exact: the distance
//! of the feature found is the true minimum (which feature wins a tie is fixed by the
//! algorithm, the same on every run and platform).
//!
//! A blocked frame around the grid ([`Outside::Blocked`]) enters both passes as virtual rows
//! -1 and `height` and virtual columns -1 and `width`, so it costs nothing per cell.
//!
//! Grids are row-major, `width` columns by `height` rows, indexed `y * width + x`, with fewer
//! than `u32::MAX` cells.

use rayon::prelude::*;

/// "No blocked cell at all" in a [`feature_transform`].
pub const NO_FEATURE: u32 = u32::MAX;

/// What lies beyond the grid's edge, for [`squared_distance_transform`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Outside {
    /// Nothing: only blocked cells of the grid count. A grid with no blocked cell gives
    /// `u32::MAX` everywhere.
    Free,
    /// A frame of blocked cells just outside the grid (row -1, row `height`, column -1 and
    /// column `width`), so that nothing is ever far from the edge of the known map.
    Blocked,
}

/// For every cell, the index of the blocked cell whose centre is nearest to its centre (exact
/// Euclidean distance), or [`NO_FEATURE`] when no cell is blocked.
pub fn feature_transform(blocked: &[bool], width: usize, height: usize) -> Vec<u32> {
    let w = as_u32(width);
    transform(blocked, width, height, Outside::Free, |_, nearest| {
        nearest.map_or(NO_FEATURE, |n| n.row() * w + n.col())
    })
}

/// For every cell, the squared distance in cells² from its centre to the centre of the nearest
/// blocked cell, with the space beyond the edge as `outside` says.
pub fn squared_distance_transform(
    blocked: &[bool],
    width: usize,
    height: usize,
    outside: Outside,
) -> Vec<u32> {
    transform(blocked, width, height, outside, |_, nearest| {
        nearest.map_or(u32::MAX, Nearest::squared_distance)
    })
}

/// Euclidean distance, in cells, between the centres of cells `i` and `j` of a grid `width`
/// wide (for example a cell and its feature).
pub fn centre_distance(i: usize, j: usize, width: usize) -> f64 {
    let (xi, yi) = ((i % width) as f64, (i / width) as f64);
    let (xj, yj) = ((j % width) as f64, (j / width) as f64);
    (xi - xj).hypot(yi - yj)
}

/// The blocked cell nearest to a cell, as pass 2 finds it: a parabola of the row's envelope.
/// Slots and stored rows are shifted by one, so that slot 0 and row 0 are the frame's column
/// -1 and row -1.
#[derive(Clone, Copy, Debug)]
struct Nearest<'a> {
    /// The cell's own column, as a float.
    x: f64,
    /// The nearest cell's slot, column (as a float) and squared vertical distance.
    slot: usize,
    pos: f64,
    dy2: f64,
    /// Per column, the nearest blocked row in that column, plus one.
    rows: &'a [u32],
}

impl Nearest<'_> {
    /// Its column (a real cell's: only without a frame).
    fn col(self) -> u32 {
        as_u32(self.slot - 1)
    }

    /// Its row (a real cell's: only without a frame), read only when asked for.
    fn row(self) -> u32 {
        self.rows[self.slot - 1] - 1
    }

    /// Squared distance between the two centres, in cells²; exact (every term is an integer
    /// below 2⁵³), saturated at `u32::MAX`.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a non-negative integer, saturated"
    )]
    fn squared_distance(self) -> u32 {
        let dx = self.x - self.pos;
        (dx * dx + self.dy2) as u32
    }
}

/// The two passes. `emit(x, nearest)` makes the output of cell x of a row from its nearest
/// blocked cell (`None` when there is none at all).
fn transform<T, F>(
    blocked: &[bool],
    width: usize,
    height: usize,
    outside: Outside,
    emit: F,
) -> Vec<T>
where
    T: Copy + Default + Send,
    F: Fn(u32, Option<Nearest<'_>>) -> T + Sync,
{
    let (w, h) = (width, height);
    assert_eq!(blocked.len(), w * h, "a {w}x{h} grid has {} cells", w * h);
    assert!(
        w.checked_mul(h).is_some_and(|c| c < u32::MAX as usize) && h < u32::MAX as usize - 1,
        "a {w}x{h} grid has too many cells"
    );
    let mut out = vec![T::default(); w * h];
    if w == 0 || h == 0 {
        return out;
    }
    let col_row = nearest_rows(blocked, w, h, outside);
    out.par_chunks_mut(w)
        .zip(col_row.par_chunks(w))
        .enumerate()
        .for_each_init(
            || Envelope::new(w, outside),
            |env, (y, (out_row, rows))| {
                if env.build(as_u32(y), rows) {
                    env.sample(rows, |x, nearest| {
                        out_row[x] = emit(as_u32(x), Some(nearest))
                    });
                } else {
                    // Nothing blocked in any column: no feature anywhere.
                    for (x, slot) in out_row.iter_mut().enumerate() {
                        *slot = emit(as_u32(x), None);
                    }
                }
            },
        );
    out
}

/// Pass 1: for each cell, the nearest blocked row in its column plus one (0 and `h + 1` are the
/// frame's rows), or [`NO_FEATURE`] if none. Two sweeps over whole rows keep memory access
/// sequential; ties go to the row below.
fn nearest_rows(blocked: &[bool], w: usize, h: usize, outside: Outside) -> Vec<u32> {
    let (below_frame, above_frame) = match outside {
        Outside::Free => (NO_FEATURE, NO_FEATURE),
        Outside::Blocked => (0, as_u32(h) + 1),
    };
    let mut col_row = vec![NO_FEATURE; w * h];
    let mut last = vec![below_frame; w];
    for y in 0..h {
        let row = &blocked[y * w..(y + 1) * w];
        let out = &mut col_row[y * w..(y + 1) * w];
        let yy = as_u32(y) + 1;
        for ((&b, l), o) in row.iter().zip(&mut last).zip(out) {
            *l = if b { yy } else { *l };
            *o = *l;
        }
    }
    last.fill(above_frame);
    for y in (0..h).rev() {
        let row = &blocked[y * w..(y + 1) * w];
        let out = &mut col_row[y * w..(y + 1) * w];
        let yy = as_u32(y) + 1;
        for ((&b, l), o) in row.iter().zip(&mut last).zip(out) {
            *l = if b { yy } else { *l };
            // Written as selects, so the loop vectorises.
            let (below, above) = (*o, *l);
            let d_below = if below == NO_FEATURE {
                u32::MAX
            } else {
                yy.wrapping_sub(below)
            };
            let d_above = if above == NO_FEATURE {
                u32::MAX
            } else {
                above.wrapping_sub(yy)
            };
            *o = if d_above < d_below { above } else { below };
        }
    }
    col_row
}

/// Pass 2's scratch for one row: the lower envelope of the parabolas `f(q) + (x - q)²`, over
/// slots `q + 1` (slot 0 and slot `w + 1` are the frame's columns, absent without a frame).
struct Envelope {
    /// Per slot, the squared vertical distance from the row to the column's nearest blocked
    /// row; infinite where there is none.
    f: Vec<f64>,
    /// The envelope's parabolas, left to right: slot, column (as a float), `f` and
    /// `f + column²`, kept side by side so that nothing is loaded through a slot.
    v: Vec<u32>,
    pos: Vec<f64>,
    fv: Vec<f64>,
    g: Vec<f64>,
    /// Boundaries: parabola `k` is lowest on `[z[k], z[k + 1]]` (in columns).
    z: Vec<f64>,
}

impl Envelope {
    fn new(w: usize, outside: Outside) -> Self {
        let frame = match outside {
            Outside::Free => f64::INFINITY,
            Outside::Blocked => 0.0,
        };
        Self {
            f: vec![frame; w + 2],
            v: vec![0; w + 2],
            pos: vec![0.0; w + 2],
            fv: vec![0.0; w + 2],
            g: vec![0.0; w + 2],
            z: vec![0.0; w + 3],
        }
    }

    /// Builds the envelope of row `y` from `rows[x]`, column x's nearest blocked row plus one.
    /// Columns with none are left out. False when every column has none.
    ///
    /// Every quantity but the boundaries is an integer below 2⁵³, so exact in any order; the
    /// boundaries are one correctly rounded division of the same two integers whatever the
    /// layout, which keeps ties where they always fell.
    fn build(&mut self, y: u32, rows: &[u32]) -> bool {
        let Self {
            f,
            v,
            pos,
            fv,
            g,
            z,
        } = self;
        let w = rows.len();
        let yy = f64::from(y) + 1.0;
        for (fq, &row) in f[1..=w].iter_mut().zip(rows) {
            let d = f64::from(row) - yy;
            *fq = if row == NO_FEATURE {
                f64::INFINITY
            } else {
                d * d
            };
        }
        let Some(first) = f.iter().position(|fq| fq.is_finite()) else {
            return false;
        };
        // The column of a slot, counted as a float (exact).
        let mut qf = first as f64 - 1.0;
        v[0] = as_u32(first);
        pos[0] = qf;
        fv[0] = f[first];
        g[0] = f[first] + qf * qf;
        z[0] = f64::NEG_INFINITY;
        z[1] = f64::INFINITY;
        // k: index of the rightmost parabola so far.
        let mut k = 0usize;
        for (q, &fq) in f.iter().enumerate().skip(first + 1) {
            qf += 1.0;
            if fq.is_infinite() {
                continue;
            }
            let gq = fq + qf * qf;
            loop {
                let s = (gq - g[k]) / (2.0 * (qf - pos[k]));
                if s <= z[k] {
                    // Never with k = 0: z[0] is -inf and s is finite.
                    k -= 1;
                    continue;
                }
                k += 1;
                v[k] = as_u32(q);
                pos[k] = qf;
                fv[k] = fq;
                g[k] = gq;
                z[k] = s;
                z[k + 1] = f64::INFINITY;
                break;
            }
        }
        true
    }

    /// Calls `out(x, nearest)` for every column x of the row, with the blocked cell nearest to
    /// it.
    fn sample<'a>(&'a self, rows: &'a [u32], mut out: impl FnMut(usize, Nearest<'a>)) {
        let mut j = 0usize;
        let mut xf = 0.0f64;
        for x in 0..rows.len() {
            while self.z[j + 1] < xf {
                j += 1;
            }
            out(
                x,
                Nearest {
                    x: xf,
                    slot: self.v[j] as usize,
                    pos: self.pos[j],
                    dy2: self.fv[j],
                    rows,
                },
            );
            xf += 1.0;
        }
    }
}

/// A grid index or coordinate as `u32`; grids hold fewer than `u32::MAX` cells (checked on
/// entry).
#[allow(
    clippy::cast_possible_truncation,
    reason = "grids are checked to hold fewer than u32::MAX cells"
)]
fn as_u32(v: usize) -> u32 {
    v as u32
}

#[cfg(test)]
#[allow(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap,
    reason = "test grids and values are small"
)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every blocked cell (and the frame, when asked), tried for every cell.
    fn brute_d2(blocked: &[bool], w: usize, h: usize, outside: Outside) -> Vec<u32> {
        let (wi, hi) = (w as i64, h as i64);
        let mut out = vec![u32::MAX; w * h];
        for y in 0..hi {
            for x in 0..wi {
                let mut best = i64::MAX;
                for yy in -1..=hi {
                    for xx in -1..=wi {
                        let inside = (0..hi).contains(&yy) && (0..wi).contains(&xx);
                        let is_blocked = if inside {
                            blocked[(yy * wi + xx) as usize]
                        } else {
                            outside == Outside::Blocked
                        };
                        if is_blocked {
                            best = best.min((yy - y).pow(2) + (xx - x).pow(2));
                        }
                    }
                }
                if best != i64::MAX {
                    out[(y * wi + x) as usize] = best as u32;
                }
            }
        }
        out
    }

    fn grid() -> impl Strategy<Value = (usize, usize, Vec<bool>)> {
        (1usize..40, 1usize..40, 0u32..=100).prop_flat_map(|(w, h, density)| {
            let cell = prop::bool::weighted(f64::from(density) / 100.0);
            (Just(w), Just(h), prop::collection::vec(cell, w * h))
        })
    }

    proptest! {
        #[test]
        fn squared_distances_match_brute_force((w, h, blocked) in grid()) {
            for outside in [Outside::Free, Outside::Blocked] {
                prop_assert_eq!(
                    squared_distance_transform(&blocked, w, h, outside),
                    brute_d2(&blocked, w, h, outside),
                    "{:?}", outside
                );
            }
        }

        #[test]
        fn features_are_blocked_and_nearest((w, h, blocked) in grid()) {
            let features = feature_transform(&blocked, w, h);
            let d2 = brute_d2(&blocked, w, h, Outside::Free);
            for (i, &f) in features.iter().enumerate() {
                if d2[i] == u32::MAX {
                    prop_assert_eq!(f, NO_FEATURE);
                    continue;
                }
                let f = f as usize;
                prop_assert!(blocked[f], "cell {} points at free cell {}", i, f);
                let (dx, dy) = ((i % w).abs_diff(f % w), (i / w).abs_diff(f / w));
                prop_assert_eq!((dx * dx + dy * dy) as u32, d2[i], "cell {}", i);
                let d = centre_distance(i, f, w);
                prop_assert!((d * d - f64::from(d2[i])).abs() < 1e-9, "cell {}", i);
            }
        }
    }

    #[test]
    fn sparse_obstacles_far_apart_on_a_wide_grid() {
        // Long rows with few parabolas stress the envelope's boundaries.
        let (w, h) = (700, 3);
        let mut blocked = vec![false; w * h];
        for &i in &[5, 350, 351, 1399, 2099] {
            blocked[i] = true;
        }
        for outside in [Outside::Free, Outside::Blocked] {
            assert_eq!(
                squared_distance_transform(&blocked, w, h, outside),
                brute_d2(&blocked, w, h, outside)
            );
        }
    }

    #[test]
    fn an_empty_grid_has_no_feature() {
        assert!(
            feature_transform(&[false; 12], 4, 3)
                .iter()
                .all(|&v| v == NO_FEATURE)
        );
        assert!(
            squared_distance_transform(&[false; 12], 4, 3, Outside::Free)
                .iter()
                .all(|&v| v == u32::MAX)
        );
        assert_eq!(
            squared_distance_transform(&[false; 12], 4, 3, Outside::Blocked),
            vec![1, 1, 1, 1, 1, 4, 4, 1, 1, 1, 1, 1]
        );
        assert!(feature_transform(&[], 0, 5).is_empty());
    }
}
