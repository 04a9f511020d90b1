//! The test fixture: the real app (real Oxigraph on disk, real SQLite) on port 0 with a fresh
//! temporary data directory, and typed helpers around a real HTTP client.
//!
//! Logs are silent unless `TEST_LOG` is set.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use mentalsim::config::{Config, LogFormat, TokenConfig};
use mentalsim::startup::Application;
use reqwest::Method;
use serde_json::Value;
use tokio_util::sync::CancellationToken;

/// A running app and a client for it. Stops the app when dropped.
pub struct TestApp {
    /// `http://127.0.0.1:PORT`.
    pub address: String,
    /// A client with no default headers.
    pub client: reqwest::Client,
    /// The app's data directory; removed when dropped unless the app was given one.
    pub data_dir: PathBuf,
    /// The engineer token the app created in its data directory (empty if it could not).
    pub token: String,
    _temp: Option<tempfile::TempDir>,
    stop: CancellationToken,
    handle: Option<tokio::task::JoinHandle<anyhow::Result<()>>>,
}

/// Starts the app with a fresh temporary data directory.
pub async fn spawn_app() -> TestApp {
    let temp = tempfile::tempdir().expect("temporary directory");
    let data_dir = temp.path().join("data");
    spawn_app_with(|c| c.data_dir = data_dir.clone(), Some(temp)).await
}

/// Starts the app with a configuration edited by `edit` (bind is forced to port 0).
pub async fn spawn_app_with(
    edit: impl FnOnce(&mut Config),
    temp: Option<tempfile::TempDir>,
) -> TestApp {
    let mut config = Config {
        log_format: LogFormat::Text,
        ..Config::default()
    };
    edit(&mut config);
    config.bind = "127.0.0.1:0".parse().expect("address");
    if std::env::var_os("TEST_LOG").is_some() {
        mentalsim::telemetry::init(&config);
    }
    let data_dir = config.data_dir.clone();
    let app = Application::build(config).await.expect("app builds");
    let address = format!("http://{}", app.local_addr());
    let stop = CancellationToken::new();
    let stopped = stop.clone();
    let handle = tokio::spawn(app.run_until(async move { stopped.cancelled().await }));
    let token = std::fs::read_to_string(data_dir.join("admin.token"))
        .map(|t| t.trim().to_owned())
        .unwrap_or_default();
    TestApp {
        address,
        client: reqwest::Client::new(),
        data_dir,
        token,
        _temp: temp,
        stop,
        handle: Some(handle),
    }
}

/// Gives `config` exactly these tokens: `(token, name, role)`; a robot's token is named after
/// the robot it may speak for (its IRI or identifier).
pub fn with_tokens(config: &mut Config, tokens: &[(&str, &str, edge::Role)]) {
    config.tokens = tokens
        .iter()
        .map(|&(token, name, role)| TokenConfig {
            token: token.to_owned(),
            name: name.to_owned(),
            role,
        })
        .collect();
}

/// `s` percent-encoded for a path segment or a query value.
pub fn url_encode(s: &str) -> String {
    percent_encoding::utf8_percent_encode(s, percent_encoding::NON_ALPHANUMERIC).to_string()
}

/// The status and JSON body of a response (`{"text": …}` when the body is not JSON).
pub async fn answer(response: reqwest::Response) -> (u16, Value) {
    let status = response.status().as_u16();
    let text = response.text().await.expect("body read");
    let body = serde_json::from_str(&text).unwrap_or_else(|_| serde_json::json!({ "text": text }));
    (status, body)
}

impl TestApp {
    /// `method path` with `token` and an optional JSON body: the status and the JSON answer.
    pub async fn json_as(
        &self,
        token: &str,
        method: Method,
        path: &str,
        body: Option<&Value>,
    ) -> (u16, Value) {
        let mut request = self
            .client
            .request(method, format!("{}{path}", self.address))
            .bearer_auth(token);
        if let Some(body) = body {
            request = request.json(body);
        }
        answer(request.send().await.expect("request sent")).await
    }

    /// `GET path` with the engineer token: the status and the JSON answer.
    pub async fn get_json(&self, path: &str) -> (u16, Value) {
        self.json_as(&self.token, Method::GET, path, None).await
    }

    /// `POST path` with `body` and the engineer token: the status and the JSON answer.
    pub async fn post_json(&self, path: &str, body: &Value) -> (u16, Value) {
        self.json_as(&self.token, Method::POST, path, Some(body))
            .await
    }

    /// `POST /sparql` with a SPARQL query, asking for JSON results, with the engineer token.
    pub async fn sparql_query(&self, query: &str) -> reqwest::Response {
        self.request(Method::POST, "/sparql")
            .header("content-type", "application/sparql-query")
            .header("accept", "application/sparql-results+json")
            .body(query.to_owned())
            .send()
            .await
            .expect("request sent")
    }

    /// `POST /sparql` with a SPARQL update, with the engineer token.
    pub async fn sparql_update(&self, update: &str) -> reqwest::Response {
        self.request(Method::POST, "/sparql")
            .header("content-type", "application/sparql-update")
            .body(update.to_owned())
            .send()
            .await
            .expect("request sent")
    }

