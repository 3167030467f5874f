//! Whole-scan spectrum prediction without a filter, as the paper's figures 8-10 do it from
//! one position to the next: detect the targets of scan k, fit each one's reflectivity by
//! eq. 13 (with the targets in front of it as occluders), move them into the frame of scan
//! k+1 by the known relative pose, predict every bin of every azimuth of scan k+1, and
//! compare with what was measured there (in-bound fraction of the paper's 99 % bound, bias).
//!
//! Used on the recorded Oxford scans and, like for like, on simulated scans.

use radar_model::compensation::Compensation;
use radar_model::geometry::{features_in_beam, wrap_angle, Beam, BeamHit, Pose2};
use radar_model::material::Material;
use radar_model::noise::{NoiseModel, PAPER_BOUND_99_DB};
use radar_model::power::{PowerModel, PowerTarget, RadarConstants, SpreadingForm};
use radar_model::spectrum::{
    beam_spectrum_targets, db_power_sum, SpectrumGeometry, SpectrumModel, SpectrumTarget,
    KERNEL_SPAN_SIGMAS,
};
use slam_node::detect::{
    BeamDetection, BeamDetector, DetectorSettings, FloorProfile, Grouper, Observation, RangeAxis,
};

use crate::error::EvalError;

/// Absorbed share assumed for every target fitted from one scan (absorption is not
/// observable from a single look; the filter's prior is 0.3, its own estimates vary).
pub const ASSUMED_ALPHA: f64 = 0.1;
/// Reflected shares are fitted into `[MIN_RHO, 1 - alpha - MIN_RHO]`.
pub const MIN_RHO: f64 = 1e-6;
/// Bins within this of a predicted target's range count as target bins (m).
pub const TARGET_BIN_HALF_WIDTH_M: f64 = 1.0;

/// One azimuth of a scan.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Time (s).
    pub timestamp_s: f64,
    /// Bearing (rad, clockwise from forward).
    pub bearing_rad: f64,
    /// Measured power per bin (dB, compensation applied, as on the wire).
    pub measured_db: Vec<f64>,
}

/// One rotation.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Scan {
    /// Azimuths in order.
    pub rows: Vec<Row>,
}

/// A predictor: spreading form and compensation slope.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Variant {
    /// Eq. 13 as the paper writes it, or the textbook radar equation.
    pub form: SpreadingForm,
    /// Receiver compensation slope (dB/decade).
    pub slope_db_per_decade: f64,
}

impl Variant {
    /// The four combinations of the brief.
    pub fn all() -> [Variant; 4] {
        [
            Variant {
                form: SpreadingForm::Paper,
                slope_db_per_decade: 40.0,
            },
            Variant {
                form: SpreadingForm::Paper,
                slope_db_per_decade: 60.0,
            },
            Variant {
                form: SpreadingForm::Textbook,
                slope_db_per_decade: 40.0,
            },
            Variant {
                form: SpreadingForm::Textbook,
                slope_db_per_decade: 60.0,
            },
        ]
    }

    /// A short name.
    pub fn name(&self) -> String {
        let form = match self.form {
            SpreadingForm::Paper => "paper",
            SpreadingForm::Textbook => "textbook",
        };
        format!("{form}, {} dB/dec", self.slope_db_per_decade)
    }

    /// Its compensation, calibrated as radar-model calibrates the simulator's.
    pub fn compensation(&self) -> Compensation {
        Compensation::calibrated(self.slope_db_per_decade, &RadarConstants::default())
    }
}

/// Predicted minus measured, accumulated.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Tally {
    /// Bins compared.
    pub bins: u64,
    /// Of those, inside the bound.
    pub inside: u64,
    /// Sum of differences (dB).
    pub sum_db: f64,
    /// Sum of squared differences.
    pub sum_sq_db: f64,
}

impl Tally {
    /// Adds one bin's difference.
    pub fn add(&mut self, diff_db: f64) {
        if !diff_db.is_finite() {
            return;
        }
        self.bins += 1;
        if diff_db.abs() <= PAPER_BOUND_99_DB {
            self.inside += 1;
        }
        self.sum_db += diff_db;
        self.sum_sq_db += diff_db * diff_db;
    }

    /// Fraction inside the bound.
    pub fn fraction_inside(&self) -> f64 {
        if self.bins == 0 {
            f64::NAN
        } else {
            self.inside as f64 / self.bins as f64
        }
    }

    /// Mean difference (bias, dB).
    pub fn bias_db(&self) -> f64 {
        if self.bins == 0 {
            f64::NAN
        } else {
            self.sum_db / self.bins as f64
        }
    }

    /// RMS difference (dB).
    pub fn rms_db(&self) -> f64 {
        if self.bins == 0 {
            f64::NAN
        } else {
            (self.sum_sq_db / self.bins as f64).sqrt()
        }
    }
}

