//! Exports that Gazebo and ROS load (paper §3.4), for one simulator, gz-sim (Harmonic, SDF 1.9):
//! the world (static walls from the metric map merged into boxes, placeholders as coloured
//! primitives, library objects as models of their parts, the gz-sim systems a robot needs, the
//! robot itself when placed), the robot as URDF (REP-105 frames, gz-sim sensors and systems as
//! `<gazebo>` extensions) and as an SDF model with the same links and joints, and the
//! `ros_gz_bridge` configuration for the topics those sensors and systems use.

use std::collections::HashSet;
use std::fmt::Write as _;

use crate::library::{self, Model};
use crate::spec::{
    CameraSpec, Colour, Occupancy, Pose2, Pose3, RobotPartSpec, RobotSpec, Shape, Size3, WheelSpec,
    WorldSpec,
};

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

/// Axis-aligned rectangles `[col, row, width, height]` (cells) covering the grid's solid cells
/// (occupied and unknown): runs along each row merged with identical runs of the next row.
fn solid_rectangles(grid: &crate::spec::OccupancyGrid) -> Vec<[usize; 4]> {
    let mut done: Vec<[usize; 4]> = Vec::new();
    let mut open: std::collections::HashMap<(usize, usize), usize> =
        std::collections::HashMap::new();
    for (row, cells) in grid.cells.chunks(grid.width.max(1)).enumerate() {
        let mut next = std::collections::HashMap::new();
        let mut col = 0;
        while col < cells.len() {
            if cells[col] == Occupancy::Free {
                col += 1;
                continue;
            }
            let start = col;
            while col < cells.len() && cells[col] != Occupancy::Free {
                col += 1;
            }
            let idx = if let Some(i) = open.remove(&(start, col)) {
                done[i][3] += 1;
                i
            } else {
                done.push([start, row, col - start, 1]);
                done.len() - 1
            };
            next.insert((start, col), idx);
        }
        open = next;
    }
    done
}

/// The name [`world_sdf`] gives the world (`<world name>`): the local name of the world's
/// identifier, so gz-sim's world-scoped topics (`/world/<name>/clock`) are known in advance.
pub fn world_name(spec: &WorldSpec) -> String {
    unique_name(
        if spec.id.is_empty() {
            "world"
        } else {
            &spec.id
        },
        &mut HashSet::new(),
    )
}

/// The gz-sim systems a world needs to run a robot (each checked against gz-sim 8's
/// `src/systems/*`): physics, the user commands `ros_gz_sim create` spawns models through, the
/// scene broadcaster the GUI and the sensors follow, and the sensors system, whose ogre2 render
/// engine the `gpu_lidar` and camera sensors need.
const WORLD_SYSTEMS: &str = r#"    <plugin filename="gz-sim-physics-system" name="gz::sim::systems::Physics"/>
    <plugin filename="gz-sim-user-commands-system" name="gz::sim::systems::UserCommands"/>
    <plugin filename="gz-sim-scene-broadcaster-system" name="gz::sim::systems::SceneBroadcaster"/>
    <plugin filename="gz-sim-sensors-system" name="gz::sim::systems::Sensors">
      <render_engine>ogre2</render_engine>
    </plugin>
"#;

/// The world as an SDF 1.9 document for gz-sim. Occupied and unknown map cells become static
/// wall boxes (merged into rectangles), boundary walls become boxes, placeholders are single
/// coloured primitives and library objects are static models made of their parts; the world
/// runs the gz-sim systems a robot needs (physics, user commands, scene broadcaster, sensors
/// with ogre2), so [`robot_sdf`] or [`robot_urdf`] can be spawned into it. No robot is in it:
/// [`world_sdf_with_robot`] places one.
pub fn world_sdf(spec: &WorldSpec) -> String {
    world_document(spec, None)
}

/// [`world_sdf`] with the robot of `spec` in it as the model [`robot_sdf`] describes, its
/// `base_footprint` at `start` on the floor.
pub fn world_sdf_with_robot(spec: &WorldSpec, start: Pose2) -> String {
    world_document(spec, Some(start))
}

