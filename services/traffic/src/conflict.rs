//! Conflicts between timed trajectories: [`first_conflict`] (two itineraries) and
//! [`conflicts`] (one new itinerary against those committed).
//!
//! A robot late or early by up to its tolerance may be, at time `T`, anywhere its schedule puts
//! it between `T − tolerance` and `T + tolerance`. Each itinerary is cut into pieces (a piece of
//! a segment between two poses, at most 0.1 s or 5 cm long; its last pose, parked until the
//! expiry) and each piece is "occupied" from its start time minus the tolerance to its end time
//! plus the tolerance. Two pieces conflict when their occupied windows overlap and the segments
//! come closer than the two radii plus the margin; the conflict's time is the start of the
//! overlap, the earliest the robots could be that close. The test is conservative: a piece
//! counts as occupied whole during its window (at most one piece length more than the robot
//! sweeps).
//!
//! Pieces are grouped into chunks of 16 consecutive pieces with a time window and a bounding box;
//! chunk pairs are visited in time order with two pointers (only chunks whose windows overlap),
//! pairs whose boxes are farther apart than the clearance are skipped, and the search stops as
//! soon as no later pair can conflict earlier. For trajectories with `n` and `m` pieces the cost
//! is O(n + m) to cut them, O(n + m + k) chunk pairs, where k is the number of chunk pairs whose
//! windows overlap (each chunk overlaps about `(2·(tol_a + tol_b) + 3.2 s) / 1.6 s` chunks of
//! the other), and 256 piece tests for each chunk pair that is near in space as well. No step is
//! quadratic in the trajectories' length.

use serde::{Deserialize, Serialize};

use crate::itinerary::{Itinerary, add_seconds, seconds_between};

/// The longest piece in time, seconds.
const MAX_PIECE_S: f64 = 0.1;
/// A piece need not be shorter than this in space, metres (a slow segment is cut by length).
const MAX_PIECE_M: f64 = 0.05;
/// The most pieces a trajectory is cut into (beyond, segments are cut coarser): bounds memory
/// for trajectories that were never checked.
const MAX_PIECES: usize = 400_000;
/// Pieces per chunk.
const CHUNK: usize = 16;

/// Where and when two robots' schedules may bring them too close.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Conflict {
    /// The earliest time the robots may be too close, Unix milliseconds.
    pub at_unix_ms: i64,
    /// The first itinerary's robot.
    pub a_robot: String,
    /// The first itinerary's plan id.
    pub a_plan_id: String,
    /// The second itinerary's robot.
    pub b_robot: String,
    /// The second itinerary's plan id.
    pub b_plan_id: String,
    /// How close the two robots' centres may come at that time, metres.
    pub distance_m: f64,
    /// Where the first robot's centre is then (the closest point of its swept positions).
    pub a_xy: [f64; 2],
    /// Where the second robot's centre is then.
    pub b_xy: [f64; 2],
}

/// The earliest time robots `a` and `b` may come closer than `a.radius_m + b.radius_m +
/// margin_m`, each anywhere its schedule puts it within its tolerance; `None` when they never
/// do, when they are the same robot, or on different floors. A non-finite margin counts as 0.
///
/// Cost: linear in the two trajectories' lengths (see the module's documentation).
/// Itineraries that fail [`Itinerary::check`] give unspecified results, never a panic.
pub fn first_conflict(a: &Itinerary, b: &Itinerary, margin_m: f64) -> Option<Conflict> {
    if a.robot == b.robot || a.floor != b.floor {
        return None;
    }
    let origin = a.start_unix_ms;
    let mut work = Work::default();
    earliest(
        &Occupancy::of(a, origin),
        &Occupancy::of(b, origin),
        Margins::same(margin_m),
        &mut work,
    )
}

/// Every committed itinerary in `others` that `new` conflicts with (see [`first_conflict`]),
/// earliest first. `new` is cut into pieces once; the cost is linear in the total length.
pub fn conflicts(new: &Itinerary, others: &[Itinerary], margin_m: f64) -> Vec<Conflict> {
    Reserved::new(others, new.start_unix_ms).conflicts(new, margin_m)
}

