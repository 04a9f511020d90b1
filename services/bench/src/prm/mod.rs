//! The PRM benchmark (paper §5.1: Table 2, Figure 9) on ROS map_server maps, ours beside OMPL.
//!
//! Protocol, as the paper's: for every map and every n, `runs` times build a fresh roadmap
//! (new seed) and ask it for a path between a random start and goal in the largest free region.
//! The configuration space (distance transform, inflation, regions) is computed once per map and
//! robot and timed apart, because the service computes it once per map version, not per roadmap.
//!
//! `ompl` runs the peers; `report` writes `prm.csv`, `prm.md` and `prm.png`.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use prm::{
    ConfigSpace, Inflation, Point2, PrmParams, QueryOptions, Roadmap, SearchAlgorithm,
    optimal_samples,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::error::{BenchError, io_err};
use crate::maps::{find_yamls, load_ros_map, map_names, map_seed};

mod ompl;
mod report;

pub use ompl::{OmplOptions, inflated_pgm};
pub use report::{Summary, summarize, to_csv};

use ompl::{OmplJob, cpp_command, python_command, run_ompl};
use report::{plot, to_markdown};

/// The paper's sample counts (§5.1); n* of each map is added to them.
pub const PAPER_SAMPLES: [usize; 6] = [50, 100, 200, 300, 400, 500];

/// The paper's Table 2 (KDJ Convention Center and Corporate Collaboration Center maps):
/// (place, n*, build ms, search ms, length m, success %).
pub const PAPER_TABLE2: [(&str, usize, f64, f64, f64, f64); 9] = [
    ("KDJ 1st floor", 329, 2664.3, 12.06, 152.58, 92.0),
    ("KDJ corridor 1", 260, 1996.5, 10.18, 114.43, 94.0),
    ("KDJ corridor 2", 176, 1502.3, 9.15, 39.41, 100.0),
    ("KDJ corridor 3", 127, 759.68, 7.86, 50.68, 98.0),
    ("CCC 7th corridor 1", 87, 247.98, 5.22, 25.60, 92.0),
    ("CCC 7th corridor 2", 92, 183.0, 4.68, 59.48, 94.0),
    ("CCC 7th corridor 3", 89, 195.37, 6.56, 13.41, 92.0),
    ("CCC 7th corridor 4", 87, 119.20, 4.99, 6.71, 98.0),
    ("CCC 7th corridor 5", 89, 169.88, 5.33, 40.57, 96.0),
];

/// What `mentalsim bench prm` runs.
#[derive(Debug, Clone, PartialEq)]
pub struct PrmBenchOptions {
    /// Directory searched recursively for ROS map_server `.yaml` files.
    pub maps_dir: PathBuf,
    /// Runs per (map, n): a fresh roadmap and a random start/goal pair each (the paper: 50).
    pub runs: usize,
    /// Where `prm.csv`, `prm.md` and `prm.png` go (created if missing).
    pub out_dir: PathBuf,
    /// Sample counts; each map's n* is added.
    pub samples: Vec<usize>,
    /// Base seed of roadmaps and start/goal pairs.
    pub seed: u64,
    /// The robot's radius, metres.
    pub robot_radius_m: f64,
    /// Extra clearance kept, metres.
    pub safety_margin_m: f64,
    /// k.
    pub neighbours: usize,
    /// d_max, metres.
    pub max_edge_m: f64,
    /// Dijkstra (as the paper) or A*.
    pub algorithm: SearchAlgorithm,
    /// OMPL beside ours; `None` skips it.
    pub ompl: Option<OmplOptions>,
    /// MovingAI maps and scenarios to run as well (see [`crate::movingai`]).
    pub movingai_dir: Option<PathBuf>,
    /// Also run our code as the paper's plain PRM (`ours_paper` rows), the like-for-like peer
    /// of OMPL's PRM.
    pub paper_variant: bool,
    /// Progress lines on stderr.
    pub verbose: bool,
}

impl Default for PrmBenchOptions {
    fn default() -> Self {
        let p = PrmParams::default();
        Self {
            maps_dir: PathBuf::from("../shared/maps/ros"),
            runs: 50,
            out_dir: PathBuf::from("target/bench/prm"),
            samples: PAPER_SAMPLES.to_vec(),
            seed: 1,
            robot_radius_m: 0.2,
            safety_margin_m: 0.05,
            neighbours: p.neighbours,
            max_edge_m: p.max_edge_m,
            algorithm: SearchAlgorithm::AStar,
            ompl: Some(OmplOptions::default()),
            movingai_dir: None,
            paper_variant: true,
            verbose: false,
        }
    }
}

