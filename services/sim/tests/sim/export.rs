//! SDF and URDF exports, validated by the real parsers from Debian when they are installed:
//! `check_urdf` (liburdfdom-tools) and libsdformat (libsdformat-dev, through a tiny C++ program).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use sim::export::{
    RobotFrames, robot_sdf, robot_urdf, ros_gz_bridge_yaml, world_name, world_sdf,
    world_sdf_with_robot,
};
use sim::{Pose2, Pose3, RobotSpec, Shape, Size3, WallSpec};

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

/// What the checker prints: for each model (the world's, or the one a URDF or model file
/// holds) its links, joints, sensors and plugins as libsdformat parsed them.
const CHECKER: &str = r#"#include <sdf/sdf.hh>
#include <iomanip>
#include <iostream>

static const char *jointType(sdf::JointType t) {
  switch (t) {
    case sdf::JointType::FIXED: return "fixed";
    case sdf::JointType::REVOLUTE: return "revolute";
    case sdf::JointType::CONTINUOUS: return "continuous";
    case sdf::JointType::BALL: return "ball";
    case sdf::JointType::PRISMATIC: return "prismatic";
    default: return "other";
  }
}

// Every <plugin> child of `e`: its filename and name, then each parameter as `param`.
static void plugins(const char *scope, sdf::ElementPtr e) {
  if (!e || !e->HasElement("plugin")) return;
  for (auto p = e->GetElement("plugin"); p; p = p->GetNextElement("plugin")) {
    std::cout << "plugin " << scope << " " << p->Get<std::string>("filename") << " "
              << p->Get<std::string>("name") << "\n";
    for (auto c = p->GetFirstElement(); c; c = c->GetNextElement()) {
      std::cout << "param " << c->GetName() << " " << c->Get<std::string>() << "\n";
    }
  }
}

static void model(const sdf::Model *m) {
  ignition::math::Pose3d mp = m->RawPose();
  std::cout << "model " << m->Name() << " " << mp.Pos().X() << " " << mp.Pos().Y() << " "
            << mp.Pos().Z() << " " << mp.Rot().Yaw() << "\n";
  for (uint64_t i = 0; i < m->LinkCount(); ++i) {
    const sdf::Link *l = m->LinkByIndex(i);
    std::cout << "link " << l->Name() << "\n";
    for (uint64_t j = 0; j < l->SensorCount(); ++j) {
      const sdf::Sensor *s = l->SensorByIndex(j);
      ignition::math::Pose3d p;
      sdf::Errors errs = s->SemanticPose().Resolve(p, "__model__");
      for (const auto &e : errs) std::cerr << e << std::endl;
      std::string frame = s->Element()->HasElement("gz_frame_id")
          ? s->Element()->Get<std::string>("gz_frame_id") : "-";
      std::cout << "sensor " << l->Name() << " " << s->Name() << " " << s->TypeStr() << " "
                << s->Topic() << " " << frame << " " << p.Pos().X() << " " << p.Pos().Y() << " "
                << p.Pos().Z() << " " << p.Rot().Roll() << " " << p.Rot().Pitch() << " "
                << p.Rot().Yaw() << "\n";
      if (const sdf::Lidar *ld = s->LidarSensor()) {
        std::cout << "lidar " << ld->HorizontalScanSamples() << " "
                  << ld->HorizontalScanMinAngle().Radian() << " "
                  << ld->HorizontalScanMaxAngle().Radian() << " " << ld->RangeMin() << " "
                  << ld->RangeMax() << "\n";
      }
    }
  }
  for (uint64_t i = 0; i < m->JointCount(); ++i) {
    const sdf::Joint *j = m->JointByIndex(i);
    std::cout << "joint " << j->Name() << " " << jointType(j->Type()) << " "
              << j->ParentLinkName() << " " << j->ChildLinkName() << "\n";
  }
  plugins("model", m->Element());
}

int main(int argc, char **argv) {
  if (argc != 2) return 64;
  std::cout << std::setprecision(17);
  sdf::Root root;
  sdf::Errors errors = root.Load(argv[1]);
  for (const auto &e : errors) std::cerr << e << std::endl;
  if (!errors.empty()) return 1;
  if (root.WorldCount() == 1) {
    const sdf::World *w = root.WorldByIndex(0);
    std::cout << "world " << w->Name() << " " << w->ModelCount() << "\n";
    plugins("world", w->Element());
    for (uint64_t i = 0; i < w->ModelCount(); ++i) model(w->ModelByIndex(i));
  } else if (root.Model() != nullptr) {
    model(root.Model());
  } else {
    std::cerr << "neither one world nor a model" << std::endl;
    return 2;
  }
  return 0;
}
"#;

