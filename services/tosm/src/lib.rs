//! TOSM vocabulary and typed model <-> RDF, with validation; no IO.
//!
//! The crate takes values (strings, bytes, RDF graphs) and returns values: it opens no files,
//! makes no network calls and knows nothing of async runtimes.
//!
//! - [`occupancy`]: ROS map_server maps (YAML + PGM/PNG) to occupancy grids and back to PNG.
//! - [`vocab`]: the IRIs of the ontology in `ontologies/tosm.ttl`.
//! - [`model`]: typed places, objects, robots and what is known about people.
//! - [`read`](mod@crate::read) and [`write`](mod@crate::write): RDF graph to typed values and back, each reporting [`Problems`].

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (`planning` and `bench` do not yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod model;
pub mod occupancy;
pub mod problems;
pub mod read;
pub mod vocab;
pub mod write;

pub use model::{
    Attractor, Camera, CameraKind, Colour, DEFAULT_MAP_FRAME, Dynamics, ESTIMATE_MIN_WEIGHT, Joint,
    JointKind, Laser, MetricMap, Object, ObjectClass, Part, People, PeopleEstimate, Physical,
    Place, PlaceKind, PlacePeople, Pose3, Relation, RelationKind, Robot, Shape, StructuralPart,
    Symbol, WalkingRoute, Wheel, is_ros_frame_name,
};
pub use occupancy::{Occupancy, OccupancyGrid, Pose2, RosMapError, RosMapMeta};
pub use problems::{Problem, Problems};
pub use read::{
    read_objects, read_objects_lenient, read_people, read_people_estimates, read_people_lenient,
    read_places, read_places_lenient, read_robot, read_robots,
};
pub use write::{
    attractor_to_triples, metric_map_to_triples, object_to_triples, occupancy_grid_to_triples,
    people_estimate_to_triples, place_people_to_triples, place_to_triples, robot_to_triples,
    walking_route_to_triples,
};
