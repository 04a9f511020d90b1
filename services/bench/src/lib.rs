//! Benchmark harnesses behind `mentalsim bench ...`.

pub mod beta;
pub mod edges;
pub mod error;
pub mod fleet;
pub mod fleet_replay;
pub mod knowledge;
pub mod learner;
pub mod maps;
pub mod movingai;
pub mod navigation;
pub mod plan_load;
pub mod prm;
pub mod queue;
pub mod sim;

/// This crate's directory (its `scripts/`, the repository's `ontologies/` two levels up). Read
/// at run time from `CARGO_MANIFEST_DIR` (cargo sets it for tests), else from the working
/// directory when it is the repository root (how `scripts/bench` runs), else the directory the
/// crate was compiled in. Test binaries are shared between clones through the per-machine
/// target directory, so a path compiled in may name a clone that no longer exists.
pub fn bench_dir() -> std::path::PathBuf {
    if let Some(dir) = std::env::var_os("CARGO_MANIFEST_DIR") {
        return dir.into();
    }
    let here = std::path::Path::new("services/bench");
    if here.join("scripts").is_dir() {
        return here.to_path_buf();
    }
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
