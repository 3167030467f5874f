//! The publisher thread: owns a one-worker tokio runtime running the SDK's server (on a
//! loopback port of its own) and the door ([`super::gate`]) on the configured address, takes
//! the pipeline's events from a bounded queue and logs them on the channels.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{bounded, Receiver, Sender, TrySendError};
use foxglove::schemas::{
    FrameTransforms, PointCloud, PoseInFrame, PosesInFrame, RawImage, SceneUpdate,
};
use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{Channel, Context, RawChannel, Schema};
use tracing::{info, warn};

use super::gate::{Gate, GateCounters};
use super::image::ImageBuilder;
use super::messages as msg;
use super::{FoxgloveError, FoxgloveOutput, FoxgloveSummary};
use crate::output::event::OutputEvent;
use crate::output::ros::RADAR_FRAME;
use crate::output::trajectory::PoseSample;

/// How long [`FoxglovePublisher::spawn`] waits for the server to start (beyond the wait for
/// a subscriber).
const READY_TIMEOUT: Duration = Duration::from_secs(10);
/// The online trajectory is published at most this often, seconds of stream.
const TRAJECTORY_EVERY_S: f64 = 1.0;
/// The most poses a trajectory message carries (thinned evenly beyond).
const MAX_TRAJECTORY_POSES: usize = 5000;
/// At the end, connected clients are given this long to take what is queued for them...
const LINGER_MAX: Duration = Duration::from_secs(2);
/// ...ending sooner once nothing has been sent for this long.
const LINGER_QUIET: Duration = Duration::from_millis(200);

/// JSON Schema of `/slam/pose_covariance`.
const POSE_COVARIANCE_SCHEMA: &str = r#"{"title":"slam_node.PoseWithCovariance","type":"object","properties":{"timestamp_s":{"type":"number","description":"Unix seconds"},"x_m":{"type":"number"},"y_m":{"type":"number"},"theta_rad":{"type":"number","description":"counter-clockwise from +x"},"covariance":{"type":"array","description":"3x3 over (x, y, theta), row-major","items":{"type":"array","items":{"type":"number"}}}}}"#;
/// JSON Schema of `/slam/counters`.
const COUNTERS_SCHEMA: &str = r#"{"title":"slam_node.Counters","type":"object","properties":{"diagnostics":{"type":"object","description":"the rotation's diagnostics, as a line of diagnostics.jsonl"},"foxglove":{"type":"object","properties":{"dropped":{"type":"integer","description":"events dropped by the publisher's full queue so far"},"published":{"type":"integer","description":"messages published so far"}}}}}"#;

struct Channels {
    image: Channel<RawImage>,
    detections: Channel<PointCloud>,
    map: Channel<SceneUpdate>,
    pose: Channel<PoseInFrame>,
    pose_covariance: Arc<RawChannel>,
    pose_uncertainty: Channel<SceneUpdate>,
    trajectory: Channel<PosesInFrame>,
    trajectory_optimised: Channel<PosesInFrame>,
    tf: Channel<FrameTransforms>,
    counters: Arc<RawChannel>,
}

fn json_channel(
    ctx: &Arc<Context>,
    topic: &str,
    schema: &'static str,
) -> Result<Arc<RawChannel>, FoxgloveError> {
    let title = serde_json::from_str::<serde_json::Value>(schema)
        .ok()
        .and_then(|v| v["title"].as_str().map(str::to_owned))
        .unwrap_or_default();
    ctx.channel_builder(topic)
        .message_encoding("json")
        .schema(Schema::new(title, "jsonschema", schema.as_bytes()))
        .build_raw()
        .map_err(|e| FoxgloveError::Server(e.to_string()))
}

impl Channels {
    /// Every channel's id.
    fn ids(&self) -> std::collections::HashSet<u64> {
        [
            self.image.id(),
            self.detections.id(),
            self.map.id(),
            self.pose.id(),
            self.pose_covariance.id(),
            self.pose_uncertainty.id(),
            self.trajectory.id(),
            self.trajectory_optimised.id(),
            self.tf.id(),
            self.counters.id(),
        ]
        .into_iter()
        .map(u64::from)
        .collect()
    }