/// The sdformat checker, compiled once per checker source and target directory; `None` (with
/// a message, or a failure under CI: `fixtures::missing`) when libsdformat or a C++ compiler is
/// missing.
fn sdf_checker() -> Option<PathBuf> {
    static CHECKER_BIN: OnceLock<Option<PathBuf>> = OnceLock::new();
    CHECKER_BIN.get_or_init(compile_checker).clone()
}

fn compile_checker() -> Option<PathBuf> {
    // Named after its source, so that a changed checker is compiled again.
    let hash = CHECKER.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    let bin = scratch(&format!("check_sdf_{hash:016x}"));
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
    let src = scratch(&format!("check_sdf_{hash:016x}.cc"));
    std::fs::write(&src, CHECKER).expect("write checker source");
    let flags = String::from_utf8_lossy(&flags.stdout).to_string();
    let partial = bin.with_extension("partial");
    let status = Command::new("g++")
        .arg("-std=c++17")
        .arg("-o")
        .arg(&partial)
        .arg(&src)
        .args(flags.split_whitespace())
        .status();
    match status {
        Ok(s) if s.success() => {
            std::fs::rename(&partial, &bin).expect("install checker");
            Some(bin)
        }
        other => {
            fixtures::missing(format!(
                "a g++ that compiles the sdformat checker ({other:?})"
            ));
            None
        }
    }
}

/// A plugin as libsdformat read it.
#[derive(Debug, Default)]
struct Plugin {
    filename: String,
    name: String,
    params: Vec<(String, String)>,
}

impl Plugin {
    fn param(&self, key: &str) -> Option<&str> {
        self.params
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    fn params(&self, key: &str) -> Vec<&str> {
        self.params
            .iter()
            .filter(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
            .collect()
    }
}

/// A sensor as libsdformat read it, its pose resolved in the model frame.
#[derive(Debug)]
struct Sensor {
    link: String,
    kind: String,
    topic: String,
    frame: String,
    pose: [f64; 6],
    /// Samples, min and max angle, min and max range.
    lidar: Option<(usize, f64, f64, f64, f64)>,
}

#[derive(Debug)]
struct Joint {
    name: String,
    kind: String,
    parent: String,
    child: String,
}

#[derive(Debug, Default)]
struct ParsedModel {
    name: String,
    /// x, y, z, yaw of the model's pose.
    pose: [f64; 4],
    links: Vec<String>,
    joints: Vec<Joint>,
    sensors: Vec<Sensor>,
    plugins: Vec<Plugin>,
}

impl ParsedModel {
    fn plugin(&self, name: &str) -> &Plugin {
        self.plugins
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("no plugin {name} in {self:#?}"))
    }

    fn joint(&self, name: &str) -> &Joint {
        self.joints
            .iter()
            .find(|j| j.name == name)
            .unwrap_or_else(|| panic!("no joint {name} in {:?}", self.joints))
    }
}

/// What libsdformat made of a file.
#[derive(Debug, Default)]
struct Parsed {
    world: Option<String>,
    world_plugins: Vec<Plugin>,
    models: Vec<ParsedModel>,
}

impl Parsed {
    fn model(&self, name: &str) -> &ParsedModel {
        self.models
            .iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("no model {name}"))
    }
}

fn numbers<const N: usize>(words: &[&str]) -> [f64; N] {
    let mut out = [0.0; N];
    for (o, w) in out.iter_mut().zip(words) {
        *o = w.parse().unwrap_or_else(|_| panic!("a number: {w}"));
    }
    out
}

