//! The format's rules beyond its encoding, checked on every map written and read: a map
//! that breaks one is refused with the first broken rule and where it is.

use crate::format::{MAX_PATH_POINTS, MAX_SCAN_POINTS};
use crate::model::{Map, Pose};

/// The longest `source` note (bytes).
pub const MAX_SOURCE_BYTES: usize = 64 * 1024;

/// The longest profile name or descriptor kind (bytes).
pub const MAX_NAME_BYTES: usize = 256;

fn finite(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

fn pose_finite(p: &Pose) -> bool {
    finite(&[p.x, p.y, p.theta])
}

/// The first rule `map` breaks, or `Ok`.
pub fn validate(map: &Map) -> Result<(), String> {
    if map.source.len() > MAX_SOURCE_BYTES {
        return Err(format!(
            "the source note holds {} bytes, more than {MAX_SOURCE_BYTES}",
            map.source.len()
        ));
    }
    let p = &map.profile;
    if p.name.is_empty() || p.name.len() > MAX_NAME_BYTES {
        return Err(format!(
            "the radar profile's name must hold 1 to {MAX_NAME_BYTES} bytes, it holds {}",
            p.name.len()
        ));
    }
    if p.azimuths == 0 || p.range_bins == 0 || p.encoder_size == 0 {
        return Err(format!(
            "the radar profile {:?} has {} azimuths, {} bins, an encoder of {}: each must be positive",
            p.name, p.azimuths, p.range_bins, p.encoder_size
        ));
    }
    if !(p.bin_size_m.is_finite() && p.bin_size_m > 0.0) {
        return Err(format!(
            "the radar profile {:?} has bin size {} m",
            p.name, p.bin_size_m
        ));
    }
    for (k, s) in map.submaps.iter().enumerate() {
        if !(pose_finite(&s.frame) && finite(&s.frame_cov)) {
            return Err(format!(
                "submap {k}: its frame or its covariance is not finite"
            ));
        }
        if !(pose_finite(&s.end_pose) && finite(&s.end_cov)) {
            return Err(format!(
                "submap {k}: its end pose or its covariance is not finite"
            ));
        }
        if !(s.end_s.is_finite() && s.loss_db.is_finite()) {
            return Err(format!("submap {k}: its end time or loss is not finite"));
        }
        for (i, f) in s.features.iter().enumerate() {
            if !(finite(&f.xy) && finite(&f.xy_cov) && finite(&f.uv) && finite(&f.uv_cov)) {
                return Err(format!(
                    "submap {k}, feature {i} (id {}): a value is not finite",
                    f.id
                ));
            }
        }
        if let Some(d) = &s.descriptor {
            if d.kind.is_empty() || d.kind.len() > MAX_NAME_BYTES {
                return Err(format!(
                    "submap {k}: the place descriptor's kind must hold 1 to {MAX_NAME_BYTES} bytes"
                ));
            }
            if !d.values.iter().all(|v| v.is_finite()) {
                return Err(format!(
                    "submap {k}: the place descriptor {:?} holds a value that is not finite",
                    d.kind
                ));
            }
        }
    }
    let n = map.submaps.len();
    for (e, l) in map.loops.iter().enumerate() {
        if l.from as usize >= n || l.to as usize >= n || l.from == l.to {
            return Err(format!(
                "loop closure {e} joins submaps {} and {} of {n}",
                l.from, l.to
            ));
        }
        if !(pose_finite(&l.transform) && finite(&l.covariance)) {
            return Err(format!(
                "loop closure {e}: its transform or covariance is not finite"
            ));
        }
    }
    let mut previous = 0u32;
    for (d, &start) in map.drive_starts.iter().enumerate() {
        if start as usize >= n || start <= previous {
            return Err(format!(
                "drive {} starts at submap {start}: the drives' first submaps must increase, each in 1..{n}",
                d + 1
            ));
        }
        previous = start;
    }
    for (e, j) in map.joins.iter().enumerate() {
        let (from, to) = (j.from as usize, j.to as usize);
        if from >= n || to >= n || map.drive_of(from) >= map.drive_of(to) {
            return Err(format!(
                "join {e} joins submaps {from} and {to} of {n}: it must lead from an earlier drive to a later one"
            ));
        }
        if !(pose_finite(&j.transform) && finite(&j.covariance)) {
            return Err(format!(
                "join {e}: its transform or covariance is not finite"
            ));
        }
    }
    point_lists(
        "scan",
        "points",
        n,
        MAX_SCAN_POINTS,
        map.scans.iter().map(|s| (s.submap, &s.points[..])),
    )?;
    point_lists(
        "path",
        "positions",
        n,
        MAX_PATH_POINTS,
        map.paths.iter().map(|p| (p.submap, &p.points[..])),
    )?;
    // Every later drive is tied to an earlier one, or its frames float free of the map's.
    for d in 1..=map.drive_starts.len() {
        let tied = map.joins.iter().chain(&map.loops).any(|l| {
            let (a, b) = (map.drive_of(l.from as usize), map.drive_of(l.to as usize));
            (a == d && b < d) || (b == d && a < d)
        });
        if !tied {
            return Err(format!(
                "drive {d} (from submap {}) has no join or loop closure to an earlier drive",
                map.drive_starts[d - 1]
            ));
        }
    }
    Ok(())
}

/// The rules of the per-submap point lists (scans, paths): each names a submap of the `n`
/// in increasing order, holds at most `max` points, all finite.
fn point_lists<'a>(
    kind: &str,
    things: &str,
    n: usize,
    max: usize,
    lists: impl Iterator<Item = (u32, &'a [[f32; 2]])>,
) -> Result<(), String> {
    let mut after = None;
    for (e, (k, points)) in lists.enumerate() {
        if k as usize >= n || after.is_some_and(|a| k <= a) {
            return Err(format!(
                "{kind} {e} belongs to submap {k}: the {kind}s' submaps must increase, each in 0..{n}"
            ));
        }
        after = Some(k);
        if points.len() > max {
            return Err(format!(
                "{kind} {e} (submap {k}) holds {} {things}, more than {max}",
                points.len()
            ));
        }
        if !points.iter().flatten().all(|v| v.is_finite()) {
            let one = things.trim_end_matches('s');
            return Err(format!(
                "{kind} {e} (submap {k}) holds a {one} that is not finite"
            ));
        }
    }
    Ok(())
}
