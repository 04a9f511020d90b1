//! The configuration space of a disc robot on a grid map: inflated free space, the distance
//! field behind it, its connected regions, and exact segment checks.
//!
//! A cell is free for the robot when the distance from its centre to the nearest blocked cell's
//! edge (the centre-to-centre distance minus half a cell) is at least robot radius + safety
//! margin. A point is free when its cell is; a straight segment is free when every cell it
//! touches is (a supercover walk, so no corner is cut). Everything is computed once per
//! (map, inflation) and shared by every roadmap built on it.

use rand::Rng;

use grid::distance::{Outside, squared_distance_transform};

use crate::error::{ConfigSpaceError, Endpoint, QueryError};
use crate::map::{PlanningGrid, Point2};

/// How far the robot keeps from obstacles.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inflation {
    /// Radius of the robot's circumscribed disc, in metres (from its TOSM footprint).
    pub robot_radius_m: f64,
    /// Extra distance kept on top of the radius, in metres.
    pub safety_margin_m: f64,
}

impl Inflation {
    /// Robot radius plus safety margin.
    pub fn total_m(&self) -> f64 {
        self.robot_radius_m + self.safety_margin_m
    }
}

/// Identifier of a 4-connected region of free configuration space (1-based).
pub type RegionId = u32;

/// Inflated free space of one map for one robot, with its distance field and regions.
#[derive(Debug, Clone)]
pub struct ConfigSpace {
    pub(crate) width: usize,
    pub(crate) height: usize,
    resolution: f64,
    origin_x: f64,
    origin_y: f64,
    inflation: Inflation,
    map_fingerprint: u64,
    /// Centre-to-centre distance to the nearest blocked cell, in cells (its square is exact).
    pub(crate) dist: Vec<f32>,
    /// Whether the robot may stand in the cell (a byte per cell: the hot loop of edge checks).
    pub(crate) free: Vec<bool>,
    /// Region per cell; 0 where the robot cannot stand.
    pub(crate) region: Vec<RegionId>,
    /// Free cells grouped by region: cells of region r are `free_cells[region_start[r-1]..region_start[r]]`.
    free_cells: Vec<u32>,
    region_start: Vec<u32>,
    /// Free cells on ridges of the distance field (an approximate medial axis).
    pub(crate) skeleton_cells: Vec<u32>,
    /// A coarser copy of the free space for roadmap bridging: block (bx, by) of `coarse.factor`²
    /// cells is free when every cell in it is.
    pub(crate) coarse: CoarseGrid,
}

/// Free space at a coarser resolution (whole blocks of cells).
#[derive(Debug, Clone)]
pub(crate) struct CoarseGrid {
    /// Cells per block side.
    pub factor: usize,
    pub width: usize,
    pub height: usize,
    pub free: Vec<bool>,
    /// 4-connected region of free blocks per block (1-based, 0 where not free): bridging joins
    /// only components whose nodes' blocks share one, so it knows in advance which it can join.
    pub region: Vec<u32>,
}

/// Block side of the coarse grid: about 0.15 m, so that a door the robot fits through with a
/// few centimetres to spare still holds a whole free block.
fn coarse_factor(resolution: f64) -> usize {
    // The epsilon keeps 0.15 / 0.05 (2.9999999999999996 in floating point) at 3.
    ((0.15 / resolution + 1e-9).floor() as usize).max(1)
}

fn coarse_grid(w: usize, h: usize, free: &[bool], factor: usize) -> CoarseGrid {
    let (cw, ch) = (w.div_ceil(factor), h.div_ceil(factor));
    let mut out = vec![false; cw * ch];
    for by in 0..ch {
        for bx in 0..cw {
            let (x0, y0) = (bx * factor, by * factor);
            // Blocks hanging over the map edge are not free: they hold no map cells there. Nor
            // are the blocks on the grid's border, so that a free block's four neighbours are
            // always inside the grid (the bridging flood reads them without bounds checks).
            if x0 + factor > w
                || y0 + factor > h
                || bx == 0
                || by == 0
                || bx + 1 == cw
                || by + 1 == ch
            {
                continue;
            }
            out[by * cw + bx] =
                (y0..y0 + factor).all(|y| free[y * w + x0..y * w + x0 + factor].iter().all(|&f| f));
        }
    }
    let region = grid::regions::label(&out, cw, ch).labels;
    CoarseGrid {
        factor,
        width: cw,
        height: ch,
        free: out,
        region,
    }
}

