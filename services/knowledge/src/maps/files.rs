//! A ROS map_server map read from its files: the one place a map is read from a path. Parsing
//! belongs to `tosm` (which does no IO: [`tosm::RosMapMeta::parse_yaml`],
//! [`tosm::OccupancyGrid::from_ros_map_server`] take bytes); this reads the bytes.

use std::path::{Path, PathBuf};

use tosm::{OccupancyGrid, RosMapError, RosMapMeta};

/// Why a map could not be read from its files, or made into a mental simulation.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// A file or directory could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The map itself is wrong: YAML, thresholds, resolution, image.
    #[error("{path}: {source}")]
    Map {
        /// The YAML file.
        path: PathBuf,
        /// What is wrong.
        source: RosMapError,
    },
    /// The map, its objects or the robot do not make a world.
    #[error("{path}: {message}")]
    World {
        /// The YAML file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> LoadError + '_ {
    move |source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A map_server map's files, read: the YAML and the image it names, as bytes.
#[derive(Debug, Clone)]
pub struct RosMapFiles {
    /// The YAML file.
    pub yaml_path: PathBuf,
    /// Its text.
    pub yaml: String,
    /// Its metadata.
    pub meta: RosMapMeta,
    /// The image it names (relative to the YAML's folder).
    pub image_path: PathBuf,
    /// The image's bytes.
    pub image: Vec<u8>,
}

impl RosMapFiles {
    /// Reads the YAML at `yaml_path` and the image it names. Checks the YAML, not the image.
    pub fn read(yaml_path: &Path) -> Result<RosMapFiles, LoadError> {
        let yaml = std::fs::read_to_string(yaml_path).map_err(io_err(yaml_path))?;
        let meta = RosMapMeta::parse_yaml(&yaml).map_err(|source| LoadError::Map {
            path: yaml_path.to_path_buf(),
            source,
        })?;
        let image_path = yaml_path
            .parent()
            .unwrap_or_else(|| Path::new("."))
            .join(&meta.image);
        let image = std::fs::read(&image_path).map_err(io_err(&image_path))?;
        Ok(RosMapFiles {
            yaml_path: yaml_path.to_path_buf(),
            yaml,
            meta,
            image_path,
            image,
        })
    }

    /// The occupancy grid of the image under the YAML's thresholds. Pure.
    pub fn grid(&self) -> Result<OccupancyGrid, LoadError> {
        OccupancyGrid::from_ros_map_server(&self.meta, &self.image).map_err(|source| {
            LoadError::Map {
                path: self.yaml_path.clone(),
                source,
            }
        })
    }
}

/// The occupancy grid of the map_server map whose YAML is `yaml_path`.
pub fn read_ros_map(yaml_path: &Path) -> Result<OccupancyGrid, LoadError> {
    RosMapFiles::read(yaml_path)?.grid()
}

/// All `.yaml`/`.yml` files under `dir`, searched recursively and sorted, that look like
/// map_server metadata (they name an image).
pub fn find_yamls(dir: &Path) -> Result<Vec<PathBuf>, LoadError> {
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

/// The name a map file is imported under by default: its folder's name (else the file's
/// stem), lower-cased, every character other than a-z, 0-9, '-' and '_' replaced by '-'.
pub fn name_for_path(yaml_path: &Path) -> String {
    let stem = yaml_path
        .parent()
        .and_then(|p| p.file_name())
        .or_else(|| yaml_path.file_stem())
        .map(|s| s.to_string_lossy().to_lowercase())
        .unwrap_or_else(|| "map".to_owned());
    stem.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_map_reads_from_its_files_and_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let yaml = dir.path().join("lab.yaml");
        std::fs::write(
            &yaml,
            "image: lab.pgm\nresolution: 0.5\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
        )
        .unwrap();
        let e = read_ros_map(&yaml).unwrap_err();
        assert!(
            matches!(&e, LoadError::Io { path, .. } if path.ends_with("lab.pgm")),
            "{e}"
        );
        let mut pgm = b"P5\n3 2\n255\n".to_vec();
        pgm.extend([254u8; 6]);
        std::fs::write(dir.path().join("lab.pgm"), pgm).unwrap();
        let grid = read_ros_map(&yaml).unwrap();
        assert_eq!((grid.width, grid.height), (3, 2));
        assert_eq!(find_yamls(dir.path()).unwrap(), vec![yaml.clone()]);
        std::fs::write(&yaml, "image: [").unwrap();
        let e = read_ros_map(&yaml).unwrap_err();
        assert!(
            matches!(&e, LoadError::Map { path, .. } if *path == yaml),
            "{e}"
        );
    }

    #[test]
    fn a_default_name_is_the_folder_made_iri_safe() {
        assert_eq!(
            name_for_path(Path::new("maps/AWS Small House/map.yaml")),
            "aws-small-house"
        );
        assert_eq!(name_for_path(Path::new("map.yaml")), "map");
    }
}
