//! The pipeline without sockets or threads: azimuths and odometry handed in directly.
//! The azimuths are the simulator's: a scene rendered by `sim_sensor::render` and decoded
//! from the frames it sends.

mod support;

use support::{still, still_radar_settings as settings, REFLECTORS};

use slam_node::output::OutputEvent;
use slam_node::pipeline::Pipeline;

/// Unix time of the first azimuth, nanoseconds.
const T0_NS: u64 = 1_700_000_000_000_000_000;
const T0: f64 = 1.7e9;

#[test]
fn without_odometry_every_beam_is_refused_and_nothing_is_mapped() {
    let mut p = Pipeline::new(settings(), None, None).unwrap();
    let mut events = Vec::new();
    for az in support::still_radar_azimuths(6, T0_NS) {
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
    let all = support::still_radar_azimuths(8, T0_NS);
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
    let mut all = support::still_radar_azimuths(1, T0_NS);
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
