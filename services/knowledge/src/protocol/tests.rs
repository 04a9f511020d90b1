//! Tests that need the module's insides: the deadline guard, and a client that hangs up while
//! its query runs.

#![allow(clippy::unwrap_used)] // reason: tests

use std::sync::Arc;
use std::time::{Duration, Instant};

use edge::Tokens;

use super::*;
use crate::{KnowledgeStore, QueryLimits};

/// A deadline of `limit` with reads counted in a state of its own.
fn deadline(limit: Duration) -> Deadline {
    Deadline::start(&Arc::new(ReadState::new()), limit)
}

#[tokio::test]
async fn dropping_the_deadline_cancels_its_token() {
    let deadline = deadline(Duration::from_secs(60));
    let token = deadline.token();
    assert!(!token.is_cancelled());
    drop(deadline);
    assert!(token.is_cancelled());
}

#[tokio::test]
async fn a_write_is_cancelled_at_its_deadline_and_its_outcome_awaited() {
    let deadline = deadline(Duration::from_millis(50));
    let token = deadline.token();
    let started = Instant::now();
    let outcome = deadline
        .write(move || {
            while !token.is_cancelled() {
                std::thread::sleep(Duration::from_millis(5));
            }
            Ok("unwound")
        })
        .await;
    assert_eq!(outcome.unwrap(), "unwound");
    assert!(started.elapsed() >= Duration::from_millis(50));
}

#[tokio::test]
async fn a_read_answers_at_its_deadline_and_cancels() {
    let deadline = deadline(Duration::from_millis(50));
    let token = deadline.token();
    let seen = token.clone();
    let outcome = deadline
        .read(move || {
            while !token.is_cancelled() {
                std::thread::sleep(Duration::from_millis(5));
            }
            Ok(())
        })
        .await;
    assert_eq!(outcome.unwrap_err().code(), ErrorCode::Timeout);
    assert!(seen.is_cancelled());
}

/// A read that was short last time runs in place; when it is slow this time, its leash stops
/// it long before its deadline and it runs again, from the start, on a blocking thread.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_read_that_outgrows_its_leash_in_place_runs_again_on_a_blocking_thread() {
    let reads = Arc::new(ReadState::new());
    let key = inline::key(&["outgrows its leash"]);
    reads.record(
        key,
        inline::Cost {
            cpu: Some(Duration::from_micros(100)),
            wall: Duration::from_micros(100),
        },
    );
    let deadline = Deadline::start(&reads, Duration::from_secs(20));
    let runs = Arc::new(std::sync::Mutex::new(Vec::new()));
    let seen = Arc::clone(&runs);
    let started = Instant::now();
    let outcome = deadline
        .read_remembered(key, move |token| {
            let mut runs = seen.lock().unwrap();
            runs.push(std::thread::current().id());
            if runs.len() == 1 {
                drop(runs);
                // Slow this time: works until stopped.
                while !token.is_cancelled() {
                    assert!(started.elapsed() < Duration::from_secs(10), "never stopped");
                    std::thread::sleep(Duration::from_millis(1));
                }
                return Err(ApiError::new(ErrorCode::Timeout, "stopped"));
            }
            Ok(runs.len())
        })
        .await;
    assert_eq!(outcome.unwrap(), 2, "the second run answers");
    assert_eq!(reads.run_in_place(), 1, "the first run was in place");
    assert_eq!(reads.running(), 0, "both runs were counted and are done");
    let elapsed = started.elapsed();
    assert!(elapsed >= inline::LEASH, "{elapsed:?}");
    assert!(
        elapsed < Duration::from_secs(2),
        "held past its leash: {elapsed:?}"
    );
    let runs = runs.lock().unwrap();
    assert_ne!(runs[0], runs[1], "the second run is on another thread");
}

#[test]
fn params_decode_once_and_reject_invalid_utf8() {
    let params = Params::parse(b"graph=http://e/%2531&q=a+b%20c&default").unwrap();
    assert_eq!(params.at_most_one("graph").unwrap(), Some("http://e/%31"));
    assert_eq!(params.at_most_one("q").unwrap(), Some("a b c"));
    assert!(params.contains("default"));
    assert!(Params::parse(b"query=%FF").is_err());
    assert!(Params::parse(b"a=1&a=2").unwrap().at_most_one("a").is_err());
}

