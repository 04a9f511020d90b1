//! The SPARQL and Graph Store endpoints over real HTTP: content negotiation, every 4xx path,
//! authorization, the query deadline and the CONSTRUCT cap.

#![allow(clippy::unwrap_used)] // reason: tests

use std::time::{Duration, Instant};

use crate::support::{
    ENGINEER_TOKEN, Options, ROBOT_TOKEN, TestApp, engineer_and_robot, spawn_app,
};
use knowledge::QueryLimits;
use reqwest::StatusCode;
use reqwest::header::{ACCEPT, ALLOW, AUTHORIZATION, CONTENT_TYPE, LOCATION};

const DATA: &str = r#"
    @prefix ex: <http://example.org/> .
    ex:kitchen a ex:Room ; ex:name "Kitchen" ; ex:area 12.5 .
    ex:hall a ex:Room ; ex:name "Hall" .
"#;

async fn app() -> TestApp {
    let app = spawn_app(Options::default()).await;
    app.load(DATA, None);
    app
}

/// The JSON error body's `code` and `message`.
async fn error(response: reqwest::Response) -> (StatusCode, String, String) {
    let status = response.status();
    let json: serde_json::Value = response.json().await.unwrap();
    (
        status,
        json["error"]["code"].as_str().unwrap().to_owned(),
        json["error"]["message"].as_str().unwrap().to_owned(),
    )
}

async fn get_query(app: &TestApp, query: &str, accept: Option<&str>) -> reqwest::Response {
    let mut request = app
        .client
        .get(app.url("/sparql"))
        .query(&[("query", query)]);
    if let Some(accept) = accept {
        request = request.header(ACCEPT, accept);
    }
    request.send().await.unwrap()
}

async fn post_direct(
    app: &TestApp,
    content_type: &str,
    body: impl Into<reqwest::Body>,
) -> reqwest::Response {
    app.client
        .post(app.url("/sparql"))
        .header(CONTENT_TYPE, content_type)
        .body(body)
        .send()
        .await
        .unwrap()
}

const SELECT: &str = "SELECT ?name WHERE { ?r <http://example.org/name> ?name } ORDER BY ?name";

#[tokio::test]
async fn select_is_served_in_every_results_format() {
    let app = app().await;
    let cases = [
        (
            "application/sparql-results+json",
            "application/sparql-results+json",
            "\"Hall\"",
        ),
        (
            "application/sparql-results+xml",
            "application/sparql-results+xml",
            "<literal>Hall</literal>",
        ),
        (
            "text/csv",
            "text/csv; charset=utf-8",
            "name\r\nHall\r\nKitchen",
        ),
        (
            "text/tab-separated-values",
            "text/tab-separated-values; charset=utf-8",
            "?name\n\"Hall\"",
        ),
    ];
    for (accept, content_type, fragment) in cases {
        let response = get_query(&app, SELECT, Some(accept)).await;
        assert_eq!(response.status(), StatusCode::OK, "{accept}");
        assert_eq!(response.headers()[CONTENT_TYPE], content_type);
        let body = response.text().await.unwrap();
        assert!(body.contains(fragment), "{accept}: {body}");
    }
}

#[tokio::test]
async fn construct_is_served_in_every_graph_format() {
    let app = app().await;
    let construct =
        "CONSTRUCT { ?r <http://example.org/label> ?n } WHERE { ?r <http://example.org/name> ?n }";
    let cases = [
        ("text/turtle", "text/turtle; charset=utf-8"),
        ("application/n-triples", "application/n-triples"),
        ("application/n-quads", "application/n-quads"),
        ("application/trig", "application/trig"),
        ("application/rdf+xml", "application/rdf+xml"),
        ("application/ld+json", "application/ld+json"),
    ];
    for (accept, content_type) in cases {
        let response = get_query(&app, construct, Some(accept)).await;
        assert_eq!(response.status(), StatusCode::OK, "{accept}");
        assert_eq!(response.headers()[CONTENT_TYPE], content_type);
        let body = response.bytes().await.unwrap();
        let format = oxigraph::io::RdfFormat::from_media_type(content_type).unwrap();
        let count = oxigraph::io::RdfParser::from_format(format)
            .for_slice(&body)
            .count();
        assert_eq!(count, 2, "{accept}: {}", String::from_utf8_lossy(&body));
    }
}

