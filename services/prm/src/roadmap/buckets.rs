//! Nearest nodes while nodes are added one by one (visibility repair): a uniform grid of
//! buckets searched ring by ring, so a query costs about the same whatever the node count,
//! where scanning every node made repair quadratic in n.

/// Node ids bucketed by position on a grid of square buckets.
pub(super) struct Buckets {
    /// Bucket side, in cells.
    side: f64,
    width: usize,
    height: usize,
    items: Vec<Vec<u32>>,
}

impl Buckets {
    /// Buckets over a `width` × `height` cell map, sized for about two of `expected` nodes
    /// spread over `free_cells` cells per bucket.
    pub(super) fn new(width: usize, height: usize, free_cells: usize, expected: usize) -> Self {
        let side = (2.0 * free_cells.max(1) as f64 / expected.max(1) as f64)
            .sqrt()
            .max(1.0);
        let (bw, bh) = (
            ((width as f64 / side).ceil() as usize).max(1),
            ((height as f64 / side).ceil() as usize).max(1),
        );
        Self {
            side,
            width: bw,
            height: bh,
            items: vec![Vec::new(); bw * bh],
        }
    }

    fn bucket(&self, p: [f64; 2]) -> (usize, usize) {
        // Points are inside the map (non-negative); clamp against rounding at the far edges.
        let bx = ((p[0].max(0.0) / self.side) as usize).min(self.width - 1);
        let by = ((p[1].max(0.0) / self.side) as usize).min(self.height - 1);
        (bx, by)
    }

    pub(super) fn insert(&mut self, id: u32, p: [f64; 2]) {
        let (bx, by) = self.bucket(p);
        self.items[by * self.width + bx].push(id);
    }

    /// The `m` nodes nearest to `p` within squared distance `r2`, as (squared distance, id),
    /// sorted by distance then id: what sorting every node by distance would give. Returns the
    /// number of node distances computed.
    pub(super) fn nearest(
        &self,
        nodes: &[[f64; 2]],
        p: [f64; 2],
        m: usize,
        r2: f64,
        out: &mut Vec<(f64, u32)>,
    ) -> usize {
        out.clear();
        if m == 0 {
            return 0;
        }
        let mut computed = 0;
        let (bx, by) = self.bucket(p);
        let (bx, by) = (bx as i64, by as i64);
        let rings = self.width.max(self.height) as i64;
        for k in 0..=rings {
            // Every point of ring k is at least (k - 1) bucket sides away from p.
            let near = ((k - 1).max(0) as f64) * self.side;
            let near2 = near * near;
            if near2 > r2 {
                break;
            }
            if out.len() >= m {
                out.select_nth_unstable_by(m - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                out.truncate(m);
                if near2 > out[m - 1].0 {
                    break;
                }
            }
            let mut scan = |x: i64, y: i64| {
                if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
                    return;
                }
                let items = &self.items[y as usize * self.width + x as usize];
                computed += items.len();
                for &j in items {
                    let q = nodes[j as usize];
                    let d2 = (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2);
                    if d2 <= r2 {
                        out.push((d2, j));
                    }
                }
            };
            if k == 0 {
                scan(bx, by);
                continue;
            }
            for x in bx - k..=bx + k {
                scan(x, by - k);
                scan(x, by + k);
            }
            for y in by - k + 1..by + k {
                scan(bx - k, y);
                scan(bx + k, y);
            }
        }
        out.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        out.truncate(m);
        computed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The buckets answer exactly what sorting every node by distance answers.
    #[test]
    fn nearest_equals_brute_force() {
        let mut state = 11u64;
        let mut next = |m: f64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * m
        };
        let (w, h) = (300usize, 120usize);
        let nodes: Vec<[f64; 2]> = (0..500).map(|_| [next(w as f64), next(h as f64)]).collect();
        let mut b = Buckets::new(w, h, w * h / 2, nodes.len());
        let mut out = Vec::new();
        for (i, &p) in nodes.iter().enumerate() {
            b.insert(i as u32, p);
            let q = [next(w as f64), next(h as f64)];
            for (m, r) in [(1, 500.0), (10, 40.0), (10, 5.0), (30, 1000.0)] {
                b.nearest(&nodes[..=i], q, m, r * r, &mut out);
                let mut all: Vec<(f64, u32)> = nodes[..=i]
                    .iter()
                    .enumerate()
                    .map(|(j, n)| ((n[0] - q[0]).powi(2) + (n[1] - q[1]).powi(2), j as u32))
                    .filter(|c| c.0 <= r * r)
                    .collect();
                all.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                all.truncate(m);
                assert_eq!(out, all, "node {i}, m {m}, r {r}");
            }
        }
    }
}
