//! Predicted against measured spectra on simulated scenes: the fraction of bins inside the
//! paper's 99 % bound (16.35 dB) and the bias, for the paper's spreading form and the
//! textbook form under 40 and 60 dB/decade compensation. Two ways: from the true state
//! (what the filter's prediction converges to), and from the previous scan alone (detect,
//! fit, move, predict: the procedure used on the real Oxford scans).

use std::fmt::Write as _;

use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::power::{PowerModel, PowerTarget};
use radar_model::spectrum::{beam_spectrum_targets, SpectrumModel};
use sim_sensor::scene::{shipped, Scene, Spreading};
use sim_sensor::OdometryNoise;
use slam_node::detect::{FloorProfile, RangeAxis};

use crate::error::EvalError;
use crate::plot::{line_chart, HLine, Labels, Series};
use crate::report::{num, pct, table, Options, Section};
use crate::scan::{
    add_peaks, detect_scan, fit_targets, median_floor, predict_and_compare, Comparison, Floor, Row,
    Scan, Tally, Variant, TARGET_BIN_HALF_WIDTH_M,
};
use crate::sections::single_scan_detector;
use crate::world::World;

/// The beam figure's file name.
const FIGURE: &str = "spectra_beam.svg";

/// Draws a measured and a predicted beam and their difference against the paper's bound
/// (figures 8 to 10 in one).
pub fn beam_figure(path: &std::path::Path, t: &BeamTrace, title: &str) -> Result<(), EvalError> {
    let (ranges, measured, predicted) = t;
    let diff: Vec<(f64, f64)> = ranges
        .iter()
        .zip(measured.iter().zip(predicted))
        .map(|(r, (m, p))| (*r, p - m))
        .collect();
    line_chart(
        path,
        Labels {
            title,
            x: "range (m)",
            y: "power (dB) / predicted - measured (dB)",
        },
        &[
            Series {
                name: "measured (8-bit wire)".into(),
                points: ranges
                    .iter()
                    .copied()
                    .zip(measured.iter().copied())
                    .collect(),
            },
            Series {
                name: "predicted (expected over looks)".into(),
                points: ranges
                    .iter()
                    .copied()
                    .zip(predicted.iter().copied())
                    .collect(),
            },
            Series {
                name: "predicted - measured".into(),
                points: diff,
            },
        ],
        &[
            HLine {
                name: "+16.35 dB (paper's 99 % bound)".into(),
                y: radar_model::noise::PAPER_BOUND_99_DB,
            },
            HLine {
                name: "-16.35 dB".into(),
                y: -radar_model::noise::PAPER_BOUND_99_DB,
            },
        ],
    )
}

/// Rendered scans of a world with the true pose at each scan's middle azimuth.
pub fn render_scans(world: &World, rotations: usize) -> Result<(Vec<Scan>, Vec<Pose2>), EvalError> {
    let mut cursor = world.cursor();
    let mut frame = bytes::BytesMut::new();
    let n = world.azimuths();
    let mut scans = Vec::new();
    let mut mids = Vec::new();
    for k in 0..rotations as u64 {
        let mut scan = Scan::default();
        for a in 0..n {
            let index = k * n + a;
            let ts = world.azimuth_timestamp(index)?;
            frame.clear();
            cursor.render(index, 0, ts, &mut frame)?;
            scan.rows.push(Row {
                timestamp_s: world.azimuth_time_s(index),
                bearing_rad: world.bearing_rad(index),
                measured_db: cursor
                    .last_power_db()
                    .iter()
                    .map(|&p| protocol::bin8_to_db(protocol::db_to_bin8(p)))
                    .collect(),
            });
        }
        scans.push(scan);
        mids.push(cursor.pose_at(world.azimuth_offset_ns(k * n + n / 2))?);
    }
    Ok((scans, mids))
}

