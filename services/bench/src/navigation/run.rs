//! One map of `mentalsim bench navigation`: every method on the map's mission, run after run.

use std::sync::Arc;
use std::time::Instant;

use grid::seed::mix;
use learning::Policy;
use prm::PrmParams;
use rehearsal::{
    AttemptDetails, AttemptOutcome, AttemptReport, ClassicalFollower, Controller, DriveLimits,
    MppiController, MppiCycles, PlanError, PlanOptions, PlanRequest, PolicyController,
    RoadmapCache, RppController,
};
use sim::{Action, Pose2, World};

use super::{Latency, Mission, NavigationBenchOptions, NavigationRow, PolicyEdges, ms, percentile};
use crate::error::BenchError;

/// Methods (first attempt, then the last), the controller, and which latency its validate
/// call is (0: the policy's, 1: the classical follower's).
type Plain = (&'static [&'static str], Box<dyn Controller>, Option<usize>);

pub(super) struct MapOutcome {
    pub(super) rows: Vec<NavigationRow>,
    pub(super) latency: Vec<Latency>,
    pub(super) edges: Option<PolicyEdges>,
    pub(super) mppi: MppiCycles,
}

pub(super) fn run_map(
    world: &Arc<World>,
    cache: &RoadmapCache,
    name: &str,
    mission: &Mission,
    policy: Option<&Arc<Policy>>,
    opts: &NavigationBenchOptions,
) -> Result<MapOutcome, BenchError> {
    let yaw = (mission.goal.y - mission.start.y).atan2(mission.goal.x - mission.start.x);
    let start = Pose2::new(mission.start.x, mission.start.y, yaw);
    let space = rehearsal::config_space(world, cache, name, opts.safety_margin_m)
        .map_err(|e| plan_err(name, &e))?;
    let people = sim::PeopleConfig {
        density: opts.people,
        ..sim::PeopleConfig::default()
    };
    let wants = |m: &str| opts.wants(m);
    let mut rows = Vec::new();
    let mut validate_ms: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let mut mppi_cycles = MppiCycles::default();
    let mut build_ms = Vec::new();
    // One policy-aware roadmap per map (on a geometric roadmap of its own seed): its rollouts
    // are the expensive part, built once per (floor, policy) as the service would; with
    // `policy_roadmap_per_run`, another one per run on that run's geometric roadmap (below).
    let rollout = rehearsal::EdgeRolloutParams {
        waypoint_timeout_s: opts.waypoint_timeout_s,
        seed: opts.seed,
        ..rehearsal::EdgeRolloutParams::default()
    };
    let on_policy_roadmap = [
        "plan_endpoint",
        "hybrid_policy_roadmap",
        "hybrid_policy_roadmap_resampled",
        "hybrid_policy_roadmap_rpp",
        "hybrid_policy_path",
    ];
    let policy_map = match policy {
        Some(p) if on_policy_roadmap.iter().any(|m| wants(m)) => {
            let t = Instant::now();
            let params = PrmParams {
                samples: prm::optimal_samples(space.free_area_m2),
                seed: opts.seed.wrapping_add(1000),
                ..PrmParams::default()
            };
            let (geometric, _) = cache
                .roadmap(name, &space, &params)
                .map_err(|e| plan_err(name, &e))?;
            let (roadmap, report) =
                policy_aware(world, &geometric, p, &rollout).map_err(|e| plan_err(name, &e))?;
            let build_s = t.elapsed().as_secs_f64();
            // The controller trial the `roadmap` job drives after the edges, here among the
            // bench's people: what `plan_endpoint` (`options.controller: auto`) validates with.
            let t = Instant::now();
            let auto = if wants("plan_endpoint") {
                let missions = planner::controllers::trial_missions(
                    &geometric,
                    planner::controllers::DEFAULT_TRIAL_MISSIONS as usize,
                    opts.seed,
                );
                let trial = planner::controllers::run_trial(
                    &planner::controllers::TrialFloor {
                        world,
                        roadmaps: cache,
                        version: name,
                        policy: Some(p),
                        policy_roadmap: Some(&roadmap),
                    },
                    &missions,
                    &people,
                    opts.seed,
                )
                .map_err(|e| plan_err(name, &e))?;
                trial.pick(|_| true).unwrap_or_else(|| {
                    planner::controllers::unmeasured("the map's trial drove no controller")
                })
            } else {
                planner::controllers::unmeasured("plan_endpoint was not asked for")
            };
            let edges = PolicyEdges {
                map: name.to_owned(),
                directions: report.edges.len(),
                kept: report.kept().count(),
                edge_success_rate: report.edge_success_rate(),
                rollouts: rollout.rollouts,
                steps: report.steps,
                build_s,
                auto,
                trial_s: t.elapsed().as_secs_f64(),
            };
            if opts.verbose {
                eprintln!(
                    "  policy-aware roadmap: {} of {} edge directions kept, edge success {:.1}%, {:.1} s",
                    edges.kept,
                    edges.directions,
                    100.0 * edges.edge_success_rate,
                    edges.build_s
                );
                eprintln!("  {} ({:.1} s)", edges.auto.why, edges.trial_s);
            }
            Some((roadmap, edges))
        }
        _ => None,
    };
    for run in 0..opts.runs {
        // Seeds far apart so the re-samples of one run never reuse another run's roadmap.
        let seed = opts.seed.wrapping_add(1000 * (run as u64 + 1));
        // The roadmap `POST /v1/plan` gives this robot (its salt), for every method alike.
        let salt = planner::roadmap_salt(&opts.robot_iri);
        let request = PlanRequest {
            start,
            goals: vec![mission.goal],
            options: PlanOptions {
                max_attempts: opts.max_attempts,
                waypoint_timeout_s: opts.waypoint_timeout_s,
                safety_margin_m: opts.safety_margin_m,
                seed,
                roadmap_salt: salt,
                trajectory_stride: 0,
                people: people.clone(),
                shortcut: opts.shortcut,
                ..PlanOptions::default()
            },
            stop: rehearsal::Stop::default(),
        };
        // The roadmap of the first attempt, built outside the timed call (the service builds it
        // once per map version and seed).
        let t = Instant::now();
        let params = PrmParams {
            samples: prm::optimal_samples(space.free_area_m2),
            seed: seed ^ salt,
            ..PrmParams::default()
        };
        let (geometric, _) = cache
            .roadmap(name, &space, &params)
            .map_err(|e| plan_err(name, &e))?;
        build_ms.push(ms(t));
        // The policy-aware roadmap this run's hybrids plan on: the map's, or this run's own.
        let run_policy_map = match (&policy_map, policy) {
            (Some((_, edges)), Some(p)) if opts.policy_roadmap_per_run => {
                let (roadmap, _) =
                    policy_aware(world, &geometric, p, &rollout).map_err(|e| plan_err(name, &e))?;
                Some((roadmap, edges))
            }
            (Some((roadmap, edges)), _) => Some((Arc::clone(roadmap), edges)),
            _ => None,
        };

        // The plain rehearsal of each controller on the first roadmap: its first attempt (and
        // its last, re-sampled, where the method has one).
        let mut plain: Vec<Plain> = vec![
            (
                &["classical_prm"],
                Box::new(ClassicalFollower::default()),
                Some(1),
            ),
            (
                &["classical_prm_shielded"],
                Box::new(rehearsal::ShieldedFollower::default()),
                None,
            ),
            (
                &["classical_rpp_shielded"],
                Box::new(RppController::new()),
                None,
            ),
        ];
        if let Some(p) = policy {
            plain.push((
                &["hybrid_prm_rl", "hybrid_prm_rl_resampled"],
                Box::new(PolicyController::new(Arc::clone(p))),
                Some(0),
            ));
            plain.push((
                &["hybrid_prm_rl_path"],
                Box::new(PolicyController::on_smoothed_path(Arc::clone(p))),
                None,
            ));
            if !people.any() {
                plain.push((
                    &["hybrid_prm_rl_no_handover"],
                    Box::new(PolicyController::without_handover(Arc::clone(p))),
                    None,
                ));
                plain.push((
                    &["hybrid_unshielded", "hybrid_unshielded_resampled"],
                    Box::new(PolicyController::without_shield(Arc::clone(p))),
                    None,
                ));
            }
        }
        for (methods, mut c, latency_of) in plain {
            if !methods.iter().any(|m| wants(m)) {
                continue;
            }
            let (first, last, elapsed) = timed_validate(world, cache, name, &request, &mut *c)?;
            if let Some(i) = latency_of {
                validate_ms[i].push(elapsed);
            }
            push_rows(
                &mut rows,
                methods,
                (name, run),
                (&first, &last),
                opts.verbose,
            );
        }
        if wants("classical_mppi_shielded") {
            let mut mppi = MppiController::new(seed);
            let (first, _, _) = timed_validate(world, cache, name, &request, &mut mppi)?;
            mppi_cycles = mppi_cycles.plus(mppi.cycles());
            rows.push(row("classical_mppi_shielded", name, run, &first));
        }

        let Some(policy) = policy else {
            continue;
        };
        if let Some((roadmap, edges)) = &run_policy_map
            && wants("plan_endpoint")
        {
            rows.push(endpoint_row(
                world,
                cache,
                name,
                run,
                &request,
                policy,
                (edges.auto.choice, roadmap),
            )?);
        }
        if let Some((roadmap, _)) = &run_policy_map {
            let on_roadmap: [(&[&'static str], PolicyController); 3] = [
                (
                    &["hybrid_policy_roadmap", "hybrid_policy_roadmap_resampled"],
                    PolicyController::new(Arc::clone(policy)),
                ),
                (
                    &["hybrid_policy_roadmap_rpp"],
                    PolicyController::with_rpp_handover(Arc::clone(policy)),
                ),
                (
                    &["hybrid_policy_path"],
                    PolicyController::on_smoothed_path(Arc::clone(policy)),
                ),
            ];
            for (methods, mut c) in on_roadmap {
                if !methods.iter().any(|m| wants(m)) {
                    continue;
                }
                let d = rehearsal::validate_detailed(
                    world,
                    cache,
                    name,
                    &request,
                    &mut c,
                    None,
                    Some(roadmap),
                );
                let (first, last) = match d.result {
                    Ok(report) => first_last(name, report.attempts, d.attempts)?,
                    Err(PlanError::NotValidated { attempts }) => {
                        first_last(name, attempts, d.attempts)?
                    }
                    // No kept edges join start and goal: a failure of the method, not of the
                    // bench.
                    Err(e @ (PlanError::Unreachable { .. } | PlanError::Map(_))) => {
                        for &method in methods {
                            rows.push(NavigationRow {
                                method,
                                map: name.to_owned(),
                                run,
                                success: false,
                                distance_m: 0.0,
                                time_s: 0.0,
                                reason: e.to_string(),
                                fallback_legs: 0,
                                person_collision: false,
                                min_person_clearance_m: None,
                                intimate_intrusions: 0,
                                personal_intrusions: 0,
                                path_length_m: 0.0,
                                time_not_moving_s: 0.0,
                                limit_time_s: 0.0,
                                recoveries: 0,
                            });
                        }
                        continue;
                    }
                    Err(e) => return Err(plan_err(name, &e)),
                };
                push_rows(
                    &mut rows,
                    methods,
                    (name, run),
                    (&first, &last),
                    opts.verbose,
                );
            }
        }
        if !wants("pure_rl") {
            continue;
        }
        // Pure RL: the policy behind the shield straight at the final goal.
        let mut shield_only = PolicyController::without_handover(Arc::clone(policy));
        shield_only.attach(world, policy.scaling().beams);
        shield_only.start_attempt(1);
        let timeout = (opts.pure_rl_seconds_per_10m * mission.prm_length_m / 10.0)
            .max(opts.pure_rl_seconds_per_10m);
        let env = sim::EnvConfig {
            people: people.clone(),
            ..rehearsal::env_config(policy.scaling().beams, true)
        };
        let pure = rehearsal::drive(
            world,
            &env,
            start,
            &[vec![mission.goal]],
            &mut shield_only,
            DriveLimits {
                waypoint_timeout_s: timeout,
                max_replans: 0,
                sim_seed: mix(seed, 0x0707),
                initial_velocity: Action::default(),
                stop: rehearsal::Stop::default(),
                trace: false,
                recoveries: rehearsal::recoveries_for(&request.options),
                others: None,
                holds: Vec::new(),
            },
            None,
        )
        .map_err(|e| plan_err(name, &e))?;
        rows.push(NavigationRow {
            method: "pure_rl",
            map: name.to_owned(),
            run,
            success: pure.outcome == AttemptOutcome::Reached,
            distance_m: pure.distance_m,
            time_s: pure.time_s,
            person_collision: rehearsal::hit_person(&pure.reason),
            reason: pure.reason,
            fallback_legs: 0,
            min_person_clearance_m: pure.min_person_clearance_m,
            intimate_intrusions: pure.social.intimate_intrusions,
            personal_intrusions: pure.social.personal_intrusions,
            path_length_m: pure.distance_m,
            time_not_moving_s: pure.social.time_not_moving_s,
            limit_time_s: pure.social.limit_time_s,
            recoveries: pure.recoveries.len(),
        });
    }
    let mut latency = Vec::new();
    for (i, controller) in ["policy", "classical"].into_iter().enumerate() {
        let v = &mut validate_ms[i];
        if v.is_empty() {
            continue;
        }
        latency.push(Latency {
            map: name.to_owned(),
            controller,
            p50_ms: percentile(v, 0.5),
            p99_ms: percentile(v, 0.99),
            roadmap_build_p50_ms: percentile(&mut build_ms.clone(), 0.5),
            samples: v.len(),
        });
    }
    Ok(MapOutcome {
        rows,
        latency,
        edges: policy_map.map(|(_, e)| e),
        mppi: mppi_cycles,
    })
}

/// The rows of one validation: its first attempt as `methods[0]`, its last as `methods[1]`
/// when the method has one.
fn push_rows(
    rows: &mut Vec<NavigationRow>,
    methods: &[&'static str],
    (name, run): (&str, usize),
    (first, last): (&Attempt, &Attempt),
    verbose: bool,
) {
    rows.push(row(methods[0], name, run, first));
    if let Some(&m) = methods.get(1) {
        rows.push(row(m, name, run, last));
    }
    if verbose {
        eprintln!(
            "  run {run}: {} {} {:.1} m {:.1} s",
            methods[0],
            first.0.outcome.as_str(),
            first.0.distance_m,
            first.0.simulated_time_s
        );
    }
}

fn plan_err(name: &str, e: &PlanError) -> BenchError {
    BenchError::BadOption(format!("{name}: {e}"))
}

/// An attempt's report and what it measured beyond it.
type Attempt = (AttemptReport, Option<AttemptDetails>);

/// One validate call: its first attempt, its last attempt (the validating one on success), and
/// its wall time in ms. A plan that no attempt validated is a result here, not an error.
fn timed_validate(
    world: &Arc<World>,
    cache: &RoadmapCache,
    name: &str,
    request: &PlanRequest,
    controller: &mut dyn Controller,
) -> Result<(Attempt, Attempt, f64), BenchError> {
    let t = Instant::now();
    let d = rehearsal::validate_detailed(world, cache, name, request, controller, None, None);
    let elapsed = ms(t);
    let attempts = match d.result {
        Ok(report) => report.attempts,
        Err(PlanError::NotValidated { attempts }) => attempts,
        Err(e) => return Err(plan_err(name, &e)),
    };
    let (first, last) = first_last(name, attempts, d.attempts)?;
    Ok((first, last, elapsed))
}

/// The first and the last attempt of a validation, with their details.
fn first_last(
    name: &str,
    attempts: Vec<AttemptReport>,
    details: Vec<AttemptDetails>,
) -> Result<(Attempt, Attempt), BenchError> {
    match (attempts.first(), attempts.last()) {
        (Some(f), Some(l)) => Ok((
            (f.clone(), details.first().cloned()),
            (l.clone(), details.get(attempts.len() - 1).cloned()),
        )),
        _ => Err(BenchError::BadOption(format!("{name}: no attempt ran"))),
    }
}

/// What the plan endpoint answers for `request`: the policy, and the follower for legs the
/// policy validated in no attempt.
fn endpoint_row(
    world: &Arc<World>,
    cache: &RoadmapCache,
    name: &str,
    run: usize,
    request: &PlanRequest,
    policy: &Arc<Policy>,
    (auto, policy_roadmap): (rehearsal::ControllerChoice, &Arc<prm::Roadmap>),
) -> Result<NavigationRow, BenchError> {
    // As the planner validates with `auto`'s pick: the policy-aware roadmap for a hybrid, the
    // classical follower (shielded among people) for a leg the pick validates in no attempt.
    let mut controller = auto
        .build(Some(policy), request.options.seed)
        .ok_or_else(|| {
            BenchError::BadOption(format!("{name}: {} needs a policy", auto.as_str()))
        })?;
    let mut follower = rehearsal::follower_for(&request.options);
    let d = rehearsal::validate_detailed(
        world,
        cache,
        name,
        request,
        &mut *controller,
        Some(&mut *follower),
        auto.needs_policy().then_some(policy_roadmap),
    );
    Ok(match d.result {
        Ok(report) => {
            let fallback_legs = report
                .legs
                .iter()
                .filter(|l| l.controller != report.controller)
                .count();
            // The validating attempts' social metrics, summed over the legs.
            let validating: Vec<&AttemptDetails> = report
                .attempts
                .iter()
                .zip(&d.attempts)
                .filter(|(a, _)| a.outcome == AttemptOutcome::Reached)
                .map(|(_, x)| x)
                .collect();
            let social = validating
                .iter()
                .fold(rehearsal::SocialMetrics::default(), |s, x| s.plus(x.social));
            NavigationRow {
                method: "plan_endpoint",
                map: name.to_owned(),
                run,
                success: true,
                distance_m: report.distance_m,
                time_s: report.simulated_time_s,
                reason: format!(
                    "validated with {}; {fallback_legs} of {} legs by the classical follower",
                    auto.as_str(),
                    report.legs.len()
                ),
                fallback_legs,
                person_collision: false,
                min_person_clearance_m: report
                    .attempts
                    .iter()
                    .filter(|a| a.outcome == AttemptOutcome::Reached)
                    .filter_map(|a| a.min_person_clearance_m)
                    .reduce(f64::min),
                intimate_intrusions: social.intimate_intrusions,
                personal_intrusions: social.personal_intrusions,
                path_length_m: report.distance_m,
                time_not_moving_s: social.time_not_moving_s,
                limit_time_s: social.limit_time_s,
                recoveries: validating.iter().map(|x| x.recoveries.len()).sum(),
            }
        }
        Err(PlanError::NotValidated { attempts }) => {
            let last = attempts
                .last()
                .ok_or_else(|| BenchError::BadOption(format!("{name}: no attempt ran")))?;
            let details = d.attempts.get(attempts.len() - 1).cloned();
            NavigationRow {
                fallback_legs: 0,
                ..row("plan_endpoint", name, run, &(last.clone(), details))
            }
        }
        Err(e) => return Err(plan_err(name, &e)),
    })
}

fn row(method: &'static str, map: &str, run: usize, (a, d): &Attempt) -> NavigationRow {
    let social = d.as_ref().map(|d| d.social).unwrap_or_default();
    NavigationRow {
        person_collision: rehearsal::hit_person(&a.reason),
        min_person_clearance_m: a.min_person_clearance_m,
        method,
        map: map.to_owned(),
        run,
        success: a.outcome == AttemptOutcome::Reached,
        distance_m: a.distance_m,
        time_s: a.simulated_time_s,
        reason: a.reason.clone(),
        fallback_legs: 0,
        intimate_intrusions: social.intimate_intrusions,
        personal_intrusions: social.personal_intrusions,
        path_length_m: a.distance_m,
        time_not_moving_s: social.time_not_moving_s,
        limit_time_s: social.limit_time_s,
        recoveries: d.as_ref().map_or(0, |d| d.recoveries.len()),
    }
}

/// The policy-aware roadmap of `geometric` as the plan endpoint's `auto` plans on it: every edge
/// driven by `policy` ([`rehearsal::policy_roadmap`]), every measured direction kept, the unkept
/// ones only where the kept ones join no route; with the edges' report.
fn policy_aware(
    world: &Arc<World>,
    geometric: &prm::Roadmap,
    policy: &Arc<Policy>,
    rollout: &rehearsal::EdgeRolloutParams,
) -> Result<(Arc<prm::Roadmap>, rehearsal::EdgeReport), PlanError> {
    let (_, report) = rehearsal::policy_roadmap(world, geometric, policy, rollout)?;
    let roadmap = rehearsal::reweight_with_unkept(geometric, &report)?;
    Ok((roadmap, report))
}
