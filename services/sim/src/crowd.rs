//! People in the mental simulation: upright cylinders that walk the floor's usual routes, go to
//! its attractors and linger there, or (where the knowledge names neither) walk between points
//! spread over the free region; they avoid each other and the robot with ORCA (van den Berg et
//! al. 2011, "Reciprocal n-Body Collision Avoidance", through the `dodgy_2d` crate) and keep off
//! walls by walking the shortest path through the free region ([`PathField`]) and sliding along
//! what they touch.
//!
//! A person's radius and walking speed are drawn per person from [`PeopleConfig`]'s ranges. The
//! defaults: radius 0.2–0.3 m (half a shoulder breadth plus the swing of the arms; Fruin's
//! "body ellipse" of 0.6 m × 0.45 m), speed 0.6–1.3 m/s (indoor walking; the free walking speed
//! outdoors averages 1.34 m/s, Weidmann 1993). People share the avoidance of the robot with it,
//! as ORCA's reciprocity assumes ([`PeopleConfig::yield_to_robot`] = 0.5), and keep 0.15 m of
//! personal space from it; a robot standing still they walk round on their own. A robot that
//! drives on without reacting can still be walked into. Someone who makes no headway for a few
//! seconds (a robot waiting in a corridor too narrow to pass, a knot of people) turns back, as
//! people do, rather than shuffling on the spot: on a route the way they came, otherwise to the
//! target whose way leads most directly away.
//!
//! Everything is deterministic for a seed: people draw from their own generator, and the
//! avoidance is computed for all people from the same state before anyone moves.

use std::borrow::Cow;
use std::sync::{Arc, Mutex, OnceLock, PoisonError, Weak};

