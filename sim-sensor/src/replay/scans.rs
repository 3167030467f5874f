//! The scans of a recording in any of the known layouts ([`ReplayFormat`]): which files, in
//! which order, at which times ([`ScanSet`]); the geometry the recording announces, learned
//! from its data ([`ScanGeometry`]); and reading one scan as rows of one azimuth each
//! ([`ScanRecording::read`]), checked against that geometry.
//!
//! Blocking file IO: call it from `spawn_blocking` in async code.

pub use super::format::{ScanFile, ENCODER_SIZE};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use protocol::{Configuration, ConfigurationData};

use super::format::ReplayFormat;
use super::png::{read_polar_png, PolarScan};
use super::radiate;
use crate::error::ReplayError;

pub use super::files::MAX_INDEX_BYTES;
/// Rotation rate announced when a recording has a single scan (a CTS350-X's and a
/// CIR204-H's 4 Hz), millihertz.
pub const NOMINAL_ROTATION_MHZ: u16 = 4000;
/// Oxford's bin size (m), the CTS350-X's 4.38 cm.
pub const OXFORD_BIN_M: f64 = 0.0438;
/// Boreas' bin size (m) before its radar's upgrade (pyboreas: `resolution = 0.0596`).
pub const BOREAS_BIN_M: f64 = 0.0596;
/// Boreas' bin size (m) after the upgrade.
pub const BOREAS_UPGRADED_BIN_M: f64 = 0.04381;
/// pyboreas' `upgrade_time` (scans named after it have the finer bins), µs since the epoch.
pub const BOREAS_UPGRADE_US: i64 = 1_632_182_400_000_000;
/// RADIATE's bin size (m): `radar_calib.range_res` in radiate_sdk's `config/config.yaml`.
pub const RADIATE_BIN_M: f64 = 0.173611;
/// At most one damaged-scan WARN per this long.
pub const DAMAGED_WARN_EVERY: Duration = Duration::from_secs(1);

/// A recording's scans, in time order (at least one).
#[derive(Debug, Clone)]
pub struct ScanSet {
    /// The layout.
    pub format: ReplayFormat,
    /// The data set's folder.
    pub dir: PathBuf,
    /// Where the scan PNGs are.
    pub scan_dir: PathBuf,
    /// The scans.
    pub files: Vec<ScanFile>,
}

impl ScanSet {
    /// Lists `dir`'s scans in layout `format` (`None`: [`ReplayFormat::detect`]).
    ///
    /// Oxford: `dir/radar/*.png`, or `dir/*.png` when there is no `radar/`; Boreas:
    /// `dir/radar/*.png` likewise; both named by their time in µs. RADIATE: the rows of
    /// `dir/Navtech_Polar.txt`, each naming `dir/Navtech_Polar/<frame:06>.png`.
    ///
    /// # Errors
    /// An unknown or ambiguous layout, a folder without scans, a file name that is not a
    /// time, an index row that does not parse or names a missing file, times that do not
    /// increase: each names the file (and row).
    pub fn open(dir: &Path, format: Option<ReplayFormat>) -> Result<ScanSet, ReplayError> {
        let format = match format {
            Some(f) => f,
            None => ReplayFormat::detect(dir)?,
        };
        let (scan_dir, mut files) = match format {
            ReplayFormat::Oxford | ReplayFormat::Boreas => {
                let radar = dir.join("radar");
                let scan_dir = if radar.is_dir() {
                    radar
                } else {
                    dir.to_path_buf()
                };
                let files = list_named_scans(&scan_dir)?;
                (scan_dir, files)
            }
            ReplayFormat::Radiate => {
                let scan_dir = dir.join("Navtech_Polar");
                let files = radiate::read_scan_index(&dir.join("Navtech_Polar.txt"), &scan_dir)?;
                (scan_dir, files)
            }
        };
        if files.is_empty() {
            return Err(ReplayError::Empty(scan_dir));
        }
        set_periods(&mut files, format == ReplayFormat::Radiate);
        Ok(ScanSet {
            format,
            dir: dir.to_path_buf(),
            scan_dir,
            files,
        })
    }

    /// The scans' times (µs since the epoch).
    pub fn times_us(&self) -> Vec<i64> {
        self.files.iter().map(|f| f.time_us).collect()
    }

    /// The median interval between scans (µs), `None` with a single scan.
    pub fn median_interval_us(&self) -> Option<i64> {
        median_interval_us(&self.files)
    }
}

fn median_interval_us(files: &[ScanFile]) -> Option<i64> {
    let mut d: Vec<i64> = files
        .windows(2)
        .map(|w| w[1].time_us.saturating_sub(w[0].time_us))
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_unstable();
    d.get(d.len() / 2).copied()
}

