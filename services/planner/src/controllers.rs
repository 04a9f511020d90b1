//! Which controller validates a plan: the one asked for, or, for `auto`, Regulated Pure Pursuit
//! unless another measured measurably better than RPP on this floor state.
//!
//! The measurement is a [`ControllerTrial`]: the `roadmap` job, once it has driven every edge
//! with the policy, drives the same missions on the floor with every candidate (the hybrid
//! with either follower as its handover, Nav2's Regulated Pure Pursuit, Nav2's MPPI), one
//! attempt each, the same seeds (noise, people) for every candidate, among the people the
//! floor's knowledge expects all day. It is stored with the policy-aware roadmap, so it is
//! measured once per floor state and policy, and every plan after it reads the pick.
//!
//! The pick ([`ControllerTrial::pick`]): every challenger is compared with Regulated Pure
//! Pursuit (never only with another challenger), mission by mission (a candidate wins a mission
//! when it reached the goal and the other did not, or both did and it was more than 1% faster),
//! and replaces RPP (or an earlier challenger that beat RPP, which it must also beat) only when
//! its wins outweigh its losses and a one-sided Wilcoxon signed-rank test over the decisive
//! missions gives p < 0.05: the missions are ranked by how much the two differed (the ratio of their times; a
//! mission only one of them reached ranks above all), so a consistent gain of a few percent
//! counts, where a count of wins (a sign test) needs three in four missions won. The classical
//! controllers come first, so where the policy does not do measurably better, a classical
//! controller validates the plan: the learning has not earned its place on that floor yet.
//! Without a trial (no policy, or its roadmap job has not finished), `auto` is Regulated Pure
//! Pursuit, the controller a Nav2 robot would otherwise run.

use std::sync::Arc;

use learning::Policy;
use prm::{Point2, Roadmap};
use rayon::prelude::*;
use rehearsal::{AttemptOutcome, ControllerChoice, PlanError, PlanRequest, RoadmapCache};
use serde::{Deserialize, Serialize};
use sim::{Pose2, World};

/// Missions a trial drives by default.
pub const DEFAULT_TRIAL_MISSIONS: u32 = 16;
/// Most missions a trial may drive.
pub const MAX_TRIAL_MISSIONS: u32 = 200;
/// Significance a candidate must reach to replace the current pick (one-sided Wilcoxon
/// signed-rank test).
pub const SIGNIFICANCE: f64 = 0.05;
/// A candidate that reached in both runs wins a mission only when it was faster by more than
/// this share of the other's time.
pub const TIME_MARGIN: f64 = 0.01;

/// The controllers `auto` considers, in the order it prefers them at equal figures: the
/// classical ones first.
pub const AUTO_ORDER: [ControllerChoice; 5] = [
    ControllerChoice::Rpp,
    ControllerChoice::Mppi,
    ControllerChoice::Hybrid,
    ControllerChoice::HybridRpp,
    ControllerChoice::HybridPath,
];

/// One candidate's run of one mission.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MissionRun {
    /// Whether it reached the goal.
    pub reached: bool,
    /// Simulated seconds to the goal, when it reached it.
    pub time_s: Option<f64>,
    /// Whether it ended touching a person.
    pub hit_person: bool,
}

/// One candidate's figures over a trial.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CandidateFigures {
    /// The controller's name ([`ControllerChoice::as_str`]).
    pub controller: String,
    /// One run per mission, in the trial's mission order.
    pub runs: Vec<MissionRun>,
    /// Wall-clock milliseconds per mission, mean: what the controller costs to rehearse.
    pub wall_ms_per_mission: f64,
}

impl CandidateFigures {
    /// Missions reached.
    pub fn reached(&self) -> usize {
        self.runs.iter().filter(|r| r.reached).count()
    }

    /// Simulated seconds summed over the missions reached.
    pub fn time_s(&self) -> f64 {
        self.runs.iter().filter_map(|r| r.time_s).sum()
    }

    /// Missions that ended touching a person.
    pub fn hit_person(&self) -> usize {
        self.runs.iter().filter(|r| r.hit_person).count()
    }

    fn choice(&self) -> Option<ControllerChoice> {
        ControllerChoice::parse(&self.controller)
    }
}

/// Every candidate driven over the same missions of one floor state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControllerTrial {
    /// Missions (start and goal on the geometric roadmap's nodes); a candidate stopped early
    /// drove fewer.
    pub missions: usize,
    /// People walking about in each mission.
    pub people: usize,
    /// Seed of the missions, the noise and the people.
    pub seed: u64,
    /// Each candidate's runs.
    pub candidates: Vec<CandidateFigures>,
}

