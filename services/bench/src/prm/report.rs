//! What the PRM benchmark writes: `prm.csv` (one row per run), the aggregates behind
//! `prm.md` (Table 2 and Figure 9's data, peers and the paper beside ours) and `prm.png`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use super::{MapInfo, PAPER_TABLE2, PrmBenchOptions, PrmRow};
use crate::error::BenchError;

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

pub(super) fn to_markdown(
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
        "| map | planner | runs | build ms | search ms (mean / p50) | length m | success | paths failing our exact check | build: peer / ours | search: peer / ours | end-to-end (build + search): peer / ours |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---|---:|---:|---:|---:|---:|---:|");
    // The least end-to-end ratio against OMPL's C++ PRM over the maps (issue 34: at least 2×).
    let mut least_cpp: Option<(f64, &str)> = None;
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
                let end_to_end = (x.build_ms + x.search_ms) / (o.build_ms + o.search_ms);
                if peer == "ompl_cpp" && least_cpp.is_none_or(|(r, _)| end_to_end < r) {
                    least_cpp = Some((end_to_end, &m.name));
                }
                let _ = writeln!(
                    s,
                    "| {} | {label} | {} | {:.2} | {:.3} / {:.3} | {:.2} | {:.0}% | {} | {:.1}× | {:.0}× | {:.1}× |",
                    m.name,
                    x.runs,
                    x.build_ms,
                    x.search_ms,
                    x.search_p50_ms,
                    x.length_m,
                    x.success_pct,
                    x.exact_invalid,
                    x.build_ms / o.build_ms,
                    x.search_ms / o.search_ms,
                    end_to_end
                );
            }
        }
    }
    if let Some((ratio, map)) = least_cpp {
        let _ = writeln!(
            s,
            "
End to end (build + search at n*), OMPL's C++ PRM takes at least {ratio:.1}× our time on every map (least on {map}); the target is 2×."
        );
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
pub(super) fn plot(path: &Path, maps: &[MapInfo], rows: &[PrmRow]) -> Result<(), BenchError> {
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
}
