//! Grid algorithms behind the world's constant-time queries: an exact Euclidean feature transform
//! (nearest blocked cell of every cell) and connected free regions.
//!
//! Grids here are row-major, `w` columns by `h` rows, indexed `y * w + x`.

use rayon::prelude::*;

/// "No blocked cell at all" in a feature transform.
pub(crate) const NO_FEATURE: u32 = u32::MAX;

/// For every cell, the index of the blocked cell whose centre is nearest to its centre (exact
/// Euclidean distance; ties broken arbitrarily), or [`NO_FEATURE`] when no cell is blocked.
///
/// Felzenszwalb and Huttenlocher's two-pass algorithm, linear in the number of cells: first the
/// nearest blocked row within each column, then per row the lower envelope of the parabolas
/// `(x - x')² + dy(x')²`. Rows of the second pass run in parallel.
pub(crate) fn feature_transform(blocked: &[bool], w: usize, h: usize) -> Vec<u32> {
    debug_assert_eq!(blocked.len(), w * h);
    // Pass 1: for each cell, the nearest blocked row in its column (NO_FEATURE if none). Two
    // sweeps over whole rows keep memory access sequential.
    let mut col_row = vec![NO_FEATURE; w * h];
    let mut last = vec![NO_FEATURE; w];
    for y in 0..h {
        let row = &blocked[y * w..(y + 1) * w];
        for x in 0..w {
            if row[x] {
                last[x] = as_u32(y);
            }
            col_row[y * w + x] = last[x];
        }
    }
    last.fill(NO_FEATURE);
    for y in (0..h).rev() {
        let row = &blocked[y * w..(y + 1) * w];
        for x in 0..w {
            if row[x] {
                last[x] = as_u32(y);
            }
            let below = col_row[y * w + x];
            let above = last[x];
            let yy = as_u32(y);
            let pick_above = match (below, above) {
                (NO_FEATURE, _) => true,
                (_, NO_FEATURE) => false,
                (b, a) => a - yy < yy - b,
            };
            if pick_above {
                col_row[y * w + x] = above;
            }
        }
    }
    // Pass 2: per row, the lower envelope of parabolas rooted at each column's nearest row.
    let mut out = vec![NO_FEATURE; w * h];
    out.par_chunks_mut(w)
        .zip(col_row.par_chunks(w))
        .enumerate()
        .for_each_init(
            || (vec![0usize; w], vec![0f64; w + 1]),
            |(v, z), (y, (out_row, rows))| envelope_row(y, rows, out_row, v, z, w),
        );
    out
}

/// The second pass for one row `y`: `rows[x]` is the nearest blocked row in column `x`.
fn envelope_row(y: usize, rows: &[u32], out: &mut [u32], v: &mut [usize], z: &mut [f64], w: usize) {
    #[allow(
        clippy::cast_precision_loss,
        reason = "grid coordinates are far below 2^52"
    )]
    let f = |x: usize| -> f64 {
        let r = rows[x];
        if r == NO_FEATURE {
            f64::INFINITY
        } else {
            let d = r as f64 - y as f64;
            d * d
        }
    };
    // k: index of the rightmost parabola of the envelope; v[..=k] their roots, z[..=k+1] the
    // boundaries between them.
    let mut k: Option<usize> = None;
    for q in 0..w {
        let fq = f(q);
        if fq.is_infinite() {
            continue;
        }
        #[allow(
            clippy::cast_precision_loss,
            reason = "grid coordinates are far below 2^52"
        )]
        let qf = q as f64;
        loop {
            match k {
                None => {
                    k = Some(0);
                    v[0] = q;
                    z[0] = f64::NEG_INFINITY;
                    z[1] = f64::INFINITY;
                    break;
                }
                Some(kk) => {
                    let p = v[kk];
                    #[allow(
                        clippy::cast_precision_loss,
                        reason = "grid coordinates are far below 2^52"
                    )]
                    let pf = p as f64;
                    let s = ((fq + qf * qf) - (f(p) + pf * pf)) / (2.0 * (qf - pf));
                    if s <= z[kk] {
                        k = kk.checked_sub(1);
                        continue;
                    }
                    let nk = kk + 1;
                    v[nk] = q;
                    z[nk] = s;
                    z[nk + 1] = f64::INFINITY;
                    k = Some(nk);
                    break;
                }
            }
        }
    }
    let Some(_) = k else {
        return; // nothing blocked anywhere in this row's columns: out stays NO_FEATURE
    };
    let mut j = 0usize;
    for (x, slot) in out.iter_mut().enumerate() {
        #[allow(
            clippy::cast_precision_loss,
            reason = "grid coordinates are far below 2^52"
        )]
        let xf = x as f64;
        while z[j + 1] < xf {
            j += 1;
        }
        let col = v[j];
        *slot = rows[col] * as_u32(w) + as_u32(col);
    }
}

