//! Where jobs get their worlds: the on-demand database of a floor, from the knowledge service
//! in the same process (`mentalsim serve`) or over its REST API (`mentalsim worker`).
//!
//! Everything a job simulates comes through here: no side channel from the graph store.

use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

use knowledge::Knowledge;
use knowledge::on_demand::{self, OnDemandError};
use oxrdf::Graph;
use sim::World;

/// Why no floor database could be had.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SourceError {
    /// The robot or the place does not exist (the caller's to fix).
    #[error("{0}")]
    NotFound(String),
    /// They exist but make no world (a place on no floor, ...).
    #[error("{0}")]
    Unprocessable(String),
    /// The knowledge service cannot answer now (down, store unavailable, refused our token).
    #[error("{0}")]
    Unavailable(String),
}

/// The on-demand database of one floor for one robot.
#[derive(Debug, Clone)]
pub struct FloorDatabase {
    /// The triples.
    pub graph: Graph,
    /// The robot's IRI.
    pub robot: String,
    /// The floor's IRI.
    pub floor: String,
}

impl FloorDatabase {
    /// The mental simulation of the floor with the robot: the simulation parser, then the
    /// world build. Blocking (milliseconds to a second for large maps). The error names what
    /// in the knowledge does not make a world.
    pub fn world(&self) -> Result<Arc<World>, String> {
        let spec = sim::parse_floor(&self.graph, &self.robot, &self.floor)
            .map_err(|p| format!("the knowledge of {} does not make a world: {p}", self.floor))?;
        World::build(spec).map_err(|e| format!("building the world of {}: {e}", self.floor))
    }
}

/// A boxed future, for the object-safe trait below.
pub type SourceFuture<'a> =
    Pin<Box<dyn Future<Output = Result<FloorDatabase, SourceError>> + Send + 'a>>;

/// Gives the on-demand database of the floor a place is on.
pub trait KnowledgeSource: Send + Sync + 'static {
    /// The database of the floor `place` (a floor, or a place on one; IRI or identifier) is
    /// on, with `robot` (IRI or identifier).
    fn floor_database<'a>(&'a self, place: &'a str, robot: &'a str) -> SourceFuture<'a>;
}

/// The knowledge service of this process.
#[derive(Debug, Clone)]
pub struct InProcessKnowledge {
    knowledge: Arc<Knowledge>,
}

impl InProcessKnowledge {
    /// Over the shared knowledge state.
    pub fn new(knowledge: Arc<Knowledge>) -> Self {
        Self { knowledge }
    }
}

fn source_error(e: OnDemandError) -> SourceError {
    match e {
        OnDemandError::UnknownRobot(_) | OnDemandError::UnknownPlace { .. } => {
            SourceError::NotFound(e.to_string())
        }
        OnDemandError::Store(_) => SourceError::Unavailable(e.to_string()),
        _ => SourceError::Unprocessable(e.to_string()),
    }
}

impl KnowledgeSource for InProcessKnowledge {
    fn floor_database<'a>(&'a self, place: &'a str, robot: &'a str) -> SourceFuture<'a> {
        let knowledge = self.knowledge.clone();
        let (place, robot) = (place.to_owned(), robot.to_owned());
        Box::pin(async move {
            tokio::task::spawn_blocking(move || {
                let store = knowledge.try_store().map_err(|e| {
                    SourceError::Unavailable(format!("the graph store is unavailable: {e}"))
                })?;
                let db = on_demand::floor_database_of_place(&store, &place, Some(&robot))
                    .map_err(source_error)?;
                let floor = db.floors.first().cloned().unwrap_or_default();
                Ok(FloorDatabase {
                    graph: db.triples.into_iter().collect(),
                    robot: db.robot,
                    floor,
                })
            })
            .await
            .map_err(|e| SourceError::Unavailable(format!("knowledge task failed: {e}")))?
        })
    }
}

