//! The collision shield: a monitor between a controller and the motors that keeps a round
//! differential robot from driving into what its laser sees. The rehearsal executor runs the
//! policy behind it, and training can run behind it too, so that a policy learns what the
//! shield will do to its commands.

use crate::{Action, Observation, Pose2, World};

/// Closest the shield lets the footprint come to a laser return, metres (the simulation counts
/// a collision below 0.02 m).
pub const SHIELD_MARGIN_M: f64 = 0.06;
/// How far ahead the shield looks, seconds of the commanded motion.
pub const SHIELD_HORIZON_S: f64 = 1.5;
/// Forward speeds the shield tries, as shares of the wanted one, fastest first.
const SHIELD_SCALES: [f64; 6] = [1.0, 0.7, 0.45, 0.25, 0.1, 0.0];
/// Time step of the shield's look-ahead, seconds.
const SHIELD_STEP_S: f64 = 0.1;
/// Consecutive returns farther apart than this belong to different things, metres.
const CLUSTER_GAP_M: f64 = 0.3;
/// Things wider than this are taken to stand still (walls, shelves), metres: a person seen by
/// the laser spans half a metre or so.
const MOVER_MAX_WIDTH_M: f64 = 0.9;
/// A thing seen in two consecutive scans has moved at most this far between them, metres (a
/// brisk walk for one control period, plus the centroid's noise).
const MOVER_MAX_STEP_M: f64 = 0.35;
/// Estimated speeds below this are the laser's noise, m/s.
const MOVER_MIN_SPEED: f64 = 0.25;
/// Estimated speeds are capped at this, m/s.
const MOVER_MAX_SPEED: f64 = 2.0;
/// Weight of a new velocity measurement in the running estimate.
const MOVER_SMOOTHING: f64 = 0.5;
/// Closest [`Shield::filter_follower`] lets the footprint come to a wall, metres (the
/// simulation counts a collision below 0.02 m).
pub const WALL_GUARD_M: f64 = 0.03;
/// How far ahead [`Shield::filter_follower`] looks for walls, seconds: the last moment.
pub const WALL_GUARD_S: f64 = 0.3;
/// A return farther than this from every wall and object the map knows is something the map
/// does not know (a person, most likely), metres: a few grid cells plus the laser's noise.
const UNKNOWN_M: f64 = 0.15;
/// A return whose room beyond its margin exceeds what the look-ahead can eat of it by more
/// than this is left out of the look-ahead, metres (more than the 1 mm the test allows).
const FAR_SLACK_M: f64 = 0.01;
/// Closest the shield lets the footprint come to a return the map does not know, metres: a
/// person may step or turn between two scans, and the laser samples a body's curve only at
/// its beams.
pub const PERSON_MARGIN_M: f64 = 0.12;

/// A collision monitor for a differential robot with a round footprint: it rolls the wanted
/// command forward for [`SHIELD_HORIZON_S`] against the current laser returns and keeps the
/// fastest share of its forward speed that never brings the footprint closer than
/// [`SHIELD_MARGIN_M`] to a return it is approaching (moving along a wall, or away from it,
/// stays allowed), nor closer than [`PERSON_MARGIN_M`] to one the map does not know (after
/// [`Shield::observe_on_map`]: people, rolled forward as they move). When even a crawl is unsafe the robot stops and turns on the spot (a
/// round robot cannot hit anything turning in place): towards the waypoint when it is off to
/// one side, else towards the side the laser sees more room on.
#[derive(Clone, Debug)]
pub struct Shield {
    /// The laser's origin in the robot frame, metres.
    origin: (f64, f64),
    /// Unit directions of the beams in the robot frame.
    dirs: Vec<(f64, f64)>,
    /// Returns at or beyond this range hit nothing.
    range_max: f64,
    /// The widest angle between neighbouring beams, radians (clustering's gap grows with it).
    spacing: f64,
    /// The footprint's radius, metres.
    radius: f64,
    /// What moves, from consecutive scans ([`Shield::observe`]); empty for a shield that only
    /// ever sees single scans.
    motion: Motion,
    /// Buffers [`Shield::observe`] reuses from scan to scan (it runs every control step).
    scratch: Scratch,
    /// The drive's linear acceleration and deceleration, m/s², when its model has them: the
    /// look-ahead then brakes as the drive can, and always ends at rest.
    braking: Option<(f64, f64)>,
    /// How often the shield found it could no longer stop short of its margins (blocked while
    /// moving too fast to stop in the room left): [`Shield::could_not_stop`].
    short_stops: std::cell::Cell<u32>,
}

