//! The built world: exact laser ray casts, footprint clearance and the free region to sample
//! starts and goals from, all answered from precomputed grids and per-object primitives.
//!
//! Why not one rapier world with every wall cell as a collider? A map like the IPA production
//! plant has three million cells; a BVH over them costs seconds to build and microseconds per ray.
//! Walls from an occupancy grid are extruded through every height, so a horizontal laser ray
//! meets exactly the cells a 2-D traversal (Amanatides–Woo DDA) visits: the grid *is* the exact
//! geometry, and casting on it is exact. A precomputed Euclidean distance field lets the ray jump
//! across open space in one step (never past a blocked cell: the jump is the distance to the
//! nearest blocked cell minus √2 cells) and gives the footprint's clearance to walls in constant
//! time.
//!
//! Objects keep their 3-D shapes as parry primitives (boxes, upright cylinders, spheres), filtered
//! by height: the laser tests the parts that cross its mounting height (a table's legs, not its
//! top) and the footprint tests the parts lower than the robot, each found through small
//! per-bucket lists. Two queries use closed forms instead of parry's general algorithms, and the
//! unit tests below check them against parry: a horizontal ray meets an upright cylinder where it
//! meets its circle (parry's cylinder cast runs its convex-shape algorithm, about 4 µs a ray), and
//! the distance between the robot's upright cylinder and a part whose height range overlaps it
//! is planar (parry's GJK distance costs a few hundred nanoseconds a pair). The robot moves
//! kinematically and nothing is pushed, so no rigid-body dynamics (rapier) is needed: a collision
//! ends the episode, as in the paper.

use std::sync::Arc;

use parry3d_f64::math::{Pose, Rot3, Vector};
use parry3d_f64::query::{Ray, RayCast};
use parry3d_f64::shape::{Ball, Cuboid, Cylinder};

use crate::library::{self, Part};
use crate::raster::{self, NO_FEATURE, as_u32};
use crate::spec::{MAX_GRID_CELLS, Occupancy, Pose2, Problem, Problems, Shape, WorldSpec};

/// Laser code of a wall cell (occupied or unknown map cell, a wall, or the border).
const BLOCKED: u8 = 255;
/// Laser code of a free cell that a laser-height object part overlaps.
const OBJECT: u8 = 254;
/// Largest jump a laser code can hold, in cells.
const MAX_SKIP: u8 = 253;
/// Side of a bucket of the laser's object lists, as a power of two of cells: small, so a ray
/// entering an object cell tests about one part.
const LASER_BUCKET_SHIFT: usize = 2;
/// Side of a bucket of the footprint's object lists, as a power of two of cells.
const COLLISION_BUCKET_SHIFT: usize = 3;
/// Objects farther from the footprint than this are not measured by [`World::clearance`].
pub const CLEARANCE_REACH: f64 = 0.5;
/// Cell size of the grid built around a world that has no metric map, metres.
const DEFAULT_RESOLUTION: f64 = 0.05;

/// Options for building a world.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildOptions {
    /// Free space required around the footprint for a cell to be in the free region that starts
    /// and goals are sampled from, metres.
    pub sampling_margin: f64,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            sampling_margin: 0.1,
        }
    }
}

/// One primitive of an object, as the queries use it.
#[derive(Clone, Debug)]
struct Solid {
    shape: SolidShape,
    pose: Pose,
    /// The same solid in closed form, for the footprint's clearance.
    footprint: Footprint,
    zmin: f64,
    zmax: f64,
    /// World-frame bounding rectangle: min x, min y, max x, max y.
    rect: [f64; 4],
}

