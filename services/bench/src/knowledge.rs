//! The knowledge-service benchmark, over real HTTP against real processes:
//!
//! 1. A building of at least 100,000 triples is made by replicating the bundled sample
//!    building's floors, rooms, maps and objects under fresh IRIs (and identifiers), and loaded
//!    into a freshly started `mentalsim serve` (embedded Oxigraph on RocksDB) through its Graph
//!    Store endpoint, which also rebuilds the inferred graph.
//! 2. On-demand database latency (p50, p99): `POST /v1/on-demand` for a robot and a mission
//!    across several connected places, one request at a time.
//! 3. SPARQL query throughput of our `/sparql` beside `oxigraph serve` (PyPI `oxigraph`, also
//!    RocksDB on disk) holding exactly the same dataset (our whole dataset, dumped as N-Quads
//!    from our `/store` and loaded into it): the same query mix, the same number of concurrent
//!    clients, measured in the same run. The ratio ours/oxigraph is what our layers (routing,
//!    auth, negotiation, deadline, serialization) cost.

use std::collections::{HashMap, HashSet, VecDeque};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use oxrdf::{Literal, NamedNode, NamedOrBlankNode, Term, Triple};
use serde::Serialize;

/// Target of the query-throughput ratio ours / oxigraph server (issue 34): our layers cost
/// under 5 %.
pub const TARGET_RATIO: f64 = 0.95;

/// The bundled sample building, as the service loads it.
const SAMPLE_BUILDING: &str = include_str!("../../../ontologies/environments/sample-building.ttl");
const BUILDING: &str = "https://mentalsim.dev/data/buildings/sample-building";
const TOSM: &str = "https://mentalsim.dev/ontology/tosm#";
/// Where the replicated floors are loaded.
pub const REPLICA_GRAPH: &str = "https://mentalsim.dev/graph/environments/sample-building-replicas";

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct KnowledgeBenchError(String);

fn fail(message: impl Into<String>) -> KnowledgeBenchError {
    KnowledgeBenchError(message.into())
}

/// What to run.
#[derive(Debug, Clone)]
pub struct KnowledgeBenchOptions {
    /// The `mentalsim` binary to start as our service.
    pub mentalsim: PathBuf,
    /// The `oxigraph` server binary (PyPI `oxigraph`).
    pub oxigraph: PathBuf,
    /// At least this many triples in the store (the building plus ontology and robot).
    pub min_triples: usize,
    /// Timed on-demand requests.
    pub on_demand_requests: usize,
    /// Concurrent SPARQL clients, the same for both servers.
    pub clients: usize,
    /// Seconds each server is measured.
    pub seconds: f64,
    /// Print progress to standard error.
    pub verbose: bool,
}

impl KnowledgeBenchOptions {
    /// Defaults: 100,000 triples, 200 on-demand requests, 4 clients, 10 s per server.
    pub fn new(mentalsim: PathBuf, oxigraph: PathBuf) -> Self {
        Self {
            mentalsim,
            oxigraph,
            min_triples: 100_000,
            on_demand_requests: 200,
            clients: 4,
            seconds: 10.0,
            verbose: true,
        }
    }
}

/// One query kind's throughput on both servers.
#[derive(Debug, Clone, Serialize)]
pub struct QueryKindReport {
    /// The kind: `lookup`, `join` or `filter_count`.
    pub kind: String,
    /// Queries per second through our `/sparql`.
    pub ours: f64,
    /// Queries per second on `oxigraph serve`.
    pub oxigraph_server: f64,
    /// ours / oxigraph.
    pub ratio: f64,
}

/// The figures.
#[derive(Debug, Clone, Serialize)]
pub struct KnowledgeBenchReport {
    /// Triples in the whole dataset (all graphs, the inferred one included).
    pub triples: usize,
    /// Copies of the sample building's floors.
    pub floor_copies: usize,
    /// Floors in the building.
    pub floors: usize,
    /// Seconds to load the replicated floors through our Graph Store endpoint (with the
    /// inference rebuild).
    pub load_s: f64,
    /// Places on the on-demand mission's route.
    pub on_demand_route_places: usize,
    /// Triples in each on-demand database.
    pub on_demand_triples: usize,
    /// Median on-demand latency, ms.
    pub on_demand_p50_ms: f64,
    /// 99th percentile on-demand latency, ms.
    pub on_demand_p99_ms: f64,
    /// Timed on-demand requests.
    pub on_demand_requests: usize,
    /// Median latency of an on-demand request right after a write (nothing read from the
    /// graph is reused), ms.
    pub on_demand_after_write_p50_ms: f64,
    /// Timed on-demand requests after a write.
    pub on_demand_after_write_requests: usize,
    /// Concurrent SPARQL clients.
    pub clients: usize,
    /// Seconds each server was measured.
    pub seconds: f64,
    /// Queries per second through our `/sparql` (the whole mix).
    pub queries_per_s_ours: f64,
    /// Queries per second on `oxigraph serve` (the whole mix).
    pub queries_per_s_oxigraph_server: f64,
    /// ours / oxigraph server.
    pub ratio: f64,
    /// The target ratio.
    pub target_ratio: f64,
    /// Per query kind.
    pub by_kind: Vec<QueryKindReport>,
    /// The oxigraph server's version.
    pub oxigraph_version: String,
    /// Whether our binary is a release build (`debug_assertions` off).
    pub release_build: bool,
}

