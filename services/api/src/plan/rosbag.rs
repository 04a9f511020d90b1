//! A rehearsal as a ROS 2 recording: an MCAP file (the `ros2` profile: `ros2msg` schemas, CDR
//! messages) that Foxglove and `ros2 bag play` open, answered by `POST /v1/plan` with
//! `Accept: application/x-mcap`.
//!
//! Topics, all stamped on one timeline that starts at the answer's wall-clock time:
//! - `/map` (`nav_msgs/msg/OccupancyGrid`) and `/plan` (`nav_msgs/msg/Path`, the validated
//!   waypoints from the start, as the JSON answer's `path`) once at the start;
//! - `/tf_static` (`tf2_msgs/msg/TFMessage`): `base_footprint` → `base_link` → the laser's frame,
//!   as the robot's URDF states them;
//! - per attempt, in the order the simulation drove them, each after the previous one's end:
//!   `/rehearsal/attempt` (`std_msgs/msg/String`, the attempt's JSON report without its trace)
//!   and `/rehearsal/attempt_path` (the roadmap path it planned) at its start; per recorded
//!   step `/rehearsal/pose` (`geometry_msgs/msg/PoseStamped`), `/tf` (map → `base_footprint`,
//!   the simulated robot's true pose) and `/rehearsal/scan` (`sensor_msgs/msg/LaserScan`).
//!
//! The scan is the laser's full sample grid (`angle_min` … `angle_max` in steps of one
//! sample), with the beams the controller read at their own samples and NaN elsewhere
//! (REP-117: no return): the policy reads a subset of samples that are not evenly spaced, and
//! a `LaserScan` can only state evenly spaced ones.

use std::collections::BTreeMap;
use std::io::Cursor;

use super::types::{PlanReport, Pose, RosPath, RosQuaternion};

/// Why no recording was written: the MCAP writer failed, or an attempt's report did not
/// serialise (neither happens for a well-formed report).
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The MCAP writer failed.
    #[error("writing the MCAP recording: {0}")]
    Mcap(#[from] mcap::McapError),
    /// An attempt's report did not serialise.
    #[error("an attempt's report: {0}")]
    Json(#[from] serde_json::Error),
}

/// The media type of the answer.
pub const MEDIA_TYPE: &str = "application/x-mcap";

/// Simulated seconds left between two attempts on the timeline.
const GAP_S: f64 = 1.0;

/// What the recording needs besides the report.
pub struct Recording<'a> {
    /// The validated path, as the JSON answer's `path`.
    pub path: &'a RosPath,
    /// The report, with `options.trace` (every attempt's trace and the laser).
    pub report: &'a PlanReport,
    /// The floor's grid, when it has a metric map.
    pub grid: Option<&'a sim::OccupancyGrid>,
    /// The map frame (the floor map's `tosm:frameId`).
    pub map_frame: &'a str,
    /// The robot's frames as its URDF names them.
    pub frames: &'a sim::export::RobotFrames,
    /// The robot's laser.
    pub laser: &'a sim::LaserSpec,
    /// Wall-clock nanoseconds since the Unix epoch of the timeline's start.
    pub start_ns: u64,
    /// `mentalsim` metadata record: robot, floor, policy, controller.
    pub metadata: BTreeMap<String, String>,
}