/// An upright solid in closed form.
#[derive(Clone, Copy, Debug)]
enum Footprint {
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
enum SolidShape {
    Cuboid(Cuboid),
    /// Kept as the reference model the closed-form casts and distances are tested against.
    #[cfg_attr(not(test), allow(dead_code))]
    Cylinder(Cylinder),
    Ball(Ball),
}

impl Solid {
    fn from_part(part: &Part) -> Solid {
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
    fn cast(&self, ray: &Ray, max: f64) -> Option<f64> {
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
    fn clearance_to(&self, x: f64, y: f64, radius: f64, height: f64) -> f64 {
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
struct Buckets {
    shift: usize,
    /// Buckets per row.
    bw: usize,
    /// `start[b]..start[b + 1]` indexes `items` for bucket `b`.
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Buckets {
    /// Buckets for solids covering the given inclusive cell rectangles `[x0, y0, x1, y1]`.
    fn build(shift: usize, pw: usize, ph: usize, rects: &[(u32, [usize; 4])]) -> Buckets {
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
    fn bucket_of(&self, cx: usize, cy: usize) -> usize {
        (cy >> self.shift) * self.bw + (cx >> self.shift)
    }

    #[inline]
    fn get(&self, b: usize) -> &[u32] {
        match (self.start.get(b), self.start.get(b + 1)) {
            (Some(s), Some(e)) => &self.items[*s as usize..*e as usize],
            _ => &[],
        }
    }
}

/// The free region starts and goals are sampled from: the largest connected set of cells where
/// the robot fits with the sampling margin.
#[derive(Clone, Debug, Default)]
pub struct FreeRegion {
    cells: Vec<u32>,
    member: Vec<u64>,
}

impl FreeRegion {
    fn contains_index(&self, i: usize) -> bool {
        self.member
            .get(i >> 6)
            .is_some_and(|w| (w >> (i & 63)) & 1 == 1)
    }

    /// Number of cells in the region.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether the region is empty (the robot fits nowhere).
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }
}

/// Where the world's grid lies and how it is padded.
#[derive(Clone, Debug)]
pub(crate) struct Frame {
    ox: f64,
    oy: f64,
    cos: f64,
    sin: f64,
    res: f64,
    inv_res: f64,
    /// Padded width and height: one blocked cell of border on every side.
    pub(crate) pw: usize,
    pub(crate) ph: usize,
}

impl Frame {
    /// World point to padded grid coordinates, in cells.
    #[inline]
    pub(crate) fn to_grid(&self, x: f64, y: f64) -> (f64, f64) {
        let (dx, dy) = (x - self.ox, y - self.oy);
        (
            (self.cos * dx + self.sin * dy) * self.inv_res + 1.0,
            (-self.sin * dx + self.cos * dy) * self.inv_res + 1.0,
        )
    }

    /// Padded grid coordinates, in cells, to a world point.
    #[inline]
    pub(crate) fn to_world(&self, gx: f64, gy: f64) -> (f64, f64) {
        let (lx, ly) = ((gx - 1.0) * self.res, (gy - 1.0) * self.res);
        (
            self.ox + self.cos * lx - self.sin * ly,
            self.oy + self.sin * lx + self.cos * ly,
        )
    }

    /// A world direction in the grid frame.
    #[inline]
    fn dir_to_grid(&self, dx: f64, dy: f64) -> (f64, f64) {
        (
            self.cos * dx + self.sin * dy,
            -self.sin * dx + self.cos * dy,
        )
    }

    /// Inclusive padded-cell rectangle covering a world rectangle, clamped to the grid.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "values are clamped into [0, pw) and [0, ph) before the cast"
    )]
    fn cell_rect(&self, rect: [f64; 4], inflate: f64) -> [usize; 4] {
        let corners = [
            (rect[0] - inflate, rect[1] - inflate),
            (rect[2] + inflate, rect[1] - inflate),
            (rect[0] - inflate, rect[3] + inflate),
            (rect[2] + inflate, rect[3] + inflate),
        ];
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for (x, y) in corners {
            let (gx, gy) = self.to_grid(x, y);
            x0 = x0.min(gx);
            y0 = y0.min(gy);
            x1 = x1.max(gx);
            y1 = y1.max(gy);
        }
        #[allow(clippy::cast_precision_loss, reason = "grid sizes are far below 2^52")]
        let (mx, my) = ((self.pw - 1) as f64, (self.ph - 1) as f64);
        [
            x0.floor().clamp(0.0, mx) as usize,
            y0.floor().clamp(0.0, my) as usize,
            x1.floor().clamp(0.0, mx) as usize,
            y1.floor().clamp(0.0, my) as usize,
        ]
    }
}

/// A world ready to simulate: immutable, shared between environments (`Arc<World>`).
#[derive(Clone, Debug)]
pub struct World {
    spec: WorldSpec,
    warnings: Vec<Problem>,
    frame: Frame,
    /// Per padded cell: [`BLOCKED`], [`OBJECT`], or how many cells a ray may jump from here.
    laser_code: Vec<u8>,
    /// Per padded cell: nearest wall cell (for footprint clearance to walls).
    wall_feature: Vec<u32>,
    solids: Vec<Solid>,
    laser_buckets: Buckets,
    collision_buckets: Buckets,
    region: FreeRegion,
    laser_z: f64,
    robot_radius: f64,
    robot_height: f64,
}

/// Why a world could not be built.
pub type BuildError = Problems;

impl World {
    /// Builds a world with default options. Fails with the description's problems when any is
    /// an error; warnings are kept in [`World::warnings`].
    pub fn build(spec: WorldSpec) -> Result<Arc<World>, BuildError> {
        World::build_with(spec, &BuildOptions::default())
    }

    /// Builds a world.
    pub fn build_with(spec: WorldSpec, options: &BuildOptions) -> Result<Arc<World>, BuildError> {
        let mut problems = spec.validate();
        if !(options.sampling_margin.is_finite() && options.sampling_margin >= 0.0) {
            problems.push(Problem::error(
                "build options",
                "sampling_margin",
                format!(
                    "must be finite and not negative, got {}",
                    options.sampling_margin
                ),
            ));
        }
        if problems.has_errors() {
            return Err(problems);
        }
        let parts: Vec<Part> = spec.objects.iter().flat_map(library::parts).collect();
        let frame = match frame_for(&spec, &parts) {
            Ok(f) => f,
            Err(p) => {
                problems.push(p);
                return Err(problems);
            }
        };
        let (pw, ph) = (frame.pw, frame.ph);
        let mut walls = vec![false; pw * ph];
        // The border, and every map cell that is not free (ROS trinary semantics).
        for x in 0..pw {
            walls[x] = true;
            walls[(ph - 1) * pw + x] = true;
        }
        for y in 0..ph {
            walls[y * pw] = true;
            walls[y * pw + pw - 1] = true;
        }
        if let Some(floor) = &spec.floor {
            let g = &floor.grid;
            for (row, cells) in g.cells.chunks(g.width).enumerate() {
                let base = (row + 1) * pw + 1;
                for (col, cell) in cells.iter().enumerate() {
                    walls[base + col] = *cell != Occupancy::Free;
                }
            }
        }
        for wall in &spec.walls {
            rasterise_wall(&frame, wall, &mut walls);
        }
        let wall_feature = raster::feature_transform(&walls, pw, ph);

        let solids: Vec<Solid> = parts.iter().map(Solid::from_part).collect();
        let robot = &spec.robot;
        let laser_z = robot.laser.mount.z;
        let mut laser_rects = Vec::new();
        let mut collision_rects = Vec::new();
        let mut collision_cells = Vec::new();
        for (i, s) in solids.iter().enumerate() {
            let id = as_u32(i);
            if s.zmin <= laser_z && laser_z <= s.zmax {
                laser_rects.push((id, frame.cell_rect(s.rect, 0.0)));
            }
            if s.zmin < robot.height && s.zmax > 0.0 {
                collision_rects.push((
                    id,
                    frame.cell_rect(s.rect, robot.footprint_radius + CLEARANCE_REACH),
                ));
                collision_cells.push(frame.cell_rect(s.rect, 0.0));
            }
        }

        // Laser codes: walls, object cells, and elsewhere the safe jump to the nearest of either.
        let laser_feature = if laser_rects.is_empty() {
            None
        } else {
            let mut mask = walls.clone();
            for (_, r) in &laser_rects {
                fill_rect(&mut mask, pw, r);
            }
            Some(raster::feature_transform(&mask, pw, ph))
        };
        let mut laser_code = vec![0u8; pw * ph];
        {
            let feature = laser_feature.as_ref().unwrap_or(&wall_feature);
            for (i, code) in laser_code.iter_mut().enumerate() {
                *code = if walls[i] {
                    BLOCKED
                } else {
                    jump_code(i, feature[i], pw)
                };
            }
            for (_, r) in &laser_rects {
                for y in r[1]..=r[3] {
                    for x in r[0]..=r[2] {
                        let c = &mut laser_code[y * pw + x];
                        if *c != BLOCKED {
                            *c = OBJECT;
                        }
                    }
                }
            }
        }
        let laser_buckets = Buckets::build(LASER_BUCKET_SHIFT, pw, ph, &laser_rects);
        let collision_buckets = Buckets::build(COLLISION_BUCKET_SHIFT, pw, ph, &collision_rects);

        // The free region: cells whose whole square keeps the footprint plus margin clear of
        // walls and of the bounding rectangles of objects within the robot's height.
        let clear_feature = if collision_cells.is_empty() {
            None
        } else {
            let mut mask = walls.clone();
            for r in &collision_cells {
                fill_rect(&mut mask, pw, r);
            }
            Some(raster::feature_transform(&mask, pw, ph))
        };
        let feature = clear_feature.as_ref().unwrap_or(&wall_feature);
        // Centre distance D to the nearest blocked centre bounds the distance from any point of
        // this cell to any blocked square from below by D - √2 cells.
        let need = (robot.footprint_radius + options.sampling_margin) * frame.inv_res
            + std::f64::consts::SQRT_2;
        let navigable: Vec<bool> = (0..pw * ph)
            .map(|i| {
                !walls[i]
                    && (feature[i] == NO_FEATURE
                        || raster::centre_distance(i, feature[i] as usize, pw) >= need)
            })
            .collect();
        let cells = raster::largest_component(&navigable, pw, ph);
        let mut member = vec![0u64; (pw * ph).div_ceil(64)];
        for &c in &cells {
            member[c as usize >> 6] |= 1 << (c & 63);
        }
        drop(navigable);

        Ok(Arc::new(World {
            robot_radius: robot.footprint_radius,
            robot_height: robot.height,
            laser_z,
            warnings: problems.0,
            spec,
            frame,
            laser_code,
            wall_feature,
            solids,
            laser_buckets,
            collision_buckets,
            region: FreeRegion { cells, member },
        }))
    }

    /// The description the world was built from.
    pub fn spec(&self) -> &WorldSpec {
        &self.spec
    }

    /// Warnings found while building (what the simulation changed from the description).
    pub fn warnings(&self) -> &[Problem] {
        &self.warnings
    }

    /// The free region starts and goals are sampled from.
    pub fn free_region(&self) -> &FreeRegion {
        &self.region
    }

    /// Area of the free region, square metres.
    #[allow(clippy::cast_precision_loss, reason = "cell counts are far below 2^52")]
    pub fn free_region_area_m2(&self) -> f64 {
        self.region.len() as f64 * self.frame.res * self.frame.res
    }

    /// Whether the free region holds world point `(x, y)`.
    pub fn in_free_region(&self, x: f64, y: f64) -> bool {
        self.cell_index(x, y)
            .is_some_and(|i| self.region.contains_index(i))
    }

    /// A point drawn uniformly from the free region, given two uniform numbers in [0, 1) and a
    /// cell choice; `None` when the region is empty.
    pub(crate) fn region_point(&self, pick: usize, u: f64, v: f64) -> Option<(f64, f64)> {
        let n = self.region.cells.len();
        let i = *self.region.cells.get(pick % n.max(1))? as usize;
        let (cx, cy) = (i % self.frame.pw, i / self.frame.pw);
        #[allow(clippy::cast_precision_loss, reason = "grid sizes are far below 2^52")]
        Some(self.frame.to_world(cx as f64 + u, cy as f64 + v))
    }

    /// The free-region point nearest to `(x, y)` (for "your goal is blocked; try here").
    pub fn nearest_free_point(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let (gx, gy) = self.frame.to_grid(x, y);
        let pw = self.frame.pw;
        #[allow(clippy::cast_precision_loss, reason = "grid sizes are far below 2^52")]
        let best = self.region.cells.iter().min_by(|a, b| {
            let d = |c: u32| {
                let c = c as usize;
                let (cx, cy) = ((c % pw) as f64 + 0.5, (c / pw) as f64 + 0.5);
                (cx - gx).hypot(cy - gy)
            };
            d(**a).total_cmp(&d(**b))
        })?;
        let c = *best as usize;
        #[allow(clippy::cast_precision_loss, reason = "grid sizes are far below 2^52")]
        Some(
            self.frame
                .to_world((c % pw) as f64 + 0.5, (c / pw) as f64 + 0.5),
        )
    }

    /// The grid's placement.
    pub(crate) fn frame(&self) -> &Frame {
        &self.frame
    }

    /// Padded indices of the free region's cells.
    pub(crate) fn region_cells(&self) -> &[u32] {
        &self.region.cells
    }

    /// Cell size, metres.
    pub fn resolution(&self) -> f64 {
        self.frame.res
    }

    /// Height of the laser above the floor, metres.
    pub fn laser_height(&self) -> f64 {
        self.laser_z
    }

    /// World rectangle covered by the grid (without its border): min x, min y, max x, max y.
    #[allow(clippy::cast_precision_loss, reason = "grid sizes are far below 2^52")]
    pub fn bounds(&self) -> [f64; 4] {
        let f = &self.frame;
        let (w, h) = ((f.pw - 1) as f64, (f.ph - 1) as f64);
        let corners = [
            f.to_world(1.0, 1.0),
            f.to_world(w, 1.0),
            f.to_world(1.0, h),
            f.to_world(w, h),
        ];
        let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for (x, y) in corners {
            b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        }
        b
    }

    /// Padded index of the cell holding world point `(x, y)`.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        clippy::cast_precision_loss,
        reason = "checked to lie inside the grid before the cast"
    )]
    fn cell_index(&self, x: f64, y: f64) -> Option<usize> {
        let (gx, gy) = self.frame.to_grid(x, y);
        let f = &self.frame;
        (gx >= 0.0 && gy >= 0.0 && gx < f.pw as f64 && gy < f.ph as f64)
            .then(|| gy as usize * f.pw + gx as usize)
    }

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
        clippy::cast_precision_loss,
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
    /// small fraction of a cell; objects farther than [`CLEARANCE_REACH`] are not measured, so a
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
        let length = (b.0 - a.0).hypot(b.1 - a.1);
        if !length.is_finite() {
            return f64::NEG_INFINITY;
        }
        let steps = ((length / (0.5 * self.frame.res)).ceil() as usize).max(1);
        #[allow(clippy::cast_precision_loss, reason = "step counts are small")]
        (0..=steps)
            .map(|i| {
                let t = i as f64 / steps as f64;
                self.clearance(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Clearance of the footprint to walls only.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        clippy::cast_precision_loss,
        reason = "positions are checked to lie inside the padded grid before the cast"
    )]
    pub fn wall_clearance(&self, x: f64, y: f64) -> f64 {
        let f = &self.frame;
        let (gx, gy) = f.to_grid(x, y);
        if !(gx >= 0.5 && gy >= 0.5 && gx < f.pw as f64 - 0.5 && gy < f.ph as f64 - 0.5) {
            return -self.robot_radius;
        }
        // The four cells whose centres surround the point: their nearest walls include the
        // point's nearest wall in all but contrived cases.
        let (x0, y0) = ((gx - 0.5) as usize, (gy - 0.5) as usize);
        let mut best = f64::INFINITY;
        for (cx, cy) in [(x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)] {
            let feat = self.wall_feature[cy * f.pw + cx];
            if feat == NO_FEATURE {
                continue;
            }
            let (fx, fy) = ((feat as usize % f.pw) as f64, (feat as usize / f.pw) as f64);
            let ddx = (fx - gx).max(gx - (fx + 1.0)).max(0.0);
            let ddy = (fy - gy).max(gy - (fy + 1.0)).max(0.0);
            best = best.min(ddx.hypot(ddy));
        }
        best * f.res - self.robot_radius
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

    /// What a padded-grid-free cell `(col, row)` of the map holds, for drawing: `None` for free,
    /// `Some(true)` for unknown map cells, `Some(false)` for other solid cells.
    pub(crate) fn cell_look(&self, col: usize, row: usize) -> Option<bool> {
        let pw = self.frame.pw;
        let blocked = self
            .laser_code
            .get((row + 1) * pw + col + 1)
            .is_some_and(|c| *c == BLOCKED);
        if !blocked {
            return None;
        }
        let unknown = self
            .spec
            .floor
            .as_ref()
            .is_some_and(|f| f.grid.get(col, row) == Some(Occupancy::Unknown));
        Some(unknown)
    }

    /// Grid size without the border, in cells.
    pub(crate) fn grid_size(&self) -> (usize, usize) {
        (self.frame.pw - 2, self.frame.ph - 2)
    }

    /// The grid's origin (world pose of the lower-left corner of cell (0, 0)).
    pub(crate) fn grid_origin(&self) -> Pose2 {
        Pose2::new(
            self.frame.ox,
            self.frame.oy,
            self.frame.sin.atan2(self.frame.cos),
        )
    }

    /// The grid cell holding world point `(x, y)` (no border), if inside the grid.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        clippy::cast_precision_loss,
        reason = "checked to lie inside the grid before the cast"
    )]
    pub(crate) fn grid_cell(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let (gx, gy) = self.frame.to_grid(x, y);
        let f = &self.frame;
        (gx >= 1.0 && gy >= 1.0 && gx < (f.pw - 1) as f64 && gy < (f.ph - 1) as f64)
            .then(|| (gx as usize - 1, gy as usize - 1))
    }

    /// Whether the free region holds grid cell `(col, row)` (no border).
    pub(crate) fn region_has_cell(&self, col: usize, row: usize) -> bool {
        self.region
            .contains_index((row + 1) * self.frame.pw + col + 1)
    }
}

/// Laser jump code for a free cell whose nearest blocked cell is `feature`.
fn jump_code(i: usize, feature: u32, pw: usize) -> u8 {
    if feature == NO_FEATURE {
        return MAX_SKIP;
    }
    // From any point of this cell, every blocked square is at least D - √2 cells away; 1.5 keeps
    // a margin for rounding.
    let d = raster::centre_distance(i, feature as usize, pw) - 1.5;
    if d < 1.0 {
        0
    } else {
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "clamped to [1, MAX_SKIP] first"
        )]
        let v = d.floor().min(f64::from(MAX_SKIP)) as u8;
        v
    }
}

