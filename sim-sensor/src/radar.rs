//! The simulated radar's parameters, the two shipped presets, and the configuration message
//! they announce.

use serde::Deserialize;

use crate::error::SceneError;

/// Bits per bin on the wire: 8 (message 30) or 16 (message 31).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataWidth {
    /// One byte a bin, power dB = value / 2 (message 30).
    Bits8,
    /// Two little-endian bytes a bin, power dB = raw / 256 x 96.5 / 141.5 (message 31).
    Bits16,
}

impl DataWidth {
    /// From a bit count (8 or 16).
    pub fn from_bits(bits: u32) -> Option<Self> {
        match bits {
            8 => Some(DataWidth::Bits8),
            16 => Some(DataWidth::Bits16),
            _ => None,
        }
    }

    /// The bit count, as the configuration's `datawidth` field carries it.
    pub fn bits(self) -> u32 {
        match self {
            DataWidth::Bits8 => 8,
            DataWidth::Bits16 => 16,
        }
    }

    /// Bytes per bin.
    pub fn bytes_per_bin(self) -> usize {
        match self {
            DataWidth::Bits8 => 1,
            DataWidth::Bits16 => 2,
        }
    }
}

/// The CTS350-X's range-Doppler coupling, seconds: a return closing on the radar at `v`
/// m/s reads `0.049 v` metres short (Burnett et al., RA-L 2021).
pub const CTS350X_DOPPLER_RANGE_COUPLING_S: f64 = 0.049;

/// A named radar preset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub enum RadarPreset {
    /// The unit in the paper: 200 azimuths of 1.8 degrees, 0.25 m bins to 200 m.
    #[serde(rename = "paper-200")]
    Paper200,
    /// A CTS350-X-like unit (Oxford Radar RobotCar): 400 azimuths, 3768 bins of 0.0438 m,
    /// encoder 5600, 4 Hz.
    #[serde(rename = "cts350x-400")]
    Cts350x400,
}

impl RadarPreset {
    /// The preset's name in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            RadarPreset::Paper200 => "paper-200",
            RadarPreset::Cts350x400 => "cts350x-400",
        }
    }

    /// Looks a preset up by name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "paper-200" => Some(RadarPreset::Paper200),
            "cts350x-400" => Some(RadarPreset::Cts350x400),
            _ => None,
        }
    }

    /// The preset's parameters (8-bit data).
    ///
    /// The paper's unit: 200 azimuths (1.8 degree steps), a 1.8 degree pencil beam, 0.25 m
    /// range resolution (c / 2B with B = 600 MHz), 800 bins (200 m). The paper does not
    /// give its rotation rate or encoder size: 2.5 Hz (500 azimuths a second) and an encoder
    /// of 5600 counts are this simulator's assumptions.
    ///
    /// The CTS350-X-like unit: 400 azimuths, encoder 5600 (steps of 14), 3768 bins of
    /// 0.0438 m (165 m), 4 Hz, 1600 azimuths a second, and the same 1.8 degree beam as the
    /// paper's (Navtech quotes 1.8 degrees horizontal beam width for the CTS350-X), and its
    /// sawtooth chirp's range-Doppler coupling of 0.049 s (Burnett et al., "Do we need to
    /// compensate for motion distortion and Doppler effects in spinning radar navigation?",
    /// RA-L 2021). The paper's unit renders no coupling.
    pub fn params(self) -> RadarParams {
        match self {
            RadarPreset::Paper200 => RadarParams {
                azimuths: 200,
                encoder_size: 5600,
                range_bins: 800,
                bin_size_tenth_mm: 2500,
                rotation_mhz: 2500,
                range_gain: 1.0,
                range_offset_m: 0.0,
                data_width: DataWidth::Bits8,
                beam_width_rad: 1.8_f64.to_radians(),
                doppler_range_coupling_s: 0.0,
            },
            RadarPreset::Cts350x400 => RadarParams {
                azimuths: 400,
                encoder_size: 5600,
                range_bins: 3768,
                bin_size_tenth_mm: 438,
                rotation_mhz: 4000,
                range_gain: 1.0,
                range_offset_m: 0.0,
                data_width: DataWidth::Bits8,
                beam_width_rad: 1.8_f64.to_radians(),
                doppler_range_coupling_s: CTS350X_DOPPLER_RANGE_COUPLING_S,
            },
        }
    }
}