/// A controller picked for a plan, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerPick {
    /// The controller.
    pub choice: ControllerChoice,
    /// What `auto` measured it against (Regulated Pure Pursuit unless that was not
    /// available); `None` when the controller was asked for.
    pub compared_with: Option<ControllerChoice>,
    /// Why it was picked, in a sentence the answer carries.
    pub why: String,
}

/// One-sided Wilcoxon signed-rank test of paired differences `d` (zeros left out; infinities
/// rank above every finite difference): the sums of the ranks of the positive and of the
/// negative differences (tied differences share their mean rank), and P(W⁺ ≥ observed) when
/// each difference's sign is + or − with probability ½, computed exactly over the ranks.
fn signed_rank(d: &[f64]) -> (f64, f64, f64) {
    let mut nonzero: Vec<f64> = d.iter().copied().filter(|x| *x != 0.0).collect();
    if nonzero.is_empty() {
        return (0.0, 0.0, 1.0);
    }
    nonzero.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    // Doubled ranks (tied groups share their mean, a multiple of ½): whole numbers.
    let n = nonzero.len();
    let mut doubled = vec![0usize; n];
    let mut i = 0;
    while i < n {
        let mut j = i;
        while j + 1 < n && nonzero[j + 1].abs() == nonzero[i].abs() {
            j += 1;
        }
        // Ranks i+1 ..= j+1, their mean doubled.
        for r in &mut doubled[i..=j] {
            *r = i + j + 2;
        }
        i = j + 1;
    }
    let observed: usize = nonzero
        .iter()
        .zip(&doubled)
        .filter(|(x, _)| **x > 0.0)
        .map(|(_, r)| r)
        .sum();
    let total: usize = doubled.iter().sum();
    // Distribution of the doubled W⁺ over the 2ⁿ sign patterns, as probabilities.
    let mut dist = vec![0.0f64; total + 1];
    dist[0] = 1.0;
    let mut reach = 0;
    for &r in &doubled {
        for sum in (0..=reach).rev() {
            let p = dist[sum] * 0.5;
            dist[sum] = p;
            dist[sum + r] += p;
        }
        reach += r;
    }
    let p = dist[observed..].iter().sum::<f64>().min(1.0);
    (observed as f64 / 2.0, (total - observed) as f64 / 2.0, p)
}

/// How a challenger `x` did against the pick so far `y` on one mission: the log of the ratio
/// of their times (positive: the challenger faster), ±∞ where only one reached, 0 where neither
/// did or their times were within [`TIME_MARGIN`].
fn difference(x: &MissionRun, y: &MissionRun) -> f64 {
    match (x.time_s, y.time_s) {
        (Some(tx), Some(ty)) if tx < ty * (1.0 - TIME_MARGIN) || ty < tx * (1.0 - TIME_MARGIN) => {
            (ty / tx).ln()
        }
        (Some(_), None) => f64::INFINITY,
        (None, Some(_)) => f64::NEG_INFINITY,
        _ => 0.0,
    }
}

/// The challenger's differences from the pick so far over the missions both ran, and `more`
/// missions it would win by the most (the best it could still do).
fn differences(a: &CandidateFigures, b: &CandidateFigures, more: usize) -> Vec<f64> {
    a.runs
        .iter()
        .zip(&b.runs)
        .map(|(x, y)| difference(x, y))
        .chain(std::iter::repeat_n(f64::INFINITY, more))
        .collect()
}

/// Whether differences `d` show the challenger measurably better: its ranks outweigh the
/// pick's and the signed-rank test gives p < [`SIGNIFICANCE`]; with the test's p.
fn measurably_better(d: &[f64]) -> (bool, f64) {
    let (plus, minus, p) = signed_rank(d);
    (plus > minus && p < SIGNIFICANCE, p)
}

/// How `a` and `b` compare over the missions both ran: the missions each won.
fn wins(a: &CandidateFigures, b: &CandidateFigures) -> (usize, usize) {
    let better = |x: &MissionRun, y: &MissionRun| match (x.time_s, y.time_s) {
        (Some(tx), Some(ty)) => tx < ty * (1.0 - TIME_MARGIN),
        (Some(_), None) => true,
        _ => false,
    };
    a.runs.iter().zip(&b.runs).fold((0, 0), |(wa, wb), (x, y)| {
        (
            wa + usize::from(better(x, y)),
            wb + usize::from(better(y, x)),
        )
    })
}

