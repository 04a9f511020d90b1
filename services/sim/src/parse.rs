//! The simulation parser (paper §3.4): an on-demand database (an RDF graph, exactly what the
//! knowledge service returns for a mission) to a [`WorldSpec`], through the typed TOSM values of
//! the `tosm` crate. Anything missing or contradictory becomes a problem naming the individual
//! and the property; nothing here panics on bad data.
//!
//! What the knowledge says about people on the chosen floor becomes [`PeopleSpec`]: the places
//! on it with an expected number of people (robots' running estimate where they have counted,
//! else the engineer's figure: [`tosm::PlacePeople::figures`]), its walking routes and its
//! attractors. People knowledge that does not read (a route with one point, a negative count)
//! is left out with a warning: the world is still built, without it.

use std::collections::HashMap;

use oxrdf::Graph;

use crate::spec::{
    AttractorSpec, CameraSpec, Colour, DiffDriveSpec, FloorMap, LaserSpec, ObjectSpec,
    PeoplePlaceSpec, PeopleSpec, RobotPartSpec, RobotSpec, RouteSpec, Shape, Size3, SpecProblem,
    SpecProblems, WallSpec, WheelSpec, WorldSpec,
};

/// Height of the walls that occupied map cells and boundaries become, metres: a storey.
pub const WALL_HEIGHT: f64 = 2.5;
/// Thickness of walls drawn along place boundaries, metres.
pub const BOUNDARY_WALL_THICKNESS: f64 = 0.1;

fn tosm_term(local: &str) -> String {
    format!("{}{local}", tosm::vocab::NS)
}

/// Reads the world of the on-demand database `graph` for the robot `robot_iri`: the one floor
/// with a metric map (or, with none, the places' boundaries), the objects inside it and the robot.
pub fn parse_on_demand(graph: &Graph, robot_iri: &str) -> Result<WorldSpec, SpecProblems> {
    parse(graph, robot_iri, None)
}

/// As [`parse_on_demand`], for the floor `floor_iri` of a graph that holds several.
pub fn parse_floor(
    graph: &Graph,
    robot_iri: &str,
    floor_iri: &str,
) -> Result<WorldSpec, SpecProblems> {
    parse(graph, robot_iri, Some(floor_iri))
}

/// The robot `robot_iri` of a graph as the simulator and the URDF export need it.
pub fn parse_robot(graph: &Graph, robot_iri: &str) -> Result<RobotSpec, SpecProblems> {
    let mut out = SpecProblems::default();
    let robot = match tosm::read_robot(graph, robot_iri) {
        Ok(r) => robot_spec(&r, &mut out),
        Err(p) => {
            from_tosm(p, &mut out);
            None
        }
    };
    match robot {
        Some(robot) if !out.has_errors() => Ok(robot),
        _ => Err(out),
    }
}

fn from_tosm(problems: tosm::Problems, out: &mut SpecProblems) {
    for p in problems.0 {
        out.push(SpecProblem::error(p.individual, p.property, p.message));
    }
}