    fn new(ctx: &Arc<Context>) -> Result<Self, FoxgloveError> {
        Ok(Self {
            image: ctx.channel_builder(super::TOPIC_IMAGE).build(),
            detections: ctx.channel_builder(super::TOPIC_DETECTIONS).build(),
            map: ctx.channel_builder(super::TOPIC_MAP).build(),
            pose: ctx.channel_builder(super::TOPIC_POSE).build(),
            pose_covariance: json_channel(
                ctx,
                super::TOPIC_POSE_COVARIANCE,
                POSE_COVARIANCE_SCHEMA,
            )?,
            pose_uncertainty: ctx.channel_builder(super::TOPIC_POSE_UNCERTAINTY).build(),
            trajectory: ctx.channel_builder(super::TOPIC_TRAJECTORY).build(),
            trajectory_optimised: ctx
                .channel_builder(super::TOPIC_TRAJECTORY_OPTIMISED)
                .build(),
            tf: ctx.channel_builder(super::TOPIC_TF).build(),
            counters: json_channel(ctx, super::TOPIC_COUNTERS, COUNTERS_SCHEMA)?,
        })
    }
}

/// The pipeline's end of the Foxglove output.
#[derive(Debug)]
pub struct FoxglovePublisher {
    sender: Option<Sender<OutputEvent>>,
    dropped: Arc<AtomicU64>,
    join: Option<JoinHandle<FoxgloveSummary>>,
    address: SocketAddr,
}

impl FoxglovePublisher {
    /// Starts the thread, its runtime, the SDK's server and the door; waits (at most 10 s)
    /// until the door listens, and logs where.
    pub fn spawn(out: FoxgloveOutput) -> Result<Self, FoxgloveError> {
        let out_wait_s = out.settings.wait_for_subscriber_s;
        let (tx, rx) = bounded(out.settings.queue.get());
        let dropped = Arc::new(AtomicU64::new(0));
        let (ready_tx, ready_rx) = bounded::<Result<SocketAddr, FoxgloveError>>(1);
        let thread_dropped = Arc::clone(&dropped);
        let join = std::thread::Builder::new()
            .name("slam-foxglove".into())
            .spawn(move || serve(out, rx, ready_tx, thread_dropped))
            .map_err(|e| FoxgloveError::Thread(e.to_string()))?;
        let wait = Duration::from_secs(u64::from(out_wait_s));
        match ready_rx.recv_timeout(READY_TIMEOUT + wait) {
            Ok(Ok(address)) => Ok(Self {
                sender: Some(tx),
                dropped,
                join: Some(join),
                address,
            }),
            Ok(Err(e)) => {
                let _ = join.join();
                Err(e)
            }
            Err(_) => Err(FoxgloveError::Thread(format!(
                "the server did not start within {} s",
                READY_TIMEOUT.as_secs()
            ))),
        }
    }

    /// Where the door listens (the port the system chose for port 0).
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// Hands the publisher what it draws from `event`, never blocking: a full queue drops
    /// the event and counts it. Spectra, odometry and the truth are not wanted.
    pub fn offer(&self, event: &OutputEvent) {
        let wanted = matches!(
            event,
            OutputEvent::Azimuth(_)
                | OutputEvent::Pose(_)
                | OutputEvent::Map(_)
                | OutputEvent::Detections(_)
                | OutputEvent::Rotation(_)
                | OutputEvent::Trajectory(_)
        );
        let Some(sender) = self.sender.as_ref().filter(|_| wanted) else {
            return;
        };
        match sender.try_send(event.clone()) {
            Ok(()) => {}
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                let n = self.dropped.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_power_of_two() {
                    warn!(dropped = n, "Foxglove output behind: events dropped");
                }
            }
        }
    }

    /// Events dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Closes the queue, lets the thread publish what is in it, gives connected clients a
    /// moment to take it, stops the server; returns the counts.
    pub fn finish(mut self) -> FoxgloveSummary {
        self.sender.take();
        let mut summary = self
            .join
            .take()
            .and_then(|j| j.join().ok())
            .unwrap_or_default();
        summary.dropped = self.dropped();
        summary
    }
}

impl Drop for FoxglovePublisher {
    fn drop(&mut self) {
        self.sender.take();
        if let Some(j) = self.join.take() {
            let _ = j.join();
        }
    }
}