impl ControllerTrial {
    /// The figures of `choice`, if it was driven.
    pub fn figures(&self, choice: ControllerChoice) -> Option<&CandidateFigures> {
        self.candidates.iter().find(|c| c.choice() == Some(choice))
    }

    /// The controller `auto` validates with on this floor state, among those `available`
    /// (the policy-driven ones only with a policy), as the module docs say; `None` when no
    /// available candidate was driven.
    ///
    /// The baseline is the first available candidate of [`AUTO_ORDER`] (Regulated Pure
    /// Pursuit): every challenger is compared with it, never only with another challenger, so
    /// the pick is never one the trial did not find measurably better than the baseline. Of the
    /// challengers that are, a later one replaces an earlier one only when it is also
    /// measurably better than that one.
    pub fn pick(&self, available: impl Fn(ControllerChoice) -> bool) -> Option<ControllerPick> {
        let mut order = AUTO_ORDER
            .into_iter()
            .filter(|c| available(*c))
            .filter_map(|c| self.figures(c));
        let baseline = order.next()?;
        let mut best = baseline;
        // The pick's wins, losses and p against the baseline.
        let mut decided: Option<(usize, usize, f64)> = None;
        for challenger in order {
            let (w, l) = wins(challenger, baseline);
            let (beats_baseline, p) = measurably_better(&differences(challenger, baseline, 0));
            let beats_best = std::ptr::eq(best, baseline)
                || measurably_better(&differences(challenger, best, 0)).0;
            if beats_baseline && beats_best {
                decided = Some((w, l, p));
                best = challenger;
            }
        }
        let choice = best.choice()?;
        let figures = self
            .candidates
            .iter()
            .map(|c| {
                let stopped = if c.runs.len() < self.missions {
                    " (stopped: could no longer win)"
                } else {
                    ""
                };
                format!(
                    "{} reached {}/{} in {:.0} s{stopped}",
                    c.controller,
                    c.reached(),
                    c.runs.len(),
                    c.time_s()
                )
            })
            .collect::<Vec<_>>()
            .join(", ");
        let verdict = match decided {
            Some((w, l, p)) => format!(
                "{} beat {} on {w} of {} decisive missions (Wilcoxon signed-rank p = {p:.3})",
                best.controller,
                baseline.controller,
                w + l
            ),
            None => format!(
                "no controller did measurably better than {} (Wilcoxon signed-rank test on the missions' times, p < {SIGNIFICANCE})",
                baseline.controller
            ),
        };
        Some(ControllerPick {
            choice,
            compared_with: baseline.choice(),
            why: format!(
                "auto: measured on this floor state over {} missions among {} people ({figures}); {verdict}",
                self.missions, self.people
            ),
        })
    }
}

/// What `auto` picks without a trial: Regulated Pure Pursuit, Nav2's default controller,
/// and why.
pub fn unmeasured(why: &str) -> ControllerPick {
    ControllerPick {
        choice: ControllerChoice::Rpp,
        compared_with: None,
        why: format!(
            "auto: {why}; validated with Regulated Pure Pursuit, the classical controller a Nav2 robot would otherwise run"
        ),
    }
}

