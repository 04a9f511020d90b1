//! OMPL beside ours: the PyPI `ompl` Python bindings and the installed C++ library, each run as
//! a side program on the same inflated grid, n, k and start/goal pairs, their paths checked with
//! our exact segment test.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use prm::{ConfigSpace, Point2};

use super::{PrmBenchOptions, PrmRow};
use crate::maps::map_seed;

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

/// The OMPL side script, embedded so that the benchmark runs from any working directory.
const OMPL_SCRIPT: &str = include_str!("../../scripts/ompl_prm.py");

/// One map's OMPL run: the same inflated grid, n, k and start/goal pairs as ours.
pub(super) struct OmplJob<'a> {
    pub(super) cs: &'a ConfigSpace,
    pub(super) opts: &'a PrmBenchOptions,
    pub(super) ompl: &'a OmplOptions,
    pub(super) map: &'a str,
    pub(super) free_area_m2: f64,
    pub(super) ns: &'a [usize],
    pub(super) pairs: &'a [(Point2, Point2)],
}

/// The C++ side program, embedded like the script.
const OMPL_CPP: &str = include_str!("../../ompl/ompl_prm.cpp");

/// The Python side: interpreter + the embedded script written into the output directory.
pub(super) fn python_command(ompl: &OmplOptions, out_dir: &Path) -> Result<Command, String> {
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
pub(super) fn cpp_command(out_dir: &Path) -> Result<Command, String> {
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
pub(super) fn run_ompl(
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
            let seed = map_seed(opts.seed, map) & 0x7fff_ffff;
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
