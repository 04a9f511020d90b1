//! The PRM benchmark (paper §5.1: Table 2, Figure 9) on ROS map_server maps, ours beside OMPL.
//!
//! Protocol, as the paper's: for every map and every n, `runs` times build a fresh roadmap
//! (new seed) and ask it for a path between a random start and goal in the largest free region.
//! The configuration space (distance transform, inflation, regions) is computed once per map and
//! robot and timed apart, because the service computes it once per map version, not per roadmap.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Instant;

use planning::{
    ConfigSpace, GridMap, Inflation, Point2, PrmParams, QueryOptions, Roadmap, SearchAlgorithm,
    optimal_samples,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

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

/// The OMPL runs beside ours: the PyPI `ompl` Python bindings and, when a C++ compiler and the
/// OMPL headers are installed (Debian `libompl-dev`), the C++ library through a small program.
#[derive(Debug, Clone, PartialEq)]
pub struct OmplOptions {
    /// Python interpreter with `ompl` 2.0.1 and numpy installed (skipped when it does not exist).
    pub python: PathBuf,
    /// Also run the C++ library (compiled on first use into the output directory).
    pub cpp: bool,
    /// Runs per (map, n); the Python bindings are slow, so fewer than ours by default.
    pub runs: usize,
    /// Distance between the points OMPL's discrete motion validator checks, in cells.
    pub check_resolution_cells: f64,
    /// Run OMPL at n* only rather than at every n.
    pub only_optimal: bool,
}

impl Default for OmplOptions {
    fn default() -> Self {
        Self {
            python: PathBuf::from(".venv/bin/python"),
            cpp: true,
            runs: 10,
            check_resolution_cells: 0.5,
            only_optimal: false,
        }
    }
}

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

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A file or directory could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A map file is malformed.
    #[error("{path}: {source}")]
    Map {
        /// The YAML file.
        path: PathBuf,
        /// What is wrong.
        source: tosm::MapError,
    },
    /// A map or scenario file is malformed (MovingAI formats).
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The planner rejected the map.
    #[error("{path}: {source}")]
    ConfigSpace {
        /// The map file.
        path: PathBuf,
        /// What is wrong.
        source: planning::ConfigSpaceError,
    },
    /// The planner rejected the parameters.
    #[error("{map}: {source}")]
    Build {
        /// The map.
        map: String,
        /// What is wrong.
        source: planning::BuildError,
    },
    /// No map to run on.
    #[error("no ROS map_server .yaml file under {0}")]
    NoMaps(PathBuf),
    /// An option is out of range.
    #[error("bad option: {0}")]
    BadOption(String),
    /// The plot could not be drawn.
    #[error("plot {path}: {message}")]
    Plot {
        /// The PNG path.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> BenchError + '_ {
    move |source| BenchError::Io {
        path: path.to_path_buf(),
        source,
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
        let pairs = random_pairs(&cs, largest, opts.runs, mix(opts.seed, hash_str(name)));
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

/// All `.yaml`/`.yml` files under `dir`, sorted, that look like map_server metadata.
pub fn find_yamls(dir: &Path) -> Result<Vec<PathBuf>, BenchError> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).map_err(io_err(&d))? {
            let path = entry.map_err(io_err(&d))?.path();
            if path.is_dir() {
                stack.push(path);
            } else if matches!(
                path.extension().and_then(|e| e.to_str()),
                Some("yaml" | "yml")
            ) {
                // Other YAML (launch parameters, etc.) is not a map: it must name an image.
                let text = std::fs::read_to_string(&path).map_err(io_err(&path))?;
                if text.lines().any(|l| l.trim_start().starts_with("image:")) {
                    out.push(path);
                }
            }
        }
    }
    out.sort();
    Ok(out)
}

/// A short unique name per map: its folder, or folder/stem when a folder holds several maps.
pub(crate) fn map_names(root: &Path, yamls: &[PathBuf]) -> Vec<String> {
    let folder = |p: &Path| {
        p.parent()
            .and_then(|d| d.strip_prefix(root).ok())
            .map(|d| d.display().to_string())
            .filter(|s| !s.is_empty())
    };
    yamls
        .iter()
        .map(|y| {
            let stem = y
                .file_stem()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
            let same_folder = yamls.iter().filter(|o| o.parent() == y.parent()).count();
            match folder(y) {
                Some(f) if same_folder == 1 => f,
                Some(f) => format!("{f}/{stem}"),
                None => stem,
            }
        })
        .collect()
}

