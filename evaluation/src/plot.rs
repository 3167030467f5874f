//! SVG figures (plotters): line charts with optional horizontal reference lines, and
//! labelled scatter charts. Non-finite points are left out; an empty chart still draws.

use std::path::Path;

use plotters::prelude::*;

use crate::error::EvalError;

/// One line of a chart.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
}

/// A horizontal reference line.
#[derive(Debug, Clone)]
pub struct HLine {
    /// Legend text.
    pub name: String,
    /// Its height.
    pub y: f64,
}

/// A labelled point of a scatter chart.
#[derive(Debug, Clone)]
pub struct LabelledPoint {
    /// Position.
    pub x: f64,
    /// Position.
    pub y: f64,
    /// Text drawn beside it.
    pub label: String,
    /// Drawn larger and in red (the shipped setting).
    pub highlight: bool,
}

/// Axis titles and the caption.
#[derive(Debug, Clone, Copy)]
pub struct Labels<'a> {
    /// Caption.
    pub title: &'a str,
    /// x axis.
    pub x: &'a str,
    /// y axis.
    pub y: &'a str,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];

fn plot_err(path: &Path, e: impl std::fmt::Display) -> EvalError {
    EvalError::Plot {
        name: path.display().to_string(),
        reason: e.to_string(),
    }
}

fn extent(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let mut out: Option<(f64, f64)> = None;
    for v in values.filter(|v| v.is_finite()) {
        out = Some(match out {
            None => (v, v),
            Some((lo, hi)) => (lo.min(v), hi.max(v)),
        });
    }
    out
}

fn padded((lo, hi): (f64, f64)) -> (f64, f64) {
    let span = (hi - lo).abs().max(1e-9);
    (lo - 0.05 * span, hi + 0.05 * span)
}

