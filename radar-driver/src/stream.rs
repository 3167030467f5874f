//! The hand-off as async streams, for consumers that live in a tokio runtime: bounded
//! `tokio::sync::mpsc` queues behind the same [`Sink`] seam as the crossbeam channels, each
//! end a [`futures_core::Stream`]. A full queue drops the newest item and the driver counts
//! it, as the crossbeam channels' drop-newest policy does (the driver never waits for a
//! consumer). Under the driver's byte budget (every azimuth carries a charge) a full
//! budget drops the new azimuth too: these queues cannot shed their oldest item.

use std::pin::Pin;
use std::task::{Context, Poll};

use tokio::sync::mpsc::{self, error::TrySendError};

use crate::azimuth::{Azimuth, Rotation};
use crate::driver::Driver;
use crate::handoff::{Delivery, HandoffSettings, Sink};
use crate::settings::DriverSettings;

/// A [`Sink`] feeding async streams.
#[derive(Debug)]
pub struct StreamSink {
    azimuths: Option<mpsc::Sender<Azimuth>>,
    rotations: Option<mpsc::Sender<Rotation>>,
    slot_bytes: usize,
}

fn offer<T>(tx: &mpsc::Sender<T>, item: T) -> Delivery {
    match tx.try_send(item) {
        Ok(()) => Delivery::Delivered,
        Err(TrySendError::Full(_)) => Delivery::DroppedNewest,
        Err(TrySendError::Closed(_)) => Delivery::Disconnected,
    }
}

impl Sink for StreamSink {
    fn send_azimuth(&mut self, azimuth: Azimuth) -> Delivery {
        self.azimuths
            .as_ref()
            .map_or(Delivery::NotWanted, |tx| offer(tx, azimuth))
    }

    fn send_rotation(&mut self, rotation: Rotation) -> Delivery {
        self.rotations
            .as_ref()
            .map_or(Delivery::NotWanted, |tx| offer(tx, rotation))
    }

    fn wants_rotations(&self) -> bool {
        self.rotations.is_some()
    }

    fn wants_azimuths(&self) -> bool {
        self.azimuths.is_some()
    }

    /// The queues' items at full capacity (tokio allocates them as they come, up to that).
    fn fixed_bytes(&self) -> usize {
        self.slot_bytes
    }
}

/// Azimuths as they arrive, in order. Ends when the driver stops.
#[derive(Debug)]
pub struct AzimuthStream(mpsc::Receiver<Azimuth>);

/// Whole rotations (assembled only when this stream is asked for). Ends when the driver
/// stops.
#[derive(Debug)]
pub struct RotationStream(mpsc::Receiver<Rotation>);

impl AzimuthStream {
    /// The next azimuth; `None` once the driver has stopped.
    pub async fn next(&mut self) -> Option<Azimuth> {
        self.0.recv().await
    }
}

impl RotationStream {
    /// The next rotation; `None` once the driver has stopped.
    pub async fn next(&mut self) -> Option<Rotation> {
        self.0.recv().await
    }
}

impl futures_core::Stream for AzimuthStream {
    type Item = Azimuth;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Azimuth>> {
        self.0.poll_recv(cx)
    }
}

impl futures_core::Stream for RotationStream {
    type Item = Rotation;

    fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Rotation>> {
        self.0.poll_recv(cx)
    }
}

/// The consumer ends: whichever of the two `settings.handoff` asks for (a `None` capacity
/// means no stream, and for rotations no assembly).
#[derive(Debug)]
pub struct Streams {
    /// Azimuths, when asked for.
    pub azimuths: Option<AzimuthStream>,
    /// Rotations, when asked for.
    pub rotations: Option<RotationStream>,
}

impl StreamSink {
    /// The sink and its streams, with the capacities of `handoff`.
    pub fn new(handoff: HandoffSettings) -> (Self, Streams) {
        let (az_tx, az_rx) = match handoff.azimuth_capacity {
            Some(c) => {
                let (tx, rx) = mpsc::channel(c.max(1));
                (Some(tx), Some(AzimuthStream(rx)))
            }
            None => (None, None),
        };
        let (rot_tx, rot_rx) = match handoff.rotation_capacity {
            Some(c) => {
                let (tx, rx) = mpsc::channel(c.max(1));
                (Some(tx), Some(RotationStream(rx)))
            }
            None => (None, None),
        };
        (
            Self {
                azimuths: az_tx,
                rotations: rot_tx,
                slot_bytes: handoff.slot_bytes(),
            },
            Streams {
                azimuths: az_rx,
                rotations: rot_rx,
            },
        )
    }
}

impl Driver {
    /// A driver handing off through async streams instead of crossbeam channels.
    pub fn with_streams(settings: DriverSettings) -> (Self, Streams) {
        let (sink, streams) = StreamSink::new(settings.handoff);
        (Self::with_sink(settings, Box::new(sink)), streams)
    }
}
