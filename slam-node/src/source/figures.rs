//! What a replay of recorded scans adds to the summary, in types that do not need the
//! simulator (so the daemon's report is the same with and without the `sim` feature).

/// The errors put on the ground truth's motion to make the odometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryErrors {
    /// Seed of the noise.
    pub seed: u64,
    /// Speed noise (m/s, standard deviation per sample).
    pub sigma_speed_mps: f64,
    /// Yaw-rate noise (rad/s, standard deviation per sample).
    pub sigma_yaw_rate_rps: f64,
    /// Speed scale (1.05: the odometry reads 5 % fast).
    pub speed_scale: f64,
    /// Yaw-rate bias (rad/s).
    pub yaw_rate_bias_rps: f64,
}

impl Default for OdometryErrors {
    fn default() -> Self {
        Self {
            seed: 1,
            sigma_speed_mps: 0.05,
            sigma_yaw_rate_rps: 0.005,
            speed_scale: 1.0,
            yaw_rate_bias_rps: 0.0,
        }
    }
}

/// What the replay adds to the summary.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayFigures {
    /// The odometry's errors.
    pub errors: OdometryErrors,
    /// Distance driven (ground truth, m).
    pub distance_m: f64,
    /// Dead reckoning's RMS position error at the scan times (m).
    pub dead_reckoning_rms_m: f64,
    /// Dead reckoning's final position error (m).
    pub dead_reckoning_final_m: f64,
    /// The data set's layout.
    pub format: Option<&'static str>,
    /// Scans in the recording.
    pub scans: usize,
    /// Scans the simulator skipped as damaged.
    pub scans_skipped: u64,
    /// Why the first of them was skipped (naming the file).
    pub first_scan_skipped: Option<String>,
    /// The range-Doppler coupling the detections were corrected with (s).
    pub doppler_range_coupling_s: f64,
    /// No odometry was made: radar odometry drove the filter (`--radar-only`).
    pub radar_only: bool,
    /// The recording had ground truth (without, nothing is scored).
    pub ground_truth: bool,
}
