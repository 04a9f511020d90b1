//! The console: the web pages under `/console/` (built from `console/` by npm and embedded into
//! the binary at compile time, or read from `console_dir` during front-end development), `/`
//! redirecting to them, and `/openapi.json`, both services' OpenAPI documents in one.
//!
//! The pages are public (they hold no data: every API call they make carries the token the
//! user pasted), so a browser can load them before signing in.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use axum::Router;
use axum::extract::{Path as UrlPath, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::get;
use edge::ApiError;
use utoipa::OpenApi;

/// The routes public without a token (for the guard).
pub const PUBLIC_ROUTES: [&str; 5] = [
    "/",
    "/console",
    "/console/",
    "/console/{*path}",
    "/openapi.json",
];

/// The pages as `npm run build` left them in `console/dist` when the binary was built.
/// A build without them (no npm on the machine) still compiles; its console answers 404
/// naming the missing build.
#[derive(rust_embed::RustEmbed)]
#[folder = "console/dist/"]
#[allow_missing = true]
struct Built;

/// Where the pages come from.
#[derive(Clone, Debug)]
pub enum Pages {
    /// The copy built into the binary.
    Embedded,
    /// A directory on disk (`console_dir`).
    Directory(PathBuf),
}

/// The console's routes and `/openapi.json`.
pub fn router(pages: Pages) -> Router {
    Router::new()
        .route("/", get(|| async { Redirect::to("/console/") }))
        .route("/console", get(|| async { Redirect::to("/console/") }))
        .route("/console/", get(index))
        .route("/console/{*path}", get(asset))
        .route("/openapi.json", get(openapi))
        .with_state(Arc::new(pages))
}

/// Both services' documents merged into one (paths, schemas, responses), for the console's
/// API reference and for clients that want one document.
pub fn merged_openapi() -> utoipa::openapi::OpenApi {
    let mut doc = knowledge::api::KnowledgeApi::openapi();
    doc.merge(api::FleetApi::openapi());
    doc.info.title = "Mentalsim".to_owned();
    doc.info.description = Some(
        "The knowledge service (places, robots, maps, objects, on-demand databases; SPARQL at \
         /sparql and the Graph Store at /store) and the worker service (plans, jobs, policies) \
         of one Mentalsim deployment."
            .to_owned(),
    );
    doc
}

async fn openapi() -> Response {
    static DOCUMENT: OnceLock<String> = OnceLock::new();
    let body = DOCUMENT.get_or_init(|| {
        merged_openapi()
            .to_json()
            .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    });
    ([(header::CONTENT_TYPE, "application/json")], body.clone()).into_response()
}

async fn index(State(pages): State<Arc<Pages>>) -> Response {
    serve(&pages, "index.html")
}

async fn asset(State(pages): State<Arc<Pages>>, UrlPath(path): UrlPath<String>) -> Response {
    // A path without an extension is a page of the single-page application.
    let file = if Path::new(&path).extension().is_some() {
        path.as_str()
    } else {
        "index.html"
    };
    serve(&pages, file)
}

fn serve(pages: &Pages, file: &str) -> Response {
    // `..` and absolute paths never leave the pages' directory.
    let safe = Path::new(file)
        .components()
        .all(|c| matches!(c, std::path::Component::Normal(_)));
    if !safe {
        return ApiError::not_found(format!("no console file {file}")).into_response();
    }
    let bytes: Option<Vec<u8>> = match pages {
        Pages::Embedded => Built::get(file).map(|f| f.data.into_owned()),
        Pages::Directory(dir) => std::fs::read(dir.join(file)).ok(),
    };
    let Some(bytes) = bytes else {
        let hint = if Built::get("index.html").is_none() && matches!(pages, Pages::Embedded) {
            " (this binary was built without the console: run `scripts/setup serve`, which builds \
             console/ with npm, then rebuild)"
        } else {
            ""
        };
        return ApiError::not_found(format!("no console file {file}{hint}")).into_response();
    };
    let mut headers = HeaderMap::new();
    let mime = mime_guess::from_path(file).first_or_octet_stream();
    if let Ok(v) = HeaderValue::from_str(mime.as_ref()) {
        headers.insert(header::CONTENT_TYPE, v);
    }
    // Vite names assets by their content's hash: they never change under one name.
    let cache = if file.starts_with("assets/") {
        "public, max-age=31536000, immutable"
    } else {
        "no-cache"
    };
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static(cache));
    (StatusCode::OK, headers, bytes).into_response()
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::body::Body;
    use axum::http::Request;
    use tower::ServiceExt;

    async fn get_path(router: Router, path: &str) -> Response {
        router
            .oneshot(Request::get(path).body(Body::empty()).unwrap())
            .await
            .unwrap()
    }

    #[tokio::test]
    async fn serves_a_directory_and_falls_back_to_the_page() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("index.html"), "<html>console</html>").unwrap();
        std::fs::create_dir(dir.path().join("assets")).unwrap();
        std::fs::write(dir.path().join("assets/app-1.js"), "let a = 1;").unwrap();
        let app = router(Pages::Directory(dir.path().to_owned()));

        let page = get_path(app.clone(), "/console/").await;
        assert_eq!(page.status(), StatusCode::OK);
        assert_eq!(page.headers()[header::CONTENT_TYPE], "text/html");
        let js = get_path(app.clone(), "/console/assets/app-1.js").await;
        assert_eq!(js.status(), StatusCode::OK);
        assert!(
            js.headers()[header::CONTENT_TYPE]
                .to_str()
                .unwrap()
                .contains("javascript")
        );
        assert!(
            js.headers()[header::CACHE_CONTROL]
                .to_str()
                .unwrap()
                .contains("immutable")
        );
        // A client-side route gets the page; a missing file is a 404; `..` cannot escape.
        assert_eq!(
            get_path(app.clone(), "/console/jobs").await.status(),
            StatusCode::OK
        );
        assert_eq!(
            get_path(app.clone(), "/console/assets/none.js")
                .await
                .status(),
            StatusCode::NOT_FOUND
        );
        assert_eq!(
            get_path(app.clone(), "/console/../Cargo.toml")
                .await
                .status(),
            StatusCode::NOT_FOUND
        );
        let root = get_path(app, "/").await;
        assert_eq!(root.status(), StatusCode::SEE_OTHER);
        assert_eq!(root.headers()[header::LOCATION], "/console/");
    }

    #[test]
    fn the_merged_document_has_both_services_paths() {
        let doc = merged_openapi();
        assert!(doc.paths.paths.contains_key("/v1/places"));
        assert!(doc.paths.paths.contains_key("/v1/plan"));
        assert!(doc.paths.paths.contains_key("/v1/jobs"));
    }
}