fn parse_checker_output(text: &str) -> Parsed {
    let mut parsed = Parsed::default();
    // Where the next `param` goes: the last plugin of the world or of the last model.
    let mut in_world_plugin = false;
    for line in text.lines() {
        let words: Vec<&str> = line.split(' ').collect();
        match words.as_slice() {
            ["world", name, _count] => parsed.world = Some((*name).to_owned()),
            ["plugin", scope, filename, name] => {
                let plugin = Plugin {
                    filename: (*filename).to_owned(),
                    name: (*name).to_owned(),
                    params: vec![],
                };
                in_world_plugin = *scope == "world";
                if in_world_plugin {
                    parsed.world_plugins.push(plugin);
                } else {
                    parsed
                        .models
                        .last_mut()
                        .expect("a model")
                        .plugins
                        .push(plugin);
                }
            }
            ["param", key, value @ ..] => {
                let plugin = if in_world_plugin {
                    parsed.world_plugins.last_mut()
                } else {
                    parsed.models.last_mut().and_then(|m| m.plugins.last_mut())
                };
                plugin
                    .expect("a plugin")
                    .params
                    .push(((*key).to_owned(), value.join(" ")));
            }
            ["model", name, pose @ ..] => parsed.models.push(ParsedModel {
                name: (*name).to_owned(),
                pose: numbers(pose),
                ..ParsedModel::default()
            }),
            ["link", name] => {
                let model = parsed.models.last_mut().expect("a model");
                model.links.push((*name).to_owned());
            }
            ["sensor", link, _name, kind, topic, frame, pose @ ..] => {
                let model = parsed.models.last_mut().expect("a model");
                model.sensors.push(Sensor {
                    link: (*link).to_owned(),
                    kind: (*kind).to_owned(),
                    topic: (*topic).to_owned(),
                    frame: (*frame).to_owned(),
                    pose: numbers(pose),
                    lidar: None,
                });
            }
            ["lidar", samples, rest @ ..] => {
                let model = parsed.models.last_mut().expect("a model");
                let [min, max, rmin, rmax] = numbers(rest);
                model.sensors.last_mut().expect("a sensor").lidar =
                    Some((samples.parse().expect("samples"), min, max, rmin, rmax));
            }
            ["joint", name, kind, parent, child] => {
                let model = parsed.models.last_mut().expect("a model");
                model.joints.push(Joint {
                    name: (*name).to_owned(),
                    kind: (*kind).to_owned(),
                    parent: (*parent).to_owned(),
                    child: (*child).to_owned(),
                });
            }
            _ => panic!("unexpected checker output: {line}"),
        }
    }
    parsed
}

