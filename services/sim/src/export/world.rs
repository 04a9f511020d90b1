//! The world as SDF 1.9 for gz-sim: walls from the metric map merged into boxes, objects as
//! primitives or models of their parts, the systems a robot needs, the robot when placed.

use std::collections::HashSet;
use std::fmt::Write as _;

use crate::library::{self, Model};
use crate::spec::{FloorMap, ObjectSpec, Occupancy, Pose2, Pose3, WallSpec, WorldSpec};

use super::actors::people_actors;
use super::layout::RobotLayout;
use super::sdf::robot_model;
use super::{pose6, sdf_geometry, sdf_material, unique_name, xml};

/// Axis-aligned rectangles `[col, row, width, height]` (cells) covering the grid's solid cells
/// (occupied and unknown): runs along each row merged with identical runs of the next row.
pub(super) fn solid_rectangles(grid: &crate::spec::OccupancyGrid) -> Vec<[usize; 4]> {
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
pub(super) const WORLD_SYSTEMS: &str = r#"    <plugin filename="gz-sim-physics-system" name="gz::sim::systems::Physics"/>
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
/// with ogre2), so [`robot_sdf`](super::robot_sdf) or [`robot_urdf`](super::robot_urdf) can be spawned into it. No robot is in it:
/// [`world_sdf_with_robot`] places one.
pub fn world_sdf(spec: &WorldSpec) -> String {
    world_document(spec, None)
}

/// [`world_sdf`] with the robot of `spec` in it as the model [`robot_sdf`](super::robot_sdf) describes, its
/// `base_footprint` at `start` on the floor.
pub fn world_sdf_with_robot(spec: &WorldSpec, start: Pose2) -> String {
    world_document(spec, Some(start))
}

pub(super) fn world_document(spec: &WorldSpec, robot_at: Option<Pose2>) -> String {
    let mut s = String::new();
    let mut names = HashSet::new();
    write_preamble(&mut s, spec);
    names.insert("ground_plane".to_owned());
    // The robot keeps its name (its topics are named after it): objects give way.
    let robot = robot_at.map(|start| (RobotLayout::new(&spec.robot), start));
    if let Some((layout, _)) = &robot {
        names.insert(layout.name.clone());
    }
    if let Some(floor) = &spec.floor {
        write_map_walls(&mut s, floor, &mut names);
    }
    if !spec.walls.is_empty() {
        write_boundary_walls(&mut s, &spec.walls, &mut names);
    }
    for o in &spec.objects {
        write_object(&mut s, o, &mut names);
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

/// The document's opening up to the world's contents: the world, its systems, the sun and the
/// ground plane.
fn write_preamble(s: &mut String, spec: &WorldSpec) {
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
}

/// The metric map's solid cells as one static model of wall boxes (merged into rectangles).
fn write_map_walls(s: &mut String, floor: &FloorMap, names: &mut HashSet<String>) {
    let g = &floor.grid;
    let name = unique_name(&format!("{}_walls", floor.id), names);
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

/// The boundary walls as one static model of boxes.
fn write_boundary_walls(s: &mut String, walls: &[WallSpec], names: &mut HashSet<String>) {
    let name = unique_name("boundary_walls", names);
    let _ = writeln!(s, r#"    <model name="{}">"#, xml(&name));
    let _ = writeln!(s, "      <static>true</static>\n      <link name=\"link\">");
    for (k, w) in walls.iter().enumerate() {
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

/// An object as a static model: a library model's parts, or a placeholder's one primitive.
fn write_object(s: &mut String, o: &ObjectSpec, names: &mut HashSet<String>) {
    let name = unique_name(&o.id, names);
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
