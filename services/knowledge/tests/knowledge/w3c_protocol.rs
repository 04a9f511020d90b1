//! The W3C SPARQL 1.1 Protocol (34 tests) and Graph Store Protocol (13 tests) suites, read from
//! their manifests at run time and replayed against the router over real HTTP, each test on a
//! fresh store.
//!
//! The manifests describe HTTP exchanges (`ht:requests` lists with paths, headers, bodies and
//! expected responses); the runner maps their endpoint paths onto ours (`/sparql/` → `/sparql`,
//! `/gsp` → `/store`), follows `mf:expectedLocation` templating, and compares Graph Store
//! response bodies by graph isomorphism. There is no skip list: every test must pass.

#![allow(clippy::unwrap_used, clippy::print_stdout)] // reason: a test reports and panics

use std::path::{Path, PathBuf};

use crate::support::{Options, spawn_app};
use oxigraph::io::{RdfFormat, RdfParser};
use oxigraph::model::dataset::CanonicalizationAlgorithm;
use oxigraph::model::{Graph, NamedNode, NamedNodeRef, NamedOrBlankNodeRef, TermRef};
use oxigraph::sparql::results::{
    QueryResultsFormat, QueryResultsParser, SliceQueryResultsParserOutput,
};

const MF: &str = "http://www.w3.org/2001/sw/DataAccess/tests/test-manifest#";
const HT: &str = "http://www.w3.org/2011/http#";
const HTS: &str = "http://www.w3.org/2011/http-statusCodes#";
const UT: &str = "http://www.w3.org/2009/sparql/tests/test-update#";
const CNT: &str = "http://www.w3.org/2011/content#";
const RDF: &str = "http://www.w3.org/1999/02/22-rdf-syntax-ns#";
const RDFS: &str = "http://www.w3.org/2000/01/rdf-schema#";

fn iri(namespace: &str, local: &str) -> NamedNode {
    NamedNode::new(format!("{namespace}{local}")).unwrap()
}

/// A manifest graph and the navigation the runner needs.
struct Manifest {
    graph: Graph,
    path: PathBuf,
}

impl Manifest {
    fn load(path: &Path) -> Self {
        let text = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let parser = RdfParser::from_format(RdfFormat::Turtle)
            .with_base_iri(format!("file://{}", path.display()))
            .unwrap();
        let mut graph = Graph::new();
        for quad in parser.for_slice(&text) {
            graph.insert(&oxigraph::model::Triple::from(quad.unwrap()));
        }
        Self {
            graph,
            path: path.to_owned(),
        }
    }

    fn object<'a>(&'a self, subject: TermRef<'_>, predicate: &NamedNode) -> Option<TermRef<'a>> {
        self.graph
            .object_for_subject_predicate(as_subject(subject), predicate)
    }

    fn objects<'a>(&'a self, subject: TermRef<'_>, predicate: &NamedNode) -> Vec<TermRef<'a>> {
        self.graph
            .objects_for_subject_predicate(as_subject(subject), predicate)
            .collect()
    }

    fn string(&self, subject: TermRef<'_>, predicate: &NamedNode) -> Option<String> {
        match self.object(subject, predicate)? {
            TermRef::Literal(l) => Some(l.value().to_owned()),
            TermRef::NamedNode(n) => Some(n.as_str().to_owned()),
            _ => None,
        }
    }

    fn list<'a>(&'a self, mut head: TermRef<'a>) -> Vec<TermRef<'a>> {
        let (first, rest, nil) = (iri(RDF, "first"), iri(RDF, "rest"), iri(RDF, "nil"));
        let mut items = Vec::new();
        while head != TermRef::NamedNode(nil.as_ref()) {
            items.push(self.object(head, &first).expect("list item"));
            head = self.object(head, &rest).expect("list rest");
        }
        items
    }

    /// The test entries of this manifest and of those it includes, in order.
    fn cases(&self) -> Vec<Case> {
        let root = self
            .graph
            .subject_for_predicate_object(&iri(RDF, "type"), &iri(MF, "Manifest"))
            .map(|s| match s {
                NamedOrBlankNodeRef::NamedNode(n) => TermRef::NamedNode(n),
                NamedOrBlankNodeRef::BlankNode(b) => TermRef::BlankNode(b),
            })
            .expect("manifest node");
        let mut cases = Vec::new();
        if let Some(includes) = self.object(root, &iri(MF, "include")) {
            for included in self.list(includes) {
                let TermRef::NamedNode(file) = included else {
                    panic!("mf:include of a non-IRI")
                };
                let path = PathBuf::from(file.as_str().trim_start_matches("file://"));
                cases.extend(Manifest::load(&path).cases());
            }
        }
        if let Some(entries) = self.object(root, &iri(MF, "entries")) {
            for entry in self.list(entries) {
                cases.push(self.case(entry));
            }
        }
        cases
    }

