//! Roadmap edges driven by a controller in the mental simulation, as PRM-RL (Faust et al. 2018)
//! decides which edges exist: every edge, in both directions, `rollouts` times, from the way the
//! executor would arrive at its start. The result is the honest measure of a policy on a
//! building (its per-edge success rate and the edges it cannot drive), and the weights of a
//! policy-aware roadmap ([`EdgeReport::cost`]).
//!
//! How a rollout starts: at the edge's first node, heading as a robot arriving over one of the
//! node's other edges would (rollout `k` takes the `k`-th of them in turn; a node with no other
//! edge heads along the edge itself), at rest in even rollouts (a plan's first waypoint) and,
//! in odd ones, still moving along that heading at `arrival_speed_share` of the top speed (the
//! executor hands the next waypoint over without stopping). Edges longer than the executor's longest
//! straight stretch get the executor's intermediate waypoints, and each waypoint the
//! executor's timer; no replanning (a rollout measures the edge, not the planner). Sensor and
//! actuation noise as in a validation, seeded per (edge, direction, rollout), so a report is
//! reproducible. Directed edges run in parallel on rayon's pool.

use std::sync::Arc;

use grid::seed::mix;
use learning::Policy;
use prm::{Point2, Roadmap};
use rayon::prelude::*;
use sim::{Action, Pose2, World};

use crate::controller::{Controller, PolicyController};
use crate::error::{PlanError, invalid};
use crate::executor::{DriveLimits, drive, env_config_for};
use crate::types::AttemptOutcome;

/// Most rollouts per edge and direction one request may ask for.
pub const MAX_ROLLOUTS: u32 = 1000;

/// How edges are driven and judged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeRolloutParams {
    /// Rollouts per edge and direction (PRM-RL's Monte Carlo estimate; default 10).
    pub rollouts: u32,
    /// Success rate an edge direction needs to be kept (default 0.9).
    pub keep_threshold: f64,
    /// The waypoint timer, simulated seconds (the executor's default, 15).
    pub waypoint_timeout_s: f64,
    /// Noise on observations and commands, as in a validation (default true).
    pub noise: bool,
    /// Seed of the rollouts' noise.
    pub seed: u64,
    /// Linear speed of the odd rollouts at the start, as a share of the top speed (0: every
    /// rollout from rest; default 0.5).
    pub arrival_speed_share: f64,
    /// People walking about, per 100 m² of free region (default 0: none). Among people the
    /// rollouts run with the executor's recoveries ([`crate::recoveries_for`]).
    pub people_density: f64,
}

impl Default for EdgeRolloutParams {
    fn default() -> Self {
        Self {
            rollouts: 10,
            keep_threshold: 0.9,
            waypoint_timeout_s: 15.0,
            noise: true,
            seed: 0,
            arrival_speed_share: 0.5,
            people_density: 0.0,
        }
    }
}

impl EdgeRolloutParams {
    /// The parameters, or which one is out of range.
    pub fn validate(&self) -> Result<(), PlanError> {
        if !(1..=MAX_ROLLOUTS).contains(&self.rollouts) {
            return Err(invalid(
                "rollouts",
                format!("must lie in [1, {MAX_ROLLOUTS}], got {}", self.rollouts),
            ));
        }
        if !(self.arrival_speed_share.is_finite()
            && (0.0..=1.0).contains(&self.arrival_speed_share))
        {
            return Err(invalid(
                "arrival_speed_share",
                format!("must lie in [0, 1], got {}", self.arrival_speed_share),
            ));
        }
        if !(self.people_density.is_finite() && (0.0..=50.0).contains(&self.people_density)) {
            return Err(invalid(
                "people_density",
                format!(
                    "must lie in [0, 50] people per 100 m², got {}",
                    self.people_density
                ),
            ));
        }
        if !(self.keep_threshold.is_finite() && (0.0..=1.0).contains(&self.keep_threshold)) {
            return Err(invalid(
                "keep_threshold",
                format!("must lie in [0, 1], got {}", self.keep_threshold),
            ));
        }
        if !(self.waypoint_timeout_s.is_finite()
            && self.waypoint_timeout_s > 0.0
            && self.waypoint_timeout_s <= crate::executor::MAX_WAYPOINT_TIMEOUT_S)
        {
            return Err(invalid(
                "waypoint_timeout_s",
                format!(
                    "must lie in (0, {}] simulated seconds, got {}",
                    crate::executor::MAX_WAYPOINT_TIMEOUT_S,
                    self.waypoint_timeout_s
                ),
            ));
        }
        Ok(())
    }
}

