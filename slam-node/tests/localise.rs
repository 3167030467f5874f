//! Localisation in a saved map (`--map FILE`, `[map] mode = "localise"`): a small scene
//! mapped by one run is localised in by a second run with another speckle seed, from a
//! prior pose and from none; a map that does not overlap the drive gives a warning and no
//! pose; a bad file or a map of another radar geometry refuses the run, naming the file.

use std::path::Path;
use std::process::{Command, Output};

use slam_map::Map;

/// Seconds of the outdoor field driven (1 m/s).
const DRIVE_S: &str = "14";

fn slam_node(config: &str, out: &Path, extra: &[&str]) -> Output {
    std::fs::create_dir_all(out).unwrap();
    let file = out.join("run.toml");
    std::fs::write(&file, config).unwrap();
    Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .args(["--config", file.to_str().unwrap()])
        .args([
            "--embedded-sim",
            "--fast",
            "--duration",
            DRIVE_S,
            "--no-figures",
        ])
        .args(["--progress-every", "0", "--out"])
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

/// Maps the outdoor field with speckle seed 1: the map file.
fn mapped(dir: &Path) -> std::path::PathBuf {
    let out = dir.join("map-run");
    let run = slam_node("[sim]\nseed = 1\n", &out, &[]);
    assert!(run.status.success(), "{}", text(&run));
    out.join("map.slmap")
}

/// The numbers in the summary line that starts with `prefix`.
fn numbers_after(text: &str, prefix: &str) -> Vec<f64> {
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with(prefix))
        .unwrap_or_else(|| panic!("no line {prefix:?} in\n{text}"));
    line[line.find(prefix).unwrap() + prefix.len()..]
        .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .filter_map(|s| s.parse().ok())
        .collect()
}

/// Published poses in trajectory.tum.
fn published(out: &Path) -> usize {
    std::fs::read_to_string(out.join("trajectory.tum"))
        .map(|t| {
            t.lines()
                .filter(|l| !l.starts_with('#') && !l.is_empty())
                .count()
        })
        .unwrap_or(0)
}

const LOCALISE: &str = "[sim]\nseed = 2\n\n[map]\nmode = \"localise\"\n";

#[test]
fn a_second_run_localises_in_the_first_ones_map_from_a_prior_and_from_none() {
    let dir = tempfile::tempdir().unwrap();
    let map = mapped(dir.path());
    let loaded = Map::load(&map).unwrap();
    assert!(loaded.feature_count() > 10, "{}", loaded.feature_count());

    // From a prior half a metre and a degree off the true start (0, 0, 0).
    let out = dir.path().join("prior");
    let config =
        format!("{LOCALISE}initial_pose = [0.4, -0.3, 0.017]\ninitial_sigma = [0.5, 0.5, 0.03]\n");
    let run = slam_node(&config, &out, &["--map", map.to_str().unwrap()]);
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    assert!(t.contains("started from the prior pose"), "{t}");
    // "localisation vs truth over N published poses: RMS along track A m, across C m,
    // heading H deg; max M m; consistency score ... mean S"
    let v = numbers_after(&t, "localisation vs truth over");
    let (poses, along, across, heading) = (v[0], v[1], v[2], v[3]);
    assert!(poses >= 20.0, "{t}");
    assert!(
        along < 0.3 && across < 0.3,
        "along {along} m, across {across} m\n{t}"
    );
    assert!(heading < 1.0, "heading {heading} deg\n{t}");
    let consistency = v[6];
    assert!(consistency.is_finite() && consistency > 0.0, "{t}");
    assert!(published(&out) as f64 >= poses, "{t}");
    // Nothing is mapped and nothing saved.
    assert!(!out.join("map.slmap").exists());

    // From no prior: place recognition, then the verifier, then tracking.
    let out = dir.path().join("unknown");
    let run = slam_node(LOCALISE, &out, &["--map", map.to_str().unwrap()]);
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    let fix = numbers_after(&t, "first fix after");
    assert!(fix[0] < 12.0, "{t}");
    let v = numbers_after(&t, "localisation vs truth over");
    let first_error_m = v[v.len() - 2];
    assert!(first_error_m < 1.0, "the fix is {first_error_m} m off\n{t}");
    assert!(v[1] < 0.5 && v[2] < 0.5, "{t}");
    // Fewer poses than rotations: none before the fix.
    assert!(published(&out) > 0);
    assert!(
        (published(&out) as f64) < numbers_after(&t, "rotations")[0],
        "{t}"
    );
}