impl ConfigSpace {
    /// Inflates `map` for a robot. O(cells): one exact distance transform and one flood fill.
    pub fn new(map: &PlanningGrid, inflation: Inflation) -> Result<Self, ConfigSpaceError> {
        map.validate()?;
        for (name, value) in [
            ("robot radius", inflation.robot_radius_m),
            ("safety margin", inflation.safety_margin_m),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ConfigSpaceError::BadRadius { name, value });
            }
        }
        let (w, h) = (map.width, map.height);
        // Space beyond the map counts as blocked: the robot is never planned off its edge.
        let d2 = squared_distance_transform(&map.blocked, w, h, Outside::Blocked);
        let need_cells = inflation.total_m() / map.resolution + 0.5;
        // Free iff sqrt(d2) >= need_cells, decided on the exact integer d2.
        let need_d2 = need_cells * need_cells;
        let free: Vec<bool> = d2
            .iter()
            .map(|&d| d >= 1 && f64::from(d) >= need_d2)
            .collect();
        let dist: Vec<f32> = d2.iter().map(|&d| (f64::from(d)).sqrt() as f32).collect();
        let grid::regions::Regions {
            labels: region,
            sizes: counts,
        } = grid::regions::label(&free, w, h);
        let mut region_start = Vec::with_capacity(counts.len() + 1);
        let mut acc = 0u32;
        region_start.push(0);
        for c in &counts {
            acc += c;
            region_start.push(acc);
        }
        let mut fill = region_start.clone();
        let mut free_cells = vec![0u32; acc as usize];
        for (i, &r) in region.iter().enumerate() {
            if r != 0 {
                let slot = &mut fill[r as usize - 1];
                free_cells[*slot as usize] = i as u32;
                *slot += 1;
            }
        }
        let skeleton_cells = ridge_cells(w, h, &d2, &free);
        let coarse = coarse_grid(w, h, &free, coarse_factor(map.resolution));
        Ok(Self {
            width: w,
            height: h,
            resolution: map.resolution,
            origin_x: map.origin_x,
            origin_y: map.origin_y,
            inflation,
            map_fingerprint: map.fingerprint(),
            dist,
            free,
            region,
            free_cells,
            region_start,
            skeleton_cells,
            coarse,
        })
    }

    /// Columns of the underlying grid.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Rows of the underlying grid.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Cell size in metres.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }
    /// The inflation this space was built for.
    pub fn inflation(&self) -> Inflation {
        self.inflation
    }
    /// Fingerprint of the map this space was built from (see [`PlanningGrid::fingerprint`]).
    pub fn map_fingerprint(&self) -> u64 {
        self.map_fingerprint
    }
    /// Number of free regions.
    pub fn region_count(&self) -> usize {
        self.region_start.len() - 1
    }
    /// Number of free cells in region `r` (0 for an unknown region).
    pub fn region_cells(&self, r: RegionId) -> usize {
        let r = r as usize;
        if r == 0 || r >= self.region_start.len() {
            return 0;
        }
        (self.region_start[r] - self.region_start[r - 1]) as usize
    }
    /// The region with the most free cells, if there is any free cell.
    pub fn largest_region(&self) -> Option<RegionId> {
        (1..self.region_start.len() as u32)
            .max_by_key(|&r| (self.region_cells(r), std::cmp::Reverse(r)))
            .filter(|&r| self.region_cells(r) > 0)
    }
    /// Area in m² where the robot's centre may be (inflated free space).
    pub fn free_area_m2(&self) -> f64 {
        self.free_cells.len() as f64 * self.resolution * self.resolution
    }
    /// Lower-left and upper-right corners of the map, in metres.
    pub fn bounds(&self) -> (Point2, Point2) {
        (
            Point2::new(self.origin_x, self.origin_y),
            Point2::new(
                self.origin_x + self.width as f64 * self.resolution,
                self.origin_y + self.height as f64 * self.resolution,
            ),
        )
    }

    /// Map-frame metres to grid coordinates (continuous cells: x right, y up, 0 at the origin).
    pub fn world_to_grid(&self, p: Point2) -> (f64, f64) {
        let g = self.to_grid(p);
        (g[0], g[1])
    }
    /// Grid coordinates (continuous cells) to map-frame metres.
    pub fn grid_to_world(&self, gx: f64, gy: f64) -> Point2 {
        self.to_world([gx, gy])
    }
    /// Whether the robot may stand in cell (`col`, `row`) (row 0 at the bottom).
    pub fn cell_free(&self, col: usize, row: usize) -> bool {
        col < self.width && row < self.height && self.region[row * self.width + col] != 0
    }

    /// Map-frame metres to grid units (cells, continuous).
    pub(crate) fn to_grid(&self, p: Point2) -> [f64; 2] {
        [
            (p.x - self.origin_x) / self.resolution,
            (p.y - self.origin_y) / self.resolution,
        ]
    }
    /// Grid units to map-frame metres.
    pub(crate) fn to_world(&self, g: [f64; 2]) -> Point2 {
        Point2::new(
            self.origin_x + g[0] * self.resolution,
            self.origin_y + g[1] * self.resolution,
        )
    }
    /// The cell index containing grid point `g`, if inside the map.
    pub(crate) fn cell_index(&self, g: [f64; 2]) -> Option<usize> {
        // For g >= 0 truncation is the floor (and `floor` is a library call); NaN fails the test.
        if g[0] >= 0.0
            && g[1] >= 0.0
            && (g[0] as usize) < self.width
            && (g[1] as usize) < self.height
        {
            Some(g[1] as usize * self.width + g[0] as usize)
        } else {
            None
        }
    }
    /// Clearance of a cell in metres: distance from its centre to the nearest blocked cell's edge.
    pub(crate) fn cell_clearance_m(&self, idx: usize) -> f64 {
        ((f64::from(self.dist[idx]) - 0.5) * self.resolution).max(0.0)
    }

    /// Whether the robot's centre may be at `p`.
    pub fn is_free(&self, p: Point2) -> bool {
        self.region_of(p).is_some()
    }
    /// Free region containing `p`, or `None` when the robot cannot stand there.
    pub fn region_of(&self, p: Point2) -> Option<RegionId> {
        let g = self.to_grid(p);
        if !(g[0].is_finite() && g[1].is_finite()) {
            return None;
        }
        self.cell_index(g)
            .map(|i| self.region[i])
            .filter(|&r| r != 0)
    }
    /// Clearance at `p` in metres (distance to the nearest blocked cell's edge), `None` off the map.
    pub fn clearance_m(&self, p: Point2) -> Option<f64> {
        let g = self.to_grid(p);
        self.cell_index(g).map(|i| self.cell_clearance_m(i))
    }

    /// The centre of the free cell nearest to `p` (clamped to the map), if any cell is free.
    pub fn nearest_free(&self, p: Point2) -> Option<Point2> {
        if self.free_cells.is_empty() {
            return None;
        }
        let mut g = self.to_grid(p);
        if !(g[0].is_finite() && g[1].is_finite()) {
            return None;
        }
        g[0] = g[0].clamp(0.0, self.width as f64 - 1e-9);
        g[1] = g[1].clamp(0.0, self.height as f64 - 1e-9);
        let (c0, r0) = (g[0].floor() as i64, g[1].floor() as i64);
        let mut best: Option<(f64, usize)> = None;
        let max_r = self.width.max(self.height) as i64;
        for r in 0..=max_r {
            // Every cell of ring r is at least r - 1 away from g (g lies in the ring-0 cell).
            if let Some((d, _)) = best
                && (r - 1) as f64 > d
            {
                break;
            }
            let mut visit = |c: i64, row: i64| {
                if c < 0 || row < 0 || c >= self.width as i64 || row >= self.height as i64 {
                    return;
                }
                let idx = row as usize * self.width + c as usize;
                if self.region[idx] == 0 {
                    return;
                }
                let d = (c as f64 + 0.5 - g[0]).hypot(row as f64 + 0.5 - g[1]);
                if best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, idx));
                }
            };
            if r == 0 {
                visit(c0, r0);
                continue;
            }
            for c in c0 - r..=c0 + r {
                visit(c, r0 - r);
                visit(c, r0 + r);
            }
            for row in r0 - r + 1..r0 + r {
                visit(c0 - r, row);
                visit(c0 + r, row);
            }
        }
        best.map(|(_, idx)| self.cell_centre(idx))
    }

    /// Centre of cell `idx`, in metres.
    pub(crate) fn cell_centre(&self, idx: usize) -> Point2 {
        let (c, r) = (idx % self.width, idx / self.width);
        self.to_world([c as f64 + 0.5, r as f64 + 0.5])
    }

    /// Checks that the robot may stand at `p` (finite, on the map, clear of obstacles), or says
    /// precisely what is wrong: the check a query runs on its start and goal.
    pub fn validate_endpoint(&self, endpoint: Endpoint, p: Point2) -> Result<(), QueryError> {
        self.check_endpoint(endpoint, p).map(|_| ())
    }

    /// Checks a query endpoint and returns it in grid units, or says precisely what is wrong.
    pub(crate) fn check_endpoint(
        &self,
        endpoint: Endpoint,
        p: Point2,
    ) -> Result<[f64; 2], QueryError> {
        if !(p.x.is_finite() && p.y.is_finite()) {
            return Err(QueryError::NonFinite {
                endpoint,
                x: p.x,
                y: p.y,
            });
        }
        let g = self.to_grid(p);
        let Some(idx) = self.cell_index(g) else {
            let (min, max) = self.bounds();
            return Err(QueryError::OutsideMap {
                endpoint,
                point: p,
                min,
                max,
                nearest_free: self.nearest_free(p),
            });
        };
        if self.region[idx] == 0 {
            return Err(QueryError::InObstacle {
                endpoint,
                point: p,
                clearance_m: self.cell_clearance_m(idx),
                required_m: self.inflation.total_m(),
                nearest_free: self.nearest_free(p),
            });
        }
        Ok(g)
    }

    /// Whether the straight segment between two map points is free for the robot.
    pub fn segment_free(&self, a: Point2, b: Point2) -> bool {
        let (ga, gb) = (self.to_grid(a), self.to_grid(b));
        match (self.cell_index(ga), self.cell_index(gb)) {
            (Some(_), Some(_)) => self.segment_free_grid(ga, gb),
            _ => false,
        }
    }

    /// Smallest clearance (metres) over the cells the segment `a`–`b` touches; 0 if it leaves the map.
    pub fn segment_clearance_m(&self, a: Point2, b: Point2) -> f64 {
        let (ga, gb) = (self.to_grid(a), self.to_grid(b));
        if self.cell_index(ga).is_none() || self.cell_index(gb).is_none() {
            return 0.0;
        }
        ((self.segment_min_dist(ga, gb) - 0.5) * self.resolution).max(0.0)
    }

    /// Segment check in grid units; both ends must lie inside the map.
    ///
    /// Sphere tracing on the distance field skips the cells that the triangle inequality proves
    /// free, so long edges through open space cost a handful of lookups; near obstacles it walks
    /// the exact supercover. The result equals the plain supercover check.
    pub(crate) fn segment_free_grid(&self, a: [f64; 2], b: [f64; 2]) -> bool {
        let need = self.need_cells();
        let mut free = true;
        self.trace(a, b, |idx, d| {
            if !self.free[idx] {
                free = false;
                return Step::Stop;
            }
            Step::Skip(d - need)
        });
        free
    }

    /// Smallest centre-to-centre obstacle distance (cells) over the cells the segment touches.
    pub(crate) fn segment_min_dist(&self, a: [f64; 2], b: [f64; 2]) -> f64 {
        let mut min = f64::INFINITY;
        self.trace(a, b, |_, d| {
            min = min.min(d);
            // No cell within d - min of this one can lower the minimum.
            Step::Skip(d - min)
        });
        min
    }

    /// Visits the cells the segment a→b touches, in order, except those inside a proven disc:
    /// `on_cell(idx, dist)` may answer `Skip(r)`, meaning every cell whose centre is within `r`
    /// of this cell's centre needs no visit. Cells the segment touches over an arc of length s
    /// from the projection of this centre lie within s + √2 of it, hence the 1.5 allowance.
    fn trace(&self, a: [f64; 2], b: [f64; 2], mut on_cell: impl FnMut(usize, f64) -> Step) {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = (dx * dx + dy * dy).sqrt();
        let at = |t: f64| {
            if len > 0.0 {
                [a[0] + dx * (t / len), a[1] + dy * (t / len)]
            } else {
                a
            }
        };
        let mut t = 0.0f64;
        loop {
            let p = at(t);
            let mut jump: Option<f64> = None;
            let mut stopped = false;
            walk_supercover(p, b, |c, r| {
                let idx = r as usize * self.width + c as usize;
                match on_cell(idx, f64::from(self.dist[idx])) {
                    Step::Stop => {
                        stopped = true;
                        false
                    }
                    Step::Skip(radius) if radius - 1.5 > 2.0 && len > 0.0 => {
                        // Arc position of this cell centre's projection onto the segment.
                        let tc =
                            ((c as f64 + 0.5 - a[0]) * dx + (r as f64 + 0.5 - a[1]) * dy) / len;
                        jump = Some(tc + radius - 1.5);
                        false
                    }
                    Step::Skip(_) => true,
                }
            });
            match jump {
                Some(tj) if !stopped && tj < len => t = tj,
                _ => return,
            }
        }
    }

    /// Robot radius + margin in cells, plus the half cell that the clearance definition adds.
    fn need_cells(&self) -> f64 {
        self.inflation.total_m() / self.resolution + 0.5
    }

    /// A uniformly random free point, optionally restricted to one region.
    pub fn sample_free<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        region: Option<RegionId>,
    ) -> Option<Point2> {
        let (lo, hi) = match region {
            Some(r) if r >= 1 && (r as usize) < self.region_start.len() => (
                self.region_start[r as usize - 1],
                self.region_start[r as usize],
            ),
            Some(_) => return None,
            None => (0, self.free_cells.len() as u32),
        };
        if lo == hi {
            return None;
        }
        let idx = self.free_cells[rng.random_range(lo..hi) as usize] as usize;
        Some(self.to_world(jitter(idx, self.width, rng)))
    }

    /// All free cells (grid indices), grouped by region.
    pub(crate) fn free_cells(&self) -> &[u32] {
        &self.free_cells
    }
}

