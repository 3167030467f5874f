//! The daemon's settings, built once from the validated `config::Config`: the filter's,
//! the detector's, the radar model's, and the pipeline's own (odometry staleness, radar
//! stall, spectrum diagnostics).

use std::time::Duration;

use config::detector::{DetectorKind as ConfigKind, Threshold};
use config::filter::Gate;
use config::model::{Compensation as ConfigCompensation, Spreading};
use config::odometry::MotionModel as ConfigMotion;
use radar_model::compensation::{Compensation, GainCurve, GainTable, RollOff};
use radar_model::motion::MotionModel;
use radar_model::noise::{FloorDistribution, NoiseModel, PAPER_BOUND_99_DB};
use radar_model::power::{PowerModel, RadarConstants, SpreadingForm};
use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::frontend::FrontEndSettings;
use super::gate::OdometryLimits;
use crate::detect::{DetectorKind, DetectorSettings};
use radar_odometry::ScanMatchSettings;
use slam_filter::FilterSettings;

/// The share of a range resolution cell and of a beam width within which a feature's
/// predicted position counts as seen again from the same viewpoint.
pub const REPEAT_LOOK_CELL_FRACTION: f64 = 1.0;

/// A setting that could not be turned into the daemon's form.
#[derive(Debug, thiserror::Error)]
pub enum SettingsError {
    /// The configured compensation table was rejected by radar-model.
    #[error("model.compensation_table was rejected by the radar model")]
    CompensationTable(#[source] radar_model::ModelError),
    /// The configuration with the radar profile's values did not validate.
    #[error("the configuration with radar profile {profile}'s values is invalid: {errors}")]
    Profile {
        /// The profile.
        profile: &'static str,
        /// What was invalid.
        errors: config::FieldErrors,
    },
    /// `[radar] model` names no profile.
    #[error(transparent)]
    UnknownModel(#[from] radar_model::profile::UnknownModel),
    /// Radar only (`[odometry] source = "none"` or `--radar-only`) with radar odometry
    /// turned off: nothing would drive the filter.
    #[error("radar only (odometry source \"none\" or --radar-only) needs radar odometry, which --no-radar-odometry turns off")]
    RadarOnlyWithoutRadarOdometry,
}

/// Everything the pipeline needs besides the radar's own geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct PipelineSettings {
    /// The EKF's settings.
    pub filter: FilterSettings,
    /// Initial pose and its standard deviations `[x, y, theta]`.
    pub initial_pose: [f64; 3],
    /// Initial pose standard deviations.
    pub initial_pose_std: [f64; 3],
    /// The process model for odometry.
    pub motion: MotionModel,
    /// Detection.
    pub detector: DetectorSettings,
    /// Bytes the detector may keep across rotations.
    pub max_detector_state_bytes: usize,
    /// Grouping across azimuths (its angular step is set from the radar's geometry).
    pub grouping_range_gate_m: f64,
    /// Widest group, in beam widths.
    pub grouping_max_width_beams: f64,
    /// Beam width, radians.
    pub beam_width_rad: f64,
    /// FMCW range-Doppler coupling (s): a return closing at `v` m/s reads `v` times this
    /// short; each detection's range is corrected with the vehicle's speed along its beam
    /// (`[model] doppler_range_coupling_s`).
    pub doppler_range_coupling_s: f64,
    /// Receiver compensation (to remove from measured spectra).
    pub compensation: Compensation,
    /// Noise model (for predicted spectra).
    pub noise: NoiseModel,
    /// Power model (eq. 13 form and constants).
    pub power: PowerModel,
    /// Bound on predicted minus measured, dB (the paper's 16.35).
    pub spectrum_bound_db: f64,
    /// Compare predicted and measured spectra on every k-th azimuth (0 = never).
    pub spectrum_every_azimuths: usize,
    /// Emit spectrum comparisons for figures every this many rotations (0 = never).
    pub spectrum_sample_every_rotations: u64,
    /// Bearings (the paper's beta, radians) whose beams are emitted then; when empty, the
    /// beam holding the most mapped features is.
    pub spectrum_bearings_rad: Vec<f64>,
    /// Odometry older than this (in stream time) behind a beam is stale: no update.
    pub odometry_stale_s: f64,
    /// Physical limits on odometry records.
    pub odometry_limits: OdometryLimits,
    /// Wall time to wait for odometry to reach a beam's time before declaring it stale.
    pub odometry_wait: Duration,
    /// Wall time without an azimuth after which the radar is declared stalled.
    pub radar_stall: Duration,
    /// Write a map snapshot every this many rotations (0 = only at the end).
    pub map_every_rotations: u64,
    /// Local submaps joined by the global layer; `None`: one dense map.
    pub submaps: Option<SubmapOptions>,
    /// Radar odometry (rotations registered against each other, see [`ScanMatchSettings`]).
    pub scan_match: ScanMatchSettings,
    /// Radar odometry drives the filter's prediction (there is no other odometry: `[odometry]
    /// source = "none"` or `--radar-only`).
    pub radar_drives: bool,
    /// Driving, each registration is composed onto the pose at the previous rotation
    /// ([`slam_filter::Ekf::compose_motion_since_mark`]) instead of fused as an update
    /// (`[odometry] radar_odometry_compose`).
    pub radar_compose: bool,
    /// A gyro's yaw rate gives the prediction's turn (radar-only driving with `[gyro]` or
    /// `--gyro-from-truth`); `None`: the last rotation's turn is held.
    pub gyro: Option<super::gyro::GyroUse>,
    /// The saved map (`[map]`).
    pub map_save: super::map_save::MapSaveSettings,
    /// Localisation in a saved map (`--map FILE`, `[map] mode = "localise"`).
    pub localise: Option<super::localise::LocaliseSettings>,
}

/// Local submaps and the global layer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubmapOptions {
    /// When a submap is closed.
    pub limits: slam_filter::SubmapLimits,
    /// The global layer.
    pub global: slam_graph::GlobalSettings,
    /// A rotation whose heading in the submap's frame differs from the frame's by more than
    /// this (rad) is not added to the submap's scan (`None`: every rotation is).
    pub scan_max_turn_rad: Option<f64>,
    /// Whether the pipeline waits, at each switch, until the global layer has joined the
    /// submap just closed, and installs its solution at once. For runs paced by the
    /// pipeline (the embedded simulator as fast as possible): without it the layer, joining
    /// a submap in up to a second of wall time, falls several submaps behind the simulated
    /// time, and its corrections reach the online pose that much later than in real time,
    /// where a join lands within a second of its switch (4 rotations, 10 m at 10 m/s; this
    /// puts it at the switch). A live radar does not wait: never set against one.
    pub wait_for_joins: bool,
}

