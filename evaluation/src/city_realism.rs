//! The realistic city's realism per kilometre of its route: groups of consecutive rotations
//! rendered along each kilometre, measured as the real Oxford scans are (largest two-sample
//! KS distance over the range bands, share of bins 10 dB above their band's median, widths
//! of isolated peaks in range and azimuth, detections per rotation by the daemon's default
//! detector and by the learned front end for current units), each against the real scans;
//! and an SVG map of the city's layout and route.
//!
//! IO: [`write_map`] writes one SVG file; the rest runs in memory.

use std::path::Path;
use std::sync::Arc;

use bytes::BytesMut;
use plotters::prelude::*;
use protocol::Timestamp;
use sim_sensor::realism::stats::{ks_distance, scan_stats, Scans};
use sim_sensor::render::SceneRenderer;
use sim_sensor::scene::objects::ObjectKind;
use sim_sensor::scene::{FeatureKind, Scene};
use sim_sensor::visits::DriveSample;
use slam_node::detect::{
    BeamDetector, DetectorKind, DetectorSettings, LearnedFloor, LineDetector, LineSettings,
    RangeAxis,
};

use crate::error::EvalError;

/// Rotations of each group that warm the detectors up (TPP keeps a per-bin minimum over
/// scans; the learned floor learns from the stream) and are not counted for detections.
pub const WARMUP_ROTATIONS: usize = 2;

/// The realism figures of a set of scans.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Figures {
    /// Rotations measured.
    pub rotations: usize,
    /// Largest two-sample KS distance over the range bands against the reference (0 for
    /// the reference itself).
    pub ks_max: f64,
    /// The band where it is largest, metres.
    pub ks_band_m: (f64, f64),
    /// Share of bins 10 dB above their band's median.
    pub above_floor: f64,
    /// Median range width (FWHM) of isolated peaks, metres.
    pub range_fwhm_m: f64,
    /// Median azimuth width (FWHM) of isolated peaks, degrees.
    pub azimuth_fwhm_deg: f64,
    /// Detections per rotation, the daemon's default detector (TPP).
    pub tpp_per_rotation: f64,
    /// Targets per rotation, the learned front end for current units.
    pub learned_per_rotation: f64,
}

/// Measures `groups` (each a run of consecutive rotations) against the reference scans
/// `reference` (the KS distance; `None`: against themselves, 0).
pub fn figures(groups: &[Scans], reference: Option<&Scans>) -> Figures {
    let mut pooled = match groups.first() {
        Some(g) => Scans::new(g.azimuths, g.bins, g.bin_m),
        None => Scans::new(0, 0, 0.0),
    };
    for g in groups {
        pooled.rotations.extend(g.rotations.iter().cloned());
    }
    let stats = scan_stats(&pooled);
    let (mut ks_max, mut ks_band_m) = (0.0, (0.0, 0.0));
    if let Some(reference) = reference {
        let r = scan_stats(reference);
        for (k, (a, b)) in r.histograms.iter().zip(&stats.histograms).enumerate() {
            let ks = ks_distance(a, b);
            if ks > ks_max {
                ks_max = ks;
                ks_band_m = stats.bands.get(k).map_or((0.0, 0.0), |b| b.range_m);
            }
        }
    }
    let (mut tpp, mut learned, mut counted) = (0.0, 0.0, 0usize);
    for g in groups {
        let n = g.rotations.len().saturating_sub(WARMUP_ROTATIONS);
        if n == 0 {
            continue;
        }
        tpp += tpp_per_rotation(g, WARMUP_ROTATIONS) * n as f64;
        learned += learned_per_rotation(g, WARMUP_ROTATIONS) * n as f64;
        counted += n;
    }
    let per = |total: f64| total / counted.max(1) as f64;
    Figures {
        rotations: pooled.rotations.len(),
        ks_max,
        ks_band_m,
        above_floor: stats.above_floor,
        range_fwhm_m: stats.widths.range_fwhm_m,
        azimuth_fwhm_deg: stats.widths.azimuth_fwhm_deg,
        tpp_per_rotation: per(tpp),
        learned_per_rotation: per(learned),
    }
}

