//! Checks of a world description: every problem named by item and field, never a panic.

use super::{
    FloorMap, MAX_CONTROL_LATENCY_S, MAX_GRID_CELLS, ObjectSpec, Occupancy, PeopleSpec, Pose3,
    RobotSpec, Shape, Size3, SpecProblem, SpecProblems, WorldSpec,
};

/// Collects problems for one item, so each check is one line.
struct Checker<'a> {
    out: &'a mut SpecProblems,
    item: &'a str,
}

impl Checker<'_> {
    fn positive(&mut self, field: &str, value: f64, what: &str) {
        if !(value.is_finite() && value > 0.0) {
            self.out.push(SpecProblem::error(
                self.item,
                field,
                format!("{what} must be a positive finite number, got {value}"),
            ));
        }
    }

    fn optional_positive(&mut self, field: &str, value: Option<f64>, what: &str) {
        if let Some(v) = value {
            self.positive(field, v, what);
        }
    }

    fn size(&mut self, field: &str, size: Size3) {
        self.positive(&format!("{field}.x"), size.x, "a size");
        self.positive(&format!("{field}.y"), size.y, "a size");
        self.positive(&format!("{field}.z"), size.z, "a size");
    }

    fn pose(&mut self, field: &str, pose: &Pose3) -> bool {
        if pose.is_finite() {
            return true;
        }
        self.out.push(SpecProblem::error(
            self.item,
            field,
            format!("every component of a pose must be finite, got {pose:?}"),
        ));
        false
    }

    fn non_negative(&mut self, field: &str, value: f64, what: &str) {
        if !(value.is_finite() && value >= 0.0) {
            self.out.push(SpecProblem::error(
                self.item,
                field,
                format!("{what} must be a finite number >= 0, got {value}"),
            ));
        }
    }

    /// Whether `point` is finite; an error naming `field` when not.
    fn point(&mut self, field: &str, point: [f64; 2]) -> bool {
        if point.iter().all(|v| v.is_finite()) {
            return true;
        }
        self.error(
            field,
            format!("a point's x and y must be finite, got {point:?}"),
        );
        false
    }

    fn error(&mut self, field: &str, message: String) {
        self.out.push(SpecProblem::error(self.item, field, message));
    }

    fn warning(&mut self, field: &str, message: String) {
        self.out
            .push(SpecProblem::warning(self.item, field, message));
    }
}

impl WorldSpec {
    /// Every problem with this description: errors that stop the world from being built and
    /// warnings about what the simulation changes. Never panics, whatever the values.
    pub fn validate(&self) -> SpecProblems {
        let mut out = SpecProblems(self.notes.clone());
        if let Some(floor) = &self.floor {
            validate_floor(floor, &self.robot, &mut out);
        }
        for wall in &self.walls {
            let mut c = Checker {
                out: &mut out,
                item: &wall.id,
            };
            for (field, v) in [
                ("start.x", wall.start[0]),
                ("start.y", wall.start[1]),
                ("end.x", wall.end[0]),
                ("end.y", wall.end[1]),
            ] {
                if !v.is_finite() {
                    c.error(field, format!("a wall end must be finite, got {v}"));
                }
            }
            c.positive("thickness", wall.thickness, "a wall thickness");
            c.positive("height", wall.height, "a wall height");
        }
        let mut seen = std::collections::HashSet::new();
        for obj in &self.objects {
            validate_object(obj, &mut out);
            if !seen.insert(obj.id.as_str()) {
                out.push(SpecProblem::error(
                    &obj.id,
                    "id",
                    "two objects share this identifier",
                ));
            }
        }
        validate_robot(&self.robot, &mut out);
        validate_people(&self.people, self.floor.as_ref(), &mut out);
        if self.floor.is_none() && self.walls.is_empty() {
            out.push(SpecProblem::warning(
                &self.id,
                "floor",
                "the world has no metric map and no walls: it is bounded by a box 1 m around its objects",
            ));
        }
        out
    }
}

