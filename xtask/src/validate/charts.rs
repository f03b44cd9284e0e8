//! Line charts as PNG and SVG through plotters, with the DejaVu Sans font embedded (no system
//! font libraries needed).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

/// One curve of a chart.
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
    /// Colour index into the palette.
    pub colour: usize,
    /// Dashed (reference / analytic curves).
    pub dashed: bool,
}

impl Series {
    /// A solid curve.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Self {
            label: label.into(),
            points,
            colour,
            dashed: false,
        }
    }

    /// A dashed reference curve.
    pub fn reference(label: impl Into<String>, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Self {
            label: label.into(),
            points,
            colour,
            dashed: true,
        }
    }
}

/// A chart: title, axis labels, curves.
pub struct Chart {
    /// File stem (without extension).
    pub stem: String,
    /// Title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Curves.
    pub series: Vec<Series>,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(90, 90, 90),
];

fn bounds(series: &[Series]) -> (f64, f64, f64, f64) {
    let pts = series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in pts.filter(|p| p.0.is_finite() && p.1.is_finite()) {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if !x0.is_finite() {
        return (0.0, 1.0, 0.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let pad = 0.05 * (y1 - y0).max(1e-300 + 1e-12 * y1.abs());
    if y1 - y0 <= 0.0 {
        return (x0, x1, y0 - 1.0, y1 + 1.0);
    }
    (x0, x1, y0 - pad, y1 + pad)
}

/// How a chart is drawn beyond its data.
#[derive(Clone, Copy, Debug, Default)]
pub struct Style {
    /// Logarithmic x axis (data must be positive).
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// Mark every data point (scatter-like), besides the line.
    pub markers: bool,
    /// Markers only, no lines (categorical scatter plots such as stability maps).
    pub no_lines: bool,
    /// Where the legend goes (where the data leave room).
    pub legend: Corner,
}

/// A corner of the plot.
#[derive(Clone, Copy, Debug, Default)]
pub enum Corner {
    #[default]
    UpperRight,
    UpperLeft,
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, chart: &Chart, st: Style) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    // Log axes: plot log10 of the data and label the ticks with the values.
    let tx = |v: f64| if st.log_x { v.log10() } else { v };
    let ty = |v: f64| if st.log_y { v.log10() } else { v };
    let owned: Vec<Series> = chart
        .series
        .iter()
        .map(|s| Series {
            label: s.label.clone(),
            points: s.points.iter().map(|&(x, y)| (tx(x), ty(y))).collect(),
            colour: s.colour,
            dashed: s.dashed,
        })
        .collect();
    let chart = &Chart {
        stem: chart.stem.clone(),
        title: chart.title.clone(),
        x_label: chart.x_label.clone(),
        y_label: chart.y_label.clone(),
        series: owned,
    };
    let (mut x0, mut x1, y0, y1) = bounds(&chart.series);
    if st.markers {
        let pad = 0.04 * (x1 - x0);
        x0 -= pad;
        x1 += pad;
    }
    let mut c = ChartBuilder::on(&root)
        .caption(&chart.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    c.configure_mesh()
        .x_desc(&chart.x_label)
        .y_desc(&chart.y_label)
        .label_style(("sans-serif", 14))
        .y_label_formatter(&|v| {
            if st.log_y {
                significant(10f64.powf(*v))
            } else {
                axis_label(*v, y1 - y0)
            }
        })
        .x_label_formatter(&|v| {
            if st.log_x {
                significant(10f64.powf(*v))
            } else {
                axis_label(*v, x1 - x0)
            }
        })
        .draw()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    for s in &chart.series {
        let colour = PALETTE[s.colour % PALETTE.len()];
        let style = colour.stroke_width(2);
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .collect();
        if st.markers {
            c.draw_series(pts.iter().map(|&p| Circle::new(p, 4, colour.filled())))
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        }
        if st.no_lines {
            let anno = c
                .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            anno.label(&s.label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
            continue;
        }
        let anno = if s.dashed {
            c.draw_series(DashedLineSeries::new(pts, 8, 5, style))
                .map_err(|e| anyhow::anyhow!("{e:?}"))?
        } else {
            c.draw_series(LineSeries::new(pts, style))
                .map_err(|e| anyhow::anyhow!("{e:?}"))?
        };
        anno.label(&s.label).legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
        });
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(match st.legend {
            Corner::UpperRight => SeriesLabelPosition::UpperRight,
            Corner::UpperLeft => SeriesLabelPosition::UpperLeft,
        })
        .draw()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    root.present().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    Ok(())
}

/// A positive value with at most three significant digits (log-axis ticks).
fn significant(v: f64) -> String {
    if (1e-3..1e4).contains(&v) {
        let digits = (2 - v.log10().floor() as i32).max(0) as usize;
        let s = format!("{v:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.2e}")
    }
}

/// A tick label: `0` for values at round-off of the axis range, plain decimals for moderate
/// magnitudes, scientific otherwise.
fn axis_label(v: f64, range: f64) -> String {
    if v.abs() <= 1e-9 * range.abs() {
        "0".into()
    } else if (1e-2..1e4).contains(&v.abs()) {
        let s = format!("{v:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{v:.2e}")
    }
}

/// Write `dir/<stem>.png` and `dir/<stem>.svg`; returns the PNG path.
pub fn write(dir: &Path, chart: &Chart) -> Result<PathBuf> {
    write_styled(dir, chart, Style::default())
}

/// [`write`] with log axes and/or point markers.
pub fn write_styled(dir: &Path, chart: &Chart, style: Style) -> Result<PathBuf> {
    femp::render::register_fonts();
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let png = dir.join(format!("{}.png", chart.stem));
    let svg = dir.join(format!("{}.svg", chart.stem));
    draw(
        BitMapBackend::new(&png, (800, 500)).into_drawing_area(),
        chart,
        style,
    )
    .with_context(|| format!("drawing {}", png.display()))?;
    draw(
        SVGBackend::new(&svg, (800, 500)).into_drawing_area(),
        chart,
        style,
    )
    .with_context(|| format!("drawing {}", svg.display()))?;
    Ok(png)
}