/// Committed itineraries cut into pieces once, to check many candidate itineraries against
/// (a plan fitted with one wait more at a time, or started one second later at a time): the
/// candidates are cut on each check, the committed ones not again.
pub struct Reserved<'a> {
    origin_ms: i64,
    others: Vec<Occupancy<'a>>,
}

impl<'a> Reserved<'a> {
    /// `others` cut with times in seconds after `origin_ms` (any instant near the candidates'
    /// starts: it only keeps the seconds small).
    pub fn new(others: &'a [Itinerary], origin_ms: i64) -> Self {
        Self {
            origin_ms,
            others: others.iter().map(|o| Occupancy::of(o, origin_ms)).collect(),
        }
    }

    /// [`conflicts`] of `new` with these itineraries.
    pub fn conflicts(&self, new: &Itinerary, margin_m: f64) -> Vec<Conflict> {
        self.conflicts_with(new, Margins::same(margin_m))
    }

    /// [`Reserved::conflicts`] with the margin depending on whether either robot stands still
    /// ([`Margins`]).
    pub fn conflicts_with(&self, new: &Itinerary, margins: Margins) -> Vec<Conflict> {
        let mine = Occupancy::of(new, self.origin_ms);
        let mut work = Work::default();
        let mut found: Vec<Conflict> = self
            .others
            .iter()
            .filter(|other| {
                other.itinerary.robot != new.robot && other.itinerary.floor == new.floor
            })
            .filter_map(|other| earliest(&mine, other, margins, &mut work))
            .collect();
        found.sort_by(|x, y| {
            x.at_unix_ms
                .cmp(&y.at_unix_ms)
                .then_with(|| x.b_robot.cmp(&y.b_robot))
        });
        found
    }

    /// The earliest of [`Reserved::conflicts`].
    pub fn first(&self, new: &Itinerary, margin_m: f64) -> Option<Conflict> {
        self.conflicts(new, margin_m).into_iter().next()
    }

    /// The earliest of [`Reserved::conflicts_with`].
    pub fn first_with(&self, new: &Itinerary, margins: Margins) -> Option<Conflict> {
        self.conflicts_with(new, margins).into_iter().next()
    }
}

/// The gaps kept between two robots' footprints beyond their radii, metres: `moving` between
/// two robots both moving, `still` where either stands still (a piece of its trajectory that
/// does not move: waiting, parked at its goal, standing at its start). A robot standing still
/// reacts to nobody, so the other may pass it as it passes any obstacle. Non-finite counts as
/// 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Margins {
    /// Both robots moving.
    pub moving: f64,
    /// Either standing still.
    pub still: f64,
}

impl Margins {
    /// One margin whether the robots move or not.
    pub fn same(margin_m: f64) -> Self {
        Self {
            moving: margin_m,
            still: margin_m,
        }
    }
}

/// What a search did: the unit test of the cost counts it.
#[derive(Debug, Default, Clone, Copy)]
struct Work {
    /// Chunk pairs whose windows overlap.
    chunk_pairs: usize,
    /// Piece pairs tested.
    piece_pairs: usize,
}

/// An axis-aligned box.
#[derive(Debug, Clone, Copy)]
struct Aabb {
    min: [f64; 2],
    max: [f64; 2],
}

impl Aabb {
    fn of(p: [f64; 2], q: [f64; 2]) -> Self {
        Self {
            min: [p[0].min(q[0]), p[1].min(q[1])],
            max: [p[0].max(q[0]), p[1].max(q[1])],
        }
    }

    fn union(self, other: Self) -> Self {
        Self {
            min: [self.min[0].min(other.min[0]), self.min[1].min(other.min[1])],
            max: [self.max[0].max(other.max[0]), self.max[1].max(other.max[1])],
        }
    }

    /// The distance between the boxes (0 when they touch or overlap).
    fn gap(&self, other: &Self) -> f64 {
        let dx = (self.min[0] - other.max[0])
            .max(other.min[0] - self.max[0])
            .max(0.0);
        let dy = (self.min[1] - other.max[1])
            .max(other.min[1] - self.max[1])
            .max(0.0);
        dx.hypot(dy)
    }
}

/// A piece of a trajectory and when the robot may be on it (tolerance included), seconds
/// after the origin.
#[derive(Debug, Clone, Copy)]
struct Piece {
    t0: f64,
    t1: f64,
    p: [f64; 2],
    q: [f64; 2],
    bbox: Aabb,
}