#[tokio::test]
async fn sparqlwrapper_format_parameters_are_honoured() {
    let app = app().await;
    let response = app
        .client
        .get(app.url("/sparql"))
        .query(&[
            ("query", SELECT),
            ("format", "csv"),
            ("output", "csv"),
            ("results", "csv"),
        ])
        .header(ACCEPT, "text/csv")
        .send()
        .await
        .unwrap();
    assert_eq!(response.headers()[CONTENT_TYPE], "text/csv; charset=utf-8");
    // SPARQLWrapper sends `format=tsv&format=text/tab-separated-values` for TSV.
    let response = app
        .client
        .get(app.url("/sparql"))
        .query(&[
            ("query", SELECT),
            ("format", "tsv"),
            ("format", "text/tab-separated-values"),
        ])
        .send()
        .await
        .unwrap();
    assert_eq!(
        response.headers()[CONTENT_TYPE],
        "text/tab-separated-values; charset=utf-8"
    );
}

#[tokio::test]
async fn unacceptable_accept_is_406_naming_the_types() {
    let app = app().await;
    let (status, code, message) = error(get_query(&app, SELECT, Some("text/turtle")).await).await;
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::NOT_ACCEPTABLE, "not_acceptable")
    );
    assert!(
        message.contains("application/sparql-results+json"),
        "{message}"
    );
}

#[tokio::test]
async fn malformed_query_is_400_naming_the_parse_error() {
    let app = app().await;
    let (status, code, message) =
        error(get_query(&app, "SELECT * WHERE { ?s ?p }", None).await).await;
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::BAD_REQUEST, "invalid_query")
    );
    assert!(message.contains("does not parse"), "{message}");
    assert!(
        message.contains("line") || message.contains("expected"),
        "{message}"
    );
}

#[tokio::test]
async fn wrong_or_missing_media_type_is_415() {
    let app = app().await;
    let (status, code, _) = error(post_direct(&app, "text/plain", "ASK {}").await).await;
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::UNSUPPORTED_MEDIA_TYPE, "unsupported_media_type")
    );
    let response = app
        .client
        .post(app.url("/sparql"))
        .body("query=ASK%20%7B%7D")
        .send()
        .await
        .unwrap();
    let (status, _, message) = error(response).await;
    assert_eq!(status, StatusCode::UNSUPPORTED_MEDIA_TYPE);
    assert!(message.contains("application/sparql-query"), "{message}");
}

