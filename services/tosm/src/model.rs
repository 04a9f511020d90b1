//! Typed TOSM values: places, objects and robots with their explicit, implicit and symbolic
//! models, as read from and written to RDF by [`crate::read`] and [`crate::write`].
//!
//! Units are SI (metres, radians, kilograms, seconds), as in the ontology. Every IRI is kept as
//! a `String` so that the values stay plain data.

use crate::occupancy::{CANONICAL_FREE_THRESH, CANONICAL_OCCUPIED_THRESH, OccupancyGrid, Pose2};

/// A pose in 3-D: position in metres, orientation as roll, pitch, yaw in radians (extrinsic
/// x, y, z rotations, as in URDF and SDF). The TOSM class `tosm:Pose`; the simulator's worlds
/// use the same type (`sim::Pose3`).
#[derive(Copy, Clone, Debug, PartialEq, Default)]
pub struct Pose3 {
    /// Position along x, metres.
    pub x: f64,
    /// Position along y, metres.
    pub y: f64,
    /// Position along z, metres.
    pub z: f64,
    /// Rotation about x, radians.
    pub roll: f64,
    /// Rotation about y, radians.
    pub pitch: f64,
    /// Rotation about z, radians.
    pub yaw: f64,
}

impl Pose3 {
    /// A pose at `(x, y, z)` turned by `yaw` about the vertical axis.
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

/// The geometry and size of an entity, centred on its pose.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Shape {
    /// A box with extents along the entity's x, y and z axes.
    Box {
        /// Extent along x, metres.
        length: f64,
        /// Extent along y, metres.
        width: f64,
        /// Extent along z, metres.
        height: f64,
    },
    /// An upright cylinder (axis along z).
    Cylinder {
        /// Diameter, metres.
        diameter: f64,
        /// Height, metres.
        height: f64,
    },
    /// A sphere.
    Sphere {
        /// Diameter, metres.
        diameter: f64,
    },
}

impl Shape {
    /// The extents of the shape's bounding box along x, y and z (its size), metres.
    pub fn size(&self) -> [f64; 3] {
        match *self {
            Shape::Box {
                length,
                width,
                height,
            } => [length, width, height],
            Shape::Cylinder { diameter, height } => [diameter, diameter, height],
            Shape::Sphere { diameter } => [diameter, diameter, diameter],
        }
    }
}

/// A colour: linear sRGB components and opacity, each in `[0, 1]`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Colour {
    /// Red.
    pub r: f64,
    /// Green.
    pub g: f64,
    /// Blue.
    pub b: f64,
    /// Opacity (1 = opaque).
    pub a: f64,
}

impl Colour {
    /// An opaque colour.
    pub fn rgb(r: f64, g: f64, b: f64) -> Self {
        Self { r, g, b, a: 1.0 }
    }
}

/// The symbolic model of an entity.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Symbol {
    /// Human-readable name (`tosm:name`, required).
    pub name: String,
    /// Identification code (`tosm:identifier`).
    pub identifier: Option<String>,
    /// Free-text description (`tosm:description`).
    pub description: Option<String>,
}

impl Symbol {
    /// A symbol with only a name.
    pub fn named(name: &str) -> Self {
        Self {
            name: name.to_owned(),
            identifier: None,
            description: None,
        }
    }
}

/// Physical properties of the implicit model shared by objects and robot parts.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Physical {
    /// Mass, kilograms (> 0).
    pub mass_kg: Option<f64>,
    /// IRI of a `tosm:Material` individual (e.g. `tosm:Wood`).
    pub material: Option<String>,
    /// Coulomb friction coefficient (>= 0).
    pub friction: Option<f64>,
}

/// The kind of a place.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PlaceKind {
    /// `tosm:Building`.
    Building,
    /// `tosm:Floor`: carries the metric map.
    Floor,
    /// `tosm:Corridor`.
    Corridor,
    /// `tosm:Room`.
    Room,
    /// `tosm:Hall`.
    Hall,
    /// A `tosm:Place` of no more specific known kind.
    Other,
}

/// The frame of a floor's map when the graph states none (REP-105's `map`).
pub const DEFAULT_MAP_FRAME: &str = "map";

/// Whether `name` is a ROS frame name as tf2 and REP-105 use them: letters, digits, `_` and
/// `/`, not starting with a digit or `/`, at most 256 bytes.
pub fn is_ros_frame_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 256
        && !name.starts_with(|c: char| c.is_ascii_digit() || c == '/')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '/')
}