/// `b` expressed in the frame of `a`.
pub fn relative(a: &Pose2, b: &Pose2) -> Pose2 {
    let (s, c) = a.theta.sin_cos();
    let dx = b.x - a.x;
    let dy = b.y - a.y;
    Pose2::new(
        c * dx + s * dy,
        -s * dx + c * dy,
        wrap_angle(b.theta - a.theta),
    )
}

/// Compares spectra predicted from the true state (true pose per azimuth, true features,
/// materials and loss) with the rendered ones, for every variant.
/// One beam for the figure: ranges, measured, predicted (first variant).
pub type BeamTrace = (Vec<f64>, Vec<f64>, Vec<f64>);

fn from_truth(
    world: &World,
    rotations: usize,
    trace: &mut Option<BeamTrace>,
) -> Result<Vec<(Variant, Comparison)>, EvalError> {
    let variants = Variant::all();
    let models = variants
        .iter()
        .map(|v| SpectrumModel::new(world.geometry, &v.compensation(), world.noise))
        .collect::<Result<Vec<_>, _>>()?;
    let mut out: Vec<(Variant, Comparison)> = variants
        .iter()
        .map(|v| (*v, Comparison::default()))
        .collect();
    let mut cursor = world.cursor();
    let mut frame = bytes::BytesMut::new();
    let mut targets = Vec::new();
    let mut best_targets = 0usize;
    let mut st = Vec::new();
    let mut predicted = vec![0.0; world.geometry.bins];
    for index in 0..(rotations as u64 * world.azimuths()) {
        let ts = world.azimuth_timestamp(index)?;
        frame.clear();
        // The features the simulator put in this beam (at their apparent, bearing-perturbed
        // positions), so that the comparison tests the power model, not the bearing noise.
        let inside = cursor.features_in_beam(index)?;
        cursor.render(index, 0, ts, &mut frame)?;
        let measured: Vec<f64> = cursor
            .last_power_db()
            .iter()
            .map(|&p| protocol::bin8_to_db(protocol::db_to_bin8(p)))
            .collect();
        targets.clear();
        targets.extend(inside.iter().filter_map(|&(range_m, id)| {
            world.feature(id).map(|f| PowerTarget {
                range_m,
                material: f.material,
            })
        }));
        for ((variant, cmp), model) in out.iter_mut().zip(&models) {
            let power = PowerModel {
                form: variant.form,
                ..world.power
            };
            beam_spectrum_targets(&power, &targets, world.scene.loss_db, &mut st)?;
            model.expected_into(&st, &mut predicted)?;
            // The figure shows the beam holding the most targets (the first such).
            if variant == &variants[0] && targets.len() > best_targets {
                best_targets = targets.len();
                let ranges = (0..world.geometry.bins)
                    .map(|b| world.geometry.bin_range_m(b))
                    .collect();
                *trace = Some((ranges, measured.clone(), predicted.clone()));
            }
            for (b, (p, m)) in predicted.iter().zip(&measured).enumerate() {
                let d = p - m;
                cmp.all.add(d);
                let r = world.geometry.bin_range_m(b);
                if st
                    .iter()
                    .any(|t| (t.range_m - r).abs() <= TARGET_BIN_HALF_WIDTH_M)
                {
                    cmp.targets.add(d);
                }
            }
            add_peaks(
                &mut cmp.peaks,
                &world.geometry,
                &st,
                &predicted,
                &measured,
                model.floor_mean_db(),
            );
        }
    }
    Ok(out)
}

