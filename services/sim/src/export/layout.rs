//! The robot's links and joints, named once so that the URDF, the SDF model and the bridge
//! configuration agree, and the gz-sim sensors and systems both documents carry.

use std::collections::HashSet;
use std::fmt::Write as _;

use crate::spec::{CameraSpec, Pose3, RobotPartSpec, RobotSpec, WheelSpec};

use super::unique_name;

/// A wheel's cylinder (standing along z) turned to lie along its axle, y.
pub(super) const WHEEL_RPY: &str = "1.5707963267948966 0 0";

/// The mass of a wheel the model gives none for: Gazebo needs one.
pub(super) const WHEEL_MASS_KG: f64 = 0.5;

/// A link that only carries a frame (`base_footprint`, `base_link`, a sensor without a shape, an
/// optical frame) still needs an inertial in SDF, where a missing one means 1 kg and 1 kg·m²:
/// a gram, negligible beside the robot.
pub(super) const FRAME_INERTIAL: &str = "<inertial><mass>0.001</mass><inertia><ixx>1e-6</ixx><ixy>0</ixy><ixz>0</ixz><iyy>1e-6</iyy><iyz>0</iyz><izz>1e-6</izz></inertia></inertial>";

/// How often the laser scans, Hz: the spec gives no rate; the bundled robot's is 10 Hz.
pub(super) const LASER_RATE_HZ: f64 = 10.0;

/// How often the drive publishes odometry, Hz (gz-sim's default).
pub(super) const ODOM_RATE_HZ: f64 = 50.0;

/// What a link of the robot is.
pub(super) enum Body<'a> {
    /// A structural or sensor part with a shape, fixed to `base_link`.
    Part(&'a RobotPartSpec),
    /// A wheel, turning about its axle (its y axis).
    Wheel(&'a WheelSpec),
    /// A sensor with no shape of its own: a bare frame at its mounting pose.
    Frame(Pose3),
    /// A camera's optical frame (REP-103: z forward, x right, y down) on the camera's link.
    Optical,
}

/// One link and the joint that attaches it to its parent.
pub(super) struct RobotLink<'a> {
    pub(super) name: String,
    pub(super) joint: String,
    pub(super) parent: String,
    pub(super) body: Body<'a>,
}

/// A camera's links: its body (or bare frame) and its optical frame.
pub(super) struct CameraLinks<'a> {
    pub(super) spec: &'a CameraSpec,
    pub(super) link: String,
    pub(super) optical: String,
}

/// The robot's links and joints, named once so that the URDF, the SDF model and the bridge
/// configuration agree: REP-105's `base_footprint` → `base_link` → parts, wheels and sensors,
/// the sensors named after their individuals in the knowledge graph (the local name of the
/// IRI), and named before any other part so that they keep that name.
pub(super) struct RobotLayout<'a> {
    /// The robot's (and the Gazebo model's) name.
    pub(super) name: String,
    /// Height of `base_link` (the drive axle) above `base_footprint`.
    pub(super) axle: f64,
    /// The fixed joint from `base_footprint` to `base_link`.
    pub(super) base_joint: String,
    pub(super) links: Vec<RobotLink<'a>>,
    /// The laser's link, named after the robot's laser.
    pub(super) laser: String,
    pub(super) cameras: Vec<CameraLinks<'a>>,
    /// The left and right drive joints, when the robot has exactly two active wheels.
    pub(super) drive: Option<[String; 2]>,
    /// Every wheel's joint: the joints that move.
    pub(super) wheel_joints: Vec<String>,
}

