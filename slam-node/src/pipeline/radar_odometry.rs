//! The pipeline's radar-odometry stage: each rotation's detections, walls and fences
//! included, registered against the previous rotation's ([`radar_odometry::ScanMatcher`])
//! measure the vehicle's motion between the two, and the filter takes the measurement
//! ([`slam_filter::Ekf::observe_motion_since_mark`]).
//!
//! With wheel odometry the measurement corrects the odometry's speed scale and steering
//! offset. Without (`[odometry] source = "none"`) this stage also *drives* the filter: after
//! each rotation the filter's motion over it (its prediction fused with the registration) is
//! turned into the process model's input for the next rotation (a constant-velocity
//! prediction refreshed every rotation). Without a motion estimate (the first rotations, a
//! failed registration) the registration searches along the vehicle's axis. Where the scene
//! does not pin the motion (an open field, a long bare wall) the registration's covariance is
//! large along that direction, so the pose's uncertainty grows there; each such rotation is
//! counted and warned about.

use radar_model::geometry::{wrap_angle, Pose2};
use radar_model::motion::MotionModel;
use radar_odometry::{RadarReturn, RotationEnd, RotationMotion, ScanMatchSettings, ScanMatcher};
use tracing::{debug, warn};

pub use super::counts::{ChainedDrift, ScanMatchCounts};
use super::ekf::DaemonEkf;
use super::gate::worth_logging;
use super::truth::TruthObserver;
use crate::detect::Detection;
use slam_filter::{MotionOutcome, OdometrySample};

/// Radar odometry's gate: the 99.9 % point of chi-square with 3 dof.
const GATE_CHI2: f64 = 16.27;

impl RadarReturn for Detection {
    fn range_m(&self) -> f64 {
        self.range_m
    }
    fn strength_db(&self) -> f64 {
        self.snr_db
    }
}

/// On the radar alone without a gyro, a registration turning this much more or less than
/// the filter over a rotation (rad) marks a manoeuvre the prediction missed
/// ([`RadarOdometryStage::widen_for_a_manoeuvre`]). Straight road's registrations differ
/// from the held turn by 0.002 rad RMS; a 90-degree junction's first and last rotations by
/// 0.03-0.05. Realistic city, radar only, odometry drift 2.55 % and 0.740 deg/100 m ->
/// 2.02 % and 0.616 (threshold 0.005: 2.16 %; 0.02: 1.94 %); the check layout (not tuned
/// on) 2.42 % and 0.731 -> 1.73 % and 0.530; the straight realistic street unchanged (1.00 %).
/// A larger constant turn noise instead (0.1 rad/s) gave the city 2.06 % but the street
/// 1.23 %, its features pulling the heading the prediction left free.
pub const MANOEUVRE_HEADING_RAD: f64 = 0.01;

/// On the radar alone without a gyro, a held turn over a rotation beyond
/// [`MANOEUVRE_HEADING_RAD`] is uncertain by this share of that excess: its square is added
/// to the pose's heading variance since the mark before the registration is fused
/// ([`RadarOdometryStage::widen_for_a_manoeuvre`]). A junction's turn rate changes by a
/// good part of itself from one rotation to the next as it begins, eases and ends; the
/// prediction holds the last rotation's turn and, weighed at the straight road's turn
/// noise, kept about half of each change [`MANOEUVRE_HEADING_RAD`] let through (at a
/// turn's end, rotations turning 31 and then 10 mrad against a held 65 and 31 lost the
/// registrations' heading by 5.4 and 2.1 mrad, in the turn's sense: check layout, seed
/// 2). On a straight road or a gentle curve nothing changes: the whole held turn
/// (not its excess) turned the Oxford scans' last rotation 17 mrad the wrong way. Realistic
/// city on the radar alone, ten drives (seeds 1-5, both layouts): slam-node/README.md,
/// "The held turn's own uncertainty".
pub const TURN_HEADING_SHARE: f64 = 1.0;

/// The largest acceleration (m/s^2) the held speed is extrapolated with.
pub const MAX_ACCEL_MPS2: f64 = 4.0;
/// A registration over less of the filter's time than this (s) does not set the held
/// motion's rate. The filter's clock at a rotation's end is its last prediction's (an
/// odometry or gyro sample, an update), not the last azimuth's, and two rotation ends can
/// fall a few milliseconds apart: the motion registered between them is right to a
/// centimetre or two, but a centimetre over 14 ms is 0.7 m/s, and the held speed went
/// from 7 to -23 m/s for a rotation (the same route localised: 2.6 m off for a second).
pub const MIN_RATE_SPAN_S: f64 = 0.1;

