//! The reinforcement-learning environment of the paper's §4.1.1: sparse laser ranges and the goal
//! as (r, θ) in, a velocity command out, the reward of Eq. 1, Gaussian noise on observations and
//! on executed commands; deterministic for a seed.

use std::f64::consts::PI;
use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::crowd::{Crowd, PeopleConfig, Person, RobotDisc};
use crate::field::PathField;
use crate::kinematics::{Action, CommandLimits, DiffDrive, wrap_angle};
use crate::others::OtherRobots;
use crate::spec::Pose2;
use crate::world::World;

mod step;

/// Coarse cell of the geodesic reward's path field, metres: four map cells at 5 cm, small
/// enough for doors, large enough that the field takes a few milliseconds per goal.
const PATH_FIELD_CELL_M: f64 = 0.2;

/// Standard deviations of the Gaussian noise (paper §4.1.1: "Gaussian errors to input and
/// output data"; the paper gives no values, these are ours).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct NoiseConfig {
    /// On each laser range, metres.
    pub range: f64,
    /// On the goal distance, metres.
    pub goal_distance: f64,
    /// On the goal angle, radians.
    pub goal_angle: f64,
    /// On the executed linear velocity, m/s (none on a zero command: standing still is exact).
    pub linear: f64,
    /// On the executed angular velocity, rad/s (none on a zero command).
    pub angular: f64,
}

impl Default for NoiseConfig {
    fn default() -> Self {
        Self {
            range: 0.02,
            goal_distance: 0.02,
            goal_angle: 0.01,
            linear: 0.02,
            angular: 0.02,
        }
    }
}

impl NoiseConfig {
    /// No noise at all.
    pub fn none() -> Self {
        Self {
            range: 0.0,
            goal_distance: 0.0,
            goal_angle: 0.0,
            linear: 0.0,
            angular: 0.0,
        }
    }
}

/// The constants of Eq. 1, all positive: `completion - t * time` on arrival at time `t` (seconds),
/// `closer` for a step that gets closer to the goal, `-collision` when too close to an obstacle,
/// and 0 otherwise.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct RewardConfig {
    /// r_completion.
    pub completion: f64,
    /// r_time, per second of the episode.
    pub time: f64,
    /// r_closer.
    pub closer: f64,
    /// r_collision.
    pub collision: f64,
    /// Pay `closer` in proportion to the distance gained in the step (the full amount for a
    /// step straight at the goal at top speed) and charge the same proportion for distance
    /// lost, instead of the paper's constant amount for any gain. With the constant, a robot
    /// that steps towards and away from the goal earns `closer` every other step without ever
    /// arriving — with γ = 0.99 that loitering is worth more than a 15-second drive to the
    /// goal, and TD3 finds it. The proportional form is potential-based shaping (Ng et al.
    /// 1999): it leaves the optimal policy unchanged.
    pub progress: bool,
    /// Charge `time` per second as the episode goes (`time × control period` every step) and
    /// pay `completion` alone on arrival, instead of `completion - t × time` on arrival only.
    /// A successful episode earns the same; one that never arrives pays for its time, so
    /// circling near the goal or standing still is no longer free.
    pub time_per_step: bool,
    /// With `progress`: also pay `closer × heading` in proportion to the bearing error removed
    /// in the step (the full amount for turning towards the goal at top angular speed) and
    /// charge it for bearing error added; potential-based too. The laser sees only ahead, so
    /// without it a goal behind the robot offers no reward for turning round, and a policy
    /// learns to stop and wait. 0 turns it off.
    pub heading: f64,
    /// With `progress`: measure progress along the shortest path through the free region
    /// ([`PathField`]) instead of in a straight line, and let the heading term point along that
    /// path. Potential-based like the straight form, but a detour round a wall to its door is
    /// progress instead of a loss. Costs one coarse Dijkstra per goal.
    pub geodesic: bool,
    /// Charged per second while the footprint is closer than [`CLEARANCE_BAND_M`] to an
    /// obstacle, in proportion to how far inside the band it is (the full amount at contact).
    /// Not potential-based, on purpose: it trades a little time for clearance, so a policy
    /// stops brushing past door frames. 0 turns it off.
    pub clearance: f64,
}

/// Clearance under which [`RewardConfig::clearance`] charges, metres: a little more than a
/// near miss (10 cm), so the charge starts before one.
pub const CLEARANCE_BAND_M: f64 = 0.15;

