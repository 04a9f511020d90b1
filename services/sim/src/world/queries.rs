//! Queries on a built world: exact laser casts (grid walk with distance-field jumps, then the
//! objects at laser height in the buckets crossed) and footprint clearance.

use grid::distance::NO_FEATURE;
use parry3d_f64::math::Vector;
use parry3d_f64::query::Ray;

use super::{BLOCKED, OBJECT, World};
use crate::spec::Pose2;

impl World {
    /// Distance from `(x, y)` along heading `angle` to the first thing at laser height, capped
    /// at `max_range` metres. A ray starting inside something returns 0.
    pub fn cast_ray(&self, x: f64, y: f64, angle: f64, max_range: f64) -> f64 {
        let (s, c) = angle.sin_cos();
        self.cast(x, y, c, s, max_range)
    }

    /// Ranges of a laser mounted on the robot at `pose`, for beams at `angles` relative to the
    /// sensor (as [`crate::LaserSpec::beam_angles`] gives them), capped at the laser's longest
    /// range (and not below its shortest). `out` must be as long as `angles`.
    pub fn scan(&self, pose: Pose2, angles: &[f64], out: &mut [f64]) {
        let laser = &self.spec.robot.laser;
        let (s, c) = pose.yaw.sin_cos();
        let m = laser.mount;
        let (lx, ly) = (pose.x + c * m.x - s * m.y, pose.y + s * m.x + c * m.y);
        let heading = pose.yaw + m.yaw;
        for (a, o) in angles.iter().zip(out.iter_mut()) {
            let (s, c) = (heading + a).sin_cos();
            *o = self
                .cast(lx, ly, c, s, laser.range_max)
                .max(laser.range_min);
        }
    }

    /// As [`World::scan`] with the beams' directions given as (cos, sin) relative to the sensor,
    /// which saves two trigonometric calls per beam in the hot loop.
    pub(crate) fn scan_dirs(&self, pose: Pose2, dirs: &[(f64, f64)], out: &mut [f64]) {
        let laser = &self.spec.robot.laser;
        let (s, c) = (pose.yaw + laser.mount.yaw).sin_cos();
        let (sy, cy) = pose.yaw.sin_cos();
        let m = laser.mount;
        let (lx, ly) = (pose.x + cy * m.x - sy * m.y, pose.y + sy * m.x + cy * m.y);
        for ((bc, bs), o) in dirs.iter().zip(out.iter_mut()) {
            let (dx, dy) = (c * bc - s * bs, s * bc + c * bs);
            *o = self
                .cast(lx, ly, dx, dy, laser.range_max)
                .max(laser.range_min);
        }
    }

