//! SVG figures (plotters): the map with covariance ellipses against ground truth, and
//! predicted vs measured spectra with their difference inside the +-16.35 dB bound (the
//! paper's figures 8-10).

use std::path::Path;

use plotters::prelude::*;

use super::diagnostics::SpectrumComparison;
use super::map::{position_covariance, MapFeature};
use super::trajectory::PoseSample;

/// A figure that could not be drawn or written.
#[derive(Debug, thiserror::Error)]
#[error("figure {path}: {message}")]
pub struct FigureError {
    /// The file being written.
    pub path: String,
    /// What went wrong.
    pub message: String,
}

fn fig_err(path: &Path, e: impl std::fmt::Display) -> FigureError {
    FigureError {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Ground truth to draw beside the estimate (empty when unknown).
#[derive(Debug, Clone, Default)]
pub struct TruthOverlay {
    /// True vehicle positions.
    pub trajectory: Vec<(f64, f64)>,
    /// True feature positions.
    pub features: Vec<(f64, f64)>,
}

/// Points of the ellipse `{p : (p - m)^T C^-1 (p - m) = k^2}` of a 2x2 covariance.
pub fn covariance_ellipse(mean: (f64, f64), c: [[f64; 2]; 2], k: f64, n: usize) -> Vec<(f64, f64)> {
    // Eigen-decomposition of a symmetric 2x2 in closed form.
    let (a, b, d) = (c[0][0], 0.5 * (c[0][1] + c[1][0]), c[1][1]);
    let tr = a + d;
    let disc = ((a - d) * (a - d) / 4.0 + b * b).sqrt();
    let l1 = (tr / 2.0 + disc).max(0.0);
    let l2 = (tr / 2.0 - disc).max(0.0);
    let phi = 0.5 * (2.0 * b).atan2(a - d);
    let (s1, s2) = (k * l1.sqrt(), k * l2.sqrt());
    (0..=n)
        .map(|i| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            let (ex, ey) = (s1 * t.cos(), s2 * t.sin());
            (
                mean.0 + ex * phi.cos() - ey * phi.sin(),
                mean.1 + ex * phi.sin() + ey * phi.cos(),
            )
        })
        .collect()
}

fn bounds(points: impl Iterator<Item = (f64, f64)>) -> Option<(f64, f64, f64, f64)> {
    let mut b: Option<(f64, f64, f64, f64)> = None;
    for (x, y) in points.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        b = Some(match b {
            None => (x, x, y, y),
            Some((x0, x1, y0, y1)) => (x0.min(x), x1.max(x), y0.min(y), y1.max(y)),
        });
    }
    b
}