/// The nodes of `roadmap`'s largest connected component.
fn largest_component(roadmap: &Roadmap) -> Vec<Point2> {
    let all: Vec<Point2> = roadmap.nodes().collect();
    let mut parent: Vec<usize> = (0..all.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (a, b) in roadmap.edges() {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        parent[ra] = rb;
    }
    let mut size = vec![0usize; all.len()];
    let roots: Vec<usize> = (0..all.len()).map(|i| root(&mut parent, i)).collect();
    for &r in &roots {
        size[r] += 1;
    }
    let Some(biggest) = (0..all.len()).max_by_key(|&r| size[r]) else {
        return Vec::new();
    };
    all.into_iter()
        .zip(roots)
        .filter(|(_, r)| *r == biggest)
        .map(|(p, _)| p)
        .collect()
}

/// The missions of a trial: `count` pairs of nodes of the geometric roadmap's largest
/// connected component, drawn with `seed`, each at least a quarter of the component's extent
/// apart (so a mission crosses the floor rather than one edge), heading for the goal at the
/// start.
pub fn trial_missions(roadmap: &Roadmap, count: usize, seed: u64) -> Vec<(Pose2, Point2)> {
    let nodes = largest_component(roadmap);
    if nodes.len() < 2 || count == 0 {
        return Vec::new();
    }
    let (mut lo, mut hi) = (nodes[0], nodes[0]);
    for p in &nodes {
        lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    let min_apart = 0.25 * lo.distance(hi);
    let n = nodes.len() as u64;
    let mut missions = Vec::with_capacity(count);
    for i in 0..(count as u64 * 50) {
        if missions.len() == count {
            break;
        }
        let a = nodes[(grid::seed::nth(seed, 2 * i) % n) as usize];
        let b = nodes[(grid::seed::nth(seed, 2 * i + 1) % n) as usize];
        if a.distance(b) >= min_apart.max(1.0) {
            let yaw = (b.y - a.y).atan2(b.x - a.x);
            missions.push((Pose2::new(a.x, a.y, yaw), b));
        }
    }
    missions
}

/// Where a trial runs: the floor, its roadmaps and the policy.
pub struct TrialFloor<'a> {
    /// The floor's mental simulation.
    pub world: &'a Arc<World>,
    /// Geometric roadmaps (shared with plans).
    pub roadmaps: &'a RoadmapCache,
    /// The roadmap cache's key ([`sim::World::geometry_key`] of `world`).
    pub version: &'a str,
    /// The policy, when the robot has one: the hybrid candidates drive it.
    pub policy: Option<&'a Arc<Policy>>,
    /// The policy-aware roadmap the hybrid candidates plan on, when there is one (as a plan
    /// with `options.roadmap: auto` does).
    pub policy_roadmap: Option<&'a Arc<Roadmap>>,
}

/// Whether `challenger`, having run the first `runs.len()` of `missions` missions, can no
/// longer replace `best` even by winning every remaining one by the largest margin (reaching
/// where `best` did not; a curtailed test): then the rest are not driven.
fn futile(challenger: &CandidateFigures, best: &CandidateFigures, missions: usize) -> bool {
    let remaining = missions.saturating_sub(challenger.runs.len());
    !measurably_better(&differences(challenger, best, remaining)).0
}

/// Drives `missions` with every candidate of [`AUTO_ORDER`] that `floor` can drive, one attempt
/// each, among `people` (the plan options' people, e.g. [`crate::knowledge_people`]): the
/// candidates one after another, each one's missions in parallel batches on rayon's pool. A
/// challenger that can no longer replace the pick so far even by winning every remaining
/// mission stops there (its `runs` are shorter): MPPI costs hundreds of times RPP's compute
/// per cycle, and most of a trial's time would otherwise go to a controller already beaten.
/// A mission that cannot be planned (unreachable) counts as not reached.
pub fn run_trial(
    floor: &TrialFloor<'_>,
    missions: &[(Pose2, Point2)],
    people: &sim::PeopleConfig,
    seed: u64,
) -> Result<ControllerTrial, PlanError> {
    let request = |i: usize| {
        let (start, goal) = missions[i];
        PlanRequest {
            start,
            goals: vec![goal],
            options: rehearsal::PlanOptions {
                max_attempts: 1,
                seed: grid::seed::mix(seed, i as u64),
                trajectory_stride: 0,
                people: people.clone(),
                ..rehearsal::PlanOptions::default()
            },
            stop: grid::Stop::never(),
        }
    };
    let drive = |choice: ControllerChoice, i: usize| -> Result<MissionRun, PlanError> {
        let mut controller = choice
            .build(floor.policy, grid::seed::mix(seed, i as u64))
            .ok_or_else(|| PlanError::Map(format!("{} needs a policy", choice.as_str())))?;
        let roadmap = floor.policy_roadmap.filter(|_| choice.needs_policy());
        let result = rehearsal::validate_with_fallback(
            floor.world,
            floor.roadmaps,
            floor.version,
            &request(i),
            &mut *controller,
            None,
            roadmap,
        );
        match result {
            Ok(report) => Ok(MissionRun {
                reached: true,
                time_s: Some(report.simulated_time_s),
                hit_person: false,
            }),
            Err(PlanError::NotValidated { attempts }) => Ok(MissionRun {
                reached: false,
                time_s: None,
                hit_person: attempts.iter().any(|a| {
                    a.outcome == AttemptOutcome::Collision && rehearsal::hit_person(&a.reason)
                }),
            }),
            Err(PlanError::Unreachable { .. } | PlanError::Blocked { .. }) => Ok(MissionRun {
                reached: false,
                time_s: None,
                hit_person: false,
            }),
            Err(e) => Err(e),
        }
    };
    let batch = rayon::current_num_threads().max(1);
    let mut trial = ControllerTrial {
        missions: missions.len(),
        people: people.count_for(floor.world.free_region_area_m2()),
        seed,
        candidates: Vec::new(),
    };
    for choice in AUTO_ORDER
        .into_iter()
        .filter(|c| !c.needs_policy() || floor.policy.is_some())
    {
        let best = trial
            .pick(|_| true)
            .and_then(|p| trial.figures(p.choice).cloned());
        let mut figures = CandidateFigures {
            controller: choice.as_str().to_owned(),
            runs: Vec::with_capacity(missions.len()),
            wall_ms_per_mission: 0.0,
        };
        let started = std::time::Instant::now();
        for first in (0..missions.len()).step_by(batch) {
            let end = (first + batch).min(missions.len());
            let runs: Result<Vec<MissionRun>, PlanError> = (first..end)
                .into_par_iter()
                .map(|i| drive(choice, i))
                .collect();
            figures.runs.extend(runs?);
            // Hopeless against the pick so far or against the baseline (the pick must beat
            // both): the rest are not driven.
            let baseline = trial.candidates.first();
            if best
                .iter()
                .chain(baseline)
                .any(|b| futile(&figures, b, missions.len()))
            {
                break;
            }
        }
        figures.wall_ms_per_mission =
            started.elapsed().as_secs_f64() * 1e3 / figures.runs.len().max(1) as f64;
        trial.candidates.push(figures);
    }
    Ok(trial)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn figures(name: &str, times: &[Option<f64>]) -> CandidateFigures {
        CandidateFigures {
            controller: name.to_owned(),
            runs: times
                .iter()
                .map(|&t| MissionRun {
                    reached: t.is_some(),
                    time_s: t,
                    hit_person: false,
                })
                .collect(),
            wall_ms_per_mission: 1.0,
        }
    }

    fn trial(candidates: Vec<CandidateFigures>) -> ControllerTrial {
        ControllerTrial {
            missions: candidates[0].runs.len(),
            people: 0,
            seed: 0,
            candidates,
        }
    }

    #[test]
    fn the_signed_rank_test_counts_the_sign_patterns() {
        // Ten differences, all positive: one pattern in 1024 reaches that sum.
        let all: Vec<f64> = (1..=10).map(f64::from).collect();
        let (plus, minus, p) = signed_rank(&all);
        assert_eq!((plus, minus), (55.0, 0.0));
        assert!((p - 1.0 / 1024.0).abs() < 1e-12);
        // Ranks 1..4, the two largest positive: W+ = 7, reached by 5 of 16 subsets.
        let (plus, _, p) = signed_rank(&[-0.1, -0.2, 0.3, 0.4]);
        assert_eq!(plus, 7.0);
        assert!((p - 5.0 / 16.0).abs() < 1e-12);
        // All tied (every mission reached by one only): the sign test's binomial tail.
        let mut tied = vec![f64::INFINITY; 12];
        tied.extend([f64::NEG_INFINITY; 4]);
        let (_, _, p) = signed_rank(&tied);
        assert!((p - 0.038_406_372).abs() < 1e-6, "{p}");
        // Zeros (ties within the margin, or neither reached) are left out.
        assert_eq!(signed_rank(&[0.0, 0.0]), (0.0, 0.0, 1.0));
    }

    #[test]
    fn a_consistent_small_gain_is_measured_where_wins_alone_are_not() {
        // 16 missions: 10.0 s against 9.0 s on ten (10% faster), 10.0 against 10.3 on six: ten
        // wins of sixteen are no majority a sign test accepts (p = 0.23).
        let rpp = figures("rpp", &[Some(10.0); 16]);
        let times: Vec<Option<f64>> = (0..16)
            .map(|i| Some(if i % 3 == 0 { 10.3 } else { 9.0 }))
            .collect();
        let hybrid = figures("hybrid", &times);
        let (w, l) = wins(&hybrid, &rpp);
        assert_eq!((w, l), (10, 6));
        let pick = trial(vec![rpp, hybrid]).pick(|_| true).unwrap();
        assert_eq!(pick.choice, ControllerChoice::Hybrid, "{}", pick.why);
        assert!(
            pick.why.contains("Wilcoxon signed-rank p = 0.0"),
            "{}",
            pick.why
        );
    }

    #[test]
    fn a_policy_only_as_good_as_rpp_does_not_replace_it() {
        let rpp = figures("rpp", &[Some(10.0); 12]);
        // Faster on half the missions, slower on the other half: no measurable gain.
        let mut hybrid = figures("hybrid", &[Some(8.0); 12]);
        for r in hybrid.runs.iter_mut().take(6) {
            r.time_s = Some(12.0);
        }
        let pick = trial(vec![rpp, hybrid]).pick(|_| true).unwrap();
        assert_eq!(pick.choice, ControllerChoice::Rpp);
        assert!(
            pick.why
                .contains("no controller did measurably better than rpp")
        );
    }

    #[test]
    fn a_policy_consistently_faster_replaces_rpp_and_says_why() {
        let rpp = figures("rpp", &[Some(10.0); 12]);
        let mut times = vec![Some(8.0); 12];
        times[3] = None;
        let hybrid = figures("hybrid", &times);
        let pick = trial(vec![rpp, hybrid]).pick(|_| true).unwrap();
        assert_eq!(pick.choice, ControllerChoice::Hybrid);
        assert!(
            pick.why.contains("hybrid beat rpp on 11 of 12"),
            "{}",
            pick.why
        );
        // Without the policy the hybrid is not available.
        let rpp = figures("rpp", &[Some(10.0); 12]);
        let hybrid = figures("hybrid", &times);
        let pick = trial(vec![rpp, hybrid])
            .pick(|c| !c.needs_policy())
            .unwrap();
        assert_eq!(pick.choice, ControllerChoice::Rpp);
    }

    #[test]
    fn a_challenger_that_beats_another_challenger_but_not_rpp_is_not_picked() {
        // The hybrid is slow; hybrid_rpp beats it clearly but is 5% slower than RPP: RPP stays,
        // and the answer says what it compared with.
        let rpp = figures("rpp", &[Some(10.0); 12]);
        let hybrid = figures("hybrid", &[Some(14.0); 12]);
        let hybrid_rpp = figures("hybrid_rpp", &[Some(10.5); 12]);
        let pick = trial(vec![rpp.clone(), hybrid, hybrid_rpp])
            .pick(|_| true)
            .unwrap();
        assert_eq!(pick.choice, ControllerChoice::Rpp, "{}", pick.why);
        assert_eq!(pick.compared_with, Some(ControllerChoice::Rpp));
        // Two challengers better than RPP: the later one only when it also beats the earlier.
        let hybrid = figures("hybrid", &[Some(8.0); 12]);
        let hybrid_rpp = figures("hybrid_rpp", &[Some(9.0); 12]);
        let pick = trial(vec![rpp.clone(), hybrid.clone(), hybrid_rpp])
            .pick(|_| true)
            .unwrap();
        assert_eq!(pick.choice, ControllerChoice::Hybrid, "{}", pick.why);
        assert!(
            pick.why.contains("hybrid beat rpp on 12 of 12"),
            "{}",
            pick.why
        );
        let hybrid_path = figures("hybrid_path", &[Some(7.0); 12]);
        let pick = trial(vec![rpp, hybrid, hybrid_path])
            .pick(|_| true)
            .unwrap();
        assert_eq!(pick.choice, ControllerChoice::HybridPath, "{}", pick.why);
        assert!(pick.why.contains("hybrid_path beat rpp"), "{}", pick.why);
    }

    #[test]
    fn failures_count_against_a_faster_controller() {
        // MPPI is faster where it arrives but fails a third of the missions.
        let rpp = figures("rpp", &[Some(10.0); 12]);
        let mppi = figures(
            "mppi",
            &(0..12)
                .map(|i| (i % 3 != 0).then_some(9.0))
                .collect::<Vec<_>>(),
        );
        let pick = trial(vec![rpp, mppi]).pick(|_| true).unwrap();
        assert_eq!(pick.choice, ControllerChoice::Rpp);
    }

    #[test]
    fn a_challenger_stops_once_it_can_no_longer_win() {
        let best = figures("rpp", &[Some(10.0); 16]);
        // 16 missions need 12 wins of 16 decisive ones (p = 0.038): 4 losses still leave
        // that open, 5 do not.
        let four = figures("mppi", &[None, None, None, None]);
        assert!(!futile(&four, &best, 16));
        let five = figures("mppi", &[None; 5]);
        assert!(futile(&five, &best, 16));
        // With 6 missions every one must be won (p = 1/64).
        let one = figures("mppi", &[None]);
        assert!(futile(&one, &best, 6));
        let won = figures("mppi", &[Some(5.0); 3]);
        assert!(!futile(&won, &best, 6));
    }
}
