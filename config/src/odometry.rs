//! `[odometry]`: where the vehicle's speed and steering come from, and the motion model that
//! turns them into a pose change.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{self, NonNegativeF64, PlacementShare, PositiveF64, ValueError};

/// The odometry source, as written: `source = "tcp" | "file" | "zenoh" | "none"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum OdometrySourceKind {
    /// The odometry stream of `docs/contracts.md` over TCP, at `address`.
    Tcp,
    /// The same format read from the file at `path`.
    File,
    /// ROS 2 messages (`message`) on the ROS 2 topic `topic`, over the Zenoh session of
    /// `[output.zenoh]` (its endpoints, mode, namespace and key convention); slam-node built
    /// with its `zenoh` feature only.
    Zenoh,
    /// No odometry: the daemon says so and refuses to pretend.
    None,
}

/// The ROS 2 message a Zenoh odometry topic carries, as written: its type name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize, Serialize)]
pub enum OdometryMessageKind {
    /// `nav_msgs/msg/Odometry`: the twist's forward speed and yaw rate.
    #[default]
    #[serde(rename = "nav_msgs/msg/Odometry")]
    Odometry,
    /// `geometry_msgs/msg/TwistStamped`: forward speed and yaw rate.
    #[serde(rename = "geometry_msgs/msg/TwistStamped")]
    TwistStamped,
}

/// Default ROS 2 topic of Zenoh odometry.
pub const DEFAULT_ODOMETRY_TOPIC: &str = "/odom";

/// The motion model, as written: `motion_model = "paper" | "bicycle"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum MotionModelKind {
    /// The paper's eq. 2, with `step_s`.
    Paper,
    /// Kinematic bicycle, with `wheelbase_m`.
    Bicycle,
}

/// Default odometry address: the simulator's odometry port.
pub const DEFAULT_ODOMETRY_ADDRESS: &str = "127.0.0.1:6318";
/// Default step of the paper's motion model, seconds.
pub const DEFAULT_STEP_S: f64 = 0.05;
/// Default wheelbase of the bicycle model, metres.
pub const DEFAULT_WHEELBASE_M: f64 = 2.7;
/// Default physical limit on the reported speed, m/s (216 km/h).
pub const DEFAULT_MAX_SPEED_MPS: f64 = 60.0;
/// Default physical limit on the reported steer, rad.
pub const DEFAULT_MAX_STEER_RAD: f64 = 1.2;
/// Default physical limit on the change of speed, m/s^2.
pub const DEFAULT_MAX_ACCEL_MPS2: f64 = 20.0;