/// An undirected roadmap edge as its driven directions sum it up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeSummary {
    /// The worse direction's success rate (`None`: neither direction was driven).
    pub success: Option<f64>,
    /// Mean simulated time of the successful rollouts of both directions, seconds.
    pub mean_time_s: Option<f64>,
    /// Whether the roadmap keeps the edge both ways (`None`: neither direction was driven).
    pub kept: Option<bool>,
}

/// An [`EdgeReport`] by edge direction.
#[derive(Debug)]
pub struct EdgeIndex<'a> {
    report: &'a EdgeReport,
    by_direction: std::collections::HashMap<(usize, usize), &'a EdgeStat>,
}

impl EdgeIndex<'_> {
    /// The edge between nodes `a` and `b`, both ways.
    pub fn summary(&self, a: usize, b: usize) -> EdgeSummary {
        let measured: Vec<&EdgeStat> = [(a, b), (b, a)]
            .iter()
            .filter_map(|d| self.by_direction.get(d).copied())
            .collect();
        if measured.is_empty() {
            return EdgeSummary {
                success: None,
                mean_time_s: None,
                kept: None,
            };
        }
        let success = measured
            .iter()
            .map(|e| e.success_rate())
            .fold(1.0, f64::min);
        let (t, n) = measured
            .iter()
            .filter_map(|e| {
                e.mean_time_s
                    .map(|t| (t * f64::from(e.successes), e.successes))
            })
            .fold((0.0, 0u32), |(t, n), (et, es)| (t + et, n + es));
        EdgeSummary {
            success: Some(success),
            mean_time_s: (n > 0).then(|| t / f64::from(n)),
            kept: Some(measured.len() == 2 && measured.iter().all(|e| self.report.keeps(e))),
        }
    }
}

/// One edge direction as driven.
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeStat {
    /// Node the rollouts started at (an index of `Roadmap::nodes`).
    pub from: usize,
    /// Node they drove to.
    pub to: usize,
    /// Straight-line length, metres.
    pub length_m: f64,
    /// Rollouts that reached `to` without a collision.
    pub successes: u32,
    /// Rollouts that ended in a collision.
    pub collisions: u32,
    /// Rollouts driven.
    pub rollouts: u32,
    /// Mean simulated time of the successful rollouts, seconds.
    pub mean_time_s: Option<f64>,
    /// Smallest footprint clearance over all rollouts, metres.
    pub min_clearance_m: f64,
    /// Rollouts whose footprint came within [`NEAR_MISS_M`] of an obstacle (collisions too).
    pub near_misses: u32,
}

/// A rollout whose footprint comes closer than this to an obstacle is a near miss, metres.
pub const NEAR_MISS_M: f64 = 0.10;

impl EdgeStat {
    /// Share of rollouts that succeeded.
    pub fn success_rate(&self) -> f64 {
        if self.rollouts == 0 {
            0.0
        } else {
            f64::from(self.successes) / f64::from(self.rollouts)
        }
    }

    /// The success probability with a uniform prior (Laplace's rule: (s + 1) / (n + 2)), so an
    /// edge that never failed in 10 rollouts is not certain, and one never tried is a coin.
    pub fn success_estimate(&self) -> f64 {
        (f64::from(self.successes) + 1.0) / (f64::from(self.rollouts) + 2.0)
    }
}

