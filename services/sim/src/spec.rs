//! The typed description of a world the simulator builds: static occupancy, walls, objects and
//! the robot, with validation that names every problem's item and field.
//!
//! Conventions: metres and radians, the world frame has z up and the floor at z = 0. A solid's
//! `pose` is the centre of its bounding box (as SDF and URDF place primitives), and its `size`
//! is the full extent of that box along the solid's own axes.

use std::fmt;

pub use tosm::{Occupancy, OccupancyGrid, Pose2};

/// A pose in space: position in metres, orientation as roll, pitch, yaw in radians (applied in
/// that order about the fixed x, y, z axes, as URDF's `rpy`).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Pose3 {
    /// Position along x, metres.
    pub x: f64,
    /// Position along y, metres.
    pub y: f64,
    /// Position along z (up), metres.
    pub z: f64,
    /// Rotation about x, radians.
    pub roll: f64,
    /// Rotation about y, radians.
    pub pitch: f64,
    /// Rotation about z, radians.
    pub yaw: f64,
}

impl Pose3 {
    /// An upright pose: position and yaw, no roll or pitch.
    pub fn new(x: f64, y: f64, z: f64, yaw: f64) -> Self {
        Self {
            x,
            y,
            z,
            roll: 0.0,
            pitch: 0.0,
            yaw,
        }
    }

    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        [self.x, self.y, self.z, self.roll, self.pitch, self.yaw]
            .iter()
            .all(|v| v.is_finite())
    }

    /// Whether roll and pitch are (numerically) zero.
    pub fn is_upright(&self) -> bool {
        self.roll.abs() < 1e-9 && self.pitch.abs() < 1e-9
    }
}

/// Full extents of a bounding box along a solid's own x, y and z axes, metres.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Size3 {
    /// Extent along x (depth), metres.
    pub x: f64,
    /// Extent along y (width), metres.
    pub y: f64,
    /// Extent along z (height), metres.
    pub z: f64,
}

impl Size3 {
    /// A size of `x` by `y` by `z` metres.
    pub fn new(x: f64, y: f64, z: f64) -> Self {
        Self { x, y, z }
    }
}

/// The primitive shape of a placeholder or of a part.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    /// A box filling its size.
    Box,
    /// An upright cylinder: diameter from the larger of `size.x`, `size.y`, length `size.z`.
    Cylinder,
    /// A sphere: diameter from the largest component of the size.
    Sphere,
}

impl Shape {
    /// The lower-case name used in TOSM data and in exports.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Box => "box",
            Shape::Cylinder => "cylinder",
            Shape::Sphere => "sphere",
        }
    }

    /// Reads a shape name (`box`, `cuboid`, `cube`, `cylinder`, `sphere`, `ball`), ignoring case.
    pub fn parse(name: &str) -> Option<Shape> {
        match name.trim().to_ascii_lowercase().as_str() {
            "box" | "cuboid" | "cube" | "rectangular" | "block" => Some(Shape::Box),
            "cylinder" | "cylindrical" => Some(Shape::Cylinder),
            "sphere" | "ball" | "spherical" => Some(Shape::Sphere),
            _ => None,
        }
    }
}

/// An sRGB colour.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub struct Colour {
    /// Red, 0–255.
    pub r: u8,
    /// Green, 0–255.
    pub g: u8,
    /// Blue, 0–255.
    pub b: u8,
}

impl Colour {
    /// A colour from its components.
    pub const fn rgb(r: u8, g: u8, b: u8) -> Self {
        Self { r, g, b }
    }

    /// Neutral grey, for objects whose colour is not known.
    pub const GREY: Colour = Colour::rgb(128, 128, 128);

