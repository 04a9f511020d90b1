//! MovingAI grid benchmarks (`.map` + `.scen`): our roadmap on the scenarios' start/goal pairs,
//! success rate and path length against each scenario's optimal grid length.
//!
//! Cells are 1 m and the robot is a point (no inflation), so a path may use every free cell.
//! The scenario's optimum is an 8-connected path without corner cutting; straight roadmap edges
//! are not tied to the grid, so our paths can be up to ~8% shorter than it.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use prm::{
    ConfigSpace, Inflation, PlanningGrid, Point2, PrmParams, QueryOptions, Roadmap,
    SearchAlgorithm, optimal_samples,
};

use crate::error::BenchError;
use crate::maps::map_seed;

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct MovingAiOptions {
    /// Directory holding `.map` files and their `.scen` files.
    pub dir: PathBuf,
    /// k.
    pub neighbours: usize,
    /// d_max, metres (= cells).
    pub max_edge_m: f64,
    /// Roadmap seed.
    pub seed: u64,
    /// Scenarios used per map, spread evenly over the file (so over all its length buckets).
    pub scenarios_per_map: usize,
    /// Dijkstra or A*.
    pub algorithm: SearchAlgorithm,
}

/// One scenario line.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// Length bucket.
    pub bucket: u32,
    /// Start column and row (row 0 at the top, as in the file).
    pub start: (usize, usize),
    /// Goal column and row.
    pub goal: (usize, usize),
    /// Optimal 8-connected length without corner cutting.
    pub optimal: f64,
}

/// Results on one map.
#[derive(Debug, Clone, PartialEq)]
pub struct MovingAiMapResult {
    /// Map file stem.
    pub map: String,
    /// Columns × rows.
    pub size: (usize, usize),
    /// Free cells (= m²).
    pub free_cells: usize,
    /// Samples (n* of the free area).
    pub n: usize,
    /// Roadmap build time, ms (one roadmap per map, reused by every scenario).
    pub build_ms: f64,
    /// Scenarios run.
    pub scenarios: usize,
    /// Scenarios solved by the roadmap alone.
    pub solved_roadmap: usize,
    /// Scenarios solved with local densification allowed.
    pub solved: usize,
    /// Mean of our length / optimal length over solved scenarios.
    pub length_ratio: f64,
    /// The same after shortcutting.
    pub shortcut_ratio: f64,
    /// Mean query time, ms.
    pub search_ms: f64,
}

/// Results on every map.
#[derive(Debug, Clone, PartialEq)]
pub struct MovingAiReport {
    /// One entry per map that has a scenario file.
    pub maps: Vec<MovingAiMapResult>,
}

/// Parses a MovingAI `.map`: `.`, `G`, `S` are free; everything else is blocked.
pub fn parse_map(text: &str) -> Result<PlanningGrid, String> {
    let mut lines = text.lines();
    let mut width = None;
    let mut height = None;
    for line in lines.by_ref() {
        let mut it = line.split_whitespace();
        match (it.next(), it.next()) {
            (Some("type"), _) => {}
            (Some("height"), Some(v)) => {
                height = Some(v.parse::<usize>().map_err(|e| format!("height: {e}"))?)
            }
            (Some("width"), Some(v)) => {
                width = Some(v.parse::<usize>().map_err(|e| format!("width: {e}"))?)
            }
            (Some("map"), None) => break,
            _ => return Err(format!("unexpected header line `{line}`")),
        }
    }
    let (w, h) = (width.ok_or("no width")?, height.ok_or("no height")?);
    let rows: Vec<&str> = lines.take(h).collect();
    if rows.len() != h {
        return Err(format!("expected {h} rows, found {}", rows.len()));
    }
    let mut blocked = vec![true; w * h];
    // File row 0 is the top; the planner's row 0 is the bottom.
    for (file_row, line) in rows.iter().enumerate() {
        let bytes = line.as_bytes();
        if bytes.len() < w {
            return Err(format!(
                "row {file_row} has {} cells, expected {w}",
                bytes.len()
            ));
        }
        let row = h - 1 - file_row;
        for (col, b) in bytes[..w].iter().enumerate() {
            blocked[row * w + col] = !matches!(b, b'.' | b'G' | b'S');
        }
    }
    Ok(PlanningGrid {
        width: w,
        height: h,
        resolution: 1.0,
        origin_x: 0.0,
        origin_y: 0.0,
        blocked,
    })
}

