//! The shared state every connection streams from: the source (a scene or a recording),
//! the configuration it announces, and the scene's timeline.
//!
//! Scene time: azimuth `k` is measured `offset_ns(k)` after the start. In real time the
//! wall clock decides which azimuth is current; as fast as possible, the **frontier** (the
//! next azimuth no client has been sent yet) is the current time, so a client that
//! connects or reconnects carries on from where the world is, odometry follows the radar,
//! and the ground truth is written up to what was served.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use protocol::Configuration;

use crate::radar::RadarParams;
use crate::render::{offset_ns, SceneRenderer};
use crate::replay::raw::RawRecording;
use crate::replay::ScanRecording;
use crate::settings::{Pacing, ShapingScope};

use super::shaping::Shaping;

/// What the world streams.
#[derive(Debug)]
pub(crate) enum Source {
    Scene(Arc<SceneRenderer>),
    Png(Arc<ScanRecording>),
    Raw(Arc<RawRecording>),
}

/// Shared by all connections of one server.
#[derive(Debug)]
pub(crate) struct World {
    pub source: Source,
    pub configuration: Configuration,
    pub pacing: Pacing,
    /// Wall-clock instant of azimuth 0 (real time) / of the server's start.
    pub wall_start: Instant,
    /// Unix time of azimuth 0, nanoseconds (scenes).
    pub start_unix_ns: u64,
    /// Next azimuth index not yet sent to any client (scenes, as fast as possible).
    frontier: AtomicU64,
    /// Scenes end after this many azimuths.
    pub stop_after: Option<u64>,
    pub replay_loop: bool,
    /// The radar's contour and blanked sectors, shared by every connection
    /// ([`crate::settings::ShapingScope::Radar`]); `None`: each connection has its own.
    pub shaping: Option<Arc<Mutex<Shaping>>>,
}

/// The configuration message a simulated radar with `radar` announces.
pub fn configuration_of(radar: &RadarParams) -> Configuration {
    radar.configuration()
}

impl World {
    /// A world whose azimuth 0 is now on the wall clock; `start_unix_ns` is its Unix time
    /// (`None`: the system clock's now, taken at the same moment).
    pub fn new(
        source: Source,
        configuration: Configuration,
        pacing: Pacing,
        start_unix_ns: Option<u64>,
        stop_after: Option<u64>,
        replay_loop: bool,
        shaping_scope: ShapingScope,
    ) -> World {
        let wall_start = Instant::now();
        let now_unix_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(0));
        World {
            source,
            configuration,
            pacing,
            wall_start,
            start_unix_ns: start_unix_ns.unwrap_or(now_unix_ns),
            frontier: AtomicU64::new(0),
            stop_after,
            replay_loop,
            shaping: (shaping_scope == ShapingScope::Radar)
                .then(|| Arc::new(Mutex::new(Shaping::default()))),
        }
    }

    /// The scene's radar, if the source is a scene.
    pub fn scene(&self) -> Option<&Arc<SceneRenderer>> {
        match &self.source {
            Source::Scene(r) => Some(r),
            _ => None,
        }
    }

    /// The first azimuth index at or after `elapsed_ns` on the scene's clock.
    fn index_at_elapsed(radar: &RadarParams, elapsed_ns: u64) -> u64 {
        let per_s = u128::from(radar.azimuths) * u128::from(radar.rotation_mhz);
        let num = u128::from(elapsed_ns) * per_s;
        let index = num.div_ceil(1_000_000_000_000);
        u64::try_from(index).unwrap_or(u64::MAX)
    }

    /// The azimuth index that is "now" for a scene: the wall clock's in real time, the
    /// frontier otherwise.
    pub fn current_index(&self) -> u64 {
        match (self.pacing, self.scene()) {
            (Pacing::Realtime, Some(scene)) => {
                let elapsed =
                    u64::try_from(self.wall_start.elapsed().as_nanos()).unwrap_or(u64::MAX);
                Self::index_at_elapsed(scene.radar(), elapsed)
            }
            _ => self.frontier.load(Ordering::Acquire),
        }
    }

    /// Scene time of "now", nanoseconds after azimuth 0.
    pub fn current_offset_ns(&self) -> u64 {
        match (self.pacing, self.scene()) {
            (Pacing::Realtime, _) => {
                u64::try_from(self.wall_start.elapsed().as_nanos()).unwrap_or(u64::MAX)
            }
            (Pacing::AsFastAsPossible, Some(scene)) => {
                offset_ns(scene.radar(), self.current_index())
            }
            (Pacing::AsFastAsPossible, None) => 0,
        }
    }

    /// Records that azimuth `index` was sent.
    pub fn note_sent(&self, index: u64) {
        self.frontier
            .fetch_max(index.saturating_add(1), Ordering::AcqRel);
    }

    /// Whether the scene has ended before azimuth `index`.
    pub fn ended_at(&self, index: u64) -> bool {
        self.stop_after.is_some_and(|n| index >= n)
    }
}