    /// Reads `#rrggbb`, `#rgb` or a basic colour name (CSS names such as `red`, `steelblue`
    /// are not all known: the common ones are), ignoring case.
    pub fn parse(text: &str) -> Option<Colour> {
        let t = text.trim().to_ascii_lowercase();
        if let Some(hex) = t.strip_prefix('#') {
            let digits: Option<Vec<u8>> = hex
                .chars()
                .map(|c| c.to_digit(16).and_then(|d| u8::try_from(d).ok()))
                .collect();
            return match digits?.as_slice() {
                [r1, r0, g1, g0, b1, b0] => {
                    Some(Colour::rgb(r1 * 16 + r0, g1 * 16 + g0, b1 * 16 + b0))
                }
                [r, g, b] => Some(Colour::rgb(r * 17, g * 17, b * 17)),
                _ => None,
            };
        }
        let c = match t.as_str() {
            "red" => Colour::rgb(220, 30, 30),
            "green" => Colour::rgb(40, 160, 40),
            "blue" => Colour::rgb(40, 80, 220),
            "yellow" => Colour::rgb(240, 210, 30),
            "orange" => Colour::rgb(245, 140, 20),
            "purple" | "violet" => Colour::rgb(140, 60, 170),
            "pink" => Colour::rgb(240, 130, 170),
            "brown" => Colour::rgb(130, 80, 40),
            "black" => Colour::rgb(20, 20, 20),
            "white" => Colour::rgb(245, 245, 245),
            "grey" | "gray" => Colour::GREY,
            "silver" => Colour::rgb(192, 192, 192),
            "beige" => Colour::rgb(225, 210, 170),
            "cyan" => Colour::rgb(30, 200, 220),
            "magenta" => Colour::rgb(210, 40, 190),
            _ => return None,
        };
        Some(c)
    }

    /// `#rrggbb`.
    pub fn to_hex(self) -> String {
        format!("#{:02x}{:02x}{:02x}", self.r, self.g, self.b)
    }

    /// Components scaled to 0–1, as SDF and URDF write colours.
    pub fn to_unit(self) -> [f64; 3] {
        [
            f64::from(self.r) / 255.0,
            f64::from(self.g) / 255.0,
            f64::from(self.b) / 255.0,
        ]
    }
}

/// A floor's metric map: every cell that is not free is solid from the floor to `wall_height`,
/// as ROS navigation's trinary maps mean it.
#[derive(Clone, Debug, PartialEq)]
pub struct GridMap {
    /// The place (or map) this grid belongs to, named in problems and exports.
    pub id: String,
    /// The occupancy grid.
    pub grid: OccupancyGrid,
    /// Height of the walls the occupied and unknown cells become, metres.
    pub wall_height: f64,
}

/// A straight wall, for example one edge of a place's boundary.
#[derive(Clone, Debug, PartialEq)]
pub struct WallSpec {
    /// The item the wall comes from (a place boundary), named in problems.
    pub id: String,
    /// One end, world (x, y), metres.
    pub start: [f64; 2],
    /// The other end, world (x, y), metres.
    pub end: [f64; 2],
    /// Thickness, metres (rasterised no thinner than one grid cell).
    pub thickness: f64,
    /// Height, metres.
    pub height: f64,
}

/// An object in the world: a library model when its class has one, otherwise a placeholder of
/// its own shape, size and colour.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectSpec {
    /// Identifier (the TOSM individual's IRI).
    pub id: String,
    /// TOSM class (IRI or local name), used to choose a library model.
    pub class: Option<String>,
    /// Perceived shape: what a placeholder is made of.
    pub shape: Shape,
    /// Bounding-box size.
    pub size: Size3,
    /// Pose of the bounding-box centre.
    pub pose: Pose3,
    /// Perceived colour.
    pub colour: Colour,
    /// For doors: whether the leaf is open (an open door leaves its frame only).
    pub open: bool,
}

/// Differential-drive kinematics from the robot's active wheels.
#[derive(Clone, Debug, PartialEq)]
pub struct DiffDriveSpec {
    /// Distance between the two active wheels' contact points, metres.
    pub wheel_separation: f64,
    /// Active wheel radius, metres.
    pub wheel_radius: f64,
    /// Largest wheel angular speed, rad/s, when the model gives one.
    pub max_wheel_speed: Option<f64>,
    /// Top linear speed either way, m/s, when the model gives one.
    pub max_linear_speed: Option<f64>,
    /// Top angular speed either way, rad/s, when the model gives one.
    pub max_angular_speed: Option<f64>,
    /// Largest linear acceleration, m/s², when the model gives one.
    pub max_linear_acceleration: Option<f64>,
    /// Largest angular acceleration, rad/s², when the model gives one.
    pub max_angular_acceleration: Option<f64>,
}

