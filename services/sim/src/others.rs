//! Other robots in one simulation: discs moving along timed tracks (the plans the fleet's
//! schedule already gave them), seen by the laser and touched by the footprint. They keep to
//! their tracks and do not react to the simulated robot: a conflict shows as a contact however
//! polite the other robot would have been, which is the safe side for a check. Made
//! [`OtherRobots::shielded`], each holds where its next step would bring it within
//! [`SHIELD_GAP_M`] of the simulated robot, closing in, as its own collision monitor would stop
//! it (late on its track from then on): a joint run of robots that all have shields.

/// One other robot.
#[derive(Clone, Debug, PartialEq)]
pub struct OtherRobot {
    /// Its name (an IRI), for reports.
    pub name: String,
    /// Footprint radius, metres.
    pub radius: f64,
    /// Where it is when: `(t, x, y)`, `t` in seconds of the simulation's clock, ascending.
    /// Between two samples it moves in a straight line; before the first and after the last
    /// it is not on the floor (as a traffic schedule places robots: from their start to
    /// their expiry).
    pub track: Vec<(f64, f64, f64)>,
}

impl OtherRobot {
    /// Where it is at `t`, if it is on the floor then.
    pub fn position_at(&self, t: f64) -> Option<(f64, f64)> {
        let (first, last) = (self.track.first()?, self.track.last()?);
        if t < first.0 || t > last.0 {
            return None;
        }
        if t == first.0 {
            return Some((first.1, first.2));
        }
        let i = self.track.partition_point(|s| s.0 < t);
        let (a, b) = (self.track[i - 1], self.track[i]);
        let span = b.0 - a.0;
        let f = if span > 0.0 { (t - a.0) / span } else { 1.0 };
        Some((a.1 + f * (b.1 - a.1), a.2 + f * (b.2 - a.2)))
    }
}

/// The other robots of one simulation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OtherRobots {
    robots: Vec<OtherRobot>,
    shielded: bool,
}

/// The gap to the simulated robot at which a shielded other robot stops, metres: the plans'
/// safety margin (`rehearsal::PlanOptions::safety_margin_m`'s default).
pub const SHIELD_GAP_M: f64 = 0.1;

impl OtherRobots {
    /// The robots, or what is wrong with one (a radius that is not positive, a sample that is
    /// not finite, times that go back).
    pub fn new(robots: Vec<OtherRobot>) -> Result<OtherRobots, String> {
        for r in &robots {
            if !(r.radius.is_finite() && r.radius > 0.0) {
                return Err(format!(
                    "{}: radius must be positive, got {}",
                    r.name, r.radius
                ));
            }
            if r.track
                .iter()
                .any(|s| !(s.0.is_finite() && s.1.is_finite() && s.2.is_finite()))
            {
                return Err(format!("{}: every track sample must be finite", r.name));
            }
            if r.track.windows(2).any(|w| w[1].0 < w[0].0) {
                return Err(format!("{}: track times must not go back", r.name));
            }
        }
        Ok(OtherRobots {
            robots,
            shielded: false,
        })
    }

    /// The same robots, each stopping for the simulated robot as its shield would (see the
    /// module).
    pub fn shielded(self) -> OtherRobots {
        OtherRobots {
            shielded: true,
            ..self
        }
    }

    /// Whether they stop for the simulated robot.
    pub fn is_shielded(&self) -> bool {
        self.shielded
    }

    /// The robots.
    pub fn robots(&self) -> &[OtherRobot] {
        &self.robots
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.robots.is_empty()
    }

    /// The same robots on a clock moved by `dt`: what was at `t` is at `t + dt`.
    pub fn shifted(&self, dt: f64) -> OtherRobots {
        OtherRobots {
            robots: self
                .robots
                .iter()
                .map(|r| OtherRobot {
                    name: r.name.clone(),
                    radius: r.radius,
                    track: r.track.iter().map(|&(t, x, y)| (t + dt, x, y)).collect(),
                })
                .collect(),
            shielded: self.shielded,
        }
    }

    /// Every robot on the floor at `t`: (its index, position, radius).
    pub fn at(&self, t: f64) -> Vec<(usize, (f64, f64), f64)> {
        self.at_late(t, &[])
    }

    /// [`OtherRobots::at`] with robot `i` `late[i]` seconds behind its track (0 past the end).
    pub fn at_late(&self, t: f64, late: &[f64]) -> Vec<(usize, (f64, f64), f64)> {
        self.robots
            .iter()
            .enumerate()
            .filter_map(|(i, r)| {
                let late = late.get(i).copied().unwrap_or(0.0);
                r.position_at(t - late).map(|p| (i, p, r.radius))
            })
            .collect()
    }

