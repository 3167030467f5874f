//! Synthetic rotations with known targets, rendered through radar-model exactly as the
//! simulator renders them (features inside each beam, eq. 13 powers, the receiver's
//! compensation, the book chapter's noise). Used to score the detectors against truth and
//! to drive benchmarks without a socket. No IO.

use radar_model::geometry::{features_in_beam, Beam, BeamHit, Pose2};
use radar_model::material::Material;
use radar_model::power::{PowerModel, PowerTarget};
use radar_model::spectrum::{beam_spectrum_targets, SpectrumModel, SpectrumTarget};
use radar_model::ModelError;
use rand::Rng;

/// A point feature of the synthetic world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthFeature {
    /// East, metres.
    pub x_m: f64,
    /// North, metres.
    pub y_m: f64,
    /// Material (u, v); rho, alpha and tau follow.
    pub material: Material,
}

/// A target that is really in one rendered beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueTarget {
    /// Index of the feature in the world.
    pub feature: usize,
    /// Range, metres.
    pub range_m: f64,
    /// Uncompensated power (eq. 13 - L), dB.
    pub power_db: f64,
    /// Expected peak height over the mean floor in the measured spectrum, dB.
    pub snr_db: f64,
}

/// A radar rendering synthetic spectra.
#[derive(Debug, Clone)]
pub struct SynthRadar {
    /// Spectra per rotation.
    pub azimuths: usize,
    /// Beam width, radians.
    pub beam_width_rad: f64,
    /// Radar loss L, dB.
    pub loss_db: f64,
    /// Power model (spreading form, constants, range resolution).
    pub power: PowerModel,
    /// Spectrum tables (geometry, compensation, noise).
    pub spectrum: SpectrumModel,
    hits: Vec<BeamHit>,
    targets: Vec<PowerTarget>,
    spectrum_targets: Vec<SpectrumTarget>,
}

impl SynthRadar {
    /// A radar of `azimuths` beams of `beam_width_rad`.
    pub fn new(
        azimuths: usize,
        beam_width_rad: f64,
        loss_db: f64,
        power: PowerModel,
        spectrum: SpectrumModel,
    ) -> Self {
        Self {
            azimuths,
            beam_width_rad,
            loss_db,
            power,
            spectrum,
            hits: Vec::new(),
            targets: Vec::new(),
            spectrum_targets: Vec::new(),
        }
    }

    /// Bearing of azimuth `index` (clockwise from forward, wrapped).
    pub fn bearing_rad(&self, index: usize) -> f64 {
        radar_model::geometry::wrap_angle(
            std::f64::consts::TAU * index as f64 / self.azimuths.max(1) as f64,
        )
    }

    /// Renders one measured spectrum (dB, compensation applied, noisy) seen from `pose`
    /// along `bearing_rad` into `out` (resized to the geometry's bins); the targets really
    /// in the beam go to `truth` (cleared first).
    pub fn render<R: Rng + ?Sized>(
        &mut self,
        pose: &Pose2,
        bearing_rad: f64,
        world: &[SynthFeature],
        rng: &mut R,
        out: &mut Vec<f64>,
        truth: &mut Vec<TrueTarget>,
    ) -> Result<(), ModelError> {
        let g = *self.spectrum.geometry();
        out.resize(g.bins, 0.0);
        let max_range = g.bin_range_m(g.bins);
        let beam = Beam {
            bearing_rad,
            width_rad: self.beam_width_rad,
            min_range_m: 0.5,
            max_range_m: max_range,
        };
        features_in_beam(
            pose,
            &beam,
            world.iter().map(|f| [f.x_m, f.y_m]),
            &mut self.hits,
        );
        self.targets.clear();
        self.targets.extend(self.hits.iter().filter_map(|h| {
            world.get(h.index).map(|f| PowerTarget {
                range_m: h.range_m,
                material: f.material,
            })
        }));
        beam_spectrum_targets(
            &self.power,
            &self.targets,
            self.loss_db,
            &mut self.spectrum_targets,
        )?;
        self.spectrum
            .synthesize_into(&self.spectrum_targets, rng, out)?;
        truth.clear();
        for (h, t) in self.hits.iter().zip(&self.spectrum_targets) {
            let bin = ((t.range_m - g.range_offset_m) / g.bin_size_m).round();
            let b = if bin.is_finite() && bin >= 0.0 {
                bin as usize
            } else {
                0
            };
            let gain = self.spectrum.gain_db().get(b).copied().unwrap_or(0.0);
            let floor = self.spectrum.floor_mean_db().get(b).copied().unwrap_or(0.0);
            truth.push(TrueTarget {
                feature: h.index,
                range_m: t.range_m,
                power_db: t.power_db,
                snr_db: t.power_db + gain - floor,
            });
        }
        Ok(())
    }
}

