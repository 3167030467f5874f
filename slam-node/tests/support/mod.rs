//! Test and benchmark support: rotations rendered by the simulator's own renderer
//! (`sim_sensor::render`), not by a copy of its physics.
//!
//! [`SimRadar`] renders a scene's azimuths with a [`RenderCursor`] into Colossus FFT frames,
//! decodes them as a client does and hands them out as [`radar_driver::Azimuth`]s; the
//! unquantised spectrum of the last azimuth stays readable in dB. For scoring detectors it
//! lists the targets really in a beam ([`RenderCursor::features_in_beam`]) with the peak each
//! should raise over the mean floor, from radar-model's eq. 13 powers and the scene's own
//! spectrum tables.
//!
//! Shared by several test targets and a benchmark, each using a different part of it.
#![allow(dead_code)]

use std::collections::HashMap;
use std::sync::Arc;

use bytes::BytesMut;
use protocol::{FrameDecoder, Geometry, Message, Timestamp};
use radar_driver::Azimuth;
use radar_model::material::Material;
use radar_model::power::{PowerModel, PowerTarget};
use radar_model::spectrum::{beam_spectrum_targets, SpectrumModel, SpectrumTarget};
use sim_sensor::radar::{RadarParams, RadarPreset};
use sim_sensor::render::{physics, RenderCursor, SceneRenderer};
use sim_sensor::scene::{Feature, FeatureKind, MotionSpec, NoiseSpec, ReceiverSpec, Scene};
use sim_sensor::schedule::ControlSchedule;

/// A target that is really in one rendered beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueTarget {
    /// The feature's id in the scene.
    pub feature: u32,
    /// Range, metres (of the apparent position the beam was rendered with).
    pub range_m: f64,
    /// Uncompensated power (eq. 13 - L), dB.
    pub power_db: f64,
    /// Expected peak height over the mean floor in the measured spectrum, dB.
    pub snr_db: f64,
}

/// A scene with `preset`'s radar, the simulator's default noise and receiver, no features,
/// and a vehicle standing still at the origin facing +x.
pub fn empty_scene(name: &str, preset: RadarPreset, seed: u64) -> Scene {
    Scene {
        name: name.to_string(),
        description: String::new(),
        seed,
        radar: preset.params(),
        preset,
        noise: NoiseSpec::default(),
        receiver: ReceiverSpec::default(),
        loss_db: 0.0,
        motion: MotionSpec::default(),
        start: [0.0, 0.0, 0.0],
        start_time_ns: None,
        schedule: ControlSchedule::stationary(),
        features: Vec::new(),
        realism: None,
        objects: Vec::new(),
        city: None,
    }
}

/// Appends a point feature of material `(rho, alpha)` at `(x_m, y_m)` with the next id.
pub fn add_point(scene: &mut Scene, x_m: f64, y_m: f64, rho: f64, alpha: f64) {
    let id = u32::try_from(scene.features.len()).expect("feature count fits u32");
    scene.features.push(Feature {
        id,
        kind: FeatureKind::Reflector,
        x_m,
        y_m,
        rho,
        alpha,
    });
}

/// The geometry a client derives from the configuration message a simulated radar with
/// `radar` announces.
pub fn client_geometry(radar: &RadarParams) -> Geometry {
    radar
        .configuration()
        .geometry()
        .expect("a validated radar makes a valid geometry")
}

/// The simulator rendering one scene, azimuth by azimuth.
#[derive(Debug)]
pub struct SimRadar {
    renderer: Arc<SceneRenderer>,
    cursor: RenderCursor,
    /// The spectrum tables the scene renders with (receiver gain, mean floor, noise).
    pub spectrum: SpectrumModel,
    power: PowerModel,
    materials: HashMap<u32, Material>,
    /// The geometry a client of this radar works with.
    pub geometry: Arc<Geometry>,
    start_unix_ns: u64,
    frame: BytesMut,
    decoder: FrameDecoder,
    targets: Vec<PowerTarget>,
    spectrum_targets: Vec<SpectrumTarget>,
}