/// The thread: starts everything, reports readiness, publishes until the queue closes.
fn serve(
    out: FoxgloveOutput,
    rx: Receiver<OutputEvent>,
    ready: Sender<Result<SocketAddr, FoxgloveError>>,
    dropped: Arc<AtomicU64>,
) -> FoxgloveSummary {
    let started = Instant::now();
    let (pose_tx, pose_rx) = bounded::<()>(1);
    let listener = Arc::new(Subscriptions {
        count: AtomicU64::new(0),
        pose: pose_tx,
    });
    let setup = || -> Result<_, FoxgloveError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("slam-foxglove-net")
            .enable_all()
            .build()
            .map_err(|e| FoxgloveError::Server(e.to_string()))?;
        let ctx = Context::new();
        let channels = Channels::new(&ctx)?;
        let server = runtime
            .block_on(
                ctx.websocket_server()
                    .name("slam-node")
                    .listener(Arc::clone(&listener) as Arc<dyn ServerListener>)
                    .bind("127.0.0.1", 0)
                    .message_backlog_size(out.settings.backlog.get())
                    .tokio_runtime(runtime.handle())
                    .start(),
            )
            .map_err(|e| FoxgloveError::Server(e.to_string()))?;
        let address = out.settings.bind;
        let door = runtime
            .block_on(tokio::net::TcpListener::bind(address))
            .map_err(|source| FoxgloveError::Bind { address, source })?;
        let bound = door
            .local_addr()
            .map_err(|source| FoxgloveError::Bind { address, source })?;
        let counters = Arc::new(GateCounters::default());
        let gate = Gate {
            upstream: SocketAddr::from(([127, 0, 0, 1], server.port())),
            max_clients: out.settings.max_clients.get(),
            assets: if out.view { super::view::ASSETS } else { &[] },
            channels: Arc::new(channels.ids()),
            counters: Arc::clone(&counters),
        };
        runtime.spawn(gate.serve(door));
        Ok((runtime, ctx, channels, server, bound, counters))
    };
    let (runtime, _ctx, channels, server, bound, counters) = match setup() {
        Ok(s) => s,
        Err(e) => {
            let _ = ready.send(Err(e));
            return FoxgloveSummary::default();
        }
    };
    if out.view {
        info!(address = %bound, "live view page at http://{bound}/ (Foxglove WebSocket on the same address)");
    }
    info!(address = %bound, "Foxglove live view: ws://{bound}");
    let wait = out.settings.wait_for_subscriber_s;
    if wait > 0 {
        info!(
            "waiting up to {wait} s for a Foxglove client to subscribe to {}",
            super::TOPIC_POSE
        );
        if pose_rx
            .recv_timeout(Duration::from_secs(u64::from(wait)))
            .is_err()
        {
            warn!(
                "no Foxglove client subscribed to {} within {wait} s: starting",
                super::TOPIC_POSE
            );
        }
    }
    let _ = ready.send(Ok(bound));
    let mut publisher = Publisher {
        channels,
        image: ImageBuilder::new(
            out.settings.image_size,
            f64::from(out.settings.image_range_m),
        ),
        poses: Vec::new(),
        last_trajectory_s: f64::NEG_INFINITY,
        published: BTreeMap::new(),
        dropped,
    };
    for event in rx {
        publisher.on_event(event);
    }
    publisher.flush();
    linger(&counters);
    let shutdown = server.stop();
    runtime.block_on(async {
        let _ = tokio::time::timeout(Duration::from_secs(1), shutdown.wait()).await;
    });
    runtime.shutdown_timeout(Duration::from_secs(1));
    let c = |a: &AtomicU64| a.load(Ordering::Relaxed);
    FoxgloveSummary {
        address: Some(bound),
        published: publisher.published,
        dropped: 0,
        failed: publisher.image.refused,
        connections: c(&counters.connections),
        refused: c(&counters.refused),
        bad_requests: c(&counters.bad_requests),
        cut_off: c(&counters.cut_off),
        pages: c(&counters.pages),
        bytes_sent: c(&counters.bytes_sent),
        subscriptions: c(&listener.count),
        unknown_subscriptions: c(&counters.unknown_subscriptions),
        served_s: started.elapsed().as_secs_f64(),
    }
}

/// Waits (at most [`LINGER_MAX`]) until nothing has been relayed to clients for
/// [`LINGER_QUIET`]: what the SDK queued for them is on its way.
fn linger(counters: &GateCounters) {
    if counters.active() == 0 {
        return;
    }
    let start = Instant::now();
    let mut last = counters.bytes_sent.load(Ordering::Relaxed);
    let mut quiet_since = Instant::now();
    while start.elapsed() < LINGER_MAX && quiet_since.elapsed() < LINGER_QUIET {
        std::thread::sleep(Duration::from_millis(20));
        let now = counters.bytes_sent.load(Ordering::Relaxed);
        if now != last {
            last = now;
            quiet_since = Instant::now();
        }
    }
}

/// Counts subscriptions and tells the waiting start about the first to the pose.
struct Subscriptions {
    count: AtomicU64,
    pose: Sender<()>,
}

impl ServerListener for Subscriptions {
    fn on_subscribe(&self, _client: Client, channel: ChannelView) {
        self.count.fetch_add(1, Ordering::Relaxed);
        if channel.topic() == super::TOPIC_POSE {
            let _ = self.pose.try_send(());
        }
    }
}