use dodgy_2d::{Agent, AvoidanceOptions, Vec2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::field::PathField;
use crate::world::World;

/// The most people in one simulation.
pub const MAX_PEOPLE: usize = 1000;

/// Coarse cell of the people's path fields, metres (as the training reward's).
const FIELD_CELL_M: f64 = 0.2;

/// Points spread over the free region for people to walk between where the knowledge names no
/// route or attractor (and for people who are not on one).
const WANDER_TARGETS: usize = 16;

/// A person is at a target within this distance, metres.
const ARRIVAL_M: f64 = 0.4;

/// Other people and the robot farther than this are not considered by a person's avoidance.
const NEIGHBOUR_M: f64 = 5.0;

/// Kept between a person's bound on the room to walls and their radius before the world is
/// asked again, metres (the wall clearance is exact to the grid's cell corners, not beyond).
const ROOM_SLACK_M: f64 = 0.02;

/// Room people keep from the robot beyond touching, metres (ORCA alone lets agents pass at a
/// hair's breadth).
const PERSONAL_SPACE_M: f64 = 0.15;

/// A robot slower than this stands still to the people about it, m/s.
const ROBOT_STANDING_MS: f64 = 0.05;

/// How far right of the way ahead people walk, radians.
const KEEP_RIGHT_RAD: f64 = 0.1;

/// A person who has made no headway for this long picks another target, seconds: someone
/// who cannot get past (a robot waiting in a corridor, a knot of people) turns away rather
/// than shuffling on the spot for ever.
const STUCK_S: f64 = 4.0;

/// Slower than this share of their own walking speed, a person makes no headway.
const HEADWAY_SHARE: f64 = 0.25;

/// People as the simulation draws them.
#[derive(Clone, Debug, PartialEq)]
pub struct PeopleConfig {
    /// People per 100 m² of the free region (0: none), used unless `count` is given.
    pub density: f64,
    /// An exact number of people, instead of the density.
    pub count: Option<usize>,
    /// Range of radii, metres (min, max).
    pub radius: (f64, f64),
    /// Range of walking speeds, m/s (min, max).
    pub speed: (f64, f64),
    /// The share of the avoidance between a person and the robot the person takes on: 0.5 is
    /// ORCA's reciprocal sharing, 1 a person who does all of it, 0 one who ignores the robot.
    pub yield_to_robot: f64,
    /// How far ahead people look for collisions, seconds (ORCA's time horizon).
    pub time_horizon: f64,
    /// No person spawns closer than this to the robot's start, metres (beyond both radii).
    pub spawn_clearance: f64,
}

impl Default for PeopleConfig {
    fn default() -> Self {
        Self {
            density: 0.0,
            count: None,
            radius: (0.2, 0.3),
            speed: (0.6, 1.3),
            yield_to_robot: 0.5,
            time_horizon: 2.0,
            spawn_clearance: 1.0,
        }
    }
}

impl PeopleConfig {
    /// How many people a world of `free_area_m2` square metres of free region gets.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a rounded non-negative product, capped at MAX_PEOPLE"
    )]
    pub fn count_for(&self, free_area_m2: f64) -> usize {
        match self.count {
            Some(n) => n.min(MAX_PEOPLE),
            None if self.density > 0.0 && free_area_m2 > 0.0 => {
                ((self.density * free_area_m2 / 100.0).round() as usize).min(MAX_PEOPLE)
            }
            None => 0,
        }
    }

    /// Whether any person could be drawn.
    pub fn any(&self) -> bool {
        self.count.map_or(self.density > 0.0, |n| n > 0)
    }

    /// A problem with a setting, named by field; `None` when all are in range.
    pub fn problem(&self) -> Option<(&'static str, String)> {
        let range = |(a, b): (f64, f64)| a.is_finite() && b.is_finite() && 0.0 < a && a <= b;
        if !(self.density.is_finite() && self.density >= 0.0) {
            return Some((
                "people.density",
                format!(
                    "must be a finite number of people per 100 m², not negative, got {}",
                    self.density
                ),
            ));
        }
        if self.count.is_some_and(|n| n > MAX_PEOPLE) {
            return Some((
                "people.count",
                format!("at most {MAX_PEOPLE} people, got {:?}", self.count),
            ));
        }
        if !range(self.radius) {
            return Some((
                "people.radius",
                format!("need 0 < min <= max, got {:?}", self.radius),
            ));
        }
        if !range(self.speed) {
            return Some((
                "people.speed",
                format!("need 0 < min <= max, got {:?}", self.speed),
            ));
        }
        if !(0.0..=1.0).contains(&self.yield_to_robot) {
            return Some((
                "people.yield_to_robot",
                format!("a share in [0, 1], got {}", self.yield_to_robot),
            ));
        }
        if !(self.time_horizon.is_finite() && self.time_horizon > 0.0) {
            return Some((
                "people.time_horizon",
                format!("must be positive, got {}", self.time_horizon),
            ));
        }
        if !(self.spawn_clearance.is_finite() && self.spawn_clearance >= 0.0) {
            return Some((
                "people.spawn_clearance",
                format!("must be finite, not negative, got {}", self.spawn_clearance),
            ));
        }
        None
    }
}

/// Where people walk in one world: the knowledge's routes and attractors, snapped into the
/// free region, and points spread over it; each with its path field, computed when first
/// needed and shared by every simulation of the world, and by every world alike (the same
/// geometry, free region and knowledge of people: the worlds of robots of one model on one
/// floor, which the service builds one per robot).
///
/// A floor's path field is a Dijkstra over its whole free region: on a 100 m floor each costs
/// milliseconds and megabytes, and a crowd needs one per target it walks to. Computed once per
/// robot, they were a third of a fleet's planning time (`bench fleet`, 20 robots on one floor).
#[derive(Debug)]
pub struct Targets {
    points: Vec<(f64, f64)>,
    fields: Vec<OnceLock<PathField>>,
    /// Routes as target indices, in walking order.
    routes: Vec<Vec<usize>>,
    /// Attractors: target index and dwell time, seconds.
    attractors: Vec<(usize, f64)>,
    /// Targets of people on neither.
    wander: Vec<usize>,
}

