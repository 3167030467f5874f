//! Hand-off from the socket task to the consumers: the [`Sink`] seam and its
//! crossbeam-channel implementation.
//!
//! The socket task must never block on a slow consumer, and nothing may grow without
//! bound, so every send is a `try_send` on a bounded channel and a full channel drops by a
//! stated [`DropPolicy`]:
//!
//! - [`DropPolicy::DropNewest`]: the item that does not fit is discarded; what is queued
//!   stays. The consumer sees an older, gap-free prefix.
//! - [`DropPolicy::DropOldest`]: the sink holds a clone of the receiver and pops the oldest
//!   queued item to make room; the consumer always sees the freshest data. (The channel then
//!   never reports the consumer gone, since the sink itself holds a receiver.)
//!
//! Every drop is counted, so `sent = delivered_to_consumer + dropped` holds exactly once
//! the consumer has drained the channel.
//!
//! Capacities are counts; what bounds the bytes is the driver's [`crate::ByteBudget`]
//! (every queued azimuth carries a charge on it, and under drop-oldest a full budget sheds
//! the oldest queued items first).

use crossbeam_channel::{bounded, Receiver, Sender, TryRecvError, TrySendError};

use crate::azimuth::{Azimuth, Rotation};

/// What a full channel drops.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum DropPolicy {
    /// Keep what is queued; drop the new item (counted).
    #[default]
    DropNewest,
    /// Drop the oldest queued item to make room (counted).
    DropOldest,
}

/// What happened to one item offered to a sink.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery {
    /// Queued for the consumer.
    Delivered,
    /// Queued, after discarding the oldest queued item (drop-oldest).
    DeliveredDroppingOldest,
    /// Discarded because the queue was full (drop-newest).
    DroppedNewest,
    /// Discarded because no consumer is listening any more.
    Disconnected,
    /// This sink does not take this kind of item (not counted as sent).
    NotWanted,
}

impl Delivery {
    /// Whether the offered item entered the queue.
    pub fn queued(self) -> bool {
        matches!(
            self,
            Delivery::Delivered | Delivery::DeliveredDroppingOldest
        )
    }

    /// Items discarded by this offer (the new one or an old one): 0 or 1.
    pub fn dropped(self) -> u64 {
        match self {
            Delivery::DeliveredDroppingOldest
            | Delivery::DroppedNewest
            | Delivery::Disconnected => 1,
            Delivery::Delivered | Delivery::NotWanted => 0,
        }
    }
}

/// Where the driver puts what it assembled. Implementations must not block.
pub trait Sink: Send + std::fmt::Debug {
    /// Offers one azimuth.
    fn send_azimuth(&mut self, azimuth: Azimuth) -> Delivery;
    /// Offers one rotation.
    fn send_rotation(&mut self, rotation: Rotation) -> Delivery;
    /// Whether whole rotations are wanted; when false the driver still assembles them for
    /// the skip and gap counts but does not offer them.
    fn wants_rotations(&self) -> bool;
    /// Whether single azimuths are wanted.
    fn wants_azimuths(&self) -> bool;
    /// Drops the oldest queued item to give its bytes back to the driver's
    /// [`crate::ByteBudget`], if this sink's policy is drop-oldest (an azimuth first, else
    /// a rotation); `None` when nothing was dropped. The default drops nothing.
    fn shed_oldest(&mut self) -> Option<Shed> {
        None
    }
    /// Bytes this sink holds whatever flows through it (its queues' slot arrays), charged
    /// once to the driver's budget. The default is nothing.
    fn fixed_bytes(&self) -> usize {
        0
    }
}

/// What [`Sink::shed_oldest`] dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shed {
    /// The oldest queued azimuth.
    Azimuth,
    /// The oldest queued rotation.
    Rotation,
}

/// Channel capacities and drop policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HandoffSettings {
    /// Azimuth channel capacity; `None` for no azimuth channel.
    pub azimuth_capacity: Option<usize>,
    /// Rotation channel capacity; `None` for no rotation channel.
    pub rotation_capacity: Option<usize>,
    /// What to drop when a channel is full.
    pub drop_policy: DropPolicy,
}

