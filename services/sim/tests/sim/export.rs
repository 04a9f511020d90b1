//! SDF and URDF exports, validated by the real parsers from Debian when they are installed:
//! `check_urdf` (liburdfdom-tools) and libsdformat (libsdformat-dev, through a tiny C++ program).

use std::path::{Path, PathBuf};
use std::process::Command;

use sim::export::{robot_urdf, world_sdf};
use sim::{Pose3, RobotSpec, Shape, Size3, WallSpec};

use crate::common::{object, room};

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("sim-export");
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir.join(name)
}

fn furnished_spec() -> sim::WorldSpec {
    let mut spec = room(8.0, 6.0);
    spec.objects.push(object(
        "http://ex.org/env#table-1",
        Some("tosm:Table"),
        Shape::Box,
        Size3::new(1.2, 0.8, 0.75),
        Pose3::new(3.0, 3.0, 0.375, 0.4),
    ));
    spec.objects.push(object(
        "http://ex.org/env#vending",
        Some("tosm:VendingMachine"),
        Shape::Box,
        Size3::new(0.8, 0.7, 1.8),
        Pose3::new(6.0, 2.0, 0.9, 0.0),
    ));
    spec.objects.push(object(
        "http://ex.org/env#bin",
        Some("tosm:Bin"),
        Shape::Cylinder,
        Size3::new(0.4, 0.4, 0.6),
        Pose3::new(6.0, 4.5, 0.3, 0.0),
    ));
    spec.objects.push(object(
        "http://ex.org/env#ball",
        None,
        Shape::Sphere,
        Size3::new(0.3, 0.3, 0.3),
        Pose3::new(1.0, 1.0, 0.15, 0.0),
    ));
    spec.objects.push(object(
        "http://ex.org/env#door",
        Some("tosm:Door"),
        Shape::Box,
        Size3::new(0.05, 0.9, 2.0),
        Pose3::new(4.0, 0.5, 1.0, 0.0),
    ));
    spec.walls.push(WallSpec {
        id: "http://ex.org/env#room".into(),
        start: [0.5, 0.5],
        end: [0.5, 5.5],
        thickness: 0.1,
        height: 2.5,
    });
    spec
}

/// The sdformat checker, compiled once per target directory; `None` (with a message, or a
/// failure under CI: `fixtures::missing`) when libsdformat or a C++ compiler is missing.
fn sdf_checker() -> Option<PathBuf> {
    let bin = scratch("check_sdf");
    if bin.exists() {
        return Some(bin);
    }
    let flags = match Command::new("pkg-config")
        .args(["--cflags", "--libs", "sdformat12"])
        .output()
    {
        Ok(out) if out.status.success() => out,
        Ok(_) => {
            fixtures::missing("libsdformat (pkg-config sdformat12)");
            return None;
        }
        Err(_) => {
            fixtures::missing("pkg-config (to find libsdformat)");
            return None;
        }
    };
    let src = scratch("check_sdf.cc");
    std::fs::write(
        &src,
        r#"#include <sdf/sdf.hh>
#include <iostream>
int main(int argc, char **argv) {
  if (argc != 2) return 64;
  sdf::Root root;
  sdf::Errors errors = root.Load(argv[1]);
  for (const auto &e : errors) std::cerr << e << std::endl;
  if (!errors.empty()) return 1;
  if (root.WorldCount() != 1) { std::cerr << "worlds: " << root.WorldCount() << std::endl; return 2; }
  const sdf::World *w = root.WorldByIndex(0);
  std::cout << w->ModelCount() << std::endl;
  return 0;
}
"#,
    )
    .expect("write checker source");
    let flags = String::from_utf8_lossy(&flags.stdout).to_string();
    let status = Command::new("g++")
        .arg("-std=c++17")
        .arg("-o")
        .arg(&bin)
        .arg(&src)
        .args(flags.split_whitespace())
        .status();
    match status {
        Ok(s) if s.success() => Some(bin),
        other => {
            fixtures::missing(format!(
                "a g++ that compiles the sdformat checker ({other:?})"
            ));
            None
        }
    }
}

fn check_sdf(path: &Path) -> Option<usize> {
    let checker = sdf_checker()?;
    let out = Command::new(checker)
        .arg(path)
        .output()
        .expect("run checker");
    assert!(
        out.status.success(),
        "libsdformat rejected {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    Some(
        String::from_utf8_lossy(&out.stdout)
            .trim()
            .parse()
            .expect("model count"),
    )
}

