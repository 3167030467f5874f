//! Loads a map file and prints what it holds, its size per feature, and whether it suits a
//! radar profile: `cargo run -p slam-map --example map_info -- out/map.slmap [profile]`.
//! With `--against SAVED.slmap` (an extended map against the map it extended) it also
//! prints how far the saved submaps' frames moved, against their saved uncertainty, and
//! whether their features are unchanged.
//! With `--scan-csv OUT.csv` it writes every scan point in the map's frame (`submap,x_m,y_m`:
//! each submap's scan placed by its frame), for plots.
//! Exit 1 with the reason when the file does not load or the profile's geometry differs.

use std::path::PathBuf;
use std::process::ExitCode;

use slam_map::Map;

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let Some(path) = args.next().map(PathBuf::from) else {
        eprintln!("usage: map_info FILE [PROFILE] [--against SAVED] [--scan-csv OUT.csv]");
        return ExitCode::FAILURE;
    };
    let mut rest: Vec<String> = args.collect();
    let (Ok(against), Ok(scan_csv)) = (
        take_path(&mut rest, "--against", "a map file"),
        take_path(&mut rest, "--scan-csv", "an output file"),
    ) else {
        return ExitCode::FAILURE;
    };
    let mut args = rest.into_iter();
    let map = match Map::load(&path) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::FAILURE;
        }
    };
    if let Some(out) = scan_csv {
        match write_scan_csv(&map, &out) {
            Ok(n) => println!(
                "{n} scan points in the map's frame written to {}",
                out.display()
            ),
            Err(e) => {
                eprintln!("{}: {e}", out.display());
                return ExitCode::FAILURE;
            }
        }
    }
    let bytes = std::fs::metadata(&path).map_or(0, |m| m.len());
    // The file's own version (the u32 after the 8-byte magic; the load above checked it),
    // not this build's: a version 1 file reads as version 1.
    let version = file_version(&path).map_or_else(|| "unknown".to_owned(), |v| v.to_string());
    let features = map.feature_count();
    let p = &map.profile;
    println!(
        "{}: format version {}, written {} s after the epoch by {:?}",
        path.display(),
        version,
        map.created_unix_s,
        map.source
    );
    println!(
        "radar: {} ({} azimuths, encoder {}, {} bins of {} m)",
        p.name, p.azimuths, p.encoder_size, p.range_bins, p.bin_size_m
    );
    println!(
        "{} submaps in {} drives, {} features, {} loop closures, {} joins, {} descriptors; {} bytes ({:.1} per feature)",
        map.submaps.len(),
        map.drive_starts.len() + 1,
        features,
        map.loops.len(),
        map.joins.len(),
        map.submaps
            .iter()
            .filter(|s| s.descriptor.is_some())
            .count(),
        bytes,
        bytes as f64 / features.max(1) as f64
    );
    if !map.scans.is_empty() {
        println!(
            "scans: {} submaps, {} points ({} bytes)",
            map.scans.len(),
            map.scan_point_count(),
            8 * map.scan_point_count()
        );
    }
    if !map.paths.is_empty() {
        let positions: usize = map.paths.iter().map(|p| p.points.len()).sum();
        println!(
            "paths: {} submaps, {} positions ({} bytes)",
            map.paths.len(),
            positions,
            8 * positions
        );
    }
    // The saved graph solved again from the saved frames: they should barely move.
    if map.submaps.len() > 1 {
        match map
            .pose_graph()
            .solve(&slam_graph::SolveSettings::default())
        {
            Ok(sol) => {
                let moved = map
                    .submaps
                    .iter()
                    .zip(&sol.nodes)
                    .map(|(s, n)| (s.frame.x - n.x).hypot(s.frame.y - n.y))
                    .fold(0.0, f64::max);
                println!(
                    "graph: {} nodes, {} edges; solved again, the frames move {:.2e} m at most (chi2 {:.3})",
                    sol.nodes.len(),
                    map.pose_graph().edges().len(),
                    moved,
                    sol.chi2
                );
            }
            Err(e) => println!("graph: the saved graph does not solve: {e}"),
        }
    }
    if let Some(saved_path) = against {
        let saved = match Map::load(&saved_path) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("{e}");
                return ExitCode::FAILURE;
            }
        };
        compare(&saved, &map);
    }
    if let Some(name) = args.next() {
        let Some(profile) = radar_model::profile::by_name(&name) else {
            eprintln!(
                "no radar profile {name:?}; known: {}",
                radar_model::profile::names().join(", ")
            );
            return ExitCode::FAILURE;
        };
        match map.check_profile(profile) {
            Ok(()) => println!("made with this radar: {}", profile.name),
            Err(e) if !e.geometry_differs() => println!("warning: {e}"),
            Err(e) => {
                eprintln!("{e}");
                return ExitCode::FAILURE;
            }
        }
    }
    ExitCode::SUCCESS
}