impl Default for RewardConfig {
    fn default() -> Self {
        Self {
            completion: 100.0,
            time: 1.0,
            closer: 0.5,
            collision: 100.0,
            progress: false,
            time_per_step: false,
            heading: 0.0,
            geodesic: false,
            clearance: 0.0,
        }
    }
}

/// Settings of an environment.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvConfig {
    /// Number of equally spaced laser readings in an observation (the paper: 23).
    pub beams: usize,
    /// Control period, seconds (the paper: 0.1).
    pub control_period: f64,
    /// Range of commands.
    pub limits: CommandLimits,
    /// Noise.
    pub noise: NoiseConfig,
    /// Reward constants.
    pub reward: RewardConfig,
    /// The goal is reached within this distance, metres.
    pub goal_tolerance: f64,
    /// "Too close to an obstacle": a footprint clearance below this is a collision, metres.
    pub collision_clearance: f64,
    /// Episodes end after this many steps.
    pub max_steps: u32,
    /// Distance range between start and goal for random resets, metres (min, max).
    pub goal_distance: (f64, f64),
    /// Random goals only where the robot can drive to them in a straight line
    /// ([`World::segment_clearance`] above `collision_clearance`), as between the waypoints
    /// of a roadmap plan; otherwise anywhere in the free region, also behind walls.
    pub goals_in_view: bool,
    /// Whether to keep the poses of the episode (for renders and plan validation).
    pub record_trajectory: bool,
    /// People walking about ([`crate::crowd`]); none by default.
    pub people: PeopleConfig,
    /// The policy sees, instead of the goal, the point this far along the shortest path to it
    /// (the goal once nearer; [`PathField::carrot`]): the carrot on the path that a plan's
    /// policy steers to, so that it learns to carry its speed round corners towards a goal it
    /// does not see. Needs the geodesic reward's field. None: the goal itself.
    pub carrot_m: Option<f64>,
}

impl Default for EnvConfig {
    fn default() -> Self {
        Self {
            beams: 23,
            control_period: 0.1,
            limits: CommandLimits::default(),
            noise: NoiseConfig::default(),
            reward: RewardConfig::default(),
            goal_tolerance: 0.3,
            collision_clearance: 0.02,
            max_steps: 500,
            goal_distance: (2.0, 10.0),
            goals_in_view: false,
            record_trajectory: false,
            people: PeopleConfig::default(),
            carrot_m: None,
        }
    }
}

/// What the policy sees.
#[derive(Clone, Debug, PartialEq)]
pub struct Observation {
    /// Laser ranges, metres, from the rightmost beam to the leftmost.
    pub ranges: Vec<f32>,
    /// Distance to the goal, metres.
    pub goal_distance: f32,
    /// Bearing of the goal in the robot frame, radians in (-π, π], counter-clockwise.
    pub goal_angle: f32,
    /// The robot's current velocity as odometry measures it: linear (m/s), angular (rad/s).
    pub velocity: [f32; 2],
}

impl Observation {
    /// Number of values: the ranges, the goal's two and the velocity's two.
    pub fn len(&self) -> usize {
        self.ranges.len() + 4
    }

    /// Whether there are no values (never: the goal is always there).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Ranges, goal distance and angle, then velocity, as one vector.
    pub fn to_vec(&self) -> Vec<f32> {
        let mut v = Vec::with_capacity(self.len());
        v.extend_from_slice(&self.ranges);
        v.push(self.goal_distance);
        v.push(self.goal_angle);
        v.extend_from_slice(&self.velocity);
        v
    }
}

/// How an episode stands after a step.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Outcome {
    /// Still going.
    Running,
    /// Within the goal tolerance.
    ReachedGoal,
    /// Too close to an obstacle.
    Collision,
    /// Out of steps (a truncation, not a failure of the policy).
    TimeLimit,
}