/// One run: a roadmap build and one query (one CSV row).
#[derive(Debug, Clone, PartialEq)]
pub struct PrmRow {
    /// `ours`, `ours_paper` (our code as the paper's plain PRM), `ompl` (OMPL's PRM through its
    /// Python bindings) or `ompl_cpp` (the C++ library).
    pub planner: &'static str,
    /// Map name.
    pub map: String,
    /// Free area of the map (uninflated), m².
    pub free_area_m2: f64,
    /// Samples.
    pub n: usize,
    /// Run index.
    pub run: usize,
    /// Roadmap build time, ms.
    pub build_ms: f64,
    /// Query time (start/goal insertion, search, path and clearance), ms.
    pub search_ms: f64,
    /// Path length, m (when found).
    pub length_m: Option<f64>,
    /// Smallest clearance along the path, m (when found).
    pub min_clearance_m: Option<f64>,
    /// A path was found.
    pub success: bool,
    /// Our query needed local densification (always false for OMPL).
    pub densified: bool,
    /// The path passes our exact segment check (OMPL's discrete check can cut corners).
    pub exact_valid: bool,
}

/// What the benchmark learned about one map.
#[derive(Debug, Clone, PartialEq)]
pub struct MapInfo {
    /// Name (the map's folder, or folder/file when a folder has several maps).
    pub name: String,
    /// The YAML file.
    pub yaml: PathBuf,
    /// Columns × rows.
    pub size: (usize, usize),
    /// Metres per cell.
    pub resolution: f64,
    /// Free area (uninflated), m²: the paper's "free space area".
    pub free_area_m2: f64,
    /// n* = ceil(0.05 · free area + 84).
    pub n_star: usize,
    /// Area the robot's centre may reach, m² (inflated free space).
    pub cspace_free_m2: f64,
    /// Area of the largest free region, m².
    pub largest_region_m2: f64,
    /// Free regions.
    pub regions: usize,
    /// Time to compute the configuration space (distance transform, inflation, regions), ms.
    pub cspace_ms: f64,
}

/// Everything the benchmark produced.
#[derive(Debug, Clone)]
pub struct PrmBenchReport {
    /// Per-map facts.
    pub maps: Vec<MapInfo>,
    /// All runs, ours and OMPL's.
    pub rows: Vec<PrmRow>,
    /// `prm.csv`.
    pub csv_path: PathBuf,
    /// `prm.md`.
    pub markdown_path: PathBuf,
    /// `prm.png`.
    pub plot_path: PathBuf,
    /// The Markdown report's text.
    pub markdown: String,
    /// Whether OMPL ran, and if not, why.
    pub ompl_status: String,
    /// MovingAI results, when asked for.
    pub movingai: Option<crate::movingai::MovingAiReport>,
}