/// What libsdformat makes of `text` written to `name` (`.sdf` or `.urdf`): it must load
/// without errors. `None` when libsdformat is not installed (outside CI).
fn load_with_libsdformat(name: &str, text: &str) -> Option<Parsed> {
    let checker = sdf_checker()?;
    let path = scratch(name);
    std::fs::write(&path, text).expect("write");
    let out = Command::new(checker)
        .arg(&path)
        .output()
        .expect("run checker");
    assert!(
        out.status.success(),
        "libsdformat rejected {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    Some(parse_checker_output(&String::from_utf8_lossy(&out.stdout)))
}

fn check_urdf(path: &Path) {
    match Command::new("check_urdf").arg(path).output() {
        Ok(out) => assert!(
            out.status.success(),
            "check_urdf rejected {}: {}{}",
            path.display(),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(_) => fixtures::missing("check_urdf (liburdfdom-tools)"),
    }
}

/// The robot's gz-sim systems and laser as libsdformat read them, checked against the spec:
/// the drive on two revolute joints of the model, in the REP-105 frames, with the spec's
/// wheels and limits; the joint states of every moving joint; a gpu_lidar with the spec's
/// samples, angles and ranges at the laser's mount, stamped with the laser's link.
fn assert_gz_robot(model: &ParsedModel, robot: &RobotSpec, laser_link: &str) {
    let drive = model.plugin("gz::sim::systems::DiffDrive");
    assert_eq!(drive.filename, "gz-sim-diff-drive-system");
    for side in ["left_joint", "right_joint"] {
        let joint = model.joint(drive.param(side).expect(side));
        assert_eq!(
            joint.kind, "revolute",
            "{joint:?}: dartsim fixes continuous joints"
        );
    }
    let left = model.joint(drive.param("left_joint").expect("left_joint"));
    assert!(left.child.contains("left"), "{left:?}");
    let num = |key: &str| -> f64 { drive.param(key).expect(key).parse().expect(key) };
    assert_eq!(num("wheel_separation"), robot.drive.wheel_separation);
    assert_eq!(num("wheel_radius"), robot.drive.wheel_radius);
    assert!(num("odom_publish_frequency") > 0.0);
    assert_eq!(drive.param("frame_id"), Some("odom"));
    assert_eq!(drive.param("child_frame_id"), Some("base_footprint"));
    for key in ["topic", "odom_topic", "tf_topic"] {
        assert!(
            drive.param(key).is_some_and(|t| t.starts_with('/')),
            "{key}"
        );
    }
    if let Some(v) = robot.drive.max_linear_speed {
        assert_eq!(num("max_linear_velocity"), v);
        assert_eq!(num("min_linear_velocity"), -v);
    }
    if let Some(v) = robot.drive.max_angular_speed {
        assert_eq!(num("max_angular_velocity"), v);
        assert_eq!(num("min_angular_velocity"), -v);
    }
    let states = model.plugin("gz::sim::systems::JointStatePublisher");
    assert_eq!(states.filename, "gz-sim-joint-state-publisher-system");
    let mut moving: Vec<&str> = model
        .joints
        .iter()
        .filter(|j| j.kind != "fixed")
        .map(|j| j.name.as_str())
        .collect();
    let mut published = states.params("joint_name");
    moving.sort_unstable();
    published.sort_unstable();
    assert_eq!(published, moving);
    assert_eq!(moving.len(), robot.wheels.len());

    let lidars: Vec<&Sensor> = model
        .sensors
        .iter()
        .filter(|s| s.kind == "gpu_lidar")
        .collect();
    assert_eq!(lidars.len(), 1, "{:?}", model.sensors);
    let lidar = lidars[0];
    let l = &robot.laser;
    let (samples, min, max, rmin, rmax) = lidar.lidar.expect("lidar parameters");
    assert_eq!(samples, l.samples);
    assert!((min - l.sample_angle(0)).abs() < 1e-9, "{min}");
    assert!((max - l.sample_angle(l.samples - 1)).abs() < 1e-9, "{max}");
    assert_eq!((rmin, rmax), (l.range_min, l.range_max));
    assert_eq!(lidar.frame, laser_link);
    assert!(lidar.topic.starts_with('/'), "{}", lidar.topic);
    let m = l.mount;
    let want = [m.x, m.y, m.z, m.roll, m.pitch, m.yaw];
    for (got, want) in lidar.pose.iter().zip(want) {
        assert!(
            (got - want).abs() < 1e-6,
            "laser at {:?}, mounted at {m:?}",
            lidar.pose
        );
    }
}

/// The world runs what gz-sim needs for the robot and its gpu_lidar.
fn assert_gz_world(parsed: &Parsed) {
    for (filename, name) in [
        ("gz-sim-physics-system", "gz::sim::systems::Physics"),
        (
            "gz-sim-user-commands-system",
            "gz::sim::systems::UserCommands",
        ),
        (
            "gz-sim-scene-broadcaster-system",
            "gz::sim::systems::SceneBroadcaster",
        ),
        ("gz-sim-sensors-system", "gz::sim::systems::Sensors"),
    ] {
        let plugin = parsed
            .world_plugins
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("the world runs {name}: {:?}", parsed.world_plugins));
        assert_eq!(plugin.filename, filename);
    }
    let sensors = parsed
        .world_plugins
        .iter()
        .find(|p| p.name == "gz::sim::systems::Sensors")
        .expect("the sensors system");
    assert_eq!(sensors.param("render_engine"), Some("ogre2"));
}

/// Link and joint names of a URDF, and each joint's parent and child.
fn urdf_tree(text: &str) -> (Vec<String>, Vec<(String, String, String)>) {
    let doc = roxmltree::Document::parse(text).expect("well-formed URDF");
    let links = doc
        .root_element()
        .children()
        .filter(|n| n.has_tag_name("link"))
        .map(|n| n.attribute("name").expect("link name").to_owned())
        .collect();
    let joints = doc
        .root_element()
        .children()
        .filter(|n| n.has_tag_name("joint"))
        .map(|j| {
            let end = |tag: &str| {
                j.children()
                    .find(|c| c.has_tag_name(tag))
                    .and_then(|c| c.attribute("link"))
                    .expect("joint end")
                    .to_owned()
            };
            (
                j.attribute("name").expect("joint name").to_owned(),
                end("parent"),
                end("child"),
            )
        })
        .collect();
    (links, joints)
}

/// The bridge's entries: ROS topic → (gz topic, ROS type, gz type, direction).
fn bridge_entries(yaml: &str) -> Vec<[String; 5]> {
    let docs = yaml_rust2::YamlLoader::load_from_str(yaml).expect("valid YAML");
    assert_eq!(docs.len(), 1);
    let entries = docs[0].as_vec().expect("a YAML array of maps");
    entries
        .iter()
        .map(|e| {
            let hash = e.as_hash().expect("a map");
            assert_eq!(hash.len(), 5, "{e:?}");
            let field = |k: &str| {
                e[k].as_str()
                    .unwrap_or_else(|| panic!("{k} in {e:?}"))
                    .to_owned()
            };
            [
                field("ros_topic_name"),
                field("gz_topic_name"),
                field("ros_type_name"),
                field("gz_type_name"),
                field("direction"),
            ]
        })
        .collect()
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
    if let Some(parsed) = load_with_libsdformat("world.sdf", &text) {
        // Ground, map walls, boundary walls and five objects.
        assert_eq!(parsed.models.len(), 8);
        assert_eq!(parsed.world, Some(world_name(&spec)));
        assert_gz_world(&parsed);
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
    // Nothing of Gazebo Classic is left.
    assert!(!text.contains("libgazebo"), "{text}");
    assert!(!text.contains(r#"type="ray""#), "{text}");
    let path = scratch("robot.urdf");
    std::fs::write(&path, &text).expect("write");
    check_urdf(&path);
    // gz-sim reads a URDF through libsdformat: the extensions must survive the conversion
    // (which merges the fixed links into base_footprint, keeping the laser's frame name).
    if let Some(parsed) = load_with_libsdformat("robot-urdf.urdf", &text) {
        assert_eq!(parsed.models.len(), 1);
        let model = &parsed.models[0];
        assert_eq!(model.name, "example_robot");
        assert_eq!(model.links[0], "base_footprint");
        assert_gz_robot(model, &robot, "laser");
        // The caster slides: its collision has no friction.
        assert!(text.contains(r#"<gazebo reference="caster"><mu1>0</mu1><mu2>0</mu2></gazebo>"#));
    }
}

#[test]
fn the_robot_sdf_has_the_urdfs_links_and_joints_and_libsdformat_loads_it() {
    let robot = RobotSpec::example_differential();
    let sdf = robot_sdf(&robot);
    let (links, joints) = urdf_tree(&robot_urdf(&robot));
    let Some(parsed) = load_with_libsdformat("robot.sdf", &sdf) else {
        return;
    };
    assert_eq!(parsed.world, None);
    let model = &parsed.models[0];
    assert_eq!(model.name, "example_robot");
    assert_eq!(model.links, links);
    let sdf_joints: Vec<(String, String, String)> = model
        .joints
        .iter()
        .map(|j| (j.name.clone(), j.parent.clone(), j.child.clone()))
        .collect();
    assert_eq!(sdf_joints, joints);
    assert_eq!(model.links[0], "base_footprint", "the canonical link");
    assert_gz_robot(model, &robot, "laser");
    let lidar = model
        .sensors
        .iter()
        .find(|s| s.kind == "gpu_lidar")
        .unwrap();
    assert_eq!(lidar.link, "laser", "the sensor is on the laser's own link");
}

#[test]
fn a_robot_with_speed_limits_and_a_camera_exports_them_for_gz_sim() {
    let mut robot = RobotSpec::example_differential();
    robot.drive.max_linear_speed = Some(0.8);
    robot.drive.max_angular_speed = Some(0.5);
    robot.drive.max_linear_acceleration = Some(1.5);
    // Braking faster than it speeds up: gz-sim takes it as the most negative acceleration.
    robot.drive.max_linear_deceleration = Some(2.5);
    robot.cameras.push(sim::CameraSpec {
        id: "http://ex.org/robot#front-camera".into(),
        width: 640,
        height: 480,
        fps: 15.0,
        hfov: 1.2,
        depth_range: None,
        mount: Pose3::new(0.15, 0.0, 0.35, 0.0),
    });
    let urdf = robot_urdf(&robot);
    let path = scratch("robot-camera.urdf");
    std::fs::write(&path, &urdf).expect("write");
    check_urdf(&path);
    let (links, _) = urdf_tree(&urdf);
    assert!(links.contains(&"front-camera".to_owned()), "{links:?}");
    assert!(
        links.contains(&"front-camera_optical_frame".to_owned()),
        "{links:?}"
    );
    for (name, text) in [
        ("robot-camera.sdf", robot_sdf(&robot)),
        ("robot-camera-urdf.urdf", urdf),
    ] {
        let Some(parsed) = load_with_libsdformat(name, &text) else {
            return;
        };
        let model = &parsed.models[0];
        assert_gz_robot(model, &robot, "laser");
        let drive = model.plugin("gz::sim::systems::DiffDrive");
        assert_eq!(drive.param("max_linear_acceleration"), Some("1.5"));
        assert_eq!(drive.param("min_linear_acceleration"), Some("-2.5"));
        assert_eq!(
            drive.param("max_angular_acceleration"),
            None,
            "not in the spec"
        );
        let camera = model
            .sensors
            .iter()
            .find(|s| s.kind == "camera")
            .unwrap_or_else(|| panic!("{name}: a camera in {:?}", model.sensors));
        assert_eq!(camera.frame, "front-camera_optical_frame");
        assert_eq!(camera.topic, "/model/example_robot/front-camera/image");
        assert!((camera.pose[0] - 0.15).abs() < 1e-9 && (camera.pose[2] - 0.35).abs() < 1e-9);
    }
    let entries = bridge_entries(&ros_gz_bridge_yaml(&robot, None));
    let image = entries
        .iter()
        .find(|e| e[0] == "/front_camera/image")
        .expect("the camera's images are bridged");
    assert_eq!(image[1], "/model/example_robot/front-camera/image");
    assert!(entries.iter().any(|e| e[0] == "/front_camera/camera_info"
        && e[1] == "/model/example_robot/front-camera/camera_info"
        && e[3] == "gz.msgs.CameraInfo"));
}

#[test]
fn the_world_with_the_robot_runs_it_in_gz_sim() {
    let spec = furnished_spec();
    let start = Pose2::new(2.0, 1.5, 0.7);
    let text = world_sdf_with_robot(&spec, start);
    let Some(parsed) = load_with_libsdformat("world-robot.sdf", &text) else {
        return;
    };
    // Ground, map walls, boundary walls, five objects and the robot.
    assert_eq!(parsed.models.len(), 9);
    assert_gz_world(&parsed);
    let robot = parsed.model("example_robot");
    let [x, y, z, yaw] = robot.pose;
    assert_eq!((x, y, z), (2.0, 1.5, 0.0));
    assert!((yaw - 0.7).abs() < 1e-12);
    assert_gz_robot(robot, &spec.robot, "laser");
}

/// Every topic the bridge names on the Gazebo side is one the robot's systems and sensors
/// subscribe or publish to (as libsdformat reads the SDF), or the world's clock.
#[test]
fn the_bridge_yaml_bridges_the_topics_the_robot_publishes_on() {
    let spec = furnished_spec();
    let world = world_name(&spec);
    let yaml = ros_gz_bridge_yaml(&spec.robot, Some(&world));
    let entries = bridge_entries(&yaml);
    let by_ros = |topic: &str| -> &[String; 5] {
        entries
            .iter()
            .find(|e| e[0] == topic)
            .unwrap_or_else(|| panic!("{topic} in {entries:?}"))
    };
    for (ros, ros_type, gz_type, direction) in [
        (
            "/cmd_vel",
            "geometry_msgs/msg/Twist",
            "gz.msgs.Twist",
            "ROS_TO_GZ",
        ),
        (
            "/odom",
            "nav_msgs/msg/Odometry",
            "gz.msgs.Odometry",
            "GZ_TO_ROS",
        ),
        (
            "/scan",
            "sensor_msgs/msg/LaserScan",
            "gz.msgs.LaserScan",
            "GZ_TO_ROS",
        ),
        (
            "/tf",
            "tf2_msgs/msg/TFMessage",
            "gz.msgs.Pose_V",
            "GZ_TO_ROS",
        ),
        (
            "/joint_states",
            "sensor_msgs/msg/JointState",
            "gz.msgs.Model",
            "GZ_TO_ROS",
        ),
        (
            "/clock",
            "rosgraph_msgs/msg/Clock",
            "gz.msgs.Clock",
            "GZ_TO_ROS",
        ),
    ] {
        let e = by_ros(ros);
        assert_eq!(
            [&e[2], &e[3], &e[4]],
            [ros_type, gz_type, direction],
            "{ros}"
        );
    }
    assert_eq!(entries.len(), 6, "no camera on the example robot");
    let without_world = bridge_entries(&ros_gz_bridge_yaml(&spec.robot, None));
    assert!(
        without_world
            .iter()
            .any(|e| e[0] == "/clock" && e[1] == "/clock")
    );

    let Some(parsed) = load_with_libsdformat(
        "world-robot-bridge.sdf",
        &world_sdf_with_robot(&spec, Pose2::new(1.0, 1.0, 0.0)),
    ) else {
        return;
    };
    let robot = parsed.model("example_robot");
    let drive = robot.plugin("gz::sim::systems::DiffDrive");
    let states = robot.plugin("gz::sim::systems::JointStatePublisher");
    let lidar = robot
        .sensors
        .iter()
        .find(|s| s.kind == "gpu_lidar")
        .unwrap();
    assert_eq!(Some(by_ros("/cmd_vel")[1].as_str()), drive.param("topic"));
    assert_eq!(Some(by_ros("/odom")[1].as_str()), drive.param("odom_topic"));
    assert_eq!(Some(by_ros("/tf")[1].as_str()), drive.param("tf_topic"));
    assert_eq!(
        Some(by_ros("/joint_states")[1].as_str()),
        states.param("topic")
    );
    assert_eq!(by_ros("/scan")[1], lidar.topic);
    // gz-sim publishes the clock under the world's name.
    assert_eq!(
        by_ros("/clock")[1],
        format!("/world/{}/clock", parsed.world.as_deref().unwrap())
    );
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
    // The stereo camera has a depth range: an RGB-D sensor; the drive names both wheels.
    assert!(urdf.contains(r#"type="rgbd_camera""#), "{urdf}");
    assert!(
        urdf.contains("<left_joint>left-wheel_joint</left_joint>"),
        "{urdf}"
    );
    // The laser's link is the robot's laser in the knowledge graph (robot:laser).
    assert_eq!(
        spec.robot.laser.id,
        "https://mentalsim.dev/data/robots/differential-robot/laser"
    );
    let (links, _) = urdf_tree(&urdf);
    assert!(links.contains(&"laser".to_owned()), "{links:?}");
    assert!(urdf.contains("<gz_frame_id>laser</gz_frame_id>"), "{urdf}");
    // The frames others stamp messages with are the URDF's.
    let frames = RobotFrames::of(&spec.robot);
    assert_eq!(frames.laser, "laser");
    assert_eq!(
        (frames.base_footprint.as_str(), frames.base_link.as_str()),
        ("base_footprint", "base_link")
    );
    assert!(
        urdf.contains(&format!(
            r#"<child link="base_link"/><origin xyz="0 0 {}" rpy="0 0 0"/>"#,
            frames.base_link_z
        )),
        "{urdf}"
    );
    assert_eq!(frames.base_link_z, 0.0975, "the drive wheels' axle");
    let path = scratch("differential-robot.urdf");
    std::fs::write(&path, &urdf).expect("write");
    check_urdf(&path);
    let Some(converted) = load_with_libsdformat("differential-robot-urdf.urdf", &urdf) else {
        return;
    };
    assert_gz_robot(&converted.models[0], &spec.robot, "laser");
    let sdf = world_sdf(&spec);
    let parsed = load_with_libsdformat("sample-building-floor-0.sdf", &sdf).expect("checker");
    assert_eq!(
        parsed.models.len(),
        2 + spec.objects.len(),
        "ground, walls and every object"
    );
    assert_gz_world(&parsed);
    let model =
        load_with_libsdformat("differential-robot.sdf", &robot_sdf(&spec.robot)).expect("checker");
    let model = &model.models[0];
    assert_gz_robot(model, &spec.robot, "laser");
    let camera = model
        .sensors
        .iter()
        .find(|s| s.kind == "rgbd_camera")
        .expect("the stereo camera");
    assert_eq!(camera.frame, "camera_optical_frame");
    let bridge = bridge_entries(&ros_gz_bridge_yaml(&spec.robot, None));
    for leaf in ["image", "depth_image", "points", "camera_info"] {
        assert!(
            bridge
                .iter()
                .any(|e| e[0] == format!("/camera/{leaf}")
                    && e[1] == format!("{}/{leaf}", camera.topic)),
            "{leaf}: {bridge:?}"
        );
    }
    let with_robot = world_sdf_with_robot(&spec, Pose2::new(1.0, 1.0, 0.0));
    let parsed =
        load_with_libsdformat("sample-building-floor-0-robot.sdf", &with_robot).expect("checker");
    assert_eq!(parsed.models.len(), 3 + spec.objects.len());
}

#[test]
fn people_the_knowledge_expects_walk_as_gz_actors() {
    let mut spec = furnished_spec();
    spec.people = sim::PeopleSpec {
        places: vec![sim::PeoplePlaceSpec {
            id: "hall".into(),
            expected: 3.0,
            by_hour: vec![],
            boundary: vec![],
        }],
        routes: vec![sim::RouteSpec {
            id: "corridor".into(),
            points: vec![[1.0, 1.0], [4.0, 1.0], [4.0, 3.0]],
        }],
        attractors: vec![
            sim::AttractorSpec {
                id: "vending".into(),
                position: [2.0, 2.0],
                dwell_s: 20.0,
            },
            sim::AttractorSpec {
                id: "desk".into(),
                position: [3.0, 3.0],
                dwell_s: 0.0,
            },
        ],
    };
    let text = world_sdf(&spec);
    let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
    let actors: Vec<_> = doc
        .descendants()
        .filter(|n| n.has_tag_name("actor"))
        .collect();
    assert_eq!(actors.len(), 3, "as many as expected");
    for actor in &actors {
        let times: Vec<f64> = actor
            .descendants()
            .filter(|n| n.has_tag_name("time"))
            .map(|n| n.text().expect("time").parse().expect("number"))
            .collect();
        assert!(times.len() >= 3);
        assert!(times.windows(2).all(|w| w[1] > w[0]), "{times:?}");
    }
    // The first walks the route there and back at 1 m/s: 3 m, 2 m, 2 m, 3 m.
    let first_times: Vec<&str> = actors[0]
        .descendants()
        .filter(|n| n.has_tag_name("time"))
        .filter_map(|n| n.text())
        .collect();
    assert_eq!(first_times, ["0.000", "3.000", "5.000", "7.000", "10.000"]);
    // The attractors' walker lingers 20 s at the vending machine.
    assert!(
        text.contains("<time>0.000</time><pose>2.0000 2.0000"),
        "{text}"
    );
    assert!(
        text.contains("<time>20.000</time><pose>2.0000 2.0000"),
        "{text}"
    );
    if let Some(parsed) = load_with_libsdformat("world-people.sdf", &text) {
        assert_eq!(parsed.world, Some(world_name(&spec)));
    }
    // No routes or attractors: as many actors walk rounds between points spread over the
    // floor, the shortest way through the free region (never through a wall).
    spec.people.routes.clear();
    spec.people.attractors.clear();
    let text = world_sdf(&spec);
    let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
    let actors: Vec<_> = doc
        .descendants()
        .filter(|n| n.has_tag_name("actor"))
        .collect();
    assert_eq!(actors.len(), 3, "{text}");
    let world = sim::World::build(spec.clone()).unwrap();
    for actor in &actors {
        let poses: Vec<(f64, f64)> = actor
            .descendants()
            .filter(|n| n.has_tag_name("pose"))
            .map(|n| {
                let v: Vec<f64> = n
                    .text()
                    .expect("pose")
                    .split_whitespace()
                    .map(|x| x.parse().expect("number"))
                    .collect();
                (v[0], v[1])
            })
            .collect();
        assert!(poses.len() >= 4, "{poses:?}");
        let spread = poses
            .iter()
            .map(|p| (p.0 - poses[0].0).hypot(p.1 - poses[0].1))
            .fold(0.0, f64::max);
        assert!(spread > 2.0, "a round that goes nowhere: {poses:?}");
        for w in poses.windows(2) {
            for k in 0..=10 {
                let t = f64::from(k) / 10.0;
                let (x, y) = (
                    w[0].0 + t * (w[1].0 - w[0].0),
                    w[0].1 + t * (w[1].1 - w[0].1),
                );
                let room = world.clearance(x, y) + spec.robot.footprint_radius;
                assert!(
                    room > 0.0,
                    "an actor walks through a wall at ({x:.2}, {y:.2})"
                );
            }
        }
    }
    if let Some(parsed) = load_with_libsdformat("world-wanderers.sdf", &text) {
        assert_eq!(parsed.world, Some(world_name(&spec)));
    }
    // Nobody expected: no actor.
    spec.people.places.clear();
    assert!(!world_sdf(&spec).contains("<actor"));
}
