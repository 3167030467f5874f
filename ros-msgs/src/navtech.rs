//! Navtech's `navtech_msgs` (the ROS 2 packages of Navtech's IASDK, 2024): what their
//! driver publishes on `radar_data/fft_data` (one azimuth a message),
//! `radar_data/b_scan_msg` (one rotation a message) and `radar_data/configuration_data`.
//!
//! The layouts are the SDK's `navtech_msgs/msg/*.msg`: `RadarBScanMsg` as in
//! `ros/ros2/src/navtech_msgs/msg/RadarBScanMsg.msg`; `RadarFftDataMsg` and
//! `RadarConfigurationMsg` with their typed fields (the 2024 SDK replaced the older
//! `nav_messages` network-order byte arrays by typed fields and added `azimuth_offset`, which
//! its `b_scan_extended_publisher` fills).

use serde::{Deserialize, Serialize};

use crate::schema::{MsgDef, RosMessage};
use crate::sensor::{Image, IMAGE};
use crate::std_msgs::{Header, HEADER};

/// `navtech_msgs/RadarFftDataMsg`: one azimuth.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RadarFftDataMsg {
    /// Time and frame.
    pub header: Header,
    /// Azimuth angle, degrees (as Navtech's driver fills it).
    pub angle: f64,
    /// Encoder count.
    pub azimuth: u16,
    /// The radar's sweep counter.
    pub sweep_counter: u16,
    /// Seconds of the radar's timestamp.
    pub ntp_seconds: u32,
    /// Nanoseconds of the radar's timestamp.
    pub ntp_split_seconds: u32,
    /// The bins.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
    /// Bins in `data`.
    pub data_length: u16,
}

/// Definition of [`RadarFftDataMsg`].
pub static RADAR_FFT_DATA_MSG: MsgDef = MsgDef {
    name: "navtech_msgs/RadarFftDataMsg",
    text: "# A ROS message based on an FFT data message from a radar\nstd_msgs/Header header\nfloat64 angle\nuint16 azimuth\nuint16 sweep_counter\nuint32 ntp_seconds\nuint32 ntp_split_seconds\nuint8[] data\nuint16 data_length\n",
    uses: &[&HEADER],
};

impl RosMessage for RadarFftDataMsg {
    const DEF: &'static MsgDef = &RADAR_FFT_DATA_MSG;
}

/// `navtech_msgs/RadarBScanMsg`: one rotation as an image (a row per azimuth, a column per
/// bin, `8UC1`) with each row's encoder value and timestamp.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RadarBScanMsg {
    /// The B-scan.
    pub b_scan_img: Image,
    /// Encoder value of each row.
    pub encoder_values: Vec<u16>,
    /// Timestamp of each row, nanoseconds since the epoch.
    pub timestamps: Vec<u64>,
}

/// Definition of [`RadarBScanMsg`].
pub static RADAR_BSCAN_MSG: MsgDef = MsgDef {
    name: "navtech_msgs/RadarBScanMsg",
    text: "# A ROS message carrying a B Scan and its associated metadata (e.g. timestamps, encoder IDs)\n\n# B Scan from one rotation of the radar, also holds the time stamp information\nsensor_msgs/Image b_scan_img\n\n# The encoder values encompassed by the b scan\nuint16[] encoder_values\n\n# The timestamps of each azimuth in the scan, in nanoseconds\nuint64[] timestamps\n",
    uses: &[&IMAGE],
};

impl RosMessage for RadarBScanMsg {
    const DEF: &'static MsgDef = &RADAR_BSCAN_MSG;
}

/// `navtech_msgs/RadarConfigurationMsg`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RadarConfigurationMsg {
    /// Time and frame.
    pub header: Header,
    /// Azimuths per rotation.
    pub azimuth_samples: u16,
    /// Encoder counts per rotation.
    pub encoder_size: u16,
    /// User azimuth offset (rows the B-scan is rotated by).
    pub azimuth_offset: u16,
    /// Bin size as the radar sends it: tenths of a millimetre (438 is 0.0438 m; Navtech's
    /// driver copies the wire's integer).
    pub bin_size: f32,
    /// Bins per azimuth.
    pub range_in_bins: u16,
    /// Rotation rate as the radar sends it: millihertz (4000 is 4 Hz).
    pub expected_rotation_rate: u16,
    /// Range gain.
    pub range_gain: f32,
    /// Range offset, metres.
    pub range_offset: f32,
}

/// Definition of [`RadarConfigurationMsg`].
pub static RADAR_CONFIGURATION_MSG: MsgDef = MsgDef {
    name: "navtech_msgs/RadarConfigurationMsg",
    text: "# A ROS message based on a configuration data message from a radar\nstd_msgs/Header header\nuint16 azimuth_samples\nuint16 encoder_size\nuint16 azimuth_offset\nfloat32 bin_size\nuint16 range_in_bins\nuint16 expected_rotation_rate\nfloat32 range_gain\nfloat32 range_offset\n",
    uses: &[&HEADER],
};

impl RosMessage for RadarConfigurationMsg {
    const DEF: &'static MsgDef = &RADAR_CONFIGURATION_MSG;
}