/// Everything the simulated radar announces in its configuration and renders with.
///
/// Fields are kept in the wire's own units (tenths of a millimetre, millihertz) so the
/// configuration message says exactly what the renderer uses.
#[derive(Debug, Clone, PartialEq)]
pub struct RadarParams {
    /// Azimuths per rotation.
    pub azimuths: u16,
    /// Encoder counts per revolution.
    pub encoder_size: u16,
    /// Bins per azimuth.
    pub range_bins: u16,
    /// Bin size in tenths of a millimetre (438 is 0.0438 m).
    pub bin_size_tenth_mm: u16,
    /// Rotation rate in millihertz (4000 is 4 Hz).
    pub rotation_mhz: u16,
    /// The configuration's range gain.
    pub range_gain: f32,
    /// The configuration's range offset, metres.
    pub range_offset_m: f32,
    /// 8 or 16 bits per bin.
    pub data_width: DataWidth,
    /// Beam width used to decide which features a beam sees, radians.
    pub beam_width_rad: f64,
    /// FMCW range-Doppler coupling, seconds: a return closing on the radar at `v` m/s is
    /// rendered `doppler_range_coupling_s x v` metres short (receding: long). A sawtooth
    /// chirp's beat frequency adds the Doppler shift to the range's; 0.049 s for a CTS350-X,
    /// 0 for the paper's unit. A client undoes it with its own estimate of the coupling
    /// (the daemon's `[model] doppler_range_coupling_s`).
    pub doppler_range_coupling_s: f64,
}

impl RadarParams {
    /// The configuration message (10) this radar announces; a client derives its geometry
    /// from it (`Configuration::geometry`).
    pub fn configuration(&self) -> protocol::Configuration {
        protocol::Configuration {
            azimuth_samples: self.azimuths,
            bin_size: self.bin_size_tenth_mm,
            range_in_bins: self.range_bins,
            encoder_size: self.encoder_size,
            rotation_speed_millihertz: self.rotation_mhz,
            packet_rate: self.packet_rate(),
            range_gain: self.range_gain,
            range_offset_m: self.range_offset_m,
            data: protocol::ConfigurationData::minimal(
                i32::try_from(self.data_width.bits()).unwrap_or(8),
                (f64::from(self.range_gain) * self.bin_size_m()) as f32,
            ),
        }
    }

    /// Checks the parameters fit the wire and make a usable radar.
    pub fn validate(&self) -> Result<(), SceneError> {
        let bad = |field: &str, reason: String| {
            Err(SceneError::Invalid {
                field: format!("radar.{field}"),
                reason,
            })
        };
        if self.azimuths == 0 {
            return bad("azimuths", "must be > 0".into());
        }
        if self.encoder_size < self.azimuths {
            return bad(
                "encoder_size",
                format!(
                    "must be >= azimuths ({}), got {}",
                    self.azimuths, self.encoder_size
                ),
            );
        }
        if self.range_bins == 0 {
            return bad("range_bins", "must be > 0".into());
        }
        if self.bin_size_tenth_mm == 0 {
            return bad("bin_size_m", "must be >= 0.0001 m".into());
        }
        if self.rotation_mhz == 0 {
            return bad("rotation_hz", "must be >= 0.001 Hz".into());
        }
        let rate = self.packet_rate_f64();
        if rate > f64::from(u16::MAX) {
            return bad(
                "rotation_hz",
                format!("azimuths x rotation rate = {rate:.1}/s does not fit the wire's u16"),
            );
        }
        if !(self.range_gain.is_finite() && self.range_gain > 0.0) {
            return bad(
                "range_gain",
                format!("must be finite and > 0, got {}", self.range_gain),
            );
        }
        if !self.range_offset_m.is_finite() {
            return bad("range_offset_m", "must be finite".into());
        }
        if !(self.beam_width_rad.is_finite()
            && self.beam_width_rad > 0.0
            && self.beam_width_rad < std::f64::consts::PI)
        {
            return bad("beam_width_deg", "must be in (0, 180) degrees".into());
        }
        if !(self.doppler_range_coupling_s.is_finite()
            && self.doppler_range_coupling_s.abs() <= 1.0)
        {
            return bad(
                "doppler_range_coupling_s",
                format!(
                    "must be finite and in [-1, 1] s, got {}",
                    self.doppler_range_coupling_s
                ),
            );
        }
        Ok(())
    }

    /// Bin size in metres.
    pub fn bin_size_m(&self) -> f64 {
        f64::from(self.bin_size_tenth_mm) / 10_000.0
    }

    /// Rotation rate in hertz.
    pub fn rotation_hz(&self) -> f64 {
        f64::from(self.rotation_mhz) / 1000.0
    }

