//! What the model knows about people: expected numbers (all day and by hour), robots' running
//! estimates, walking routes and attractors survive a round trip through triples; bad values
//! are reported with the individual and property; the estimate moves as documented; and the
//! figures a simulation uses prefer robots' counts to an engineer's.

use oxrdf::Graph;
use tosm::{
    Attractor, PeopleEstimate, PlacePeople, Pose3, Problems, Relation, RelationKind, WalkingRoute,
};

const PREFIXES: &str = "@prefix tosm: <https://mentalsim.dev/ontology/tosm#> .\n\
                        @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .\n\
                        @prefix ex: <https://example.org/> .\n";

fn t(s: &str) -> String {
    format!("https://example.org/{s}")
}

fn prop(local: &str) -> String {
    format!("{}{local}", tosm::vocab::NS)
}

fn parse_turtle(text: &str) -> Graph {
    let mut graph = Graph::new();
    for t in oxttl::TurtleParser::new().for_slice(text.as_bytes()) {
        graph.insert(&t.expect("valid turtle"));
    }
    graph
}

fn assert_problem(problems: &Problems, individual: &str, property: &str, needle: &str) {
    assert!(
        problems.iter().any(|p| p.individual == individual
            && p.property == property
            && p.message.contains(needle)),
        "expected a problem on <{individual}> <{property}> containing {needle:?}; got {problems}"
    );
}

/// A corridor in a building and a vending machine, as Turtle.
fn places() -> String {
    format!(
        "{PREFIXES}
ex:building a tosm:Building ; tosm:name \"Building\" .
ex:corridor a tosm:Corridor ; tosm:name \"Corridor\" ; tosm:isDirectlyInsideOf ex:building ;
    tosm:hasBoundaryPoint ex:c0, ex:c1, ex:c2 .
ex:c0 a tosm:BoundaryPoint ; tosm:pointIndex 0 ; tosm:xM 0.0 ; tosm:yM 0.0 .
ex:c1 a tosm:BoundaryPoint ; tosm:pointIndex 1 ; tosm:xM 10.0 ; tosm:yM 0.0 .
ex:c2 a tosm:BoundaryPoint ; tosm:pointIndex 2 ; tosm:xM 10.0 ; tosm:yM 2.0 .
ex:machine a tosm:VendingMachine ; tosm:name \"Machine\" .
"
    )
}

fn sample_people() -> PlacePeople {
    PlacePeople {
        place: t("corridor"),
        expected: Some(1.5),
        by_hour: vec![(9, 4.0), (12, 6.0)],
        estimates: vec![
            PeopleEstimate {
                hour: None,
                people: 2.25,
                observations: 7,
                last_observed_at: Some("2025-05-06T12:30:00+02:00".to_owned()),
            },
            PeopleEstimate {
                hour: Some(12),
                people: 5.0,
                observations: 2,
                last_observed_at: Some("2025-05-06T12:30:00+02:00".to_owned()),
            },
        ],
    }
}

fn sample_route() -> WalkingRoute {
    WalkingRoute {
        iri: t("route-1"),
        name: Some("Along the corridor".to_owned()),
        inside_of: t("corridor"),
        points: vec![(0.5, 1.0), (5.0, 1.0), (9.5, 1.5)],
    }
}

fn sample_attractor() -> Attractor {
    Attractor {
        iri: t("coffee"),
        name: None,
        inside_of: t("corridor"),
        pose: Pose3::new(8.0, 1.0, 0.0, 0.0),
        dwell_s: 45.0,
        relations: vec![Relation {
            kind: RelationKind::InFrontOf,
            target: t("machine"),
        }],
    }
}

