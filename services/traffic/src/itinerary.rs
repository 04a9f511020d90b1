//! A robot's committed plan in time: [`Itinerary`] (a timed trajectory with a footprint, a
//! time tolerance, an expiry and an observed delay), its checks and where it puts the robot
//! ([`Itinerary::pose_at`]).

use serde::{Deserialize, Serialize};

use crate::error::TrafficError;

/// The most poses one trajectory may hold.
pub const MAX_POSES: usize = 100_000;
/// The longest schedule one itinerary may span, trajectory and delay together (a day).
pub const MAX_HORIZON_S: f64 = 86_400.0;
/// The longest plan id, robot name or floor name, in bytes.
pub const MAX_NAME_BYTES: usize = 200;

/// A pose of a trajectory, at a time counted from the itinerary's start.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TimedPose {
    /// Seconds after the itinerary's start (`start_unix_ms`), before any delay.
    pub t_s: f64,
    /// Position on the floor, metres.
    pub x: f64,
    /// Position on the floor, metres.
    pub y: f64,
    /// Heading, radians.
    pub yaw: f64,
}

/// A robot's plan as the fleet's traffic schedule holds it: where the robot will be and when.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Itinerary {
    /// The plan this itinerary comes from; unique in the schedule.
    pub plan_id: String,
    /// The robot driving it. A robot has at most one itinerary: a new one replaces the old.
    pub robot: String,
    /// The floor it drives on.
    pub floor: String,
    /// When the trajectory's time 0 is, Unix milliseconds.
    pub start_unix_ms: i64,
    /// The poses, with strictly increasing times.
    pub trajectory: Vec<TimedPose>,
    /// The radius of a disc covering the robot's footprint, metres.
    pub radius_m: f64,
    /// How late or early the robot may be, seconds: at any time it may be anywhere its
    /// schedule puts it within this many seconds of that time.
    pub tolerance_s: f64,
    /// When the schedule forgets this itinerary, Unix milliseconds. Until then, after the
    /// trajectory's end, the robot is parked at its last pose. A progress report moves it by
    /// the change in delay, so the robot keeps the parking time it was committed with.
    pub expires_unix_ms: i64,
    /// The delay observed from the robot's progress, seconds: every time of the trajectory is
    /// this much later (negative: earlier).
    pub delay_s: f64,
    /// The plan's revision: 1 when committed, one more with each revision of its timing or
    /// route before its robot sets off ([`crate::Schedule::revise`]). What a caller puts here
    /// is ignored: the schedule numbers them.
    #[serde(default = "first_revision")]
    pub revision: u32,
}

fn first_revision() -> u32 {
    1
}

/// How far from its first position the robot has left it, metres: below this it still stands
/// at its start (a wait there is poses at one place).
const LEFT_START_M: f64 = 1e-3;