impl KnowledgeBenchReport {
    /// `Err` with a message for people when the mix's ratio ours/oxigraph is below `min` (or
    /// not a number): what `bench knowledge --min-ratio` guards.
    pub fn check_ratio(&self, min: f64) -> Result<(), String> {
        if self.ratio >= min {
            return Ok(());
        }
        let kinds: Vec<String> = self
            .by_kind
            .iter()
            .map(|k| format!("{} {:.3}", k.kind, k.ratio))
            .collect();
        Err(format!(
            "the SPARQL mix ran at {:.3}x oxigraph serve ({:.0} against {:.0} queries/s), below \
             the minimum {min} ({}); profile both servers under the same load \
             (docs/benchmarks.md) before accepting the change",
            self.ratio,
            self.queries_per_s_ours,
            self.queries_per_s_oxigraph_server,
            kinds.join(", ")
        ))
    }

    /// A table for people.
    pub fn table(&self) -> String {
        let mut out = String::new();
        out.push_str(&format!(
            "knowledge benchmark: {} triples ({} floors from {} copies of the sample building's floors), load {:.2} s\n",
            self.triples, self.floors, self.floor_copies, self.load_s
        ));
        out.push_str(&format!(
            "on-demand database ({} places, {} triples): p50 {:.2} ms, p99 {:.2} ms over {} requests\n",
            self.on_demand_route_places,
            self.on_demand_triples,
            self.on_demand_p50_ms,
            self.on_demand_p99_ms,
            self.on_demand_requests
        ));
        out.push_str(&format!(
            "on-demand database right after a write: p50 {:.2} ms over {} requests\n",
            self.on_demand_after_write_p50_ms, self.on_demand_after_write_requests
        ));
        out.push_str(&format!(
            "SPARQL throughput, {} clients, {:.0} s each ({}):\n",
            self.clients,
            self.seconds,
            if self.release_build {
                "release build"
            } else {
                "DEBUG build: our crates unoptimised"
            }
        ));
        out.push_str(
            "| queries | ours (q/s) | oxigraph serve (q/s) | ratio |\n|---|---:|---:|---:|\n",
        );
        for k in &self.by_kind {
            out.push_str(&format!(
                "| {} | {:.0} | {:.0} | {:.3} |\n",
                k.kind, k.ours, k.oxigraph_server, k.ratio
            ));
        }
        out.push_str(&format!(
            "| **mix** | **{:.0}** | **{:.0}** | **{:.3}** (target ≥ {}) |\n",
            self.queries_per_s_ours,
            self.queries_per_s_oxigraph_server,
            self.ratio,
            self.target_ratio
        ));
        out.push_str(&format!("oxigraph server: {}\n", self.oxigraph_version));
        out
    }
}

/// The replicated building: the sample building's asserted triples plus `copies` copies of
/// everything below the building (floors, places, boundaries, maps, objects) under
/// `…/sample-building/c{k}/…`, with identifiers prefixed `C{k}-`.
pub struct Replicas {
    /// The copies' triples (not the original's: the service has those bundled).
    pub triples: Vec<Triple>,
    /// Copies made.
    pub copies: usize,
    /// Triples per copy.
    pub per_copy: usize,
}

fn parse_sample() -> Result<Vec<Triple>, KnowledgeBenchError> {
    oxttl::TurtleParser::new()
        .for_slice(SAMPLE_BUILDING.as_bytes())
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| fail(format!("the bundled sample building does not parse: {e}")))
}

fn copied_iri(iri: &str, k: usize) -> Option<String> {
    iri.strip_prefix(&format!("{BUILDING}/"))
        .map(|rest| format!("{BUILDING}/c{k}/{rest}"))
}

