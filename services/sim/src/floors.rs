//! Procedurally generated building floors for training: rooms, corridors, doors (some narrow),
//! open halls and clutter, as occupancy grids a ROS map_server would load. A policy trained on
//! many of them has seen more kinds of places than any one shared map holds, so it does not
//! overfit to the map it was trained on, and training needs no map at all.
//!
//! The floor is a binary space partition: the building's rectangle is split by walls, each with
//! one or more doors, until the pieces are room-sized; some splits carve a corridor between two
//! walls instead. Walls never cover a door's approach, so every piece stays reachable. Clutter
//! (pillars, boxes) goes into rooms and halls one piece at a time, and a piece that would cut a
//! part of the floor off for the robot (its disc of `robot_radius_m` no longer gets through) is
//! not placed.
//!
//! [`furnish`] furnishes any floor, generated or a real map, with a deterministic mix of
//! library models and placeholders where each fits (the benchmarks' furniture).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use tosm::{Occupancy, OccupancyGrid, Pose2, Pose3};

use crate::spec::{Colour, ObjectSpec, Shape, Size3};

/// Ranges the generator draws from (metres unless named otherwise).
#[derive(Clone, Debug, PartialEq)]
pub struct FloorParams {
    /// Metres per cell.
    pub resolution: f64,
    /// Width of the building.
    pub width_m: (f64, f64),
    /// Depth of the building.
    pub height_m: (f64, f64),
    /// Wall thickness.
    pub wall_m: (f64, f64),
    /// Door width.
    pub door_m: (f64, f64),
    /// Share of doors drawn narrow, from `narrow_door_m`.
    pub narrow_share: f64,
    /// Width of a narrow door (a narrow passage for the robot).
    pub narrow_door_m: (f64, f64),
    /// A piece narrower than twice this on both sides is not split further.
    pub min_room_m: f64,
    /// A piece wider than this on either side is always split (unless it becomes a hall).
    pub max_room_m: f64,
    /// Probability that a split carves a corridor between two walls.
    pub corridor_share: f64,
    /// Corridor width.
    pub corridor_m: (f64, f64),
    /// Probability that a large piece stays one open hall.
    pub hall_share: f64,
    /// Clutter pieces per 100 m² of floor.
    pub clutter_per_100m2: (f64, f64),
    /// Side of a clutter piece.
    pub clutter_m: (f64, f64),
    /// Radius of the robot the floor must stay passable for.
    pub robot_radius_m: f64,
}

impl Default for FloorParams {
    fn default() -> Self {
        Self {
            resolution: 0.05,
            width_m: (16.0, 36.0),
            height_m: (12.0, 28.0),
            wall_m: (0.1, 0.25),
            door_m: (0.9, 1.6),
            narrow_share: 0.25,
            narrow_door_m: (0.8, 0.9),
            min_room_m: 2.5,
            max_room_m: 9.0,
            corridor_share: 0.35,
            corridor_m: (1.2, 2.4),
            hall_share: 0.15,
            clutter_per_100m2: (0.5, 4.0),
            clutter_m: (0.2, 0.9),
            robot_radius_m: 0.36,
        }
    }
}

/// A rectangle of cells, `[x0, x1) × [y0, y1)`.
#[derive(Clone, Copy, Debug)]
struct Rect {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl Rect {
    fn w(self) -> usize {
        self.x1 - self.x0
    }
    fn h(self) -> usize {
        self.y1 - self.y0
    }
}

struct Canvas {
    width: usize,
    height: usize,
    blocked: Vec<bool>,
    /// Cells walls must not cover: every door with its approach on both sides.
    keep_open: Vec<bool>,
    rng: ChaCha8Rng,
    p: FloorParams,
    /// Leaf pieces (rooms, halls, corridors) for the clutter.
    leaves: Vec<Rect>,
}

#[allow(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    reason = "metre ranges become small positive cell counts"
)]
fn cells(m: f64, resolution: f64) -> usize {
    (m / resolution).round().max(1.0) as usize
}

impl Canvas {
    fn draw(&mut self, range: (f64, f64)) -> usize {
        let m = if range.1 > range.0 {
            self.rng.random_range(range.0..range.1)
        } else {
            range.0
        };
        cells(m, self.p.resolution)
    }

