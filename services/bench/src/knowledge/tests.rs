//! Unit tests of the knowledge benchmark's parts (the run itself needs both servers).

use super::*;

#[test]
fn replicas_have_fresh_iris_and_identifiers() {
    let r = replicate(5_000).unwrap();
    assert!(r.triples.len() >= 5_000);
    assert_eq!(r.triples.len(), r.copies * r.per_copy);
    let sample = parse_sample().unwrap();
    let original: HashSet<String> = sample.iter().map(|t| t.subject.to_string()).collect();
    assert!(
        r.triples
            .iter()
            .all(|t| !original.contains(&t.subject.to_string())),
        "every copied subject is new"
    );
    assert!(
        r.triples
            .iter()
            .any(|t| t.object.to_string() == "\"C1-F0-bedroom\"")
    );
    // The copies' floors stay in the one building.
    assert!(
        r.triples
            .iter()
            .any(|t| t.object.to_string() == format!("<{BUILDING}>"))
    );
    let (start, goal, places) = mission(2).unwrap();
    assert!(start.starts_with("C2-") && goal.starts_with("C2-"));
    assert!(places >= 3, "{start} -> {goal}: {places}");
}

#[test]
fn the_ratio_check_fails_below_the_minimum_and_names_the_figures() {
    let report = |ratio: f64| KnowledgeBenchReport {
        triples: 0,
        floor_copies: 0,
        floors: 0,
        load_s: 0.0,
        on_demand_route_places: 0,
        on_demand_triples: 0,
        on_demand_p50_ms: 0.0,
        on_demand_p99_ms: 0.0,
        on_demand_requests: 0,
        on_demand_after_write_p50_ms: 0.0,
        on_demand_after_write_requests: 0,
        clients: 4,
        seconds: 10.0,
        queries_per_s_ours: 700.0 * ratio,
        queries_per_s_oxigraph_server: 700.0,
        ratio,
        target_ratio: TARGET_RATIO,
        by_kind: vec![QueryKindReport {
            kind: "join".to_owned(),
            ours: 1.0,
            oxigraph_server: 2.0,
            ratio: 0.5,
        }],
        oxigraph_version: String::new(),
        release_build: true,
    };
    assert!(report(0.95).check_ratio(0.9).is_ok());
    assert!(report(0.9).check_ratio(0.9).is_ok());
    let message = report(0.7).check_ratio(0.9).unwrap_err();
    assert!(message.contains("0.700x"), "{message}");
    assert!(message.contains("minimum 0.9"), "{message}");
    assert!(message.contains("join 0.500"), "{message}");
    assert!(report(f64::NAN).check_ratio(0.9).is_err());
}

#[test]
fn percentiles_pick_ranks() {
    let v: Vec<f64> = (1..=100).map(f64::from).collect();
    assert_eq!(percentile(&v, 50.0), 50.0);
    assert_eq!(percentile(&v, 99.0), 99.0);
}