/// `[odometry]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawOdometry {
    /// `"tcp"`, `"file"` or `"none"`. Default `"tcp"`.
    pub source: OdometrySourceKind,
    /// With `source = "tcp"`: `ip:port`. Default `127.0.0.1:6318`.
    pub address: Option<String>,
    /// With `source = "file"`: the odometry file (required then).
    pub path: Option<PathBuf>,
    /// With `source = "zenoh"`: the ROS 2 topic, absolute (`/odom`, the default); its key
    /// follows `[output.zenoh] convention` and `namespace`.
    pub topic: Option<String>,
    /// With `source = "zenoh"`: `"nav_msgs/msg/Odometry"` (default) or
    /// `"geometry_msgs/msg/TwistStamped"`; the yaw rate becomes the motion model's steering.
    pub message: Option<OdometryMessageKind>,
    /// `"paper"` (eq. 2) or `"bicycle"`. Default `"paper"`.
    pub motion_model: MotionModelKind,
    /// With `motion_model = "paper"`: the step, s > 0, over which a steer value is the whole
    /// heading change. Default 0.05.
    pub step_s: Option<f64>,
    /// With `motion_model = "bicycle"`: wheelbase, m > 0. Default 2.7.
    pub wheelbase_m: Option<f64>,
    /// Standard deviation of the speed input, m/s >= 0 (process noise). Default 0.1.
    pub sigma_speed_mps: f64,
    /// Standard deviation of the steering input, rad >= 0 (process noise). Default 0.01.
    pub sigma_steer_rad: f64,
    /// Prior standard deviation of the odometry's speed scale error, in [0, 0.5): the filter
    /// estimates a correction `k` (the model's speed is `speed (1 + k)`) when this is > 0.
    /// White input noise cannot describe a wheel radius or a calibration a few per cent
    /// off; with `k` in the state the landmarks measure it. Default 0 (not estimated: the
    /// paper's filter).
    pub speed_scale_std: f64,
    /// Prior standard deviation of a constant steering offset, rad >= 0 (in the motion
    /// model's steering units); estimated when > 0. Default 0.
    pub steer_bias_std_rad: f64,
    /// How fast the speed correction may drift, per sqrt(s), >= 0. Default 1e-4.
    pub speed_scale_walk_per_sqrt_s: f64,
    /// How fast the steering offset may drift, rad per sqrt(s), >= 0. Default 1e-5.
    pub steer_bias_walk_rad_per_sqrt_s: f64,
    /// Odometry older than this (ms > 0) is stale. Default 500.
    pub stale_after_ms: i64,
    /// A record reporting a faster speed (m/s > 0, either direction) is refused. Default 60.
    pub max_speed_mps: f64,
    /// A record reporting a larger steer (rad > 0, either side) is refused. Default 1.2.
    pub max_steer_rad: f64,
    /// A record whose speed changed faster than this since the last accepted one (m/s^2 > 0;
    /// checked over intervals up to 1 s) is refused. Default 20 (2 g).
    pub max_accel_mps2: f64,
    /// Whether landmark updates may move the odometry's speed correction (`speed_scale_std`),
    /// or only motion measurements (radar odometry) may: false holds it as a consider
    /// parameter in every landmark update (its cross-covariances are updated, its estimate
    /// is not). `slam-node --replay-dir` sets it false with its radar odometry. Default true.
    pub speed_scale_from_landmarks: bool,
    /// The same for the steering offset (`steer_bias_std_rad`): whether landmark updates
    /// may move it, or only radar odometry's registrations may. Default true. False suits
    /// long drives where the map's features are not true points (the realistic city: the
    /// map pulled the offset 0.0003 rad off, 0.64 degrees every 100 m); true suits a short
    /// drive from a standstill, whose slow registrations are biased (slam-node/README.md,
    /// "The point-feature map pulls the steering offset").
    pub steer_bias_from_landmarks: bool,
    /// Radar odometry: register each rotation's detections (walls and fences included)
    /// against the previous rotation's and give the measured motion to the filter, an update
    /// of the pose's change since the previous rotation (and, where they are estimated, of
    /// the odometry corrections). Default false.
    pub radar_odometry: bool,
    /// Standard deviation of one registration's translation, each axis, m > 0. Default 0.05.
    pub radar_odometry_sigma_m: f64,
    /// Standard deviation of one registration's rotation, rad > 0. Default 0.003; unset
    /// where radar odometry runs beside wheel odometry (not localising), 0.0015: registered
    /// against keyframes too, so placed they err 1.6 mrad (slam-node's
    /// `FUSED_SIGMA_RAD`).
    pub radar_odometry_sigma_rad: f64,
    /// Share of a registration's covariance that is its two clouds' placement, in
    /// `[0, 0.45]`: how far each cloud was bent by the motion it was placed along. A
    /// registration of a rotation against the one before errs by the difference of the two
    /// clouds' placement errors plus white noise, so consecutive registrations' errors
    /// correlate by minus this share and cancel when chained; the filter holds the newest
    /// cloud's placement error in its state (slam-filter's
    /// `FilterSettings::registration_placement_share`). Default 0: every registration
    /// independent (measured both ways in slam-node's README, "The registrations' placement
    /// in the state"); unset on the radar alone (`source = "none"`) without a gyro and not
    /// localising, 0.2 (slam-node's `RADAR_ALONE_PLACEMENT_SHARE`; slam-node's README,
    /// "Where the turns' heading error comes from").
    pub radar_odometry_placement_share: f64,
    /// Radar only (`source = "none"`): the registration is composed onto the pose at the
    /// previous rotation, as odometry drives a pose, instead of fused as an update with a
    /// prediction that repeats the last rotation's motion. Default false. See slam-node's
    /// README, "Radar only".
    pub radar_odometry_compose: bool,
    /// With odometry of its own: each rotation's returns are placed for the registration
    /// with the turn the previous rotation's were placed with (held over this rotation's
    /// span), not the odometry's, while the odometry turns within 0.01 rad of it; the
    /// odometry's translation, and its start, are kept. A registration follows about half
    /// of the heading error of the motion its cloud is placed along, and two rotations
    /// placed alike cancel it on a steady road. Default true; the radar alone places along
    /// the held motion anyway. See slam-node's README, "Radar odometry placed with its
    /// reference's turn".
    pub radar_odometry_place_held: bool,
    /// With odometry of its own: registrations are run again from headings 5 mrad either
    /// side of their result, to measure the share of its start's heading each follows (the
    /// first ten, then every fourth while recent ones follow under 0.3 of it).
    /// Where the scene does not pin the heading (posts and poles smeared across the beam) a
    /// registration stays where it starts and would return the odometry's own heading as
    /// if measured: once the recent ones follow more than 0.6 of it on the average, and
    /// until they follow under 0.35, their heading and the motion across the track are not
    /// used (found so within the first 20 probed, the steering offset learned from
    /// the ones before is forgotten); a WARN and the summary say so. Below that, the recent
    /// average share is taken out of each registration's heading before the filter uses
    /// it (moved away from the odometry's heading it started from, and widened, by
    /// `1 / (1 - share)`, the share at most 0.5), so the odometry's heading is not counted
    /// twice. Default false: on the
    /// Oxford scans the share a registration follows measured 0.10-0.96 a rotation (0.55 on
    /// the mean, against 0.18 on the realistic city and 0.73 on a road of lamp posts), and
    /// with the evaluation's biased odometry their registrations were taken as unpinned
    /// from the first (final error 0.086 -> 0.514 m). The realistic city's examples and
    /// `vehicle.toml` turn it on. The radar alone has no other heading, and does not probe.
    /// See slam-node's README, "A registration that stays where it starts".
    pub radar_odometry_probe_start: bool,
    /// Earlier rotations' clouds each rotation is registered against besides the previous
    /// one's, kept where the registrations placed them (0 to 8). Unset: 3 when radar
    /// odometry alone drives the prediction (`source = "none"`, no gyro), where its errors
    /// add up rotation by rotation, and beside wheel odometry; 0 with a gyro or localising.
    /// See slam-node's README, "Radar only" and "The user's configuration on the realistic
    /// city".
    pub radar_odometry_keyframes: Option<i64>,
    /// A rotation's cloud becomes a keyframe when the vehicle ended it at least this far
    /// from where the newest keyframe's rotation ended, m >= 0. Default 0 (every rotation).
    pub radar_odometry_keyframe_spacing_m: f64,
    /// Times each registration is run again on its cloud from its own result, its pairs
    /// chosen afresh around it (0 to 4). A registration follows about a quarter of its
    /// start's heading error; beside wheel odometry the start is the wheels' motion, whose
    /// steering noise then comes into the filter twice (the wheels', and the
    /// registration's share of it). Unset: 0; the run without hard pairs
    /// (`radar_odometry_soft_kernel_m`) follows less, for less. Each run costs a
    /// registration. See slam-node's README, "The registration run again from its own
    /// result".
    pub radar_odometry_refine_runs: Option<i64>,
    /// Kernel width (m) of a last registration without hard pairs, from each registration's
    /// result: every return drawn towards every reference point within three widths,
    /// weighted by a Gaussian on their distance, so that the pose found moves continuously
    /// with the pose tried instead of stopping wherever one set of nearest pairs holds it
    /// (0 to 0.5; 0 for none). Unset: 0.1 whenever radar odometry runs (beside the wheels
    /// and on the radar alone). It costs about a registration. See slam-node's README, "A
    /// registration without hard pairs".
    pub radar_odometry_soft_kernel_m: Option<f64>,
}

