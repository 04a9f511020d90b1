//! `mentalsim bench edges`: every roadmap edge of every map under a directory, both
//! directions, driven by each controller (the policy as plans drive it, the policy behind the
//! shield alone, the policy with RPP handover, the classical follower, Nav2's RPP and MPPI) at
//! each people density; `edges.csv`, `edges.md` and one edge map per map and controller.

use std::path::PathBuf;
use std::sync::Arc;

use learning::Policy;
use sim::World;

use crate::error::{BenchError, io_err};

/// What `bench edges` runs.
#[derive(Debug, Clone)]
pub struct EdgeBenchOptions {
    /// Directory searched recursively for ROS map_server YAML files.
    pub maps: PathBuf,
    /// Exported policies, side by side.
    pub policies: Vec<PathBuf>,
    /// Rollouts per edge direction.
    pub rollouts: u32,
    /// At most this many edges per map (both directions each), a seeded sample; `None`: all.
    pub edges: Option<usize>,
    /// Seed of the roadmaps and rollouts.
    pub seed: u64,
    /// Where `edges.csv`, `edges.md` and the edge maps go.
    pub out: PathBuf,
    /// People densities (per 100 m² of free region), each its own rows; empty: 0.
    pub people: Vec<f64>,
    /// Controllers to drive (empty: all).
    pub controllers: Vec<String>,
    /// The robot's TOSM description (Turtle).
    pub robot_ttl: Vec<u8>,
    /// The robot's IRI in it.
    pub robot_iri: String,
}

/// The undirected edges of `roadmap` to drive: all, or `at_most` of them drawn with `seed`
/// (in the roadmap's order).
fn edge_sample(roadmap: &prm::Roadmap, at_most: Option<usize>, seed: u64) -> Vec<(usize, usize)> {
    use rand::SeedableRng;
    let all: Vec<(usize, usize)> = roadmap.edges().collect();
    match at_most {
        Some(n) if n < all.len() => {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut picked = rand::seq::index::sample(&mut rng, all.len(), n).into_vec();
            picked.sort_unstable();
            picked.into_iter().map(|i| all[i]).collect()
        }
        _ => all,
    }
}

/// The map with every roadmap edge in the colour of what the controller made of it: green
/// where both directions are kept (≥ the keep threshold), orange where one is, red where
/// neither is (drawn last, on top).
fn edge_map_png(
    world: &World,
    roadmap: &prm::Roadmap,
    report: &rehearsal::EdgeReport,
) -> Result<Vec<u8>, String> {
    let nodes: Vec<prm::Point2> = roadmap.nodes().collect();
    let keep = report.params.keep_threshold;
    let mut segments: Vec<(usize, sim::render::Segment)> = report
        .edges
        .chunks(2)
        .map(|pair| {
            let kept = pair.iter().filter(|e| e.success_rate() >= keep).count();
            let (a, b) = (nodes[pair[0].from], nodes[pair[0].to]);
            let rgb = match kept {
                2 => [40, 160, 70],
                1 => [240, 150, 0],
                _ => [220, 30, 30],
            };
            (
                kept,
                sim::render::Segment {
                    from: (a.x, a.y),
                    to: (b.x, b.y),
                    rgb,
                },
            )
        })
        .collect();
    segments.sort_by_key(|(kept, _)| std::cmp::Reverse(*kept));
    let overlay = sim::render::Overlay {
        segments: segments.into_iter().map(|(_, s)| s).collect(),
        ..sim::render::Overlay::default()
    };
    sim::render::png(world, &overlay, &sim::render::RenderOptions::default())
        .map_err(|e| format!("cannot draw the edge map: {e}"))
}

/// One row of `bench edges`: a controller on every roadmap edge of one map.
#[derive(Debug, Clone, serde::Serialize)]
pub struct EdgeBenchRow {
    /// The map's short name.
    pub map: String,
    /// `follower`, or the policy directory's name.
    pub controller: String,
    /// Edge directions driven.
    pub edge_directions: usize,
    /// Rollouts per direction.
    pub rollouts: u32,
    /// Successful rollouts.
    pub successes: u64,
    /// Rollouts that ended in a collision (the rest of the failures ran out of time).
    pub collisions: u64,
    /// Share of rollouts that arrived.
    pub edge_success_rate: f64,
    /// Edge directions driven in at least 90% of rollouts.
    pub kept: usize,
    /// Mean simulated time of the arrivals, seconds.
    pub mean_edge_time_s: Option<f64>,
    /// Share of rollouts closer than 10 cm to an obstacle.
    pub near_miss_rate: f64,
    /// Share of the control steps the follower drove inside the policy controller.
    pub handover_share: f64,
    /// Control steps of all rollouts.
    pub steps: u64,
    /// Wall-clock seconds of the rollouts.
    pub wall_s: f64,
}

