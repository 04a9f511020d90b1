//! Occupancy grids read from ROS `map_server` maps (a YAML file beside a PGM or PNG image), with
//! exactly `map_server`'s rules for turning pixels into free, occupied and unknown cells.
//!
//! Conventions, the same as ROS `nav_msgs/OccupancyGrid`:
//! - the grid's `origin` is the world pose of the lower-left corner of cell `(0, 0)`; its yaw
//!   rotates the whole grid counter-clockwise about that corner (most ROS maps have yaw 0, and
//!   every function here supports any yaw);
//! - `cells` is row-major and row 0 is the bottom row (lowest y), whereas row 0 of the image is
//!   the top of the map.
//!
//! How a pixel becomes a cell (ROS 1 `map_server` `loadMapFromFile`, nav2 `map_io`):
//! the pixel's value `v` is the mean of its colour channels (grey images: the grey value);
//! its occupancy probability is `p = (255 - v) / 255`, or `p = v / 255` when `negate` is set;
//! a cell is occupied if `p > occupied_thresh`, free if `p < free_thresh`, unknown otherwise.
//! In `scale` mode the cells between the thresholds carry a probability in ROS; a three-state
//! grid keeps them unknown (not free), as the navigation stack's trinary semantics do, and a
//! fully transparent pixel is unknown. In `raw` mode the value (after `negate`) is itself the
//! occupancy in percent: `0..=100` is thresholded as `v / 100`, anything above 100 is unknown.
//! One deliberate difference from ROS 1: in `trinary` mode ROS 1 averages the alpha channel
//! together with the colours (an accident of its loop bounds); we ignore alpha there, as nav2 does.

use std::io::Cursor;

use image::{ImageFormat, ImageReader};
use yaml_rust2::{Yaml, YamlLoader};

/// The state of one grid cell, as ROS navigation sees it.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Occupancy {
    /// Known to be free of obstacles.
    Free,
    /// Known to hold an obstacle.
    Occupied,
    /// Not observed, or between the thresholds; never treated as free.
    Unknown,
}

/// A pose in the plane: position in metres, yaw in radians counter-clockwise from +x.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Pose2 {
    /// Position along x, metres.
    pub x: f64,
    /// Position along y, metres.
    pub y: f64,
    /// Heading, radians counter-clockwise from the +x axis.
    pub yaw: f64,
}

impl Pose2 {
    /// A pose at `(x, y)` with heading `yaw`.
    pub fn new(x: f64, y: f64, yaw: f64) -> Self {
        Self { x, y, yaw }
    }
}

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

/// The grey value `to_png` writes for a free cell (as `map_saver` does).
pub const PNG_FREE: u8 = 254;
/// The grey value `to_png` writes for an occupied cell.
pub const PNG_OCCUPIED: u8 = 0;
/// The grey value `to_png` writes for an unknown cell.
pub const PNG_UNKNOWN: u8 = 205;
/// The `free_thresh` under which `to_png`'s images decode back to the same cells.
pub const CANONICAL_FREE_THRESH: f64 = 0.196;
/// The `occupied_thresh` under which `to_png`'s images decode back to the same cells.
pub const CANONICAL_OCCUPIED_THRESH: f64 = 0.65;

/// The map modes `map_server` knows.
const MODES: [&str; 3] = ["trinary", "scale", "raw"];