/// Consecutive pieces, their window and their box.
#[derive(Debug, Clone)]
struct Chunk {
    t0: f64,
    t1: f64,
    bbox: Aabb,
    pieces: std::ops::Range<usize>,
}

/// An itinerary cut into pieces and chunks, times in seconds after a shared origin.
struct Occupancy<'a> {
    itinerary: &'a Itinerary,
    origin_ms: i64,
    pieces: Vec<Piece>,
    chunks: Vec<Chunk>,
}

impl<'a> Occupancy<'a> {
    fn of(itinerary: &'a Itinerary, origin_ms: i64) -> Self {
        let tol = if itinerary.tolerance_s.is_finite() {
            itinerary.tolerance_s.max(0.0)
        } else {
            0.0
        };
        let offset = seconds_between(origin_ms, itinerary.start_unix_ms) + itinerary.delay_s;
        let expiry = seconds_between(origin_ms, itinerary.expires_unix_ms);
        let poses = &itinerary.trajectory;
        let per_segment = (MAX_PIECES / poses.len().max(1)).max(1);
        let mut pieces = Vec::new();
        for pair in poses.windows(2) {
            let (a, b) = (&pair[0], &pair[1]);
            let (s0, s1) = (offset + a.t_s, offset + b.t_s);
            if s0 > expiry {
                break;
            }
            let (p, q) = ([a.x, a.y], [b.x, b.y]);
            let length = (q[0] - p[0]).hypot(q[1] - p[1]);
            let n = pieces_for(s1 - s0, length, per_segment);
            let at = |k: usize| {
                let u = k as f64 / n as f64;
                (
                    s0 + u * (s1 - s0),
                    [p[0] + u * (q[0] - p[0]), p[1] + u * (q[1] - p[1])],
                )
            };
            for k in 0..n {
                let ((t0, from), (t1, to)) = (at(k), at(k + 1));
                pieces.push(Piece {
                    t0: t0 - tol,
                    t1: t1 + tol,
                    p: from,
                    q: to,
                    bbox: Aabb::of(from, to),
                });
            }
        }
        let moving = pieces.len();
        if let Some(last) = poses.last() {
            let end = offset + last.t_s;
            if end <= expiry {
                // Parked at the goal until the expiry; a late robot arrives up to `tol` later.
                let xy = [last.x, last.y];
                pieces.push(Piece {
                    t0: end - tol,
                    t1: expiry.max(end + tol),
                    p: xy,
                    q: xy,
                    bbox: Aabb::of(xy, xy),
                });
            }
        }
        let mut chunks = Vec::with_capacity(pieces.len() / CHUNK + 2);
        let mut start = 0;
        while start < pieces.len() {
            // The parked piece gets a chunk of its own: its window is long, its box a point.
            let end = if start < moving {
                (start + CHUNK).min(moving)
            } else {
                pieces.len()
            };
            let slice = &pieces[start..end];
            let bbox = slice
                .iter()
                .skip(1)
                .fold(slice[0].bbox, |acc, piece| acc.union(piece.bbox));
            let t0 = slice.iter().map(|x| x.t0).fold(f64::INFINITY, f64::min);
            let t1 = slice.iter().map(|x| x.t1).fold(f64::NEG_INFINITY, f64::max);
            chunks.push(Chunk {
                t0,
                t1,
                bbox,
                pieces: start..end,
            });
            start = end;
        }
        Self {
            itinerary,
            origin_ms,
            pieces,
            chunks,
        }
    }
}

/// How many pieces a segment lasting `duration` seconds and `length` metres long is cut into.
fn pieces_for(duration: f64, length: f64, cap: usize) -> usize {
    // Less a rounding error, so that a segment of exactly 0.1 s stays one piece.
    let by_time = (duration / MAX_PIECE_S - 1e-9).ceil();
    let by_length = (length / MAX_PIECE_M - 1e-9).ceil();
    let n = by_time.min(by_length);
    if n.is_nan() || n < 1.0 {
        return 1;
    }
    // Float-to-int `as` saturates; the value is then capped.
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // reason: n >= 1, capped
    let n = n.min(1e9) as usize;
    n.min(cap)
}

