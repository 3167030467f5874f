//! The pipeline's settings, derived once from the configuration and the radar's profile.
//!
//! A radar profile (`radar_model::profile`) holds what a radar model is and what was
//! measured on it. Every setting the profile owns takes the profile's value unless the
//! configuration file writes its key; then the file's value wins and the log says which key
//! did. What a source knows exactly (the simulator's scene: its motion model, its receiver,
//! its beam, its start pose) is a [`SourceFacts`] and is applied in the same step. Nothing
//! patches the settings afterwards.

use std::collections::BTreeSet;

use config::detector::DetectorKind as ConfigKind;
use config::model::CompensationKind;
use radar_model::compensation::Compensation;
use radar_model::motion::MotionModel;
use radar_model::profile::{Choice, CompensationSlope, FrontEndFamily, RadarProfile};
use tracing::{info, warn};

use super::settings::{PipelineSettings, SettingsError, REPEAT_LOOK_CELL_FRACTION};
use crate::detect::DetectorSettings;

/// Prior standard deviation of the odometry's speed scale when radar odometry runs and the
/// configuration writes none: a wheel odometry 5 % off is a 1-sigma event.
pub const RADAR_ODOMETRY_SPEED_SCALE_STD: f64 = 0.05;
/// The same for the steering offset (rad): 0.02 rad/s of yaw rate at 7 m/s on a 2.7 m
/// wheelbase is 0.0077 rad.
pub const RADAR_ODOMETRY_STEER_BIAS_STD_RAD: f64 = 0.01;
/// Standard deviation of one registration's heading (rad) when radar odometry runs beside
/// wheel odometry and the configuration writes none: each rotation is placed with the turn
/// its reference was placed with and registered against the last few rotations as well
/// ([`DRIVING_KEYFRAMES`]), and so placed the registrations err 1.6 mrad RMS on the
/// realistic city (the configuration default, 3 mrad, is for one registration against the
/// previous rotation alone). Through `config/examples/vehicle.toml` on the realistic city,
/// with three keyframes, 3 mrad gave 1.16 / 1.06 % odometry drift on the two layouts,
/// 1.5 mrad 0.90 / 0.74 % (slam-node/README.md, "The user's configuration on the
/// realistic city").
pub const FUSED_SIGMA_RAD: f64 = 0.0015;
/// Radar only: the process model's input is the vehicle's motion over the last rotation,
/// held for the next; its standard deviation is the change of speed a car makes over a
/// rotation (1 m/s^2 for 0.25 s), as m/s.
pub const RADAR_ONLY_SIGMA_SPEED_MPS: f64 = 0.25;
/// The same for the turn rate (rad/s): a gentle car's 0.12 rad/s^2 for 0.25 s. Measured on
/// the realistic street (`sim-sensor/scenes/urban-street.toml`, 20 s, radar only), online
/// drift: 0.15 rad/s 2.64 % (the map's features, most of them not true points, pull the
/// heading the prediction leaves free), 0.03 rad/s 1.04 % (NEES 4.9), 0.006 rad/s 0.70 % but
/// over-confident (NEES 39). slam-node/README.md, "Radar only".
pub const RADAR_ONLY_SIGMA_YAW_RATE_RPS: f64 = 0.03;
/// Radar only, the bicycle model: the steering that standard deviation of turn rate is at
/// a town's 7 m/s on a 2.7 m wheelbase (rad).
pub const RADAR_ONLY_SIGMA_BICYCLE_STEER_RAD: f64 = 0.012;
/// Radar only, without a gyro: the share of a registration's covariance that is its two
/// clouds' placement when the configuration writes none
/// (`[odometry] radar_odometry_placement_share`, slam-filter's
/// `FilterSettings::registration_placement_share`). The realistic city's registrations
/// chained add up as a share of 0.42-0.47 says (`evaluation/heading_budget.py`), but the
/// filter's pose drifts more than they chain and, told that much, claims more than it has.
/// Ten drives on the radar alone (slam-node/README.md, "Where the turns' heading error comes
/// from"), the pose's NEES inside its band online / optimised: 0 (before) 93.8 / 96.4 %
/// (conservative after the first loops), 0.2 96.3 / 98.9 %, 0.35 (at 3.2 mrad) 90.5 / 94.6
/// % (optimistic); with 0.2 the online pose 6.46 -> 5.96 m RMS, odometry 0.816 -> 0.812 %,
/// aligned 0.47 -> 0.58 m (every drive under 1 m).
pub const RADAR_ALONE_PLACEMENT_SHARE: f64 = 0.2;
/// Radar only: odometry is fresh for at least this long (ms), since radar odometry gives one
/// sample a rotation.
pub const RADAR_ONLY_STALE_AFTER_MS: i64 = 1000;