struct Publisher {
    channels: Channels,
    image: ImageBuilder,
    poses: Vec<PoseSample>,
    last_trajectory_s: f64,
    published: BTreeMap<String, u64>,
    dropped: Arc<AtomicU64>,
}

/// Logs `message` on `channel` stamped `unix_s` when someone is subscribed, counting it.
fn log<T: foxglove::Encode>(
    published: &mut BTreeMap<String, u64>,
    channel: &Channel<T>,
    message: &T,
    unix_s: f64,
) {
    if channel.has_sinks() {
        channel.log_with_time(message, msg::log_time_ns(unix_s));
        *published.entry(channel.topic().to_owned()).or_insert(0) += 1;
    }
}

/// Logs `message` as JSON on `channel` when someone is subscribed, counting it.
fn log_json<T: serde::Serialize>(
    published: &mut BTreeMap<String, u64>,
    channel: &RawChannel,
    message: &T,
    unix_s: f64,
) {
    if !channel.has_sinks() {
        return;
    }
    match serde_json::to_vec(message) {
        Ok(bytes) => {
            channel.log_with_meta(
                &bytes,
                foxglove::PartialMetadata::with_log_time(msg::log_time_ns(unix_s)),
            );
            *published.entry(channel.topic().to_owned()).or_insert(0) += 1;
        }
        Err(e) => warn!(error = %e, topic = channel.topic(), "Foxglove message not encoded"),
    }
}

impl Publisher {
    fn on_event(&mut self, event: OutputEvent) {
        let out = &mut self.published;
        let c = &self.channels;
        match event {
            OutputEvent::Azimuth(az) if c.image.has_sinks() => {
                if let Some(img) = self.image.push(&az) {
                    self.publish_image(img);
                }
            }
            OutputEvent::Pose(p) => self.on_pose(p),
            OutputEvent::Map(m) => log(out, &c.map, &msg::map_scene(&m), m.timestamp_s),
            OutputEvent::Detections(d) => log(
                out,
                &c.detections,
                &msg::detections_cloud(&d),
                d.timestamp_s,
            ),
            OutputEvent::Rotation(r) => {
                let total: u64 = out.values().sum();
                let counters = serde_json::json!({
                    "diagnostics": &*r,
                    "foxglove": {
                        "dropped": self.dropped.load(Ordering::Relaxed),
                        "published": total,
                    },
                });
                log_json(out, &c.counters, &counters, r.timestamp_s);
            }
            OutputEvent::Trajectory(t) => {
                if let Some(last) = t.last() {
                    let m = msg::poses_in_frame(&t, MAX_TRAJECTORY_POSES);
                    log(out, &c.trajectory_optimised, &m, last.timestamp_s);
                }
            }
            _ => {}
        }
    }

    fn on_pose(&mut self, p: PoseSample) {
        self.poses.push(p);
        let t = p.timestamp_s;
        let (out, c) = (&mut self.published, &self.channels);
        log(out, &c.pose, &msg::pose_in_frame(&p), t);
        log(out, &c.tf, &msg::transforms(&p), t);
        log(out, &c.pose_uncertainty, &msg::pose_scene(&p), t);
        log_json(out, &c.pose_covariance, &p, t);
        if t - self.last_trajectory_s >= TRAJECTORY_EVERY_S {
            self.publish_trajectory();
        }
    }

    fn publish_trajectory(&mut self) {
        let Some(last) = self.poses.last() else {
            return;
        };
        self.last_trajectory_s = last.timestamp_s;
        let m = msg::poses_in_frame(&self.poses, MAX_TRAJECTORY_POSES);
        log(
            &mut self.published,
            &self.channels.trajectory,
            &m,
            self.last_trajectory_s,
        );
    }

    fn publish_image(&mut self, img: super::image::RotationImage) {
        let message = RawImage {
            timestamp: Some(msg::timestamp(img.timestamp_s)),
            frame_id: RADAR_FRAME.into(),
            width: img.size,
            height: img.size,
            encoding: "mono8".into(),
            step: img.size,
            data: img.pixels.into(),
        };
        log(
            &mut self.published,
            &self.channels.image,
            &message,
            img.timestamp_s,
        );
    }

    /// Publishes the whole online trajectory (the rotation in progress is not drawn: the
    /// last image stays the last complete rotation).
    fn flush(&mut self) {
        if self
            .poses
            .last()
            .is_some_and(|p| p.timestamp_s > self.last_trajectory_s)
        {
            self.publish_trajectory();
        }
    }
}