/// The knowledge service's REST API: `GET /v1/places/{id}/on-demand?robot=…` as N-Triples.
#[derive(Clone)]
pub struct HttpKnowledge {
    base: String,
    token: Option<String>,
    client: reqwest::Client,
}

impl std::fmt::Debug for HttpKnowledge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HttpKnowledge")
            .field("base", &self.base)
            .finish_non_exhaustive()
    }
}

impl HttpKnowledge {
    /// A client of the service at `base` (`http://host:port`), sending `token` as bearer.
    pub fn new(base: &str, token: Option<String>) -> Result<Self, String> {
        let client = reqwest::Client::builder()
            .connect_timeout(Duration::from_secs(10))
            .timeout(Duration::from_secs(300))
            .build()
            .map_err(|e| format!("HTTP client: {e}"))?;
        Ok(Self {
            base: base.trim_end_matches('/').to_owned(),
            token,
            client,
        })
    }

    /// The service's URL.
    pub fn base(&self) -> &str {
        &self.base
    }

    /// `GET {base}/readyz` answers 200.
    pub async fn ready(&self) -> Result<(), String> {
        let url = format!("{}/readyz", self.base);
        match self.client.get(&url).send().await {
            Ok(r) if r.status().is_success() => Ok(()),
            Ok(r) => Err(format!("{url} answered {}", r.status())),
            Err(e) => Err(format!("cannot reach {url}: {e}")),
        }
    }
}

fn encode(s: &str) -> String {
    percent_encoding::utf8_percent_encode(s, percent_encoding::NON_ALPHANUMERIC).to_string()
}

/// The `message` of our JSON error body, or the body itself.
fn error_message(body: &str) -> String {
    serde_json::from_str::<serde_json::Value>(body)
        .ok()
        .and_then(|v| v["error"]["message"].as_str().map(str::to_owned))
        .unwrap_or_else(|| body.chars().take(500).collect())
}

impl KnowledgeSource for HttpKnowledge {
    fn floor_database<'a>(&'a self, place: &'a str, robot: &'a str) -> SourceFuture<'a> {
        Box::pin(async move {
            let url = format!(
                "{}/v1/places/{}/on-demand?robot={}",
                self.base,
                encode(place),
                encode(robot)
            );
            let mut request = self
                .client
                .get(&url)
                .header(reqwest::header::ACCEPT, "application/n-triples");
            if let Some(token) = &self.token {
                request = request.bearer_auth(token);
            }
            let response = request.send().await.map_err(|e| {
                SourceError::Unavailable(format!("cannot reach the knowledge service: {e}"))
            })?;
            let status = response.status();
            let header = |name: &str| {
                response
                    .headers()
                    .get(name)
                    .and_then(|v| v.to_str().ok())
                    .map(str::to_owned)
            };
            let (floor, robot_iri) = (header("x-floor"), header("x-robot"));
            let body = response.bytes().await.map_err(|e| {
                SourceError::Unavailable(format!("reading the on-demand database: {e}"))
            })?;
            if !status.is_success() {
                let message = error_message(&String::from_utf8_lossy(&body));
                return Err(match status.as_u16() {
                    404 => SourceError::NotFound(message),
                    400 | 422 => SourceError::Unprocessable(message),
                    _ => SourceError::Unavailable(format!(
                        "the knowledge service answered {status}: {message}"
                    )),
                });
            }
            let (Some(floor), Some(robot)) = (floor, robot_iri) else {
                return Err(SourceError::Unavailable(
                    "the knowledge service sent no X-Floor/X-Robot headers".to_owned(),
                ));
            };
            let mut graph = Graph::new();
            for triple in oxttl::NTriplesParser::new().for_slice(&body) {
                let triple = triple.map_err(|e| {
                    SourceError::Unavailable(format!("the on-demand database does not parse: {e}"))
                })?;
                graph.insert(&triple);
            }
            Ok(FloorDatabase {
                graph,
                robot,
                floor,
            })
        })
    }
}