/// Parses a `.scen` file (version 1).
pub fn parse_scen(text: &str) -> Result<Vec<Scenario>, String> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if i == 0 && line.starts_with("version") || line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split('\t').collect();
        if f.len() < 9 {
            return Err(format!("line {}: expected 9 tab-separated fields", i + 1));
        }
        let num = |j: usize| {
            f[j].trim()
                .parse::<f64>()
                .map_err(|e| format!("line {}: field {}: {e}", i + 1, j + 1))
        };
        out.push(Scenario {
            bucket: num(0)? as u32,
            start: (num(4)? as usize, num(5)? as usize),
            goal: (num(6)? as usize, num(7)? as usize),
            optimal: num(8)?,
        });
    }
    Ok(out)
}

/// Runs every map in `opts.dir` that has a scenario file.
pub fn run_movingai_bench(opts: &MovingAiOptions) -> Result<MovingAiReport, BenchError> {
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| BenchError::Io { path: p, source }
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&opts.dir)
        .map_err(io(&opts.dir))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    files.sort();
    let mut maps = Vec::new();
    for map_path in files
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "map"))
    {
        let stem = map_path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        // `x.map.scen` (classic sets) or `x-random-1.scen` (multi-agent sets).
        let Some(scen_path) = files.iter().find(|p| {
            let name = p
                .file_name()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
            name.ends_with(".scen")
                && (name == format!("{stem}.map.scen") || name.starts_with(&format!("{stem}-")))
        }) else {
            continue;
        };
        let fmt = |p: &Path| {
            let p = p.to_path_buf();
            move |message| BenchError::Format { path: p, message }
        };
        let grid = parse_map(&std::fs::read_to_string(map_path).map_err(io(map_path))?)
            .map_err(fmt(map_path))?;
        let scens = parse_scen(&std::fs::read_to_string(scen_path).map_err(io(scen_path))?)
            .map_err(fmt(scen_path))?;
        maps.push(
            run_map(opts, &stem, &grid, &scens).map_err(|source| BenchError::Build {
                map: stem.clone(),
                source,
            })?,
        );
    }
    Ok(MovingAiReport { maps })
}