impl Targets {
    /// The targets of `world` (see [`World::people_targets`]).
    pub(crate) fn new(world: &World) -> Targets {
        let mut points: Vec<(f64, f64)> = Vec::new();
        let mut snap = |p: [f64; 2]| -> Option<usize> {
            let q = if world.in_free_region(p[0], p[1]) {
                (p[0], p[1])
            } else {
                world.nearest_free_point(p[0], p[1])?
            };
            points.push(q);
            Some(points.len() - 1)
        };
        let people = &world.spec().people;
        let routes: Vec<Vec<usize>> = people
            .routes
            .iter()
            .map(|r| r.points.iter().filter_map(|p| snap(*p)).collect::<Vec<_>>())
            .filter(|r| r.len() >= 2)
            .collect();
        let attractors: Vec<(usize, f64)> = people
            .attractors
            .iter()
            .filter_map(|a| Some((snap(a.position)?, a.dwell_s.max(0.0))))
            .collect();
        let wander = spread_points(world, WANDER_TARGETS)
            .into_iter()
            .filter_map(|p| snap([p.0, p.1]))
            .collect();
        let fields = points.iter().map(|_| OnceLock::new()).collect();
        Targets {
            points,
            fields,
            routes,
            attractors,
            wander,
        }
    }

    /// The targets of `world`, shared with every world alike still alive (see [`Targets`]).
    pub(crate) fn shared(world: &World) -> Arc<Targets> {
        type Key = ((String, u64), String);
        static SHARED: Mutex<Vec<(Key, Weak<Targets>)>> = Mutex::new(Vec::new());
        let key = (world.region_key(), format!("{:?}", world.spec().people));
        let mut shared = SHARED.lock().unwrap_or_else(PoisonError::into_inner);
        shared.retain(|(_, targets)| targets.strong_count() > 0);
        if let Some(targets) = shared
            .iter()
            .find(|(k, _)| *k == key)
            .and_then(|(_, targets)| targets.upgrade())
        {
            return targets;
        }
        let targets = Arc::new(Targets::new(world));
        shared.push((key, Arc::downgrade(&targets)));
        targets
    }

    fn field(&self, world: &World, target: usize) -> &PathField {
        self.fields[target].get_or_init(|| PathField::new(world, self.points[target], FIELD_CELL_M))
    }

    /// Makes every target's path field now (in parallel), so no later step pays for one.
    pub fn prepare(&self, world: &World) {
        use rayon::prelude::*;
        (0..self.points.len()).into_par_iter().for_each(|i| {
            self.field(world, i);
        });
    }

    /// Every target point, metres.
    pub fn points(&self) -> &[(f64, f64)] {
        &self.points
    }

    /// A round through `stops` of the wander targets (people on neither a route nor an
    /// attractor walk between them), from the `first`-th on in turn and back to it, each leg
    /// the shortest way through the free region, as points about `spacing_m` apart: where such
    /// a walker goes, for a trajectory given ahead of time (an SDF actor). Empty with fewer than
    /// two wander targets.
    pub fn wander_round(
        &self,
        world: &World,
        first: usize,
        stops: usize,
        spacing_m: f64,
    ) -> Vec<(f64, f64)> {
        let n = self.wander.len();
        if n < 2 || stops < 2 {
            return Vec::new();
        }
        let order: Vec<usize> = (0..=stops.min(n))
            .map(|k| self.wander[(first + k % stops.min(n)) % n])
            .collect();
        let mut out = vec![self.points[order[0]]];
        for leg in order.windows(2) {
            let (goal, field) = (self.points[leg[1]], self.field(world, leg[1]));
            let mut at = *out.last().unwrap_or(&goal);
            let mut since = 0.0;
            // A leg crosses at most every coarse cell once; the bound only guards the loop.
            for _ in 0..100_000 {
                let next = field.lookahead(at.0, at.1).unwrap_or(goal);
                since += norm(next.0 - at.0, next.1 - at.1);
                at = next;
                if at == goal {
                    break;
                }
                if since >= spacing_m {
                    out.push(at);
                    since = 0.0;
                }
            }
            out.push(goal);
        }
        out
    }
}