/// A planar laser range finder.
#[derive(Clone, Debug, PartialEq)]
pub struct LaserSpec {
    /// Identifier (the sensor part's IRI).
    pub id: String,
    /// Shortest range reported, metres.
    pub range_min: f64,
    /// Longest range reported, metres; rays that hit nothing report this.
    pub range_max: f64,
    /// Field of view, radians, centred on the sensor's x axis.
    pub fov: f64,
    /// Number of samples in one full scan.
    pub samples: usize,
    /// Mounting pose relative to the robot's base frame (on the floor, under its centre).
    pub mount: Pose3,
}

impl LaserSpec {
    /// Angle of sample `i` relative to the sensor's x axis, as ROS `LaserScan` numbers them
    /// (from `-fov/2` counter-clockwise; a full circle does not repeat its first sample).
    #[allow(
        clippy::cast_precision_loss,
        reason = "sample counts are far below 2^52"
    )]
    pub fn sample_angle(&self, i: usize) -> f64 {
        let full = self.fov >= std::f64::consts::TAU - 1e-9;
        let steps = if full {
            self.samples
        } else {
            self.samples.saturating_sub(1)
        };
        if steps == 0 {
            return 0.0;
        }
        -self.fov / 2.0 + self.fov * (i as f64) / (steps as f64)
    }

    /// Angles of `n` equally spaced beams picked from the scan's samples (the paper's 23 sparse
    /// readings), relative to the sensor's x axis; `None` when `n` is 0 or exceeds the samples.
    #[allow(
        clippy::cast_precision_loss,
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "sample counts are far below 2^52 and the rounded index is within 0..samples"
    )]
    pub fn beam_angles(&self, n: usize) -> Option<Vec<f64>> {
        if n == 0 || n > self.samples {
            return None;
        }
        if n == 1 {
            return Some(vec![self.sample_angle(self.samples / 2)]);
        }
        let last = (self.samples - 1) as f64;
        Some(
            (0..n)
                .map(|i| {
                    let idx = (i as f64 * last / (n - 1) as f64).round() as usize;
                    self.sample_angle(idx)
                })
                .collect(),
        )
    }
}

/// A camera, recorded for exports (the headless simulator renders no images).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraSpec {
    /// Identifier (the sensor part's IRI).
    pub id: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Frames per second.
    pub fps: f64,
    /// Horizontal field of view, radians.
    pub hfov: f64,
    /// Depth range of an RGB-D camera, metres.
    pub depth_range: Option<(f64, f64)>,
    /// Mounting pose relative to the robot's base frame.
    pub mount: Pose3,
}

/// A structural part of the robot's body.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotPartSpec {
    /// Identifier (the part's IRI).
    pub id: String,
    /// Primitive shape.
    pub shape: Shape,
    /// Bounding-box size.
    pub size: Size3,
    /// Pose of the bounding-box centre relative to the robot's base frame.
    pub pose: Pose3,
    /// Colour.
    pub colour: Colour,
    /// Mass, kilograms, when known.
    pub mass: Option<f64>,
}

/// A wheel of the robot.
#[derive(Clone, Debug, PartialEq)]
pub struct WheelSpec {
    /// Identifier (the wheel's IRI).
    pub id: String,
    /// Radius, metres.
    pub radius: f64,
    /// Width, metres.
    pub width: f64,
    /// Pose of the wheel centre relative to the robot's base frame (the axle along y).
    pub pose: Pose3,
    /// Whether the wheel is driven (active) or a caster (passive).
    pub active: bool,
}

/// The robot as the simulator needs it.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotSpec {
    /// Identifier (the robot's IRI).
    pub id: String,
    /// Radius of the circle that covers the robot seen from above, metres.
    pub footprint_radius: f64,
    /// Height of the robot, metres: it collides with anything lower than this.
    pub height: f64,
    /// Drive kinematics.
    pub drive: DiffDriveSpec,
    /// The laser range finder the policy reads.
    pub laser: LaserSpec,
    /// Cameras, recorded for exports.
    pub cameras: Vec<CameraSpec>,
    /// Structural parts, for exports and for deriving the footprint.
    pub parts: Vec<RobotPartSpec>,
    /// Wheels, for exports.
    pub wheels: Vec<WheelSpec>,
}

