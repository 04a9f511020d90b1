//! What the grid waves of bridging and densification share: per-thread cell tables reset in
//! O(1), and 4-neighbourhoods.

/// Per-cell tables for the grid waves, kept per thread and reset in O(1) by a generation stamp:
/// a fresh zeroed table per wave costs a memset of the whole map (megabytes) each time.
pub(super) struct CellTables {
    /// Per cell: [generation stamp, table 0, table 1, table 2], interleaved so that one cell's
    /// entries share a cache line.
    cells: Vec<[u32; 4]>,
    generation: u32,
}

impl CellTables {
    /// Runs `f` with tables for `cells` cells, all reading 0.
    pub(super) fn with<R>(cells: usize, f: impl FnOnce(&mut CellTables) -> R) -> R {
        thread_local! {
            static TABLES: std::cell::RefCell<CellTables> = const {
                std::cell::RefCell::new(CellTables { cells: Vec::new(), generation: 0 })
            };
        }
        TABLES.with(|t| {
            let mut t = t.borrow_mut();
            if t.cells.len() < cells || t.generation == u32::MAX {
                t.cells = vec![[0; 4]; cells];
                t.generation = 0;
            }
            t.generation += 1;
            f(&mut t)
        })
    }
    pub(super) fn get(&self, table: usize, c: usize) -> u32 {
        let e = &self.cells[c];
        if e[0] == self.generation {
            e[table + 1]
        } else {
            0
        }
    }
    pub(super) fn set(&mut self, table: usize, c: usize, v: u32) {
        let generation = self.generation;
        let e = &mut self.cells[c];
        if e[0] != generation {
            *e = [generation, 0, 0, 0];
        }
        e[table + 1] = v;
    }
}

/// The 4-neighbours of cell `c` inside a `w` × `h` grid. Waves use 4-connectivity: half the
/// work of 8, no corner rule, and the thinning straightens the staircases afterwards.
pub(super) fn neighbours4(c: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (c % w, c / w);
    // Out-of-grid neighbours map to `usize::MAX` and are filtered, which compiles to a simple
    // unrolled loop (an array of Options did not).
    let n = [
        if x > 0 { c - 1 } else { usize::MAX },
        if x + 1 < w { c + 1 } else { usize::MAX },
        if y > 0 { c - w } else { usize::MAX },
        if y + 1 < h { c + w } else { usize::MAX },
    ];
    n.into_iter().filter(|&v| v != usize::MAX)
}
