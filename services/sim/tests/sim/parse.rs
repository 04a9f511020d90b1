//! The simulation parser on the bundled sample building and robot, and on broken robots.

use std::path::PathBuf;
use std::sync::Arc;

use oxrdf::{Graph, NamedNode, Triple};
use sim::{
    EnvConfig, LibraryModel, Model, NavEnv, Severity, Shape, World, parse_floor, parse_on_demand,
};

const ROBOT: &str = "https://mentalsim.dev/data/robots/differential-robot";
const FLOOR0: &str = "https://mentalsim.dev/data/buildings/sample-building/floors/0";
const TOSM: &str = "https://mentalsim.dev/ontology/tosm#";

fn ontology(rel: &str) -> PathBuf {
    PathBuf::from(
        std::env::var("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
    )
    .join("../../ontologies")
    .join(rel)
}

fn load(graph: &mut Graph, rel: &str) {
    let text = std::fs::read(ontology(rel)).expect("bundled ontology file");
    for t in oxttl::TurtleParser::new().for_slice(&text) {
        graph.insert(&t.expect("valid Turtle"));
    }
}

fn building_and_robot() -> Graph {
    let mut g = Graph::new();
    load(&mut g, "environments/sample-building.ttl");
    load(&mut g, "robots/differential-robot.ttl");
    g
}

fn robot_only() -> Graph {
    let mut g = Graph::new();
    load(&mut g, "robots/differential-robot.ttl");
    g
}

fn node(iri: &str) -> NamedNode {
    NamedNode::new_unchecked(iri)
}

#[test]
fn the_sample_building_floor_becomes_a_world() {
    let g = building_and_robot();
    // Two floors have maps: the parser asks which one.
    let err = parse_on_demand(&g, ROBOT).expect_err("two floors");
    assert!(err.to_string().contains("floors/1"), "{err}");

    let spec = parse_floor(&g, ROBOT, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(spec.id, FLOOR0);
    let floor = spec.floor.as_ref().expect("the floor's metric map");
    assert_eq!((floor.grid.width, floor.grid.height), (544, 768));
    // The robot from its parts: the base box 0.5 x 0.38 m centred 5 cm behind the axle reaches
    // (-0.3, ±0.19) from the origin; the camera tops it at 0.375 + 0.015 m.
    let r = &spec.robot;
    assert!(
        (r.footprint_radius - 0.3f64.hypot(0.19)).abs() < 1e-9,
        "{}",
        r.footprint_radius
    );
    assert!((r.height - 0.39).abs() < 1e-9, "{}", r.height);
    assert!((r.drive.wheel_separation - 0.44).abs() < 1e-9);
    assert!((r.drive.wheel_radius - 0.0975).abs() < 1e-9);
    assert_eq!(r.drive.max_linear_speed, Some(0.8));
    assert_eq!(r.drive.max_angular_speed, Some(0.5));
    assert_eq!(r.laser.samples, 690);
    assert!((r.laser.mount.z - 0.305).abs() < 1e-9 && (r.laser.range_max - 10.0).abs() < 1e-9);
    assert_eq!(r.cameras.len(), 1);
    assert_eq!(r.wheels.iter().filter(|w| w.active).count(), 2);
    // Objects of floor 0 only, as library models or placeholders.
    // Eight objects stand on floor 0; the bin is in floor 1's kitchen.
    assert_eq!(
        spec.objects.len(),
        8,
        "{:?}",
        spec.objects.iter().map(|o| &o.id).collect::<Vec<_>>()
    );
    assert!(spec.objects.iter().all(|o| !o.id.ends_with("bin-1")));
    let door = spec
        .objects
        .iter()
        .find(|o| o.id.ends_with("door-1"))
        .expect("door");
    assert!(door.open, "the sample's steel door stands open");
    let vending = spec
        .objects
        .iter()
        .find(|o| {
            o.class
                .as_deref()
                .is_some_and(|c| c.ends_with("VendingMachine"))
        })
        .expect("the vending machine is on floor 0");
    assert_eq!(sim::library::model_for(vending), Model::Placeholder);
    assert_eq!(vending.shape, Shape::Box);
    assert!(
        vending.colour.r > 150 && vending.colour.g < 30,
        "red: {:?}",
        vending.colour
    );
    let models: Vec<Model> = spec.objects.iter().map(sim::library::model_for).collect();
    assert!(
        models.contains(&Model::Library(LibraryModel::Table)),
        "{models:?}"
    );

    let world = World::build(spec).unwrap_or_else(|p| panic!("{p}"));
    let mut env = NavEnv::new(
        Arc::clone(&world),
        EnvConfig {
            goal_distance: (1.0, 5.0),
            ..EnvConfig::default()
        },
        3,
    )
    .expect("env");
    for _ in 0..10 {
        env.reset_random()
            .expect("a start and goal in the apartment");
    }
}

#[test]
fn a_robot_without_a_laser_is_refused_naming_it() {
    let mut g = building_and_robot();
    g.remove(&Triple::new(
        node(ROBOT),
        node(&format!("{TOSM}hasSensor")),
        node(&format!("{ROBOT}/laser")),
    ));
    g.remove(&Triple::new(
        node(ROBOT),
        node(&format!("{TOSM}hasPart")),
        node(&format!("{ROBOT}/laser-joint")),
    ));
    let err = parse_floor(&g, ROBOT, FLOOR0).expect_err("no laser");
    assert!(
        err.0.iter().any(|p| p.severity == Severity::Error
            && p.item == ROBOT
            && p.field.ends_with("hasSensor")),
        "{err}"
    );
}

#[test]
fn a_missing_robot_or_floor_is_named() {
    let g = building_and_robot();
    let err = parse_floor(&g, "https://example.org/no-robot", FLOOR0).expect_err("no robot");
    assert!(
        err.0
            .iter()
            .any(|p| p.item == "https://example.org/no-robot"),
        "{err}"
    );
    let err = parse_floor(&g, ROBOT, "https://example.org/no-floor").expect_err("no floor");
    assert!(
        err.0
            .iter()
            .any(|p| p.item == "https://example.org/no-floor"),
        "{err}"
    );
    // A database with a robot and no place at all has nothing to simulate.
    let err = parse_on_demand(&robot_only(), ROBOT).expect_err("no places");
    assert!(err.has_errors(), "{err}");
}

#[test]
fn a_drive_with_three_active_wheels_is_refused() {
    let mut g = building_and_robot();
    g.insert(&Triple::new(
        node(&format!("{ROBOT}/caster")),
        node("http://www.w3.org/1999/02/22-rdf-syntax-ns#type"),
        node(&format!("{TOSM}ActiveWheel")),
    ));
    let err = parse_floor(&g, ROBOT, FLOOR0).expect_err("three drive wheels");
    assert!(err.has_errors(), "{err}");
}

/// The sample building and the paper's robot with its acceleration limits left out, for tests
/// that give the robot limits of their own.
fn building_and_robot_without_dynamics() -> Graph {
    let mut g = Graph::new();
    load(&mut g, "environments/sample-building.ttl");
    let text = std::fs::read_to_string(ontology("robots/differential-robot.ttl"))
        .expect("the bundled robot");
    let kept: String = text
        .lines()
        .filter(|l| {
            !l.contains("AccelerationRadPerS2")
                && !l.contains("MPerS2")
                && !l.contains("DecelerationRadPerS2")
        })
        .map(|l| format!("{l}\n"))
        .collect();
    for t in oxttl::TurtleParser::new().for_slice(kept.as_bytes()) {
        g.insert(&t.expect("valid Turtle"));
    }
    g
}

#[test]
fn the_robots_acceleration_limits_reach_its_drive_and_bound_it() {
    // The bundled robot carries no acceleration limits yet (see its file).
    let spec = parse_floor(&building_and_robot(), ROBOT, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    let d = &spec.robot.drive;
    assert_eq!(
        (
            d.max_linear_acceleration,
            d.max_linear_deceleration,
            d.max_angular_acceleration,
            d.max_angular_deceleration,
            d.control_latency
        ),
        (None, None, None, None, None)
    );
    let mut g = building_and_robot_without_dynamics();
    let spec = parse_floor(&g, ROBOT, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(spec.robot.drive.max_linear_acceleration, None);
    add_turtle(
        &mut g,
        &format!(
            "<{ROBOT}> tosm:maxLinearAccelerationMPerS2 0.5 ; tosm:maxLinearDecelerationMPerS2 1.0 ; \
             tosm:maxAngularAccelerationRadPerS2 1.5 ."
        ),
    );
    let spec = parse_floor(&g, ROBOT, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    let d = &spec.robot.drive;
    assert_eq!(
        (
            d.max_linear_acceleration,
            d.max_linear_deceleration,
            d.max_angular_acceleration,
            d.max_angular_deceleration
        ),
        (Some(0.5), Some(1.0), Some(1.5), None)
    );
    // The drive the simulation builds from it reaches 0.8 m/s in 1.6 s, and brakes twice as
    // fast as it speeds up.
    let drive = sim::kinematics::DiffDrive::new(d.clone());
    let mut a = sim::Action::default();
    let mut steps = 0;
    while a.linear < 0.8 - 1e-9 {
        a = drive.execute(a, sim::Action::new(0.8, 0.0), 0.1);
        steps += 1;
    }
    assert_eq!(steps, 16);
    let braking = drive.execute(a, sim::Action::new(0.0, 0.0), 0.1);
    assert!((braking.linear - 0.7).abs() < 1e-12, "{braking:?}");
    // A non-positive limit in the knowledge is a problem named with its property.
    add_turtle(
        &mut g,
        &format!("<{ROBOT}> tosm:maxAngularDecelerationRadPerS2 -1.0 ."),
    );
    let err = parse_floor(&g, ROBOT, FLOOR0).expect_err("negative deceleration");
    assert!(
        err.to_string().contains("maxAngularDecelerationRadPerS2"),
        "{err}"
    );
}

#[test]
fn a_control_latency_delays_what_reaches_the_wheels() {
    // No acceleration limits, a latency of 2.5 control periods: a command sent from standing
    // still reaches the wheels half-way through the third period.
    let mut g = building_and_robot_without_dynamics();
    add_turtle(&mut g, &format!("<{ROBOT}> tosm:controlLatencyS 0.25 ."));
    let spec = parse_floor(&g, ROBOT, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(spec.robot.drive.control_latency, Some(0.25));
    let world = World::build(spec).unwrap_or_else(|p| panic!("{p}"));
    let mut env = NavEnv::new(world, EnvConfig::default(), 3).expect("env");
    env.reset_random().expect("a start and goal");
    let speeds: Vec<f64> = (0..4)
        .map(|_| env.step(sim::Action::new(0.4, 0.0)).info.executed.linear)
        .collect();
    for (got, want) in speeds.iter().zip([0.0, 0.0, 0.2, 0.4]) {
        assert!((got - want).abs() < 0.05, "{speeds:?}");
    }
    // A latency beyond a second is refused, naming it.
    let mut g = building_and_robot_without_dynamics();
    add_turtle(&mut g, &format!("<{ROBOT}> tosm:controlLatencyS 1.5 ."));
    let err = parse_floor(&g, ROBOT, FLOOR0).expect_err("a latency of 1.5 s");
    assert!(err.to_string().contains("latency"), "{err}");
}

#[test]
fn the_tiago_like_base_is_another_robot_model() {
    const TIAGO: &str = "https://mentalsim.dev/data/robots/tiago-base";
    let mut g = Graph::new();
    load(&mut g, "environments/sample-building.ttl");
    load(&mut g, "robots/tiago-base.ttl");
    let spec = parse_floor(&g, TIAGO, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    let r = &spec.robot;
    let d = &r.drive;
    assert_eq!(
        (
            d.max_linear_speed,
            d.max_angular_speed,
            d.max_linear_acceleration,
            d.control_latency
        ),
        (Some(1.0), Some(1.05), Some(0.5), Some(0.05))
    );
    // Round, 0.54 m across: its footprint is the cylinder's radius (and a little for the
    // casters' boxes inside it).
    assert!(
        (0.27..0.30).contains(&r.footprint_radius),
        "{}",
        r.footprint_radius
    );
    assert!((r.laser.fov - 4.712389).abs() < 1e-6);
    let world = World::build(spec).unwrap_or_else(|p| panic!("{p}"));
    let mut env = NavEnv::new(world, EnvConfig::default(), 1).expect("env");
    env.reset_random()
        .expect("a start and goal for the TIAGo-like base");
}

/// Turtle triples added to a graph (prefixes `tosm:` and `xsd:` declared).
fn add_turtle(graph: &mut Graph, turtle: &str) {
    let text = format!(
        "@prefix tosm: <{TOSM}> .\n@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .\n{turtle}"
    );
    for t in oxttl::TurtleParser::new().for_slice(text.as_bytes()) {
        graph.insert(&t.expect("valid Turtle"));
    }
}

#[test]
fn the_sample_floor_carries_what_is_known_about_its_people() {
    let g = building_and_robot();
    let spec = parse_floor(&g, ROBOT, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    let people = &spec.people;
    // Floor 0's places with people, sorted by IRI; the kitchen is on floor 1.
    let ids: Vec<&str> = people.places.iter().map(|p| p.id.as_str()).collect();
    assert_eq!(
        ids,
        ["hall", "hallway", "living-room", "office"]
            .map(|s| format!("{FLOOR0}/{s}"))
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>()
    );
    let living = &people.places[2];
    assert_eq!(living.expected, 1.5);
    assert_eq!(living.by_hour, vec![(12, 4.0), (13, 3.0), (15, 2.0)]);
    assert_eq!(living.boundary.len(), 4, "people spawn inside its polygon");
    // At noon: hall 3 + hallway 2 + living room 4 + office 1 (its all-day figure).
    assert_eq!(people.expected_at(Some(12)), 10.0);
    assert_eq!(people.expected_at(None), 1.0 + 0.5 + 1.5 + 1.0);
    assert_eq!(people.routes.len(), 2);
    assert!(people.routes.iter().all(|r| r.points.len() == 6));
    let to_machine = people
        .routes
        .iter()
        .find(|r| r.id.ends_with("hall-to-vending-machine"))
        .expect("the route to the vending machine");
    assert_eq!(to_machine.points.last(), Some(&[3.075, -1.975]));
    assert_eq!(people.attractors.len(), 1);
    let a = &people.attractors[0];
    assert_eq!((a.position, a.dwell_s), ([3.3, -2.0], 60.0));
    assert!(spec.validate().is_empty(), "{}", spec.validate());

    let kitchen =
        parse_floor(&g, ROBOT, &FLOOR0.replace("/0", "/1")).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(kitchen.people.places.len(), 1);
    assert_eq!(kitchen.people.places[0].expected_at(Some(12)), 5.0);
    assert!(kitchen.people.routes.is_empty() && kitchen.people.attractors.is_empty());
}

#[test]
fn robots_counts_replace_the_engineers_figures_in_the_world() {
    let mut g = building_and_robot();
    add_turtle(
        &mut g,
        &format!(
            "<{FLOOR0}/hall> tosm:hasPeopleEstimate <{FLOOR0}/hall/people/estimate>, <{FLOOR0}/hall/people/estimate/hour/12> .
<{FLOOR0}/hall/people/estimate> a tosm:PeopleEstimate ; tosm:estimatedPeople 2.6 ; tosm:observationCount 9 .
<{FLOOR0}/hall/people/estimate/hour/12> a tosm:PeopleEstimate ; tosm:hourOfDay 12 ;
    tosm:estimatedPeople 6 ; tosm:observationCount 3 ;
    tosm:lastObservedAt \"2025-05-06T12:40:00+02:00\"^^xsd:dateTime .
"
        ),
    );
    let spec = parse_floor(&g, ROBOT, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    let hall = spec
        .people
        .places
        .iter()
        .find(|p| p.id == format!("{FLOOR0}/hall"))
        .expect("the hall");
    // The engineer said 1 all day and 3 at noon; robots counted 2.6 and 6.
    assert_eq!(hall.expected, 2.6);
    assert_eq!(hall.by_hour, vec![(12, 6.0), (13, 2.0)]);
}

#[test]
fn people_knowledge_that_does_not_read_is_left_out_with_a_warning() {
    let mut g = building_and_robot();
    add_turtle(
        &mut g,
        &format!(
            "<{FLOOR0}/routes/stub> a tosm:WalkingRoute ; tosm:isDirectlyInsideOf <{FLOOR0}> ;
    tosm:hasRoutePoint <{FLOOR0}/routes/stub/point/0> .
<{FLOOR0}/routes/stub/point/0> a tosm:RoutePoint ; tosm:pointIndex 0 ; tosm:xM 1 ; tosm:yM 1 .
<{FLOOR0}/office> tosm:hasHourlyPeopleCount <{FLOOR0}/office/people/hour/25> .
<{FLOOR0}/office/people/hour/25> a tosm:HourlyPeopleCount ; tosm:hourOfDay 25 ; tosm:expectedPeople 2 .
"
        ),
    );
    let spec = parse_floor(&g, ROBOT, FLOOR0).unwrap_or_else(|p| panic!("{p}"));
    let warned = |item: &str, field: &str| {
        spec.notes.iter().any(|p| {
            p.severity == Severity::Warning
                && p.item == item
                && p.field == format!("{TOSM}{field}")
                && p.message.contains("left out")
        })
    };
    assert!(
        warned(&format!("{FLOOR0}/routes/stub"), "hasRoutePoint"),
        "{:?}",
        spec.notes
    );
    assert!(
        warned(&format!("{FLOOR0}/office/people/hour/25"), "hourOfDay"),
        "{:?}",
        spec.notes
    );
    assert_eq!(spec.people.routes.len(), 2, "the stub is left out");
    assert!(
        spec.people.places.iter().all(|p| !p.id.ends_with("office")),
        "the office's figures are left out"
    );
}
