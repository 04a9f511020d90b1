//! The typed description of a world the simulator builds: static occupancy, walls, objects and
//! the robot, with validation that names every problem's item and field.
//!
//! Conventions: metres and radians, the world frame has z up and the floor at z = 0. A solid's
//! `pose` is the centre of its bounding box (as SDF and URDF place primitives), and its `size`
//! is the full extent of that box along the solid's own axes.
//!
//! `problems` holds what validation reports ([`SpecProblem`]); `validate` the checks.

mod problems;
mod validate;

pub use problems::{Severity, SpecProblem, SpecProblems};

pub use tosm::{Occupancy, OccupancyGrid, Pose2, Pose3};

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
pub struct FloorMap {
    /// The place (or map) this grid belongs to, named in problems and exports.
    pub id: String,
    /// The occupancy grid.
    pub grid: OccupancyGrid,
    /// Height of the walls the occupied and unknown cells become, metres.
    pub wall_height: f64,
    /// The ROS frame the grid's coordinates are in (the map's `tosm:frameId`, REP-105's `map`
    /// by default): what plans, map exports and route graphs of this floor name.
    pub frame_id: String,
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

/// What the knowledge says about people on a floor (TOSM's symbolic and implicit models of a
/// place): how many to expect where, and where they walk. The simulation spawns people from it
/// ([`crate::crowd`]); nothing here is a person, only what the fleet knows about people.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PeopleSpec {
    /// Places with a known expected number of people.
    pub places: Vec<PeoplePlaceSpec>,
    /// Usual walking routes: people walk them end to end and back.
    pub routes: Vec<RouteSpec>,
    /// Attractors (a vending machine, a desk): people walk to one and linger.
    pub attractors: Vec<AttractorSpec>,
}

impl PeopleSpec {
    /// Whether the knowledge says nothing about people.
    pub fn is_empty(&self) -> bool {
        self.places.is_empty() && self.routes.is_empty() && self.attractors.is_empty()
    }

    /// The number of people expected on the floor at `hour` (0–23; `None`: no time of day
    /// given): the sum over its places of [`PeoplePlaceSpec::expected_at`].
    pub fn expected_at(&self, hour: Option<u8>) -> f64 {
        self.places.iter().map(|p| p.expected_at(hour)).sum()
    }
}

/// A place's expected number of people.
#[derive(Clone, Debug, PartialEq)]
pub struct PeoplePlaceSpec {
    /// Identifier (the place's IRI).
    pub id: String,
    /// Expected number of people at any time of day (an engineer's figure, or the running
    /// estimate from robots' observations when there is one).
    pub expected: f64,
    /// Expected number by hour of the day where known: (hour 0–23, people).
    pub by_hour: Vec<(u8, f64)>,
    /// The place's boundary on the floor, metres (x, y), when it has one: people of this place
    /// spawn inside it. Without one they spawn anywhere on the floor.
    pub boundary: Vec<[f64; 2]>,
}

impl PeoplePlaceSpec {
    /// The expected number at `hour`: the hour's own figure when there is one, else
    /// [`Self::expected`].
    pub fn expected_at(&self, hour: Option<u8>) -> f64 {
        hour.and_then(|h| self.by_hour.iter().find(|(k, _)| *k == h))
            .map_or(self.expected, |(_, n)| *n)
    }
}

/// A usual walking route: a polyline on the floor, metres.
#[derive(Clone, Debug, PartialEq)]
pub struct RouteSpec {
    /// Identifier (the route's IRI).
    pub id: String,
    /// The points walked in order, at least two.
    pub points: Vec<[f64; 2]>,
}

/// A point people walk to and linger at.
#[derive(Clone, Debug, PartialEq)]
pub struct AttractorSpec {
    /// Identifier (the attractor's IRI: an object or a place).
    pub id: String,
    /// Where people stand, metres.
    pub position: [f64; 2],
    /// How long people linger there, seconds.
    pub dwell_s: f64,
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
    /// Largest linear deceleration (braking), m/s²; absent: the linear acceleration.
    pub max_linear_deceleration: Option<f64>,
    /// Largest angular deceleration, rad/s²; absent: the angular acceleration.
    pub max_angular_deceleration: Option<f64>,
    /// Seconds a velocity command takes to reach the wheels (at most
    /// [`MAX_CONTROL_LATENCY_S`]); absent: none.
    pub control_latency: Option<f64>,
}

/// Longest control latency a robot model may give, seconds (the ontology's bound too).
pub const MAX_CONTROL_LATENCY_S: f64 = 1.0;

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
    pub fn beam_angles(&self, n: usize) -> Option<Vec<f64>> {
        Some(
            self.beam_samples(n)?
                .into_iter()
                .map(|i| self.sample_angle(i))
                .collect(),
        )
    }

    /// The samples [`LaserSpec::beam_angles`] reads for `n` beams, in its order: `n` spread
    /// evenly over the scan (rounded to the nearest sample), both ends included; the middle one
    /// for a single beam. `None` when `n` is 0 or exceeds the samples.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "sample counts are far below 2^52 and the rounded index is within 0..samples"
    )]
    pub fn beam_samples(&self, n: usize) -> Option<Vec<usize>> {
        if n == 0 || n > self.samples {
            return None;
        }
        if n == 1 {
            return Some(vec![self.samples / 2]);
        }
        let last = (self.samples - 1) as f64;
        Some(
            (0..n)
                .map(|i| (i as f64 * last / (n - 1) as f64).round() as usize)
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
                max_linear_deceleration: None,
                max_angular_deceleration: None,
                control_latency: None,
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
        // Round parts (cylinders standing up, spheres) reach out by their circle, not by the
        // corners of its square: a round base's footprint is its radius.
        for p in parts
            .iter()
            .filter(|p| matches!(p.shape, Shape::Cylinder | Shape::Sphere))
        {
            let (r, _) = half_extents_xy(p.shape, p.size);
            let reach = p.pose.x.hypot(p.pose.y) + r;
            radius = Some(radius.map_or(reach, |best| best.max(reach)));
        }
        let boxes = parts
            .iter()
            .filter(|p| p.shape == Shape::Box)
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
    pub floor: Option<FloorMap>,
    /// Walls, for example from place boundaries.
    pub walls: Vec<WallSpec>,
    /// Objects.
    pub objects: Vec<ObjectSpec>,
    /// The robot.
    pub robot: RobotSpec,
    /// What knowledge says about the people on the floor; empty when it says nothing.
    pub people: PeopleSpec,
    /// Problems found while reading the description that did not stop it (an object skipped,
    /// a value assumed); [`crate::World`] reports them with its own warnings.
    pub notes: Vec<SpecProblem>,
}

impl WorldSpec {
    /// The ROS frame the world's coordinates are in: the floor map's, else REP-105's `map`.
    pub fn map_frame(&self) -> &str {
        self.floor
            .as_ref()
            .map_or(tosm::DEFAULT_MAP_FRAME, |f| f.frame_id.as_str())
    }
}

/// The largest grid the simulator accepts: cell indices are `u32` and a grid this size already
/// takes about 3 GiB of distance fields.
pub const MAX_GRID_CELLS: usize = 400_000_000;

/// A grid index or coordinate as `u32`; every grid is below [`MAX_GRID_CELLS`].
#[allow(
    clippy::cast_possible_truncation,
    reason = "grids are validated to hold fewer than u32::MAX cells"
)]
pub(crate) fn as_u32(v: usize) -> u32 {
    v as u32
}
