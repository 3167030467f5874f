//! One connection to the radar: handshake, reading, decoding, hand-off, watchdog.
//!
//! The [`SessionState`] (geometry, rotation assembly, sink, metrics, recorder) belongs to
//! the driver and survives reconnections; [`SessionState::serve`] runs one connection until
//! it fails or the shutdown fires.
//!
//! Handshake (`docs/colossus-protocol.md`, section 4): the radar speaks first with its
//! configuration (10); only then does the client send start FFT data (21, or 140 for
//! non-contoured data). A configuration re-sent while streaming replaces the geometry and,
//! as Navtech's 2016 SDK does, is answered with the start message again.
//!
//! Watchdog: the link is declared dead when no whole frame (of any type) has been decoded
//! for `watchdog_timeout`. Bytes alone do not count, so a peer trickling bytes that never
//! complete a frame is reconnected like a silent one. The clock alone does not decide
//! ([`crate::liveness`]): when the deadline passes, whatever the socket already holds is
//! read and decoded first, and only if it holds nothing (or nothing that completes a frame)
//! is the link dead. A process that was itself frozen (stopped, descheduled, stalled) for
//! longer than the watchdog finds the radar's frames waiting in its receive buffer on
//! resume: the link is alive and they are kept, not thrown away with a reconnection. A
//! deadline noticed late with nothing waiting gives the radar a moment more
//! ([`crate::liveness::RESUME_GRACE`]): one frozen with this process has not sent yet.

use std::sync::Arc;
use std::time::Duration;

use bytes::BytesMut;
use protocol::{
    Configuration, DecodeError, FftData, FrameDecoder, Geometry, Message, PayloadError,
};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use crate::assembly::{PushReport, RotationAssembler};
use crate::azimuth::{Azimuth, Rotation};
use crate::budget::AZIMUTH_OVERHEAD_BYTES;
use crate::clock::Clock;
use crate::error::{ErrorChain, SessionError};
use crate::handoff::{Shed, Sink};
use crate::liveness::{bytes_waiting, resume_grace};
use crate::metrics::{DecodeErrorKind, Metrics};
use crate::ratelimit::RateLimiter;
use crate::record::Recorder;
use crate::settings::DriverSettings;
use crate::shutdown::Shutdown;

/// How long a whole frame the decoder holds back (its last bytes could begin the next
/// frame's signature) waits for more bytes before it is taken as it is. A streaming radar
/// sends its next frame within a millisecond; one that has stopped to wait for the client
/// (its configuration, before the start message) would otherwise wait for the watchdog.
/// The simulator waits as long for a client's held command.
pub const HELD_FRAME_WAIT: Duration = Duration::from_millis(50);

impl From<&DecodeError> for DecodeErrorKind {
    fn from(e: &DecodeError) -> Self {
        match e {
            DecodeError::BadSignature { .. } => DecodeErrorKind::Signature,
            DecodeError::BadVersion { .. } => DecodeErrorKind::Version,
            DecodeError::Oversized { .. } => DecodeErrorKind::Oversized,
            DecodeError::Payload { source, .. } => match source {
                PayloadError::Truncated { .. }
                | PayloadError::WrongLength { .. }
                | PayloadError::CutShort { .. } => DecodeErrorKind::Truncated,
                PayloadError::FftDataOffsetTooSmall { .. }
                | PayloadError::FftDataOffsetBeyondPayload { .. }
                | PayloadError::OddBinPayload { .. } => DecodeErrorKind::FftLayout,
                PayloadError::BadNanos { .. } => DecodeErrorKind::Timestamp,
                PayloadError::Protobuf(_) => DecodeErrorKind::Protobuf,
                _ => DecodeErrorKind::Other,
            },
        }
    }
}

/// How a connection ended without error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SessionEnd {
    /// The shutdown fired; stop (22) was sent if data had been requested.
    Shutdown,
}

/// What one connection achieved, whatever its end.
#[derive(Debug)]
pub struct SessionOutcome {
    /// True once the radar's configuration was received on this connection.
    pub configured: bool,
    /// The end.
    pub end: Result<SessionEnd, SessionError>,
}

