//! `docker/compose.yaml` (the scale-out deployment: PostgreSQL, knowledge, workers) is valid:
//! `docker-compose config` accepts it. Without docker-compose (scripts/setup installs it) the
//! test fails under CI or with `MENTALSIM_REQUIRE_ALL=1`, and otherwise says why it returns
//! ([`fixtures::missing`]).

#![allow(clippy::unwrap_used, clippy::print_stdout)] // reason: a test reports and panics

use std::process::Command;

#[test]
fn compose_file_validates() {
    let file = std::path::PathBuf::from(
        std::env::var("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
    )
    .join("../../docker/compose.yaml");
    let out = match Command::new("docker-compose")
        .arg("-f")
        .arg(&file)
        .arg("config")
        .env_remove("POSTGRES_PASSWORD")
        .output()
    {
        Ok(out) => out,
        Err(e) => {
            fixtures::missing(format!("docker-compose ({e}); scripts/setup installs it"));
            return;
        }
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "docker-compose config rejected {}:\n{}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    for needle in [
        "image: postgres:15",
        "MENTALSIM_DATABASE_URL: postgres://mentalsim:mentalsim@postgres:5432/mentalsim",
        "http://knowledge:8080",
        "replicas: 3",
        "/readyz",
        "condition: service_healthy",
        "- --knowledge-url",
        "MENTALSIM_WORKER_CONCURRENCY: '0'",
        "MENTALSIM_KNOWLEDGE_TOKEN_FILE: /knowledge/admin.token",
        "policies:/data/policies",
    ] {
        assert!(
            stdout.contains(needle),
            "{needle:?} missing from:\n{stdout}"
        );
    }
}
