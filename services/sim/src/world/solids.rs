//! Objects as the queries see them: each part a parry primitive with its height range and
//! planar footprint (closed forms for the common cases, checked against parry below), and the
//! per-bucket lists that find the parts near a cell.

use parry3d_f64::math::{Pose, Rot3, Vector};
use parry3d_f64::query::{Ray, RayCast};
use parry3d_f64::shape::{Ball, Cuboid, Cylinder};

use crate::library::Part;
use crate::spec::Shape;

/// One primitive of an object, as the queries use it.
#[derive(Clone, Debug)]
pub(super) struct Solid {
    pub(super) shape: SolidShape,
    pub(super) pose: Pose,
    /// The same solid in closed form, for the footprint's clearance.
    pub(super) footprint: Footprint,
    pub(super) zmin: f64,
    pub(super) zmax: f64,
    /// World-frame bounding rectangle: min x, min y, max x, max y.
    pub(super) rect: [f64; 4],
}

/// An upright solid in closed form.
#[derive(Clone, Copy, Debug)]
pub(super) enum Footprint {
    /// A box turned by `yaw`: centre, (cos, sin) of the yaw, half extents.
    Rect {
        cx: f64,
        cy: f64,
        c: f64,
        s: f64,
        hx: f64,
        hy: f64,
    },
    /// An upright cylinder.
    Disc { cx: f64, cy: f64, r: f64 },
    /// A sphere.
    Ball { cx: f64, cy: f64, cz: f64, r: f64 },
}

#[derive(Clone, Debug)]
pub(super) enum SolidShape {
    Cuboid(Cuboid),
    /// Kept as the reference model the closed-form casts and distances are tested against.
    #[cfg_attr(not(test), allow(dead_code))]
    Cylinder(Cylinder),
    Ball(Ball),
}

impl Solid {
    pub(super) fn from_part(part: &Part) -> Solid {
        let p = part.pose;
        let (hx, hy, hz) = (part.size.x / 2.0, part.size.y / 2.0, part.size.z / 2.0);
        let centre = Vector::new(p.x, p.y, p.z);
        let yaw = Rot3::from_rotation_z(p.yaw);
        let (shape, pose, half_z, rect_half, footprint) = match part.shape {
            Shape::Box => {
                let (s, c) = p.yaw.sin_cos();
                let ex = (c * hx).abs() + (s * hy).abs();
                let ey = (s * hx).abs() + (c * hy).abs();
                (
                    SolidShape::Cuboid(Cuboid::new(Vector::new(hx, hy, hz))),
                    Pose::from_parts(centre, yaw),
                    hz,
                    (ex, ey),
                    Footprint::Rect {
                        cx: p.x,
                        cy: p.y,
                        c,
                        s,
                        hx,
                        hy,
                    },
                )
            }
            Shape::Cylinder => {
                let r = hx.max(hy);
                // parry's cylinders stand along y: turn them upright.
                let upright = yaw * Rot3::from_rotation_x(std::f64::consts::FRAC_PI_2);
                (
                    SolidShape::Cylinder(Cylinder::new(hz, r)),
                    Pose::from_parts(centre, upright),
                    hz,
                    (r, r),
                    Footprint::Disc {
                        cx: p.x,
                        cy: p.y,
                        r,
                    },
                )
            }
            Shape::Sphere => {
                let r = hx.max(hy).max(hz);
                (
                    SolidShape::Ball(Ball::new(r)),
                    Pose::from_parts(centre, yaw),
                    r,
                    (r, r),
                    Footprint::Ball {
                        cx: p.x,
                        cy: p.y,
                        cz: p.z,
                        r,
                    },
                )
            }
        };
        Solid {
            shape,
            pose,
            footprint,
            zmin: p.z - half_z,
            zmax: p.z + half_z,
            rect: [
                p.x - rect_half.0,
                p.y - rect_half.1,
                p.x + rect_half.0,
                p.y + rect_half.1,
            ],
        }
    }

