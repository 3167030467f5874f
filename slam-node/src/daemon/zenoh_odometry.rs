//! The vehicle's odometry over Zenoh (`[odometry] source = "zenoh"`, feature `zenoh`):
//! `nav_msgs/msg/Odometry` or `geometry_msgs/msg/TwistStamped` on a ROS 2 topic, keyed by
//! `[output.zenoh] convention`, decoded as an MCAP replay decodes its odometry topic
//! ([`crate::output::ros::OdometryMessage`]) and handed to the pipeline through the same
//! [`OdometrySource`] seam the TCP odometry client feeds.
//!
//! A peer's bad input costs that message only: a payload that does not decode (garbage,
//! truncated, another type's layout) is counted as malformed, a sample whose encoding names
//! another ROS type as of another type; the first ten and then every power of two are logged.
//! Decoding runs in Zenoh's callback and never blocks: decoded records go to the pipeline on
//! a bounded channel, and a full channel drops the record and counts it.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// What the Zenoh odometry subscription received.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ZenohOdometryCounts {
    /// The key subscribed to.
    pub key: String,
    /// Samples received.
    pub received: u64,
    /// Records decoded and handed to the pipeline.
    pub decoded: u64,
    /// Samples whose payload did not decode.
    pub malformed: u64,
    /// Samples whose encoding named another ROS type.
    pub wrong_type: u64,
    /// Records dropped because the pipeline's channel was full.
    pub dropped: u64,
}

impl ZenohOdometryCounts {
    /// Samples lost for any reason.
    pub fn lost(&self) -> u64 {
        self.malformed + self.wrong_type + self.dropped
    }
}

/// The subscription's live counters (the prior pose's subscription, `zenoh_prior`, keeps
/// the same).
#[derive(Debug, Default)]
pub struct ZenohOdometryStats {
    pub(crate) key: String,
    pub(crate) received: AtomicU64,
    pub(crate) decoded: AtomicU64,
    pub(crate) malformed: AtomicU64,
    pub(crate) wrong_type: AtomicU64,
    pub(crate) dropped: AtomicU64,
}

impl ZenohOdometryStats {
    /// A copy of the counters.
    pub fn snapshot(&self) -> ZenohOdometryCounts {
        let g = |a: &AtomicU64| a.load(Ordering::Relaxed);
        ZenohOdometryCounts {
            key: self.key.clone(),
            received: g(&self.received),
            decoded: g(&self.decoded),
            malformed: g(&self.malformed),
            wrong_type: g(&self.wrong_type),
            dropped: g(&self.dropped),
        }
    }

    /// Samples lost so far for any reason.
    pub fn lost(&self) -> u64 {
        self.malformed.load(Ordering::Relaxed)
            + self.wrong_type.load(Ordering::Relaxed)
            + self.dropped.load(Ordering::Relaxed)
    }
}

/// Shared handle to the counters.
pub type SharedStats = Arc<ZenohOdometryStats>;

#[cfg(feature = "zenoh")]
pub use subscriber::ZenohOdometry;

#[cfg(feature = "zenoh")]
pub(crate) mod subscriber {
    use std::sync::atomic::Ordering;
    use std::sync::Arc;
    use std::time::Duration;

    use crossbeam_channel::{bounded, Receiver, TrySendError};
    use radar_driver::{OdometryError, OdometryPoll, OdometryRecord, OdometrySource};
    use radar_model::motion::MotionModel;
    use tracing::{info, warn};

    use super::{SharedStats, ZenohOdometryStats};
    use crate::output::live::LiveError;
    use crate::output::ros::OdometryMessage;
    use crate::output::zenoh_node::{Subscription, ZenohNode};

    /// Records waiting for the pipeline (about 50 s at 20 Hz); more are dropped and counted.
    pub const CAPACITY: usize = 1024;

    /// A subscription whose samples are decoded in Zenoh's callback and handed to the
    /// pipeline on a bounded channel, never blocking: each sample counted as received, then
    /// as taken, or as lost (another ROS type named by its encoding, a payload that does not
    /// decode, the channel full), the first ten losses and then every power of two logged.
    /// Odometry and prior poses share it.
    #[derive(Debug)]
    pub struct Decoded<T> {
        /// The decoded messages.
        pub rx: Receiver<T>,
        stats: SharedStats,
        _subscription: Subscription,
    }

