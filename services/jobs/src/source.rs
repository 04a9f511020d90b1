//! Where jobs get their worlds: the on-demand database of a floor, from the knowledge service
//! in the same process (`mentalsim serve`) or over its REST API (`mentalsim worker`).
//!
//! Everything a job simulates comes through here: no side channel from the graph store.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use knowledge::Knowledge;
use knowledge::on_demand::{self, OnDemandError};
use oxrdf::Graph;
pub use planner::floor::{FloorDatabase, KnowledgeSource, SourceError, SourceFuture};

/// Databases kept per source (one per place and robot asked for recently).
const CACHED_DATABASES: usize = 32;

/// The databases a source read, by (place, robot) as asked, with the state tag each was read
/// at. Databases of equal version are shared, so two places on one floor share one world.
#[derive(Debug, Default)]
struct DatabaseCache {
    entries: Mutex<HashMap<PlaceRobot, (String, Arc<FloorDatabase>)>>,
}

/// (place, robot) as a caller asked for them.
type PlaceRobot = (String, String);

impl DatabaseCache {
    /// The database for (place, robot) read at state `tag`, if cached.
    fn get(
        &self,
        place: &str,
        robot: &str,
        tag: Option<&str>,
    ) -> Option<(String, Arc<FloorDatabase>)> {
        let entries = self.entries.lock().unwrap_or_else(PoisonError::into_inner);
        entries
            .get(&(place.to_owned(), robot.to_owned()))
            .filter(|(t, _)| tag.is_none_or(|tag| t == tag))
            .cloned()
    }

    /// Keeps `db` (read at state `tag`) for (place, robot); returns the shared copy, which is
    /// an existing database of the same version when there is one.
    fn put(&self, place: &str, robot: &str, tag: String, db: FloorDatabase) -> Arc<FloorDatabase> {
        let mut entries = self.entries.lock().unwrap_or_else(PoisonError::into_inner);
        let db = entries
            .values()
            .find(|(_, d)| d.version == db.version)
            .map_or_else(|| Arc::new(db), |(_, d)| Arc::clone(d));
        if entries.len() >= CACHED_DATABASES {
            entries.clear();
        }
        entries.insert((place.to_owned(), robot.to_owned()), (tag, Arc::clone(&db)));
        db
    }
}

/// The knowledge service of this process.
#[derive(Debug, Clone)]
pub struct InProcessKnowledge {
    knowledge: Arc<Knowledge>,
    cache: Arc<DatabaseCache>,
}