    /// First hit of a horizontal ray at a height within this solid's height range.
    pub(super) fn cast(&self, ray: &Ray, max: f64) -> Option<f64> {
        match &self.shape {
            SolidShape::Cuboid(s) => s.cast_ray(&self.pose, ray, max, true),
            SolidShape::Ball(s) => s.cast_ray(&self.pose, ray, max, true),
            // parry casts rays on cylinders with its general convex-shape algorithm, about 4 µs a
            // ray; a horizontal ray within the height range of an upright cylinder meets it
            // where it meets its circle, which is a quadratic.
            SolidShape::Cylinder(_) => {
                let Footprint::Disc { cx, cy, r } = self.footprint else {
                    return None;
                };
                let (ox, oy) = (ray.origin.x - cx, ray.origin.y - cy);
                let (dx, dy) = (ray.dir.x, ray.dir.y);
                let a = dx * dx + dy * dy;
                let c = ox * ox + oy * oy - r * r;
                if c <= 0.0 {
                    return Some(0.0); // starts inside: solid
                }
                let b = ox * dx + oy * dy;
                let disc = b * b - a * c;
                if b >= 0.0 || disc < 0.0 || a == 0.0 {
                    return None;
                }
                let t = (-b - disc.sqrt()) / a;
                (t <= max).then_some(t)
            }
        }
    }

    /// Signed clearance between this solid and an upright cylinder of radius `radius` standing
    /// on the floor at `(x, y)` and `height` tall, for solids whose height range overlaps the
    /// cylinder's (the only ones the footprint is tested against): then the closest points of a
    /// box or an upright cylinder lie at the same height and the distance is planar. Negative
    /// values measure overlap in the plane.
    pub(super) fn clearance_to(&self, x: f64, y: f64, radius: f64, height: f64) -> f64 {
        match self.footprint {
            Footprint::Rect {
                cx,
                cy,
                c,
                s,
                hx,
                hy,
            } => {
                let (dx, dy) = (x - cx, y - cy);
                let (lx, ly) = (c * dx + s * dy, -s * dx + c * dy);
                let (ox, oy) = (lx.abs() - hx, ly.abs() - hy);
                let outside = ox.max(0.0).hypot(oy.max(0.0));
                let inside = ox.max(oy).min(0.0);
                outside + inside - radius
            }
            Footprint::Disc { cx, cy, r } => (x - cx).hypot(y - cy) - r - radius,
            Footprint::Ball { cx, cy, cz, r } => {
                // Closest point of the cylinder to the centre: the horizontal gap to its side and
                // the vertical gap to its height range.
                let dh = ((x - cx).hypot(y - cy) - radius).max(0.0);
                let dz = (cz - height).max(-cz).max(0.0);
                let d = dh.hypot(dz);
                if d > 0.0 { d - r } else { -r }
            }
        }
    }
}

/// Lists of solids per square bucket of `2^shift` cells, stored compactly (CSR).
#[derive(Clone, Debug, Default)]
pub(super) struct Buckets {
    pub(super) shift: usize,
    /// Buckets per row.
    pub(super) bw: usize,
    /// `start[b]..start[b + 1]` indexes `items` for bucket `b`.
    pub(super) start: Vec<u32>,
    pub(super) items: Vec<u32>,
}

impl Buckets {
    /// Buckets for solids covering the given inclusive cell rectangles `[x0, y0, x1, y1]`.
    pub(super) fn build(
        shift: usize,
        pw: usize,
        ph: usize,
        rects: &[(u32, [usize; 4])],
    ) -> Buckets {
        let bw = (pw >> shift) + 1;
        let bh = (ph >> shift) + 1;
        let mut count = vec![0u32; bw * bh + 1];
        let each = |r: &[usize; 4], f: &mut dyn FnMut(usize)| {
            for by in (r[1] >> shift)..=(r[3] >> shift) {
                for bx in (r[0] >> shift)..=(r[2] >> shift) {
                    f(by * bw + bx);
                }
            }
        };
        for (_, r) in rects {
            each(r, &mut |b| count[b + 1] += 1);
        }
        for b in 0..bw * bh {
            count[b + 1] += count[b];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; count[bw * bh] as usize];
        for (id, r) in rects {
            each(r, &mut |b| {
                items[fill[b] as usize] = *id;
                fill[b] += 1;
            });
        }
        Buckets {
            shift,
            bw,
            start: count,
            items,
        }
    }

    #[inline]
    pub(super) fn bucket_of(&self, cx: usize, cy: usize) -> usize {
        (cy >> self.shift) * self.bw + (cx >> self.shift)
    }