#[test]
fn a_map_of_another_place_gives_a_warning_and_no_pose() {
    let dir = tempfile::tempdir().unwrap();
    let map = mapped(dir.path());
    // The map mirrored (y -> -y): no rigid motion puts the drive on it. (The same map
    // moved elsewhere would be found there: place recognition does not care where.)
    let mut mirrored = Map::load(&map).unwrap();
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
    let mirrored_file = dir.path().join("mirrored.slmap");
    mirrored.save(&mirrored_file).unwrap();
    let out = dir.path().join("mirrored");
    let run = slam_node(LOCALISE, &out, &["--map", mirrored_file.to_str().unwrap()]);
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    assert!(t.contains("not localised in the map yet"), "{t}");
    assert!(
        t.contains("mirrored.slmap"),
        "the warning names the file\n{t}"
    );
    assert!(t.contains("NO FIX"), "{t}");
    assert_eq!(published(&out), 0, "no pose before a fix\n{t}");
}

#[test]
fn bad_map_files_and_a_map_of_another_radar_refuse_the_run_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let map = mapped(dir.path());
    let bytes = std::fs::read(&map).unwrap();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.slmap", Vec::new(), "empty"),
        (
            "truncated.slmap",
            bytes[..bytes.len() / 2].to_vec(),
            "truncated",
        ),
        (
            "corrupt.slmap",
            {
                let mut b = bytes.clone();
                let k = b.len() - 10;
                b[k] ^= 0xff;
                b
            },
            "CRC",
        ),
        (
            "future.slmap",
            {
                let mut b = bytes.clone();
                b[8] = 9;
                b
            },
            "version 9",
        ),
    ];
    for (name, content, why) in cases {
        let file = dir.path().join(name);
        std::fs::write(&file, content).unwrap();
        let run = slam_node(
            LOCALISE,
            &dir.path().join("bad"),
            &["--map", file.to_str().unwrap()],
        );
        let t = text(&run);
        assert!(!run.status.success(), "{name} was taken\n{t}");
        assert!(t.contains(name), "{name}: the error names the file\n{t}");
        assert!(
            t.to_lowercase().contains(&why.to_lowercase()),
            "{name}: {why}\n{t}"
        );
    }
    let missing = dir.path().join("missing.slmap");
    let run = slam_node(
        LOCALISE,
        &dir.path().join("bad"),
        &["--map", missing.to_str().unwrap()],
    );
    assert!(!run.status.success());
    assert!(text(&run).contains("missing.slmap"), "{}", text(&run));
    // A map given without localise mode, and localise mode without a map.
    let run = slam_node(
        "",
        &dir.path().join("bad"),
        &["--map", map.to_str().unwrap()],
    );
    assert!(!run.status.success() && text(&run).contains("mode = \"localise\""));
    let run = slam_node(LOCALISE, &dir.path().join("bad"), &[]);
    assert!(!run.status.success() && text(&run).contains("--map FILE"));

    // Another radar geometry: refused. The same geometry under another name: a warning.
    let mut other = Map::load(&map).unwrap();
    other.profile.azimuths *= 2;
    let file = dir.path().join("other-radar.slmap");
    other.save(&file).unwrap();
    let run = slam_node(
        LOCALISE,
        &dir.path().join("bad"),
        &["--map", file.to_str().unwrap()],
    );
    let t = text(&run);
    assert!(!run.status.success(), "{t}");
    assert!(
        t.contains("other-radar.slmap") && t.contains("azimuths"),
        "{t}"
    );
    let mut renamed = Map::load(&map).unwrap();
    renamed.profile.name = "another-name".into();
    let file = dir.path().join("renamed.slmap");
    renamed.save(&file).unwrap();
    let out = dir.path().join("renamed");
    let config = format!("{LOCALISE}initial_pose = [0.0, 0.0, 0.0]\n");
    let run = slam_node(&config, &out, &["--map", file.to_str().unwrap()]);
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    assert!(
        t.contains("another-name") && t.contains("localising anyway"),
        "{t}"
    );
}

