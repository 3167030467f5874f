//! The detections of one rotation that reached the filter, in the radar's frame, for the
//! MCAP recording's detections topic.

/// One target down one beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// When its beam was measured, Unix seconds.
    pub timestamp_s: f64,
    /// Range, metres.
    pub range_m: f64,
    /// Bearing, radians clockwise from forward (`docs/contracts.md`).
    pub bearing_rad: f64,
    /// Uncompensated received power, dB.
    pub power_db: f64,
}

impl Detection {
    /// Position in a ROS frame at the radar (x forward, y left, REP 103): the bearing is
    /// clockwise, so y = -r sin(beta).
    pub fn xy_ros(&self) -> (f64, f64) {
        (
            self.range_m * self.bearing_rad.cos(),
            -self.range_m * self.bearing_rad.sin(),
        )
    }
}

/// The detections of one rotation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RotationDetections {
    /// Rotation counter (as in the diagnostics).
    pub rotation: u64,
    /// Time of the rotation's last azimuth, Unix seconds.
    pub timestamp_s: f64,
    /// The targets of every beam the filter processed.
    pub detections: Vec<Detection>,
}