#[tokio::test]
async fn missing_or_duplicate_operations_are_400() {
    let app = app().await;
    let form = "application/x-www-form-urlencoded";
    for body in [
        "default-graph-uri=http%3A%2F%2Fexample.org%2F",
        "query=ASK%20%7B%7D&query=ASK%20%7B%7D",
        "query=ASK%20%7B%7D&update=CLEAR%20ALL",
        "update=CLEAR%20ALL&update=CLEAR%20ALL",
    ] {
        let (status, code, _) = error(post_direct(&app, form, body).await).await;
        assert_eq!(
            (status, code.as_str()),
            (StatusCode::BAD_REQUEST, "bad_request"),
            "{body}"
        );
    }
    let response = app
        .client
        .get(app.url("/sparql?query=ASK%20%7B%7D&query=ASK%20%7B%7D"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
    // A query both in the URL and directly in the body.
    let response = app
        .client
        .post(app.url("/sparql?query=ASK%20%7B%7D"))
        .header(CONTENT_TYPE, "application/sparql-query")
        .body("ASK {}")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
}

#[tokio::test]
async fn update_by_get_and_other_methods_are_405_with_allow() {
    let app = app().await;
    let response = app
        .client
        .get(app.url("/sparql?update=CLEAR%20ALL"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.headers()[ALLOW], "POST");
    let (status, code, _) = error(response).await;
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::METHOD_NOT_ALLOWED, "method_not_allowed")
    );
    let response = app
        .client
        .put(app.url("/sparql?query=ASK%20%7B%7D"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::METHOD_NOT_ALLOWED);
    assert!(response.headers()[ALLOW].to_str().unwrap().contains("POST"));
    let response = app
        .client
        .patch(app.url("/store?default"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::METHOD_NOT_ALLOWED);
}

#[tokio::test]
async fn non_utf8_requests_are_400() {
    let app = app().await;
    let (status, _, _) =
        error(post_direct(&app, "application/sparql-query; charset=UTF-16", "ASK {}").await).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    let (status, _, _) = error(
        post_direct(
            &app,
            "application/sparql-update; charset=latin1",
            "CLEAR ALL",
        )
        .await,
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    let (status, _, message) =
        error(post_direct(&app, "application/sparql-query", vec![b'A', 0xFF, b'K']).await).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(message.contains("UTF-8"), "{message}");
    let response = app
        .client
        .get(app.url("/sparql?query=ASK%20%7B%FF%7D"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
    // rdflib's header is fine.
    let response = post_direct(
        &app,
        "application/sparql-update; charset=UTF-8",
        "INSERT DATA { <http://example.org/a> <http://example.org/b> 1 }",
    )
    .await;
    assert_eq!(response.status(), StatusCode::NO_CONTENT);
}

#[tokio::test]
async fn update_with_its_own_dataset_and_protocol_dataset_is_400() {
    let app = app().await;
    let response = app
        .client
        .post(app.url("/sparql?using-graph-uri=http%3A%2F%2Fexample.org%2Fg"))
        .header(CONTENT_TYPE, "application/sparql-update")
        .body("WITH <http://example.org/h> DELETE { ?s ?p ?o } WHERE { ?s ?p ?o }")
        .send()
        .await
        .unwrap();
    let (status, _, message) = error(response).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(message.contains("USING or WITH"), "{message}");
    let response = app
        .client
        .get(app.url("/sparql?query=ASK%20%7B%7D&default-graph-uri=not%20an%20iri"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
}

#[tokio::test]
async fn writes_need_an_engineer_token_and_reads_any_token() {
    let app = spawn_app(Options {
        tokens: engineer_and_robot(),
        ..Options::default()
    })
    .await;
    let update = "INSERT DATA { <http://example.org/a> <http://example.org/b> 1 }";
    let post = |token: Option<&str>| {
        let mut request = app
            .client
            .post(app.url("/sparql"))
            .header(CONTENT_TYPE, "application/sparql-update")
            .body(update);
        if let Some(token) = token {
            request = request.header(AUTHORIZATION, format!("Bearer {token}"));
        }
        request.send()
    };
    assert_eq!(error(post(None).await.unwrap()).await.1, "unauthorized");
    assert_eq!(
        error(post(Some("wrong")).await.unwrap()).await.1,
        "unauthorized"
    );
    let (status, code, _) = error(post(Some(ROBOT_TOKEN)).await.unwrap()).await;
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::FORBIDDEN, "forbidden")
    );
    assert_eq!(
        post(Some(ENGINEER_TOKEN)).await.unwrap().status(),
        StatusCode::NO_CONTENT
    );

    // Reads: any valid token.
    let ask = app.client.get(app.url("/sparql?query=ASK%20%7B%7D"));
    assert_eq!(
        ask.try_clone().unwrap().send().await.unwrap().status(),
        StatusCode::UNAUTHORIZED
    );
    let response = ask.bearer_auth(ROBOT_TOKEN).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    let response = app.client.get(app.url("/sparql")).send().await.unwrap();
    assert_eq!(
        response.status(),
        StatusCode::UNAUTHORIZED,
        "the service description too"
    );

    // Graph Store writes.
    let put = |token: &str| {
        app.client
            .put(app.url("/store?graph=http%3A%2F%2Fexample.org%2Fg"))
            .bearer_auth(token)
            .header(CONTENT_TYPE, "text/turtle")
            .body("<http://example.org/s> <http://example.org/p> 1 .")
            .send()
    };
    assert_eq!(
        put(ROBOT_TOKEN).await.unwrap().status(),
        StatusCode::FORBIDDEN
    );
    assert_eq!(
        put(ENGINEER_TOKEN).await.unwrap().status(),
        StatusCode::CREATED
    );
    let response = app
        .client
        .delete(app.url("/store?graph=http%3A%2F%2Fexample.org%2Fg"))
        .bearer_auth(ROBOT_TOKEN)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::FORBIDDEN);
    let response = app
        .client
        .get(app.url("/store?graph=http%3A%2F%2Fexample.org%2Fg"))
        .bearer_auth(ROBOT_TOKEN)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
}

/// A store where `?a ?b ?c . ?d ?e ?f . ?g ?h ?i` has 10^9 solutions.
async fn slow_app(limits: QueryLimits) -> TestApp {
    let app = spawn_app(Options {
        limits,
        ..Options::default()
    })
    .await;
    let turtle: String = (0..1000)
        .map(|i| format!("<http://example.org/s{i}> <http://example.org/p> {i} .\n"))
        .collect();
    app.load(&turtle, None);
    app
}

const SLOW: &str = "SELECT (COUNT(*) AS ?n) WHERE { ?a ?b ?c . ?d ?e ?f . ?g ?h ?i }";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_query_past_its_deadline_is_stopped_with_an_error_status() {
    let app = slow_app(QueryLimits {
        deadline: Duration::from_millis(500),
        max_construct_triples: 1000,
        ..QueryLimits::default()
    })
    .await;
    let started = Instant::now();
    let (status, code, message) = error(get_query(&app, SLOW, None).await).await;
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::SERVICE_UNAVAILABLE, "timeout")
    );
    assert!(message.contains("deadline"), "{message}");
    assert!(
        started.elapsed() < Duration::from_secs(5),
        "{:?}",
        started.elapsed()
    );
    // The store is free again: a cheap query answers at once.
    let response = get_query(&app, "ASK {}", None).await;
    assert_eq!(response.status(), StatusCode::OK);
    // An update whose WHERE clause runs past the deadline is an error and changes nothing.
    let response = app
        .client
        .post(app.url("/sparql"))
        .header(CONTENT_TYPE, "application/sparql-update")
        .body("INSERT { <http://example.org/x> <http://example.org/y> ?a } WHERE { ?a ?b ?c . ?d ?e ?f . ?g ?h ?i }")
        .send()
        .await
        .unwrap();
    assert_eq!(error(response).await.1, "timeout");
    let response = get_query(
        &app,
        "ASK { <http://example.org/x> ?p ?o }",
        Some("application/sparql-results+json"),
    )
    .await;
    assert_eq!(
        response.text().await.unwrap(),
        r#"{"head":{},"boolean":false}"#
    );
}

#[tokio::test]
async fn construct_and_graph_reads_over_the_cap_are_errors_not_truncated() {
    let app = slow_app(QueryLimits {
        deadline: Duration::from_secs(20),
        max_construct_triples: 999,
        ..QueryLimits::default()
    })
    .await;
    let (status, code, message) =
        error(get_query(&app, "CONSTRUCT WHERE { ?s ?p ?o }", Some("text/turtle")).await).await;
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::INSUFFICIENT_STORAGE, "result_too_large")
    );
    assert!(message.contains("999"), "{message}");
    let response = app
        .client
        .get(app.url("/store?default"))
        .send()
        .await
        .unwrap();
    assert_eq!(error(response).await.1, "result_too_large");
    // At the cap exactly, the whole graph is served.
    let response = get_query(
        &app,
        "CONSTRUCT WHERE { ?s ?p ?o } LIMIT 999",
        Some("application/n-triples"),
    )
    .await;
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.text().await.unwrap().lines().count(), 999);
}

