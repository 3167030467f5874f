//! `[output.zenoh]`: live ROS 2 topics over Zenoh (pose, tf, map, detections), off by
//! default. Only slam-node built with its `zenoh` feature publishes; this crate only checks
//! the settings.
//!
//! Keys follow `convention`: zenoh-bridge-ros2dds's by default (the ROS 2 topic
//! `/slam/odometry` is the key `slam/odometry`, with `namespace = "robot1"`
//! `robot1/slam/odometry`), or rmw_zenoh's (`<domain_id>/<topic>/<DDS type>/<type hash>`);
//! the payload is the CDR serialisation with its 4-byte encapsulation header either way. The
//! same session takes `[odometry] source = "zenoh"`.

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{Capacity, ValueError};

/// The most events a publisher queue may hold.
pub const MAX_ZENOH_QUEUE: usize = 4096;
/// The most endpoints a list may name.
pub const MAX_ZENOH_ENDPOINTS: usize = 64;

/// How the daemon's Zenoh session joins the network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ZenohMode {
    /// A peer: talks directly to the peers and routers it connects to or that connect to it.
    #[default]
    Peer,
    /// A client of a router (`zenohd`, zenoh-bridge-ros2dds): needs `connect`.
    Client,
}

/// Which ROS 2 mapping of topics to Zenoh keys, as written: `convention = "ros2dds" |
/// "rmw_zenoh"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize, Serialize)]
pub enum ZenohConvention {
    /// zenoh-bridge-ros2dds: the topic name without its leading slash, under `namespace`;
    /// the bridge's liveliness tokens. The default: a ROS 2 system on its usual DDS reaches
    /// us through the bridge, and plain Zenoh tools read the keys as topic names.
    #[default]
    #[serde(rename = "ros2dds")]
    Ros2dds,
    /// rmw_zenoh (`RMW_IMPLEMENTATION=rmw_zenoh_cpp`): `<domain_id>/<namespace>/<topic>/
    /// <package>::msg::dds_::<Type>_/RIHS01_<sha256>`, each message with rmw_zenoh's
    /// attachment (sequence number, time, publisher GID), and its liveliness graph tokens.
    #[serde(rename = "rmw_zenoh")]
    RmwZenoh,
}

/// The largest ROS 2 domain id (as DDS allows).
pub const MAX_DOMAIN_ID: i64 = 232;

/// `[output.zenoh]` as written in the file.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawZenoh {
    /// Publish live. Default false.
    pub enabled: bool,
    /// `"peer"` or `"client"`. Default `"peer"`.
    pub mode: ZenohMode,
    /// Endpoints to connect to, `tcp/host:port`. Default `["tcp/127.0.0.1:7447"]` (a
    /// router or zenoh-bridge-ros2dds on this host, at Zenoh's default port).
    pub connect: Vec<String>,
    /// Endpoints to listen on, `tcp/host:port` (port 0: any free port). Default none.
    pub listen: Vec<String>,
    /// Find peers by UDP multicast. Default false: only the endpoints above.
    pub multicast_scouting: bool,
    /// Prefix of every key (the ROS 2 namespace without its slashes). Default `""`.
    pub namespace: String,
    /// Events waiting for the publisher thread; more are dropped and counted. Default 64.
    pub queue: i64,
    /// `"ros2dds"` (default) or `"rmw_zenoh"`: how ROS 2 topics map to keys.
    pub convention: ZenohConvention,
    /// The ROS 2 domain (`ROS_DOMAIN_ID`, 0 to 232): the first chunk of every rmw_zenoh key.
    /// Default 0.
    pub domain_id: i64,
}

impl Default for RawZenoh {
    fn default() -> Self {
        Self {
            enabled: false,
            mode: ZenohMode::Peer,
            connect: vec!["tcp/127.0.0.1:7447".into()],
            listen: Vec::new(),
            multicast_scouting: false,
            namespace: String::new(),
            queue: 64,
            convention: ZenohConvention::Ros2dds,
            domain_id: 0,
        }
    }
}

/// `[output.zenoh]`, validated.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct ZenohSettings {
    /// Publish live.
    pub enabled: bool,
    /// Peer or client.
    pub mode: ZenohMode,
    /// Endpoints to connect to.
    pub connect: Vec<String>,
    /// Endpoints to listen on.
    pub listen: Vec<String>,
    /// Multicast scouting.
    pub multicast_scouting: bool,
    /// Key prefix (empty: none).
    pub namespace: String,
    /// Publisher queue, events.
    pub queue: Capacity,
    /// Key convention.
    pub convention: ZenohConvention,
    /// ROS 2 domain id (rmw_zenoh keys).
    pub domain_id: u32,
}

