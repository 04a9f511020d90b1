//! What `mentalsim bench navigation` writes: `navigation.csv` (one row per run) and
//! `navigation.md` (the tables per method, over all maps and per map, with the social metrics
//! per 100 m driven).

use std::fmt::Write as _;

use super::{
    Latency, METHODS, Mission, MppiCost, NavigationBenchOptions, NavigationRow, PolicyEdges,
};

/// `navigation.csv`: method, map, run, success, distance_m, time_s, person_collision,
/// min_person_clearance_m (empty without people), and the social metrics of Francis et al.
/// 2023 / HuNavSim: intimate_intrusions, personal_intrusions, path_length_m,
/// time_not_moving_s; then the recoveries tried, and the time the driven line takes at the
/// robot's top speeds (limit_time_s).
pub fn to_csv(rows: &[NavigationRow]) -> String {
    let mut s = String::from(
        "method,map,run,success,distance_m,time_s,person_collision,min_person_clearance_m,intimate_intrusions,personal_intrusions,path_length_m,time_not_moving_s,recoveries,limit_time_s\n",
    );
    for r in rows {
        let map = if r.map.contains([',', '"', '\n']) {
            format!("\"{}\"", r.map.replace('"', "\"\""))
        } else {
            r.map.clone()
        };
        let _ = writeln!(
            s,
            "{},{},{},{},{:.3},{:.3},{},{},{},{},{:.3},{:.1},{},{:.3}",
            r.method,
            map,
            r.run,
            r.success,
            r.distance_m,
            r.time_s,
            r.person_collision,
            r.min_person_clearance_m
                .map_or_else(String::new, |c| format!("{c:.3}")),
            r.intimate_intrusions,
            r.personal_intrusions,
            r.path_length_m,
            r.time_not_moving_s,
            r.recoveries,
            r.limit_time_s
        );
    }
    s
}

/// Success rate and means of a set of runs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    /// Runs.
    pub runs: usize,
    /// Successful runs.
    pub successes: usize,
    /// Mean distance over successes, metres.
    pub success_distance: Option<f64>,
    /// Mean time over successes, seconds.
    pub success_time: Option<f64>,
    /// Mean over successes of the time their driven lines take at the top speeds, seconds.
    pub success_limit_time: Option<f64>,
    /// Mean distance over failures, metres.
    pub failure_distance: Option<f64>,
    /// Runs that ended by touching a person.
    pub person_collisions: usize,
    /// Runs that came within [`rehearsal::NEAR_MISS_M`] of a person without touching one.
    pub person_near_misses: usize,
    /// Distance driven over all runs, metres.
    pub distance_total: f64,
    /// Intimate-space intrusions over all runs.
    pub intimate: u64,
    /// Personal-space intrusions over all runs.
    pub personal: u64,
    /// Time not moving over all runs, seconds.
    pub not_moving_s: f64,
    /// Recoveries over all runs.
    pub recoveries: usize,
}

impl Stats {
    /// The statistics of `rows`.
    pub fn of<'a>(rows: impl Iterator<Item = &'a NavigationRow>) -> Stats {
        let (mut n, mut ok) = (0usize, 0usize);
        let (mut sd, mut st, mut fd, mut sl) = (0.0, 0.0, 0.0, 0.0);
        let (mut hit, mut near) = (0usize, 0usize);
        let (mut dist, mut intimate, mut personal, mut still, mut rec) = (0.0, 0, 0, 0.0, 0);
        for r in rows {
            n += 1;
            dist += r.path_length_m;
            intimate += u64::from(r.intimate_intrusions);
            personal += u64::from(r.personal_intrusions);
            still += r.time_not_moving_s;
            rec += r.recoveries;
            if r.person_collision {
                hit += 1;
            } else if r
                .min_person_clearance_m
                .is_some_and(|c| c < rehearsal::NEAR_MISS_M)
            {
                near += 1;
            }
            if r.success {
                ok += 1;
                sd += r.distance_m;
                st += r.time_s;
                sl += r.limit_time_s;
            } else {
                fd += r.distance_m;
            }
        }
        let mean = |sum: f64, k: usize| (k > 0).then(|| sum / k as f64);
        Stats {
            runs: n,
            successes: ok,
            success_distance: mean(sd, ok),
            success_time: mean(st, ok),
            success_limit_time: mean(sl, ok),
            failure_distance: mean(fd, n - ok),
            person_collisions: hit,
            person_near_misses: near,
            distance_total: dist,
            intimate,
            personal,
            not_moving_s: still,
            recoveries: rec,
        }
    }

    /// `x` per 100 m driven (`None` when nothing was driven).
    pub fn per_100m(&self, x: f64) -> Option<f64> {
        (self.distance_total > 0.0).then(|| 100.0 * x / self.distance_total)
    }

    /// Share of successes.
    pub fn rate(&self) -> f64 {
        if self.runs == 0 {
            0.0
        } else {
            self.successes as f64 / self.runs as f64
        }
    }
}