    /// Job `id` (`GET /v1/jobs/{id}`, which must answer 200) once `done` says so; fails after
    /// `timeout` naming the job's last state.
    pub async fn wait_for_job(
        &self,
        id: &str,
        timeout: Duration,
        done: impl Fn(&Value) -> bool,
    ) -> Value {
        let deadline = Instant::now() + timeout;
        loop {
            let (status, job) = self.get_json(&format!("/v1/jobs/{id}")).await;
            assert_eq!(status, 200, "GET /v1/jobs/{id}: {job}");
            if done(&job) {
                return job;
            }
            assert!(Instant::now() < deadline, "timed out; job is {job:#}");
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    }

    /// Job `id` once it has succeeded or failed (two minutes at most).
    pub async fn finished_job(&self, id: &str) -> Value {
        self.wait_for_job(id, Duration::from_secs(120), |j| {
            j["state"] == "succeeded" || j["state"] == "failed"
        })
        .await
    }

    /// `GET path`.
    pub async fn get(&self, path: &str) -> reqwest::Response {
        self.client
            .get(format!("{}{path}", self.address))
            .send()
            .await
            .expect("request sent")
    }

    /// A request builder for `method path` carrying the engineer token.
    pub fn request(&self, method: Method, path: &str) -> reqwest::RequestBuilder {
        self.client
            .request(method, format!("{}{path}", self.address))
            .bearer_auth(&self.token)
    }

    /// Reports a box-shaped table `id` of `size` metres (length = width = height) at `(x, y)`
    /// in `place` through `POST /v1/places/{place}/objects`, and checks it was created.
    pub async fn report_box(&self, place: &str, id: &str, (x, y): (f64, f64), size: f64) {
        let created = self
            .request(Method::POST, &format!("/v1/places/{place}/objects"))
            .json(&serde_json::json!({
                "id": id,
                "class": "Table",
                "pose": {"x": x, "y": y, "yaw": 0.0},
                "shape": {"type": "box", "length": size, "width": size, "height": size},
                "colour": {"r": 0.5, "g": 0.4, "b": 0.2}
            }))
            .send()
            .await
            .expect("request sent");
        let status = created.status();
        assert_eq!(status, 201, "{}", created.text().await.unwrap_or_default());
    }

    /// Stops the app gracefully and waits for it.
    pub async fn stop(mut self) {
        self.stop.cancel();
        if let Some(handle) = self.handle.take() {
            handle
                .await
                .expect("app task")
                .expect("app stopped cleanly");
        }
    }
}

impl Drop for TestApp {
    fn drop(&mut self) {
        self.stop.cancel();
    }
}

/// One server-sent event whose data is JSON.
#[derive(Debug)]
pub struct SseEvent {
    /// Its `id`, an integer.
    pub id: i64,
    /// Its `event` name.
    pub event: String,
    /// Its `data`, parsed.
    pub data: Value,
}

/// Reads server-sent events from a response as they arrive.
pub struct EventReader {
    response: reqwest::Response,
    text: String,
}

impl EventReader {
    /// Checks the response is a 200 event stream.
    pub fn new(response: reqwest::Response) -> Self {
        assert_eq!(response.status(), 200);
        assert!(
            response.headers()[reqwest::header::CONTENT_TYPE]
                .to_str()
                .unwrap()
                .starts_with("text/event-stream")
        );
        Self {
            response,
            text: String::new(),
        }
    }

    /// The next event with an id (comments and keep-alives skipped); `None` when the server
    /// closed the stream. Panics when none arrives by `deadline`.
    pub async fn next(&mut self, deadline: tokio::time::Instant) -> Option<SseEvent> {
        loop {
            while let Some(end) = self.text.find("\n\n") {
                let block: String = self.text.drain(..end + 2).collect();
                if let Some(event) = parse_event(&block) {
                    return Some(event);
                }
            }
            match tokio::time::timeout_at(deadline, self.response.chunk()).await {
                Ok(Ok(Some(chunk))) => self.text.push_str(&String::from_utf8_lossy(&chunk)),
                Ok(Ok(None)) => return None,
                Ok(Err(e)) => panic!("stream failed: {e}"),
                Err(_) => panic!("no event before the deadline; unparsed:\n{}", self.text),
            }
        }
    }
}

fn parse_event(block: &str) -> Option<SseEvent> {
    let (mut id, mut event, mut data) = (None, String::new(), String::new());
    for line in block.lines() {
        if let Some(v) = line.strip_prefix("id:") {
            id = Some(v.trim().parse::<i64>().unwrap());
        } else if let Some(v) = line.strip_prefix("event:") {
            event = v.trim().to_owned();
        } else if let Some(v) = line.strip_prefix("data:") {
            data.push_str(v.trim());
        }
    }
    Some(SseEvent {
        id: id?,
        event,
        data: serde_json::from_str(&data).unwrap(),
    })
}

/// Reads an event stream until the server closes it (panics after `timeout`).
pub async fn read_events(response: reqwest::Response, timeout: Duration) -> Vec<SseEvent> {
    let deadline = tokio::time::Instant::now() + timeout;
    let mut reader = EventReader::new(response);
    let mut events = Vec::new();
    while let Some(e) = reader.next(deadline).await {
        events.push(e);
    }
    events
}