impl RobotSpec {
    /// A small differential robot like the paper's (a 0.2 m-radius base carrying a 180° laser with
    /// 690 samples at 0.3 m): useful defaults for tests, benchmarks and examples.
    pub fn example_differential() -> RobotSpec {
        let body = RobotPartSpec {
            id: "base".into(),
            shape: Shape::Cylinder,
            size: Size3::new(0.4, 0.4, 0.3),
            pose: Pose3::new(0.0, 0.0, 0.2, 0.0),
            colour: Colour::rgb(60, 60, 70),
            mass: Some(12.0),
        };
        let wheel = |id: &str, y: f64| WheelSpec {
            id: id.into(),
            radius: 0.05,
            width: 0.03,
            pose: Pose3::new(0.0, y, 0.05, 0.0),
            active: true,
        };
        RobotSpec {
            id: "example_robot".into(),
            footprint_radius: 0.2,
            height: 0.4,
            drive: DiffDriveSpec {
                wheel_separation: 0.34,
                wheel_radius: 0.05,
                max_wheel_speed: None,
                max_linear_speed: None,
                max_angular_speed: None,
                max_linear_acceleration: None,
                max_angular_acceleration: None,
            },
            laser: LaserSpec {
                id: "laser".into(),
                range_min: 0.05,
                range_max: 10.0,
                fov: std::f64::consts::PI,
                samples: 690,
                mount: Pose3::new(0.1, 0.0, 0.3, 0.0),
            },
            cameras: vec![],
            parts: vec![body],
            wheels: vec![
                wheel("left_wheel", 0.17),
                wheel("right_wheel", -0.17),
                WheelSpec {
                    id: "caster".into(),
                    radius: 0.025,
                    width: 0.02,
                    pose: Pose3::new(-0.15, 0.0, 0.025, 0.0),
                    active: false,
                },
            ],
        }
    }

    /// Radius of the smallest circle about the base origin covering the parts' and wheels'
    /// bounding boxes seen from above; `None` with no parts or wheels.
    pub fn footprint_from_parts(parts: &[RobotPartSpec], wheels: &[WheelSpec]) -> Option<f64> {
        let mut radius: Option<f64> = None;
        let boxes = parts
            .iter()
            .map(|p| (p.pose, half_extents_xy(p.shape, p.size)))
            .chain(wheels.iter().map(|w| (w.pose, (w.radius, w.width / 2.0))));
        for (pose, (hx, hy)) in boxes {
            let (s, c) = pose.yaw.sin_cos();
            for (sx, sy) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                let (lx, ly) = (sx * hx, sy * hy);
                let (x, y) = (pose.x + c * lx - s * ly, pose.y + s * lx + c * ly);
                let r = x.hypot(y);
                radius = Some(radius.map_or(r, |best| best.max(r)));
            }
        }
        radius
    }
}

/// Half extents in the plane of a solid's footprint (a cylinder and a sphere by their square).
fn half_extents_xy(shape: Shape, size: Size3) -> (f64, f64) {
    match shape {
        Shape::Box => (size.x / 2.0, size.y / 2.0),
        Shape::Cylinder => {
            let r = size.x.max(size.y) / 2.0;
            (r, r)
        }
        Shape::Sphere => {
            let r = size.x.max(size.y).max(size.z) / 2.0;
            (r, r)
        }
    }
}

/// Everything the simulator builds a world from.
#[derive(Clone, Debug, PartialEq)]
pub struct WorldSpec {
    /// Identifier (the mission or place), named in exports.
    pub id: String,
    /// The floor's metric map, if any. Without one the world is bounded by a box around its
    /// walls and objects.
    pub floor: Option<GridMap>,
    /// Walls, for example from place boundaries.
    pub walls: Vec<WallSpec>,
    /// Objects.
    pub objects: Vec<ObjectSpec>,
    /// The robot.
    pub robot: RobotSpec,
    /// Problems found while reading the description that did not stop it (an object skipped,
    /// a value assumed); [`crate::World`] reports them with its own warnings.
    pub notes: Vec<Problem>,
}

/// How serious a problem is.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Severity {
    /// The world cannot be built as described.
    Error,
    /// The world can be built, but differs from the description as the message says.
    Warning,
}