/// The stage: the matcher, what the filter did with its measurements, and, when it drives
/// the filter, whether it has a motion estimate.
#[derive(Debug)]
pub struct RadarOdometryStage {
    matcher: ScanMatcher,
    counts: ScanMatchCounts,
    /// Whether it drives the filter's prediction (no other odometry).
    drives: bool,
    /// The filter's process model (driving turns motions into its inputs).
    motion: MotionModel,
    /// Driving, before the filter has started: the last rotation's end (s).
    last_end_s: Option<f64>,
    /// Driving: the last registration failed, so the next searches for the motion.
    lost: bool,
    /// Driving with a gyro: the turn is the gyro's, the registration gives the speed.
    gyro: bool,
    /// Driving: registrations composed onto the pose at the mark, not fused as updates.
    compose: bool,
    /// Driving: the speed the last applied registration measured (m/s) and the middle of
    /// its rotation (s), for the next speed's extrapolation.
    last_speed: Option<(f64, f64)>,
    /// With ground truth: radar odometry's own trajectory (each rotation's registered
    /// motion chained, the odometry's prediction where the registration failed) and the truth chained
    /// over the same intervals, scored at the end ([`ScanMatchCounts::chained`]). A pair of
    /// poses a rotation: 4 MB for six hours at 4 Hz.
    chain: Vec<(Pose2, Pose2)>,
}

impl RadarOdometryStage {
    /// A stage with `settings`; `drives` when there is no other odometry, with `gyro` when
    /// a gyro gives the turn (`super::gyro`). Unless the radar drives alone, the filter
    /// learns a bias from the registrations' turns (a gyro's, wheel odometry's steering
    /// offset): a slow registration's heading is then given at least
    /// `radar_odometry::SLOW_HEADING_SIGMA_RAD`.
    pub fn new(settings: ScanMatchSettings, drives: bool, motion: MotionModel, gyro: bool) -> Self {
        let gyro = drives && gyro;
        Self {
            matcher: ScanMatcher::new(ScanMatchSettings {
                turn_known: settings.turn_known || gyro,
                slow_heading_floor: settings.slow_heading_floor || gyro || !drives,
                ..settings
            }),
            counts: ScanMatchCounts {
                drives,
                ..ScanMatchCounts::default()
            },
            drives,
            motion,
            last_end_s: None,
            last_speed: None,
            lost: false,
            gyro,
            compose: false,
            chain: Vec::new(),
        }
    }

    /// Driving, each registration is composed onto the pose at the previous rotation
    /// ([`slam_filter::Ekf::compose_motion_since_mark`]) instead of fused as an update with
    /// the prediction ([`slam_filter::Ekf::observe_motion_since_mark`]).
    pub fn composing(mut self, compose: bool) -> Self {
        self.compose = self.drives && compose;
        self
    }

    /// Whether it runs.
    pub fn enabled(&self) -> bool {
        self.matcher.enabled()
    }

    /// Whether it drives the filter's prediction.
    pub fn drives(&self) -> bool {
        self.drives
    }

    /// The last rotation's registered cloud in the vehicle's frame at its end (see
    /// [`radar_odometry::ScanMatcher::last_cloud`]).
    pub fn last_cloud(&self) -> Option<&[[f64; 2]]> {
        self.matcher.last_cloud()
    }

    /// Counts a rotation with no beam for the filter, whose end the caller reached by the
    /// motion held ([`ScanMatchCounts::still_clock`]).
    pub fn note_still_clock(&mut self) {
        self.counts.still_clock += 1;
    }

    /// What it did so far.
    pub fn counts(&self) -> ScanMatchCounts {
        ScanMatchCounts {
            registrations: self.matcher.counts(),
            chained: chained_drift(&self.chain),
            ..self.counts
        }
    }

    /// Adds one azimuth's detections at `bearing_rad` and `time_s`, their ranges corrected
    /// for the range-Doppler coupling at `corrected_speed_mps`. The sensor is placed
    /// where the filter's motion since the last mark puts it; driving, before the filter has
    /// started, at the origin (the first rotations are not de-skewed).
    pub fn add_azimuth(
        &mut self,
        ekf: &DaemonEkf,
        time_s: f64,
        bearing_rad: f64,
        detections: &[Detection],
        corrected_speed_mps: f64,
    ) {
        let sensor = match ekf.motion_since_mark(time_s) {
            None if self.drives && ekf.held_odometry().is_none() => Some(Pose2::new(0.0, 0.0, 0.0)),
            sensor => sensor,
        };
        self.matcher.add_azimuth_corrected(
            sensor,
            time_s,
            bearing_rad,
            detections,
            corrected_speed_mps,
        );
    }