/// A grid index or coordinate as `u32`; every grid is below [`crate::spec::MAX_GRID_CELLS`].
#[allow(
    clippy::cast_possible_truncation,
    reason = "grids are validated to hold fewer than u32::MAX cells"
)]
pub(crate) fn as_u32(v: usize) -> u32 {
    v as u32
}

/// Squared centre distance, in cells, between cell `i` and cell `j` of a grid `w` wide.
#[allow(
    clippy::cast_precision_loss,
    reason = "grid coordinates are far below 2^52"
)]
pub(crate) fn centre_distance(i: usize, j: usize, w: usize) -> f64 {
    let (xi, yi) = ((i % w) as f64, (i / w) as f64);
    let (xj, yj) = ((j % w) as f64, (j / w) as f64);
    (xi - xj).hypot(yi - yj)
}

/// The cells of the largest 4-connected component of `mask`, in ascending index order.
pub(crate) fn largest_component(mask: &[bool], w: usize, h: usize) -> Vec<u32> {
    let mut label = vec![0u32; w * h];
    let mut best: (u32, usize) = (0, 0); // (label, size)
    let mut next = 1u32;
    let mut stack: Vec<usize> = Vec::new();
    for start in 0..w * h {
        if !mask[start] || label[start] != 0 {
            continue;
        }
        let id = next;
        next += 1;
        label[start] = id;
        stack.push(start);
        let mut size = 0usize;
        while let Some(i) = stack.pop() {
            size += 1;
            let (x, y) = (i % w, i / w);
            let mut visit = |j: usize| {
                if mask[j] && label[j] == 0 {
                    label[j] = id;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        if size > best.1 {
            best = (id, size);
        }
    }
    if best.1 == 0 {
        return Vec::new();
    }
    label
        .iter()
        .enumerate()
        .filter(|(_, l)| **l == best.0)
        .map(|(i, _)| as_u32(i))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute-force nearest blocked centre distance for every cell.
    fn brute(blocked: &[bool], w: usize, h: usize) -> Vec<f64> {
        (0..w * h)
            .map(|i| {
                (0..w * h)
                    .filter(|j| blocked[*j])
                    .map(|j| centre_distance(i, j, w))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    #[test]
    fn feature_transform_matches_brute_force() {
        // A small deterministic pseudo-random pattern, plus an empty grid.
        let (w, h) = (23, 17);
        let mut s = 12345u64;
        let blocked: Vec<bool> = (0..w * h)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 33).is_multiple_of(13)
            })
            .collect();
        let f = feature_transform(&blocked, w, h);
        let b = brute(&blocked, w, h);
        for i in 0..w * h {
            let d = centre_distance(i, f[i] as usize, w);
            assert!((d - b[i]).abs() < 1e-9, "cell {i}: {d} vs {}", b[i]);
            assert!(blocked[f[i] as usize]);
        }
        let none = feature_transform(&[false; 12], 4, 3);
        assert!(none.iter().all(|v| *v == NO_FEATURE));
    }

    #[test]
    fn largest_component_picks_the_biggest() {
        // Two regions split by a blocked column: 2 cells wide on the left, 3 on the right.
        let (w, h) = (6, 2);
        let mask: Vec<bool> = (0..w * h).map(|i| i % w != 2).collect();
        let c = largest_component(&mask, w, h);
        assert_eq!(c, vec![3, 4, 5, 9, 10, 11]);
    }
}
