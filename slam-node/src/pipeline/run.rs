//! The pipeline's thread: azimuths from the driver's lock-free channel, odometry from its
//! source, events to the writer. It waits (bounded) for odometry to reach each azimuth's
//! time, says so when the radar stalls and keeps its state until the stream returns, and
//! stops on request, at the end of the stream, or after a set stream duration.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError};
use radar_driver::{Azimuth, OdometryPoll, OdometrySource};
use tracing::{error, info, warn};

use super::core::{Pipeline, PipelineError};
use super::ekf::DaemonEkf;
use super::summary::PipelineSummary;
use crate::output::{OutputEvent, OutputHandle};
use crate::source::gyro::{GyroPoll, GyroSource};
use slam_filter::OdometrySample;

/// What the pipeline thread reads.
pub struct PipelineInputs {
    /// Azimuths from the driver.
    pub azimuths: Receiver<Azimuth>,
    /// Odometry, or `None` when there is none (the filter then refuses to run).
    pub odometry: Option<Box<dyn OdometrySource>>,
    /// The gyro of radar-only driving, or `None`.
    pub gyro: Option<Box<dyn GyroSource>>,
    /// Prior poses in the saved map's frame (`[map] initial_pose_topic`), or `None`.
    pub priors: Option<Receiver<super::localise::PriorPose>>,
}

impl std::fmt::Debug for PipelineInputs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PipelineInputs")
            .field("odometry", &self.odometry.is_some())
            .field("gyro", &self.gyro.is_some())
            .field("priors", &self.priors.is_some())
            .finish_non_exhaustive()
    }
}

/// Builds the pipeline for the radar that connected, from the geometry its first azimuth
/// brings (the radar's profile is chosen from it).
pub type BuildOnFirstAzimuth =
    Box<dyn FnOnce(&protocol::Geometry) -> Result<Pipeline, PipelineError> + Send>;

/// The pipeline, or how to build it once the radar has said what it is.
pub enum PipelineStart {
    /// Built already (the source knew its radar).
    Ready(Box<Pipeline>),
    /// Built on the first azimuth (a radar over TCP, a recording): its profile is chosen
    /// from what it announces.
    OnFirstAzimuth(BuildOnFirstAzimuth),
}

impl std::fmt::Debug for PipelineStart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            PipelineStart::Ready(_) => "PipelineStart::Ready",
            PipelineStart::OnFirstAzimuth(_) => "PipelineStart::OnFirstAzimuth",
        })
    }
}

impl From<Pipeline> for PipelineStart {
    fn from(p: Pipeline) -> Self {
        PipelineStart::Ready(Box::new(p))
    }
}

/// Progress callback: called after every rotation with the running totals and the filter.
pub type ProgressFn = Box<dyn FnMut(&PipelineSummary, &DaemonEkf) + Send>;

/// How the thread is stopped and watched.
pub struct RunControl {
    /// Set to stop at the next azimuth.
    pub stop: Arc<AtomicBool>,
    /// Stop after this much stream time from the first azimuth.
    pub max_stream_s: Option<f64>,
    /// Called after every rotation.
    pub progress: Option<ProgressFn>,
    /// End the run when no azimuth has come for this long after the first (a recording
    /// that has been played out); `None` waits through silences (a live radar stalls and
    /// comes back).
    pub end_after_silence: Option<Duration>,
    /// Whether the source has sent all it will (a recording played out): the run then ends
    /// after `end_after_silence` even if no azimuth ever came, instead of waiting for a
    /// first one.
    pub played_out: Option<PlayedOut>,
}

/// Whether a source has sent all it will.
pub type PlayedOut = Box<dyn Fn() -> bool + Send>;

impl std::fmt::Debug for RunControl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunControl")
            .field("max_stream_s", &self.max_stream_s)
            .finish_non_exhaustive()
    }
}