fn validate_floor(floor: &FloorMap, robot: &RobotSpec, out: &mut SpecProblems) {
    let g = &floor.grid;
    let mut c = Checker {
        out,
        item: &floor.id,
    };
    c.positive("resolution", g.resolution, "the map resolution");
    c.positive("wall_height", floor.wall_height, "the wall height");
    for (field, v) in [
        ("origin.x", g.origin.x),
        ("origin.y", g.origin.y),
        ("origin.yaw", g.origin.yaw),
    ] {
        if !v.is_finite() {
            c.error(field, format!("the map origin must be finite, got {v}"));
        }
    }
    if g.width == 0 || g.height == 0 {
        c.error(
            "cells",
            format!("the map has no cells ({} x {})", g.width, g.height),
        );
    } else if g.width.checked_mul(g.height) != Some(g.cells.len()) {
        c.error(
            "cells",
            format!(
                "the map is {} x {} but holds {} cells",
                g.width,
                g.height,
                g.cells.len()
            ),
        );
    } else if (g.width + 2).saturating_mul(g.height + 2) > MAX_GRID_CELLS {
        c.error(
            "cells",
            format!(
                "the map has {} cells, more than the {MAX_GRID_CELLS} the simulator accepts",
                g.cells.len()
            ),
        );
    } else if !g.cells.contains(&Occupancy::Free) {
        c.error("cells", "the map has no free cell".into());
    }
    if floor.wall_height.is_finite() && floor.wall_height < robot.laser.mount.z {
        c.warning(
            "wall_height",
            format!(
                "walls of {} m are lower than the laser at {} m; the simulator still extrudes them through every height",
                floor.wall_height, robot.laser.mount.z
            ),
        );
    }
}

fn validate_object(obj: &ObjectSpec, out: &mut SpecProblems) {
    let mut c = Checker { out, item: &obj.id };
    if obj.id.trim().is_empty() {
        c.error("id", "an object needs a non-empty identifier".into());
    }
    c.size("size", obj.size);
    if c.pose("pose", &obj.pose) {
        if !obj.pose.is_upright() {
            c.warning(
                "pose",
                format!(
                    "roll {} and pitch {} are ignored: objects are simulated upright",
                    obj.pose.roll, obj.pose.pitch
                ),
            );
        }
        if obj.size.z.is_finite() && obj.pose.z - obj.size.z / 2.0 < -0.01 {
            c.warning(
                "pose.z",
                format!(
                    "the object reaches {:.3} m below the floor (pose.z is its centre)",
                    obj.size.z / 2.0 - obj.pose.z
                ),
            );
        }
    }
    match obj.shape {
        Shape::Cylinder if (obj.size.x - obj.size.y).abs() > 1e-6 => c.warning(
            "size",
            format!(
                "a cylinder needs equal x and y sizes; {} m is used as its diameter",
                obj.size.x.max(obj.size.y)
            ),
        ),
        Shape::Sphere
            if (obj.size.x - obj.size.y).abs() > 1e-6 || (obj.size.x - obj.size.z).abs() > 1e-6 =>
        {
            c.warning(
                "size",
                format!(
                    "a sphere needs equal sizes; {} m is used as its diameter",
                    obj.size.x.max(obj.size.y).max(obj.size.z)
                ),
            )
        }
        _ => {}
    }
}