/// All bins, only the bins near predicted targets, and the peaks.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Comparison {
    /// Every bin.
    pub all: Tally,
    /// Bins within [`TARGET_BIN_HALF_WIDTH_M`] of a predicted target.
    pub targets: Tally,
    /// Predicted peak level minus the strongest measured bin within [`PEAK_WINDOW_M`] of it,
    /// for predicted targets at least [`PEAK_MIN_SNR_DB`] above the floor with no other
    /// predicted target within [`PEAK_ISOLATION_M`] (the paper's figure 8 against 9).
    pub peaks: Tally,
}

/// Half-width of the window searched for a target's measured peak (m).
pub const PEAK_WINDOW_M: f64 = 0.5;
/// A predicted peak must stand this far above the floor to be compared (dB).
pub const PEAK_MIN_SNR_DB: f64 = 10.0;
/// No other predicted target may lie within this of a compared peak (m).
pub const PEAK_ISOLATION_M: f64 = 2.0;

/// Adds the peak comparison of every isolated, visible predicted target of one beam.
pub fn add_peaks(
    tally: &mut Tally,
    geometry: &SpectrumGeometry,
    targets: &[SpectrumTarget],
    predicted: &[f64],
    measured: &[f64],
    floor: &[f64],
) {
    for (i, t) in targets.iter().enumerate() {
        let isolated = targets
            .iter()
            .enumerate()
            .all(|(j, u)| j == i || (u.range_m - t.range_m).abs() > PEAK_ISOLATION_M);
        if !isolated {
            continue;
        }
        let centre = ((t.range_m - geometry.range_offset_m) / geometry.bin_size_m).round();
        if !(centre.is_finite() && centre >= 0.0) {
            continue;
        }
        // Finite and non-negative; out-of-range indices fall through `get`.
        let c = centre as usize;
        let (Some(p), Some(f)) = (predicted.get(c), floor.get(c)) else {
            continue;
        };
        if p - f < PEAK_MIN_SNR_DB {
            continue;
        }
        let half = (PEAK_WINDOW_M / geometry.bin_size_m).ceil().max(1.0) as usize;
        let lo = c.saturating_sub(half);
        let hi = (c + half + 1).min(measured.len());
        let Some(window) = measured.get(lo..hi) else {
            continue;
        };
        let m = window.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        tally.add(p - m);
    }
}

/// A target fitted from one scan, in that scan's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FittedTarget {
    /// Position (m) in the scan's frame (radar at the origin, heading 0).
    pub xy: [f64; 2],
    /// Fitted material.
    pub material: Material,
    /// The fit hit a bound of rho.
    pub clamped: bool,
}

/// The detector and grouper run over one scan: one observation per target.
pub fn detect_scan(
    scan: &Scan,
    detector: DetectorSettings,
    floor: &FloorProfile,
    gain_db: &[f64],
    axis: &RangeAxis,
    beam_width_rad: f64,
) -> Vec<Observation> {
    let azimuths = scan.rows.len().max(1);
    let mut det = BeamDetector::new(detector, azimuths);
    // The daemon's grouping for this radar (one owner: the front end's settings).
    let shipped = crate::daemon::shipped_settings().map(|s| s.front_end());
    let grouping = match shipped {
        Ok(fe) => slam_node::pipeline::FrontEndSettings {
            beam_width_rad,
            ..fe
        }
        .grouping(u16::try_from(azimuths).unwrap_or(u16::MAX)),
        Err(_) => return Vec::new(),
    };
    let mut grouper = Grouper::new(grouping);
    let mut found = Vec::new();
    let mut handoff = Vec::new();
    let mut out = Vec::new();
    for (slot, row) in scan.rows.iter().enumerate() {
        found.clear();
        det.detect(
            slot,
            &row.measured_db,
            gain_db,
            floor.floor(row.measured_db.len()),
            axis,
            &mut found,
        );
        handoff.clear();
        handoff.extend(found.iter().map(|d| BeamDetection {
            range_m: d.range_m,
            power_db: d.power_db,
            extent_m: d.extent_m,
            snr_db: d.snr_db,
        }));
        grouper.push(row.bearing_rad, row.timestamp_s, &handoff, &mut out);
    }
    grouper.flush(&mut out);
    out
}