/// What the thread did besides the pipeline's own summary.
#[derive(Debug, Clone, Default)]
pub struct RunReport {
    /// The pipeline's summary.
    pub summary: PipelineSummary,
    /// Radar stalls declared.
    pub stalls: u64,
    /// Odometry lines the source rejected.
    pub odometry_errors: u64,
    /// Gyro lines the source rejected.
    pub gyro_errors: u64,
    /// Output events dropped because the writer was behind.
    pub output_drops: u64,
    /// Wall time of the whole loop.
    pub wall_s: f64,
    /// Azimuths the pipeline could not process (bad radar geometry), logged sparsely.
    pub azimuth_errors: u64,
    /// Why the pipeline could not be built for the radar that connected, if it could not.
    pub start_failure: Option<String>,
    /// Azimuths stamped more than [`FAR_AHEAD_OF_ODOMETRY_S`] after the latest odometry,
    /// processed without waiting for odometry to reach them.
    pub far_ahead_of_odometry: u64,
}

/// An azimuth stamped this far (s) after the latest odometry is not waited for: waiting
/// the odometry wait cannot close such a gap, and a radar whose clock runs in the future
/// would otherwise cost that wait on every azimuth (a queue of them, half an hour).
pub const FAR_AHEAD_OF_ODOMETRY_S: f64 = 10.0;

/// How long the pipeline waits for a radar's first azimuth before saying it waits.
const FIRST_AZIMUTH_NOTICE: Duration = Duration::from_secs(2);

