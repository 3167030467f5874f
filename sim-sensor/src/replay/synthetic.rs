//! Small synthetic recordings in the Boreas and RADIATE layouts, laid out as the real data
//! sets are (see [`super::format`]), for tests and demonstrations where no real data is at
//! hand: a vehicle driving a constant-speed, constant-yaw-rate arc past point reflectors,
//! seen by a rotating radar whose every azimuth is drawn from the pose at its own time.
//!
//! File IO: each `write_*` creates the layout's files under a folder.

use std::f64::consts::PI;
use std::io::Write as _;
use std::path::Path;

use radar_model::geometry::{wrap_angle, Pose2};

use super::scans::ENCODER_SIZE;

/// A synthetic drive and the radar that recorded it.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticDrive {
    /// Scans (rotations).
    pub scans: usize,
    /// Azimuths per rotation.
    pub azimuths: u16,
    /// Range bins per azimuth.
    pub bins: u16,
    /// Bin size (m).
    pub bin_m: f64,
    /// Rotation period (µs).
    pub period_us: i64,
    /// Start of the first rotation (µs since the epoch).
    pub start_us: i64,
    /// Speed (m/s).
    pub speed_mps: f64,
    /// Yaw rate (rad/s, counter-clockwise).
    pub yaw_rate_rps: f64,
    /// Pose at `start_us` in the world frame (x east, y north, heading counter-clockwise
    /// from east).
    pub start: Pose2,
    /// Point reflectors (world x, y; m).
    pub reflectors: Vec<(f64, f64)>,
}

impl SyntheticDrive {
    /// Six 4 Hz rotations of 400 azimuths of `bins` bins of `bin_m`, driving at 8 m/s and
    /// 0.1 rad/s from (100, 200) heading 0.5 rad, past six reflectors.
    pub fn new(bins: u16, bin_m: f64) -> SyntheticDrive {
        SyntheticDrive {
            scans: 6,
            azimuths: 400,
            bins,
            bin_m,
            period_us: 250_000,
            start_us: 1_600_000_000_000_000,
            speed_mps: 8.0,
            yaw_rate_rps: 0.1,
            start: Pose2::new(100.0, 200.0, 0.5),
            reflectors: vec![
                (110.0, 215.0),
                (125.0, 205.0),
                (95.0, 220.0),
                (130.0, 225.0),
                (85.0, 195.0),
                (115.0, 190.0),
            ],
        }
    }

    /// The world pose at `t_us` (exact arc).
    pub fn pose_at(&self, t_us: i64) -> Pose2 {
        let t = (t_us - self.start_us) as f64 * 1e-6;
        let (v, w, p) = (self.speed_mps, self.yaw_rate_rps, self.start);
        let theta = p.theta + w * t;
        let (x, y) = if w.abs() < 1e-12 {
            (p.x + v * t * p.theta.cos(), p.y + v * t * p.theta.sin())
        } else {
            (
                p.x + v / w * (theta.sin() - p.theta.sin()),
                p.y - v / w * (theta.cos() - p.theta.cos()),
            )
        };
        Pose2::new(x, y, wrap_angle(theta))
    }

    /// Time of azimuth `a` of scan `k` (µs).
    pub fn azimuth_time_us(&self, k: usize, a: u16) -> i64 {
        self.start_us
            + k as i64 * self.period_us
            + i64::from(a) * self.period_us / i64::from(self.azimuths.max(1))
    }