/// Fits each observation's reflectivity by eq. 13 (the chosen form), nearest first, with
/// the already fitted targets inside its beam in front of it as occluders; `alpha` fixed at
/// [`ASSUMED_ALPHA`], radar loss 0 (absorbed into rho).
pub fn fit_targets(
    observations: &[Observation],
    power: &PowerModel,
    beam_half_width_rad: f64,
) -> Result<Vec<FittedTarget>, EvalError> {
    let mut order: Vec<&Observation> = observations.iter().collect();
    order.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
    let origin = Pose2::default();
    let reference = Material::from_rho_alpha(0.1, ASSUMED_ALPHA)?;
    let mut fitted: Vec<(f64, f64, FittedTarget)> = Vec::new(); // (range, bearing, target)
    let mut targets: Vec<PowerTarget> = Vec::new();
    let mut powers: Vec<f64> = Vec::new();
    for o in order {
        targets.clear();
        for (r, b, f) in &fitted {
            if *r < o.range_m && wrap_angle(b - o.bearing_rad).abs() <= beam_half_width_rad {
                targets.push(PowerTarget {
                    range_m: *r,
                    material: f.material,
                });
            }
        }
        targets.push(PowerTarget {
            range_m: o.range_m,
            material: reference,
        });
        powers.resize(targets.len(), 0.0);
        radar_model::power::beam_powers_db(power, &targets, 0.0, &mut powers)?;
        let p_ref = powers.last().copied().unwrap_or(f64::NAN);
        let rho_raw = 0.1 * 10f64.powf((o.power_db - p_ref) / 10.0);
        let hi = 1.0 - ASSUMED_ALPHA - MIN_RHO;
        let rho = if rho_raw.is_finite() {
            rho_raw.clamp(MIN_RHO, hi)
        } else {
            MIN_RHO
        };
        let material = Material::from_rho_alpha(rho, ASSUMED_ALPHA)?;
        let xy = origin.point_at(o.range_m, o.bearing_rad);
        fitted.push((
            o.range_m,
            o.bearing_rad,
            FittedTarget {
                xy,
                material,
                clamped: rho != rho_raw,
            },
        ));
    }
    Ok(fitted.into_iter().map(|(_, _, f)| f).collect())
}

/// Expected measured spectrum over a given floor, as radar-model's `expected_into` builds it
/// over its own floor: `floor` power-summed with each target's peak
/// `P_i + gain(R_b) - c ((R_b - R_i)^2 + jitter_var)`, `c = 10 / ln 10 / (2 sigma^2)`,
/// `sigma_m` one look's peak width and `jitter_var_m2` the phase-noise variance (the mean
/// in dB over looks).
pub fn predict_over_floor(
    geometry: &SpectrumGeometry,
    gain_db: &[f64],
    floor_db: &[f64],
    targets: &[SpectrumTarget],
    sigma_m: f64,
    jitter_var_m2: f64,
    out: &mut Vec<f64>,
) {
    out.clear();
    out.extend_from_slice(floor_db);
    let coef = -radar_model::power::DB_PER_NEPER_POWER / (2.0 * sigma_m * sigma_m);
    let half = KERNEL_SPAN_SIGMAS * sigma_m;
    for t in targets {
        let lo = ((t.range_m - half - geometry.range_offset_m) / geometry.bin_size_m)
            .ceil()
            .max(0.0);
        let hi = ((t.range_m + half - geometry.range_offset_m) / geometry.bin_size_m).floor();
        if !(lo.is_finite() && hi.is_finite()) || hi < lo {
            continue;
        }
        // Both are finite and non-negative; the slice access below is bounds-checked.
        for b in (lo as usize)..=(hi as usize) {
            let (Some(v), Some(g)) = (out.get_mut(b), gain_db.get(b)) else {
                break;
            };
            let d = geometry.bin_range_m(b) - t.range_m;
            *v = db_power_sum(*v, t.power_db + g + coef * (d * d + jitter_var_m2));
        }
    }
}

/// Which floor a prediction uses.
#[derive(Debug, Clone, PartialEq)]
pub enum Floor {
    /// radar-model's target-absent model (the paper's unit, book chapter figures).
    Model,
    /// The per-bin median of the previous scan's measured spectra.
    PreviousScan(Vec<f64>),
}

/// Per-bin median over a scan's rows.
pub fn median_floor(scan: &Scan, bins: usize) -> Vec<f64> {
    let mut column = Vec::with_capacity(scan.rows.len());
    (0..bins)
        .map(|b| {
            column.clear();
            column.extend(
                scan.rows
                    .iter()
                    .filter_map(|r| r.measured_db.get(b).copied()),
            );
            column.sort_by(f64::total_cmp);
            column.get(column.len() / 2).copied().unwrap_or(0.0)
        })
        .collect()
}

