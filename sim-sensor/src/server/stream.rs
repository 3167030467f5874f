//! One client's stream of azimuths, rendered (or read) on demand, one frame at a time, so a
//! slow client holds at most one frame in memory.

use std::sync::Arc;
use std::time::{Duration, Instant};

use bytes::BytesMut;
use protocol::{encode_fft_frame, BinWidth, Message, Timestamp};

use super::world::{Source, World};
use super::SimStats;
use crate::error::ClientError;
use crate::render::RenderCursor;
use crate::replay::png::PolarScan;
use crate::replay::raw::{RawReader, RawRecording};
use crate::replay::ScanRecording;
use crate::settings::Pacing;

/// Largest gap between two recorded timestamps that a real-time replay waits out.
const MAX_REPLAY_GAP: Duration = Duration::from_secs(2);

/// One produced azimuth.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Produced {
    /// When to send it (real time); `None` = at once.
    pub due: Option<Instant>,
    /// The fault injector asked to leave it out: nothing was written.
    pub skipped: bool,
}

pub(crate) enum AzimuthStream {
    Scene(Box<SceneStream>),
    Png(PngStream),
    Raw(Box<RawStream>),
}

impl std::fmt::Debug for AzimuthStream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            AzimuthStream::Scene(_) => "AzimuthStream::Scene",
            AzimuthStream::Png(_) => "AzimuthStream::Png",
            AzimuthStream::Raw(_) => "AzimuthStream::Raw",
        })
    }
}

pub(crate) struct SceneStream {
    world: Arc<World>,
    cursor: RenderCursor,
    next: u64,
}

pub(crate) struct PngStream {
    world: Arc<World>,
    stats: Arc<SimStats>,
    recording: Arc<ScanRecording>,
    file: usize,
    scan: Option<PolarScan>,
    row: usize,
    produced: u64,
    /// Azimuths produced since the recording last started over (a looping replay whose
    /// every scan is damaged ends instead of spinning).
    produced_this_pass: u64,
    sweep: u16,
    pacer: ReplayPacer,
}

pub(crate) struct RawStream {
    world: Arc<World>,
    recording: Arc<RawRecording>,
    reader: RawReader,
    produced: u64,
    pacer: ReplayPacer,
}

/// Paces a replay by its own timestamps.
#[derive(Debug, Default)]
struct ReplayPacer {
    anchor: Option<(Instant, u64)>,
    last_ns: u64,
    last_due: Option<Instant>,
}

impl ReplayPacer {
    fn due(&mut self, pacing: Pacing, timestamp_ns: u64) -> Option<Instant> {
        if pacing == Pacing::AsFastAsPossible {
            return None;
        }
        let now = Instant::now();
        let (anchor_wall, anchor_ns) = *self.anchor.get_or_insert((now, timestamp_ns));
        let mut due = anchor_wall + Duration::from_nanos(timestamp_ns.saturating_sub(anchor_ns));
        // Time going backwards, or a long gap: re-anchor so the replay never stalls.
        let gap = timestamp_ns.saturating_sub(self.last_ns);
        if timestamp_ns < self.last_ns || Duration::from_nanos(gap) > MAX_REPLAY_GAP {
            let base = self.last_due.unwrap_or(now);
            self.anchor = Some((base, timestamp_ns));
            due = base;
        }
        self.last_ns = timestamp_ns;
        self.last_due = Some(due);
        Some(due)
    }
}

fn timestamp_ns(ts: Timestamp) -> u64 {
    u64::from(ts.seconds()) * 1_000_000_000 + u64::from(ts.nanos())
}

/// The wire timestamp of `unix_ns`.
pub(crate) fn wire_timestamp(unix_ns: u64) -> Timestamp {
    let secs = u32::try_from(unix_ns / 1_000_000_000).unwrap_or(u32::MAX);
    let nanos = u32::try_from(unix_ns % 1_000_000_000).unwrap_or(0);
    Timestamp::new(secs, nanos).unwrap_or_default()
}

impl AzimuthStream {
    /// A new stream positioned at "now" (scenes) or at the start (recordings).
    pub(crate) async fn open(
        world: &Arc<World>,
        stats: &Arc<SimStats>,
    ) -> Result<AzimuthStream, ClientError> {
        Ok(match &world.source {
            Source::Scene(renderer) => AzimuthStream::Scene(Box::new(SceneStream {
                world: Arc::clone(world),
                cursor: renderer.cursor(),
                next: world.current_index(),
            })),
            Source::Png(recording) => AzimuthStream::Png(PngStream {
                world: Arc::clone(world),
                stats: Arc::clone(stats),
                recording: Arc::clone(recording),
                file: 0,
                scan: None,
                row: 0,
                produced: 0,
                produced_this_pass: 0,
                sweep: 0,
                pacer: ReplayPacer::default(),
            }),
            Source::Raw(recording) => AzimuthStream::Raw(Box::new(RawStream {
                world: Arc::clone(world),
                recording: Arc::clone(recording),
                reader: RawReader::open(&recording.path).await?,
                produced: 0,
                pacer: ReplayPacer::default(),
            })),
        })
    }