    /// Closes a rotation whose last azimuth came at `end_s`: registers it and gives the
    /// measurement to the filter. Driving, returns the odometry sample that carries the
    /// motion over this rotation into the next; the caller applies it, then marks the
    /// filter ([`slam_filter::Ekf::mark_motion`]) for the next rotation. Driving, before the
    /// filter has started, the registration searches for the motion and its first result
    /// starts the filter.
    /// `doppler_coupling_s` is the radar's range-Doppler coupling: the returns read before
    /// the filter started were not corrected for it, and the reference the first rotation
    /// after the start registers against is corrected with the speed it starts at.
    pub fn end_rotation(
        &mut self,
        ekf: &mut DaemonEkf,
        truth: Option<&TruthObserver>,
        end_s: f64,
        doppler_coupling_s: f64,
    ) -> Option<OdometrySample> {
        if self.drives && ekf.held_odometry().is_none() {
            let sample = self.start(end_s);
            if let Some(first) = sample.as_ref() {
                let speed = first.speed_mps;
                self.matcher.shift_reference_ranges(|bearing| {
                    super::frontend::doppler_range_shift_m(doppler_coupling_s, speed, bearing)
                });
            }
            return sample;
        }
        let tally = ekf.motion_tally().copied();
        let until_s = ekf.state().time_s();
        let end = tally.map(|t| RotationEnd {
            pose: t.rel,
            since_s: t.since_s,
            until_s,
        });
        let measured = self.matcher.end_rotation(end, self.drives && self.lost);
        self.lost = self.drives && measured.is_none();
        // With ground truth, the true motion over the same interval (scores only).
        let true_rel = tally
            .as_ref()
            .zip(truth)
            .and_then(|(tally, t)| true_motion(t, tally.since_s, until_s));
        if let Some(tally) = tally.as_ref() {
            let motion = measured.as_ref().map_or(tally.rel, |m| m.motion);
            self.chain_motion(motion, true_rel);
        }
        let mut applied = None;
        if measured.is_none() || tally.is_none() {
            self.counts.break_heading_run();
        }
        // The next registration's reference is this rotation's cloud: its placement error is
        // in the filter's state only if this registration is applied below.
        let mut placement_held = false;
        if let (Some(m), Some(tally)) = (measured.as_ref(), tally) {
            self.score(m, &tally, until_s, true_rel);
            self.warn_if_weak(m, ekf.state().time_s());
            self.warn_if_start_followed(m, ekf.state().time_s());
            if m.unpinned_from_start {
                // What the registrations before it taught the steering offset came from
                // the same scene, from the few that pinned by chance: its variance goes
                // back to its prior.
                ekf.forget_steer_bias();
            }
            // Driving, the registration is the odometry: it is not gated against a
            // prediction that only repeats the last rotation's motion (a turn's onset would
            // be refused, and then every registration after it).
            let gate = if self.drives {
                f64::INFINITY
            } else {
                GATE_CHI2
            };
            // Driving, the registration is the motion: composed onto the mark, not fused
            // with a prediction that only repeats the last rotation's motion.
            self.widen_for_a_manoeuvre(ekf, m);
            // Measured against the estimate it started from (with start probes: beside a
            // sensor of the vehicle's own), the share of that start it followed is taken
            // out, so the prediction is not counted twice (`RotationMotion::unfollowed`).
            let (motion, covariance) = m.unfollowed(&tally.rel);
            let result = if self.compose {
                ekf.compose_motion_since_mark(motion, &covariance)
            } else {
                ekf.observe_motion_since_mark(motion, &covariance, gate)
            };
            match result {
                Ok(outcome) => {
                    if let MotionOutcome::Applied { .. } = outcome {
                        applied = Some(*m);
                        placement_held = !self.compose;
                    }
                    if let MotionOutcome::Gated { .. } = outcome {
                        let gated = self.counts.gated + 1;
                        if worth_logging(gated) {
                            warn!(
                                ?outcome,
                                pairs = m.registration.pairs,
                                rms_m = m.registration.rms_m,
                                gated,
                                "radar odometry disagrees with the prediction beyond its gate: not used"
                            );
                        }
                    }
                    self.counts.record(outcome);
                }
                Err(e) => warn!(error = %e, "radar odometry update failed"),
            }
        }
        if !placement_held {
            ekf.forget_placement();
        }
        // The next rotation registers against this one placed along the motion the filter
        // settled on: the frame its next mark stands for.
        if let Some(settled) = ekf.pose_since_mark() {
            self.matcher.place_reference(settled);
        }
        if self.drives {
            let sample = drive_sample(ekf, &self.motion, tally, applied.as_ref(), self.gyro)?;
            Some(self.extrapolated(sample, applied.as_ref(), tally))
        } else {
            None
        }
    }