/// Which keys the configuration writes.
#[derive(Debug, Clone, Copy)]
pub enum Written<'a> {
    /// Every key: the configuration's values win everywhere (a configuration built in code).
    Everything,
    /// These dotted keys (`model.sigma_range_m`), as `config::written_keys` reads them.
    Keys(&'a BTreeSet<String>),
}

impl Written<'_> {
    fn has(&self, key: &str) -> bool {
        match self {
            Written::Everything => true,
            Written::Keys(keys) => keys.contains(key),
        }
    }
}

/// What a source knows exactly about its radar and its drive, applied over the profile and
/// the configuration.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SourceFacts {
    /// The motion model the source's odometry means (the simulator's scene; the bicycle
    /// the recorded odometry was made with).
    pub motion: Option<MotionModel>,
    /// The receiver's compensation, known exactly (the simulator's).
    pub compensation: Option<Compensation>,
    /// The beam width (rad), known exactly (the simulator's).
    pub beam_width_rad: Option<f64>,
    /// The range-Doppler coupling (s), known exactly (the simulator's).
    pub doppler_range_coupling_s: Option<f64>,
    /// A point's peak width in the spectrum (m), known exactly (the simulator draws each
    /// peak one bin wide).
    pub peak_fwhm_m: Option<f64>,
    /// The start pose and its standard deviations, known exactly (the scene's).
    pub initial_pose: Option<([f64; 3], [f64; 3])>,
    /// The detector's base, replacing `[detector]` but for the front end's kind, learned
    /// floor and landmark thresholds (the run without a configuration file uses slam-node's
    /// measured default).
    pub detector: Option<DetectorSettings>,
    /// Radar odometry forced off (`--no-radar-odometry`).
    pub no_radar_odometry: bool,
    /// The source brings no odometry (`--radar-only`): radar odometry drives the filter, as
    /// with `[odometry] source = "none"`.
    pub radar_only: bool,
    /// The source brings a gyro of its own (`--gyro-from-truth`); `[gyro] source` brings
    /// one too.
    pub gyro: bool,
    /// The radar's full range (m), bounding the filter's and the detector's.
    pub max_range_m: Option<f64>,
    /// Bearings (rad) whose predicted and measured spectra are drawn (`--spectrum-bearing`).
    pub spectrum_bearings_rad: Vec<f64>,
}

/// What the settings are derived from, before the radar is known: the configuration, the
/// keys it writes, and what the run adds (`--spectrum-bearing`, the measured default
/// detector of the run without a configuration file).
#[derive(Debug, Clone)]
pub struct SettingsRecipe {
    /// The validated configuration.
    pub config: config::Config,
    /// The keys the configuration file writes; `None`: every key (a configuration built in
    /// code, whose values win everywhere).
    pub written: Option<BTreeSet<String>>,
    /// What the run adds.
    pub facts: SourceFacts,
    /// The saved map to localise in (`--map FILE`, `[map] mode = "localise"`).
    pub localise: Option<super::localise::LocaliseSettings>,
}

impl SettingsRecipe {
    /// A recipe from a configuration built in code: its values win everywhere.
    pub fn from_config(config: config::Config) -> Self {
        Self {
            config,
            written: None,
            facts: SourceFacts::default(),
            localise: None,
        }
    }

    /// `[radar] model`, checked against the profiles.
    pub fn named_model(&self) -> Result<Option<&'static RadarProfile>, SettingsError> {
        match self.config.radar.model.as_deref() {
            None => Ok(None),
            Some(name) => radar_model::profile::by_name(name)
                .map(Some)
                .ok_or_else(|| {
                    radar_model::profile::UnknownModel {
                        name: name.to_owned(),
                        known: radar_model::profile::names().join(", "),
                    }
                    .into()
                }),
        }
    }

    /// The settings for a radar that announced `geometry` (the profile chosen from it unless
    /// `[radar] model` names one), with the source's `facts` over the run's; logged.
    pub fn for_radar(
        &self,
        geometry: &protocol::Geometry,
        facts: SourceFacts,
    ) -> Result<Derived, SettingsError> {
        let choice =
            radar_model::profile::select(self.config.radar.model.as_deref(), &announced(geometry))?;
        let facts = SourceFacts {
            max_range_m: facts.max_range_m.or(Some(full_range_m(geometry))),
            ..facts
        };
        self.derive(choice, facts)
    }

    /// The settings for `choice` with the source's `facts` over the run's; logged.
    pub fn derive(&self, choice: Choice, facts: SourceFacts) -> Result<Derived, SettingsError> {
        let derived = self.derive_quietly(choice, facts)?;
        derived.log();
        Ok(derived)
    }

    /// [`Self::derive`] without the log lines.
    pub fn derive_quietly(
        &self,
        choice: Choice,
        facts: SourceFacts,
    ) -> Result<Derived, SettingsError> {
        let run = &self.facts;
        let facts = SourceFacts {
            detector: facts.detector.or(run.detector),
            no_radar_odometry: facts.no_radar_odometry || run.no_radar_odometry,
            radar_only: facts.radar_only || run.radar_only,
            gyro: facts.gyro || run.gyro,
            spectrum_bearings_rad: if facts.spectrum_bearings_rad.is_empty() {
                run.spectrum_bearings_rad.clone()
            } else {
                facts.spectrum_bearings_rad
            },
            ..facts
        };
        let written = match &self.written {
            Some(keys) => Written::Keys(keys),
            None => Written::Everything,
        };
        let mut derived = PipelineSettings::derive(&self.config, written, choice, &facts)?;
        if let Some(l) = &self.localise {
            l.apply(&mut derived.settings);
            derived.settings.localise = Some(l.clone());
        }
        Ok(derived)
    }
}