/// What a segment trace does after a cell.
enum Step {
    /// Stop the trace.
    Stop,
    /// Cells with centres within this distance (cells) of this cell's centre need no visit.
    Skip(f64),
}

/// A uniformly random point inside cell `idx`, in grid units, kept off the cell's borders so
/// that float rounding cannot move it into a neighbour.
pub(crate) fn jitter<R: Rng + ?Sized>(idx: usize, width: usize, rng: &mut R) -> [f64; 2] {
    let (c, r) = ((idx % width) as f64, (idx / width) as f64);
    [
        c + 0.001 + 0.998 * rng.random::<f64>(),
        r + 0.001 + 0.998 * rng.random::<f64>(),
    ]
}

/// Visits every cell the segment a→b touches, in order (grid units; both ends inside the map).
/// Where the segment passes exactly through a cell corner, both side cells are visited too, so
/// a path never squeezes diagonally between two blocked cells. Stops early when `visit` says so.
pub(crate) fn walk_supercover(a: [f64; 2], b: [f64; 2], mut visit: impl FnMut(i64, i64) -> bool) {
    let (mut cx, mut cy) = (cell_of(a[0]), cell_of(a[1]));
    let (ex, ey) = (cell_of(b[0]), cell_of(b[1]));
    if !visit(cx, cy) {
        return;
    }
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let sx: i64 = if ex > cx { 1 } else { -1 };
    let sy: i64 = if ey > cy { 1 } else { -1 };
    // Counting the remaining steps per axis, rather than comparing t with 1, makes the walk end
    // exactly in b's cell whatever the rounding.
    let mut nx = (ex - cx).abs();
    let mut ny = (ey - cy).abs();
    let t_delta_x = if nx > 0 {
        1.0 / dx.abs()
    } else {
        f64::INFINITY
    };
    let t_delta_y = if ny > 0 {
        1.0 / dy.abs()
    } else {
        f64::INFINITY
    };
    let mut t_max_x = if nx == 0 {
        f64::INFINITY
    } else if sx > 0 {
        (cx as f64 + 1.0 - a[0]) * t_delta_x
    } else {
        (a[0] - cx as f64) * t_delta_x
    };
    let mut t_max_y = if ny == 0 {
        f64::INFINITY
    } else if sy > 0 {
        (cy as f64 + 1.0 - a[1]) * t_delta_y
    } else {
        (a[1] - cy as f64) * t_delta_y
    };
    while nx > 0 || ny > 0 {
        let diff = t_max_x - t_max_y;
        if nx > 0 && ny > 0 && diff.abs() <= 1e-9 * t_max_x.abs().max(1.0) {
            // Through a corner: the two side cells count as touched.
            if !visit(cx + sx, cy) || !visit(cx, cy + sy) {
                return;
            }
            cx += sx;
            cy += sy;
            nx -= 1;
            ny -= 1;
            t_max_x += t_delta_x;
            t_max_y += t_delta_y;
        } else if ny == 0 || (nx > 0 && diff < 0.0) {
            cx += sx;
            nx -= 1;
            t_max_x += t_delta_x;
        } else {
            cy += sy;
            ny -= 1;
            t_max_y += t_delta_y;
        }
        if !visit(cx, cy) {
            return;
        }
    }
}