/// A floor's metric map: a map_server occupancy grid stored in the graph as a PNG.
#[derive(Clone, Debug, PartialEq)]
pub struct MetricMap {
    /// The map individual's IRI (conventionally `<floor>/map`).
    pub iri: String,
    /// Metres per cell.
    pub resolution: f64,
    /// World pose of the lower-left corner of the lower-left cell.
    pub origin: Pose2,
    /// map_server `occupied_thresh`.
    pub occupied_thresh: f64,
    /// map_server `free_thresh`.
    pub free_thresh: f64,
    /// map_server `negate`.
    pub negate: bool,
    /// The ROS frame the map's coordinates are in (`tosm:frameId`; [`DEFAULT_MAP_FRAME`] when
    /// not stated).
    pub frame_id: String,
    /// The PNG image as stored (image row 0 = top of the map).
    pub png: Vec<u8>,
    /// The grid the PNG decodes to under the thresholds above.
    pub grid: OccupancyGrid,
}

impl MetricMap {
    /// The conventional IRI of a floor's map.
    pub fn iri_for_floor(floor_iri: &str) -> String {
        format!("{floor_iri}/map")
    }

    /// A metric map holding `grid`, stored as [`OccupancyGrid::to_png`] with the thresholds
    /// under which that image decodes back to `grid`.
    pub fn from_grid(iri: &str, grid: OccupancyGrid) -> Self {
        Self {
            iri: iri.to_owned(),
            resolution: grid.resolution,
            origin: grid.origin,
            occupied_thresh: CANONICAL_OCCUPIED_THRESH,
            free_thresh: CANONICAL_FREE_THRESH,
            negate: false,
            frame_id: DEFAULT_MAP_FRAME.to_owned(),
            png: grid.to_png(),
            grid,
        }
    }
}

/// A place: building, floor, corridor, room or hall.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    /// The place's IRI.
    pub iri: String,
    /// Its most specific known kind.
    pub kind: PlaceKind,
    /// Symbolic model.
    pub symbol: Symbol,
    /// Boundary polygon `(x, y)` in the floor's frame, in order, not closed. Empty when unknown.
    pub boundary: Vec<(f64, f64)>,
    /// The place this one is directly inside of (`tosm:isDirectlyInsideOf`).
    pub parent: Option<String>,
    /// Places a robot can drive to directly from this one, sorted.
    pub connected: Vec<String>,
    /// Share of the area that is occupied, in `[0, 1]`.
    pub complexity: Option<f64>,
    /// Storey number, for floors.
    pub level: Option<i64>,
    /// The metric map (required for floors).
    pub map: Option<MetricMap>,
}

/// The object classes the ontology names.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ObjectClass {
    /// `tosm:Door`.
    Door,
    /// `tosm:Table`.
    Table,
    /// `tosm:Chair`.
    Chair,
    /// `tosm:Shelf`.
    Shelf,
    /// `tosm:Cabinet`.
    Cabinet,
    /// `tosm:Sofa`.
    Sofa,
    /// `tosm:Bin`.
    Bin,
    /// `tosm:VendingMachine`.
    VendingMachine,
    /// Any other class (a plain `tosm:Object` or a class from another vocabulary).
    Other,
}

/// A spatial relation from one object to another entity.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum RelationKind {
    /// `tosm:isInFrontOf`.
    InFrontOf,
    /// `tosm:isNextTo` (symmetric).
    NextTo,
    /// `tosm:isInsideOf` asserted besides the direct container (e.g. from a robot's report).
    InsideOf,
}

/// A spatial relation to another entity.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Relation {
    /// Which relation.
    pub kind: RelationKind,
    /// The other entity's IRI.
    pub target: String,
}

/// An object in a place.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    /// The object's IRI.
    pub iri: String,
    /// Its most specific class IRI.
    pub class_iri: String,
    /// That class, when the ontology names it.
    pub class: ObjectClass,
    /// Symbolic model.
    pub symbol: Symbol,
    /// Pose of the shape's centre in the floor's frame.
    pub pose: Pose3,
    /// Shape and size.
    pub shape: Shape,
    /// Colour, when known.
    pub colour: Option<Colour>,
    /// Colour name, when known.
    pub colour_name: Option<String>,
    /// Mass, material, friction.
    pub physical: Physical,
    /// The place (or object) it is directly inside of.
    pub inside_of: String,
    /// Other spatial relations, sorted.
    pub relations: Vec<Relation>,
    /// For doors: whether the door stands open.
    pub is_open: Option<bool>,
    /// The robot that reported it.
    pub reported_by: Option<String>,
    /// When it was reported, as an `xsd:dateTime` lexical form.
    pub reported_at: Option<String>,
}

