//! Extend mode (`--map FILE`, `[map] mode = "extend"`): the outdoor field's first 20 m are
//! mapped in submaps of 8 m (speckle seed 1); a second run (seed 2) over the whole 40 m
//! drive localises in that map from no prior, then maps on in its frame. The merged map
//! holds the saved submaps (features unchanged, frames moved within their uncertainty), new
//! submaps, the join and loop closures from new submaps to saved ones, and loads back; a
//! third run extends the merged map again. Extend mode without submaps is refused.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use slam_map::Map;

const SUBMAPS: &str = "[submaps]\nenabled = true\nmax_distance_m = 8.0\n";

fn slam_node(config: &str, out: &Path, duration_s: &str, extra: &[&str]) -> Output {
    std::fs::create_dir_all(out).unwrap();
    let file = out.join("run.toml");
    std::fs::write(&file, config).unwrap();
    Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .args(["--config", file.to_str().unwrap()])
        .args(["--embedded-sim", "--fast", "--duration", duration_s])
        .args(["--no-figures", "--progress-every", "0", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn published(out: &Path) -> usize {
    std::fs::read_to_string(out.join("trajectory-online.tum"))
        .map(|t| {
            t.lines()
                .filter(|l| !l.starts_with('#') && !l.is_empty())
                .count()
        })
        .unwrap_or(0)
}

/// Extends `map` with speckle seed `seed` over `duration_s` of the drive: the merged map.
fn extend(map: &Path, out: &Path, seed: u32, duration_s: &str) -> (PathBuf, String) {
    let config = format!("[sim]\nseed = {seed}\n\n{SUBMAPS}\n[map]\nmode = \"extend\"\n");
    let run = slam_node(&config, out, duration_s, &["--map", map.to_str().unwrap()]);
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    (out.join("map.slmap"), t)
}

/// Checks that `merged` holds `saved` as its first submaps: the same features, frames
/// moved within three standard deviations of their saved uncertainty (submap 0 is the
/// map's frame and does not move).
fn holds_the_saved_map(saved: &Map, merged: &Map) {
    let n = saved.submaps.len();
    for (k, (a, b)) in saved.submaps.iter().zip(&merged.submaps).enumerate() {
        assert_eq!(a.features, b.features, "saved submap {k}'s features");
        assert_eq!(a.end_pose, b.end_pose, "saved submap {k}'s chain edge");
        let moved = (a.frame.x - b.frame.x).hypot(a.frame.y - b.frame.y);
        let sigma = (a.frame_cov[0] + a.frame_cov[3]).sqrt();
        let turned = (a.frame.theta - b.frame.theta).abs();
        if k == 0 {
            assert_eq!(a.frame, b.frame);
        } else {
            assert!(
                moved <= 3.0 * sigma + 1e-9 && turned <= 3.0 * a.frame_cov[5].sqrt() + 1e-12,
                "saved submap {k} moved {moved:.4} m ({sigma:.4} m sigma), turned {turned:.5} rad"
            );
        }
    }
    for scan in &saved.scans {
        assert_eq!(
            merged.scan_of(scan.submap as usize),
            Some(&scan.points[..]),
            "saved submap {}'s scan",
            scan.submap
        );
    }
    assert!(merged.submaps.len() > n, "no new submap");
    assert_eq!(merged.loops[..saved.loops.len()], saved.loops[..]);
    assert_eq!(merged.joins[..saved.joins.len()], saved.joins[..]);
}

#[test]
fn a_second_run_extends_the_first_ones_map_and_a_third_the_merged_one() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first");
    let run = slam_node(&format!("[sim]\nseed = 1\n\n{SUBMAPS}"), &first, "20", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let saved_file = first.join("map.slmap");
    let saved = Map::load(&saved_file).unwrap();
    let n = saved.submaps.len();
    assert!(n >= 3, "{n} submaps");
    assert!(saved.drive_starts.is_empty());

    let out = dir.path().join("second");
    let (merged_file, t) = extend(&saved_file, &out, 2, "40");
    assert!(t.contains("localised in the map"), "{t}");
    assert!(t.contains("extend: mapping from"), "{t}");
    let merged = Map::load(&merged_file).unwrap();
    holds_the_saved_map(&saved, &merged);
    // The new drive starts after the saved submaps, joined to one of them.
    assert_eq!(merged.drive_starts, vec![n as u32]);
    assert_eq!(merged.joins.len(), 1);
    let join = merged.joins[0];
    assert!(
        (join.from as usize) < n && join.to as usize == n,
        "{join:?}"
    );
    // The join sits where the truth puts the new drive's start: the first new frame is
    // within half a metre of the true path (the field's drive runs along y = 0 at first).
    let start = merged.submaps[n].frame;
    assert!(start.y.abs() < 0.5 && start.x > 5.0, "{start:?}");
    let cross = merged
        .loops
        .iter()
        .filter(|l| (l.from as usize) < n && (l.to as usize) >= n)
        .count();
    assert!(
        cross >= 1,
        "no loop closure from a new submap to a saved one\n{t}"
    );
    // The new submaps reach past the saved drive's end (the first run drove 20 m).
    let furthest = merged.submaps[n..]
        .iter()
        .map(|s| s.frame.x.hypot(s.frame.y))
        .fold(0.0, f64::max);
    assert!(furthest > 25.0, "new submaps reach {furthest:.1} m");
    // No pose before the fix: fewer published poses than rotations.
    let rotations: usize = t
        .lines()
        .find_map(|l| l.trim().strip_prefix("rotations "))
        .and_then(|l| l.split(',').next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap();
    assert!(published(&out) > 0 && published(&out) < rotations, "{t}");
    // Feature ids stay unique in the merged map (the new drive numbers past the saved).
    let mut ids: Vec<u64> = merged
        .submaps
        .iter()
        .flat_map(|s| s.features.iter().map(|f| f.id))
        .collect();
    let all = ids.len();
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len(), all, "repeated feature ids in the merged map");
    // The merged map's graph solves to its frames.
    let sol = merged
        .pose_graph()
        .solve(&slam_graph::SolveSettings::default())
        .unwrap();
    for (s, node) in merged.submaps.iter().zip(&sol.nodes) {
        assert!((s.frame.x - node.x).hypot(s.frame.y - node.y) < 1e-3);
    }

    // A third drive extends the merged map: three drives, two joins.
    let (third_file, t) = extend(&merged_file, &dir.path().join("third"), 3, "30");
    assert!(t.contains("extend: mapping from"), "{t}");
    let third = Map::load(&third_file).unwrap();
    holds_the_saved_map(&merged, &third);
    assert_eq!(third.drive_starts.len(), 2, "{:?}", third.drive_starts);
    assert_eq!(third.joins.len(), 2);
}

#[test]
fn extend_mode_without_submaps_or_without_a_map_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first");
    let run = slam_node(&format!("[sim]\nseed = 1\n\n{SUBMAPS}"), &first, "6", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let map = first.join("map.slmap");
    let run = slam_node(
        "[map]\nmode = \"extend\"\n",
        &dir.path().join("bad"),
        "6",
        &["--map", map.to_str().unwrap()],
    );
    let t = text(&run);
    assert!(!run.status.success(), "{t}");
    assert!(
        t.contains("map.slmap") && t.contains("[submaps] enabled = true"),
        "{t}"
    );
    let run = slam_node(
        &format!("{SUBMAPS}\n[map]\nmode = \"extend\"\n"),
        &dir.path().join("bad"),
        "6",
        &[],
    );
    assert!(!run.status.success() && text(&run).contains("--map FILE"));
    // A truncated file refuses the run, naming it.
    let bytes = std::fs::read(&map).unwrap();
    let cut = dir.path().join("cut.slmap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let run = slam_node(
        &format!("{SUBMAPS}\n[map]\nmode = \"extend\"\n"),
        &dir.path().join("bad"),
        "6",
        &["--map", cut.to_str().unwrap()],
    );
    let t = text(&run);
    assert!(
        !run.status.success() && t.contains("cut.slmap") && t.contains("truncated"),
        "{t}"
    );
}

#[test]
fn an_extend_run_that_never_localises_saves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first");
    let run = slam_node(&format!("[sim]\nseed = 1\n\n{SUBMAPS}"), &first, "20", &[]);
    assert!(run.status.success(), "{}", text(&run));
    // The map mirrored (y -> -y): no rigid motion puts the drive on it.
    let mut mirrored = Map::load(&first.join("map.slmap")).unwrap();
    for s in &mut mirrored.submaps {
        s.frame.y = -s.frame.y;
        s.frame.theta = -s.frame.theta;
        s.end_pose.y = -s.end_pose.y;
        s.end_pose.theta = -s.end_pose.theta;
        for f in &mut s.features {
            f.xy[1] = -f.xy[1];
            f.xy_cov[1] = -f.xy_cov[1];
        }
    }
    let file = dir.path().join("mirrored.slmap");
    mirrored.save(&file).unwrap();
    let out = dir.path().join("never");
    let (merged, t) = extend(&file, &out, 2, "14");
    assert!(t.contains("NO FIX") && t.contains("NOT EXTENDED"), "{t}");
    assert!(!merged.exists(), "a map was saved without a fix\n{t}");
    assert_eq!(published(&out), 0, "{t}");
}

#[test]
fn with_a_prior_pose_mapping_starts_after_a_few_tracked_rotations() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first");
    let run = slam_node(&format!("[sim]\nseed = 1\n\n{SUBMAPS}"), &first, "20", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let saved_file = first.join("map.slmap");
    let config = format!(
        "[sim]\nseed = 2\n\n{SUBMAPS}\n[map]\nmode = \"extend\"\ninitial_pose = [0.3, -0.2, 0.01]\n"
    );
    let out = dir.path().join("prior");
    let run = slam_node(
        &config,
        &out,
        "30",
        &["--map", saved_file.to_str().unwrap()],
    );
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    assert!(t.contains("started from the prior pose"), "{t}");
    // 8 rotations at 2.5 Hz after the start.
    let after: f64 = t
        .lines()
        .find_map(|l| l.trim().strip_prefix("extend: mapping from "))
        .and_then(|l| l.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no extend line\n{t}"));
    assert!(after < 5.0, "mapping started after {after} s\n{t}");
    let saved = Map::load(&saved_file).unwrap();
    let merged = Map::load(&out.join("map.slmap")).unwrap();
    holds_the_saved_map(&saved, &merged);
    // The new drive starts near the true start (the origin), 3 m in at most.
    let start = merged.submaps[saved.submaps.len()].frame;
    assert!(start.x.hypot(start.y) < 4.0, "{start:?}");
}

#[test]
fn the_saved_scans_are_carried_into_the_merged_map_and_the_new_submaps_add_theirs() {
    // Radar odometry on: each submap keeps its scan (loop closure by scans).
    let with_scans = format!("{SUBMAPS}\n[odometry]\nradar_odometry = true\n");
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first");
    let run = slam_node(
        &format!("[sim]\nseed = 1\n\n{with_scans}"),
        &first,
        "20",
        &[],
    );
    assert!(run.status.success(), "{}", text(&run));
    let saved = Map::load(&first.join("map.slmap")).unwrap();
    let n = saved.submaps.len();
    assert!(
        !saved.scans.is_empty() && saved.scans.iter().all(|s| (s.submap as usize) < n),
        "{} scans for {n} submaps",
        saved.scans.len()
    );
    assert!(text(&run).contains("the scans of"), "{}", text(&run));
    // The outdoor field's scans are a few hundred points of posts: it localises by the
    // map's features (by scans: the street test below).
    let config = format!(
        "[sim]\nseed = 2\n\n{with_scans}\n[map]\nmode = \"extend\"\nlocalise_with = \"features\"\n"
    );
    let out = dir.path().join("second");
    let run = slam_node(
        &config,
        &out,
        "30",
        &["--map", first.join("map.slmap").to_str().unwrap()],
    );
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    let merged = Map::load(&out.join("map.slmap")).unwrap();
    holds_the_saved_map(&saved, &merged);
    assert!(
        merged.scans.iter().any(|s| s.submap as usize >= n),
        "no scan of a new submap\n{t}"
    );
}

/// The urban street driven on the radar alone (submaps of 30 m keep their scans).
fn street(seed: u32, extra_config: &str, out: &Path, duration_s: &str, extra: &[&str]) -> Output {
    let config = format!(
        "[sim]\nseed = {seed}\n\n[odometry]\nsource = \"none\"\n\n[submaps]\nenabled = true\nmax_distance_m = 30.0\n\n{extra_config}"
    );
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../sim-sensor/scenes/urban-street.toml"
    );
    let mut args = vec!["--scene", scene];
    args.extend_from_slice(extra);
    slam_node(&config, out, duration_s, &args)
}

/// On the radar alone the run localises by the map's scans and joins the new drive where
/// the scan tracker puts it: the street's first 90 m mapped (seed 1), a second drive
/// (seed 2, other moving cars) over 180 m finds itself in that map from no prior and maps
/// the rest of the street as new submaps, with their scans, past the saved ones' end.
#[test]
fn a_drive_on_the_radar_alone_extends_a_map_by_its_scans() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first");
    let run = street(1, "", &first, "10", &[]);
    assert!(run.status.success(), "{}", text(&run));
    let saved_file = first.join("map.slmap");
    let saved = Map::load(&saved_file).unwrap();
    let n = saved.submaps.len();
    assert!(n >= 3 && saved.scan_point_count() > 1000, "{n} submaps");

    let out = dir.path().join("second");
    let run = street(
        2,
        "[map]\nmode = \"extend\"\n",
        &out,
        "20",
        &["--map", saved_file.to_str().unwrap()],
    );
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    assert!(t.contains("by its scans"), "{t}");
    assert!(t.contains("extend: mapping from"), "{t}");
    let merged = Map::load(&out.join("map.slmap")).unwrap();
    holds_the_saved_map(&saved, &merged);
    assert_eq!(merged.drive_starts, vec![n as u32]);
    let join = merged.joins[0];
    assert!(
        (join.from as usize) < n && join.to as usize == n,
        "{join:?}"
    );
    // The join rests on the rotations registered against the map since the fix.
    assert_eq!(
        u64::from(join.matches),
        slam_node::pipeline::extend::TRACK_BEFORE_MAPPING
    );
    // The new drive's submaps keep their scans, and reach past the saved drive's end along
    // the street.
    let new_scans = (n..merged.submaps.len())
        .filter(|&k| merged.scan_of(k).is_some_and(|p| !p.is_empty()))
        .count();
    assert!(new_scans >= 2, "{new_scans} new submaps with scans");
    let saved_end = saved
        .submaps
        .iter()
        .map(|s| s.frame.x)
        .fold(f64::MIN, f64::max);
    let furthest = merged.submaps[n..]
        .iter()
        .map(|s| s.frame.x)
        .fold(f64::MIN, f64::max);
    assert!(
        furthest > saved_end + 40.0,
        "new submaps reach x = {furthest:.1} m, the saved ones {saved_end:.1} m"
    );
    // The new drive's final trajectory against the truth (radar only: the saved map is
    // about a metre off at its end, and 90 m more on the radar alone add about as much).
    let rms: f64 = t
        .lines()
        .find_map(|l| {
            l.trim()
                .strip_prefix("global trajectory vs truth (trajectory.tum, final frames): RMS ")
        })
        .and_then(|l| l.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no global trajectory line\n{t}"));
    assert!(rms < 2.0, "the new drive {rms} m RMS from the truth\n{t}");
}
