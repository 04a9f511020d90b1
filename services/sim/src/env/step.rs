//! One control period of the environment: the noisy command driven, people and other robots
//! moved, the footprint checked along the arc, and Eq. 1's reward.

use super::{CLEARANCE_BAND_M, NavEnv, Observation, Outcome, StepResult, gauss};
use crate::crowd::RobotDisc;
use crate::kinematics::{Action, integrate};

/// What the footprint met along one step's arc.
struct Sweep {
    /// Smallest clearance to walls, objects, people and other robots, metres.
    min_clearance: f64,
    /// Whether it came closer than the collision clearance (the pose is where it did).
    collided: bool,
}

/// Where the step started from, for the progress reward.
struct Before {
    /// [`NavEnv::bearing_error`] at the start.
    bearing: f64,
    /// The potential at the start.
    potential: f64,
}

impl NavEnv {
    /// Applies `action` for one control period.
    ///
    /// Stepping an episode that has ended (or never started) changes nothing and returns the
    /// last observation again with `done` set and zero reward.
    pub fn step(&mut self, action: Action) -> StepResult {
        if !self.started || self.outcome != Outcome::Running {
            return self.ended_step();
        }
        let exec = self.drive_noisy(action);
        let before = Before {
            bearing: self.bearing_error(),
            potential: self.potential,
        };
        let sweep = self.sweep(exec);
        let cfg = &self.config;
        self.steps += 1;
        if cfg.record_trajectory {
            self.trajectory.push(self.pose);
        }
        let distance = crate::norm(self.goal.0 - self.pose.x, self.goal.1 - self.pose.y);
        self.potential = self.potential_at(distance);
        self.outcome = if sweep.collided {
            Outcome::Collision
        } else if distance <= cfg.goal_tolerance {
            Outcome::ReachedGoal
        } else if self.steps >= cfg.max_steps {
            Outcome::TimeLimit
        } else {
            Outcome::Running
        };
        let reward = self.reward(distance, &before, sweep.min_clearance);
        self.distance = distance;
        let observation = self.observe();
        self.remember(&observation);
        StepResult {
            observation,
            reward,
            done: self.outcome != Outcome::Running,
            info: self.info(sweep.min_clearance),
            reset_observation: None,
        }
    }

    /// The answer to a step of an episode that has ended (or never started).
    fn ended_step(&self) -> StepResult {
        StepResult {
            observation: self
                .last_observation
                .clone()
                .unwrap_or_else(|| Observation {
                    ranges: vec![0.0; self.config.beams],
                    goal_distance: 0.0,
                    goal_angle: 0.0,
                    velocity: [0.0; 2],
                }),
            reward: 0.0,
            done: true,
            info: self.info(f64::NAN),
            reset_observation: None,
        }
    }

    /// Drives `action` (clamped to the limits, with the configured noise) through the
    /// drive's dynamics, and moves the people first, seeing the robot as it was moving. The
    /// velocity the robot executes over the step.
    fn drive_noisy(&mut self, action: Action) -> Action {
        let cfg = &self.config;
        let dt = cfg.control_period;
        let wanted = cfg.limits.clamp(action);
        // Noise on what moves: a wheel told to stand still stands still (a robot stopped a
        // few centimetres from a wall does not creep into it), a moving one slips.
        let (dv, dw) = (
            gauss(&mut self.rng, cfg.noise.linear),
            gauss(&mut self.rng, cfg.noise.angular),
        );
        let noisy = Action {
            linear: if wanted.linear == 0.0 {
                0.0
            } else {
                wanted.linear + dv
            },
            angular: if wanted.angular == 0.0 {
                0.0
            } else {
                wanted.angular + dw
            },
        };
        let arriving = self.delayed(noisy);
        let exec = self.drive.execute(self.executed, arriving, dt);
        let radius = self.world.spec().robot.footprint_radius;
        if let Some(crowd) = &mut self.crowd {
            // People move first, seeing the robot as it was moving.
            let (s, c) = self.pose.yaw.sin_cos();
            let v = self.executed.linear;
            let robot = RobotDisc {
                position: (self.pose.x, self.pose.y),
                velocity: (v * c, v * s),
                radius,
            };
            crowd.step(&self.world, robot, dt);
        }
        self.executed = exec;
        exec
    }