/// What every robot part has: identity, mounting pose and the explicit/implicit basics.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// The part's IRI.
    pub iri: String,
    /// Symbolic model.
    pub symbol: Symbol,
    /// Pose of the part's centre in the robot frame.
    pub mounting: Pose3,
    /// Shape and size, when given (wheels are described by radius and width instead).
    pub shape: Option<Shape>,
    /// Colour, when known.
    pub colour: Option<Colour>,
    /// Mass, material, friction.
    pub physical: Physical,
}

/// A rigid structural part (a URDF link); mass and material are required.
#[derive(Clone, Debug, PartialEq)]
pub struct StructuralPart {
    /// Common part data.
    pub part: Part,
}

/// A wheel; its axle is the y axis of its mounting pose.
#[derive(Clone, Debug, PartialEq)]
pub struct Wheel {
    /// Common part data.
    pub part: Part,
    /// Driven (`tosm:ActiveWheel`) or not (`tosm:PassiveWheel`).
    pub active: bool,
    /// A swivelling caster (`tosm:CasterWheel`, always passive).
    pub caster: bool,
    /// Radius, metres.
    pub radius: f64,
    /// Tread width, metres.
    pub width: Option<f64>,
}

/// How a joint moves.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// `tosm:FixedJoint`.
    Fixed,
    /// `tosm:ContinuousJoint`: unlimited rotation about `axis`.
    Continuous,
}

/// A joint between two parts; its origin is the child's mounting pose.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// The joint's IRI.
    pub iri: String,
    /// Symbolic model.
    pub symbol: Symbol,
    /// Fixed or continuous.
    pub kind: JointKind,
    /// IRI of the parent part.
    pub parent: String,
    /// IRI of the child part.
    pub child: String,
    /// Rotation axis in the child's frame; `[0, 1, 0]` when not stated.
    pub axis: [f64; 3],
}

/// A planar laser range finder.
#[derive(Clone, Debug, PartialEq)]
pub struct Laser {
    /// Common part data.
    pub part: Part,
    /// Nearest measurable range, metres.
    pub range_min: f64,
    /// Farthest measurable range, metres.
    pub range_max: f64,
    /// Angle swept, radians, centred on the sensor's x axis.
    pub view_angle: f64,
    /// Number of samples per scan.
    pub samples: u32,
    /// Angle between samples, radians.
    pub angular_resolution: f64,
    /// Scan rate, Hz.
    pub rate_hz: Option<f64>,
}

/// The kind of a camera.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum CameraKind {
    /// `tosm:Camera`.
    Mono,
    /// `tosm:StereoCamera`.
    Stereo,
    /// `tosm:RGBDCamera`.
    RgbD,
}

/// A camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Common part data.
    pub part: Part,
    /// Mono, stereo or RGB-D.
    pub kind: CameraKind,
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// Frames per second.
    pub fps: f64,
    /// Horizontal field of view, radians.
    pub horizontal_fov: f64,
    /// Vertical field of view, radians.
    pub vertical_fov: Option<f64>,
    /// Depth range `(min, max)`, metres (stereo and RGB-D cameras).
    pub depth_range: Option<(f64, f64)>,
    /// Stereo baseline, metres.
    pub baseline: Option<f64>,
}

/// A robot's acceleration limits (`None`: not in its model). A deceleration absent where the
/// acceleration is given brakes as fast as it accelerates.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dynamics {
    /// Largest linear acceleration, m/s².
    pub max_linear_acceleration: Option<f64>,
    /// Largest linear deceleration (braking), m/s².
    pub max_linear_deceleration: Option<f64>,
    /// Largest angular acceleration, rad/s².
    pub max_angular_acceleration: Option<f64>,
    /// Largest angular deceleration, rad/s².
    pub max_angular_deceleration: Option<f64>,
    /// Seconds a velocity command takes to reach the wheels.
    pub control_latency: Option<f64>,
}