/// Mean detections per rotation of the daemon's default detector (TPP, default settings,
/// no per-bin gain removed) over the rotations after `warmup`.
pub fn tpp_per_rotation(scans: &Scans, warmup: usize) -> f64 {
    let settings = DetectorSettings {
        kind: DetectorKind::Tpp,
        ..DetectorSettings::default()
    };
    let mut detector = BeamDetector::new(settings, scans.azimuths);
    let gain = vec![0.0; scans.bins];
    let axis = RangeAxis {
        first_bin_m: 0.0,
        bin_m: scans.bin_m,
    };
    let (mut out, mut total, mut counted) = (Vec::new(), 0usize, 0usize);
    let mut row_db = vec![0.0; scans.bins];
    for (r, rot) in scans.rotations.iter().enumerate() {
        for (a, row) in rot.chunks_exact(scans.bins.max(1)).enumerate() {
            for (d, &v) in row_db.iter_mut().zip(row) {
                *d = f64::from(v) / 2.0;
            }
            out.clear();
            detector.detect(a, &row_db, &gain, None, &axis, &mut out);
            if r >= warmup {
                total += out.len();
            }
        }
        counted += usize::from(r >= warmup);
    }
    total as f64 / counted.max(1) as f64
}

/// Mean targets per rotation of the learned front end for current units (the CTS350-X
/// profile's settings, as `slam-node --replay-dir` runs it) over the rotations after
/// `warmup`.
pub fn learned_per_rotation(scans: &Scans, warmup: usize) -> f64 {
    let facts = slam_node::pipeline::SourceFacts {
        max_range_m: Some(scans.bins as f64 * scans.bin_m),
        peak_fwhm_m: Some(scans.bin_m),
        ..Default::default()
    };
    let Ok(settings) =
        slam_node::pipeline::PipelineSettings::for_profile(&radar_model::profile::CTS350X, &facts)
    else {
        return f64::NAN;
    };
    let settings = settings.detector;
    let mut floor = LearnedFloor::new(settings.floor, scans.bins);
    let mut line = LineDetector::new();
    let axis = RangeAxis {
        first_bin_m: 0.0,
        bin_m: scans.bin_m,
    };
    let line_settings = LineSettings {
        merge_gap_bins: settings.peaks.merge_gap_bins,
        max_peaks: settings.peaks.max_peaks,
        min_range_m: settings.min_range_m,
        max_range_m: settings.max_range_m,
    };
    let (mut peaks, mut total, mut counted) = (Vec::new(), 0usize, 0usize);
    for (r, rot) in scans.rotations.iter().enumerate() {
        for row in rot.chunks_exact(scans.bins.max(1)) {
            line.detect(row, &mut floor, &axis, &line_settings, &mut peaks);
            if r >= warmup {
                total += peaks.len();
            }
        }
        counted += usize::from(r >= warmup);
    }
    total as f64 / counted.max(1) as f64
}

/// Renders `count` consecutive whole rotations from rotation `first` into 8-bit scans,
/// quantised as the wire does.
pub fn render_rotations(
    renderer: &Arc<SceneRenderer>,
    first: u64,
    count: u64,
) -> Result<Scans, EvalError> {
    let radar = renderer.radar();
    let n = u64::from(radar.azimuths);
    let mut scans = Scans::new(
        usize::from(radar.azimuths),
        usize::from(radar.range_bins),
        f64::from(radar.range_gain) * radar.bin_size_m(),
    );
    let mut cursor = renderer.cursor();
    let mut frame = BytesMut::new();
    let mut rows = Vec::with_capacity(usize::from(radar.azimuths) * usize::from(radar.range_bins));
    for rot in first..first + count {
        rows.clear();
        for k in rot * n..(rot + 1) * n {
            frame.clear();
            cursor.render(k, 0, Timestamp::EPOCH, &mut frame)?;
            rows.extend_from_slice(cursor.last_power_db());
        }
        scans.push_db(&rows);
    }
    Ok(scans)
}