/// Writes the recording. Fails only when the MCAP writer does (never for a well-formed report).
pub fn write(rec: &Recording<'_>) -> Result<Vec<u8>, RecordingError> {
    let mut out = Writer::new()?;
    let t0 = rec.start_ns;
    let map = out.channel("/map", OCCUPANCY_GRID)?;
    let plan = out.channel("/plan", PATH)?;
    let tf_static = out.channel("/tf_static", TF_MESSAGE)?;
    let tf = out.channel("/tf", TF_MESSAGE)?;
    let pose = out.channel("/rehearsal/pose", POSE_STAMPED)?;
    let scan = out.channel("/rehearsal/scan", LASER_SCAN)?;
    let attempt_info = out.channel("/rehearsal/attempt", STRING)?;
    let attempt_path = out.channel("/rehearsal/attempt_path", PATH)?;

    if let Some(grid) = rec.grid {
        out.message(map, t0, &occupancy_grid(grid, rec.map_frame, t0))?;
    }
    out.message(plan, t0, &path_message(rec.path, t0))?;
    let f = rec.frames;
    out.message(
        tf_static,
        t0,
        &tf_message(&[
            Transform::planar(
                t0,
                &f.base_footprint,
                &f.base_link,
                [0.0, 0.0, f.base_link_z],
                0.0,
            ),
            Transform::planar(
                t0,
                &f.base_link,
                &f.laser,
                [
                    rec.laser.mount.x,
                    rec.laser.mount.y,
                    rec.laser.mount.z - f.base_link_z,
                ],
                rec.laser.mount.yaw,
            ),
        ]),
    )?;

    let scan_grid = ScanGrid::of(rec.laser, rec.report);
    let mut offset_s = 0.0;
    for attempt in &rec.report.attempts {
        let Some(trace) = &attempt.trace else {
            continue;
        };
        let at = |t: f64| t0 + seconds_ns(offset_s + t);
        let mut info = serde_json::to_value(attempt)?;
        if let Some(o) = info.as_object_mut() {
            o.remove("trace");
        }
        out.message(attempt_info, at(0.0), &string_message(&info.to_string()))?;
        if let Some((first, rest)) = trace.path.split_first() {
            let from = Pose {
                x: first.x,
                y: first.y,
                yaw: 0.0,
            };
            let planned = RosPath::through(&from, rest, rec.map_frame);
            out.message(attempt_path, at(0.0), &path_message(&planned, at(0.0)))?;
        }
        for (i, (p, t)) in trace.poses.iter().zip(&trace.times_s).enumerate() {
            let stamp = at(*t);
            out.message(pose, stamp, &pose_stamped(p, rec.map_frame, stamp))?;
            out.message(
                tf,
                stamp,
                &tf_message(&[Transform::planar(
                    stamp,
                    rec.map_frame,
                    &f.base_footprint,
                    [p.x, p.y, 0.0],
                    p.yaw,
                )]),
            )?;
            if let (Some(grid), Some(ranges)) = (&scan_grid, trace.ranges.get(i)) {
                out.message(
                    scan,
                    stamp,
                    &grid.message(ranges, &f.laser, stamp, rec.laser),
                )?;
            }
        }
        offset_s += trace.times_s.last().copied().unwrap_or(0.0) + GAP_S;
    }
    out.finish(&rec.metadata)
}

fn seconds_ns(s: f64) -> u64 {
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "simulated times are non-negative and far below 584 years"
    )]
    let ns = (s.max(0.0) * 1e9).round() as u64;
    ns
}

/// The MCAP writer with the `ros2` profile's conventions.
struct Writer {
    inner: mcap::Writer<Cursor<Vec<u8>>>,
    sequence: u32,
}

impl Writer {
    fn new() -> Result<Self, RecordingError> {
        let inner = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("mentalsim ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .create(Cursor::new(Vec::new()))?;
        Ok(Self { inner, sequence: 0 })
    }

    fn channel(&mut self, topic: &str, schema: &Schema) -> Result<u16, RecordingError> {
        let text = schema.text();
        let id = self
            .inner
            .add_schema(schema.name, "ros2msg", text.as_bytes())?;
        // rosbag2 reads a topic's QoS from here; Foxglove ignores it.
        let qos = if topic == "/map" || topic == "/tf_static" {
            "- history: 1\n  depth: 1\n  reliability: 1\n  durability: 1\n  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false\n"
        } else {
            ""
        };
        let metadata = BTreeMap::from([("offered_qos_profiles".to_owned(), qos.to_owned())]);
        self.inner
            .add_channel(id, topic, "cdr", &metadata)
            .map_err(RecordingError::from)
    }

    fn message(&mut self, channel: u16, stamp: u64, data: &[u8]) -> Result<(), RecordingError> {
        self.sequence += 1;
        self.inner
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: channel,
                    sequence: self.sequence,
                    log_time: stamp,
                    publish_time: stamp,
                },
                data,
            )
            .map_err(RecordingError::from)
    }

    fn finish(mut self, metadata: &BTreeMap<String, String>) -> Result<Vec<u8>, RecordingError> {
        self.inner.write_metadata(&mcap::records::Metadata {
            name: "mentalsim".to_owned(),
            metadata: metadata.clone(),
        })?;
        self.inner.finish()?;
        Ok(self.inner.into_inner().into_inner())
    }
}