/// Detect-fit-move-predict from each scan to the next, for every variant and both floors.
pub fn from_previous_scan(
    scans: &[Scan],
    relative_poses: &[Pose2],
    geometry: &radar_model::spectrum::SpectrumGeometry,
    noise: &radar_model::noise::NoiseModel,
    power: &PowerModel,
    beam_width_rad: f64,
) -> Result<Vec<(Variant, &'static str, Comparison, f64)>, EvalError> {
    let mut out = Vec::new();
    let detector = single_scan_detector()?;
    let axis = RangeAxis {
        first_bin_m: geometry.range_offset_m,
        bin_m: geometry.bin_size_m,
    };
    for variant in Variant::all() {
        let comp = variant.compensation();
        let gain: Vec<f64> = (0..geometry.bins)
            .map(|b| comp.gain_db(geometry.bin_range_m(b)))
            .collect();
        let floor_model = SpectrumModel::new(*geometry, &comp, *noise)?;
        let floor_profile = FloorProfile::new(&floor_model, &noise.absent, detector.floor_tail_pfa);
        let model_power = PowerModel {
            form: variant.form,
            ..*power
        };
        for floor_name in ["model floor", "previous scan's floor"] {
            let mut cmp = Comparison::default();
            let mut clamped = 0usize;
            let mut fitted_total = 0usize;
            for (k, pose) in relative_poses.iter().enumerate() {
                let (Some(prev), Some(next)) = (scans.get(k), scans.get(k + 1)) else {
                    continue;
                };
                let obs = detect_scan(prev, detector, &floor_profile, &gain, &axis, beam_width_rad);
                let fitted = fit_targets(&obs, &model_power, 0.5 * beam_width_rad)?;
                clamped += fitted.iter().filter(|f| f.clamped).count();
                fitted_total += fitted.len();
                let floor = if floor_name == "model floor" {
                    Floor::Model
                } else {
                    Floor::PreviousScan(median_floor(prev, geometry.bins))
                };
                let c = predict_and_compare(
                    next,
                    &fitted,
                    pose,
                    &variant,
                    &model_power,
                    geometry,
                    noise,
                    &floor,
                    beam_width_rad,
                )?;
                merge(&mut cmp.all, &c.all);
                merge(&mut cmp.targets, &c.targets);
                merge(&mut cmp.peaks, &c.peaks);
            }
            out.push((
                variant,
                floor_name,
                cmp,
                clamped as f64 / fitted_total.max(1) as f64,
            ));
        }
    }
    Ok(out)
}

/// Adds `b` into `a`.
pub fn merge(a: &mut Tally, b: &Tally) {
    a.bins += b.bins;
    a.inside += b.inside;
    a.sum_db += b.sum_db;
    a.sum_sq_db += b.sum_sq_db;
}

fn truth_name(scene: &Scene) -> String {
    let form = match scene.receiver.spreading {
        Spreading::Paper => "paper",
        Spreading::Textbook => "textbook",
    };
    format!(
        "{form}, {} dB/dec",
        scene.receiver.compensation_db_per_decade
    )
}

/// The column names of [`cells`], in its order.
pub const COMPARISON_COLUMNS: [&str; 9] = [
    "all bins in bound",
    "bias (dB)",
    "RMS (dB)",
    "target bins in bound",
    "target-bin bias (dB)",
    "target bins",
    "peak bias (dB)",
    "peak RMS (dB)",
    "peaks",
];