/// Loads one triple `<s{i}> <p> i` for each `i` of `range`.
fn load_numbered(store: &KnowledgeStore, range: std::ops::Range<usize>) {
    let turtle: String = range
        .map(|i| format!("<http://example.org/s{i}> <http://example.org/p> {i} .\n"))
        .collect();
    store
        .embedded()
        .unwrap()
        .load_from_slice(oxigraph::io::RdfFormat::Turtle, turtle.as_bytes())
        .unwrap();
}

/// A query that scans, so Oxigraph checks its cancellation token all the time.
const SLOW: &str = "SELECT * WHERE { ?a ?b ?c . ?d ?e ?f . ?g ?h ?i }";

/// Regression: a client that disconnects must not leave its query running. Dropping the
/// handler's future does not stop a blocking evaluation; the deadline guard's `Drop` does.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_hangs_up_stops_its_query() {
    let store = KnowledgeStore::in_memory().unwrap();
    load_numbered(&store, 0..1000);
    let limits = QueryLimits {
        deadline: Duration::from_secs(120),
        max_construct_triples: 10,
        ..QueryLimits::default()
    };
    let knowledge = Arc::new(Knowledge::new(store, Tokens::open(), limits));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    let app = router(knowledge.clone());
    tokio::spawn(async move { axum::serve(listener, app).await });

    let client = reqwest::Client::builder()
        .timeout(Duration::from_millis(500))
        .build()
        .unwrap();
    let request = client
        .get(format!("http://{address}/sparql"))
        .query(&[("query", SLOW)])
        .send();
    let started = Instant::now();
    let wait_running = async {
        while knowledge.running_reads() == 0 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    };
    let (result, ()) = tokio::join!(request, wait_running);
    assert!(result.unwrap_err().is_timeout(), "the client gave up");
    while knowledge.running_reads() > 0 {
        assert!(
            started.elapsed() < Duration::from_secs(10),
            "the query still runs after its client left"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// A query fast enough last time runs in place on the async worker; when the data has grown
/// and it is slow this time, its leash stops it, it runs again on a blocking thread, and it is
/// stopped at its deadline there, through HTTP.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_query_run_in_place_still_stops_at_its_deadline() {
    let store = KnowledgeStore::in_memory().unwrap();
    load_numbered(&store, 0..2);
    let limits = QueryLimits {
        deadline: Duration::from_millis(300),
        max_construct_triples: 10,
        ..QueryLimits::default()
    };
    let knowledge = Arc::new(Knowledge::new(store.clone(), Tokens::open(), limits));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    let app = router(knowledge.clone());
    tokio::spawn(async move { axum::serve(listener, app).await });
    let client = reqwest::Client::new();
    // `SLOW` itself, as the hang-up test sends: what runs in place is remembered per service,
    // so that test's service still sees its query on the blocking path.
    let query = SLOW;
    let ask = || {
        client
            .get(format!("http://{address}/sparql"))
            .query(&[("query", query)])
            .header("accept", "application/sparql-results+json")
            .send()
    };
    // Two triples: 8 rows, well under the in-place budget, twice (the second runs in place).
    for _ in 0..2 {
        assert_eq!(ask().await.unwrap().status(), 200);
    }
    // 2,000 triples: 8·10⁹ rows. In place (short last time), stopped by the watchdog.
    load_numbered(&store, 2..2000);
    let before = knowledge.reads().run_in_place();
    let started = Instant::now();
    let response = ask().await.unwrap();
    assert_eq!(response.status(), 503, "{:?}", response.text().await);
    assert!(knowledge.reads().run_in_place() > before, "it ran in place");
    assert!(
        started.elapsed() < Duration::from_secs(5),
        "stopped late: {:?}",
        started.elapsed()
    );
    // Slow last time: the next run takes the blocking path and is stopped as well.
    let response = ask().await.unwrap();
    assert_eq!(response.status(), 503);
}