fn run_map(
    opts: &MovingAiOptions,
    name: &str,
    grid: &PlanningGrid,
    scens: &[Scenario],
) -> Result<MovingAiMapResult, prm::BuildError> {
    let free_cells = grid.blocked.iter().filter(|b| !**b).count();
    let inflation = Inflation {
        robot_radius_m: 0.0,
        safety_margin_m: 0.0,
    };
    let cs = match ConfigSpace::new(grid, inflation) {
        Ok(cs) => Arc::new(cs),
        // A map the planner rejects has nothing to measure; report it as empty.
        Err(_) => {
            return Ok(MovingAiMapResult {
                map: name.to_string(),
                size: (grid.width, grid.height),
                free_cells,
                n: 0,
                build_ms: 0.0,
                scenarios: 0,
                solved_roadmap: 0,
                solved: 0,
                length_ratio: f64::NAN,
                shortcut_ratio: f64::NAN,
                search_ms: f64::NAN,
            });
        }
    };
    let n = optimal_samples(free_cells as f64);
    let params = PrmParams {
        samples: n,
        neighbours: opts.neighbours,
        max_edge_m: opts.max_edge_m,
        seed: map_seed(opts.seed, name),
        ..PrmParams::default()
    };
    let t = Instant::now();
    let roadmap = Roadmap::build(cs, &params)?;
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let step = (scens.len() / opts.scenarios_per_map.max(1)).max(1);
    let chosen: Vec<&Scenario> = scens
        .iter()
        .step_by(step)
        .take(opts.scenarios_per_map)
        .collect();
    let centre =
        |(c, r): (usize, usize)| Point2::new(c as f64 + 0.5, (grid.height - 1 - r) as f64 + 0.5);
    let (mut solved_roadmap, mut solved) = (0, 0);
    let (mut ratio, mut sc_ratio, mut search) = (0.0, 0.0, 0.0);
    for s in &chosen {
        let (a, b) = (centre(s.start), centre(s.goal));
        let strict = QueryOptions {
            algorithm: opts.algorithm,
            no_densify: true,
        };
        if roadmap.query(a, b, strict).is_ok() {
            solved_roadmap += 1;
        }
        let t = Instant::now();
        let plan = roadmap.query(
            a,
            b,
            QueryOptions {
                no_densify: false,
                ..strict
            },
        );
        search += t.elapsed().as_secs_f64() * 1e3;
        if let Ok(p) = plan {
            solved += 1;
            let opt = s.optimal.max(1e-9);
            ratio += p.length_m / opt;
            sc_ratio += roadmap.shortcut(&p).length_m / opt;
        }
    }
    let k = chosen.len().max(1) as f64;
    let sol = solved.max(1) as f64;
    Ok(MovingAiMapResult {
        map: name.to_string(),
        size: (grid.width, grid.height),
        free_cells,
        n,
        build_ms,
        scenarios: chosen.len(),
        solved_roadmap,
        solved,
        length_ratio: ratio / sol,
        shortcut_ratio: sc_ratio / sol,
        search_ms: search / k,
    })
}

/// The MovingAI section of the Markdown report.
pub fn to_markdown(r: &MovingAiReport) -> String {
    let mut s = String::from(
        "\n## MovingAI grid benchmarks (1 m cells, point robot, one roadmap per map at n*)\n\n",
    );
    s.push_str("| map | cells | free | n* | build ms | scenarios | solved by roadmap alone | solved (with densification) | length / optimal | after shortcut | search ms |\n");
    s.push_str("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for m in &r.maps {
        let pct = |x: usize| 100.0 * x as f64 / m.scenarios.max(1) as f64;
        let _ = writeln!(
            s,
            "| {} | {}×{} | {} | {} | {:.2} | {} | {:.1}% | {:.1}% | {:.3} | {:.3} | {:.3} |",
            m.map,
            m.size.0,
            m.size.1,
            m.free_cells,
            m.n,
            m.build_ms,
            m.scenarios,
            pct(m.solved_roadmap),
            pct(m.solved),
            m.length_ratio,
            m.shortcut_ratio,
            m.search_ms
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_a_small_map_with_row_zero_at_the_bottom() {
        let g = parse_map("type octile\nheight 2\nwidth 3\nmap\n.@.\n..T\n").expect("map");
        assert_eq!((g.width, g.height), (3, 2));
        // Bottom row (file row 1) is "..T".
        assert_eq!(g.blocked, vec![false, false, true, false, true, false]);
    }

    #[test]
    fn rejects_a_short_map() {
        assert!(parse_map("type octile\nheight 3\nwidth 3\nmap\n...\n").is_err());
    }

    #[test]
    fn parses_scenarios() {
        let s = parse_scen("version 1\n0\tmaps/a.map\t49\t49\t1\t11\t1\t12\t1\n").expect("scen");
        assert_eq!(s.len(), 1);
        assert_eq!(s[0].start, (1, 11));
        assert_eq!(s[0].goal, (1, 12));
        assert!((s[0].optimal - 1.0).abs() < 1e-12);
    }
}
