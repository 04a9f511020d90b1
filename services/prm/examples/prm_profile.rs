//! Profiles roadmap builds on ROS map_server maps (a development tool, not the benchmark:
//! `mentalsim bench prm` is). For every `.yaml` under the directory given (default
//! `../shared/maps/ros`): n*, median build time over `RUNS` seeds (default 20), nodes, edges,
//! components, edge checks, and the time per build phase.
//!
//! `cargo run --release -p planning --example prm_profile -- /work/shared/maps/ros [runs] [n-scale]`

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use prm::{BuildPhase, ConfigSpace, Inflation, PlanningGrid, PrmParams, Roadmap};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = PathBuf::from(args.get(1).map_or("../shared/maps/ros", String::as_str));
    let runs: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(20);
    let scale: f64 = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(1.0);
    let filter = args.get(4).cloned();
    let mut yamls = Vec::new();
    find(&dir, &mut yamls);
    yamls.sort();
    for yaml in yamls {
        let name = yaml
            .parent()
            .and_then(Path::file_name)
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        if filter.as_ref().is_some_and(|f| !name.contains(f.as_str())) {
            continue;
        }
        let Some(grid) = load(&yaml) else {
            eprintln!("{}: cannot read", yaml.display());
            continue;
        };
        let free =
            grid.blocked.iter().filter(|b| !**b).count() as f64 * grid.resolution * grid.resolution;
        let cs = Arc::new(
            ConfigSpace::new(
                &grid,
                Inflation {
                    robot_radius_m: 0.2,
                    safety_margin_m: 0.05,
                },
            )
            .expect("cspace"),
        );
        let n = ((prm::optimal_samples(free) as f64) * scale).round() as usize;
        let mut times = Vec::new();
        let mut phases = [0.0f64; BuildPhase::COUNT];
        let (mut nodes, mut edges, mut comps, mut checks, mut bridge, mut flood) =
            (0, 0, 0, 0, 0, 0);
        for run in 0..runs {
            let params = PrmParams {
                samples: n,
                seed: run as u64 + 1,
                ..PrmParams::default()
            };
            let t = Instant::now();
            let mut last = t;
            let mut on_phase = |p: BuildPhase| {
                let now = Instant::now();
                phases[p as usize] += (now - last).as_secs_f64() * 1e3;
                last = now;
            };
            let rm = Roadmap::build_observed(
                Arc::clone(&cs),
                &params,
                &grid::Stop::never(),
                &mut on_phase,
            )
            .expect("build");
            times.push(t.elapsed().as_secs_f64() * 1e3);
            let s = rm.stats();
            nodes += rm.nodes().count();
            edges += s.edges;
            comps += s.components;
            checks += s.edge_checks;
            bridge += s.bridge_nodes;
            flood += s.flood_blocks;
        }
        times.sort_by(f64::total_cmp);
        let r = runs as f64;
        println!(
            "{name:28} n={n:4} median {:7.3} ms | nodes {:6.1} edges {:7.1} comps {:5.2} checks {:7.1} bridge {:5.1} flood {:7.0} | {}",
            times[runs / 2],
            nodes as f64 / r,
            edges as f64 / r,
            comps as f64 / r,
            checks as f64 / r,
            bridge as f64 / r,
            flood as f64 / r,
            BuildPhase::ALL
                .iter()
                .map(|p| format!("{} {:.3}", p.name(), phases[*p as usize] / r))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
}

fn find(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            find(&p, out);
        } else if p.extension().is_some_and(|x| x == "yaml") {
            out.push(p);
        }
    }
}

/// A minimal map_server reader: P5 images, `trinary` (only cells below free_thresh are free).
fn load(yaml: &Path) -> Option<PlanningGrid> {
    let text = std::fs::read_to_string(yaml).ok()?;
    let field = |k: &str| {
        text.lines()
            .find_map(|l| l.trim().strip_prefix(k)?.strip_prefix(':'))
            .map(|v| v.trim().to_string())
    };
    let image = yaml.parent()?.join(field("image")?);
    let resolution: f64 = field("resolution")?.parse().ok()?;
    let negate = field("negate").is_some_and(|v| v == "1");
    let free_thresh: f64 = field("free_thresh")?.parse().ok()?;
    let origin: Vec<f64> = field("origin")?
        .trim_matches(['[', ']'])
        .split(',')
        .filter_map(|v| v.trim().parse().ok())
        .collect();
    let bytes = std::fs::read(image).ok()?;
    // Header: magic, width, height, maxval, separated by whitespace, comments skipped.
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        if bytes[i] == b'#' {
            while bytes[i] != b'\n' {
                i += 1;
            }
            continue;
        }
        let s = i;
        while !bytes[i].is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[s..i]).to_string());
    }
    i += 1;
    let (w, h): (usize, usize) = (fields[1].parse().ok()?, fields[2].parse().ok()?);
    let max: f64 = fields[3].parse().ok()?;
    let px = &bytes[i..i + w * h];
    let mut blocked = vec![true; w * h];
    for row in 0..h {
        for col in 0..w {
            let v = f64::from(px[(h - 1 - row) * w + col]) / max;
            let occ = if negate { v } else { 1.0 - v };
            blocked[row * w + col] = occ >= free_thresh;
        }
    }
    Some(PlanningGrid {
        width: w,
        height: h,
        resolution,
        origin_x: origin[0],
        origin_y: origin[1],
        blocked,
    })
}
