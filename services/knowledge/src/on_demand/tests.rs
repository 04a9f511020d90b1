//! The on-demand database's tests: missions over the bundled building.

use super::*;

fn store() -> KnowledgeStore {
    let store = KnowledgeStore::in_memory().unwrap();
    crate::bundled::load_if_empty(&store).unwrap();
    store
}

fn robot() -> String {
    "https://mentalsim.dev/data/robots/differential-robot".to_owned()
}

fn places(store: &KnowledgeStore) -> Vec<Place> {
    all_places(store).unwrap().to_vec()
}

#[test]
fn sample_building_places_read_without_problems() {
    let store = store();
    let places = places(&store);
    assert!(
        places
            .iter()
            .any(|p| p.kind == PlaceKind::Floor && p.map.is_some())
    );
    assert!(places.iter().any(|p| p.kind == PlaceKind::Room));
}

#[test]
fn a_stopped_request_builds_nothing() {
    let store = store();
    let floor = places(&store)
        .into_iter()
        .find(|p| p.kind == PlaceKind::Floor)
        .unwrap();
    let mission = Mission {
        robot: robot(),
        start: Waypoint::Place(floor.iri.clone()),
        goals: vec![Waypoint::Place(floor.iri.clone()); 1000],
    };
    let stop = grid::Stop::new();
    assert!(build_until(&store, &mission, &stop).is_ok());
    stop.request();
    assert!(matches!(
        build_until(&store, &mission, &stop),
        Err(OnDemandError::Stopped)
    ));
}

#[test]
fn a_mission_between_two_rooms_holds_the_route_objects_map_and_robot() {
    let store = store();
    let places = places(&store);
    // Two connected rooms that are not the same place.
    let room = places
        .iter()
        .find(|p| {
            p.kind != PlaceKind::Floor && p.kind != PlaceKind::Building && !p.connected.is_empty()
        })
        .unwrap();
    let goal = room.connected[0].clone();
    let mission = Mission {
        robot: robot(),
        start: Waypoint::Place(room.iri.clone()),
        goals: vec![Waypoint::Place(goal.clone())],
    };
    let db = build(&store, &mission).unwrap();
    assert_eq!(db.route, vec![room.iri.clone(), goal]);
    assert_eq!(db.floors.len(), 1);
    let graph: Graph = db.triples.iter().cloned().collect();
    // Self-sufficient: the typed readers find the robot, the route's places and a map.
    tosm::read_robot(&graph, &robot()).unwrap();
    let read = tosm::read_places(&graph).unwrap();
    assert!(read.iter().any(|p| p.map.is_some()));
    // Nothing else: no place off the route except ancestors and the places people are
    // expected in, and no object off the route.
    let about = |iri: &str| {
        graph
            .iter()
            .any(|t| t.subject.to_string() == format!("<{iri}>"))
    };
    let people = tosm::read_people(&graph).unwrap();
    let off_route = places.iter().filter(|p| {
        !db.route.contains(&p.iri) && p.kind != PlaceKind::Floor && p.kind != PlaceKind::Building
    });
    let mut people_places = 0;
    for p in off_route {
        let has_people = people.places.iter().any(|q| q.place == p.iri);
        people_places += usize::from(has_people);
        assert_eq!(about(&p.iri), has_people, "{} leaked or is missing", p.iri);
    }
    assert!(
        people_places > 0,
        "the sample expects people off this route"
    );
    let objects = tosm::read_objects(&graph).unwrap();
    assert!(
        objects.iter().all(|o| db.route.contains(&o.inside_of)),
        "objects off the route: {objects:?}"
    );
    // The floor's walking routes and attractor, whichever places they are in.
    assert_eq!((people.routes.len(), people.attractors.len()), (2, 1));
    // Deterministic.
    let again = build(&store, &mission).unwrap();
    assert_eq!(again.triples, db.triples);
}