/// What is wrong with a map's YAML or image.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MapError {
    /// The text is not YAML at all.
    #[error("map YAML is malformed: {message}")]
    MalformedYaml {
        /// The parser's message, with line and column.
        message: String,
    },
    /// The YAML holds no document, or its top level is not a key/value mapping.
    #[error("map YAML must be a mapping of keys (image, resolution, origin, ...), found {found}")]
    NotAMapping {
        /// What the top level was instead.
        found: String,
    },
    /// A required key is absent.
    #[error("map YAML has no `{key}` key (required by map_server)")]
    MissingKey {
        /// The missing key.
        key: &'static str,
    },
    /// A key holds a value of the wrong type.
    #[error("map YAML key `{key}` must be {expected}, found {found}")]
    WrongType {
        /// The key.
        key: &'static str,
        /// What was expected there.
        expected: &'static str,
        /// What was found, as YAML.
        found: String,
    },
    /// The resolution is zero, negative, infinite or NaN.
    #[error("map resolution must be a finite number of metres per pixel > 0, found {value}")]
    InvalidResolution {
        /// The value found.
        value: f64,
    },
    /// A coordinate of the origin is infinite or NaN.
    #[error("map origin must be three finite numbers [x, y, yaw], found {found}")]
    InvalidOrigin {
        /// The origin found.
        found: String,
    },
    /// A threshold is outside `[0, 1]` or NaN.
    #[error("map YAML key `{key}` must be a probability in [0, 1], found {value}")]
    ThresholdOutOfRange {
        /// `occupied_thresh` or `free_thresh`.
        key: &'static str,
        /// The value found.
        value: f64,
    },
    /// The free threshold is not below the occupied threshold.
    #[error("map free_thresh ({free}) must be below occupied_thresh ({occupied})")]
    ThresholdsNotOrdered {
        /// `free_thresh`.
        free: f64,
        /// `occupied_thresh`.
        occupied: f64,
    },
    /// The mode is not one `map_server` knows.
    #[error("map mode must be one of trinary, scale, raw; found `{value}`")]
    UnknownMode {
        /// The mode found.
        value: String,
    },
    /// The image bytes are neither PGM (P2/P5) nor PNG.
    #[error("map image must be PGM (P2/P5) or PNG, found {found}")]
    UnsupportedImageFormat {
        /// What the bytes look like.
        found: String,
    },
    /// The image is PGM or PNG but could not be decoded (truncated, corrupt, too large).
    #[error("map image ({format}) cannot be decoded: {message}")]
    BadImage {
        /// `PGM` or `PNG`.
        format: &'static str,
        /// The decoder's message.
        message: String,
    },
    /// The image decoded to zero pixels.
    #[error("map image is {width}x{height} pixels; a map needs at least one pixel")]
    EmptyImage {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
}