/// State that outlives a connection.
#[derive(Debug)]
pub struct SessionState {
    pub(crate) settings: DriverSettings,
    pub(crate) sink: Box<dyn Sink>,
    pub(crate) clock: Arc<dyn Clock>,
    pub(crate) metrics: Arc<Metrics>,
    pub(crate) recorder: Option<Recorder>,
    pub(crate) assembler: RotationAssembler,
    pub(crate) geometry: Option<Arc<Geometry>>,
    /// The last configuration received, published for anyone interested (the CLI prints
    /// it; a daemon may log it).
    pub(crate) configuration_tx: tokio::sync::watch::Sender<Option<Arc<Configuration>>>,
    /// Rotations closed because the encoder did not wrap (logged 1st, 2nd, 4th...).
    pub(crate) overlong_rotations: u64,
    /// Rate limits of the log lines the wire can cause.
    pub(crate) logs: LogLimits,
}

/// One [`RateLimiter`] per kind of log line that what arrives on the wire can cause, so a
/// misbehaving radar cannot flood the log. They outlive connections.
#[derive(Debug, Clone)]
pub struct LogLimits {
    /// A configuration re-sent unchanged (INFO).
    pub configuration_repeated: RateLimiter,
    /// A configuration that differs from the one in force (INFO): a radar that alternates
    /// between two must not log at the rate it sends them.
    pub configuration_changed: RateLimiter,
    /// A configuration message that does not decode (WARN).
    pub configuration_undecodable: RateLimiter,
    /// A lost link, about to reconnect (WARN).
    pub link_lost: RateLimiter,
    /// Stop (22) could not be sent at the end of a connection (WARN).
    pub stop_failed: RateLimiter,
    /// A rotation in progress grew past its cap and was discarded (WARN).
    pub rotation_oversized: RateLimiter,
    /// The byte budget was full: an azimuth or a recording chunk dropped (WARN).
    pub budget_full: RateLimiter,
}

impl LogLimits {
    /// Every kind at most once per `interval`.
    pub fn new(interval: Duration) -> Self {
        let limiter = RateLimiter::new(interval);
        Self {
            configuration_repeated: limiter.clone(),
            configuration_changed: limiter.clone(),
            configuration_undecodable: limiter.clone(),
            link_lost: limiter.clone(),
            stop_failed: limiter.clone(),
            rotation_oversized: limiter.clone(),
            budget_full: limiter,
        }
    }
}

/// What handling one message asks of the connection.
enum Reply {
    None,
    StartData,
    /// The configuration is unusable: end the connection.
    Refuse(protocol::GeometryError),
}

impl SessionState {
    /// The geometry from the last configuration received (on any connection).
    pub fn geometry(&self) -> Option<&Arc<Geometry>> {
        self.geometry.as_ref()
    }

    /// Runs one connection until it fails or `shutdown` fires.
    pub async fn serve(
        &mut self,
        mut stream: TcpStream,
        shutdown: &mut Shutdown,
    ) -> SessionOutcome {
        let mut configured = false;
        let mut streaming = false;
        let end = self
            .serve_inner(&mut stream, shutdown, &mut configured, &mut streaming)
            .await;
        if streaming
            && matches!(
                end,
                Ok(SessionEnd::Shutdown)
                    | Err(SessionError::Garbled { .. } | SessionError::BadConfiguration(_))
            )
        {
            // Best effort: the link is alive, so tell the radar to stop before closing.
            match send(
                &mut stream,
                &Message::StopFftData,
                self.settings.stop_timeout,
            )
            .await
            {
                Ok(()) => tracing::debug!("sent stop FFT data (22)"),
                Err(e) => crate::warn_limited!(
                    self.logs.stop_failed,
                    error = %ErrorChain(&e),
                    "could not send stop FFT data (22)"
                ),
            }
            let _ = tokio::time::timeout(self.settings.stop_timeout, stream.shutdown()).await;
        }
        SessionOutcome { configured, end }
    }

