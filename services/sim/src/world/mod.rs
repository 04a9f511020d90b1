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
//! unit tests in `solids` check them against parry: a horizontal ray meets an upright cylinder
//! where it meets its circle (parry's cylinder cast runs its convex-shape algorithm, about 4 µs a
//! ray), and the distance between the robot's upright cylinder and a part whose height range
//! overlaps it is planar (parry's GJK distance costs a few hundred nanoseconds a pair). The robot
//! moves kinematically and nothing is pushed, so no rigid-body dynamics (rapier) is needed: a
//! collision ends the episode, as in the paper.
//!
//! `solids` holds the per-object primitives and the buckets that find them; `queries` the
//! laser casts and clearance queries; this module builds the world and its grids.

use std::sync::Arc;

use grid::distance::{NO_FEATURE, centre_distance, feature_transform};

use self::solids::{Buckets, Solid};
use crate::library::{self, Part};
use crate::spec::{MAX_GRID_CELLS, Occupancy, Pose2, SpecProblem, SpecProblems, WorldSpec, as_u32};

mod queries;
mod solids;

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
    warnings: Vec<SpecProblem>,
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
    /// Where people walk ([`crate::crowd`]), made when a simulation first has people.
    people_targets: std::sync::OnceLock<Arc<crate::crowd::Targets>>,
    /// [`World::geometry_key`], made on first use.
    geometry_key: std::sync::OnceLock<String>,
}