/// Details of a step beyond the reward.
#[derive(Clone, Debug, PartialEq)]
pub struct StepInfo {
    /// How the episode stands.
    pub outcome: Outcome,
    /// True pose after the step.
    pub pose: Pose2,
    /// The command as executed (after limits and noise).
    pub executed: Action,
    /// Smallest footprint clearance during the step, metres (see [`World::clearance`]).
    pub min_clearance: f64,
    /// True distance to the goal, metres.
    pub distance_to_goal: f64,
    /// Steps taken in this episode.
    pub steps: u32,
    /// Simulated time of this episode, seconds.
    pub time_s: f64,
    /// Smallest gap between the footprint and a person during the step, metres (infinite with
    /// no one about); a collision with a person when below the collision clearance.
    pub person_clearance: f64,
    /// Smallest gap between the footprint and another robot during the step, metres
    /// (infinite with none about; [`NavEnv::set_other_robots`]).
    pub robot_clearance: f64,
    /// The other robot nearest during the step (an index of [`OtherRobots::robots`]).
    pub nearest_robot: Option<usize>,
}

/// The result of [`NavEnv::step`].
#[derive(Clone, Debug, PartialEq)]
pub struct StepResult {
    /// The observation after the step.
    pub observation: Observation,
    /// Eq. 1.
    pub reward: f64,
    /// Whether the episode has ended (any outcome but `Running`).
    pub done: bool,
    /// Details.
    pub info: StepInfo,
    /// Set only by [`crate::EnvBatch`] with auto-reset: the first observation of the episode
    /// that started because this one ended.
    pub reset_observation: Option<Observation>,
}

/// Why an environment could not be made or reset.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EnvError {
    /// A setting is out of range.
    #[error("invalid environment setting `{field}`: {message}")]
    Config {
        /// The setting.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The start is not finite or the robot does not fit there.
    #[error(
        "the robot does not fit at the start ({x:.3}, {y:.3}): clearance {clearance:.3} m; nearest free point {nearest_free:?}"
    )]
    StartBlocked {
        /// Start x.
        x: f64,
        /// Start y.
        y: f64,
        /// Footprint clearance there, metres.
        clearance: f64,
        /// The nearest point of the free region, if any.
        nearest_free: Option<(f64, f64)>,
    },
    /// The goal is not finite or the robot does not fit there.
    #[error(
        "the goal ({x:.3}, {y:.3}) is inside an obstacle: the robot does not fit there; nearest free point {nearest_free:?}"
    )]
    GoalBlocked {
        /// Goal x.
        x: f64,
        /// Goal y.
        y: f64,
        /// The nearest point of the free region, if any.
        nearest_free: Option<(f64, f64)>,
    },
    /// The robot fits nowhere in the world.
    #[error("the world has no free region large enough for the robot")]
    NoFreeRegion,
    /// No goal in the requested distance range was found from the sampled starts.
    #[error("found no free goal between {min} and {max} m from a start in the free region")]
    NoGoalInRange {
        /// Smallest distance asked for.
        min: f64,
        /// Largest distance asked for.
        max: f64,
    },
}

/// A navigation environment in a shared world.
#[derive(Clone, Debug)]
pub struct NavEnv {
    world: Arc<World>,
    config: EnvConfig,
    drive: DiffDrive,
    /// (cos, sin) of each beam relative to the sensor.
    dirs: Vec<(f64, f64)>,
    rng: ChaCha8Rng,
    pose: Pose2,
    goal: (f64, f64),
    /// Where the robot stood when it got the current goal (the demonstrator's segment start).
    goal_from: (f64, f64),
    executed: Action,
    /// The last commands sent, newest last, while the robot model has a control latency: the
    /// wheels execute the one sent that long ago ([`NavEnv::delayed`]).
    pending: std::collections::VecDeque<Action>,
    steps: u32,
    distance: f64,
    outcome: Outcome,
    started: bool,
    ranges: Vec<f64>,
    trajectory: Vec<Pose2>,
    last_observation: Option<Observation>,
    /// The goal's path field, with `reward.geodesic`.
    field: Option<PathField>,
    /// The progress reward's potential at the current pose: path or straight distance, metres.
    potential: f64,
    /// People, when the configuration has any.
    crowd: Option<Crowd>,
    /// The people's own seed, so that they leave the robot's noise as it was without them.
    crowd_seed: u64,
    /// Smallest gap to a person in the last step.
    person_clearance: f64,
    /// Other robots moving along their tracks, when set.
    others: Option<Arc<OtherRobots>>,
    /// Smallest gap to another robot in the last step, and which.
    robot_clearance: (f64, Option<usize>),
    /// How late each other robot is on its track, seconds: shielded ones stop for this one.
    others_late: Vec<f64>,
}

/// Mixed into an environment's seed for its people's own generator, so that people leave the
/// robot's noise as it was without them.
const CROWD_STREAM: u64 = 0xc0ff_ee00_9e37_79b9;