/// The settings and how they were made.
#[derive(Debug, Clone)]
pub struct Derived {
    /// The pipeline's settings.
    pub settings: PipelineSettings,
    /// The profile and why it was chosen.
    pub choice: Choice,
    /// The profile's keys the configuration wrote (its values won).
    pub overridden: Vec<&'static str>,
    /// Keys the configuration wrote that the chosen detector does not use (the CFAR
    /// window's under `tpp` or `learned`): warned about, not silently taken.
    pub unused: Vec<&'static str>,
}

/// The CFAR window's keys: only `ca-cfar` and `os-cfar` use them.
const CFAR_KEYS: [&str; 3] = [
    "detector.guard_cells",
    "detector.reference_cells",
    "detector.os_rank",
];

/// The profile's value of `key` unless the configuration writes it: records the override.
fn take<T>(
    written: &Written<'_>,
    overridden: &mut Vec<&'static str>,
    key: &'static str,
    slot: &mut T,
    profile_value: T,
) {
    if written.has(key) {
        if matches!(written, Written::Keys(_)) {
            overridden.push(key);
        }
    } else {
        *slot = profile_value;
    }
}

/// The configuration with the profile's values where it writes no key, and the profile's
/// keys it does write.
pub fn effective_config(
    c: &config::Config,
    written: Written<'_>,
    profile: &RadarProfile,
    no_radar_odometry: bool,
    radar_only: bool,
    gyro: bool,
) -> Result<(config::Config, Vec<&'static str>), SettingsError> {
    let gyro = gyro || c.gyro.source != config::gyro::GyroSource::None;
    let mut raw = config::RawConfig::from(c);
    let mut over = Vec::new();
    let w = &written;
    let m = &mut raw.model;
    take(
        w,
        &mut over,
        "model.beam_width_deg",
        &mut m.beam_width_deg,
        profile.beam_width_deg.value,
    );
    take(
        w,
        &mut over,
        "model.range_resolution_m",
        &mut m.range_resolution_m,
        profile.range_resolution_m.value,
    );
    take(
        w,
        &mut over,
        "model.sigma_range_m",
        &mut m.sigma_range_m,
        profile.sigma_range_m.value,
    );
    take(
        w,
        &mut over,
        "model.sigma_bearing_deg",
        &mut m.sigma_bearing_deg,
        profile.sigma_bearing_deg.value,
    );
    take(
        w,
        &mut over,
        "model.sigma_power_db",
        &mut m.sigma_power_db,
        profile.sigma_power_db.value,
    );
    take(
        w,
        &mut over,
        "model.doppler_range_coupling_s",
        &mut m.doppler_range_coupling_s,
        profile.doppler_range_coupling_s.value,
    );
    take(
        w,
        &mut over,
        "model.compensation",
        &mut m.compensation,
        match profile.compensation.value {
            CompensationSlope::Sixty => CompensationKind::Slope60,
            CompensationSlope::Forty => CompensationKind::Slope40,
        },
    );
    let d = &mut raw.detector;
    take(
        w,
        &mut over,
        "detector.kind",
        &mut d.kind,
        match profile.front_end.value {
            FrontEndFamily::PaperTpp => ConfigKind::Tpp,
            FrontEndFamily::Learned => ConfigKind::Learned,
        },
    );
    let floor = profile.learned_floor.value;
    take(
        w,
        &mut over,
        "detector.floor_sigma",
        &mut d.floor_sigma,
        floor.floor_sigma,
    );
    take(
        w,
        &mut over,
        "detector.floor_min_snr_db",
        &mut d.floor_min_snr_db,
        floor.floor_min_snr_db,
    );
    let l = profile.landmarks.value;
    take(
        w,
        &mut over,
        "detector.points_only",
        &mut d.points_only,
        l.points_only,
    );
    take(
        w,
        &mut over,
        "detector.point_max_extent_m",
        &mut d.point_max_extent_m,
        l.point_max_extent_m,
    );
    take(
        w,
        &mut over,
        "detector.point_max_width_beams",
        &mut d.point_max_width_beams,
        l.point_max_width_beams,
    );
    take(
        w,
        &mut over,
        "detector.point_min_snr_db",
        &mut d.point_min_snr_db,
        l.point_min_snr_db,
    );
    take(
        w,
        &mut over,
        "detector.extended_reobserve",
        &mut d.extended_reobserve,
        l.extended_reobserve,
    );
    take(
        w,
        &mut over,
        "filter.confirm_after",
        &mut raw.filter.confirm_after,
        i64::from(l.confirm_after),
    );
    let o = &mut raw.odometry;
    take(
        w,
        &mut over,
        "odometry.radar_odometry",
        &mut o.radar_odometry,
        profile.radar_odometry.value,
    );
    if no_radar_odometry {
        o.radar_odometry = false;
    }
    let radar_only = radar_only || o.source == config::odometry::OdometrySourceKind::None;
    if radar_only {
        // Radar odometry drives the prediction: its input is the motion over the last
        // rotation, unbiased (no corrections to estimate), one sample a rotation.
        if no_radar_odometry {
            return Err(SettingsError::RadarOnlyWithoutRadarOdometry);
        }
        o.radar_odometry = true;
        // The paper's model: its heading noise does not vanish standing still, as the
        // bicycle's does (the input is the radar's motion, not a vehicle's controls).
        o.motion_model = config::odometry::MotionModelKind::Paper;
        if !written.has("odometry.sigma_speed_mps") {
            o.sigma_speed_mps = RADAR_ONLY_SIGMA_SPEED_MPS;
        }
        if !written.has("odometry.sigma_steer_rad") {
            o.sigma_steer_rad = match o.motion_model {
                config::odometry::MotionModelKind::Paper => {
                    RADAR_ONLY_SIGMA_YAW_RATE_RPS
                        * o.step_s.unwrap_or(config::odometry::DEFAULT_STEP_S)
                }
                config::odometry::MotionModelKind::Bicycle => RADAR_ONLY_SIGMA_BICYCLE_STEER_RAD,
            };
        }
        o.speed_scale_std = 0.0;
        o.steer_bias_std_rad = 0.0;
        o.speed_scale_walk_per_sqrt_s = 0.0;
        o.steer_bias_walk_rad_per_sqrt_s = 0.0;
        o.speed_scale_from_landmarks = false;
        // Each rotation's cloud is placed along a motion (held, then registered), and a
        // registration against the rotation before errs by both clouds' placement:
        // consecutive errors cancel when chained (lag one -0.48 on the realistic city).
        // Driving on the radar alone, the filter holds a share of that in its state; with a
        // gyro (not measured) or localising (the map's registrations hold the pose), none.
        if !gyro
            && c.map.mode != config::MapMode::Localise
            && !written.has("odometry.radar_odometry_placement_share")
        {
            o.radar_odometry_placement_share = RADAR_ALONE_PLACEMENT_SHARE;
        }
        if gyro {
            super::gyro::model_in_process_noise(
                o,
                &c.gyro,
                slam_filter::FilterSettings::default().input_noise_correlation_s,
            );
        }
        o.stale_after_ms = o.stale_after_ms.max(RADAR_ONLY_STALE_AFTER_MS);
    }
    // With radar odometry, the odometry's corrections are estimated, the speed scale from
    // the registrations alone (slam-node/README.md, "Odometry corrections"), unless the
    // configuration says otherwise.
    if o.radar_odometry && !radar_only {
        if !written.has("odometry.speed_scale_std") && o.speed_scale_std == 0.0 {
            o.speed_scale_std = RADAR_ODOMETRY_SPEED_SCALE_STD;
        }
        if !written.has("odometry.steer_bias_std_rad") && o.steer_bias_std_rad == 0.0 {
            o.steer_bias_std_rad = RADAR_ODOMETRY_STEER_BIAS_STD_RAD;
        }
        if !written.has("odometry.speed_scale_from_landmarks") {
            o.speed_scale_from_landmarks = false;
        }
        // Registered against keyframes too (see `PipelineSettings::derive`), a registration's
        // heading is known better than the default's one-rotation figure; localising, the
        // map's registrations hold the pose and keep the default.
        if !written.has("odometry.radar_odometry_sigma_rad")
            && c.map.mode != config::MapMode::Localise
        {
            o.radar_odometry_sigma_rad = FUSED_SIGMA_RAD;
        }
    }
    let effective = raw.validate().map_err(|errors| SettingsError::Profile {
        profile: profile.name,
        errors,
    })?;
    Ok((effective, over))
}

