//! The ROS map_server maps the benchmarks run on: finding them under a directory, naming them,
//! loading them as the planner sees them, and the seed of each map's runs.

use std::path::{Path, PathBuf};

use grid::hash::fnv1a;
use grid::seed::mix;
use prm::PlanningGrid;

use crate::error::BenchError;

/// All `.yaml`/`.yml` files under `dir`, sorted, that look like map_server metadata
/// ([`knowledge::maps::find_yamls`]).
pub fn find_yamls(dir: &Path) -> Result<Vec<PathBuf>, BenchError> {
    Ok(knowledge::maps::find_yamls(dir)?)
}

/// A short unique name per map: its folder, or folder/stem when a folder holds several maps.
pub(crate) fn map_names(root: &Path, yamls: &[PathBuf]) -> Vec<String> {
    let folder = |p: &Path| {
        p.parent()
            .and_then(|d| d.strip_prefix(root).ok())
            .map(|d| d.display().to_string())
            .filter(|s| !s.is_empty())
    };
    yamls
        .iter()
        .map(|y| {
            let stem = y
                .file_stem()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
            let same_folder = yamls.iter().filter(|o| o.parent() == y.parent()).count();
            match folder(y) {
                Some(f) if same_folder == 1 => f,
                Some(f) => format!("{f}/{stem}"),
                None => stem,
            }
        })
        .collect()
}

/// Reads a map_server map ([`knowledge::maps::read_ros_map`]) and keeps what the planner
/// needs: unknown counts as blocked.
pub fn load_ros_map(yaml: &Path) -> Result<PlanningGrid, BenchError> {
    let grid = knowledge::maps::read_ros_map(yaml)?;
    Ok(planning_grid_from_occupancy(&grid))
}

/// The planner's view of an occupancy grid. The origin's yaw is not applied: the planner works
/// in the grid's own frame (every shared map has yaw 0).
pub fn planning_grid_from_occupancy(grid: &tosm::OccupancyGrid) -> PlanningGrid {
    PlanningGrid {
        width: grid.width,
        height: grid.height,
        resolution: grid.resolution,
        origin_x: grid.origin.x,
        origin_y: grid.origin.y,
        blocked: grid
            .cells
            .iter()
            .map(|c| *c != tosm::Occupancy::Free)
            .collect(),
    }
}

/// The seed of a map's runs: `seed` mixed with the FNV-1a hash of the map's name, so each map
/// gets its own stream and adding a map changes no other map's runs.
pub(crate) fn map_seed(seed: u64, map: &str) -> u64 {
    mix(seed, fnv1a(map.as_bytes()))
}
