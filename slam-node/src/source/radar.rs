//! The vehicle's radar over TCP: the radar driver dials `[radar] address`, the odometry
//! comes from `[odometry]` (or from Zenoh, opened by the daemon), and the pipeline is built
//! on the first azimuth, whose geometry chooses the radar's profile.

use radar_driver::{Driver, DriverSettings, OdometrySource, Shutdown};

use super::{Inputs, NothingRunning, SourceError};
use crate::output::figures::TruthOverlay;
use crate::pipeline::run::PipelineStart;
use crate::pipeline::{Pipeline, SettingsRecipe, SourceFacts};

/// The radar at `[radar] address`, with `odometry` (Zenoh's, opened by the daemon) or else
/// the configured odometry source.
pub fn open(
    recipe: SettingsRecipe,
    driver_settings: DriverSettings,
    odometry: Option<Box<dyn OdometrySource>>,
    odo_shutdown: Shutdown,
) -> Result<Inputs, SourceError> {
    let config = &recipe.config;
    let gyro = super::gyro::open_configured(
        &config.gyro,
        &tokio::runtime::Handle::current(),
        odo_shutdown.clone(),
    )?;
    let odometry = match odometry {
        Some(o) => Some(o),
        None => radar_driver::odometry::open_configured(
            &config.odometry,
            &tokio::runtime::Handle::current(),
            odo_shutdown,
        )?,
    };
    if odometry.is_none() {
        tracing::info!(
            "no odometry source ([odometry] source = \"none\"): radar odometry drives the filter's prediction (radar only)"
        );
    }
    let motion = crate::pipeline::settings::motion_model(config);
    let (driver, receivers) = Driver::new(driver_settings);
    let azimuths = receivers.azimuths.ok_or(SourceError::NoAzimuthChannel)?;
    Ok(Inputs {
        azimuths,
        driver: Some(driver),
        odometry,
        gyro,
        pipeline: PipelineStart::OnFirstAzimuth(Box::new(move |geometry: &protocol::Geometry| {
            let derived = recipe.for_radar(geometry, SourceFacts::default())?;
            Pipeline::new(derived.settings, None, None)
        })),
        motion,
        name: None,
        truth_overlay: TruthOverlay::default(),
        end_after_silence: None,
        played_out: None,
        replay: None,
        running: Box::new(NothingRunning),
    })
}
