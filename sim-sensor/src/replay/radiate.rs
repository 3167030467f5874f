//! RADIATE (Heriot-Watt; read against radiate_sdk's `radiate.py`, `config/config.yaml` and
//! README): the radar scans and the GPS/INS ground truth of one sequence folder.
//!
//! Scans: `Navtech_Polar/<frame:06>.png`, 8-bit, **576 range rows x 400 azimuth columns**
//! (transposed against Oxford's azimuth rows), bins of 0.173611 m (`radar_calib.range_res`),
//! no metadata: column `a` is the azimuth `a * 360 / 400` degrees clockwise from forward
//! (encoder `a * 5600 / 400`; the SDK's README says column 399 "represents 360 degrees",
//! which 400 columns of 0.9 degrees cannot mean literally). Scan times: `Navtech_Polar.txt`,
//! one `Frame: 000001 Time: 1574859771.744660272` line per scan, seconds since the epoch,
//! which the SDK's README calls each sensor's "time of arrival": the scan has been received,
//! so the time is its last azimuth's, and azimuth `a` of `M` is put `(M - 1 - a) / M` of a
//! rotation before it ([`super::scans::ScanFile::period_us`], the interval from the previous
//! scan).
//!
//! Ground truth: `GPS_IMU_Twist.txt` (the same `Frame: N Time: s` index, about 20 Hz, each
//! time written twice) and `GPS_IMU_Twist/<frame:06>.txt`, 18 lines of which this reads
//! line 1 (latitude, longitude, altitude; degrees) and line 17 (`Twist.Linear`: on the SDK's
//! sample sequence `fog_6_0` its x and y are the north and east velocity, matching the
//! velocity differentiated from the GPS fixes to 0.1-0.3 m/s). Position: the fix on a local
//! tangent plane at the first fix used. Heading: the course over ground from that velocity
//! (held while slower than [`MIN_COURSE_SPEED_MPS`]).
//!
//! What RADIATE does not give: post-processed poses (these are the raw GPS/INS solution; its
//! own covariance puts the fixes at 0.16-0.2 m, one sigma), a heading of the vehicle itself
//! (the IMU's orientation quaternion, line 5, disagrees with the course over ground by about
//! 55 degrees on `fog_6_0`, so it is not used; sideslip is invisible), the GPS antenna's
//! offset from the radar (the poses are the antenna's), per-azimuth times or encoder values,
//! and any relative radar odometry like Oxford's.

use std::path::{Path, PathBuf};

use radar_model::geometry::{wrap_angle, Pose2};

use super::files::{read_bounded, read_bounded_text, FileKind};
use super::format::{ScanFile, ENCODER_SIZE};
use super::png::{PolarRow, PolarScan, MAX_IMAGE_BYTES};
use super::truth::{
    check_span, plausible, read_text, relative_to_first, TruthError, MAX_SPEED_MPS,
};
use crate::error::ReplayError;

/// Below this speed (m/s) the course over ground is not a heading; the last one is held.
pub const MIN_COURSE_SPEED_MPS: f64 = 1.0;
/// Largest gap between the GPS fixes a scan's pose is interpolated between (µs).
pub const MAX_GPS_GAP_US: i64 = 1_000_000;

/// Parses `s.fraction` seconds since the epoch into µs (sub-µs digits are dropped).
pub fn parse_time_us(text: &str) -> Option<i64> {
    let (int, frac) = text.split_once('.').unwrap_or((text, ""));
    if int.is_empty() || !int.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    if !frac.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let secs: i64 = int.parse().ok()?;
    let mut micros = 0i64;
    for k in 0..6 {
        let d = frac.as_bytes().get(k).map_or(0, |b| i64::from(b - b'0'));
        micros = micros * 10 + d;
    }
    secs.checked_mul(1_000_000)?.checked_add(micros)
}

/// One `Frame: N Time: s` line: the frame number and its time (µs).
fn parse_index_line(line: &str) -> Result<(u32, i64), String> {
    let t: Vec<&str> = line.split_whitespace().collect();
    match t.as_slice() {
        ["Frame:", frame, "Time:", time] => {
            let frame = frame
                .parse::<u32>()
                .map_err(|_| format!("frame {frame:?} is not a number"))?;
            let time = parse_time_us(time)
                .ok_or_else(|| format!("time {time:?} is not seconds since the epoch"))?;
            Ok((frame, time))
        }
        _ => Err(format!(
            "expected `Frame: <number> Time: <seconds>`, got {line:?}"
        )),
    }
}