/// How the saved map's submaps moved in `merged` (the map that extended it).
fn compare(saved: &Map, merged: &Map) {
    let n = saved.submaps.len().min(merged.submaps.len());
    let (mut worst, mut worst_ratio, mut sum, mut outside) = (0.0f64, 0.0f64, 0.0, 0);
    let mut same_features = true;
    for (a, b) in saved.submaps.iter().zip(&merged.submaps).skip(1) {
        let moved = (a.frame.x - b.frame.x).hypot(a.frame.y - b.frame.y);
        let sigma = (a.frame_cov[0] + a.frame_cov[3]).max(0.0).sqrt();
        let ratio = moved / sigma.max(1e-12);
        worst = worst.max(moved);
        worst_ratio = worst_ratio.max(ratio);
        sum += moved;
        if ratio > 3.0 {
            outside += 1;
        }
        same_features &= a.features == b.features;
    }
    println!(
        "against the saved map ({} submaps): frames moved mean {:.3} m, max {:.3} m; at most {:.2} of their saved sigma, {} beyond 3 sigma; features {}; {} new submaps, {} new loop closures, {} new joins",
        saved.submaps.len(),
        sum / (n.max(2) - 1) as f64,
        worst,
        worst_ratio,
        outside,
        if same_features { "unchanged" } else { "CHANGED" },
        merged.submaps.len().saturating_sub(saved.submaps.len()),
        merged.loops.len().saturating_sub(saved.loops.len()),
        merged.joins.len().saturating_sub(saved.joins.len())
    );
}

/// The format version written in `path`'s header (bytes 8 to 12, little-endian).
fn file_version(path: &std::path::Path) -> Option<u32> {
    use std::io::Read;
    let mut head = [0u8; 12];
    std::fs::File::open(path).ok()?.read_exact(&mut head).ok()?;
    Some(u32::from_le_bytes([head[8], head[9], head[10], head[11]]))
}

/// Every scan point of `map` in the map's frame, as `submap,x_m,y_m` lines: the count.
fn write_scan_csv(map: &Map, out: &std::path::Path) -> std::io::Result<usize> {
    use std::io::Write;
    let mut w = std::io::BufWriter::new(std::fs::File::create(out)?);
    writeln!(w, "submap,x_m,y_m")?;
    let mut n = 0;
    for (k, s) in map.submaps.iter().enumerate() {
        let f = s.frame_pose();
        let (sin, cos) = f.theta.sin_cos();
        for p in map.scan_points(k).unwrap_or_default() {
            let (x, y) = (f.x + cos * p[0] - sin * p[1], f.y + sin * p[0] + cos * p[1]);
            writeln!(w, "{k},{x:.3},{y:.3}")?;
            n += 1;
        }
    }
    w.flush()?;
    Ok(n)
}

/// Takes `flag PATH` out of `rest`: the path, `None` without the flag, `Err` (said on
/// stderr) when the flag has no value.
fn take_path(rest: &mut Vec<String>, flag: &str, what: &str) -> Result<Option<PathBuf>, ()> {
    match rest.iter().position(|a| a == flag) {
        Some(i) if i + 1 < rest.len() => {
            let p = PathBuf::from(rest.remove(i + 1));
            rest.remove(i);
            Ok(Some(p))
        }
        Some(_) => {
            eprintln!("{flag} needs {what}");
            Err(())
        }
        None => Ok(None),
    }
}