/// Reads a map_server map and keeps what the planner needs: unknown counts as blocked.
pub fn load_ros_map(yaml: &Path) -> Result<GridMap, BenchError> {
    let text = std::fs::read_to_string(yaml).map_err(io_err(yaml))?;
    let meta = tosm::RosMapMeta::parse_yaml(&text).map_err(|source| BenchError::Map {
        path: yaml.to_path_buf(),
        source,
    })?;
    let image_path = yaml.parent().unwrap_or(Path::new(".")).join(&meta.image);
    let image = std::fs::read(&image_path).map_err(io_err(&image_path))?;
    let grid = tosm::OccupancyGrid::from_ros_map_server(&meta, &image).map_err(|source| {
        BenchError::Map {
            path: yaml.to_path_buf(),
            source,
        }
    })?;
    Ok(grid_map_from_occupancy(&grid))
}

/// The planner's view of an occupancy grid. The origin's yaw is not applied: the planner works
/// in the grid's own frame (every shared map has yaw 0).
pub fn grid_map_from_occupancy(grid: &tosm::OccupancyGrid) -> GridMap {
    GridMap {
        width: grid.width,
        height: grid.height,
        resolution: grid.resolution,
        origin_x: grid.origin.x,
        origin_y: grid.origin.y,
        blocked: grid
            .cells
            .iter()
            .map(|c| *c != tosm::Occupancy::Free)
            .collect(),
    }
}

/// SplitMix64 step: decorrelates seeds derived from (seed, map, n, run).
pub(crate) fn mix(a: u64, b: u64) -> u64 {
    let mut z = a ^ b.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

pub(crate) fn hash_str(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
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
            seed: mix(mix(opts.seed, hash_str(map)), (n as u64) << 20 | run as u64),
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

/// The OMPL side script, embedded so that the benchmark runs from any working directory.
const OMPL_SCRIPT: &str = include_str!("../scripts/ompl_prm.py");

/// One map's OMPL run: the same inflated grid, n, k and start/goal pairs as ours.
struct OmplJob<'a> {
    cs: &'a ConfigSpace,
    opts: &'a PrmBenchOptions,
    ompl: &'a OmplOptions,
    map: &'a str,
    free_area_m2: f64,
    ns: &'a [usize],
    pairs: &'a [(Point2, Point2)],
}

/// The C++ side program, embedded like the script.
const OMPL_CPP: &str = include_str!("../ompl/ompl_prm.cpp");

/// The Python side: interpreter + the embedded script written into the output directory.
fn python_command(ompl: &OmplOptions, out_dir: &Path) -> Result<Command, String> {
    if !ompl.python.exists() {
        return Err(format!(
            "interpreter {} not found (create it with `python3 -m venv .venv && .venv/bin/pip install ompl==2.0.1 numpy`)",
            ompl.python.display()
        ));
    }
    let dir = out_dir.join("ompl");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let script = dir.join("ompl_prm.py");
    std::fs::write(&script, OMPL_SCRIPT).map_err(|e| format!("{}: {e}", script.display()))?;
    let mut cmd = Command::new(&ompl.python);
    cmd.arg(script);
    Ok(cmd)
}

/// The C++ side: compiles the embedded program against the installed OMPL once (recompiled
/// when the source changes), then runs it.
fn cpp_command(out_dir: &Path) -> Result<Command, String> {
    let dir = out_dir.join("ompl");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let src = dir.join("ompl_prm.cpp");
    let bin = dir.join("ompl_prm_cpp");
    let fresh = std::fs::read_to_string(&src).is_ok_and(|s| s == OMPL_CPP) && bin.exists();
    if !fresh {
        std::fs::write(&src, OMPL_CPP).map_err(|e| format!("{}: {e}", src.display()))?;
        // pkg-config knows where the distribution put OMPL's and Eigen's headers. Only its -I
        // flags are used: Debian's ompl.pc also lists Boost and ODE libraries that need not be
        // installed, and the program itself only needs libompl.
        let mut flags: Vec<String> = Command::new("pkg-config")
            .args(["--cflags", "ompl"])
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| {
                String::from_utf8_lossy(&o.stdout)
                    .split_whitespace()
                    .filter(|f| f.starts_with("-I"))
                    .map(str::to_string)
                    .collect()
            })
            .ok_or("OMPL's C++ library is not installed (Debian: apt-get install libompl-dev)")?;
        flags.push("-lompl".into());
        let out = Command::new("c++")
            .args(["-O2", "-std=c++17", "-o"])
            .arg(&bin)
            .arg(&src)
            .args(&flags)
            .output()
            .map_err(|e| format!("cannot run c++: {e}"))?;
        if !out.status.success() {
            let err = String::from_utf8_lossy(&out.stderr);
            return Err(format!(
                "compiling {} failed: {}",
                src.display(),
                err.lines().take(3).collect::<Vec<_>>().join(" | ")
            ));
        }
    }
    Ok(Command::new(bin))
}