    #[inline]
    pub(super) fn get(&self, b: usize) -> &[u32] {
        match (self.start.get(b), self.start.get(b + 1)) {
            (Some(s), Some(e)) => &self.items[*s as usize..*e as usize],
            _ => &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::{Colour, Pose3, Size3};

    fn part(shape: Shape, size: Size3, pose: Pose3) -> Part {
        Part {
            name: "p",
            shape,
            size,
            pose,
            colour: Colour::GREY,
        }
    }

    /// The closed-form footprint clearance equals parry's 3-D distance between the robot's
    /// cylinder and the solid wherever they are apart (and is not positive where they touch).
    #[test]
    fn closed_form_clearance_matches_parry() {
        use parry3d_f64::query::distance;
        let (radius, height) = (0.25, 0.6);
        let robot = Cylinder::new(height / 2.0, radius);
        let solids = [
            part(
                Shape::Box,
                Size3::new(1.0, 0.4, 0.8),
                Pose3::new(0.3, -0.2, 0.4, 0.7),
            ),
            part(
                Shape::Cylinder,
                Size3::new(0.5, 0.5, 1.5),
                Pose3::new(-0.4, 0.5, 0.75, 0.0),
            ),
            part(
                Shape::Sphere,
                Size3::new(0.6, 0.6, 0.6),
                Pose3::new(0.2, 0.9, 0.5, 0.0),
            ),
            part(
                Shape::Sphere,
                Size3::new(0.4, 0.4, 0.4),
                Pose3::new(-0.6, -0.6, 0.9, 0.0),
            ),
        ]
        .map(|p| Solid::from_part(&p));
        let mut checked = 0;
        for i in 0..60 {
            for j in 0..60 {
                let (x, y) = (-2.0 + f64::from(i) * 0.067, -2.0 + f64::from(j) * 0.067);
                let pose = Pose::from_parts(
                    Vector::new(x, y, height / 2.0),
                    Rot3::from_rotation_x(std::f64::consts::FRAC_PI_2),
                );
                for s in &solids {
                    let ours = s.clearance_to(x, y, radius, height);
                    let theirs = match &s.shape {
                        SolidShape::Cuboid(c) => distance(&pose, &robot, &s.pose, c),
                        SolidShape::Cylinder(c) => distance(&pose, &robot, &s.pose, c),
                        SolidShape::Ball(c) => distance(&pose, &robot, &s.pose, c),
                    }
                    .expect("supported")
                    .distance;
                    if theirs > 1e-6 {
                        assert!(
                            (ours - theirs).abs() < 1e-6,
                            "at ({x}, {y}): {ours} vs {theirs}"
                        );
                        checked += 1;
                    } else {
                        assert!(ours <= 1e-6, "at ({x}, {y}): {ours} vs touching");
                    }
                }
            }
        }
        assert!(checked > 5000);
    }

    /// The closed-form ray cast on upright cylinders equals parry's.
    #[test]
    fn cylinder_ray_cast_matches_parry() {
        let s = Solid::from_part(&part(
            Shape::Cylinder,
            Size3::new(0.6, 0.6, 1.0),
            Pose3::new(1.0, 0.5, 0.5, 0.3),
        ));
        let SolidShape::Cylinder(cyl) = &s.shape else {
            panic!("a cylinder");
        };
        let mut hits = 0;
        for k in 0..360 {
            let a = f64::from(k).to_radians();
            for (x, y) in [(-1.0, 0.2), (2.5, 2.0), (1.1, 0.5), (1.0, -0.5)] {
                let ray = Ray::new(Vector::new(x, y, 0.3), Vector::new(a.cos(), a.sin(), 0.0));
                let ours = s.cast(&ray, 5.0);
                let theirs = cyl.cast_ray(&s.pose, &ray, 5.0, true);
                match (ours, theirs) {
                    (Some(o), Some(t)) => {
                        assert!((o - t).abs() < 1e-6, "{o} vs {t}");
                        hits += 1;
                    }
                    (None, None) => {}
                    other => {
                        // Only a tangent ray may be a hit for one and a miss for the other.
                        let (ox, oy) = (1.0 - x, 0.5 - y);
                        let miss = (ox * a.sin() - oy * a.cos()).abs();
                        assert!(
                            (miss - 0.3).abs() < 1e-6,
                            "from ({x}, {y}) at {a}: {other:?}"
                        );
                    }
                }
            }
        }
        assert!(hits > 300);
    }
}