    async fn serve_inner(
        &mut self,
        stream: &mut TcpStream,
        shutdown: &mut Shutdown,
        configured: &mut bool,
        streaming: &mut bool,
    ) -> Result<SessionEnd, SessionError> {
        let chunk = self.settings.read_chunk_bytes;
        let watchdog = self.settings.watchdog_timeout;
        let mut buf = BytesMut::with_capacity(chunk * 2);
        let mut record_pending = BytesMut::new();
        let mut decoder = FrameDecoder::new();
        let mut errors_in_a_row = 0u32;
        // The watchdog counts whole decoded frames, not bytes: a peer that trickles bytes
        // without ever completing a frame is as dead as a silent one.
        let expiry = tokio::time::sleep(watchdog);
        tokio::pin!(expiry);
        // The read time of the bytes that completed a held frame (see below).
        let mut last_read_ns = self.clock.monotonic_ns();
        loop {
            buf.reserve(chunk);
            let before = buf.len();
            // A whole frame whose last bytes could begin the next frame's signature is held
            // by the decoder until more bytes tell a cut frame from a whole one; a radar
            // that sends it and then waits (its configuration, before the start message;
            // its last azimuth before a pause) would have it held until the watchdog ends
            // the session. After HELD_FRAME_WAIT without a byte it is taken as it is.
            let holding = decoder.holds_whole_frame(&buf);
            let mut take_held = false;
            let read = tokio::select! {
                biased;
                () = shutdown.triggered() => return Ok(SessionEnd::Shutdown),
                () = &mut expiry => None,
                r = stream.read_buf(&mut buf) => Some(r),
                () = tokio::time::sleep(HELD_FRAME_WAIT), if holding => {
                    take_held = true;
                    Some(Ok(0))
                }
            };
            let read = match read {
                // The deadline has passed (and stays passed until a frame decodes): judge the
                // link by what can be read now. Bytes already in the socket are read and
                // decoded below; the next turn of the loop comes back here until a frame
                // decodes (the watchdog is re-armed) or nothing is left (the link is dead).
                None if bytes_waiting(stream) => Some(stream.read_buf(&mut buf).await),
                // Nothing waiting, but the deadline was noticed late: this process was not
                // running, and a radar frozen with it has not sent yet. A moment more.
                None => match resume_grace(expiry.deadline(), watchdog) {
                    Some(grace) => {
                        tracing::debug!(
                            ?grace,
                            "watchdog deadline noticed late (this process was not running): waiting a moment for the radar"
                        );
                        expiry.as_mut().reset(tokio::time::Instant::now() + grace);
                        continue;
                    }
                    None => None,
                },
                other => other,
            };
            let n = match read {
                None => {
                    self.metrics.add_watchdog_timeouts(1);
                    return Err(SessionError::Watchdog(watchdog));
                }
                Some(Err(e)) => return Err(SessionError::Read(e)),
                Some(Ok(0)) if !take_held => return Err(SessionError::Closed),
                Some(Ok(n)) => n,
            };
            // A held frame keeps the time its last bytes were read.
            let read_ns = if take_held {
                last_read_ns
            } else {
                self.clock.monotonic_ns()
            };
            last_read_ns = read_ns;
            self.metrics.add_bytes(n as u64);
            if self.recorder.is_some() {
                record_pending.extend_from_slice(buf.get(before..).unwrap_or_default());
            }
            let mut frames_this_read = false;
            loop {
                let decoded = if std::mem::take(&mut take_held) {
                    decoder.decode_eof(&mut buf)
                } else {
                    decoder.decode(&mut buf)
                };
                match decoded {
                    Ok(None) => break,
                    Ok(Some(message)) => {
                        errors_in_a_row = 0;
                        self.metrics.add_frames(1);
                        frames_this_read = true;
                        match self.on_message(message, read_ns, configured) {
                            Reply::None => {}
                            Reply::StartData => {
                                let start = self.settings.start_message();
                                send(stream, &start, watchdog).await?;
                                if !*streaming {
                                    tracing::info!(id = start.id(), "requested FFT data");
                                }
                                *streaming = true;
                            }
                            Reply::Refuse(e) => return Err(SessionError::BadConfiguration(e)),
                        }
                    }
                    Err(e) => {
                        self.metrics.add_decode_error(DecodeErrorKind::from(&e));
                        if let DecodeError::Payload {
                            message_id: protocol::message_id::CONFIGURATION,
                            ..
                        } = e
                        {
                            crate::warn_limited!(
                                self.logs.configuration_undecodable,
                                error = %ErrorChain(&e),
                                "undecodable radar configuration message skipped"
                            );
                        } else {
                            tracing::debug!(error = %ErrorChain(&e), "decode error; frame skipped");
                        }
                        errors_in_a_row += 1;
                        if errors_in_a_row >= self.settings.max_consecutive_decode_errors {
                            return Err(SessionError::Garbled {
                                count: errors_in_a_row,
                                last: e,
                            });
                        }
                    }
                }
            }
            if frames_this_read {
                expiry
                    .as_mut()
                    .reset(tokio::time::Instant::now() + watchdog);
            }
            if let Some(recorder) = &self.recorder {
                let consumed = record_pending.len().saturating_sub(buf.len());
                if consumed > 0 {
                    // Copied into a charged allocation of its own: a queued chunk neither
                    // pins the pending buffer nor escapes the byte budget.
                    let chunk = record_pending.split_to(consumed);
                    match self.metrics.budget().copy(&chunk, 0) {
                        Some(bytes) => {
                            self.metrics.add_record_bytes(bytes.len() as u64);
                            recorder.write(bytes);
                        }
                        None => {
                            self.metrics.add_record_budget_drops(1);
                            recorder.count_dropped();
                            crate::warn_limited!(
                                self.logs.budget_full,
                                held_bytes = self.metrics.budget().held(),
                                max_held_bytes = self.metrics.budget().limit(),
                                "the driver's byte budget is full: recording chunk dropped"
                            );
                        }
                    }
                }
            }
        }
    }