// ROS 2 message definitions (`ros2msg`, as rosbag2 records them: the type's fields, then each
// type it uses after a separator line and `MSG: package/Type`).

/// A message type and the types its fields use.
struct Schema {
    name: &'static str,
    fields: &'static str,
    uses: &'static [&'static Schema],
}

impl Schema {
    fn text(&self) -> String {
        let mut seen: Vec<&'static str> = Vec::new();
        let mut out = format!("{}\n", self.fields);
        let mut stack: Vec<&Schema> = self.uses.iter().rev().copied().collect();
        while let Some(s) = stack.pop() {
            if seen.contains(&s.name) {
                continue;
            }
            seen.push(s.name);
            let short = s.name.replace("/msg/", "/");
            out.push_str(&"=".repeat(80));
            out.push_str(&format!("\nMSG: {short}\n{}\n", s.fields));
            stack.extend(s.uses.iter().rev().copied());
        }
        out
    }
}

const TIME: &Schema = &Schema {
    name: "builtin_interfaces/msg/Time",
    fields: "int32 sec\nuint32 nanosec",
    uses: &[],
};
const HEADER: &Schema = &Schema {
    name: "std_msgs/msg/Header",
    fields: "builtin_interfaces/Time stamp\nstring frame_id",
    uses: &[TIME],
};
const STRING: &Schema = &Schema {
    name: "std_msgs/msg/String",
    fields: "string data",
    uses: &[],
};
const POINT: &Schema = &Schema {
    name: "geometry_msgs/msg/Point",
    fields: "float64 x\nfloat64 y\nfloat64 z",
    uses: &[],
};
const VECTOR3: &Schema = &Schema {
    name: "geometry_msgs/msg/Vector3",
    fields: "float64 x\nfloat64 y\nfloat64 z",
    uses: &[],
};
const QUATERNION: &Schema = &Schema {
    name: "geometry_msgs/msg/Quaternion",
    fields: "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    uses: &[],
};
const POSE: &Schema = &Schema {
    name: "geometry_msgs/msg/Pose",
    fields: "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation",
    uses: &[POINT, QUATERNION],
};
const POSE_STAMPED: &Schema = &Schema {
    name: "geometry_msgs/msg/PoseStamped",
    fields: "std_msgs/Header header\ngeometry_msgs/Pose pose",
    uses: &[HEADER, POSE],
};
const TRANSFORM: &Schema = &Schema {
    name: "geometry_msgs/msg/Transform",
    fields: "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation",
    uses: &[VECTOR3, QUATERNION],
};
const TRANSFORM_STAMPED: &Schema = &Schema {
    name: "geometry_msgs/msg/TransformStamped",
    fields: "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform",
    uses: &[HEADER, TRANSFORM],
};
const TF_MESSAGE: &Schema = &Schema {
    name: "tf2_msgs/msg/TFMessage",
    fields: "geometry_msgs/TransformStamped[] transforms",
    uses: &[TRANSFORM_STAMPED],
};
const PATH: &Schema = &Schema {
    name: "nav_msgs/msg/Path",
    fields: "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses",
    uses: &[HEADER, POSE_STAMPED],
};
const MAP_META_DATA: &Schema = &Schema {
    name: "nav_msgs/msg/MapMetaData",
    fields: "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\ngeometry_msgs/Pose origin",
    uses: &[TIME, POSE],
};
const OCCUPANCY_GRID: &Schema = &Schema {
    name: "nav_msgs/msg/OccupancyGrid",
    fields: "std_msgs/Header header\nnav_msgs/MapMetaData info\nint8[] data",
    uses: &[HEADER, MAP_META_DATA],
};
const LASER_SCAN: &Schema = &Schema {
    name: "sensor_msgs/msg/LaserScan",
    fields: "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\nfloat32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities",
    uses: &[HEADER],
};