/// Copies enough floors for `extra_triples` more triples.
pub fn replicate(extra_triples: usize) -> Result<Replicas, KnowledgeBenchError> {
    let sample = parse_sample()?;
    let identifier = NamedNode::new_unchecked(format!("{TOSM}identifier"));
    let below: Vec<&Triple> = sample
        .iter()
        .filter(
            |t| matches!(&t.subject, NamedOrBlankNode::NamedNode(n) if copied_iri(n.as_str(), 0).is_some()),
        )
        .collect();
    let per_copy = below.len().max(1);
    let copies = extra_triples.div_ceil(per_copy).max(1);
    let mut triples = Vec::with_capacity(copies * per_copy);
    for k in 1..=copies {
        for t in &below {
            let NamedOrBlankNode::NamedNode(s) = &t.subject else {
                continue;
            };
            let subject = NamedNode::new_unchecked(copied_iri(s.as_str(), k).unwrap_or_default());
            let object = match &t.object {
                Term::NamedNode(o) => match copied_iri(o.as_str(), k) {
                    Some(iri) => Term::NamedNode(NamedNode::new_unchecked(iri)),
                    None => t.object.clone(),
                },
                Term::Literal(l) if t.predicate == identifier => {
                    Term::Literal(Literal::new_simple_literal(format!("C{k}-{}", l.value())))
                }
                other => other.clone(),
            };
            triples.push(Triple::new(subject, t.predicate.clone(), object));
        }
    }
    Ok(Replicas {
        triples,
        copies,
        per_copy,
    })
}

/// A mission across connected places on the first floor of copy `k`: from the place with the
/// most distant reachable place, to that place. Returns (start id, goal id, places on route).
fn mission(k: usize) -> Result<(String, String, usize), KnowledgeBenchError> {
    let sample = parse_sample()?;
    let connected = format!("{TOSM}isConnectedTo");
    let identifier = format!("{TOSM}identifier");
    let mut edges: HashMap<String, Vec<String>> = HashMap::new();
    let mut ids: HashMap<String, String> = HashMap::new();
    for t in &sample {
        let NamedOrBlankNode::NamedNode(s) = &t.subject else {
            continue;
        };
        if t.predicate.as_str() == connected
            && let Term::NamedNode(o) = &t.object
        {
            edges
                .entry(s.as_str().to_owned())
                .or_default()
                .push(o.as_str().to_owned());
            edges
                .entry(o.as_str().to_owned())
                .or_default()
                .push(s.as_str().to_owned());
        } else if t.predicate.as_str() == identifier
            && let Term::Literal(l) = &t.object
        {
            ids.insert(s.as_str().to_owned(), l.value().to_owned());
        }
    }
    let mut best: Option<(usize, String, String)> = None;
    let mut starts: Vec<&String> = edges.keys().collect();
    starts.sort();
    for start in starts {
        let mut distance: HashMap<&str, usize> = HashMap::from([(start.as_str(), 0)]);
        let mut queue = VecDeque::from([start.as_str()]);
        while let Some(at) = queue.pop_front() {
            for next in edges.get(at).into_iter().flatten() {
                if !distance.contains_key(next.as_str()) {
                    distance.insert(next, distance[at] + 1);
                    queue.push_back(next);
                }
            }
        }
        let mut far: Vec<(&&str, &usize)> = distance.iter().collect();
        far.sort();
        if let Some((goal, d)) = far.into_iter().max_by_key(|(_, d)| **d)
            && best.as_ref().is_none_or(|(bd, _, _)| d > bd)
        {
            best = Some((*d, start.clone(), (*goal).to_owned()));
        }
    }
    let (hops, start, goal) =
        best.ok_or_else(|| fail("the sample building has no connected places"))?;
    let id = |iri: &str| {
        ids.get(iri)
            .map(|i| format!("C{k}-{i}"))
            .ok_or_else(|| fail(format!("{iri} has no identifier")))
    };
    Ok((id(&start)?, id(&goal)?, hops + 1))
}

/// A child process killed when dropped, and how to start it again.
struct Server {
    child: Child,
    url: String,
    /// Its RocksDB directory.
    store_dir: PathBuf,
    binary: PathBuf,
    args: Vec<std::ffi::OsString>,
    stderr: Option<PathBuf>,
    ready: String,
    _dir: tempfile::TempDir,
}

impl Server {
    fn spawn(
        binary: &Path,
        args: &[std::ffi::OsString],
        stderr: Option<&Path>,
    ) -> Result<Child, KnowledgeBenchError> {
        let stderr = match stderr {
            Some(path) => Stdio::from(
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(path)
                    .map_err(|e| fail(format!("log file: {e}")))?,
            ),
            None => Stdio::null(),
        };
        Command::new(binary)
            .args(args)
            .env_remove("MENTALSIM_STORE_URL")
            .env_remove("MENTALSIM_CONFIG")
            .stdout(Stdio::null())
            .stderr(stderr)
            .spawn()
            .map_err(|e| fail(format!("cannot start {}: {e}", binary.display())))
    }