    /// Azimuths per second as a real number.
    pub fn packet_rate_f64(&self) -> f64 {
        f64::from(self.azimuths) * self.rotation_hz()
    }

    /// Azimuths per second as the configuration message carries it (rounded).
    pub fn packet_rate(&self) -> u16 {
        let rate = self.packet_rate_f64().round();
        if rate >= f64::from(u16::MAX) {
            u16::MAX
        } else if rate <= 0.0 {
            0
        } else {
            rate as u16
        }
    }

    /// Time between two azimuths, nanoseconds (rounded).
    pub fn azimuth_period_ns(&self) -> u64 {
        // rate >= 0.001 Hz x 1 azimuth, validated; the quotient is finite and positive.
        (1e9 / self.packet_rate_f64()).round() as u64
    }

    /// The encoder value of azimuth `index` within a rotation (`index < azimuths`).
    pub fn encoder_of(&self, index: u16) -> u16 {
        let value = (u32::from(index) * u32::from(self.encoder_size))
            .checked_div(u32::from(self.azimuths))
            .unwrap_or(0);
        u16::try_from(value).unwrap_or(u16::MAX)
    }

    /// The azimuth angle of encoder value `encoder`, radians clockwise from forward.
    pub fn angle_of_encoder(&self, encoder: u16) -> f64 {
        f64::from(encoder) * std::f64::consts::TAU / f64::from(self.encoder_size)
    }

    /// The range in metres of the centre of bin `bin`, as a client computes it from the
    /// configuration: `gain x bin x bin_size + offset`.
    pub fn range_of_bin_m(&self, bin: usize) -> f64 {
        f64::from(self.range_gain) * (bin as f64) * self.bin_size_m()
            + f64::from(self.range_offset_m)
    }

    /// How much nearer than its range a return closing on the radar at `closing_mps`
    /// (m/s; negative: receding) is rendered, metres: `doppler_range_coupling_s x
    /// closing_mps`. For a static return seen from a vehicle moving forward at `speed`,
    /// along a beam at bearing `b` (clockwise from forward), the closing speed is `speed x
    /// cos(b)`.
    pub fn doppler_range_shift_m(&self, closing_mps: f64) -> f64 {
        self.doppler_range_coupling_s * closing_mps
    }

    /// The far end of the rendered range, metres.
    pub fn max_range_m(&self) -> f64 {
        self.range_of_bin_m(usize::from(self.range_bins))
    }
}

/// Nanoseconds from azimuth 0 to azimuth `index` at the radar's rate (exact integer maths).
pub fn offset_ns(radar: &RadarParams, index: u64) -> u64 {
    let per_s = u128::from(radar.azimuths) * u128::from(radar.rotation_mhz);
    if per_s == 0 {
        return 0;
    }
    let ns = u128::from(index) * 1_000_000_000_000 / per_s;
    u64::try_from(ns).unwrap_or(u64::MAX)
}

/// Index of azimuth `index` within its rotation.
pub fn azimuth_in_rotation(radar: &RadarParams, index: u64) -> u16 {
    u16::try_from(index % u64::from(radar.azimuths.max(1))).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cts350x_preset_matches_the_oxford_recordings() {
        let p = RadarPreset::Cts350x400.params();
        p.validate().expect("valid");
        assert_eq!(p.azimuths, 400);
        assert_eq!(p.range_bins, 3768);
        assert_eq!(p.encoder_size, 5600);
        assert_eq!(p.packet_rate(), 1600);
        assert_eq!(p.encoder_of(1), 14);
        assert_eq!(p.encoder_of(399), 5586);
        assert!((p.bin_size_m() - 0.0438).abs() < 1e-12);
        assert_eq!(p.azimuth_period_ns(), 625_000);
    }

    #[test]
    fn the_paper_preset_has_1_8_degree_steps_and_reaches_200_m() {
        let p = RadarPreset::Paper200.params();
        p.validate().expect("valid");
        let step_deg = p.angle_of_encoder(p.encoder_of(1)).to_degrees();
        assert!((step_deg - 1.8).abs() < 1e-9);
        assert!((p.max_range_m() - 200.0).abs() < 1e-9);
    }

    #[test]
    fn an_unrepresentable_packet_rate_is_rejected() {
        let mut p = RadarPreset::Cts350x400.params();
        p.rotation_mhz = 60_000;
        p.azimuths = 2000;
        p.encoder_size = 5600;
        assert!(p.validate().is_err());
    }
}
