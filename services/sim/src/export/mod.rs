//! Exports that Gazebo and ROS load (paper §3.4), for one simulator, gz-sim (Harmonic, SDF 1.9):
//! the world (static walls from the metric map merged into boxes, placeholders as coloured
//! primitives, library objects as models of their parts, the gz-sim systems a robot needs, the
//! robot itself when placed), the robot as URDF (REP-105 frames, gz-sim sensors and systems as
//! `<gazebo>` extensions) and as an SDF model with the same links and joints, and the
//! `ros_gz_bridge` configuration for the topics those sensors and systems use.

mod actors;
mod bridge;
mod layout;
mod sdf;
mod urdf;
mod world;

pub use bridge::ros_gz_bridge_yaml;
pub use sdf::robot_sdf;
pub use urdf::robot_urdf;
pub use world::{world_name, world_sdf, world_sdf_with_robot};

use std::collections::HashSet;
use std::fmt::Write as _;

use crate::spec::{Colour, Pose3, RobotSpec, Shape, Size3};
use layout::RobotLayout;

/// A name usable in SDF and URDF (letters, digits, `_` and `-`), from an IRI's local part, made
/// unique among `taken`.
fn unique_name(iri: &str, taken: &mut HashSet<String>) -> String {
    let local = iri
        .trim_end_matches(['/', '#'])
        .rsplit(['#', '/', ':'])
        .next()
        .unwrap_or(iri);
    let mut base: String = local
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if base.is_empty() || base.starts_with(|c: char| c.is_ascii_digit()) {
        base.insert_str(0, "n_");
    }
    let mut name = base.clone();
    let mut k = 2;
    while !taken.insert(name.clone()) {
        name = format!("{base}_{k}");
        k += 1;
    }
    name
}

fn xml(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// `x y z roll pitch yaw`, as SDF's `<pose>` writes it.
fn pose6(p: &Pose3) -> String {
    format!("{} {} {} {} {} {}", p.x, p.y, p.z, p.roll, p.pitch, p.yaw)
}

/// An SDF `<geometry>` for a primitive (SDF cylinders stand along z, as ours).
fn sdf_geometry(shape: Shape, size: Size3) -> String {
    match shape {
        Shape::Box => format!("<box><size>{} {} {}</size></box>", size.x, size.y, size.z),
        Shape::Cylinder => format!(
            "<cylinder><radius>{}</radius><length>{}</length></cylinder>",
            size.x.max(size.y) / 2.0,
            size.z
        ),
        Shape::Sphere => format!(
            "<sphere><radius>{}</radius></sphere>",
            size.x.max(size.y).max(size.z) / 2.0
        ),
    }
}

fn sdf_material(c: Colour) -> String {
    let [r, g, b] = c.to_unit();
    format!(
        "<material><ambient>{r:.4} {g:.4} {b:.4} 1</ambient><diffuse>{r:.4} {g:.4} {b:.4} 1</diffuse></material>"
    )
}

/// `text` with every line indented by `prefix`, ending with a newline.
fn indented(text: &str, prefix: &str) -> String {
    let mut s = String::new();
    for line in text.lines() {
        let _ = writeln!(s, "{prefix}{line}");
    }
    s
}

/// The robot's frames as its URDF and SDF name them (REP-105): what a recording of its
/// rehearsal stamps its transforms and scans with.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotFrames {
    /// The root on the floor, under the drive axle's midpoint.
    pub base_footprint: String,
    /// The body frame, at the axle's height.
    pub base_link: String,
    /// Height of `base_link` above `base_footprint`, metres.
    pub base_link_z: f64,
    /// The laser's frame (named after the robot's laser in the knowledge graph), on
    /// `base_link`.
    pub laser: String,
}

impl RobotFrames {
    /// The frames of `robot`.
    pub fn of(robot: &RobotSpec) -> Self {
        let layout = RobotLayout::new(robot);
        Self {
            base_footprint: "base_footprint".to_owned(),
            base_link: "base_link".to_owned(),
            base_link_z: layout.axle,
            laser: layout.laser,
        }
    }
}