/// Working buffers of one [`Shield::observe`]: kept between scans, so a scan allocates nothing.
#[derive(Clone, Debug, Default)]
struct Scratch {
    points: Vec<Option<(f64, f64)>>,
    unknown: Vec<bool>,
    clusters: Vec<(usize, usize)>,
    previous: Vec<Mover>,
}

/// A small thing a scan saw: its centroid and velocity, in that scan's robot frame.
type Mover = ((f64, f64), (f64, f64));

/// Things the laser sees move, from consecutive scans.
#[derive(Clone, Debug, Default)]
struct Motion {
    /// The last scan's small clusters: centroid and velocity in that scan's robot frame.
    last: Vec<Mover>,
    /// Velocity of each of the current scan's returns (beam order, returns only), robot frame.
    velocities: Vec<(f64, f64)>,
    /// Whether each of the current scan's returns is something the map does not know (all
    /// `false` without a map: [`Shield::observe`]).
    unknown: Vec<bool>,
}

/// A laser return as the shield's look-ahead treats it.
#[derive(Copy, Clone, Debug)]
struct Return {
    at: (f64, f64),
    velocity: (f64, f64),
    /// Something the map does not know: kept [`PERSON_MARGIN_M`] from, and, when it moves,
    /// avoided anywhere between where it is and where it would be (a walker may stop).
    unknown: bool,
}

/// The robot's motion since the last scan, from odometry: what turns the last scan's frame into
/// this one's.
struct EgoMotion {
    /// Where the robot is now in the last scan's frame.
    mx: f64,
    my: f64,
    /// Sine and cosine of minus its turn.
    s: f64,
    c: f64,
}

impl EgoMotion {
    /// The motion over `dt` seconds at the velocity `obs` reports.
    fn of(obs: &Observation, dt: f64) -> Self {
        let (v, w) = (f64::from(obs.velocity[0]), f64::from(obs.velocity[1]));
        let dtheta = w * dt;
        let (mx, my) = (v * dt * (dtheta / 2.0).cos(), v * dt * (dtheta / 2.0).sin());
        let (s, c) = (-dtheta).sin_cos();
        Self { mx, my, s, c }
    }

    /// A point of the last scan's frame in this one's.
    fn to_now(&self, p: (f64, f64)) -> (f64, f64) {
        let (x, y) = (p.0 - self.mx, p.1 - self.my);
        (self.c * x - self.s * y, self.s * x + self.c * y)
    }

    /// A direction of the last scan's frame in this one's.
    fn rotate(&self, u: (f64, f64)) -> (f64, f64) {
        (self.c * u.0 - self.s * u.1, self.s * u.0 + self.c * u.1)
    }
}

/// Which returns the map does not explain (all `false` without a map).
fn unknown_into(
    points: &[Option<(f64, f64)>],
    map: Option<(Pose2, &World)>,
    unknown: &mut Vec<bool>,
) {
    unknown.clear();
    match map {
        Some((pose, world)) => {
            let (sy, cy) = pose.yaw.sin_cos();
            unknown.extend(points.iter().map(|p| {
                p.is_some_and(|(x, y)| {
                    let (wx, wy) = (pose.x + cy * x - sy * y, pose.y + sy * x + cy * y);
                    !world.knows_within(wx, wy, UNKNOWN_M)
                })
            }));
        }
        None => unknown.resize(points.len(), false),
    }
}

/// The returns of the cluster of `len` beams from `start` (all present: a missing one ends a
/// cluster).
fn members(
    points: &[Option<(f64, f64)>],
    start: usize,
    len: usize,
) -> impl Iterator<Item = &(f64, f64)> {
    points[start..start + len].iter().flatten()
}

/// The centroid of a cluster's returns.
fn centroid(points: &[Option<(f64, f64)>], start: usize, len: usize) -> (f64, f64) {
    let n = len as f64;
    (
        members(points, start, len).map(|p| p.0).sum::<f64>() / n,
        members(points, start, len).map(|p| p.1).sum::<f64>() / n,
    )
}

/// The smoothed velocity of a small thing at `centroid`, from the nearest of the last scan's
/// (`previous`: centroid and velocity, in this scan's frame) when it is near enough to be the
/// same thing, capped at [`MOVER_MAX_SPEED`]; else standing.
fn matched_velocity(previous: &[Mover], centroid: (f64, f64), dt: f64) -> (f64, f64) {
    let mut velocity = (0.0, 0.0);
    let nearest = previous.iter().min_by(|a, b| {
        let d = |q: &(f64, f64)| crate::norm(q.0 - centroid.0, q.1 - centroid.1);
        d(&a.0).total_cmp(&d(&b.0))
    });
    if let Some((q, u)) = nearest
        && crate::norm(q.0 - centroid.0, q.1 - centroid.1) <= MOVER_MAX_STEP_M
    {
        let raw = ((centroid.0 - q.0) / dt, (centroid.1 - q.1) / dt);
        let k = MOVER_SMOOTHING;
        velocity = (k * raw.0 + (1.0 - k) * u.0, k * raw.1 + (1.0 - k) * u.1);
        let speed = crate::norm(velocity.0, velocity.1);
        if speed > MOVER_MAX_SPEED {
            velocity = (
                velocity.0 * MOVER_MAX_SPEED / speed,
                velocity.1 * MOVER_MAX_SPEED / speed,
            );
        }
    }
    velocity
}