    /// The bins of azimuth `a` of scan `k`: a noise floor of 20-40 and each reflector within
    /// half an azimuth step drawn as a peak of 220 one bin wide with shoulders of 120.
    pub fn azimuth_bins(&self, k: usize, a: u16) -> Vec<u8> {
        let n = usize::from(self.bins);
        let mut seed = (k as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ u64::from(a);
        let mut bins: Vec<u8> = (0..n)
            .map(|_| {
                seed = seed
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                20 + ((seed >> 59) as u8) + ((seed >> 40) & 3) as u8
            })
            .collect();
        let pose = self.pose_at(self.azimuth_time_us(k, a));
        let step = 2.0 * PI / f64::from(self.azimuths.max(1));
        // The azimuth's bearing, clockwise from forward.
        let beam = f64::from(a) * step;
        for &(x, y) in &self.reflectors {
            let (dx, dy) = (x - pose.x, y - pose.y);
            let range = dx.hypot(dy);
            let clockwise = wrap_angle(pose.theta - dy.atan2(dx));
            if wrap_angle(clockwise - beam).abs() > 0.5 * step {
                continue;
            }
            let bin = (range / self.bin_m).floor() as usize;
            for (b, v) in [(bin.wrapping_sub(1), 120), (bin, 220), (bin + 1, 120)] {
                if let Some(slot) = bins.get_mut(b) {
                    *slot = (*slot).max(v);
                }
            }
        }
        bins
    }

    /// Writes a Boreas sequence folder: `radar/<µs>.png` (rows of 8-byte time, 2-byte
    /// encoder, an unused byte of 0, the bins; named by the time of azimuth
    /// `azimuths / 2 - 1`, the middle of the scan) and `applanix/radar_poses.csv` (the
    /// radar's pose at each scan's time, its z axis down: roll pi, heading counter-clockwise
    /// from east).
    pub fn write_boreas(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir.join("radar"))?;
        std::fs::create_dir_all(dir.join("applanix"))?;
        let mut csv = String::from("GPSTime,easting,northing,altitude,vel_east,vel_north,vel_up,roll,pitch,heading,angvel_z,angvel_y,angvel_x\n");
        for k in 0..self.scans {
            let name_us = self.boreas_scan_time_us(k);
            let width = 11 + usize::from(self.bins);
            let mut data = Vec::with_capacity(width * usize::from(self.azimuths));
            for a in 0..self.azimuths {
                data.extend_from_slice(&self.azimuth_time_us(k, a).to_le_bytes());
                let enc = u32::from(a) * u32::from(ENCODER_SIZE) / u32::from(self.azimuths);
                data.extend_from_slice(&(enc as u16).to_le_bytes());
                data.push(0);
                data.extend_from_slice(&self.azimuth_bins(k, a));
            }
            write_gray_png(
                &dir.join("radar").join(format!("{name_us}.png")),
                width,
                usize::from(self.azimuths),
                &data,
            )?;
            let p = self.pose_at(name_us);
            let (v, w) = (self.speed_mps, self.yaw_rate_rps);
            csv.push_str(&format!(
                "{name_us},{:.6},{:.6},150.0,{:.6},{:.6},0.0,{:.15},0.0,{:.15},{:.6},0.0,0.0\n",
                p.x,
                p.y,
                v * p.theta.cos(),
                v * p.theta.sin(),
                PI,
                p.theta,
                -w
            ));
        }
        std::fs::write(dir.join("applanix").join("radar_poses.csv"), csv)
    }

    /// The RADIATE index time (µs) of scan `k`: its last azimuth's.
    pub fn radiate_scan_time_us(&self, k: usize) -> i64 {
        self.azimuth_time_us(k, self.azimuths.saturating_sub(1))
    }

    /// The Boreas file name (µs) of scan `k`.
    pub fn boreas_scan_time_us(&self, k: usize) -> i64 {
        self.azimuth_time_us(k, (self.azimuths / 2).saturating_sub(1))
    }