/// How often the plan endpoint needed the classical follower, when it ran.
pub(super) fn fallback_line(rows: &[NavigationRow]) -> Option<String> {
    let endpoint: Vec<&NavigationRow> = rows
        .iter()
        .filter(|r| r.method == "plan_endpoint")
        .collect();
    if endpoint.is_empty() {
        return None;
    }
    let with = endpoint.iter().filter(|r| r.fallback_legs > 0).count();
    let legs: usize = endpoint.iter().map(|r| r.fallback_legs).sum();
    Some(format!(
        "plan_endpoint: the classical follower validated {legs} leg(s) the picked controller could not, in {with} of {} runs ({:.0}%)",
        endpoint.len(),
        100.0 * with as f64 / endpoint.len() as f64
    ))
}

pub(super) fn fmt_opt(v: Option<f64>, unit: &str) -> String {
    v.map_or_else(|| "—".to_owned(), |v| format!("{v:.2} {unit}"))
}

fn cell(v: Option<f64>) -> String {
    v.map_or_else(|| "—".to_owned(), |v| format!("{v:.2}"))
}

fn table(out: &mut String, rows: &[&NavigationRow], people: bool) {
    out.push_str("| Method | Success: avg distance (m) | Success: avg time (s) | Its line at the top speeds (s) | Failure: avg distance (m) | Success rate | Not moving (s per 100 m) | Recoveries |");
    out.push_str(if people {
        " Collisions with people | Near misses (< 10 cm of a person) | Intimate intrusions per 100 m | Personal intrusions per 100 m |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    } else {
        "\n|---|---|---|---|---|---|---|---|\n"
    });
    for m in METHODS {
        let st = Stats::of(rows.iter().copied().filter(|r| r.method == m));
        if st.runs == 0 {
            continue;
        }
        let _ = write!(
            out,
            "| {m} | {} | {} | {} | {} | {:.0}% ({}/{}) |",
            cell(st.success_distance),
            cell(st.success_time),
            cell(st.success_limit_time),
            cell(st.failure_distance),
            100.0 * st.rate(),
            st.successes,
            st.runs
        );
        let _ = write!(
            out,
            " {} | {} |",
            cell(st.per_100m(st.not_moving_s)),
            st.recoveries
        );
        if people {
            let _ = write!(
                out,
                " {} | {} | {} | {} |",
                st.person_collisions,
                st.person_near_misses,
                cell(st.per_100m(st.intimate as f64)),
                cell(st.per_100m(st.personal as f64))
            );
        }
        out.push('\n');
    }
}

