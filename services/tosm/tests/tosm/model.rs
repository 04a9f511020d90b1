//! The typed model against the bundled ontology files: the robot reads without problems,
//! typed values survive a round trip through triples, every kind of bad data is reported with
//! the individual and property it concerns, and mangled graphs never panic.

use std::collections::BTreeSet;
use std::path::PathBuf;

use oxrdf::vocab::rdf;
use oxrdf::{Graph, Literal, NamedNode, NamedOrBlankNode, Term, Triple};
use tosm::{
    CameraKind, Colour, JointKind, Object, ObjectClass, Physical, Place, PlaceKind, Pose3,
    Problems, Relation, RelationKind, Robot, Shape, Symbol, vocab,
};

const ROBOT: &str = "https://mentalsim.dev/data/robots/differential-robot";

fn ontologies() -> PathBuf {
    PathBuf::from(
        std::env::var("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
    )
    .join("../../ontologies")
}

fn parse_turtle(text: &str) -> Graph {
    let mut graph = Graph::new();
    for t in oxttl::TurtleParser::new().for_slice(text.as_bytes()) {
        graph.insert(&t.expect("valid turtle"));
    }
    graph
}

fn load(relative: &str) -> Graph {
    let text = std::fs::read_to_string(ontologies().join(relative)).expect("read ontology file");
    parse_turtle(&text)
}

fn graph_of(triples: Vec<Triple>) -> Graph {
    let mut g = Graph::new();
    for t in &triples {
        g.insert(t);
    }
    g
}

/// Asserts that `problems` has one naming `individual` and `property` whose message contains
/// `needle`.
fn assert_problem(problems: &Problems, individual: &str, property: &str, needle: &str) {
    assert!(
        problems.iter().any(|p| p.individual == individual
            && p.property == property
            && p.message.contains(needle)),
        "expected a problem on <{individual}> <{property}> containing {needle:?}; got {problems}"
    );
}

const PREFIXES: &str = "@prefix tosm: <https://mentalsim.dev/ontology/tosm#> .\n\
                        @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .\n\
                        @prefix ex: <https://example.org/> .\n";

fn t(s: &str) -> String {
    format!("https://example.org/{s}")
}

fn prop(local: &str) -> String {
    format!("{}{local}", vocab::NS)
}

#[test]
fn vocabulary_matches_the_ontology_file() {
    let graph = load("tosm.ttl");
    let declared: BTreeSet<String> = graph
        .triples_for_predicate(rdf::TYPE)
        .filter_map(|t| match t.subject {
            oxrdf::NamedOrBlankNodeRef::NamedNode(n) if n.as_str().starts_with(vocab::NS) => {
                Some(n.as_str().to_owned())
            }
            _ => None,
        })
        .collect();
    let constants: BTreeSet<String> = vocab::ALL
        .iter()
        .map(|(local, iri)| {
            assert_eq!(iri.as_str(), format!("{}{local}", vocab::NS));
            iri.as_str().to_owned()
        })
        .collect();
    let missing: Vec<_> = declared.difference(&constants).collect();
    let extra: Vec<_> = constants.difference(&declared).collect();
    assert!(
        missing.is_empty(),
        "terms in tosm.ttl without a vocab constant: {missing:?}"
    );
    assert!(
        extra.is_empty(),
        "vocab constants not declared in tosm.ttl: {extra:?}"
    );
}

#[test]
fn bundled_robot_reads_without_problems() {
    let graph = load("robots/differential-robot.ttl");
    let robot = tosm::read_robot(&graph, ROBOT).unwrap_or_else(|p| panic!("{p}"));
    assert!(robot.differential_drive);
    assert_eq!(robot.max_linear_speed, Some(0.8));
    assert_eq!(robot.max_angular_speed, Some(0.5));
    assert_eq!(robot.footprint(), Some((0.5, 0.38)));
    assert_eq!(robot.active_wheels().count(), 2);
    assert_eq!(
        robot
            .wheels
            .iter()
            .filter(|w| w.caster && !w.active)
            .count(),
        1
    );
    let separation = robot.wheel_separation().expect("two drive wheels");
    assert!((separation - 0.44).abs() < 1e-9, "{separation}");
    assert_eq!(robot.lasers.len(), 1);
    let laser = &robot.lasers[0];
    assert!(
        laser.samples >= 23,
        "the policy samples 23 ranges from this laser"
    );
    assert_eq!(laser.samples % 23, 0, "23 equally spaced samples");
    assert_eq!((laser.range_min, laser.range_max), (0.1, 10.0));
    assert_eq!(robot.cameras.len(), 1);
    assert_eq!(robot.cameras[0].kind, CameraKind::Stereo);
    assert_eq!(
        (robot.cameras[0].width_px, robot.cameras[0].height_px),
        (1280, 720)
    );
    assert_eq!(robot.cameras[0].depth_range, Some((0.3, 20.0)));
    assert_eq!(robot.joints.len(), 5);
    assert!(robot.joints.iter().all(|j| j.parent == robot.base));
    assert_eq!(
        robot
            .joints
            .iter()
            .filter(|j| j.kind == JointKind::Continuous)
            .count(),
        3
    );
    let base = robot.base_part().expect("base");
    assert_eq!(base.part.physical.mass_kg, Some(9.0));
    assert_eq!(
        base.part.physical.material.as_deref(),
        Some(vocab::ALUMINIUM.as_str())
    );
    assert_eq!(tosm::read_robots(&graph).expect("robots"), vec![robot]);
}

#[test]
fn robot_round_trips_through_triples() {
    let graph = load("robots/differential-robot.ttl");
    let robot = tosm::read_robot(&graph, ROBOT).expect("robot");
    let triples = tosm::robot_to_triples(&robot).expect("valid robot");
    assert!(
        triples
            .iter()
            .all(|t| matches!(t.subject, NamedOrBlankNode::NamedNode(_)))
    );
    let again = tosm::read_robot(&graph_of(triples.clone()), ROBOT).expect("reads back");
    assert_eq!(again, robot);
    // Writing is deterministic, so two downloads of the same robot merge exactly.
    assert_eq!(tosm::robot_to_triples(&again).expect("valid"), triples);
}

#[test]
fn a_robots_acceleration_limits_round_trip() {
    let graph = load("robots/differential-robot.ttl");
    let mut robot = tosm::read_robot(&graph, ROBOT).expect("robot");
    robot.dynamics = tosm::Dynamics {
        max_linear_acceleration: Some(0.5),
        max_linear_deceleration: Some(0.8),
        max_angular_acceleration: Some(1.2),
        max_angular_deceleration: None,
        control_latency: Some(0.05),
    };
    let triples = tosm::robot_to_triples(&robot).expect("valid robot");
    let again = tosm::read_robot(&graph_of(triples), ROBOT).expect("reads back");
    assert_eq!(again.dynamics, robot.dynamics);
}

fn sample_object() -> Object {
    Object {
        iri: t("box-1"),
        class_iri: t("Crate"),
        class: ObjectClass::Other,
        symbol: Symbol {
            name: "Crate".to_owned(),
            identifier: Some("C-1".to_owned()),
            description: Some("Seen by the robot".to_owned()),
        },
        pose: Pose3 {
            x: 1.25,
            y: -0.5,
            z: 0.2,
            roll: 0.0,
            pitch: 0.1,
            yaw: 3.0,
        },
        shape: Shape::Sphere { diameter: 0.4 },
        colour: Some(Colour {
            r: 0.1,
            g: 0.2,
            b: 0.3,
            a: 0.5,
        }),
        colour_name: None,
        physical: Physical {
            mass_kg: Some(2.5),
            material: Some(vocab::CARDBOARD.as_str().to_owned()),
            friction: Some(0.4),
        },
        inside_of: t("room"),
        relations: vec![
            Relation {
                kind: RelationKind::InFrontOf,
                target: t("elsewhere"),
            },
            Relation {
                kind: RelationKind::InsideOf,
                target: t("other-room"),
            },
        ],
        is_open: None,
        reported_by: Some(ROBOT.to_owned()),
        reported_at: Some("2026-11-22T03:00:00Z".to_owned()),
    }
}

fn sample_room() -> Place {
    Place {
        iri: t("room"),
        kind: PlaceKind::Room,
        symbol: Symbol::named("Room"),
        boundary: vec![(0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (0.0, 3.0)],
        parent: None,
        connected: vec![],
        complexity: Some(0.25),
        level: None,
        map: None,
    }
}

#[test]
fn object_with_a_foreign_class_round_trips() {
    let object = sample_object();
    let mut triples = tosm::object_to_triples(&object).expect("valid object");
    triples.extend(tosm::place_to_triples(&sample_room()).expect("valid room"));
    let graph = graph_of(triples);
    let objects = tosm::read_objects(&graph).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(objects, vec![object]);
    assert_eq!(
        tosm::read_places(&graph).expect("room"),
        vec![sample_room()]
    );
}

#[test]
fn a_class_declared_in_the_graph_is_recognised() {
    let graph = parse_turtle(&format!(
        "{PREFIXES}
        @prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
        ex:Piano rdfs:subClassOf ex:Instrument . ex:Instrument rdfs:subClassOf tosm:Object .
        ex:room a tosm:Room ; tosm:name \"R\" ;
            tosm:hasBoundaryPoint ex:b0, ex:b1, ex:b2 .
        ex:b0 tosm:pointIndex 0 ; tosm:xM 0 ; tosm:yM 0 .
        ex:b1 tosm:pointIndex 1 ; tosm:xM 1 ; tosm:yM 0 .
        ex:b2 tosm:pointIndex 2 ; tosm:xM 1 ; tosm:yM 1 .
        ex:piano a ex:Piano ; tosm:name \"Piano\" ; tosm:isDirectlyInsideOf ex:room ;
            tosm:hasPose ex:piano-pose ; tosm:hasShape ex:piano-shape .
        ex:piano-pose a tosm:Pose ; tosm:xM 0.5 ; tosm:yM 0.5 .
        ex:piano-shape a tosm:BoxShape ; tosm:lengthM 1.5 ; tosm:widthM 0.6 ; tosm:heightM 1.2 .
        "
    ));
    let objects = tosm::read_objects(&graph).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(objects.len(), 1);
    assert_eq!(objects[0].class_iri, t("Piano"));
    assert_eq!(objects[0].class, ObjectClass::Other);
    assert_eq!(objects[0].pose, Pose3::new(0.5, 0.5, 0.0, 0.0));
}

/// A well-formed room and object that each bad-data test below breaks in one way.
fn object_graph(object_extra: &str, pose_extra: &str, shape: &str) -> Graph {
    parse_turtle(&format!(
        "{PREFIXES}
        ex:room a tosm:Room ; tosm:name \"Room\" ; tosm:complexity 0.2 ;
            tosm:hasBoundaryPoint ex:b0, ex:b1, ex:b2 .
        ex:b0 tosm:pointIndex 0 ; tosm:xM 0 ; tosm:yM 0 .
        ex:b1 tosm:pointIndex 1 ; tosm:xM 4 ; tosm:yM 0 .
        ex:b2 tosm:pointIndex 2 ; tosm:xM 4 ; tosm:yM 3 .
        ex:table a tosm:Table ; tosm:name \"Table\" ; tosm:isDirectlyInsideOf ex:room ;
            tosm:hasPose ex:pose ; tosm:hasShape ex:shape {object_extra} .
        ex:pose a tosm:Pose ; tosm:xM 1 ; tosm:yM 1 {pose_extra} .
        ex:shape {shape} .
        "
    ))
}

const GOOD_SHAPE: &str = "a tosm:BoxShape ; tosm:lengthM 1 ; tosm:widthM 1 ; tosm:heightM 0.7";

fn object_problems(object_extra: &str, pose_extra: &str, shape: &str) -> Problems {
    tosm::read_objects(&object_graph(object_extra, pose_extra, shape))
        .expect_err("bad data must be reported")
}

#[test]
fn the_well_formed_fixture_has_no_problems() {
    let graph = object_graph("", "", GOOD_SHAPE);
    let objects = tosm::read_objects(&graph).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(objects[0].class, ObjectClass::Table);
    tosm::read_places(&graph).unwrap_or_else(|p| panic!("{p}"));
}

#[test]
fn missing_required_properties_are_reported() {
    let graph = parse_turtle(&format!(
        "{PREFIXES} ex:room a tosm:Room ; tosm:name \"R\" ; tosm:hasBoundaryPoint ex:b0, ex:b1, ex:b2 .
        ex:b0 tosm:pointIndex 0 ; tosm:xM 0 ; tosm:yM 0 .
        ex:b1 tosm:pointIndex 1 ; tosm:xM 4 ; tosm:yM 0 .
        ex:b2 tosm:pointIndex 2 ; tosm:xM 4 .
        ex:chair a tosm:Chair ; tosm:isDirectlyInsideOf ex:room .
        ex:floor a tosm:Floor ; tosm:name \"F\" .
        "
    ));
    let problems = tosm::read_objects(&graph).expect_err("chair is incomplete");
    for p in ["name", "hasPose", "hasShape"] {
        assert_problem(&problems, &t("chair"), &prop(p), "missing");
    }
    let problems = tosm::read_places(&graph).expect_err("places are incomplete");
    assert_problem(&problems, &t("b2"), &prop("yM"), "missing");
    assert_problem(&problems, &t("floor"), &prop("hasMetricMap"), "missing");
}

#[test]
fn ill_typed_literals_are_reported() {
    let problems = object_problems("; tosm:massKg \"abc\"", "", GOOD_SHAPE);
    assert_problem(&problems, &t("table"), &prop("massKg"), "\"abc\"");
    let problems = object_problems("; tosm:massKg \"12\"", "", GOOD_SHAPE);
    assert_problem(&problems, &t("table"), &prop("massKg"), "must be a number");
    let problems = object_problems("", "; tosm:yawRad \"NaN\"^^xsd:double", GOOD_SHAPE);
    assert_problem(&problems, &t("pose"), &prop("yawRad"), "finite");
    let problems = object_problems("; tosm:isOpen \"maybe\"^^xsd:boolean", "", GOOD_SHAPE);
    assert_problem(&problems, &t("table"), &prop("isOpen"), "boolean");
    let problems = object_problems("; tosm:hasMaterial \"wood\"", "", GOOD_SHAPE);
    assert_problem(
        &problems,
        &t("table"),
        &prop("hasMaterial"),
        "must be an IRI",
    );
    let problems = object_problems("; tosm:hasMaterial ex:cheese", "", GOOD_SHAPE);
    assert_problem(
        &problems,
        &t("table"),
        &prop("hasMaterial"),
        "not a tosm:Material",
    );
    let problems = object_problems("; tosm:reportedAt \"yesterday\"", "", GOOD_SHAPE);
    assert_problem(&problems, &t("table"), &prop("reportedAt"), "xsd:dateTime");
}

#[test]
fn out_of_range_values_are_reported() {
    let problems = object_problems(
        "",
        "",
        "a tosm:BoxShape ; tosm:lengthM -1 ; tosm:widthM 0 ; tosm:heightM 0.7",
    );
    assert_problem(&problems, &t("shape"), &prop("lengthM"), "> 0");
    assert_problem(&problems, &t("shape"), &prop("widthM"), "> 0");
    let problems = object_problems(
        "; tosm:colourRed 1.5 ; tosm:colourGreen 0 ; tosm:colourBlue 0",
        "",
        GOOD_SHAPE,
    );
    assert_problem(&problems, &t("table"), &prop("colourRed"), "[0, 1]");
    let problems = object_problems("; tosm:massKg -3", "", GOOD_SHAPE);
    assert_problem(&problems, &t("table"), &prop("massKg"), "> 0");
    let problems = object_problems(
        "",
        "",
        "a tosm:CylinderShape ; tosm:lengthM 1 ; tosm:widthM 2 ; tosm:heightM 0.7",
    );
    assert_problem(&problems, &t("shape"), &prop("widthM"), "round shape");

    let graph = parse_turtle(&format!(
        "{PREFIXES} ex:room a tosm:Room ; tosm:name \"R\" ; tosm:complexity 1.7 ;
            tosm:hasBoundaryPoint ex:b0, ex:b1, ex:b2 .
        ex:b0 tosm:pointIndex 0 ; tosm:xM 0 ; tosm:yM 0 .
        ex:b1 tosm:pointIndex 0 ; tosm:xM 4 ; tosm:yM 0 .
        ex:b2 tosm:pointIndex 2 ; tosm:xM 4 ; tosm:yM 3 ."
    ));
    let problems = tosm::read_places(&graph).expect_err("complexity out of range");
    assert_problem(
        &problems,
        &t("room"),
        &prop("complexity"),
        "in [0, 1], found 1.7",
    );
    assert!(
        problems
            .iter()
            .any(|p| p.property == prop("pointIndex") && p.message.contains("two boundary points")),
        "{problems}"
    );
}

#[test]
fn dangling_and_wrong_kind_references_are_reported() {
    let problems = object_problems("; tosm:isNextTo ex:shape", "", GOOD_SHAPE);
    assert_problem(
        &problems,
        &t("table"),
        &prop("isNextTo"),
        "not a place or an object",
    );
    // An object's container must be in the graph.
    let graph = parse_turtle(&format!(
        "{PREFIXES} ex:chair a tosm:Chair ; tosm:name \"C\" ; tosm:isDirectlyInsideOf ex:nowhere ;
            tosm:hasPose ex:p ; tosm:hasShape ex:s .
        ex:p tosm:xM 0 ; tosm:yM 0 .
        ex:s a tosm:SphereShape ; tosm:lengthM 1 ; tosm:widthM 1 ; tosm:heightM 1 ."
    ));
    let problems = tosm::read_objects(&graph).expect_err("dangling container");
    assert_problem(
        &problems,
        &t("chair"),
        &prop("isDirectlyInsideOf"),
        "dangling",
    );
    // A joint whose child is not part of the robot.
    let mut graph = load("robots/differential-robot.ttl");
    let joint = NamedNode::new_unchecked(format!("{ROBOT}/left-wheel-joint"));
    let child = graph
        .object_for_subject_predicate(&joint, vocab::HAS_CHILD_PART)
        .map(|t| t.into_owned())
        .expect("child");
    graph.remove(&Triple::new(
        joint.clone(),
        vocab::HAS_CHILD_PART.into_owned(),
        child,
    ));
    graph.insert(&Triple::new(
        joint.clone(),
        vocab::HAS_CHILD_PART.into_owned(),
        NamedNode::new_unchecked(t("ghost")),
    ));
    let problems = tosm::read_robot(&graph, ROBOT).expect_err("dangling joint child");
    assert_problem(&problems, joint.as_str(), &prop("hasChildPart"), "dangling");
    // A place connected to an object.
    let graph = object_graph("", "", GOOD_SHAPE);
    let mut graph2 = graph.clone();
    graph2.insert(&Triple::new(
        NamedNode::new_unchecked(t("room")),
        vocab::IS_CONNECTED_TO.into_owned(),
        NamedNode::new_unchecked(t("table")),
    ));
    let problems = tosm::read_places(&graph2).expect_err("connected to an object");
    assert_problem(
        &problems,
        &t("room"),
        &prop("isConnectedTo"),
        "not a tosm:Place",
    );
    // A robot that is not in the graph.
    let problems = tosm::read_robot(&graph, &t("robot")).expect_err("no such robot");
    assert_problem(&problems, &t("robot"), rdf::TYPE.as_str(), "not described");
}

#[test]
fn repeated_values_and_blank_nodes_are_reported() {
    let problems = object_problems("", "; tosm:xM 2", GOOD_SHAPE);
    assert_problem(&problems, &t("pose"), &prop("xM"), "2 values");
    let graph = parse_turtle(&format!(
        "{PREFIXES} [] a tosm:Chair ; tosm:name \"anonymous\" ."
    ));
    let problems = tosm::read_objects(&graph).expect_err("blank node");
    assert!(
        problems
            .iter()
            .any(|p| p.individual.starts_with("_:") && p.message.contains("IRI")),
        "{problems}"
    );
}

#[test]
fn robot_problems_are_reported() {
    let graph = load("robots/differential-robot.ttl");
    let laser = NamedNode::new_unchecked(format!("{ROBOT}/laser"));
    let base = NamedNode::new_unchecked(format!("{ROBOT}/base"));
    let mut bad = graph.clone();
    for (s, p) in [(&laser, vocab::SAMPLE_COUNT), (&base, vocab::MASS_KG)] {
        let o = bad
            .object_for_subject_predicate(s, p)
            .map(|t| t.into_owned())
            .expect("value");
        bad.remove(&Triple::new(s.clone(), p.into_owned(), o));
    }
    bad.insert(&Triple::new(
        laser.clone(),
        vocab::SAMPLE_COUNT.into_owned(),
        Literal::new_typed_literal("0", oxrdf::vocab::xsd::INTEGER),
    ));
    let problems = tosm::read_robot(&bad, ROBOT).expect_err("bad robot");
    assert_problem(&problems, laser.as_str(), &prop("sampleCount"), ">= 1");
    assert_problem(&problems, base.as_str(), &prop("massKg"), "missing");
}

#[test]
fn metric_map_problems_are_reported() {
    let graph = parse_turtle(&format!(
        "{PREFIXES} ex:floor a tosm:Floor ; tosm:name \"F\" ; tosm:hasMetricMap ex:map .
        ex:map a tosm:OccupancyGridMap ; tosm:resolutionM -0.05 ; tosm:originXM 0 ; tosm:originYM 0 ;
            tosm:occupiedThreshold 0.65 ; tosm:freeThreshold 0.196 ; tosm:widthCells 2 ; tosm:heightCells 2 ;
            tosm:mapImagePng \"!!!not base64\"^^xsd:base64Binary ."
    ));
    let problems = tosm::read_places(&graph).expect_err("bad map");
    assert_problem(&problems, &t("map"), &prop("resolutionM"), "> 0");
    assert_problem(&problems, &t("map"), &prop("mapImagePng"), "base64");

    let grid = tosm::OccupancyGrid::filled(
        3,
        2,
        0.1,
        tosm::Pose2::new(0.0, 0.0, 0.0),
        tosm::Occupancy::Free,
    );
    let mut triples =
        tosm::occupancy_grid_to_triples(&t("floor"), &grid, &grid.to_png()).expect("valid map");
    // Claim a different size than the image has.
    let map = NamedNode::new_unchecked(format!("{}/map", t("floor")));
    triples.retain(|t| t.predicate != vocab::WIDTH_CELLS);
    triples.push(Triple::new(
        map.clone(),
        vocab::WIDTH_CELLS.into_owned(),
        Literal::new_typed_literal("4", oxrdf::vocab::xsd::INTEGER),
    ));
    triples.push(Triple::new(
        NamedNode::new_unchecked(t("floor")),
        rdf::TYPE,
        vocab::FLOOR.into_owned(),
    ));
    triples.push(Triple::new(
        NamedNode::new_unchecked(t("floor")),
        vocab::NAME.into_owned(),
        Literal::new_simple_literal("F"),
    ));
    let problems = tosm::read_places(&graph_of(triples)).expect_err("size mismatch");
    assert_problem(&problems, map.as_str(), &prop("widthCells"), "4x2");
}

#[test]
fn a_map_states_its_ros_frame_and_defaults_to_rep_105_map() {
    let grid = tosm::OccupancyGrid::filled(
        3,
        2,
        0.1,
        tosm::Pose2::new(0.0, 0.0, 0.0),
        tosm::Occupancy::Free,
    );
    let floor = NamedNode::new_unchecked(t("floor"));
    let map = NamedNode::new_unchecked(format!("{}/map", t("floor")));
    let with_frame = |frame: Option<&str>| {
        let mut triples = tosm::occupancy_grid_to_triples(floor.as_str(), &grid, &grid.to_png())
            .expect("valid map");
        // The writer states the default.
        assert!(triples.iter().any(|t| t.predicate == vocab::FRAME_ID
            && t.object == Term::Literal(Literal::new_simple_literal("map"))));
        triples.retain(|t| t.predicate != vocab::FRAME_ID);
        if let Some(frame) = frame {
            triples.push(Triple::new(
                map.clone(),
                vocab::FRAME_ID.into_owned(),
                Literal::new_simple_literal(frame),
            ));
        }
        triples.push(Triple::new(
            floor.clone(),
            rdf::TYPE,
            vocab::FLOOR.into_owned(),
        ));
        triples.push(Triple::new(
            floor.clone(),
            vocab::NAME.into_owned(),
            Literal::new_simple_literal("F"),
        ));
        tosm::read_places(&graph_of(triples))
    };
    let frame_of = |places: Vec<Place>| places[0].map.as_ref().unwrap().frame_id.clone();
    assert_eq!(frame_of(with_frame(None).expect("no frame stated")), "map");
    assert_eq!(
        frame_of(with_frame(Some("level_2/map")).expect("a ROS name")),
        "level_2/map"
    );
    for bad in ["", "/map", "2nd_floor", "floor two", "map\u{e9}"] {
        let problems = with_frame(Some(bad)).expect_err(bad);
        assert_problem(&problems, map.as_str(), &prop("frameId"), "ROS frame name");
    }
    // Writing refuses one too.
    let mut m = tosm::MetricMap::from_grid(map.as_str(), grid.clone());
    m.frame_id = "a b".into();
    assert!(tosm::metric_map_to_triples(floor.as_str(), &m).is_err());
}

#[test]
fn writers_validate_values() {
    let mut object = sample_object();
    object.shape = Shape::Box {
        length: -1.0,
        width: 1.0,
        height: f64::NAN,
    };
    object.colour = Some(Colour::rgb(2.0, 0.0, 0.0));
    object.inside_of = "not an iri".to_owned();
    object.symbol.name = String::new();
    let problems = tosm::object_to_triples(&object).expect_err("invalid object");
    assert_problem(
        &problems,
        &format!("{}/shape", t("box-1")),
        &prop("lengthM"),
        "> 0",
    );
    assert_problem(
        &problems,
        &format!("{}/shape", t("box-1")),
        &prop("heightM"),
        "NaN",
    );
    assert_problem(&problems, &t("box-1"), &prop("colourRed"), "[0, 1]");
    assert_problem(
        &problems,
        &t("box-1"),
        &prop("isDirectlyInsideOf"),
        "not a valid IRI",
    );
    assert_problem(&problems, &t("box-1"), &prop("name"), "missing");

    let mut room = sample_room();
    room.complexity = Some(1.7);
    room.boundary.truncate(2);
    let problems = tosm::place_to_triples(&room).expect_err("invalid room");
    assert_problem(&problems, &t("room"), &prop("complexity"), "1.7");
    assert_problem(
        &problems,
        &t("room"),
        &prop("hasBoundaryPoint"),
        "at least 3",
    );

    let graph = load("robots/differential-robot.ttl");
    let mut robot: Robot = tosm::read_robot(&graph, ROBOT).expect("robot");
    robot.joints[0].child = t("ghost");
    robot.lasers[0].range_min = 20.0;
    let problems = tosm::robot_to_triples(&robot).expect_err("invalid robot");
    assert_problem(
        &problems,
        &robot.joints[0].iri,
        &prop("hasChildPart"),
        "dangling",
    );
    assert_problem(
        &problems,
        &robot.lasers[0].part.iri,
        &prop("rangeMaxM"),
        "exceed",
    );
}

/// A small deterministic generator, so the mangling test needs no extra dependency.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

#[test]
fn mangled_graphs_never_panic() {
    let mut base: Vec<Triple> = Vec::new();
    for file in [
        "robots/differential-robot.ttl",
        "environments/sample-building.ttl",
    ] {
        base.extend(load(file).iter().map(|t| t.into_owned()));
    }
    // The map images are large; keep the mangling on the small triples and one map.
    base.sort_by_cached_key(ToString::to_string);
    let garbage: Vec<Term> = vec![
        Literal::new_simple_literal("abc").into(),
        Literal::new_typed_literal("-1", oxrdf::vocab::xsd::DECIMAL).into(),
        Literal::new_typed_literal("1e400", oxrdf::vocab::xsd::DOUBLE).into(),
        Literal::new_typed_literal("x", oxrdf::vocab::xsd::BASE_64_BINARY).into(),
        Literal::new_typed_literal("99999999999999999999", oxrdf::vocab::xsd::INTEGER).into(),
        NamedNode::new_unchecked(t("ghost")).into(),
        NamedNode::new_unchecked(ROBOT).into(),
        vocab::ROOM.into_owned().into(),
        oxrdf::BlankNode::default().into(),
    ];
    let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
    for round in 0..200 {
        let mut triples = base.clone();
        for _ in 0..(1 + rng.below(6)) {
            let i = rng.below(triples.len());
            match rng.below(3) {
                0 => {
                    triples.swap_remove(i);
                }
                1 => {
                    let g = garbage[rng.below(garbage.len())].clone();
                    triples[i].object = g;
                }
                _ => {
                    let j = rng.below(triples.len());
                    let subject = triples[j].subject.clone();
                    triples[i].subject = subject;
                }
            }
        }
        let graph = graph_of(triples);
        let (_, place_problems) = tosm::read_places_lenient(&graph);
        let (_, object_problems) = tosm::read_objects_lenient(&graph);
        let (people, people_problems) = tosm::read_people_lenient(&graph);
        let robot = tosm::read_robot(&graph, ROBOT);
        let _ = tosm::read_robots(&graph);
        for p in place_problems
            .iter()
            .chain(object_problems.iter())
            .chain(people_problems.iter())
        {
            assert!(
                !p.individual.is_empty() && !p.property.is_empty(),
                "round {round}: {p}"
            );
        }
        if let Ok(robot) = robot {
            // Whatever reads back without problems also writes without problems.
            tosm::robot_to_triples(&robot).unwrap_or_else(|p| panic!("round {round}: {p}"));
        }
        for p in &people.places {
            tosm::place_people_to_triples(p).unwrap_or_else(|e| panic!("round {round}: {e}"));
        }
        for r in &people.routes {
            tosm::walking_route_to_triples(r).unwrap_or_else(|e| panic!("round {round}: {e}"));
        }
        for a in &people.attractors {
            tosm::attractor_to_triples(a).unwrap_or_else(|e| panic!("round {round}: {e}"));
        }
    }
}

/// What the knowledge service materialises (class and property hierarchy, symmetric and
/// inverse properties, transitive containment) must not change what the readers return.
#[test]
fn reading_is_unchanged_by_materialised_entailments() {
    let ontology = load("tosm.ttl");
    let mut data: Vec<Triple> = Vec::new();
    for file in [
        "robots/differential-robot.ttl",
        "environments/sample-building.ttl",
    ] {
        data.extend(load(file).iter().map(|t| t.into_owned()));
    }
    let plain = graph_of(data.clone());
    let named = |t: oxrdf::TermRef<'_>| match t {
        oxrdf::TermRef::NamedNode(n) => Some(n.into_owned()),
        _ => None,
    };
    let supers = |p: oxrdf::NamedNodeRef<'_>, x: &NamedNode| -> Vec<NamedNode> {
        let mut out = vec![];
        let mut todo = vec![x.clone()];
        while let Some(c) = todo.pop() {
            for s in ontology
                .objects_for_subject_predicate(&c, p)
                .filter_map(named)
            {
                if !out.contains(&s) {
                    out.push(s.clone());
                    todo.push(s);
                }
            }
        }
        out
    };
    let rdfs_sub_class = oxrdf::vocab::rdfs::SUB_CLASS_OF;
    let rdfs_sub_property = oxrdf::vocab::rdfs::SUB_PROPERTY_OF;
    let mut inferred = graph_of(data.clone());
    for t in &data {
        if t.predicate == rdf::TYPE {
            if let Term::NamedNode(c) = &t.object {
                for s in supers(rdfs_sub_class, c) {
                    inferred.insert(&Triple::new(t.subject.clone(), rdf::TYPE, s));
                }
            }
        } else {
            for p in supers(rdfs_sub_property, &t.predicate) {
                inferred.insert(&Triple::new(t.subject.clone(), p, t.object.clone()));
            }
        }
        let symmetric = [vocab::IS_CONNECTED_TO, vocab::IS_NEXT_TO];
        if symmetric.contains(&t.predicate.as_ref())
            && let (NamedOrBlankNode::NamedNode(s), Term::NamedNode(o)) = (&t.subject, &t.object)
        {
            inferred.insert(&Triple::new(o.clone(), t.predicate.clone(), s.clone()));
        }
    }
    // Transitive containment and its inverse.
    let inside: Vec<(NamedNode, NamedNode)> = inferred
        .triples_for_predicate(vocab::IS_DIRECTLY_INSIDE_OF)
        .filter_map(|t| match (t.subject, t.object) {
            (oxrdf::NamedOrBlankNodeRef::NamedNode(s), oxrdf::TermRef::NamedNode(o)) => {
                Some((s.into_owned(), o.into_owned()))
            }
            _ => None,
        })
        .collect();
    for (s, o) in &inside {
        let mut next = Some(o.clone());
        while let Some(c) = next {
            inferred.insert(&Triple::new(
                s.clone(),
                vocab::IS_INSIDE_OF.into_owned(),
                c.clone(),
            ));
            inferred.insert(&Triple::new(
                c.clone(),
                vocab::CONTAINS.into_owned(),
                s.clone(),
            ));
            next = inside.iter().find(|(x, _)| *x == c).map(|(_, p)| p.clone());
        }
    }
    assert!(inferred.len() > plain.len());
    assert_eq!(
        tosm::read_places(&inferred).expect("places"),
        tosm::read_places(&plain).expect("places")
    );
    assert_eq!(
        tosm::read_objects(&inferred).expect("objects"),
        tosm::read_objects(&plain).expect("objects")
    );
    assert_eq!(
        tosm::read_robots(&inferred).expect("robots"),
        tosm::read_robots(&plain).expect("robots")
    );
    let people = tosm::read_people(&plain).expect("people");
    assert!(!people.routes.is_empty() && !people.attractors.is_empty());
    assert_eq!(tosm::read_people(&inferred).expect("people"), people);
}