    /// Writes a RADIATE sequence folder: `Navtech_Polar/<frame:06>.png` (range rows x
    /// azimuth columns), `Navtech_Polar.txt` (each scan's arrival: its last azimuth's time,
    /// [`SyntheticDrive::radiate_scan_time_us`]), `GPS_IMU_Twist.txt` and
    /// `GPS_IMU_Twist/<frame:06>.txt` at 20 Hz from half a second before the first scan to
    /// half a second after the last, each time written twice as RADIATE does (latitude and
    /// longitude about 55.9 N 3.3 W on line 1; north, east, down velocity on line 17).
    pub fn write_radiate(&self, dir: &Path) -> std::io::Result<()> {
        let polar = dir.join("Navtech_Polar");
        let gps = dir.join("GPS_IMU_Twist");
        std::fs::create_dir_all(&polar)?;
        std::fs::create_dir_all(&gps)?;
        let mut index = String::new();
        let (rows, cols) = (usize::from(self.bins), usize::from(self.azimuths));
        for k in 0..self.scans {
            let mut data = vec![0u8; rows * cols];
            for a in 0..self.azimuths {
                for (r, v) in self.azimuth_bins(k, a).into_iter().enumerate() {
                    if let Some(px) = data.get_mut(r * cols + usize::from(a)) {
                        *px = v;
                    }
                }
            }
            write_gray_png(&polar.join(format!("{:06}.png", k + 1)), cols, rows, &data)?;
            index.push_str(&format!(
                "Frame: {:06} Time: {}\n",
                k + 1,
                seconds_text(self.radiate_scan_time_us(k))
            ));
        }
        std::fs::write(dir.join("Navtech_Polar.txt"), index)?;
        let (lat0, lon0) = (55.892_359_288, -3.321_673_745);
        let (m_per_deg_lat, m_per_deg_lon) = metres_per_degree(lat0);
        let mut gps_index = String::new();
        let end = self.start_us + self.scans as i64 * self.period_us + 500_000;
        let mut t = self.start_us - 500_000;
        let mut frame = 1;
        while t <= end {
            let p = self.pose_at(t);
            let (lat, lon) = (lat0 + p.y / m_per_deg_lat, lon0 + p.x / m_per_deg_lon);
            let (vn, ve) = (
                self.speed_mps * p.theta.sin(),
                self.speed_mps * p.theta.cos(),
            );
            for _ in 0..2 {
                let mut f = std::fs::File::create(gps.join(format!("{frame:06}.txt")))?;
                writeln!(f, "{lat:.15},{lon:.15},60.0 ")?;
                for line in GPS_FILLER {
                    writeln!(f, "{line}")?;
                }
                writeln!(f, "{vn:.5},{ve:.5},0.00000 ")?;
                writeln!(f, "0.00000,0.00000,{:.5} ", -self.yaw_rate_rps)?;
                gps_index.push_str(&format!("Frame: {frame:06} Time: {}\n", seconds_text(t)));
                frame += 1;
            }
            t += 50_000;
        }
        std::fs::write(dir.join("GPS_IMU_Twist.txt"), gps_index)
    }
}

/// Lines 2-16 of a RADIATE GPS/IMU file: covariances, orientation, rates, accelerations.
const GPS_FILLER: [&str; 15] = [
    "0.026894760054574,0.000000000000000,0.000000000000000 ",
    " 0.000000000000000,0.040273964608809,0.000000000000000 ",
    " 0.000000000000000,0.000000000000000,0.146884650049395 ",
    "-0.00388,0.00605,-0.98632,-0.16469 ",
    "-0.00266,-0.01089,0.03308 ",
    "-0.52967,0.51694,-0.04700 ",
    "0.0,0.0,0.0 ",
    " 0.0,0.0,0.0 ",
    " 0.0,0.0,0.0 ",
    "0.0,0.0,0.0 ",
    " 0.0,0.0,0.0 ",
    " 0.0,0.0,0.0 ",
    "0.0,0.0,0.0 ",
    " 0.0,0.0,0.0 ",
    " 0.0,0.0,0.0 ",
];

/// Metres per degree of latitude and of longitude at `lat_deg` (WGS-84), the inverse of
/// [`super::radiate::local_east_north`].
pub fn metres_per_degree(lat_deg: f64) -> (f64, f64) {
    let origin = super::radiate::GpsFix {
        time_us: 0,
        lat_deg,
        lon_deg: 0.0,
        v_north_mps: 0.0,
        v_east_mps: 0.0,
    };
    let north = super::radiate::local_east_north(
        &origin,
        &super::radiate::GpsFix {
            lat_deg: lat_deg + 1.0,
            ..origin
        },
    )
    .1;
    let east = super::radiate::local_east_north(
        &origin,
        &super::radiate::GpsFix {
            lon_deg: 1.0,
            ..origin
        },
    )
    .0;
    (north, east)
}

/// `s.nnnnnnnnn` for µs since the epoch, as RADIATE's index files write times.
pub fn seconds_text(us: i64) -> String {
    format!("{}.{:06}000", us / 1_000_000, us % 1_000_000)
}

/// Writes an 8-bit greyscale PNG.
pub fn write_gray_png(
    path: &Path,
    width: usize,
    height: usize,
    data: &[u8],
) -> std::io::Result<()> {
    let too_big = |_| std::io::Error::new(std::io::ErrorKind::InvalidInput, "image too large");
    let file = std::fs::File::create(path)?;
    let mut enc = png::Encoder::new(
        std::io::BufWriter::new(file),
        u32::try_from(width).map_err(too_big)?,
        u32::try_from(height).map_err(too_big)?,
    );
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    let mut w = enc.write_header().map_err(std::io::Error::other)?;
    w.write_image_data(data).map_err(std::io::Error::other)?;
    w.finish().map_err(std::io::Error::other)
}