/// Draws the map: features with 3-sigma position ellipses, the estimated trajectory, and
/// the true trajectory and features when known.
pub fn draw_map(
    path: &Path,
    features: &[MapFeature],
    trajectory: &[PoseSample],
    truth: &TruthOverlay,
) -> Result<(), FigureError> {
    let all = features
        .iter()
        .map(|f| (f.x_m, f.y_m))
        .chain(trajectory.iter().map(|p| (p.x_m, p.y_m)))
        .chain(truth.trajectory.iter().copied())
        .chain(truth.features.iter().copied());
    let (x0, x1, y0, y1) = bounds(all).unwrap_or((-10.0, 10.0, -10.0, 10.0));
    let span = (x1 - x0).max(y1 - y0).max(1.0) * 0.55;
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let root = SVGBackend::new(path, (900, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fig_err(path, e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "map: features (3-sigma), trajectory vs truth",
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(cx - span..cx + span, cy - span..cy + span)
        .map_err(|e| fig_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()
        .map_err(|e| fig_err(path, e))?;
    if !truth.features.is_empty() {
        chart
            .draw_series(
                truth
                    .features
                    .iter()
                    .map(|&p| Cross::new(p, 5, BLACK.stroke_width(1))),
            )
            .map_err(|e| fig_err(path, e))?
            .label("true feature")
            .legend(|(x, y)| Cross::new((x, y), 5, BLACK));
    }
    if !truth.trajectory.is_empty() {
        chart
            .draw_series(LineSeries::new(
                truth.trajectory.iter().copied(),
                BLACK.stroke_width(2),
            ))
            .map_err(|e| fig_err(path, e))?
            .label("true trajectory")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    }
    chart
        .draw_series(LineSeries::new(
            trajectory.iter().map(|p| (p.x_m, p.y_m)),
            BLUE.stroke_width(2),
        ))
        .map_err(|e| fig_err(path, e))?
        .label("estimated trajectory")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    for f in features {
        let ring = covariance_ellipse((f.x_m, f.y_m), position_covariance(f), 3.0, 48);
        chart
            .draw_series(std::iter::once(PathElement::new(ring, RED.stroke_width(1))))
            .map_err(|e| fig_err(path, e))?;
    }
    chart
        .draw_series(
            features
                .iter()
                .map(|f| Circle::new((f.x_m, f.y_m), 3, RED.filled())),
        )
        .map_err(|e| fig_err(path, e))?
        .label("mapped feature")
        .legend(|(x, y)| Circle::new((x, y), 3, RED.filled()));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| fig_err(path, e))?;
    root.present().map_err(|e| fig_err(path, e))
}

/// Draws one beam: predicted and measured spectra (top) and predicted minus measured with
/// the +-bound (bottom), as in the paper's figures 8, 9 and 10.
pub fn draw_spectrum(path: &Path, cmp: &SpectrumComparison) -> Result<(), FigureError> {
    let range = |i: usize| cmp.first_bin_m + i as f64 * cmp.bin_m;
    let n = cmp.measured_db.len().min(cmp.predicted_db.len());
    let r_max = range(n.max(1));
    let finite = |v: &&f64| v.is_finite();
    let lo = cmp
        .measured_db
        .iter()
        .chain(&cmp.predicted_db)
        .filter(finite)
        .fold(f64::INFINITY, |a, &b| a.min(b));
    let hi = cmp
        .measured_db
        .iter()
        .chain(&cmp.predicted_db)
        .filter(finite)
        .fold(f64::NEG_INFINITY, |a, &b| a.max(b));
    let (lo, hi) = if lo < hi {
        (lo - 5.0, hi + 5.0)
    } else {
        (-20.0, 80.0)
    };
    let root = SVGBackend::new(path, (1000, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fig_err(path, e))?;
    let (top, bottom) = root.split_vertically(480);
    let title = format!(
        "rotation {} bearing {:.1} deg: predicted vs measured",
        cmp.rotation,
        cmp.bearing_rad.to_degrees()
    );
    let mut chart = ChartBuilder::on(&top)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(45)
        .build_cartesian_2d(0.0..r_max, lo..hi)
        .map_err(|e| fig_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("range (m)")
        .y_desc("power (dB)")
        .draw()
        .map_err(|e| fig_err(path, e))?;
    chart
        .draw_series(LineSeries::new(
            (0..n).filter_map(|i| cmp.measured_db.get(i).map(|&v| (range(i), v))),
            BLACK,
        ))
        .map_err(|e| fig_err(path, e))?
        .label("measured")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
    chart
        .draw_series(LineSeries::new(
            (0..n).filter_map(|i| cmp.predicted_db.get(i).map(|&v| (range(i), v))),
            RED,
        ))
        .map_err(|e| fig_err(path, e))?
        .label("predicted")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| fig_err(path, e))?;
    let bound = cmp.bound_db;
    let mut diff = ChartBuilder::on(&bottom)
        .caption(
            "predicted - measured, with the 99% bound",
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(45)
        .build_cartesian_2d(0.0..r_max, -3.0 * bound..3.0 * bound)
        .map_err(|e| fig_err(path, e))?;
    diff.configure_mesh()
        .x_desc("range (m)")
        .y_desc("error (dB)")
        .draw()
        .map_err(|e| fig_err(path, e))?;
    diff.draw_series(LineSeries::new(
        (0..n).filter_map(|i| {
            let (p, m) = (cmp.predicted_db.get(i)?, cmp.measured_db.get(i)?);
            let d = (p - m).clamp(-3.0 * bound, 3.0 * bound);
            Some((range(i), d))
        }),
        BLUE,
    ))
    .map_err(|e| fig_err(path, e))?;
    for b in [bound, -bound] {
        diff.draw_series(LineSeries::new([(0.0, b), (r_max, b)], RED.stroke_width(2)))
            .map_err(|e| fig_err(path, e))?;
    }
    root.present().map_err(|e| fig_err(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_ellipse_of_a_diagonal_covariance_has_its_axes_on_x_and_y() {
        let pts = covariance_ellipse((1.0, 2.0), [[4.0, 0.0], [0.0, 1.0]], 3.0, 4);
        // t = 0: +6 along x; t = pi/2: +3 along y.
        assert!((pts[0].0 - 7.0).abs() < 1e-9 && (pts[0].1 - 2.0).abs() < 1e-9);
        assert!((pts[1].0 - 1.0).abs() < 1e-9 && (pts[1].1 - 5.0).abs() < 1e-9);
    }

    #[test]
    fn both_figures_are_written_as_svg() {
        let dir = tempfile::tempdir().unwrap();
        let f = MapFeature {
            id: 1,
            x_m: 3.0,
            y_m: 4.0,
            rho: 0.3,
            alpha: 0.3,
            tau: 0.4,
            covariance: [
                [0.5, 0.1, 0.0, 0.0],
                [0.1, 0.3, 0.0, 0.0],
                [0.0; 4],
                [0.0; 4],
            ],
            observations: 3,
        };
        let pose = PoseSample {
            timestamp_s: 0.0,
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
            covariance: [[0.0; 3]; 3],
        };
        let map_path = dir.path().join("map.svg");
        draw_map(&map_path, &[f], &[pose], &TruthOverlay::default()).unwrap();
        let cmp = SpectrumComparison {
            rotation: 1,
            bearing_rad: 0.5,
            first_bin_m: 0.0,
            bin_m: 0.25,
            measured_db: (0..100).map(|i| (i % 7) as f64).collect(),
            predicted_db: (0..100).map(|i| (i % 5) as f64).collect(),
            bound_db: 16.35,
        };
        let sp = dir.path().join("spectrum.svg");
        draw_spectrum(&sp, &cmp).unwrap();
        for p in [map_path, sp] {
            let text = std::fs::read_to_string(p).unwrap();
            assert!(text.starts_with("<svg") || text.contains("<svg"));
        }
    }
}