/// Waits for the first azimuth, watching `control`; `None` when stopped or the channel
/// closed first.
fn first_azimuth(azimuths: &Receiver<Azimuth>, control: &RunControl) -> Option<Azimuth> {
    let waiting = Instant::now();
    let mut said = false;
    let mut played_out_at: Option<Instant> = None;
    loop {
        if control.stop.load(Ordering::Relaxed) {
            info!("stop requested before the radar's first azimuth");
            return None;
        }
        match azimuths.recv_timeout(Duration::from_millis(100)) {
            Ok(az) => return Some(az),
            Err(RecvTimeoutError::Timeout) => {
                if !said && waiting.elapsed() >= FIRST_AZIMUTH_NOTICE {
                    info!(
                        "waiting for the radar's first azimuth (its geometry chooses its profile)"
                    );
                    said = true;
                }
                if played_out_at.is_none() && control.played_out.as_ref().is_some_and(|f| f()) {
                    played_out_at = Some(Instant::now());
                }
                if let Some(limit) = control.end_after_silence {
                    if let Some(at) = played_out_at.filter(|at| at.elapsed() >= limit) {
                        warn!(
                            waited_s = at.duration_since(waiting).as_secs_f64(),
                            "the recording has played out and no azimuth came from it"
                        );
                        return None;
                    }
                    if waiting.elapsed() >= limit.max(Duration::from_secs(30)) {
                        warn!("no azimuth came from the recording");
                        return None;
                    }
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                info!("the radar driver closed its channel before the first azimuth");
                return None;
            }
        }
    }
}

fn to_sample(r: radar_driver::OdometryRecord) -> OdometrySample {
    OdometrySample {
        timestamp_s: r.timestamp_s,
        speed_mps: r.speed_mps,
        steer_rad: r.steer_rad,
    }
}

/// Polls the source once; false when it has ended. A recording gets each sample too.
fn poll_odometry(
    pipeline: &mut Pipeline,
    source: &mut dyn OdometrySource,
    timeout: Duration,
    errors: &mut u64,
    output: &OutputHandle,
) -> bool {
    match source.poll_next(timeout) {
        Ok(OdometryPoll::Record(r)) => {
            let sample = to_sample(r);
            pipeline.push_odometry(sample);
            if output.wants_odometry() {
                output.send(OutputEvent::Odometry(sample));
            }
            true
        }
        Ok(OdometryPoll::Pending) => true,
        Ok(OdometryPoll::Ended) => false,
        Err(e) => {
            *errors += 1;
            if *errors <= 10 || errors.is_power_of_two() {
                warn!(error = %e, count = *errors, "odometry error");
            }
            e.is_recoverable()
        }
    }
}

/// Polls the gyro once; false when it has ended.
fn poll_gyro(
    pipeline: &mut Pipeline,
    source: &mut dyn GyroSource,
    timeout: Duration,
    errors: &mut u64,
) -> bool {
    match source.poll_next(timeout) {
        Ok(GyroPoll::Sample(s)) => {
            pipeline.push_gyro(s);
            true
        }
        Ok(GyroPoll::Pending) => true,
        Ok(GyroPoll::Ended) => false,
        Err(e) => {
            *errors += 1;
            if *errors <= 10 || errors.is_power_of_two() {
                warn!(error = %e, count = *errors, "gyro error");
            }
            e.is_recoverable()
        }
    }
}

/// The gyro is read at most this far (s) ahead of the azimuth being processed: a file or a
/// truth-made gyro has every sample at once, and its queue is bounded.
const GYRO_LEAD_S: f64 = 1.0;

/// Takes what the gyro has up to [`GYRO_LEAD_S`] past `time_s` (without waiting), then,
/// when `wait` is given, waits that long at most for it to reach `time_s`. Ends the source
/// when it has ended.
fn feed_gyro(
    pipeline: &mut Pipeline,
    gyro: &mut Option<Box<dyn GyroSource>>,
    time_s: f64,
    wait: Option<Duration>,
    errors: &mut u64,
) {
    let Some(src) = gyro.as_mut() else {
        return;
    };
    let deadline = Instant::now() + wait.unwrap_or(Duration::ZERO);
    for _ in 0..100_000 {
        let latest = pipeline.gyro_latest_s();
        if latest.is_some_and(|g| g >= time_s + GYRO_LEAD_S) {
            return;
        }
        let behind = wait.is_some() && latest.is_none_or(|g| g < time_s);
        let now = Instant::now();
        let timeout = if behind && now < deadline {
            (deadline - now).min(Duration::from_millis(20))
        } else {
            Duration::ZERO
        };
        let received = pipeline.gyro_received();
        if !poll_gyro(pipeline, src.as_mut(), timeout, errors) {
            info!("gyro source ended");
            *gyro = None;
            return;
        }
        let got = pipeline.gyro_received() > received;
        if !got && (!behind || Instant::now() >= deadline) {
            return;
        }
    }
}

/// Runs the pipeline until the azimuth channel closes, `stop` is set, or the stream
/// duration is reached; then flushes it and returns its summary.
pub fn run_pipeline(
    start: impl Into<PipelineStart>,
    mut inputs: PipelineInputs,
    output: &OutputHandle,
    mut control: RunControl,
) -> RunReport {
    let started = Instant::now();
    let mut report = RunReport::default();
    let mut held = None;
    let mut pipeline = match start.into() {
        PipelineStart::Ready(p) => *p,
        PipelineStart::OnFirstAzimuth(build) => {
            let Some(az) = first_azimuth(&inputs.azimuths, &control) else {
                report.wall_s = started.elapsed().as_secs_f64();
                return report;
            };
            match build(&az.geometry) {
                Ok(p) => {
                    held = Some(az);
                    p
                }
                Err(e) => {
                    error!(error = %e, "the pipeline could not be built for this radar");
                    report.start_failure = Some(format!("{e}"));
                    report.wall_s = started.elapsed().as_secs_f64();
                    return report;
                }
            }
        }
    };
    let mut events = Vec::new();
    let stall_after = pipeline.settings().radar_stall;
    let odometry_wait = pipeline.settings().odometry_wait;
    let mut last_azimuth = Instant::now();
    let mut stalled_since: Option<Instant> = None;
    let mut first_time_s: Option<f64> = None;
    if inputs.odometry.is_none() {
        if pipeline.settings().radar_drives {
            info!("no odometry source: radar odometry drives the filter (the radar alone)");
        } else {
            error!("no odometry source: the filter will not run (no motion is fabricated); detection and diagnostics only");
        }
    }
    loop {
        if control.stop.load(Ordering::Relaxed) {
            info!("stop requested");
            break;
        }
        // Take whatever odometry has arrived, without waiting.
        if let Some(src) = inputs.odometry.as_mut() {
            for _ in 0..1024 {
                let before = pipeline.summary().odometry_samples;
                if !poll_odometry(
                    &mut pipeline,
                    src.as_mut(),
                    Duration::ZERO,
                    &mut report.odometry_errors,
                    output,
                ) {
                    info!("odometry source ended");
                    inputs.odometry = None;
                    break;
                }
                if pipeline.summary().odometry_samples == before {
                    break;
                }
            }
        }
        if let Some(rx) = inputs.priors.as_ref() {
            // Bounded by the channel's capacity; the latest wins in the localiser.
            while let Ok(p) = rx.try_recv() {
                pipeline.prior_pose(p);
            }
        }
        let next = match held.take() {
            Some(az) => Ok(az),
            None => inputs.azimuths.recv_timeout(Duration::from_millis(100)),
        };
        let az = match next {
            Ok(az) => az,
            Err(RecvTimeoutError::Timeout) => {
                if let Some(limit) = control.end_after_silence {
                    if first_time_s.is_some() && last_azimuth.elapsed() >= limit {
                        info!(
                            silent_s = last_azimuth.elapsed().as_secs_f64(),
                            "the recording has played out"
                        );
                        break;
                    }
                }
                if stalled_since.is_none() && last_azimuth.elapsed() >= stall_after {
                    warn!(
                        silent_s = last_azimuth.elapsed().as_secs_f64(),
                        "radar stalled: no azimuth received; keeping the map and pose, waiting for the stream"
                    );
                    stalled_since = Some(Instant::now());
                    report.stalls += 1;
                }
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => {
                info!("the radar driver closed its channel");
                break;
            }
        };
        if let Some(since) = stalled_since.take() {
            info!(
                stalled_s = since.elapsed().as_secs_f64() + stall_after.as_secs_f64(),
                "radar stream resumed"
            );
        }
        last_azimuth = Instant::now();
        // Wait, bounded, for odometry to reach this azimuth's time, unless it is stamped so
        // far ahead of the odometry that no wait can close the gap.
        let far_ahead = pipeline
            .odometry_latest_s()
            .is_some_and(|t| az.timestamp_s - t > FAR_AHEAD_OF_ODOMETRY_S);
        if far_ahead {
            report.far_ahead_of_odometry += 1;
            if report.far_ahead_of_odometry.is_power_of_two() {
                warn!(
                    azimuth_s = az.timestamp_s,
                    odometry_s = pipeline.odometry_latest_s(),
                    count = report.far_ahead_of_odometry,
                    "azimuth stamped far ahead of the odometry (a radar clock in the future?): not waiting for odometry"
                );
            }
        }
        if let Some(src) = inputs.odometry.as_mut().filter(|_| !far_ahead) {
            let deadline = Instant::now() + odometry_wait;
            while pipeline
                .odometry_latest_s()
                .is_none_or(|t| t < az.timestamp_s)
            {
                let now = Instant::now();
                if now >= deadline {
                    break;
                }
                let wait = (deadline - now).min(Duration::from_millis(20));
                if !poll_odometry(
                    &mut pipeline,
                    src.as_mut(),
                    wait,
                    &mut report.odometry_errors,
                    output,
                ) {
                    info!("odometry source ended");
                    inputs.odometry = None;
                    break;
                }
            }
        }
        // The gyro, likewise: what has come, then a bounded wait for it to reach this
        // azimuth (radar only with a gyro).
        if pipeline.uses_gyro() {
            feed_gyro(
                &mut pipeline,
                &mut inputs.gyro,
                az.timestamp_s,
                (!far_ahead).then_some(odometry_wait),
                &mut report.gyro_errors,
            );
        }
        let rotations = pipeline.summary().rotations;
        if let Err(e) = pipeline.process_azimuth(&az, &mut events) {
            report.azimuth_errors += 1;
            if report.azimuth_errors <= 3 || report.azimuth_errors.is_power_of_two() {
                error!(error = %e, count = report.azimuth_errors, "azimuth not processed");
            }
        }
        for ev in events.drain(..) {
            output.send(ev);
        }
        // After the events of a rotation this azimuth closed: a recording sees each
        // rotation's azimuths before its end.
        if output.wants_inputs() {
            output.send(OutputEvent::Azimuth(az));
        }
        if pipeline.summary().rotations > rotations {
            if let Some(p) = control.progress.as_mut() {
                p(pipeline.summary(), pipeline.ekf());
            }
        }
        // Stream time is the pipeline's accepted clock, summed over its jumps: one wild
        // timestamp neither ends the run nor stretches it, and a clock that jumps back does
        // not make the run longer.
        if let Some(now) = pipeline.last_time_s() {
            first_time_s.get_or_insert(now);
            let stream_s = pipeline.summary().stream_s();
            if control.max_stream_s.is_some_and(|limit| stream_s >= limit) {
                info!(stream_s, "stream duration reached");
                break;
            }
        }
    }
    report.summary = pipeline.finish(&mut events);
    for ev in events.drain(..) {
        output.send_blocking(ev);
    }
    report.output_drops = output.dropped();
    report.wall_s = started.elapsed().as_secs_f64();
    report
}