impl Shield {
    /// The shield for the robot of `world` reading `beams` beams; `None` when its laser cannot
    /// give them.
    pub fn new(world: &World, beams: usize) -> Option<Self> {
        let robot = &world.spec().robot;
        let laser = &robot.laser;
        let dirs: Vec<(f64, f64)> = laser
            .beam_angles(beams)?
            .into_iter()
            .map(|a| ((a + laser.mount.yaw).cos(), (a + laser.mount.yaw).sin()))
            .collect();
        Some(Self {
            origin: (laser.mount.x, laser.mount.y),
            spacing: beam_spacing(&dirs),
            dirs,
            range_max: laser.range_max,
            radius: robot.footprint_radius,
            motion: Motion::default(),
            scratch: Scratch::default(),
            braking: braking_of(&robot.drive),
            short_stops: std::cell::Cell::new(0),
        })
    }

    /// How many times, since it was made, the shield was blocked while the robot was moving
    /// too fast to stop short of its margins with the drive's deceleration: each a moment the
    /// stop it commanded could not be kept (the drive brakes no harder than it can).
    pub fn could_not_stop(&self) -> u32 {
        self.short_stops.get()
    }

    /// Distance the robot covers braking from `speed` to rest with the drive's deceleration,
    /// metres (0 without one).
    pub fn braking_distance(&self, speed: f64) -> f64 {
        self.braking.map_or(0.0, |(_, b)| speed * speed / (2.0 * b))
    }

    /// Takes in a new scan `dt` seconds after the last one, so the shield knows what moves:
    /// consecutive returns cluster into things; a thing narrower than a person's reach is
    /// matched with the nearest one of the last scan (moved by the robot's own motion, from
    /// the odometry in `obs`), and its velocity is the smoothed displacement of its centroid.
    /// [`Shield::filter`] and [`Shield::keeps_margin`] then roll such returns forward with
    /// their velocity. Wide things (walls) and things seen once stand still.
    pub fn observe(&mut self, obs: &Observation, dt: f64) {
        self.observe_with(obs, dt, None);
    }

    /// [`Shield::observe`] for a robot at `pose` on the map of `world`: the returns the map
    /// explains (walls, known objects) stand still, and everything else counts as a possible
    /// person, whatever its shape and wherever it stands (beside a wall, too): only those are
    /// tracked, kept [`PERSON_MARGIN_M`] from, and seen by [`Shield::filter_follower`].
    pub fn observe_on_map(&mut self, obs: &Observation, dt: f64, pose: Pose2, world: &World) {
        self.observe_with(obs, dt, Some((pose, world)));
    }

    fn observe_with(&mut self, obs: &Observation, dt: f64, map: Option<(Pose2, &World)>) {
        let Scratch {
            mut points,
            mut unknown,
            mut clusters,
            mut previous,
        } = std::mem::take(&mut self.scratch);
        self.points_into(obs, &mut points);
        unknown_into(&points, map, &mut unknown);
        self.clusters_into(&points, &unknown, map.is_some(), &mut clusters);
        let ego = EgoMotion::of(obs, dt);
        // The last scan's buffers are refilled with this one's.
        let Motion {
            last: mut now_small,
            mut velocities,
            unknown: mut unknown_returns,
        } = std::mem::take(&mut self.motion);
        previous.clear();
        previous.extend(
            now_small
                .iter()
                .map(|(p, u)| (ego.to_now(*p), ego.rotate(*u))),
        );
        now_small.clear();
        velocities.clear();
        for &(start, len) in &clusters {
            let (Some(first), Some(end)) = (points[start], points[start + len - 1]) else {
                continue;
            };
            let small = if map.is_some() {
                unknown[start]
            } else {
                crate::norm(first.0 - end.0, first.1 - end.1) <= MOVER_MAX_WIDTH_M
                    && self.in_front(&points, start, len)
            };
            let centroid = centroid(&points, start, len);
            let mut velocity = (0.0, 0.0);
            if small && dt > 0.0 {
                velocity = matched_velocity(&previous, centroid, dt);
                now_small.push((centroid, velocity));
            }
            let moving = crate::norm(velocity.0, velocity.1) >= MOVER_MIN_SPEED;
            velocities.extend(std::iter::repeat_n(
                if moving { velocity } else { (0.0, 0.0) },
                len,
            ));
        }
        unknown_returns.clear();
        unknown_returns.extend(
            unknown
                .iter()
                .zip(&points)
                .filter(|(_, p)| p.is_some())
                .map(|(u, _)| *u),
        );
        self.scratch = Scratch {
            points,
            unknown,
            clusters,
            previous,
        };
        self.motion = Motion {
            last: now_small,
            velocities,
            unknown: unknown_returns,
        };
    }

