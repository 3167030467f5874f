//! A short embedded run writes its saved map (`[map]`, slam-map's file) beside map.csv: it
//! loads back with the submaps and features the run reports, the features where map.csv
//! puts them, and the radar the run used.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use slam_map::Map;

fn run(config: &str, out: &Path) -> String {
    let file = out.join("run.toml");
    std::fs::write(&file, config).unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .args(["--config", file.to_str().unwrap()])
        .args([
            "--embedded-sim",
            "--fast",
            "--duration",
            "8",
            "--no-figures",
        ])
        .args(["--progress-every", "0", "--out"])
        .arg(out)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(run.status.success(), "{text}");
    text
}

/// The number after `key` in the run's summary.
fn figure_after(text: &str, key: &str) -> usize {
    let at = text
        .find(key)
        .unwrap_or_else(|| panic!("no {key:?} in\n{text}"))
        + key.len();
    text[at..]
        .split(|c: char| !c.is_ascii_digit())
        .find(|s| !s.is_empty())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no number after {key:?}"))
}

/// map.csv's features: id -> (x, y).
fn csv_features(path: &Path) -> BTreeMap<u64, (f64, f64)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("id,"))
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            (
                v[0].parse().unwrap(),
                (v[1].parse().unwrap(), v[2].parse().unwrap()),
            )
        })
        .collect()
}

#[test]
fn a_run_on_submaps_saves_a_map_that_loads_back_as_the_run_reports_it() {
    let dir = tempfile::tempdir().unwrap();
    let text = run(
        "[submaps]\nenabled = true\nmax_distance_m = 3.0\n\n[map]\nsave_every_s = 1.0\n",
        dir.path(),
    );
    let map = Map::load(&dir.path().join("map.slmap")).unwrap();
    let submaps = figure_after(&text, "  submaps: ");
    assert!(submaps >= 3, "a few submaps closed: {submaps}");
    assert_eq!(map.submaps.len(), submaps);
    assert_eq!(map.feature_count(), figure_after(&text, "  map: "));
    // "saved map: S submaps, F features, L loop closures and near links; B bytes... (N saves)"
    let line = text
        .lines()
        .find(|l| l.contains("saved map: "))
        .unwrap_or_else(|| panic!("no saved map line in\n{text}"));
    let numbers: Vec<u64> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|s| s.parse().ok())
        .collect();
    assert_eq!(
        numbers[..3],
        [
            map.submaps.len() as u64,
            map.feature_count() as u64,
            map.loops.len() as u64
        ],
        "{line}"
    );
    assert_eq!(
        numbers[3],
        std::fs::metadata(dir.path().join("map.slmap"))
            .unwrap()
            .len(),
        "{line}"
    );
    let saves: u64 = line
        .split('(')
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no save count in {line}"));
    assert!(
        saves >= 5,
        "saved every second of an 8 s run and at the end: {line}"
    );
    // The outdoor field runs the paper's unit.
    map.check_profile(&radar_model::profile::PAPER_2006)
        .unwrap();
    // Every feature of map.csv, by id, at the place the saved map's frames put it.
    let csv = csv_features(&dir.path().join("map.csv"));
    assert_eq!(csv.len(), map.feature_count());
    for s in &map.submaps {
        let frame = s.frame_pose();
        for f in &s.features {
            let (x, y) = csv[&f.id];
            let w = slam_graph::se2::transform_point(&frame, f.xy);
            assert!(
                (w[0] - x).abs() < 1e-6 && (w[1] - y).abs() < 1e-6,
                "feature {}: {w:?} against map.csv's ({x}, {y})",
                f.id
            );
        }
    }
    // Nothing but the map is left of the atomic writes.
    let leftovers: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn a_dense_run_saves_one_submap_and_save_false_saves_none() {
    let dir = tempfile::tempdir().unwrap();
    let text = run("", dir.path());
    let map = Map::load(&dir.path().join("map.slmap")).unwrap();
    assert_eq!(map.submaps.len(), 1);
    assert_eq!(map.feature_count(), figure_after(&text, "  map: "));
    assert_eq!(map.submaps[0].frame_pose().x, 0.0);
    let other = tempfile::tempdir().unwrap();
    let text = run("[map]\nsave = false\n", other.path());
    assert!(!other.path().join("map.slmap").exists());
    assert!(!text.contains("saved map:"), "{text}");
}

#[cfg(unix)]
#[test]
fn sigusr1_saves_the_map_while_the_run_goes_on() {
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.toml");
    // No save at the end: a file can only come from the signal.
    std::fs::write(&file, "[map]\nsave = false\n").unwrap();
    let log = std::fs::File::create(dir.path().join("log.txt")).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_slam-node"))
        .args(["--config", file.to_str().unwrap()])
        .args([
            "--embedded-sim",
            "--fast",
            "--duration",
            "3000",
            "--no-figures",
        ])
        .args(["--progress-every", "0", "--out"])
        .arg(dir.path())
        .stdout(std::process::Stdio::null())
        .stderr(log)
        .spawn()
        .unwrap();
    let pid = child.id().to_string();
    let signal = |name: &str| {
        let ok = Command::new("kill")
            .args([name, &pid])
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill {name}");
    };
    let map_path = dir.path().join("map.slmap");
    // The handler is in place once the run has started (its log says so).
    let started = Instant::now();
    while !std::fs::read_to_string(dir.path().join("log.txt"))
        .unwrap_or_default()
        .contains("embedded simulator started")
    {
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "the run did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    signal("-USR1");
    let asked = Instant::now();
    while !map_path.exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended without saving"
        );
        assert!(
            asked.elapsed() < Duration::from_secs(20),
            "no map 20 s after SIGUSR1"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let still_running = child.try_wait().unwrap().is_none();
    signal("-INT");
    let waited = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if waited.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            panic!("still running 30 s after Ctrl-C");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(still_running, "the map was saved while the run went on");
    assert!(status.success(), "{status:?}");
    let map = Map::load(&map_path).unwrap();
    assert_eq!(map.submaps.len(), 1);
    let log = std::fs::read_to_string(dir.path().join("log.txt")).unwrap();
    assert!(log.contains("saving the map (SIGUSR1)"), "{log}");
}
