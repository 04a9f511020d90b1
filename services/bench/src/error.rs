//! Why a benchmark could not run: the one error type of every harness here.

use std::path::{Path, PathBuf};

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A file or directory could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A map file is malformed.
    #[error("{path}: {source}")]
    Map {
        /// The YAML file.
        path: PathBuf,
        /// What is wrong.
        source: tosm::RosMapError,
    },
    /// A map or scenario file is malformed (MovingAI formats).
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The planner rejected the map.
    #[error("{path}: {source}")]
    ConfigSpace {
        /// The map file.
        path: PathBuf,
        /// What is wrong.
        source: prm::ConfigSpaceError,
    },
    /// The planner rejected the parameters.
    #[error("{map}: {source}")]
    Build {
        /// The map.
        map: String,
        /// What is wrong.
        source: prm::BuildError,
    },
    /// No map to run on.
    #[error("no ROS map_server .yaml file under {0}")]
    NoMaps(PathBuf),
    /// An option is out of range.
    #[error("bad option: {0}")]
    BadOption(String),
    /// The planner's idle-time improver failed (the schedule, a simulation).
    #[error("improving the fleet's schedule: {0}")]
    Improve(#[source] planner::PlanFailure),
    /// The rehearsal (roadmap, rollouts) failed on a map.
    #[error("{map}: {source}")]
    Rehearsal {
        /// The map.
        map: String,
        /// What failed.
        source: rehearsal::PlanError,
    },
    /// The plot could not be drawn.
    #[error("plot {path}: {message}")]
    Plot {
        /// The PNG path.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

impl From<knowledge::maps::LoadError> for BenchError {
    fn from(e: knowledge::maps::LoadError) -> Self {
        use knowledge::maps::LoadError;
        match e {
            LoadError::Io { path, source } => BenchError::Io { path, source },
            LoadError::Map { path, source } => BenchError::Map { path, source },
            LoadError::World { path, message } => BenchError::Format { path, message },
        }
    }
}

/// Maps an IO error on `path` to [`BenchError::Io`].
pub(crate) fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> BenchError + '_ {
    move |source| BenchError::Io {
        path: path.to_path_buf(),
        source,
    }
}