    /// The scan's returns in the robot frame, in beam order (`None` where a beam hit nothing).
    fn points_into(&self, obs: &Observation, points: &mut Vec<Option<(f64, f64)>>) {
        points.clear();
        points.extend(obs.ranges.iter().zip(&self.dirs).map(|(r, (c, s))| {
            let r = f64::from(*r);
            (r < self.range_max - 1e-3).then(|| (self.origin.0 + r * c, self.origin.1 + r * s))
        }));
    }

    /// Clusters: runs of returns with no gap between neighbours. Far away, neighbouring beams
    /// hit one surface further apart than a gap near by: the gap allowed grows with the spacing
    /// of the beams there, so a wall stays one (wide) thing. A cluster is a run of consecutive
    /// beams (a beam without a return ends it): its first beam and its length. `on_map`, what
    /// the map knows and what it does not are different things.
    fn clusters_into(
        &self,
        points: &[Option<(f64, f64)>],
        unknown: &[bool],
        on_map: bool,
        clusters: &mut Vec<(usize, usize)>,
    ) {
        let spacing = self.spacing;
        clusters.clear();
        let mut last: Option<(f64, f64)> = None;
        for (i, p) in points.iter().enumerate() {
            let gap_allowed = |p: (f64, f64)| {
                let r = self.range_of(p);
                CLUSTER_GAP_M.max(1.5 * r * spacing)
            };
            let same_kind = i > 0 && unknown[i] == unknown[i - 1];
            match (p, last) {
                (Some(p), Some(q))
                    if (!on_map || same_kind)
                        && crate::norm(p.0 - q.0, p.1 - q.1) <= gap_allowed(*p) =>
                {
                    if let Some((_, len)) = clusters.last_mut() {
                        *len += 1;
                    }
                }
                (Some(_), _) => clusters.push((i, 1)),
                (None, _) => {}
            }
            last = *p;
        }
    }

    /// Distance of a point in the robot frame from the laser.
    fn range_of(&self, p: (f64, f64)) -> f64 {
        crate::norm(p.0 - self.origin.0, p.1 - self.origin.1)
    }

    /// Whether the cluster of `len` returns from beam `first` is a thing in front of what is
    /// behind it: the beams either side of it reach farther (or nothing). The end of a wall
    /// seen at a grazing angle is not: the wall goes on nearer on one side.
    fn in_front(&self, points: &[Option<(f64, f64)>], first: usize, len: usize) -> bool {
        let near = members(points, first, len)
            .map(|p| self.range_of(*p))
            .fold(f64::INFINITY, f64::min);
        let beyond = |j: Option<usize>| {
            j.and_then(|j| points.get(j).copied().flatten())
                .is_none_or(|q| self.range_of(q) > near + CLUSTER_GAP_M)
        };
        beyond(first.checked_sub(1)) && beyond(Some(first + len))
    }

    /// Forgets what it saw move (a new drive).
    pub fn reset_motion(&mut self) {
        self.motion = Motion::default();
    }

    /// The laser returns in the robot frame, with what the last [`Shield::observe`] learnt of
    /// them when it was of this scan (else all standing, all known).
    fn returns(&self, obs: &Observation) -> Vec<Return> {
        let mut out: Vec<Return> = obs
            .ranges
            .iter()
            .zip(&self.dirs)
            .filter(|(r, _)| f64::from(**r) < self.range_max - 1e-3)
            .map(|(r, (c, s))| {
                let r = f64::from(*r);
                Return {
                    at: (self.origin.0 + r * c, self.origin.1 + r * s),
                    velocity: (0.0, 0.0),
                    unknown: false,
                }
            })
            .collect();
        let m = &self.motion;
        if m.velocities.len() == out.len() && m.unknown.len() == out.len() {
            for ((p, v), u) in out.iter_mut().zip(&m.velocities).zip(&m.unknown) {
                p.velocity = *v;
                p.unknown = *u;
            }
        }
        out
    }

