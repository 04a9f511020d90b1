//! Integration tests of the simulator: ray casts against analytic cases, collision, the
//! environment's determinism and batches, validation, renders and a real ROS map.

mod common;
mod env;
mod export;
mod nav2;
mod parse;
mod people;
mod raycast;
mod render;
mod ros_map;
mod validation;
