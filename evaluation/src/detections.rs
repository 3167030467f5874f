//! The daemon's detectors (`slam_node::detect`) scored against the simulator's truth:
//! spectra rendered by the simulator's own renderer (through [`World`]) with a shipped
//! scene's radar, receiver, noise and trajectory, and every detection checked against the
//! targets really in its beam ([`sim_sensor::render::RenderCursor::features_in_beam`]),
//! each with the peak it should raise over the mean floor (radar-model's eq. 13 powers and
//! the scene's own spectrum tables).
//!
//! [`score_detector`] runs CA-CFAR, OS-CFAR or TPP on the unquantised spectrum in dB;
//! [`score_learned`] runs the learned front end (`detect::learned` and `detect::line`) on
//! the wire's bins as the driver delivers them (8-bit, or 16-bit brought to the 8-bit scale
//! as the daemon does), the floor learned from the stream. The first three rotations are
//! warm-up (TPP learns its floor over scans) and are not scored.
//!
//! No IO: everything is rendered in memory from the scene and a seed.

use std::sync::Arc;

use bytes::BytesMut;
use protocol::{FrameDecoder, Geometry, Message};
use radar_driver::Azimuth;
use radar_model::power::PowerTarget;
use radar_model::spectrum::{beam_spectrum_targets, SpectrumModel, SpectrumTarget};
use sim_sensor::render::RenderCursor;
use sim_sensor::OdometryNoise;
use slam_node::detect::{
    BeamDetector, DetectorSettings, FloorProfile, LearnedFloor, LineDetector, LinePeak,
    LineSettings, RangeAxis,
};

use crate::error::EvalError;
use crate::world::World;

/// Detections within this of a true target's range hit it, metres (two range cells).
pub const TOL_M: f64 = 0.5;
/// Targets whose expected peak stands less than this over the mean floor are not scored.
pub const MIN_SNR_DB: f64 = 10.0;
/// Rotations of warm-up, not scored.
pub const WARMUP_ROTATIONS: u64 = 3;

/// A target really in one rendered beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueTarget {
    /// Range, metres (of the apparent position the beam was rendered with).
    pub range_m: f64,
    /// Expected peak height over the mean floor in the measured spectrum, dB.
    pub snr_db: f64,
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
    /// Rotations scored.
    pub rotations: u64,
}

impl DetectionScore {
    /// Probability of detection (0 without targets).
    pub fn pd(&self) -> f64 {
        if self.targets == 0 {
            0.0
        } else {
            self.hits as f64 / self.targets as f64
        }
    }

