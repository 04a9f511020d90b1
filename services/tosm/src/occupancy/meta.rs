//! The `map_server` YAML file: its keys, read and checked one by one, each problem named.

use yaml_rust2::{Yaml, YamlLoader};

use super::{CANONICAL_FREE_THRESH, CANONICAL_OCCUPIED_THRESH, Pose2, RosMapError};

/// Coarsest resolution a map may have, metres per pixel: beyond it a cell is larger than any
/// room and the numbers only overflow what uses them.
pub const MAX_RESOLUTION_M: f64 = 100.0;
/// Farthest a map's origin may lie from the frame's origin, metres (in x and y).
pub const MAX_ORIGIN_M: f64 = 1e7;

/// The contents of a `map_server` YAML file.
#[derive(Clone, Debug, PartialEq)]
pub struct RosMapMeta {
    /// The image file name, relative to the YAML file (as written; this crate opens no files).
    pub image: String,
    /// Metres per pixel; finite and > 0.
    pub resolution: f64,
    /// World pose of the lower-left corner of the lower-left pixel.
    pub origin: Pose2,
    /// When set, white is occupied and black is free.
    pub negate: bool,
    /// Occupancy probability above which a cell is occupied, in `[0, 1]`.
    pub occupied_thresh: f64,
    /// Occupancy probability below which a cell is free, in `[0, 1]` and below `occupied_thresh`.
    pub free_thresh: f64,
    /// `trinary` (the default when the key is absent), `scale` or `raw`.
    pub mode: String,
}

/// The map modes `map_server` knows.
const MODES: [&str; 3] = ["trinary", "scale", "raw"];

impl RosMapMeta {
    /// Parses a `map_server` YAML file's text and validates every value.
    ///
    /// Required keys: `image`, `resolution`, `origin`, `negate`, `occupied_thresh`,
    /// `free_thresh`; `mode` defaults to `trinary`. `negate` may be `0`/`1` or a boolean.
    pub fn parse_yaml(yaml: &str) -> Result<RosMapMeta, RosMapError> {
        let docs = YamlLoader::load_from_str(yaml).map_err(|e| RosMapError::MalformedYaml {
            message: e.to_string(),
        })?;
        let doc = match docs.first() {
            Some(doc @ Yaml::Hash(_)) => doc,
            Some(other) => {
                return Err(RosMapError::NotAMapping {
                    found: describe(other),
                });
            }
            None => {
                return Err(RosMapError::NotAMapping {
                    found: "an empty document".to_owned(),
                });
            }
        };

        let image = match required(doc, "image")? {
            Yaml::String(s) if !s.trim().is_empty() => s.clone(),
            other => return Err(wrong_type("image", "a non-empty file name", other)),
        };
        let resolution = number(doc, "resolution")?;
        if !(resolution.is_finite() && resolution > 0.0 && resolution <= MAX_RESOLUTION_M) {
            return Err(RosMapError::InvalidResolution { value: resolution });
        }
        let origin = match required(doc, "origin")? {
            Yaml::Array(items) if items.len() == 3 => {
                let mut xyz = [0.0; 3];
                for (slot, item) in xyz.iter_mut().zip(items) {
                    *slot = as_number(item).ok_or_else(|| {
                        wrong_type(
                            "origin",
                            "a list of three numbers [x, y, yaw]",
                            &doc["origin"],
                        )
                    })?;
                }
                if xyz.iter().any(|v| !v.is_finite())
                    || xyz[..2].iter().any(|v| v.abs() > MAX_ORIGIN_M)
                {
                    return Err(RosMapError::InvalidOrigin {
                        found: format!("[{}, {}, {}]", xyz[0], xyz[1], xyz[2]),
                    });
                }
                Pose2::new(xyz[0], xyz[1], xyz[2])
            }
            other => {
                return Err(wrong_type(
                    "origin",
                    "a list of three numbers [x, y, yaw]",
                    other,
                ));
            }
        };
        let negate = match required(doc, "negate")? {
            Yaml::Integer(0) => false,
            Yaml::Integer(1) => true,
            Yaml::Boolean(b) => *b,
            other => return Err(wrong_type("negate", "0, 1, true or false", other)),
        };
        let occupied_thresh = threshold(doc, "occupied_thresh")?;
        let free_thresh = threshold(doc, "free_thresh")?;
        if free_thresh >= occupied_thresh {
            return Err(RosMapError::ThresholdsNotOrdered {
                free: free_thresh,
                occupied: occupied_thresh,
            });
        }
        let mode = match &doc["mode"] {
            Yaml::BadValue => "trinary".to_owned(),
            Yaml::String(s) if MODES.contains(&s.as_str()) => s.clone(),
            Yaml::String(s) => return Err(RosMapError::UnknownMode { value: s.clone() }),
            other => return Err(wrong_type("mode", "trinary, scale or raw", other)),
        };
        Ok(RosMapMeta {
            image,
            resolution,
            origin,
            negate,
            occupied_thresh,
            free_thresh,
            mode,
        })
    }