impl SimRadar {
    /// Prepares `scene` for rendering up to `horizon_s` (later azimuths still render, the
    /// trajectory integrating on), with `seed` overriding the scene's; azimuth 0 is
    /// stamped `start_unix_ns`.
    pub fn new(scene: &Scene, seed: Option<u64>, horizon_s: f64, start_unix_ns: u64) -> Self {
        let renderer = Arc::new(SceneRenderer::new(scene, seed, horizon_s).expect("scene renders"));
        let cursor = renderer.cursor();
        let (power, compensation, noise, geometry) = physics(scene);
        let spectrum = SpectrumModel::new(geometry, &compensation, noise).expect("spectrum tables");
        let materials = scene
            .features
            .iter()
            .map(|f| {
                let m = Material::from_rho_alpha(f.rho, f.alpha).expect("valid material");
                (f.id, m)
            })
            .collect();
        Self {
            geometry: Arc::new(client_geometry(&scene.radar)),
            renderer,
            cursor,
            spectrum,
            power,
            materials,
            start_unix_ns,
            frame: BytesMut::new(),
            decoder: FrameDecoder::new(),
            targets: Vec::new(),
            spectrum_targets: Vec::new(),
        }
    }

    /// Azimuths per rotation.
    pub fn azimuths(&self) -> u64 {
        u64::from(self.renderer.radar().azimuths)
    }

    /// Unix time of azimuth `index`, nanoseconds.
    pub fn unix_ns(&self, index: u64) -> u64 {
        self.start_unix_ns + self.renderer.offset_ns(index)
    }

    /// Renders azimuth `index` (counted from the scene's first) and returns it as the
    /// driver would deliver it: decoded from the frame the simulator sends.
    pub fn azimuth(&mut self, index: u64) -> Azimuth {
        let ns = self.unix_ns(index);
        let timestamp = Timestamp::new(
            u32::try_from(ns / 1_000_000_000).expect("time before 2106"),
            u32::try_from(ns % 1_000_000_000).expect("nanoseconds"),
        )
        .expect("timestamp");
        self.frame.clear();
        self.cursor
            .render(index, (index % 65_536) as u16, timestamp, &mut self.frame)
            .expect("render");
        match self.decoder.decode_eof(&mut self.frame) {
            Ok(Some(Message::FftData(fft))) => Azimuth {
                // As the driver numbers rotations.
                rotation: index / self.azimuths(),
                ..Azimuth::from_fft(fft, Arc::clone(&self.geometry))
            },
            other => panic!("azimuth {index}: the rendered frame decoded as {other:?}"),
        }
    }

    /// Renders azimuth `index` and returns its spectrum in dB before quantisation.
    pub fn render_db(&mut self, index: u64) -> &[f64] {
        let _ = self.azimuth(index);
        self.cursor.last_power_db()
    }

    /// The targets really in azimuth `index`'s beam, nearest first, into `out` (cleared).
    pub fn true_targets(&mut self, index: u64, out: &mut Vec<TrueTarget>) {
        let hits = self.cursor.features_in_beam(index).expect("beam");
        self.targets.clear();
        self.targets
            .extend(hits.iter().map(|&(range_m, id)| PowerTarget {
                range_m,
                material: self.materials[&id],
            }));
        beam_spectrum_targets(
            &self.power,
            &self.targets,
            self.renderer.loss_db(),
            &mut self.spectrum_targets,
        )
        .expect("eq. 13 powers");
        let g = *self.spectrum.geometry();
        let gain = self.spectrum.gain_db();
        let floor = self.spectrum.floor_mean_db();
        out.clear();
        out.extend(
            hits.iter()
                .zip(&self.spectrum_targets)
                .map(|(&(_, id), t)| {
                    let bin = ((t.range_m - g.range_offset_m) / g.bin_size_m).round();
                    let b = if bin.is_finite() && bin >= 0.0 {
                        bin as usize
                    } else {
                        0
                    };
                    TrueTarget {
                        feature: id,
                        range_m: t.range_m,
                        power_db: t.power_db,
                        snr_db: t.power_db + gain.get(b).copied().unwrap_or(0.0)
                            - floor.get(b).copied().unwrap_or(0.0),
                    }
                }),
        );
    }
}

/// The four reflectors the still radar of the pipeline tests looks at, world metres.
pub const REFLECTORS: [(f64, f64); 4] = [(10.0, 5.0), (-8.0, 12.0), (20.0, -15.0), (-12.0, -9.0)];

