//! The planner's map input: a metric occupancy grid reduced to blocked / not blocked.

use grid::hash::Fnv1a;

use crate::error::GridError;

/// A point in the map frame, in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point2 {
    /// x in metres (map frame).
    pub x: f64,
    /// y in metres (map frame).
    pub y: f64,
}

impl Point2 {
    /// A point from its coordinates in metres.
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    /// Euclidean distance to `other`, in metres.
    pub fn distance(self, other: Point2) -> f64 {
        (self.x - other.x).hypot(self.y - other.y)
    }

    /// The point `f` of the way from `self` to `b` (0: `self`, 1: `b`).
    pub fn lerp(self, b: Point2, f: f64) -> Point2 {
        Point2::new(self.x + f * (b.x - self.x), self.y + f * (b.y - self.y))
    }

    /// Distance to the segment `a`–`b`, in metres.
    pub fn distance_to_segment(self, a: Point2, b: Point2) -> f64 {
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let len2 = dx * dx + dy * dy;
        let f = if len2 > 0.0 {
            (((self.x - a.x) * dx + (self.y - a.y) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.distance(a.lerp(b, f))
    }
}

/// A metric grid map as the planner needs it: which cells a robot may not enter.
///
/// Callers convert their own map types (a ROS map_server image, a TOSM place's metric map) into
/// this, so the planner knows nothing of file formats. Unknown cells should be given as blocked:
/// the planner never plans through space nobody has seen.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanningGrid {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Edge length of one cell, in metres.
    pub resolution: f64,
    /// x of the outer corner of cell (0, 0), in metres.
    pub origin_x: f64,
    /// y of the outer corner of cell (0, 0), in metres.
    pub origin_y: f64,
    /// Row-major, row 0 is the bottom row (lowest y), as in ROS: `blocked[row * width + col]`.
    pub blocked: Vec<bool>,
}

impl PlanningGrid {
    /// Checks that the grid is usable: non-empty, sizes agree, finite positive resolution.
    pub fn validate(&self) -> Result<(), GridError> {
        if self.width == 0 || self.height == 0 {
            return Err(GridError::Empty {
                width: self.width,
                height: self.height,
            });
        }
        // Cell indices are stored as u32 in the roadmap's hot structures.
        let cells = self
            .width
            .checked_mul(self.height)
            .filter(|&c| c < u32::MAX as usize)
            .ok_or(GridError::TooLarge {
                width: self.width,
                height: self.height,
            })?;
        if self.blocked.len() != cells {
            return Err(GridError::SizeMismatch {
                expected: cells,
                actual: self.blocked.len(),
            });
        }
        if !(self.resolution.is_finite() && self.resolution > 0.0) {
            return Err(GridError::BadResolution(self.resolution));
        }
        if !(self.origin_x.is_finite() && self.origin_y.is_finite()) {
            return Err(GridError::BadOrigin {
                x: self.origin_x,
                y: self.origin_y,
            });
        }
        Ok(())
    }

    /// A content fingerprint (FNV-1a over geometry and cells), usable as a map version when the
    /// caller has none: equal maps give equal fingerprints on every platform.
    pub fn fingerprint(&self) -> u64 {
        let mut h = Fnv1a::new();
        h.write(&(self.width as u64).to_le_bytes());
        h.write(&(self.height as u64).to_le_bytes());
        h.write(&self.resolution.to_bits().to_le_bytes());
        h.write(&self.origin_x.to_bits().to_le_bytes());
        h.write(&self.origin_y.to_bits().to_le_bytes());
        // Pack eight cells per byte: hashing 3 M bools one by one would dominate a cache lookup.
        for chunk in self.blocked.chunks(8) {
            let mut b = 0u8;
            for (i, &c) in chunk.iter().enumerate() {
                b |= u8::from(c) << i;
            }
            h.write(&[b]);
        }
        h.finish()
    }

    /// Free area in m² (cells not blocked), before any inflation: the paper's "free space area".
    pub fn free_area_m2(&self) -> f64 {
        let free = self.blocked.iter().filter(|b| !**b).count();
        free as f64 * self.resolution * self.resolution
    }
}