/// The widest kernel of radar odometry's registration without hard pairs (`[odometry]
/// radar_odometry_soft_kernel_m`), m: its neighbours lie within three widths, 1.5 m, beyond
/// which a return's neighbours are most of a street's width apart.
pub const MAX_RADAR_ODOMETRY_SOFT_KERNEL_M: f64 = 0.5;

/// A soft kernel's width: finite, in `[0, MAX_RADAR_ODOMETRY_SOFT_KERNEL_M]`.
fn soft_kernel(k: f64) -> Result<f64, ValueError> {
    if k.is_finite() && (0.0..=MAX_RADAR_ODOMETRY_SOFT_KERNEL_M).contains(&k) {
        Ok(k)
    } else {
        Err(ValueError::OutOfRange {
            range: format!("[0, {MAX_RADAR_ODOMETRY_SOFT_KERNEL_M}]"),
            got: values::number(k),
        })
    }
}

/// Registrations run again from their own result at most (`[odometry]
/// radar_odometry_refine_runs`): each costs a registration a rotation.
pub const MAX_RADAR_ODOMETRY_REFINE_RUNS: u64 = 4;

/// Keyframes radar odometry registers against at most (`[odometry] radar_odometry_keyframes`):
/// each adds a cloud to the reference built every rotation.
pub const MAX_RADAR_ODOMETRY_KEYFRAMES: u64 = 8;

