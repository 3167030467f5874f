//! Registers two recorded radar scans (Oxford Radar RobotCar polar PNGs) with radar-odometry
//! alone: k-strongest returns per azimuth, the second scan's cloud registered against the
//! first's from starts along the vehicle's axis (no motion estimate), and the result set
//! beside the data set's own radar odometry for the same pair when `radar_odometry.csv` is
//! there.
//!
//! ```text
//! cargo run --release -p radar-odometry --example register_two_scans -- \
//!     ../shared/data/oxford-radar-robotcar/radar/1547131046353776.png \
//!     ../shared/data/oxford-radar-robotcar/radar/1547131046606586.png
//! ```
//! With no arguments it takes the first two scans of `../shared/data/oxford-radar-robotcar`.
//! Neither rotation is de-skewed (the motion within them is unknown to a two-scan example;
//! with `ScanMatchSettings::deskew` the second would be registered swept along the motion
//! tried, from its rows' timestamps): at 10 m/s that costs a few centimetres.

use std::path::{Path, PathBuf};

use radar_model::geometry::Pose2;
use radar_odometry::{KStrongest, RotationEnd, ScanMatchSettings, ScanMatcher};
use sim_sensor::replay::png::read_polar_png;

/// The CTS350-X of the Oxford data set: bin size (m) and encoder counts per rotation.
const BIN_SIZE_M: f64 = 0.0438;
const ENCODER_SIZE: f64 = 5600.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let (a, b) = match args.as_slice() {
        [a, b] => (a.clone(), b.clone()),
        [] => first_two(Path::new("../shared/data/oxford-radar-robotcar/radar"))?,
        _ => return Err("usage: register_two_scans [SCAN_A.png SCAN_B.png]".into()),
    };
    let settings = ScanMatchSettings {
        enabled: true,
        points_per_azimuth: 12,
        ..ScanMatchSettings::default()
    };
    let extract = KStrongest {
        k: settings.points_per_azimuth,
        ..KStrongest::default()
    };
    let mut matcher = ScanMatcher::new(settings);
    let origin = Pose2::new(0.0, 0.0, 0.0);
    let mut result = None;
    // Times relative to the first scan's first row; a rotation ends at its last row.
    let (mut epoch_us, mut since_s) = (None, 0.0);
    for path in [&a, &b] {
        let scan = read_polar_png(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut points = 0;
        let mut until_s = since_s;
        for row in scan.rows.iter().filter(|r| r.valid) {
            let bearing = std::f64::consts::TAU * f64::from(row.encoder) / ENCODER_SIZE;
            let returns = extract.returns(&row.bins, BIN_SIZE_M);
            points += returns.len().min(settings.points_per_azimuth);
            let epoch = *epoch_us.get_or_insert(row.timestamp_us);
            until_s = (row.timestamp_us - epoch) as f64 * 1e-6;
            matcher.add_azimuth(Some(origin), until_s, bearing, &returns);
        }
        println!(
            "{}: {} azimuths, {points} returns",
            path.display(),
            scan.rows.len()
        );
        let t = std::time::Instant::now();
        let end = RotationEnd {
            pose: origin,
            since_s,
            until_s,
        };
        since_s = until_s;
        result = matcher.end_rotation(Some(end), true);
        if matcher.counts().tried > 0 {
            println!("registered in {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let Some(m) = result else {
        return Err("the registration failed (too few pairs)".into());
    };
    let sd = |i: usize| m.covariance[(i, i)].sqrt();
    println!(
        "motion of the second scan in the first's frame: x {:.3} m, y {:.3} m, heading {:.3} deg",
        m.motion.x,
        m.motion.y,
        m.motion.theta.to_degrees()
    );
    println!(
        "  sigma x {:.3} m, y {:.3} m, heading {:.3} deg; {} pairs ({} on lines), rms {:.3} m, {} iterations",
        sd(0),
        sd(1),
        sd(2).to_degrees(),
        m.registration.pairs,
        m.registration.line_pairs,
        m.registration.rms_m,
        m.registration.iterations
    );
    println!(
        "  weakest constraint {:.3} per pair along [{:.2}, {:.2}, {:.2}]{}",
        m.constraint.weakest,
        m.constraint.direction[0],
        m.constraint.direction[1],
        m.constraint.direction[2],
        if m.weak { ": weak" } else { "" }
    );
    match dataset_motion(&a, &b) {
        Some((x, y, yaw)) => println!(
            "the data set's radar odometry for the pair: x {x:.3} m, y {y:.3} m, heading {:.3} deg",
            yaw.to_degrees()
        ),
        None => println!("(no radar_odometry.csv row for the pair beside the scans)"),
    }
    Ok(())
}

fn first_two(dir: &Path) -> Result<(PathBuf, PathBuf), Box<dyn std::error::Error>> {
    let mut scans: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| {
            format!(
                "{}: {e} (the Oxford scans are not there; name two scans)",
                dir.display()
            )
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    scans.sort();
    match scans.as_slice() {
        [a, b, ..] => Ok((a.clone(), b.clone())),
        _ => Err(format!("fewer than two scans in {}", dir.display()).into()),
    }
}

/// The data set's motion from scan `a` to scan `b` (`radar_odometry.csv`'s row whose
/// destination is `a` and source is `b`), in the frame of `a`.
fn dataset_motion(a: &Path, b: &Path) -> Option<(f64, f64, f64)> {
    let stamp = |p: &Path| p.file_stem()?.to_str()?.parse::<i64>().ok();
    let (ta, tb) = (stamp(a)?, stamp(b)?);
    let csv = a.parent()?.parent()?.join("radar_odometry.csv");
    let text = std::fs::read_to_string(csv).ok()?;
    text.lines().skip(1).find_map(|line| {
        let f: Vec<&str> = line.split(',').collect();
        let src: i64 = f.get(8)?.parse().ok()?;
        let dst: i64 = f.get(9)?.parse().ok()?;
        if src != tb || dst != ta {
            return None;
        }
        let num = |i: usize| f.get(i)?.parse::<f64>().ok();
        Some((num(2)?, num(3)?, num(7)?))
    })
}
