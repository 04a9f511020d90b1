//! The test fixture: the real app (real Oxigraph on disk, real SQLite) on port 0 with a fresh
//! temporary data directory, and typed helpers around a real HTTP client.
//!
//! Logs are silent unless `TEST_LOG` is set.

use std::path::PathBuf;

use mentalsim::config::{Config, LogFormat};
use mentalsim::startup::Application;
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

impl TestApp {
    /// `GET path`.
    pub async fn get(&self, path: &str) -> reqwest::Response {
        self.client
            .get(format!("{}{path}", self.address))
            .send()
            .await
            .expect("request sent")
    }

    /// A request builder for `method path` carrying the engineer token.
    pub fn request(&self, method: reqwest::Method, path: &str) -> reqwest::RequestBuilder {
        self.client
            .request(method, format!("{}{path}", self.address))
            .bearer_auth(&self.token)
    }

    /// Reports a box-shaped table `id` of `size` metres (length = width = height) at `(x, y)`
    /// in `place` through `POST /v1/places/{place}/objects`, and checks it was created.
    pub async fn report_box(&self, place: &str, id: &str, (x, y): (f64, f64), size: f64) {
        let created = self
            .request(
                reqwest::Method::POST,
                &format!("/v1/places/{place}/objects"),
            )
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