pub(super) fn to_markdown(
    opts: &NavigationBenchOptions,
    missions: &[Mission],
    rows: &[NavigationRow],
    latency: &[Latency],
    skipped: &[(String, String)],
    edges: &[PolicyEdges],
    mppi: &[MppiCost],
) -> String {
    let mut s =
        String::from("# Long-range navigation (paper Table 3) in the mental simulation\n\n");
    let _ = writeln!(
        s,
        "{} runs per method and map; one mission per map of about {} m of roadmap path where the map allows (otherwise the longest route among {} sampled points of the largest free region); waypoint timer {} s; safety margin {} m; {} furniture objects; {} people per 100 m² of free region (drawn afresh per run and attempt; radius 0.2–0.3 m, 0.6–1.3 m/s, ORCA sharing the avoidance with the robot); seed {}.\n",
        opts.runs,
        opts.mission_length_m,
        opts.candidates,
        opts.waypoint_timeout_s,
        opts.safety_margin_m,
        opts.objects,
        opts.people,
        opts.seed
    );
    if opts.shortcut {
        s.push_str("Every method's roadmap path has its detours removed (`--shortcut`: each waypoint joined to the farthest one in straight sight, the plan endpoint's `options.shortcut`); `auto`'s trial keeps the default.\n\n");
    }
    if opts.policy_roadmap_per_run {
        s.push_str("The policy-aware roadmap is built again in every run on that run's geometric roadmap, the one the classical methods drive (`--policy-roadmap-per-run`); the controller trial and the edge table below are the first build's.\n\n");
    }
    match &opts.policy {
        Some(p) => {
            let _ = writeln!(s, "Policy: `{}`.\n", p.display());
        }
        None => s.push_str(
            "**No policy given: only the classical controllers (`classical_prm`, `classical_prm_shielded`, `classical_rpp_shielded`, `classical_mppi_shielded`) ran.** Pass an exported policy directory to run hybrid PRM-RL and pure RL.\n\n",
        ),
    }
    s.push_str(
        "Methods: `hybrid_prm_rl` = the policy through the roadmap's waypoints (15 s timer, replanning) behind the collision shield, the classical follower taking over where the policy would come within 0.3 m of what the laser sees, until the policy's own command has kept that margin for 1 s with no person within 1.2 m or the next waypoint, first attempt only — the paper's measure; `hybrid_prm_rl_no_handover` = the same without the follower's handover (the shield alone); `hybrid_policy_roadmap` = the same controller on the policy-aware roadmap (PRM-RL, below), first attempt, and `_resampled` with re-tries; `hybrid_unshielded` = the paper's hybrid, the policy's commands unchanged; `hybrid_prm_rl_resampled` = the plan endpoint's behaviour, up to ",
    );
    let _ = write!(s, "{}", opts.max_attempts);
    s.push_str(
        " roadmap re-samples after a collision or stall, success = a validated plan, distance and time of the validating drive; `plan_endpoint` = what `POST /v1/plan` answers with `options.controller: auto`: the controller the map's trial picks (below; a hybrid on the policy-aware roadmap), re-sampled likewise, then the classical follower (re-sampled too) when no attempt validated the mission, so it is never worse than `classical_prm`; `pure_rl` = the policy behind the shield straight at the final goal; `classical_prm` = rotate-then-go follower on the roadmap's waypoints, first attempt; `classical_prm_shielded` = the same behind the shield; `classical_rpp_shielded` = Nav2's Regulated Pure Pursuit and `classical_mppi_shielded` = Nav2's MPPI, each on the roadmap path smoothed as Nav2's Simple Smoother does, passing through the vertices, behind the same shield, first attempt (Nav2's documented defaults scaled to the robot, never tuned on these maps); `hybrid_policy_roadmap_rpp` = `hybrid_policy_roadmap` with Regulated Pure Pursuit as the follower the policy hands over to; `hybrid_policy_path` = the same with the policy steering to a carrot 1.2 m ahead on the smoothed path instead of to each vertex. Among people every method tries Nav2's recovery behaviours (wait, back up, spin, re-route around the blocked edge) when it moves less than 0.5 m in 10 s; in the empty building the waypoint timer and replanning alone, as before. Social metrics (Francis et al. 2023, HuNavSim): entries into a person's intimate (0.45 m) and personal (1.2 m) space, counted once per approach, and the time the robot stands still, each per 100 m driven over all runs (failed ones too). Distances are driven distances; failures count the distance driven before the collision or stall.\n\n",
    );
    s.push_str("The paper's Table 3 (Gazebo, one building, ~140 m): Move Base 141.04 m / 123.31 s / 100%; Constrained Move Base 140.21 m / 125.19 s, failure 26.87 m / 60%; Pure RL failure 14.7 m / 0%; Hybrid PRM-RL 149.71 m / 160.45 s, failure 102.4 m / 90%.\n\n");

    s.push_str("## All maps\n\n");
    let all: Vec<&NavigationRow> = rows.iter().collect();
    table(&mut s, &all, opts.people > 0.0);
    if let Some(line) = fallback_line(rows) {
        let _ = writeln!(s, "\n{line}.");
    }

    verdict(&mut s, rows, opts.people);
    if mppi.iter().any(|m| m.cycles.cycles > 0) {
        s.push_str("\n## MPPI's cost per control cycle\n\nWall time of one MPPI control cycle (sampling, rollouts and critics, one thread) on this machine, and the mean critic cost of the optimal rollout.\n\n| Map | Cycles | Rollouts × steps | Mean (ms) | Max (ms) | Mean optimal cost |\n|---|---|---|---|---|---|\n");
        for m in mppi.iter().filter(|m| m.cycles.cycles > 0) {
            let c = &m.cycles;
            let _ = writeln!(
                s,
                "| {} | {} | {} × {} | {:.2} | {:.2} | {:.2} |",
                m.map,
                c.cycles,
                c.batch_size,
                c.time_steps,
                c.mean_ms(),
                1e3 * c.max_s,
                c.mean_cost()
            );
        }
    }
    s.push_str("\n## Missions\n\n| Map | Start | Goal | Roadmap path (m) | Straight line (m) | Full length | Free area (m²) | World build (ms) |\n|---|---|---|---|---|---|---|---|\n");
    for m in missions {
        let _ = writeln!(
            s,
            "| {} | ({:.2}, {:.2}) | ({:.2}, {:.2}) | {:.1} | {:.1} | {} | {:.0} | {:.0} |",
            m.map,
            m.start.x,
            m.start.y,
            m.goal.x,
            m.goal.y,
            m.prm_length_m,
            m.straight_m,
            if m.full_length { "yes" } else { "no" },
            m.free_area_m2,
            m.world_build_ms
        );
    }

    if !edges.is_empty() {
        s.push_str("\n## The policy on the roadmap edges\n\nEvery edge of the map's geometric roadmap driven by the policy as plans drive it (shield and handover), both directions, 10 rollouts each (heading as if arriving over a neighbouring edge, at rest in even rollouts and at half the top speed in odd ones, noise on); kept where at least 90% succeed. Build = the rollouts and the reweighting, wall time on this machine's cores.\n\n| Map | Edge directions | Kept | Edge success rate | Simulated steps | Build (s) |\n|---|---|---|---|---|---|\n");
        for e in edges {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.2}% | {} | {:.1} |",
                e.map,
                e.directions,
                e.kept,
                100.0 * e.edge_success_rate,
                e.steps,
                e.build_s
            );
        }
        s.push_str("\n## What `options.controller: auto` picks\n\nThe controller trial the `roadmap` job drives after the edges (`planner::controllers`): 16 missions between the geometric roadmap's nodes, each driven once by every candidate with the same seeds, among this run's people; a candidate replaces the classical pick only when its wins outweigh its losses and a one-sided Wilcoxon signed-rank test on the missions' times gives p < 0.05. `plan_endpoint` validates with this pick.\n\n| Map | Pick | Why | Trial (s) |\n|---|---|---|---|\n");
        for e in edges {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.1} |",
                e.map,
                e.auto.choice.as_str(),
                e.auto.why.replace('|', "/"),
                e.trial_s
            );
        }
    }

    s.push_str("\n## Plan latency\n\nWall time of one `rehearsal::validate` call for the map's long mission (roadmap of the first attempt cached, as the service keeps it per map version; re-samples build theirs inside the call), and of building that roadmap once.\n\n| Map | Controller | p50 (ms) | p99 (ms) | Calls | Roadmap build p50 (ms) |\n|---|---|---|---|---|---|\n");
    for l in latency {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {} | {:.1} |",
            l.map, l.controller, l.p50_ms, l.p99_ms, l.samples, l.roadmap_build_p50_ms
        );
    }

    for m in missions {
        let _ = writeln!(
            s,
            "\n## {} ({:.1} m of roadmap path)\n",
            m.map, m.prm_length_m
        );
        let mine: Vec<&NavigationRow> = rows.iter().filter(|r| r.map == m.map).collect();
        table(&mut s, &mine, opts.people > 0.0);
        let failures: Vec<&&NavigationRow> = mine.iter().filter(|r| !r.success).collect();
        if !failures.is_empty() {
            // Up to a few per method, so no method's failures hide another's.
            s.push_str("\nFailures (at most 5 per method):\n\n");
            let mut shown: Vec<(&str, usize)> = Vec::new();
            for r in failures {
                let n = match shown.iter_mut().find(|(m, _)| *m == r.method) {
                    Some((_, n)) => n,
                    None => {
                        shown.push((r.method, 0));
                        &mut shown.last_mut().expect("just pushed").1
                    }
                };
                *n += 1;
                if *n <= 5 {
                    let _ = writeln!(s, "- {} run {}: {}", r.method, r.run, r.reason);
                }
            }
        }
    }
    if !skipped.is_empty() {
        s.push_str("\n## Skipped maps\n\n");
        for (m, why) in skipped {
            let _ = writeln!(s, "- {m}: {why}");
        }
    }
    s
}