/// Every edge direction of a roadmap driven by one controller.
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeReport {
    /// Both directions of every roadmap edge, in `Roadmap::edges` order (forward, then back).
    pub edges: Vec<EdgeStat>,
    /// The parameters they were driven with.
    pub params: EdgeRolloutParams,
    /// Simulated control steps over all rollouts.
    pub steps: u64,
    /// Of those, the steps a fallback inside the controller drove (the follower a policy
    /// hands over to near obstacles).
    pub handover_steps: u64,
}

impl EdgeReport {
    /// Successful rollouts over all rollouts: the per-edge success rate of the controller.
    pub fn edge_success_rate(&self) -> f64 {
        let (s, n) = self.edges.iter().fold((0u64, 0u64), |(s, n), e| {
            (s + u64::from(e.successes), n + u64::from(e.rollouts))
        });
        if n == 0 { 0.0 } else { s as f64 / n as f64 }
    }

    /// Share of the control steps a fallback inside the controller drove.
    pub fn handover_share(&self) -> f64 {
        #[allow(clippy::cast_precision_loss, reason = "step counts are far below 2^52")]
        if self.steps == 0 {
            0.0
        } else {
            self.handover_steps as f64 / self.steps as f64
        }
    }

    /// Share of all rollouts that were near misses ([`NEAR_MISS_M`]).
    pub fn near_miss_rate(&self) -> f64 {
        let (m, n) = self.edges.iter().fold((0u64, 0u64), |(m, n), e| {
            (m + u64::from(e.near_misses), n + u64::from(e.rollouts))
        });
        if n == 0 { 0.0 } else { m as f64 / n as f64 }
    }

    /// Whether the roadmap keeps the edge direction `e`: its success rate reaches the keep
    /// threshold (the one rule every caller uses).
    pub fn keeps(&self, e: &EdgeStat) -> bool {
        e.success_rate() >= self.params.keep_threshold
    }

    /// Edge directions whose success rate reaches the keep threshold.
    pub fn kept(&self) -> impl Iterator<Item = &EdgeStat> + '_ {
        self.edges.iter().filter(|e| self.keeps(e))
    }

    /// Edge directions below the threshold: the ones the controller cannot drive.
    pub fn dropped(&self) -> impl Iterator<Item = &EdgeStat> + '_ {
        self.edges.iter().filter(|e| !self.keeps(e))
    }

    /// The report by edge direction, to sum up undirected edges ([`EdgeIndex::summary`]).
    pub fn index(&self) -> EdgeIndex<'_> {
        EdgeIndex {
            report: self,
            by_direction: self.edges.iter().map(|e| ((e.from, e.to), e)).collect(),
        }
    }

    /// Mean simulated time per successful edge rollout, seconds.
    pub fn mean_edge_time_s(&self) -> Option<f64> {
        let (t, n) = self
            .edges
            .iter()
            .filter_map(|e| {
                e.mean_time_s
                    .map(|t| (t * f64::from(e.successes), e.successes))
            })
            .fold((0.0, 0u64), |(t, n), (et, es)| (t + et, n + u64::from(es)));
        (n > 0).then(|| t / n as f64)
    }

    /// The cost of driving `from` → `to` on a policy-aware roadmap, metres: the edge's length
    /// plus `risk_m` per unit of `-ln p` (p its estimated success probability), so the search
    /// prefers the route the controller most likely finishes and pays `risk_m · ln 2` metres of
    /// detour to halve a route's risk of failing. `None` for a direction below the keep
    /// threshold, or one not in the report.
    pub fn cost(&self, from: usize, to: usize, risk_m: f64) -> Option<f64> {
        let e = self.edges.iter().find(|e| e.from == from && e.to == to)?;
        (e.success_rate() >= self.params.keep_threshold)
            .then(|| e.length_m + risk_m * -e.success_estimate().ln())
    }

    /// [`EdgeReport::cost`] for every measured direction, those below the keep threshold
    /// included at [`UNKEPT_PENALTY_M`] more: a search takes them only where the kept ones join
    /// no route within that detour, and then the ones the controller most likely drives.
    pub fn cost_with_unkept(&self, from: usize, to: usize, risk_m: f64) -> Option<f64> {
        let e = self.edges.iter().find(|e| e.from == from && e.to == to)?;
        let penalty = if e.success_rate() >= self.params.keep_threshold {
            0.0
        } else {
            UNKEPT_PENALTY_M
        };
        Some(e.length_m + risk_m * -e.success_estimate().ln() + penalty)
    }
}