/// Sets each scan's period from its neighbour: the previous scan when `from_previous`, the
/// next otherwise.
fn set_periods(files: &mut [ScanFile], from_previous: bool) {
    let median = median_interval_us(files)
        .unwrap_or(1_000_000_000 / i64::from(NOMINAL_ROTATION_MHZ))
        .max(1);
    let neighbour: Vec<Option<i64>> = (0..files.len())
        .map(|i| {
            let (Some(this), other) = (
                files.get(i),
                if from_previous {
                    i.checked_sub(1).and_then(|j| files.get(j))
                } else {
                    files.get(i + 1)
                },
            ) else {
                return None;
            };
            other.map(|o| o.time_us.saturating_sub(this.time_us).saturating_abs())
        })
        .collect();
    // In i128: an interval of centuries (a scan named 9000000000000000000) must not
    // overflow the comparison.
    let (wide_median, wide) = (i128::from(median), |d: i64| 2 * i128::from(d));
    for (file, interval) in files.iter_mut().zip(neighbour) {
        file.period_us = match interval {
            Some(d) if wide(d) >= wide_median && wide(d) <= 3 * wide_median => d,
            _ => median,
        };
    }
}

/// `scan_dir`'s `.png` files named by their time in µs, in time order.
fn list_named_scans(scan_dir: &Path) -> Result<Vec<ScanFile>, ReplayError> {
    let io = |source| ReplayError::Io {
        path: scan_dir.to_path_buf(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(scan_dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if !path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            continue;
        }
        let time_us = path
            .file_stem()
            .and_then(|s| s.to_str())
            .filter(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
            .and_then(|s| s.parse::<i64>().ok())
            .ok_or_else(|| ReplayError::BadName { path: path.clone() })?;
        files.push(ScanFile {
            path,
            time_us,
            period_us: 0,
        });
    }
    files.sort_by(|a, b| a.time_us.cmp(&b.time_us).then_with(|| a.path.cmp(&b.path)));
    if let Some(w) = files.windows(2).find(|w| w[1].time_us <= w[0].time_us) {
        return Err(ReplayError::OutOfOrder {
            path: w[1].path.clone(),
            row: None,
            earlier_path: Some(w[0].path.clone()),
            earlier_us: w[0].time_us,
            later_us: w[1].time_us,
        });
    }
    Ok(files)
}

/// What a recording announces, learned from its first scan and its scan times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanGeometry {
    /// Azimuths per rotation.
    pub azimuths: u16,
    /// Range bins per azimuth.
    pub bins: u16,
    /// Bin size (m).
    pub bin_size_m: f64,
    /// Encoder counts per revolution.
    pub encoder_size: u16,
    /// Rotation rate (mHz): from the median interval between scans.
    pub rotation_mhz: u16,
}

impl ScanGeometry {
    /// The far end of the last bin (m).
    pub fn max_range_m(&self) -> f64 {
        f64::from(self.bins) * self.bin_size_m
    }

    /// The configuration message a radar with this geometry sends (8-bit data).
    pub fn configuration(&self) -> Configuration {
        let rate = u32::from(self.azimuths) * u32::from(self.rotation_mhz) / 1000;
        let bin_tenth_mm = (self.bin_size_m * 10_000.0).round();
        Configuration {
            azimuth_samples: self.azimuths,
            bin_size: if bin_tenth_mm >= 1.0 && bin_tenth_mm <= f64::from(u16::MAX) {
                bin_tenth_mm as u16
            } else {
                u16::MAX
            },
            range_in_bins: self.bins,
            encoder_size: self.encoder_size,
            rotation_speed_millihertz: self.rotation_mhz,
            packet_rate: u16::try_from(rate).unwrap_or(u16::MAX),
            range_gain: 1.0,
            range_offset_m: 0.0,
            data: ConfigurationData::minimal(8, self.bin_size_m as f32),
        }
    }
}

/// Damaged scans met while replaying: counted, and warned about at most once per
/// [`DAMAGED_WARN_EVERY`].
#[derive(Debug, Default)]
pub struct DamagedScans {
    state: Mutex<DamagedState>,
}

#[derive(Debug, Default)]
struct DamagedState {
    count: u64,
    last_warn: Option<Instant>,
    unreported: u64,
}

impl DamagedScans {
    /// Records one skipped scan and WARNs (naming the file, through `error`) unless a WARN
    /// went out less than [`DAMAGED_WARN_EVERY`] ago.
    pub fn record(&self, error: &ReplayError) {
        let Ok(mut s) = self.state.lock() else {
            return;
        };
        s.count += 1;
        let now = Instant::now();
        if s.last_warn
            .is_some_and(|t| now.duration_since(t) < DAMAGED_WARN_EVERY)
        {
            s.unreported += 1;
            return;
        }
        let also = std::mem::take(&mut s.unreported);
        s.last_warn = Some(now);
        tracing::warn!(%error, skipped_total = s.count, not_reported_since_last_warning = also, "skipping a damaged scan; the replay goes on");
    }

    /// Scans skipped so far.
    pub fn count(&self) -> u64 {
        self.state.lock().map_or(0, |s| s.count)
    }
}

/// A recording opened for replay: its scans and their geometry.
#[derive(Debug)]
pub struct ScanRecording {
    /// The scans.
    pub scans: ScanSet,
    /// What it announces.
    pub geometry: ScanGeometry,
    /// Scans skipped as damaged (over all clients).
    pub damaged: DamagedScans,
}

impl ScanRecording {
    /// Lists the scans ([`ScanSet::open`]) and reads the first to learn the geometry.
    ///
    /// # Errors
    /// Those of [`ScanSet::open`]; a first scan that cannot be read or whose shape does not
    /// fit its layout.
    pub fn open(dir: &Path, format: Option<ReplayFormat>) -> Result<ScanRecording, ReplayError> {
        Self::from_scans(ScanSet::open(dir, format)?)
    }

    /// Reads the first of `scans` to learn the geometry.
    ///
    /// # Errors
    /// A first scan that cannot be read or whose shape does not fit its layout.
    pub fn from_scans(scans: ScanSet) -> Result<ScanRecording, ReplayError> {
        let first = scans
            .files
            .first()
            .ok_or_else(|| ReplayError::Empty(scans.scan_dir.clone()))?;
        let scan = read_scan(scans.format, first)?;
        let layout = |reason: &str| ReplayError::Layout {
            path: first.path.clone(),
            reason: reason.to_string(),
        };
        let azimuths = u16::try_from(scan.rows.len()).map_err(|_| layout("too many azimuths"))?;
        let bins = u16::try_from(scan.bins).map_err(|_| layout("too many bins"))?;
        let bin_size_m = match scans.format {
            ReplayFormat::Oxford => OXFORD_BIN_M,
            ReplayFormat::Boreas if first.time_us > BOREAS_UPGRADE_US => BOREAS_UPGRADED_BIN_M,
            ReplayFormat::Boreas => BOREAS_BIN_M,
            ReplayFormat::Radiate => RADIATE_BIN_M,
        };
        let rotation_mhz =
            scans
                .median_interval_us()
                .filter(|&d| d > 0)
                .map_or(NOMINAL_ROTATION_MHZ, |d| {
                    let mhz = (1e9 / d as f64).round();
                    if mhz >= 1.0 && mhz <= f64::from(u16::MAX) {
                        mhz as u16
                    } else {
                        NOMINAL_ROTATION_MHZ
                    }
                });
        Ok(ScanRecording {
            geometry: ScanGeometry {
                azimuths,
                bins,
                bin_size_m,
                encoder_size: ENCODER_SIZE,
                rotation_mhz,
            },
            scans,
            damaged: DamagedScans::default(),
        })
    }

    /// The configuration message every client receives.
    pub fn configuration(&self) -> Configuration {
        self.geometry.configuration()
    }

    /// Reads scan `index`: its rows must be the recording's azimuths and bins, and every
    /// row's time must be on the wire's clock.
    ///
    /// # Errors
    /// An index past the end, a file that cannot be read or decoded, a different shape.
    pub fn read(&self, index: usize) -> Result<PolarScan, ReplayError> {
        let file = self
            .scans
            .files
            .get(index)
            .ok_or_else(|| ReplayError::Layout {
                path: self.scans.scan_dir.clone(),
                reason: format!("no scan {index}"),
            })?;
        let scan = read_scan(self.scans.format, file)?;
        let g = &self.geometry;
        if scan.rows.len() != usize::from(g.azimuths) || scan.bins != usize::from(g.bins) {
            return Err(ReplayError::Layout {
                path: file.path.clone(),
                reason: format!(
                    "{} azimuths of {} bins, where the recording's scans have {} of {}",
                    scan.rows.len(),
                    scan.bins,
                    g.azimuths,
                    g.bins
                ),
            });
        }
        if let Some((k, reason)) = scan
            .rows
            .iter()
            .enumerate()
            .find_map(|(k, r)| r.wire_timestamp().err().map(|e| (k, e)))
        {
            return Err(ReplayError::Layout {
                path: file.path.clone(),
                reason: format!("azimuth {k}: {reason}"),
            });
        }
        encoders_within(&scan, g.encoder_size, &file.path)?;
        Ok(scan)
    }
}

/// Refuses a scan whose rows to be sent carry encoder values at or past `encoder_size`,
/// naming how many, which values, and the size.
fn encoders_within(scan: &PolarScan, encoder_size: u16, path: &Path) -> Result<(), ReplayError> {
    let mut past = scan
        .rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.valid && r.encoder >= encoder_size);
    let Some((first_row, first)) = past.next() else {
        return Ok(());
    };
    let (mut rows, mut min, mut max) = (1, first.encoder, first.encoder);
    for (_, r) in past {
        rows += 1;
        min = min.min(r.encoder);
        max = max.max(r.encoder);
    }
    Err(ReplayError::EncoderPastSize {
        path: path.to_path_buf(),
        rows,
        of: scan.rows.len(),
        first_row,
        min,
        max,
        encoder_size,
    })
}