/// A robot: its parts, joints, wheels and sensors.
#[derive(Clone, Debug, PartialEq)]
pub struct Robot {
    /// The robot's IRI.
    pub iri: String,
    /// Symbolic model.
    pub symbol: Symbol,
    /// Whether it is a `tosm:DifferentialDriveRobot`.
    pub differential_drive: bool,
    /// Top linear speed, m/s.
    pub max_linear_speed: Option<f64>,
    /// Top angular speed, rad/s.
    pub max_angular_speed: Option<f64>,
    /// How fast it gains and loses linear and angular speed.
    pub dynamics: Dynamics,
    /// IRI of the base part (root of the kinematic tree), one of `structure`.
    pub base: String,
    /// Structural parts other than wheels, sorted by IRI.
    pub structure: Vec<StructuralPart>,
    /// Wheels, sorted by IRI.
    pub wheels: Vec<Wheel>,
    /// Joints, sorted by IRI.
    pub joints: Vec<Joint>,
    /// Laser range finders, sorted by IRI.
    pub lasers: Vec<Laser>,
    /// Cameras, sorted by IRI.
    pub cameras: Vec<Camera>,
}

impl Robot {
    /// The base part.
    pub fn base_part(&self) -> Option<&StructuralPart> {
        self.structure.iter().find(|p| p.part.iri == self.base)
    }

    /// Length (x) and width (y) of the base part's shape, metres: the robot's footprint.
    pub fn footprint(&self) -> Option<(f64, f64)> {
        let [l, w, _] = self.base_part()?.part.shape?.size();
        Some((l, w))
    }

    /// The driven wheels.
    pub fn active_wheels(&self) -> impl Iterator<Item = &Wheel> {
        self.wheels.iter().filter(|w| w.active)
    }

    /// Distance between the two driven wheels' mounting positions (for a differential drive
    /// with exactly two), metres.
    pub fn wheel_separation(&self) -> Option<f64> {
        let mut active = self.active_wheels();
        let (a, b) = (active.next()?, active.next()?);
        if active.next().is_some() {
            return None;
        }
        let (pa, pb) = (a.part.mounting, b.part.mounting);
        Some(((pa.x - pb.x).powi(2) + (pa.y - pb.y).powi(2) + (pa.z - pb.z).powi(2)).sqrt())
    }

    /// Every part's common data, in a stable order (structure, wheels, lasers, cameras).
    pub fn parts(&self) -> impl Iterator<Item = &Part> {
        self.structure
            .iter()
            .map(|p| &p.part)
            .chain(self.wheels.iter().map(|w| &w.part))
            .chain(self.lasers.iter().map(|l| &l.part))
            .chain(self.cameras.iter().map(|c| &c.part))
    }
}

/// The weight a new count has at least in a running people estimate: each count moves the
/// estimate by `max(1/n, ESTIMATE_MIN_WEIGHT)` of the way to it, `n` the number of counts so
/// far (this one included). The first five counts give their plain mean; after that the
/// estimate is an exponentially weighted mean in which the latest count weighs 0.2, so it
/// follows a place that gets busier or quieter within about ten counts.
pub const ESTIMATE_MIN_WEIGHT: f64 = 0.2;

/// What robots' counts of people in a place add up to (`tosm:PeopleEstimate`): over the whole
/// day, or for one hour of the day.
#[derive(Clone, Debug, PartialEq)]
pub struct PeopleEstimate {
    /// The hour of day (0–23) the estimate is for; `None`: the whole day.
    pub hour: Option<u8>,
    /// The estimated number of people (`tosm:estimatedPeople`), >= 0.
    pub people: f64,
    /// How many counts it is made of (`tosm:observationCount`), >= 1.
    pub observations: u64,
    /// When the latest of them was observed, as an `xsd:dateTime` lexical form.
    pub last_observed_at: Option<String>,
}

impl PeopleEstimate {
    /// `previous` (if any) moved towards `count` people observed at `observed_at`, by the
    /// weight [`ESTIMATE_MIN_WEIGHT`] documents. The estimate is for `hour` (`None`: all day).
    pub fn observe(
        previous: Option<&PeopleEstimate>,
        hour: Option<u8>,
        count: f64,
        observed_at: &str,
    ) -> PeopleEstimate {
        let (people, observations) = match previous {
            None => (count, 1),
            Some(p) => {
                let n = p.observations.saturating_add(1);
                let weight = (1.0 / n as f64).max(ESTIMATE_MIN_WEIGHT);
                (p.people + weight * (count - p.people), n)
            }
        };
        PeopleEstimate {
            hour,
            people,
            observations,
            last_observed_at: Some(observed_at.to_owned()),
        }
    }