impl<'a> RobotLayout<'a> {
    pub(super) fn new(robot: &'a RobotSpec) -> Self {
        let mut names = HashSet::new();
        names.insert("base_footprint".to_owned());
        names.insert("base_link".to_owned());
        let base_joint = unique_name("base_footprint_joint", &mut names);
        let axle = robot
            .wheels
            .iter()
            .filter(|w| w.active)
            .map(|w| w.pose.z)
            .fold(0.0, f64::max);
        let laser = unique_name(&robot.laser.id, &mut names);
        let camera_names: Vec<String> = robot
            .cameras
            .iter()
            .map(|c| unique_name(&c.id, &mut names))
            .collect();
        let mut laser_placed = false;
        let mut camera_placed = vec![false; robot.cameras.len()];
        let mut links = Vec::new();
        let attach = |links: &mut Vec<RobotLink<'a>>,
                      names: &mut HashSet<String>,
                      name: String,
                      parent: &str,
                      body: Body<'a>| {
            let joint = unique_name(&format!("{name}_joint"), names);
            links.push(RobotLink {
                name,
                joint: joint.clone(),
                parent: parent.to_owned(),
                body,
            });
            joint
        };
        for p in &robot.parts {
            let camera = robot
                .cameras
                .iter()
                .enumerate()
                .position(|(k, c)| c.id == p.id && !camera_placed[k]);
            let name = if p.id == robot.laser.id && !laser_placed {
                laser_placed = true;
                laser.clone()
            } else if let Some(k) = camera {
                camera_placed[k] = true;
                camera_names[k].clone()
            } else {
                unique_name(&p.id, &mut names)
            };
            attach(&mut links, &mut names, name, "base_link", Body::Part(p));
        }
        let mut active = Vec::new();
        let mut wheel_joints = Vec::new();
        for w in &robot.wheels {
            let name = unique_name(&w.id, &mut names);
            let joint = attach(&mut links, &mut names, name, "base_link", Body::Wheel(w));
            if w.active {
                active.push((w.pose.y, joint.clone()));
            }
            wheel_joints.push(joint);
        }
        if !laser_placed {
            let mount = Body::Frame(robot.laser.mount);
            attach(&mut links, &mut names, laser.clone(), "base_link", mount);
        }
        for (k, cam) in robot.cameras.iter().enumerate() {
            if !camera_placed[k] {
                let mount = Body::Frame(cam.mount);
                attach(
                    &mut links,
                    &mut names,
                    camera_names[k].clone(),
                    "base_link",
                    mount,
                );
            }
        }
        let mut cameras = Vec::new();
        for (spec, link) in robot.cameras.iter().zip(camera_names) {
            let optical = unique_name(&format!("{link}_optical_frame"), &mut names);
            attach(
                &mut links,
                &mut names,
                optical.clone(),
                &link,
                Body::Optical,
            );
            cameras.push(CameraLinks {
                spec,
                link,
                optical,
            });
        }
        let drive = if let [a, b] = active.as_mut_slice() {
            if a.0 < b.0 {
                std::mem::swap(a, b); // left (larger y) first
            }
            Some([a.1.clone(), b.1.clone()])
        } else {
            None
        };
        RobotLayout {
            name: unique_name(&robot.id, &mut HashSet::new()),
            axle,
            base_joint,
            links,
            laser,
            cameras,
            drive,
            wheel_joints,
        }
    }

    /// Where a link sits on its parent: a part, wheel or sensor frame at its mounting pose
    /// (given from `base_footprint`, so lowered by the axle's height onto `base_link`), an
    /// optical frame turned from its camera's x-forward frame to z forward.
    pub(super) fn origin(&self, link: &RobotLink<'_>) -> Pose3 {
        let on_base = |p: &Pose3| Pose3 {
            z: p.z - self.axle,
            ..*p
        };
        match link.body {
            Body::Part(p) => on_base(&p.pose),
            Body::Wheel(w) => on_base(&w.pose),
            Body::Frame(mount) => on_base(&mount),
            Body::Optical => Pose3 {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                roll: -std::f64::consts::FRAC_PI_2,
                pitch: 0.0,
                yaw: -std::f64::consts::FRAC_PI_2,
            },
        }
    }
}

/// The gz-transport topics the robot's systems and sensors use, all under `/model/<robot>/`
/// so that robots sharing a world do not mix; [`ros_gz_bridge_yaml`](super::ros_gz_bridge_yaml) bridges the same ones.
pub(super) struct GzTopics {
    /// DiffDrive subscribes to `gz.msgs.Twist` here.
    pub(super) cmd_vel: String,
    /// DiffDrive publishes `gz.msgs.Odometry` here.
    pub(super) odometry: String,
    /// DiffDrive publishes the `odom` → `base_footprint` transform (`gz.msgs.Pose_V`) here.
    pub(super) tf: String,
    /// JointStatePublisher publishes the wheels' `gz.msgs.Model` here.
    pub(super) joint_states: String,
    /// The gpu_lidar publishes `gz.msgs.LaserScan` here.
    pub(super) scan: String,
}

impl GzTopics {
    pub(super) fn new(layout: &RobotLayout<'_>) -> Self {
        let m = format!("/model/{}", layout.name);
        GzTopics {
            cmd_vel: format!("{m}/cmd_vel"),
            odometry: format!("{m}/odometry"),
            tf: format!("{m}/tf"),
            joint_states: format!("{m}/joint_states"),
            scan: format!("{m}/scan"),
        }
    }

    /// The topic a camera's images and camera info are published under: `<it>/image` and
    /// `<it>/camera_info`, for an RGB-D camera also `<it>/depth_image` and `<it>/points`.
    pub(super) fn camera(layout: &RobotLayout<'_>, camera: &CameraLinks<'_>) -> String {
        format!("/model/{}/{}", layout.name, camera.link)
    }
}

