//! Asserts what the daemon relies on from its default detector, on spectra rendered by the
//! simulator's own renderer (`sim_sensor::render`) with the scene's radar, receiver, noise
//! and trajectory, every detection checked against the targets really in its beam: it finds
//! both targets of the paper's penetration scenes down one beam, and on the outdoor field it
//! keeps most targets at a bounded false-alarm rate.
//!
//! The measurements (every detector over a sweep of thresholds, and the learned front end
//! against TPP) are an evaluation command:
//! `cargo run --release -p evaluation --bin detection_scoring`.

mod support;

use slam_node::detect::{BeamDetector, DetectorSettings, FloorProfile, RangeAxis};
use support::{SimRadar, TrueTarget};

/// Detections within this of a true target's range hit it, metres (two range cells).
const TOL_M: f64 = 0.5;
/// Targets whose expected peak stands less than this over the mean floor are not scored.
const MIN_SNR_DB: f64 = 10.0;

/// Counts of a detector's performance against truth.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct DetectionScore {
    /// True targets at or above the SNR of interest.
    targets: u64,
    /// Of those, detected (a detection within the range tolerance).
    hits: u64,
    /// Detections near no true target of the beam.
    false_alarms: u64,
    /// Beams scored.
    beams: u64,
    /// Beams that held two or more targets of interest.
    multi_target_beams: u64,
    /// Of those, beams where every target of interest was detected.
    multi_target_complete: u64,
}

impl DetectionScore {
    /// Probability of detection.
    fn pd(&self) -> f64 {
        if self.targets == 0 {
            0.0
        } else {
            self.hits as f64 / self.targets as f64
        }
    }

    /// Scores one beam: detections at `detected_m` against `truth`. Targets weaker than
    /// `min_snr_db` count neither as targets nor, when detected, as false alarms.
    fn score_beam(
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

struct Run {
    score: DetectionScore,
    rotations: u64,
}

impl Run {
    fn fa_per_rotation(&self) -> f64 {
        self.score.false_alarms as f64 / self.rotations.max(1) as f64
    }
}

fn run(scene_name: &str, settings: DetectorSettings, rotations: u64, seed: u64) -> Run {
    let scene = sim_sensor::scene::shipped::load(scene_name).expect("shipped scene");
    let horizon_s = rotations as f64 / scene.radar.rotation_hz() + 2.0;
    let mut radar = SimRadar::new(&scene, Some(seed), horizon_s, 0);
    let g = *radar.spectrum.geometry();
    let axis = RangeAxis {
        first_bin_m: g.range_offset_m,
        bin_m: g.bin_size_m,
    };
    let gain = radar.spectrum.gain_db().to_vec();
    let floor = FloorProfile::new(
        &radar.spectrum,
        &radar.spectrum.noise().absent,
        settings.floor_tail_pfa,
    );
    let n_az = radar.azimuths();
    let mut detector = BeamDetector::new(settings, n_az as usize);
    let (mut truth, mut found) = (Vec::<TrueTarget>::new(), Vec::new());
    let mut score = DetectionScore::default();
    for k in 0..rotations {
        for i in 0..n_az {
            let index = k * n_az + i;
            let measured = radar.render_db(index);
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
            // TPP needs a few scans to learn the floor: score it only once warm.
            if k >= 3 {
                radar.true_targets(index, &mut truth);
                score.score_beam(&truth, &ranges, TOL_M, MIN_SNR_DB);
            }
        }
    }
    Run {
        score,
        rotations: rotations.saturating_sub(3),
    }
}

#[test]
fn the_default_detector_finds_both_targets_down_the_penetration_beam() {
    for scene in ["penetration-wood", "penetration-perspex"] {
        let r = run(scene, DetectorSettings::default(), 10, 11);
        println!(
            "{scene}: Pd {:.3}, multi-target beams complete {}/{}, FA/rotation {:.2}",
            r.score.pd(),
            r.score.multi_target_complete,
            r.score.multi_target_beams,
            r.fa_per_rotation()
        );
        assert!(
            r.score.multi_target_beams > 0,
            "{scene}: no two-target beam scored"
        );
        let complete = r.score.multi_target_complete as f64 / r.score.multi_target_beams as f64;
        assert!(
            complete >= 0.9,
            "{scene}: both targets in only {complete:.2} of beams"
        );
    }
}

#[test]
fn the_default_detector_keeps_most_outdoor_field_targets_at_few_false_alarms() {
    let r = run("outdoor-field", DetectorSettings::default(), 12, 5);
    println!(
        "outdoor-field default: Pd {:.3} over {} targets, FA/rotation {:.2}",
        r.score.pd(),
        r.score.targets,
        r.fa_per_rotation()
    );
    assert!(r.score.pd() >= 0.8, "Pd {:.3}", r.score.pd());
    assert!(
        r.fa_per_rotation() <= 20.0,
        "FA/rotation {:.2}",
        r.fa_per_rotation()
    );
}