impl HandoffSettings {
    /// The bytes of the channels' slot arrays, allocated up front whatever flows: per slot
    /// the item's size and a stamp. Charged once to the driver's byte budget.
    pub fn slot_bytes(&self) -> usize {
        fn slots<T>(capacity: Option<usize>) -> usize {
            capacity.map_or(0, |c| {
                c.max(1)
                    .saturating_mul(std::mem::size_of::<T>() + std::mem::size_of::<usize>())
            })
        }
        slots::<Azimuth>(self.azimuth_capacity)
            .saturating_add(slots::<Rotation>(self.rotation_capacity))
    }
}

impl Default for HandoffSettings {
    fn default() -> Self {
        Self {
            azimuth_capacity: Some(4096),
            rotation_capacity: Some(8),
            drop_policy: DropPolicy::DropNewest,
        }
    }
}

/// The consumer ends of the channels.
#[derive(Debug, Clone)]
pub struct Receivers {
    /// One message per azimuth, when configured.
    pub azimuths: Option<Receiver<Azimuth>>,
    /// One message per rotation, when configured.
    pub rotations: Option<Receiver<Rotation>>,
}

#[derive(Debug)]
struct Lane<T> {
    tx: Sender<T>,
    /// Held only under drop-oldest, to pop the oldest item.
    rx: Option<Receiver<T>>,
}

impl<T> Lane<T> {
    fn new(capacity: usize, policy: DropPolicy) -> (Self, Receiver<T>) {
        let (tx, rx) = bounded(capacity.max(1));
        let own = match policy {
            DropPolicy::DropOldest => Some(rx.clone()),
            DropPolicy::DropNewest => None,
        };
        (Self { tx, rx: own }, rx)
    }

    /// Drops the oldest queued item (drop-oldest only): whether one was dropped.
    fn shed(&self) -> bool {
        self.rx.as_ref().is_some_and(|rx| rx.try_recv().is_ok())
    }

    fn offer(&self, item: T) -> Delivery {
        match self.tx.try_send(item) {
            Ok(()) => Delivery::Delivered,
            Err(TrySendError::Disconnected(_)) => Delivery::Disconnected,
            Err(TrySendError::Full(item)) => match &self.rx {
                None => Delivery::DroppedNewest,
                Some(rx) => {
                    let popped = match rx.try_recv() {
                        Ok(_old) => true,
                        // The consumer emptied the queue in the meantime.
                        Err(TryRecvError::Empty) => false,
                        Err(TryRecvError::Disconnected) => return Delivery::Disconnected,
                    };
                    // We are the only sender, so after a pop there is room.
                    match (self.tx.try_send(item), popped) {
                        (Ok(()), true) => Delivery::DeliveredDroppingOldest,
                        (Ok(()), false) => Delivery::Delivered,
                        (Err(TrySendError::Disconnected(_)), _) => Delivery::Disconnected,
                        (Err(TrySendError::Full(_)), true) => {
                            // Only possible with a second sender; count both losses.
                            Delivery::DroppedNewest
                        }
                        (Err(TrySendError::Full(_)), false) => Delivery::DroppedNewest,
                    }
                }
            },
        }
    }
}

/// A [`Sink`] over bounded crossbeam channels.
#[derive(Debug)]
pub struct ChannelSink {
    azimuths: Option<Lane<Azimuth>>,
    rotations: Option<Lane<Rotation>>,
    slot_bytes: usize,
}

impl ChannelSink {
    /// Creates the channels; returns the sink for the driver and the receivers for the
    /// consumers.
    pub fn new(settings: HandoffSettings) -> (Self, Receivers) {
        let (az_lane, az_rx) = match settings.azimuth_capacity {
            Some(c) => {
                let (lane, rx) = Lane::new(c, settings.drop_policy);
                (Some(lane), Some(rx))
            }
            None => (None, None),
        };
        let (rot_lane, rot_rx) = match settings.rotation_capacity {
            Some(c) => {
                let (lane, rx) = Lane::new(c, settings.drop_policy);
                (Some(lane), Some(rx))
            }
            None => (None, None),
        };
        (
            Self {
                azimuths: az_lane,
                rotations: rot_lane,
                slot_bytes: settings.slot_bytes(),
            },
            Receivers {
                azimuths: az_rx,
                rotations: rot_rx,
            },
        )
    }
}