    /// Whether the laser sees a return the map does not know (a person) within `gap` metres
    /// of the footprint (as of the last [`Shield::observe_on_map`] of this scan).
    pub fn sees_unknown_within(&self, obs: &Observation, gap: f64) -> bool {
        self.returns(obs)
            .iter()
            .any(|p| p.unknown && crate::norm(p.at.0, p.at.1) - self.radius < gap)
    }

    /// Whether anything the shield sees is moving.
    pub fn sees_motion(&self) -> bool {
        self.motion
            .velocities
            .iter()
            .any(|v| v.0 != 0.0 || v.1 != 0.0)
    }

    /// Whether driving `command` for the horizon keeps the footprint `margin` clear of what
    /// the laser sees (returns it is not approaching excepted; unknown ones at least
    /// [`PERSON_MARGIN_M`]), as the shield checks its own margin.
    pub fn keeps_margin(&self, command: Action, obs: &Observation, margin: f64) -> bool {
        let points = self.returns(obs);
        points.is_empty() || self.keeps(command, &points, margin)
    }

    /// Whether driving `command` for [`SHIELD_HORIZON_S`] keeps the footprint clear of
    /// `points`: `margin` from known returns and at least [`PERSON_MARGIN_M`] from unknown ones,
    /// unless it is not getting any closer to them than it is now (driving along a wall). A
    /// moving return is rolled forward with its velocity, and since a walker may stop at any
    /// moment, the whole stretch it would walk counts, not only where it would be.
    /// The command is held at a constant speed: with a braking tail the fleet benches' crossing
    /// and doorway deadlocked, so the braking look-ahead only says when the robot could no
    /// longer stop ([`Shield::could_not_stop`]).
    fn keeps(&self, command: Action, points: &[Return], margin: f64) -> bool {
        self.keeps_for(command, points, margin, SHIELD_HORIZON_S, None)
    }

    /// [`Shield::keeps`] over `horizon_s` seconds.
    fn keeps_for(
        &self,
        command: Action,
        points: &[Return],
        margin: f64,
        horizon_s: f64,
        braking_from: Option<f64>,
    ) -> bool {
        let person_margin = margin.max(PERSON_MARGIN_M);
        let keep = |p: &Return| if p.unknown { person_margin } else { margin };
        // Over the horizon the footprint moves at most |linear| t and a return's stretch grows
        // by |velocity| t, so a return whose room now exceeds what both can eat by more than
        // `FAR_SLACK_M` never comes within a margin: it cannot decide below (it only ever adds
        // a positive room, and the test is for a negative one smaller than the room now).
        // Leaving such returns out is exact and spares most of them the look-ahead.
        let profile = self.speed_profile(command.linear, braking_from, horizon_s);
        let total_s = SHIELD_STEP_S * profile.len() as f64;
        let travel: f64 = profile.iter().map(|v| v.abs() * SHIELD_STEP_S).sum();
        let near: Vec<&Return> = points
            .iter()
            .filter(|p| {
                let reach =
                    travel + crate::norm(p.velocity.0, p.velocity.1) * total_s.min(horizon_s);
                crate::norm(p.at.0, p.at.1) - keep(p) - self.radius - reach <= FAR_SLACK_M
            })
            .collect();
        if near.is_empty() {
            return true;
        }
        // Room beyond the margins at (x, y) after t seconds: negative inside one. What moves is
        // predicted over the horizon only (the braking past it is the robot's own motion).
        let excess_at = |x: f64, y: f64, t: f64| {
            let t = t.min(horizon_s);
            near.iter()
                .map(|p| {
                    let ahead = (p.at.0 + p.velocity.0 * t, p.at.1 + p.velocity.1 * t);
                    segment_distance((x, y), p.at, ahead) - keep(p) - self.radius
                })
                .fold(f64::INFINITY, f64::min)
        };
        let now = excess_at(0.0, 0.0, 0.0);
        let (mut x, mut y, mut yaw) = (0.0_f64, 0.0_f64, 0.0_f64);
        let mut t = 0.0;
        for v in profile {
            x += v * yaw.cos() * SHIELD_STEP_S;
            y += v * yaw.sin() * SHIELD_STEP_S;
            yaw += command.angular * SHIELD_STEP_S;
            t += SHIELD_STEP_S;
            let e = excess_at(x, y, t);
            if e < 0.0 && e < now - 1e-3 {
                return false;
            }
        }
        true
    }

