//! Connected regions of a binary grid, 4-connected: two cells are joined when they share an
//! edge, never through a corner alone (what a robot that may not squeeze diagonally between
//! two blocked cells can cross, and what the planner's supercover segment checks allow).
//!
//! Labels are numbered from 1 in the order of each region's first cell in row-major order, so
//! they depend only on the mask. Grids are row-major, `width` columns by `height` rows, indexed
//! `y * width + x`, with fewer than `u32::MAX` cells.

/// The regions of a mask.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Regions {
    /// Per cell, its region (1-based), or 0 where the mask is false.
    pub labels: Vec<u32>,
    /// Cells per region: `sizes[r - 1]` for region `r`.
    pub sizes: Vec<u32>,
}

impl Regions {
    /// Number of regions.
    pub fn count(&self) -> usize {
        self.sizes.len()
    }

    /// The region with the most cells (the first of equals), if the mask has any cell.
    pub fn largest(&self) -> Option<u32> {
        let mut best: Option<(u32, u32)> = None; // (size, label)
        for (r, &size) in (1u32..).zip(&self.sizes) {
            if best.is_none_or(|(s, _)| size > s) {
                best = Some((size, r));
            }
        }
        best.map(|(_, r)| r)
    }

    /// The cells of region `r`, in ascending index order.
    pub fn cells(&self, r: u32) -> Vec<u32> {
        if r == 0 {
            return Vec::new();
        }
        let size = self.sizes.get(r as usize - 1).copied().unwrap_or(0);
        let mut out = Vec::with_capacity(size as usize);
        out.extend(
            (0u32..)
                .zip(&self.labels)
                .filter(|(_, l)| **l == r)
                .map(|(i, _)| i),
        );
        out
    }
}

/// Labels the 4-connected regions of the cells where `mask` is true.
pub fn label(mask: &[bool], width: usize, height: usize) -> Regions {
    let (w, h) = (width, height);
    assert_eq!(mask.len(), w * h, "a {w}x{h} grid has {} cells", w * h);
    assert!(
        w.checked_mul(h).is_some_and(|c| c < u32::MAX as usize),
        "a {w}x{h} grid has too many cells"
    );
    let mut labels = vec![0u32; w * h];
    let mut sizes = Vec::new();
    let mut stack: Vec<u32> = Vec::new();
    for start in 0..w * h {
        if !mask[start] || labels[start] != 0 {
            continue;
        }
        let id = as_u32(sizes.len()) + 1;
        let mut size = 0u32;
        labels[start] = id;
        stack.push(as_u32(start));
        while let Some(i) = stack.pop() {
            let i = i as usize;
            size += 1;
            let (x, y) = (i % w, i / w);
            let mut push = |j: usize| {
                if mask[j] && labels[j] == 0 {
                    labels[j] = id;
                    stack.push(as_u32(j));
                }
            };
            if x > 0 {
                push(i - 1);
            }
            if x + 1 < w {
                push(i + 1);
            }
            if y > 0 {
                push(i - w);
            }
            if y + 1 < h {
                push(i + w);
            }
        }
        sizes.push(size);
    }
    Regions { labels, sizes }
}

/// A grid index as `u32`; grids hold fewer than `u32::MAX` cells (checked on entry).
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

    /// Union-find over edge-sharing pairs, then labels renumbered by first cell.
    fn brute(mask: &[bool], w: usize, h: usize) -> Regions {
        let mut parent: Vec<usize> = (0..w * h).collect();
        fn find(p: &mut [usize], mut a: usize) -> usize {
            while p[a] != a {
                a = p[a];
            }
            a
        }
        for i in 0..w * h {
            let (x, y) = (i % w, i / w);
            for j in [(x + 1 < w).then(|| i + 1), (y + 1 < h).then(|| i + w)]
                .into_iter()
                .flatten()
            {
                if mask[i] && mask[j] {
                    let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
        let mut labels = vec![0u32; w * h];
        let mut sizes = Vec::new();
        let mut by_root = std::collections::HashMap::new();
        for i in 0..w * h {
            if !mask[i] {
                continue;
            }
            let root = find(&mut parent, i);
            let id = *by_root.entry(root).or_insert_with(|| {
                sizes.push(0);
                sizes.len() as u32
            });
            labels[i] = id;
            sizes[id as usize - 1] += 1;
        }
        Regions { labels, sizes }
    }

    proptest! {
        #[test]
        fn labels_match_union_find(
            (w, h, mask) in (1usize..30, 1usize..30, 0u32..=100).prop_flat_map(|(w, h, d)| {
                let cell = prop::bool::weighted(f64::from(d) / 100.0);
                (Just(w), Just(h), prop::collection::vec(cell, w * h))
            })
        ) {
            let r = label(&mask, w, h);
            prop_assert_eq!(&r, &brute(&mask, w, h));
            let total: u32 = r.sizes.iter().sum();
            prop_assert_eq!(total as usize, mask.iter().filter(|m| **m).count());
            if let Some(big) = r.largest() {
                let cells = r.cells(big);
                prop_assert_eq!(cells.len(), r.sizes[big as usize - 1] as usize);
                prop_assert!(r.sizes.iter().all(|&s| s <= cells.len() as u32));
                prop_assert!(cells.windows(2).all(|c| c[0] < c[1]));
            } else {
                prop_assert!(mask.iter().all(|m| !*m));
            }
        }
    }

    #[test]
    fn corners_do_not_connect() {
        // A diagonal pair: two regions.
        let r = label(&[true, false, false, true], 2, 2);
        assert_eq!(r.labels, vec![1, 0, 0, 2]);
        assert_eq!(r.sizes, vec![1, 1]);
    }

    #[test]
    fn the_largest_is_the_first_of_equals() {
        // Two regions split by a blocked column: 2 cells wide on the left, 3 on the right.
        let (w, h) = (6, 2);
        let mask: Vec<bool> = (0..w * h).map(|i| i % w != 2).collect();
        let r = label(&mask, w, h);
        assert_eq!(r.largest(), Some(2));
        assert_eq!(r.cells(2), vec![3, 4, 5, 9, 10, 11]);
        let tie = label(&[true, false, true], 3, 1);
        assert_eq!(tie.largest(), Some(1));
        assert_eq!(label(&[false; 4], 2, 2).largest(), None);
    }
}