/// Runs the benchmark and writes `prm.csv`, `prm.md` and `prm.png` into `opts.out_dir`.
pub fn run_prm_bench(opts: PrmBenchOptions) -> Result<PrmBenchReport, BenchError> {
    if opts.runs == 0 {
        return Err(BenchError::BadOption("runs must be at least 1".into()));
    }
    std::fs::create_dir_all(&opts.out_dir).map_err(io_err(&opts.out_dir))?;
    let yamls = find_yamls(&opts.maps_dir)?;
    if yamls.is_empty() {
        return Err(BenchError::NoMaps(opts.maps_dir.clone()));
    }
    let names = map_names(&opts.maps_dir, &yamls);
    let inflation = Inflation {
        robot_radius_m: opts.robot_radius_m,
        safety_margin_m: opts.safety_margin_m,
    };
    let mut maps = Vec::new();
    let mut rows = Vec::new();
    let mut ompl_notes = Vec::new();
    for (yaml, name) in yamls.iter().zip(&names) {
        let grid = load_ros_map(yaml)?;
        let free_area_m2 = grid.free_area_m2();
        let t = Instant::now();
        let cs = Arc::new(ConfigSpace::new(&grid, inflation).map_err(|source| {
            BenchError::ConfigSpace {
                path: yaml.clone(),
                source,
            }
        })?);
        let cspace_ms = ms(t);
        let n_star = optimal_samples(free_area_m2);
        let largest = cs.largest_region();
        let res2 = cs.resolution() * cs.resolution();
        let info = MapInfo {
            name: name.clone(),
            yaml: yaml.clone(),
            size: (grid.width, grid.height),
            resolution: grid.resolution,
            free_area_m2,
            n_star,
            cspace_free_m2: cs.free_area_m2(),
            largest_region_m2: largest.map_or(0.0, |r| cs.region_cells(r) as f64 * res2),
            regions: cs.region_count(),
            cspace_ms,
        };
        if opts.verbose {
            eprintln!(
                "prm: {name}: {}x{} cells, free {:.0} m², n* {n_star}, config space {cspace_ms:.1} ms",
                info.size.0, info.size.1, free_area_m2
            );
        }
        let Some(largest) = largest else {
            ompl_notes.push(format!("{name}: no free space once inflated; skipped"));
            maps.push(info);
            continue;
        };
        let pairs = random_pairs(&cs, largest, opts.runs, map_seed(opts.seed, name));
        let mut ns = opts.samples.clone();
        ns.push(n_star);
        ns.sort_unstable();
        ns.dedup();
        for &n in &ns {
            rows.extend(run_ours(&cs, &opts, name, free_area_m2, n, &pairs, false)?);
            if opts.paper_variant {
                rows.extend(run_ours(&cs, &opts, name, free_area_m2, n, &pairs, true)?);
            }
        }
        if let Some(ompl) = &opts.ompl {
            let ompl_ns: Vec<usize> = if ompl.only_optimal {
                vec![n_star]
            } else {
                ns.clone()
            };
            let ompl_pairs = &pairs[..ompl.runs.min(pairs.len())];
            let job = OmplJob {
                cs: &cs,
                opts: &opts,
                ompl,
                map: name,
                free_area_m2,
                ns: &ompl_ns,
                pairs: ompl_pairs,
            };
            match python_command(ompl, &opts.out_dir).and_then(|cmd| run_ompl(&job, cmd, "ompl")) {
                Ok(r) => rows.extend(r),
                Err(e) => ompl_notes.push(format!("{name}: Python: {e}")),
            }
            if ompl.cpp {
                match cpp_command(&opts.out_dir).and_then(|cmd| run_ompl(&job, cmd, "ompl_cpp")) {
                    Ok(r) => rows.extend(r),
                    Err(e) => ompl_notes.push(format!("{name}: C++: {e}")),
                }
            }
        }
        maps.push(info);
    }

    let movingai = match &opts.movingai_dir {
        Some(dir) => Some(crate::movingai::run_movingai_bench(
            &crate::movingai::MovingAiOptions {
                dir: dir.clone(),
                neighbours: opts.neighbours,
                max_edge_m: opts.max_edge_m,
                seed: opts.seed,
                scenarios_per_map: 200,
                algorithm: opts.algorithm,
            },
        )?),
        None => None,
    };

    let ompl_status = match &opts.ompl {
        None => "OMPL not run (disabled)".to_string(),
        Some(o) if ompl_notes.is_empty() => format!(
            "OMPL: the 2.0.1 Python bindings via {}{}, {} runs per n, motion check every {} cells",
            o.python.display(),
            if o.cpp {
                " and the installed C++ library"
            } else {
                ""
            },
            o.runs,
            o.check_resolution_cells
        ),
        Some(_) => format!("OMPL incomplete: {}", ompl_notes.join("; ")),
    };
    let csv_path = opts.out_dir.join("prm.csv");
    std::fs::write(&csv_path, to_csv(&rows)).map_err(io_err(&csv_path))?;
    let markdown = to_markdown(&opts, &maps, &rows, &ompl_status, movingai.as_ref());
    let markdown_path = opts.out_dir.join("prm.md");
    std::fs::write(&markdown_path, &markdown).map_err(io_err(&markdown_path))?;
    let plot_path = opts.out_dir.join("prm.png");
    plot(&plot_path, &maps, &rows)?;
    Ok(PrmBenchReport {
        maps,
        rows,
        csv_path,
        markdown_path,
        plot_path,
        markdown,
        ompl_status,
        movingai,
    })
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// `count` start/goal pairs drawn uniformly in one free region.
pub fn random_pairs(
    cs: &ConfigSpace,
    region: u32,
    count: usize,
    seed: u64,
) -> Vec<(Point2, Point2)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .filter_map(|_| {
            Some((
                cs.sample_free(&mut rng, Some(region))?,
                cs.sample_free(&mut rng, Some(region))?,
            ))
        })
        .collect()
}