impl Sink for ChannelSink {
    fn send_azimuth(&mut self, azimuth: Azimuth) -> Delivery {
        self.azimuths
            .as_ref()
            .map_or(Delivery::NotWanted, |lane| lane.offer(azimuth))
    }

    fn send_rotation(&mut self, rotation: Rotation) -> Delivery {
        self.rotations
            .as_ref()
            .map_or(Delivery::NotWanted, |lane| lane.offer(rotation))
    }

    fn wants_rotations(&self) -> bool {
        self.rotations.is_some()
    }

    fn wants_azimuths(&self) -> bool {
        self.azimuths.is_some()
    }

    fn shed_oldest(&mut self) -> Option<Shed> {
        if self.azimuths.as_ref().is_some_and(Lane::shed) {
            return Some(Shed::Azimuth);
        }
        self.rotations
            .as_ref()
            .is_some_and(Lane::shed)
            .then_some(Shed::Rotation)
    }

    fn fixed_bytes(&self) -> usize {
        self.slot_bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drop_newest_keeps_the_queue_and_discards_the_new_item() {
        let (lane, rx) = Lane::new(2, DropPolicy::DropNewest);
        assert_eq!(lane.offer(1), Delivery::Delivered);
        assert_eq!(lane.offer(2), Delivery::Delivered);
        assert_eq!(lane.offer(3), Delivery::DroppedNewest);
        assert_eq!(rx.try_iter().collect::<Vec<_>>(), vec![1, 2]);
    }

    #[test]
    fn drop_oldest_discards_the_head_to_make_room() {
        let (lane, rx) = Lane::new(2, DropPolicy::DropOldest);
        assert_eq!(lane.offer(1), Delivery::Delivered);
        assert_eq!(lane.offer(2), Delivery::Delivered);
        assert_eq!(lane.offer(3), Delivery::DeliveredDroppingOldest);
        assert_eq!(lane.offer(4), Delivery::DeliveredDroppingOldest);
        assert_eq!(rx.try_iter().collect::<Vec<_>>(), vec![3, 4]);
    }

    #[test]
    fn only_drop_oldest_sheds_the_oldest_queued_item_for_the_byte_budget() {
        let (oldest, rx) = Lane::new(4, DropPolicy::DropOldest);
        oldest.offer(1);
        oldest.offer(2);
        assert!(oldest.shed());
        assert_eq!(rx.try_iter().collect::<Vec<_>>(), vec![2]);
        assert!(!oldest.shed(), "nothing left to shed");
        let (newest, rx) = Lane::new(4, DropPolicy::DropNewest);
        newest.offer(1);
        assert!(!newest.shed());
        assert_eq!(rx.len(), 1);
    }

    #[test]
    fn a_gone_consumer_is_reported_under_drop_newest() {
        let (lane, rx) = Lane::new(2, DropPolicy::DropNewest);
        drop(rx);
        assert_eq!(lane.offer(1), Delivery::Disconnected);
        assert_eq!(Delivery::Disconnected.dropped(), 1);
    }

    #[test]
    fn sent_equals_received_plus_dropped_under_both_policies() {
        for policy in [DropPolicy::DropNewest, DropPolicy::DropOldest] {
            let (lane, rx) = Lane::new(7, policy);
            let mut dropped = 0;
            let mut received = 0;
            for i in 0..1000u32 {
                dropped += lane.offer(i).dropped();
                if i % 3 == 0 {
                    received += rx.try_iter().take(1).count() as u64;
                }
            }
            received += rx.try_iter().count() as u64;
            assert_eq!(received + dropped, 1000, "{policy:?}");
        }
    }
}