    /// The estimate's IRI for `place`: `<place>/people/estimate`, or
    /// `<place>/people/estimate/hour/<h>` for one hour.
    pub fn iri_for(place: &str, hour: Option<u8>) -> String {
        match hour {
            None => format!("{place}/people/estimate"),
            Some(h) => format!("{place}/people/estimate/hour/{h}"),
        }
    }
}

/// What is known about people in one place: an engineer's expected numbers
/// (`tosm:expectedPeople`, all day and by hour) and robots' running estimates.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct PlacePeople {
    /// The place's IRI.
    pub place: String,
    /// The engineer's expected number over the whole day (`tosm:expectedPeople` on the place).
    pub expected: Option<f64>,
    /// The engineer's expected numbers by hour of day (`tosm:HourlyPeopleCount`): (hour 0–23,
    /// people), sorted by hour.
    pub by_hour: Vec<(u8, f64)>,
    /// Robots' estimates (`tosm:PeopleEstimate`): at most one for the whole day and one per
    /// hour, the whole day's first, then by hour.
    pub estimates: Vec<PeopleEstimate>,
}

impl PlacePeople {
    /// The figures a simulation uses: (all day, by hour sorted by hour).
    ///
    /// Robots' counts win over an engineer's figure: they are what was seen in the building.
    /// For each hour, the hour's estimate, else the engineer's figure for the hour; over the
    /// whole day, the all-day estimate, else the engineer's all-day figure, else the mean of
    /// the hourly figures (engineers' and robots' by hour, as above); 0 when nothing is known.
    pub fn figures(&self) -> (f64, Vec<(u8, f64)>) {
        let mut hours: std::collections::BTreeMap<u8, f64> = self.by_hour.iter().copied().collect();
        let mut all_day_estimate = None;
        for e in &self.estimates {
            match e.hour {
                Some(h) => {
                    hours.insert(h, e.people);
                }
                None => all_day_estimate = Some(e.people),
            }
        }
        let by_hour: Vec<(u8, f64)> = hours.into_iter().collect();
        let all_day = all_day_estimate.or(self.expected).unwrap_or_else(|| {
            if by_hour.is_empty() {
                0.0
            } else {
                by_hour.iter().map(|(_, n)| n).sum::<f64>() / by_hour.len() as f64
            }
        });
        (all_day, by_hour)
    }

    /// The conventional IRI of the engineer's figure for `hour` in `place`.
    pub fn hour_iri(place: &str, hour: u8) -> String {
        format!("{place}/people/hour/{hour}")
    }
}

/// A path people usually walk (`tosm:WalkingRoute`): from door to door along corridors.
#[derive(Clone, Debug, PartialEq)]
pub struct WalkingRoute {
    /// The route's IRI.
    pub iri: String,
    /// Its name (`tosm:name`), when it has one.
    pub name: Option<String>,
    /// The place it lies in (`tosm:isDirectlyInsideOf`): a corridor, or the floor.
    pub inside_of: String,
    /// The points walked, in order, `(x, y)` in the floor's frame; at least two.
    pub points: Vec<(f64, f64)>,
}

/// A point people walk to and linger at (`tosm:Attractor`).
#[derive(Clone, Debug, PartialEq)]
pub struct Attractor {
    /// The attractor's IRI.
    pub iri: String,
    /// Its name (`tosm:name`), when it has one.
    pub name: Option<String>,
    /// The place it is in (`tosm:isDirectlyInsideOf`).
    pub inside_of: String,
    /// Where people stand, in the floor's frame.
    pub pose: Pose3,
    /// How long they linger, seconds (`tosm:dwellTimeS`), >= 0.
    pub dwell_s: f64,
    /// What draws them (`tosm:isInFrontOf`, `tosm:isNextTo` an object), sorted.
    pub relations: Vec<Relation>,
}

/// Everything known about people in a graph, each list sorted by IRI.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct People {
    /// Places with an expected number of people or an estimate.
    pub places: Vec<PlacePeople>,
    /// Walking routes.
    pub routes: Vec<WalkingRoute>,
    /// Attractors.
    pub attractors: Vec<Attractor>,
}