/// Keyframes radar odometry registers against when it drives the prediction and
/// `[odometry] radar_odometry_keyframes` is unset.
pub const DRIVING_KEYFRAMES: usize = 3;

/// Kernel width (m) of radar odometry's last registration without hard pairs when
/// `[odometry] radar_odometry_soft_kernel_m` is unset.
pub const SOFT_KERNEL_M: f64 = 0.1;

/// On the radar alone (no gyro), a rotation whose heading in its submap's frame is more than
/// this (rad) from the frame's is not added to the submap's scan
/// ([`super::settings::SubmapOptions::scan_max_turn_rad`]).
pub const RADAR_ALONE_SCAN_MAX_TURN_RAD: f64 = 0.5;

impl PipelineSettings {
    /// The settings for a radar of profile `choice` from configuration `c` (which writes
    /// `written`) and what the source knows (`facts`): derived once, logged once.
    pub fn derive(
        c: &config::Config,
        written: Written<'_>,
        choice: Choice,
        facts: &SourceFacts,
    ) -> Result<Derived, SettingsError> {
        let profile = choice.profile;
        let (effective, overridden) = effective_config(
            c,
            written,
            profile,
            facts.no_radar_odometry,
            facts.radar_only,
            facts.gyro,
        )?;
        let mut s = Self::from_config(&effective)?;
        // A setting with no key of its own: the profile's, unless the configuration was
        // built in code (whose values, and the library's defaults, win everywhere).
        if let Written::Keys(_) = written {
            s.filter.confirm_min_separation_s = profile.landmarks.value.confirm_min_separation_s;
        }
        let mut s = s.with_facts(facts);
        s.map_save.profile = profile.name.to_owned();
        s.radar_drives = s.scan_match.enabled
            && (facts.radar_only
                || effective.odometry.source == config::odometry::OdometrySource::None);
        let gyro = facts.gyro || effective.gyro.source != config::gyro::GyroSource::None;
        if effective.odometry.radar_odometry_keyframes.is_none()
            && s.scan_match.enabled
            && !gyro
            && effective.map.mode != config::MapMode::Localise
        {
            // Driving on the radar alone, the registrations are the odometry and their
            // errors add up rotation by rotation: registered against the last few rotations
            // too, they add up more slowly (slam-node/README.md, "Radar only"). Fused with
            // wheel odometry, the same: through `config/examples/vehicle.toml` the realistic
            // city's two layouts drifted 1.10 / 1.31 % without them and 0.90 / 0.74 % with,
            // the urban street 1.17 m RMS against 0.28 m (slam-node/README.md, "The user's
            // configuration on the realistic city"). With a gyro, none (the gyro turns the prediction and the
            // registrations teach its bias: with keyframes two drives of three drifted
            // more); localising, none (the map's registrations hold the pose).
            s.scan_match.keyframes = DRIVING_KEYFRAMES;
        }
        if effective.odometry.radar_odometry_soft_kernel_m.is_none() && s.scan_match.enabled {
            // A registration stops wherever one set of nearest pairs holds it, which depends
            // on its start: beside the wheels it follows their steering noise, on the radar
            // alone the motion held. Run once more without hard pairs from its result, it
            // follows less, and it takes the place of the runs again with hard pairs
            // (`radar_odometry_refine_runs`, 0 unless written) (slam-node/README.md, "A
            // registration without hard pairs").
            s.scan_match.soft_kernel_m = SOFT_KERNEL_M;
        }
        if s.radar_drives && !gyro {
            // The prediction is the last rotation's motion held, which places a turn's
            // onset straight: the cloud is placed again along the motion registered and
            // registered once more (slam-node/README.md, "Radar only").
            s.scan_match.replace = true;
            // The same prediction misses the onset itself: the rotation swept through it
            // is bent only late and registered near straight; probes from headings either
            // side and a swept registration find it (slam-node/README.md, "Radar only").
            s.scan_match.onset_probes = true;
            // Pulling away or crawling, a rotation's shift is within the pair gate of the
            // ground's clutter, whose shadows turn with the vehicle: the registrations pair
            // with surfaces only, the first (searched) one run again from its result so
            // (slam-node/README.md, "Registrations at a crawl pair with surfaces only", "The
            // first registration at a pull-away").
            s.scan_match.crawl_surfaces_only = true;
            // The radar alone loses a degree or two of each junction's turn: a submap's scan
            // gathered on through one is bent, and closures aligning it put the frames
            // degrees off; the scan stops at the turn (slam-node/README.md, "Radar only").
            if let Some(o) = s.submaps.as_mut() {
                o.scan_max_turn_rad = Some(RADAR_ALONE_SCAN_MAX_TURN_RAD);
            }
        }
        if s.radar_drives {
            // The prediction is the held motion already (or a gyro's turn): the
            // registration places the cloud along it.
            s.scan_match.place_held = false;
            // Its start is the held motion, not a sensor's: the radar's own turn is the
            // only one there is (and its probes re-place the cloud along each start).
            s.scan_match.start_probe = false;
            // What drives the filter is the radar's motion, whatever model a source's own
            // odometry meant.
            s.motion = super::settings::motion_model(&effective);
            if gyro {
                s.gyro = Some(super::gyro::GyroUse {
                    max_yaw_rate_rad_s: effective.gyro.max_yaw_rate_rad_s.get(),
                });
                // The gyro's bias is learned from the registrations only (see
                // `slam_filter::FilterSettings::steer_bias_from_landmarks`).
                s.filter.steer_bias_from_landmarks = false;
            }
        }
        let cfar = matches!(
            s.detector.kind,
            crate::detect::DetectorKind::CaCfar | crate::detect::DetectorKind::OsCfar
        );
        let unused = match written {
            Written::Keys(keys) if !cfar => CFAR_KEYS
                .into_iter()
                .filter(|k| keys.contains(*k))
                .collect(),
            _ => Vec::new(),
        };
        Ok(Derived {
            settings: s,
            choice,
            overridden,
            unused,
        })
    }
}

