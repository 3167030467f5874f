//! The filter's own settings: plain values, validated once, independent of the config crate.

use thiserror::Error;

/// Everything the EKF needs to know that is not state. Units are in the names.
///
/// Build one with [`FilterSettings::default`] and adjust fields; [`FilterSettings::validate`]
/// is called by the filter's constructor and rejects any value that would make the filter
/// meaningless (non-finite, non-positive standard deviations, probabilities outside (0, 1)).
#[derive(Debug, Clone, PartialEq)]
pub struct FilterSettings {
    /// Use the received power as a third observation row (the paper's filter). When false the
    /// filter is ordinary range-bearing SLAM (for the evaluation's comparison); u, v and L are
    /// then unobserved and keep their priors.
    pub use_power: bool,
    /// Evaluate each feature's range and bearing Jacobians (and the range part of its power
    /// Jacobian) at the position it entered the state with, not at its current estimate:
    /// the first-estimates Jacobian EKF (Huang, Mourikis and Roumeliotis). The standard EKF
    /// linearises each feature at a different, moving point, which makes the map's global
    /// heading look observable and the filter over-confident in it; fixing the linearisation
    /// point keeps that direction unobservable. The innovation always uses the current
    /// estimate.
    pub first_estimate_jacobians: bool,
    /// Repeated looks from an unchanged viewpoint are not independent: while a feature's
    /// predicted range and bearing in the radar's frame stay within `repeat_look_range_m`
    /// and `repeat_look_bearing_rad` of where a run of looks began (a stationary or slowly
    /// moving vehicle), the errors that depend on the geometry (azimuth and range-bin
    /// quantisation, partial occlusion, speckle) repeat, so the k-th look of the run is
    /// used with its noise variance times k. The run's total information then grows as
    /// `ln k`, not `k`, and a vehicle parked for a minute does not become certain of a
    /// biased answer. Looks within one sweep (less than `confirm_min_separation_s` apart:
    /// neighbouring azimuths, quantised differently) count as independent. 0 turns it off.
    pub repeat_look_range_m: f64,
    /// See [`Self::repeat_look_range_m`] (rad): one azimuth step is the natural cell.
    pub repeat_look_bearing_rad: f64,
    /// The largest factor a repeated look's noise variance is multiplied by: the k-th look of
    /// a run is used with `min(k, repeat_look_max_factor)` times its variance (at least 1;
    /// infinity gives the uncapped `ln k` growth). Not every error of a look repeats (the
    /// receiver's noise is new each rotation), and a parked vehicle's odometry moves the
    /// pose every rotation, which only new information holds: uncapped, a vehicle parked for
    /// hours follows its odometry's noise and drags the map with it (the heading wanders by
    /// several standard deviations while its variance stays put). Default 32 (13 s of looks
    /// at 2.5 rotations a second, then a steady 1/32 of a fresh look's information each).
    pub repeat_look_max_factor: f64,
    /// Standard deviation of an observed range (m).
    pub range_std_m: f64,
    /// Standard deviation of an observed bearing (rad). The paper: 1 degree.
    pub bearing_std_rad: f64,
    /// Standard deviation of an observed (uncompensated) power (dB).
    pub power_std_db: f64,
    /// Standard deviation of one odometry speed sample (m/s).
    pub speed_std_mps: f64,
    /// Standard deviation of one odometry steering sample (rad).
    pub steer_std_rad: f64,
    /// The time over which one odometry sample's error persists (s): usually the odometry
    /// period. Input noise is treated as white with spectral density `std^2 * correlation`, so
    /// predicting over `dt` in one step or many gives the same pose covariance growth.
    pub input_noise_correlation_s: f64,
    /// Prior standard deviation of the odometry's speed correction `k` (the motion model is
    /// driven by `speed (1 + k)`; a wheel radius or a calibration 5 % off is `k` near
    /// -0.05). Zero (the default, the paper's filter) does not estimate it. The input noise
    /// above is white: it cannot describe an error that persists for the whole drive, and a
    /// filter fed odometry a few per cent fast becomes certain of a wrong path; with `k` in
    /// the state the landmarks measure the scale.
    pub speed_scale_std: f64,
    /// Prior standard deviation of the odometry's steering offset `b` (rad, in the motion
    /// model's steering units: the model is driven by `steer + b`). Zero (default): not
    /// estimated. See [`Self::speed_scale_std`].
    pub steer_bias_std_rad: f64,
    /// Random walk of `k` (per square root of a second): how fast the scale may drift (tyre
    /// pressure, load). Used only when `k` is estimated.
    pub speed_scale_walk_per_sqrt_s: f64,
    /// Random walk of `b` (rad per square root of a second). Used only when `b` is estimated.
    pub steer_bias_walk_rad_per_sqrt_s: f64,
    /// Whether the landmarks' updates may move the odometry's speed correction `k` (the
    /// default, its only source without radar odometry). False holds `k` as a consider
    /// parameter in every landmark update (the Schmidt-Kalman update: its cross-covariances
    /// are updated, its estimate and variance are not), so that only the motion
    /// measurements ([`crate::Ekf::observe_motion_since_mark`]) learn it: a mapped return
    /// whose peak slides along with the vehicle (a car body, a hedge's corner) pulls every
    /// pose it is seen from back along the path, and through the poses the scale.
    pub speed_scale_from_landmarks: bool,
    /// The same for the steering offset `b`: false holds it as a consider parameter in every
    /// landmark update, so that only the motion measurements learn it. Radar only with a
    /// gyro (`b` is the gyro's bias) slam-node sets it false: a mapped return that is not a
    /// true point pulls the heading it is seen from, and through the heading the bias, which
    /// then turns every later prediction. Default true.
    pub steer_bias_from_landmarks: bool,
    /// Growth rate of the variance of each feature's u and v (1/s): the paper's Gaussian
    /// change of reflectivity and absorption with viewing angle.
    pub material_variance_per_s: f64,
    /// How far the apparent position of each feature may wander between looks (m, one
    /// sigma per axis): a return that is not a true point (a crown, a car body, a patch of
    /// clutter) peaks at a point that moves as the viewpoint does, so its looks' errors are
    /// correlated from one rotation to the next. Between two looks `d` metres of driving
    /// apart its x and y variances grow by `sigma^2 (1 - exp(-d / length))` (see
    /// [`Self::feature_wander_length_m`]). 0 models every feature as a true point.
    pub feature_wander_m: f64,
    /// The distance driven over which a feature's apparent position decorrelates (m > 0).
    pub feature_wander_length_m: f64,
    /// A beam with no targets does not predict the state (nothing is updated, so nothing
    /// needs it): its candidates come from a mean-only extrapolation of the pose, and the
    /// next beam with targets (or odometry) predicts across the gap in one go. Saves an O(n)
    /// covariance prediction per empty azimuth; the state's time then lags to the last beam
    /// with targets or odometry sample.
    pub defer_empty_beams: bool,
    /// Longest single integration step of the process model (s); longer predictions are split.
    pub max_predict_step_s: f64,
    /// Longest gap the filter will predict across in one call (s); a longer one is an error
    /// (stale odometry or a clock jump), not something to integrate blindly.
    pub max_predict_gap_s: f64,
    /// Across an odometry gap longer than `max_predict_gap_s` nothing is known of the motion:
    /// the filter jumps to the new sample's time and re-initialises the pose covariance by
    /// adding `(gap_speed_mps * gap)^2` to x and y and `(gap_yaw_rate_rps * gap)^2` to the
    /// heading, capped at `gap_max_sigma_m` and pi (the map is kept). With no map to
    /// relocalise against (no feature, or fewer than `relocalise_min_features` when
    /// relocalising, which are dropped) nothing is added: the map frame is re-anchored at
    /// the pose estimate.
    pub gap_speed_mps: f64,
    /// See [`Self::gap_speed_mps`] (rad/s).
    pub gap_yaw_rate_rps: f64,
    /// See [`Self::gap_speed_mps`] (m).
    pub gap_max_sigma_m: f64,
    /// After a bridged gap or a clock resynchronisation the pose is known only to the
    /// inflated covariance, and one beam's nearest neighbour inside such wide gates is as
    /// likely another feature, or clutter, as the right one: a single wrong pairing then
    /// drags the pose metres away, and every later beam follows it. So the filter
    /// *relocalises* first: it holds a rotation's targets (no update, no new features, no
    /// misses), looks for the rigid correction that puts at least
    /// `relocalise_min_features` distinct mapped features under them jointly, refuses it
    /// when a distinct correction explains nearly as many (see
    /// [`Self::relocalise_rival_share`]: a repetitive map), and applies the accepted
    /// pairings as one iterated update. False switches it off (each beam is associated
    /// under the inflated covariance, as before).
    pub relocalise_after_gap: bool,
    /// See [`Self::relocalise_after_gap`]: distinct features that must agree. A map with
    /// fewer features is not relocalised against (there is nothing to check a pairing by).
    pub relocalise_min_features: usize,
    /// See [`Self::relocalise_after_gap`]: a correction is refused when a rival (one that
    /// shares fewer than half of its pairings with it) explains at least this share of its
    /// features.
    pub relocalise_rival_share: f64,
    /// See [`Self::relocalise_after_gap`]: rigid corrections tried per rotation (each from
    /// two targets paired with two features at the same distance apart), at most.
    pub relocalise_max_hypotheses: usize,
    /// See [`Self::relocalise_after_gap`]: targets held for one attempt, at most (the
    /// strongest are kept).
    pub relocalise_max_targets: usize,
    /// See [`Self::relocalise_after_gap`]: after this long without an accepted correction
    /// (s) the filter stops relocalising and associates beam by beam again (counted in
    /// [`crate::FilterStats::relocalisations_abandoned`]): the vehicle may have driven out
    /// of the mapped area during the gap, and refusing to map for ever is a dead state.
    pub relocalise_give_up_s: f64,
    /// A burst of detections (interference, a noisy receiver, spray) must not flood the map:
    /// the filter keeps two exponentially weighted rates of targets per second, a short one
    /// (time constant `burst_window_s`) and the learned norm (time constant `burst_norm_s`,
    /// bias-corrected so that it is the plain mean early on). While the short rate is above
    /// `burst_factor` times the norm plus `burst_floor_per_s`, the radar is taken to be
    /// blind: the beams are not used (no update, no misses, no new features), and no feature
    /// counts as unseen before the burst's end. The norm keeps learning, from a burst at most
    /// the threshold's rate (so it grows geometrically, not to the burst's rate within a few
    /// seconds), and a lasting change of scene (a street after a field) is accepted within
    /// about a norm time constant. Infinity switches the guard off.
    pub burst_factor: f64,
    /// See [`Self::burst_factor`] (targets per second).
    pub burst_floor_per_s: f64,
    /// See [`Self::burst_factor`] (s).
    pub burst_window_s: f64,
    /// See [`Self::burst_factor`] (s). The guard waits for this long, or 2 s if shorter, of
    /// beams before it judges a rate.
    pub burst_norm_s: f64,
    /// Probability mass inside the association gate (for example 0.95 or 0.99).
    pub gate_probability: f64,
    /// Probability mass of the wider exclusion gate: an unpaired target inside some feature's
    /// exclusion gate is not made a tentative (it is most likely that feature, just outside
    /// its association gate), so gate misses do not breed duplicate features.
    pub exclusion_probability: f64,
    /// Node budget of the joint compatibility branch and bound per beam; 0 turns JCBB off
    /// (greedy nearest neighbour even where gates overlap). At most
    /// [`MAX_JCBB_NODES`] (the search recurses once per node).
    pub jcbb_max_nodes: usize,
    /// Half the beam width (rad): features within this of a beam's azimuth are in that beam
    /// and attenuate each other. The paper's radar: 0.9 degrees.
    pub beam_half_width_rad: f64,
    /// Extra half-width (rad) when choosing a beam's candidate features: a feature whose
    /// *estimated* bearing is within `beam_half_width_rad + association_margin_rad` of the
    /// beam is predicted in it and may be associated (estimates carry bearing error). Such
    /// features are also treated as in the beam by the power model.
    pub association_margin_rad: f64,
    /// Standard deviations of the bearing innovation (the feature's predicted bearing and the
    /// measurement's bearing noise) added to the candidate arc.
    pub candidate_sigmas: f64,
    /// Features nearer than this are not predicted (m): a feature on top of the radar has no
    /// bearing.
    pub min_range_m: f64,
    /// Features further than this are not predicted (m).
    pub max_range_m: f64,
    /// A feature predicted weaker than this (dB, uncompensated) is not expected to be detected,
    /// so not seeing it is not a miss.
    pub min_detectable_power_db: f64,
    /// A tentative target must be seen again at least this much later (s) to be confirmed
    /// (so two adjacent beams of one rotation do not confirm each other).
    pub confirm_min_separation_s: f64,
    /// Looks (sightings at least `confirm_min_separation_s` apart) that confirm a tentative
    /// target into a feature; 1 maps every unclaimed target at once. Default 2.
    pub confirm_after: u32,
    /// A feature within the radar's range (`min_range_m..max_range_m` of the pose) that no
    /// target has been associated with for this long is retired by
    /// [`crate::Ekf::retire_unseen`] (s; 0 switches it off). The radar looks in every
    /// direction each rotation, so a real feature in range is seen within a few rotations;
    /// misses inside beams count only where something else was detected, so without this a
    /// phantom in a direction that stays empty would be kept for ever.
    pub retire_unseen_after_s: f64,
    /// A feature re-observed in fewer than this fraction of the rotations it was in view
    /// (counted by [`crate::Ekf::score_rotation`], once it has been in view in
    /// [`Self::repeatability_min_rotations`] of them) is retired: its returns are not
    /// repeatable, so it is clutter or an extended return's passing peak, not a landmark
    /// (`[0, 1]`; 0 switches it off, the default).
    pub retire_unrepeatable_below: f64,
    /// Rotations in view before a feature's repeatability is judged (at least 1). Default 8.
    pub repeatability_min_rotations: u32,
    /// A tentative target not seen again within this time is forgotten (s).
    pub tentative_timeout_s: f64,
    /// A beam with more targets than this is refused (typed error, state untouched): a
    /// detector gives a handful per beam, so thousands mean bad input.
    pub max_targets_per_beam: usize,
    /// Upper bound on the number of tentative targets held (bounded memory).
    pub max_tentatives: usize,
    /// Unclaimed targets become tentatives and, once confirmed, features (the SLAM filter).
    /// False: the map is what [`crate::Ekf::insert_known_feature`] put in (localisation in
    /// a saved map); unclaimed targets are counted and dropped. Default true.
    pub add_features: bool,
    /// Upper bound on the number of features in the state (bounded memory).
    pub max_features: usize,
    /// A feature is retired after this many consecutive beams in which it was predicted to be
    /// visible and was not associated.
    pub retire_after_misses: u32,
    /// Reflected share a new feature starts from.
    pub initial_rho: f64,
    /// Absorbed share a new feature starts from.
    pub initial_alpha: f64,
    /// Standard deviation of a new feature's u and v (softmax logits).
    pub initial_material_std: f64,
    /// Share `s` of a motion measurement's covariance that is its clouds' placement
    /// ([`crate::Ekf::observe_motion_since_mark`]), in `[0, 0.45]`: a radar registration of
    /// a cloud against the one before errs by how each was bent by the motion it was placed
    /// along (`d_k - d_{k-1}`, each of covariance `s R`) plus white noise (`(1 - 2 s) R`),
    /// so consecutive registrations' errors correlate `-s` and cancel when chained; the
    /// state holds the newest cloud's placement error. 0 (the default): every measurement
    /// independent, as before.
    pub registration_placement_share: f64,
    /// Initial radar loss L (dB).
    pub initial_loss_db: f64,
    /// Standard deviation of the initial loss (dB).
    pub initial_loss_std_db: f64,
}