/// Our planner on every pair at one n. `paper` runs the paper's plain PRM instead (uniform
/// samples, no repair or bridging, no local densification): the like-for-like peer of OMPL's.
#[allow(clippy::too_many_arguments)]
fn run_ours(
    cs: &Arc<ConfigSpace>,
    opts: &PrmBenchOptions,
    map: &str,
    free_area_m2: f64,
    n: usize,
    pairs: &[(Point2, Point2)],
    paper: bool,
) -> Result<Vec<PrmRow>, BenchError> {
    let mut rows = Vec::with_capacity(pairs.len());
    let query = QueryOptions {
        algorithm: opts.algorithm,
        no_densify: paper,
    };
    for (run, &(s, g)) in pairs.iter().enumerate() {
        let mut params = PrmParams {
            samples: n,
            neighbours: opts.neighbours,
            max_edge_m: opts.max_edge_m,
            seed: grid::seed::mix(map_seed(opts.seed, map), (n as u64) << 20 | run as u64),
            ..PrmParams::default()
        };
        if paper {
            params.skeleton_share = 0.0;
            params.repair_share = 0.0;
        }
        let t = Instant::now();
        let roadmap =
            Roadmap::build(Arc::clone(cs), &params).map_err(|source| BenchError::Build {
                map: map.to_string(),
                source,
            })?;
        let build_ms = ms(t);
        let t = Instant::now();
        let plan = roadmap.query(s, g, query);
        let search_ms = ms(t);
        let (length_m, min_clearance_m, densified) = match &plan {
            Ok(p) => (
                Some(p.length_m),
                Some(p.min_clearance_m),
                p.densified_nodes > 0,
            ),
            Err(_) => (None, None, false),
        };
        rows.push(PrmRow {
            planner: if paper { "ours_paper" } else { "ours" },
            map: map.to_string(),
            free_area_m2,
            n,
            run,
            build_ms,
            search_ms,
            length_m,
            min_clearance_m,
            success: plan.is_ok(),
            densified,
            exact_valid: plan.is_ok(),
        });
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use std::fmt::Write as _;

    use super::*;

    fn shared_maps() -> Option<PathBuf> {
        fixtures::shared_fixture("maps/ros", "the shared maps")
    }

    /// The floor: at n*, a path for ≥ 99% of random pairs in the largest region of
    /// every real map, one fresh roadmap per pair as in the paper. Local densification is part of
    /// the planner; how often the roadmap alone sufficed is printed (and reported by the bench).
    #[test]
    fn real_maps_succeed_at_n_star() {
        let Some(dir) = shared_maps() else { return };
        // Few runs by default: the dev profile does not optimise our crates.
        let runs: usize = std::env::var("PRM_TEST_RUNS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(8);
        let opts = PrmBenchOptions::default();
        let inflation = Inflation {
            robot_radius_m: opts.robot_radius_m,
            safety_margin_m: opts.safety_margin_m,
        };
        let yamls = find_yamls(&dir).expect("maps");
        assert!(yamls.len() >= 11, "{} maps", yamls.len());
        let mut report = String::new();
        let mut failures = Vec::new();
        for (yaml, name) in yamls.iter().zip(map_names(&dir, &yamls)) {
            let grid = load_ros_map(yaml).expect("map loads");
            let cs = Arc::new(ConfigSpace::new(&grid, inflation).expect("cspace"));
            let region = cs.largest_region().expect("free space");
            let n = optimal_samples(grid.free_area_m2());
            let pairs = random_pairs(&cs, region, runs, map_seed(7, &name));
            let (mut alone, mut found) = (0, 0);
            for (run, &(s, g)) in pairs.iter().enumerate() {
                let params = PrmParams {
                    samples: n,
                    seed: run as u64 + 1,
                    ..PrmParams::default()
                };
                let rm = Roadmap::build(Arc::clone(&cs), &params).expect("roadmap");
                let strict = QueryOptions {
                    algorithm: SearchAlgorithm::AStar,
                    no_densify: true,
                };
                if rm.query(s, g, strict).is_ok() {
                    alone += 1;
                }
                if let Ok(p) = rm.query(s, g, QueryOptions::default()) {
                    assert!(
                        p.waypoints.windows(2).all(|w| cs.segment_free(w[0], w[1])),
                        "{name}: invalid path"
                    );
                    assert_eq!(
                        (p.waypoints.first(), p.waypoints.last()),
                        (Some(&s), Some(&g))
                    );
                    found += 1;
                }
            }
            let pct = |k: usize| 100.0 * k as f64 / pairs.len() as f64;
            let _ = writeln!(
                report,
                "{name}: n* = {n}: success {:.1}% (roadmap alone {:.1}%)",
                pct(found),
                pct(alone)
            );
            if pct(found) < 99.0 {
                failures.push(name);
            }
        }
        println!("{report}");
        assert!(
            failures.is_empty(),
            "below 99% at n*: {failures:?}\n{report}"
        );
    }

    #[test]
    fn an_empty_directory_has_no_maps() {
        let dir = std::env::temp_dir().join(format!("prm-bench-empty-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("tmp");
        let e = run_prm_bench(PrmBenchOptions {
            maps_dir: dir.clone(),
            out_dir: dir.join("out"),
            ..PrmBenchOptions::default()
        });
        assert!(matches!(e, Err(BenchError::NoMaps(_))), "{e:?}");
        let _ = std::fs::remove_dir_all(dir);
    }
}