#[test]
fn people_knowledge_round_trips_through_triples() {
    let mut graph = parse_turtle(&places());
    let people = sample_people();
    for triples in [
        tosm::place_people_to_triples(&people).unwrap(),
        tosm::walking_route_to_triples(&sample_route()).unwrap(),
        tosm::attractor_to_triples(&sample_attractor()).unwrap(),
    ] {
        for tr in &triples {
            graph.insert(tr);
        }
    }
    let read = tosm::read_people(&graph).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(read.places, vec![people.clone()]);
    assert_eq!(read.routes, vec![sample_route()]);
    assert_eq!(read.attractors, vec![sample_attractor()]);
    // Descriptors are named after their owner, as every TOSM descriptor.
    let text: String = graph.iter().map(|t| format!("{t}\n")).collect();
    for iri in [
        "corridor/people/hour/9>",
        "corridor/people/estimate>",
        "corridor/people/estimate/hour/12>",
        "route-1/point/2>",
        "coffee/pose>",
    ] {
        assert!(text.contains(iri), "{iri} missing from\n{text}");
    }
    // The estimates alone, as the knowledge service reads them before adding a count.
    let estimates = tosm::read_people_estimates(&graph, &t("corridor")).unwrap();
    assert_eq!(estimates, people.estimates);
    // The places themselves still read, and nothing about people is taken for an object.
    assert_eq!(tosm::read_places(&graph).unwrap().len(), 2);
    let (objects, problems) = tosm::read_objects_lenient(&graph);
    assert!(objects.is_empty(), "the machine has no pose: {objects:?}");
    assert!(
        problems.iter().all(|p| p.individual == t("machine")),
        "{problems}"
    );
}

#[test]
fn engineers_turtle_reads_with_a_figure_by_hour() {
    let graph = parse_turtle(&format!(
        "{}
ex:corridor tosm:expectedPeople 2 ; tosm:hasHourlyPeopleCount ex:corridor-12 .
ex:corridor-12 a tosm:HourlyPeopleCount ; tosm:hourOfDay 12 ; tosm:expectedPeople 5.5 .
ex:building tosm:expectedPeople 0.5 .
",
        places()
    ));
    let read = tosm::read_people(&graph).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(read.places.len(), 2);
    // Sorted by IRI: the building, then the corridor.
    assert_eq!(read.places[0].place, t("building"));
    assert_eq!(read.places[0].expected, Some(0.5));
    let corridor = &read.places[1];
    assert_eq!(corridor.place, t("corridor"));
    assert_eq!(corridor.expected, Some(2.0));
    assert_eq!(corridor.by_hour, vec![(12, 5.5)]);
}

#[test]
fn bad_people_knowledge_is_reported_by_individual_and_property() {
    let graph = parse_turtle(&format!(
        "{}
ex:corridor tosm:expectedPeople -1 ; tosm:hasHourlyPeopleCount ex:h24, ex:h9a, ex:h9b .
ex:h24 a tosm:HourlyPeopleCount ; tosm:hourOfDay 24 ; tosm:expectedPeople 1 .
ex:h9a a tosm:HourlyPeopleCount ; tosm:hourOfDay 9 ; tosm:expectedPeople 1 .
ex:h9b a tosm:HourlyPeopleCount ; tosm:hourOfDay 9 ; tosm:expectedPeople \"many\" .
ex:building tosm:hasPeopleEstimate ex:e .
ex:e a tosm:PeopleEstimate ; tosm:estimatedPeople 2 ; tosm:observationCount 0 .
ex:machine tosm:expectedPeople 3 .
ex:short a tosm:WalkingRoute ; tosm:isDirectlyInsideOf ex:corridor ; tosm:hasRoutePoint ex:p0 .
ex:p0 a tosm:RoutePoint ; tosm:pointIndex 0 ; tosm:xM 1 ; tosm:yM 1 .
ex:lost a tosm:WalkingRoute ; tosm:isDirectlyInsideOf ex:machine ;
    tosm:hasRoutePoint ex:q0, ex:q1 .
ex:q0 a tosm:RoutePoint ; tosm:pointIndex 0 ; tosm:xM 1 ; tosm:yM 1 .
ex:q1 a tosm:RoutePoint ; tosm:pointIndex 0 ; tosm:xM 2 ; tosm:yM 1 .
ex:idle a tosm:Attractor ; tosm:isDirectlyInsideOf ex:corridor ; tosm:dwellTimeS -5 .
",
        places()
    ));
    let (people, problems) = tosm::read_people_lenient(&graph);
    assert!(people.places.is_empty(), "{people:?}");
    assert!(people.routes.is_empty() && people.attractors.is_empty());
    assert_problem(&problems, &t("corridor"), &prop("expectedPeople"), ">= 0");
    assert_problem(&problems, &t("h24"), &prop("hourOfDay"), "0 to 23");
    assert_problem(
        &problems,
        &t("h9b"),
        &prop("expectedPeople"),
        "must be a number",
    );
    assert_problem(&problems, &t("e"), &prop("observationCount"), ">= 1");
    assert_problem(
        &problems,
        &t("machine"),
        &prop("expectedPeople"),
        "tosm:Place",
    );
    assert_problem(&problems, &t("short"), &prop("hasRoutePoint"), "at least 2");
    assert_problem(
        &problems,
        &t("lost"),
        &prop("isDirectlyInsideOf"),
        "not a tosm:Place",
    );
    assert_problem(&problems, &t("q1"), &prop("pointIndex"), "two route points");
    assert_problem(&problems, &t("idle"), &prop("hasPose"), "missing");
    assert_problem(&problems, &t("idle"), &prop("dwellTimeS"), ">= 0");
    assert!(tosm::read_people(&graph).is_err());

    // Two figures for one hour are reported on the place.
    let graph = parse_turtle(&format!(
        "{}
ex:corridor tosm:hasHourlyPeopleCount ex:h9a, ex:h9b .
ex:h9a a tosm:HourlyPeopleCount ; tosm:hourOfDay 9 ; tosm:expectedPeople 1 .
ex:h9b a tosm:HourlyPeopleCount ; tosm:hourOfDay 9 ; tosm:expectedPeople 2 .
",
        places()
    ));
    let problems = tosm::read_people(&graph).unwrap_err();
    assert_problem(
        &problems,
        &t("corridor"),
        &prop("hasHourlyPeopleCount"),
        "hour 9",
    );
}