impl SubmapOptions {
    /// From `[submaps]`; `None` when disabled.
    pub fn from_config(s: &config::SubmapSettings) -> Option<Self> {
        if !s.enabled {
            return None;
        }
        let mut global = slam_graph::GlobalSettings {
            loop_closure: s.loop_closure,
            search_sigmas: s.search_sigmas.get(),
            ..slam_graph::GlobalSettings::default()
        };
        global.align.min_matches = s.min_matches.get();
        global.align.max_rival_ratio = s.max_rival_ratio.get();
        global.place.enabled = s.place_recognition;
        global.scans.enabled = s.scan_loop_closure;
        // Without scans (`scan_loop_closure = false`) the layer has none to link.
        global.near_links = s.near_links as usize;
        global.near_covariance_scale = s.near_link_covariance_scale.get();
        global.scan_smear = s.scan_smear.get();
        Some(Self {
            limits: slam_filter::SubmapLimits {
                max_distance_m: s.max_distance_m.get(),
                max_features: s.max_features.get(),
            },
            global,
            scan_max_turn_rad: None,
            wait_for_joins: false,
        })
    }
}

/// The motion model the configured odometry means (`[odometry] motion_model`): what the
/// odometry's steering input is, whatever the radar.
pub fn motion_model(c: &config::Config) -> MotionModel {
    match c.odometry.motion_model {
        ConfigMotion::Paper { step_s } => MotionModel::Paper {
            step_s: step_s.get(),
        },
        ConfigMotion::Bicycle { wheelbase_m } => MotionModel::Bicycle {
            wheelbase_m: wheelbase_m.get(),
        },
    }
}