/// The urban street driven on the radar alone for this long (s, 9 m/s).
const STREET_S: &str = "20";

fn street_run(seed: u32, extra_config: &str, out: &Path, extra: &[&str]) -> Output {
    std::fs::create_dir_all(out).unwrap();
    let file = out.join("run.toml");
    // Submaps keep the scans the map file saves.
    let config = format!(
        "[sim]\nseed = {seed}\n\n[odometry]\nsource = \"none\"\n\n[submaps]\nenabled = true\nmax_distance_m = 100.0\n\n{extra_config}"
    );
    std::fs::write(&file, config).unwrap();
    Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .args(["--config", file.to_str().unwrap()])
        .args(["--embedded-sim", "--scene"])
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../sim-sensor/scenes/urban-street.toml"
        ))
        .args(["--fast", "--duration", STREET_S, "--no-figures"])
        .args(["--progress-every", "0", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

/// A street mapped on the radar alone keeps its scans in the map; a second drive (another
/// speckle seed, other moving cars) localises in them from no prior: the search finds the
/// place from the last stretch's scan, then each rotation registers against the map.
#[test]
fn a_drive_on_the_radar_alone_localises_by_the_maps_scans_from_no_prior() {
    let dir = tempfile::tempdir().unwrap();
    let dir = if let Ok(keep) = std::env::var("LOCALISE_TEST_KEEP") {
        std::path::PathBuf::from(keep)
    } else {
        dir.path().to_path_buf()
    };
    let dir = dir.as_path();
    let map_out = dir.join("map-run");
    let run = street_run(1, "", &map_out, &[]);
    assert!(run.status.success(), "{}", text(&run));
    let map = map_out.join("map.slmap");
    let loaded = Map::load(&map).unwrap();
    assert!(
        loaded.scan_point_count() > 1000,
        "{}",
        loaded.scan_point_count()
    );
    // Where the vehicle drove through each submap (format version 4): the first path
    // begins where the drive began (the first pose of the run's trajectory: submap 0's
    // frame is the map's), positions 2 m apart, each path ending at its submap's end.
    assert!(!loaded.paths.is_empty(), "no path in the map");
    let trajectory = std::fs::read_to_string(map_out.join("trajectory.tum")).unwrap();
    let first: Vec<f64> = trajectory
        .lines()
        .find(|l| !l.starts_with('#'))
        .unwrap()
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    let start = loaded.path_of(0).expect("submap 0's path")[0];
    assert!(
        (f64::from(start[0]) - first[1]).hypot(f64::from(start[1]) - first[2]) < 0.5,
        "the path begins at {start:?}, the drive at {:?}",
        &first[1..3]
    );
    for path in &loaded.paths {
        let s = &loaded.submaps[path.submap as usize];
        let end = path.points.last().unwrap();
        if (path.submap as usize) + 1 < loaded.submaps.len() {
            assert!(
                (f64::from(end[0]) - s.end_pose.x).hypot(f64::from(end[1]) - s.end_pose.y) < 1e-3,
                "submap {}'s path ends at {end:?}",
                path.submap
            );
        }
        for w in path.points[..path.points.len() - 1].windows(2) {
            let step = f64::from(w[1][0] - w[0][0]).hypot(f64::from(w[1][1] - w[0][1]));
            assert!(
                (2.0..6.0).contains(&step),
                "a step of {step} m in submap {}",
                path.submap
            );
        }
    }

    let out = dir.join("by-scans");
    let run = street_run(
        2,
        "[map]\nmode = \"localise\"\n",
        &out,
        &["--map", map.to_str().unwrap()],
    );
    let t = text(&run);
    assert!(run.status.success(), "{t}");
    assert!(t.contains("by its scans"), "{t}");
    let fix = numbers_after(&t, "first fix after");
    assert!(fix[0] < 15.0, "{t}");
    // "tracking by scans: N rotations published ...; F fixes, L lost ...; registrations
    // fused A, none found B, outside the gate C"
    let tr = numbers_after(&t, "tracking by scans:");
    let (published_rotations, fused) = (tr[0], tr[4]);
    assert!(published_rotations >= 10.0, "{t}");
    assert!(fused >= 0.8 * published_rotations, "{t}");
    // The map's frame is the mapping run's estimate (metres from the truth after 180 m
    // on the radar alone): each published pose is scored against the truth in the map's
    // frame, where the map puts the true pose (evaluation/localise_in_map.py).
    let errors = errors_in_map_frame(&map_out, &out);
    assert!(errors.len() >= 10, "{t}");
    let rms =
        |k: usize| (errors.iter().map(|e| e[k] * e[k]).sum::<f64>() / errors.len() as f64).sqrt();
    let (along, across, heading) = (rms(0), rms(1), rms(2).to_degrees());
    assert!(
        along < 0.15 && across < 0.15,
        "along {along} m, across {across} m\n{t}"
    );
    assert!(heading < 0.5, "heading {heading} deg\n{t}");
    assert!(
        errors[0][0].hypot(errors[0][1]) < 1.0,
        "the fix: {:?}\n{t}",
        errors[0]
    );
    assert!(
        !t.contains("localisation lost"),
        "the fix held on the mapped street\n{t}"
    );
    assert!(!out.join("map.slmap").exists());
}

/// A TUM file's poses `(time, x, y, heading)`.
fn tum(path: &Path) -> Vec<[f64; 4]> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], 2.0 * v[6].atan2(v[7])]
        })
        .collect()
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