#[test]
fn writers_refuse_what_readers_would_refuse() {
    let mut people = sample_people();
    people.expected = Some(f64::NAN);
    people.by_hour.push((24, 1.0));
    people.estimates[0].observations = 0;
    people.estimates[1].people = -2.0;
    let problems = tosm::place_people_to_triples(&people).unwrap_err();
    assert_problem(&problems, &t("corridor"), &prop("expectedPeople"), "NaN");
    assert_problem(
        &problems,
        &format!("{}/people/hour/24", t("corridor")),
        &prop("hourOfDay"),
        "0 to 23",
    );
    assert_problem(
        &problems,
        &format!("{}/people/estimate", t("corridor")),
        &prop("observationCount"),
        ">= 1",
    );
    assert_problem(
        &problems,
        &format!("{}/people/estimate/hour/12", t("corridor")),
        &prop("estimatedPeople"),
        ">= 0",
    );
    let mut route = sample_route();
    route.points.truncate(1);
    route.name = Some("  ".to_owned());
    let problems = tosm::walking_route_to_triples(&route).unwrap_err();
    assert_problem(
        &problems,
        &t("route-1"),
        &prop("hasRoutePoint"),
        "at least 2",
    );
    assert_problem(&problems, &t("route-1"), &prop("name"), "blank");
    let mut attractor = sample_attractor();
    attractor.dwell_s = -1.0;
    let problems = tosm::attractor_to_triples(&attractor).unwrap_err();
    assert_problem(&problems, &t("coffee"), &prop("dwellTimeS"), ">= 0");
}

#[test]
fn the_estimate_is_the_mean_of_five_counts_then_weighs_each_new_one_a_fifth() {
    let mut e: Option<PeopleEstimate> = None;
    let mut seen = Vec::new();
    for (i, count) in [2.0, 4.0, 6.0, 0.0, 8.0].into_iter().enumerate() {
        let next = PeopleEstimate::observe(e.as_ref(), None, count, "2025-05-06T09:00:00Z");
        seen.push(count);
        let mean = seen.iter().sum::<f64>() / seen.len() as f64;
        assert!(
            (next.people - mean).abs() < 1e-12,
            "after {seen:?}: {next:?}"
        );
        assert_eq!(next.observations, i as u64 + 1);
        e = Some(next);
    }
    // The sixth count weighs 0.2 (1/6 would be less).
    let sixth = PeopleEstimate::observe(e.as_ref(), None, 14.0, "2025-05-06T10:00:00Z");
    assert!(
        (sixth.people - (4.0 + 0.2 * (14.0 - 4.0))).abs() < 1e-12,
        "{sixth:?}"
    );
    assert_eq!(sixth.observations, 6);
    assert_eq!(
        sixth.last_observed_at.as_deref(),
        Some("2025-05-06T10:00:00Z")
    );
    assert_eq!(tosm::ESTIMATE_MIN_WEIGHT, 0.2);
    // A steady count is a fixed point; a place that empties is followed.
    let mut e = sixth;
    for _ in 0..30 {
        e = PeopleEstimate::observe(Some(&e), Some(9), 0.0, "2025-05-06T09:30:00Z");
    }
    assert!(e.people < 0.01, "{e:?}");
    assert_eq!(e.hour, Some(9));
}