/// `n` points of the free region far from each other: farthest-point sampling over a fixed
/// draw of candidates, so a world always gets the same points.
fn spread_points(world: &World, n: usize) -> Vec<(f64, f64)> {
    let cells = world.free_region().len();
    if cells == 0 || n == 0 {
        return Vec::new();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(0x7065_6f70_6c65);
    let candidates: Vec<(f64, f64)> = (0..(n * 32))
        .filter_map(|_| {
            let pick = rng.random_range(0..cells);
            world.region_point(pick, rng.random(), rng.random())
        })
        .filter(|p| world.clearance(p.0, p.1) > 0.0)
        .collect();
    let Some(&first) = candidates.first() else {
        return Vec::new();
    };
    let mut chosen = vec![first];
    let mut nearest: Vec<f64> = candidates
        .iter()
        .map(|c| (c.0 - first.0).hypot(c.1 - first.1))
        .collect();
    while chosen.len() < n {
        let Some((i, d)) = nearest
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        if d <= 0.0 {
            break;
        }
        let p = candidates[i];
        chosen.push(p);
        for (c, m) in candidates.iter().zip(nearest.iter_mut()) {
            *m = m.min((c.0 - p.0).hypot(c.1 - p.1));
        }
    }
    chosen
}

/// What a person is doing.
#[derive(Copy, Clone, Debug, PartialEq)]
enum Plan {
    /// Walking to a spread-out target.
    Wander { target: usize },
    /// Walking a route: towards its point `index`, forwards or back.
    Route {
        route: usize,
        index: usize,
        forward: bool,
    },
    /// Walking to an attractor, then lingering there.
    Attractor { attractor: usize },
}

/// One person.
#[derive(Clone, Debug, PartialEq)]
pub struct Person {
    /// Position, metres.
    pub position: (f64, f64),
    /// Velocity, m/s.
    pub velocity: (f64, f64),
    /// Radius, metres.
    pub radius: f64,
    /// Preferred walking speed, m/s.
    pub speed: f64,
    plan: Plan,
    /// Seconds left to linger at an attractor.
    dwell: f64,
    /// Seconds without moving.
    stuck: f64,
    /// A lower bound on the room to walls and objects at `position`, metres: room is
    /// 1-Lipschitz, so a step of length `l` lowers it by at most `l`, and the world is asked
    /// again only when the bound gets close to the radius.
    room: f64,
}

/// The robot as people see it.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct RobotDisc {
    /// Position, metres.
    pub position: (f64, f64),
    /// Velocity, m/s.
    pub velocity: (f64, f64),
    /// Footprint radius, metres.
    pub radius: f64,
}

/// The people of one simulation.
#[derive(Clone, Debug)]
pub struct Crowd {
    config: PeopleConfig,
    targets: Arc<Targets>,
    people: Vec<Person>,
    rng: ChaCha8Rng,
}

