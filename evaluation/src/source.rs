//! Where a run's observations come from.
//!
//! - [`TargetSource`]: every feature inside the beam, observed from the true pose with
//!   radar-model's eq. 3, 4, 13 and the noise the filter assumes (eq. 15). No detection, no
//!   clutter, exact labels: the setting in which the filter's own consistency is judged.
//! - [`SpectrumSource`]: the whole pipeline the daemon runs: the simulator renders each
//!   azimuth's spectrum (its physics, noise floor, phase noise, bearing error), quantised to
//!   the 8-bit wire; slam-node's detector finds the targets with the compensation removed;
//!   its grouper turns detections in neighbouring azimuths into one observation per
//!   target. Labels are found afterwards by matching each observation to the nearest true
//!   feature in range and bearing.

use std::collections::VecDeque;

use bytes::BytesMut;
use protocol::Timestamp;
use radar_model::geometry::{features_in_beam, range_bearing, wrap_angle, Beam, BeamHit, Pose2};
use radar_model::observation::{observe_beam, BeamFeature};
use radar_model::spectrum::quantize_8bit;
use radar_model::spectrum::{SpectrumGeometry, SpectrumModel};
use rand_chacha::ChaCha8Rng;
use sim_sensor::render::RenderCursor;
use slam_filter::Target;
use slam_node::detect::{
    BeamDetection, BeamDetector, Detection, FloorProfile, Grouper, GroupingSettings, Observation,
    RangeAxis,
};

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

/// Detections of consecutive azimuths grouped into one observation per target (slam-node's
/// grouper), each observation attached to the azimuth of its timestamp, azimuths handed on
/// in order once no open group can still attach to them.
#[derive(Debug)]
pub struct BeamAssembler {
    grouper: Grouper,
    handoff: Vec<BeamDetection>,
    ready: Vec<Observation>,
    /// Azimuths seen but not yet final (a group may still close onto them).
    queue: VecDeque<AzimuthBeam>,
    lag: usize,
}

impl BeamAssembler {
    /// An assembler with `grouping` settings.
    pub fn new(grouping: GroupingSettings) -> Self {
        let steps = (grouping.max_width_rad / grouping.max_step_rad * 1.5).ceil();
        let lag = if steps.is_finite() && steps > 0.0 {
            // A small positive count of azimuths.
            steps as usize + 2
        } else {
            8
        };
        Self {
            grouper: Grouper::new(grouping),
            handoff: Vec::new(),
            ready: Vec::new(),
            queue: VecDeque::new(),
            lag,
        }
    }

    /// Adds one azimuth (with no targets yet) and its detections.
    pub fn push(&mut self, beam: AzimuthBeam, detections: &[Detection]) {
        self.handoff.clear();
        self.handoff
            .extend(detections.iter().map(|d| BeamDetection {
                range_m: d.range_m,
                power_db: d.power_db,
            }));
        self.grouper.push(
            beam.bearing_rad,
            beam.timestamp_s,
            &self.handoff,
            &mut self.ready,
        );
        self.queue.push_back(beam);
    }

    /// Moves the released observations onto their azimuths, and hands back the azimuths
    /// that can no longer receive any (all of them when `flush`).
    pub fn take_final(&mut self, flush: bool, out: &mut Vec<AzimuthBeam>) {
        if flush {
            self.grouper.flush(&mut self.ready);
        }
        for o in self.ready.drain(..) {
            let target = LabelledTarget {
                target: Target {
                    range_m: o.range_m,
                    bearing_rad: o.bearing_rad,
                    power_db: o.power_db,
                },
                label: None,
            };
            match self
                .queue
                .iter_mut()
                .find(|b| b.timestamp_s == o.timestamp_s)
            {
                Some(b) => b.targets.push(target),
                // Released for an azimuth already handed on (a group wider than the lag):
                // attach it to the oldest one still held, so it is not lost.
                None => {
                    if let Some(b) = self.queue.front_mut() {
                        b.targets.push(target);
                    }
                }
            }
        }
        let keep = if flush { 0 } else { self.lag };
        while self.queue.len() > keep {
            if let Some(b) = self.queue.pop_front() {
                out.push(b);
            }
        }
    }
}

/// The detection pipeline on rendered spectra.
#[derive(Debug)]
pub struct SpectrumSource {
    cursor: RenderCursor,
    detector: BeamDetector,
    floor: FloorProfile,
    assembler: BeamAssembler,
    bin_stride: usize,
    axis: RangeAxis,
    gain_db: Vec<f64>,
    measured_db: Vec<f64>,
    frame: BytesMut,
    detections: Vec<Detection>,
    rendered: Option<AzimuthBeam>,
    sweep: u16,
}

/// Grouping settings for a radar of `azimuths` per rotation, beam `beam_width_rad`, bins of
/// `bin_m`, processing every `stride`-th azimuth.
pub fn grouping_for(
    azimuths: u64,
    beam_width_rad: f64,
    bin_m: f64,
    stride: usize,
) -> GroupingSettings {
    let step = std::f64::consts::TAU / azimuths.max(1) as f64 * stride.max(1) as f64;
    GroupingSettings {
        range_gate_m: (3.0 * bin_m).max(0.75),
        max_step_rad: 1.5 * step,
        max_width_rad: (4.0 * step).max(2.5 * beam_width_rad),
    }
}