    /// False alarms per scored rotation.
    pub fn fa_per_rotation(&self) -> f64 {
        self.false_alarms as f64 / self.rotations.max(1) as f64
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

/// A shipped scene rendered azimuth by azimuth, with the truth of each beam.
struct TruthRadar {
    world: World,
    cursor: RenderCursor,
    spectrum: SpectrumModel,
    geometry: Arc<Geometry>,
    frame: BytesMut,
    decoder: FrameDecoder,
    targets: Vec<PowerTarget>,
    spectrum_targets: Vec<SpectrumTarget>,
}

impl TruthRadar {
    /// `scene_name` ready for `rotations` rotations with `seed`.
    fn new(scene_name: &str, rotations: u64, seed: u64) -> Result<Self, EvalError> {
        let scene = sim_sensor::scene::shipped::load(scene_name)?;
        let horizon_s = rotations as f64 / scene.radar.rotation_hz();
        let geometry = Arc::new(crate::daemon::geometry_of(&scene)?);
        let world = World::new(scene, seed, horizon_s, OdometryNoise::default())?;
        let spectrum = SpectrumModel::new(world.geometry, &world.compensation, world.noise)?;
        Ok(Self {
            cursor: world.cursor(),
            world,
            spectrum,
            geometry,
            frame: BytesMut::new(),
            decoder: FrameDecoder::new(),
            targets: Vec::new(),
            spectrum_targets: Vec::new(),
        })
    }

    /// The range axis of the rendered bins.
    fn axis(&self) -> RangeAxis {
        let g = self.spectrum.geometry();
        RangeAxis {
            first_bin_m: g.range_offset_m,
            bin_m: g.bin_size_m,
        }
    }

    /// Renders azimuth `index` and returns it as the driver would deliver it: decoded from
    /// the frame the simulator sends.
    fn azimuth(&mut self, index: u64) -> Result<Azimuth, EvalError> {
        let timestamp = self.world.azimuth_timestamp(index)?;
        self.frame.clear();
        self.cursor
            .render(index, (index % 65_536) as u16, timestamp, &mut self.frame)?;
        match self.decoder.decode_eof(&mut self.frame) {
            Ok(Some(Message::FftData(fft))) => {
                Ok(Azimuth::from_fft(fft, Arc::clone(&self.geometry)))
            }
            other => Err(EvalError::Setting(format!(
                "azimuth {index}: the rendered frame decoded as {other:?}"
            ))),
        }
    }

    /// Renders azimuth `index` and returns its spectrum in dB before quantisation.
    fn render_db(&mut self, index: u64) -> Result<&[f64], EvalError> {
        self.azimuth(index)?;
        Ok(self.cursor.last_power_db())
    }

    /// The targets really in azimuth `index`'s beam, nearest first, into `out` (cleared).
    fn true_targets(&mut self, index: u64, out: &mut Vec<TrueTarget>) -> Result<(), EvalError> {
        let hits = self.cursor.features_in_beam(index)?;
        self.targets.clear();
        for &(range_m, id) in &hits {
            let feature = self.world.feature(id).ok_or_else(|| {
                EvalError::Setting(format!("the renderer put unknown feature {id} in a beam"))
            })?;
            self.targets.push(PowerTarget {
                range_m,
                material: feature.material,
            });
        }
        beam_spectrum_targets(
            &self.world.power,
            &self.targets,
            self.world.renderer.loss_db(),
            &mut self.spectrum_targets,
        )?;
        let g = *self.spectrum.geometry();
        let gain = self.spectrum.gain_db();
        let floor = self.spectrum.floor_mean_db();
        out.clear();
        out.extend(self.spectrum_targets.iter().map(|t| {
            let bin = ((t.range_m - g.range_offset_m) / g.bin_size_m).round();
            let b = if bin.is_finite() && bin >= 0.0 {
                bin as usize
            } else {
                0
            };
            TrueTarget {
                range_m: t.range_m,
                snr_db: t.power_db + gain.get(b).copied().unwrap_or(0.0)
                    - floor.get(b).copied().unwrap_or(0.0),
            }
        }));
        Ok(())
    }
}

/// Scores the beam detector `settings` (CA-CFAR, OS-CFAR or TPP, in its domain) over
/// `rotations` rotations of the shipped scene `scene_name` rendered with `seed`.
pub fn score_detector(
    scene_name: &str,
    settings: DetectorSettings,
    rotations: u64,
    seed: u64,
) -> Result<DetectionScore, EvalError> {
    let mut radar = TruthRadar::new(scene_name, rotations, seed)?;
    let axis = radar.axis();
    let gain = radar.spectrum.gain_db().to_vec();
    let floor = FloorProfile::new(
        &radar.spectrum,
        &radar.spectrum.noise().absent,
        settings.floor_tail_pfa,
    );
    let n_az = radar.world.azimuths();
    let mut detector = BeamDetector::new(settings, n_az as usize);
    let (mut truth, mut found) = (Vec::new(), Vec::new());
    let mut score = DetectionScore {
        rotations: rotations.saturating_sub(WARMUP_ROTATIONS),
        ..DetectionScore::default()
    };
    for k in 0..rotations {
        for i in 0..n_az {
            let index = k * n_az + i;
            let measured = radar.render_db(index)?;
            found.clear();
            detector.detect(
                i as usize,
                measured,
                &gain,
                floor.floor(measured.len()),
                &axis,
                &mut found,
            );
            let ranges: Vec<f64> = found.iter().map(|d| d.range_m).collect();
            if k >= WARMUP_ROTATIONS {
                radar.true_targets(index, &mut truth)?;
                score.score_beam(&truth, &ranges, TOL_M, MIN_SNR_DB);
            }
        }
    }
    Ok(score)
}

/// As [`score_detector`] for the learned front end with `settings`' floor and peak
/// settings.
pub fn score_learned(
    scene_name: &str,
    settings: DetectorSettings,
    rotations: u64,
    seed: u64,
) -> Result<DetectionScore, EvalError> {
    let mut radar = TruthRadar::new(scene_name, rotations, seed)?;
    let axis = radar.axis();
    let line = LineSettings {
        merge_gap_bins: settings.peaks.merge_gap_bins,
        max_peaks: settings.peaks.max_peaks,
        min_range_m: settings.min_range_m,
        max_range_m: settings.max_range_m,
    };
    let mut floor = LearnedFloor::new(settings.floor, radar.spectrum.geometry().bins);
    let mut detector = LineDetector::new();
    let mut peaks: Vec<LinePeak> = Vec::new();
    let n_az = radar.world.azimuths();
    let (mut truth, mut eight) = (Vec::new(), Vec::<u8>::new());
    let mut score = DetectionScore {
        rotations: rotations.saturating_sub(WARMUP_ROTATIONS),
        ..DetectionScore::default()
    };
    for k in 0..rotations {
        for i in 0..n_az {
            let index = k * n_az + i;
            let az = radar.azimuth(index)?;
            eight.clear();
            match az.width {
                protocol::BinWidth::Eight => eight.extend_from_slice(&az.bins),
                protocol::BinWidth::Sixteen => {
                    eight.extend(az.bins_db().map(protocol::db_to_bin8));
                }
            }
            detector.detect(&eight, &mut floor, &axis, &line, &mut peaks);
            let ranges: Vec<f64> = peaks.iter().map(|p| axis.range_m(p.bin)).collect();
            if k >= WARMUP_ROTATIONS {
                radar.true_targets(index, &mut truth)?;
                score.score_beam(&truth, &ranges, TOL_M, MIN_SNR_DB);
            }
        }
    }
    Ok(score)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn target(range_m: f64, snr_db: f64) -> TrueTarget {
        TrueTarget { range_m, snr_db }
    }

    #[test]
    fn a_beam_counts_hits_misses_false_alarms_and_complete_multi_target_beams() {
        let mut s = DetectionScore {
            rotations: 2,
            ..DetectionScore::default()
        };
        // Two targets of interest, both found (one within the tolerance), one weak target
        // found (neither a target nor a false alarm), one detection near nothing.
        let truth = [target(10.0, 20.0), target(30.0, 15.0), target(50.0, 5.0)];
        s.score_beam(&truth, &[10.4, 30.0, 50.2, 70.0], TOL_M, MIN_SNR_DB);
        // Two targets of interest, one missed (0.6 m off is outside the tolerance).
        s.score_beam(&truth[..2], &[10.6, 30.1], TOL_M, MIN_SNR_DB);
        assert_eq!(
            (s.beams, s.targets, s.hits, s.false_alarms),
            (2, 4, 3, 2),
            "{s:?}"
        );
        assert_eq!((s.multi_target_beams, s.multi_target_complete), (2, 1));
        assert!((s.pd() - 0.75).abs() < 1e-12);
        assert!((s.fa_per_rotation() - 1.0).abs() < 1e-12);
        assert_eq!(DetectionScore::default().pd(), 0.0);
    }
}