    fn fill(&mut self, r: Rect, respect_doors: bool) {
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let i = y * self.width + x;
                if !(respect_doors && self.keep_open[i]) {
                    self.blocked[i] = true;
                }
            }
        }
    }

    fn open(&mut self, r: Rect) {
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                self.keep_open[y * self.width + x] = true;
            }
        }
    }

    /// A wall across `r` at `at` (a column when `vertical`, else a row), `t` cells thick, with
    /// one to three doors.
    fn wall(&mut self, r: Rect, vertical: bool, at: usize, t: usize) {
        let wall = if vertical {
            Rect {
                x0: at,
                x1: at + t,
                y0: r.y0,
                y1: r.y1,
            }
        } else {
            Rect {
                x0: r.x0,
                x1: r.x1,
                y0: at,
                y1: at + t,
            }
        };
        let length = if vertical { r.h() } else { r.w() };
        let doors =
            1 + usize::from(length > cells(8.0, self.p.resolution) && self.rng.random_bool(0.5));
        let approach = cells(0.8, self.p.resolution);
        let end_gap = cells(0.3, self.p.resolution);
        for _ in 0..doors {
            let narrow = self.rng.random_bool(self.p.narrow_share);
            let width = if narrow {
                self.draw(self.p.narrow_door_m)
            } else {
                self.draw(self.p.door_m)
            };
            if width + 2 * end_gap >= length {
                continue;
            }
            let start = self.rng.random_range(end_gap..length - width - end_gap);
            let door = if vertical {
                Rect {
                    x0: at.saturating_sub(approach),
                    x1: (at + t + approach).min(self.width),
                    y0: r.y0 + start,
                    y1: r.y0 + start + width,
                }
            } else {
                Rect {
                    x0: r.x0 + start,
                    x1: r.x0 + start + width,
                    y0: at.saturating_sub(approach),
                    y1: (at + t + approach).min(self.height),
                }
            };
            self.open(door);
        }
        self.fill(wall, true);
    }

    fn split(&mut self, r: Rect, depth: u32) {
        let res = self.p.resolution;
        let min = cells(self.p.min_room_m, res);
        let max = cells(self.p.max_room_m, res);
        let t = self.draw(self.p.wall_m);
        let can_split_x = r.w() >= 2 * min + t;
        let can_split_y = r.h() >= 2 * min + t;
        let big = r.w() > max || r.h() > max;
        let stop = (!can_split_x && !can_split_y)
            || (!big && depth > 0 && self.rng.random_bool(0.35))
            || (big
                && depth > 0
                && r.w() * r.h() < 4 * max * max
                && self.rng.random_bool(self.p.hall_share));
        if stop {
            self.leaves.push(r);
            return;
        }
        let vertical = match (can_split_x, can_split_y) {
            (true, false) => true,
            (false, true) => false,
            _ => r.w() > r.h() || (r.w() == r.h() && self.rng.random_bool(0.5)),
        };
        let length = if vertical { r.w() } else { r.h() };
        let corridor = self.draw(self.p.corridor_m);
        if self.rng.random_bool(self.p.corridor_share) && length >= 2 * min + 2 * t + corridor {
            // room | corridor | room
            let a = self.rng.random_range(min..=length - min - 2 * t - corridor);
            let (first, second) = (a, a + t + corridor);
            let base = if vertical { r.x0 } else { r.y0 };
            self.wall(r, vertical, base + first, t);
            self.wall(r, vertical, base + second, t);
            let (lo, mid, hi) = if vertical {
                (
                    Rect {
                        x1: base + first,
                        ..r
                    },
                    Rect {
                        x0: base + first + t,
                        x1: base + second,
                        ..r
                    },
                    Rect {
                        x0: base + second + t,
                        ..r
                    },
                )
            } else {
                (
                    Rect {
                        y1: base + first,
                        ..r
                    },
                    Rect {
                        y0: base + first + t,
                        y1: base + second,
                        ..r
                    },
                    Rect {
                        y0: base + second + t,
                        ..r
                    },
                )
            };
            self.leaves.push(mid);
            self.split(lo, depth + 1);
            self.split(hi, depth + 1);
        } else {
            let a = self.rng.random_range(min..=length - min - t);
            let base = if vertical { r.x0 } else { r.y0 };
            self.wall(r, vertical, base + a, t);
            let (lo, hi) = if vertical {
                (
                    Rect { x1: base + a, ..r },
                    Rect {
                        x0: base + a + t,
                        ..r
                    },
                )
            } else {
                (
                    Rect { y1: base + a, ..r },
                    Rect {
                        y0: base + a + t,
                        ..r
                    },
                )
            };
            self.split(lo, depth + 1);
            self.split(hi, depth + 1);
        }
    }

    /// Regions of the floor the robot's disc can move in, counting only those of at least a
    /// square metre.
    fn passable_regions(&self) -> usize {
        let r = self.p.robot_radius_m / self.p.resolution;
        let d2 = grid::distance::squared_distance_transform(
            &self.blocked,
            self.width,
            self.height,
            grid::distance::Outside::Blocked,
        );
        let mask: Vec<bool> = d2.iter().map(|&d| f64::from(d) >= r * r).collect();
        let regions = grid::regions::label(&mask, self.width, self.height);
        let square_metre = 1.0 / (self.p.resolution * self.p.resolution);
        regions
            .sizes
            .iter()
            .filter(|&&s| f64::from(s) >= square_metre)
            .count()
    }

    fn clutter(&mut self) {
        let res = self.p.resolution;
        let area_m2 = (self.width * self.height) as f64 * res * res;
        let (lo, hi) = self.p.clutter_per_100m2;
        let density = if hi > lo {
            self.rng.random_range(lo..hi)
        } else {
            lo
        };
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a small positive count"
        )]
        let pieces = (density * area_m2 / 100.0).round() as usize;
        let mut regions = self.passable_regions();
        let leaves = self.leaves.clone();
        for _ in 0..pieces {
            if leaves.is_empty() {
                break;
            }
            let room = leaves[self.rng.random_range(0..leaves.len())];
            let (w, h) = (self.draw(self.p.clutter_m), self.draw(self.p.clutter_m));
            if w + 2 >= room.w() || h + 2 >= room.h() {
                continue;
            }
            let x0 = room.x0 + self.rng.random_range(1..room.w() - w - 1);
            let y0 = room.y0 + self.rng.random_range(1..room.h() - h - 1);
            let piece = Rect {
                x0,
                y0,
                x1: x0 + w,
                y1: y0 + h,
            };
            let before = self.blocked.clone();
            self.fill(piece, true);
            let now = self.passable_regions();
            if now > regions {
                self.blocked = before;
            } else {
                regions = now;
            }
        }
    }
}

