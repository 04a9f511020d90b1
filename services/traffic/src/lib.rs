//! The fleet's traffic schedule: where every robot was told to drive on each floor and when,
//! stored in the job database, and the geometry that finds where two schedules conflict.
//!
//! - [`Itinerary`] ([`TimedPose`]s with a footprint radius, a time tolerance, an expiry and an
//!   observed delay) and [`Itinerary::pose_at`].
//! - [`Schedule`]: per floor, every robot's committed itinerary and a version; optimistic
//!   commits against that version ([`Schedule::commit`]), cancels, progress reports that shift
//!   a robot's schedule by its observed delay, snapshots, and this process's [`Change`]s;
//!   revisions of plans whose robots have not set off ([`Schedule::revise`], [`Planned`]),
//!   acknowledged with the robot's progress; [`passings`]: the order plans pass where they
//!   meet, so a robot waits for the robots before it, not for the clock; [`Wait`]s: plans
//!   waiting for robots standing with no plan, seen by every process sharing the database.
//! - [`first_conflict`] and [`conflicts`]: the earliest time two robots may come too close,
//!   each anywhere within its tolerance of its schedule ([`Conflict`]).
//!
//! No HTTP and no simulation: the API maps [`TrafficError`] to statuses, the planner decides
//! what to do about a conflict.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

#[cfg(feature = "store")]
mod change;
mod conflict;
mod error;
mod itinerary;
mod precedence;
#[cfg(feature = "store")]
mod progress;
mod revision;
#[cfg(feature = "store")]
mod schedule;
mod wait;

#[cfg(feature = "store")]
pub use change::{Change, Removal};
pub use conflict::{Conflict, Margins, Reserved, conflicts, first_conflict};
pub use error::TrafficError;
pub use itinerary::{Itinerary, MAX_HORIZON_S, MAX_NAME_BYTES, MAX_POSES, TimedPose};
pub use precedence::{Passing, may_go_until_s, passings};
pub use revision::{Planned, REVISION_NOTICE_S};
#[cfg(feature = "store")]
pub use schedule::Schedule;
pub use wait::Wait;