/// Runs one OMPL side program on the job and parses its rows.
fn run_ompl(
    job: &OmplJob<'_>,
    mut cmd: Command,
    planner: &'static str,
) -> Result<Vec<PrmRow>, String> {
    let OmplJob {
        cs,
        opts,
        ompl,
        map,
        free_area_m2,
        ns,
        pairs,
    } = *job;
    let dir = opts.out_dir.join("ompl");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let safe = map.replace(['/', '\\'], "_");
    let pgm = dir.join(format!("{safe}.pgm"));
    std::fs::write(&pgm, inflated_pgm(cs)).map_err(|e| format!("{}: {e}", pgm.display()))?;
    let mut jobs = String::new();
    for &n in ns {
        for (run, (s, g)) in pairs.iter().enumerate() {
            let (sx, sy) = cs.world_to_grid(*s);
            let (gx, gy) = cs.world_to_grid(*g);
            let seed = mix(opts.seed, hash_str(map)) & 0x7fff_ffff;
            let _ = writeln!(
                jobs,
                "{n} {run} {seed} {} {} {sx:.9} {sy:.9} {gx:.9} {gy:.9}",
                opts.neighbours, ompl.check_resolution_cells
            );
        }
    }
    let jobs_path = dir.join(format!("{safe}.jobs"));
    std::fs::write(&jobs_path, jobs).map_err(|e| format!("{}: {e}", jobs_path.display()))?;
    if opts.verbose {
        eprintln!("prm: {map}: {planner} {} jobs", ns.len() * pairs.len());
    }
    let out = cmd
        .arg(&pgm)
        .arg(&jobs_path)
        .output()
        .map_err(|e| format!("cannot start {:?}: {e}", cmd.get_program()))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: String = err.lines().rev().take(5).collect::<Vec<_>>().join(" | ");
        return Err(format!("OMPL side program failed ({}): {tail}", out.status));
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let mut rows = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let f: Vec<&str> = line.splitn(7, ',').collect();
        if f.len() != 7 {
            return Err(format!("unexpected OMPL output line: {line}"));
        }
        let num = |i: usize| {
            f[i].parse::<f64>()
                .map_err(|e| format!("OMPL output `{line}`: {e}"))
        };
        let n = num(0)? as usize;
        let run = num(1)? as usize;
        let success = f[4] == "1";
        let pts: Vec<Point2> = f[6]
            .split(';')
            .filter(|p| !p.is_empty())
            .filter_map(|p| {
                let mut it = p.split_whitespace().map(str::parse::<f64>);
                match (it.next(), it.next()) {
                    (Some(Ok(x)), Some(Ok(y))) => Some(cs.grid_to_world(x, y)),
                    _ => None,
                }
            })
            .collect();
        let (length_m, min_clearance_m, exact_valid) = if success && pts.len() >= 2 {
            let len: f64 = pts.windows(2).map(|w| w[0].distance(w[1])).sum();
            let clear = pts
                .windows(2)
                .map(|w| cs.segment_clearance_m(w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            let valid = pts.windows(2).all(|w| cs.segment_free(w[0], w[1]));
            (Some(len), Some(clear), valid)
        } else {
            (None, None, false)
        };
        rows.push(PrmRow {
            planner,
            map: map.to_string(),
            free_area_m2,
            n,
            run,
            build_ms: num(2)?,
            search_ms: num(3)?,
            length_m,
            min_clearance_m,
            success,
            densified: false,
            exact_valid,
        });
    }
    Ok(rows)
}

/// The inflated free space as a binary PGM (255 = free), top row first as PGM requires.
pub fn inflated_pgm(cs: &ConfigSpace) -> Vec<u8> {
    let (w, h) = (cs.width(), cs.height());
    let mut out = format!("P5\n{w} {h}\n255\n").into_bytes();
    out.reserve(w * h);
    for row in (0..h).rev() {
        out.extend((0..w).map(|col| if cs.cell_free(col, row) { 255u8 } else { 0 }));
    }
    out
}

/// `prm.csv`: one row per run, the issue's columns exactly.
pub fn to_csv(rows: &[PrmRow]) -> String {
    let mut s = String::from(
        "planner,map,free_area_m2,n,run,build_ms,search_ms,length_m,min_clearance_m,success\n",
    );
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{:.2},{},{},{:.5},{:.5},{},{},{}",
            r.planner,
            csv_field(&r.map),
            r.free_area_m2,
            r.n,
            r.run,
            r.build_ms,
            r.search_ms,
            opt(r.length_m),
            opt(r.min_clearance_m),
            u8::from(r.success)
        );
    }
    s
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Aggregates of one (planner, map, n).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Summary {
    /// Runs.
    pub runs: usize,
    /// Mean build time, ms.
    pub build_ms: f64,
    /// Mean query time, ms.
    pub search_ms: f64,
    /// Median query time, ms.
    pub search_p50_ms: f64,
    /// Slowest query, ms.
    pub search_max_ms: f64,
    /// Mean length of found paths, m.
    pub length_m: f64,
    /// Mean of the paths' minimum clearance, m.
    pub min_clearance_m: f64,
    /// Share of runs with a path, %.
    pub success_pct: f64,
    /// Runs whose query densified locally.
    pub densified: usize,
    /// Share of runs the roadmap answered without densification, %.
    pub roadmap_alone_pct: f64,
    /// Found paths that fail our exact segment check.
    pub exact_invalid: usize,
}