/// Metres of detour a route on the complete policy-aware roadmap
/// ([`reweight_with_unkept`]) accepts to avoid one edge direction below the keep threshold.
pub const UNKEPT_PENALTY_M: f64 = 100.0;

/// Drives both directions of every edge of `roadmap` with the controllers `make` returns (one
/// per worker thread; each is attached to `world` first), as the module docs describe.
pub fn drive_edges<C, F>(
    world: &Arc<World>,
    roadmap: &Roadmap,
    make: F,
    params: &EdgeRolloutParams,
) -> Result<EdgeReport, PlanError>
where
    C: Controller,
    F: Fn() -> C + Sync + Send,
{
    let all: Vec<(usize, usize)> = roadmap.edges().collect();
    drive_some_edges(world, roadmap, &all, make, params)
}

/// As [`drive_edges`] for the undirected edges `some` of `roadmap` only (both directions each,
/// in that order): a sample for a quick look. A report of a sample is not a policy-aware
/// roadmap's measurement; [`policy_roadmap`] drives every edge.
pub fn drive_some_edges<C, F>(
    world: &Arc<World>,
    roadmap: &Roadmap,
    some: &[(usize, usize)],
    make: F,
    params: &EdgeRolloutParams,
) -> Result<EdgeReport, PlanError>
where
    C: Controller,
    F: Fn() -> C + Sync + Send,
{
    params.validate()?;
    let nodes: Vec<Point2> = roadmap.nodes().collect();
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
    for (a, b) in roadmap.edges() {
        neighbours[a].push(b);
        neighbours[b].push(a);
    }
    if let Some(&(a, b)) = some
        .iter()
        .find(|&&(a, b)| !neighbours.get(a).is_some_and(|n| n.contains(&b)))
    {
        return Err(invalid(
            "edges",
            format!("({a}, {b}) is not an edge of the roadmap"),
        ));
    }
    let directed: Vec<(usize, usize)> = some.iter().flat_map(|&(a, b)| [(a, b), (b, a)]).collect();
    let probe = make();
    let beams = probe.beams().unwrap_or(sim::EnvConfig::default().beams);
    if world.spec().robot.laser.beam_angles(beams).is_none() {
        return Err(invalid(
            "policy",
            format!(
                "the controller reads {beams} laser beams but the robot's laser cannot give them"
            ),
        ));
    }
    let mut env = env_config_for(world, beams, params.noise);
    env.record_trajectory = false;
    env.people = sim::PeopleConfig {
        density: params.people_density,
        ..sim::PeopleConfig::default()
    };
    let recoveries = crate::recoveries_for(&crate::PlanOptions {
        people: env.people.clone(),
        ..crate::PlanOptions::default()
    });
    if let Some(t) = probe.goal_tolerance() {
        env.goal_tolerance = t;
    }
    drop(probe);
    let max_segment_m = (0.5 * env.limits.linear_max * params.waypoint_timeout_s).max(0.5);
    let arrival_speed = params.arrival_speed_share * env.limits.linear_max;
    let results: Result<Vec<(EdgeStat, u64, u64)>, PlanError> = directed
        .par_iter()
        .map_init(
            || {
                let mut c = make();
                c.attach(world, beams);
                c
            },
            |controller, &(a, b)| {
                let (pa, pb) = (nodes[a], nodes[b]);
                let waypoints = crate::paths::subdivide(pa, vec![pb], max_segment_m);
                let others: Vec<usize> =
                    neighbours[a].iter().copied().filter(|&w| w != b).collect();
                let mut stat = EdgeStat {
                    from: a,
                    to: b,
                    length_m: pa.distance(pb),
                    successes: 0,
                    collisions: 0,
                    rollouts: params.rollouts,
                    mean_time_s: None,
                    min_clearance_m: f64::INFINITY,
                    near_misses: 0,
                };
                let mut time_sum = 0.0;
                let (mut steps, mut handover_steps) = (0u64, 0u64);
                for k in 0..params.rollouts {
                    let yaw = if others.is_empty() {
                        (pb.y - pa.y).atan2(pb.x - pa.x)
                    } else {
                        let w = nodes[others[k as usize % others.len()]];
                        (pa.y - w.y).atan2(pa.x - w.x)
                    };
                    controller.start_attempt(k + 1);
                    let edge_key = ((a as u64) << 32) | (b as u64 & 0xffff_ffff);
                    let run = drive(
                        world,
                        &env,
                        Pose2::new(pa.x, pa.y, yaw),
                        std::slice::from_ref(&waypoints),
                        controller,
                        DriveLimits {
                            waypoint_timeout_s: params.waypoint_timeout_s,
                            max_replans: 0,
                            sim_seed: mix(mix(params.seed, edge_key), u64::from(k)),
                            initial_velocity: if k % 2 == 1 && !others.is_empty() {
                                Action::new(arrival_speed, 0.0)
                            } else {
                                Action::default()
                            },
                            stop: grid::Stop::never(),
                            trace: false,
                            recoveries: recoveries.clone(),
                            others: None,
                            holds: Vec::new(),
                        },
                        None,
                    )?;
                    steps += run.steps;
                    handover_steps += run.handover_steps;
                    stat.min_clearance_m = stat.min_clearance_m.min(run.min_clearance_m);
                    if run.min_clearance_m < NEAR_MISS_M {
                        stat.near_misses += 1;
                    }
                    match run.outcome {
                        AttemptOutcome::Reached => {
                            stat.successes += 1;
                            time_sum += run.time_s;
                        }
                        AttemptOutcome::Collision => stat.collisions += 1,
                        AttemptOutcome::Stalled => {}
                    }
                }
                stat.mean_time_s =
                    (stat.successes > 0).then(|| time_sum / f64::from(stat.successes));
                Ok((stat, steps, handover_steps))
            },
        )
        .collect();
    let results = results?;
    let steps = results.iter().map(|r| r.1).sum();
    let handover_steps = results.iter().map(|r| r.2).sum();
    Ok(EdgeReport {
        edges: results.into_iter().map(|r| r.0).collect(),
        params: *params,
        steps,
        handover_steps,
    })
}