/// The times (seconds after the start) where each whole or last partial kilometre of the
/// drive starts and ends, from the sampled ground truth.
pub fn kilometres(samples: &[DriveSample]) -> Vec<(f64, f64, f64)> {
    let driven = samples.last().map_or(0.0, |s| s.travelled_m);
    let time_at = |d: f64| {
        samples
            .iter()
            .find(|s| s.travelled_m >= d)
            .or(samples.last())
            .map_or(0.0, |s| s.t_s)
    };
    let mut out = Vec::new();
    let mut d = 0.0;
    while d < driven - 100.0 {
        let end = (d + 1000.0).min(driven);
        out.push((time_at(d), time_at(end), end - d));
        d += 1000.0;
    }
    out
}

/// Largest trajectory file read, bytes (a TUM row is under 100 bytes: hours of 4 Hz poses).
pub const MAX_TRAJECTORY_BYTES: u64 = 256 << 20;

/// The positions `(x, y)` of a trajectory in the TUM format (`timestamp x y z qx qy qz qw`
/// a row, `#` comments), as the daemon writes `trajectory.tum` and `trajectory-online.tum`.
pub fn read_tum_xy(path: &Path) -> Result<Vec<(f64, f64)>, EvalError> {
    Ok(read_tum_poses(path)?
        .into_iter()
        .map(|p| (p[1], p[2]))
        .collect())
}

/// The poses of a trajectory in the TUM format (`timestamp x y z qx qy qz qw` a row, `#`
/// comments; a rotation about +z, as the daemon writes them): `[time s, x m, y m, heading
/// rad]` a row. A file that is not a regular file (a FIFO, a device) is refused before it is
/// opened, and at most [`MAX_TRAJECTORY_BYTES`] are read.
pub fn read_tum_poses(path: &Path) -> Result<Vec<[f64; 4]>, EvalError> {
    let text = read_bounded_text(path, MAX_TRAJECTORY_BYTES)?;
    let data = |line: usize, reason: String| EvalError::Data {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut out = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let v: Vec<&str> = line.split_whitespace().collect();
        if v.len() != 8 {
            return Err(data(k + 1, format!("{} fields, a TUM row has 8", v.len())));
        }
        let num = |s: &str| {
            s.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| data(k + 1, format!("{s:?} is not a finite number")))
        };
        out.push([
            num(v[0])?,
            num(v[1])?,
            num(v[2])?,
            2.0 * num(v[6])?.atan2(num(v[7])?),
        ]);
    }
    Ok(out)
}

/// The whole of a text file of at most `max_bytes` (the daemon's outputs: a trajectory, a
/// diagnostics table). A path that is not a regular file (a FIFO, a device) is refused
/// before it is opened, and no more than `max_bytes + 1` bytes are ever read.
pub fn read_bounded_text(path: &Path, max_bytes: u64) -> Result<String, EvalError> {
    use std::io::Read as _;
    let io = |source| EvalError::Io {
        path: path.to_path_buf(),
        source,
    };
    let refuse = |reason: String| EvalError::Data {
        path: path.to_path_buf(),
        line: 0,
        reason,
    };
    if !std::fs::metadata(path).map_err(io)?.is_file() {
        return Err(refuse("not a regular file".into()));
    }
    let mut text = String::new();
    std::fs::File::open(path)
        .map_err(io)?
        .take(max_bytes + 1)
        .read_to_string(&mut text)
        .map_err(io)?;
    if text.len() as u64 > max_bytes {
        return Err(refuse(format!("larger than {max_bytes} bytes")));
    }
    Ok(text)
}