/// Reads `Navtech_Polar.txt`: the scans in `scan_dir`, in the index's order, whose times
/// must increase.
///
/// # Errors
/// An index that cannot be read, is not a regular file or is larger than
/// [`super::files::MAX_INDEX_BYTES`], a row that does not parse or names a scan that is not
/// there or not a regular file, a time that does not increase: each names the index and the
/// row.
pub fn read_scan_index(index: &Path, scan_dir: &Path) -> Result<Vec<ScanFile>, ReplayError> {
    let text = read_bounded_text(index, FileKind::ScanIndex)?;
    let mut files: Vec<ScanFile> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let row = i + 1;
        let bad = |reason: String| ReplayError::IndexRow {
            path: index.to_path_buf(),
            row,
            reason,
        };
        let (frame, time_us) = parse_index_line(line).map_err(bad)?;
        let path = scan_dir.join(format!("{frame:06}.png"));
        if !path.is_file() {
            let reason = if path.exists() {
                "is not a regular file"
            } else {
                "is not there"
            };
            return Err(bad(format!("its scan {} {reason}", path.display())));
        }
        if let Some(prev) = files.last() {
            if time_us <= prev.time_us {
                return Err(ReplayError::OutOfOrder {
                    path: index.to_path_buf(),
                    row: Some(row),
                    earlier_path: None,
                    earlier_us: prev.time_us,
                    later_us: time_us,
                });
            }
        }
        files.push(ScanFile {
            path,
            time_us,
            period_us: 0,
        });
    }
    Ok(files)
}

/// Decodes a RADIATE polar PNG: 8 bits a sample, range rows by azimuth columns (a colour
/// image is read by its first channel). Row `a` of the result is column `a`, with its time
/// `time_us - (azimuths - 1 - a) * period_us / azimuths` (the scan's time is its last
/// azimuth's) and encoder `a * 5600 / azimuths`.
///
/// # Errors
/// Bytes that do not decode, a bit depth other than 8, a palette image, more than 65535
/// range rows or azimuth columns, or none.
pub fn decode_radiate_png(
    bytes: &[u8],
    path: &Path,
    time_us: i64,
    period_us: i64,
) -> Result<PolarScan, ReplayError> {
    let layout = |reason: String| ReplayError::Layout {
        path: path.to_path_buf(),
        reason,
    };
    let png_err = |source| ReplayError::Png {
        path: path.to_path_buf(),
        source,
    };
    let mut decoder = png::Decoder::new(bytes);
    decoder.set_limits(png::Limits {
        bytes: MAX_IMAGE_BYTES,
    });
    let mut reader = decoder.read_info().map_err(png_err)?;
    let (color, depth) = reader.output_color_type();
    if depth != png::BitDepth::Eight || color == png::ColorType::Indexed {
        return Err(layout(format!(
            "expected 8-bit grey (range rows x azimuth columns), got {color:?} {depth:?}"
        )));
    }
    let samples = color.samples();
    let info = reader.info();
    let azimuths = usize::try_from(info.width).map_err(|_| layout("width does not fit".into()))?;
    let bins = usize::try_from(info.height).map_err(|_| layout("height does not fit".into()))?;
    let limit = usize::from(u16::MAX);
    if azimuths == 0 || azimuths > limit || bins == 0 || bins > limit {
        return Err(layout(format!(
            "{bins} range rows x {azimuths} azimuth columns: expected 1 to 65535 of each"
        )));
    }
    let size = reader.output_buffer_size();
    if size > MAX_IMAGE_BYTES {
        return Err(layout(format!(
            "{size} bytes decoded exceeds {MAX_IMAGE_BYTES}"
        )));
    }
    let mut buf = vec![0u8; size];
    let frame = reader.next_frame(&mut buf).map_err(png_err)?;
    let stride = frame.line_size;
    if stride < azimuths * samples {
        return Err(layout(format!("line size {stride} below the width")));
    }
    let lines: Vec<&[u8]> = buf.chunks_exact(stride).take(bins).collect();
    if lines.len() != bins {
        return Err(layout(format!("decoded {} rows of {bins}", lines.len())));
    }
    let m = azimuths as i64;
    let mut rows = Vec::with_capacity(azimuths);
    for a in 0..azimuths {
        let mut row_bins = Vec::with_capacity(bins);
        for line in &lines {
            row_bins.push(line.get(a * samples).copied().unwrap_or(0));
        }
        let a_i = a as i64;
        let before = i64::try_from(i128::from(m - 1 - a_i) * i128::from(period_us) / i128::from(m))
            .map_err(|_| layout("scan period out of range".into()))?;
        let encoder = (a_i * i64::from(ENCODER_SIZE) + m / 2) / m;
        rows.push(PolarRow {
            timestamp_us: time_us.saturating_sub(before),
            encoder: u16::try_from(encoder).unwrap_or(0),
            valid: true,
            bins: row_bins,
        });
    }
    Ok(PolarScan { rows, bins })
}

