//! A back-pressuring hand-off for runs against the embedded simulator paced as fast as
//! possible: instead of dropping azimuths when the pipeline is behind, the driver's task
//! waits (inside `block_in_place`, so the runtime moves its other tasks away), the socket
//! stops being read, and TCP back-pressure slows the simulator to the pipeline's pace.
//! A live radar does not wait for anyone: against it the driver's own drop policy applies.

use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
use radar_driver::{Azimuth, Delivery, Rotation, Sink};

/// A sink that blocks when its bounded channel is full.
#[derive(Debug)]
pub struct BlockingSink {
    tx: Sender<Azimuth>,
}

impl BlockingSink {
    /// A sink and its receiver, `capacity` azimuths in flight.
    pub fn new(capacity: usize) -> (Self, Receiver<Azimuth>) {
        let (tx, rx) = bounded(capacity.max(1));
        (Self { tx }, rx)
    }
}

impl Sink for BlockingSink {
    fn send_azimuth(&mut self, azimuth: Azimuth) -> Delivery {
        let item = match self.tx.try_send(azimuth) {
            Ok(()) => return Delivery::Delivered,
            Err(TrySendError::Disconnected(_)) => return Delivery::Disconnected,
            Err(TrySendError::Full(item)) => item,
        };
        let multi_thread = tokio::runtime::Handle::try_current()
            .is_ok_and(|h| h.runtime_flavor() == tokio::runtime::RuntimeFlavor::MultiThread);
        let sent = if multi_thread {
            tokio::task::block_in_place(|| self.tx.send(item))
        } else {
            // A current-thread runtime cannot block: drop, as the driver would.
            return Delivery::DroppedNewest;
        };
        match sent {
            Ok(()) => Delivery::Delivered,
            Err(_) => Delivery::Disconnected,
        }
    }

    fn send_rotation(&mut self, _rotation: Rotation) -> Delivery {
        Delivery::NotWanted
    }

    fn wants_rotations(&self) -> bool {
        false
    }

    fn wants_azimuths(&self) -> bool {
        true
    }
}