/// `mentalsim bench edges`: every roadmap edge of every map under `maps`, both directions,
/// `rollouts` times, driven by each controller named in `controllers` (all when empty:
/// `policy`, `shield_only` and `hybrid_rpp` per policy, `follower`, `rpp`, `mppi`) at each
/// people density of `people` (per 100 m² of free region); `edges.csv` and `edges.md` in `out`.
pub fn run_edge_bench(options: &EdgeBenchOptions) -> Result<String, BenchError> {
    let EdgeBenchOptions {
        maps,
        policies,
        rollouts,
        edges,
        seed,
        out,
        people,
        controllers,
        robot_ttl,
        robot_iri,
    } = options;
    let (rollouts, seed) = (*rollouts, *seed);
    use rehearsal::ControllerChoice;
    let out = out.as_path();

    /// Which controller drives: one of the rehearsal's choices, or the policy without handover.
    #[derive(Clone, Copy)]
    enum Which {
        Choice(ControllerChoice),
        ShieldOnly,
    }

    fn drive_with(
        world: &Arc<World>,
        roadmap: &prm::Roadmap,
        some: &[(usize, usize)],
        which: Which,
        policy: Option<&Arc<Policy>>,
        params: &rehearsal::EdgeRolloutParams,
    ) -> Result<(rehearsal::EdgeReport, f64), BenchError> {
        let t = std::time::Instant::now();
        let report = match (which, policy) {
            (Which::ShieldOnly, Some(p)) => rehearsal::drive_some_edges(
                world,
                roadmap,
                some,
                || rehearsal::PolicyController::without_handover(Arc::clone(p)),
                params,
            ),
            (Which::ShieldOnly, None) => {
                return Err(BenchError::BadOption("shield_only needs a policy".into()));
            }
            (Which::Choice(c), p) => {
                if c.needs_policy() && p.is_none() {
                    return Err(BenchError::BadOption(format!(
                        "{} needs a policy",
                        c.as_str()
                    )));
                }
                let seed = params.seed;
                rehearsal::drive_some_edges(
                    world,
                    roadmap,
                    some,
                    || -> Box<dyn rehearsal::Controller + Send> {
                        c.build(p, seed)
                            .unwrap_or_else(|| Box::new(rehearsal::ClassicalFollower::default()))
                    },
                    params,
                )
            }
        }
        .map_err(|source| BenchError::Rehearsal {
            map: "edges".into(),
            source,
        })?;
        Ok((report, t.elapsed().as_secs_f64()))
    }

    if rollouts == 0 {
        return Err(BenchError::BadOption(
            "--rollouts must be at least 1".into(),
        ));
    }
    if *edges == Some(0) {
        return Err(BenchError::BadOption("--edges must be at least 1".into()));
    }
    if let Some(d) = people
        .iter()
        .find(|d| !(d.is_finite() && (0.0..=50.0).contains(*d)))
    {
        return Err(BenchError::BadOption(format!(
            "--people must lie in [0, 50] people per 100 m², got {d}"
        )));
    }
    const NAMES: [&str; 6] = [
        "policy",
        "shield_only",
        "hybrid_rpp",
        "follower",
        "rpp",
        "mppi",
    ];
    if let Some(c) = controllers.iter().find(|c| !NAMES.contains(&c.as_str())) {
        return Err(BenchError::BadOption(format!(
            "--controller {c}: one of {}",
            NAMES.join(", ")
        )));
    }
    let wanted = |n: &str| controllers.is_empty() || controllers.iter().any(|c| c == n);
    let densities: Vec<f64> = if people.is_empty() {
        vec![0.0]
    } else {
        people.to_vec()
    };
    let yamls = crate::maps::find_yamls(maps)?;
    if yamls.is_empty() {
        return Err(BenchError::NoMaps(maps.clone()));
    }
    let loaded: Vec<(String, Arc<Policy>)> = policies
        .iter()
        .map(|dir| {
            let name = dir.file_name().map_or_else(
                || dir.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            Policy::load(dir)
                .map(|p| (name, Arc::new(p)))
                .map_err(|e| BenchError::Format {
                    path: dir.clone(),
                    message: format!("cannot load the policy: {e}"),
                })
        })
        .collect::<Result<_, BenchError>>()?;
    // (display name, which, policy)
    let mut drivers: Vec<(String, Which, Option<&Arc<Policy>>)> = Vec::new();
    for (n, p) in &loaded {
        if wanted("policy") {
            drivers.push((n.clone(), Which::Choice(ControllerChoice::Hybrid), Some(p)));
        }
        if wanted("shield_only") {
            drivers.push((format!("{n} (shield only)"), Which::ShieldOnly, Some(p)));
        }
        if wanted("hybrid_rpp") {
            drivers.push((
                format!("{n} (RPP handover)"),
                Which::Choice(ControllerChoice::HybridRpp),
                Some(p),
            ));
        }
    }
    for (name, choice) in [
        ("follower", ControllerChoice::Follower),
        ("rpp", ControllerChoice::Rpp),
        ("mppi", ControllerChoice::Mppi),
    ] {
        if wanted(name) {
            drivers.push((name.to_owned(), Which::Choice(choice), None));
        }
    }
    let label = |name: &str, d: f64| {
        if d > 0.0 {
            format!("{name} @ {d} people/100 m²")
        } else {
            name.to_owned()
        }
    };
    let mut rows = Vec::new();
    for yaml in &yamls {
        let map = learning::run::map_name(yaml);
        let world = crate::sim::world_from_map(yaml, robot_ttl, robot_iri, 0, seed)?;
        let roadmap = rehearsal::first_attempt_roadmap(&world, seed).map_err(|source| {
            BenchError::Rehearsal {
                map: map.clone(),
                source,
            }
        })?;
        let some = edge_sample(&roadmap, *edges, seed);
        std::fs::create_dir_all(out).map_err(io_err(out))?;
        for &density in &densities {
            for (name, which, policy) in &drivers {
                let params = rehearsal::EdgeRolloutParams {
                    rollouts,
                    seed,
                    people_density: density,
                    ..rehearsal::EdgeRolloutParams::default()
                };
                let (report, wall_s) =
                    drive_with(&world, &roadmap, &some, *which, *policy, &params)?;
                let name = label(name, density);
                let slug = name
                    .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                    .filter(|w| !w.is_empty())
                    .collect::<Vec<_>>()
                    .join("-");
                let png_path = out.join(format!("{map}-{slug}.png"));
                let png = edge_map_png(&world, &roadmap, &report).map_err(|message| {
                    BenchError::Plot {
                        path: png_path.clone(),
                        message,
                    }
                })?;
                std::fs::write(&png_path, png).map_err(io_err(&png_path))?;
                let row = EdgeBenchRow {
                    map: map.clone(),
                    controller: name,
                    edge_directions: report.edges.len(),
                    rollouts,
                    successes: report.edges.iter().map(|e| u64::from(e.successes)).sum(),
                    collisions: report.edges.iter().map(|e| u64::from(e.collisions)).sum(),
                    edge_success_rate: report.edge_success_rate(),
                    kept: report.kept().count(),
                    mean_edge_time_s: report.mean_edge_time_s(),
                    near_miss_rate: report.near_miss_rate(),
                    handover_share: report.handover_share(),
                    steps: report.steps,
                    wall_s,
                };
                eprintln!(
                    "{:<28} {:<16} edges {:>5} success {:>6.2}% time {:>5.2} s near misses {:>5.1}%",
                    row.map,
                    row.controller,
                    row.edge_directions,
                    row.edge_success_rate * 100.0,
                    row.mean_edge_time_s.unwrap_or(f64::NAN),
                    row.near_miss_rate * 100.0
                );
                rows.push(row);
            }
        }
    }
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let mut csv = String::from(
        "map,controller,edge_directions,rollouts,successes,collisions,edge_success_rate,kept,mean_edge_time_s,near_miss_rate,handover_share,wall_s\n",
    );
    for r in &rows {
        csv.push_str(&format!(
            "{},{},{},{},{},{},{:.5},{},{},{:.5},{:.5},{:.2}\n",
            r.map,
            r.controller,
            r.edge_directions,
            r.rollouts,
            r.successes,
            r.collisions,
            r.edge_success_rate,
            r.kept,
            r.mean_edge_time_s
                .map_or(String::new(), |t| format!("{t:.3}")),
            r.near_miss_rate,
            r.handover_share,
            r.wall_s
        ));
    }
    let csv_path = out.join("edges.csv");
    std::fs::write(&csv_path, csv).map_err(io_err(&csv_path))?;
    // Pooled over maps: rollouts weighted equally; times weighted by arrivals.
    let names: Vec<String> = densities
        .iter()
        .flat_map(|&d| drivers.iter().map(move |(n, _, _)| (n, d)))
        .map(|(n, d)| label(n, d))
        .collect();
    let which = match edges {
        Some(n) => format!("A sample of at most {n} roadmap edges per map (seed {seed})"),
        None => "Every roadmap edge".to_owned(),
    };
    let mut md = format!(
        "# {which}, both directions, {rollouts} rollouts each (seed {seed})\n\nA policy drives behind the collision shield with the classical follower taking over within {} m of what the laser sees, as plans drive it; `(shield only)` is the same policy without that handover, `(RPP handover)` with Nav2's Regulated Pure Pursuit taking over instead of the follower; `rpp` and `mppi` are Nav2's Regulated Pure Pursuit and MPPI on the smoothed edge behind the same shield (Nav2's defaults scaled to the robot); `handover` is the share of control steps the follower drove. `@ d people/100 m²`: among people (each rollout its own draw; the executor's recoveries on).\n\n| map | controller | edge directions | success | collided | kept (≥ 90%) | mean edge time (s) | near misses (< 10 cm) | handover |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n",
        rehearsal::HANDOVER_MARGIN_M
    );
    for r in &rows {
        md.push_str(&format!(
            "| {} | {} | {} | {:.2}% | {:.2}% | {} | {} | {:.1}% | {:.1}% |\n",
            r.map,
            r.controller,
            r.edge_directions,
            r.edge_success_rate * 100.0,
            r.collisions as f64 * 100.0
                / (r.edge_directions as f64 * f64::from(r.rollouts)).max(1.0),
            r.kept,
            r.mean_edge_time_s.map_or("–".into(), |t| format!("{t:.2}")),
            r.near_miss_rate * 100.0,
            r.handover_share * 100.0
        ));
    }
    md.push_str("\n## Pooled over the maps\n\n| controller | rollouts | success | collided | mean edge time (s) | near misses | handover | maps at ≥ 99.5% |\n|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for name in &names {
        let mine: Vec<&EdgeBenchRow> = rows.iter().filter(|r| &r.controller == name).collect();
        let n: u64 = mine
            .iter()
            .map(|r| (r.edge_directions as u64) * u64::from(r.rollouts))
            .sum();
        let s: u64 = mine.iter().map(|r| r.successes).sum();
        let collided: u64 = mine.iter().map(|r| r.collisions).sum();
        let t: f64 = mine
            .iter()
            .filter_map(|r| r.mean_edge_time_s.map(|t| t * r.successes as f64))
            .sum();
        let near: f64 = mine
            .iter()
            .map(|r| r.near_miss_rate * (r.edge_directions as f64) * f64::from(r.rollouts))
            .sum();
        let good = mine.iter().filter(|r| r.edge_success_rate >= 0.995).count();
        let steps: u64 = mine.iter().map(|r| r.steps).sum();
        let handed: f64 = mine.iter().map(|r| r.handover_share * r.steps as f64).sum();
        let rate = |x: f64| if n == 0 { 0.0 } else { x / n as f64 };
        md.push_str(&format!(
            "| {} | {} | {:.3}% | {:.3}% | {:.2} | {:.2}% | {:.1}% | {}/{} |\n",
            name,
            n,
            rate(s as f64) * 100.0,
            rate(collided as f64) * 100.0,
            if s == 0 { f64::NAN } else { t / s as f64 },
            rate(near) * 100.0,
            if steps == 0 {
                0.0
            } else {
                handed * 100.0 / steps as f64
            },
            good,
            mine.len()
        ));
    }
    let md_path = out.join("edges.md");
    std::fs::write(&md_path, &md).map_err(io_err(&md_path))?;
    Ok(md)
}