impl PipelineSettings {
    /// These settings with what a source knows exactly (`facts`) in place of the profile's
    /// and the configuration's values: the one step [`PipelineSettings::derive`] ends with.
    pub fn with_facts(mut self, facts: &SourceFacts) -> Self {
        let s = &mut self;
        if let Some(motion) = facts.motion {
            if motion != s.motion {
                info!(?motion, configured = ?s.motion, "using the source's motion model for its odometry");
                s.motion = motion;
            }
        }
        if let Some(compensation) = &facts.compensation {
            s.compensation = compensation.clone();
        }
        if let Some(beam) = facts.beam_width_rad {
            s.beam_width_rad = beam;
            s.filter.beam_half_width_rad = 0.5 * beam;
        }
        if let Some(coupling) = facts.doppler_range_coupling_s {
            if coupling != s.doppler_range_coupling_s {
                info!(
                    source_s = coupling,
                    configured_s = s.doppler_range_coupling_s,
                    "using the source's range-Doppler coupling"
                );
            }
            s.doppler_range_coupling_s = coupling;
        }
        if let Some(fwhm) = facts.peak_fwhm_m {
            s.noise.range.resolution_fwhm_m = fwhm;
        }
        if s.filter.repeat_look_range_m > 0.0 && s.filter.repeat_look_bearing_rad > 0.0 {
            s.filter.repeat_look_range_m =
                REPEAT_LOOK_CELL_FRACTION * s.noise.range.resolution_fwhm_m;
            s.filter.repeat_look_bearing_rad = REPEAT_LOOK_CELL_FRACTION * s.beam_width_rad;
        }
        if let Some((pose, std)) = facts.initial_pose {
            s.initial_pose = pose;
            s.initial_pose_std = std;
        }
        // The measured default detector is the base; the profile's front end (its kind, its
        // learned floor, its landmark thresholds) and the configuration's keys stand on it.
        if let Some(base) = facts
            .detector
            .filter(|_| s.detector.kind == crate::detect::DetectorKind::Tpp)
        {
            let chosen = s.detector;
            s.detector = DetectorSettings {
                kind: chosen.kind,
                floor: crate::detect::learned::FloorSettings {
                    detect_sigma: chosen.floor.detect_sigma,
                    min_snr_db: chosen.floor.min_snr_db,
                    ..base.floor
                },
                landmarks: chosen.landmarks,
                ..base
            };
        }
        if facts.no_radar_odometry {
            s.scan_match.enabled = false;
        }
        s.spectrum_bearings_rad = facts.spectrum_bearings_rad.clone();
        if let Some(range) = facts.max_range_m.filter(|r| r.is_finite() && *r > 0.0) {
            s.filter.max_range_m = s.filter.max_range_m.min(range);
            s.detector.max_range_m = s.detector.max_range_m.min(range);
        }
        self
    }

