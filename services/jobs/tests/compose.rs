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

/// One Dockerfile instruction: its keyword (upper case) and its arguments, continuation lines
/// joined.
#[derive(Debug)]
struct Instruction {
    keyword: String,
    args: String,
}

/// One build stage: its name (`FROM ... AS name`), its index, and its instructions.
#[derive(Debug)]
struct Stage {
    name: Option<String>,
    instructions: Vec<Instruction>,
}

fn stages(dockerfile: &str) -> Vec<Stage> {
    let mut logical = Vec::new();
    let mut current = String::new();
    for line in dockerfile.lines() {
        let trimmed = line.trim();
        if trimmed.starts_with('#') || (trimmed.is_empty() && current.is_empty()) {
            continue;
        }
        match trimmed.strip_suffix('\\') {
            Some(part) => {
                current.push_str(part);
                current.push(' ');
            }
            None => {
                current.push_str(trimmed);
                logical.push(std::mem::take(&mut current));
            }
        }
    }
    let mut stages: Vec<Stage> = Vec::new();
    for line in logical {
        let (keyword, args) = line.split_once(char::is_whitespace).unwrap_or((&line, ""));
        let keyword = keyword.to_uppercase();
        let args = args.split_whitespace().collect::<Vec<_>>().join(" ");
        if keyword == "FROM" {
            let words: Vec<&str> = args.split(' ').collect();
            let name = words
                .iter()
                .position(|w| w.eq_ignore_ascii_case("as"))
                .and_then(|i| words.get(i + 1))
                .map(|n| (*n).to_owned());
            stages.push(Stage {
                name,
                instructions: Vec::new(),
            });
        } else if let Some(stage) = stages.last_mut() {
            stage.instructions.push(Instruction { keyword, args });
        }
    }
    stages
}

/// What keeps an image built from a clean clone (no console/dist: it is git-ignored) from
/// serving the console: empty when a stage runs `npm ci` and `npm run build` on console/'s
/// sources and the stage that runs `cargo build` copies that stage's dist to console/dist
/// first, where nothing from the build context can replace it afterwards.
fn console_build_problems(dockerfile: &str, dockerignore: &str) -> Vec<String> {
    let stages = stages(dockerfile);
    let mut problems = Vec::new();
    let runs = |s: &Stage, what: &str| {
        s.instructions
            .iter()
            .any(|i| i.keyword == "RUN" && i.args.contains(what))
    };
    let console = stages.iter().enumerate().find(|(_, s)| {
        runs(s, "npm ci")
            && runs(s, "npm run build")
            && s.instructions
                .iter()
                .any(|i| i.keyword == "COPY" && i.args.contains("console/"))
    });
    let Some((console_index, console)) = console else {
        problems.push(
            "no stage copies console/ and runs `npm ci` and `npm run build` \
             (console/dist is git-ignored: a clean clone has no pages to embed)"
                .to_owned(),
        );
        return problems;
    };
    let Some(builder) = stages.iter().find(|s| runs(s, "cargo build")) else {
        problems.push("no stage runs `cargo build`".to_owned());
        return problems;
    };
    let refs: Vec<String> = console
        .name
        .iter()
        .cloned()
        .chain([console_index.to_string()])
        .collect();
    let mut workdir = String::from("/");
    let mut dist_copy = None;
    let mut cargo_build = None;
    let mut context_copies_after = Vec::new();
    for (n, i) in builder.instructions.iter().enumerate() {
        match i.keyword.as_str() {
            "WORKDIR" => workdir = i.args.clone(),
            "RUN" if i.args.contains("cargo build") && cargo_build.is_none() => {
                cargo_build = Some(n);
            }
            "COPY" | "ADD" => {
                let words: Vec<&str> = i.args.split(' ').collect();
                let from = words
                    .iter()
                    .find_map(|w| w.strip_prefix("--from="))
                    .map(str::to_owned);
                let paths: Vec<&str> = words.into_iter().filter(|w| !w.starts_with("--")).collect();
                let Some((dest, sources)) = paths.split_last() else {
                    continue;
                };
                let dest = dest.trim_end_matches('/');
                let dest_abs = if dest.starts_with('/') {
                    dest.to_owned()
                } else {
                    format!("{}/{dest}", workdir.trim_end_matches('/'))
                };
                let into_console_dist =
                    dest_abs == format!("{}/console/dist", workdir.trim_end_matches('/'));
                match from {
                    Some(f)
                        if refs.contains(&f)
                            && into_console_dist
                            && sources
                                .iter()
                                .any(|s| s.trim_end_matches('/').ends_with("dist")) =>
                    {
                        dist_copy = Some(n);
                    }
                    None if dist_copy.is_some()
                        && sources.iter().any(|s| {
                            let s = s.trim_end_matches('/');
                            s == "." || s == "console" || s.starts_with("console/dist")
                        }) =>
                    {
                        context_copies_after.push(i.args.clone());
                    }
                    _ => {}
                }
            }
            _ => {}
        }
    }
    match (dist_copy, cargo_build) {
        (None, _) => problems.push(format!(
            "the builder never copies the console stage's dist (COPY --from={}) to console/dist",
            refs.join("|")
        )),
        (Some(copy), Some(build)) if copy > build => {
            problems.push("the builder copies the console's dist after `cargo build`".to_owned());
        }
        _ => {}
    }
    let ignored = |p: &str| {
        dockerignore
            .lines()
            .map(|l| l.trim().trim_start_matches("./").trim_end_matches('/'))
            .any(|l| l == p)
    };
    if !context_copies_after.is_empty() && !ignored("console/dist") {
        problems.push(format!(
            "`COPY {}` after the dist copy can replace the pages with a stale local console/dist \
             (.dockerignore does not exclude it)",
            context_copies_after.join("`, `COPY ")
        ));
    }
    // A local node_modules would be copied over the one `npm ci` installed.
    if !ignored("console/node_modules") {
        problems.push(".dockerignore does not exclude console/node_modules".to_owned());
    }
    problems
}