#[tokio::test]
async fn graph_store_errors() {
    let app = app().await;
    let graph = "/store?graph=http%3A%2F%2Fexample.org%2Fnone";
    let (status, _, message) = error(app.client.get(app.url(graph)).send().await.unwrap()).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(message.contains("http://example.org/none"), "{message}");
    assert_eq!(
        app.client
            .delete(app.url(graph))
            .send()
            .await
            .unwrap()
            .status(),
        StatusCode::NOT_FOUND
    );
    let put = |content_type: &'static str, body: &'static str| {
        app.client
            .put(app.url(graph))
            .header(CONTENT_TYPE, content_type)
            .body(body)
            .send()
    };
    let (status, code, _) = error(put("application/pdf", "%PDF").await.unwrap()).await;
    assert_eq!(
        (status, code.as_str()),
        (StatusCode::UNSUPPORTED_MEDIA_TYPE, "unsupported_media_type")
    );
    let (status, _, message) = error(put("text/turtle", "<a> <b> .").await.unwrap()).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(message.contains("Turtle"), "{message}");
    let (status, _, _) = error(
        put(
            "application/trig",
            "GRAPH <http://e/g> { <http://e/a> <http://e/b> 1 }",
        )
        .await
        .unwrap(),
    )
    .await;
    assert_eq!(
        status,
        StatusCode::BAD_REQUEST,
        "named graphs in a graph payload"
    );
    // A failed PUT leaves nothing behind.
    assert_eq!(
        app.client
            .get(app.url(graph))
            .send()
            .await
            .unwrap()
            .status(),
        StatusCode::NOT_FOUND
    );
    let response = app
        .client
        .put(app.url("/store?graph=https%3A%2F%2Fmentalsim.dev%2Fgraph%2Finferred"))
        .header(CONTENT_TYPE, "text/turtle")
        .body("")
        .send()
        .await
        .unwrap();
    assert_eq!(error(response).await.1, "conflict");
    let response = app
        .client
        .get(app.url("/store?graph=x&default"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
    let response = app
        .client
        .get(app.url("/store?graph=relative"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
    let response = app
        .client
        .put(app.url("/store"))
        .header(CONTENT_TYPE, "text/turtle")
        .body("")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
}

#[tokio::test]
async fn graph_store_round_trip_and_dataset_dump() {
    let app = app().await;
    // POST to the store creates a graph and says where.
    let response = app
        .client
        .post(app.url("/store"))
        .header(CONTENT_TYPE, "application/n-triples")
        .body("<http://example.org/s> <http://example.org/p> \"new\" .\n")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::CREATED);
    let location = response.headers()[LOCATION].to_str().unwrap().to_owned();
    assert!(location.starts_with(&app.url("/store/")), "{location}");
    // That IRI is also the graph's direct URL.
    let response = app
        .client
        .get(&location)
        .header(ACCEPT, "application/n-triples")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert!(response.text().await.unwrap().contains("\"new\""));
    let response = app.client.head(&location).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(
        response.headers()[CONTENT_TYPE],
        "text/turtle; charset=utf-8"
    );
    // The whole dataset, as N-Quads.
    let response = app
        .client
        .get(app.url("/store"))
        .header(ACCEPT, "application/n-quads")
        .send()
        .await
        .unwrap();
    assert_eq!(response.headers()[CONTENT_TYPE], "application/n-quads");
    let body = response.text().await.unwrap();
    assert!(body.contains(&format!("<{location}>")), "{body}");
    assert!(body.contains("\"Kitchen\""), "{body}");
    let response = app
        .client
        .get(app.url("/store"))
        .header(ACCEPT, "text/turtle")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::NOT_ACCEPTABLE);
    assert_eq!(
        app.client.delete(&location).send().await.unwrap().status(),
        StatusCode::NO_CONTENT
    );
    assert_eq!(
        app.client.get(&location).send().await.unwrap().status(),
        StatusCode::NOT_FOUND
    );
}

#[tokio::test]
async fn writes_refresh_the_inferred_graph() {
    let app = app().await;
    let response = post_direct(
        &app,
        "application/sparql-update",
        "PREFIX rdfs: <http://www.w3.org/2000/01/rdf-schema#> \
         INSERT DATA { <http://example.org/Room> rdfs:subClassOf <http://example.org/Place> }",
    )
    .await;
    assert_eq!(response.status(), StatusCode::NO_CONTENT);
    let ask = "ASK { GRAPH <https://mentalsim.dev/graph/inferred> { <http://example.org/kitchen> a <http://example.org/Place> } }";
    let response = get_query(&app, ask, Some("application/sparql-results+json")).await;
    assert_eq!(
        response.text().await.unwrap(),
        r#"{"head":{},"boolean":true}"#
    );
}

#[tokio::test]
async fn service_description_names_the_endpoint() {
    let app = app().await;
    let response = app
        .client
        .get(app.url("/sparql"))
        .header(ACCEPT, "application/n-triples")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()[CONTENT_TYPE], "application/n-triples");
    let body = response.text().await.unwrap();
    let endpoint = format!(
        "<http://www.w3.org/ns/sparql-service-description#endpoint> <{}>",
        app.url("/sparql")
    );
    assert!(body.contains(&endpoint), "{body}");
    assert!(body.contains("SPARQL11Update"), "{body}");
    let response = app.client.get(app.url("/sparql")).send().await.unwrap();
    assert_eq!(
        response.headers()[CONTENT_TYPE],
        "text/turtle; charset=utf-8"
    );
}

#[tokio::test]
async fn rdflib_default_graph_name_means_the_default_graph() {
    let app = app().await;
    let response = app
        .client
        .get(app.url("/sparql"))
        .query(&[
            (
                "query",
                "SELECT ?n WHERE { ?r <http://example.org/name> ?n }",
            ),
            ("default-graph-uri", "urn:x-rdflib:default"),
        ])
        .header(ACCEPT, "text/csv")
        .send()
        .await
        .unwrap();
    assert_eq!(response.text().await.unwrap().lines().count(), 3);
}
