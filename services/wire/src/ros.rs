//! A plan's path as ROS 2 messages are written in JSON: `nav_msgs/Path` and its parts.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::types::{Point, Pose};

/// A path as ROS 2's `nav_msgs/Path` is written in JSON (rosbridge, `ros2 topic pub`): the
/// start and every waypoint in the floor's map frame (REP-103: metres, x forward, z up), each
/// facing along the path (towards the next pose; the last as it is reached).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RosPath {
    /// `std_msgs/Header`: the frame the poses are in.
    pub header: RosHeader,
    /// `geometry_msgs/PoseStamped[]`.
    pub poses: Vec<RosPoseStamped>,
}

/// `std_msgs/Header`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RosHeader {
    /// The floor map's frame (its `tosm:frameId`; `map` unless the graph states another).
    pub frame_id: String,
    /// `builtin_interfaces/Time`: on a path's poses, when the plan has the robot there (a pose
    /// it waits at: when it may go on), from the floor's traffic schedule; absent on the
    /// path's own header, and where the plan has no schedule.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stamp: Option<RosTime>,
}

/// `builtin_interfaces/Time`: seconds and nanoseconds since the Unix epoch.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct RosTime {
    /// Seconds.
    pub sec: i64,
    /// Nanoseconds, 0-999 999 999.
    pub nanosec: u32,
}

impl RosTime {
    /// The time `unix_ms` milliseconds after the epoch.
    pub fn from_unix_ms(unix_ms: i64) -> Self {
        Self {
            sec: unix_ms.div_euclid(1000),
            nanosec: u32::try_from(unix_ms.rem_euclid(1000) * 1_000_000).unwrap_or(0),
        }
    }
}

/// `geometry_msgs/PoseStamped`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RosPoseStamped {
    /// The frame.
    pub header: RosHeader,
    /// `geometry_msgs/Pose`.
    pub pose: RosPose,
}

/// `geometry_msgs/Pose`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RosPose {
    /// `geometry_msgs/Point`, metres (z = 0: on the floor).
    pub position: RosPoint,
    /// `geometry_msgs/Quaternion`: a rotation about z by the heading.
    pub orientation: RosQuaternion,
}

/// `geometry_msgs/Point`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RosPoint {
    /// Metres.
    pub x: f64,
    /// Metres.
    pub y: f64,
    /// Metres.
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RosQuaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl RosQuaternion {
    /// The rotation by `yaw` radians about z (REP-103: counter-clockwise from x).
    pub fn about_z(yaw: f64) -> Self {
        let (s, c) = (yaw / 2.0).sin_cos();
        Self {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }
    }
}

impl RosPath {
    /// The path from `start` through `waypoints` in `frame_id`, each pose facing the next
    /// (the last facing as it was reached).
    pub fn through(start: &Pose, waypoints: &[Point], frame_id: &str) -> Self {
        let points: Vec<(f64, f64)> = std::iter::once((start.x, start.y))
            .chain(waypoints.iter().map(|p| (p.x, p.y)))
            .collect();
        let mut heading = start.yaw;
        let header = RosHeader {
            frame_id: frame_id.to_owned(),
            stamp: None,
        };
        let poses = points
            .iter()
            .enumerate()
            .map(|(i, &(x, y))| {
                if let Some(&(nx, ny)) = points.get(i + 1)
                    && (nx - x).hypot(ny - y) > 1e-9
                {
                    heading = (ny - y).atan2(nx - x);
                }
                RosPoseStamped {
                    header: header.clone(),
                    pose: RosPose {
                        position: RosPoint { x, y, z: 0.0 },
                        orientation: RosQuaternion::about_z(heading),
                    },
                }
            })
            .collect();
        Self { header, poses }
    }

    /// Stamps each pose with `times[i]` (ms since the Unix epoch; the start is pose 0).
    pub fn stamped(mut self, times: &[i64]) -> Self {
        for (pose, &t) in self.poses.iter_mut().zip(times) {
            pose.header.stamp = Some(RosTime::from_unix_ms(t));
        }
        self
    }
}

#[cfg(test)]
mod ros_path_tests {
    use super::*;

    #[test]
    fn poses_face_along_the_path() {
        let start = Pose {
            x: 0.0,
            y: 0.0,
            yaw: 1.0,
        };
        let path = RosPath::through(
            &start,
            &[Point { x: 1.0, y: 0.0 }, Point { x: 1.0, y: 2.0 }],
            "map",
        );
        assert_eq!(path.header.frame_id, "map");
        assert_eq!(path.poses.len(), 3);
        let yaw = |q: &RosQuaternion| 2.0 * q.z.atan2(q.w);
        let yaws: Vec<f64> = path
            .poses
            .iter()
            .map(|p| yaw(&p.pose.orientation))
            .collect();
        assert!(yaws[0].abs() < 1e-12, "{yaws:?}");
        assert!(
            (yaws[1] - std::f64::consts::FRAC_PI_2).abs() < 1e-12,
            "{yaws:?}"
        );
        assert!(
            (yaws[2] - std::f64::consts::FRAC_PI_2).abs() < 1e-12,
            "{yaws:?}"
        );
        for p in &path.poses {
            let q = &p.pose.orientation;
            assert!((q.z * q.z + q.w * q.w - 1.0).abs() < 1e-12);
        }
        assert_eq!(
            path.poses[2].pose.position,
            RosPoint {
                x: 1.0,
                y: 2.0,
                z: 0.0
            }
        );
    }
}
