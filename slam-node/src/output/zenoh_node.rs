//! One Zenoh session as one ROS 2 node (feature `zenoh`): opened from `[output.zenoh]`,
//! shared by the live publisher ([`super::live`]) and the odometry subscription
//! (`crate::daemon::zenoh_odometry`), declaring publishers and subscribers keyed by the
//! configured convention with that convention's liveliness tokens, and under rmw_zenoh's
//! convention putting each message with its attachment.

use std::sync::atomic::{AtomicI64, AtomicU32, Ordering};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use config::live::{ZenohConvention, ZenohSettings};
use tracing::{info, warn};
use zenoh::bytes::Encoding;
use zenoh::qos::CongestionControl;
use zenoh::Wait;

use super::live_error::LiveError;
use super::zenoh_keys::{
    bridge_liveliness_key, bridge_qos, key_for, rmw_zenoh_attachment, rmw_zenoh_entity_token,
    rmw_zenoh_node_token, rmw_zenoh_qos, EntityKind,
};

/// How long [`ZenohNode::open`] waits for the session to open.
const OPEN_TIMEOUT: Duration = Duration::from_secs(10);
/// The node's id within its session (rmw_zenoh's liveliness graph).
const NODE_ID: u32 = 0;

/// A value as JSON5 text for `zenoh::Config::insert_json5` (JSON is JSON5).
fn json<T: serde::Serialize + ?Sized>(value: &T) -> Result<String, LiveError> {
    serde_json::to_string(value).map_err(|e| LiveError::Open(e.to_string()))
}

/// The Zenoh session's configuration from `[output.zenoh]`: the mode, exactly the endpoints
/// given (no default listener on every interface), multicast scouting as set.
pub fn zenoh_config(s: &ZenohSettings) -> Result<zenoh::Config, LiveError> {
    let open = |e: zenoh::Error| LiveError::Open(e.to_string());
    let mut c = zenoh::Config::default();
    let mode = match s.mode {
        config::live::ZenohMode::Peer => "peer",
        config::live::ZenohMode::Client => "client",
    };
    c.insert_json5("mode", &json(mode)?).map_err(open)?;
    c.insert_json5("connect/endpoints", &json(&s.connect)?)
        .map_err(open)?;
    c.insert_json5("listen/endpoints", &json(&s.listen)?)
        .map_err(open)?;
    c.insert_json5("scouting/multicast/enabled", &json(&s.multicast_scouting)?)
        .map_err(open)?;
    Ok(c)
}

/// The locators `session` listens on (a `tcp/127.0.0.1:0` listener shows the port it got).
pub fn listening_on(session: &zenoh::Session) -> Vec<String> {
    session
        .info()
        .locators()
        .wait()
        .iter()
        .map(ToString::to_string)
        .collect()
}

/// A peer session listening on a port the system chose on 127.0.0.1 (multicast scouting
/// off, connecting nowhere), and the locator it is bound to: the other end of loopback
/// tests and benchmarks, which hand the locator to the daemon's `connect` endpoints (no
/// port is picked, released and reused).
pub fn loopback_peer() -> zenoh::Result<(zenoh::Session, String)> {
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", "\"peer\"")?;
    c.insert_json5("listen/endpoints", "[\"tcp/127.0.0.1:0\"]")?;
    c.insert_json5("connect/endpoints", "[]")?;
    c.insert_json5("scouting/multicast/enabled", "false")?;
    let session = zenoh::open(c).wait()?;
    let locator = listening_on(&session)
        .into_iter()
        .find(|l| l.starts_with("tcp/127.0.0.1:") && !l.ends_with(":0"))
        .ok_or("the loopback peer reports no bound tcp/127.0.0.1 locator")?;
    Ok((session, locator))
}

/// An open session standing for one ROS 2 node.
pub struct ZenohNode {
    session: zenoh::Session,
    settings: ZenohSettings,
    name: &'static str,
    zid: String,
    next_entity: AtomicU32,
    _node_token: Option<zenoh::liveliness::LivelinessToken>,
}