fn fill_rect(mask: &mut [bool], pw: usize, r: &[usize; 4]) {
    for y in r[1]..=r[3] {
        mask[y * pw + r[0]..=y * pw + r[2]].fill(true);
    }
}

/// Marks the cells whose centre lies within the wall's half thickness (at least half a cell, so
/// a thin wall is never a gap).
#[allow(clippy::cast_precision_loss, reason = "grid sizes are far below 2^52")]
fn rasterise_wall(frame: &Frame, wall: &crate::spec::WallSpec, mask: &mut [bool]) {
    let half = (wall.thickness / 2.0).max(frame.res * std::f64::consts::FRAC_1_SQRT_2);
    let [ax, ay] = wall.start;
    let [bx, by] = wall.end;
    let rect = [ax.min(bx), ay.min(by), ax.max(bx), ay.max(by)];
    let r = frame.cell_rect(rect, half);
    let (vx, vy) = (bx - ax, by - ay);
    let len2 = vx * vx + vy * vy;
    for cy in r[1]..=r[3] {
        for cx in r[0]..=r[2] {
            let (px, py) = frame.to_world(cx as f64 + 0.5, cy as f64 + 0.5);
            let t = if len2 > 0.0 {
                (((px - ax) * vx + (py - ay) * vy) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (qx, qy) = (ax + t * vx, ay + t * vy);
            if (px - qx).hypot(py - qy) <= half {
                mask[cy * frame.pw + cx] = true;
            }
        }
    }
}

/// The grid frame: the floor map's, or a box 1 m around the walls and objects.
#[allow(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    reason = "the extent is checked to be finite and bounded before the cast"
)]
fn frame_for(spec: &WorldSpec, parts: &[Part]) -> Result<Frame, Problem> {
    if let Some(floor) = &spec.floor {
        let g = &floor.grid;
        let (sin, cos) = g.origin.yaw.sin_cos();
        return Ok(Frame {
            ox: g.origin.x,
            oy: g.origin.y,
            cos,
            sin,
            res: g.resolution,
            inv_res: 1.0 / g.resolution,
            pw: g.width + 2,
            ph: g.height + 2,
        });
    }
    let mut b = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    let mut grow = |x: f64, y: f64, r: f64| {
        b = [
            b[0].min(x - r),
            b[1].min(y - r),
            b[2].max(x + r),
            b[3].max(y + r),
        ];
    };
    for w in &spec.walls {
        grow(w.start[0], w.start[1], w.thickness);
        grow(w.end[0], w.end[1], w.thickness);
    }
    for p in parts {
        let r = p.size.x.hypot(p.size.y) / 2.0;
        grow(p.pose.x, p.pose.y, r);
    }
    if b[0] > b[2] {
        return Err(Problem::error(
            &spec.id,
            "floor",
            "the world has no metric map, no walls and no objects: there is nothing to bound it",
        ));
    }
    let margin = 1.0;
    let (w, h) = (
        ((b[2] - b[0] + 2.0 * margin) / DEFAULT_RESOLUTION).ceil(),
        ((b[3] - b[1] + 2.0 * margin) / DEFAULT_RESOLUTION).ceil(),
    );
    if !(w.is_finite() && h.is_finite() && (w + 2.0) * (h + 2.0) <= MAX_GRID_CELLS as f64) {
        return Err(Problem::error(
            &spec.id,
            "walls",
            format!(
                "walls and objects span {:.0} x {:.0} m, too large for a {DEFAULT_RESOLUTION} m grid",
                b[2] - b[0],
                b[3] - b[1]
            ),
        ));
    }
    Ok(Frame {
        ox: b[0] - margin,
        oy: b[1] - margin,
        cos: 1.0,
        sin: 0.0,
        res: DEFAULT_RESOLUTION,
        inv_res: 1.0 / DEFAULT_RESOLUTION,
        pw: w as usize + 2,
        ph: h as usize + 2,
    })
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