impl SpectrumSource {
    /// A pipeline with `detector` settings, keeping every `bin_stride`-th bin (the strongest
    /// of each group of `bin_stride`), processing every `azimuth_stride`-th azimuth.
    pub fn new(
        world: &World,
        settings: &crate::run::SpectraSettings,
        bin_stride: usize,
        azimuth_stride: usize,
    ) -> Result<Self, EvalError> {
        let detector = settings.detector;
        if bin_stride == 0 || azimuth_stride == 0 {
            return Err(EvalError::Setting("strides must be at least 1".into()));
        }
        let g = world.geometry;
        let bins = g.bins / bin_stride;
        // The decimated bin k covers bins [k s, k s + s); its range is the group's centre.
        let axis = RangeAxis {
            first_bin_m: g.range_offset_m + 0.5 * (bin_stride as f64 - 1.0) * g.bin_size_m,
            bin_m: g.bin_size_m * bin_stride as f64,
        };
        let gain_db = (0..bins)
            .map(|k| settings.compensation.gain_db(axis.range_m(k as f64)))
            .collect();
        let step = std::f64::consts::TAU / world.azimuths().max(1) as f64 * azimuth_stride as f64;
        let grouping = GroupingSettings {
            range_gate_m: settings.grouping_range_gate_m.max(1.5 * axis.bin_m),
            max_step_rad: 1.5 * step,
            max_width_rad: (settings.grouping_max_width_beams * world.scene.radar.beam_width_rad)
                .max(step),
        };
        let az = usize::try_from(world.azimuths()).unwrap_or(usize::MAX);
        let decimated = SpectrumGeometry {
            bins,
            bin_size_m: axis.bin_m,
            range_offset_m: axis.first_bin_m,
        };
        let model = SpectrumModel::new(decimated, &settings.compensation, settings.noise)?;
        Ok(Self {
            floor: FloorProfile::new(&model, &settings.noise.absent, detector.floor_tail_pfa),
            cursor: world.cursor(),
            detector: BeamDetector::new(detector, az),
            assembler: BeamAssembler::new(grouping),
            bin_stride,
            axis,
            gain_db,
            measured_db: Vec::with_capacity(bins),
            frame: BytesMut::new(),
            detections: Vec::new(),
            rendered: None,
            sweep: 0,
        })
    }

    /// Renders azimuth `index` (not timed: the radar's work, not ours).
    pub fn render(&mut self, world: &World, index: u64) -> Result<(), EvalError> {
        let offset = world.azimuth_offset_ns(index);
        let secs = u32::try_from(1_700_000_000 + offset / 1_000_000_000).unwrap_or(u32::MAX);
        let nanos = u32::try_from(offset % 1_000_000_000).unwrap_or(0);
        let ts = Timestamp::new(secs, nanos)
            .map_err(|e| EvalError::Setting(format!("timestamp: {e}")))?;
        self.frame.clear();
        let rendered = self.cursor.render(index, self.sweep, ts, &mut self.frame)?;
        self.sweep = self.sweep.wrapping_add(1);
        // What the wire carries: 8-bit bins, 0.5 dB steps; then bin decimation by max.
        let s = self.bin_stride;
        self.measured_db.clear();
        for chunk in self.cursor.last_power_db().chunks_exact(s) {
            let best = chunk
                .iter()
                .map(|&p| f64::from(quantize_8bit(p)) * 0.5)
                .fold(f64::NEG_INFINITY, f64::max);
            self.measured_db.push(best);
        }
        self.rendered = Some(AzimuthBeam {
            index,
            timestamp_s: world.azimuth_time_s(index),
            bearing_rad: world.bearing_rad(index),
            truth: rendered.pose,
            targets: Vec::new(),
        });
        Ok(())
    }

    /// Detects and groups the last rendered azimuth (the timed part of the pipeline).
    pub fn detect(&mut self, world: &World) {
        let Some(last) = self.rendered.take() else {
            return;
        };
        let slot = usize::try_from(last.index % world.azimuths()).unwrap_or(0);
        self.detections.clear();
        self.detector.detect(
            slot,
            &self.measured_db,
            &self.gain_db,
            self.floor.floor(self.measured_db.len()),
            &self.axis,
            &mut self.detections,
        );
        self.assembler.push(last, &self.detections);
    }

    /// See [`BeamAssembler::take_final`].
    pub fn take_final(&mut self, flush: bool, out: &mut Vec<AzimuthBeam>) {
        self.assembler.take_final(flush, out);
    }

    /// The range axis of the (decimated) spectra.
    pub fn axis(&self) -> RangeAxis {
        self.axis
    }
}

/// Labels each target of `beam` with the nearest true feature within `range_tol_m` and
/// `bearing_tol_rad` (normalised distance), seen from the beam's true pose.
pub fn label_targets(
    world: &World,
    beam: &mut AzimuthBeam,
    range_tol_m: f64,
    bearing_tol_rad: f64,
) {
    for t in &mut beam.targets {
        let mut best: Option<(f64, u32)> = None;
        for f in &world.features {
            let rb = range_bearing(&beam.truth, f.xy);
            let dr = (rb.range_m - t.target.range_m) / range_tol_m;
            if dr.abs() > 1.0 {
                continue;
            }
            let db = wrap_angle(rb.bearing_rad - t.target.bearing_rad) / bearing_tol_rad;
            if db.abs() > 1.0 {
                continue;
            }
            let d = dr * dr + db * db;
            if best.map_or(true, |(bd, _)| d < bd) {
                best = Some((d, f.id));
            }
        }
        t.label = best.map(|(_, id)| id);
    }
}
