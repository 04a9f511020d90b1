//! Path distance to a goal through the free region: a navigation function on a coarse copy of
//! the world's grid. The shaped training reward measures progress with it, so that driving round
//! a wall towards its door counts as progress where the straight-line distance says "further
//! away". Only the reward uses it; the policy never sees it.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::spec::as_u32;
use crate::world::{Frame, World};

/// Coarse cells searched around a point for a reachable one: a robot pressed against a wall
/// stands in a cell outside the free region, whose neighbours are in it.
const REACH: isize = 2;

/// Path distances to one goal, metres, on a grid of `cell` × `cell` squares.
#[derive(Clone, Debug)]
pub struct PathField {
    frame: Frame,
    /// Fine cells per coarse cell, along each side.
    k: usize,
    cw: usize,
    ch: usize,
    /// Path distance from each coarse cell's centre to the goal; infinite where unreachable.
    dist: Vec<f32>,
    /// The neighbour one step closer to the goal (the goal's cell points at itself).
    next: Vec<u32>,
    goal: (f64, f64),
    /// Coarse cell size, metres.
    cell: f64,
}

impl PathField {
    /// The field of `goal` in `world`, on coarse cells of about `cell_m` metres (at least one of
    /// the world's cells). A coarse cell is passable when any of its cells is in the free
    /// region; moves are 8-connected, diagonals only between two passable sides.
    pub fn new(world: &World, goal: (f64, f64), cell_m: f64) -> PathField {
        let frame = world.frame().clone();
        let res = world.resolution();
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a small positive ratio"
        )]
        let k = ((cell_m / res).round() as usize).max(1);
        let (cw, ch) = (frame.pw.div_ceil(k), frame.ph.div_ceil(k));
        let mut passable = vec![false; cw * ch];
        for &c in world.region_cells() {
            let c = c as usize;
            passable[(c / frame.pw / k) * cw + (c % frame.pw) / k] = true;
        }
        let cell = k as f64 * res;
        let mut field = PathField {
            frame,
            k,
            cw,
            ch,
            dist: vec![f32::INFINITY; cw * ch],
            next: (0..cw * ch).map(as_u32).collect(),
            goal,
            cell,
        };
        let Some(g) = field.coarse_index(goal.0, goal.1) else {
            return field;
        };
        passable[g] = true;
        field.search(&passable, g);
        field
    }

    /// Dijkstra from the goal's cell over passable cells.
    #[allow(clippy::cast_possible_truncation, reason = "metres fit an f32")]
    fn search(&mut self, passable: &[bool], g: usize) {
        let (gx, gy) = self.centre(g);
        let d0 = (gx - self.goal.0).hypot(gy - self.goal.1) as f32;
        self.dist[g] = d0;
        let mut heap = BinaryHeap::new();
        heap.push(Reverse((d0.to_bits(), as_u32(g))));
        let (cw, ch) = (self.cw, self.ch);
        let straight = self.cell as f32;
        let diagonal = straight * std::f32::consts::SQRT_2;
        while let Some(Reverse((bits, i))) = heap.pop() {
            let d = f32::from_bits(bits);
            let i = i as usize;
            if d > self.dist[i] {
                continue;
            }
            let (x, y) = (i % cw, i / cw);
            for (dx, dy) in [
                (-1isize, 0isize),
                (1, 0),
                (0, -1),
                (0, 1),
                (-1, -1),
                (1, -1),
                (-1, 1),
                (1, 1),
            ] {
                let (nx, ny) = (x.wrapping_add_signed(dx), y.wrapping_add_signed(dy));
                if nx >= cw || ny >= ch {
                    continue;
                }
                let j = ny * cw + nx;
                if !passable[j] {
                    continue;
                }
                let step = if dx != 0 && dy != 0 {
                    // No corner cutting: both sides of the diagonal must be passable.
                    if !(passable[y * cw + nx] && passable[ny * cw + x]) {
                        continue;
                    }
                    diagonal
                } else {
                    straight
                };
                let nd = d + step;
                if nd < self.dist[j] {
                    self.dist[j] = nd;
                    self.next[j] = as_u32(i);
                    heap.push(Reverse((nd.to_bits(), as_u32(j))));
                }
            }
        }
    }

    /// The goal.
    pub fn goal(&self) -> (f64, f64) {
        self.goal
    }

    /// Path distance from `(x, y)` to the goal, metres: the best over nearby reachable cells of
    /// the straight distance to the cell's centre plus the cell's path distance, and within two
    /// cells of the goal the straight distance to it (every cell's sum is at least that). `None`
    /// when no reachable cell is near (outside the free region's reach).
    pub fn distance(&self, x: f64, y: f64) -> Option<f64> {
        let (_, d) = self.best_cell(x, y)?;
        let direct = (self.goal.0 - x).hypot(self.goal.1 - y);
        Some(if direct <= 2.0 * self.cell { direct } else { d })
    }

    /// A point one or two coarse cells along the path from `(x, y)`: the direction to drive in
    /// (the goal itself once it is that close). `None` as for [`PathField::distance`].
    pub fn lookahead(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let (i, _) = self.best_cell(x, y)?;
        let n = self.next[i] as usize;
        let direct = (self.goal.0 - x).hypot(self.goal.1 - y);
        if n == i || self.next[n] as usize == n || direct <= 2.0 * self.cell {
            return Some(self.goal);
        }
        Some(self.centre(n))
    }

    /// The point `ahead_m` along the path from `(x, y)` to the goal (the goal once the path
    /// is shorter): a path tracker's carrot on the field's shortest path. `None` as for
    /// [`PathField::distance`].
    pub fn carrot(&self, x: f64, y: f64, ahead_m: f64) -> Option<(f64, f64)> {
        let (mut i, _) = self.best_cell(x, y)?;
        let mut at = (x, y);
        let mut left = ahead_m;
        loop {
            let n = self.next[i] as usize;
            let to = if n == i { self.goal } else { self.centre(n) };
            let d = (to.0 - at.0).hypot(to.1 - at.1);
            if d >= left {
                let t = left / d;
                return Some((at.0 + t * (to.0 - at.0), at.1 + t * (to.1 - at.1)));
            }
            if n == i {
                return Some(self.goal);
            }
            left -= d;
            at = to;
            i = n;
        }
    }

    /// As [`PathField::lookahead`], but from the cell holding `(x, y)` alone when it is
    /// reachable (one lookup instead of a search of the cells around): for people, who walk
    /// inside the free region and ask every step.
    pub fn lookahead_quick(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        match self.coarse_index(x, y) {
            Some(i) if self.dist[i].is_finite() => {
                let n = self.next[i] as usize;
                let (dx, dy) = (self.goal.0 - x, self.goal.1 - y);
                let near = 2.0 * self.cell;
                if n == i || self.next[n] as usize == n || dx * dx + dy * dy <= near * near {
                    Some(self.goal)
                } else {
                    Some(self.centre(n))
                }
            }
            _ => self.lookahead(x, y),
        }
    }

    fn best_cell(&self, x: f64, y: f64) -> Option<(usize, f64)> {
        let (gx, gy) = self.frame.to_grid(x, y);
        let k = self.k as f64;
        #[allow(
            clippy::cast_possible_truncation,
            reason = "grid coordinates of a finite point are far below isize::MAX"
        )]
        let (cx, cy) = ((gx / k).floor() as isize, (gy / k).floor() as isize);
        if !(gx.is_finite() && gy.is_finite()) {
            return None;
        }
        let mut best: Option<(usize, f64)> = None;
        for dy in -REACH..=REACH {
            for dx in -REACH..=REACH {
                let (nx, ny) = (cx + dx, cy + dy);
                #[allow(
                    clippy::cast_possible_wrap,
                    reason = "grid sizes are far below isize::MAX"
                )]
                if nx < 0 || ny < 0 || nx >= self.cw as isize || ny >= self.ch as isize {
                    continue;
                }
                #[allow(clippy::cast_sign_loss, reason = "checked non-negative above")]
                let j = ny as usize * self.cw + nx as usize;
                let d = self.dist[j];
                if !d.is_finite() {
                    continue;
                }
                let (px, py) = self.centre(j);
                let total = f64::from(d) + (px - x).hypot(py - y);
                if best.is_none_or(|(_, b)| total < b) {
                    best = Some((j, total));
                }
            }
        }
        best
    }

    /// Padded coarse index of the cell holding world point `(x, y)`.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "checked to lie inside the grid before the cast"
    )]
    fn coarse_index(&self, x: f64, y: f64) -> Option<usize> {
        let (gx, gy) = self.frame.to_grid(x, y);
        let k = self.k as f64;
        let (cx, cy) = (gx / k, gy / k);
        (cx >= 0.0 && cy >= 0.0 && cx < self.cw as f64 && cy < self.ch as f64)
            .then(|| cy as usize * self.cw + cx as usize)
    }

    /// World point at the centre of coarse cell `i`.
    fn centre(&self, i: usize) -> (f64, f64) {
        let k = self.k as f64;
        let (x, y) = ((i % self.cw) as f64, (i / self.cw) as f64);
        self.frame.to_world((x + 0.5) * k, (y + 0.5) * k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::{FloorMap, Occupancy, OccupancyGrid, Pose2, RobotSpec, WorldSpec};

    /// A 6 m × 4 m room split by a wall at x = 3 m with a door at its top, y in [2.9, 4).
    fn split_room() -> std::sync::Arc<World> {
        let (w, h) = (120usize, 80usize);
        let origin = Pose2::new(0.0, 0.0, 0.0);
        let mut grid = OccupancyGrid::filled(w, h, 0.05, origin, Occupancy::Free);
        for y in 0..h {
            for x in 0..w {
                let border = x == 0 || y == 0 || x == w - 1 || y == h - 1;
                let wall = (59..=61).contains(&x) && y < 58;
                if border || wall {
                    grid.cells[y * w + x] = Occupancy::Occupied;
                }
            }
        }
        World::build(WorldSpec {
            id: "split-room".into(),
            floor: Some(FloorMap {
                id: "split-room".into(),
                grid,
                wall_height: 2.5,
                frame_id: "map".into(),
            }),
            walls: vec![],
            objects: vec![],
            robot: RobotSpec::example_differential(),
            people: Default::default(),
            notes: vec![],
        })
        .expect("world")
    }

    #[test]
    fn the_path_goes_through_the_door_not_through_the_wall() {
        let world = split_room();
        let field = PathField::new(&world, (4.5, 1.0), 0.2);
        // From (1.5, 1.0) the straight line is 3 m; the path climbs to the door, whose free
        // centres start about y = 3.2 m, round the wall's end and down again: two legs of
        // about hypot(1.2, 2.2) m and the 0.6 m through the door, 5.6 m.
        let d = field.distance(1.5, 1.0).expect("reachable");
        assert!((5.3..6.5).contains(&d), "path distance {d}");
        // Beside the goal the path distance is the straight one, to within a cell.
        let near = field.distance(4.2, 1.0).expect("reachable");
        assert!((near - 0.3).abs() < 0.2, "near {near}");
        // The way to go from the left room is up, towards the door.
        let (_, ly) = field.lookahead(1.5, 1.0).expect("reachable");
        assert!(ly > 1.0, "lookahead y {ly}");
        // Far outside the map nothing is reachable.
        assert_eq!(field.distance(-50.0, -50.0), None);
    }

    #[test]
    fn the_distance_falls_along_the_lookahead() {
        let world = split_room();
        let field = PathField::new(&world, (4.5, 1.0), 0.2);
        let mut p = (1.5, 1.0);
        let mut d = field.distance(p.0, p.1).expect("reachable");
        for _ in 0..200 {
            let t = field.lookahead(p.0, p.1).expect("reachable");
            let (dx, dy) = (t.0 - p.0, t.1 - p.1);
            let n = dx.hypot(dy);
            if n < 0.05 {
                break;
            }
            p = (p.0 + 0.05 * dx / n, p.1 + 0.05 * dy / n);
            let nd = field.distance(p.0, p.1).expect("reachable");
            assert!(
                nd <= d + 1e-3,
                "the distance rose from {d} to {nd} at {p:?}"
            );
            d = nd;
        }
        assert!(
            d < 0.3,
            "followed the lookahead to within {d} m of the goal"
        );
        assert!(world.clearance(p.0, p.1) > 0.0);
    }

    #[test]
    fn the_carrot_lies_ahead_on_the_path_and_is_the_goal_once_nearer() {
        let world = split_room();
        let field = PathField::new(&world, (4.5, 1.0), 0.2);
        // From the left room the carrot 1.2 m ahead is up towards the door, 1.2 m away (the
        // path's first steps are nearly straight), not towards the goal through the wall.
        let (cx, cy) = field.carrot(1.5, 1.0, 1.2).expect("reachable");
        assert!(cy > 1.8 && cx >= 1.5, "carrot ({cx}, {cy})");
        let d = (cx - 1.5).hypot(cy - 1.0);
        assert!((1.0..=1.21).contains(&d), "carrot {d} m away");
        // Its path distance is about 1.2 m less than the robot's.
        let ahead = field.distance(1.5, 1.0).unwrap() - field.distance(cx, cy).unwrap();
        assert!((0.9..1.5).contains(&ahead), "{ahead} m along the path");
        // Within the look-ahead of the goal, the carrot is the goal.
        assert_eq!(field.carrot(4.0, 1.2, 1.2), Some((4.5, 1.0)));
        assert_eq!(field.carrot(-50.0, -50.0, 1.2), None);
    }
}