impl Default for ZenohSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawZenoh::default().check(&mut c, "output.zenoh");
        debug_assert!(c.is_clean(), "the [output.zenoh] defaults must be valid");
        settings
    }
}

/// One endpoint: `tcp/host:port`, host an IPv4 address, a bracketed IPv6 address or a name.
pub fn endpoint(text: &str) -> Result<String, ValueError> {
    let bad = || {
        ValueError::Rule(format!(
            "must be a Zenoh endpoint `tcp/host:port` such as `tcp/127.0.0.1:7447` (only TCP is built in), got {text:?}"
        ))
    };
    let rest = text.strip_prefix("tcp/").ok_or_else(bad)?;
    let (host, port) = rest.rsplit_once(':').ok_or_else(bad)?;
    port.parse::<u16>().map_err(|_| bad())?;
    let host_ok = if let Some(v6) = host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        v6.parse::<std::net::Ipv6Addr>().is_ok()
    } else {
        !host.is_empty()
            && host
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '.' || c == '-')
    };
    if host_ok {
        Ok(text.to_owned())
    } else {
        Err(bad())
    }
}

fn endpoints(list: &[String]) -> Result<Vec<String>, ValueError> {
    if list.len() > MAX_ZENOH_ENDPOINTS {
        return Err(ValueError::Rule(format!(
            "must name at most {MAX_ZENOH_ENDPOINTS} endpoints, got {}",
            list.len()
        )));
    }
    list.iter().map(|e| endpoint(e)).collect()
}

/// A key prefix: chunks of letters, digits, `_` and `-` joined by single slashes.
pub fn namespace(text: &str) -> Result<String, ValueError> {
    let ok = text.is_empty()
        || text.split('/').all(|chunk| {
            !chunk.is_empty()
                && chunk
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        });
    if ok {
        Ok(text.to_owned())
    } else {
        Err(ValueError::Rule(format!(
            "must be empty or names of letters, digits, `_` and `-` joined by single slashes (no leading or trailing slash, no wildcards), got {text:?}"
        )))
    }
}

/// A ROS 2 domain id, 0 to [`MAX_DOMAIN_ID`].
pub fn domain_id(value: i64) -> Result<u32, ValueError> {
    match u32::try_from(value) {
        Ok(id) if value <= MAX_DOMAIN_ID => Ok(id),
        _ => Err(ValueError::Rule(format!(
            "must be a ROS 2 domain id from 0 to {MAX_DOMAIN_ID}, got {value}"
        ))),
    }
}

impl RawZenoh {
    /// Validates this table alone; errors name `output.zenoh.<field>`.
    pub fn validate(&self) -> Result<ZenohSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c, "output.zenoh");
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker, table: &str) -> ZenohSettings {
        let connect = c.check_ok(&format!("{table}.connect"), endpoints(&self.connect));
        if let Some(list) = &connect {
            if self.mode == ZenohMode::Client && list.is_empty() {
                c.fail(
                    &format!("{table}.connect"),
                    ValueError::Rule(
                        "must name at least one endpoint with output.zenoh.mode = \"client\""
                            .into(),
                    ),
                );
            }
        }
        ZenohSettings {
            enabled: self.enabled,
            mode: self.mode,
            connect: connect.unwrap_or_default(),
            listen: c
                .check_ok(&format!("{table}.listen"), endpoints(&self.listen))
                .unwrap_or_default(),
            multicast_scouting: self.multicast_scouting,
            namespace: c
                .check_ok(&format!("{table}.namespace"), namespace(&self.namespace))
                .unwrap_or_default(),
            queue: c.check(
                &format!("{table}.queue"),
                Capacity::new(self.queue, MAX_ZENOH_QUEUE),
            ),
            convention: self.convention,
            domain_id: c
                .check_ok(&format!("{table}.domain_id"), domain_id(self.domain_id))
                .unwrap_or_default(),
        }
    }
}

impl From<&ZenohSettings> for RawZenoh {
    /// The settings written back out.
    fn from(s: &ZenohSettings) -> Self {
        Self {
            enabled: s.enabled,
            mode: s.mode,
            connect: s.connect.clone(),
            listen: s.listen.clone(),
            multicast_scouting: s.multicast_scouting,
            namespace: s.namespace.clone(),
            queue: crate::values::as_i64(s.queue.get()),
            convention: s.convention,
            domain_id: i64::from(s.domain_id),
        }
    }
}
