//! The pipeline without sockets or threads: azimuths and odometry handed in directly.

use std::sync::Arc;

use bytes::Bytes;
use protocol::{BinWidth, Geometry};
use radar_driver::Azimuth;
use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::material::Material;
use radar_model::noise::seeded_rng;
use radar_model::spectrum::quantize_8bit;
use slam_filter::OdometrySample;
use slam_node::output::OutputEvent;
use slam_node::pipeline::{Pipeline, PipelineSettings};
use slam_node::synth::{SynthFeature, SynthRadar};

const T0: f64 = 1.7e9;

fn geometry() -> Arc<Geometry> {
    Arc::new(Geometry {
        azimuth_samples: 200,
        range_in_bins: 800,
        bin_size_m: 0.25,
        encoder_size: 5600,
        rotation_hz: 2.5,
        packet_rate: 500,
        range_gain: 1.0,
        range_offset_m: 0.0,
        data_width: BinWidth::Eight,
        range_resolution_m: Some(0.25),
    })
}

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

/// A stationary radar looking at four reflectors; `rotations` rotations of azimuths.
fn azimuths(rotations: u64) -> Vec<Azimuth> {
    let g = geometry();
    let spectrum = radar_model::spectrum::SpectrumModel::new(
        radar_model::spectrum::SpectrumGeometry {
            bins: 800,
            bin_size_m: 0.25,
            range_offset_m: 0.0,
        },
        &settings().compensation,
        radar_model::noise::NoiseModel::default(),
    )
    .unwrap();
    let mut radar = SynthRadar::new(
        200,
        1.8f64.to_radians(),
        0.0,
        radar_model::power::PowerModel::default(),
        spectrum,
    );
    let world: Vec<SynthFeature> = [(10.0, 5.0), (-8.0, 12.0), (20.0, -15.0), (-12.0, -9.0)]
        .iter()
        .map(|&(x_m, y_m)| SynthFeature {
            x_m,
            y_m,
            material: Material::from_rho_alpha(0.5, 0.3).unwrap(),
        })
        .collect();
    let mut rng = seeded_rng(5);
    let (mut measured, mut truth) = (Vec::new(), Vec::new());
    let pose = Pose2::new(0.0, 0.0, 0.0);
    (0..rotations * 200)
        .map(|k| {
            let i = k % 200;
            let encoder = u16::try_from(i * 28).unwrap();
            let angle = f64::from(encoder) * std::f64::consts::TAU / 5600.0;
            radar
                .render(
                    &pose,
                    wrap_angle(angle),
                    &world,
                    &mut rng,
                    &mut measured,
                    &mut truth,
                )
                .unwrap();
            Azimuth {
                encoder,
                angle_rad: angle,
                timestamp_s: T0 + k as f64 / 500.0,
                sweep_counter: u16::try_from(k % 65536).unwrap(),
                width: BinWidth::Eight,
                bins: Bytes::from(
                    measured
                        .iter()
                        .map(|&p| quantize_8bit(p))
                        .collect::<Vec<u8>>(),
                ),
                geometry: Arc::clone(&g),
            }
        })
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
    for (x, y) in [(10.0, 5.0), (-8.0, 12.0), (20.0, -15.0), (-12.0, -9.0)] {
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