type Chart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// Clears `root` and draws the caption, the axes and their titles over `x` and `y`.
fn axes<'a, 'b>(
    root: &'a DrawingArea<SVGBackend<'b>, plotters::coord::Shift>,
    path: &Path,
    labels: Labels<'_>,
    x: (f64, f64),
    y: (f64, f64),
) -> Result<Chart<'a, 'b>, EvalError> {
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    let mut chart = ChartBuilder::on(root)
        .caption(labels.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc(labels.x)
        .y_desc(labels.y)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    Ok(chart)
}

/// Draws `series` as lines, with `hlines` dashed across the chart.
pub fn line_chart(
    path: &Path,
    labels: Labels<'_>,
    series: &[Series],
    hlines: &[HLine],
) -> Result<(), EvalError> {
    let xs = extent(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let ys = extent(
        series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .chain(hlines.iter().map(|h| h.y)),
    );
    let (x0, x1) = padded(xs.unwrap_or((0.0, 1.0)));
    let (y0, y1) = padded(ys.unwrap_or((0.0, 1.0)));
    let root = SVGBackend::new(path, (900, 500)).into_drawing_area();
    let mut chart = axes(&root, path, labels, (x0, x1), (y0, y1))?;
    for (k, s) in series.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect();
        chart
            .draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(|e| plot_err(path, e))?
            .label(s.name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
    }
    for h in hlines {
        let dashes = (0..60).map(|i| {
            let a = x0 + (x1 - x0) * (2 * i) as f64 / 120.0;
            let b = x0 + (x1 - x0) * (2 * i + 1) as f64 / 120.0;
            PathElement::new(vec![(a, h.y), (b, h.y)], BLACK.stroke_width(1))
        });
        chart
            .draw_series(dashes)
            .map_err(|e| plot_err(path, e))?
            .label(h.name.as_str())
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(1)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}

/// Draws labelled points (speed against error).
pub fn scatter_chart(
    path: &Path,
    labels: Labels<'_>,
    points: &[LabelledPoint],
) -> Result<(), EvalError> {
    let x = padded(extent(points.iter().map(|p| p.x)).unwrap_or((0.0, 1.0)));
    let y = padded(extent(points.iter().map(|p| p.y)).unwrap_or((0.0, 1.0)));
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    let mut chart = axes(&root, path, labels, x, y)?;
    let finite = points.iter().filter(|p| p.x.is_finite() && p.y.is_finite());
    chart
        .draw_series(finite.map(|p| {
            let (size, color) = if p.highlight {
                (7, RED)
            } else {
                (4, PALETTE[0])
            };
            EmptyElement::at((p.x, p.y))
                + Circle::new((0, 0), size, color.filled())
                + Text::new(p.label.clone(), (6, -12), ("sans-serif", 11))
        }))
        .map_err(|e| plot_err(path, e))?;
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}

/// Mapped features of one run: positions and their 2x2 position covariances.
#[derive(Debug, Clone)]
pub struct FeatureSet {
    /// Legend text.
    pub name: String,
    /// `(x, y, [[c_xx, c_xy], [c_xy, c_yy]])`.
    pub features: Vec<(f64, f64, [[f64; 2]; 2])>,
}

/// The 3-sigma ellipse of a 2x2 covariance around `(x, y)`, as a closed polyline.
fn ellipse(x: f64, y: f64, c: [[f64; 2]; 2]) -> Vec<(f64, f64)> {
    let (a, b, d) = (c[0][0], c[0][1], c[1][1]);
    let mean = 0.5 * (a + d);
    let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let (l1, l2) = ((mean + r).max(0.0), (mean - r).max(0.0));
    let angle = 0.5 * (2.0 * b).atan2(a - d);
    let (s1, s2) = (3.0 * l1.sqrt(), 3.0 * l2.sqrt());
    (0..=36)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / 36.0;
            let (u, v) = (s1 * t.cos(), s2 * t.sin());
            (
                x + u * angle.cos() - v * angle.sin(),
                y + u * angle.sin() + v * angle.cos(),
            )
        })
        .collect()
}

/// Draws a map: `paths` as lines and each set's features as dots with their 3-sigma
/// ellipses, one metre the same length on both axes.
pub fn map_chart(
    path: &Path,
    labels: Labels<'_>,
    paths: &[Series],
    sets: &[FeatureSet],
) -> Result<(), EvalError> {
    let all = || {
        paths.iter().flat_map(|s| s.points.iter().copied()).chain(
            sets.iter()
                .flat_map(|s| s.features.iter().map(|f| (f.0, f.1))),
        )
    };
    let (mut x0, mut x1) = padded(extent(all().map(|p| p.0)).unwrap_or((0.0, 1.0)));
    let (mut y0, mut y1) = padded(extent(all().map(|p| p.1)).unwrap_or((0.0, 1.0)));
    // Equal scale: the plotting area is about 828 x 520 pixels of 900 x 620.
    let (w, h) = (828.0, 520.0);
    let scale = ((x1 - x0) / w).max((y1 - y0) / h);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    (x0, x1) = (cx - 0.5 * w * scale, cx + 0.5 * w * scale);
    (y0, y1) = (cy - 0.5 * h * scale, cy + 0.5 * h * scale);
    let root = SVGBackend::new(path, (900, 620)).into_drawing_area();
    let mut chart = axes(&root, path, labels, (x0, x1), (y0, y1))?;
    for (k, s) in paths.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect();
        chart
            .draw_series(LineSeries::new(pts, color.stroke_width(2)))
            .map_err(|e| plot_err(path, e))?
            .label(s.name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
    }
    for (k, s) in sets.iter().enumerate() {
        let color = PALETTE[(paths.len() + k) % PALETTE.len()];
        let finite = s
            .features
            .iter()
            .filter(|f| f.0.is_finite() && f.1.is_finite());
        chart
            .draw_series(
                finite
                    .clone()
                    .map(|f| PathElement::new(ellipse(f.0, f.1, f.2), color.stroke_width(1))),
            )
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(finite.map(|f| Circle::new((f.0, f.1), 3, color.filled())))
            .map_err(|e| plot_err(path, e))?
            .label(s.name.as_str())
            .legend(move |(x, y)| Circle::new((x + 9, y), 3, color.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}