    fn on_message(&mut self, message: Message, read_ns: u64, configured: &mut bool) -> Reply {
        match message {
            Message::FftData(fft) => {
                self.on_fft(fft, read_ns);
                Reply::None
            }
            Message::KeepAlive => {
                self.metrics.add_keep_alives(1);
                Reply::None
            }
            Message::Configuration(configuration) => {
                self.on_configuration(*configuration, configured)
            }
            _ => {
                self.metrics.add_other_messages(1);
                Reply::None
            }
        }
    }

    /// A configuration: the first one or a changed one is logged at INFO and replaces the
    /// geometry; one identical to the one in force is counted and logged at most once per
    /// `log_interval`; an unusable one is refused (the connection ends). Any usable one is
    /// answered with the start message (as Navtech's 2016 SDK does).
    fn on_configuration(&mut self, configuration: Configuration, configured: &mut bool) -> Reply {
        self.metrics.add_configurations(1);
        let geometry = match configuration.geometry() {
            Ok(g) => g,
            Err(e) => {
                self.metrics.add_configurations_refused(1);
                return Reply::Refuse(e);
            }
        };
        *configured = true;
        let unchanged = self.configuration_tx.borrow().as_deref() == Some(&configuration);
        if unchanged {
            self.metrics.add_configurations_repeated(1);
            if let Some(suppressed) = self
                .logs
                .configuration_repeated
                .check(tokio::time::Instant::now())
            {
                tracing::info!(
                    repeats = suppressed + 1,
                    "radar re-sent its configuration, unchanged"
                );
            }
            return Reply::StartData;
        }
        if let Some(suppressed) = self
            .logs
            .configuration_changed
            .check(tokio::time::Instant::now())
        {
            tracing::info!(
                azimuths = geometry.azimuth_samples,
                bins = geometry.range_in_bins,
                bin_size_m = geometry.bin_size_m,
                encoder_size = geometry.encoder_size,
                rotation_hz = geometry.rotation_hz,
                width = geometry.data_width.bits(),
                changes_not_logged = suppressed,
                "radar configuration"
            );
        }
        let geometry = Arc::new(geometry);
        if let Some(partial) = self.assembler.set_geometry(Arc::clone(&geometry)) {
            self.deliver_rotation(partial);
        }
        self.geometry = Some(geometry);
        self.configuration_tx
            .send_replace(Some(Arc::new(configuration)));
        Reply::StartData
    }

    fn on_fft(&mut self, fft: FftData, read_ns: u64) {
        let Some(geometry) = &self.geometry else {
            self.metrics.add_fft_before_configuration(1);
            return;
        };
        if fft.azimuth >= geometry.encoder_size {
            self.metrics.add_encoder_out_of_range(1);
            return;
        }
        self.metrics.add_fft_frames(1);
        let geometry = Arc::clone(geometry);
        // The bins are copied out of the read buffer into an allocation charged to the byte
        // budget; when it is full the azimuth is dropped (after shedding the oldest queued
        // items under drop-oldest).
        let bins = self.charge_bins(&fft.bins);
        let mut azimuth = Azimuth::from_fft(fft, geometry);
        // The assembler numbers the rotations (one owner of rotation boundaries): push first,
        // then hand the azimuth on with its rotation number.
        self.assembler
            .set_counting_only(!self.sink.wants_rotations());
        let Some(bins) = bins else {
            let report = self.assembler.push_unheld(&azimuth);
            self.metrics.add_budget_drops(1);
            crate::warn_limited!(
                self.logs.budget_full,
                held_bytes = self.metrics.budget().held(),
                max_held_bytes = self.metrics.budget().limit(),
                azimuth_bytes = azimuth.bins.len(),
                "the driver's byte budget is full (consumer too slow?): azimuth dropped"
            );
            self.after_push(report);
            return;
        };
        azimuth.bins = bins;
        let report = self.assembler.push(azimuth.clone());
        azimuth.rotation = report.rotation;
        if self.sink.wants_azimuths() {
            let delivery = self.sink.send_azimuth(azimuth);
            let sent_ns = self.clock.monotonic_ns();
            self.metrics.add_azimuths_sent(1);
            if delivery.queued() {
                self.metrics.add_azimuths_delivered(1);
            }
            self.metrics.add_azimuth_drops(delivery.dropped());
            self.metrics
                .record_latency_ns(sent_ns.saturating_sub(read_ns));
        }
        self.after_push(report);
    }