impl Default for FilterSettings {
    fn default() -> Self {
        Self {
            use_power: true,
            first_estimate_jacobians: true,
            repeat_look_range_m: 0.25,
            repeat_look_bearing_rad: 1.8_f64.to_radians(),
            repeat_look_max_factor: 32.0,
            range_std_m: 0.25,
            bearing_std_rad: 1.0_f64.to_radians(),
            power_std_db: 2.4,
            speed_std_mps: 0.05,
            steer_std_rad: 0.5_f64.to_radians(),
            input_noise_correlation_s: 0.05,
            speed_scale_std: 0.0,
            steer_bias_std_rad: 0.0,
            speed_scale_walk_per_sqrt_s: 1e-4,
            steer_bias_walk_rad_per_sqrt_s: 1e-5,
            speed_scale_from_landmarks: true,
            steer_bias_from_landmarks: true,
            material_variance_per_s: 1e-4,
            feature_wander_m: 0.0,
            feature_wander_length_m: 2.0,
            defer_empty_beams: true,
            max_predict_step_s: 0.05,
            max_predict_gap_s: 5.0,
            gap_speed_mps: 2.0,
            gap_yaw_rate_rps: 0.2,
            gap_max_sigma_m: 100.0,
            relocalise_after_gap: true,
            relocalise_min_features: 3,
            relocalise_rival_share: 0.75,
            relocalise_max_hypotheses: 50_000,
            relocalise_max_targets: 2_000,
            relocalise_give_up_s: 30.0,
            burst_factor: 4.0,
            burst_floor_per_s: 250.0,
            burst_window_s: 0.1,
            burst_norm_s: 60.0,
            gate_probability: 0.99,
            exclusion_probability: 0.9999,
            jcbb_max_nodes: 5_000,
            beam_half_width_rad: 0.9_f64.to_radians(),
            association_margin_rad: 1.0_f64.to_radians(),
            candidate_sigmas: 3.0,
            min_range_m: 0.5,
            max_range_m: 200.0,
            min_detectable_power_db: f64::NEG_INFINITY,
            confirm_min_separation_s: 0.1,
            confirm_after: 2,
            retire_unseen_after_s: 0.0,
            retire_unrepeatable_below: 0.0,
            repeatability_min_rotations: 8,
            tentative_timeout_s: 2.0,
            max_targets_per_beam: 64,
            max_tentatives: 4_096,
            add_features: true,
            max_features: 2_000,
            retire_after_misses: 8,
            initial_rho: 0.3,
            initial_alpha: 0.3,
            initial_material_std: 2.0,
            registration_placement_share: 0.0,
            initial_loss_db: 0.0,
            initial_loss_std_db: 10.0,
        }
    }
}