impl std::fmt::Debug for ZenohNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohNode")
            .field("name", &self.name)
            .field("zid", &self.zid)
            .field("convention", &self.settings.convention)
            .finish_non_exhaustive()
    }
}

/// A declared publisher.
pub struct Topic {
    /// Its key.
    pub key: String,
    publisher: zenoh::pubsub::Publisher<'static>,
    _token: Option<zenoh::liveliness::LivelinessToken>,
    /// rmw_zenoh's GID, when that convention is in use.
    gid: Option<[u8; 16]>,
    sequence: AtomicI64,
}

impl std::fmt::Debug for Topic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Topic")
            .field("key", &self.key)
            .finish_non_exhaustive()
    }
}

impl Topic {
    /// Puts one payload (with rmw_zenoh's attachment under that convention).
    pub fn put(&self, payload: Vec<u8>) -> Result<(), zenoh::Error> {
        match &self.gid {
            None => self.publisher.put(payload).wait(),
            Some(gid) => {
                let sequence = self.sequence.fetch_add(1, Ordering::Relaxed) + 1;
                let now_ns = SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX));
                let attachment = rmw_zenoh_attachment(sequence, now_ns, gid).to_vec();
                self.publisher.put(payload).attachment(attachment).wait()
            }
        }
    }
}

/// A declared subscriber (undeclared when dropped).
pub struct Subscription {
    /// Its key.
    pub key: String,
    _subscriber: zenoh::pubsub::Subscriber<()>,
    _token: Option<zenoh::liveliness::LivelinessToken>,
}

impl std::fmt::Debug for Subscription {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subscription")
            .field("key", &self.key)
            .finish_non_exhaustive()
    }
}

impl ZenohNode {
    /// Opens the session (on a thread of its own, waiting at most 10 s: Zenoh's blocking
    /// open must not run on an async task) and, under rmw_zenoh's convention, declares the
    /// node's liveliness token. Logs the locators it listens on.
    pub fn open(settings: &ZenohSettings, name: &'static str) -> Result<Self, LiveError> {
        let config = zenoh_config(settings)?;
        let (tx, rx) = crossbeam_channel::bounded(1);
        std::thread::Builder::new()
            .name("zenoh-open".into())
            .spawn(move || {
                let _ = tx.send(zenoh::open(config).wait());
            })
            .map_err(|e| LiveError::Thread(e.to_string()))?;
        let session = match rx.recv_timeout(OPEN_TIMEOUT) {
            Ok(opened) => opened.map_err(|e| LiveError::Open(e.to_string()))?,
            Err(_) => {
                return Err(LiveError::Open(format!(
                    "the session did not open within {} s",
                    OPEN_TIMEOUT.as_secs()
                )))
            }
        };
        let zid = session.zid().to_string();
        let node_token = match settings.convention {
            ZenohConvention::Ros2dds => None,
            ZenohConvention::RmwZenoh => {
                let key = rmw_zenoh_node_token(
                    settings.domain_id,
                    &zid,
                    NODE_ID,
                    &settings.namespace,
                    name,
                );
                token(&session, key)
            }
        };
        info!(
            %zid,
            node = name,
            convention = ?settings.convention,
            listening = %listening_on(&session).join(" "),
            "Zenoh session open"
        );
        Ok(Self {
            session,
            settings: settings.clone(),
            name,
            zid,
            next_entity: AtomicU32::new(1),
            _node_token: node_token,
        })
    }

    /// The session.
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// The settings it was opened with.
    pub fn settings(&self) -> &ZenohSettings {
        &self.settings
    }

    /// The key of `topic` of `ros_type` under the node's convention.
    pub fn key(&self, topic: &str, ros_type: &str) -> Result<String, LiveError> {
        key_for(&self.settings, topic, ros_type)
    }