    /// The speed held over the next rotation: the one measured over this rotation carried
    /// on by the change since the last (constant acceleration, at most
    /// [`MAX_ACCEL_MPS2`]), when both were registered and neither was weak or searched.
    /// A vehicle slowing into a junction or pulling away from it changes its speed by
    /// 0.1-0.3 m/s a rotation; held constant, the prediction overshoots or lags by a
    /// decimetre a rotation, and the filter, fusing it with the registration, follows it
    /// part of the way (the registrations err 1-2 cm along the track).
    fn extrapolated(
        &mut self,
        sample: OdometrySample,
        applied: Option<&RotationMotion>,
        tally: Option<slam_filter::motion_tally::MotionTally>,
    ) -> OdometrySample {
        let (Some(m), Some(t)) = (applied, tally) else {
            self.last_speed = None;
            return sample;
        };
        if m.weak || m.searched {
            self.last_speed = None;
            return sample;
        }
        let span = sample.timestamp_s - t.since_s;
        if span < MIN_RATE_SPAN_S {
            // The sample holds the motion held so far (`drive_sample`).
            self.last_speed = None;
            return sample;
        }
        let centre = t.since_s + 0.5 * span;
        let speed = sample.speed_mps;
        let previous = self.last_speed.replace((speed, centre));
        let Some((before, before_centre)) = previous else {
            return sample;
        };
        let dt = centre - before_centre;
        if !(dt > 0.05 && dt < 1.0) {
            self.last_speed = None;
            return sample;
        }
        let accel = ((speed - before) / dt).clamp(-MAX_ACCEL_MPS2, MAX_ACCEL_MPS2);
        let next = speed + accel * span;
        OdometrySample {
            speed_mps: if speed >= 0.0 {
                next.max(0.0)
            } else {
                next.min(0.0)
            },
            ..sample
        }
    }

    /// Driving, before the filter has started: the registration (searched, from the
    /// origin) of this rotation against the last gives the first motion, stamped at this
    /// rotation's end.
    fn start(&mut self, end_s: f64) -> Option<OdometrySample> {
        let previous_end_s = self.last_end_s.replace(end_s);
        // Before the filter has started the cloud was placed from the origin; the rotation
        // spans from the previous one's end (unknown for the first: no re-placing).
        let origin = Some(RotationEnd {
            pose: Pose2::new(0.0, 0.0, 0.0),
            since_s: previous_end_s.unwrap_or(end_s),
            until_s: end_s,
        });
        let measured = self.matcher.end_rotation(origin, true);
        let (m, start_s) = (measured?, previous_end_s?);
        let distance = m.motion.x.signum() * m.motion.x.hypot(m.motion.y);
        let input = self
            .motion
            .input_for(distance, m.motion.theta, end_s - start_s)?;
        debug!(
            measured_x = m.motion.x,
            measured_y = m.motion.y,
            measured_theta = m.motion.theta,
            pairs = m.registration.pairs,
            "radar only: the first registration starts the filter"
        );
        Some(OdometrySample {
            timestamp_s: end_s,
            speed_mps: input.speed_mps,
            steer_rad: input.steer_rad,
        })
    }

    /// On the radar alone, without a gyro: when the registration's turn over the rotation
    /// differs from the filter's by more than [`MANOEUVRE_HEADING_RAD`], the prediction
    /// (the last rotation's motion held) missed a turn's onset or end, and its small turn
    /// noise would keep the pose near it; the difference squared is added to the pose's
    /// heading variance since the mark, as process noise the model did not hold, before the
    /// registration is fused. Counted in [`ScanMatchCounts::manoeuvres`]. While the vehicle
    /// turns faster than that, the held turn is uncertain by [`TURN_HEADING_SHARE`] of its
    /// excess on top, whether or not this registration left it.
    fn widen_for_a_manoeuvre(&mut self, ekf: &mut DaemonEkf, m: &RotationMotion) {
        if !self.drives || self.gyro || self.compose {
            return;
        }
        let Some(held) = ekf.pose_since_mark() else {
            return;
        };
        let turning = TURN_HEADING_SHARE * (held.theta.abs() - MANOEUVRE_HEADING_RAD).max(0.0);
        if turning > 0.0 {
            ekf.add_process_noise_since_mark([0.0, 0.0, turning * turning]);
        }
        let missed = wrap_angle(m.motion.theta - held.theta);
        if missed.abs() > MANOEUVRE_HEADING_RAD {
            ekf.add_process_noise_since_mark([0.0, 0.0, missed * missed]);
            self.counts.manoeuvres += 1;
        }
    }