/// Reads and decodes one RADIATE scan ([`decode_radiate_png`]): a regular file of at most
/// [`super::files::MAX_SCAN_BYTES`].
///
/// # Errors
/// As [`decode_radiate_png`], or the file cannot be read, is not a regular file or is too
/// large.
pub fn read_radiate_png(file: &ScanFile) -> Result<PolarScan, ReplayError> {
    let bytes = read_bounded(&file.path, FileKind::Scan)?;
    decode_radiate_png(&bytes, &file.path, file.time_us, file.period_us)
}

/// One GPS/INS record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpsFix {
    /// µs since the epoch.
    pub time_us: i64,
    /// Latitude (degrees).
    pub lat_deg: f64,
    /// Longitude (degrees).
    pub lon_deg: f64,
    /// North velocity (m/s).
    pub v_north_mps: f64,
    /// East velocity (m/s).
    pub v_east_mps: f64,
}

/// Reads `GPS_IMU_Twist.txt`: `(row, frame, time_us)`, times never decreasing (RADIATE
/// writes each time twice).
///
/// # Errors
/// A file that cannot be read, a row that does not parse, a time that goes back.
pub fn read_gps_index(path: &Path) -> Result<Vec<(usize, u32, i64)>, TruthError> {
    let text = read_text(path, FileKind::GroundTruth)?;
    let mut out: Vec<(usize, u32, i64)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let row = i + 1;
        let (frame, time_us) = parse_index_line(line).map_err(|reason| TruthError::Row {
            path: path.to_path_buf(),
            row,
            reason,
        })?;
        if let Some(&(_, _, prev)) = out.last() {
            if time_us < prev {
                return Err(TruthError::OutOfOrder {
                    path: path.to_path_buf(),
                    row,
                    earlier_us: prev,
                    later_us: time_us,
                });
            }
        }
        out.push((row, frame, time_us));
    }
    Ok(out)
}

/// Reads one `GPS_IMU_Twist/<frame>.txt`: line 1's latitude and longitude, line 17's
/// north and east velocity.
///
/// # Errors
/// A file that cannot be read, fewer than 17 lines, a field that is not a finite number;
/// each names the file and line.
pub fn read_gps_fix(path: &Path, time_us: i64) -> Result<GpsFix, TruthError> {
    let text = read_text(path, FileKind::GpsRecord)?;
    let lines: Vec<&str> = text.lines().collect();
    let fields = |line: usize, want: usize| -> Result<Vec<f64>, TruthError> {
        let bad = |reason: String| TruthError::Row {
            path: path.to_path_buf(),
            row: line,
            reason,
        };
        let text = lines.get(line - 1).ok_or_else(|| {
            bad(format!(
                "missing: the file has {} lines, expected 18",
                lines.len()
            ))
        })?;
        let v: Vec<f64> = text
            .split(',')
            .map(|s| s.trim().parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| bad(format!("{text:?} is not comma-separated finite numbers")))?;
        if v.len() < want {
            return Err(bad(format!("{} fields, expected {want}", v.len())));
        }
        Ok(v)
    };
    let position = fields(1, 3)?;
    let twist = fields(17, 3)?;
    let (lat, lon) = (position[0], position[1]);
    if !(-90.0..=90.0).contains(&lat) || !(-180.0..=180.0).contains(&lon) {
        return Err(TruthError::Row {
            path: path.to_path_buf(),
            row: 1,
            reason: format!("latitude {lat} / longitude {lon} out of range"),
        });
    }
    let speed = |k: usize, what: &str| {
        plausible(twist[k], MAX_SPEED_MPS, k, what).map_err(|reason| TruthError::Row {
            path: path.to_path_buf(),
            row: 17,
            reason,
        })
    };
    Ok(GpsFix {
        time_us,
        lat_deg: lat,
        lon_deg: lon,
        v_north_mps: speed(0, "north velocity, m/s")?,
        v_east_mps: speed(1, "east velocity, m/s")?,
    })
}