/// The earliest conflict between two occupancies cut with the same origin.
fn earliest(
    a: &Occupancy<'_>,
    b: &Occupancy<'_>,
    margins: Margins,
    work: &mut Work,
) -> Option<Conflict> {
    let finite = |m: f64| if m.is_finite() { m } else { 0.0 };
    let radii = a.itinerary.radius_m + b.itinerary.radius_m;
    let (moving, still) = (
        radii + finite(margins.moving),
        radii + finite(margins.still),
    );
    // Chunks are skipped by the larger clearance: either may hold still pieces.
    let clearance = moving.max(still);
    // (time, distance, a's point, b's point)
    let mut best: Option<(f64, f64, [f64; 2], [f64; 2])> = None;
    let mut lo = 0;
    for ca in &a.chunks {
        if best.is_some_and(|(t, ..)| t <= ca.t0) {
            break; // every later pair starts no earlier than this chunk
        }
        while lo < b.chunks.len() && b.chunks[lo].t1 < ca.t0 {
            lo += 1;
        }
        for cb in b.chunks[lo..].iter().take_while(|cb| cb.t0 <= ca.t1) {
            work.chunk_pairs += 1;
            if cb.t1 < ca.t0
                || best.is_some_and(|(t, ..)| t <= ca.t0.max(cb.t0))
                || ca.bbox.gap(&cb.bbox) >= clearance
            {
                continue;
            }
            for pa in &a.pieces[ca.pieces.clone()] {
                for pb in &b.pieces[cb.pieces.clone()] {
                    work.piece_pairs += 1;
                    if pb.t1 < pa.t0 || pb.t0 > pa.t1 {
                        continue;
                    }
                    let t = pa.t0.max(pb.t0);
                    if best.is_some_and(|(bt, ..)| bt <= t) || pa.bbox.gap(&pb.bbox) >= clearance {
                        continue;
                    }
                    let (distance, xa, xb) = segment_distance(pa.p, pa.q, pb.p, pb.q);
                    let keep = if pa.p == pa.q || pb.p == pb.q {
                        still
                    } else {
                        moving
                    };
                    if distance < keep {
                        best = Some((t, distance, xa, xb));
                    }
                }
            }
        }
    }
    let (t, distance_m, a_xy, b_xy) = best?;
    Some(Conflict {
        at_unix_ms: add_seconds(a.origin_ms, t),
        a_robot: a.itinerary.robot.clone(),
        a_plan_id: a.itinerary.plan_id.clone(),
        b_robot: b.itinerary.robot.clone(),
        b_plan_id: b.itinerary.plan_id.clone(),
        distance_m,
        a_xy,
        b_xy,
    })
}