/// One thing wrong with a description, naming the item and the field.
#[derive(Clone, Debug, PartialEq)]
pub struct Problem {
    /// Error or warning.
    pub severity: Severity,
    /// The item (IRI or identifier) the problem is about.
    pub item: String,
    /// The field or property, for example `size.z` or `tosm:hasRange`.
    pub field: String,
    /// What is wrong, in a full sentence.
    pub message: String,
}

impl Problem {
    /// An error about `item`'s `field`.
    pub fn error(
        item: impl Into<String>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            severity: Severity::Error,
            item: item.into(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// A warning about `item`'s `field`.
    pub fn warning(
        item: impl Into<String>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Self {
            severity: Severity::Warning,
            ..Self::error(item, field, message)
        }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let level = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
        };
        write!(f, "{level}: {} {}: {}", self.item, self.field, self.message)
    }
}

/// A list of problems; an error type when any of them is an error.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Problems(pub Vec<Problem>);

impl Problems {
    /// Whether any problem is an error.
    pub fn has_errors(&self) -> bool {
        self.0.iter().any(|p| p.severity == Severity::Error)
    }

    /// The errors only.
    pub fn errors(&self) -> impl Iterator<Item = &Problem> {
        self.0.iter().filter(|p| p.severity == Severity::Error)
    }

    /// Whether there are no problems at all.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Adds a problem.
    pub fn push(&mut self, problem: Problem) {
        self.0.push(problem);
    }

    /// `Ok(warnings)` when there is no error, else `Err(self)`.
    pub fn into_result(self) -> Result<Vec<Problem>, Problems> {
        if self.has_errors() {
            Err(self)
        } else {
            Ok(self.0)
        }
    }
}

impl fmt::Display for Problems {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.errors().count();
        write!(f, "{n} error(s), {} warning(s)", self.0.len() - n)?;
        for p in &self.0 {
            write!(f, "\n  {p}")?;
        }
        Ok(())
    }
}

impl std::error::Error for Problems {}

/// The largest grid the simulator accepts: cell indices are `u32` and a grid this size already
/// takes about 3 GiB of distance fields.
pub const MAX_GRID_CELLS: usize = 400_000_000;

/// Collects problems for one item, so each check is one line.
struct Checker<'a> {
    out: &'a mut Problems,
    item: &'a str,
}

impl Checker<'_> {
    fn positive(&mut self, field: &str, value: f64, what: &str) {
        if !(value.is_finite() && value > 0.0) {
            self.out.push(Problem::error(
                self.item,
                field,
                format!("{what} must be a positive finite number, got {value}"),
            ));
        }
    }

    fn optional_positive(&mut self, field: &str, value: Option<f64>, what: &str) {
        if let Some(v) = value {
            self.positive(field, v, what);
        }
    }

    fn size(&mut self, field: &str, size: Size3) {
        self.positive(&format!("{field}.x"), size.x, "a size");
        self.positive(&format!("{field}.y"), size.y, "a size");
        self.positive(&format!("{field}.z"), size.z, "a size");
    }

    fn pose(&mut self, field: &str, pose: &Pose3) -> bool {
        if pose.is_finite() {
            return true;
        }
        self.out.push(Problem::error(
            self.item,
            field,
            format!("every component of a pose must be finite, got {pose:?}"),
        ));
        false
    }

    fn error(&mut self, field: &str, message: String) {
        self.out.push(Problem::error(self.item, field, message));
    }

    fn warning(&mut self, field: &str, message: String) {
        self.out.push(Problem::warning(self.item, field, message));
    }
}