/// East and north (m) of `fix` from `origin` on the WGS-84 ellipsoid's tangent plane at
/// the origin (meridian and prime-vertical radii of curvature).
pub fn local_east_north(origin: &GpsFix, fix: &GpsFix) -> (f64, f64) {
    const A: f64 = 6_378_137.0;
    const F: f64 = 1.0 / 298.257_223_563;
    let e2 = F * (2.0 - F);
    let phi = origin.lat_deg.to_radians();
    let w = (1.0 - e2 * phi.sin().powi(2)).sqrt();
    let meridian = A * (1.0 - e2) / (w * w * w);
    let normal = A / w;
    let north = (fix.lat_deg - origin.lat_deg).to_radians() * meridian;
    let east = (fix.lon_deg - origin.lon_deg).to_radians() * normal * phi.cos();
    (east, north)
}

/// The poses of the scans at `scan_times_us` (increasing) in the first scan's frame, from
/// `dir/GPS_IMU_Twist.txt` and the fixes it names within a second of the scans.
///
/// # Errors
/// The scans span more than [`super::truth::MAX_SPAN_US`], the index or a fix file cannot
/// be read or parsed, times go back, or a scan has no fix within [`MAX_GPS_GAP_US`] on both
/// sides.
pub fn radiate_poses(dir: &Path, scan_times_us: &[i64]) -> Result<Vec<Pose2>, TruthError> {
    let index = dir.join("GPS_IMU_Twist.txt");
    let fix_dir = dir.join("GPS_IMU_Twist");
    check_span(&index, scan_times_us)?;
    let rows = read_gps_index(&index)?;
    let (Some(&first), Some(&last)) = (scan_times_us.first(), scan_times_us.last()) else {
        return Ok(Vec::new());
    };
    let mut fixes: Vec<GpsFix> = Vec::new();
    for &(_, frame, time_us) in &rows {
        if time_us < first.saturating_sub(MAX_GPS_GAP_US)
            || time_us > last.saturating_add(MAX_GPS_GAP_US)
        {
            continue;
        }
        let path: PathBuf = fix_dir.join(format!("{frame:06}.txt"));
        let fix = read_gps_fix(&path, time_us)?;
        // Each time appears twice: the later record stands.
        match fixes.last_mut() {
            Some(prev) if prev.time_us == time_us => *prev = fix,
            _ => fixes.push(fix),
        }
    }
    let Some(origin) = fixes.first().copied() else {
        return Err(TruthError::NoPose {
            path: index,
            scan_us: first,
            reason: "no GPS fix within a second of the scans".into(),
        });
    };
    let headings = course_headings(&fixes);
    let world: Vec<Pose2> = fixes
        .iter()
        .zip(&headings)
        .map(|(f, &h)| {
            let (e, n) = local_east_north(&origin, f);
            Pose2::new(e, n, h)
        })
        .collect();
    let mut poses = Vec::with_capacity(scan_times_us.len());
    for &t in scan_times_us {
        let k = fixes.partition_point(|f| f.time_us <= t);
        let no_fix = |reason: &str| TruthError::NoPose {
            path: index.clone(),
            scan_us: t,
            reason: reason.to_string(),
        };
        let (Some(a), Some(pa)) = (
            k.checked_sub(1).and_then(|j| fixes.get(j)),
            k.checked_sub(1).and_then(|j| world.get(j)),
        ) else {
            return Err(no_fix("no GPS fix at or before it"));
        };
        if a.time_us == t {
            poses.push(*pa);
            continue;
        }
        let (Some(b), Some(pb)) = (fixes.get(k), world.get(k)) else {
            return Err(no_fix("no GPS fix after it"));
        };
        if b.time_us - a.time_us > MAX_GPS_GAP_US {
            return Err(no_fix(
                "the GPS fixes around it are more than a second apart",
            ));
        }
        let f = (t - a.time_us) as f64 / (b.time_us - a.time_us) as f64;
        poses.push(Pose2::new(
            pa.x + f * (pb.x - pa.x),
            pa.y + f * (pb.y - pa.y),
            wrap_angle(pa.theta + f * wrap_angle(pb.theta - pa.theta)),
        ));
    }
    Ok(relative_to_first(&poses))
}

