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

/// Docker creates a volume's mount point as root when the image lacks it, and the non-root
/// user then cannot write there: every `/data/...` directory `compose.yaml` mounts must be
/// created, owned by the user, in `docker/Dockerfile`.
#[test]
fn every_mounted_data_directory_exists_in_the_image() {
    let docker = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docker");
    let compose = std::fs::read_to_string(docker.join("compose.yaml")).unwrap();
    let dockerfile = std::fs::read_to_string(docker.join("Dockerfile")).unwrap();
    let created: Vec<&str> = dockerfile
        .lines()
        .filter(|l| l.contains("install -d -o mentalsim -g mentalsim"))
        .flat_map(str::split_whitespace)
        .filter(|w| w.starts_with("/data/"))
        .collect();
    let mounted: Vec<&str> = compose
        .lines()
        .filter_map(|l| l.trim().strip_prefix("- "))
        .filter_map(|v| v.split(':').nth(1))
        .filter(|target| target.starts_with("/data/"))
        .collect();
    assert!(mounted.contains(&"/data/policies"), "{mounted:?}");
    for target in mounted {
        assert!(
            created.contains(&target),
            "compose.yaml mounts {target} but the Dockerfile creates only {created:?}"
        );
    }
}