    /// The metadata under which an image written by [`super::OccupancyGrid::to_png`] decodes back
    /// to the same cells (trinary, not negated, thresholds 0.65 / 0.196).
    pub fn for_grid_png(image: &str, resolution: f64, origin: Pose2) -> RosMapMeta {
        RosMapMeta {
            image: image.to_owned(),
            resolution,
            origin,
            negate: false,
            occupied_thresh: CANONICAL_OCCUPIED_THRESH,
            free_thresh: CANONICAL_FREE_THRESH,
            mode: "trinary".to_owned(),
        }
    }

    /// The metadata as map_server's YAML (the keys [`RosMapMeta::parse_yaml`] reads, which
    /// reads this back to equal values).
    pub fn to_yaml(&self) -> String {
        format!(
            "image: {}\nresolution: {}\norigin: [{}, {}, {}]\nnegate: {}\noccupied_thresh: {}\nfree_thresh: {}\nmode: {}\n",
            self.image,
            self.resolution,
            self.origin.x,
            self.origin.y,
            self.origin.yaw,
            u8::from(self.negate),
            self.occupied_thresh,
            self.free_thresh,
            self.mode
        )
    }

    /// Checks the values a caller may have built by hand (the parser already checks them).
    pub fn validate(&self) -> Result<(), RosMapError> {
        if !(self.resolution.is_finite()
            && self.resolution > 0.0
            && self.resolution <= MAX_RESOLUTION_M)
        {
            return Err(RosMapError::InvalidResolution {
                value: self.resolution,
            });
        }
        let o = self.origin;
        if !(o.x.is_finite() && o.y.is_finite() && o.yaw.is_finite())
            || o.x.abs() > MAX_ORIGIN_M
            || o.y.abs() > MAX_ORIGIN_M
        {
            return Err(RosMapError::InvalidOrigin {
                found: format!("[{}, {}, {}]", o.x, o.y, o.yaw),
            });
        }
        for (key, value) in [
            ("occupied_thresh", self.occupied_thresh),
            ("free_thresh", self.free_thresh),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(RosMapError::ThresholdOutOfRange { key, value });
            }
        }
        if self.free_thresh >= self.occupied_thresh {
            return Err(RosMapError::ThresholdsNotOrdered {
                free: self.free_thresh,
                occupied: self.occupied_thresh,
            });
        }
        if !MODES.contains(&self.mode.as_str()) {
            return Err(RosMapError::UnknownMode {
                value: self.mode.clone(),
            });
        }
        Ok(())
    }
}

fn required<'a>(doc: &'a Yaml, key: &'static str) -> Result<&'a Yaml, RosMapError> {
    match &doc[key] {
        Yaml::BadValue => Err(RosMapError::MissingKey { key }),
        value => Ok(value),
    }
}

fn as_number(value: &Yaml) -> Option<f64> {
    match value {
        Yaml::Real(_) => value.as_f64(),
        Yaml::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

fn number(doc: &Yaml, key: &'static str) -> Result<f64, RosMapError> {
    let value = required(doc, key)?;
    as_number(value).ok_or_else(|| wrong_type(key, "a number", value))
}

fn threshold(doc: &Yaml, key: &'static str) -> Result<f64, RosMapError> {
    let value = number(doc, key)?;
    if (0.0..=1.0).contains(&value) {
        Ok(value)
    } else {
        Err(RosMapError::ThresholdOutOfRange { key, value })
    }
}

fn wrong_type(key: &'static str, expected: &'static str, found: &Yaml) -> RosMapError {
    RosMapError::WrongType {
        key,
        expected,
        found: describe(found),
    }
}

/// A short YAML-like rendering of a value for error messages.
fn describe(value: &Yaml) -> String {
    match value {
        Yaml::Real(s) => s.clone(),
        Yaml::Integer(i) => i.to_string(),
        Yaml::String(s) => format!("the string {s:?}"),
        Yaml::Boolean(b) => b.to_string(),
        Yaml::Array(items) => {
            let inner: Vec<String> = items.iter().map(describe).collect();
            format!("[{}]", inner.join(", "))
        }
        Yaml::Hash(_) => "a mapping".to_owned(),
        Yaml::Alias(_) => "an alias".to_owned(),
        Yaml::Null => "null".to_owned(),
        Yaml::BadValue => "nothing".to_owned(),
    }
}
