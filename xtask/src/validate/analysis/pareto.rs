//! Speed against accuracy: each run of a method as a point (wall time, error, penetrations),
//! each method's Pareto front as a chart series with every run as a report row, and the chart
//! itself — what the `compare` and `disk_plates` experiments share.

use anyhow::Result;

use crate::validate::charts::{self, Chart, Series, Style};
use crate::validate::{Check, Ctx, Outcome};

/// One run's outcome.
#[derive(Clone, Debug)]
pub(in crate::validate) struct Point {
    pub method: &'static str,
    pub h: f64,
    pub dt: f64,
    pub wall: f64,
    pub error: f64,
    pub penetrations: usize,
    /// How deep the deepest point went, in words (`analysis_depth`).
    pub depth: String,
}

/// The runs of `method`, fastest first.
fn runs_of<'a>(points: &'a [Point], method: &str) -> Vec<&'a Point> {
    let mut pts: Vec<&Point> = points.iter().filter(|p| p.method == method).collect();
    pts.sort_by(|a, b| a.wall.total_cmp(&b.wall));
    pts
}

/// Each method's Pareto front (the most accurate run up to each wall time) as a chart series.
pub(in crate::validate) fn fronts(points: &[Point], methods: &[&str]) -> Vec<Series> {
    let mut series = Vec::new();
    for (c, m) in methods.iter().enumerate() {
        let mut best = f64::INFINITY;
        let mut front = Vec::new();
        for p in runs_of(points, m) {
            if p.error < best {
                best = p.error;
                front.push((p.wall, p.error.max(1e-6)));
            }
        }
        series.push(Series::line(*m, front, c));
    }
    series
}

/// Every run as a table row (figure prefixed by `prefix`), method by method, fastest first.
pub(in crate::validate) fn run_rows(
    points: &[Point],
    methods: &[&str],
    prefix: &str,
    out: &mut Outcome,
) {
    for m in methods {
        for p in runs_of(points, m) {
            out.checks.push(Check::info(
                &format!("{prefix}{m}, h = {}, Δt = {:.2e} s", p.h, p.dt),
                format!(
                    "error {:.2} %, {:.2} s wall, max penetrations {}{}",
                    100.0 * p.error,
                    p.wall,
                    p.penetrations,
                    if p.penetrations > 0 {
                        format!(" ({})", p.depth)
                    } else {
                        String::new()
                    }
                ),
                "→ 0".into(),
            ));
        }
    }
}

/// The largest penetration count over the runs of methods whose name starts with `prefix`.
pub(in crate::validate) fn max_penetrations(points: &[Point], prefix: &str) -> usize {
    points
        .iter()
        .filter(|p| p.method.starts_with(prefix))
        .map(|p| p.penetrations)
        .max()
        .unwrap_or(0)
}

/// The speed-against-accuracy chart (log–log, markers) of `series` as `stem` (tier appended).
pub(in crate::validate) fn pareto_chart(
    ctx: &Ctx,
    stem: &str,
    title: &str,
    y_label: &str,
    series: Vec<Series>,
) -> Result<std::path::PathBuf> {
    charts::write_styled(
        &ctx.charts,
        &Chart {
            stem: format!("{stem}_{}", ctx.tier.name()),
            title: title.into(),
            x_label: "wall time (s)".into(),
            y_label: y_label.into(),
            series,
        },
        Style {
            log_x: true,
            log_y: true,
            markers: true,
            ..Default::default()
        },
    )
}