/// Asserts that at least three of [`REFLECTORS`] have a feature of `ekf` within 1 m (a
/// parked radar's map churns: one of the four may be between retirement and re-mapping).
pub fn assert_reflectors_mapped(ekf: &slam_node::pipeline::DaemonEkf) {
    let features = ekf.features();
    let mapped = REFLECTORS
        .iter()
        .filter(|&&(x, y)| features.iter().any(|f| (f.x_m - x).hypot(f.y_m - y) < 1.0))
        .count();
    assert!(
        mapped >= 3,
        "{mapped} reflectors mapped within 1 m: {features:?}"
    );
}

/// The daemon's shipped settings with slam-node's measured detector, the simulator's
/// 40 dB/decade receiver, and an exactly known start pose.
pub fn still_radar_settings() -> slam_node::pipeline::PipelineSettings {
    let mut s = slam_node::pipeline::PipelineSettings::from_config(&config::Config::default())
        .expect("the shipped configuration converts");
    s.detector = slam_node::detect::DetectorSettings::default();
    s.compensation = radar_model::compensation::Compensation::calibrated(
        40.0,
        &radar_model::power::RadarConstants::default(),
    );
    s.initial_pose_std = [0.0; 3];
    s
}

/// A stationary radar (the paper's unit: 200 azimuths of 800 bins) looking at
/// [`REFLECTORS`]; `rotations` rotations of azimuths from `t0_ns`, 8-bit as on the wire.
pub fn still_radar_azimuths(rotations: u64, t0_ns: u64) -> Vec<Azimuth> {
    let mut scene = empty_scene("four-reflectors", RadarPreset::Paper200, 5);
    for (x, y) in REFLECTORS {
        add_point(&mut scene, x, y, 0.5, 0.3);
    }
    let mut radar = SimRadar::new(&scene, None, rotations as f64 / 2.5 + 1.0, t0_ns);
    (0..rotations * radar.azimuths())
        .map(|k| radar.azimuth(k))
        .collect()
}

/// Odometry of a parked vehicle at `t` (s).
pub fn still(t: f64) -> slam_filter::OdometrySample {
    slam_filter::OdometrySample {
        timestamp_s: t,
        speed_mps: 0.0,
        steer_rad: 0.0,
    }
}

/// Runs the pipeline thread's loop as the daemon does over `azimuths` (all queued before it
/// starts) with `odometry` behind the seam, writing its outputs, figures off, to a temporary
/// folder that is gone when it returns.
pub fn run_queued(
    pipeline: slam_node::pipeline::Pipeline,
    azimuths: Vec<Azimuth>,
    odometry: Box<dyn radar_driver::OdometrySource>,
    control: slam_node::pipeline::RunControl,
) -> slam_node::pipeline::RunReport {
    let (tx, rx) = crossbeam_channel::bounded(azimuths.len().max(1));
    for az in azimuths {
        tx.send(az).expect("room");
    }
    drop(tx);
    let dir = tempfile::tempdir().expect("tempdir");
    let mut files = slam_node::output::OutputFiles::in_dir(dir.path().to_path_buf());
    files.figures = false;
    let output = slam_node::output::OutputHandle::spawn(files).expect("writer");
    let report = slam_node::pipeline::run_pipeline(
        pipeline,
        slam_node::pipeline::PipelineInputs {
            azimuths: rx,
            odometry: Some(odometry),
            gyro: None,
            priors: None,
        },
        &output,
        control,
    );
    drop(output);
    report
}

/// The daemon's options for a run of the embedded simulator `sim` under `config`, for
/// `max_stream_s` of stream, outputs in `out`: no figures, no progress lines, the default
/// detector.
pub fn embedded_options(
    config: config::Config,
    sim: sim_sensor::SimOptions,
    out: &std::path::Path,
    max_stream_s: f64,
) -> slam_node::daemon::DaemonOptions {
    slam_node::daemon::DaemonOptions {
        config,
        simulator: Some(slam_node::daemon::Simulator {
            sim: slam_node::daemon::EmbeddedSim::new(sim),
            recorded: None,
        }),
        mcap: None,
        max_stream_s: Some(max_stream_s),
        out_dir: out.to_path_buf(),
        figures: false,
        progress_every_rotations: 0,
        stop: Arc::new(std::sync::atomic::AtomicBool::new(false)),
        keep_configured_compensation: false,
        spectrum_bearings_deg: Vec::new(),
        detector: Some(slam_node::detect::DetectorSettings::default()),
        written: None,
    }
}
