//! Where a run's observations come from.
//!
//! - [`TargetSource`]: every feature inside the beam, observed from the true pose with
//!   radar-model's eq. 3, 4, 13 and the noise the filter assumes (eq. 15). No detection, no
//!   clutter, exact labels: the setting in which the filter's own consistency is judged.
//!
//! Spectra go through the daemon's own pipeline instead (`crate::daemon`): no copy of its
//! detection or grouping lives here.

use radar_model::geometry::{features_in_beam, Beam, BeamHit, Pose2};
use radar_model::observation::{observe_beam, BeamFeature};
use rand_chacha::ChaCha8Rng;
use sim_sensor::render::RenderCursor;
use slam_filter::Target;

use crate::error::EvalError;
use crate::world::World;

/// A target with the true feature it came from (`None`: clutter or unmatched).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelledTarget {
    /// What the filter sees.
    pub target: Target,
    /// The scene id of the feature that produced it.
    pub label: Option<u32>,
}

/// One azimuth ready for the filter.
#[derive(Debug, Clone, PartialEq)]
pub struct AzimuthBeam {
    /// Azimuth index from the start of the run.
    pub index: u64,
    /// Its time (s).
    pub timestamp_s: f64,
    /// Its bearing (rad).
    pub bearing_rad: f64,
    /// The true pose at its time.
    pub truth: Pose2,
    /// The targets attributed to it.
    pub targets: Vec<LabelledTarget>,
}

/// Observations from the true pose with the filter's own noise model.
#[derive(Debug)]
pub struct TargetSource {
    rng: ChaCha8Rng,
    hits: Vec<BeamHit>,
    cursor: RenderCursor,
}

impl TargetSource {
    /// A source drawing noise from `seed`.
    pub fn new(world: &World, seed: u64) -> Self {
        Self {
            rng: radar_model::noise::seeded_rng(seed ^ 0x07A6_7E75),
            hits: Vec::new(),
            cursor: world.cursor(),
        }
    }

    /// The beam of azimuth `index`: every feature inside it, observed with noise.
    pub fn beam(&mut self, world: &World, index: u64) -> Result<AzimuthBeam, EvalError> {
        let truth = self.cursor.pose_at(world.azimuth_offset_ns(index))?;
        let bearing = world.bearing_rad(index);
        let radar = &world.scene.radar;
        let beam = Beam {
            bearing_rad: bearing,
            width_rad: radar.beam_width_rad,
            min_range_m: 0.5,
            max_range_m: radar.max_range_m(),
        };
        features_in_beam(
            &truth,
            &beam,
            world.features.iter().map(|f| f.xy),
            &mut self.hits,
        );
        let mut targets = Vec::with_capacity(self.hits.len());
        if !self.hits.is_empty() {
            let feats: Vec<BeamFeature> = self
                .hits
                .iter()
                .filter_map(|h| world.features.get(h.index))
                .map(|f| BeamFeature {
                    xy: f.xy,
                    material: f.material,
                })
                .collect();
            let obs = observe_beam(&truth, &feats, world.scene.loss_db, &world.power)?;
            for (z, h) in obs.z.iter().zip(&self.hits) {
                let zn = world.noise.perturb_observation(z.as_array(), &mut self.rng);
                targets.push(LabelledTarget {
                    target: Target {
                        range_m: zn[0],
                        bearing_rad: zn[1],
                        power_db: zn[2],
                    },
                    label: world.features.get(h.index).map(|f| f.id),
                });
            }
        }
        Ok(AzimuthBeam {
            index,
            timestamp_s: world.azimuth_time_s(index),
            bearing_rad: bearing,
            truth,
            targets,
        })
    }
}