    /// Moves the robot along the arc of `exec` for one period, checking the footprint often
    /// enough that no wall thinner than the robot can be crossed between two checks (every half
    /// radius of travel), and stops where it collides. Records the clearances to people and
    /// other robots on the way.
    fn sweep(&mut self, exec: Action) -> Sweep {
        let cfg = &self.config;
        let dt = cfg.control_period;
        let radius = self.world.spec().robot.footprint_radius;
        let travel = exec.linear.abs() * dt;
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a small positive count, bounded by the clamp"
        )]
        let n = ((travel / (0.5 * radius)).ceil() as usize).clamp(1, 1000);
        let start = self.pose;
        let mut min_clearance = f64::INFINITY;
        let mut collided = false;
        self.person_clearance = f64::INFINITY;
        self.robot_clearance = (f64::INFINITY, None);
        // The other robots where they are at the end of the step (shielded ones holding
        // where they would come too close to this one).
        let robots_at = match &self.others {
            Some(o) => {
                let now = f64::from(self.steps) * dt;
                o.hold_for(&mut self.others_late, now, dt, (start.x, start.y), radius);
                o.at_late(now + dt, &self.others_late)
            }
            None => Vec::new(),
        };
        for k in 1..=n {
            let p = integrate(start, exec, dt * k as f64 / n as f64);
            let mut c = self.world.clearance(p.x, p.y);
            if let Some(crowd) = &self.crowd {
                let to_people = crowd.clearance(p.x, p.y, radius);
                self.person_clearance = self.person_clearance.min(to_people);
                c = c.min(to_people);
            }
            if !robots_at.is_empty() {
                let to_robots = crate::others::clearance(&robots_at, p.x, p.y, radius);
                if to_robots.0 < self.robot_clearance.0 {
                    self.robot_clearance = to_robots;
                }
                c = c.min(to_robots.0);
            }
            min_clearance = min_clearance.min(c);
            self.pose = p;
            if c < cfg.collision_clearance {
                collided = true;
                break;
            }
        }
        Sweep {
            min_clearance,
            collided,
        }
    }

    /// Eq. 1's reward for the step just taken, ending `distance` from the goal with
    /// `min_clearance` on the way: completion, collision, or the progress term (constant
    /// r_closer, or in proportion to the progress and turn made since `before`), less the
    /// time and clearance costs configured.
    fn reward(&self, distance: f64, before: &Before, min_clearance: f64) -> f64 {
        let cfg = &self.config;
        let dt = cfg.control_period;
        let time_s = f64::from(self.steps) * dt;
        let r = &cfg.reward;
        let step_cost = if r.time_per_step { r.time * dt } else { 0.0 };
        -step_cost
            + match self.outcome {
                Outcome::ReachedGoal if r.time_per_step => r.completion,
                Outcome::ReachedGoal => r.completion - time_s * r.time,
                Outcome::Collision => -r.collision,
                Outcome::Running | Outcome::TimeLimit if r.progress => {
                    let most = (cfg.limits.linear_max.abs() * dt).max(1e-9);
                    let turn = (cfg.limits.angular_max.abs() * dt).max(1e-9);
                    let turned = before.bearing - self.bearing_error();
                    r.closer * ((before.potential - self.potential) / most).clamp(-1.0, 1.0)
                        + r.closer * r.heading * (turned / turn).clamp(-1.0, 1.0)
                }
                Outcome::Running | Outcome::TimeLimit if distance < self.distance => r.closer,
                Outcome::Running | Outcome::TimeLimit => 0.0,
            }
            - if self.outcome == Outcome::Collision || !min_clearance.is_finite() {
                0.0
            } else {
                r.clearance
                    * dt
                    * ((CLEARANCE_BAND_M - min_clearance) / CLEARANCE_BAND_M).clamp(0.0, 1.0)
            }
    }
}