/// Counts finite and >= 0, hours 0–23 and each once, boundaries of none or at least 3 finite
/// points, routes of at least 2 finite points, dwell times finite and >= 0, identifiers unique
/// per kind; points off the floor's map are warned about (people there cannot reach them).
fn validate_people(people: &PeopleSpec, floor: Option<&FloorMap>, out: &mut SpecProblems) {
    let off_map = |p: [f64; 2]| floor.is_some_and(|f| f.grid.cell_of(p[0], p[1]).is_none());
    let mut ids = std::collections::HashSet::new();
    for place in &people.places {
        let mut c = Checker {
            out,
            item: &place.id,
        };
        if place.id.trim().is_empty() {
            c.error(
                "id",
                "a place with people needs a non-empty identifier".into(),
            );
        } else if !ids.insert(place.id.as_str()) {
            c.error("id", "two people places share this identifier".into());
        }
        c.non_negative("expected", place.expected, "an expected number of people");
        let mut hours = std::collections::HashSet::new();
        for (i, &(hour, n)) in place.by_hour.iter().enumerate() {
            if hour > 23 {
                c.error(
                    &format!("by_hour[{i}].hour"),
                    format!("an hour of the day is 0 to 23, got {hour}"),
                );
            } else if !hours.insert(hour) {
                c.error(
                    &format!("by_hour[{i}].hour"),
                    format!("hour {hour} has two figures"),
                );
            }
            c.non_negative(
                &format!("by_hour[{i}].people"),
                n,
                "an expected number of people",
            );
        }
        if matches!(place.boundary.len(), 1 | 2) {
            c.error(
                "boundary",
                format!(
                    "a boundary needs at least 3 points (or none: people then spawn anywhere on the floor), got {}",
                    place.boundary.len()
                ),
            );
        }
        for (i, &p) in place.boundary.iter().enumerate() {
            c.point(&format!("boundary[{i}]"), p);
        }
    }
    let mut ids = std::collections::HashSet::new();
    for route in &people.routes {
        let mut c = Checker {
            out,
            item: &route.id,
        };
        if route.id.trim().is_empty() {
            c.error("id", "a walking route needs a non-empty identifier".into());
        } else if !ids.insert(route.id.as_str()) {
            c.error("id", "two walking routes share this identifier".into());
        }
        if route.points.len() < 2 {
            c.error(
                "points",
                format!(
                    "a walking route needs at least 2 points, got {}",
                    route.points.len()
                ),
            );
        }
        for (i, &p) in route.points.iter().enumerate() {
            let field = format!("points[{i}]");
            if c.point(&field, p) && off_map(p) {
                c.warning(
                    &field,
                    format!("the point {p:?} lies off the floor's map: people cannot walk there"),
                );
            }
        }
    }
    let mut ids = std::collections::HashSet::new();
    for attractor in &people.attractors {
        let mut c = Checker {
            out,
            item: &attractor.id,
        };
        if attractor.id.trim().is_empty() {
            c.error("id", "an attractor needs a non-empty identifier".into());
        } else if !ids.insert(attractor.id.as_str()) {
            c.error("id", "two attractors share this identifier".into());
        }
        if c.point("position", attractor.position) && off_map(attractor.position) {
            c.warning(
                "position",
                format!(
                    "the attractor at {:?} lies off the floor's map: people cannot reach it",
                    attractor.position
                ),
            );
        }
        c.non_negative("dwell_s", attractor.dwell_s, "a dwell time");
    }
}