impl Default for RawOdometry {
    fn default() -> Self {
        Self {
            source: OdometrySourceKind::Tcp,
            address: None,
            path: None,
            topic: None,
            message: None,
            motion_model: MotionModelKind::Paper,
            step_s: None,
            wheelbase_m: None,
            sigma_speed_mps: 0.1,
            sigma_steer_rad: 0.01,
            speed_scale_std: 0.0,
            steer_bias_std_rad: 0.0,
            speed_scale_walk_per_sqrt_s: 1e-4,
            steer_bias_walk_rad_per_sqrt_s: 1e-5,
            stale_after_ms: 500,
            max_speed_mps: DEFAULT_MAX_SPEED_MPS,
            max_steer_rad: DEFAULT_MAX_STEER_RAD,
            max_accel_mps2: DEFAULT_MAX_ACCEL_MPS2,
            speed_scale_from_landmarks: true,
            steer_bias_from_landmarks: true,
            radar_odometry: false,
            radar_odometry_sigma_m: 0.05,
            radar_odometry_sigma_rad: 0.003,
            radar_odometry_placement_share: 0.0,
            radar_odometry_compose: false,
            radar_odometry_place_held: true,
            radar_odometry_probe_start: false,
            radar_odometry_keyframes: None,
            radar_odometry_keyframe_spacing_m: 0.0,
            radar_odometry_refine_runs: None,
            radar_odometry_soft_kernel_m: None,
        }
    }
}

/// Where odometry comes from, validated.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum OdometrySource {
    /// A TCP stream.
    Tcp {
        /// Where it is served.
        address: SocketAddr,
    },
    /// A file in the stream format.
    File {
        /// The file.
        path: PathBuf,
    },
    /// ROS 2 messages over Zenoh.
    Zenoh {
        /// The ROS 2 topic, absolute.
        topic: String,
        /// Its message type.
        message: OdometryMessageKind,
    },
    /// None.
    None,
}

/// The motion model, validated. The equations live in `radar-model`'s `motion` module.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionModel {
    /// The paper's eq. 2; `steer * dt / step_s` is the heading change over `dt`.
    Paper {
        /// The step, seconds.
        step_s: PositiveF64,
    },
    /// Kinematic bicycle: heading rate `v tan(steer) / wheelbase_m`.
    Bicycle {
        /// Wheelbase, metres.
        wheelbase_m: PositiveF64,
    },
}