/// `v.floor()` as an integer. Without SSE4.1 `floor` is a library call, and segment walks
/// start two per jump; coordinates inside the map are never negative, where truncation is
/// the floor.
fn cell_of(v: f64) -> i64 {
    if v >= 0.0 { v as i64 } else { v.floor() as i64 }
}

/// Free cells that are ridges of the distance field along some direction: an approximate
/// medial axis. Samples there have the most clearance and fall into doors and corridors
/// far more often than uniform samples do.
fn ridge_cells(w: usize, h: usize, d2: &[u32], free: &[bool]) -> Vec<u32> {
    let mut out = Vec::new();
    if w < 3 || h < 3 {
        return out;
    }
    for r in 1..h - 1 {
        for c in 1..w - 1 {
            let i = r * w + c;
            if !free[i] {
                continue;
            }
            let v = d2[i];
            let ridge = |a: usize, b: usize| {
                let (da, db) = (d2[a], d2[b]);
                v >= da && v >= db && (v > da || v > db)
            };
            if ridge(i - 1, i + 1)
                || ridge(i - w, i + w)
                || ridge(i - w - 1, i + w + 1)
                || ridge(i - w + 1, i + w - 1)
            {
                out.push(i as u32);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plain_supercover(cs: &ConfigSpace, a: [f64; 2], b: [f64; 2]) -> bool {
        let mut ok = true;
        walk_supercover(a, b, |c, r| {
            ok = cs.region[r as usize * cs.width + c as usize] != 0;
            ok
        });
        ok
    }

    /// The sphere-traced check must agree exactly with the full supercover walk.
    #[test]
    fn sphere_tracing_equals_the_full_walk() {
        let (w, h) = (120usize, 90usize);
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state >> 11
        };
        let mut blocked = vec![false; w * h];
        for _ in 0..25 {
            let (x, y, rw, rh) = (
                next() as usize % w,
                next() as usize % h,
                1 + next() as usize % 10,
                1 + next() as usize % 10,
            );
            for r in y..(y + rh).min(h) {
                for c in x..(x + rw).min(w) {
                    blocked[r * w + c] = true;
                }
            }
        }
        let map = PlanningGrid {
            width: w,
            height: h,
            resolution: 0.05,
            origin_x: 0.0,
            origin_y: 0.0,
            blocked,
        };
        for radius in [0.0, 0.05, 0.2] {
            let cs = ConfigSpace::new(
                &map,
                Inflation {
                    robot_radius_m: radius,
                    safety_margin_m: 0.0,
                },
            )
            .expect("cspace");
            let mut agree = 0;
            for _ in 0..20_000 {
                let u = |n: u64, m: usize| (n % (m as u64 * 1000)) as f64 / 1000.0;
                let a = [u(next(), w), u(next(), h)];
                // Also axis-aligned and corner-crossing segments, where rounding matters most.
                let b = match next() % 4 {
                    0 => [a[0], u(next(), h)],
                    1 => [u(next(), w), a[1]],
                    2 => {
                        let d = (next() % 40) as f64;
                        [
                            (a[0].floor() + d).min(w as f64 - 0.5),
                            (a[1].floor() + d).min(h as f64 - 0.5),
                        ]
                    }
                    _ => [u(next(), w), u(next(), h)],
                };
                assert_eq!(
                    cs.segment_free_grid(a, b),
                    plain_supercover(&cs, a, b),
                    "{a:?} {b:?} r={radius}"
                );
                let mut min = f32::INFINITY;
                walk_supercover(a, b, |c, r| {
                    min = min.min(cs.dist[r as usize * cs.width + c as usize]);
                    true
                });
                assert_eq!(cs.segment_min_dist(a, b), f64::from(min), "{a:?} {b:?}");
                agree += 1;
            }
            assert_eq!(agree, 20_000);
        }
    }
}