/// A generated floor: same `seed`, same floor. The grid's origin is (0, 0); outside the outer
/// walls nothing is known.
pub fn generate_floor(params: &FloorParams, seed: u64) -> OccupancyGrid {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let res = params.resolution;
    let pick = |rng: &mut ChaCha8Rng, r: (f64, f64)| {
        if r.1 > r.0 {
            rng.random_range(r.0..r.1)
        } else {
            r.0
        }
    };
    let (wm, hm) = (
        pick(&mut rng, params.width_m),
        pick(&mut rng, params.height_m),
    );
    let margin = cells(0.5, res);
    let outer = cells(pick(&mut rng, params.wall_m), res);
    let (bw, bh) = (cells(wm, res), cells(hm, res));
    let (width, height) = (bw + 2 * margin, bh + 2 * margin);
    let mut canvas = Canvas {
        width,
        height,
        blocked: vec![false; width * height],
        keep_open: vec![false; width * height],
        rng,
        p: params.clone(),
        leaves: Vec::new(),
    };
    let inside = Rect {
        x0: margin + outer,
        y0: margin + outer,
        x1: margin + bw - outer,
        y1: margin + bh - outer,
    };
    canvas.split(inside, 0);
    canvas.clutter();
    let building = Rect {
        x0: margin,
        y0: margin,
        x1: margin + bw,
        y1: margin + bh,
    };
    let mut cells_out = vec![Occupancy::Unknown; width * height];
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            let in_building =
                x >= building.x0 && x < building.x1 && y >= building.y0 && y < building.y1;
            let in_inside = x >= inside.x0 && x < inside.x1 && y >= inside.y0 && y < inside.y1;
            cells_out[i] = if in_inside && !canvas.blocked[i] {
                Occupancy::Free
            } else if in_building {
                Occupancy::Occupied
            } else {
                Occupancy::Unknown
            };
        }
    }
    OccupancyGrid {
        width,
        height,
        resolution: res,
        origin: Pose2::new(0.0, 0.0, 0.0),
        cells: cells_out,
    }
}