/// The laser as a gz-sim `gpu_lidar` sensor: the spec's samples over its field of view, at the
/// angles [`crate::LaserSpec::sample_angle`] gives them (as ROS `LaserScan` numbers them),
/// published with the laser's link as frame.
pub(super) fn gz_laser_sensor(
    robot: &RobotSpec,
    layout: &RobotLayout<'_>,
    topics: &GzTopics,
) -> String {
    let l = &robot.laser;
    let last = l.samples.saturating_sub(1);
    format!(
        r#"<sensor name="{link}_sensor" type="gpu_lidar">
  <topic>{topic}</topic>
  <gz_frame_id>{link}</gz_frame_id>
  <update_rate>{LASER_RATE_HZ}</update_rate>
  <always_on>true</always_on>
  <visualize>false</visualize>
  <lidar>
    <scan>
      <horizontal><samples>{}</samples><resolution>1</resolution><min_angle>{}</min_angle><max_angle>{}</max_angle></horizontal>
    </scan>
    <range><min>{}</min><max>{}</max><resolution>0.01</resolution></range>
  </lidar>
</sensor>"#,
        l.samples,
        l.sample_angle(0),
        l.sample_angle(last),
        l.range_min,
        l.range_max,
        link = layout.laser,
        topic = topics.scan,
    )
}

/// A camera as a gz-sim `camera` sensor, or an `rgbd_camera` when it measures depth; its
/// images are stamped with its optical frame.
pub(super) fn gz_camera_sensor(layout: &RobotLayout<'_>, camera: &CameraLinks<'_>) -> String {
    let base = GzTopics::camera(layout, camera);
    let c = camera.spec;
    // A camera publishes on its topic and its info beside it; an RGB-D camera under its topic.
    let (kind, topic, (near, far)) = match c.depth_range {
        Some(range) => ("rgbd_camera", base, range),
        None => ("camera", format!("{base}/image"), (0.05, 100.0)),
    };
    format!(
        r#"<sensor name="{link}_sensor" type="{kind}">
  <topic>{topic}</topic>
  <gz_frame_id>{optical}</gz_frame_id>
  <update_rate>{}</update_rate>
  <always_on>true</always_on>
  <camera>
    <horizontal_fov>{}</horizontal_fov>
    <image><width>{}</width><height>{}</height><format>R8G8B8</format></image>
    <clip><near>{near}</near><far>{far}</far></clip>
  </camera>
</sensor>"#,
        c.fps,
        c.hfov,
        c.width,
        c.height,
        link = camera.link,
        optical = camera.optical,
    )
}

/// The model's gz-sim systems (each checked against gz-sim 8's `src/systems/*/*.hh`): the
/// differential drive on the two active wheels' joints, commanded in velocity, publishing
/// odometry and the `odom` → `base_footprint` transform, with the spec's speed and acceleration
/// limits in both directions; the joint state publisher for the wheels.
pub(super) fn gz_model_plugins(
    robot: &RobotSpec,
    layout: &RobotLayout<'_>,
    topics: &GzTopics,
) -> String {
    let mut s = String::new();
    if let Some([left, right]) = &layout.drive {
        let d = &robot.drive;
        let _ = writeln!(
            s,
            r#"<plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">
  <left_joint>{left}</left_joint>
  <right_joint>{right}</right_joint>
  <wheel_separation>{}</wheel_separation>
  <wheel_radius>{}</wheel_radius>
  <odom_publish_frequency>{ODOM_RATE_HZ}</odom_publish_frequency>
  <topic>{}</topic>
  <odom_topic>{}</odom_topic>
  <tf_topic>{}</tf_topic>
  <frame_id>odom</frame_id>
  <child_frame_id>base_footprint</child_frame_id>"#,
            d.wheel_separation, d.wheel_radius, topics.cmd_vel, topics.odometry, topics.tf
        );
        // gz-sim's DiffDrive takes the braking limit as the most negative acceleration.
        let usable = |v: Option<f64>| v.filter(|v| v.is_finite() && *v > 0.0);
        for (kind, max, min) in [
            ("linear_velocity", d.max_linear_speed, d.max_linear_speed),
            ("angular_velocity", d.max_angular_speed, d.max_angular_speed),
            (
                "linear_acceleration",
                d.max_linear_acceleration,
                d.max_linear_deceleration.or(d.max_linear_acceleration),
            ),
            (
                "angular_acceleration",
                d.max_angular_acceleration,
                d.max_angular_deceleration.or(d.max_angular_acceleration),
            ),
        ] {
            if let Some(v) = usable(max) {
                let _ = writeln!(s, "  <max_{kind}>{v}</max_{kind}>");
            }
            if let Some(v) = usable(min) {
                let _ = writeln!(s, "  <min_{kind}>{}</min_{kind}>", -v);
            }
        }
        let _ = writeln!(s, "</plugin>");
    }
    let _ = writeln!(
        s,
        r#"<plugin filename="gz-sim-joint-state-publisher-system" name="gz::sim::systems::JointStatePublisher">
  <topic>{}</topic>"#,
        topics.joint_states
    );
    for joint in &layout.wheel_joints {
        let _ = writeln!(s, "  <joint_name>{joint}</joint_name>");
    }
    s.push_str("</plugin>");
    s
}