#[test]
fn robots_counts_win_over_engineers_figures_hour_by_hour() {
    let people = sample_people();
    // All day: the estimate (2.25), not the engineer's 1.5. Hour 12: the hour's estimate (5),
    // not the engineer's 6. Hour 9: only the engineer said.
    assert_eq!(people.figures(), (2.25, vec![(9, 4.0), (12, 5.0)]));
    let engineer_only = PlacePeople {
        estimates: vec![],
        ..sample_people()
    };
    assert_eq!(engineer_only.figures(), (1.5, vec![(9, 4.0), (12, 6.0)]));
    let hours_only = PlacePeople {
        expected: None,
        estimates: vec![],
        ..sample_people()
    };
    assert_eq!(hours_only.figures(), (5.0, vec![(9, 4.0), (12, 6.0)]));
    assert_eq!(PlacePeople::default().figures(), (0.0, vec![]));
}

/// What the knowledge service writes for robots' counts, as the HermiT check reads it
/// (`tests/hermit/perceived-people.ttl`, beside the bundled files): the writer's own output, so
/// the reasoner sees exactly the datatypes and IRIs the service stores. Refresh it with
/// `UPDATE_ONTOLOGIES=1 cargo test --release -p tosm --test tosm people`.
#[test]
fn estimates_as_written_are_the_reasoner_fixture() {
    let hall = "https://mentalsim.dev/data/buildings/sample-building/floors/0/hall";
    let first = PeopleEstimate::observe(None, Some(12), 3.0, "2025-05-06T12:10:00+02:00");
    let hour = PeopleEstimate::observe(Some(&first), Some(12), 2.0, "2025-05-06T12:40:00+02:00");
    let all_day = PeopleEstimate {
        hour: None,
        ..hour.clone()
    };
    let mut triples = Vec::new();
    for e in [&all_day, &hour] {
        triples.extend(tosm::people_estimate_to_triples(hall, e).unwrap());
    }
    triples.sort_by_cached_key(ToString::to_string);
    triples.dedup();
    let mut serializer = oxttl::TurtleSerializer::new()
        .with_prefix("tosm", tosm::vocab::NS)
        .and_then(|s| s.with_prefix("owl", "http://www.w3.org/2002/07/owl#"))
        .and_then(|s| s.with_prefix("xsd", "http://www.w3.org/2001/XMLSchema#"))
        .expect("prefixes")
        .for_writer(Vec::new());
    for t in &triples {
        serializer.serialize_triple(t).expect("serialize");
    }
    let body = String::from_utf8(serializer.finish().expect("finish")).expect("utf-8");
    let generated = format!(
        "# GENERATED by services/tosm/tests/tosm/people.rs: robots' people counts in the sample\n\
         # building's hall, as the knowledge service stores them; the HermiT check reads it.\n\
         # Refresh: UPDATE_ONTOLOGIES=1 cargo test --release -p tosm --test tosm people\n{body}"
    );
    let path = std::path::PathBuf::from(
        std::env::var("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
    )
    .join("../../tests/hermit/perceived-people.ttl");
    if std::env::var_os("UPDATE_ONTOLOGIES").is_some() {
        std::fs::write(&path, &generated).expect("write the fixture");
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "{} is out of date with the writer; run \
         UPDATE_ONTOLOGIES=1 cargo test --release -p tosm --test tosm people",
        path.display()
    );
}