impl RosMapMeta {
    /// Parses a `map_server` YAML file's text and validates every value.
    ///
    /// Required keys: `image`, `resolution`, `origin`, `negate`, `occupied_thresh`,
    /// `free_thresh`; `mode` defaults to `trinary`. `negate` may be `0`/`1` or a boolean.
    pub fn parse_yaml(yaml: &str) -> Result<RosMapMeta, MapError> {
        let docs = YamlLoader::load_from_str(yaml).map_err(|e| MapError::MalformedYaml {
            message: e.to_string(),
        })?;
        let doc = match docs.first() {
            Some(doc @ Yaml::Hash(_)) => doc,
            Some(other) => {
                return Err(MapError::NotAMapping {
                    found: describe(other),
                });
            }
            None => {
                return Err(MapError::NotAMapping {
                    found: "an empty document".to_owned(),
                });
            }
        };

        let image = match required(doc, "image")? {
            Yaml::String(s) if !s.trim().is_empty() => s.clone(),
            other => return Err(wrong_type("image", "a non-empty file name", other)),
        };
        let resolution = number(doc, "resolution")?;
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(MapError::InvalidResolution { value: resolution });
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
                if xyz.iter().any(|v| !v.is_finite()) {
                    return Err(MapError::InvalidOrigin {
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
            return Err(MapError::ThresholdsNotOrdered {
                free: free_thresh,
                occupied: occupied_thresh,
            });
        }
        let mode = match &doc["mode"] {
            Yaml::BadValue => "trinary".to_owned(),
            Yaml::String(s) if MODES.contains(&s.as_str()) => s.clone(),
            Yaml::String(s) => return Err(MapError::UnknownMode { value: s.clone() }),
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

    /// The metadata under which an image written by [`OccupancyGrid::to_png`] decodes back
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

    /// Checks the values a caller may have built by hand (the parser already checks them).
    pub fn validate(&self) -> Result<(), MapError> {
        if !(self.resolution.is_finite() && self.resolution > 0.0) {
            return Err(MapError::InvalidResolution {
                value: self.resolution,
            });
        }
        let o = self.origin;
        if !(o.x.is_finite() && o.y.is_finite() && o.yaw.is_finite()) {
            return Err(MapError::InvalidOrigin {
                found: format!("[{}, {}, {}]", o.x, o.y, o.yaw),
            });
        }
        for (key, value) in [
            ("occupied_thresh", self.occupied_thresh),
            ("free_thresh", self.free_thresh),
        ] {
            if !(0.0..=1.0).contains(&value) {
                return Err(MapError::ThresholdOutOfRange { key, value });
            }
        }
        if self.free_thresh >= self.occupied_thresh {
            return Err(MapError::ThresholdsNotOrdered {
                free: self.free_thresh,
                occupied: self.occupied_thresh,
            });
        }
        if !MODES.contains(&self.mode.as_str()) {
            return Err(MapError::UnknownMode {
                value: self.mode.clone(),
            });
        }
        Ok(())
    }
}

fn required<'a>(doc: &'a Yaml, key: &'static str) -> Result<&'a Yaml, MapError> {
    match &doc[key] {
        Yaml::BadValue => Err(MapError::MissingKey { key }),
        value => Ok(value),
    }
}

fn as_number(value: &Yaml) -> Option<f64> {
    match value {
        Yaml::Real(_) => value.as_f64(),
        #[allow(clippy::cast_precision_loss, reason = "map values are small integers")]
        Yaml::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

fn number(doc: &Yaml, key: &'static str) -> Result<f64, MapError> {
    let value = required(doc, key)?;
    as_number(value).ok_or_else(|| wrong_type(key, "a number", value))
}

fn threshold(doc: &Yaml, key: &'static str) -> Result<f64, MapError> {
    let value = number(doc, key)?;
    if (0.0..=1.0).contains(&value) {
        Ok(value)
    } else {
        Err(MapError::ThresholdOutOfRange { key, value })
    }
}

fn wrong_type(key: &'static str, expected: &'static str, found: &Yaml) -> MapError {
    MapError::WrongType {
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

/// A 2-D occupancy grid in the world frame.
#[derive(Clone, Debug, PartialEq)]
pub struct OccupancyGrid {
    /// Number of columns (cells along the grid's x axis).
    pub width: usize,
    /// Number of rows (cells along the grid's y axis).
    pub height: usize,
    /// Metres per cell.
    pub resolution: f64,
    /// World pose of the lower-left corner of cell `(0, 0)`.
    pub origin: Pose2,
    /// Row-major cells, row 0 at the bottom (lowest y); `width * height` long.
    pub cells: Vec<Occupancy>,
}

impl OccupancyGrid {
    /// A grid of `width x height` cells all in state `fill`.
    pub fn filled(
        width: usize,
        height: usize,
        resolution: f64,
        origin: Pose2,
        fill: Occupancy,
    ) -> Self {
        Self {
            width,
            height,
            resolution,
            origin,
            cells: vec![fill; width.saturating_mul(height)],
        }
    }

    /// Builds the grid `map_server` would publish from a map's metadata and image bytes
    /// (PGM P2/P5 or PNG; grey, grey+alpha, RGB or RGBA; 8 or 16 bits).
    pub fn from_ros_map_server(meta: &RosMapMeta, image: &[u8]) -> Result<OccupancyGrid, MapError> {
        meta.validate()?;
        let format = match image::guess_format(image) {
            Ok(ImageFormat::Png) => ImageFormat::Png,
            Ok(ImageFormat::Pnm) if image.starts_with(b"P2") || image.starts_with(b"P5") => {
                ImageFormat::Pnm
            }
            Ok(other) => {
                return Err(MapError::UnsupportedImageFormat {
                    found: format!("{other:?} data"),
                });
            }
            Err(_) => {
                let head: String = image
                    .iter()
                    .take(8)
                    .map(|b| format!("{b:02x}"))
                    .collect::<Vec<_>>()
                    .join(" ");
                return Err(MapError::UnsupportedImageFormat {
                    found: if image.is_empty() {
                        "no bytes at all".to_owned()
                    } else {
                        format!("bytes starting {head}")
                    },
                });
            }
        };
        let format_name = if format == ImageFormat::Png {
            "PNG"
        } else {
            "PGM"
        };
        let bad = |e: image::ImageError| MapError::BadImage {
            format: format_name,
            message: e.to_string(),
        };
        let mut reader = ImageReader::with_format(Cursor::new(image), format);
        // The default limits (512 MiB of allocation) keep a hostile header from exhausting memory.
        reader.limits(image::Limits::default());
        let decoded = reader.decode().map_err(bad)?;
        let (w, h) = (decoded.width(), decoded.height());
        if w == 0 || h == 0 {
            return Err(MapError::EmptyImage {
                width: w,
                height: h,
            });
        }
        let has_alpha = decoded.color().has_alpha();
        let colour = decoded.color().has_color();
        let rgba = decoded.to_rgba8();
        let (width, height) = (w as usize, h as usize);
        let mut cells = vec![Occupancy::Unknown; width * height];
        for (img_row, pixels) in rgba.rows().enumerate() {
            // Image row 0 is the top of the map; grid row 0 is the bottom.
            let grid_row = height - 1 - img_row;
            for (col, px) in pixels.enumerate() {
                let [r, g, b, a] = px.0;
                let mut value = if colour {
                    (f64::from(r) + f64::from(g) + f64::from(b)) / 3.0
                } else {
                    f64::from(r)
                };
                if meta.negate {
                    value = 255.0 - value;
                }
                let transparent = has_alpha && a == 0;
                cells[grid_row * width + col] = classify(meta, value, transparent);
            }
        }
        Ok(OccupancyGrid {
            width,
            height,
            resolution: meta.resolution,
            origin: meta.origin,
            cells,
        })
    }

    /// The index of cell `(col, row)` in `cells`, if it is inside the grid.
    pub fn index(&self, col: usize, row: usize) -> Option<usize> {
        (col < self.width && row < self.height).then(|| row * self.width + col)
    }

    /// The state of cell `(col, row)`; `None` outside the grid.
    pub fn get(&self, col: usize, row: usize) -> Option<Occupancy> {
        self.index(col, row)
            .and_then(|i| self.cells.get(i).copied())
    }

    /// Whether cell `(col, row)` is known free; unknown cells and cells outside the grid are not.
    pub fn is_free(&self, col: usize, row: usize) -> bool {
        self.get(col, row) == Some(Occupancy::Free)
    }

    /// The cell holding world point `(x, y)`, honouring the origin's yaw; `None` outside the grid.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let (lx, ly) = self.world_to_grid_frame(x, y);
        let col = (lx / self.resolution).floor();
        let row = (ly / self.resolution).floor();
        // NaN fails both comparisons, so NaN input lands in `None`.
        #[allow(
            clippy::cast_precision_loss,
            reason = "grid sizes are far below 2^52 cells"
        )]
        let inside =
            col >= 0.0 && row >= 0.0 && col < self.width as f64 && row < self.height as f64;
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "checked to be a whole number in [0, size) above"
        )]
        if inside {
            Some((col as usize, row as usize))
        } else {
            None
        }
    }

    /// The world position of the centre of cell `(col, row)` (also for cells outside the grid).
    #[allow(
        clippy::cast_precision_loss,
        reason = "grid sizes are far below 2^52 cells"
    )]
    pub fn cell_center(&self, col: usize, row: usize) -> (f64, f64) {
        let lx = (col as f64 + 0.5) * self.resolution;
        let ly = (row as f64 + 0.5) * self.resolution;
        self.grid_frame_to_world(lx, ly)
    }

    /// Converts a world point to the grid frame (metres from the origin corner, along the
    /// grid's axes).
    pub fn world_to_grid_frame(&self, x: f64, y: f64) -> (f64, f64) {
        let (s, c) = self.origin.yaw.sin_cos();
        let (dx, dy) = (x - self.origin.x, y - self.origin.y);
        (c * dx + s * dy, -s * dx + c * dy)
    }

    /// Converts a point in the grid frame to world coordinates.
    pub fn grid_frame_to_world(&self, lx: f64, ly: f64) -> (f64, f64) {
        let (s, c) = self.origin.yaw.sin_cos();
        (
            self.origin.x + c * lx - s * ly,
            self.origin.y + s * lx + c * ly,
        )
    }

    /// Number of free cells.
    pub fn free_cell_count(&self) -> usize {
        self.cells.iter().filter(|c| **c == Occupancy::Free).count()
    }

    /// Free area in square metres (free cells times the cell area).
    #[allow(clippy::cast_precision_loss, reason = "cell counts are far below 2^52")]
    pub fn free_area_m2(&self) -> f64 {
        self.free_cell_count() as f64 * self.resolution * self.resolution
    }

    /// An 8-bit grey PNG in `map_saver`'s convention: free 254, occupied 0, unknown 205, top row
    /// first. It decodes back to this grid under [`RosMapMeta::for_grid_png`].
    ///
    /// Returns an empty vector only for a grid with zero width or height, which has no PNG form.
    /// Cells missing from a too-short `cells` vector are written as unknown.
    pub fn to_png(&self) -> Vec<u8> {
        self.try_to_png().unwrap_or_default()
    }

    /// Like [`OccupancyGrid::to_png`], with the encoder's error for grids that have no PNG form
    /// (zero or more than `u32::MAX` columns or rows).
    pub fn try_to_png(&self) -> Result<Vec<u8>, MapError> {
        use image::ImageEncoder;
        let (w, h) = match (u32::try_from(self.width), u32::try_from(self.height)) {
            (Ok(w), Ok(h)) if w > 0 && h > 0 => (w, h),
            _ => {
                return Err(MapError::EmptyImage {
                    width: u32::try_from(self.width).unwrap_or(u32::MAX),
                    height: u32::try_from(self.height).unwrap_or(u32::MAX),
                });
            }
        };
        let mut pixels = Vec::with_capacity(self.width * self.height);
        for img_row in 0..self.height {
            let row = self.height - 1 - img_row;
            for col in 0..self.width {
                pixels.push(match self.get(col, row) {
                    Some(Occupancy::Free) => PNG_FREE,
                    Some(Occupancy::Occupied) => PNG_OCCUPIED,
                    Some(Occupancy::Unknown) | None => PNG_UNKNOWN,
                });
            }
        }
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(&pixels, w, h, image::ExtendedColorType::L8)
            .map_err(|e| MapError::BadImage {
                format: "PNG",
                message: e.to_string(),
            })?;
        Ok(out)
    }
}

/// `map_server`'s thresholding of one pixel value (already negated if `negate` is set).
fn classify(meta: &RosMapMeta, value: f64, transparent: bool) -> Occupancy {
    let p = if meta.mode == "raw" {
        if value > 100.0 {
            return Occupancy::Unknown;
        }
        value / 100.0
    } else {
        (255.0 - value) / 255.0
    };
    if meta.mode == "scale" && transparent {
        return Occupancy::Unknown;
    }
    if p > meta.occupied_thresh {
        Occupancy::Occupied
    } else if p < meta.free_thresh {
        Occupancy::Free
    } else {
        Occupancy::Unknown
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "image: map.pgm\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";

    fn meta() -> RosMapMeta {
        RosMapMeta::parse_yaml(GOOD).expect("good yaml")
    }

    /// Replaces the line that starts with `key:` in GOOD (or drops it when `line` is empty).
    fn with_line(key: &str, line: &str) -> String {
        GOOD.lines()
            .map(|l| {
                if l.starts_with(&format!("{key}:")) {
                    line.to_owned()
                } else {
                    l.to_owned()
                }
            })
            .filter(|l| !l.is_empty())
            .collect::<Vec<_>>()
            .join("\n")
    }

    fn parse_err(yaml: &str) -> MapError {
        RosMapMeta::parse_yaml(yaml).expect_err("should be rejected")
    }

    #[test]
    fn parses_a_map_server_yaml() {
        let m = meta();
        assert_eq!(m.image, "map.pgm");
        assert_eq!(m.resolution, 0.05);
        assert_eq!(m.origin, Pose2::new(-1.0, 2.0, 0.0));
        assert!(!m.negate);
        assert_eq!(m.mode, "trinary");
        let m = RosMapMeta::parse_yaml(&with_line("negate", "negate: true")).expect("bool negate");
        assert!(m.negate);
        let m = RosMapMeta::parse_yaml(&format!("{GOOD}mode: scale\n")).expect("mode");
        assert_eq!(m.mode, "scale");
        let m = RosMapMeta::parse_yaml(&with_line("origin", "origin: [0, 0, 0]")).expect("ints");
        assert_eq!(m.origin, Pose2::new(0.0, 0.0, 0.0));
    }

    #[test]
    fn malformed_yaml_is_reported() {
        assert!(matches!(
            parse_err("image: [map.pgm\nresolution: 0.05"),
            MapError::MalformedYaml { .. }
        ));
        assert!(matches!(
            parse_err("- just\n- a list\n"),
            MapError::NotAMapping { .. }
        ));
        assert!(matches!(parse_err(""), MapError::NotAMapping { .. }));
    }

    #[test]
    fn each_missing_key_is_named() {
        for key in [
            "image",
            "resolution",
            "origin",
            "negate",
            "occupied_thresh",
            "free_thresh",
        ] {
            let err = parse_err(&with_line(key, ""));
            assert_eq!(
                err,
                MapError::MissingKey {
                    key: match key {
                        "image" => "image",
                        "resolution" => "resolution",
                        "origin" => "origin",
                        "negate" => "negate",
                        "occupied_thresh" => "occupied_thresh",
                        _ => "free_thresh",
                    }
                }
            );
            assert!(err.to_string().contains(key), "{err}");
        }
    }

    #[test]
    fn bad_resolutions_are_rejected() {
        for (text, check) in [
            ("resolution: 0", 0.0),
            ("resolution: -0.05", -0.05),
            ("resolution: .inf", f64::INFINITY),
        ] {
            let err = parse_err(&with_line("resolution", text));
            assert_eq!(err, MapError::InvalidResolution { value: check }, "{text}");
        }
        let err = parse_err(&with_line("resolution", "resolution: .nan"));
        assert!(matches!(err, MapError::InvalidResolution { value } if value.is_nan()));
        let err = parse_err(&with_line("resolution", "resolution: fine"));
        assert!(
            matches!(
                err,
                MapError::WrongType {
                    key: "resolution",
                    ..
                }
            ),
            "{err:?}"
        );
        assert!(err.to_string().contains("\"fine\""), "{err}");
    }

    #[test]
    fn bad_origins_are_rejected() {
        for text in [
            "origin: [1.0, 2.0]",
            "origin: 3",
            "origin: [a, 1, 2]",
            "origin: {x: 1}",
        ] {
            let err = parse_err(&with_line("origin", text));
            assert!(
                matches!(err, MapError::WrongType { key: "origin", .. }),
                "{text}: {err:?}"
            );
        }
        let err = parse_err(&with_line("origin", "origin: [.nan, 0, 0]"));
        assert!(matches!(err, MapError::InvalidOrigin { .. }), "{err:?}");
    }

    #[test]
    fn bad_thresholds_are_rejected() {
        let err = parse_err(&with_line("occupied_thresh", "occupied_thresh: 1.5"));
        assert_eq!(
            err,
            MapError::ThresholdOutOfRange {
                key: "occupied_thresh",
                value: 1.5
            }
        );
        let err = parse_err(&with_line("free_thresh", "free_thresh: -0.1"));
        assert_eq!(
            err,
            MapError::ThresholdOutOfRange {
                key: "free_thresh",
                value: -0.1
            }
        );
        let err = parse_err(&with_line("free_thresh", "free_thresh: .nan"));
        assert!(matches!(
            err,
            MapError::ThresholdOutOfRange {
                key: "free_thresh",
                ..
            }
        ));
        let err = parse_err(&with_line("free_thresh", "free_thresh: 0.65"));
        assert_eq!(
            err,
            MapError::ThresholdsNotOrdered {
                free: 0.65,
                occupied: 0.65
            }
        );
    }

    #[test]
    fn bad_negate_image_and_mode_are_rejected() {
        let err = parse_err(&with_line("negate", "negate: 2"));
        assert!(matches!(err, MapError::WrongType { key: "negate", .. }));
        let err = parse_err(&with_line("image", "image: 7"));
        assert!(matches!(err, MapError::WrongType { key: "image", .. }));
        let err = parse_err(&format!("{GOOD}mode: fancy\n"));
        assert_eq!(
            err,
            MapError::UnknownMode {
                value: "fancy".to_owned()
            }
        );
        let err = parse_err(&format!("{GOOD}mode: 3\n"));
        assert!(matches!(err, MapError::WrongType { key: "mode", .. }));
    }

    fn pgm_p5(width: usize, height: usize, pixels: &[u8]) -> Vec<u8> {
        let mut out = format!("P5\n# test\n{width} {height}\n255\n").into_bytes();
        out.extend_from_slice(pixels);
        out
    }

    #[test]
    fn thresholds_and_row_order_follow_map_server() {
        // Top image row: free (254), unknown (205), occupied (0); bottom row: 255, 100, 128.
        let img = pgm_p5(3, 2, &[254, 205, 0, 255, 100, 128]);
        let grid = OccupancyGrid::from_ros_map_server(&meta(), &img).expect("decodes");
        assert_eq!((grid.width, grid.height), (3, 2));
        use Occupancy::*;
        // Grid row 0 is the image's bottom row. p(100) = 0.608 -> unknown; p(128) = 0.498 -> unknown.
        assert_eq!(
            grid.cells,
            vec![Free, Unknown, Unknown, Free, Unknown, Occupied]
        );
        assert!(grid.is_free(0, 1));
        assert!(!grid.is_free(1, 1), "unknown is not free");
        assert!(!grid.is_free(3, 0), "outside is not free");

        let mut negated = meta();
        negated.negate = true;
        let grid = OccupancyGrid::from_ros_map_server(&negated, &img).expect("decodes");
        // Negated, p = v / 255: 205 -> 0.80 is occupied.
        assert_eq!(
            grid.cells,
            vec![Occupied, Unknown, Unknown, Occupied, Occupied, Free]
        );
    }

    #[test]
    fn threshold_boundaries_are_strict() {
        // p = (255 - v) / 255 must be strictly below free_thresh to be free.
        let mut m = meta();
        m.free_thresh = 50.0 / 255.0;
        m.occupied_thresh = 200.0 / 255.0;
        let img = pgm_p5(4, 1, &[205, 206, 55, 54]);
        let grid = OccupancyGrid::from_ros_map_server(&m, &img).expect("decodes");
        use Occupancy::*;
        assert_eq!(grid.cells, vec![Unknown, Free, Unknown, Occupied]);
    }

    #[test]
    fn ascii_pgm_and_png_decode() {
        let p2 = b"P2\n3 1\n255\n254 205 0\n";
        let grid = OccupancyGrid::from_ros_map_server(&meta(), p2).expect("P2 decodes");
        use Occupancy::*;
        assert_eq!(grid.cells, vec![Free, Unknown, Occupied]);
        let png = grid.to_png();
        let back = OccupancyGrid::from_ros_map_server(&meta(), &png).expect("PNG decodes");
        assert_eq!(back, grid);
    }

    #[test]
    fn raw_and_scale_modes() {
        use Occupancy::*;
        let mut m = meta();
        m.mode = "raw".to_owned();
        let img = pgm_p5(4, 1, &[0, 100, 50, 255]);
        let grid = OccupancyGrid::from_ros_map_server(&m, &img).expect("decodes");
        assert_eq!(grid.cells, vec![Free, Occupied, Unknown, Unknown]);
        m.mode = "scale".to_owned();
        let img = pgm_p5(3, 1, &[254, 150, 0]);
        let grid = OccupancyGrid::from_ros_map_server(&m, &img).expect("decodes");
        assert_eq!(grid.cells, vec![Free, Unknown, Occupied]);
    }

    #[test]
    fn colour_pixels_are_averaged() {
        use image::ImageEncoder;
        // (254+254+254)/3 free; (255+0+0)/3 = 85 -> p = 0.667 occupied; (255,255,0) -> 170 -> p=0.333 unknown.
        let rgb = [254, 254, 254, 255, 0, 0, 255, 255, 0];
        let mut png = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&rgb, 3, 1, image::ExtendedColorType::Rgb8)
            .expect("encode");
        let grid = OccupancyGrid::from_ros_map_server(&meta(), &png).expect("decodes");
        use Occupancy::*;
        assert_eq!(grid.cells, vec![Free, Occupied, Unknown]);
    }

    #[test]
    fn bad_images_are_rejected() {
        let err = OccupancyGrid::from_ros_map_server(&meta(), b"GIF89a....").expect_err("gif");
        assert!(
            matches!(err, MapError::UnsupportedImageFormat { .. }),
            "{err:?}"
        );
        let err = OccupancyGrid::from_ros_map_server(&meta(), b"").expect_err("empty");
        assert!(
            matches!(err, MapError::UnsupportedImageFormat { .. }),
            "{err:?}"
        );
        let err = OccupancyGrid::from_ros_map_server(&meta(), b"hello world").expect_err("text");
        assert!(
            matches!(err, MapError::UnsupportedImageFormat { .. }),
            "{err:?}"
        );
        // PBM (P4) is PNM but not a map_server image.
        let err = OccupancyGrid::from_ros_map_server(&meta(), b"P4\n1 1\n\x00").expect_err("pbm");
        assert!(
            matches!(err, MapError::UnsupportedImageFormat { .. }),
            "{err:?}"
        );

        // Truncated: the header promises 3x2 pixels, the data holds 4.
        let truncated = pgm_p5(3, 2, &[1, 2, 3, 4]);
        let err = OccupancyGrid::from_ros_map_server(&meta(), &truncated).expect_err("short");
        assert!(
            matches!(err, MapError::BadImage { format: "PGM", .. }),
            "{err:?}"
        );
        // A huge header with no data must not allocate gigabytes or panic.
        let huge = b"P5\n100000 100000\n255\n".to_vec();
        let err = OccupancyGrid::from_ros_map_server(&meta(), &huge).expect_err("huge");
        assert!(matches!(err, MapError::BadImage { .. }), "{err:?}");
        let zero = b"P5\n0 0\n255\n".to_vec();
        let err = OccupancyGrid::from_ros_map_server(&meta(), &zero).expect_err("zero");
        assert!(
            matches!(err, MapError::BadImage { .. } | MapError::EmptyImage { .. }),
            "{err:?}"
        );

        let png =
            OccupancyGrid::filled(4, 4, 0.1, Pose2::new(0.0, 0.0, 0.0), Occupancy::Free).to_png();
        let err = OccupancyGrid::from_ros_map_server(&meta(), &png[..png.len() / 2])
            .expect_err("cut PNG");
        assert!(
            matches!(err, MapError::BadImage { format: "PNG", .. }),
            "{err:?}"
        );
    }

    #[test]
    fn invalid_meta_built_by_hand_is_rejected_before_decoding() {
        let mut m = meta();
        m.resolution = f64::NAN;
        let img = pgm_p5(1, 1, &[254]);
        assert!(matches!(
            OccupancyGrid::from_ros_map_server(&m, &img),
            Err(MapError::InvalidResolution { .. })
        ));
        let mut m = meta();
        m.mode = "binary".to_owned();
        assert!(matches!(
            OccupancyGrid::from_ros_map_server(&m, &img),
            Err(MapError::UnknownMode { .. })
        ));
    }

    #[test]
    fn world_and_cell_coordinates() {
        let grid = OccupancyGrid::filled(10, 5, 0.5, Pose2::new(-1.0, 2.0, 0.0), Occupancy::Free);
        assert_eq!(grid.cell_of(-1.0, 2.0), Some((0, 0)));
        assert_eq!(grid.cell_of(-0.76, 2.26), Some((0, 0)));
        assert_eq!(grid.cell_of(3.99, 4.49), Some((9, 4)));
        assert_eq!(grid.cell_of(4.0, 3.0), None);
        assert_eq!(grid.cell_of(-1.01, 3.0), None);
        assert_eq!(grid.cell_of(f64::NAN, 3.0), None);
        assert_eq!(grid.cell_center(0, 0), (-0.75, 2.25));
        assert_eq!(grid.cell_center(9, 4), (3.75, 4.25));
        assert_eq!(grid.free_area_m2(), 12.5);
    }

    #[test]
    fn rotated_origin_is_honoured() {
        let yaw = std::f64::consts::FRAC_PI_2;
        let grid = OccupancyGrid::filled(4, 2, 1.0, Pose2::new(10.0, 0.0, yaw), Occupancy::Free);
        // The grid's x axis points along world +y, its y axis along world -x.
        let (x, y) = grid.cell_center(3, 1);
        assert!((x - 8.5).abs() < 1e-9 && (y - 3.5).abs() < 1e-9, "{x} {y}");
        assert_eq!(grid.cell_of(8.5, 3.5), Some((3, 1)));
        assert_eq!(grid.cell_of(10.5, 0.5), None);
        for row in 0..2 {
            for col in 0..4 {
                let (x, y) = grid.cell_center(col, row);
                assert_eq!(grid.cell_of(x, y), Some((col, row)));
            }
        }
    }

    #[test]
    fn png_round_trip_keeps_every_state() {
        use Occupancy::*;
        let mut grid = OccupancyGrid::filled(3, 2, 0.05, Pose2::new(1.0, 1.0, 0.0), Unknown);
        grid.cells = vec![Free, Occupied, Unknown, Occupied, Free, Free];
        let png = grid.to_png();
        let meta = RosMapMeta::for_grid_png("x.png", 0.05, Pose2::new(1.0, 1.0, 0.0));
        let back = OccupancyGrid::from_ros_map_server(&meta, &png).expect("decodes");
        assert_eq!(back, grid);
        // The top image row holds grid row 1.
        let decoded = image::load_from_memory(&png).expect("png").to_luma8();
        assert_eq!(decoded.as_raw(), &vec![0, 254, 254, 254, 0, 205]);
        assert!(
            OccupancyGrid::filled(0, 3, 1.0, Pose2::new(0.0, 0.0, 0.0), Free)
                .to_png()
                .is_empty()
        );
    }
}