impl NavEnv {
    /// An environment in `world` whose randomness all comes from `seed`.
    pub fn new(world: Arc<World>, config: EnvConfig, seed: u64) -> Result<NavEnv, EnvError> {
        check_config(&config)?;
        let laser = &world.spec().robot.laser;
        let angles = laser
            .beam_angles(config.beams)
            .ok_or_else(|| EnvError::Config {
                field: "beams",
                message: format!(
                    "{} beams cannot be picked from a laser with {} samples",
                    config.beams, laser.samples
                ),
            })?;
        let dirs = angles.iter().map(|a| (a.cos(), a.sin())).collect();
        let drive = DiffDrive::new(world.spec().robot.drive.clone());
        let crowd_seed = seed ^ CROWD_STREAM;
        let crowd = config
            .people
            .any()
            .then(|| Crowd::new(&world, config.people.clone(), crowd_seed));
        Ok(NavEnv {
            crowd,
            crowd_seed,
            person_clearance: f64::INFINITY,
            others: None,
            robot_clearance: (f64::INFINITY, None),
            others_late: Vec::new(),
            drive,
            dirs,
            rng: ChaCha8Rng::seed_from_u64(seed),
            pose: Pose2::new(0.0, 0.0, 0.0),
            goal: (0.0, 0.0),
            goal_from: (0.0, 0.0),
            executed: Action::default(),
            pending: std::collections::VecDeque::new(),
            steps: 0,
            distance: 0.0,
            outcome: Outcome::Running,
            started: false,
            ranges: vec![0.0; config.beams],
            trajectory: Vec::new(),
            last_observation: None,
            field: None,
            potential: 0.0,
            world,
            config,
        })
    }

    /// The world.
    pub fn world(&self) -> &Arc<World> {
        &self.world
    }

    /// The settings.
    pub fn config(&self) -> &EnvConfig {
        &self.config
    }

    /// Changes the distance range of random goals (a training curriculum widens it as the
    /// policy improves). Takes effect at the next random reset.
    pub fn set_goal_distance(&mut self, range: (f64, f64)) -> Result<(), EnvError> {
        let mut config = self.config.clone();
        config.goal_distance = range;
        check_config(&config)?;
        self.config = config;
        Ok(())
    }

    /// Changes who walks about (a training curriculum raises the density). Takes effect at the
    /// next reset; the people's generator is kept, so a run stays deterministic.
    pub fn set_people(&mut self, people: PeopleConfig) -> Result<(), EnvError> {
        let mut config = self.config.clone();
        config.people = people.clone();
        check_config(&config)?;
        self.config = config;
        match &mut self.crowd {
            Some(c) => c.set_config(people),
            None if people.any() => {
                self.crowd = Some(Crowd::new(&self.world, people, self.crowd_seed));
            }
            None => {}
        }
        Ok(())
    }

    /// Other robots on the floor, moving along their tracks on this episode's clock (seconds
    /// since the reset); `None` for none. Their footprints are seen by the laser, and touching
    /// one is a collision.
    pub fn set_other_robots(&mut self, others: Option<Arc<OtherRobots>>) {
        self.others = others.filter(|o| !o.is_empty());
        self.others_late.clear();
    }

    /// The other robots, when set.
    pub fn other_robots(&self) -> Option<&Arc<OtherRobots>> {
        self.others.as_ref()
    }

    /// The robot's footprint clearance at `(x, y)` now to what moves: the people about and
    /// the other robots where they are (metres, as [`crate::World::clearance`] is to walls and
    /// objects; infinite with neither).
    pub fn moving_clearance_at(&self, x: f64, y: f64) -> f64 {
        let radius = self.world.spec().robot.footprint_radius;
        let mut c = f64::INFINITY;
        if let Some(crowd) = &self.crowd {
            c = c.min(crowd.clearance(x, y, radius));
        }
        if let Some(others) = &self.others {
            let now = f64::from(self.steps) * self.config.control_period;
            let at = others.at_late(now, &self.others_late);
            c = c.min(crate::others::clearance(&at, x, y, radius).0);
        }
        c
    }

    /// The people about now (none without people in the configuration).
    pub fn people(&self) -> &[Person] {
        self.crowd.as_ref().map_or(&[], |c| c.people())
    }

