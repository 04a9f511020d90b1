//! The ROS map_server maps the benchmarks run on: finding them under a directory, naming them,
//! loading them as the planner sees them, and the seed of each map's runs.

use std::path::{Path, PathBuf};

use grid::hash::fnv1a;
use grid::seed::mix;
use planning::PlanningGrid;

use crate::error::{BenchError, io_err};

/// All `.yaml`/`.yml` files under `dir`, sorted, that look like map_server metadata.
pub fn find_yamls(dir: &Path) -> Result<Vec<PathBuf>, BenchError> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).map_err(io_err(&d))? {
            let path = entry.map_err(io_err(&d))?.path();
            if path.is_dir() {
                stack.push(path);
            } else if matches!(
                path.extension().and_then(|e| e.to_str()),
                Some("yaml" | "yml")
            ) {
                // Other YAML (launch parameters, etc.) is not a map: it must name an image.
                let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
                if text.lines().any(|l| l.trim_start().starts_with("image:")) {
                    out.push(path);
                }
            }
        }
    }
    out.sort();
    Ok(out)
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

/// Reads a map_server map and keeps what the planner needs: unknown counts as blocked.
pub fn load_ros_map(yaml: &Path) -> Result<PlanningGrid, BenchError> {
    let text = std::fs::read_to_string(yaml).map_err(io_err(yaml))?;
    let meta = tosm::RosMapMeta::parse_yaml(&text).map_err(|source| BenchError::Map {
        path: yaml.to_path_buf(),
        source,
    })?;
    let image_path = yaml.parent().unwrap_or(Path::new(".")).join(&meta.image);
    let image = std::fs::read(&image_path).map_err(io_err(&image_path))?;
    let grid = tosm::OccupancyGrid::from_ros_map_server(&meta, &image).map_err(|source| {
        BenchError::Map {
            path: yaml.to_path_buf(),
            source,
        }
    })?;
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