fn compose(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    let (s, c) = a[2].sin_cos();
    [
        a[0] + c * b[0] - s * b[1],
        a[1] + s * b[0] + c * b[1],
        wrap(a[2] + b[2]),
    ]
}

fn inverse(a: [f64; 3]) -> [f64; 3] {
    let (s, c) = a[2].sin_cos();
    [-(c * a[0] + s * a[1]), -(-s * a[0] + c * a[1]), -a[2]]
}

fn nearest_in_time(rows: &[[f64; 4]], t: f64) -> [f64; 3] {
    let r = rows
        .iter()
        .min_by(|a, b| (a[0] - t).abs().total_cmp(&(b[0] - t).abs()))
        .unwrap();
    [r[1], r[2], r[3]]
}

/// Each pose the localising run published against the truth in the map's frame: the
/// mapping run's true pose nearest the true one (by position) and its estimate there give
/// the map's frame, `truth in map = estimate * inv(mapping truth) * truth`. `[along m,
/// across m, heading rad]` per pose, along and across the true heading.
fn errors_in_map_frame(map_run: &Path, run: &Path) -> Vec<[f64; 3]> {
    let (m_truth, m_est) = (
        tum(&map_run.join("groundtruth.tum")),
        tum(&map_run.join("trajectory.tum")),
    );
    let truth = tum(&run.join("groundtruth.tum"));
    tum(&run.join("trajectory.tum"))
        .iter()
        .map(|p| {
            let t = nearest_in_time(&truth, p[0]);
            let m = m_truth
                .iter()
                .min_by(|a, b| {
                    (a[1] - t[0])
                        .hypot(a[2] - t[1])
                        .total_cmp(&(b[1] - t[0]).hypot(b[2] - t[1]))
                })
                .unwrap();
            let est = nearest_in_time(&m_est, m[0]);
            let tm = compose(est, compose(inverse([m[1], m[2], m[3]]), t));
            let (dx, dy) = (p[1] - tm[0], p[2] - tm[1]);
            let (s, c) = tm[2].sin_cos();
            [c * dx + s * dy, -s * dx + c * dy, wrap(p[3] - tm[2])]
        })
        .collect()
}