/// Aggregates rows by (planner, map, n).
pub fn summarize(rows: &[PrmRow]) -> BTreeMap<(&'static str, String, usize), Summary> {
    let mut groups: BTreeMap<(&'static str, String, usize), Vec<&PrmRow>> = BTreeMap::new();
    for r in rows {
        groups
            .entry((r.planner, r.map.clone(), r.n))
            .or_default()
            .push(r);
    }
    groups
        .into_iter()
        .map(|(key, rs)| {
            let count = rs.len() as f64;
            let mut search: Vec<f64> = rs.iter().map(|r| r.search_ms).collect();
            search.sort_by(f64::total_cmp);
            let found: Vec<&&PrmRow> = rs.iter().filter(|r| r.success).collect();
            let mean_found = |f: fn(&PrmRow) -> Option<f64>| {
                let v: Vec<f64> = found.iter().filter_map(|r| f(r)).collect();
                if v.is_empty() {
                    f64::NAN
                } else {
                    v.iter().sum::<f64>() / v.len() as f64
                }
            };
            let s = Summary {
                runs: rs.len(),
                build_ms: rs.iter().map(|r| r.build_ms).sum::<f64>() / count,
                search_ms: search.iter().sum::<f64>() / count,
                search_p50_ms: search[search.len() / 2],
                search_max_ms: search.last().copied().unwrap_or(0.0),
                length_m: mean_found(|r| r.length_m),
                min_clearance_m: mean_found(|r| r.min_clearance_m),
                success_pct: 100.0 * found.len() as f64 / count,
                densified: rs.iter().filter(|r| r.densified).count(),
                roadmap_alone_pct: 100.0
                    * rs.iter().filter(|r| r.success && !r.densified).count() as f64
                    / count,
                exact_invalid: found.iter().filter(|r| !r.exact_valid).count(),
            };
            (key, s)
        })
        .collect()
}

fn to_markdown(
    opts: &PrmBenchOptions,
    maps: &[MapInfo],
    rows: &[PrmRow],
    ompl_status: &str,
    movingai: Option<&crate::movingai::MovingAiReport>,
) -> String {
    let sums = summarize(rows);
    let get = |planner: &'static str, map: &str, n: usize| sums.get(&(planner, map.to_string(), n));
    let mut s = String::new();
    let _ = writeln!(s, "# PRM benchmark (paper §5.1, Table 2 and Figure 9)\n");
    let _ = writeln!(
        s,
        "Maps from `{}`; {} runs per (map, n), each a fresh roadmap and a random start/goal pair in the \
         largest free region; robot radius {} m + margin {} m; k = {}, d_max = {} m; {:?}; seed {}. \
         {}.\n",
        opts.maps_dir.display(),
        opts.runs,
        opts.robot_radius_m,
        opts.safety_margin_m,
        opts.neighbours,
        opts.max_edge_m,
        opts.algorithm,
        opts.seed,
        ompl_status
    );
    let _ = writeln!(
        s,
        "What is timed: *build* = sampling, k-NN, edge checks, re-sampling of isolated nodes, visibility repair, \
         bridging of components that share a free region, and the graph with each edge's clearance (not the configuration space, which is computed once per map and robot and shown in its own column); \
         *search* = checking start and goal, linking them to the roadmap, the shortest-path search, local \
         densification when needed, and the path's clearance (traced along the links and densification segments the query adds; the roadmap edges' own clearance is read, as computed in the build). OMPL: *build* = `growRoadmap` until n milestones, \
         *search* = `solve` (adds start and goal, checks for a solution in a second thread, keeps growing the \
         roadmap until it finds one; 2 s limit).\n"
    );
    let _ = writeln!(s, "## At n* (Eq. 19), like the paper's Table 2\n");
    let _ = writeln!(
        s,
        "| map | free m² | n* | config space ms (once per map) | build ms | search ms (mean / p50 / max) | length m | min clearance m | success | roadmap alone | densified runs |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|");
    for m in maps {
        let Some(o) = get("ours", &m.name, m.n_star) else {
            continue;
        };
        let _ = writeln!(
            s,
            "| {} | {:.0} | {} | {:.1} | {:.3} | {:.4} / {:.4} / {:.3} | {:.2} | {:.3} | {:.0}% | {:.0}% | {} |",
            m.name,
            m.free_area_m2,
            m.n_star,
            m.cspace_ms,
            o.build_ms,
            o.search_ms,
            o.search_p50_ms,
            o.search_max_ms,
            o.length_m,
            o.min_clearance_m,
            o.success_pct,
            o.roadmap_alone_pct,
            o.densified
        );
    }
    let _ = writeln!(
        s,
        "\n## Peers at n* (same inflated grid, n, k, start/goal pairs; ratios against `ours`)\n"
    );
    let _ = writeln!(
        s,
        "| map | planner | runs | build ms | search ms (mean / p50) | length m | success | paths failing our exact check | build: peer / ours | search: peer / ours |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---|---:|---:|---:|---:|---:|");
    for m in maps {
        let Some(o) = get("ours", &m.name, m.n_star) else {
            continue;
        };
        for (peer, label) in [
            ("ours_paper", "ours as the paper's plain PRM"),
            ("ompl_cpp", "OMPL 1.5 C++"),
            ("ompl", "OMPL 2.0.1 Python"),
        ] {
            if let Some(x) = get(peer, &m.name, m.n_star) {
                let _ = writeln!(
                    s,
                    "| {} | {label} | {} | {:.2} | {:.3} / {:.3} | {:.2} | {:.0}% | {} | {:.1}× | {:.0}× |",
                    m.name,
                    x.runs,
                    x.build_ms,
                    x.search_ms,
                    x.search_p50_ms,
                    x.length_m,
                    x.success_pct,
                    x.exact_invalid,
                    x.build_ms / o.build_ms,
                    x.search_ms / o.search_ms
                );
            }
        }
    }
    // The paper's own figures, and ours against them on the largest map.
    let _ = writeln!(s, "\n## Against the paper\n");
    let _ = writeln!(
        s,
        "| paper map | n* | build ms | search ms | length m | success |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
    for (name, n, b, q, l, sr) in PAPER_TABLE2 {
        let _ = writeln!(s, "| {name} | {n} | {b} | {q} | {l} | {sr:.0}% |");
    }
    // "Largest" as the issue means it: the most cells (the most work per query and per check).
    if let Some(big) = maps.iter().max_by_key(|m| m.size.0 * m.size.1)
        && let Some(o) = get("ours", &big.name, big.n_star)
    {
        {
            let (_, pn, pb, pq, _, _) = PAPER_TABLE2[0];
            let _ = writeln!(
                s,
                "\nLargest map here (most cells): {} ({:.0} m² free, n* = {}): build {:.3} ms vs the paper's {pb} ms for n = {pn} \
                 on its largest map ({:.0}× faster; {:.0}× counting the once-per-map configuration space too), \
                 search {:.4} ms vs {pq} ms ({:.0}× faster), success {:.0}% vs 92–100%.",
                big.name,
                big.free_area_m2,
                big.n_star,
                o.build_ms,
                pb / o.build_ms,
                pb / (o.build_ms + big.cspace_ms),
                o.search_ms,
                pq / o.search_ms,
                o.success_pct
            );
        }
    }
    let _ = writeln!(s, "\n## Every n (the data of Figure 9)\n");
    let _ = writeln!(
        s,
        "| map | n | build ms | search ms | length m | success | roadmap alone | OMPL C++ build ms | OMPL C++ search ms | OMPL C++ success | OMPL Py build ms | OMPL Py success |"
    );
    let _ = writeln!(
        s,
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    let cell =
        |x: Option<&Summary>, f: fn(&Summary) -> String| x.map_or_else(|| "–".to_string(), f);
    for ((planner, map, n), o) in &sums {
        if *planner != "ours" {
            continue;
        }
        let cpp = get("ompl_cpp", map, *n);
        let py = get("ompl", map, *n);
        let _ = writeln!(
            s,
            "| {map} | {n} | {:.3} | {:.4} | {:.2} | {:.0}% | {:.0}% | {} | {} | {} | {} | {} |",
            o.build_ms,
            o.search_ms,
            o.length_m,
            o.success_pct,
            o.roadmap_alone_pct,
            cell(cpp, |x| format!("{:.2}", x.build_ms)),
            cell(cpp, |x| format!("{:.3}", x.search_ms)),
            cell(cpp, |x| format!("{:.0}%", x.success_pct)),
            cell(py, |x| format!("{:.1}", x.build_ms)),
            cell(py, |x| format!("{:.0}%", x.success_pct)),
        );
    }
    let _ = writeln!(s, "\n## Maps\n");
    let _ = writeln!(
        s,
        "| map | cells | m/cell | free m² | reachable m² (inflated) | largest region m² | regions |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|");
    for m in maps {
        let _ = writeln!(
            s,
            "| {} | {}×{} | {} | {:.0} | {:.0} | {:.0} | {} |",
            m.name,
            m.size.0,
            m.size.1,
            m.resolution,
            m.free_area_m2,
            m.cspace_free_m2,
            m.largest_region_m2,
            m.regions
        );
    }
    if let Some(mai) = movingai {
        s.push_str(&crate::movingai::to_markdown(mai));
    }
    s
}

/// `prm.png`: four panels like the paper's Figure 9 (build time, search time, length and
/// success against n), one line per map, ours.
fn plot(path: &Path, maps: &[MapInfo], rows: &[PrmRow]) -> Result<(), BenchError> {
    use plotters::prelude::*;
    let err = |e: &dyn std::fmt::Display| BenchError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    learning::curves::register_font();
    let sums = summarize(rows);
    let root = BitMapBackend::new(path, (1600, 1200)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let panels = root.split_evenly((2, 2));
    type Metric = fn(&Summary) -> f64;
    let metrics: [(&str, Metric); 4] = [
        ("graph build time (ms)", |s| s.build_ms),
        ("path search time (ms)", |s| s.search_ms),
        ("path length (m)", |s| s.length_m),
        // With local densification every run succeeds; the roadmap's own success is what
        // varies with n, as in the paper's figure.
        ("success rate, roadmap alone (%)", |s| s.roadmap_alone_pct),
    ];
    let max_n = sums.keys().map(|k| k.2).max().unwrap_or(500).max(1) as f64;
    for (panel, (title, metric)) in panels.iter().zip(metrics) {
        let series: Vec<(String, Vec<(f64, f64)>)> = maps
            .iter()
            .map(|m| {
                let pts = sums
                    .iter()
                    .filter(|((p, name, _), _)| *p == "ours" && *name == m.name)
                    .map(|((_, _, n), s)| (*n as f64, metric(s)))
                    .filter(|(_, v)| v.is_finite())
                    .collect();
                (m.name.clone(), pts)
            })
            .collect();
        let ymax = series
            .iter()
            .flat_map(|(_, p)| p.iter().map(|q| q.1))
            .fold(0.0f64, f64::max)
            .max(1e-6)
            * 1.1;
        let mut chart = ChartBuilder::on(panel)
            .caption(title, ("sans-serif", 26))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(0.0..max_n * 1.05, 0.0..ymax)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("number of samples n")
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(|e| err(&e))?;
        for (i, (name, pts)) in series.into_iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                .map_err(|e| err(&e))?
                .label(name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
            chart
                .draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))
                .map_err(|e| err(&e))?;
        }
        if title.starts_with("graph build") {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .position(SeriesLabelPosition::UpperLeft)
                .draw()
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shared_maps() -> Option<PathBuf> {
        let p = crate::bench_dir().join("../../../shared/maps/ros");
        if p.is_dir() {
            Some(p)
        } else {
            println!("skipped: the shared maps are not at {}", p.display());
            None
        }
    }

    /// The issue's floor: at n*, a path for ≥ 99% of random pairs in the largest region of
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
            let pairs = random_pairs(&cs, region, runs, mix(7, hash_str(&name)));
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
    fn csv_has_exactly_the_issue_columns() {
        let row = PrmRow {
            planner: "ours",
            map: "a,b".into(),
            free_area_m2: 1.0,
            n: 50,
            run: 0,
            build_ms: 1.0,
            search_ms: 0.01,
            length_m: None,
            min_clearance_m: None,
            success: false,
            densified: false,
            exact_valid: false,
        };
        let csv = to_csv(&[row]);
        let mut lines = csv.lines();
        assert_eq!(
            lines.next(),
            Some(
                "planner,map,free_area_m2,n,run,build_ms,search_ms,length_m,min_clearance_m,success"
            )
        );
        assert_eq!(
            lines.next(),
            Some("ours,\"a,b\",1.00,50,0,1.00000,0.01000,,,0")
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

    /// Minimum and median build and query times on one map, robust to a busy machine:
    /// `PRM_PROFILE_MAP=.../map.yaml cargo test --release -p bench --lib prm::tests::profile -- --ignored --nocapture`
    #[test]
    #[ignore = "measuring aid; run by hand in release"]
    fn profile() {
        let Ok(yaml) = std::env::var("PRM_PROFILE_MAP") else {
            return;
        };
        let grid = load_ros_map(Path::new(&yaml)).expect("map");
        let d = PrmBenchOptions::default();
        let inflation = Inflation {
            robot_radius_m: d.robot_radius_m,
            safety_margin_m: d.safety_margin_m,
        };
        let cs = Arc::new(ConfigSpace::new(&grid, inflation).expect("cspace"));
        let n = optimal_samples(grid.free_area_m2());
        let region = cs.largest_region().expect("free");
        let pairs = random_pairs(&cs, region, 2000, 5);
        let (mut builds, mut queries) = (Vec::new(), Vec::new());
        let mut last = None;
        for seed in 0..40 {
            let t = Instant::now();
            let rm = Roadmap::build(
                Arc::clone(&cs),
                &PrmParams {
                    samples: n,
                    seed,
                    ..PrmParams::default()
                },
            )
            .expect("rm");
            builds.push(ms(t));
            if std::env::var("PRM_PROFILE_VERBOSE").is_ok() {
                println!(
                    "seed {seed}: {:.3} ms {:?}",
                    builds[builds.len() - 1],
                    rm.stats()
                );
            }
            last = Some(rm);
        }
        let rm = last.expect("built");
        let opts = QueryOptions {
            algorithm: d.algorithm,
            no_densify: false,
        };
        for &(s, g) in &pairs {
            let t = Instant::now();
            let _ = rm.query(s, g, opts);
            queries.push(ms(t));
        }
        builds.sort_by(f64::total_cmp);
        queries.sort_by(f64::total_cmp);
        println!(
            "n={n} stats {:?}\nbuild ms: min {:.3} p50 {:.3}\nquery ms: min {:.4} p50 {:.4} p90 {:.4} mean {:.4}",
            rm.stats(),
            builds[0],
            builds[builds.len() / 2],
            queries[0],
            queries[queries.len() / 2],
            queries[queries.len() * 9 / 10],
            queries.iter().sum::<f64>() / queries.len() as f64
        );
    }

    /// The benchmark's own runs (`run_ours`: fresh roadmap and one query per run, timed as in
    /// `prm.csv`) at n* only, every map, without OMPL or plots: the quick way to check the
    /// Table 2 targets.
    /// `cargo test --release -p bench --lib prm::tests::n_star_table -- --ignored --nocapture`
    /// (`PRM_BENCH_MAPS`, `PRM_BENCH_RUNS` as for the full benchmark; `PRM_BENCH_VERBOSE=1`
    /// prints every run).
    #[test]
    #[ignore = "measuring aid; run by hand in release"]
    fn n_star_table() {
        let Some(shared) = shared_maps() else { return };
        let env = |k: &str| std::env::var(k).ok();
        let dir = env("PRM_BENCH_MAPS").map_or(shared, PathBuf::from);
        let opts = PrmBenchOptions {
            runs: env("PRM_BENCH_RUNS")
                .and_then(|v| v.parse().ok())
                .unwrap_or(50),
            ompl: None,
            ..PrmBenchOptions::default()
        };
        let verbose = env("PRM_BENCH_VERBOSE").is_some_and(|v| v != "0");
        let inflation = Inflation {
            robot_radius_m: opts.robot_radius_m,
            safety_margin_m: opts.safety_margin_m,
        };
        let yamls = find_yamls(&dir).expect("maps");
        println!(
            "| map | cells | n* | build ms mean / p50 | search ms mean / p50 / max | success | densified |"
        );
        println!("|---|---:|---:|---|---|---:|---:|");
        for (yaml, name) in yamls.iter().zip(map_names(&dir, &yamls)) {
            let grid = load_ros_map(yaml).expect("map loads");
            let free_area_m2 = grid.free_area_m2();
            let cs = Arc::new(ConfigSpace::new(&grid, inflation).expect("cspace"));
            let Some(region) = cs.largest_region() else {
                continue;
            };
            let n = optimal_samples(free_area_m2);
            let pairs = random_pairs(&cs, region, opts.runs, mix(opts.seed, hash_str(&name)));
            let rows = run_ours(&cs, &opts, &name, free_area_m2, n, &pairs, false).expect("runs");
            if verbose {
                for r in &rows {
                    println!(
                        "  {name} run {}: build {:.4} search {:.5} densified {} length {:?}",
                        r.run, r.build_ms, r.search_ms, r.densified, r.length_m
                    );
                }
            }
            let s = &summarize(&rows)[&("ours", name.clone(), n)];
            let mut builds: Vec<f64> = rows.iter().map(|r| r.build_ms).collect();
            builds.sort_by(f64::total_cmp);
            println!(
                "| {name} | {}×{} | {n} | {:.3} / {:.3} | {:.4} / {:.4} / {:.4} | {:.0}% | {} |",
                grid.width,
                grid.height,
                s.build_ms,
                builds[builds.len() / 2],
                s.search_ms,
                s.search_p50_ms,
                s.search_max_ms,
                s.success_pct,
                s.densified
            );
        }
    }

    /// The full benchmark, for measuring by hand:
    /// `PRM_BENCH_OUT=/tmp/prm cargo test --release -p bench --lib prm::tests::full_benchmark -- --ignored --nocapture`
    /// (`PRM_BENCH_RUNS`, `PRM_BENCH_PYTHON`, `PRM_BENCH_OMPL_RUNS`, `PRM_BENCH_MOVINGAI` adjust it).
    #[test]
    #[ignore = "minutes long; run by hand in release"]
    fn full_benchmark() {
        let Some(shared) = shared_maps() else { return };
        let env = |k: &str| std::env::var(k).ok();
        let dir = env("PRM_BENCH_MAPS").map_or(shared, PathBuf::from);
        let python = env("PRM_BENCH_PYTHON").map(PathBuf::from);
        let opts = PrmBenchOptions {
            maps_dir: dir,
            out_dir: PathBuf::from(env("PRM_BENCH_OUT").unwrap_or_else(|| "/tmp/prm-bench".into())),
            runs: env("PRM_BENCH_RUNS")
                .and_then(|v| v.parse().ok())
                .unwrap_or(50),
            ompl: python.map(|python| OmplOptions {
                python,
                cpp: env("PRM_BENCH_CPP").is_none_or(|v| v != "0"),
                runs: env("PRM_BENCH_OMPL_RUNS")
                    .and_then(|v| v.parse().ok())
                    .unwrap_or(10),
                ..OmplOptions::default()
            }),
            movingai_dir: env("PRM_BENCH_MOVINGAI").map(PathBuf::from),
            verbose: true,
            ..PrmBenchOptions::default()
        };
        let report = run_prm_bench(opts).expect("benchmark");
        println!("{}", report.markdown);
    }
}