/// Draws the city: building fronts, walls, fences and hedges as lines, parked vehicles,
/// trunks and lamp posts as dots, the moving vehicles' starts, the driven route (the
/// ground truth) with a mark every kilometre, and `trajectories` (name, positions: the
/// daemon's estimates) over it. One metre is the same length on both axes.
pub fn write_map(
    path: &Path,
    scene: &Scene,
    samples: &[DriveSample],
    trajectories: &[(String, Vec<(f64, f64)>)],
) -> Result<(), EvalError> {
    let err = |e: &dyn std::fmt::Display| EvalError::Plot {
        name: path.display().to_string(),
        reason: e.to_string(),
    };
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    let mut grow = |p: [f64; 2]| {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    };
    for o in &scene.objects {
        if o.kind != ObjectKind::Clutter {
            o.from
                .into_iter()
                .chain(o.to)
                .chain(o.at)
                .for_each(&mut grow);
        }
    }
    samples.iter().for_each(|s| grow([s.pose.x_m, s.pose.y_m]));
    trajectories
        .iter()
        .flat_map(|(_, t)| t.iter())
        .for_each(|&(x, y)| grow([x, y]));
    if !(lo[0].is_finite() && hi[0].is_finite()) {
        return Err(err(&"nothing to draw"));
    }
    let (w_px, h_px) = (1400u32, 1000u32);
    let span = ((hi[0] - lo[0]) / f64::from(w_px - 80)).max((hi[1] - lo[1]) / f64::from(h_px - 90));
    let (cx, cy) = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]));
    let half = [
        0.5 * span * f64::from(w_px - 80),
        0.5 * span * f64::from(h_px - 90),
    ];
    let root = SVGBackend::new(path, (w_px, h_px)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "{}: layout and route ({:.0} m driven)",
                scene.name,
                samples.last().map_or(0.0, |s| s.travelled_m)
            ),
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(cx - half[0]..cx + half[0], cy - half[1]..cy + half[1])
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()
        .map_err(|e| err(&e))?;
    let lines = |kind: ObjectKind| {
        scene
            .objects
            .iter()
            .filter(move |o| o.kind == kind)
            .filter_map(|o| Some([o.from?, o.to?]))
    };
    let grey = RGBColor(90, 90, 90);
    let green = RGBColor(44, 140, 44);
    let brown = RGBColor(160, 110, 60);
    for (kind, color, width, name) in [
        (ObjectKind::BuildingFront, grey, 2, "building fronts"),
        (ObjectKind::Wall, grey, 2, "walls"),
        (ObjectKind::Hedge, green, 2, "hedges"),
        (ObjectKind::Fence, brown, 1, "fences"),
    ] {
        let segs: Vec<[[f64; 2]; 2]> = lines(kind).collect();
        if segs.is_empty() {
            continue;
        }
        chart
            .draw_series(segs.iter().map(|s| {
                PathElement::new(
                    vec![(s[0][0], s[0][1]), (s[1][0], s[1][1])],
                    color.stroke_width(width),
                )
            }))
            .map_err(|e| err(&e))?
            .label(name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
    }
    let dots = |pts: Vec<(f64, f64)>, color: RGBColor, size: u32, name: &'static str| {
        (pts, color, size, name)
    };
    let features = |kind: FeatureKind| -> Vec<(f64, f64)> {
        scene
            .features
            .iter()
            .filter(|f| f.kind == kind)
            .map(|f| (f.x_m, f.y_m))
            .collect()
    };
    let vehicles = |moving: bool| -> Vec<(f64, f64)> {
        scene
            .objects
            .iter()
            .filter(|o| o.kind == ObjectKind::Vehicle && (o.speed_mps != 0.0) == moving)
            .filter_map(|o| o.at.map(|p| (p[0], p[1])))
            .collect()
    };
    for (pts, color, size, name) in [
        dots(features(FeatureKind::Tree), green, 2, "trees (trunk)"),
        dots(
            features(FeatureKind::LampPost),
            RGBColor(200, 160, 0),
            2,
            "lamp posts",
        ),
        dots(
            vehicles(false),
            RGBColor(31, 119, 180),
            2,
            "parked vehicles",
        ),
        dots(
            vehicles(true),
            RGBColor(148, 103, 189),
            4,
            "moving vehicles (start)",
        ),
    ] {
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, size, color.filled())))
            .map_err(|e| err(&e))?
            .label(name)
            .legend(move |(x, y)| Circle::new((x + 9, y), 3, color.filled()));
    }
    let red = RGBColor(214, 39, 40);
    let route: Vec<(f64, f64)> = samples.iter().map(|s| (s.pose.x_m, s.pose.y_m)).collect();
    chart
        .draw_series(LineSeries::new(route, red.stroke_width(2)))
        .map_err(|e| err(&e))?
        .label("route (ground truth)")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], red.stroke_width(2)));
    let estimates = [
        RGBColor(0, 0, 0),
        RGBColor(255, 127, 14),
        RGBColor(23, 190, 207),
    ];
    for (k, (name, points)) in trajectories.iter().enumerate() {
        let color = estimates[k % estimates.len()];
        chart
            .draw_series(LineSeries::new(
                points.iter().copied(),
                color.stroke_width(2),
            ))
            .map_err(|e| err(&e))?
            .label(name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
    }
    let mut marks = Vec::new();
    let mut next_km = 0.0;
    for s in samples {
        if s.travelled_m >= next_km {
            marks.push((
                (s.pose.x_m, s.pose.y_m),
                format!("{:.0} km", next_km / 1000.0),
            ));
            next_km += 1000.0;
        }
    }
    chart
        .draw_series(marks.iter().map(|(p, label)| {
            EmptyElement::at(*p)
                + Circle::new((0, 0), 6, red.filled())
                + Text::new(label.clone(), (8, -16), ("sans-serif", 16).into_font())
        }))
        .map_err(|e| err(&e))?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tum_file_gives_its_positions_and_a_bad_row_is_a_typed_error_naming_the_line() {
        let dir = tempfile::tempdir().expect("dir");
        let path = dir.path().join("t.tum");
        std::fs::write(
            &path,
            "# timestamp x y z qx qy qz qw\n1.0 2.5 -3.0 0 0 0 0 1\n\n2.0 3.5 -4.0 0 0 0 0 1\n",
        )
        .expect("write");
        assert_eq!(
            read_tum_xy(&path).expect("read"),
            vec![(2.5, -3.0), (3.5, -4.0)]
        );
        std::fs::write(&path, "1.0 2.5 -3.0 0 0 0 0 1\n2.0 nan 1 0 0 0 0 1\n").expect("write");
        let err = read_tum_xy(&path).expect_err("nan");
        assert!(matches!(err, EvalError::Data { line: 2, .. }), "{err}");
        std::fs::write(&path, "1.0 2.5\n").expect("write");
        assert!(matches!(
            read_tum_xy(&path),
            Err(EvalError::Data { line: 1, .. })
        ));
        // Not a regular file (here a folder; a FIFO or a device alike): refused unread.
        assert!(matches!(
            read_tum_xy(dir.path()),
            Err(EvalError::Data { line: 0, .. })
        ));
    }

    #[test]
    fn a_drive_is_cut_into_whole_kilometres_and_a_last_stretch_over_100_m() {
        use sim_sensor::visits::Pose2Serde;
        let samples: Vec<DriveSample> = (0..=2250)
            .map(|k| DriveSample {
                t_s: f64::from(k) * 0.1,
                pose: Pose2Serde {
                    x_m: f64::from(k),
                    y_m: 0.0,
                    theta_rad: 0.0,
                },
                travelled_m: f64::from(k),
            })
            .collect();
        let km = kilometres(&samples);
        assert_eq!(km.len(), 3);
        assert!((km[0].0 - 0.0).abs() < 1e-9 && (km[0].1 - 100.0).abs() < 1e-9);
        assert!((km[2].2 - 250.0).abs() < 1e-9, "{km:?}");
    }
}