impl WorldSpec {
    /// Every problem with this description: errors that stop the world from being built and
    /// warnings about what the simulation changes. Never panics, whatever the values.
    pub fn validate(&self) -> Problems {
        let mut out = Problems(self.notes.clone());
        if let Some(floor) = &self.floor {
            validate_floor(floor, &self.robot, &mut out);
        }
        for wall in &self.walls {
            let mut c = Checker {
                out: &mut out,
                item: &wall.id,
            };
            for (field, v) in [
                ("start.x", wall.start[0]),
                ("start.y", wall.start[1]),
                ("end.x", wall.end[0]),
                ("end.y", wall.end[1]),
            ] {
                if !v.is_finite() {
                    c.error(field, format!("a wall end must be finite, got {v}"));
                }
            }
            c.positive("thickness", wall.thickness, "a wall thickness");
            c.positive("height", wall.height, "a wall height");
        }
        let mut seen = std::collections::HashSet::new();
        for obj in &self.objects {
            validate_object(obj, &mut out);
            if !seen.insert(obj.id.as_str()) {
                out.push(Problem::error(
                    &obj.id,
                    "id",
                    "two objects share this identifier",
                ));
            }
        }
        validate_robot(&self.robot, &mut out);
        if self.floor.is_none() && self.walls.is_empty() {
            out.push(Problem::warning(
                &self.id,
                "floor",
                "the world has no metric map and no walls: it is bounded by a box 1 m around its objects",
            ));
        }
        out
    }
}

fn validate_floor(floor: &GridMap, robot: &RobotSpec, out: &mut Problems) {
    let g = &floor.grid;
    let mut c = Checker {
        out,
        item: &floor.id,
    };
    c.positive("resolution", g.resolution, "the map resolution");
    c.positive("wall_height", floor.wall_height, "the wall height");
    for (field, v) in [
        ("origin.x", g.origin.x),
        ("origin.y", g.origin.y),
        ("origin.yaw", g.origin.yaw),
    ] {
        if !v.is_finite() {
            c.error(field, format!("the map origin must be finite, got {v}"));
        }
    }
    if g.width == 0 || g.height == 0 {
        c.error(
            "cells",
            format!("the map has no cells ({} x {})", g.width, g.height),
        );
    } else if g.width.checked_mul(g.height) != Some(g.cells.len()) {
        c.error(
            "cells",
            format!(
                "the map is {} x {} but holds {} cells",
                g.width,
                g.height,
                g.cells.len()
            ),
        );
    } else if (g.width + 2).saturating_mul(g.height + 2) > MAX_GRID_CELLS {
        c.error(
            "cells",
            format!(
                "the map has {} cells, more than the {MAX_GRID_CELLS} the simulator accepts",
                g.cells.len()
            ),
        );
    } else if !g.cells.contains(&Occupancy::Free) {
        c.error("cells", "the map has no free cell".into());
    }
    if floor.wall_height.is_finite() && floor.wall_height < robot.laser.mount.z {
        c.warning(
            "wall_height",
            format!(
                "walls of {} m are lower than the laser at {} m; the simulator still extrudes them through every height",
                floor.wall_height, robot.laser.mount.z
            ),
        );
    }
}

fn validate_object(obj: &ObjectSpec, out: &mut Problems) {
    let mut c = Checker { out, item: &obj.id };
    if obj.id.trim().is_empty() {
        c.error("id", "an object needs a non-empty identifier".into());
    }
    c.size("size", obj.size);
    if c.pose("pose", &obj.pose) {
        if !obj.pose.is_upright() {
            c.warning(
                "pose",
                format!(
                    "roll {} and pitch {} are ignored: objects are simulated upright",
                    obj.pose.roll, obj.pose.pitch
                ),
            );
        }
        if obj.size.z.is_finite() && obj.pose.z - obj.size.z / 2.0 < -0.01 {
            c.warning(
                "pose.z",
                format!(
                    "the object reaches {:.3} m below the floor (pose.z is its centre)",
                    obj.size.z / 2.0 - obj.pose.z
                ),
            );
        }
    }
    match obj.shape {
        Shape::Cylinder if (obj.size.x - obj.size.y).abs() > 1e-6 => c.warning(
            "size",
            format!(
                "a cylinder needs equal x and y sizes; {} m is used as its diameter",
                obj.size.x.max(obj.size.y)
            ),
        ),
        Shape::Sphere
            if (obj.size.x - obj.size.y).abs() > 1e-6 || (obj.size.x - obj.size.z).abs() > 1e-6 =>
        {
            c.warning(
                "size",
                format!(
                    "a sphere needs equal sizes; {} m is used as its diameter",
                    obj.size.x.max(obj.size.y).max(obj.size.z)
                ),
            )
        }
        _ => {}
    }
}