    fn entity_token(
        &self,
        kind: EntityKind,
        key: &str,
        topic: &str,
        ros_type: &str,
        transient_local: bool,
        depth: u32,
    ) -> Result<(Option<zenoh::liveliness::LivelinessToken>, u32), LiveError> {
        let entity = self.next_entity.fetch_add(1, Ordering::Relaxed);
        let token_key = match self.settings.convention {
            ZenohConvention::Ros2dds => {
                if kind == EntityKind::Subscription {
                    // The bridge routes to any subscriber of the key; it declares no token
                    // for a Zenoh-side subscriber.
                    return Ok((None, entity));
                }
                bridge_liveliness_key(
                    &self.zid,
                    key,
                    ros_type,
                    &bridge_qos(transient_local, depth),
                )
            }
            ZenohConvention::RmwZenoh => rmw_zenoh_entity_token(
                self.settings.domain_id,
                &self.zid,
                NODE_ID,
                entity,
                kind,
                &self.settings.namespace,
                self.name,
                topic,
                ros_type,
                &rmw_zenoh_qos(transient_local, depth),
            )?,
        };
        Ok((token(&self.session, token_key), entity))
    }

    /// The 16-byte GID of entity `entity`: the session's id with the entity's number in its
    /// last four bytes.
    fn gid(&self, entity: u32) -> [u8; 16] {
        let mut gid = self.session.zid().to_le_bytes();
        for (g, e) in gid[12..].iter_mut().zip(entity.to_le_bytes()) {
            *g ^= e;
        }
        gid
    }

    /// Declares a publisher of `ros_type` on `topic` (keep-last 10, or transient-local
    /// keep-last 1) with Zenoh's congestion control `Drop` (`express`: no batching).
    pub fn publisher(
        &self,
        topic: &str,
        ros_type: &str,
        transient_local: bool,
        express: bool,
    ) -> Result<Topic, LiveError> {
        let key = self.key(topic, ros_type)?;
        let declare_err = |e: zenoh::Error| LiveError::Declare {
            key: key.clone(),
            message: e.to_string(),
        };
        let publisher = self
            .session
            .declare_publisher(key.clone())
            .encoding(Encoding::APPLICATION_CDR.with_schema(ros_type))
            .congestion_control(CongestionControl::Drop)
            .express(express)
            .wait()
            .map_err(declare_err)?;
        let depth = if transient_local { 1 } else { 10 };
        let (token, entity) = self.entity_token(
            EntityKind::Publisher,
            &key,
            topic,
            ros_type,
            transient_local,
            depth,
        )?;
        let gid = (self.settings.convention == ZenohConvention::RmwZenoh).then(|| self.gid(entity));
        Ok(Topic {
            key,
            publisher,
            _token: token,
            gid,
            sequence: AtomicI64::new(0),
        })
    }

    /// Declares a subscriber of `ros_type` on `topic`; `on_sample` runs on Zenoh's threads
    /// for each sample and must not block.
    pub fn subscriber<F>(
        &self,
        topic: &str,
        ros_type: &str,
        on_sample: F,
    ) -> Result<Subscription, LiveError>
    where
        F: Fn(zenoh::sample::Sample) + Send + Sync + 'static,
    {
        let key = self.key(topic, ros_type)?;
        let subscriber = self
            .session
            .declare_subscriber(key.clone())
            .callback(on_sample)
            .wait()
            .map_err(|e| LiveError::Declare {
                key: key.clone(),
                message: e.to_string(),
            })?;
        let (token, _) =
            self.entity_token(EntityKind::Subscription, &key, topic, ros_type, false, 10)?;
        Ok(Subscription {
            key,
            _subscriber: subscriber,
            _token: token,
        })
    }

    /// Closes the session (every publisher, subscriber and token goes with it).
    pub fn close(&self) {
        if let Err(e) = self.session.close().wait() {
            warn!(error = %e, "closing the Zenoh session");
        }
    }
}

/// Declares a liveliness token; failing to declare it costs only discoverability.
fn token(session: &zenoh::Session, key: String) -> Option<zenoh::liveliness::LivelinessToken> {
    match session.liveliness().declare_token(key.clone()).wait() {
        Ok(t) => Some(t),
        Err(e) => {
            warn!(key = %key, error = %e, "Zenoh liveliness token not declared");
            None
        }
    }
}