/// Why a world could not be built.
pub type BuildError = SpecProblems;

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
            problems.push(SpecProblem::error(
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
        let walls = wall_cells(&frame, &spec);
        let wall_feature = feature_transform(&walls, pw, ph);
        let solids: Vec<Solid> = parts.iter().map(Solid::from_part).collect();
        let robot = &spec.robot;
        let laser_z = robot.laser.mount.z;
        let rects = SolidRects::of(&frame, &solids, robot);
        let laser_code = laser_codes(&walls, &wall_feature, &rects.laser, pw, ph);
        let laser_buckets = Buckets::build(LASER_BUCKET_SHIFT, pw, ph, &rects.laser);
        let collision_buckets = Buckets::build(COLLISION_BUCKET_SHIFT, pw, ph, &rects.collision);
        let region = free_region(
            &walls,
            &wall_feature,
            &rects.collision_cells,
            &frame,
            robot.footprint_radius + options.sampling_margin,
        );
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
            region,
            people_targets: std::sync::OnceLock::new(),
            geometry_key: std::sync::OnceLock::new(),
        }))
    }

    /// Names what a planner's grid of this world depends on, and nothing else: the floor's
    /// cells, its walls and objects, the robot's footprint radius and height (an FNV-1a hash,
    /// 16 hex digits). Two robots of one model on one floor share it whatever their names, so
    /// they share configuration spaces and roadmaps; any change to the floor changes it.
    pub fn geometry_key(&self) -> &str {
        self.geometry_key.get_or_init(|| {
            let mut h = grid::hash::Fnv1a::new();
            let spec = &self.spec;
            if let Some(floor) = &spec.floor {
                let g = &floor.grid;
                for v in [g.width as u64, g.height as u64] {
                    h.write(&v.to_le_bytes());
                }
                for v in [
                    g.resolution,
                    g.origin.x,
                    g.origin.y,
                    g.origin.yaw,
                    floor.wall_height,
                ] {
                    h.write(&v.to_bits().to_le_bytes());
                }
                let cells: Vec<u8> = g
                    .cells
                    .iter()
                    .map(|c| match c {
                        Occupancy::Free => 0,
                        Occupancy::Occupied => 1,
                        Occupancy::Unknown => 2,
                    })
                    .collect();
                h.write(&cells);
            }
            h.write(format!("{:?}|{:?}", spec.walls, spec.objects).as_bytes());
            for v in [self.robot_radius, self.robot_height] {
                h.write(&v.to_bits().to_le_bytes());
            }
            format!("{:016x}", h.finish())
        })
    }

    /// Where people walk in this world: the knowledge's routes and attractors and points spread
    /// over the free region, with their path fields; made on first use, then shared.
    pub fn people_targets(&self) -> &Arc<crate::crowd::Targets> {
        self.people_targets
            .get_or_init(|| crate::crowd::Targets::shared(self))
    }

    /// What a world's people targets depend on besides the knowledge of people: its geometry
    /// ([`World::geometry_key`]) and its free region (which also depends on the build's
    /// sampling margin). Worlds alike in these share their targets and path fields.
    pub(crate) fn region_key(&self) -> (String, u64) {
        let mut h = grid::hash::Fnv1a::new();
        h.write(&(self.region.cells.len() as u64).to_le_bytes());
        for word in &self.region.member {
            h.write(&word.to_le_bytes());
        }
        (self.geometry_key().to_owned(), h.finish())
    }

    /// Origin and heading of the laser of a robot at `pose`: (x, y, yaw).
    pub fn laser_origin(&self, pose: Pose2) -> (f64, f64, f64) {
        let m = self.spec.robot.laser.mount;
        let (s, c) = pose.yaw.sin_cos();
        (
            pose.x + c * m.x - s * m.y,
            pose.y + s * m.x + c * m.y,
            pose.yaw + m.yaw,
        )
    }

    /// The description the world was built from.
    pub fn spec(&self) -> &WorldSpec {
        &self.spec
    }

    /// Warnings found while building (what the simulation changed from the description).
    pub fn warnings(&self) -> &[SpecProblem] {
        &self.warnings
    }

    /// The free region starts and goals are sampled from.
    pub fn free_region(&self) -> &FreeRegion {
        &self.region
    }

    /// Area of the free region, square metres.
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
        Some(self.frame.to_world(cx as f64 + u, cy as f64 + v))
    }

    /// The free-region point nearest to `(x, y)` (for "your goal is blocked; try here").
    pub fn nearest_free_point(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let (gx, gy) = self.frame.to_grid(x, y);
        let pw = self.frame.pw;
        let best = self.region.cells.iter().min_by(|a, b| {
            let d = |c: u32| {
                let c = c as usize;
                let (cx, cy) = ((c % pw) as f64 + 0.5, (c / pw) as f64 + 0.5);
                (cx - gx).hypot(cy - gy)
            };
            d(**a).total_cmp(&d(**b))
        })?;
        let c = *best as usize;
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
        reason = "checked to lie inside the grid before the cast"
    )]
    fn cell_index(&self, x: f64, y: f64) -> Option<usize> {
        let (gx, gy) = self.frame.to_grid(x, y);
        let f = &self.frame;
        (gx >= 0.0 && gy >= 0.0 && gx < f.pw as f64 && gy < f.ph as f64)
            .then(|| gy as usize * f.pw + gx as usize)
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

/// The padded grid's blocked cells: the border, every map cell that is not free (ROS trinary
/// semantics) and the rasterised walls.
fn wall_cells(frame: &Frame, spec: &WorldSpec) -> Vec<bool> {
    let (pw, ph) = (frame.pw, frame.ph);
    let mut walls = vec![false; pw * ph];
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
        rasterise_wall(frame, wall, &mut walls);
    }
    walls
}

/// The cell rectangles of the solids the laser and the footprint meet.
struct SolidRects {
    /// Solids at the laser's height: id and cells.
    laser: Vec<(u32, [usize; 4])>,
    /// Solids within the robot's height: id and cells, grown by its footprint radius and
    /// [`CLEARANCE_REACH`].
    collision: Vec<(u32, [usize; 4])>,
    /// The cells of the same solids, not grown.
    collision_cells: Vec<[usize; 4]>,
}