fn validate_robot(robot: &RobotSpec, out: &mut Problems) {
    let mut c = Checker {
        out,
        item: &robot.id,
    };
    c.positive(
        "footprint_radius",
        robot.footprint_radius,
        "the footprint radius",
    );
    c.positive("height", robot.height, "the robot height");
    let d = &robot.drive;
    c.positive(
        "drive.wheel_separation",
        d.wheel_separation,
        "the wheel separation",
    );
    c.positive("drive.wheel_radius", d.wheel_radius, "the wheel radius");
    c.optional_positive(
        "drive.max_wheel_speed",
        d.max_wheel_speed,
        "the wheel speed limit",
    );
    c.optional_positive(
        "drive.max_linear_speed",
        d.max_linear_speed,
        "the linear speed limit",
    );
    c.optional_positive(
        "drive.max_angular_speed",
        d.max_angular_speed,
        "the angular speed limit",
    );
    c.optional_positive(
        "drive.max_linear_acceleration",
        d.max_linear_acceleration,
        "the linear acceleration limit",
    );
    c.optional_positive(
        "drive.max_angular_acceleration",
        d.max_angular_acceleration,
        "the angular acceleration limit",
    );
    let l = &robot.laser;
    let mut c = Checker { out, item: &l.id };
    if !(l.range_min.is_finite() && l.range_min >= 0.0) {
        c.error(
            "range_min",
            format!(
                "the shortest range must be finite and not negative, got {}",
                l.range_min
            ),
        );
    }
    c.positive("range_max", l.range_max, "the longest range");
    if l.range_max.is_finite() && l.range_min.is_finite() && l.range_max <= l.range_min {
        c.error(
            "range_max",
            format!(
                "the longest range {} m must exceed the shortest {} m",
                l.range_max, l.range_min
            ),
        );
    }
    if !(l.fov.is_finite() && l.fov > 0.0 && l.fov <= std::f64::consts::TAU + 1e-9) {
        c.error(
            "fov",
            format!(
                "the field of view must be in (0, 2π] radians, got {}",
                l.fov
            ),
        );
    }
    if l.samples == 0 {
        c.error("samples", "a laser needs at least one sample".into());
    }
    if c.pose("mount", &l.mount) {
        if !l.mount.is_upright() {
            c.warning(
                "mount",
                "the laser is tilted; the simulator casts its rays horizontally".into(),
            );
        }
        if l.mount.z <= 0.0 {
            c.error(
                "mount.z",
                format!("the laser must be above the floor, got z = {} m", l.mount.z),
            );
        } else if robot.height.is_finite() && l.mount.z > robot.height + 1e-9 {
            c.warning(
                "mount.z",
                format!(
                    "the laser at {} m is above the robot's height {} m",
                    l.mount.z, robot.height
                ),
            );
        }
    }
    for cam in &robot.cameras {
        let mut c = Checker { out, item: &cam.id };
        if cam.width == 0 || cam.height == 0 {
            c.error(
                "resolution",
                format!(
                    "a camera image of {} x {} pixels is empty",
                    cam.width, cam.height
                ),
            );
        }
        c.positive("fps", cam.fps, "the frame rate");
        if !(cam.hfov.is_finite() && cam.hfov > 0.0 && cam.hfov < std::f64::consts::PI) {
            c.error(
                "hfov",
                format!(
                    "the horizontal field of view must be in (0, π) radians, got {}",
                    cam.hfov
                ),
            );
        }
        if let Some((near, far)) = cam.depth_range
            && !(near.is_finite() && far.is_finite() && near >= 0.0 && far > near)
        {
            c.error(
                "depth_range",
                format!("the depth range must satisfy 0 <= near < far, got {near} to {far}"),
            );
        }
        c.pose("mount", &cam.mount);
    }
    for part in &robot.parts {
        let mut c = Checker {
            out,
            item: &part.id,
        };
        c.size("size", part.size);
        c.pose("pose", &part.pose);
        c.optional_positive("mass", part.mass, "the mass");
    }
    for wheel in &robot.wheels {
        let mut c = Checker {
            out,
            item: &wheel.id,
        };
        c.positive("radius", wheel.radius, "the wheel radius");
        c.positive("width", wheel.width, "the wheel width");
        c.pose("pose", &wheel.pose);
    }
}