    /// How late each robot is after the step from `t` to `t + dt`, given how late each was
    /// (`late`, updated): a shielded robot whose step would bring it within [`SHIELD_GAP_M`]
    /// of the disc at `xy` of `radius`, closing in, holds (one more `dt` late).
    pub fn hold_for(&self, late: &mut Vec<f64>, t: f64, dt: f64, xy: (f64, f64), radius: f64) {
        late.resize(self.robots.len(), 0.0);
        if !self.shielded {
            return;
        }
        for (r, late) in self.robots.iter().zip(late.iter_mut()) {
            let gap = |p: (f64, f64)| crate::norm(p.0 - xy.0, p.1 - xy.1) - r.radius - radius;
            if let (Some(now), Some(next)) =
                (r.position_at(t - *late), r.position_at(t + dt - *late))
                && gap(next) < SHIELD_GAP_M
                && gap(next) < gap(now)
            {
                *late += dt;
            }
        }
    }
}

/// The smallest gap between a disc at `(x, y)` of `radius` and the robots `at` (from
/// [`OtherRobots::at`]), with the nearest one's index; infinite with none.
pub fn clearance(
    at: &[(usize, (f64, f64), f64)],
    x: f64,
    y: f64,
    radius: f64,
) -> (f64, Option<usize>) {
    at.iter()
        .map(|&(i, (ox, oy), r)| (crate::norm(ox - x, oy - y) - r - radius, Some(i)))
        .fold(
            (f64::INFINITY, None),
            |best, c| if c.0 < best.0 { c } else { best },
        )
}

/// Shortens each range in `out` (beams from `origin` along unit world directions `dirs`) to
/// the nearest robot of `at` it meets.
pub fn occlude(
    at: &[(usize, (f64, f64), f64)],
    origin: (f64, f64),
    dirs: impl Iterator<Item = (f64, f64)>,
    out: &mut [f64],
) {
    if at.is_empty() {
        return;
    }
    for (d, range) in dirs.zip(out.iter_mut()) {
        for &(_, c, r) in at {
            if let Some(t) = crate::crowd::ray_circle(origin, d, c, r) {
                *range = range.min(t);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walker() -> OtherRobot {
        OtherRobot {
            name: "r".into(),
            radius: 0.2,
            track: vec![(1.0, 0.0, 0.0), (3.0, 2.0, 0.0)],
        }
    }

    #[test]
    fn a_robot_is_on_the_floor_from_its_first_sample_to_its_last() {
        let r = walker();
        assert_eq!(r.position_at(0.9), None);
        assert_eq!(r.position_at(1.0), Some((0.0, 0.0)));
        assert_eq!(r.position_at(2.0), Some((1.0, 0.0)));
        assert_eq!(r.position_at(3.0), Some((2.0, 0.0)));
        assert_eq!(r.position_at(3.1), None);
    }

    #[test]
    fn a_shielded_robot_holds_before_it_touches_one_standing_in_its_track() {
        // The walker drives along y = 0 through a robot of radius 0.3 standing at (1.5, 0).
        let drive = |others: &OtherRobots| {
            let mut late = Vec::new();
            let mut closest = f64::INFINITY;
            let dt = 0.1;
            for k in 10..40 {
                let t = f64::from(k) * dt;
                others.hold_for(&mut late, t, dt, (1.5, 0.0), 0.3);
                for (_, (x, y), r) in others.at_late(t + dt, &late) {
                    closest = closest.min(crate::norm(x - 1.5, y) - r - 0.3);
                }
            }
            (closest, late[0])
        };
        let scripted = OtherRobots::new(vec![walker()]).unwrap();
        let (closest, late) = drive(&scripted);
        assert!(closest < 0.0, "it drives through: {closest}");
        assert_eq!(late, 0.0);
        let (closest, late) = drive(&scripted.clone().shielded());
        assert!(
            (0.0..SHIELD_GAP_M).contains(&closest),
            "it stops short: {closest}"
        );
        assert!(late > 1.5, "and is late on its track from then on: {late}");
    }

    #[test]
    fn the_nearest_robot_and_the_laser_see_it() {
        let others = OtherRobots::new(vec![walker()]).unwrap();
        let at = others.at(2.0);
        let (gap, which) = clearance(&at, 1.0, 1.0, 0.3);
        assert!((gap - 0.5).abs() < 1e-9, "{gap}");
        assert_eq!(which, Some(0));
        let mut ranges = [10.0, 10.0];
        occlude(
            &at,
            (1.0, 2.0),
            [(0.0, -1.0), (0.0, 1.0)].into_iter(),
            &mut ranges,
        );
        assert!((ranges[0] - 1.8).abs() < 1e-9, "{ranges:?}");
        assert_eq!(ranges[1], 10.0);
    }

    #[test]
    fn bad_tracks_are_refused_naming_the_robot() {
        let mut r = walker();
        r.track.reverse();
        assert!(OtherRobots::new(vec![r]).unwrap_err().contains("go back"));
        let mut r = walker();
        r.radius = 0.0;
        assert!(OtherRobots::new(vec![r]).unwrap_err().starts_with("r:"));
    }
}