    /// The ray cast proper: world origin, unit world direction, range in metres.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "positions are checked to lie inside the padded grid before each cast"
    )]
    fn cast(&self, x: f64, y: f64, dx: f64, dy: f64, max_range: f64) -> f64 {
        let f = &self.frame;
        if !(x.is_finite() && y.is_finite() && dx.is_finite() && dy.is_finite()) {
            return 0.0;
        }
        let (ox, oy) = f.to_grid(x, y);
        let (gdx, gdy) = f.dir_to_grid(dx, dy);
        let max_t = max_range.max(0.0) * f.inv_res;
        let (pwf, phf) = (f.pw as f64, f.ph as f64);
        let inv_x = if gdx != 0.0 {
            1.0 / gdx.abs()
        } else {
            f64::INFINITY
        };
        let inv_y = if gdy != 0.0 {
            1.0 / gdy.abs()
        } else {
            f64::INFINITY
        };
        let pw = f.pw;
        let code = &self.laser_code;
        let mut best = max_t;
        let mut last_bucket = usize::MAX;
        let mut t = 0.0f64;
        'jump: loop {
            if t >= best {
                return best * f.res;
            }
            let (px, py) = (ox + t * gdx, oy + t * gdy);
            if !(px >= 0.0 && py >= 0.0 && px < pwf && py < phf) {
                // Only a ray that starts outside the map gets here: outside is solid.
                return t.min(best) * f.res;
            }
            let (mut cx, mut cy) = (px as usize, py as usize);
            let mut idx = cy * pw + cx;
            let c = code[idx];
            if c == BLOCKED {
                return t.min(best) * f.res;
            }
            if c != 0 && c != OBJECT {
                t += f64::from(c);
                continue 'jump;
            }
            // Step cell by cell (Amanatides–Woo) until a jump is possible again.
            let mut next_x = if gdx > 0.0 {
                t + ((cx + 1) as f64 - px) * inv_x
            } else if gdx < 0.0 {
                t + (px - cx as f64) * inv_x
            } else {
                f64::INFINITY
            };
            let mut next_y = if gdy > 0.0 {
                t + ((cy + 1) as f64 - py) * inv_y
            } else if gdy < 0.0 {
                t + (py - cy as f64) * inv_y
            } else {
                f64::INFINITY
            };
            let mut enter = t;
            loop {
                let c = code[idx];
                if c == BLOCKED {
                    return enter.min(best) * f.res;
                }
                if enter >= best {
                    return best * f.res;
                }
                if c == OBJECT {
                    let b = self.laser_buckets.bucket_of(cx, cy);
                    if b != last_bucket {
                        last_bucket = b;
                        best = best.min(self.hit_objects(b, x, y, dx, dy, best));
                    }
                } else if c != 0 {
                    t = enter + f64::from(c);
                    continue 'jump;
                }
                if next_x < next_y {
                    enter = next_x;
                    next_x += inv_x;
                    cx = if gdx > 0.0 {
                        cx + 1
                    } else {
                        cx.wrapping_sub(1)
                    };
                } else {
                    enter = next_y;
                    next_y += inv_y;
                    cy = if gdy > 0.0 {
                        cy + 1
                    } else {
                        cy.wrapping_sub(1)
                    };
                }
                if cx >= pw || cy >= f.ph {
                    return enter.min(best) * f.res;
                }
                idx = cy * pw + cx;
            }
        }
    }

    /// Nearest hit, in cells, of a laser ray with the solids listed in bucket `b`.
    fn hit_objects(&self, b: usize, x: f64, y: f64, dx: f64, dy: f64, best_cells: f64) -> f64 {
        let res = self.frame.res;
        let ray = Ray::new(Vector::new(x, y, self.laser_z), Vector::new(dx, dy, 0.0));
        let mut best = best_cells * res;
        for &i in self.laser_buckets.get(b) {
            if let Some(s) = self.solids.get(i as usize)
                && let Some(toi) = s.cast(&ray, best)
            {
                best = best.min(toi);
            }
        }
        best * self.frame.inv_res
    }

    /// Clearance of the robot's footprint at `(x, y)`: the distance from its circle to the
    /// nearest wall or object part lower than the robot, in metres; 0 or less means a collision
    /// (walls report how deep the centre is, object parts report 0). Exact for walls to within a
    /// small fraction of a cell; objects farther than [`super::CLEARANCE_REACH`] are not measured, so a
    /// value above that is a bound, not a distance.
    pub fn clearance(&self, x: f64, y: f64) -> f64 {
        let wall = self.wall_clearance(x, y);
        self.object_clearance(x, y, wall)
    }

    /// The smallest footprint clearance ([`World::clearance`]) along the straight segment from
    /// `a` to `b`, sampled every half map cell: above the collision threshold, the robot can
    /// drive the segment straight, as it drives a roadmap edge.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "the step count is a small positive number"
    )]
    pub fn segment_clearance(&self, a: (f64, f64), b: (f64, f64)) -> f64 {
        let length = crate::norm(b.0 - a.0, b.1 - a.1);
        if !length.is_finite() {
            return f64::NEG_INFINITY;
        }
        let steps = ((length / (0.5 * self.frame.res)).ceil() as usize).max(1);
        (0..=steps)
            .map(|i| {
                let t = i as f64 / steps as f64;
                self.clearance(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Clearance of the footprint to walls only.
    pub fn wall_clearance(&self, x: f64, y: f64) -> f64 {
        match self.wall_distance2(x, y, -1.0) {
            Some(d2) => d2.sqrt() * self.frame.res - self.robot_radius,
            None => -self.robot_radius,
        }
    }

    /// Whether a wall or object the map knows lies within `d` metres of the point `(x, y)`:
    /// `self.clearance(x, y) + footprint radius <= d` (so always outside the map), with an
    /// early answer from the first nearby wall cell close enough. Laser returns ask it once
    /// per beam and step, and most of them lie on a wall.
    pub fn knows_within(&self, x: f64, y: f64, d: f64) -> bool {
        let reach = d * self.frame.inv_res;
        let reach2 = if reach > 0.0 { reach * reach } else { -1.0 };
        match self.wall_distance2(x, y, reach2) {
            None => d >= 0.0,
            Some(d2) if d2 <= reach2 => true,
            Some(d2) => {
                let wall = d2.sqrt() * self.frame.res - self.robot_radius;
                self.object_clearance(x, y, wall) + self.robot_radius <= d
            }
        }
    }

    /// Squared distance in cells from `(x, y)` to its nearest wall, `None` outside the map;
    /// it returns the first distance at or below `enough` as soon as it finds one (`-1`: never).
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "positions are checked to lie inside the padded grid before the lookup"
    )]
    #[inline]
    fn wall_distance2(&self, x: f64, y: f64, enough: f64) -> Option<f64> {
        let f = &self.frame;
        let (gx, gy) = f.to_grid(x, y);
        if !(gx >= 0.5 && gy >= 0.5 && gx < f.pw as f64 - 0.5 && gy < f.ph as f64 - 0.5) {
            return None;
        }
        // The four cells whose centres surround the point: their nearest walls include the
        // point's nearest wall in all but contrived cases.
        let (x0, y0) = ((gx - 0.5) as usize, (gy - 0.5) as usize);
        // Squared distances, one square root at the end: `hypot`'s overflow care costs more
        // than the rest of the query, and cell distances are far from overflowing.
        let mut best = f64::INFINITY;
        for (cx, cy) in [(x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)] {
            let feat = self.wall_feature[cy * f.pw + cx];
            if feat == NO_FEATURE {
                continue;
            }
            let (fx, fy) = ((feat as usize % f.pw) as f64, (feat as usize / f.pw) as f64);
            let ddx = (fx - gx).max(gx - (fx + 1.0)).max(0.0);
            let ddy = (fy - gy).max(gy - (fy + 1.0)).max(0.0);
            let d2 = ddx * ddx + ddy * ddy;
            if d2 <= enough {
                return Some(d2);
            }
            best = best.min(d2);
        }
        Some(best)
    }

    /// `min(bound, clearance to object parts within reach)`.
    fn object_clearance(&self, x: f64, y: f64, bound: f64) -> f64 {
        let Some(i) = self.cell_index(x, y) else {
            return bound;
        };
        let pw = self.frame.pw;
        let b = self.collision_buckets.bucket_of(i % pw, i / pw);
        let mut best = bound;
        for &k in self.collision_buckets.get(b) {
            if let Some(s) = self.solids.get(k as usize) {
                best = best.min(s.clearance_to(x, y, self.robot_radius, self.robot_height));
            }
        }
        best
    }
}
