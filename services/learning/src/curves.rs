//! Training curves like the paper's Figure 10: per-episode reward with its moving average and
//! standard deviation over 100 episodes, as CSV and PNG.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;

use crate::trainer::EpisodeRecord;

/// Window of the moving statistics, episodes.
pub const WINDOW: usize = 100;

/// One point of a smoothed curve.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct CurvePoint {
    /// Episode index (from 1).
    pub episode: u64,
    /// Environment steps when the episode ended.
    pub env_steps: u64,
    /// Training seconds when the episode ended.
    pub wall_s: f64,
    /// Mean reward over the last [`WINDOW`] episodes.
    pub mean: f64,
    /// Their standard deviation.
    pub std: f64,
    /// Share of them that reached the goal.
    pub success: f64,
}

/// The moving statistics of `episodes`.
pub fn smooth(episodes: &[EpisodeRecord]) -> Vec<CurvePoint> {
    let mut out = Vec::with_capacity(episodes.len());
    for (i, e) in episodes.iter().enumerate() {
        let w = &episodes[i.saturating_sub(WINDOW - 1)..=i];
        let n = w.len() as f64;
        let mean = w.iter().map(|e| e.reward).sum::<f64>() / n;
        let var = w.iter().map(|e| (e.reward - mean).powi(2)).sum::<f64>() / n;
        let success = w.iter().filter(|e| e.outcome == "goal").count() as f64 / n;
        out.push(CurvePoint {
            episode: e.episode,
            env_steps: e.env_steps,
            wall_s: e.wall_s,
            mean,
            std: var.sqrt(),
            success,
        });
    }
    out
}

/// `curves.csv`: one row per episode with its reward, outcome and the moving statistics.
pub fn curves_csv(episodes: &[EpisodeRecord]) -> String {
    let mut s = String::from(
        "episode,env_steps,wall_s,reward,outcome,steps,reward_mean_100,reward_std_100,success_rate_100\n",
    );
    for (e, p) in episodes.iter().zip(smooth(episodes)) {
        let _ = writeln!(
            s,
            "{},{},{:.3},{:.3},{},{},{:.3},{:.3},{:.3}",
            e.episode,
            e.env_steps,
            e.wall_s,
            e.reward,
            e.outcome,
            e.steps,
            p.mean,
            p.std,
            p.success
        );
    }
    s
}

/// Writes `curves.csv` and `curves.png` (the reward's moving statistics) of `episodes` into
/// `dir`.
pub fn write_curves(dir: &Path, title: &str, episodes: &[EpisodeRecord]) -> Result<(), PlotError> {
    let csv = dir.join(CSV_FILE);
    std::fs::write(&csv, curves_csv(episodes)).map_err(|e| PlotError {
        path: csv.display().to_string(),
        message: e.to_string(),
    })?;
    plot_curves(
        &dir.join(PNG_FILE),
        title,
        &[("reward".into(), smooth(episodes))],
    )
}

/// The curves' file names.
pub const CSV_FILE: &str = "curves.csv";
/// See [`CSV_FILE`].
pub const PNG_FILE: &str = "curves.png";

/// Why a plot could not be drawn.
#[derive(Debug, thiserror::Error)]
#[error("plot {path}: {message}")]
pub struct PlotError {
    /// The file.
    pub path: String,
    /// What went wrong.
    pub message: String,
}

/// Draws curves (label, points) into a PNG: the mean as a line, ± one standard deviation as a
/// band, x = episode.
pub fn plot_curves(
    path: &Path,
    title: &str,
    series: &[(String, Vec<CurvePoint>)],
) -> Result<(), PlotError> {
    register_font();
    let err = |e: &dyn std::fmt::Display| PlotError {
        path: path.display().to_string(),
        message: e.to_string(),
    };
    let root = BitMapBackend::new(path, (960, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let x_max = series
        .iter()
        .flat_map(|(_, p)| p.last().map(|p| p.episode as f64))
        .fold(1.0, f64::max);
    let (mut y_min, mut y_max) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in series.iter().flat_map(|(_, p)| p) {
        y_min = y_min.min(p.mean - p.std);
        y_max = y_max.max(p.mean + p.std);
    }
    if !y_min.is_finite() {
        (y_min, y_max) = (-1.0, 1.0);
    }
    let pad = (y_max - y_min).max(1.0) * 0.05;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x_max, (y_min - pad)..(y_max + pad))
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("episode")
        .y_desc(format!("reward (moving mean ± std over {WINDOW} episodes)"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    let colours = [BLUE, GREEN, RED, MAGENTA, CYAN, BLACK];
    for (k, (label, points)) in series.iter().enumerate() {
        let colour = colours[k % colours.len()];
        let upper: Vec<(f64, f64)> = points
            .iter()
            .map(|p| (p.episode as f64, p.mean + p.std))
            .collect();
        let lower: Vec<(f64, f64)> = points
            .iter()
            .rev()
            .map(|p| (p.episode as f64, p.mean - p.std))
            .collect();
        let band: Vec<(f64, f64)> = upper.into_iter().chain(lower).collect();
        chart
            .draw_series(std::iter::once(Polygon::new(
                band,
                colour.mix(0.15).filled(),
            )))
            .map_err(|e| err(&e))?;
        chart
            .draw_series(LineSeries::new(
                points.iter().map(|p| (p.episode as f64, p.mean)),
                colour.stroke_width(2),
            ))
            .map_err(|e| err(&e))?
            .label(label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::LowerRight)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Registers the embedded DejaVu Sans as plotters' "sans-serif" (no system fonts needed);
/// every plot of the project (training curves, benchmark plots) calls it first.
pub fn register_font() {
    use std::sync::Once;
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // Only unparsable font bytes fail; the plot is drawn without text then.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ep(i: u64, reward: f64, goal: bool) -> EpisodeRecord {
        EpisodeRecord {
            episode: i,
            env_steps: i * 10,
            wall_s: i as f64,
            reward,
            outcome: if goal { "goal" } else { "collision" }.into(),
            steps: 10,
        }
    }

    #[test]
    fn the_moving_window_is_100_episodes() {
        let eps: Vec<_> = (1..=150)
            .map(|i| ep(i, if i > 100 { 10.0 } else { 0.0 }, i > 100))
            .collect();
        let s = smooth(&eps);
        assert_eq!(s[0].mean, 0.0);
        // Episode 150: the last 100 are 51..=150, of which 50 scored 10.
        assert!((s[149].mean - 5.0).abs() < 1e-9);
        assert!((s[149].std - 5.0).abs() < 1e-9);
        assert!((s[149].success - 0.5).abs() < 1e-9);
        let csv = curves_csv(&eps);
        assert_eq!(csv.lines().count(), 151);
        let dir = tempfile::tempdir().expect("tmp");
        let png = dir.path().join("c.png");
        plot_curves(&png, "test", &[("run".into(), s)]).expect("plot");
        assert!(std::fs::metadata(&png).expect("png").len() > 1000);
    }
}
