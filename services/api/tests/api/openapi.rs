//! The committed OpenAPI document (`openapi/fleet.json`) must match the code. Refresh it with
//! `UPDATE_OPENAPI=1 cargo test --release -p api --test api openapi` (after a workspace build).

use utoipa::OpenApi;

#[test]
fn committed_openapi_document_matches_the_code() {
    let path = std::path::PathBuf::from(
        std::env::var("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
    )
    .join("../../openapi/fleet.json");
    let generated = api::FleetApi::openapi()
        .to_pretty_json()
        .expect("the document serialises");
    if std::env::var_os("UPDATE_OPENAPI").is_some() {
        std::fs::write(&path, format!("{generated}\n")).expect("write openapi/fleet.json");
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed.trim_end() == generated.trim_end(),
        "openapi/fleet.json is out of date with the code: run \
         `UPDATE_OPENAPI=1 cargo test --release -p api --test api openapi` and commit the result"
    );
}