    fn case(&self, entry: TermRef<'_>) -> Case {
        let id = match entry {
            TermRef::NamedNode(n) => n.as_str().rsplit('#').next().unwrap_or_default().to_owned(),
            other => other.to_string(),
        };
        let graph_data = self
            .objects(entry, &iri(UT, "graphData"))
            .into_iter()
            .map(|data| {
                let file = match self.object(data, &iri(UT, "graph")) {
                    Some(TermRef::NamedNode(n)) => {
                        PathBuf::from(n.as_str().trim_start_matches("file://"))
                    }
                    other => panic!("{id}: ut:graph {other:?}"),
                };
                let label = self.string(data, &iri(RDFS, "label")).expect("graph label");
                (file, label)
            })
            .collect();
        let action = self.object(entry, &iri(MF, "action")).expect("mf:action");
        let requests = self
            .list(
                self.object(action, &iri(HT, "requests"))
                    .expect("ht:requests"),
            )
            .into_iter()
            .map(|request| self.request(request))
            .collect();
        Case {
            id,
            name: self.string(entry, &iri(MF, "name")).unwrap_or_default(),
            source: self.path.clone(),
            graph_data,
            requests,
        }
    }

    fn headers(&self, node: TermRef<'_>) -> Vec<(String, String)> {
        self.object(node, &iri(HT, "headers"))
            .map(|list| {
                self.list(list)
                    .into_iter()
                    .map(|h| {
                        (
                            self.string(h, &iri(HT, "fieldName"))
                                .unwrap()
                                .to_ascii_lowercase(),
                            self.string(h, &iri(HT, "fieldValue")).unwrap(),
                        )
                    })
                    .collect()
            })
            .unwrap_or_default()
    }

    fn body(&self, node: TermRef<'_>) -> Option<Body> {
        let body = self.object(node, &iri(HT, "body"))?;
        Some(Body {
            chars: self.string(body, &iri(CNT, "chars")).expect("cnt:chars"),
            encoding: self
                .string(body, &iri(CNT, "characterEncoding"))
                .unwrap_or_else(|| "UTF-8".to_owned()),
        })
    }

    fn request(&self, request: TermRef<'_>) -> Request {
        let response = self.object(request, &iri(HT, "resp")).expect("ht:resp");
        let statuses = self
            .objects(response, &iri(MF, "expectedStatus"))
            .into_iter()
            .map(|s| match s {
                TermRef::NamedNode(n) => Status::from_iri(n),
                other => panic!("status {other}"),
            })
            .collect();
        let boolean = match self.object(response, &iri(MF, "expectedBoolean")) {
            Some(TermRef::Literal(l)) => Some(l.value() == "true"),
            _ => None,
        };
        Request {
            method: self
                .string(request, &iri(HT, "methodName"))
                .expect("method"),
            path: self
                .string(request, &iri(HT, "absolutePath"))
                .expect("path"),
            headers: self.headers(request),
            body: self.body(request),
            expected: Expected {
                statuses,
                boolean,
                format: self.string(response, &iri(MF, "expectedFormat")),
                location_variable: self.string(response, &iri(MF, "expectedLocation")),
                headers: self.headers(response),
                body: self.body(response),
            },
        }
    }
}