/// A CDR (XCDR1, little-endian) message body, as ROS 2's middleware serialises it: primitives
/// aligned to their size from the end of the 4-byte encapsulation header, strings and
/// sequences prefixed by a `uint32` length (strings counting their NUL).
struct Cdr(Vec<u8>);

impl Cdr {
    fn new() -> Self {
        Self(vec![0x00, 0x01, 0x00, 0x00])
    }
    fn align(&mut self, n: usize) {
        while !(self.0.len() - 4).is_multiple_of(n) {
            self.0.push(0);
        }
    }
    fn u32(&mut self, v: u32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn len(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }
    fn string(&mut self, s: &str) {
        self.len(s.len() + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
    }
    fn time(&mut self, ns: u64) {
        let sec = i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX);
        let nanosec = u32::try_from(ns % 1_000_000_000).unwrap_or(0);
        self.i32(sec);
        self.u32(nanosec);
    }
    fn header(&mut self, ns: u64, frame: &str) {
        self.time(ns);
        self.string(frame);
    }
    /// `geometry_msgs/Pose` of a planar pose.
    fn pose(&mut self, x: f64, y: f64, z: f64, yaw: f64) {
        for v in [x, y, z] {
            self.f64(v);
        }
        for v in yaw_quaternion(yaw) {
            self.f64(v);
        }
    }
}

/// `[x, y, z, w]` of a rotation by `yaw` about z.
fn yaw_quaternion(yaw: f64) -> [f64; 4] {
    let q = RosQuaternion::about_z(yaw);
    [q.x, q.y, q.z, q.w]
}

fn string_message(text: &str) -> Vec<u8> {
    let mut m = Cdr::new();
    m.string(text);
    m.0
}

fn pose_stamped(p: &Pose, frame: &str, stamp: u64) -> Vec<u8> {
    let mut m = Cdr::new();
    m.header(stamp, frame);
    m.pose(p.x, p.y, 0.0, p.yaw);
    m.0
}

/// The JSON answer's `path`, stamped.
fn path_message(path: &RosPath, stamp: u64) -> Vec<u8> {
    let mut m = Cdr::new();
    m.header(stamp, &path.header.frame_id);
    m.len(path.poses.len());
    for p in &path.poses {
        m.header(stamp, &p.header.frame_id);
        let (pos, q) = (&p.pose.position, &p.pose.orientation);
        for v in [pos.x, pos.y, pos.z, q.x, q.y, q.z, q.w] {
            m.f64(v);
        }
    }
    m.0
}

/// A planar transform `parent` → `child`.
struct Transform<'a> {
    stamp: u64,
    parent: &'a str,
    child: &'a str,
    translation: [f64; 3],
    yaw: f64,
}

impl<'a> Transform<'a> {
    fn planar(
        stamp: u64,
        parent: &'a str,
        child: &'a str,
        translation: [f64; 3],
        yaw: f64,
    ) -> Self {
        Self {
            stamp,
            parent,
            child,
            translation,
            yaw,
        }
    }
}