    /// Writes the next azimuth's frame into `dst` (cleared first) unless `skip`; `None` when
    /// the stream has ended.
    pub(crate) async fn next(
        &mut self,
        dst: &mut BytesMut,
        skip: bool,
    ) -> Result<Option<Produced>, ClientError> {
        dst.clear();
        match self {
            AzimuthStream::Scene(s) => s.next(dst, skip),
            AzimuthStream::Png(s) => s.next(dst, skip).await,
            AzimuthStream::Raw(s) => s.next(dst, skip).await,
        }
    }
}

impl SceneStream {
    fn next(&mut self, dst: &mut BytesMut, skip: bool) -> Result<Option<Produced>, ClientError> {
        let world = &*self.world;
        let Some(renderer) = world.scene() else {
            return Ok(None);
        };
        let radar = renderer.radar();
        if world.pacing == Pacing::Realtime {
            // A client more than one rotation behind the wall clock is moved to "now", as a
            // real radar would not wait for it either.
            let now = world.current_index();
            let rotation = u64::from(radar.azimuths);
            if now > self.next.saturating_add(rotation) {
                let jumped = now - self.next;
                tracing::warn!(
                    jumped,
                    "client fell more than a rotation behind real time; skipping ahead"
                );
                self.next = now;
            }
        }
        let index = self.next;
        if world.ended_at(index) {
            return Ok(None);
        }
        self.next += 1;
        let offset = renderer.offset_ns(index);
        let due = match world.pacing {
            Pacing::Realtime => Some(world.wall_start + Duration::from_nanos(offset)),
            Pacing::AsFastAsPossible => None,
        };
        world.note_sent(index);
        if skip {
            return Ok(Some(Produced { due, skipped: true }));
        }
        let timestamp = wire_timestamp(world.start_unix_ns.saturating_add(offset));
        let sweep = u16::try_from(index % 65_536).unwrap_or(0);
        self.cursor
            .render(index, sweep, timestamp, dst)
            .map_err(|e| ClientError::Internal(format!("rendering failed: {e}")))?;
        Ok(Some(Produced {
            due,
            skipped: false,
        }))
    }
}

impl PngStream {
    async fn next(
        &mut self,
        dst: &mut BytesMut,
        skip: bool,
    ) -> Result<Option<Produced>, ClientError> {
        loop {
            if self.scan.is_none() {
                if self.file >= self.recording.scans.files.len() {
                    if !self.world.replay_loop || self.produced_this_pass == 0 {
                        return Ok(None);
                    }
                    self.file = 0;
                    self.produced_this_pass = 0;
                }
                let recording = Arc::clone(&self.recording);
                let index = self.file;
                let read = tokio::task::spawn_blocking(move || recording.read(index))
                    .await
                    .map_err(|e| ClientError::Internal(format!("scan reader task: {e}")))?;
                match read {
                    Ok(scan) => {
                        self.scan = Some(scan);
                        self.row = 0;
                    }
                    Err(error) => {
                        // A damaged scan costs that scan only.
                        self.stats
                            .scans_skipped
                            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if let Ok(mut first) = self.stats.first_scan_skipped.lock() {
                            first.get_or_insert_with(|| error.to_string());
                        }
                        self.recording.damaged.record(&error);
                        self.file += 1;
                        continue;
                    }
                }
            }
            let Some(scan) = &self.scan else { continue };
            let Some(row) = scan.rows.get(self.row) else {
                self.scan = None;
                self.file += 1;
                continue;
            };
            self.row += 1;
            if !row.valid {
                continue;
            }
            // Checked by `ScanRecording::read`.
            let Ok(timestamp) = row.wire_timestamp() else {
                continue;
            };
            let due = self.pacer.due(self.world.pacing, timestamp_ns(timestamp));
            self.produced += 1;
            self.produced_this_pass += 1;
            let sweep = self.sweep;
            self.sweep = self.sweep.wrapping_add(1);
            if !skip {
                encode_fft_frame(
                    dst,
                    BinWidth::Eight,
                    sweep,
                    row.encoder,
                    timestamp,
                    &row.bins,
                )
                .map_err(|e| ClientError::Internal(format!("encoding a replayed row: {e}")))?;
            }
            return Ok(Some(Produced { due, skipped: skip }));
        }
    }
}

impl RawStream {
    async fn next(
        &mut self,
        dst: &mut BytesMut,
        skip: bool,
    ) -> Result<Option<Produced>, ClientError> {
        let fft = match self.reader.next_fft().await? {
            Some(fft) => fft,
            None if self.world.replay_loop && self.produced > 0 => {
                self.reader = RawReader::open(&self.recording.path).await?;
                match self.reader.next_fft().await? {
                    Some(fft) => fft,
                    None => return Ok(None),
                }
            }
            None => return Ok(None),
        };
        let due = self
            .pacer
            .due(self.world.pacing, timestamp_ns(fft.timestamp));
        self.produced += 1;
        if !skip {
            Message::FftData(fft)
                .encode(dst)
                .map_err(|e| ClientError::Internal(format!("re-encoding a recorded frame: {e}")))?;
        }
        Ok(Some(Produced { due, skipped: skip }))
    }
}