    /// The settings of the shipped configuration for a radar of `profile`, with `facts`:
    /// what the evaluation and the benchmarks run a profile with.
    pub fn for_profile(
        profile: &'static RadarProfile,
        facts: &SourceFacts,
    ) -> Result<Self, SettingsError> {
        let none = BTreeSet::new();
        let choice = Choice {
            profile,
            how: radar_model::profile::Chosen::Named,
        };
        Ok(Self::derive(
            &config::Config::default(),
            Written::Keys(&none),
            choice,
            facts,
        )?
        .settings)
    }
}

impl Derived {
    /// Logs the choice of profile and the configuration's overrides (once per run).
    pub fn log(&self) {
        match &self.choice.how {
            radar_model::profile::Chosen::Nearest(_) => {
                warn!(profile = %self.choice, "no radar profile matches this radar")
            }
            _ => info!(profile = %self.choice, "radar profile"),
        }
        if !self.overridden.is_empty() {
            info!(
                keys = %self.overridden.join(", "),
                profile = self.choice.profile.name,
                "the configuration overrides the profile's values"
            );
        }
        info!(kind = ?self.settings.detector.kind, domain = ?self.settings.detector.domain, "detector");
        if !self.unused.is_empty() {
            warn!(
                keys = %self.unused.join(", "),
                kind = ?self.settings.detector.kind,
                "the configuration sets CFAR window keys this detector does not use: they have no effect"
            );
        }
    }
}

