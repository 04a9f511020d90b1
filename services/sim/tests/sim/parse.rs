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