impl SolidRects {
    fn of(frame: &Frame, solids: &[Solid], robot: &crate::spec::RobotSpec) -> Self {
        let laser_z = robot.laser.mount.z;
        let mut rects = SolidRects {
            laser: Vec::new(),
            collision: Vec::new(),
            collision_cells: Vec::new(),
        };
        for (i, s) in solids.iter().enumerate() {
            let id = as_u32(i);
            if s.zmin <= laser_z && laser_z <= s.zmax {
                rects.laser.push((id, frame.cell_rect(s.rect, 0.0)));
            }
            if s.zmin < robot.height && s.zmax > 0.0 {
                rects.collision.push((
                    id,
                    frame.cell_rect(s.rect, robot.footprint_radius + CLEARANCE_REACH),
                ));
                rects.collision_cells.push(frame.cell_rect(s.rect, 0.0));
            }
        }
        rects
    }
}

/// Laser codes: walls, object cells, and elsewhere the safe jump to the nearest of either.
fn laser_codes(
    walls: &[bool],
    wall_feature: &[u32],
    laser_rects: &[(u32, [usize; 4])],
    pw: usize,
    ph: usize,
) -> Vec<u8> {
    let laser_feature = if laser_rects.is_empty() {
        None
    } else {
        let mut mask = walls.to_vec();
        for (_, r) in laser_rects {
            fill_rect(&mut mask, pw, r);
        }
        Some(feature_transform(&mask, pw, ph))
    };
    let mut laser_code = vec![0u8; pw * ph];
    let feature = laser_feature.as_deref().unwrap_or(wall_feature);
    for (i, code) in laser_code.iter_mut().enumerate() {
        *code = if walls[i] {
            BLOCKED
        } else {
            jump_code(i, feature[i], pw)
        };
    }
    for (_, r) in laser_rects {
        for y in r[1]..=r[3] {
            for x in r[0]..=r[2] {
                let c = &mut laser_code[y * pw + x];
                if *c != BLOCKED {
                    *c = OBJECT;
                }
            }
        }
    }
    laser_code
}

/// The free region: the largest 4-connected set of cells whose whole square keeps a disc of
/// `keep_m` (the footprint plus the sampling margin) clear of walls and of the bounding
/// rectangles `collision_cells` of objects within the robot's height.
fn free_region(
    walls: &[bool],
    wall_feature: &[u32],
    collision_cells: &[[usize; 4]],
    frame: &Frame,
    keep_m: f64,
) -> FreeRegion {
    let (pw, ph) = (frame.pw, frame.ph);
    let clear_feature = if collision_cells.is_empty() {
        None
    } else {
        let mut mask = walls.to_vec();
        for r in collision_cells {
            fill_rect(&mut mask, pw, r);
        }
        Some(feature_transform(&mask, pw, ph))
    };
    let feature = clear_feature.as_deref().unwrap_or(wall_feature);
    // Centre distance D to the nearest blocked centre bounds the distance from any point of
    // this cell to any blocked square from below by D - √2 cells.
    let need = keep_m * frame.inv_res + std::f64::consts::SQRT_2;
    let navigable: Vec<bool> = (0..pw * ph)
        .map(|i| {
            !walls[i]
                && (feature[i] == NO_FEATURE || centre_distance(i, feature[i] as usize, pw) >= need)
        })
        .collect();
    let regions = grid::regions::label(&navigable, pw, ph);
    let cells = regions
        .largest()
        .map_or_else(Vec::new, |r| regions.cells(r));
    let mut member = vec![0u64; (pw * ph).div_ceil(64)];
    for &c in &cells {
        member[c as usize >> 6] |= 1 << (c & 63);
    }
    FreeRegion { cells, member }
}

/// Laser jump code for a free cell whose nearest blocked cell is `feature`.
fn jump_code(i: usize, feature: u32, pw: usize) -> u8 {
    if feature == NO_FEATURE {
        return MAX_SKIP;
    }
    // From any point of this cell, every blocked square is at least D - √2 cells away; 1.5 keeps
    // a margin for rounding.
    let d = centre_distance(i, feature as usize, pw) - 1.5;
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
fn frame_for(spec: &WorldSpec, parts: &[Part]) -> Result<Frame, SpecProblem> {
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
        return Err(SpecProblem::error(
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
        return Err(SpecProblem::error(
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
