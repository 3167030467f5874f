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