/// The geometric roadmap of `world` a plan's first attempt uses: n* samples of the free
/// region at the plan's default safety margin, seeded with `seed`. What `mentalsim eval
/// --goals edges`, a run's learner selection and `bench edges` drive edge by edge.
pub fn first_attempt_roadmap(world: &Arc<World>, seed: u64) -> Result<Arc<Roadmap>, PlanError> {
    let cache = crate::RoadmapCache::default();
    let opts = crate::PlanOptions::default();
    let space = crate::config_space(world, &cache, "first-attempt", opts.safety_margin_m)?;
    let params = prm::PrmParams {
        samples: prm::optimal_samples(space.free_area_m2),
        seed,
        ..prm::PrmParams::default()
    };
    let (roadmap, _) = cache.roadmap("first-attempt", &space, &params)?;
    Ok(roadmap)
}

/// Metres of detour a policy-aware roadmap's search pays per unit of `-ln p` of an edge
/// ([`EdgeReport::cost`]): about 7 m to halve a route's risk of failing.
pub const RISK_M: f64 = 10.0;

/// The policy-aware roadmap of `roadmap` (PRM-RL): every edge driven by the shielded `policy`
/// as [`drive_edges`] does, the directions below the keep threshold removed, the others
/// weighted by length and risk ([`RISK_M`]). Plan on it with `QueryOptions::no_densify`.
pub fn policy_roadmap(
    world: &Arc<World>,
    roadmap: &Roadmap,
    policy: &Arc<Policy>,
    params: &EdgeRolloutParams,
) -> Result<(Arc<Roadmap>, EdgeReport), PlanError> {
    let report = drive_edges(
        world,
        roadmap,
        || PolicyController::new(Arc::clone(policy)),
        params,
    )?;
    let reweighted = reweight(roadmap, &report)?;
    Ok((reweighted, report))
}

