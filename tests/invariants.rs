//! The invariants of ARCHITECTURE.md, checked on the workspace's own manifests (`cargo metadata
//! --no-deps`): which crate may depend on which of ours (the direction of every crate), and
//! which crates alone may know libtorch, HTTP serving, SQL, the graph store and OpenAPI. A new
//! dependency that breaks one fails here, naming the crate and the rule; one that is meant
//! changes the table below and ARCHITECTURE.md together.

#![allow(clippy::unwrap_used, clippy::expect_used)] // reason: tests panic on failure

use std::collections::{BTreeMap, BTreeSet};

/// Each workspace crate and the workspace crates its library (or the binary) may depend on.
/// The core (tosm, grid, sim, prm, rehearsal, learning) depends only on the core; `wire` and
/// `planner` on the core and the schedule's types; the edges on what they serve; `bench` and
/// `fixtures` on anything, and nothing of the product depends on them but the binary (for
/// `mentalsim bench`).
const DIRECTION: &[(&str, &[&str])] = &[
    ("tosm", &[]),
    ("grid", &[]),
    ("sim", &["tosm", "grid"]),
    ("prm", &["grid"]),
    ("learning", &["sim"]),
    ("rehearsal", &["grid", "learning", "prm", "sim"]),
    ("queue", &[]),
    ("traffic", &["queue"]),
    (
        "planner",
        &["grid", "learning", "prm", "rehearsal", "sim", "traffic"],
    ),
    (
        "wire",
        &["learning", "planner", "prm", "rehearsal", "sim", "traffic"],
    ),
    ("edge", &[]),
    ("knowledge", &["edge", "grid", "sim", "tosm"]),
    (
        "jobs",
        &[
            "edge",
            "grid",
            "knowledge",
            "learning",
            "planner",
            "prm",
            "queue",
            "rehearsal",
            "sim",
            "traffic",
            "wire",
        ],
    ),
    (
        "api",
        &[
            "edge",
            "jobs",
            "learning",
            "planner",
            "queue",
            "rehearsal",
            "sim",
            "traffic",
            "wire",
        ],
    ),
    ("fixtures", &["queue", "sim"]),
    (
        "bench",
        &[
            "fixtures",
            "grid",
            "knowledge",
            "learning",
            "planner",
            "prm",
            "queue",
            "rehearsal",
            "sim",
            "tosm",
            "traffic",
        ],
    ),
    (
        "mentalsim",
        &[
            "api",
            "bench",
            "edge",
            "jobs",
            "knowledge",
            "learning",
            "planner",
            "prm",
            "queue",
            "rehearsal",
            "sim",
            "tosm",
        ],
    ),
];

/// External crates only some of ours may name as a (normal) dependency, and why.
const ONLY: &[(&[&str], &[&str], &str)] = &[
    (
        &["tch", "torch-sys"],
        &["learning"],
        "only `learning` (feature `train`) knows libtorch",
    ),
    (
        &["axum", "hyper", "hyper-util", "tower-http"],
        &["edge", "knowledge", "api", "mentalsim"],
        "only the HTTP edges serve HTTP",
    ),
    (
        &["sqlx"],
        &["queue", "traffic", "fixtures"],
        "only the job engine and the fleet schedule know the job database",
    ),
    (
        &["oxigraph"],
        &["knowledge"],
        "only `knowledge` opens a graph store",
    ),
    (
        &["utoipa"],
        &["edge", "knowledge", "api", "wire", "jobs", "mentalsim"],
        "OpenAPI schemas (wire types) live at the HTTP edge",
    ),
    (
        &["tokio", "reqwest"],
        &[
            "planner",
            "queue",
            "traffic",
            "edge",
            "knowledge",
            "jobs",
            "api",
            "fixtures",
            "bench",
            "mentalsim",
        ],
        "the core (tosm, grid, sim, prm, rehearsal, learning, wire) does no IO and knows no async runtime",
    ),
];