/// `[odometry]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct OdometrySettings {
    /// Source.
    pub source: OdometrySource,
    /// Motion model.
    pub motion_model: MotionModel,
    /// Speed input noise, m/s.
    pub sigma_speed_mps: NonNegativeF64,
    /// Steering input noise, rad.
    pub sigma_steer_rad: NonNegativeF64,
    /// Prior standard deviation of the speed scale correction (0: not estimated), < 0.5.
    pub speed_scale_std: NonNegativeF64,
    /// Prior standard deviation of the steering offset, rad (0: not estimated).
    pub steer_bias_std_rad: NonNegativeF64,
    /// Random walk of the speed scale correction, per sqrt(s).
    pub speed_scale_walk_per_sqrt_s: NonNegativeF64,
    /// Random walk of the steering offset, rad per sqrt(s).
    pub steer_bias_walk_rad_per_sqrt_s: NonNegativeF64,
    /// Age past which odometry is stale.
    pub stale_after: Duration,
    /// Largest believable speed, m/s.
    pub max_speed_mps: PositiveF64,
    /// Largest believable steer, rad.
    pub max_steer_rad: PositiveF64,
    /// Largest believable change of speed, m/s^2.
    pub max_accel_mps2: PositiveF64,
    /// Landmark updates may move the odometry's speed correction.
    pub speed_scale_from_landmarks: bool,
    /// Landmark updates may move the odometry's steering offset.
    pub steer_bias_from_landmarks: bool,
    /// Radar odometry on.
    pub radar_odometry: bool,
    /// One registration's translation standard deviation, m.
    pub radar_odometry_sigma_m: PositiveF64,
    /// One registration's rotation standard deviation, rad.
    pub radar_odometry_sigma_rad: PositiveF64,
    /// Share of a registration's covariance that is its clouds' placement, `[0, 0.45]`.
    pub radar_odometry_placement_share: PlacementShare,
    /// Radar only: registrations composed onto the pose, not fused as updates.
    pub radar_odometry_compose: bool,
    /// With odometry of its own, each rotation placed with the turn its reference was
    /// placed with.
    pub radar_odometry_place_held: bool,
    /// With odometry of its own, each registration probed from headings either side, and
    /// its heading not used where recent ones followed their start's.
    pub radar_odometry_probe_start: bool,
    /// Earlier rotations' clouds registered against besides the previous one's (`None`:
    /// chosen by what drives the prediction).
    pub radar_odometry_keyframes: Option<u64>,
    /// Distance between keyframes, m.
    pub radar_odometry_keyframe_spacing_m: NonNegativeF64,
    /// Times each registration is run again from its own result (`None`: 0).
    pub radar_odometry_refine_runs: Option<u64>,
    /// Kernel width (m) of the registration without hard pairs, 0 for none (`None`: the
    /// daemon's default).
    pub radar_odometry_soft_kernel_m: Option<f64>,
}

impl Default for OdometrySettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawOdometry::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [odometry] defaults must be valid");
        settings
    }
}

fn only_with(other_key: &str, value: &str) -> ValueError {
    ValueError::Rule(format!(
        "is only used with {other_key} = \"{value}\"; remove it"
    ))
}

/// An absolute ROS 2 topic name: `/` then names of letters, digits and `_` (not starting
/// with a digit) joined by single slashes, no trailing slash.
pub fn ros_topic(text: &str) -> Result<String, ValueError> {
    let ok = text.strip_prefix('/').is_some_and(|rest| {
        rest.split('/').all(|name| {
            name.chars().next().is_some_and(|c| !c.is_ascii_digit())
                && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        })
    });
    if ok {
        Ok(text.to_owned())
    } else {
        Err(ValueError::Rule(format!(
            "must be an absolute ROS 2 topic name such as \"/odom\" (names of letters, digits and `_` after single slashes), got {text:?}"
        )))
    }
}

