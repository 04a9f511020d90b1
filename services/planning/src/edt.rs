//! Exact Euclidean distance transform of a binary grid (Felzenszwalb–Huttenlocher, O(cells)).
//!
//! For every cell it gives the squared distance, in cells², from the cell's centre to the centre
//! of the nearest blocked cell. Space outside the map counts as blocked, so a robot is never
//! planned off the edge of the map.

/// Squared distance from every cell to the nearest blocked cell (or to the virtual blocked frame
/// just outside the map), row-major like `blocked`.
pub(crate) fn squared_distance_transform(
    width: usize,
    height: usize,
    blocked: &[bool],
) -> Vec<u32> {
    debug_assert_eq!(blocked.len(), width * height);
    // Pass 1, along columns: distance to the nearest blocked cell in the same column. Done as two
    // row-by-row sweeps so that memory is read in order (the grid is row-major).
    let mut g = vec![0u32; width * height];
    for row in 0..height {
        let (prev, cur) = if row == 0 {
            (None, &mut g[..width])
        } else {
            let (before, after) = g.split_at_mut(row * width);
            (Some(&before[(row - 1) * width..]), &mut after[..width])
        };
        let b = &blocked[row * width..(row + 1) * width];
        for col in 0..width {
            cur[col] = if b[col] {
                0
            } else {
                // Row -1 is the virtual blocked frame.
                prev.map_or(1, |p| p[col] + 1)
            };
        }
    }
    for row in (0..height).rev() {
        if row + 1 == height {
            for v in &mut g[row * width..(row + 1) * width] {
                *v = (*v).min(1);
            }
        } else {
            let (cur, after) = g[row * width..].split_at_mut(width);
            for (c, n) in cur.iter_mut().zip(&after[..width]) {
                *c = (*c).min(n + 1);
            }
        }
    }

    // Pass 2, along rows: lower envelope of parabolas f(q) + (x - q)², with the virtual blocked
    // columns -1 and width as extra parabolas of height 0.
    let n = width + 2;
    let mut f = vec![0f64; n];
    let mut out = vec![0u32; width * height];
    let mut v = vec![0usize; n];
    let mut z = vec![0f64; n + 1];
    for row in 0..height {
        let gr = &g[row * width..(row + 1) * width];
        f[0] = 0.0;
        f[n - 1] = 0.0;
        for (fi, &gv) in f[1..=width].iter_mut().zip(gr) {
            *fi = f64::from(gv) * f64::from(gv);
        }
        lower_envelope(&f, &mut v, &mut z);
        let mut k = 0usize;
        let o = &mut out[row * width..(row + 1) * width];
        for (i, ov) in o.iter_mut().enumerate() {
            let q = i + 1;
            while z[k + 1] < q as f64 {
                k += 1;
            }
            let d = q as f64 - v[k] as f64;
            // Exact: every term is an integer below 2⁵³.
            *ov = (d * d + f[v[k]]) as u32;
        }
    }
    out
}

/// Fills `v` (parabola vertices) and `z` (their boundaries) with the lower envelope of the
/// parabolas `f[q] + (x - q)²`.
fn lower_envelope(f: &[f64], v: &mut [usize], z: &mut [f64]) {
    let n = f.len();
    let mut k = 0usize;
    v[0] = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        let qf = q as f64;
        loop {
            let p = v[k] as f64;
            let s = ((f[q] + qf * qf) - (f[v[k]] + p * p)) / (2.0 * qf - 2.0 * p);
            if s <= z[k] {
                // k > 0 here because z[0] is -inf.
                k -= 1;
            } else {
                k += 1;
                v[k] = q;
                z[k] = s;
                z[k + 1] = f64::INFINITY;
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(width: usize, height: usize, blocked: &[bool]) -> Vec<u32> {
        let mut out = vec![u32::MAX; width * height];
        for r in 0..height as i64 {
            for c in 0..width as i64 {
                let mut best = i64::MAX;
                // The virtual frame around the map.
                for rr in -1..=height as i64 {
                    for cc in -1..=width as i64 {
                        let inside = rr >= 0 && cc >= 0 && rr < height as i64 && cc < width as i64;
                        let is_blocked = !inside || blocked[(rr as usize) * width + cc as usize];
                        if is_blocked {
                            best = best.min((rr - r).pow(2) + (cc - c).pow(2));
                        }
                    }
                }
                out[r as usize * width + c as usize] = best as u32;
            }
        }
        out
    }

    #[test]
    fn matches_brute_force_on_pseudo_random_grids() {
        let mut state = 12345u64;
        for (w, h) in [(1, 1), (7, 3), (13, 17), (31, 8), (20, 20)] {
            for density in [0u64, 5, 30, 70] {
                let blocked: Vec<bool> = (0..w * h)
                    .map(|_| {
                        state = state
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        (state >> 33) % 100 < density
                    })
                    .collect();
                assert_eq!(
                    squared_distance_transform(w, h, &blocked),
                    brute(w, h, &blocked),
                    "{w}x{h} d={density}"
                );
            }
        }
    }
}