/// A table header: `lead` columns, then [`COMPARISON_COLUMNS`], then `trail`.
pub fn comparison_header<'a>(lead: &[&'a str], trail: &[&'a str]) -> Vec<&'a str> {
    lead.iter()
        .chain(COMPARISON_COLUMNS.iter())
        .chain(trail.iter())
        .copied()
        .collect()
}

/// The cells of one comparison row.
pub fn cells(c: &Comparison) -> Vec<String> {
    vec![
        pct(c.all.fraction_inside()),
        num(c.all.bias_db(), 2),
        num(c.all.rms_db(), 2),
        pct(c.targets.fraction_inside()),
        num(c.targets.bias_db(), 2),
        c.targets.bins.to_string(),
        num(c.peaks.bias_db(), 2),
        num(c.peaks.rms_db(), 2),
        c.peaks.bins.to_string(),
    ]
}

/// Runs the section.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    let rotations = opts.budget.spectra_rotations.max(1);
    let mut truth_rows = Vec::new();
    let mut scan_rows = Vec::new();
    let mut figure = false;
    let cases: [(&str, Option<(Spreading, f64)>); 4] = [
        ("penetration-wood", None),
        ("outdoor-field", None),
        ("outdoor-field", Some((Spreading::Textbook, 60.0))),
        ("dense-clutter", None),
    ];
    for (name, receiver) in cases {
        let mut scene = shipped::load(name)?;
        if let Some((spreading, slope)) = receiver {
            scene.receiver.spreading = spreading;
            scene.receiver.compensation_db_per_decade = slope;
        }
        let truth = truth_name(&scene);
        let seconds = (rotations + 1) as f64 / scene.radar.rotation_hz();
        let world = World::new(scene, 21, seconds, OdometryNoise::default())?;
        let mut trace = None;
        for (variant, cmp) in from_truth(&world, rotations, &mut trace)? {
            let mut row = vec![name.to_string(), truth.clone(), variant.name()];
            row.extend(cells(&cmp));
            truth_rows.push(row);
        }
        if name == "penetration-wood" && receiver.is_none() {
            if let Some(t) = trace {
                beam_figure(&opts.out_dir.join(FIGURE), &t, "penetration-wood, the beam with the most targets: prediction from the true state (paper form, 40 dB/dec)")?;
                figure = true;
            }
        }
        let (scans, mids) = render_scans(&world, rotations + 1)?;
        let rel: Vec<Pose2> = mids.windows(2).map(|w| relative(&w[0], &w[1])).collect();
        for (variant, floor, cmp, clamped) in from_previous_scan(
            &scans,
            &rel,
            &world.geometry,
            &world.noise,
            &world.power,
            world.scene.radar.beam_width_rad,
        )? {
            let mut row = vec![
                name.to_string(),
                truth.clone(),
                variant.name(),
                floor.to_string(),
            ];
            row.extend(cells(&cmp));
            row.push(pct(clamped));
            scan_rows.push(row);
        }
    }
    let mut body = String::new();
    let _ = writeln!(
        body,
        "Bound: the paper's 99 % bound of +/-16.35 dB on predicted minus measured. Measured \
         spectra are the simulator's, quantised to the 8-bit wire. `all bins` counts every \
         bin of every azimuth (mostly noise floor); `target bins` only those within {} m of a \
         predicted target. Bias = mean of predicted minus measured. {rotations} rotation(s) \
         per scene, seed 21. The scene's own physics is given in the *truth* column: a \
         predictor equal to it is the reference, the others show what a wrong model costs.\n",
        TARGET_BIN_HALF_WIDTH_M
    );
    let _ = writeln!(
        body,
        "**From the true state** (true pose, the features the simulator placed in each beam at \
         their apparent positions, true materials and loss):\n"
    );
    body.push_str(&table(
        &comparison_header(&["scene", "truth", "predictor"], &[]),
        &truth_rows,
    ));
    if figure {
        let _ = writeln!(body, "\n![a predicted and a measured beam]({FIGURE})\n");
    }
    let _ = writeln!(
        body,
        "\n**From the previous scan alone** (detect with the shipped detector, or, when that \
         is TPP, which needs several scans, with OS-CFAR and the shipped window and \
         threshold; fit each \
         target's rho by eq. 13 with alpha = {} and L = 0, move by the true relative pose \
         between the scans' middle azimuths, predict the next scan). The floor is either \
         radar-model's target-absent model or the per-bin median of the previous scan. \
         `rho clamped`: share of fitted targets whose rho hit a bound.\n",
        crate::scan::ASSUMED_ALPHA
    );
    body.push_str(&table(
        &comparison_header(&["scene", "truth", "predictor", "floor"], &["rho clamped"]),
        &scan_rows,
    ));
    Ok(Section {
        title: "Spectra: predicted against measured (simulated)".into(),
        body,
    })
}