    /// Chains `motion` (this rotation's, registered or predicted) and the true motion over
    /// the same interval onto radar odometry's own trajectory and the truth's; a rotation
    /// without the truth's motion (or without a mark) is left out of both.
    fn chain_motion(&mut self, motion: Pose2, truth: Option<Pose2>) {
        let Some(truth) = truth else {
            return;
        };
        let origin = Pose2::new(0.0, 0.0, 0.0);
        let &(last, last_truth) = self.chain.last().unwrap_or(&(origin, origin));
        if self.chain.is_empty() {
            self.chain.push((origin, origin));
        }
        self.chain
            .push((last.compose(&motion), last_truth.compose(&truth)));
    }

    /// Scores the registration `m` over the rotation from the mark to `until_s` against
    /// `truth`, the true motion over the same interval (with ground truth), and logs both
    /// with the prediction it started from (the `radar odometry registration` debug line),
    /// with the matcher's running counts of the paths a registration can take (retried from
    /// other headings, an onset probe or a swept probe taken, placed again): their changes
    /// from one line to the next say which path this registration took.
    fn score(
        &mut self,
        m: &RotationMotion,
        tally: &slam_filter::motion_tally::MotionTally,
        until_s: f64,
        truth: Option<Pose2>,
    ) {
        let truth = truth.map(|rel| [rel.x, rel.y, rel.theta]);
        let motion = m.motion;
        let c = self.matcher.counts();
        if let Some(t) = truth {
            self.counts.record_truth_error(
                [
                    motion.x - t[0],
                    motion.y - t[1],
                    wrap_angle(motion.theta - t[2]),
                ],
                &m.covariance,
            );
        } else {
            self.counts.break_heading_run();
        }
        debug!(
            since_s = tally.since_s,
            until_s,
            truth_x = truth.map(|t| t[0]),
            truth_y = truth.map(|t| t[1]),
            truth_theta = truth.map(|t| t[2]),
            measured_x = motion.x,
            measured_y = motion.y,
            measured_theta = motion.theta,
            predicted_x = tally.rel.x,
            predicted_y = tally.rel.y,
            predicted_theta = tally.rel.theta,
            pairs = m.registration.pairs,
            rms_m = m.registration.rms_m,
            iterations = m.registration.iterations,
            weakest = m.constraint.weakest,
            searched = m.searched,
            start_follow_average = m.start_follow.unwrap_or(-1.0),
            heading_sigma_rad = m.covariance[(2, 2)].max(0.0).sqrt(),
            turned = c.turned,
            onsets = c.onsets,
            probed = c.probed,
            replaced = c.replaced,
            crawled = c.crawled,
            "radar odometry registration"
        );
    }

    /// A WARN (on the first, then rarer) when registrations have followed their start's
    /// heading so far on the recent average that this one's heading says nothing: the scene
    /// does not pin the heading (posts and poles smeared across the beam, few surfaces).
    fn warn_if_start_followed(&self, m: &RotationMotion, time_s: f64) {
        if !m.heading_unpinned {
            return;
        }
        let unpinned = self.matcher.counts().start_unpinned;
        if worth_logging(unpinned) {
            warn!(
                time_s,
                share_followed = m.start_follow,
                unpinned,
                "radar odometry's registrations stay at the heading they start from (the scene does not pin the heading: returns smeared across the beam, few surfaces): they are not used for the heading, and the odometry alone turns the pose"
            );
        }
    }

    fn warn_if_weak(&self, m: &RotationMotion, time_s: f64) {
        if !m.weak {
            return;
        }
        let weak = self.matcher.counts().weak;
        if worth_logging(weak) {
            let d = m.constraint.direction;
            warn!(
                time_s,
                weakest = m.constraint.weakest,
                direction_x = d[0],
                direction_y = d[1],
                direction_heading = d[2],
                sigma_along_m = (m.covariance[(0, 0)] * d[0] * d[0] + m.covariance[(1, 1)] * d[1] * d[1]).sqrt(),
                weak,
                "the radar cannot see the motion along one direction here (an open field, a long bare wall): the pose's uncertainty grows along it"
            );
        }
    }
}

