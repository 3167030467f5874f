//! When the pipeline builds a saved map (`[map]`): the settings, shared by the pipeline's
//! settings and the saved-map step. No IO.

/// When the pipeline builds a saved map (`[map]`).
#[derive(Debug, Clone, PartialEq)]
pub struct MapSaveSettings {
    /// Build one at the end of the run.
    pub enabled: bool,
    /// And every this many seconds of the run's clock.
    pub every_s: Option<f64>,
    /// The radar profile's name recorded in the map: the profile the settings were derived
    /// from; for settings built from a configuration alone, `[radar] model` or, without it,
    /// the paper's unit (whose values the configuration's defaults are).
    pub profile: String,
}

impl MapSaveSettings {
    /// From `[map]` and `[radar] model`.
    pub fn from_config(c: &config::Config) -> Self {
        Self {
            enabled: c.map.save,
            every_s: c.map.save_every_s,
            profile: c
                .radar
                .model
                .clone()
                .unwrap_or_else(|| radar_model::profile::PAPER_2006.name.into()),
        }
    }
}