    /// The bins copied into an allocation charged to the byte budget; `None` when they do
    /// not fit even after shedding what the sink can shed (drop-oldest).
    fn charge_bins(&mut self, bins: &bytes::Bytes) -> Option<bytes::Bytes> {
        let budget = Arc::clone(self.metrics.budget());
        loop {
            if let Some(charged) = budget.copy(bins, AZIMUTH_OVERHEAD_BYTES) {
                return Some(charged);
            }
            match self.sink.shed_oldest() {
                Some(Shed::Azimuth) => self.metrics.add_azimuth_drops(1),
                Some(Shed::Rotation) => self.metrics.add_rotation_drops(1),
                None => return None,
            }
        }
    }

    /// Counts and logs what pushing one azimuth found, and hands on a finished rotation.
    fn after_push(&mut self, report: PushReport) {
        if report.overlong {
            self.overlong_rotations += 1;
            if self.overlong_rotations.is_power_of_two() {
                tracing::warn!(
                    count = self.overlong_rotations,
                    "the encoder has not wrapped in twice a rotation (stuck?): rotation closed as partial"
                );
            }
        }
        self.metrics
            .add_skipped_azimuths(u64::from(report.skipped_azimuths));
        if report.sweep_missing > 0 {
            self.metrics.add_sweep_gaps(1);
            self.metrics
                .add_sweep_missing(u64::from(report.sweep_missing));
        }
        if let Some(rotation) = report.finished {
            self.deliver_rotation(rotation);
        }
    }

    pub(crate) fn deliver_rotation(&mut self, rotation: Rotation) {
        if !self.sink.wants_rotations() {
            return;
        }
        let delivery = self.sink.send_rotation(rotation);
        self.metrics.add_rotations_sent(1);
        if delivery.queued() {
            self.metrics.add_rotations_delivered(1);
        }
        self.metrics.add_rotation_drops(delivery.dropped());
    }
}

async fn send(
    stream: &mut TcpStream,
    message: &Message,
    timeout: Duration,
) -> Result<(), SessionError> {
    let id = message.id();
    let bytes = message.to_bytes().map_err(|source| SessionError::Encode {
        message_id: id,
        source,
    })?;
    match tokio::time::timeout(timeout, stream.write_all(&bytes)).await {
        Ok(Ok(())) => Ok(()),
        Ok(Err(source)) => Err(SessionError::Write {
            message_id: id,
            source,
        }),
        Err(_) => Err(SessionError::WriteTimeout {
            message_id: id,
            timeout,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_decode_error_maps_to_its_kind() {
        let payload = |source| DecodeError::Payload {
            message_id: 30,
            source,
        };
        let cases = [
            (
                DecodeError::BadSignature { skipped_bytes: 3 },
                DecodeErrorKind::Signature,
            ),
            (
                DecodeError::BadVersion { version: 2 },
                DecodeErrorKind::Version,
            ),
            (
                DecodeError::Oversized {
                    message_id: 30,
                    payload_size: 2_000_000,
                },
                DecodeErrorKind::Oversized,
            ),
            (
                payload(PayloadError::Truncated { needed: 14, got: 3 }),
                DecodeErrorKind::Truncated,
            ),
            (
                payload(PayloadError::FftDataOffsetBeyondPayload {
                    offset: 99,
                    payload_len: 20,
                }),
                DecodeErrorKind::FftLayout,
            ),
            (
                payload(PayloadError::OddBinPayload { len: 3 }),
                DecodeErrorKind::FftLayout,
            ),
            (
                payload(PayloadError::BadNanos {
                    nanos: 1_000_000_000,
                }),
                DecodeErrorKind::Timestamp,
            ),
            (
                payload(PayloadError::BadSectorCount {
                    count: 2,
                    payload_len: 1,
                }),
                DecodeErrorKind::Other,
            ),
        ];
        for (error, kind) in cases {
            assert_eq!(DecodeErrorKind::from(&error), kind, "{error}");
        }
    }
}
