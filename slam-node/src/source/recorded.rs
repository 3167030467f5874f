//! Recorded scans (Oxford Radar RobotCar, Boreas, RADIATE) replayed by the simulator in
//! this process over TCP, read by the radar driver as a radar's would be, with odometry
//! made from the data set's ground truth ([`super::replay`]); the pipeline scores itself
//! against that truth and is built on the first azimuth, whose geometry chooses the
//! recorded radar's profile.

use std::time::Duration;

use radar_driver::DriverSettings;
use sim_sensor::{SimOptions, SimServer};
use tracing::info;

use super::embedded::{connect, SimRunning};
use super::replay::{
    replay_figures, MemoryOdometry, OdometryErrors, RecordedTruth, ReplayError, ReplayFigures,
    WHEELBASE_M,
};
use super::{Inputs, SourceError};
use crate::output::figures::TruthOverlay;
use crate::pipeline::run::PipelineStart;
use crate::pipeline::{Pipeline, SettingsRecipe, SourceFacts, TruthOracle};

/// A recording has played out when no azimuth has come for this long.
const PLAYED_OUT: Duration = Duration::from_secs(2);

/// Recorded scans to replay through the simulator, with their ground truth.
#[derive(Debug, Clone)]
pub struct RecordedReplay {
    /// The data set's folder (Oxford: `radar/` and `radar_odometry.csv`; Boreas: `radar/`
    /// and `applanix/radar_poses.csv`; RADIATE: `Navtech_Polar/`, `Navtech_Polar.txt` and
    /// `GPS_IMU_Twist*`).
    pub dir: std::path::PathBuf,
    /// Its layout (`None`: detected from the folder's contents).
    pub format: Option<sim_sensor::replay::ReplayFormat>,
    /// The errors put on the ground truth's motion to make the odometry.
    pub errors: OdometryErrors,
    /// Radar odometry with the odometry corrections estimated (see
    /// the radar profile's `radar_odometry`); `false` turns it off.
    pub radar_odometry: bool,
    /// Also write the odometry samples to this file (the odometry stream's format).
    pub write_odometry: Option<std::path::PathBuf>,
    /// No odometry: radar odometry drives the filter, and a recording without ground truth
    /// runs unscored (`--radar-only`).
    pub radar_only: bool,
    /// Radar only: a gyro made from the ground truth with this bias and noise
    /// (`--gyro-from-truth`).
    pub gyro_from_truth: Option<sim_sensor::gyro::GyroNoise>,
}