/// The input for the next rotation: the motion the registration measured over the rotation
/// just closed (a constant-velocity prediction), or, along a direction the scene did not pin
/// and when no registration was applied, the input held so far. Not the filter's own change
/// of pose over the rotation: that holds the map's corrections of the pose, which are
/// displacements, not motion, and carried into the next rotation they would repeat.
/// Corrected back through the filter's odometry bias, so that the process model applies it
/// as measured. With a gyro only the speed is the registration's: the steering stays the
/// last gyro sample's (the gyro's samples carry the turn, `super::gyro`).
fn drive_sample(
    ekf: &DaemonEkf,
    motion: &MotionModel,
    tally: Option<slam_filter::motion_tally::MotionTally>,
    applied: Option<&RotationMotion>,
    gyro: bool,
) -> Option<OdometrySample> {
    let now_s = ekf.state().time_s();
    let tally = tally?;
    let held = ekf.held_odometry()?;
    let [k, b] = ekf.state().odometry_bias();
    let Some(m) = applied else {
        // Nothing measured: the motion held so far goes on.
        return Some(OdometrySample {
            timestamp_s: now_s,
            ..held
        });
    };
    let dt = now_s - tally.since_s;
    if dt < MIN_RATE_SPAN_S {
        // Too short to take a rate from: the motion held so far goes on.
        return Some(OdometrySample {
            timestamp_s: now_s,
            ..held
        });
    }
    let measured_distance = m.motion.x.signum() * m.motion.x.hypot(m.motion.y);
    let (distance, turn) = if m.weak {
        // Along the weak direction the registration said nothing: the translation it pins
        // poorly keeps the held speed; a heading it pins poorly keeps the held turn.
        let held_distance = held.speed_mps * (1.0 + k) * dt;
        let d = m.constraint.direction;
        let translation_weak = d[0].hypot(d[1]) > 0.5;
        let held_turn = motion
            .predict(
                &Pose2::new(0.0, 0.0, 0.0),
                &radar_model::motion::ControlInput::new(
                    held.speed_mps * (1.0 + k),
                    held.steer_rad + b,
                ),
                dt,
            )
            .map(|p| p.theta)
            .unwrap_or(0.0);
        if translation_weak {
            (held_distance, m.motion.theta)
        } else {
            (measured_distance, held_turn)
        }
    } else {
        (measured_distance, m.motion.theta)
    };
    let input = motion.input_for(distance, turn, dt)?;
    Some(OdometrySample {
        timestamp_s: now_s,
        speed_mps: input.speed_mps / (1.0 + k),
        steer_rad: if gyro {
            held.steer_rad
        } else {
            input.steer_rad - b
        },
    })
}

/// The true motion from `since_s` to `until_s`: the pose at the end in the frame of the
/// pose at the start; `None` where the truth does not cover either.
fn true_motion(truth: &TruthObserver, since_s: f64, until_s: f64) -> Option<Pose2> {
    truth
        .pose_at(since_s)
        .zip(truth.pose_at(until_s))
        .map(|(a, b)| slam_graph::se2::between(&a, &b))
}