/// The policy-aware roadmap of `roadmap` from a report of its edges driven earlier (a stored
/// one): the directions below the keep threshold removed, the others weighted by length and
/// risk ([`RISK_M`]).
pub fn reweight(roadmap: &Roadmap, report: &EdgeReport) -> Result<Arc<Roadmap>, PlanError> {
    roadmap
        .reweighted(|a, b, _| report.cost(a, b, RISK_M))
        .map(Arc::new)
        .map_err(|e| PlanError::Map(e.to_string()))
}

/// The complete policy-aware roadmap of `roadmap`: every measured direction, weighted by
/// length and risk ([`RISK_M`]), the ones below the keep threshold at [`UNKEPT_PENALTY_M`]
/// more. Where the kept directions join start and goal it plans the same routes as
/// [`reweight`]'s (within that detour); where they do not, the route the controller most
/// likely finishes rather than none. What `options.roadmap: auto` plans on.
pub fn reweight_with_unkept(
    roadmap: &Roadmap,
    report: &EdgeReport,
) -> Result<Arc<Roadmap>, PlanError> {
    roadmap
        .reweighted(|a, b, _| report.cost_with_unkept(a, b, RISK_M))
        .map(Arc::new)
        .map_err(|e| PlanError::Map(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stat(from: usize, to: usize, successes: u32, mean_time_s: Option<f64>) -> EdgeStat {
        EdgeStat {
            from,
            to,
            length_m: 1.0,
            successes,
            collisions: 10 - successes,
            rollouts: 10,
            mean_time_s,
            min_clearance_m: 0.3,
            near_misses: 0,
        }
    }

    /// An edge is kept where both directions reach the threshold; its success is the worse
    /// direction's and its time the mean over both directions' arrivals.
    #[test]
    fn an_edge_sums_up_both_directions_by_the_keep_rule() {
        let report = EdgeReport {
            edges: vec![
                stat(0, 1, 10, Some(2.0)),
                stat(1, 0, 9, Some(4.0)),
                stat(1, 2, 10, Some(3.0)),
                stat(2, 1, 8, None),
                stat(2, 3, 10, Some(1.0)),
            ],
            params: EdgeRolloutParams {
                keep_threshold: 0.9,
                ..EdgeRolloutParams::default()
            },
            steps: 0,
            handover_steps: 0,
        };
        let index = report.index();
        let both = index.summary(1, 0);
        assert_eq!(both.success, Some(0.9));
        assert_eq!(both.kept, Some(true));
        let mean = (2.0 * 10.0 + 4.0 * 9.0) / 19.0;
        assert!((both.mean_time_s.unwrap() - mean).abs() < 1e-12);
        let one_way = index.summary(1, 2);
        assert_eq!(one_way.success, Some(0.8));
        assert_eq!(one_way.kept, Some(false));
        assert_eq!(one_way.mean_time_s, Some(3.0));
        // Only one direction driven: not kept both ways.
        assert_eq!(index.summary(3, 2).kept, Some(false));
        assert_eq!(index.summary(0, 3).success, None);
        assert_eq!(report.kept().count(), 4);
        assert_eq!(report.dropped().count(), 1);
    }
}