    impl<T: Send + 'static> Decoded<T> {
        /// Subscribes to `topic` (`ros_type`, `package/msg/Type`) on `node`, decoding each
        /// payload with `decode`, at most `capacity` waiting; `what` names the messages in
        /// the log.
        pub fn subscribe<E: std::fmt::Display>(
            node: &ZenohNode,
            topic: &str,
            ros_type: &str,
            capacity: usize,
            what: &'static str,
            decode: impl Fn(&[u8]) -> Result<T, E> + Send + Sync + 'static,
        ) -> Result<Self, LiveError> {
            let (tx, rx) = bounded(capacity);
            let stats = Arc::new(ZenohOdometryStats {
                key: node.key(topic, ros_type)?,
                ..ZenohOdometryStats::default()
            });
            let s = Arc::clone(&stats);
            let expected = ros_type.to_owned();
            let lost = move |s: &ZenohOdometryStats, why: &str, detail: &str| {
                let n = s.lost();
                if n <= 10 || n.is_power_of_two() {
                    warn!(key = %s.key, why, detail, lost = n, "{what} from Zenoh lost");
                }
            };
            let subscription = node.subscriber(topic, ros_type, move |sample| {
                s.received.fetch_add(1, Ordering::Relaxed);
                if names_other_than(sample.encoding(), &expected) {
                    s.wrong_type.fetch_add(1, Ordering::Relaxed);
                    lost(&s, "another type", &sample.encoding().to_string());
                    return;
                }
                match decode(&sample.payload().to_bytes()) {
                    Ok(item) => match tx.try_send(item) {
                        Ok(()) => {
                            s.decoded.fetch_add(1, Ordering::Relaxed);
                        }
                        Err(TrySendError::Full(_)) => {
                            s.dropped.fetch_add(1, Ordering::Relaxed);
                            lost(&s, "queue full", "the pipeline is behind");
                        }
                        Err(TrySendError::Disconnected(_)) => {}
                    },
                    Err(e) => {
                        s.malformed.fetch_add(1, Ordering::Relaxed);
                        lost(&s, "malformed", &e.to_string());
                    }
                }
            })?;
            info!(key = %subscription.key, message = %ros_type, "{what} from Zenoh");
            Ok(Self {
                rx,
                stats,
                _subscription: subscription,
            })
        }

        /// The counters (live).
        pub fn stats(&self) -> SharedStats {
            Arc::clone(&self.stats)
        }
    }

    /// Whether a sample's encoding names a ROS type other than `expected` (`package/msg/Type`;
    /// `package/Type` is the same type); no schema is not.
    fn names_other_than(encoding: &zenoh::bytes::Encoding, expected: &str) -> bool {
        let text = encoding.to_string();
        match text.split_once(';') {
            Some((_, schema)) if !schema.is_empty() => {
                schema != expected && schema != expected.replacen("/msg/", "/", 1)
            }
            _ => false,
        }
    }

    /// The pipeline's end of the odometry subscription.
    #[derive(Debug)]
    pub struct ZenohOdometry(Decoded<OdometryRecord>);

    impl ZenohOdometry {
        /// Subscribes to `topic` (`message`) on `node`, decoding under `motion`.
        pub fn subscribe(
            node: &ZenohNode,
            topic: &str,
            message: OdometryMessage,
            motion: MotionModel,
        ) -> Result<Self, LiveError> {
            Decoded::subscribe(
                node,
                topic,
                &message.type_name(),
                CAPACITY,
                "odometry",
                move |payload| message.decode(payload, &motion),
            )
            .map(Self)
        }

        /// The counters (live).
        pub fn stats(&self) -> SharedStats {
            self.0.stats()
        }
    }

    impl OdometrySource for ZenohOdometry {
        fn poll_next(&mut self, timeout: Duration) -> Result<OdometryPoll, OdometryError> {
            Ok(radar_driver::odometry::poll_channel(&self.0.rx, timeout))
        }
    }
}