fn tf_message(transforms: &[Transform<'_>]) -> Vec<u8> {
    let mut m = Cdr::new();
    m.len(transforms.len());
    for t in transforms {
        m.header(t.stamp, t.parent);
        m.string(t.child);
        for v in t.translation {
            m.f64(v);
        }
        for v in yaw_quaternion(t.yaw) {
            m.f64(v);
        }
    }
    m.0
}

/// `nav_msgs/OccupancyGrid`: row 0 at the bottom (as ours), free 0, occupied 100, unknown -1.
fn occupancy_grid(grid: &sim::OccupancyGrid, frame: &str, stamp: u64) -> Vec<u8> {
    let mut m = Cdr::new();
    m.header(stamp, frame);
    m.time(stamp);
    #[allow(
        clippy::cast_possible_truncation,
        reason = "map resolutions are centimetres to metres: f32 keeps them"
    )]
    m.f32(grid.resolution as f32);
    m.len(grid.width);
    m.len(grid.height);
    let o = grid.origin;
    m.pose(o.x, o.y, 0.0, o.yaw);
    m.len(grid.cells.len());
    m.0.extend(grid.cells.iter().map(|c| match c {
        sim::Occupancy::Free => 0u8,
        sim::Occupancy::Occupied => 100u8,
        #[allow(clippy::cast_sign_loss, reason = "-1 as the int8 ROS reads")]
        sim::Occupancy::Unknown => (-1i8) as u8,
    }));
    m.0
}

/// The laser's sample grid and which sample each beam the controller read is.
struct ScanGrid {
    samples: usize,
    beam_samples: Vec<usize>,
    angle_min: f64,
    increment: f64,
    scan_time: f64,
}

impl ScanGrid {
    fn of(laser: &sim::LaserSpec, report: &PlanReport) -> Option<Self> {
        let beams = report.laser.as_ref()?.angles_rad.len();
        let beam_samples = laser.beam_samples(beams)?;
        let angle_min = laser.sample_angle(0);
        let increment = if laser.samples > 1 {
            laser.sample_angle(1) - angle_min
        } else {
            0.0
        };
        Some(Self {
            samples: laser.samples,
            beam_samples,
            angle_min,
            increment,
            scan_time: report.laser.as_ref().map_or(0.0, |l| l.control_period_s),
        })
    }

    #[allow(
        clippy::cast_possible_truncation,
        reason = "LaserScan's fields are float32"
    )]
    fn message(&self, ranges: &[f32], frame: &str, stamp: u64, laser: &sim::LaserSpec) -> Vec<u8> {
        let mut m = Cdr::new();
        m.header(stamp, frame);
        let angle_max = self.angle_min + self.increment * (self.samples.saturating_sub(1)) as f64;
        for v in [
            self.angle_min,
            angle_max,
            self.increment,
            0.0,
            self.scan_time,
            laser.range_min,
            laser.range_max,
        ] {
            m.f32(v as f32);
        }
        let mut full = vec![f32::NAN; self.samples];
        for (&s, &r) in self.beam_samples.iter().zip(ranges) {
            if let Some(slot) = full.get_mut(s) {
                *slot = r;
            }
        }
        m.len(full.len());
        for r in full {
            m.0.extend_from_slice(&r.to_le_bytes());
        }
        m.len(0);
        m.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_aligns_from_the_end_of_the_encapsulation_header() {
        let mut m = Cdr::new();
        m.string("ab"); // 4 + 3 bytes: the f64 after it starts at payload offset 8
        m.f64(1.5);
        assert_eq!(&m.0[..4], &[0, 1, 0, 0]);
        assert_eq!(&m.0[4..8], &3u32.to_le_bytes());
        assert_eq!(&m.0[8..11], b"ab\0");
        assert_eq!(&m.0[11..12], &[0]);
        assert_eq!(&m.0[12..20], &1.5f64.to_le_bytes());
    }

    #[test]
    fn schemas_carry_every_type_they_use_once() {
        let text = PATH.text();
        assert!(text.starts_with("std_msgs/Header header\n"));
        for used in [
            "MSG: std_msgs/Header",
            "MSG: builtin_interfaces/Time",
            "MSG: geometry_msgs/PoseStamped",
            "MSG: geometry_msgs/Pose\n",
            "MSG: geometry_msgs/Point",
            "MSG: geometry_msgs/Quaternion",
        ] {
            assert_eq!(text.matches(used).count(), 1, "{used} in\n{text}");
        }
    }
}