/// The image built from a clean clone serves the console: docker/Dockerfile builds console/
/// with npm in a stage of its own, and the builder embeds that build (no Docker engine needed).
#[test]
fn the_image_builds_the_console_before_the_binary() {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dockerfile = std::fs::read_to_string(root.join("docker/Dockerfile")).unwrap();
    let dockerignore = std::fs::read_to_string(root.join(".dockerignore")).unwrap_or_default();
    let problems = console_build_problems(&dockerfile, &dockerignore);
    assert!(
        problems.is_empty(),
        "docker/Dockerfile: {}",
        problems.join("; ")
    );
}

/// The check itself catches what it is for: the Dockerfile before the console stage, a dist
/// copied after `cargo build`, and a context copy that may override the dist.
#[test]
fn the_console_check_refuses_images_without_the_pages() {
    let ignore = "console/node_modules\nconsole/dist\n";
    let before = "FROM rust:1 AS builder\nWORKDIR /src\nCOPY . .\nRUN cargo build --release\n";
    assert!(console_build_problems(before, ignore)[0].contains("npm ci"));

    let console = "FROM node:20-bookworm-slim AS console\nWORKDIR /console\n\
                   COPY console/ ./\nRUN npm ci \\\n && npm run build\n";
    let good = format!(
        "{console}FROM rust:1 AS builder\nWORKDIR /src\nCOPY . .\n\
         COPY --from=console /console/dist/ console/dist/\nRUN cargo build --release\n"
    );
    assert_eq!(console_build_problems(&good, ignore), Vec::<String>::new());

    let late = format!(
        "{console}FROM rust:1 AS builder\nWORKDIR /src\nCOPY . .\nRUN cargo build --release\n\
         COPY --from=console /console/dist/ console/dist/\n"
    );
    assert!(console_build_problems(&late, ignore)[0].contains("after `cargo build`"));

    let overridden = format!(
        "{console}FROM rust:1 AS builder\nWORKDIR /src\n\
         COPY --from=console /console/dist /src/console/dist\nCOPY . .\nRUN cargo build\n"
    );
    assert_eq!(
        console_build_problems(&overridden, ignore),
        Vec::<String>::new()
    );
    let problems = console_build_problems(&overridden, "console/node_modules\n");
    assert!(
        problems[0].contains("stale local console/dist"),
        "{problems:?}"
    );

    let no_build = format!(
        "{}FROM rust:1 AS builder\nWORKDIR /src\nCOPY . .\nRUN cargo build\n",
        console.replace(" \\\n && npm run build", "")
    );
    assert!(console_build_problems(&no_build, ignore)[0].contains("npm run build"));
}
