//! A dense path and the robot's progress along it, as path-tracking controllers (Regulated Pure
//! Pursuit, MPPI) keep it: the path is pruned behind the robot (Nav2 prunes the global path to
//! the part ahead of the robot's closest point each cycle, searching no farther than
//! `max_robot_pose_search_dist`), and the carrot is the first point at least the look-ahead
//! distance away from the robot.

use crate::Pose2;

/// A dense path (points a few centimetres apart) and how far along it the robot is.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PathTrack {
    points: Vec<(f64, f64)>,
    /// Distance along the path of each point from its start, metres.
    along: Vec<f64>,
    /// Index of the point closest to the robot at the last update.
    progress: usize,
}

impl PathTrack {
    /// A track on `points` (at least one), the robot at its start.
    pub fn new(points: Vec<(f64, f64)>) -> Self {
        let mut along = Vec::with_capacity(points.len());
        let mut s = 0.0;
        for (i, p) in points.iter().enumerate() {
            if i > 0 {
                let q = points[i - 1];
                s += crate::norm(p.0 - q.0, p.1 - q.1);
            }
            along.push(s);
        }
        Self {
            points,
            along,
            progress: 0,
        }
    }

    /// The path's points.
    pub fn points(&self) -> &[(f64, f64)] {
        &self.points
    }

    /// Whether the path has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Index of the point closest to the robot at the last [`PathTrack::update`].
    pub fn progress(&self) -> usize {
        self.progress
    }

    /// The path's last point.
    pub fn end(&self) -> Option<(f64, f64)> {
        self.points.last().copied()
    }

    /// Distance along the path from point `i` to its end, metres.
    pub fn remaining_from(&self, i: usize) -> f64 {
        match (self.along.last(), self.along.get(i)) {
            (Some(total), Some(here)) => total - here,
            _ => 0.0,
        }
    }

    /// Moves the progress to the point closest to `pose` among those at most `search_m`
    /// further along the path than the current one (the path behind is pruned: progress never
    /// goes back).
    pub fn update(&mut self, pose: Pose2, search_m: f64) {
        if self.points.is_empty() {
            return;
        }
        let start = self.progress.min(self.points.len() - 1);
        let limit = self.along[start] + search_m;
        let d = |p: &(f64, f64)| crate::norm(p.0 - pose.x, p.1 - pose.y);
        let mut best = (start, d(&self.points[start]));
        for i in start + 1..self.points.len() {
            if self.along[i] > limit {
                break;
            }
            let di = d(&self.points[i]);
            if di < best.1 {
                best = (i, di);
            }
        }
        self.progress = best.0;
    }

    /// The carrot: the first point after the progress at least `lookahead_m` from `pose`
    /// (interpolated on the segment that crosses that circle), or the path's end.
    pub fn carrot(&self, pose: Pose2, lookahead_m: f64) -> Option<(f64, f64)> {
        let d = |p: &(f64, f64)| crate::norm(p.0 - pose.x, p.1 - pose.y);
        let start = self.progress.min(self.points.len().checked_sub(1)?);
        for i in start..self.points.len() {
            if d(&self.points[i]) >= lookahead_m {
                if i == start {
                    return Some(self.points[i]);
                }
                // The crossing of the circle on the segment (i - 1, i).
                let (a, b) = (self.points[i - 1], self.points[i]);
                let (dx, dy) = (b.0 - a.0, b.1 - a.1);
                let (fx, fy) = (a.0 - pose.x, a.1 - pose.y);
                let qa = dx * dx + dy * dy;
                let qb = 2.0 * (fx * dx + fy * dy);
                let qc = fx * fx + fy * fy - lookahead_m * lookahead_m;
                let disc = qb * qb - 4.0 * qa * qc;
                if qa < 1e-12 || disc < 0.0 {
                    return Some(b);
                }
                let t = ((-qb + disc.sqrt()) / (2.0 * qa)).clamp(0.0, 1.0);
                return Some((a.0 + t * dx, a.1 + t * dy));
            }
        }
        self.end()
    }

    /// Index of the point closest to `p` (over the whole path).
    pub fn closest_index(&self, p: (f64, f64)) -> usize {
        self.points
            .iter()
            .enumerate()
            .min_by(|a, b| {
                let da = crate::norm(a.1.0 - p.0, a.1.1 - p.1);
                let db = crate::norm(b.1.0 - p.0, b.1.1 - p.1);
                da.total_cmp(&db)
            })
            .map_or(0, |(i, _)| i)
    }

    /// `points[from..=to]` (clamped to the path).
    pub fn window(&self, from: usize, to: usize) -> &[(f64, f64)] {
        if self.points.is_empty() {
            return &[];
        }
        let last = self.points.len() - 1;
        let (a, b) = (from.min(last), to.min(last));
        &self.points[a..=b.max(a)]
    }
}