/// Predicts scan `next` from targets fitted in the previous scan's frame, seen from `pose`
/// (the next scan's pose in the previous scan's frame), and compares bin by bin.
#[allow(clippy::too_many_arguments)]
pub fn predict_and_compare(
    next: &Scan,
    fitted: &[FittedTarget],
    pose: &Pose2,
    variant: &Variant,
    power: &PowerModel,
    geometry: &SpectrumGeometry,
    noise: &NoiseModel,
    floor: &Floor,
    beam_width_rad: f64,
) -> Result<Comparison, EvalError> {
    let compensation = variant.compensation();
    let model = SpectrumModel::new(*geometry, &compensation, *noise)?;
    let power = PowerModel {
        form: variant.form,
        ..*power
    };
    let sigma = noise.range.look_sigma_m();
    let jitter_var = noise.range.phase_noise_sigma_m.powi(2);
    let mut hits: Vec<BeamHit> = Vec::new();
    let mut targets = Vec::new();
    let mut spectrum_targets = Vec::new();
    let mut predicted = vec![0.0; geometry.bins];
    let mut scratch = Vec::new();
    let mut cmp = Comparison::default();
    for row in &next.rows {
        let beam = Beam {
            bearing_rad: row.bearing_rad,
            width_rad: beam_width_rad,
            min_range_m: 0.5,
            max_range_m: geometry.bin_range_m(geometry.bins),
        };
        features_in_beam(pose, &beam, fitted.iter().map(|f| f.xy), &mut hits);
        targets.clear();
        targets.extend(hits.iter().filter_map(|h| {
            fitted.get(h.index).map(|f| PowerTarget {
                range_m: h.range_m,
                material: f.material,
            })
        }));
        beam_spectrum_targets(&power, &targets, 0.0, &mut spectrum_targets)?;
        let floor_db: &[f64] = match floor {
            Floor::Model => model.floor_mean_db(),
            Floor::PreviousScan(f) => f,
        };
        match floor {
            Floor::Model => model.expected_into(&spectrum_targets, &mut predicted)?,
            Floor::PreviousScan(f) => {
                predict_over_floor(
                    geometry,
                    model.gain_db(),
                    f,
                    &spectrum_targets,
                    sigma,
                    jitter_var,
                    &mut scratch,
                );
                predicted.clear();
                predicted.extend_from_slice(&scratch);
            }
        }
        for (b, (p, m)) in predicted.iter().zip(&row.measured_db).enumerate() {
            let d = p - m;
            cmp.all.add(d);
            let r = geometry.bin_range_m(b);
            if spectrum_targets
                .iter()
                .any(|t| (t.range_m - r).abs() <= TARGET_BIN_HALF_WIDTH_M)
            {
                cmp.targets.add(d);
            }
        }
        add_peaks(
            &mut cmp.peaks,
            geometry,
            &spectrum_targets,
            &predicted,
            &row.measured_db,
            floor_db,
        );
    }
    Ok(cmp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prediction_over_the_model_floor_matches_radar_models_own_expected_spectrum() {
        let geometry = SpectrumGeometry::paper_unit();
        let noise = NoiseModel::default();
        let model = SpectrumModel::new(geometry, &Compensation::default(), noise).expect("model");
        let targets = [
            SpectrumTarget {
                range_m: 12.3,
                power_db: -20.0,
            },
            SpectrumTarget {
                range_m: 30.0,
                power_db: -60.0,
            },
        ];
        let mut expected = vec![0.0; geometry.bins];
        model
            .expected_into(&targets, &mut expected)
            .expect("predict");
        let mut ours = Vec::new();
        predict_over_floor(
            &geometry,
            model.gain_db(),
            model.floor_mean_db(),
            &targets,
            noise.range.look_sigma_m(),
            noise.range.phase_noise_sigma_m.powi(2),
            &mut ours,
        );
        let worst = expected
            .iter()
            .zip(&ours)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // radar-model's kernel window is one bin wider and drops terms 100 dB down: both
        // change the sum by far less than a micro-dB.
        assert!(worst < 1e-6, "largest difference {worst} dB");
    }

    #[test]
    fn a_fitted_lone_target_reproduces_its_measured_power() {
        let power = PowerModel::default();
        let obs = Observation {
            range_m: 20.0,
            bearing_rad: 0.1,
            power_db: -40.0,
            timestamp_s: 0.0,
            azimuths: 2,
            peak_range_m: 20.0,
            extent_m: 0.2,
            snr_db: 30.0,
            width_rad: 0.01,
            cut: false,
            may_start: true,
        };
        let fitted = fit_targets(&[obs], &power, 0.9_f64.to_radians()).expect("fit");
        let t = [PowerTarget {
            range_m: 20.0,
            material: fitted[0].material,
        }];
        let mut p = [0.0];
        radar_model::power::beam_powers_db(&power, &t, 0.0, &mut p).expect("power");
        assert!((p[0] + 40.0).abs() < 1e-9, "{}", p[0]);
        assert!(!fitted[0].clamped);
    }
}