    /// True pose of the robot.
    pub fn pose(&self) -> Pose2 {
        self.pose
    }

    /// The goal.
    pub fn goal(&self) -> (f64, f64) {
        self.goal
    }

    /// What the classical follower would command now, driving the straight segment from where
    /// the robot got its goal to the goal ([`crate::follow`]): the demonstrator of training.
    pub fn demonstration(&self, params: &crate::FollowerParams) -> Action {
        crate::follow(params, self.goal_from, self.goal, self.pose)
    }

    /// Poses of the current episode, when the configuration records them.
    pub fn trajectory(&self) -> &[Pose2] {
        &self.trajectory
    }

    /// Angles of the observation's beams relative to the laser, radians.
    pub fn beam_angles(&self) -> Vec<f64> {
        self.dirs.iter().map(|(c, s)| s.atan2(*c)).collect()
    }

    /// Starts an episode at `start` with goal `goal`.
    pub fn reset(&mut self, start: Pose2, goal: (f64, f64)) -> Result<Observation, EnvError> {
        let clearance = if start.x.is_finite() && start.y.is_finite() && start.yaw.is_finite() {
            self.world.clearance(start.x, start.y)
        } else {
            f64::NEG_INFINITY
        };
        // NaN clearance (a non-finite start) must be refused too: compare so NaN fails.
        if clearance
            .partial_cmp(&self.config.collision_clearance)
            .is_none_or(|o| o.is_lt())
        {
            return Err(EnvError::StartBlocked {
                x: start.x,
                y: start.y,
                clearance,
                nearest_free: self.world.nearest_free_point(start.x, start.y),
            });
        }
        let goal_ok =
            goal.0.is_finite() && goal.1.is_finite() && self.world.clearance(goal.0, goal.1) > 0.0;
        if !goal_ok {
            return Err(EnvError::GoalBlocked {
                x: goal.0,
                y: goal.1,
                nearest_free: self.world.nearest_free_point(goal.0, goal.1),
            });
        }
        Ok(self.begin(Pose2::new(start.x, start.y, wrap_angle(start.yaw)), goal))
    }

    /// Gives the episode a new goal (the next waypoint of a plan) and keeps the robot where it
    /// is: an episode that ended at its goal goes on; one that ended in a collision or out of
    /// time stays ended. Time and steps keep counting.
    pub fn set_goal(&mut self, goal: (f64, f64)) -> Result<Observation, EnvError> {
        let fits =
            goal.0.is_finite() && goal.1.is_finite() && self.world.clearance(goal.0, goal.1) > 0.0;
        if !fits {
            return Err(EnvError::GoalBlocked {
                x: goal.0,
                y: goal.1,
                nearest_free: self.world.nearest_free_point(goal.0, goal.1),
            });
        }
        self.goal = goal;
        self.goal_from = (self.pose.x, self.pose.y);
        self.distance = (goal.0 - self.pose.x).hypot(goal.1 - self.pose.y);
        self.refresh_field();
        if self.outcome == Outcome::ReachedGoal {
            self.outcome = Outcome::Running;
        }
        let obs = self.observe();
        self.remember(&obs);
        Ok(obs)
    }

    /// Sets the robot's velocity (clamped to the command limits) as if it were already moving,
    /// as a previous drive would leave it; returns the observation with that odometry.
    pub fn set_velocity(&mut self, velocity: Action) -> Observation {
        self.hold(self.config.limits.clamp(velocity));
        let obs = self.observe();
        self.remember(&obs);
        obs
    }

    /// Starts an episode at a random start with a random goal, both in the world's free region,
    /// the goal at a distance within the configured range.
    pub fn reset_random(&mut self) -> Result<Observation, EnvError> {
        let (start, goal) = self.sample_start_goal()?;
        Ok(self.begin(start, goal))
    }

    /// A random start pose and goal as [`NavEnv::reset_random`] draws them.
    pub fn sample_start_goal(&mut self) -> Result<(Pose2, (f64, f64)), EnvError> {
        let world = Arc::clone(&self.world);
        let n = world.free_region().len();
        if n == 0 {
            return Err(EnvError::NoFreeRegion);
        }
        let (dmin, dmax) = self.config.goal_distance;
        for _ in 0..64 {
            let Some(s) = self.region_point(&world, n) else {
                break;
            };
            if world.clearance(s.0, s.1) < self.config.collision_clearance {
                continue;
            }
            if let Some(g) = self.sample_goal_from(&world, s) {
                let yaw = wrap_angle(self.rng.random::<f64>() * 2.0 * PI - PI);
                return Ok((Pose2::new(s.0, s.1, yaw), g));
            }
        }
        Err(EnvError::NoGoalInRange {
            min: dmin,
            max: dmax,
        })
    }