/// The drift of a chained trajectory (estimate, truth) over 100-800 m segments; `None`
/// over 100 m or less, or where the chain is not finite.
fn chained_drift(chain: &[(Pose2, Pose2)]) -> Option<ChainedDrift> {
    let (estimate, truth): (Vec<Pose2>, Vec<Pose2>) = chain.iter().copied().unzip();
    slam_filter::drift::odometry_drift(&truth, &estimate)
        .ok()
        .flatten()
        .map(|d| ChainedDrift {
            translation_percent: d.translation_percent,
            rotation_deg_per_100m: d.rotation_deg_per_100m,
            segments: d.segments,
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;
    use radar_odometry::{Constraint, Registration};
    use slam_filter::motion_tally::MotionTally;

    fn stage() -> RadarOdometryStage {
        RadarOdometryStage::new(
            ScanMatchSettings::default(),
            true,
            MotionModel::Bicycle { wheelbase_m: 2.7 },
            false,
        )
    }

    /// Radar odometry's own trajectory is scored as the literature scores it: every rotation's
    /// motion chained against the truth's over the same interval, 100-800 m segments. A
    /// registration turning 1 mrad too far every metre drifts 1 mrad/m (5.73 deg/100 m); a
    /// rotation without the truth's motion is left out; 100 m or less scores nothing.
    #[test]
    fn radar_odometry_alone_is_scored_by_chaining_its_motions() {
        let mut s = stage();
        let step = Pose2::new(1.0, 0.0, 0.0);
        for _ in 0..99 {
            s.chain_motion(Pose2::new(1.0, 0.0, 0.001), Some(step));
        }
        s.chain_motion(Pose2::new(5.0, 0.0, 0.0), None);
        assert_eq!(s.chain.len(), 100, "the first pose and 99 motions");
        assert!(s.counts().chained.is_none(), "99 m: no segment");
        for _ in 0..300 {
            s.chain_motion(Pose2::new(1.0, 0.0, 0.001), Some(step));
        }
        let c = s.counts().chained.expect("399 m driven");
        // A segment ends at the first pose at least its length on, a metre later where
        // the sum of the steps falls a hair short: within 1 %.
        let expected = 0.001_f64.to_degrees() * 100.0;
        assert!(
            (c.rotation_deg_per_100m - expected).abs() < 0.01 * expected,
            "{c:?}"
        );
        assert!(c.translation_percent > 1.0 && c.segments > 0, "{c:?}");

        let mut exact = stage();
        for _ in 0..400 {
            exact.chain_motion(step, Some(step));
        }
        let c = exact.counts().chained.expect("400 m driven");
        assert!(
            c.translation_percent.abs() < 1e-9 && c.rotation_deg_per_100m.abs() < 1e-9,
            "{c:?}"
        );
    }

    /// A slow registration's heading is floored wherever the filter learns a bias from the
    /// registrations' turns: with wheel odometry (the stage does not drive) and with a gyro,
    /// not on the radar alone.
    #[test]
    fn a_slow_registration_s_heading_is_floored_unless_the_radar_drives_alone() {
        let floored = |drives: bool, gyro: bool| {
            RadarOdometryStage::new(
                ScanMatchSettings::default(),
                drives,
                MotionModel::Bicycle { wheelbase_m: 2.7 },
                gyro,
            )
            .matcher
            .settings()
            .slow_heading_floor
        };
        assert!(floored(false, false), "wheel odometry");
        assert!(floored(true, true), "radar and a gyro");
        assert!(!floored(true, false), "the radar alone");
    }

    fn registered(weak: bool) -> RotationMotion {
        let pose = Pose2::new(2.0, 0.0, 0.0);
        RotationMotion {
            motion: pose,
            covariance: Matrix3::identity() * 1e-4,
            registration: Registration {
                pose,
                pairs: 500,
                line_pairs: 400,
                rms_m: 0.05,
                iterations: 12,
                information: Matrix3::identity(),
            },
            constraint: Constraint {
                weakest: if weak { 0.0 } else { 0.5 },
                direction: [1.0, 0.0, 0.0],
            },
            weak,
            searched: false,
            start_follow: None,
            heading_unpinned: false,
            unpinned_from_start: false,
        }
    }

    /// The stage's held speed after a rotation from `since_s` to `until_s` measured at
    /// `speed_mps`.
    fn held(
        s: &mut RadarOdometryStage,
        since_s: f64,
        until_s: f64,
        speed_mps: f64,
        weak: bool,
    ) -> f64 {
        let sample = OdometrySample {
            timestamp_s: until_s,
            speed_mps,
            steer_rad: 0.0,
        };
        let tally = MotionTally {
            since_s,
            rel: Pose2::new(speed_mps * (until_s - since_s), 0.0, 0.0),
        };
        s.extrapolated(sample, Some(&registered(weak)), Some(tally))
            .speed_mps
    }

    #[test]
    fn the_held_speed_goes_on_with_the_acceleration_measured_and_no_further() {
        let mut s = stage();
        // The first rotation has nothing to extrapolate from.
        assert_eq!(held(&mut s, 0.0, 0.25, 8.0, false), 8.0);
        // 8 -> 9 m/s over a rotation: 4 m/s^2, carried over the next quarter second.
        assert!((held(&mut s, 0.25, 0.5, 9.0, false) - 10.0).abs() < 1e-9);
        // Rotations of other lengths: the rate between the rotations' middles (0.375 and
        // 0.56 s), carried over this rotation's length.
        let next = held(&mut s, 0.5, 0.62, 9.2, false);
        assert!((next - (9.2 + 0.2 / 0.185 * 0.12)).abs() < 1e-9, "{next}");
        // Rotation ends 14 ms apart on the filter's clock: no rate from them, and the next
        // rotation starts afresh.
        assert_eq!(held(&mut s, 0.62, 0.634, 7.0, false), 7.0);
        assert_eq!(held(&mut s, 0.634, 0.85, 9.0, false), 9.0);
        // A weak registration holds its speed and the next one starts afresh.
        assert_eq!(held(&mut s, 0.85, 1.1, 9.0, true), 9.0);
        assert_eq!(held(&mut s, 1.1, 1.35, 9.5, false), 9.5);
        // A jump beyond MAX_ACCEL_MPS2 (a bad registration) is carried at that at most.
        let next = held(&mut s, 1.35, 1.6, 13.5, false);
        assert!(
            (next - (13.5 + MAX_ACCEL_MPS2 * 0.25)).abs() < 1e-9,
            "{next}"
        );
        // Slowing to a stop never reverses the held speed.
        let mut s = stage();
        held(&mut s, 0.0, 0.25, 0.8, false);
        assert_eq!(held(&mut s, 0.25, 0.5, 0.1, false), 0.0);
        // Without a registration applied the sample is the held one, unchanged.
        let sample = OdometrySample {
            timestamp_s: 0.75,
            speed_mps: 5.0,
            steer_rad: 0.0,
        };
        assert_eq!(s.extrapolated(sample, None, None), sample);
    }

    /// On the radar alone, a registration turning 0.05 rad where the filter held the
    /// motion straight (a turn's onset) widens the heading's variance since the mark by
    /// 0.05^2 before it is fused, and is counted; one within the threshold changes nothing;
    /// while the filter holds a turn beyond the threshold, [`TURN_HEADING_SHARE`] of the
    /// excess is added as well; with a gyro nothing is widened (the gyro gave the turn).
    #[test]
    fn a_turn_the_held_motion_missed_widens_the_heading_before_the_registration() {
        let widened = |gyro: bool, held_turn: f64, turn: f64| {
            let mut ekf = DaemonEkf::new(
                slam_filter::FilterSettings::default(),
                Pose2::new(0.0, 0.0, 0.0),
                Matrix3::from_diagonal(&nalgebra::Vector3::new(1e-4, 1e-4, 1e-6)),
                0.0,
                MotionModel::Paper { step_s: 0.05 },
                slam_filter::RadarBeamModel {
                    power: radar_model::power::PowerModel::default(),
                },
            )
            .expect("filter");
            ekf.mark_motion();
            // The filter's motion since the mark: the held turn.
            ekf.compose_motion_since_mark(Pose2::new(2.0, 0.0, held_turn), &Matrix3::zeros())
                .expect("composed");
            let before = ekf.pose_covariance()[(2, 2)];
            let mut s = RadarOdometryStage::new(
                ScanMatchSettings::default(),
                true,
                MotionModel::Bicycle { wheelbase_m: 2.7 },
                gyro,
            );
            let mut m = registered(false);
            m.motion.theta = turn;
            s.widen_for_a_manoeuvre(&mut ekf, &m);
            (ekf.pose_covariance()[(2, 2)] - before, s.counts.manoeuvres)
        };
        let (grown, counted) = widened(false, 0.0, 0.05);
        assert!((grown - 0.05f64.powi(2)).abs() < 1e-12, "{grown}");
        assert_eq!(counted, 1);
        assert_eq!(widened(false, 0.0, 0.5 * MANOEUVRE_HEADING_RAD), (0.0, 0));
        assert_eq!(widened(true, 0.0, 0.05), (0.0, 0));
        // Turning 0.04 rad a rotation and registered so: the held turn's own share is
        // added, and the rotation is not counted as a manoeuvre.
        let (grown, counted) = widened(false, 0.04, 0.04);
        let share = (TURN_HEADING_SHARE * (0.04 - MANOEUVRE_HEADING_RAD)).powi(2);
        assert!((grown - share).abs() < 1e-12, "{grown}");
        assert_eq!(counted, 0);
        // A turn easing from 0.04 to 0.02: both.
        let (grown, counted) = widened(false, 0.04, 0.02);
        assert!((grown - share - 0.02f64.powi(2)).abs() < 1e-12, "{grown}");
        assert_eq!(counted, 1);
        // With a gyro, neither.
        assert_eq!(widened(true, 0.04, 0.02), (0.0, 0));
        // A gentle curve held at the threshold or under adds nothing.
        let curve = MANOEUVRE_HEADING_RAD;
        assert_eq!(widened(false, curve, curve), (0.0, 0));
    }
}