/// Largest JCBB node budget accepted.
pub const MAX_JCBB_NODES: usize = 100_000;

/// A setting that makes no sense.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SettingsError {
    /// A speed correction this uncertain would let the model's speed change sign.
    #[error("speed_scale_std must be < 0.5 (a prior that lets the speed correction reach -100 % is not a correction), got {0}")]
    SpeedScaleTooUncertain(f64),
    /// The value must be finite and strictly positive.
    #[error("{name} must be finite and > 0, got {value}")]
    NotPositive {
        /// Field name.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// The value must be finite and >= 0.
    #[error("{name} must be finite and >= 0, got {value}")]
    Negative {
        /// Field name.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// The value must lie in [0, max].
    #[error("{name} must lie in [0, {max}], got {value}")]
    OutOfRange {
        /// Field name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// The largest value allowed.
        max: f64,
    },
    /// The value must lie in [0, 1].
    #[error("{name} must lie in [0, 1], got {value}")]
    NotAFraction {
        /// Field name.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// The value must lie strictly between 0 and 1.
    #[error("{name} must lie in (0, 1), got {value}")]
    NotAProbability {
        /// Field name.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// rho + alpha must be < 1 so the transmitted share is positive.
    #[error("initial rho + alpha must be < 1, got {rho} + {alpha}")]
    SharesExceedOne {
        /// Initial rho.
        rho: f64,
        /// Initial alpha.
        alpha: f64,
    },
    /// A count must be at least one.
    #[error("{name} must be at least 1")]
    ZeroCount {
        /// Field name.
        name: &'static str,
    },
    /// A count above its limit.
    #[error("{name} must be at most {max}")]
    TooLarge {
        /// Field name.
        name: &'static str,
        /// The limit.
        max: usize,
    },
    /// The value must be at least 1 (infinity allowed).
    #[error("{name} must be >= 1, got {value}")]
    BelowOne {
        /// Field name.
        name: &'static str,
        /// Offending value.
        value: f64,
    },
    /// A count below its minimum.
    #[error("{name} must be at least {min}")]
    TooSmall {
        /// Field name.
        name: &'static str,
        /// The minimum.
        min: usize,
    },
    /// The value must not be NaN (infinities are allowed where documented).
    #[error("{name} must not be NaN")]
    NaN {
        /// Field name.
        name: &'static str,
    },
}

/// The largest [`FilterSettings::registration_placement_share`]: at 0.5 a registration
/// would hold no white noise, and chained registrations no drift at all.
pub const MAX_PLACEMENT_SHARE: f64 = 0.45;

fn positive(name: &'static str, value: f64) -> Result<(), SettingsError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(SettingsError::NotPositive { name, value })
    }
}

fn non_negative(name: &'static str, value: f64) -> Result<(), SettingsError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(SettingsError::Negative { name, value })
    }
}

fn probability(name: &'static str, value: f64) -> Result<(), SettingsError> {
    if value.is_finite() && value > 0.0 && value < 1.0 {
        Ok(())
    } else {
        Err(SettingsError::NotAProbability { name, value })
    }
}

fn fraction(name: &'static str, value: f64) -> Result<(), SettingsError> {
    if (0.0..=1.0).contains(&value) {
        Ok(())
    } else {
        Err(SettingsError::NotAFraction { name, value })
    }
}

fn count(name: &'static str, value: usize) -> Result<(), SettingsError> {
    if value >= 1 {
        Ok(())
    } else {
        Err(SettingsError::ZeroCount { name })
    }
}

impl FilterSettings {
    /// Checks every field; the filter's constructor calls this.
    pub fn validate(&self) -> Result<(), SettingsError> {
        positive("range_std_m", self.range_std_m)?;
        positive("bearing_std_rad", self.bearing_std_rad)?;
        positive("power_std_db", self.power_std_db)?;
        positive("speed_std_mps", self.speed_std_mps)?;
        positive("steer_std_rad", self.steer_std_rad)?;
        positive("input_noise_correlation_s", self.input_noise_correlation_s)?;
        non_negative("speed_scale_std", self.speed_scale_std)?;
        non_negative("steer_bias_std_rad", self.steer_bias_std_rad)?;
        non_negative(
            "speed_scale_walk_per_sqrt_s",
            self.speed_scale_walk_per_sqrt_s,
        )?;
        non_negative(
            "steer_bias_walk_rad_per_sqrt_s",
            self.steer_bias_walk_rad_per_sqrt_s,
        )?;
        if self.speed_scale_std >= 0.5 {
            return Err(SettingsError::SpeedScaleTooUncertain(self.speed_scale_std));
        }
        non_negative("material_variance_per_s", self.material_variance_per_s)?;
        non_negative("feature_wander_m", self.feature_wander_m)?;
        positive("feature_wander_length_m", self.feature_wander_length_m)?;
        non_negative("repeat_look_range_m", self.repeat_look_range_m)?;
        non_negative("repeat_look_bearing_rad", self.repeat_look_bearing_rad)?;
        if self.repeat_look_max_factor.is_nan() || self.repeat_look_max_factor < 1.0 {
            return Err(SettingsError::BelowOne {
                name: "repeat_look_max_factor",
                value: self.repeat_look_max_factor,
            });
        }
        positive("max_predict_step_s", self.max_predict_step_s)?;
        positive("max_predict_gap_s", self.max_predict_gap_s)?;
        positive("gap_speed_mps", self.gap_speed_mps)?;
        positive("gap_yaw_rate_rps", self.gap_yaw_rate_rps)?;
        positive("gap_max_sigma_m", self.gap_max_sigma_m)?;
        if self.relocalise_min_features < 2 {
            return Err(SettingsError::TooSmall {
                name: "relocalise_min_features",
                min: 2,
            });
        }
        probability("relocalise_rival_share", self.relocalise_rival_share)?;
        count("relocalise_max_hypotheses", self.relocalise_max_hypotheses)?;
        count("relocalise_max_targets", self.relocalise_max_targets)?;
        positive("relocalise_give_up_s", self.relocalise_give_up_s)?;
        if self.burst_factor.is_nan() || self.burst_factor < 1.0 {
            return Err(SettingsError::BelowOne {
                name: "burst_factor",
                value: self.burst_factor,
            });
        }
        non_negative("burst_floor_per_s", self.burst_floor_per_s)?;
        positive("burst_window_s", self.burst_window_s)?;
        positive("burst_norm_s", self.burst_norm_s)?;
        probability("gate_probability", self.gate_probability)?;
        probability("exclusion_probability", self.exclusion_probability)?;
        positive("beam_half_width_rad", self.beam_half_width_rad)?;
        non_negative("association_margin_rad", self.association_margin_rad)?;
        non_negative("candidate_sigmas", self.candidate_sigmas)?;
        positive("min_range_m", self.min_range_m)?;
        positive("max_range_m", self.max_range_m)?;
        if self.min_detectable_power_db.is_nan() {
            return Err(SettingsError::NaN {
                name: "min_detectable_power_db",
            });
        }
        non_negative("confirm_min_separation_s", self.confirm_min_separation_s)?;
        count("confirm_after", self.confirm_after as usize)?;
        non_negative("retire_unseen_after_s", self.retire_unseen_after_s)?;
        fraction("retire_unrepeatable_below", self.retire_unrepeatable_below)?;
        count(
            "repeatability_min_rotations",
            self.repeatability_min_rotations as usize,
        )?;
        positive("tentative_timeout_s", self.tentative_timeout_s)?;
        count("max_targets_per_beam", self.max_targets_per_beam)?;
        count("max_tentatives", self.max_tentatives)?;
        if self.jcbb_max_nodes > MAX_JCBB_NODES {
            return Err(SettingsError::TooLarge {
                name: "jcbb_max_nodes",
                max: MAX_JCBB_NODES,
            });
        }
        count("max_features", self.max_features)?;
        count("retire_after_misses", self.retire_after_misses as usize)?;
        probability("initial_rho", self.initial_rho)?;
        probability("initial_alpha", self.initial_alpha)?;
        if self.initial_rho + self.initial_alpha >= 1.0 {
            return Err(SettingsError::SharesExceedOne {
                rho: self.initial_rho,
                alpha: self.initial_alpha,
            });
        }
        positive("initial_material_std", self.initial_material_std)?;
        if !self.initial_loss_db.is_finite() {
            return Err(SettingsError::Negative {
                name: "initial_loss_db",
                value: self.initial_loss_db,
            });
        }
        positive("initial_loss_std_db", self.initial_loss_std_db)?;
        let share = self.registration_placement_share;
        if !(0.0..=MAX_PLACEMENT_SHARE).contains(&share) {
            return Err(SettingsError::OutOfRange {
                name: "registration_placement_share",
                value: share,
                max: MAX_PLACEMENT_SHARE,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_are_valid() {
        assert_eq!(FilterSettings::default().validate(), Ok(()));
    }

    #[test]
    fn a_nan_standard_deviation_is_rejected_by_name() {
        let s = FilterSettings {
            range_std_m: f64::NAN,
            ..FilterSettings::default()
        };
        assert!(matches!(
            s.validate(),
            Err(SettingsError::NotPositive {
                name: "range_std_m",
                ..
            })
        ));
    }

    #[test]
    fn shares_that_leave_nothing_transmitted_are_rejected() {
        let s = FilterSettings {
            initial_rho: 0.6,
            initial_alpha: 0.4,
            ..FilterSettings::default()
        };
        assert!(matches!(
            s.validate(),
            Err(SettingsError::SharesExceedOne { .. })
        ));
    }

    #[test]
    fn a_repeat_look_cap_below_one_or_nan_is_rejected_and_infinity_accepted() {
        for bad in [0.5, f64::NAN, -1.0] {
            let s = FilterSettings {
                repeat_look_max_factor: bad,
                ..FilterSettings::default()
            };
            assert!(matches!(
                s.validate(),
                Err(SettingsError::BelowOne {
                    name: "repeat_look_max_factor",
                    ..
                })
            ));
        }
        let s = FilterSettings {
            repeat_look_max_factor: f64::INFINITY,
            ..FilterSettings::default()
        };
        assert_eq!(s.validate(), Ok(()));
    }
}