impl InProcessKnowledge {
    /// Over the shared knowledge state.
    pub fn new(knowledge: Arc<Knowledge>) -> Self {
        Self {
            knowledge,
            cache: Arc::default(),
        }
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
        let cache = Arc::clone(&self.cache);
        let (place, robot) = (place.to_owned(), robot.to_owned());
        Box::pin(async move {
            tokio::task::spawn_blocking(move || {
                let unavailable =
                    |e| SourceError::Unavailable(format!("the graph store is unavailable: {e}"));
                let store = knowledge.try_store().map_err(unavailable)?;
                let tag = store.state_tag().map_err(unavailable)?;
                if let Some((_, db)) = cache.get(&place, &robot, Some(&tag)) {
                    return Ok(db);
                }
                let db = on_demand::floor_database_of_place(&store, &place, Some(&robot))
                    .map_err(source_error)?;
                let floor = db.floors.first().cloned().unwrap_or_default();
                let db =
                    FloorDatabase::new(db.triples.into_iter().collect(), db.robot, floor, &tag);
                // A write while the database was read leaves it unnamed: not cached.
                if store.state_tag().ok().as_deref() == Some(tag.as_str()) {
                    Ok(cache.put(&place, &robot, tag, db))
                } else {
                    Ok(Arc::new(db))
                }
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
    /// By (place, robot): the service's `ETag` and the database it came with.
    cache: Arc<DatabaseCache>,
}

impl std::fmt::Debug for HttpKnowledge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HttpKnowledge")
            .field("base", &self.base)
            .finish_non_exhaustive()
    }
}

/// Why the knowledge service is not ready for a worker: a summary naming no URL or credential
/// (what probes see), and the full reason (what the log has).
#[derive(Debug, Clone, thiserror::Error)]
#[error("{summary}: {reason}")]
pub struct NotReady {
    /// The summary.
    pub summary: &'static str,
    /// The full reason.
    pub reason: String,
}

impl NotReady {
    fn new(summary: &'static str, reason: String) -> Self {
        Self { summary, reason }
    }
}

impl HttpKnowledge {
    /// A client of the service at `base` (`http://host:port`), sending `token` as bearer.
    pub fn new(base: &str, token: Option<String>) -> Result<Self, reqwest::Error> {
        let client = reqwest::Client::builder()
            .connect_timeout(Duration::from_secs(10))
            .timeout(Duration::from_secs(300))
            .build()?;
        Ok(Self {
            base: base.trim_end_matches('/').to_owned(),
            token,
            client,
            cache: Arc::default(),
        })
    }

    /// The service's URL.
    pub fn base(&self) -> &str {
        &self.base
    }

    /// `GET {base}/readyz` answers 200, and the service accepts this worker's token (a
    /// worker without one would claim jobs only to fail each with a 401). The error is a
    /// summary naming no URL or credential, and the full reason.
    pub async fn ready(&self) -> Result<(), NotReady> {
        let url = format!("{}/readyz", self.base);
        match self.client.get(&url).send().await {
            Ok(r) if r.status().is_success() => {}
            Ok(r) => {
                return Err(NotReady::new(
                    "the knowledge service is not ready",
                    format!("{url} answered {}", r.status()),
                ));
            }
            Err(e) => {
                return Err(NotReady::new(
                    "the knowledge service cannot be reached",
                    format!("cannot reach {url}: {e}"),
                ));
            }
        }
        let Some(token) = &self.token else {
            return Err(NotReady::new(
                "no knowledge token configured",
                "no token for the knowledge service: set knowledge_token or knowledge_token_file"
                    .to_owned(),
            ));
        };
        // The service description: the cheapest answer that needs a valid token.
        let url = format!("{}/sparql", self.base);
        match self.client.get(&url).bearer_auth(token).send().await {
            Ok(r) if r.status().is_success() => Ok(()),
            Ok(r) if r.status() == reqwest::StatusCode::UNAUTHORIZED => Err(NotReady::new(
                "the knowledge service rejects the worker's token",
                format!("{url} answered 401 to the configured knowledge token"),
            )),
            Ok(r) => Err(NotReady::new(
                "the knowledge service is not ready",
                format!("{url} answered {}", r.status()),
            )),
            Err(e) => Err(NotReady::new(
                "the knowledge service cannot be reached",
                format!("cannot reach {url}: {e}"),
            )),
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
            let cached = self.cache.get(place, robot, None);
            if let Some((etag, _)) = &cached {
                request = request.header(reqwest::header::IF_NONE_MATCH, etag);
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
            if status == reqwest::StatusCode::NOT_MODIFIED
                && let Some((_, db)) = cached
            {
                return Ok(db);
            }
            let (floor, robot_iri) = (header("x-floor"), header("x-robot"));
            let etag = header("etag");
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
            let (Some(floor), Some(robot_iri)) = (floor, robot_iri) else {
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
            Ok(match etag {
                Some(etag) => {
                    let db = FloorDatabase::new(graph, robot_iri, floor, &etag);
                    self.cache.put(place, robot, etag, db)
                }
                // No tag: a state that changed while it was read; not cached.
                None => Arc::new(FloorDatabase::new(
                    graph,
                    robot_iri,
                    floor,
                    &format!("untagged-{}", uuid::Uuid::new_v4()),
                )),
            })
        })
    }
}
