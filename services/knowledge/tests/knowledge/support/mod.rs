//! Test fixture: the protocol router over a fresh in-memory store, wrapped in the shared
//! middleware stack and served over real HTTP on a port of its own.

#![allow(dead_code, clippy::unwrap_used)] // reason: each module uses part of the fixture

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use edge::{Role, Tokens};
use knowledge::{Knowledge, KnowledgeStore, QueryLimits};

/// Tokens the fixtures configure when a test asks for authentication.
pub const ENGINEER_TOKEN: &str = "engineer-secret";
/// A robot's token: may read, may not write.
pub const ROBOT_TOKEN: &str = "robot-secret";

/// A running service.
pub struct TestApp {
    /// Where it listens.
    pub address: SocketAddr,
    /// The shared state, to load fixtures straight into the store.
    pub knowledge: Arc<Knowledge>,
    /// A client without default headers.
    pub client: reqwest::Client,
}

impl TestApp {
    /// `http://127.0.0.1:port` followed by `path`.
    pub fn url(&self, path: &str) -> String {
        format!("http://{}{}", self.address, path)
    }

    /// Loads Turtle into `graph` (or the default graph), bypassing the protocols.
    pub fn load(&self, turtle: &str, graph: Option<&str>) {
        let mut parser = oxigraph::io::RdfParser::from_format(oxigraph::io::RdfFormat::Turtle);
        if let Some(graph) = graph {
            parser = parser.with_default_graph(oxigraph::model::NamedNode::new(graph).unwrap());
        }
        self.knowledge
            .store()
            .unwrap()
            .embedded()
            .unwrap()
            .load_from_slice(parser, turtle.as_bytes())
            .unwrap();
    }
}

/// Options of [`spawn_app`].
pub struct Options {
    /// Tokens; open (everyone is an engineer) by default.
    pub tokens: Tokens,
    /// Query limits.
    pub limits: QueryLimits,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            tokens: Tokens::open(),
            limits: QueryLimits {
                deadline: Duration::from_secs(20),
                max_construct_triples: 100_000,
                ..QueryLimits::default()
            },
        }
    }
}

/// Tokens with one engineer and one robot.
pub fn engineer_and_robot() -> Tokens {
    Tokens::default()
        .with(ENGINEER_TOKEN, "alice", Role::Engineer)
        .with(ROBOT_TOKEN, "robot-7", Role::Robot)
}

/// Starts the router on 127.0.0.1:0 over a fresh in-memory store.
pub async fn spawn_app(options: Options) -> TestApp {
    let store = KnowledgeStore::in_memory().unwrap();
    let knowledge = Arc::new(Knowledge::new(store, options.tokens, options.limits));
    let app = edge::middleware::stack(
        knowledge::protocol::router(knowledge.clone()),
        edge::middleware::Limits {
            request_timeout: Duration::from_secs(60),
            body_limit: 16 * 1024 * 1024,
        },
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, app).await });
    TestApp {
        address,
        knowledge,
        client: reqwest::Client::new(),
    }
}

/// The repository root (two levels above this crate).
pub fn repository_root() -> PathBuf {
    PathBuf::from(
        std::env::var("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
    )
    .join("../..")
    .canonicalize()
    .unwrap()
}