/// The chi-square probability mass inside a fixed 3-dof threshold.
fn gate_probability(gate: Gate) -> f64 {
    match gate {
        Gate::Probability(p) => p.get(),
        Gate::Chi2(t) => ChiSquared::new(3.0)
            .map(|d| d.cdf(t.get()))
            .unwrap_or(0.99)
            .clamp(1e-6, 1.0 - 1e-12),
    }
}

/// CA-CFAR scale for a false-alarm probability with `n` reference cells, for exponential
/// (square-law) noise: `alpha = n (pfa^(-1/n) - 1)`, in dB.
pub fn ca_scale_db_for_pfa(pfa: f64, n: usize) -> f64 {
    let n = n.max(1) as f64;
    10.0 * (n * (pfa.powf(-1.0 / n) - 1.0)).log10()
}

/// OS-CFAR scale for a false-alarm probability, rank `k` of `n` cells, exponential noise:
/// solves `pfa = prod_{i=0}^{k-1} (n - i) / (n - i + T)` for `T` by bisection; in dB.
pub fn os_scale_db_for_pfa(pfa: f64, k: usize, n: usize) -> f64 {
    let pfa_of = |t: f64| -> f64 {
        (0..k.min(n))
            .map(|i| {
                let m = (n - i) as f64;
                m / (m + t)
            })
            .product()
    };
    let (mut lo, mut hi) = (0.0f64, 1.0e6f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if pfa_of(mid) > pfa {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    10.0 * (0.5 * (lo + hi)).log10()
}

impl PipelineSettings {
    /// Builds the daemon's settings from a validated configuration.
    pub fn from_config(c: &config::Config) -> Result<Self, SettingsError> {
        let constants = RadarConstants::default();
        // The configured roll-off replaces the slope curves' default one; a measured table is
        // the whole curve, roll-off included.
        let rolloff = c.model.rolloff.map(|r| RollOff {
            corner_m: r.corner_m.get(),
            order: r.order.get(),
        });
        let compensation = match &c.model.compensation {
            ConfigCompensation::Slope40DbPerDecade => Compensation {
                rolloff,
                ..Compensation::calibrated(40.0, &constants)
            },
            ConfigCompensation::Slope60DbPerDecade => Compensation {
                rolloff,
                ..Compensation::paper_sixty(&constants)
            },
            ConfigCompensation::Table(t) => {
                let points: Vec<(f64, f64)> = t
                    .points()
                    .iter()
                    .map(|p| (p.range_m.get(), p.gain_db.get()))
                    .collect();
                let table = GainTable::new(&points).map_err(SettingsError::CompensationTable)?;
                Compensation {
                    curve: GainCurve::Table(table),
                    rolloff: None,
                }
            }
        };
        let mut noise = NoiseModel::default();
        let nf = &c.model.noise_floor;
        noise.absent.near_mean_db = nf.near_mean_db.get();
        noise.absent.near_range_m = nf.near_range_m.get();
        noise.absent.near_variance_db2 = nf.near_variance_db2.get();
        noise.absent.weibull_from_m = nf.transition_m.get();
        noise.absent.weibull_scale_db = nf.weibull_scale.get();
        noise.absent.weibull_shape = nf.weibull_shape.get();
        noise.present.variance_db2 = c.model.sigma_power_db.get().powi(2);
        noise.range.resolution_fwhm_m = c.model.range_resolution_m.get();
        noise.bearing_sigma_rad = c.model.sigma_bearing_rad();
        let power = PowerModel {
            form: match c.model.spreading {
                Spreading::Paper => SpreadingForm::Paper,
                Spreading::Textbook => SpreadingForm::Textbook,
            },
            constants,
            range_resolution_m: c.model.range_resolution_m.get(),
        };
        let motion = motion_model(c);
        let beam_width_rad = c.model.beam_width_rad();
        let f = &c.filter;
        let filter = FilterSettings {
            use_power: f.use_power_in_observation,
            first_estimate_jacobians: f.first_estimate_jacobians,
            // A look repeats while the feature stays within a quarter of a range cell and a
            // quarter of a beam of where the run began.
            repeat_look_range_m: if f.repeat_look_decorrelation {
                REPEAT_LOOK_CELL_FRACTION * c.model.range_resolution_m.get()
            } else {
                0.0
            },
            repeat_look_bearing_rad: if f.repeat_look_decorrelation {
                REPEAT_LOOK_CELL_FRACTION * beam_width_rad
            } else {
                0.0
            },
            repeat_look_max_factor: f.repeat_look_max_factor,
            range_std_m: c.model.sigma_range_m.get(),
            bearing_std_rad: c.model.sigma_bearing_rad(),
            power_std_db: c.model.sigma_power_db.get(),
            speed_std_mps: c.odometry.sigma_speed_mps.get().max(1e-3),
            steer_std_rad: c.odometry.sigma_steer_rad.get().max(1e-5),
            speed_scale_std: c.odometry.speed_scale_std.get(),
            steer_bias_std_rad: c.odometry.steer_bias_std_rad.get(),
            speed_scale_walk_per_sqrt_s: c.odometry.speed_scale_walk_per_sqrt_s.get(),
            steer_bias_walk_rad_per_sqrt_s: c.odometry.steer_bias_walk_rad_per_sqrt_s.get(),
            speed_scale_from_landmarks: c.odometry.speed_scale_from_landmarks,
            steer_bias_from_landmarks: c.odometry.steer_bias_from_landmarks,
            // Only radar odometry's registrations are motion measurements.
            registration_placement_share: if c.odometry.radar_odometry {
                c.odometry.radar_odometry_placement_share.get()
            } else {
                0.0
            },
            material_variance_per_s: f.sigma_u.get().max(f.sigma_v.get()).powi(2),
            feature_wander_m: f.sigma_wander_m.get(),
            feature_wander_length_m: f.wander_length_m.get(),
            gate_probability: gate_probability(f.gate),
            jcbb_max_nodes: match f.association {
                // A budget of one node is nearest neighbour: the first compatible pairing.
                config::filter::Association::NearestNeighbour => 1,
                config::filter::Association::Jcbb => FilterSettings::default().jcbb_max_nodes,
            },
            beam_half_width_rad: 0.5 * beam_width_rad,
            min_range_m: c.detector.range.min_m().max(0.5),
            max_range_m: c.detector.range.max_m(),
            max_features: f.max_features.get(),
            retire_after_misses: u32::try_from(f.retire_after_misses.get()).unwrap_or(u32::MAX),
            retire_unseen_after_s: f.retire_unseen_after_s.get(),
            retire_unrepeatable_below: f.retire_unrepeatable_below.get(),
            repeatability_min_rotations: u32::try_from(f.repeatability_min_rotations.get())
                .unwrap_or(u32::MAX),
            confirm_after: u32::try_from(f.confirm_after.get()).unwrap_or(u32::MAX),
            initial_loss_db: f.initial_loss_db.get(),
            initial_loss_std_db: f.initial_sigma_loss_db.get(),
            ..FilterSettings::default()
        };
        let far_floor = noise.absent.distribution_at(noise.absent.weibull_from_m);
        let detector = detector_from_config(&c.detector, &far_floor);
        Ok(Self {
            filter,
            initial_pose: [
                f.initial_pose.x_m.get(),
                f.initial_pose.y_m.get(),
                f.initial_pose.theta_rad.get(),
            ],
            initial_pose_std: [
                f.initial_pose.sigma_x_m.get(),
                f.initial_pose.sigma_y_m.get(),
                f.initial_pose.sigma_theta_rad.get(),
            ],
            motion,
            detector,
            max_detector_state_bytes: c.detector.max_state_mib.get().saturating_mul(1 << 20),
            grouping_range_gate_m: (2.0 * c.model.range_resolution_m.get()).max(0.5),
            grouping_max_width_beams: 3.0,
            beam_width_rad,
            doppler_range_coupling_s: c.model.doppler_range_coupling_s.get(),
            compensation,
            noise,
            power,
            spectrum_bound_db: PAPER_BOUND_99_DB,
            spectrum_every_azimuths: 1,
            spectrum_sample_every_rotations: 25,
            spectrum_bearings_rad: Vec::new(),
            odometry_stale_s: c.odometry.stale_after.as_secs_f64(),
            odometry_limits: OdometryLimits {
                max_speed_mps: c.odometry.max_speed_mps.get(),
                max_steer_rad: c.odometry.max_steer_rad.get(),
                max_accel_mps2: c.odometry.max_accel_mps2.get(),
            },
            odometry_wait: c.odometry.stale_after,
            radar_stall: Duration::from_secs(2),
            map_every_rotations: 20,
            submaps: SubmapOptions::from_config(&c.submaps),
            map_save: super::map_save::MapSaveSettings::from_config(c),
            scan_match: ScanMatchSettings {
                enabled: c.odometry.radar_odometry,
                sigma_xy_m: c.odometry.radar_odometry_sigma_m.get(),
                sigma_theta_rad: c.odometry.radar_odometry_sigma_rad.get(),
                keyframes: c
                    .odometry
                    .radar_odometry_keyframes
                    .map_or(0, |k| usize::try_from(k).unwrap_or(0)),
                keyframe_spacing_m: c.odometry.radar_odometry_keyframe_spacing_m.get(),
                place_held: c.odometry.radar_odometry_place_held,
                start_probe: c.odometry.radar_odometry_probe_start,
                refine_runs: c
                    .odometry
                    .radar_odometry_refine_runs
                    .map_or(0, |k| usize::try_from(k).unwrap_or(0)),
                soft_kernel_m: c.odometry.radar_odometry_soft_kernel_m.unwrap_or(0.0),
                ..ScanMatchSettings::default()
            },
            radar_drives: false,
            radar_compose: c.odometry.radar_odometry_compose,
            gyro: None,
            localise: None,
        })
    }

    /// The front end's settings.
    pub fn front_end(&self) -> FrontEndSettings {
        FrontEndSettings {
            detector: self.detector,
            grouping_range_gate_m: self.grouping_range_gate_m,
            grouping_max_width_beams: self.grouping_max_width_beams,
            beam_width_rad: self.beam_width_rad,
            doppler_range_coupling_s: self.doppler_range_coupling_s,
            compensation: self.compensation.clone(),
            noise: self.noise,
            max_detector_state_bytes: self.max_detector_state_bytes,
            keep_spectrum_every: self.spectrum_every_azimuths,
            spectrum_bound_db: self.spectrum_bound_db,
        }
    }
}

/// CFAR margins (CA, OS) over each detector's noise estimate for a per-bin false-alarm
/// probability `pfa`, from the radar's target-absent floor distribution (in dB, as the
/// book chapter measured it) rather than from the textbook's square-law noise: the
/// measured floor is far more spread (standard deviation about 5 dB far out) than
/// exponential power, and the textbook scale gives hundreds of false alarms a rotation.
///
/// CA: the reference mean of 2N cells is close to the floor's linear mean, so the margin is
/// `Q(1 - pfa) - 10 log10 E[10^(X/10)]`. OS: the k-th of 2N cells is close to the floor's
/// `k/2N` quantile, so the margin is `Q(1 - pfa) - Q(k/2N)`. `Q` comes from the
/// distribution's inverse via an Exp(1) variate, `Q(p) = F^-1(-ln(1 - p))`.
pub fn cfar_scales_for_floor(
    floor: &FloorDistribution,
    pfa: f64,
    os_rank_fraction: f64,
) -> (f64, f64) {
    let q = |p: f64| floor.from_exp1(-(1.0 - p.clamp(1e-12, 1.0 - 1e-12)).ln());
    let high = q(1.0 - pfa);
    const STEPS: usize = 20_000;
    let mean_linear = (0..STEPS)
        .map(|i| 10f64.powf(q((i as f64 + 0.5) / STEPS as f64) / 10.0))
        .sum::<f64>()
        / STEPS as f64;
    (
        high - 10.0 * mean_linear.log10(),
        high - q(os_rank_fraction),
    )
}

/// The detector settings a `[detector]` section asks for. A false-alarm probability is
/// turned into CFAR margins by [`cfar_scales_for_floor`] on the radar's far noise floor;
/// TPP's SNR threshold is taken from `threshold_db` when set and otherwise keeps the
/// measured default (a Pfa does not map onto TPP's minimum-tracking statistic).
pub fn detector_from_config(
    d: &config::detector::DetectorSettings,
    far_floor: &FloorDistribution,
) -> DetectorSettings {
    let mut s = DetectorSettings::default();
    let per_side = (d.reference_cells.get() / 2).max(1);
    s.window.reference_cells = per_side;
    s.window.guard_cells = d.guard_cells;
    s.window.min_reference_cells = per_side;
    s.os_rank_fraction = d.os_rank.get() as f64 / d.reference_cells.get().max(1) as f64;
    s.kind = match d.kind {
        ConfigKind::CaCfar => DetectorKind::CaCfar,
        ConfigKind::OsCfar => DetectorKind::OsCfar,
        ConfigKind::Tpp => DetectorKind::Tpp,
        ConfigKind::Learned => DetectorKind::Learned,
    };
    match d.threshold {
        Threshold::Db(db) => {
            s.ca_scale_db = db.get();
            s.os_scale_db = db.get();
            s.tpp.snr_threshold_db = db.get();
        }
        Threshold::Pfa(p) => {
            let (ca, os) = cfar_scales_for_floor(far_floor, p.get(), s.os_rank_fraction);
            s.ca_scale_db = ca;
            s.os_scale_db = os;
        }
    }
    s.tpp.alpha = d.tpp_alpha.get();
    s.tpp.detect_probability = d.tpp_detect.get();
    s.peaks.max_peaks = d.max_targets_per_beam.get();
    s.min_range_m = d.range.min_m();
    s.max_range_m = d.range.max_m();
    s.floor.detect_sigma = d.floor_sigma.get();
    s.floor.min_snr_db = d.floor_min_snr_db.get();
    s.landmarks = crate::detect::LandmarkSettings {
        points_only: d.points_only,
        max_extent_m: d.point_max_extent_m.get(),
        max_width_beams: d.point_max_width_beams.get(),
        min_snr_db: d.point_min_snr_db.get(),
        reobserve_radius_m: 2.0,
        extended_reobserve: d.extended_reobserve,
    };
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ca_cfar_scale_for_pfa_matches_the_closed_form() {
        // n = 70, pfa = 1e-4: alpha = 70 (1e-4^(-1/70) - 1) = 9.85 -> 9.93 dB.
        let db = ca_scale_db_for_pfa(1e-4, 70);
        assert!((db - 10.0 * (70.0 * (1e-4f64.powf(-1.0 / 70.0) - 1.0)).log10()).abs() < 1e-12);
        assert!((db - 9.93).abs() < 0.01, "{db}");
    }

    #[test]
    fn the_os_cfar_scale_reproduces_its_false_alarm_probability() {
        let (k, n) = (53, 70);
        let t = 10f64.powf(os_scale_db_for_pfa(1e-4, k, n) / 10.0);
        let pfa: f64 = (0..k)
            .map(|i| (n - i) as f64 / ((n - i) as f64 + t))
            .product();
        assert!((pfa - 1e-4).abs() < 1e-9, "{pfa}");
    }

    #[test]
    fn floor_calibrated_margins_exceed_the_textbook_ones_for_the_spread_far_floor() {
        let floor = NoiseModel::default().absent.distribution_at(100.0);
        let (ca, os) = cfar_scales_for_floor(&floor, 1e-4, 0.75);
        println!(
            "CA {ca:.2} dB (textbook {:.2}), OS {os:.2} dB",
            ca_scale_db_for_pfa(1e-4, 70)
        );
        assert!(ca > ca_scale_db_for_pfa(1e-4, 70));
        assert!(os > 0.0 && ca.is_finite());
    }

    #[test]
    fn every_model_and_filter_setting_of_the_reference_file_reaches_the_pipeline() {
        let text = "[filter]\nconfirm_after = 4\n[model]\nrolloff_corner_m = 150.0\nrolloff_order = 2\nnoise_floor_near_range_m = 12.0\n";
        let c = config::Config::from_toml_str(text).unwrap();
        let s = PipelineSettings::from_config(&c).unwrap();
        assert_eq!(s.filter.confirm_after, 4);
        assert_eq!(
            s.compensation.rolloff,
            Some(RollOff {
                corner_m: 150.0,
                order: 2
            })
        );
        assert_eq!(s.noise.absent.near_range_m, 12.0);
        let none = config::Config::from_toml_str("[model]\nrolloff_order = 0\n").unwrap();
        let s = PipelineSettings::from_config(&none).unwrap();
        assert_eq!(s.compensation.rolloff, None);
    }

    #[test]
    fn the_shipped_configuration_converts() {
        let c = config::Config::default();
        let s = PipelineSettings::from_config(&c).unwrap();
        assert!(s.filter.validate().is_ok());
        assert!((s.beam_width_rad - 1.8f64.to_radians()).abs() < 1e-12);
    }
}