/// Counts of a detector's performance against truth.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DetectionScore {
    /// True targets at or above the SNR of interest.
    pub targets: u64,
    /// Of those, detected (a detection within the range tolerance).
    pub hits: u64,
    /// Detections near no true target of the beam.
    pub false_alarms: u64,
    /// Beams scored.
    pub beams: u64,
    /// Beams that held two or more targets of interest.
    pub multi_target_beams: u64,
    /// Of those, beams where every target of interest was detected.
    pub multi_target_complete: u64,
}

impl DetectionScore {
    /// Probability of detection.
    pub fn pd(&self) -> f64 {
        if self.targets == 0 {
            0.0
        } else {
            self.hits as f64 / self.targets as f64
        }
    }

    /// Scores one beam: detections at `detected_m` against `truth`. Targets weaker than
    /// `min_snr_db` count neither as targets nor, when detected, as false alarms.
    pub fn score_beam(
        &mut self,
        truth: &[TrueTarget],
        detected_m: &[f64],
        tol_m: f64,
        min_snr_db: f64,
    ) {
        self.beams += 1;
        let mut of_interest = 0;
        let mut complete = true;
        for t in truth {
            if t.snr_db < min_snr_db {
                continue;
            }
            of_interest += 1;
            self.targets += 1;
            if detected_m.iter().any(|&d| (d - t.range_m).abs() <= tol_m) {
                self.hits += 1;
            } else {
                complete = false;
            }
        }
        if of_interest >= 2 {
            self.multi_target_beams += 1;
            if complete {
                self.multi_target_complete += 1;
            }
        }
        for &d in detected_m {
            if !truth.iter().any(|t| (d - t.range_m).abs() <= tol_m) {
                self.false_alarms += 1;
            }
        }
    }
}

/// The simulator's scene as a synthetic radar and world: the same radar geometry, receiver
/// compensation, spreading form, noise and loss that `sim-sensor` renders with.
pub fn from_scene(
    scene: &sim_sensor::scene::Scene,
) -> Result<(SynthRadar, Vec<SynthFeature>), ModelError> {
    use radar_model::compensation::Compensation;
    use radar_model::noise::NoiseModel;
    use radar_model::power::{RadarConstants, SpreadingForm};
    use radar_model::spectrum::SpectrumGeometry;

    let r = &scene.radar;
    let geometry = SpectrumGeometry {
        bins: usize::from(r.range_bins),
        bin_size_m: f64::from(r.range_gain) * r.bin_size_m(),
        range_offset_m: f64::from(r.range_offset_m),
    };
    let constants = RadarConstants::default();
    let compensation =
        Compensation::calibrated(scene.receiver.compensation_db_per_decade, &constants);
    let mut noise = NoiseModel::default();
    // The simulator draws each peak one bin wide (FWHM).
    noise.range.resolution_fwhm_m = geometry.bin_size_m;
    if scene.noise.enabled {
        noise.present.variance_db2 = scene.noise.target_power_variance_db2;
        noise.range.phase_noise_sigma_m = scene.noise.range_sigma_m;
    } else {
        noise.present.variance_db2 = 0.0;
        noise.range.phase_noise_sigma_m = 0.0;
    }
    let power = PowerModel {
        form: match scene.receiver.spreading {
            sim_sensor::scene::Spreading::Paper => SpreadingForm::Paper,
            sim_sensor::scene::Spreading::Textbook => SpreadingForm::Textbook,
        },
        constants,
        ..PowerModel::default()
    };
    let spectrum = SpectrumModel::new(geometry, &compensation, noise)?;
    let world = scene
        .features
        .iter()
        .map(|f| {
            Material::from_rho_alpha(f.rho, f.alpha).map(|material| SynthFeature {
                x_m: f.x_m,
                y_m: f.y_m,
                material,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok((
        SynthRadar::new(
            usize::from(r.azimuths),
            r.beam_width_rad,
            scene.loss_db,
            power,
            spectrum,
        ),
        world,
    ))
}