impl RawOdometry {
    /// Validates this section alone; errors name `odometry.<field>`.
    pub fn validate(&self) -> Result<OdometrySettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> OdometrySettings {
        if self.source != OdometrySourceKind::Tcp && self.address.is_some() {
            c.fail("odometry.address", only_with("odometry.source", "tcp"));
        }
        if self.source != OdometrySourceKind::File && self.path.is_some() {
            c.fail("odometry.path", only_with("odometry.source", "file"));
        }
        if self.source != OdometrySourceKind::Zenoh && self.topic.is_some() {
            c.fail("odometry.topic", only_with("odometry.source", "zenoh"));
        }
        if self.source != OdometrySourceKind::Zenoh && self.message.is_some() {
            c.fail("odometry.message", only_with("odometry.source", "zenoh"));
        }
        let source = match self.source {
            OdometrySourceKind::Tcp => OdometrySource::Tcp {
                address: c.check(
                    "odometry.address",
                    values::socket_addr(
                        self.address.as_deref().unwrap_or(DEFAULT_ODOMETRY_ADDRESS),
                    ),
                ),
            },
            OdometrySourceKind::File => match &self.path {
                Some(path) => OdometrySource::File {
                    path: c.check("odometry.path", values::non_empty_path(path)),
                },
                None => {
                    c.fail(
                        "odometry.path",
                        ValueError::Rule("is required with odometry.source = \"file\"".into()),
                    );
                    OdometrySource::None
                }
            },
            OdometrySourceKind::Zenoh => OdometrySource::Zenoh {
                topic: c
                    .check_ok(
                        "odometry.topic",
                        ros_topic(self.topic.as_deref().unwrap_or(DEFAULT_ODOMETRY_TOPIC)),
                    )
                    .unwrap_or_default(),
                message: self.message.unwrap_or_default(),
            },
            OdometrySourceKind::None => OdometrySource::None,
        };
        if self.motion_model != MotionModelKind::Paper && self.step_s.is_some() {
            c.fail(
                "odometry.step_s",
                only_with("odometry.motion_model", "paper"),
            );
        }
        if self.motion_model != MotionModelKind::Bicycle && self.wheelbase_m.is_some() {
            c.fail(
                "odometry.wheelbase_m",
                only_with("odometry.motion_model", "bicycle"),
            );
        }
        let motion_model = match self.motion_model {
            MotionModelKind::Paper => MotionModel::Paper {
                step_s: c.check(
                    "odometry.step_s",
                    PositiveF64::new(self.step_s.unwrap_or(DEFAULT_STEP_S)),
                ),
            },
            MotionModelKind::Bicycle => MotionModel::Bicycle {
                wheelbase_m: c.check(
                    "odometry.wheelbase_m",
                    PositiveF64::new(self.wheelbase_m.unwrap_or(DEFAULT_WHEELBASE_M)),
                ),
            },
        };
        OdometrySettings {
            source,
            motion_model,
            sigma_speed_mps: c.check(
                "odometry.sigma_speed_mps",
                NonNegativeF64::new(self.sigma_speed_mps),
            ),
            sigma_steer_rad: c.check(
                "odometry.sigma_steer_rad",
                NonNegativeF64::new(self.sigma_steer_rad),
            ),
            speed_scale_std: c.check(
                "odometry.speed_scale_std",
                NonNegativeF64::new(self.speed_scale_std).and_then(|v| {
                    if v.get() < 0.5 {
                        Ok(v)
                    } else {
                        Err(ValueError::Rule(format!(
                            "must be < 0.5 (a correction as uncertain as the speed itself is no correction), got {}",
                            values::number(v.get())
                        )))
                    }
                }),
            ),
            steer_bias_std_rad: c.check(
                "odometry.steer_bias_std_rad",
                NonNegativeF64::new(self.steer_bias_std_rad),
            ),
            speed_scale_walk_per_sqrt_s: c.check(
                "odometry.speed_scale_walk_per_sqrt_s",
                NonNegativeF64::new(self.speed_scale_walk_per_sqrt_s),
            ),
            steer_bias_walk_rad_per_sqrt_s: c.check(
                "odometry.steer_bias_walk_rad_per_sqrt_s",
                NonNegativeF64::new(self.steer_bias_walk_rad_per_sqrt_s),
            ),
            stale_after: c.check(
                "odometry.stale_after_ms",
                values::duration_from_ms(self.stale_after_ms),
            ),
            max_speed_mps: c.check(
                "odometry.max_speed_mps",
                PositiveF64::new(self.max_speed_mps),
            ),
            max_steer_rad: c.check(
                "odometry.max_steer_rad",
                PositiveF64::new(self.max_steer_rad),
            ),
            max_accel_mps2: c.check(
                "odometry.max_accel_mps2",
                PositiveF64::new(self.max_accel_mps2),
            ),
            speed_scale_from_landmarks: self.speed_scale_from_landmarks,
            steer_bias_from_landmarks: self.steer_bias_from_landmarks,
            radar_odometry: self.radar_odometry,
            radar_odometry_sigma_m: c.check(
                "odometry.radar_odometry_sigma_m",
                PositiveF64::new(self.radar_odometry_sigma_m),
            ),
            radar_odometry_sigma_rad: c.check(
                "odometry.radar_odometry_sigma_rad",
                PositiveF64::new(self.radar_odometry_sigma_rad),
            ),
            radar_odometry_placement_share: c.check(
                "odometry.radar_odometry_placement_share",
                PlacementShare::new(self.radar_odometry_placement_share),
            ),
            radar_odometry_compose: self.radar_odometry_compose,
            radar_odometry_place_held: self.radar_odometry_place_held,
            radar_odometry_probe_start: self.radar_odometry_probe_start,
            radar_odometry_keyframes: self.radar_odometry_keyframes.map(|k| {
                c.check(
                    "odometry.radar_odometry_keyframes",
                    values::count(k, MAX_RADAR_ODOMETRY_KEYFRAMES),
                )
            }),
            radar_odometry_keyframe_spacing_m: c.check(
                "odometry.radar_odometry_keyframe_spacing_m",
                NonNegativeF64::new(self.radar_odometry_keyframe_spacing_m),
            ),
            radar_odometry_refine_runs: self.radar_odometry_refine_runs.map(|k| {
                c.check(
                    "odometry.radar_odometry_refine_runs",
                    values::count(k, MAX_RADAR_ODOMETRY_REFINE_RUNS),
                )
            }),
            radar_odometry_soft_kernel_m: self
                .radar_odometry_soft_kernel_m
                .and_then(|k| c.check_ok("odometry.radar_odometry_soft_kernel_m", soft_kernel(k))),
        }
    }
}

