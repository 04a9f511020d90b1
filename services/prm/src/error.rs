//! Typed errors of the planning layer: bad maps, bad parameters, bad queries.

use std::fmt;

use crate::map::Point2;

/// A [`crate::PlanningGrid`] the planner cannot use.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// Zero width or height.
    #[error("the map is empty ({width}x{height} cells)")]
    Empty {
        /// Columns given.
        width: usize,
        /// Rows given.
        height: usize,
    },
    /// More cells than the planner indexes (2³² − 1).
    #[error("the map is too large ({width}x{height} cells)")]
    TooLarge {
        /// Columns given.
        width: usize,
        /// Rows given.
        height: usize,
    },
    /// `blocked.len()` is not `width * height`.
    #[error("the map has {actual} cells but width x height is {expected}")]
    SizeMismatch {
        /// width × height.
        expected: usize,
        /// Length of the cell vector.
        actual: usize,
    },
    /// Resolution not finite and positive.
    #[error("the map resolution must be a finite positive number of metres, got {0}")]
    BadResolution(f64),
    /// Origin not finite.
    #[error("the map origin must be finite, got ({x}, {y})")]
    BadOrigin {
        /// x given.
        x: f64,
        /// y given.
        y: f64,
    },
}

/// A configuration space that cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigSpaceError {
    /// The map itself is unusable.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// Robot radius or safety margin negative or not finite.
    #[error("{name} must be a finite number of metres >= 0, got {value}")]
    BadRadius {
        /// Which parameter.
        name: &'static str,
        /// The value given.
        value: f64,
    },
}

/// Roadmap parameters that cannot work.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BuildError {
    /// The caller asked the build to stop.
    #[error("the roadmap build was stopped")]
    Stopped,
    /// n = 0.
    #[error("the number of samples n must be at least 1")]
    ZeroSamples,
    /// n beyond [`crate::MAX_SAMPLES`].
    #[error("the number of samples n = {0} is more than the planner takes (10 000 000)")]
    TooManySamples(usize),
    /// k = 0.
    #[error("the number of neighbours k must be at least 1")]
    ZeroNeighbours,
    /// d_max not finite and positive.
    #[error("the maximum edge length d_max must be a finite positive number of metres, got {0}")]
    BadMaxEdge(f64),
    /// The skeleton share is outside [0, 1].
    #[error("the skeleton sampling share must lie in [0, 1], got {0}")]
    BadSkeletonShare(f64),
    /// The repair share is outside [0, 1].
    #[error("the repair sampling share must lie in [0, 1], got {0}")]
    BadRepairShare(f64),
    /// No cell of the map is free once inflated by the robot radius.
    #[error(
        "no free space: once inflated by {inflation_m} m (robot radius + margin) every cell is blocked"
    )]
    NoFreeSpace {
        /// Robot radius + safety margin, in metres.
        inflation_m: f64,
    },
}

/// Which end of a query an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Endpoint {
    /// The robot's position.
    Start,
    /// The requested goal.
    Goal,
}

impl fmt::Display for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Endpoint::Start => "start",
            Endpoint::Goal => "goal",
        })
    }
}

/// Formats an optional nearest free point for error messages.
struct Nearest(Option<Point2>);

impl fmt::Display for Nearest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(p) => write!(f, "; nearest free point ({:.3}, {:.3})", p.x, p.y),
            None => f.write_str("; the map has no free point"),
        }
    }
}

/// A query that cannot be answered with a path.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QueryError {
    /// A coordinate is NaN or infinite.
    #[error("{endpoint} ({x}, {y}) is not a finite point")]
    NonFinite {
        /// Start or goal.
        endpoint: Endpoint,
        /// x given.
        x: f64,
        /// y given.
        y: f64,
    },
    /// The point lies outside the map.
    #[error(
        "{endpoint} ({:.3}, {:.3}) is outside the map (x in [{:.3}, {:.3}], y in [{:.3}, {:.3}]){}",
        point.x, point.y, min.x, max.x, min.y, max.y, Nearest(*nearest_free)
    )]
    OutsideMap {
        /// Start or goal.
        endpoint: Endpoint,
        /// The point given.
        point: Point2,
        /// Lower-left corner of the map.
        min: Point2,
        /// Upper-right corner of the map.
        max: Point2,
        /// The closest point the robot may stand on, if any.
        nearest_free: Option<Point2>,
    },
    /// The robot cannot stand at the point: an obstacle, unknown space, or closer to one than
    /// the robot radius plus safety margin.
    #[error(
        "{endpoint} ({:.3}, {:.3}) is inside an obstacle or too close to one (clearance {:.3} m, the robot needs {:.3} m){}",
        point.x, point.y, clearance_m, required_m, Nearest(*nearest_free)
    )]
    InObstacle {
        /// Start or goal.
        endpoint: Endpoint,
        /// The point given.
        point: Point2,
        /// Distance from the point's cell to the nearest blocked cell, in metres.
        clearance_m: f64,
        /// Robot radius + safety margin, in metres.
        required_m: f64,
        /// The closest point the robot may stand on, if any.
        nearest_free: Option<Point2>,
    },
    /// Start and goal lie in different connected regions of free space: no path exists.
    #[error(
        "the goal is unreachable: start and goal lie in different free regions ({start_region} and {goal_region})"
    )]
    Unreachable {
        /// Free region of the start.
        start_region: u32,
        /// Free region of the goal.
        goal_region: u32,
    },
    /// Start and goal share a free region but the roadmap does not connect them and local
    /// densification was disabled.
    #[error("the roadmap does not connect start and goal (local densification is disabled)")]
    NotConnected,
}