    /// The forward speed of each look-ahead step for `command` from speed `v0`: the command's
    /// for the horizon without a deceleration limit; with one, the command's (or slowing down
    /// to it from a faster `v0`) for the horizon, then braking to rest.
    fn speed_profile(&self, command: f64, braking_from: Option<f64>, horizon_s: f64) -> Vec<f64> {
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "the horizon is a few seconds, the braking time bounded by speed / decel"
        )]
        let steps = |s: f64| (s / SHIELD_STEP_S - 1e-9).ceil().max(1.0) as usize;
        let (Some((_, b)), Some(v0)) = (self.braking, braking_from) else {
            return vec![command; steps(horizon_s)];
        };
        // Held for the whole horizon at the command's speed, or slowing down to it no faster
        // than the drive brakes when faster now; then braking to rest.
        let mut out = Vec::with_capacity(steps(horizon_s) + 32);
        let mut v = v0.max(0.0);
        for _ in 0..steps(horizon_s) {
            v = if v > command {
                (v - b * SHIELD_STEP_S).max(command)
            } else {
                command
            };
            out.push(v);
        }
        // Brake to rest (bounded: at most speed / decel of them).
        while v.abs() > 1e-9 && out.len() < 1000 {
            v = (v.abs() - b * SHIELD_STEP_S).max(0.0).copysign(v);
            out.push(v);
        }
        out
    }

    /// The fastest share of `wanted`'s forward speed that keeps the shield's margins from
    /// `points`, `None` when not even a crawl does.
    fn fastest_safe(&self, wanted: Action, points: &[Return]) -> Option<Action> {
        SHIELD_SCALES
            .into_iter()
            .filter(|scale| *scale > 0.0)
            .map(|scale| Action {
                linear: wanted.linear * scale,
                angular: wanted.angular,
            })
            .find(|command| self.keeps(*command, points, SHIELD_MARGIN_M))
    }

    /// Blocked (not even a crawl keeps the margins): counts it when braking from `v0` does not
    /// keep them either, the robot too fast to stop in the room it has.
    fn note_blocked(&self, points: &[Return], v0: f64) {
        if self.braking.is_some()
            && v0 > 0.0
            && !self.keeps_for(
                Action::new(0.0, 0.0),
                points,
                SHIELD_MARGIN_M,
                SHIELD_HORIZON_S,
                Some(v0),
            )
        {
            self.short_stops
                .set(self.short_stops.get().saturating_add(1));
        }
    }

    /// `wanted` for a controller that keeps to the map's free space on its own, as a path
    /// follower on a roadmap does, at `pose` on the map of `world`: held back by what the map
    /// does not know (the returns the last [`Shield::observe_on_map`] found unexplained) as
    /// [`Shield::filter`] holds back, and by the map's walls and objects only at the last
    /// moment (the footprint within [`WALL_GUARD_M`] over the next [`WALL_GUARD_S`], on any
    /// side, seen by the laser or not), so a tight spot never stalls it; where it may not go
    /// on, it stops, turning as wanted (which a round robot may).
    pub fn filter_follower(
        &self,
        wanted: Action,
        obs: &Observation,
        pose: Pose2,
        world: &World,
    ) -> Action {
        if wanted.linear <= 0.0 {
            return wanted;
        }
        let stop = Action {
            linear: 0.0,
            angular: wanted.angular,
        };
        let people: Vec<Return> = self
            .returns(obs)
            .into_iter()
            .filter(|p| p.unknown)
            .collect();
        let held = if people.is_empty() {
            wanted
        } else {
            match self.fastest_safe(wanted, &people) {
                Some(command) => command,
                None => {
                    self.note_blocked(&people, current_speed(obs));
                    return stop;
                }
            }
        };
        // The last moment, on the map: the arc of the command, every control step.
        let now = world.clearance(pose.x, pose.y);
        let mut p = pose;
        let mut t = 0.0;
        while t < WALL_GUARD_S - 1e-9 {
            p = crate::kinematics::integrate(p, held, SHIELD_STEP_S / 2.0);
            t += SHIELD_STEP_S / 2.0;
            let c = world.clearance(p.x, p.y);
            if c < WALL_GUARD_M && c < now - 1e-3 {
                return stop;
            }
        }
        held
    }

    /// The command to send instead of `wanted`, given the observation and the angular limit.
    pub fn filter(&self, wanted: Action, obs: &Observation, angular_max: f64) -> Action {
        if wanted.linear <= 0.0 {
            return wanted;
        }
        let points = self.returns(obs);
        if points.is_empty() {
            return wanted;
        }
        if let Some(command) = self.fastest_safe(wanted, &points) {
            return command;
        }
        self.note_blocked(&points, current_speed(obs));
        // Blocked: turn in place, towards the waypoint when it is to one side, else towards
        // the side with more room.
        let bearing = f64::from(obs.goal_angle);
        let side = if bearing.abs() > 0.2 {
            bearing.signum()
        } else {
            let room = |left: bool| -> f64 {
                obs.ranges
                    .iter()
                    .zip(&self.dirs)
                    .filter(|(_, (_, s))| (*s > 0.0) == left)
                    .map(|(r, _)| f64::from(*r))
                    .sum()
            };
            if room(true) >= room(false) { 1.0 } else { -1.0 }
        };
        Action {
            linear: 0.0,
            angular: side * angular_max,
        }
    }
}