fn parse(
    graph: &Graph,
    robot_iri: &str,
    floor_iri: Option<&str>,
) -> Result<WorldSpec, SpecProblems> {
    let mut out = SpecProblems::default();
    let robot = match tosm::read_robot(graph, robot_iri) {
        Ok(r) => robot_spec(&r, &mut out),
        Err(p) => {
            from_tosm(p, &mut out);
            None
        }
    };
    let (places, place_problems) = tosm::read_places_lenient(graph);
    from_tosm(place_problems, &mut out);
    let (objects, object_problems) = tosm::read_objects_lenient(graph);
    from_tosm(object_problems, &mut out);
    let (people_knowledge, people_problems) = tosm::read_people_lenient(graph);

    let floor = choose_floor(&places, floor_iri, &mut out);
    let mut spec_floor = None;
    let mut walls = Vec::new();
    let mut notes = Vec::new();
    let mut world_objects = Vec::new();
    let mut people = PeopleSpec::default();
    for p in people_problems.0 {
        notes.push(SpecProblem::warning(
            p.individual,
            p.property,
            format!(
                "{}; this people knowledge is left out of the simulation",
                p.message
            ),
        ));
    }
    if let Some(floor) = floor {
        let parents: HashMap<&str, Option<&str>> = places
            .iter()
            .map(|p| (p.iri.as_str(), p.parent.as_deref()))
            .collect();
        let on_floor = |iri: &str| reaches(iri, &floor.iri, &parents);
        if let Some(map) = &floor.map {
            spec_floor = Some(FloorMap {
                id: floor.iri.clone(),
                grid: map.grid.clone(),
                wall_height: WALL_HEIGHT,
                frame_id: map.frame_id.clone(),
            });
        } else {
            // No metric map: the boundary of the floor bounds the world; lacking that, every
            // place's boundary becomes a wall (doorways between places are then closed).
            let bounded: Vec<&tosm::Place> = if floor.boundary.len() >= 3 {
                vec![floor]
            } else {
                places
                    .iter()
                    .filter(|p| p.boundary.len() >= 3 && on_floor(&p.iri))
                    .collect()
            };
            if bounded.is_empty() {
                out.push(SpecProblem::error(
                    &floor.iri,
                    tosm_term("hasMap"),
                    "the floor has no metric map and no place on it has a boundary: there is no static geometry to simulate",
                ));
            } else if bounded.len() > 1 || bounded[0].iri != floor.iri {
                notes.push(SpecProblem::warning(
                    &floor.iri,
                    tosm_term("hasMap"),
                    "the floor has no metric map: the boundaries of its places become walls, so doorways between them are closed",
                ));
            }
            for place in bounded {
                let n = place.boundary.len();
                for i in 0..n {
                    let (a, b) = (place.boundary[i], place.boundary[(i + 1) % n]);
                    walls.push(WallSpec {
                        id: place.iri.clone(),
                        start: [a.0, a.1],
                        end: [b.0, b.1],
                        thickness: BOUNDARY_WALL_THICKNESS,
                        height: WALL_HEIGHT,
                    });
                }
            }
        }
        // Objects inside the floor, through any chain of places and containing objects.
        let containers: HashMap<&str, Option<&str>> = places
            .iter()
            .map(|p| (p.iri.as_str(), p.parent.as_deref()))
            .chain(
                objects
                    .iter()
                    .map(|o| (o.iri.as_str(), Some(o.inside_of.as_str()))),
            )
            .collect();
        for o in &objects {
            if reaches(&o.iri, &floor.iri, &containers) {
                world_objects.push(object_spec(o, &mut notes));
            }
        }
        people = people_spec(&people_knowledge, &places, &floor.iri, &containers);
    }
    let Some(robot) = robot else {
        return Err(out);
    };
    if out.has_errors() {
        return Err(out);
    }
    // Only warnings are left: they travel with the description.
    notes.extend(out.0);
    let spec = WorldSpec {
        id: floor.map_or_else(String::new, |f| f.iri.clone()),
        floor: spec_floor,
        walls,
        objects: world_objects,
        robot,
        people,
        notes,
    };
    // The description's own checks (sizes, ranges, …) belong to the same list.
    let problems = spec.validate();
    if problems.has_errors() {
        return Err(problems);
    }
    Ok(spec)
}

/// What `people` says about the floor `floor`: its places (the floor itself included) with
/// their figures and boundaries, and the routes and attractors inside it, each sorted by IRI.
fn people_spec(
    people: &tosm::People,
    places: &[tosm::Place],
    floor: &str,
    up: &HashMap<&str, Option<&str>>,
) -> PeopleSpec {
    let point = |&(x, y): &(f64, f64)| [x, y];
    PeopleSpec {
        places: people
            .places
            .iter()
            .filter(|p| reaches(&p.place, floor, up))
            .filter_map(|p| {
                // A place that did not read is an error of its own already.
                let place = places.iter().find(|q| q.iri == p.place)?;
                let (expected, by_hour) = p.figures();
                Some(PeoplePlaceSpec {
                    id: p.place.clone(),
                    expected,
                    by_hour,
                    boundary: place.boundary.iter().map(point).collect(),
                })
            })
            .collect(),
        routes: people
            .routes
            .iter()
            .filter(|r| reaches(&r.inside_of, floor, up))
            .map(|r| RouteSpec {
                id: r.iri.clone(),
                points: r.points.iter().map(point).collect(),
            })
            .collect(),
        attractors: people
            .attractors
            .iter()
            .filter(|a| reaches(&a.inside_of, floor, up))
            .map(|a| AttractorSpec {
                id: a.iri.clone(),
                position: [a.pose.x, a.pose.y],
                dwell_s: a.dwell_s,
            })
            .collect(),
    }
}