impl From<&OdometrySettings> for RawOdometry {
    /// The settings written back out.
    fn from(s: &OdometrySettings) -> Self {
        let (source, address, path) = match &s.source {
            OdometrySource::Tcp { address } => {
                (OdometrySourceKind::Tcp, Some(address.to_string()), None)
            }
            OdometrySource::File { path } => (OdometrySourceKind::File, None, Some(path.clone())),
            OdometrySource::Zenoh { .. } => (OdometrySourceKind::Zenoh, None, None),
            OdometrySource::None => (OdometrySourceKind::None, None, None),
        };
        let (topic, message) = match &s.source {
            OdometrySource::Zenoh { topic, message } => (Some(topic.clone()), Some(*message)),
            _ => (None, None),
        };
        let (motion_model, step_s, wheelbase_m) = match s.motion_model {
            MotionModel::Paper { step_s } => (MotionModelKind::Paper, Some(step_s.get()), None),
            MotionModel::Bicycle { wheelbase_m } => {
                (MotionModelKind::Bicycle, None, Some(wheelbase_m.get()))
            }
        };
        Self {
            source,
            address,
            path,
            topic,
            message,
            motion_model,
            step_s,
            wheelbase_m,
            sigma_speed_mps: s.sigma_speed_mps.get(),
            sigma_steer_rad: s.sigma_steer_rad.get(),
            speed_scale_std: s.speed_scale_std.get(),
            steer_bias_std_rad: s.steer_bias_std_rad.get(),
            speed_scale_walk_per_sqrt_s: s.speed_scale_walk_per_sqrt_s.get(),
            steer_bias_walk_rad_per_sqrt_s: s.steer_bias_walk_rad_per_sqrt_s.get(),
            stale_after_ms: values::whole_ms(s.stale_after),
            max_speed_mps: s.max_speed_mps.get(),
            max_steer_rad: s.max_steer_rad.get(),
            max_accel_mps2: s.max_accel_mps2.get(),
            speed_scale_from_landmarks: s.speed_scale_from_landmarks,
            steer_bias_from_landmarks: s.steer_bias_from_landmarks,
            radar_odometry: s.radar_odometry,
            radar_odometry_sigma_m: s.radar_odometry_sigma_m.get(),
            radar_odometry_sigma_rad: s.radar_odometry_sigma_rad.get(),
            radar_odometry_placement_share: s.radar_odometry_placement_share.get(),
            radar_odometry_compose: s.radar_odometry_compose,
            radar_odometry_place_held: s.radar_odometry_place_held,
            radar_odometry_probe_start: s.radar_odometry_probe_start,
            radar_odometry_keyframes: s.radar_odometry_keyframes.map(values::as_i64),
            radar_odometry_keyframe_spacing_m: s.radar_odometry_keyframe_spacing_m.get(),
            radar_odometry_refine_runs: s.radar_odometry_refine_runs.map(values::as_i64),
            radar_odometry_soft_kernel_m: s.radar_odometry_soft_kernel_m,
        }
    }
}
