//! What can be wrong with a `map_server` map's YAML file or image.

/// What is wrong with a map's YAML or image.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RosMapError {
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
    #[error("map resolution must be a number of metres per pixel in (0, 100], found {value}")]
    InvalidResolution {
        /// The value found.
        value: f64,
    },
    /// A coordinate of the origin is infinite or NaN.
    #[error("map origin must be [x, y, yaw], finite, x and y within 1e7 m, found {found}")]
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
    /// The image's header declares more pixels than a map may have: refused before decoding.
    #[error(
        "map image declares {width}x{height} pixels, more than the {max_pixels} a map may have"
    )]
    TooManyPixels {
        /// Declared width.
        width: u32,
        /// Declared height.
        height: u32,
        /// The budget.
        max_pixels: u64,
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