/// Reads one scan in layout `format` as rows of one azimuth each. Boreas' column 10 is
/// unused, so its rows are all valid; RADIATE's rows get times spread over the scan's
/// period and encoder values from their column.
///
/// # Errors
/// A file that cannot be read, does not decode, or does not fit the layout.
pub fn read_scan(format: ReplayFormat, file: &ScanFile) -> Result<PolarScan, ReplayError> {
    match format {
        ReplayFormat::Oxford => read_polar_png(&file.path),
        ReplayFormat::Boreas => {
            let mut scan = read_polar_png(&file.path)?;
            for row in &mut scan.rows {
                row.valid = true;
            }
            Ok(scan)
        }
        ReplayFormat::Radiate => radiate::read_radiate_png(file),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(us: i64) -> ScanFile {
        ScanFile {
            path: PathBuf::from(format!("{us}.png")),
            time_us: us,
            period_us: 0,
        }
    }

    #[test]
    fn periods_follow_the_next_scan_unless_it_is_far_off_the_median() {
        let mut files: Vec<ScanFile> = [0, 250_000, 498_000, 1_500_000, 1_751_000]
            .into_iter()
            .map(file)
            .collect();
        set_periods(&mut files, false);
        let periods: Vec<i64> = files.iter().map(|f| f.period_us).collect();
        // Intervals 250000, 248000, 1002000, 251000: median 251000; the gap takes it.
        assert_eq!(periods, vec![250_000, 248_000, 251_000, 251_000, 251_000]);
        set_periods(&mut files, true);
        let periods: Vec<i64> = files.iter().map(|f| f.period_us).collect();
        assert_eq!(periods, vec![251_000, 250_000, 248_000, 251_000, 251_000]);
    }

    #[test]
    fn rows_past_the_encoder_size_are_refused_naming_their_values_and_the_size() {
        use super::super::png::PolarRow;
        let row = |encoder, valid| PolarRow {
            timestamp_us: 1,
            encoder,
            valid,
            bins: vec![0; 4],
        };
        let scan = PolarScan {
            rows: vec![
                row(0, true),
                row(5600, true),
                row(9000, false),
                row(6000, true),
            ],
            bins: 4,
        };
        let e = encoders_within(&scan, 5600, Path::new("a.png")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "a.png: 2 of 4 azimuths carry encoder values from 5600 to 6000 (the first is row 1), \
             at or past the encoder size 5600"
        );
        let fine = PolarScan {
            rows: vec![row(0, true), row(5599, true), row(9000, false)],
            bins: 4,
        };
        assert!(encoders_within(&fine, 5600, Path::new("a.png")).is_ok());
    }

    #[test]
    fn damaged_scans_are_all_counted_but_warned_about_at_most_once_a_second() {
        let damaged = DamagedScans::default();
        let error = ReplayError::Empty(PathBuf::from("x"));
        for _ in 0..5 {
            damaged.record(&error);
        }
        assert_eq!(damaged.count(), 5);
        let s = damaged.state.lock().unwrap();
        assert_eq!(s.unreported, 4, "one WARN, four held back");
    }

    #[test]
    fn the_geometry_announces_its_bin_size_and_rate() {
        let g = ScanGeometry {
            azimuths: 400,
            bins: 576,
            bin_size_m: RADIATE_BIN_M,
            encoder_size: ENCODER_SIZE,
            rotation_mhz: 4000,
        };
        let c = g.configuration();
        assert_eq!(
            (c.bin_size, c.range_in_bins, c.packet_rate),
            (1736, 576, 1600)
        );
        assert!((g.max_range_m() - 100.0).abs() < 0.01);
    }
}
