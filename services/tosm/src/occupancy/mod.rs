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
//!
//! `meta` reads and checks the YAML file ([`RosMapMeta`]); `error` says what can be wrong with
//! either file ([`RosMapError`]); this module decodes images into [`OccupancyGrid`]s and writes
//! them back.

use std::io::Cursor;

use image::{ImageFormat, ImageReader};

mod error;
mod meta;
#[cfg(test)]
mod tests;

pub use error::RosMapError;
pub use meta::{MAX_ORIGIN_M, MAX_RESOLUTION_M, RosMapMeta};

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

/// The grey value `to_png` writes for a free cell (as `map_saver` does).
pub const PNG_FREE: u8 = 254;
/// The grey value `to_png` writes for an occupied cell.
pub const PNG_OCCUPIED: u8 = 0;
/// The grey value `to_png` writes for an unknown cell.
pub const PNG_UNKNOWN: u8 = 205;
/// Most pixels a map image may have (64 megapixels: 400 m × 400 m at 5 cm). The grid, its
/// distance transforms and the world built on it take tens of bytes per cell.
pub const MAX_MAP_PIXELS: u64 = 64 * 1024 * 1024;

/// The `free_thresh` under which `to_png`'s images decode back to the same cells.
pub const CANONICAL_FREE_THRESH: f64 = 0.196;
/// The `occupied_thresh` under which `to_png`'s images decode back to the same cells.
pub const CANONICAL_OCCUPIED_THRESH: f64 = 0.65;

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
    pub fn from_ros_map_server(
        meta: &RosMapMeta,
        image: &[u8],
    ) -> Result<OccupancyGrid, RosMapError> {
        meta.validate()?;
        let format = match image::guess_format(image) {
            Ok(ImageFormat::Png) => ImageFormat::Png,
            Ok(ImageFormat::Pnm) if image.starts_with(b"P2") || image.starts_with(b"P5") => {
                ImageFormat::Pnm
            }
            Ok(other) => {
                return Err(RosMapError::UnsupportedImageFormat {
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
                return Err(RosMapError::UnsupportedImageFormat {
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
        let bad = |e: image::ImageError| RosMapError::BadImage {
            format: format_name,
            message: e.to_string(),
        };
        // The header's size first: a small file may declare a huge image (a decompression
        // bomb), refused before anything is allocated for its pixels.
        let (dw, dh) = ImageReader::with_format(Cursor::new(image), format)
            .into_dimensions()
            .map_err(bad)?;
        if u64::from(dw) * u64::from(dh) > MAX_MAP_PIXELS {
            return Err(RosMapError::TooManyPixels {
                width: dw,
                height: dh,
                max_pixels: MAX_MAP_PIXELS,
            });
        }
        let mut reader = ImageReader::with_format(Cursor::new(image), format);
        // The default limits (512 MiB of allocation) stay as a second line.
        reader.limits(image::Limits::default());
        let decoded = reader.decode().map_err(bad)?;
        let (w, h) = (decoded.width(), decoded.height());
        if w == 0 || h == 0 {
            return Err(RosMapError::EmptyImage {
                width: w,
                height: h,
            });
        }
        let has_alpha = decoded.color().has_alpha();
        let colour = decoded.color().has_color();
        let (width, height) = (w as usize, h as usize);
        let mut cells = vec![Occupancy::Unknown; width * height];
        let mut put = |i: usize, value: f64, transparent: bool| {
            // Image row 0 is the top of the map; grid row 0 is the bottom.
            let (img_row, col) = (i / width, i % width);
            let value = if meta.negate { 255.0 - value } else { value };
            cells[(height - 1 - img_row) * width + col] = classify(meta, value, transparent);
        };
        match &decoded {
            // Maps are grey: read the bytes as they are (a conversion to RGBA through the
            // colour-space machinery was most of a map's decoding time).
            image::DynamicImage::ImageLuma8(grey) => {
                for (i, &v) in grey.as_raw().iter().enumerate() {
                    put(i, f64::from(v), false);
                }
            }
            image::DynamicImage::ImageLumaA8(grey) => {
                for (i, px) in grey.as_raw().chunks_exact(2).enumerate() {
                    put(i, f64::from(px[0]), px[1] == 0);
                }
            }
            _ => {
                let rgba = decoded.to_rgba8();
                for (i, px) in rgba.pixels().enumerate() {
                    let [r, g, b, a] = px.0;
                    let value = if colour {
                        (f64::from(r) + f64::from(g) + f64::from(b)) / 3.0
                    } else {
                        f64::from(r)
                    };
                    put(i, value, has_alpha && a == 0);
                }
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

    /// The grid as a binary PGM (P5) in `map_saver`'s convention, as nav2's `map_server` loads
    /// it: free 254, occupied 0, unknown 205, top row first; [`RosMapMeta::for_grid_png`] with
    /// this file's name is its YAML. Empty for a grid with zero width or height.
    pub fn to_pgm(&self) -> Vec<u8> {
        if self.width == 0 || self.height == 0 {
            return Vec::new();
        }
        let header = format!("P5\n{} {}\n255\n", self.width, self.height);
        let mut out = Vec::with_capacity(header.len() + self.width * self.height);
        out.extend_from_slice(header.as_bytes());
        for img_row in 0..self.height {
            let row = self.height - 1 - img_row;
            out.extend((0..self.width).map(|col| match self.get(col, row) {
                Some(Occupancy::Free) => PNG_FREE,
                Some(Occupancy::Occupied) => PNG_OCCUPIED,
                Some(Occupancy::Unknown) | None => PNG_UNKNOWN,
            }));
        }
        out
    }

    /// Like [`OccupancyGrid::to_png`], with the encoder's error for grids that have no PNG form
    /// (zero or more than `u32::MAX` columns or rows).
    pub fn try_to_png(&self) -> Result<Vec<u8>, RosMapError> {
        use image::ImageEncoder;
        let (w, h) = match (u32::try_from(self.width), u32::try_from(self.height)) {
            (Ok(w), Ok(h)) if w > 0 && h > 0 => (w, h),
            _ => {
                return Err(RosMapError::EmptyImage {
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
            .map_err(|e| RosMapError::BadImage {
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