/// Replays recorded scans through the simulator's server, with odometry from their ground
/// truth; the pipeline scores itself against that truth.
pub async fn start(
    mut options: SimOptions,
    recorded: RecordedReplay,
    recipe: &SettingsRecipe,
    mut driver_settings: DriverSettings,
) -> Result<Inputs, SourceError> {
    let scans = sim_sensor::replay::ScanSet::open(&recorded.dir, recorded.format)
        .map_err(ReplayError::from)?;
    let truth = match RecordedTruth::read(&scans) {
        Ok(truth) => Some(truth),
        Err(error) if recorded.radar_only => {
            tracing::warn!(
                error = %radar_driver::ErrorChain(&error),
                "no usable ground truth in the recording: radar only, the run is not scored"
            );
            None
        }
        Err(error) => return Err(error.into()),
    };
    let (format, scan_dir) = (scans.format, scans.scan_dir.clone());
    let recording =
        sim_sensor::replay::ScanRecording::from_scans(scans).map_err(ReplayError::from)?;
    let geometry = recording.geometry;
    info!(
        %format,
        scans = recording.scans.files.len(),
        azimuths = geometry.azimuths,
        bins = geometry.bins,
        bin_m = geometry.bin_size_m,
        rotation_mhz = geometry.rotation_mhz,
        "recorded scans"
    );
    options.source = sim_sensor::settings::SourceSpec::PolarScans {
        dir: recorded.dir.clone(),
        format: Some(format),
    };
    options.odometry_bind = None;
    options.ground_truth_path = None;
    options.start_time_ns = None;
    // The recorded radar's profile is chosen from what the simulator announces for it, on
    // its first azimuth, as a radar's on a vehicle is; the odometry made from the ground
    // truth means the bicycle it was made with.
    let facts = SourceFacts {
        motion: Some(radar_model::motion::MotionModel::Bicycle {
            wheelbase_m: WHEELBASE_M,
        }),
        no_radar_odometry: !recorded.radar_odometry,
        radar_only: recorded.radar_only,
        gyro: recorded.radar_only && recorded.gyro_from_truth.is_some(),
        ..SourceFacts::default()
    };
    let announced = radar_model::profile::Announced {
        azimuths: geometry.azimuths,
        encoder_size: geometry.encoder_size,
        range_bins: geometry.bins,
        bin_size_m: geometry.bin_size_m,
        rotation_hz: f64::from(geometry.rotation_mhz) / 1000.0,
    };
    let expected = recipe
        .derive_quietly(
            radar_model::profile::select(recipe.config.radar.model.as_deref(), &announced)
                .map_err(crate::pipeline::settings::SettingsError::from)?,
            SourceFacts {
                max_range_m: Some(geometry.max_range_m()),
                ..facts.clone()
            },
        )?
        .settings;
    let samples = match truth.as_ref() {
        Some(truth) if !recorded.radar_only => truth.odometry(&recorded.errors),
        _ => Vec::new(),
    };
    if let Some(path) = &recorded.write_odometry {
        super::replay::write_odometry(path, &samples).map_err(|source| {
            ReplayError::WriteOdometry {
                path: path.clone(),
                source,
            }
        })?;
        info!(path = %path.display(), samples = samples.len(), "odometry written");
    }
    let mut figures = match truth.as_ref() {
        Some(truth) => replay_figures(truth, &samples, recorded.errors),
        None => ReplayFigures {
            errors: recorded.errors,
            distance_m: 0.0,
            dead_reckoning_rms_m: 0.0,
            dead_reckoning_final_m: 0.0,
            format: None,
            scans: recording.scans.files.len(),
            scans_skipped: 0,
            first_scan_skipped: None,
            doppler_range_coupling_s: 0.0,
            radar_only: true,
            ground_truth: false,
        },
    };
    figures.radar_only = recorded.radar_only;
    figures.format = Some(format.name());
    figures.doppler_range_coupling_s = expected.doppler_range_coupling_s;
    let truth_overlay = TruthOverlay {
        features: Vec::new(),
        trajectory: truth
            .iter()
            .flat_map(|truth| truth.times_s().iter().filter_map(|&t| truth.pose_at(t)))
            .map(|p| (p.x, p.y))
            .collect(),
    };
    let gyro: Option<Box<dyn super::gyro::GyroSource>> = match (
        recorded.gyro_from_truth,
        truth.as_ref(),
    ) {
        (Some(noise), Some(t)) if recorded.radar_only => {
            let times = t.times_s();
            let (start, end) = (
                times.first().copied().unwrap_or(0.0),
                times.last().copied().unwrap_or(0.0),
            );
            info!(
                bias_rad_s = noise.bias_rad_s,
                noise_density = noise.noise_density_rad_s_per_sqrt_hz,
                rate_hz = noise.rate_hz,
                "gyro made from the ground truth"
            );
            Some(Box::new(super::gyro::TruthGyro::new(
                Box::new(t.clone()),
                start,
                end,
                noise,
                recipe.config.sim.seed,
            )))
        }
        (Some(_), None) => {
            tracing::warn!("--gyro-from-truth: no ground truth, no gyro");
            None
        }
        _ => {
            if recipe.config.gyro.source != config::gyro::GyroSource::None {
                tracing::warn!("[gyro] source is not read in a replay of recorded scans: --gyro-from-truth makes one from the ground truth");
            }
            None
        }
    };
    let recipe = recipe.clone();
    let pipeline = PipelineStart::OnFirstAzimuth(Box::new(move |g: &protocol::Geometry| {
        let derived = recipe.for_radar(g, facts)?;
        Pipeline::new(
            derived.settings,
            None,
            truth.map(|t| Box::new(t) as Box<dyn TruthOracle>),
        )
    }));
    let fast = options.pacing == sim_sensor::settings::Pacing::AsFastAsPossible;
    let handle = SimServer::spawn(options).await?;
    info!(radar = %handle.local_addr(), scans = %scan_dir.display(), "replaying recorded scans");
    driver_settings.address = handle.local_addr();
    let (azimuths, driver) = connect(driver_settings, fast)?;
    // The recording has played out once the simulator's stream for the driver has ended.
    let stats = handle.shared_stats();
    Ok(Inputs {
        azimuths,
        driver: Some(driver),
        gyro,
        odometry: (!recorded.radar_only).then(|| {
            Box::new(MemoryOdometry::new(samples)) as Box<dyn radar_driver::OdometrySource>
        }),
        pipeline,
        motion: expected.motion,
        name: Some(format!("recorded {format} scans in {}", scan_dir.display())),
        truth_overlay,
        end_after_silence: Some(PLAYED_OUT),
        played_out: Some(Box::new(move || {
            stats
                .streams_ended
                .load(std::sync::atomic::Ordering::Relaxed)
                > 0
        })),
        replay: Some(figures),
        running: Box::new(SimRunning(handle)),
    })
}