fn as_subject(term: TermRef<'_>) -> NamedOrBlankNodeRef<'_> {
    match term {
        TermRef::NamedNode(n) => n.into(),
        TermRef::BlankNode(b) => b.into(),
        other => panic!("{other} cannot be a subject"),
    }
}

#[derive(Debug)]
struct Case {
    id: String,
    name: String,
    source: PathBuf,
    graph_data: Vec<(PathBuf, String)>,
    requests: Vec<Request>,
}

#[derive(Debug)]
struct Request {
    method: String,
    path: String,
    headers: Vec<(String, String)>,
    body: Option<Body>,
    expected: Expected,
}

#[derive(Debug)]
struct Body {
    chars: String,
    encoding: String,
}

impl Body {
    fn bytes(&self, variables: &[(String, String)]) -> Vec<u8> {
        let text = substitute(&self.chars, variables);
        if self.encoding.eq_ignore_ascii_case("UTF-16") {
            // Little-endian with a byte order mark, as a Windows client would send it.
            let mut bytes = vec![0xFF, 0xFE];
            bytes.extend(text.encode_utf16().flat_map(u16::to_le_bytes));
            bytes
        } else {
            text.into_bytes()
        }
    }
}

#[derive(Debug)]
struct Expected {
    statuses: Vec<Status>,
    boolean: Option<bool>,
    format: Option<String>,
    location_variable: Option<String>,
    headers: Vec<(String, String)>,
    body: Option<Body>,
}

#[derive(Debug, Clone, Copy)]
enum Status {
    Exactly(u16),
    Class(u16),
}

impl Status {
    fn from_iri(iri: NamedNodeRef<'_>) -> Self {
        let local = iri
            .as_str()
            .strip_prefix(HTS)
            .unwrap_or_else(|| panic!("status {iri}"));
        match local {
            "OK" => Status::Exactly(200),
            "Created" => Status::Exactly(201),
            "NoContent" => Status::Exactly(204),
            "NotFound" => Status::Exactly(404),
            "StatusCode2xx" => Status::Class(2),
            "StatusCode3xx" => Status::Class(3),
            "StatusCode4xx" => Status::Class(4),
            "StatusCode5xx" => Status::Class(5),
            other => panic!("unknown expected status {other}"),
        }
    }

    fn matches(self, status: u16) -> bool {
        match self {
            Status::Exactly(s) => s == status,
            Status::Class(c) => status / 100 == c,
        }
    }
}

fn substitute(text: &str, variables: &[(String, String)]) -> String {
    variables
        .iter()
        .fold(text.to_owned(), |text, (name, value)| {
            text.replace(name, value)
        })
}

/// The manifests' endpoint paths on our router.
fn our_path(path: &str) -> String {
    if let Some(rest) = path.strip_prefix("/sparql/") {
        format!("/sparql{rest}")
    } else if let Some(rest) = path.strip_prefix("/gsp") {
        format!("/store{rest}")
    } else {
        path.to_owned()
    }
}

fn media_type(content_type: &str) -> String {
    content_type
        .split(';')
        .next()
        .unwrap_or_default()
        .trim()
        .to_ascii_lowercase()
}

fn charset(content_type: &str) -> Option<String> {
    content_type.split(';').skip(1).find_map(|p| {
        let (name, value) = p.split_once('=')?;
        name.trim()
            .eq_ignore_ascii_case("charset")
            .then(|| value.trim().trim_matches('"').to_ascii_lowercase())
    })
}

fn parse_graph(body: &[u8], format: RdfFormat) -> Result<Graph, String> {
    let parser = RdfParser::from_format(format)
        .with_base_iri("http://www.example/")
        .unwrap();
    let mut graph = Graph::new();
    for quad in parser.for_slice(body) {
        let quad = quad.map_err(|e| format!("response body does not parse: {e}"))?;
        graph.insert(&oxigraph::model::Triple::from(quad));
    }
    graph.canonicalize(CanonicalizationAlgorithm::Unstable);
    Ok(graph)
}

/// Checks one response against its expectations; records `$LOCATION$`-style variables.
fn check(
    expected: &Expected,
    status: u16,
    headers: &reqwest::header::HeaderMap,
    body: &[u8],
    variables: &mut Vec<(String, String)>,
) -> Result<(), String> {
    let body_text = String::from_utf8_lossy(body);
    if !expected.statuses.iter().any(|s| s.matches(status)) {
        return Err(format!(
            "status {status}, expected one of {:?}; body: {body_text}",
            expected.statuses
        ));
    }
    let content_type = headers
        .get(reqwest::header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or_default()
        .to_owned();
    if let Some(variable) = &expected.location_variable {
        let location = headers
            .get(reqwest::header::LOCATION)
            .and_then(|v| v.to_str().ok())
            .ok_or("no Location header")?;
        variables.push((variable.clone(), location.to_owned()));
    }
    match expected.format.as_deref() {
        None => {}
        Some(kind @ ("boolean" | "tabular")) => {
            let format = QueryResultsFormat::from_media_type(&content_type)
                .ok_or_else(|| format!("Content-Type `{content_type}` is no results format"))?;
            if kind == "boolean"
                && !matches!(format, QueryResultsFormat::Json | QueryResultsFormat::Xml)
            {
                return Err(format!("boolean in `{content_type}`, expected XML or JSON"));
            }
            let parsed = QueryResultsParser::from_format(format)
                .for_slice(body)
                .map_err(|e| format!("results do not parse: {e}"))?;
            match (kind, parsed) {
                ("boolean", SliceQueryResultsParserOutput::Boolean(value)) => {
                    if let Some(expected) = expected.boolean
                        && value != expected
                    {
                        return Err(format!("boolean {value}, expected {expected}"));
                    }
                }
                ("tabular", SliceQueryResultsParserOutput::Solutions(solutions)) => {
                    for solution in solutions {
                        solution.map_err(|e| format!("solutions do not parse: {e}"))?;
                    }
                }
                (kind, _) => return Err(format!("expected {kind} results, got the other kind")),
            }
        }
        Some("RDF") => {
            let format = RdfFormat::from_media_type(&content_type)
                .ok_or_else(|| format!("Content-Type `{content_type}` is no RDF format"))?;
            parse_graph(body, format)?;
        }
        Some(other) => return Err(format!("unknown expected format {other}")),
    }
    for (name, value) in &expected.headers {
        if name != "content-type" {
            return Err(format!("runner does not check response header {name}"));
        }
        if media_type(&content_type) != media_type(value) {
            return Err(format!("Content-Type `{content_type}`, expected `{value}`"));
        }
        if charset(value).is_some() && charset(value) != charset(&content_type) {
            return Err(format!("Content-Type `{content_type}`, expected `{value}`"));
        }
    }
    if let Some(expected_body) = &expected.body {
        let expected_type = expected
            .headers
            .iter()
            .find(|(n, _)| n == "content-type")
            .map(|(_, v)| v.as_str())
            .unwrap_or("text/turtle");
        let expected_format = RdfFormat::from_media_type(expected_type).unwrap();
        let expected_graph = parse_graph(&expected_body.bytes(variables), expected_format)?;
        let format = RdfFormat::from_media_type(&content_type)
            .ok_or_else(|| format!("Content-Type `{content_type}` is no RDF format"))?;
        let graph = parse_graph(body, format)?;
        if graph != expected_graph {
            return Err(format!(
                "graph not isomorphic to the expected one:\n got: {graph}\n expected: {expected_graph}"
            ));
        }
    }
    Ok(())
}

async fn run(case: &Case) -> Result<(), String> {
    let app = spawn_app(Options::default()).await;
    for (file, graph) in &case.graph_data {
        let data = std::fs::read_to_string(file).map_err(|e| format!("{}: {e}", file.display()))?;
        app.load(&data, Some(graph));
    }
    let mut variables = Vec::new();
    for (i, request) in case.requests.iter().enumerate() {
        let url = app.url(&substitute(&our_path(&request.path), &variables));
        let method = reqwest::Method::from_bytes(request.method.as_bytes()).unwrap();
        let mut builder = app.client.request(method, &url);
        for (name, value) in &request.headers {
            builder = builder.header(name, value);
        }
        if let Some(body) = &request.body {
            builder = builder.body(body.bytes(&variables));
        }
        let response = builder
            .send()
            .await
            .map_err(|e| format!("request {i} {} {url}: {e}", request.method))?;
        let status = response.status().as_u16();
        let headers = response.headers().clone();
        let body = response
            .bytes()
            .await
            .map_err(|e| format!("request {i}: {e}"))?;
        check(&request.expected, status, &headers, &body, &mut variables)
            .map_err(|e| format!("request {i} ({} {url}): {e}", request.method))?;
    }
    Ok(())
}

/// Runs every case of `manifest`; returns (passed, failures).
async fn run_suite(label: &str, manifest: &str) -> Option<(usize, Vec<String>)> {
    let manifest = fixtures::shared_fixture(
        manifest,
        format_args!(
            "the {label} suite's manifest (the W3C tests live in shared/ beside the \
             repository; set MENTALSIM_SHARED to point elsewhere)"
        ),
    )?;
    let cases = Manifest::load(&manifest).cases();
    let mut passed = 0;
    let mut failures = Vec::new();
    for case in &cases {
        match run(case).await {
            Ok(()) => {
                passed += 1;
                println!("ok   {label} {}", case.id);
            }
            Err(e) => {
                println!("FAIL {label} {} ({}): {e}", case.id, case.name);
                failures.push(format!(
                    "{} [{}] {}: {e}",
                    case.id,
                    case.source.display(),
                    case.name
                ));
            }
        }
    }
    println!("{label}: {passed} passed, {} failed", failures.len());
    Some((passed, failures))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn w3c_sparql_protocol_suite_passes() {
    let manifest = "w3c-tests/protocol/manifest.ttl";
    let Some((passed, failures)) = run_suite("SPARQL 1.1 Protocol", manifest).await else {
        return;
    };
    assert!(
        failures.is_empty(),
        "failing tests:\n{}",
        failures.join("\n")
    );
    assert_eq!(passed, 34, "the suite has 34 tests");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn w3c_graph_store_protocol_suite_passes() {
    let manifest = "w3c-tests/graph-store-protocol/manifest.ttl";
    let Some((passed, failures)) = run_suite("Graph Store Protocol", manifest).await else {
        return;
    };
    assert!(
        failures.is_empty(),
        "failing tests:\n{}",
        failures.join("\n")
    );
    assert_eq!(passed, 13, "the suite has 13 tests");
}