    /// Stops the server, compacts its RocksDB store with `oxigraph optimize`, and starts it
    /// again on the same port: both servers are measured on compacted stores, whatever path
    /// the data took in (our transactional PUT, their bulk load).
    fn optimize_and_restart(
        &mut self,
        oxigraph: &Path,
        client: &reqwest::blocking::Client,
    ) -> Result<(), KnowledgeBenchError> {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let status = Command::new(oxigraph)
            .arg("optimize")
            .arg("--location")
            .arg(&self.store_dir)
            .stdout(Stdio::null())
            .status()
            .map_err(|e| fail(format!("oxigraph optimize: {e}")))?;
        if !status.success() {
            return Err(fail(format!(
                "oxigraph optimize --location {} failed: {status}",
                self.store_dir.display()
            )));
        }
        self.child = Self::spawn(&self.binary, &self.args, self.stderr.as_deref())?;
        wait_until_ready(client, &self.ready, &mut self.child, "the restarted server")
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        if std::env::var_os("BENCH_KEEP_STORES").is_some() {
            let keep = std::env::temp_dir().join(format!("bench-store-{}", self.child.id()));
            if std::fs::rename(&self.store_dir, &keep).is_ok() {
                eprintln!("[bench knowledge] kept {} in {}", self.url, keep.display());
            }
        }
    }
}

fn free_port() -> Result<u16, KnowledgeBenchError> {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .map_err(|e| fail(format!("no free port: {e}")))
}