/// A triple written about a place of the route (as the service writes: the store, then the
/// inference refreshed) is in the next database, and one removed is gone: nothing read for
/// one database outlives a write.
#[test]
fn a_write_shows_in_the_next_database() {
    let store = store();
    let room = places(&store)
        .into_iter()
        .find(|p| p.kind == PlaceKind::Room && !p.connected.is_empty())
        .unwrap();
    let mission = Mission {
        robot: robot(),
        start: Waypoint::Place(room.iri.clone()),
        goals: vec![Waypoint::Place(room.connected[0].clone())],
    };
    let before = build(&store, &mission).unwrap();
    // Read again, from the closures kept for this state: the same database.
    assert_eq!(build(&store, &mission).unwrap().triples, before.triples);
    let comment = oxigraph::model::Quad::new(
        NamedNode::new_unchecked(room.iri.clone()),
        oxigraph::model::vocab::rdfs::COMMENT,
        oxigraph::model::Literal::new_simple_literal("freshly painted"),
        oxigraph::model::GraphName::DefaultGraph,
    );
    store.insert(std::slice::from_ref(&comment)).unwrap();
    crate::inference::refresh(&store).unwrap();
    let after = build(&store, &mission).unwrap();
    let said = |db: &OnDemandDatabase| {
        db.triples
            .iter()
            .any(|t| t.object.to_string().contains("freshly painted"))
    };
    assert!(!said(&before));
    assert!(
        said(&after),
        "the cached read of {} was served after a write",
        room.iri
    );
    assert_eq!(after.triples.len(), before.triples.len() + 1);
    store.embedded().unwrap().remove(comment.as_ref()).unwrap();
    crate::inference::refresh(&store).unwrap();
    assert_eq!(build(&store, &mission).unwrap().triples, before.triples);
}

#[test]
fn points_resolve_to_the_smallest_place_holding_them() {
    let store = store();
    let places = places(&store);
    let room = places
        .iter()
        .find(|p| p.kind == PlaceKind::Room && p.boundary.len() >= 3)
        .unwrap();
    let (cx, cy) = room
        .boundary
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let n = room.boundary.len() as f64;
    let mission = Mission {
        robot: "R-001".to_owned(),
        start: Waypoint::Point {
            x: cx / n,
            y: cy / n,
            floor: None,
        },
        goals: vec![Waypoint::Place(room.iri.clone())],
    };
    let db = build(&store, &mission).unwrap();
    assert_eq!(db.route, vec![room.iri.clone()]);
}

#[test]
fn bad_missions_name_what_is_wrong() {
    let store = store();
    let any_place = places(&store)[0].iri.clone();
    let mission = |robot: &str, start: Waypoint, goals: Vec<Waypoint>| Mission {
        robot: robot.to_owned(),
        start,
        goals,
    };
    let err = build(
        &store,
        &mission(
            "R-999",
            Waypoint::Place(any_place.clone()),
            vec![Waypoint::Place(any_place.clone())],
        ),
    )
    .unwrap_err();
    assert!(matches!(err, OnDemandError::UnknownRobot(_)), "{err}");
    let err = build(
        &store,
        &mission("R-001", Waypoint::Place(any_place.clone()), vec![]),
    )
    .unwrap_err();
    assert!(matches!(err, OnDemandError::NoGoals), "{err}");
    let far = Waypoint::Point {
        x: 1e6,
        y: 1e6,
        floor: None,
    };
    let err = build(
        &store,
        &mission("R-001", far, vec![Waypoint::Place(any_place.clone())]),
    )
    .unwrap_err();
    assert!(
        matches!(err, OnDemandError::OutsideEveryPlace { .. }),
        "{err}"
    );
    let nan = Waypoint::Point {
        x: f64::NAN,
        y: 0.0,
        floor: None,
    };
    let err = build(
        &store,
        &mission("R-001", nan, vec![Waypoint::Place(any_place.clone())]),
    )
    .unwrap_err();
    assert!(matches!(err, OnDemandError::NotFinite { .. }), "{err}");
    let err = build(
        &store,
        &mission(
            "R-001",
            Waypoint::Place("nowhere".into()),
            vec![Waypoint::Place(any_place)],
        ),
    )
    .unwrap_err();
    assert!(matches!(err, OnDemandError::UnknownPlace { .. }), "{err}");
    assert!(err.is_client_error());
}

#[test]
fn places_on_different_floors_without_a_link_are_not_connected() {
    let store = store();
    let places = places(&store);
    let floors: Vec<&Place> = places
        .iter()
        .filter(|p| p.kind == PlaceKind::Floor)
        .collect();
    assert!(floors.len() >= 2, "the sample building has two floors");
    let index: HashMap<&str, &Place> = places.iter().map(|p| (p.iri.as_str(), p)).collect();
    let a = places
        .iter()
        .find(|p| p.kind == PlaceKind::Room && on_floor(&index, p, &floors[0].iri))
        .unwrap();
    let b = places
        .iter()
        .find(|p| {
            p.kind != PlaceKind::Floor
                && p.kind != PlaceKind::Building
                && on_floor(&index, p, &floors[1].iri)
        })
        .unwrap();
    let err = build(
        &store,
        &Mission {
            robot: "R-001".into(),
            start: Waypoint::Place(a.iri.clone()),
            goals: vec![Waypoint::Place(b.iri.clone())],
        },
    )
    .unwrap_err();
    assert!(matches!(err, OnDemandError::NotConnected { .. }), "{err}");
}