/// Whether following `up` from `iri` reaches `target` (an individual reaches itself).
fn reaches(iri: &str, target: &str, up: &HashMap<&str, Option<&str>>) -> bool {
    let mut at = iri;
    // Containment chains in a building are short; the bound stops a cycle in bad data.
    for _ in 0..64 {
        if at == target {
            return true;
        }
        match up.get(at) {
            Some(Some(next)) => at = next,
            _ => return false,
        }
    }
    false
}

fn choose_floor<'a>(
    places: &'a [tosm::Place],
    wanted: Option<&str>,
    out: &mut SpecProblems,
) -> Option<&'a tosm::Place> {
    if let Some(iri) = wanted {
        let found = places.iter().find(|p| p.iri == iri);
        if found.is_none() {
            out.push(SpecProblem::error(
                iri,
                "rdf:type",
                "is not described as a tosm:Place in the on-demand database",
            ));
        }
        return found;
    }
    let mapped: Vec<&tosm::Place> = places.iter().filter(|p| p.map.is_some()).collect();
    match mapped.as_slice() {
        [one] => Some(one),
        [] => {
            // No map anywhere: the outermost floor (or place) with boundaries.
            let floors: Vec<&tosm::Place> = places
                .iter()
                .filter(|p| p.kind == tosm::PlaceKind::Floor)
                .collect();
            match floors.as_slice() {
                [one] => Some(one),
                _ => {
                    let top: Vec<&tosm::Place> = places
                        .iter()
                        .filter(|p| {
                            p.parent
                                .as_deref()
                                .is_none_or(|q| !places.iter().any(|o| o.iri == q))
                        })
                        .collect();
                    if let [one] = top.as_slice() {
                        Some(one)
                    } else {
                        out.push(SpecProblem::error(
                            "on-demand database",
                            tosm_term("hasMap"),
                            format!(
                                "no place has a metric map and {} places could be the floor; name the floor to simulate",
                                top.len()
                            ),
                        ));
                        None
                    }
                }
            }
        }
        many => {
            out.push(SpecProblem::error(
                "on-demand database",
                tosm_term("hasMap"),
                format!(
                    "{} places have metric maps ({}); a simulation covers one floor: name it",
                    many.len(),
                    many.iter()
                        .map(|p| p.iri.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
            None
        }
    }
}

fn shape_size(shape: &tosm::Shape) -> (Shape, Size3) {
    let [x, y, z] = shape.size();
    let s = match shape {
        tosm::Shape::Box { .. } => Shape::Box,
        tosm::Shape::Cylinder { .. } => Shape::Cylinder,
        tosm::Shape::Sphere { .. } => Shape::Sphere,
    };
    (s, Size3::new(x, y, z))
}

#[allow(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    reason = "clamped to [0, 255] before the cast"
)]
fn colour(c: Option<&tosm::Colour>, name: Option<&str>) -> Option<Colour> {
    let unit = |v: f64| {
        if v.is_finite() {
            (v.clamp(0.0, 1.0) * 255.0).round() as u8
        } else {
            0
        }
    };
    c.map(|c| Colour::rgb(unit(c.r), unit(c.g), unit(c.b)))
        .or_else(|| name.and_then(Colour::parse))
}

fn object_spec(o: &tosm::Object, notes: &mut Vec<SpecProblem>) -> ObjectSpec {
    let (shape, size) = shape_size(&o.shape);
    let colour = colour(o.colour.as_ref(), o.colour_name.as_deref()).unwrap_or_else(|| {
        let is_placeholder = crate::library::LibraryModel::for_class(&o.class_iri).is_none();
        if is_placeholder {
            notes.push(SpecProblem::warning(
                &o.iri,
                tosm_term("colourRed"),
                "the object has no colour: its placeholder is grey",
            ));
        }
        Colour::GREY
    });
    ObjectSpec {
        id: o.iri.clone(),
        class: Some(o.class_iri.clone()),
        shape,
        size,
        pose: o.pose,
        colour,
        open: o.is_open.unwrap_or(false),
    }
}

/// The robot as the simulator needs it, or `None` with the reasons in `out`.
fn robot_spec(r: &tosm::Robot, out: &mut SpecProblems) -> Option<RobotSpec> {
    let iri = r.iri.as_str();
    let before = out.0.len();
    if !r.differential_drive {
        out.push(SpecProblem::error(
            iri,
            "rdf:type",
            "the simulator drives differential robots only (tosm:DifferentialDriveRobot)",
        ));
    }
    let active: Vec<&tosm::Wheel> = r.active_wheels().collect();
    let (separation, radius) = if let [a, b] = active.as_slice() {
        if (a.radius - b.radius).abs() > 1e-3 {
            out.push(SpecProblem::warning(
                &b.part.iri,
                tosm_term("wheelRadiusM"),
                format!(
                    "the drive wheels' radii differ ({} and {} m): their mean is used",
                    a.radius, b.radius
                ),
            ));
        }
        (r.wheel_separation(), Some((a.radius + b.radius) / 2.0))
    } else {
        out.push(SpecProblem::error(
            iri,
            tosm_term("hasPart"),
            format!(
                "a differential drive needs exactly two active wheels, found {}",
                active.len()
            ),
        ));
        (None, None)
    };
    let laser = match r.lasers.as_slice() {
        [] => {
            out.push(SpecProblem::error(
                iri,
                tosm_term("hasSensor"),
                "the robot has no laser range finder: the simulated policy observes one",
            ));
            None
        }
        [first, rest @ ..] => {
            if !rest.is_empty() {
                out.push(SpecProblem::warning(
                    iri,
                    tosm_term("hasSensor"),
                    format!(
                        "the robot has {} lasers: {} is simulated",
                        rest.len() + 1,
                        first.part.iri
                    ),
                ));
            }
            Some(LaserSpec {
                id: first.part.iri.clone(),
                range_min: first.range_min,
                range_max: first.range_max,
                fov: first.view_angle,
                samples: first.samples as usize,
                mount: first.part.mounting,
            })
        }
    };
    let parts: Vec<RobotPartSpec> = r
        .structure
        .iter()
        .map(|p| &p.part)
        .chain(r.lasers.iter().map(|l| &l.part))
        .chain(r.cameras.iter().map(|c| &c.part))
        .filter_map(|p| {
            let (shape, size) = shape_size(p.shape.as_ref()?);
            Some(RobotPartSpec {
                id: p.iri.clone(),
                shape,
                size,
                pose: p.mounting,
                colour: colour(p.colour.as_ref(), None).unwrap_or(Colour::GREY),
                mass: p.physical.mass_kg,
            })
        })
        .collect();
    let wheels: Vec<WheelSpec> = r
        .wheels
        .iter()
        .map(|w| WheelSpec {
            id: w.part.iri.clone(),
            radius: w.radius,
            width: w.width.unwrap_or(w.radius / 2.0),
            pose: w.part.mounting,
            active: w.active,
        })
        .collect();
    let footprint = RobotSpec::footprint_from_parts(&parts, &wheels);
    if footprint.is_none() {
        out.push(SpecProblem::error(
            iri,
            tosm_term("hasShape"),
            "no part of the robot has a shape: its footprint is unknown",
        ));
    }
    let height = parts
        .iter()
        .map(|p| p.pose.z + p.size.z / 2.0)
        .chain(wheels.iter().map(|w| w.pose.z + w.radius))
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))));
    let cameras = r
        .cameras
        .iter()
        .map(|c| CameraSpec {
            id: c.part.iri.clone(),
            width: c.width_px,
            height: c.height_px,
            fps: c.fps,
            hfov: c.horizontal_fov,
            depth_range: c.depth_range,
            mount: c.part.mounting,
        })
        .collect();
    if out.0[before..]
        .iter()
        .any(|p| p.severity == crate::spec::Severity::Error)
    {
        return None;
    }
    Some(RobotSpec {
        id: iri.to_owned(),
        footprint_radius: footprint?,
        height: height?,
        drive: DiffDriveSpec {
            wheel_separation: separation?,
            wheel_radius: radius?,
            max_wheel_speed: None,
            max_linear_speed: r.max_linear_speed,
            max_angular_speed: r.max_angular_speed,
            max_linear_acceleration: r.dynamics.max_linear_acceleration,
            max_angular_acceleration: r.dynamics.max_angular_acceleration,
            max_linear_deceleration: r.dynamics.max_linear_deceleration,
            max_angular_deceleration: r.dynamics.max_angular_deceleration,
            control_latency: r.dynamics.control_latency,
        },
        laser: laser?,
        cameras,
        parts,
        wheels,
    })
}