/// The course over ground (counter-clockwise from east) at each fix, held while slower than
/// [`MIN_COURSE_SPEED_MPS`]; fixes before the first fast one take its course (0 when the
/// vehicle never moves).
fn course_headings(fixes: &[GpsFix]) -> Vec<f64> {
    let course = |f: &GpsFix| {
        (f.v_north_mps.hypot(f.v_east_mps) >= MIN_COURSE_SPEED_MPS)
            .then(|| f.v_north_mps.atan2(f.v_east_mps))
    };
    let mut held = fixes.iter().find_map(course).unwrap_or(0.0);
    fixes
        .iter()
        .map(|f| {
            if let Some(c) = course(f) {
                held = c;
            }
            held
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_times_parse_to_microseconds() {
        assert_eq!(
            parse_time_us("1574859771.744660272"),
            Some(1_574_859_771_744_660)
        );
        assert_eq!(parse_time_us("12.5"), Some(12_500_000));
        assert_eq!(parse_time_us("12"), Some(12_000_000));
        assert_eq!(parse_time_us("-1.0"), None);
        assert_eq!(parse_time_us("1e9"), None);
        assert_eq!(
            parse_index_line("Frame: 000002 Time: 1574859771.977525228"),
            Ok((2, 1_574_859_771_977_525))
        );
        assert!(parse_index_line("Frame: x Time: 1").is_err());
    }

    #[test]
    fn a_transposed_scan_gets_angles_and_times_from_its_columns() {
        // 3 range rows x 4 azimuth columns; pixel = 10 * row + column.
        let (w, h) = (4u32, 3u32);
        let data: Vec<u8> = (0..h)
            .flat_map(|r| (0..w).map(move |c| (10 * r + c) as u8))
            .collect();
        let mut bytes = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut bytes, w, h);
            enc.set_color(png::ColorType::Grayscale);
            enc.set_depth(png::BitDepth::Eight);
            let mut wr = enc.write_header().unwrap();
            wr.write_image_data(&data).unwrap();
        }
        let scan = decode_radiate_png(&bytes, Path::new("000001.png"), 1_187_500, 250_000).unwrap();
        assert_eq!((scan.rows.len(), scan.bins), (4, 3));
        assert_eq!(scan.rows[1].bins, vec![1, 11, 21]);
        let times: Vec<i64> = scan.rows.iter().map(|r| r.timestamp_us).collect();
        assert_eq!(times, vec![1_000_000, 1_062_500, 1_125_000, 1_187_500]);
        let enc: Vec<u16> = scan.rows.iter().map(|r| r.encoder).collect();
        assert_eq!(enc, vec![0, 1400, 2800, 4200]);
    }

    #[test]
    fn the_course_is_held_while_standing_still() {
        let fix = |vn: f64, ve: f64| GpsFix {
            time_us: 0,
            lat_deg: 0.0,
            lon_deg: 0.0,
            v_north_mps: vn,
            v_east_mps: ve,
        };
        let h = course_headings(&[fix(0.0, 0.1), fix(5.0, 0.0), fix(0.2, 0.0), fix(0.0, -5.0)]);
        let pi = std::f64::consts::PI;
        assert!((h[0] - pi / 2.0).abs() < 1e-12 && (h[2] - pi / 2.0).abs() < 1e-12);
        assert!((h[3].abs() - pi).abs() < 1e-12);
    }

    #[test]
    fn a_degree_of_latitude_is_about_111_km_and_longitude_shrinks_with_it() {
        let o = GpsFix {
            time_us: 0,
            lat_deg: 55.892,
            lon_deg: -3.322,
            v_north_mps: 0.0,
            v_east_mps: 0.0,
        };
        let p = GpsFix {
            lat_deg: 55.893,
            lon_deg: -3.321,
            ..o
        };
        let (e, n) = local_east_north(&o, &p);
        assert!((n - 111.3).abs() < 0.3, "{n}");
        assert!((e - 62.6).abs() < 0.3, "{e}");
    }
}