/// How `method`'s mean time on success compares with `baseline`'s map by map: the mean of the
/// per-map ratios, their range and standard error, in words. One map's ratio is one draw of
/// routes (a method on the policy-aware roadmap drives that map's one roadmap in every run), so
/// the spread over maps says how far the mean can be trusted. `None` below two maps.
fn per_map_ratio(rows: &[NavigationRow], method: &str, baseline: &str) -> Option<String> {
    let mean_time = |m: &str, map: &str| {
        let t: Vec<f64> = rows
            .iter()
            .filter(|r| r.method == m && r.map == map && r.success)
            .map(|r| r.time_s)
            .collect();
        (!t.is_empty()).then(|| t.iter().sum::<f64>() / t.len() as f64)
    };
    let mut maps: Vec<&str> = rows.iter().map(|r| r.map.as_str()).collect();
    maps.sort_unstable();
    maps.dedup();
    let ratios: Vec<f64> = maps
        .iter()
        .filter_map(|map| Some(mean_time(method, map)? / mean_time(baseline, map)?))
        .collect();
    let n = ratios.len();
    if n < 2 {
        return None;
    }
    let mean = ratios.iter().sum::<f64>() / n as f64;
    let var = ratios.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let se = (var / n as f64).sqrt();
    let (lo, hi) = ratios
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| {
            (a.min(*r), b.max(*r))
        });
    Some(format!(
        "per map, its mean time over `{baseline}`'s: {mean:.2} on average ({lo:.2}–{hi:.2}, standard error {se:.3} over {n} maps)"
    ))
}