/// The robot's forward speed now, from the odometry in `obs`.
fn current_speed(obs: &Observation) -> f64 {
    f64::from(obs.velocity[0])
}

/// The linear acceleration and deceleration of `drive`, when its model gives either.
fn braking_of(drive: &crate::spec::DiffDriveSpec) -> Option<(f64, f64)> {
    let a = drive.max_linear_acceleration.filter(|a| *a > 0.0);
    let b = drive.max_linear_deceleration.filter(|b| *b > 0.0).or(a);
    match (a, b) {
        (None, None) => None,
        (a, b) => Some((a.unwrap_or(f64::INFINITY), b.unwrap_or(f64::INFINITY))),
    }
}

/// The widest angle between neighbouring beam directions, radians.
fn beam_spacing(dirs: &[(f64, f64)]) -> f64 {
    dirs.windows(2)
        .map(|w| (w[0].0 * w[1].0 + w[0].1 * w[1].1).clamp(-1.0, 1.0).acos())
        .fold(0.0, f64::max)
}

/// Distance from `p` to the segment from `a` to `b`.
fn segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (ex, ey) = (a.0 + t * dx - p.0, a.1 + t * dy - p.1);
    (ex * ex + ey * ey).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn obs() -> Observation {
        Observation {
            ranges: vec![5.0; 23],
            goal_distance: 1.0,
            goal_angle: 0.0,
            velocity: [0.0; 2],
        }
    }

    /// A shield for a 0.2 m robot with 23 beams over the front half, laser at the centre.
    fn shield() -> Shield {
        let dirs: Vec<(f64, f64)> = (0..23)
            .map(|i| {
                let a = -PI / 2.0 + PI * f64::from(i) / 22.0;
                (a.cos(), a.sin())
            })
            .collect();
        Shield {
            origin: (0.0, 0.0),
            spacing: beam_spacing(&dirs),
            dirs,
            range_max: 10.0,
            radius: 0.2,
            motion: Motion::default(),
            scratch: Scratch::default(),
            braking: None,
            short_stops: std::cell::Cell::new(0),
        }
    }

    /// The ranges a laser at the origin sees with a wall `ahead` metres in front (x = ahead)
    /// and one `left` metres to the left (y = left), each `None` for no wall.
    #[allow(clippy::cast_possible_truncation, reason = "test ranges are small")]
    fn scan(s: &Shield, ahead: Option<f64>, left: Option<f64>) -> Observation {
        let ranges = s
            .dirs
            .iter()
            .map(|&(c, sn)| {
                let hit_ahead = ahead.filter(|_| c > 1e-9).map(|d| d / c);
                let hit_left = left.filter(|_| sn > 1e-9).map(|d| d / sn);
                [hit_ahead, hit_left]
                    .into_iter()
                    .flatten()
                    .fold(10.0_f64, f64::min) as f32
            })
            .collect();
        Observation { ranges, ..obs() }
    }

    #[test]
    fn the_shield_slows_and_stops_before_a_wall_but_not_along_one() {
        let s = shield();
        let go = Action::new(0.8, 0.0);
        // Open space: unchanged.
        assert_eq!(s.filter(go, &scan(&s, None, None), 0.5), go);
        // A wall 3 m ahead: 0.8 m/s for 1.5 s stays 1.6 m short of it.
        assert_eq!(s.filter(go, &scan(&s, Some(3.0), None), 0.5), go);
        // 1 m ahead: slower, still forward.
        let slowed = s.filter(go, &scan(&s, Some(1.0), None), 0.5);
        assert!(slowed.linear > 0.0 && slowed.linear < 0.8, "{slowed:?}");
        // 0.25 m ahead (5 cm from the footprint): stop and turn in place.
        let stopped = s.filter(go, &scan(&s, Some(0.25), None), 0.5);
        assert_eq!(stopped.linear, 0.0);
        assert_eq!(stopped.angular.abs(), 0.5);
        // Along a wall 4 cm from the footprint: driving parallel does not approach it.
        assert_eq!(s.filter(go, &scan(&s, None, Some(0.24)), 0.5), go);
        // Turning in place and reversing pass untouched.
        let turn = Action::new(0.0, 0.5);
        assert_eq!(s.filter(turn, &scan(&s, Some(0.25), None), 0.5), turn);
        // Blocked with the waypoint to the right: turns right.
        let right = Observation {
            goal_angle: -1.0,
            ..scan(&s, Some(0.25), None)
        };
        assert_eq!(s.filter(go, &right, 0.5).angular, -0.5);
    }

    /// A person-sized thing straight ahead: returns 0.2 m wide at `distance`.
    #[allow(clippy::cast_possible_truncation, reason = "test ranges are small")]
    fn person_ahead(s: &Shield, distance: f64, velocity: [f32; 2]) -> Observation {
        let ranges = s
            .dirs
            .iter()
            .map(|&(c, sn)| {
                let hit = (c > 1e-9 && (distance / c * sn).abs() <= 0.1).then(|| distance / c);
                hit.unwrap_or(10.0) as f32
            })
            .collect();
        Observation {
            ranges,
            velocity,
            ..obs()
        }
    }

    #[test]
    fn the_shield_slows_for_someone_walking_at_it_that_a_single_scan_lets_pass() {
        let mut s = shield();
        let go = Action::new(0.5, 0.0);
        // Someone 2.0 m ahead: 0.5 m/s for 1.5 s stays 1.05 m short of them if they stand.
        let first = person_ahead(&s, 2.1, [0.5, 0.0]);
        assert_eq!(s.filter(go, &first, 0.5), go);
        s.observe(&first, 0.1);
        assert!(!s.sees_motion(), "one scan shows no motion");
        // 0.1 s later they are 0.15 m closer: 0.05 m of it the robot's own motion, 0.1 m theirs
        // (1 m/s towards the robot). Twice, so the smoothed estimate settles.
        let mut d = 2.1;
        for _ in 0..3 {
            d -= 0.15;
            let next = person_ahead(&s, d, [0.5, 0.0]);
            s.observe(&next, 0.1);
        }
        assert!(s.sees_motion());
        let now = person_ahead(&s, d, [0.5, 0.0]);
        let slowed = s.filter(go, &now, 0.5);
        assert!(slowed.linear < go.linear, "{slowed:?} at {d:.2} m");
        // The same scan on its own (a fresh shield): nothing moves, full speed.
        assert_eq!(shield().filter(go, &now, 0.5), go);
        // A wall is no mover: a wide thing approached at the robot's own speed stays still.
        let mut w = shield();
        for k in 0..4 {
            let wall = scan(&w, Some(3.0 - 0.05 * f64::from(k)), None);
            let wall = Observation {
                velocity: [0.5, 0.0],
                ..wall
            };
            w.observe(&wall, 0.1);
        }
        assert!(!w.sees_motion());
    }

    #[test]
    fn with_a_deceleration_limit_the_shield_slows_down_in_time_and_says_when_it_cannot_stop() {
        // A wall 2.5 m ahead, the robot at 0.8 m/s. Without limits the full speed keeps the
        // margin for the horizon (1.2 m) and stopping is instant.
        let free = shield();
        let obs = |s: &Shield, v: f32| Observation {
            velocity: [v, 0.0],
            ..scan(s, Some(2.5), None)
        };
        let go = Action::new(0.8, 0.0);
        assert_eq!(free.filter(go, &obs(&free, 0.8), 0.5), go);
        // Braking at 0.3 m/s² takes 1.07 m from 0.8 m/s: the shield must keep that room too.
        let braking = Shield {
            braking: Some((0.3, 0.3)),
            ..shield()
        };
        assert!((braking.braking_distance(0.8) - 0.8 * 0.8 / 0.6).abs() < 1e-12);
        assert_eq!(braking.filter(go, &obs(&braking, 0.8), 0.5), go);
        // 1.0 m ahead at 0.8 m/s: the shield decides as without the limit (slower).
        let late = Observation {
            velocity: [0.8, 0.0],
            ..scan(&braking, Some(1.0), None)
        };
        assert_eq!(braking.filter(go, &late, 0.5), free.filter(go, &late, 0.5));
        assert_eq!(braking.could_not_stop(), 0);
        // 0.3 m ahead at 0.8 m/s: blocked, and braking needs 1.07 m: counted.
        let blocked = Observation {
            velocity: [0.8, 0.0],
            ..scan(&braking, Some(0.3), None)
        };
        assert_eq!(braking.filter(go, &blocked, 0.5).linear, 0.0);
        assert_eq!(braking.could_not_stop(), 1);
        // Standing still inside its margin, it is blocked but not short of a stop.
        let standing = Observation {
            velocity: [0.0, 0.0],
            ..scan(&braking, Some(0.25), None)
        };
        assert_eq!(braking.filter(go, &standing, 0.5).linear, 0.0);
        assert_eq!(braking.could_not_stop(), 1);
    }
}