/// What a radar announced, in the profiles' terms.
pub fn announced(geometry: &protocol::Geometry) -> radar_model::profile::Announced {
    radar_model::profile::Announced {
        azimuths: geometry.azimuth_samples,
        encoder_size: geometry.encoder_size,
        range_bins: geometry.range_in_bins,
        bin_size_m: geometry.range_gain * geometry.bin_size_m,
        rotation_hz: geometry.rotation_hz,
    }
}

/// The radar's full range (m): its bins times its bin size, plus its offset.
pub fn full_range_m(geometry: &protocol::Geometry) -> f64 {
    f64::from(geometry.range_in_bins) * geometry.range_gain * geometry.bin_size_m
        + geometry.range_offset_m
}

#[cfg(test)]
mod tests {
    use super::*;
    use radar_model::profile::{self, Chosen};

    fn named(p: &'static RadarProfile) -> Choice {
        Choice {
            profile: p,
            how: Chosen::Named,
        }
    }

    /// The settings for profile `p` from a configuration file's `text`.
    fn derive_from(text: &str, p: &'static RadarProfile) -> Derived {
        let c = config::Config::from_toml_str(text).unwrap();
        let keys = config::written_keys(text);
        PipelineSettings::derive(&c, Written::Keys(&keys), named(p), &SourceFacts::default())
            .unwrap()
    }

    #[test]
    fn cfar_window_keys_written_for_a_detector_that_does_not_use_them_are_named() {
        // Issue 38: `guard_cells` with `kind = "learned"` was taken without a word.
        let d = derive_from(
            "[detector]\nkind = \"learned\"\nguard_cells = 3\nreference_cells = 40\n",
            &profile::CTS350X,
        );
        assert_eq!(
            d.unused,
            vec!["detector.guard_cells", "detector.reference_cells"]
        );
        let d = derive_from("[detector]\nguard_cells = 3\n", &profile::PAPER_2006);
        assert_eq!(d.unused, vec!["detector.guard_cells"], "tpp, the default");
        let d = derive_from(
            "[detector]\nkind = \"ca-cfar\"\nguard_cells = 3\n",
            &profile::PAPER_2006,
        );
        assert!(d.unused.is_empty());
    }

    #[test]
    fn the_paper_profile_is_the_configuration_defaults() {
        let from_profile = derive_from("", &profile::PAPER_2006);
        let from_config = PipelineSettings::from_config(&config::Config::default()).unwrap();
        assert_eq!(from_profile.settings, from_config);
        assert!(from_profile.overridden.is_empty());
    }

