//! The pipeline without sockets or threads: azimuths and odometry handed in directly.
//! The azimuths are the simulator's: a scene rendered by `sim_sensor::render` and decoded
//! from the frames it sends.

mod support;

use radar_driver::Azimuth;
use sim_sensor::radar::RadarPreset;
use slam_filter::OdometrySample;
use slam_node::output::OutputEvent;
use slam_node::pipeline::{Pipeline, PipelineSettings};
use support::SimRadar;

/// Unix time of the first azimuth, nanoseconds.
const T0_NS: u64 = 1_700_000_000_000_000_000;
const T0: f64 = 1.7e9;

/// The four reflectors the still radar looks at, world metres.
const REFLECTORS: [(f64, f64); 4] = [(10.0, 5.0), (-8.0, 12.0), (20.0, -15.0), (-12.0, -9.0)];

fn settings() -> PipelineSettings {
    let mut s = PipelineSettings::from_config(&config::Config::default()).unwrap();
    s.detector = slam_node::detect::DetectorSettings::default();
    s.compensation = radar_model::compensation::Compensation::calibrated(
        40.0,
        &radar_model::power::RadarConstants::default(),
    );
    s.initial_pose_std = [0.0; 3];
    s
}

/// A stationary radar (the paper's unit: 200 azimuths of 800 bins) looking at four
/// reflectors; `rotations` rotations of azimuths, 8-bit as on the wire.
fn azimuths(rotations: u64) -> Vec<Azimuth> {
    let mut scene = support::empty_scene("four-reflectors", RadarPreset::Paper200, 5);
    for (x, y) in REFLECTORS {
        support::add_point(&mut scene, x, y, 0.5, 0.3);
    }
    let mut radar = SimRadar::new(&scene, None, rotations as f64 / 2.5 + 1.0, T0_NS);
    (0..rotations * radar.azimuths())
        .map(|k| radar.azimuth(k))
        .collect()
}

fn still(t: f64) -> OdometrySample {
    OdometrySample {
        timestamp_s: t,
        speed_mps: 0.0,
        steer_rad: 0.0,
    }
}

#[test]
fn without_odometry_every_beam_is_refused_and_nothing_is_mapped() {
    let mut p = Pipeline::new(settings(), None, None).unwrap();
    let mut events = Vec::new();
    for az in azimuths(6) {
        p.process_azimuth(&az, &mut events).unwrap();
    }
    let s = p.finish(&mut events);
    assert!(s.detections > 0);
    assert!(s.refused.no_odometry > 0);
    assert_eq!(s.beams, 0);
    assert_eq!(p.ekf().feature_count(), 0);
}

#[test]
fn with_odometry_a_still_radar_maps_its_four_reflectors_at_each_azimuths_time() {
    let mut p = Pipeline::new(settings(), Some(T0), None).unwrap();
    let mut events = Vec::new();
    let mut next_odometry = T0;
    let all = azimuths(8);
    for az in &all {
        while next_odometry <= az.timestamp_s + 0.05 {
            p.push_odometry(still(next_odometry));
            next_odometry += 0.05;
        }
        p.process_azimuth(az, &mut events).unwrap();
        // The filter never runs ahead of the azimuth being processed.
        assert!(p.ekf().state().time_s() <= az.timestamp_s + 1e-9);
    }
    let s = p.finish(&mut events);
    assert_eq!(s.rotations, 8);
    assert!(s.beams > 0);
    let features = p.ekf().features();
    for (x, y) in REFLECTORS {
        let nearest = features
            .iter()
            .map(|f| (f.x_m - x).hypot(f.y_m - y))
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < 1.0,
            "reflector at ({x}, {y}) mapped {nearest:.2} m away"
        );
    }
    let rotations = events
        .iter()
        .filter(|e| matches!(e, OutputEvent::Rotation(_)))
        .count();
    assert_eq!(rotations, 8, "one diagnostics record per rotation");
}

#[test]
fn malformed_azimuths_are_counted_and_skipped() {
    let mut p = Pipeline::new(settings(), Some(T0), None).unwrap();
    let mut events = Vec::new();
    let mut all = azimuths(1);
    let mut past_revolution = all[10].clone();
    past_revolution.encoder = 60_000;
    let mut nan_time = all[11].clone();
    nan_time.timestamp_s = f64::NAN;
    let mut backwards = all[12].clone();
    backwards.timestamp_s = T0 - 10.0;
    all.truncate(20);
    for az in &all {
        p.process_azimuth(az, &mut events).unwrap();
    }
    for az in [&past_revolution, &nan_time, &backwards] {
        p.process_azimuth(az, &mut events).unwrap();
    }
    assert_eq!(p.summary().bad_azimuths, 3);
}