fn world_document(spec: &WorldSpec, robot_at: Option<Pose2>) -> String {
    let mut s = String::new();
    let mut names = HashSet::new();
    let world_name = world_name(spec);
    let _ = writeln!(s, r#"<?xml version="1.0" ?>"#);
    let _ = writeln!(s, r#"<sdf version="1.9">"#);
    let _ = writeln!(s, r#"  <world name="{}">"#, xml(&world_name));
    let _ = writeln!(
        s,
        r#"    <!-- Generated by Mentalsim's simulation parser from the on-demand database {}. -->"#,
        xml(&spec.id).replace("--", "- -")
    );
    s.push_str(WORLD_SYSTEMS);
    s.push_str(
        r#"    <light type="directional" name="sun">
      <cast_shadows>true</cast_shadows>
      <pose>0 0 10 0 0 0</pose>
      <diffuse>0.8 0.8 0.8 1</diffuse>
      <specular>0.2 0.2 0.2 1</specular>
      <direction>-0.5 0.1 -0.9</direction>
    </light>
    <model name="ground_plane">
      <static>true</static>
      <link name="link">
        <collision name="collision"><geometry><plane><normal>0 0 1</normal><size>1000 1000</size></plane></geometry></collision>
        <visual name="visual"><geometry><plane><normal>0 0 1</normal><size>1000 1000</size></plane></geometry>
          <material><ambient>0.8 0.8 0.8 1</ambient><diffuse>0.8 0.8 0.8 1</diffuse></material></visual>
      </link>
    </model>
"#,
    );
    names.insert("ground_plane".to_owned());
    // The robot keeps its name (its topics are named after it): objects give way.
    let robot = robot_at.map(|start| (RobotLayout::new(&spec.robot), start));
    if let Some((layout, _)) = &robot {
        names.insert(layout.name.clone());
    }
    if let Some(floor) = &spec.floor {
        let g = &floor.grid;
        let name = unique_name(&format!("{}_walls", floor.id), &mut names);
        let _ = writeln!(s, r#"    <model name="{}">"#, xml(&name));
        let _ = writeln!(s, "      <static>true</static>");
        // The model frame is the grid's origin corner; boxes are placed in cells from there.
        let _ = writeln!(
            s,
            "      <pose>{} {} 0 0 0 {}</pose>",
            g.origin.x, g.origin.y, g.origin.yaw
        );
        let _ = writeln!(s, r#"      <link name="link">"#);
        let h = floor.wall_height;
        for (k, [c, r, w, hh]) in solid_rectangles(g).into_iter().enumerate() {
            let (x, y, sx, sy) = (
                (c as f64 + w as f64 / 2.0) * g.resolution,
                (r as f64 + hh as f64 / 2.0) * g.resolution,
                w as f64 * g.resolution,
                hh as f64 * g.resolution,
            );
            let geom = format!("<box><size>{sx} {sy} {h}</size></box>");
            let _ = writeln!(
                s,
                r#"        <collision name="c{k}"><pose>{x} {y} {} 0 0 0</pose><geometry>{geom}</geometry></collision>"#,
                h / 2.0
            );
            let _ = writeln!(
                s,
                r#"        <visual name="v{k}"><pose>{x} {y} {} 0 0 0</pose><geometry>{geom}</geometry><material><ambient>0.6 0.6 0.6 1</ambient><diffuse>0.7 0.7 0.7 1</diffuse></material></visual>"#,
                h / 2.0
            );
        }
        let _ = writeln!(s, "      </link>\n    </model>");
    }
    if !spec.walls.is_empty() {
        let name = unique_name("boundary_walls", &mut names);
        let _ = writeln!(s, r#"    <model name="{}">"#, xml(&name));
        let _ = writeln!(s, "      <static>true</static>\n      <link name=\"link\">");
        for (k, w) in spec.walls.iter().enumerate() {
            let (dx, dy) = (w.end[0] - w.start[0], w.end[1] - w.start[1]);
            let len = dx.hypot(dy).max(w.thickness);
            let pose = Pose3::new(
                (w.start[0] + w.end[0]) / 2.0,
                (w.start[1] + w.end[1]) / 2.0,
                w.height / 2.0,
                dy.atan2(dx),
            );
            let geom = format!("<box><size>{len} {} {}</size></box>", w.thickness, w.height);
            let _ = writeln!(
                s,
                r#"        <collision name="c{k}"><pose>{}</pose><geometry>{geom}</geometry></collision>"#,
                pose6(&pose)
            );
            let _ = writeln!(
                s,
                r#"        <visual name="v{k}"><pose>{}</pose><geometry>{geom}</geometry></visual>"#,
                pose6(&pose)
            );
        }
        let _ = writeln!(s, "      </link>\n    </model>");
    }
    for o in &spec.objects {
        let name = unique_name(&o.id, &mut names);
        let kind = match library::model_for(o) {
            Model::Library(m) => format!("library model `{}`", m.name()),
            Model::Placeholder => format!(
                "placeholder {} of class {}",
                o.shape.name(),
                o.class.as_deref().unwrap_or("unknown")
            ),
        };
        let _ = writeln!(s, r#"    <model name="{}">"#, xml(&name));
        let _ = writeln!(
            s,
            "      <!-- {} : {} -->",
            xml(&o.id).replace("--", "- -"),
            xml(&kind).replace("--", "- -")
        );
        let _ = writeln!(s, "      <static>true</static>");
        let _ = writeln!(s, "      <pose>{}</pose>", pose6(&o.pose));
        let _ = writeln!(s, r#"      <link name="link">"#);
        // Parts are placed in the world by the library; SDF wants them in the model frame.
        let (sn, cs) = o.pose.yaw.sin_cos();
        for p in library::parts(o) {
            let (dx, dy) = (p.pose.x - o.pose.x, p.pose.y - o.pose.y);
            let local = Pose3::new(
                cs * dx + sn * dy,
                -sn * dx + cs * dy,
                p.pose.z - o.pose.z,
                0.0,
            );
            let geom = sdf_geometry(p.shape, p.size);
            let _ = writeln!(
                s,
                r#"        <collision name="{n}_collision"><pose>{}</pose><geometry>{geom}</geometry></collision>"#,
                pose6(&local),
                n = p.name
            );
            let _ = writeln!(
                s,
                r#"        <visual name="{n}_visual"><pose>{}</pose><geometry>{geom}</geometry>{}</visual>"#,
                pose6(&local),
                sdf_material(p.colour),
                n = p.name
            );
        }
        let _ = writeln!(s, "      </link>\n    </model>");
    }
    if let Some((layout, start)) = &robot {
        let model = robot_model(&spec.robot, layout, Some(*start));
        for line in model.lines() {
            let _ = writeln!(s, "    {line}");
        }
    }
    s.push_str(&people_actors(spec));
    s.push_str("  </world>\n</sdf>\n");
    s
}

/// Stops in the round of an actor that walks between the wanderers' points.
const WANDER_STOPS: usize = 4;

/// Walking speed of the exported actors, m/s (the middle of the simulation's range).
const ACTOR_SPEED: f64 = 1.0;
/// Gazebo Fuel's walking actor (Mingfei's, as gz-sim's own actor examples use it).
const ACTOR_MESH: &str =
    "https://fuel.gazebosim.org/1.0/Mingfei/models/actor/tip/files/meshes/walk.dae";

/// The people the knowledge expects, as gz-sim actors: as many as expected (rounded, at least
/// one per route when routes are known), each walking a known route there and back, or the
/// attractors in turn lingering at each; their trajectories loop. Without routes or attractors
/// they walk rounds between the points the simulation's wanderers walk between
/// ([`crate::crowd::Targets::wander_round`]), the shortest way through the free region.
fn people_actors(spec: &WorldSpec) -> String {
    let people = &spec.people;
    let mut tracks: Vec<Vec<[f64; 2]>> = people
        .routes
        .iter()
        .filter(|r| r.points.len() >= 2)
        .map(|r| {
            let mut there_and_back = r.points.clone();
            there_and_back.extend(r.points.iter().rev().skip(1));
            there_and_back
        })
        .collect();
    if people.attractors.len() >= 2 {
        let mut tour: Vec<[f64; 2]> = people.attractors.iter().map(|a| a.position).collect();
        tour.push(people.attractors[0].position);
        tracks.push(tour);
    }
    let expected = people.expected_at(None);
    if tracks.is_empty() && expected >= 0.5 {
        // No known way to walk: rounds between the wanderers' points, as many as people.
        if let Ok(world) = crate::World::build(spec.clone()) {
            let targets = world.people_targets();
            #[allow(
                clippy::cast_possible_truncation,
                clippy::cast_sign_loss,
                reason = "a rounded count, capped"
            )]
            let count = (expected.round() as usize).min(crate::crowd::MAX_PEOPLE);
            tracks = (0..count)
                .map(|k| {
                    targets
                        .wander_round(&world, k * WANDER_STOPS, WANDER_STOPS, 1.0)
                        .into_iter()
                        .map(|(x, y)| [x, y])
                        .collect::<Vec<_>>()
                })
                .filter(|t| t.len() >= 2)
                .collect();
        }
    }
    if tracks.is_empty() {
        return String::new();
    }
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a rounded count, capped"
    )]
    let count = (expected.round().max(0.0) as usize).clamp(tracks.len(), crate::crowd::MAX_PEOPLE);
    let dwell = |p: [f64; 2]| {
        people
            .attractors
            .iter()
            .find(|a| a.position == p)
            .map_or(0.0, |a| a.dwell_s.max(0.0))
    };
    let mut s = String::from(
        "    <!-- People the knowledge expects, walking its routes and attractors (else about the floor). -->\n",
    );
    for k in 0..count {
        let track = &tracks[k % tracks.len()];
        // Later walkers of one track start further along it.
        let shift = (k / tracks.len()) % (track.len() - 1);
        let points: Vec<[f64; 2]> = track[shift..]
            .iter()
            .chain(track[1..=shift].iter())
            .copied()
            .collect();
        let _ = writeln!(
            s,
            r#"    <actor name="person_{k}">
      <skin><filename>{ACTOR_MESH}</filename><scale>1.0</scale></skin>
      <animation name="walking"><filename>{ACTOR_MESH}</filename><scale>1.000000</scale><interpolate_x>true</interpolate_x></animation>
      <script>
        <loop>true</loop>
        <delay_start>0</delay_start>
        <auto_start>true</auto_start>
        <trajectory id="{k}" type="walking">"#
        );
        let mut t = 0.0;
        for (i, p) in points.iter().enumerate() {
            let next = points.get(i + 1).or(points.get(i.saturating_sub(1)));
            let yaw = next.map_or(0.0, |q| (q[1] - p[1]).atan2(q[0] - p[0]));
            let _ = writeln!(
                s,
                "          <waypoint><time>{t:.3}</time><pose>{:.4} {:.4} 0 0 0 {yaw:.4}</pose></waypoint>",
                p[0], p[1]
            );
            let linger = dwell(*p);
            if linger > 0.0 {
                t += linger;
                let _ = writeln!(
                    s,
                    "          <waypoint><time>{t:.3}</time><pose>{:.4} {:.4} 0 0 0 {yaw:.4}</pose></waypoint>",
                    p[0], p[1]
                );
            }
            if let Some(q) = points.get(i + 1) {
                t += ((q[0] - p[0]).hypot(q[1] - p[1]) / ACTOR_SPEED).max(0.1);
            }
        }
        s.push_str("        </trajectory>\n      </script>\n    </actor>\n");
    }
    s
}

/// A URDF `<geometry>`: URDF cylinders stand along z like ours.
fn urdf_geometry(shape: Shape, size: Size3) -> String {
    match shape {
        Shape::Box => format!(r#"<box size="{} {} {}"/>"#, size.x, size.y, size.z),
        Shape::Cylinder => format!(
            r#"<cylinder radius="{}" length="{}"/>"#,
            size.x.max(size.y) / 2.0,
            size.z
        ),
        Shape::Sphere => format!(
            r#"<sphere radius="{}"/>"#,
            size.x.max(size.y).max(size.z) / 2.0
        ),
    }
}

/// The inertia tensor's diagonal of a solid primitive about its centre.
fn inertia(shape: Shape, size: Size3, mass: f64) -> [f64; 3] {
    match shape {
        Shape::Box => [
            mass / 12.0 * (size.y * size.y + size.z * size.z),
            mass / 12.0 * (size.x * size.x + size.z * size.z),
            mass / 12.0 * (size.x * size.x + size.y * size.y),
        ],
        Shape::Cylinder => {
            let r = size.x.max(size.y) / 2.0;
            let side = mass / 12.0 * (3.0 * r * r + size.z * size.z);
            [side, side, mass * r * r / 2.0]
        }
        Shape::Sphere => {
            let r = size.x.max(size.y).max(size.z) / 2.0;
            let i = 0.4 * mass * r * r;
            [i; 3]
        }
    }
}

fn urdf_origin(p: &Pose3) -> String {
    format!(
        r#"<origin xyz="{} {} {}" rpy="{} {} {}"/>"#,
        p.x, p.y, p.z, p.roll, p.pitch, p.yaw
    )
}

fn urdf_link(
    s: &mut String,
    name: &str,
    shape: Shape,
    size: Size3,
    colour: Colour,
    mass: Option<f64>,
    visual_rpy: &str,
) {
    let [r, g, b] = colour.to_unit();
    let geom = urdf_geometry(shape, size);
    let _ = writeln!(s, r#"  <link name="{name}">"#);
    let _ = writeln!(
        s,
        r#"    <visual><origin xyz="0 0 0" rpy="{visual_rpy}"/><geometry>{geom}</geometry><material name="{name}_colour"><color rgba="{r:.4} {g:.4} {b:.4} 1"/></material></visual>"#
    );
    let _ = writeln!(
        s,
        r#"    <collision><origin xyz="0 0 0" rpy="{visual_rpy}"/><geometry>{geom}</geometry></collision>"#
    );
    if let Some(m) = mass.filter(|m| *m > 0.0 && m.is_finite()) {
        let [ixx, iyy, izz] = inertia(shape, size, m);
        // A wheel's cylinder is turned to lie along y: swap the axes it spins about.
        let (ixx, iyy, izz) = if visual_rpy == "0 0 0" {
            (ixx, iyy, izz)
        } else {
            (ixx, izz, iyy)
        };
        let _ = writeln!(
            s,
            r#"    <inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="{m}"/><inertia ixx="{ixx:.6e}" ixy="0" ixz="0" iyy="{iyy:.6e}" iyz="0" izz="{izz:.6e}"/></inertial>"#
        );
    }
    let _ = writeln!(s, "  </link>");
}

/// A wheel's cylinder (standing along z) turned to lie along its axle, y.
const WHEEL_RPY: &str = "1.5707963267948966 0 0";

/// The mass of a wheel the model gives none for: Gazebo needs one.
const WHEEL_MASS_KG: f64 = 0.5;

/// A link that only carries a frame (`base_footprint`, `base_link`, a sensor without a shape, an
/// optical frame) still needs an inertial in SDF, where a missing one means 1 kg and 1 kg·m²:
/// a gram, negligible beside the robot.
const FRAME_INERTIAL: &str = "<inertial><mass>0.001</mass><inertia><ixx>1e-6</ixx><ixy>0</ixy><ixz>0</ixz><iyy>1e-6</iyy><iyz>0</iyz><izz>1e-6</izz></inertia></inertial>";

/// How often the laser scans, Hz: the spec gives no rate; the bundled robot's is 10 Hz.
const LASER_RATE_HZ: f64 = 10.0;

/// How often the drive publishes odometry, Hz (gz-sim's default).
const ODOM_RATE_HZ: f64 = 50.0;

/// What a link of the robot is.
enum Body<'a> {
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
struct RobotLink<'a> {
    name: String,
    joint: String,
    parent: String,
    body: Body<'a>,
}

/// A camera's links: its body (or bare frame) and its optical frame.
struct CameraLinks<'a> {
    spec: &'a CameraSpec,
    link: String,
    optical: String,
}

/// The robot's links and joints, named once so that the URDF, the SDF model and the bridge
/// configuration agree: REP-105's `base_footprint` → `base_link` → parts, wheels and sensors,
/// the sensors named after their individuals in the knowledge graph (the local name of the
/// IRI), and named before any other part so that they keep that name.
struct RobotLayout<'a> {
    /// The robot's (and the Gazebo model's) name.
    name: String,
    /// Height of `base_link` (the drive axle) above `base_footprint`.
    axle: f64,
    /// The fixed joint from `base_footprint` to `base_link`.
    base_joint: String,
    links: Vec<RobotLink<'a>>,
    /// The laser's link, named after the robot's laser.
    laser: String,
    cameras: Vec<CameraLinks<'a>>,
    /// The left and right drive joints, when the robot has exactly two active wheels.
    drive: Option<[String; 2]>,
    /// Every wheel's joint: the joints that move.
    wheel_joints: Vec<String>,
}

impl<'a> RobotLayout<'a> {
    fn new(robot: &'a RobotSpec) -> Self {
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
    fn origin(&self, link: &RobotLink<'_>) -> Pose3 {
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
/// so that robots sharing a world do not mix; [`ros_gz_bridge_yaml`] bridges the same ones.
struct GzTopics {
    /// DiffDrive subscribes to `gz.msgs.Twist` here.
    cmd_vel: String,
    /// DiffDrive publishes `gz.msgs.Odometry` here.
    odometry: String,
    /// DiffDrive publishes the `odom` → `base_footprint` transform (`gz.msgs.Pose_V`) here.
    tf: String,
    /// JointStatePublisher publishes the wheels' `gz.msgs.Model` here.
    joint_states: String,
    /// The gpu_lidar publishes `gz.msgs.LaserScan` here.
    scan: String,
}

impl GzTopics {
    fn new(layout: &RobotLayout<'_>) -> Self {
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
    fn camera(layout: &RobotLayout<'_>, camera: &CameraLinks<'_>) -> String {
        format!("/model/{}/{}", layout.name, camera.link)
    }
}

/// The laser as a gz-sim `gpu_lidar` sensor: the spec's samples over its field of view, at the
/// angles [`crate::LaserSpec::sample_angle`] gives them (as ROS `LaserScan` numbers them),
/// published with the laser's link as frame.
fn gz_laser_sensor(robot: &RobotSpec, layout: &RobotLayout<'_>, topics: &GzTopics) -> String {
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
fn gz_camera_sensor(layout: &RobotLayout<'_>, camera: &CameraLinks<'_>) -> String {
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
fn gz_model_plugins(robot: &RobotSpec, layout: &RobotLayout<'_>, topics: &GzTopics) -> String {
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
        for (kind, limit) in [
            ("linear_velocity", d.max_linear_speed),
            ("angular_velocity", d.max_angular_speed),
            ("linear_acceleration", d.max_linear_acceleration),
            ("angular_acceleration", d.max_angular_acceleration),
        ] {
            if let Some(v) = limit.filter(|v| v.is_finite() && *v > 0.0) {
                let _ = writeln!(s, "  <max_{kind}>{v}</max_{kind}>");
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

/// `text` with every line indented by `prefix`, ending with a newline.
fn indented(text: &str, prefix: &str) -> String {
    let mut s = String::new();
    for line in text.lines() {
        let _ = writeln!(s, "{prefix}{line}");
    }
    s
}

/// The robot as a URDF document, framed as REP-105 asks: a `base_footprint` root link on the
/// floor under the drive axle's midpoint, `base_link` above it at the axle's height on a fixed
/// joint, and on `base_link` each structural part and sensor a link on a fixed joint at its
/// mounting pose (the laser's and cameras' links named after the robot's sensors in the
/// knowledge graph, a camera's `<camera>_optical_frame` on its link), each wheel a link on a
/// continuous joint about its axle. Its `<gazebo>` extensions target gz-sim (Harmonic): the
/// laser a `gpu_lidar` sensor, cameras `camera` or `rgbd_camera` sensors, the passive wheels
/// frictionless, and the DiffDrive and JointStatePublisher systems, on the topics
/// [`ros_gz_bridge_yaml`] bridges. The world must run the sensors system ([`world_sdf`] does).
pub fn robot_urdf(robot: &RobotSpec) -> String {
    let layout = RobotLayout::new(robot);
    let topics = GzTopics::new(&layout);
    let mut s = String::new();
    let _ = writeln!(s, r#"<?xml version="1.0"?>"#);
    let _ = writeln!(s, r#"<robot name="{}">"#, xml(&layout.name));
    let _ = writeln!(
        s,
        "  <!-- Generated by Mentalsim's simulation parser from {} -->",
        xml(&robot.id).replace("--", "- -")
    );
    let _ = writeln!(s, r#"  <link name="base_footprint"/>"#);
    let _ = writeln!(s, r#"  <link name="base_link"/>"#);
    let _ = writeln!(
        s,
        r#"  <joint name="{}" type="fixed"><parent link="base_footprint"/><child link="base_link"/><origin xyz="0 0 {}" rpy="0 0 0"/></joint>"#,
        layout.base_joint, layout.axle
    );
    for link in &layout.links {
        let name = &link.name;
        let kind = match link.body {
            Body::Part(p) => {
                urdf_link(&mut s, name, p.shape, p.size, p.colour, p.mass, "0 0 0");
                "fixed"
            }
            Body::Wheel(w) => {
                let size = Size3::new(2.0 * w.radius, 2.0 * w.radius, w.width);
                let colour = Colour::rgb(25, 25, 25);
                let mass = Some(WHEEL_MASS_KG);
                urdf_link(&mut s, name, Shape::Cylinder, size, colour, mass, WHEEL_RPY);
                "continuous"
            }
            Body::Frame(_) | Body::Optical => {
                let _ = writeln!(s, r#"  <link name="{name}"/>"#);
                "fixed"
            }
        };
        let axis = if kind == "continuous" {
            r#"<axis xyz="0 1 0"/>"#
        } else {
            ""
        };
        let _ = writeln!(
            s,
            r#"  <joint name="{}" type="{kind}"><parent link="{}"/><child link="{name}"/>{}{axis}</joint>"#,
            link.joint,
            link.parent,
            urdf_origin(&layout.origin(link))
        );
    }
    let _ = writeln!(s, r#"  <gazebo reference="{}">"#, layout.laser);
    s.push_str(&indented(&gz_laser_sensor(robot, &layout, &topics), "    "));
    let _ = writeln!(s, "  </gazebo>");
    for camera in &layout.cameras {
        let _ = writeln!(s, r#"  <gazebo reference="{}">"#, camera.link);
        s.push_str(&indented(&gz_camera_sensor(&layout, camera), "    "));
        let _ = writeln!(s, "  </gazebo>");
    }
    for link in &layout.links {
        if matches!(link.body, Body::Wheel(w) if !w.active) {
            // A caster turns about its axle only: it slides where it would have to swivel.
            let _ = writeln!(
                s,
                r#"  <gazebo reference="{}"><mu1>0</mu1><mu2>0</mu2></gazebo>"#,
                link.name
            );
        }
    }
    let _ = writeln!(s, "  <gazebo>");
    s.push_str(&indented(
        &gz_model_plugins(robot, &layout, &topics),
        "    ",
    ));
    let _ = writeln!(s, "  </gazebo>");
    s.push_str("</robot>\n");
    s
}

fn sdf_inertial(shape: Shape, size: Size3, mass: f64, lying: bool) -> String {
    let [ixx, iyy, izz] = inertia(shape, size, mass);
    // A wheel's cylinder lies along y: it spins about y.
    let (iyy, izz) = if lying { (izz, iyy) } else { (iyy, izz) };
    format!(
        "<inertial><mass>{mass}</mass><inertia><ixx>{ixx:.6e}</ixx><ixy>0</ixy><ixz>0</ixz><iyy>{iyy:.6e}</iyy><iyz>0</iyz><izz>{izz:.6e}</izz></inertia></inertial>"
    )
}

/// The robot's `<model>` element (not indented), at `at` when placed in a world.
fn robot_model(robot: &RobotSpec, layout: &RobotLayout<'_>, at: Option<Pose2>) -> String {
    let topics = GzTopics::new(layout);
    let mut s = String::new();
    let _ = writeln!(s, r#"<model name="{}">"#, xml(&layout.name));
    let _ = writeln!(
        s,
        "  <!-- Generated by Mentalsim's simulation parser from {} -->",
        xml(&robot.id).replace("--", "- -")
    );
    if let Some(p) = at {
        let _ = writeln!(s, "  <pose>{} {} 0 0 0 {}</pose>", p.x, p.y, p.yaw);
    }
    let _ = writeln!(
        s,
        r#"  <link name="base_footprint">{FRAME_INERTIAL}</link>
  <link name="base_link"><pose relative_to="base_footprint">0 0 {} 0 0 0</pose>{FRAME_INERTIAL}</link>
  <joint name="{}" type="fixed"><parent>base_footprint</parent><child>base_link</child></joint>"#,
        layout.axle, layout.base_joint
    );
    for link in &layout.links {
        let name = &link.name;
        let _ = writeln!(s, r#"  <link name="{name}">"#);
        let _ = writeln!(
            s,
            r#"    <pose relative_to="{}">{}</pose>"#,
            link.parent,
            pose6(&layout.origin(link))
        );
        match link.body {
            Body::Part(p) => {
                let inertial = p.mass.filter(|m| *m > 0.0 && m.is_finite()).map_or_else(
                    || FRAME_INERTIAL.to_owned(),
                    |m| sdf_inertial(p.shape, p.size, m, false),
                );
                let geom = sdf_geometry(p.shape, p.size);
                let _ = writeln!(s, "    {inertial}");
                let _ = writeln!(
                    s,
                    r#"    <collision name="collision"><geometry>{geom}</geometry></collision>"#
                );
                let _ = writeln!(
                    s,
                    r#"    <visual name="visual"><geometry>{geom}</geometry>{}</visual>"#,
                    sdf_material(p.colour)
                );
            }
            Body::Wheel(w) => {
                let size = Size3::new(2.0 * w.radius, 2.0 * w.radius, w.width);
                let geom = sdf_geometry(Shape::Cylinder, size);
                let _ = writeln!(
                    s,
                    "    {}",
                    sdf_inertial(Shape::Cylinder, size, WHEEL_MASS_KG, true)
                );
                // A caster turns about its axle only: it slides where it would have to swivel.
                let surface = if w.active {
                    ""
                } else {
                    "<surface><friction><ode><mu>0</mu><mu2>0</mu2></ode></friction></surface>"
                };
                let _ = writeln!(
                    s,
                    r#"    <collision name="collision"><pose>0 0 0 {WHEEL_RPY}</pose><geometry>{geom}</geometry>{surface}</collision>"#
                );
                let _ = writeln!(
                    s,
                    r#"    <visual name="visual"><pose>0 0 0 {WHEEL_RPY}</pose><geometry>{geom}</geometry>{}</visual>"#,
                    sdf_material(Colour::rgb(25, 25, 25))
                );
            }
            Body::Frame(_) | Body::Optical => {
                let _ = writeln!(s, "    {FRAME_INERTIAL}");
            }
        }
        if *name == layout.laser {
            s.push_str(&indented(&gz_laser_sensor(robot, layout, &topics), "    "));
        }
        for camera in layout.cameras.iter().filter(|c| c.link == *name) {
            s.push_str(&indented(&gz_camera_sensor(layout, camera), "    "));
        }
        let _ = writeln!(s, "  </link>");
        if matches!(link.body, Body::Wheel(_)) {
            // dartsim builds no `continuous` joint (it falls back to fixed): an unlimited
            // revolute joint, as gz-sim's diff_drive example has it.
            let _ = writeln!(
                s,
                r#"  <joint name="{}" type="revolute"><parent>{}</parent><child>{name}</child><axis><xyz>0 1 0</xyz><limit><lower>-1.79769e+308</lower><upper>1.79769e+308</upper></limit></axis></joint>"#,
                link.joint, link.parent
            );
        } else {
            let _ = writeln!(
                s,
                r#"  <joint name="{}" type="fixed"><parent>{}</parent><child>{name}</child></joint>"#,
                link.joint, link.parent
            );
        }
    }
    s.push_str(&indented(&gz_model_plugins(robot, layout, &topics), "  "));
    s.push_str("</model>\n");
    s
}

/// The robot as an SDF 1.9 model for gz-sim (`ros_gz_sim create -file robot.sdf`, or placed in
/// a world by [`world_sdf_with_robot`]): the links and joints of [`robot_urdf`] (the model
/// frame is `base_footprint`'s, each link posed on its parent as the URDF's joint origins
/// place it; wheels on unlimited revolute joints, as gz-sim's physics has no continuous
/// joint; frame-only links weigh a gram), the laser a `gpu_lidar` sensor, cameras `camera` or
/// `rgbd_camera` sensors, and the DiffDrive and JointStatePublisher systems on the topics
/// [`ros_gz_bridge_yaml`] bridges.
pub fn robot_sdf(robot: &RobotSpec) -> String {
    let layout = RobotLayout::new(robot);
    let mut s = String::new();
    let _ = writeln!(s, r#"<?xml version="1.0" ?>"#);
    let _ = writeln!(s, r#"<sdf version="1.9">"#);
    s.push_str(&indented(&robot_model(robot, &layout, None), "  "));
    s.push_str("</sdf>\n");
    s
}

/// A YAML double-quoted scalar.
fn yaml_str(text: &str) -> String {
    let mut s = String::from("\"");
    for c in text.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            c if c.is_control() => {
                let _ = write!(s, "\\u{:04x}", u32::from(c));
            }
            c => s.push(c),
        }
    }
    s.push('"');
    s
}

/// A ROS topic name segment from a link name (ROS names take no `-`).
fn ros_segment(name: &str) -> String {
    name.replace('-', "_")
}

/// The `ros_gz_bridge` configuration (`parameter_bridge --ros-args -p config_file:=...`) for the
/// robot of [`robot_sdf`] or [`robot_urdf`] in gz-sim: `/cmd_vel` to the drive, `/odom`,
/// `/scan`, `/tf` (the drive's `odom` → `base_footprint`; `robot_state_publisher` with the
/// URDF publishes the rest from `/joint_states`), `/joint_states` and `/clock` from Gazebo, and
/// each camera's `image` and `camera_info` (an RGB-D camera's also `depth_image` and `points`)
/// under `/<camera>/`. The clock is the world's, `/world/<world_name>/clock` (the name
/// [`world_name`] gives), or without a world name gz-sim's global `/clock`.
pub fn ros_gz_bridge_yaml(robot: &RobotSpec, world_name: Option<&str>) -> String {
    const GZ_TO_ROS: &str = "GZ_TO_ROS";
    let layout = RobotLayout::new(robot);
    let topics = GzTopics::new(&layout);
    let clock = world_name.map_or_else(|| "/clock".to_owned(), |w| format!("/world/{w}/clock"));
    let mut entries: Vec<(String, String, &str, &str, &str)> = vec![
        (
            "/cmd_vel".into(),
            topics.cmd_vel.clone(),
            "geometry_msgs/msg/Twist",
            "gz.msgs.Twist",
            "ROS_TO_GZ",
        ),
        (
            "/odom".into(),
            topics.odometry.clone(),
            "nav_msgs/msg/Odometry",
            "gz.msgs.Odometry",
            GZ_TO_ROS,
        ),
        (
            "/scan".into(),
            topics.scan.clone(),
            "sensor_msgs/msg/LaserScan",
            "gz.msgs.LaserScan",
            GZ_TO_ROS,
        ),
        (
            "/tf".into(),
            topics.tf.clone(),
            "tf2_msgs/msg/TFMessage",
            "gz.msgs.Pose_V",
            GZ_TO_ROS,
        ),
        (
            "/joint_states".into(),
            topics.joint_states.clone(),
            "sensor_msgs/msg/JointState",
            "gz.msgs.Model",
            GZ_TO_ROS,
        ),
        (
            "/clock".into(),
            clock,
            "rosgraph_msgs/msg/Clock",
            "gz.msgs.Clock",
            GZ_TO_ROS,
        ),
    ];
    for camera in &layout.cameras {
        let gz = GzTopics::camera(&layout, camera);
        let ros = format!("/{}", ros_segment(&camera.link));
        let mut streams = vec![
            ("image", "sensor_msgs/msg/Image", "gz.msgs.Image"),
            (
                "camera_info",
                "sensor_msgs/msg/CameraInfo",
                "gz.msgs.CameraInfo",
            ),
        ];
        if camera.spec.depth_range.is_some() {
            streams.push(("depth_image", "sensor_msgs/msg/Image", "gz.msgs.Image"));
            streams.push((
                "points",
                "sensor_msgs/msg/PointCloud2",
                "gz.msgs.PointCloudPacked",
            ));
        }
        for (leaf, ros_type, gz_type) in streams {
            entries.push((
                format!("{ros}/{leaf}"),
                format!("{gz}/{leaf}"),
                ros_type,
                gz_type,
                GZ_TO_ROS,
            ));
        }
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# ros_gz_bridge configuration for {} in gz-sim, generated by Mentalsim.",
        robot.id.replace(['\n', '\r'], " ")
    );
    let _ = writeln!(
        s,
        "# ros2 run ros_gz_bridge parameter_bridge --ros-args -p config_file:=bridge.yaml"
    );
    for (ros, gz, ros_type, gz_type, direction) in entries {
        let _ = writeln!(s, "- ros_topic_name: {}", yaml_str(&ros));
        let _ = writeln!(s, "  gz_topic_name: {}", yaml_str(&gz));
        let _ = writeln!(s, "  ros_type_name: {}", yaml_str(ros_type));
        let _ = writeln!(s, "  gz_type_name: {}", yaml_str(gz_type));
        let _ = writeln!(s, "  direction: {direction}");
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