fn validate_robot(robot: &RobotSpec, out: &mut SpecProblems) {
    let mut c = Checker {
        out,
        item: &robot.id,
    };
    c.positive(
        "footprint_radius",
        robot.footprint_radius,
        "the footprint radius",
    );
    c.positive("height", robot.height, "the robot height");
    let d = &robot.drive;
    c.positive(
        "drive.wheel_separation",
        d.wheel_separation,
        "the wheel separation",
    );
    c.positive("drive.wheel_radius", d.wheel_radius, "the wheel radius");
    c.optional_positive(
        "drive.max_wheel_speed",
        d.max_wheel_speed,
        "the wheel speed limit",
    );
    c.optional_positive(
        "drive.max_linear_speed",
        d.max_linear_speed,
        "the linear speed limit",
    );
    c.optional_positive(
        "drive.max_angular_speed",
        d.max_angular_speed,
        "the angular speed limit",
    );
    c.optional_positive(
        "drive.max_linear_acceleration",
        d.max_linear_acceleration,
        "the linear acceleration limit",
    );
    c.optional_positive(
        "drive.max_angular_acceleration",
        d.max_angular_acceleration,
        "the angular acceleration limit",
    );
    c.optional_positive(
        "drive.max_linear_deceleration",
        d.max_linear_deceleration,
        "the linear deceleration limit",
    );
    c.optional_positive(
        "drive.max_angular_deceleration",
        d.max_angular_deceleration,
        "the angular deceleration limit",
    );
    if let Some(l) = d.control_latency
        && !(l.is_finite() && (0.0..=MAX_CONTROL_LATENCY_S).contains(&l))
    {
        c.error(
            "drive.control_latency",
            format!("the control latency must be between 0 and {MAX_CONTROL_LATENCY_S} s, got {l}"),
        );
    }
    let l = &robot.laser;
    let mut c = Checker { out, item: &l.id };
    if !(l.range_min.is_finite() && l.range_min >= 0.0) {
        c.error(
            "range_min",
            format!(
                "the shortest range must be finite and not negative, got {}",
                l.range_min
            ),
        );
    }
    c.positive("range_max", l.range_max, "the longest range");
    if l.range_max.is_finite() && l.range_min.is_finite() && l.range_max <= l.range_min {
        c.error(
            "range_max",
            format!(
                "the longest range {} m must exceed the shortest {} m",
                l.range_max, l.range_min
            ),
        );
    }
    if !(l.fov.is_finite() && l.fov > 0.0 && l.fov <= std::f64::consts::TAU + 1e-9) {
        c.error(
            "fov",
            format!(
                "the field of view must be in (0, 2π] radians, got {}",
                l.fov
            ),
        );
    }
    if l.samples == 0 {
        c.error("samples", "a laser needs at least one sample".into());
    }
    if c.pose("mount", &l.mount) {
        if !l.mount.is_upright() {
            c.warning(
                "mount",
                "the laser is tilted; the simulator casts its rays horizontally".into(),
            );
        }
        if l.mount.z <= 0.0 {
            c.error(
                "mount.z",
                format!("the laser must be above the floor, got z = {} m", l.mount.z),
            );
        } else if robot.height.is_finite() && l.mount.z > robot.height + 1e-9 {
            c.warning(
                "mount.z",
                format!(
                    "the laser at {} m is above the robot's height {} m",
                    l.mount.z, robot.height
                ),
            );
        }
    }
    for cam in &robot.cameras {
        let mut c = Checker { out, item: &cam.id };
        if cam.width == 0 || cam.height == 0 {
            c.error(
                "resolution",
                format!(
                    "a camera image of {} x {} pixels is empty",
                    cam.width, cam.height
                ),
            );
        }
        c.positive("fps", cam.fps, "the frame rate");
        if !(cam.hfov.is_finite() && cam.hfov > 0.0 && cam.hfov < std::f64::consts::PI) {
            c.error(
                "hfov",
                format!(
                    "the horizontal field of view must be in (0, π) radians, got {}",
                    cam.hfov
                ),
            );
        }
        if let Some((near, far)) = cam.depth_range
            && !(near.is_finite() && far.is_finite() && near >= 0.0 && far > near)
        {
            c.error(
                "depth_range",
                format!("the depth range must satisfy 0 <= near < far, got {near} to {far}"),
            );
        }
        c.pose("mount", &cam.mount);
    }
    for part in &robot.parts {
        let mut c = Checker {
            out,
            item: &part.id,
        };
        c.size("size", part.size);
        c.pose("pose", &part.pose);
        c.optional_positive("mass", part.mass, "the mass");
    }
    for wheel in &robot.wheels {
        let mut c = Checker {
            out,
            item: &wheel.id,
        };
        c.positive("radius", wheel.radius, "the wheel radius");
        c.positive("width", wheel.width, "the wheel width");
        c.pose("pose", &wheel.pose);
    }
}