    /// A goal in the free region at a distance from `s` within the configured range (and in
    /// view, with `goals_in_view`): uniform over the annulus's area, up to 64 draws.
    fn sample_goal_from(&mut self, world: &World, s: (f64, f64)) -> Option<(f64, f64)> {
        let (dmin, dmax) = self.config.goal_distance;
        for _ in 0..64 {
            let u: f64 = self.rng.random();
            let r = (dmin * dmin + u * (dmax * dmax - dmin * dmin)).sqrt();
            let a: f64 = self.rng.random::<f64>() * 2.0 * PI;
            let g = (s.0 + r * a.cos(), s.1 + r * a.sin());
            if world.in_free_region(g.0, g.1)
                && world.clearance(g.0, g.1) > 0.0
                && (!self.config.goals_in_view
                    || world.segment_clearance(s, g) > self.config.collision_clearance)
            {
                return Some(g);
            }
        }
        None
    }

    /// Starts a new episode where the last one reached its goal: same pose, same velocity, a
    /// new random goal — the robot arriving at one waypoint of a plan and going on to the next,
    /// which a reset from standstill never shows a policy. Falls back to
    /// [`NavEnv::reset_random`] when the last episode did not reach its goal or no goal in range
    /// is found from here.
    pub fn continue_random(&mut self) -> Result<Observation, EnvError> {
        if !(self.started && self.outcome == Outcome::ReachedGoal) {
            return self.reset_random();
        }
        let world = Arc::clone(&self.world);
        let here = (self.pose.x, self.pose.y);
        let Some(goal) = self.sample_goal_from(&world, here) else {
            return self.reset_random();
        };
        let velocity = self.executed;
        let obs = self.begin(self.pose, goal);
        self.hold(velocity);
        #[allow(
            clippy::cast_possible_truncation,
            reason = "speeds are bounded by the drive limits; observations are f32"
        )]
        let obs = Observation {
            velocity: [velocity.linear as f32, velocity.angular as f32],
            ..obs
        };
        self.remember(&obs);
        Ok(obs)
    }

    /// The robot moving at `velocity`, and every command still on its way to the wheels the
    /// same (as a robot that has been sending it for a while).
    fn hold(&mut self, velocity: Action) {
        self.executed = velocity;
        self.pending.clear();
        if let Some(steps) = self.latency_steps() {
            #[allow(
                clippy::cast_possible_truncation,
                clippy::cast_sign_loss,
                reason = "the latency is at most a second, a handful of control periods"
            )]
            let k = steps.floor() as usize;
            self.pending.extend(std::iter::repeat_n(velocity, k + 1));
        }
    }

    /// The robot model's control latency in control periods, when it has one.
    fn latency_steps(&self) -> Option<f64> {
        let latency = self.world.spec().robot.drive.control_latency?;
        (latency > 0.0).then(|| latency / self.config.control_period)
    }

    /// What reaches the wheels this period when `command` is sent now: the command sent the
    /// control latency ago. A latency of `k + f` periods executes, over this period, the one
    /// sent `k + 1` periods ago for the first `f` of it and the one sent `k` ago for the rest
    /// (their mean, weighted by those shares). Without a latency, `command` itself.
    pub(crate) fn delayed(&mut self, command: Action) -> Action {
        let Some(steps) = self.latency_steps() else {
            return command;
        };
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "the latency is at most a second, a handful of control periods"
        )]
        let k = steps.floor() as usize;
        let f = steps - k as f64;
        self.pending.push_back(command);
        while self.pending.len() > k + 2 {
            self.pending.pop_front();
        }
        let n = self.pending.len();
        let newer = self.pending[n - 1 - k];
        let older = self.pending[n.saturating_sub(2 + k)];
        Action {
            linear: f * older.linear + (1.0 - f) * newer.linear,
            angular: f * older.angular + (1.0 - f) * newer.angular,
        }
    }

    fn region_point(&mut self, world: &World, n: usize) -> Option<(f64, f64)> {
        let pick = self.rng.random_range(0..n);
        let (u, v): (f64, f64) = (self.rng.random(), self.rng.random());
        world.region_point(pick, u, v)
    }

    fn begin(&mut self, start: Pose2, goal: (f64, f64)) -> Observation {
        self.pose = start;
        self.goal = goal;
        self.goal_from = (start.x, start.y);
        self.hold(Action::default());
        self.steps = 0;
        self.others_late.clear();
        self.distance = (goal.0 - start.x).hypot(goal.1 - start.y);
        self.outcome = Outcome::Running;
        self.started = true;
        self.person_clearance = f64::INFINITY;
        self.robot_clearance = (f64::INFINITY, None);
        if let Some(crowd) = &mut self.crowd {
            let robot = RobotDisc {
                position: (start.x, start.y),
                velocity: (0.0, 0.0),
                radius: self.world.spec().robot.footprint_radius,
            };
            crowd.spawn(&self.world, robot);
        }
        self.refresh_field();
        self.trajectory.clear();
        if self.config.record_trajectory {
            self.trajectory.push(start);
        }
        let obs = self.observe();
        self.remember(&obs);
        obs
    }

    /// The true angle between the robot's heading and the way to the goal (straight at it, or
    /// along the path field's lookahead with `reward.geodesic`), radians in [0, π].
    fn bearing_error(&self) -> f64 {
        let target = self
            .field
            .as_ref()
            .and_then(|f| f.lookahead(self.pose.x, self.pose.y))
            .unwrap_or(self.goal);
        let (dx, dy) = (target.0 - self.pose.x, target.1 - self.pose.y);
        wrap_angle(dy.atan2(dx) - self.pose.yaw).abs()
    }

    /// Recomputes the path field for a new goal (with `reward.geodesic`) and the potential.
    fn refresh_field(&mut self) {
        let r = &self.config.reward;
        self.field = (r.progress && r.geodesic)
            .then(|| PathField::new(&self.world, self.goal, PATH_FIELD_CELL_M));
        self.potential = self.potential_at(self.distance);
    }

    /// The progress potential at the current pose, given the straight distance to the goal.
    /// Off the path field's reach (pressed into a wall corner) the last potential stands, so
    /// the reward shows no jump.
    fn potential_at(&self, straight: f64) -> f64 {
        match &self.field {
            Some(f) => f
                .distance(self.pose.x, self.pose.y)
                .unwrap_or(self.potential),
            None => straight,
        }
    }

    /// Keeps a copy of the latest observation for steps after the end, reusing its buffer.
    fn remember(&mut self, obs: &Observation) {
        match &mut self.last_observation {
            Some(last) => {
                last.ranges.clone_from(&obs.ranges);
                last.goal_distance = obs.goal_distance;
                last.goal_angle = obs.goal_angle;
                last.velocity = obs.velocity;
            }
            None => self.last_observation = Some(obs.clone()),
        }
    }

    fn info(&self, min_clearance: f64) -> StepInfo {
        StepInfo {
            outcome: self.outcome,
            pose: self.pose,
            executed: self.executed,
            min_clearance,
            distance_to_goal: self.distance,
            steps: self.steps,
            time_s: f64::from(self.steps) * self.config.control_period,
            person_clearance: self.person_clearance,
            robot_clearance: self.robot_clearance.0,
            nearest_robot: self.robot_clearance.1,
        }
    }

    /// The noisy observation at the current pose.
    #[allow(
        clippy::cast_possible_truncation,
        reason = "observations are f32 by design"
    )]
    fn observe(&mut self) -> Observation {
        self.world
            .scan_dirs(self.pose, &self.dirs, &mut self.ranges);
        // People and other robots shorten the beams, cast from the laser in world directions.
        if self.crowd.is_some() || self.others.is_some() {
            let (lx, ly, heading) = self.world.laser_origin(self.pose);
            let (s, c) = heading.sin_cos();
            let dirs = self
                .dirs
                .iter()
                .map(move |(bc, bs)| (c * bc - s * bs, s * bc + c * bs));
            if let Some(crowd) = &self.crowd {
                crowd.occlude((lx, ly), dirs.clone(), &mut self.ranges);
            }
            if let Some(others) = &self.others {
                let at = others.at_late(
                    f64::from(self.steps) * self.config.control_period,
                    &self.others_late,
                );
                crate::others::occlude(&at, (lx, ly), dirs, &mut self.ranges);
            }
        }
        let laser = &self.world.spec().robot.laser;
        let (lo, hi) = (laser.range_min, laser.range_max);
        let noise = self.config.noise;
        let ranges = self
            .ranges
            .iter()
            .map(|r| (r + gauss(&mut self.rng, noise.range)).clamp(lo, hi) as f32)
            .collect();
        let goal = match (self.config.carrot_m, &self.field) {
            (Some(l), Some(f)) => f.carrot(self.pose.x, self.pose.y, l).unwrap_or(self.goal),
            _ => self.goal,
        };
        let (dx, dy) = (goal.0 - self.pose.x, goal.1 - self.pose.y);
        let dist = dx.hypot(dy) + gauss(&mut self.rng, noise.goal_distance);
        let angle =
            wrap_angle(dy.atan2(dx) - self.pose.yaw + gauss(&mut self.rng, noise.goal_angle));
        Observation {
            ranges,
            goal_distance: dist.max(0.0) as f32,
            goal_angle: angle as f32,
            velocity: [self.executed.linear as f32, self.executed.angular as f32],
        }
    }
}