fn wait_until_ready(
    client: &reqwest::blocking::Client,
    url: &str,
    child: &mut Child,
    what: &str,
) -> Result<(), KnowledgeBenchError> {
    let started = Instant::now();
    loop {
        if client
            .get(url)
            .send()
            .is_ok_and(|r| r.status().is_success())
        {
            return Ok(());
        }
        if let Ok(Some(status)) = child.try_wait() {
            return Err(fail(format!("{what} exited during start-up: {status}")));
        }
        if started.elapsed() > Duration::from_secs(120) {
            return Err(fail(format!("{what} did not become ready at {url}")));
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn start_ours(
    options: &KnowledgeBenchOptions,
    client: &reqwest::blocking::Client,
) -> Result<(Server, String), KnowledgeBenchError> {
    let dir = tempfile::tempdir().map_err(|e| fail(format!("temporary directory: {e}")))?;
    let port = free_port()?;
    let data = dir.path().join("data");
    let log = dir.path().join("serve.log");
    let args: Vec<std::ffi::OsString> = vec![
        "serve".into(),
        "--bind".into(),
        format!("127.0.0.1:{port}").into(),
        "--data-dir".into(),
        data.clone().into(),
    ];
    let mut child = Server::spawn(&options.mentalsim, &args, Some(&log))?;
    let url = format!("http://127.0.0.1:{port}");
    let ready = format!("{url}/readyz");
    wait_until_ready(client, &ready, &mut child, "mentalsim serve")?;
    let token = std::fs::read_to_string(data.join("admin.token"))
        .map_err(|e| fail(format!("no admin token in {}: {e}", data.display())))?
        .trim()
        .to_owned();
    Ok((
        Server {
            child,
            url,
            store_dir: data.join("oxigraph"),
            binary: options.mentalsim.clone(),
            args,
            stderr: Some(log),
            ready,
            _dir: dir,
        },
        token,
    ))
}

fn start_oxigraph(
    options: &KnowledgeBenchOptions,
    client: &reqwest::blocking::Client,
) -> Result<Server, KnowledgeBenchError> {
    let dir = tempfile::tempdir().map_err(|e| fail(format!("temporary directory: {e}")))?;
    let port = free_port()?;
    let store_dir = dir.path().join("oxigraph");
    let args: Vec<std::ffi::OsString> = vec![
        "serve".into(),
        "--location".into(),
        store_dir.clone().into(),
        "--bind".into(),
        format!("127.0.0.1:{port}").into(),
    ];
    let mut child = Server::spawn(&options.oxigraph, &args, None)
        .map_err(|e| fail(format!("{e} (pip install oxigraph)")))?;
    let url = format!("http://127.0.0.1:{port}");
    let ready = format!("{url}/query?query=ASK%7B%7D");
    wait_until_ready(client, &ready, &mut child, "oxigraph serve")?;
    Ok(Server {
        child,
        url,
        store_dir,
        binary: options.oxigraph.clone(),
        args,
        stderr: None,
        ready,
        _dir: dir,
    })
}

fn checked(
    response: reqwest::Result<reqwest::blocking::Response>,
    what: &str,
) -> Result<reqwest::blocking::Response, KnowledgeBenchError> {
    let response = response.map_err(|e| fail(format!("{what}: {e}")))?;
    if !response.status().is_success() {
        let status = response.status();
        let body = response.text().unwrap_or_default();
        return Err(fail(format!("{what}: {status}: {body}")));
    }
    Ok(response)
}

/// A SPARQL query by POST (direct), asking for JSON results, with the bearer token if any.
fn sparql_request(
    client: &reqwest::blocking::Client,
    endpoint: &str,
    token: Option<&str>,
    query: &str,
) -> reqwest::blocking::RequestBuilder {
    let request = client
        .post(endpoint)
        .header("content-type", "application/sparql-query")
        .header("accept", "application/sparql-results+json")
        .body(query.to_owned());
    match token {
        Some(token) => request.bearer_auth(token),
        None => request,
    }
}

fn count_triples(
    client: &reqwest::blocking::Client,
    url: &str,
    token: &str,
) -> Result<usize, KnowledgeBenchError> {
    let response = checked(
        sparql_request(
            client,
            &format!("{url}/sparql"),
            Some(token),
            "SELECT (COUNT(*) AS ?n) WHERE { { ?s ?p ?o } UNION { GRAPH ?g { ?s ?p ?o } } }",
        )
        .send(),
        "counting triples",
    )?;
    let body: serde_json::Value = response
        .json()
        .map_err(|e| fail(format!("counting triples: {e}")))?;
    body["results"]["bindings"][0]["n"]["value"]
        .as_str()
        .and_then(|n| n.parse().ok())
        .ok_or_else(|| fail(format!("counting triples: unexpected answer {body}")))
}

/// Runs every query of the mix once on both servers: each must find something (a query that
/// answers nothing measures only request overhead), and both servers the same rows.
fn check_mix(
    client: &reqwest::blocking::Client,
    ours: (&str, &str),
    theirs: &str,
    mix: &[(&'static str, String)],
) -> Result<(), KnowledgeBenchError> {
    let rows = |endpoint: &str, token: Option<&str>, query: &str| {
        let request = sparql_request(client, endpoint, token, query);
        let body: serde_json::Value = checked(request.send(), endpoint)?
            .json()
            .map_err(|e| fail(format!("{endpoint}: {e}")))?;
        body["results"]["bindings"]
            .as_array()
            .map(Vec::len)
            .ok_or_else(|| fail(format!("{endpoint}: not a SELECT result: {body}")))
    };
    for (kind, query) in mix {
        let (n_ours, n_theirs) = (
            rows(ours.0, Some(ours.1), query)?,
            rows(theirs, None, query)?,
        );
        if n_ours == 0 {
            return Err(fail(format!(
                "a {kind} query of the mix finds nothing: {query}"
            )));
        }
        if n_ours != n_theirs {
            return Err(fail(format!(
                "a {kind} query answers {n_ours} rows here and {n_theirs} on oxigraph serve: {query}"
            )));
        }
    }
    Ok(())
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// The query mix: (kind, query) pairs, each kind with several variants.
fn query_mix(place_iris: &[String]) -> Vec<(&'static str, String)> {
    let mut mix = Vec::new();
    for iri in place_iris.iter().take(32) {
        mix.push((
            "lookup",
            format!("SELECT ?p ?o WHERE {{ GRAPH ?g {{ <{iri}> ?p ?o }} }}"),
        ));
    }
    // Every variant has answers: the sample's ground floor holds rooms, corridors and a hall,
    // its first floor a kitchen (a room).
    for (class, level) in [("Room", 0), ("Room", 1), ("Corridor", 0), ("Hall", 0)] {
        mix.push((
            "join",
            format!(
                "PREFIX tosm: <{TOSM}>
                 SELECT ?place ?name ?floor WHERE {{ GRAPH ?g {{
                   ?place a tosm:{class} ; tosm:name ?name ; tosm:isDirectlyInsideOf ?floor .
                   ?floor tosm:floorLevel {level} }} }} LIMIT 50"
            ),
        ));
    }
    for threshold in [-10, -5, 0, 5] {
        mix.push((
            "filter_count",
            format!(
                "PREFIX tosm: <{TOSM}>
                 SELECT (COUNT(?o) AS ?n) WHERE {{ GRAPH ?g {{
                   ?o a tosm:Object ; tosm:hasPose ?pose . ?pose tosm:xM ?x FILTER(?x > {threshold}) }} }}"
            ),
        ));
    }
    mix
}

/// Runs `queries` round-robin from `clients` threads for `seconds`; answers queries/s per kind
/// and overall. Each request must answer 200.
fn throughput(
    endpoint: &str,
    token: Option<&str>,
    queries: &[(&'static str, String)],
    clients: usize,
    seconds: f64,
) -> Result<(f64, HashMap<&'static str, f64>), KnowledgeBenchError> {
    // Each kind gets the same share of requests, whatever its number of variants.
    let kinds: Vec<&'static str> = {
        let mut k: Vec<&'static str> = queries.iter().map(|(k, _)| *k).collect();
        k.dedup();
        k
    };
    let by_kind: Vec<Vec<String>> = kinds
        .iter()
        .map(|k| {
            queries
                .iter()
                .filter(|(q, _)| q == k)
                .map(|(_, text)| text.clone())
                .collect()
        })
        .collect();
    let by_kind = Arc::new(by_kind);
    let stop = Arc::new(AtomicBool::new(false));
    let failed = Arc::new(std::sync::Mutex::new(None::<String>));
    // Per kind: requests done and nanoseconds spent in them (summed over clients).
    let counters: Arc<Vec<(AtomicU64, AtomicU64)>> = Arc::new(
        kinds
            .iter()
            .map(|_| (AtomicU64::new(0), AtomicU64::new(0)))
            .collect(),
    );
    let mut handles = Vec::new();
    let started = Instant::now();
    for c in 0..clients {
        let (by_kind, stop, failed, counters) = (
            by_kind.clone(),
            stop.clone(),
            failed.clone(),
            counters.clone(),
        );
        let endpoint = endpoint.to_owned();
        let token = token.map(str::to_owned);
        handles.push(std::thread::spawn(move || {
            let client = reqwest::blocking::Client::builder()
                .pool_max_idle_per_host(1)
                .build()
                .unwrap_or_default();
            let mut i = c;
            while !stop.load(Ordering::Relaxed) {
                let kind = i % by_kind.len();
                let variants = &by_kind[kind];
                let query = &variants[(i / by_kind.len()) % variants.len()];
                i += 1;
                let request = sparql_request(&client, &endpoint, token.as_deref(), query);
                let t0 = Instant::now();
                let outcome = request.send().and_then(|r| {
                    let status = r.status();
                    r.bytes().map(|body| (status, body))
                });
                match outcome {
                    Ok((status, _)) if status.is_success() => {
                        counters[kind].0.fetch_add(1, Ordering::Relaxed);
                        counters[kind]
                            .1
                            .fetch_add(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
                    }
                    other => {
                        let message = match other {
                            Ok((status, body)) => format!(
                                "{endpoint} answered {status}: {}",
                                String::from_utf8_lossy(&body)
                            ),
                            Err(e) => format!("{endpoint}: {e}"),
                        };
                        *failed.lock().unwrap_or_else(|p| p.into_inner()) = Some(message);
                        stop.store(true, Ordering::Relaxed);
                    }
                }
            }
        }));
    }
    std::thread::sleep(Duration::from_secs_f64(seconds));
    stop.store(true, Ordering::Relaxed);
    for h in handles {
        let _ = h.join();
    }
    let elapsed = started.elapsed().as_secs_f64();
    if let Some(message) = failed.lock().unwrap_or_else(|p| p.into_inner()).take() {
        return Err(fail(message));
    }
    let total: u64 = counters
        .iter()
        .map(|(n, _)| n.load(Ordering::Relaxed))
        .sum();
    // Per kind: the rate the clients would reach on that kind alone (requests per busy
    // client-second), so kinds of different cost are comparable between servers.
    let mut per_kind = HashMap::new();
    for (k, (n, nanos)) in kinds.iter().zip(counters.iter()) {
        let busy_s = nanos.load(Ordering::Relaxed) as f64 / 1e9;
        let rate = if busy_s > 0.0 {
            n.load(Ordering::Relaxed) as f64 / busy_s * clients as f64
        } else {
            0.0
        };
        per_kind.insert(*k, rate);
    }
    Ok((total as f64 / elapsed, per_kind))
}

/// The oxigraph binary's version line.
fn version_of(binary: &Path) -> String {
    Command::new(binary)
        .arg("--version")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
        .filter(|v| !v.is_empty())
        .unwrap_or_else(|| "unknown".to_owned())
}

/// Runs the benchmark.
pub fn run_knowledge_bench(
    options: KnowledgeBenchOptions,
) -> Result<KnowledgeBenchReport, KnowledgeBenchError> {
    let say = |m: &str| {
        if options.verbose {
            eprintln!("[bench knowledge] {m}");
        }
    };
    if options.clients == 0 || options.seconds <= 0.0 || options.on_demand_requests == 0 {
        return Err(fail(
            "clients, seconds and on-demand requests must be positive",
        ));
    }
    let client = reqwest::blocking::Client::builder()
        .timeout(Duration::from_secs(600))
        .build()
        .map_err(|e| fail(format!("HTTP client: {e}")))?;

    say("starting mentalsim serve (embedded RocksDB store)");
    let (ours, token) = start_ours(&options, &client)?;
    let bundled = count_triples(&client, &ours.url, &token)?;
    // Inferred triples come on top of the replicas; aim for the asserted ones alone.
    let replicas = replicate(options.min_triples.saturating_sub(bundled))?;
    say(&format!(
        "loading {} triples ({} copies of {} triples) through PUT /store",
        replicas.triples.len(),
        replicas.copies,
        replicas.per_copy
    ));
    let mut ntriples = String::with_capacity(replicas.triples.len() * 150);
    for t in &replicas.triples {
        ntriples.push_str(&t.to_string());
        ntriples.push_str(" .\n");
    }
    let t0 = Instant::now();
    checked(
        client
            .put(format!("{}/store", ours.url))
            .query(&[("graph", REPLICA_GRAPH)])
            .bearer_auth(&token)
            .header("content-type", "application/n-triples")
            .body(ntriples)
            .send(),
        "loading the replicas into our service",
    )?;
    let load_s = t0.elapsed().as_secs_f64();
    let triples = count_triples(&client, &ours.url, &token)?;
    if triples < options.min_triples {
        return Err(fail(format!(
            "only {triples} triples after loading, below {}",
            options.min_triples
        )));
    }

    // On-demand latency.
    let copy = replicas.copies.div_ceil(2);
    let (start, goal, route_places) = mission(copy)?;
    let body = serde_json::json!({
        "robot": "R-001",
        "start": {"place": start},
        "goals": [{"place": goal}],
    })
    .to_string();
    let on_demand = || -> Result<(f64, usize, usize), KnowledgeBenchError> {
        let t0 = Instant::now();
        let response = checked(
            client
                .post(format!("{}/v1/on-demand", ours.url))
                .bearer_auth(&token)
                .header("content-type", "application/json")
                .header("accept", "application/n-triples")
                .body(body.clone())
                .send(),
            "POST /v1/on-demand",
        )?;
        let count = response
            .headers()
            .get("x-triple-count")
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.parse().ok())
            .unwrap_or(0);
        let route = response
            .headers()
            .get("x-route")
            .and_then(|v| v.to_str().ok())
            .map_or(0, |v| v.split(' ').count());
        let _ = response.bytes();
        Ok((t0.elapsed().as_secs_f64() * 1e3, count, route))
    };
    say(&format!("on-demand database {start} -> {goal}: warming up"));
    let mut on_demand_triples = 0;
    let mut on_demand_route = route_places;
    for _ in 0..5 {
        let (_, count, route) = on_demand()?;
        on_demand_triples = count;
        on_demand_route = route;
    }
    let mut latencies = Vec::with_capacity(options.on_demand_requests);
    for _ in 0..options.on_demand_requests {
        latencies.push(on_demand()?.0);
    }
    latencies.sort_by(f64::total_cmp);
    // The first request after a write: every write makes what was read from the graph stale
    // (the places, the closures of the places crossed), so this is what a mission costs when
    // robots report often. Each write is one triple in a graph of its own, then one request.
    let writes = (options.on_demand_requests / 10).max(5);
    say(&format!(
        "on-demand database: {writes} requests, each after a write"
    ));
    let mut after_write = Vec::with_capacity(writes);
    let update = |body: String, what: &str| {
        checked(
            client
                .post(format!("{}/sparql", ours.url))
                .bearer_auth(&token)
                .header("content-type", "application/sparql-update")
                .body(body)
                .send(),
            what,
        )
    };
    for k in 0..writes {
        update(
            format!(
                "INSERT DATA {{ GRAPH <urn:x-bench:writes> {{ <urn:x-bench:write> <urn:x-bench:k> {k} }} }}"
            ),
            "a write between on-demand requests (SPARQL update)",
        )?;
        after_write.push(on_demand()?.0);
    }
    after_write.sort_by(f64::total_cmp);
    // The dataset as it was, for the comparison with oxigraph serve.
    update(
        "DROP GRAPH <urn:x-bench:writes>".to_owned(),
        "dropping the writes' graph",
    )?;

    // The same dataset into oxigraph serve.
    say("dumping our dataset and loading it into oxigraph serve");
    let dump = checked(
        client
            .get(format!("{}/store", ours.url))
            .bearer_auth(&token)
            .header("accept", "application/n-quads")
            .send(),
        "GET /store (N-Quads)",
    )?
    .bytes()
    .map_err(|e| fail(format!("GET /store: {e}")))?;
    let oxigraph = start_oxigraph(&options, &client)?;
    checked(
        client
            .post(format!("{}/store", oxigraph.url))
            .header("content-type", "application/n-quads")
            .body(dump)
            .send(),
        "loading oxigraph serve",
    )?;
    let theirs_count = {
        let response = checked(
            client
                .post(format!("{}/query", oxigraph.url))
                .header("content-type", "application/sparql-query")
                .header("accept", "application/sparql-results+json")
                .body("SELECT (COUNT(*) AS ?n) WHERE { { ?s ?p ?o } UNION { GRAPH ?g { ?s ?p ?o } } }")
                .send(),
            "counting oxigraph's triples",
        )?;
        let body: serde_json::Value = response.json().map_err(|e| fail(e.to_string()))?;
        body["results"]["bindings"][0]["n"]["value"]
            .as_str()
            .and_then(|n| n.parse::<usize>().ok())
            .unwrap_or(0)
    };
    if theirs_count != triples {
        return Err(fail(format!(
            "oxigraph serve holds {theirs_count} triples, ours {triples}: not the same data"
        )));
    }

    say("compacting both stores (oxigraph optimize) and restarting both servers");
    let mut ours = ours;
    let mut oxigraph = oxigraph;
    ours.optimize_and_restart(&options.oxigraph, &client)?;
    oxigraph.optimize_and_restart(&options.oxigraph, &client)?;

    // Throughput, side by side: warm both, then measure each in turn, twice, interleaved.
    let places: Vec<String> = {
        let mut seen = HashSet::new();
        replicas
            .triples
            .iter()
            .filter(|t| t.predicate.as_str() == format!("{TOSM}isConnectedTo"))
            .filter_map(|t| match &t.subject {
                NamedOrBlankNode::NamedNode(n) if seen.insert(n.as_str().to_owned()) => {
                    Some(n.as_str().to_owned())
                }
                _ => None,
            })
            .collect()
    };
    let mix = query_mix(&places);
    let our_endpoint = format!("{}/sparql", ours.url);
    let their_endpoint = format!("{}/query", oxigraph.url);
    check_mix(&client, (&our_endpoint, &token), &their_endpoint, &mix)?;
    say("warming up both servers");
    throughput(&our_endpoint, Some(&token), &mix, options.clients, 1.0)?;
    throughput(&their_endpoint, None, &mix, options.clients, 1.0)?;
    let half = options.seconds / 2.0;
    let mut ours_total = 0.0;
    let mut theirs_total = 0.0;
    let mut ours_kinds: HashMap<&'static str, f64> = HashMap::new();
    let mut theirs_kinds: HashMap<&'static str, f64> = HashMap::new();
    for round in 0..2 {
        say(&format!("measuring round {}: ours", round + 1));
        let (q, k) = throughput(&our_endpoint, Some(&token), &mix, options.clients, half)?;
        ours_total += q / 2.0;
        for (kind, v) in k {
            *ours_kinds.entry(kind).or_default() += v / 2.0;
        }
        say(&format!("measuring round {}: oxigraph serve", round + 1));
        let (q, k) = throughput(&their_endpoint, None, &mix, options.clients, half)?;
        theirs_total += q / 2.0;
        for (kind, v) in k {
            *theirs_kinds.entry(kind).or_default() += v / 2.0;
        }
    }
    let by_kind = ["lookup", "join", "filter_count"]
        .iter()
        .map(|kind| {
            let ours = ours_kinds.get(kind).copied().unwrap_or(0.0);
            let theirs = theirs_kinds.get(kind).copied().unwrap_or(0.0);
            QueryKindReport {
                kind: (*kind).to_owned(),
                ours,
                oxigraph_server: theirs,
                ratio: if theirs > 0.0 {
                    ours / theirs
                } else {
                    f64::NAN
                },
            }
        })
        .collect();
    let release_build = !is_debug_build(&options.mentalsim);
    let sample_floors = parse_sample()?
        .iter()
        .filter(|t| t.object.to_string() == format!("<{TOSM}Floor>"))
        .count();
    Ok(KnowledgeBenchReport {
        triples,
        floor_copies: replicas.copies,
        floors: sample_floors * (replicas.copies + 1),
        load_s,
        on_demand_route_places: on_demand_route,
        on_demand_triples,
        on_demand_p50_ms: percentile(&latencies, 50.0),
        on_demand_p99_ms: percentile(&latencies, 99.0),
        on_demand_requests: latencies.len(),
        on_demand_after_write_p50_ms: percentile(&after_write, 50.0),
        on_demand_after_write_requests: after_write.len(),
        clients: options.clients,
        seconds: options.seconds,
        queries_per_s_ours: ours_total,
        queries_per_s_oxigraph_server: theirs_total,
        ratio: ours_total / theirs_total,
        target_ratio: TARGET_RATIO,
        by_kind,
        oxigraph_version: version_of(&options.oxigraph),
        release_build,
    })
}

/// Whether `binary` lives in a `debug` profile directory (our crates unoptimised).
fn is_debug_build(binary: &Path) -> bool {
    binary
        .parent()
        .and_then(|p| p.file_name())
        .is_some_and(|n| n == "debug" || n == "deps")
}

#[cfg(test)]
mod tests;