/// The targets, checked on these runs: each hybrid on the policy-aware roadmap against
/// the better of the shielded Regulated Pure Pursuit and MPPI (by mean time on success).
fn verdict(s: &mut String, rows: &[NavigationRow], people: f64) {
    let st = |m: &str| Stats::of(rows.iter().filter(|r| r.method == m));
    let classical = ["classical_rpp_shielded", "classical_mppi_shielded"]
        .into_iter()
        .map(|m| (m, st(m)))
        .filter(|(_, s)| s.success_time.is_some())
        .min_by(|a, b| {
            // More successes first, then the faster.
            let t = |s: &Stats| s.success_time.unwrap_or(f64::INFINITY);
            b.1.rate()
                .total_cmp(&a.1.rate())
                .then(t(&a.1).total_cmp(&t(&b.1)))
        });
    let Some((best, b)) = classical else {
        return;
    };
    let hybrids: Vec<(&str, Stats)> = [
        "hybrid_policy_roadmap",
        "hybrid_policy_path",
        "hybrid_policy_roadmap_rpp",
    ]
    .into_iter()
    .map(|m| (m, st(m)))
    .filter(|(_, h)| h.runs > 0)
    .collect();
    if hybrids.is_empty() {
        return;
    }
    let (rate_target, speed_target) = if people > 0.0 {
        (0.97, 0.15)
    } else {
        (0.99, 0.10)
    };
    let yes = |ok: bool| if ok { "met" } else { "**not met**" };
    let _ = writeln!(
        s,
        "\n## Who wins\n\nEach hybrid on the policy-aware roadmap against the better of the shielded Nav2 controllers here, `{best}` (by success rate, then mean time on success)."
    );
    for (name, hybrid) in hybrids {
        let faster = match (hybrid.success_time, b.success_time) {
            (Some(h), Some(c)) if c > 0.0 => Some(1.0 - h / c),
            _ => None,
        };
        let _ = writeln!(s, "\n`{name}`:\n");
        let _ = writeln!(
            s,
            "- first-attempt success {:.1}% (target ≥ {:.0}%): {}",
            100.0 * hybrid.rate(),
            100.0 * rate_target,
            yes(hybrid.rate() >= rate_target)
        );
        let _ = writeln!(
            s,
            "- faster by {} (target ≥ {:.0}%): {}",
            faster.map_or_else(|| "—".to_owned(), |f| format!("{:.1}%", 100.0 * f)),
            100.0 * speed_target,
            yes(faster.is_some_and(|f| f >= speed_target))
        );
        if let Some(spread) = per_map_ratio(rows, name, best) {
            let _ = writeln!(s, "- {spread}");
        }
        if people > 0.0 {
            let _ = writeln!(
                s,
                "- collisions with people: {} (target 0): {}",
                hybrid.person_collisions,
                yes(hybrid.person_collisions == 0)
            );
            let (h, c) = (
                hybrid.per_100m(hybrid.personal as f64),
                b.per_100m(b.personal as f64),
            );
            let _ = writeln!(
                s,
                "- personal-space intrusions per 100 m: {} against {} (target: no more): {}",
                cell(h),
                cell(c),
                yes(matches!((h, c), (Some(h), Some(c)) if h <= c))
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: &'static str, map: &str, success: bool, time_s: f64) -> NavigationRow {
        NavigationRow {
            method,
            map: map.to_owned(),
            run: 0,
            success,
            distance_m: 1.0,
            time_s,
            reason: String::new(),
            fallback_legs: 0,
            person_collision: false,
            min_person_clearance_m: None,
            intimate_intrusions: 0,
            personal_intrusions: 0,
            path_length_m: 1.0,
            time_not_moving_s: 0.0,
            limit_time_s: 0.0,
            recoveries: 0,
        }
    }

    #[test]
    fn per_map_ratios_show_their_spread() {
        let rows = [
            row("a", "m1", true, 8.0),
            row("a", "m1", true, 10.0),
            row("a", "m1", false, 1.0),
            row("b", "m1", true, 10.0),
            row("a", "m2", true, 12.0),
            row("b", "m2", true, 10.0),
            // Only one method reached on m3: left out.
            row("b", "m3", true, 10.0),
        ];
        // m1: 9 / 10, m2: 12 / 10; mean 1.05, sample sd 0.212, standard error 0.150.
        let s = per_map_ratio(&rows, "a", "b").expect("two maps");
        assert!(
            s.contains("1.05 on average (0.90–1.20, standard error 0.150 over 2 maps)"),
            "{s}"
        );
        assert!(per_map_ratio(&rows[..4], "a", "b").is_none());
    }
}