/// A normal draw with standard deviation `sd`; no draw at all when `sd` is 0, so noiseless
/// environments consume no randomness.
#[inline]
fn gauss(rng: &mut ChaCha8Rng, sd: f64) -> f64 {
    if sd == 0.0 {
        0.0
    } else {
        let z: f64 = rng.sample(StandardNormal);
        z * sd
    }
}

fn check_config(c: &EnvConfig) -> Result<(), EnvError> {
    let bad = |field: &'static str, message: String| Err(EnvError::Config { field, message });
    let pos = |v: f64| v.is_finite() && v > 0.0;
    let nonneg = |v: f64| v.is_finite() && v >= 0.0;
    if c.beams == 0 {
        return bad("beams", "at least one beam is needed".into());
    }
    if !pos(c.control_period) {
        return bad(
            "control_period",
            format!(
                "must be a positive number of seconds, got {}",
                c.control_period
            ),
        );
    }
    let l = &c.limits;
    if !(l.linear_min.is_finite() && l.linear_max.is_finite() && l.linear_min <= l.linear_max) {
        return bad(
            "limits.linear",
            format!("need min <= max, got [{}, {}]", l.linear_min, l.linear_max),
        );
    }
    if !nonneg(l.angular_max) {
        return bad(
            "limits.angular_max",
            format!("must be finite and not negative, got {}", l.angular_max),
        );
    }
    let n = &c.noise;
    for (field, v) in [
        ("noise.range", n.range),
        ("noise.goal_distance", n.goal_distance),
        ("noise.goal_angle", n.goal_angle),
        ("noise.linear", n.linear),
        ("noise.angular", n.angular),
    ] {
        if !nonneg(v) {
            return bad(
                field,
                format!("a standard deviation must be finite and not negative, got {v}"),
            );
        }
    }
    let r = &c.reward;
    for (field, v) in [
        ("reward.completion", r.completion),
        ("reward.time", r.time),
        ("reward.closer", r.closer),
        ("reward.collision", r.collision),
        ("reward.heading", r.heading),
    ] {
        if !nonneg(v) {
            return bad(
                field,
                format!("Eq. 1's constants are positive numbers, got {v}"),
            );
        }
    }
    if !pos(c.goal_tolerance) {
        return bad(
            "goal_tolerance",
            format!("must be positive, got {}", c.goal_tolerance),
        );
    }
    if !c.collision_clearance.is_finite() {
        return bad(
            "collision_clearance",
            format!("must be finite, got {}", c.collision_clearance),
        );
    }
    if c.max_steps == 0 {
        return bad("max_steps", "an episode needs at least one step".into());
    }
    if let Some(l) = c.carrot_m
        && !(pos(l) && c.reward.progress && c.reward.geodesic)
    {
        return bad(
            "carrot_m",
            format!("needs a positive distance and the geodesic progress reward, got {l}"),
        );
    }
    if let Some((field, message)) = c.people.problem() {
        return bad(field, message);
    }
    let (a, b) = c.goal_distance;
    if !(nonneg(a) && b.is_finite() && a <= b && b > 0.0) {
        return bad(
            "goal_distance",
            format!("need 0 <= min <= max, max > 0, got ({a}, {b})"),
        );
    }
    Ok(())
}