impl Crowd {
    /// No one yet, in `world`; people draw from `seed`.
    pub fn new(world: &World, config: PeopleConfig, seed: u64) -> Crowd {
        Crowd {
            config,
            targets: Arc::clone(world.people_targets()),
            people: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// The settings.
    pub fn config(&self) -> &PeopleConfig {
        &self.config
    }

    /// Changes the settings; takes effect at the next [`Crowd::spawn`].
    pub fn set_config(&mut self, config: PeopleConfig) {
        self.config = config;
    }

    /// The people.
    pub fn people(&self) -> &[Person] {
        &self.people
    }

    /// Replaces everyone with the configured number of people, each where they and the robot
    /// at `robot` both fit, apart from each other; people who find no such place after a
    /// bounded search are left out (a full floor).
    pub fn spawn(&mut self, world: &World, robot: RobotDisc) {
        self.people.clear();
        let n = self.config.count_for(world.free_region_area_m2());
        let cells = world.free_region().len();
        if n == 0 || cells == 0 {
            return;
        }
        let t = Arc::clone(&self.targets);
        let cfg = self.config.clone();
        for k in 0..n {
            let radius = draw(&mut self.rng, cfg.radius);
            let speed = draw(&mut self.rng, cfg.speed);
            let plan = self.first_plan(&t, k);
            for _ in 0..64 {
                let pick = self.rng.random_range(0..cells);
                let Some(p) = world.region_point(pick, self.rng.random(), self.rng.random()) else {
                    break;
                };
                let near_robot = (p.0 - robot.position.0).hypot(p.1 - robot.position.1)
                    < robot.radius + radius + cfg.spawn_clearance;
                let near_person = self.people.iter().any(|q| {
                    (p.0 - q.position.0).hypot(p.1 - q.position.1) < q.radius + radius + 0.1
                });
                let room = wall_room(world, p);
                if near_robot || near_person || room < radius {
                    continue;
                }
                self.people.push(Person {
                    position: p,
                    velocity: (0.0, 0.0),
                    radius,
                    speed,
                    plan,
                    dwell: 0.0,
                    stuck: 0.0,
                    room,
                });
                break;
            }
        }
    }

    /// The first plan of person `k`: routes and attractors first (the knowledge's), in turn,
    /// with a third of people wandering when either exists, everyone when neither does.
    fn first_plan(&mut self, t: &Targets, k: usize) -> Plan {
        let known = t.routes.len() + t.attractors.len();
        if known > 0 && (k % 3 != 2 || t.wander.is_empty()) {
            let i = self.rng.random_range(0..known);
            if i < t.routes.len() {
                let len = t.routes[i].len();
                return Plan::Route {
                    route: i,
                    index: self.rng.random_range(0..len),
                    forward: self.rng.random(),
                };
            }
            return Plan::Attractor {
                attractor: i - t.routes.len(),
            };
        }
        self.wander_plan(t, None)
    }

    fn wander_plan(&mut self, t: &Targets, not: Option<usize>) -> Plan {
        if t.wander.is_empty() {
            return Plan::Wander { target: 0 };
        }
        let mut target = t.wander[self.rng.random_range(0..t.wander.len())];
        if Some(target) == not && t.wander.len() > 1 {
            target = t.wander
                [(t.wander.iter().position(|&w| w == target).unwrap_or(0) + 1) % t.wander.len()];
        }
        Plan::Wander { target }
    }

    fn target_of(t: &Targets, plan: Plan) -> Option<usize> {
        match plan {
            Plan::Wander { target } => t.points.get(target).map(|_| target),
            Plan::Route { route, index, .. } => t.routes.get(route)?.get(index).copied(),
            Plan::Attractor { attractor } => t.attractors.get(attractor).map(|a| a.0),
        }
    }

    /// The plan of someone who made no headway towards `blocked_target` from `at`: on a route,
    /// back the way they came; otherwise the wander target whose way from here leads most
    /// directly away from the blocked one (ties to the nearer in the points' order).
    fn turn_back(
        &mut self,
        world: &World,
        t: &Targets,
        plan: Plan,
        at: (f64, f64),
        blocked_target: usize,
    ) -> Plan {
        if let Plan::Route {
            route,
            index,
            forward,
        } = plan
        {
            let len = t.routes[route].len();
            let index = if forward {
                index.saturating_sub(1)
            } else {
                (index + 1).min(len - 1)
            };
            return Plan::Route {
                route,
                index,
                forward: !forward,
            };
        }
        let heading = |target: usize| {
            let goal = t.points[target];
            let ahead = t
                .field(world, target)
                .lookahead_quick(at.0, at.1)
                .unwrap_or(goal);
            let (dx, dy) = (ahead.0 - at.0, ahead.1 - at.1);
            let d = norm(dx, dy);
            (d > 1e-9).then(|| (dx / d, dy / d))
        };
        let Some(blocked) = heading(blocked_target) else {
            return self.wander_plan(t, Some(blocked_target));
        };
        let away = t
            .wander
            .iter()
            .copied()
            .filter(|&w| w != blocked_target)
            .filter_map(|w| heading(w).map(|h| (w, h.0 * blocked.0 + h.1 * blocked.1)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match away {
            Some((target, _)) => Plan::Wander { target },
            None => self.wander_plan(t, Some(blocked_target)),
        }
    }

    /// The plan after arriving (or giving up).
    fn next_plan(&mut self, t: &Targets, plan: Plan) -> Plan {
        match plan {
            Plan::Route {
                route,
                index,
                forward,
            } => {
                let len = t.routes[route].len();
                let (index, forward) = match (forward, index) {
                    (true, i) if i + 1 < len => (i + 1, true),
                    (true, i) => (i.saturating_sub(1), false),
                    (false, 0) => (1.min(len - 1), true),
                    (false, i) => (i - 1, false),
                };
                Plan::Route {
                    route,
                    index,
                    forward,
                }
            }
            Plan::Attractor { attractor } => {
                // After lingering: another attractor or a walk.
                if t.attractors.len() > 1 && self.rng.random::<bool>() {
                    Plan::Attractor {
                        attractor: (attractor
                            + 1
                            + self.rng.random_range(0..t.attractors.len() - 1))
                            % t.attractors.len(),
                    }
                } else {
                    let here = t.attractors[attractor].0;
                    self.wander_plan(t, Some(here))
                }
            }
            Plan::Wander { target } => self.wander_plan(t, Some(target)),
        }
    }

    /// Moves everyone on by `dt` seconds around the robot.
    pub fn step(&mut self, world: &World, robot: RobotDisc, dt: f64) {
        if self.people.is_empty() {
            return;
        }
        let t = Arc::clone(&self.targets);
        // Preferred velocities, and plans moved on by arrivals.
        let mut preferred = Vec::with_capacity(self.people.len());
        for i in 0..self.people.len() {
            preferred.push(self.preferred_velocity(world, &t, i, dt));
        }
        let velocities = self.avoiding_velocities(robot, &preferred, dt);
        // Move, sliding along walls.
        for (p, v) in self.people.iter_mut().zip(velocities) {
            walk(world, robot, p, v, dt);
        }
    }

    /// Person `i`'s preferred velocity this step: towards their target along its path field,
    /// slowing over the last metre, or none while they linger. Moves their plan on when they
    /// arrive, finish lingering or are stuck.
    fn preferred_velocity(&mut self, world: &World, t: &Targets, i: usize, dt: f64) -> (f64, f64) {
        let mut p = self.people[i].clone();
        if p.dwell > 0.0 {
            p.dwell -= dt;
            if p.dwell <= 0.0 {
                p.plan = self.next_plan(t, p.plan);
            }
            self.people[i] = p;
            return (0.0, 0.0);
        }
        let Some(mut target) = Crowd::target_of(t, p.plan) else {
            return (0.0, 0.0);
        };
        let goal = t.points[target];
        let stuck = p.stuck > STUCK_S;
        if norm(goal.0 - p.position.0, goal.1 - p.position.1) < ARRIVAL_M || stuck {
            if let (Plan::Attractor { attractor }, false) = (p.plan, stuck) {
                p.dwell = t.attractors[attractor].1;
            }
            p.stuck = 0.0;
            if stuck {
                p.plan = self.turn_back(world, t, p.plan, p.position, target);
            } else if p.dwell <= 0.0 {
                p.plan = self.next_plan(t, p.plan);
            }
            match Crowd::target_of(t, p.plan) {
                Some(next) if p.dwell <= 0.0 => target = next,
                _ => {
                    self.people[i] = p;
                    return (0.0, 0.0);
                }
            }
        }
        let goal = t.points[target];
        let ahead = t
            .field(world, target)
            .lookahead_quick(p.position.0, p.position.1)
            .unwrap_or(goal);
        let (dx, dy) = (ahead.0 - p.position.0, ahead.1 - p.position.1);
        let d = norm(dx, dy);
        let left = norm(goal.0 - p.position.0, goal.1 - p.position.1);
        // Slow down over the last metre, as people do.
        let speed = p.speed * left.clamp(0.3, 1.0);
        let velocity = if d > 1e-9 {
            // Keep right, a little: two people walking the same line head-on would
            // otherwise meet exactly, where ORCA has no side to prefer and both stop.
            let (s, c) = (-KEEP_RIGHT_RAD).sin_cos();
            let (ux, uy) = (dx / d, dy / d);
            ((c * ux - s * uy) * speed, (s * ux + c * uy) * speed)
        } else {
            (0.0, 0.0)
        };
        self.people[i] = p;
        velocity
    }

    /// Everyone's velocity this step: ORCA's answer to their `preferred` velocities among the
    /// people within [`NEIGHBOUR_M`] and the robot, all from the same state.
    fn avoiding_velocities(
        &self,
        robot: RobotDisc,
        preferred: &[(f64, f64)],
        dt: f64,
    ) -> Vec<(f64, f64)> {
        let cfg = &self.config;
        let options = AvoidanceOptions {
            obstacle_margin: 0.0,
            time_horizon: f32_of(cfg.time_horizon),
            obstacle_time_horizon: f32_of(cfg.time_horizon),
        };
        let robot_agent = self.robot_agent(robot);
        let agents: Vec<Agent> = self
            .people
            .iter()
            .map(|p| Agent {
                position: vec2(p.position),
                velocity: vec2(p.velocity),
                radius: f32_of(p.radius),
                avoidance_responsibility: 1.0,
            })
            .collect();
        let mut velocities = Vec::with_capacity(self.people.len());
        let mut neighbours: Vec<Cow<'_, Agent>> = Vec::new();
        // Positions side by side: the search below reads every one for every person.
        let positions: Vec<(f64, f64)> = self.people.iter().map(|p| p.position).collect();
        for (i, (p, pref)) in self.people.iter().zip(preferred).enumerate() {
            neighbours.clear();
            let near = |q: (f64, f64)| {
                let (dx, dy) = (q.0 - p.position.0, q.1 - p.position.1);
                dx * dx + dy * dy < NEIGHBOUR_M * NEIGHBOUR_M
            };
            for (j, q) in positions.iter().enumerate() {
                if j != i && near(*q) {
                    neighbours.push(Cow::Borrowed(&agents[j]));
                }
            }
            if cfg.yield_to_robot > 0.0 && near(robot.position) {
                neighbours.push(Cow::Borrowed(&robot_agent));
            }
            if neighbours.is_empty() {
                // No one to avoid: the preferred velocity, as ORCA would return it.
                velocities.push(*pref);
                continue;
            }
            let v = agents[i].compute_avoiding_velocity(
                &neighbours,
                &[],
                vec2(*pref),
                f32_of(p.speed),
                f32_of(dt),
                &options,
            );
            let v = (f64::from(v.x), f64::from(v.y));
            velocities.push(if v.0.is_finite() && v.1.is_finite() {
                v
            } else {
                (0.0, 0.0)
            });
        }
        velocities
    }

    /// The robot as an ORCA agent, its disc grown by people's personal space. A person takes
    /// `yield` of the avoidance with a moving robot (responsibility p / (p + r)), and all of it
    /// with one standing still, which takes none.
    fn robot_agent(&self, robot: RobotDisc) -> Agent {
        let cfg = &self.config;
        let standing = robot.velocity.0.hypot(robot.velocity.1) < ROBOT_STANDING_MS;
        let robot_share = if cfg.yield_to_robot <= 0.0 {
            f32::MAX
        } else if standing {
            0.0
        } else {
            f32_of((1.0 - cfg.yield_to_robot) / cfg.yield_to_robot)
        };
        Agent {
            position: vec2(robot.position),
            velocity: vec2(robot.velocity),
            radius: f32_of(robot.radius + PERSONAL_SPACE_M),
            avoidance_responsibility: robot_share.max(1e-6),
        }
    }

    /// Shortens each range in `out` (beams from `origin` along unit world directions `dirs`)
    /// to the nearest person it meets.
    pub fn occlude(
        &self,
        origin: (f64, f64),
        dirs: impl Iterator<Item = (f64, f64)>,
        out: &mut [f64],
    ) {
        if self.people.is_empty() {
            return;
        }
        // Only people nearer than the longest beam can shorten one.
        let reach = out.iter().copied().fold(0.0, f64::max);
        let near: Vec<&Person> = self
            .people
            .iter()
            .filter(|p| norm(p.position.0 - origin.0, p.position.1 - origin.1) - p.radius < reach)
            .collect();
        if near.is_empty() {
            return;
        }
        for ((dx, dy), range) in dirs.zip(out.iter_mut()) {
            for p in &near {
                if let Some(t) = ray_circle(origin, (dx, dy), p.position, p.radius) {
                    *range = range.min(t);
                }
            }
        }
    }

    /// The smallest gap between a disc at `(x, y)` of `radius` and any person, metres
    /// (negative when they overlap); infinite with no one about.
    pub fn clearance(&self, x: f64, y: f64, radius: f64) -> f64 {
        self.people
            .iter()
            .map(|p| {
                let (dx, dy) = (p.position.0 - x, p.position.1 - y);
                (dx * dx + dy * dy).sqrt() - p.radius - radius
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// Distance along a ray from `o` in unit direction `d` to the circle, if it meets it ahead (0
/// from inside).
pub(crate) fn ray_circle(o: (f64, f64), d: (f64, f64), c: (f64, f64), r: f64) -> Option<f64> {
    let (fx, fy) = (o.0 - c.0, o.1 - c.1);
    let b = fx * d.0 + fy * d.1;
    let cc = fx * fx + fy * fy - r * r;
    if cc <= 0.0 {
        return Some(0.0);
    }
    if b >= 0.0 {
        return None;
    }
    let disc = b * b - cc;
    (disc >= 0.0).then(|| -b - disc.sqrt())
}

/// Moves person `p` on by `dt` seconds at velocity `v`, sliding along a wall it would come too
/// close to (but not, within the robot's personal space, nearer the robot), and counts the time
/// they have been held back.
fn walk(world: &World, robot: RobotDisc, p: &mut Person, v: (f64, f64), dt: f64) {
    let from = p.position;
    let candidates = [
        (from.0 + v.0 * dt, from.1 + v.1 * dt),
        (from.0 + v.0 * dt, from.1),
        (from.0, from.1 + v.1 * dt),
    ];
    let step = norm(v.0, v.1) * dt;
    let (to, room) = if p.room - step - ROOM_SLACK_M >= p.radius {
        (candidates[0], p.room - step)
    } else {
        // A slide along a wall is not the velocity ORCA chose: it may not take the
        // person nearer the robot once within its personal space.
        let gap = |q: (f64, f64)| {
            norm(q.0 - robot.position.0, q.1 - robot.position.1) - robot.radius - p.radius
        };
        let keep = gap(from).min(PERSONAL_SPACE_M);
        candidates
            .into_iter()
            .enumerate()
            .map(|(k, c)| (k, c, wall_room(world, c)))
            .find(|(k, c, room)| *room >= p.radius && (*k == 0 || gap(*c) >= keep))
            .map_or((from, p.room), |(_, c, room)| (c, room))
    };
    p.room = room;
    p.velocity = ((to.0 - from.0) / dt, (to.1 - from.1) / dt);
    let moved = norm(to.0 - from.0, to.1 - from.1);
    if p.dwell <= 0.0 && moved < HEADWAY_SHARE * p.speed * dt {
        p.stuck += dt;
    } else {
        p.stuck = 0.0;
    }
    p.position = to;
}

/// Room around a point to walls and objects, metres (the robot's footprint clearance plus its
/// radius).
fn wall_room(world: &World, p: (f64, f64)) -> f64 {
    world.clearance(p.0, p.1) + world.spec().robot.footprint_radius
}

/// Length of `(dx, dy)`: `sqrt` is several times faster than libm's `hypot`, and the
/// distances here are far from overflow.
#[inline]
fn norm(dx: f64, dy: f64) -> f64 {
    (dx * dx + dy * dy).sqrt()
}

fn draw(rng: &mut ChaCha8Rng, (a, b): (f64, f64)) -> f64 {
    if b > a { rng.random_range(a..=b) } else { a }
}

#[allow(
    clippy::cast_possible_truncation,
    reason = "positions and speeds in metres fit f32, which the avoidance works in"
)]
fn f32_of(v: f64) -> f32 {
    v as f32
}

fn vec2(v: (f64, f64)) -> Vec2 {
    Vec2::new(f32_of(v.0), f32_of(v.1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_meets_circle_at_its_near_side() {
        let t = ray_circle((0.0, 0.0), (1.0, 0.0), (5.0, 0.0), 0.5).unwrap();
        assert!((t - 4.5).abs() < 1e-12);
        assert_eq!(ray_circle((0.0, 0.0), (-1.0, 0.0), (5.0, 0.0), 0.5), None);
        assert_eq!(ray_circle((0.0, 0.0), (0.0, 1.0), (5.0, 0.0), 0.5), None);
        assert_eq!(
            ray_circle((5.0, 0.1), (0.0, 1.0), (5.0, 0.0), 0.5),
            Some(0.0)
        );
    }

    #[test]
    fn density_gives_a_count() {
        let c = PeopleConfig {
            density: 2.0,
            ..PeopleConfig::default()
        };
        assert_eq!(c.count_for(250.0), 5);
        assert_eq!(PeopleConfig::default().count_for(250.0), 0);
        assert!(!PeopleConfig::default().any());
        let fixed = PeopleConfig {
            count: Some(3),
            ..c
        };
        assert_eq!(fixed.count_for(0.0), 3);
        assert!(
            PeopleConfig {
                density: -1.0,
                ..PeopleConfig::default()
            }
            .problem()
            .is_some_and(|(f, _)| f == "people.density")
        );
    }
}
