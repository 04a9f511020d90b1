//! From knowledge to the simulation's people: an engineer's SPARQL update and a robot's counts
//! reach a mission's on-demand database, and the simulation parser reads exactly the expected
//! `PeopleSpec` out of it (robots' estimate where they counted, the engineer's figures
//! elsewhere; only the mission's floor).

#![allow(clippy::unwrap_used)] // reason: tests

use std::sync::Arc;
use std::time::Duration;

use crate::support::{ENGINEER_TOKEN, ROBOT_TOKEN, engineer_and_robot};
use knowledge::{Knowledge, KnowledgeStore, QueryLimits};
use sim::{AttractorSpec, PeoplePlaceSpec};

const FLOOR0: &str = "https://mentalsim.dev/data/buildings/sample-building/floors/0";
const ROBOT: &str = "https://mentalsim.dev/data/robots/differential-robot";

/// A place's id, all-day figure and figures by hour.
type PlaceFigures = (String, f64, Vec<(u8, f64)>);

/// The REST API and the protocols over a fresh in-memory store holding the bundled data.
async fn spawn() -> String {
    let store = KnowledgeStore::in_memory().unwrap();
    knowledge::bundled::load_if_empty(&store).unwrap();
    let k = Arc::new(Knowledge::new(
        store,
        engineer_and_robot(),
        QueryLimits::default(),
    ));
    let app = edge::middleware::stack(
        knowledge::api::router(k.clone()).merge(knowledge::protocol::router(k)),
        edge::middleware::Limits {
            request_timeout: Duration::from_secs(60),
            body_limit: 1024 * 1024,
        },
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, app).await });
    format!("http://{address}")
}

#[tokio::test]
async fn the_simulation_parser_reads_the_people_a_missions_database_carries() {
    let base = spawn().await;
    let client = reqwest::Client::new();
    // The engineer: fewer people in the office all day, more at ten.
    let update = format!(
        "PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>
         DELETE {{ GRAPH ?g {{ <{FLOOR0}/office> tosm:expectedPeople ?n }} }}
         INSERT {{ GRAPH ?g {{ <{FLOOR0}/office> tosm:expectedPeople 0.8 ;
                                 tosm:hasHourlyPeopleCount <{FLOOR0}/office/people/hour/10> .
                               <{FLOOR0}/office/people/hour/10> a tosm:HourlyPeopleCount ;
                                 tosm:hourOfDay 10 ; tosm:expectedPeople 2.5 . }} }}
         WHERE {{ GRAPH ?g {{ <{FLOOR0}/office> tosm:expectedPeople ?n }} }}"
    );
    let r = client
        .post(format!("{base}/sparql"))
        .bearer_auth(ENGINEER_TOKEN)
        .header("content-type", "application/sparql-update")
        .body(update)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204, "{}", r.text().await.unwrap());
    // A robot counts people in the hall: twice at noon (local time), once without a time.
    let r = client
        .post(format!("{base}/v1/places/F0-hall/observations"))
        .bearer_auth(ROBOT_TOKEN)
        .json(&serde_json::json!({"observations": [
            {"count": 2, "observed_at": "2025-05-06T12:10:00+02:00"},
            {"count": 4, "observed_at": "2025-05-06T12:50:00+02:00"},
            {"count": 0}
        ]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());

    // A mission from the office to the hallway: the hall, the living room and the routes are
    // off it, and still in its database.
    let r = client
        .post(format!("{base}/v1/on-demand"))
        .bearer_auth(ROBOT_TOKEN)
        .header("accept", "application/n-triples")
        .json(&serde_json::json!({
            "robot": "R-001",
            "start": {"place": "F0-office"},
            "goals": [{"place": "F0-hallway"}]
        }))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let text = r.text().await.unwrap();
    let mut graph = oxigraph::model::Graph::new();
    for t in oxigraph::io::RdfParser::from_format(oxigraph::io::RdfFormat::NTriples)
        .for_slice(text.as_bytes())
    {
        graph.insert(&oxigraph::model::Triple::from(t.unwrap()));
    }
    let spec = sim::parse_on_demand(&graph, ROBOT).unwrap_or_else(|p| panic!("{p}"));
    let people = &spec.people;
    let place = |slug: &str, expected: f64, by_hour: Vec<(u8, f64)>| {
        (format!("{FLOOR0}/{slug}"), expected, by_hour)
    };
    let got: Vec<PlaceFigures> = people
        .places
        .iter()
        .map(|p: &PeoplePlaceSpec| (p.id.clone(), p.expected, p.by_hour.clone()))
        .collect();
    assert_eq!(
        got,
        vec![
            // Robots' counts: mean of 2, 4 and 0 all day, of 2 and 4 at noon; the engineer's
            // 2 at one o'clock stays.
            place("hall", 2.0, vec![(12, 3.0), (13, 2.0)]),
            place("hallway", 0.5, vec![(8, 1.5), (12, 2.0), (17, 1.5)]),
            place("living-room", 1.5, vec![(12, 4.0), (13, 3.0), (15, 2.0)]),
            place("office", 0.8, vec![(10, 2.5)]),
        ]
    );
    assert!(people.places.iter().all(|p| p.boundary.len() >= 4));
    let routes: Vec<&str> = people.routes.iter().map(|r| r.id.as_str()).collect();
    assert_eq!(
        routes,
        [
            format!("{FLOOR0}/routes/bedroom-door-to-hall"),
            format!("{FLOOR0}/routes/hall-to-vending-machine"),
        ]
    );
    assert_eq!(
        people.attractors,
        vec![AttractorSpec {
            id: format!("{FLOOR0}/attractors/vending-machine"),
            position: [3.3, -2.0],
            dwell_s: 60.0,
        }]
    );
    // Only the floor's objects on the route: the living room's vending machine is not in it.
    assert!(spec.objects.is_empty(), "{:?}", spec.objects);
    assert!(spec.validate().is_empty(), "{}", spec.validate());
}