    #[test]
    fn a_cts350x_gets_its_front_end_and_a_written_key_overrides_one_value() {
        let d = derive_from("[model]\nsigma_range_m = 0.2\n", &profile::CTS350X);
        let s = &d.settings;
        assert_eq!(d.overridden, vec!["model.sigma_range_m"]);
        assert_eq!(s.filter.range_std_m, 0.2);
        assert!((s.filter.bearing_std_rad - 1.3f64.to_radians()).abs() < 1e-12);
        assert_eq!(s.filter.power_std_db, 3.5);
        assert_eq!(s.detector.kind, crate::detect::DetectorKind::Learned);
        assert!(s.detector.landmarks.points_only);
        assert_eq!(s.detector.landmarks.min_snr_db, 32.0);
        assert_eq!(s.filter.confirm_after, 4);
        assert_eq!(s.filter.confirm_min_separation_s, 0.2);
        assert_eq!(s.power.range_resolution_m, 0.0438);
        assert_eq!(s.noise.range.resolution_fwhm_m, 0.0438);
        assert_eq!(s.doppler_range_coupling_s, 0.0488);
        assert!(s.scan_match.enabled);
        assert_eq!(s.filter.speed_scale_std, RADAR_ODOMETRY_SPEED_SCALE_STD);
        assert!(!s.filter.speed_scale_from_landmarks);
        // The steering offset is learned from the map as well unless a configuration says
        // otherwise (slam-node/README.md, "The point-feature map pulls the steering offset").
        assert!(s.filter.steer_bias_from_landmarks);
        // Beside wheel odometry the registrations run against keyframes too, their heading
        // taken at 1.5 mrad, each independent of the last; a configuration that writes any
        // of the keys gets it.
        assert_eq!(s.scan_match.keyframes, DRIVING_KEYFRAMES);
        assert_eq!(s.scan_match.sigma_theta_rad, FUSED_SIGMA_RAD);
        assert_eq!(s.filter.registration_placement_share, 0.0);
        // Beside the wheels and on the radar alone each registration is run once more
        // without hard pairs, and not again with hard pairs; written, the configuration's.
        assert_eq!(s.scan_match.refine_runs, 0);
        assert_eq!(s.scan_match.soft_kernel_m, SOFT_KERNEL_M);
        let matching = |toml: &str| {
            let m = derive_from(toml, &profile::CTS350X).settings.scan_match;
            (m.refine_runs, m.soft_kernel_m)
        };
        assert_eq!(
            matching("[odometry]\nsource = \"none\"\n"),
            (0, SOFT_KERNEL_M)
        );
        assert_eq!(
            matching("[odometry]\nsource = \"none\"\nradar_odometry_soft_kernel_m = 0.1\n"),
            (0, 0.1)
        );
        assert_eq!(
            matching("[odometry]\nradar_odometry_refine_runs = 1\n"),
            (1, SOFT_KERNEL_M)
        );
        assert_eq!(
            matching(
                "[odometry]\nsource = \"none\"\nradar_odometry_refine_runs = 3\n\
                 radar_odometry_soft_kernel_m = 0.0\n"
            ),
            (3, 0.0)
        );
        assert_eq!(
            matching("[odometry]\nradar_odometry_soft_kernel_m = 0.2\n"),
            (0, 0.2)
        );
        let d = derive_from(
            "[odometry]\nradar_odometry_keyframes = 0\nradar_odometry_sigma_rad = 0.003\n\
             radar_odometry_placement_share = 0.25\n",
            &profile::CTS350X,
        );
        assert_eq!(d.settings.scan_match.keyframes, 0);
        assert_eq!(d.settings.scan_match.sigma_theta_rad, 0.003);
        assert_eq!(d.settings.filter.registration_placement_share, 0.25);
        // Without radar odometry there are no registrations to model.
        let d = derive_from(
            "[odometry]\nradar_odometry = false\nradar_odometry_placement_share = 0.25\n",
            &profile::CTS350X,
        );
        assert_eq!(d.settings.filter.registration_placement_share, 0.0);
        // On the radar alone the filter holds a share of each registration's placement;
        // written, the configuration's; with a gyro or localising, none.
        let alone = |extra: &str| {
            derive_from(
                &format!("[odometry]\nsource = \"none\"\n{extra}"),
                &profile::CTS350X,
            )
            .settings
            .filter
            .registration_placement_share
        };
        assert_eq!(alone(""), RADAR_ALONE_PLACEMENT_SHARE);
        assert_eq!(alone("radar_odometry_placement_share = 0.0\n"), 0.0);
        assert_eq!(alone("radar_odometry_placement_share = 0.35\n"), 0.35);
        // Parsed only, never connected to: a documentation address (RFC 5737).
        assert_eq!(
            alone("\n[gyro]\nsource = \"tcp\"\naddress = \"192.0.2.1:7000\"\n"),
            0.0
        );
        assert_eq!(alone("\n[map]\nmode = \"localise\"\n"), 0.0);
        // The configuration's bound is the filter's: a share the configuration takes, the
        // filter's validation takes too.
        assert_eq!(
            config::values::PlacementShare::MAX,
            slam_filter::settings::MAX_PLACEMENT_SHARE
        );
        let d = derive_from(
            "[odometry]\nsteer_bias_from_landmarks = false\n",
            &profile::CTS350X,
        );
        assert!(!d.settings.filter.steer_bias_from_landmarks);
        // A configuration that writes a lower threshold gets it (no max() with a constant).
        let d = derive_from("[detector]\npoint_min_snr_db = 20.0\n", &profile::CTS350X);
        assert_eq!(d.settings.detector.landmarks.min_snr_db, 20.0);
    }

    #[test]
    fn the_radar_full_range_bounds_the_filter_and_the_detector() {
        let c = config::Config::default();
        let facts = SourceFacts {
            max_range_m: Some(165.0),
            ..SourceFacts::default()
        };
        let d = PipelineSettings::derive(&c, Written::Everything, named(&profile::CTS350X), &facts)
            .unwrap();
        assert_eq!(d.settings.filter.max_range_m, 165.0);
        assert_eq!(d.settings.detector.max_range_m, 165.0);
    }
}