/// Furniture for `grid`: a deterministic mix of library models and placeholders, each placed
/// where its whole footprint and a margin are free.
pub fn furnish(grid: &OccupancyGrid, count: usize, seed: u64) -> Vec<ObjectSpec> {
    // (class, shape, size, colour)
    let kinds: [(&str, Shape, Size3, Colour); 6] = [
        (
            "Table",
            Shape::Box,
            Size3::new(1.2, 0.8, 0.75),
            Colour::rgb(150, 100, 50),
        ),
        (
            "Chair",
            Shape::Box,
            Size3::new(0.5, 0.5, 0.9),
            Colour::rgb(90, 60, 30),
        ),
        (
            "Shelf",
            Shape::Box,
            Size3::new(0.4, 1.5, 1.8),
            Colour::rgb(120, 120, 130),
        ),
        (
            "Cabinet",
            Shape::Box,
            Size3::new(0.6, 0.5, 1.0),
            Colour::rgb(200, 200, 190),
        ),
        (
            "VendingMachine",
            Shape::Box,
            Size3::new(0.8, 0.7, 1.8),
            Colour::rgb(220, 20, 20),
        ),
        (
            "Bin",
            Shape::Cylinder,
            Size3::new(0.4, 0.4, 0.6),
            Colour::rgb(40, 90, 200),
        ),
    ];
    let free: Vec<usize> = grid
        .cells
        .iter()
        .enumerate()
        .filter(|(_, c)| **c == Occupancy::Free)
        .map(|(i, _)| i)
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x00b1_ec75);
    let mut out = Vec::with_capacity(count);
    let mut tries = 0usize;
    while out.len() < count && !free.is_empty() && tries < count * 200 {
        tries += 1;
        let (class, shape, size, colour) = kinds[out.len() % kinds.len()];
        let cell = free[rng.random_range(0..free.len())];
        let (col, row) = (cell % grid.width, cell / grid.width);
        let (x, y) = grid.cell_center(col, row);
        let reach = size.x.hypot(size.y) / 2.0 + 0.1;
        if !disc_free(grid, x, y, reach) {
            continue;
        }
        let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        out.push(ObjectSpec {
            id: format!("http://mentalsim.example/bench#object{}", out.len()),
            class: Some(format!("https://mentalsim.example/tosm#{class}")),
            shape,
            size,
            pose: Pose3::new(x, y, size.z / 2.0, yaw),
            colour,
            open: false,
        });
    }
    out
}

/// Whether every cell within `r` of `(x, y)` is free.
fn disc_free(grid: &OccupancyGrid, x: f64, y: f64, r: f64) -> bool {
    let res = grid.resolution;
    #[allow(
        clippy::cast_possible_truncation,
        reason = "a furniture item's reach in cells: small and positive"
    )]
    let n = (r / res).ceil() as isize;
    let Some((c0, r0)) = grid.cell_of(x, y) else {
        return false;
    };
    for dr in -n..=n {
        for dc in -n..=n {
            if ((dr * dr + dc * dc) as f64) * res * res > r * r {
                continue;
            }
            // A cell left of or below the grid is not free.
            let (Some(c), Some(rr)) = (c0.checked_add_signed(dc), r0.checked_add_signed(dr)) else {
                return false;
            };
            if !grid.is_free(c, rr) {
                return false;
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floors_are_deterministic_varied_and_passable_in_one_piece() {
        let p = FloorParams::default();
        let a = generate_floor(&p, 7);
        assert_eq!(a, generate_floor(&p, 7), "same seed, same floor");
        let b = generate_floor(&p, 8);
        assert_ne!(a.cells, b.cells, "another seed, another floor");
        for seed in 0..12 {
            let g = generate_floor(&p, seed);
            let free = g.free_area_m2();
            assert!(free > 0.5 * 16.0 * 12.0, "seed {seed}: only {free} m² free");
            // Walls split the floor: more than one room, so it is not one empty hall.
            let blocked: Vec<bool> = g.cells.iter().map(|c| *c != Occupancy::Free).collect();
            let mut canvas_like = blocked.clone();
            let d2 = grid::distance::squared_distance_transform(
                &canvas_like,
                g.width,
                g.height,
                grid::distance::Outside::Blocked,
            );
            let r = p.robot_radius_m / p.resolution;
            let mask: Vec<bool> = d2.iter().map(|&d| f64::from(d) >= r * r).collect();
            let regions = grid::regions::label(&mask, g.width, g.height);
            let largest = regions.largest().expect("some room");
            let passable: u32 = regions.sizes.iter().sum();
            // Nearly all of the floor the robot can stand on is one connected piece (tiny
            // corners behind clutter aside).
            assert!(
                f64::from(regions.sizes[largest as usize - 1]) >= 0.95 * f64::from(passable),
                "seed {seed}: {} regions, sizes {:?}",
                regions.count(),
                regions.sizes
            );
            canvas_like.clear();
        }
    }
}