/// The distance between segments `p1q1` and `p2q2` and the closest point of each (the
/// clamped closest points of the two lines; exact for points, parallel and crossing segments).
fn segment_distance(
    p1: [f64; 2],
    q1: [f64; 2],
    p2: [f64; 2],
    q2: [f64; 2],
) -> (f64, [f64; 2], [f64; 2]) {
    const TINY: f64 = 1e-24;
    let dot = |u: [f64; 2], v: [f64; 2]| u[0] * v[0] + u[1] * v[1];
    let d1 = [q1[0] - p1[0], q1[1] - p1[1]];
    let d2 = [q2[0] - p2[0], q2[1] - p2[1]];
    let r = [p1[0] - p2[0], p1[1] - p2[1]];
    let (a, e, f) = (dot(d1, d1), dot(d2, d2), dot(d2, r));
    let (s, t) = if a <= TINY && e <= TINY {
        (0.0, 0.0)
    } else if a <= TINY {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = dot(d1, r);
        if e <= TINY {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = dot(d1, d2);
            let denom = a * e - b * b;
            // Parallel segments: any point of the first will do before the clamping below.
            let s = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t = (b * s + f) / e;
            if t < 0.0 {
                ((-c / a).clamp(0.0, 1.0), 0.0)
            } else if t > 1.0 {
                (((b - c) / a).clamp(0.0, 1.0), 1.0)
            } else {
                (s, t)
            }
        }
    };
    let x1 = [p1[0] + s * d1[0], p1[1] + s * d1[1]];
    let x2 = [p2[0] + t * d2[0], p2[1] + t * d2[1]];
    ((x1[0] - x2[0]).hypot(x1[1] - x2[1]), x1, x2)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)] // reason: tests panic on failure

    use super::*;
    use crate::itinerary::TimedPose;

    const START: i64 = 1_700_000_000_000;

    /// A robot driving from `from` to `to` at `speed` m/s, poses every `step_s` seconds,
    /// starting `start_s` after `START`.
    fn drive(
        robot: &str,
        from: [f64; 2],
        to: [f64; 2],
        speed: f64,
        step_s: f64,
        start_s: f64,
    ) -> Itinerary {
        let length = (to[0] - from[0]).hypot(to[1] - from[1]);
        let duration = length / speed;
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // reason: test sizes
        let steps = (duration / step_s).ceil() as usize;
        let trajectory = (0..=steps)
            .map(|i| {
                let u = (i as f64 / steps as f64).min(1.0);
                TimedPose {
                    t_s: u * duration,
                    x: from[0] + u * (to[0] - from[0]),
                    y: from[1] + u * (to[1] - from[1]),
                    yaw: 0.0,
                }
            })
            .collect();
        let start = add_seconds(START, start_s);
        Itinerary {
            plan_id: format!("plan-{robot}"),
            robot: robot.to_owned(),
            floor: "f1".to_owned(),
            start_unix_ms: start,
            trajectory,
            radius_m: 0.3,
            tolerance_s: 1.0,
            expires_unix_ms: add_seconds(start, duration),
            delay_s: 0.0,
            revision: 1,
        }
    }

    fn work_for(a: &Itinerary, b: &Itinerary) -> (Option<Conflict>, Work) {
        let mut work = Work::default();
        let found = earliest(
            &Occupancy::of(a, a.start_unix_ms),
            &Occupancy::of(b, a.start_unix_ms),
            Margins::same(0.1),
            &mut work,
        );
        (found, work)
    }

    /// Two robots side by side in parallel diagonal lanes, 0.9 m apart (clearance 0.7 m): near
    /// in space during their whole drive, never in conflict, and their chunks' boxes overlap (the
    /// lanes are diagonal), so this is the search's worst case. Its work must grow linearly with
    /// the trajectories' length.
    #[test]
    fn the_search_is_linear_in_the_trajectories_length() {
        let lanes = |n_poses: usize| {
            let side = n_poses as f64 * 0.1 / std::f64::consts::SQRT_2; // 1 m/s, a pose every 0.1 s
            let off = 0.9 / std::f64::consts::SQRT_2;
            let a = drive("a", [0.0, 0.0], [side, side], 1.0, 0.1, 0.0);
            let b = drive("b", [-off, off], [side - off, side + off], 1.0, 0.1, 0.0);
            let (found, work) = work_for(&a, &b);
            assert!(found.is_none(), "{found:?}");
            (a.trajectory.len(), work)
        };
        let (n, small) = lanes(2_000);
        let (_, large) = lanes(4_000);
        // Each chunk (1.6 s) overlaps about 5 of the other's in time (windows widened by 1 s
        // either side), near in space: 5·256 piece tests a chunk, 80 a piece. A quadratic search
        // would make n² = 4·10⁶.
        assert!(
            small.piece_pairs > 0,
            "the boxes must not filter everything: {small:?}"
        );
        assert!(small.piece_pairs <= 100 * n, "{small:?} for {n} poses");
        assert!(
            small.chunk_pairs <= 8 * n / CHUNK,
            "{small:?} for {n} poses"
        );
        let ratio = large.piece_pairs as f64 / small.piece_pairs as f64;
        assert!(
            ratio < 2.2,
            "twice the poses cost {ratio}× the work: {small:?} → {large:?}"
        );
    }

    /// A robot standing still (its trajectory one pose) is passed with the `still` margin, two
    /// robots driving past each other keep the `moving` one: 0.9 m between centres of 0.3 m
    /// robots is a 0.3 m gap.
    #[test]
    fn a_robot_standing_still_is_passed_closer_than_one_driving() {
        let margins = Margins {
            moving: 0.38,
            still: 0.1,
        };
        let passing = drive("a", [0.0, 0.0], [10.0, 0.0], 1.0, 0.1, 0.0);
        let mut standing = drive("b", [5.0, 0.9], [5.0, 0.9], 1.0, 0.1, 0.0);
        standing.trajectory.truncate(1);
        standing.expires_unix_ms = add_seconds(START, 60.0);
        let others = [standing.clone()];
        let reserved = Reserved::new(&others, passing.start_unix_ms);
        assert!(reserved.first_with(&passing, margins).is_none());
        // The same margin for both: the standing robot is too close.
        assert!(reserved.first(&passing, 0.38).is_some());
        // Driving the other way 0.9 m beside it: both move, the moving margin holds.
        let oncoming = [drive("c", [10.0, 0.9], [0.0, 0.9], 1.0, 0.1, 0.0)];
        let found = Reserved::new(&oncoming, passing.start_unix_ms).first_with(&passing, margins);
        assert!(
            found.as_ref().is_some_and(|c| c.b_robot == "c"),
            "{found:?}"
        );
        // Closer than the still margin: a conflict still.
        let mut near = standing;
        near.trajectory[0].y = 0.65;
        let others = [near];
        assert!(
            Reserved::new(&others, passing.start_unix_ms)
                .first_with(&passing, margins)
                .is_some()
        );
    }

    /// Robots far apart in space cost only the chunk pairs of their time overlap, no piece test.
    #[test]
    fn robots_far_apart_cost_no_piece_test() {
        let a = drive("a", [0.0, 0.0], [200.0, 0.0], 1.0, 0.1, 0.0);
        let b = drive("b", [0.0, 50.0], [200.0, 50.0], 1.0, 0.1, 0.0);
        let (found, work) = work_for(&a, &b);
        assert!(found.is_none());
        assert_eq!(work.piece_pairs, 0, "{work:?}");
        assert!(
            work.chunk_pairs <= 8 * a.trajectory.len() / CHUNK,
            "{work:?}"
        );
    }

    /// The same corridor used at different times: no piece test either.
    #[test]
    fn robots_apart_in_time_cost_no_piece_test() {
        let a = drive("a", [0.0, 0.0], [200.0, 0.0], 1.0, 0.1, 0.0);
        let mut b = drive("b", [0.0, 0.0], [200.0, 0.0], 1.0, 0.1, 1_000.0);
        b.tolerance_s = 5.0;
        let (found, work) = work_for(&a, &b);
        assert!(found.is_none());
        assert_eq!(work.piece_pairs, 0, "{work:?}");
    }

    #[test]
    fn segment_distance_matches_brute_force() {
        let cases = [
            ([0.0, 0.0], [4.0, 0.0], [1.0, 1.0], [3.0, 2.0]), // above
            ([0.0, 0.0], [4.0, 0.0], [2.0, -1.0], [2.0, 1.0]), // crossing
            ([0.0, 0.0], [4.0, 0.0], [5.0, 0.0], [7.0, 0.0]), // collinear, apart
            ([0.0, 0.0], [4.0, 0.0], [1.0, 0.5], [3.0, 0.5]), // parallel, overlapping
            ([0.0, 0.0], [0.0, 0.0], [1.0, 1.0], [1.0, 1.0]), // two points
            ([1.0, 1.0], [1.0, 1.0], [0.0, 0.0], [4.0, 0.0]), // a point and a segment
            ([0.0, 0.0], [1.0, 1.0], [3.0, 0.0], [2.0, 5.0]), // skew
        ];
        for (p1, q1, p2, q2) in cases {
            let (d, x1, x2) = segment_distance(p1, q1, p2, q2);
            let mut brute = f64::INFINITY;
            for i in 0..=400 {
                for j in 0..=400 {
                    let (s, t) = (f64::from(i) / 400.0, f64::from(j) / 400.0);
                    let a = [p1[0] + s * (q1[0] - p1[0]), p1[1] + s * (q1[1] - p1[1])];
                    let b = [p2[0] + t * (q2[0] - p2[0]), p2[1] + t * (q2[1] - p2[1])];
                    brute = brute.min((a[0] - b[0]).hypot(a[1] - b[1]));
                }
            }
            assert!(
                d <= brute + 1e-12 && brute - d < 0.02,
                "{p1:?}{q1:?}{p2:?}{q2:?}: {d} vs {brute}"
            );
            let between = (x1[0] - x2[0]).hypot(x1[1] - x2[1]);
            assert!((between - d).abs() < 1e-12);
        }
    }
}