/// Crates whose only place is a test or a harness: never a normal dependency of a product library.
const HARNESSES: &[&str] = &["bench", "fixtures"];

/// [`DIRECTION`] as sets.
fn direction() -> BTreeMap<&'static str, BTreeSet<&'static str>> {
    DIRECTION
        .iter()
        .map(|(c, deps)| (*c, deps.iter().copied().collect()))
        .collect()
}

struct Manifest {
    /// Normal (not dev, not build) dependencies by crate, ours and external.
    normal: BTreeMap<String, BTreeSet<String>>,
}

fn manifest() -> Manifest {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    let out = std::process::Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut normal = BTreeMap::new();
    for p in meta["packages"].as_array().unwrap() {
        let deps = p["dependencies"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|d| d["kind"].is_null())
            .map(|d| d["name"].as_str().unwrap().to_owned())
            .collect();
        normal.insert(p["name"].as_str().unwrap().to_owned(), deps);
    }
    Manifest { normal }
}

#[test]
fn every_crate_is_in_the_direction_table_and_depends_only_downwards() {
    let m = manifest();
    let table = direction();
    let ours: BTreeSet<&str> = m.normal.keys().map(String::as_str).collect();
    let listed: BTreeSet<&str> = table.keys().copied().collect();
    assert_eq!(
        ours, listed,
        "every workspace crate has a row in DIRECTION (and ARCHITECTURE.md)"
    );
    let mut broken = Vec::new();
    for (krate, deps) in &m.normal {
        for dep in deps.iter().filter(|d| ours.contains(d.as_str())) {
            if !table[krate.as_str()].contains(dep.as_str()) {
                broken.push(format!("{krate} depends on {dep}"));
            }
        }
    }
    assert!(
        broken.is_empty(),
        "dependencies against the direction of ARCHITECTURE.md: {broken:?}"
    );
}

#[test]
fn libtorch_http_sql_the_graph_store_and_openapi_stay_where_they_belong() {
    let m = manifest();
    let mut broken = Vec::new();
    for (externals, allowed, why) in ONLY {
        for (krate, deps) in &m.normal {
            for ext in externals.iter().filter(|e| deps.contains(**e)) {
                if !allowed.contains(&krate.as_str()) {
                    broken.push(format!("{krate} depends on {ext}: {why}"));
                }
            }
        }
    }
    assert!(broken.is_empty(), "{broken:#?}");
}

#[test]
fn no_product_library_carries_a_benchmark_harness_or_test_fixture() {
    let m = manifest();
    let mut broken = Vec::new();
    for (krate, deps) in &m.normal {
        if HARNESSES.contains(&krate.as_str()) || krate == "mentalsim" {
            continue;
        }
        for h in HARNESSES.iter().filter(|h| deps.contains(**h)) {
            broken.push(format!("{krate} depends on {h}"));
        }
    }
    assert!(
        broken.is_empty(),
        "product crates export no benchmark harness or test fixture: {broken:?}"
    );
}

/// The rules above can fail: a manifest that breaks each is caught.
#[test]
fn the_rules_catch_what_they_forbid() {
    let deps = |names: &[&str]| {
        names
            .iter()
            .map(|n| (*n).to_owned())
            .collect::<BTreeSet<_>>()
    };
    let broken = Manifest {
        normal: BTreeMap::from([
            (
                "sim".to_owned(),
                deps(&["tosm", "grid", "planner", "tokio"]),
            ),
            ("planner".to_owned(), deps(&["tch", "fixtures"])),
        ]),
    };
    let table = direction();
    assert!(!table["sim"].contains("planner"));
    let forbidden = |krate: &str, ext: &str| {
        ONLY.iter()
            .any(|(e, allowed, _)| e.contains(&ext) && !allowed.contains(&krate))
    };
    assert!(broken.normal["sim"].iter().any(|d| forbidden("sim", d)));
    assert!(forbidden("planner", "tch"));
    assert!(HARNESSES.contains(&"fixtures") && broken.normal["planner"].contains("fixtures"));
}