impl Itinerary {
    /// Where the schedule puts the robot at `unix_ms`: the trajectory interpolated linearly
    /// (times shifted by `delay_s`), its last pose after its end until `expires_unix_ms`.
    /// `None` before the first pose's time, after the expiry, or for an empty trajectory.
    pub fn pose_at(&self, unix_ms: i64) -> Option<(f64, f64)> {
        if unix_ms > self.expires_unix_ms {
            return None;
        }
        let t = self.schedule_s(unix_ms);
        let first = self.trajectory.first()?;
        if t.is_nan() || t < first.t_s {
            return None;
        }
        // The first pose whose time is after `t`; the one before it is at or before `t`.
        let next = self.trajectory.partition_point(|p| p.t_s <= t);
        let Some(b) = self.trajectory.get(next) else {
            return self.trajectory.last().map(|p| (p.x, p.y));
        };
        let a = &self.trajectory[next.saturating_sub(1)];
        let span = b.t_s - a.t_s;
        if span.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Some((b.x, b.y));
        }
        let u = ((t - a.t_s) / span).clamp(0.0, 1.0);
        Some((a.x + u * (b.x - a.x), a.y + u * (b.y - a.y)))
    }

    /// The trajectory time (seconds after the start, before the delay) the schedule is at by
    /// `unix_ms`, with the delay taken into account.
    pub fn schedule_s(&self, unix_ms: i64) -> f64 {
        seconds_between(self.start_unix_ms, unix_ms) - self.delay_s
    }

    /// The trajectory time the robot leaves its first position at (the end of its wait at the
    /// start), seconds after the start before the delay; the last pose's time for an itinerary
    /// that stands.
    pub fn departure_s(&self) -> f64 {
        let Some(first) = self.trajectory.first() else {
            return 0.0;
        };
        let leaves = self
            .trajectory
            .iter()
            .position(|p| (p.x - first.x).hypot(p.y - first.y) > LEFT_START_M);
        match leaves {
            Some(k) => self.trajectory[k.saturating_sub(1)].t_s,
            None => self.trajectory.last().map_or(0.0, |p| p.t_s),
        }
    }

    /// When the robot sets off from its start, with the delay, Unix milliseconds.
    pub fn departs_unix_ms(&self) -> i64 {
        add_seconds(self.start_unix_ms, self.departure_s() + self.delay_s)
    }

    /// When the robot reaches its last pose, with the delay, Unix milliseconds.
    pub fn end_unix_ms(&self) -> i64 {
        let last = self.trajectory.last().map_or(0.0, |p| p.t_s);
        add_seconds(self.start_unix_ms, last + self.delay_s)
    }

    /// Checks what the schedule relies on: names present, a non-empty trajectory of finite
    /// poses with strictly increasing, non-negative times, a positive radius, a non-negative
    /// tolerance, a finite delay, bounds ([`MAX_POSES`], [`MAX_HORIZON_S`],
    /// [`MAX_NAME_BYTES`]) and an expiry no earlier than the trajectory's end.
    pub fn check(&self) -> Result<(), TrafficError> {
        let invalid = |what: String| Err(TrafficError::Invalid(what));
        for (field, value) in [
            ("plan_id", &self.plan_id),
            ("robot", &self.robot),
            ("floor", &self.floor),
        ] {
            if value.trim().is_empty() {
                return invalid(format!("{field} is empty"));
            }
            if value.len() > MAX_NAME_BYTES {
                return invalid(format!(
                    "{field} is {} bytes long, more than {MAX_NAME_BYTES}",
                    value.len()
                ));
            }
        }
        if self.trajectory.is_empty() {
            return invalid("the trajectory is empty".to_owned());
        }
        if self.trajectory.len() > MAX_POSES {
            return invalid(format!(
                "the trajectory has {} poses, more than {MAX_POSES}",
                self.trajectory.len()
            ));
        }
        let mut previous: Option<f64> = None;
        for (i, p) in self.trajectory.iter().enumerate() {
            for (field, value) in [("t_s", p.t_s), ("x", p.x), ("y", p.y), ("yaw", p.yaw)] {
                if !value.is_finite() {
                    return invalid(format!("trajectory[{i}].{field} is {value}, not finite"));
                }
            }
            if p.t_s < 0.0 {
                return invalid(format!("trajectory[{i}].t_s is {} < 0", p.t_s));
            }
            if let Some(before) = previous
                && p.t_s <= before
            {
                return invalid(format!(
                    "trajectory[{i}].t_s is {}, not after trajectory[{}].t_s = {before}",
                    p.t_s,
                    i - 1
                ));
            }
            previous = Some(p.t_s);
        }
        let last = previous.unwrap_or(0.0);
        if last > MAX_HORIZON_S {
            return invalid(format!(
                "the trajectory lasts {last} s, more than {MAX_HORIZON_S} s"
            ));
        }
        if !(self.radius_m.is_finite() && self.radius_m > 0.0) {
            return invalid(format!(
                "radius_m is {}, not a positive number",
                self.radius_m
            ));
        }
        if !(self.tolerance_s.is_finite() && self.tolerance_s >= 0.0) {
            return invalid(format!(
                "tolerance_s is {}, not a non-negative number",
                self.tolerance_s
            ));
        }
        if !(self.delay_s.is_finite() && self.delay_s.abs() <= MAX_HORIZON_S) {
            return invalid(format!(
                "delay_s is {}, not a number of seconds within ±{MAX_HORIZON_S}",
                self.delay_s
            ));
        }
        if self.start_unix_ms < 0 {
            return invalid(format!(
                "start_unix_ms is {}, before 1970",
                self.start_unix_ms
            ));
        }
        let end = self.end_unix_ms();
        if self.expires_unix_ms < end {
            return invalid(format!(
                "expires_unix_ms ({}) is before the trajectory ends ({end})",
                self.expires_unix_ms
            ));
        }
        Ok(())
    }
}

/// Seconds from `from_ms` to `to_ms` (Unix milliseconds).
pub(crate) fn seconds_between(from_ms: i64, to_ms: i64) -> f64 {
    // i128: the difference of two i64 cannot overflow it; f64 holds any realistic span exactly.
    #[allow(clippy::cast_precision_loss)] // reason: spans far below 2^53 ms convert exactly
    let ms = (i128::from(to_ms) - i128::from(from_ms)) as f64;
    ms / 1000.0
}

/// `ms` plus `seconds`, Unix milliseconds, rounded to the nearest millisecond and saturating
/// (a non-finite `seconds` adds nothing).
pub(crate) fn add_seconds(ms: i64, seconds: f64) -> i64 {
    if !seconds.is_finite() {
        return ms;
    }
    // A float-to-int `as` saturates at the bounds; the clamp makes that explicit.
    #[allow(clippy::cast_possible_truncation)] // reason: rounded and clamped to i64's range
    let delta = (seconds * 1000.0)
        .round()
        .clamp(i64::MIN as f64, i64::MAX as f64) as i64;
    ms.saturating_add(delta)
}