#[test]
fn the_world_sdf_is_loaded_by_libsdformat() {
    let spec = furnished_spec();
    let text = world_sdf(&spec);
    roxmltree::Document::parse(&text).expect("well-formed XML");
    assert!(text.contains(r#"<sdf version="1.9">"#));
    // The placeholder keeps its colour (200, 30, 30 in the fixtures); a closed door has a leaf.
    assert!(
        text.contains("<diffuse>0.7843 0.1176 0.1176 1</diffuse>"),
        "placeholder colour"
    );
    assert!(
        text.contains("leaf_collision"),
        "a closed door has its leaf"
    );
    let path = scratch("world.sdf");
    std::fs::write(&path, &text).expect("write");
    if let Some(models) = check_sdf(&path) {
        // Ground, map walls, boundary walls and five objects.
        assert_eq!(models, 8);
    }
}

#[test]
fn the_robot_urdf_is_accepted_by_check_urdf() {
    let robot = RobotSpec::example_differential();
    let text = robot_urdf(&robot);
    let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
    let links = doc.descendants().filter(|n| n.has_tag_name("link")).count();
    assert_eq!(
        links,
        1 + 1 + 1 + 3 + 1,
        "base_footprint, base_link, body, three wheels, laser"
    );
    // REP-105: base_footprint → base_link (at the axle's height) → everything else.
    let parent_of = |child: &str| {
        doc.descendants()
            .filter(|n| n.has_tag_name("joint"))
            .find(|j| {
                j.children()
                    .any(|c| c.has_tag_name("child") && c.attribute("link") == Some(child))
            })
            .and_then(|j| {
                j.children()
                    .find(|c| c.has_tag_name("parent"))
                    .and_then(|c| c.attribute("link"))
                    .map(str::to_owned)
            })
    };
    assert_eq!(parent_of("base_link").as_deref(), Some("base_footprint"));
    let children: Vec<&str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("child"))
        .filter_map(|c| c.attribute("link"))
        .filter(|l| *l != "base_link")
        .collect();
    assert_eq!(children.len(), 5, "{children:?}");
    for child in children {
        assert_eq!(parent_of(child).as_deref(), Some("base_link"), "{child}");
    }
    assert!(text.contains("<samples>690</samples>"));
    assert!(text.contains("<left_joint>left_wheel_joint</left_joint>"));
    let path = scratch("robot.urdf");
    std::fs::write(&path, &text).expect("write");
    match Command::new("check_urdf").arg(&path).output() {
        Ok(out) => assert!(
            out.status.success(),
            "check_urdf rejected the URDF: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(_) => fixtures::missing("check_urdf (liburdfdom-tools)"),
    }
}

#[test]
fn the_sample_building_and_robot_export_to_files_gazebo_and_ros_load() {
    let mut g = oxrdf::Graph::new();
    for rel in [
        "environments/sample-building.ttl",
        "robots/differential-robot.ttl",
    ] {
        let path = PathBuf::from(
            std::env::var("CARGO_MANIFEST_DIR")
                .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
        )
        .join("../../ontologies")
        .join(rel);
        let text = std::fs::read(&path).expect("bundled ontology file");
        for t in oxttl::TurtleParser::new().for_slice(&text) {
            g.insert(&t.expect("valid Turtle"));
        }
    }
    let spec = sim::parse_floor(
        &g,
        "https://mentalsim.dev/data/robots/differential-robot",
        "https://mentalsim.dev/data/buildings/sample-building/floors/0",
    )
    .unwrap_or_else(|p| panic!("{p}"));
    let urdf = robot_urdf(&spec.robot);
    // The stereo camera has a depth range: a depth sensor; the drive plugin names both wheels.
    assert!(urdf.contains(r#"<sensor type="depth""#), "{urdf}");
    assert!(
        urdf.contains("<left_joint>left-wheel_joint</left_joint>"),
        "{urdf}"
    );
    let path = scratch("differential-robot.urdf");
    std::fs::write(&path, &urdf).expect("write");
    if let Ok(out) = Command::new("check_urdf").arg(&path).output() {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stdout)
        );
    } else {
        fixtures::missing("check_urdf (liburdfdom-tools)");
    }
    let sdf = world_sdf(&spec);
    let path = scratch("sample-building-floor-0.sdf");
    std::fs::write(&path, &sdf).expect("write");
    if let Some(models) = check_sdf(&path) {
        assert_eq!(
            models,
            2 + spec.objects.len(),
            "ground, walls and every object"
        );
    }
}
