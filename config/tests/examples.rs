//! The shipped example files, the defaults, and loading from disk.

use std::io::Write;
use std::net::SocketAddr;
use std::path::Path;

use config::odometry::{MotionModel, OdometrySource};
use config::radar::{DropPolicy, ReconnectAttempts};
use config::sim::{Pacing, SceneRef};
use config::{examples, Config, ConfigError, Preset, RawConfig};

fn example_path(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples")
        .join(name)
}

#[test]
fn every_shipped_example_parses_and_validates() {
    for preset in [Preset::Vehicle, Preset::Sim, Preset::Test] {
        let config = Config::preset(preset);
        assert!(config.is_ok(), "{preset:?}: {}", config.unwrap_err());
    }
    for name in ["vehicle.toml", "sim.toml", "test.toml"] {
        let loaded = Config::load(example_path(name));
        assert!(loaded.is_ok(), "{name}: {}", loaded.unwrap_err());
    }
    // Every file in the folder, the scene configurations included.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).expect("the examples folder") {
        let path = entry.expect("a folder entry").path();
        if path.extension().is_some_and(|e| e == "toml") {
            let loaded = Config::load(&path);
            assert!(
                loaded.is_ok(),
                "{}: {}",
                path.display(),
                loaded.unwrap_err()
            );
            seen += 1;
        }
    }
    assert!(seen >= 8, "only {seen} examples found in {}", dir.display());
}

#[test]
fn compiled_in_examples_are_the_files_on_disk() {
    for (text, name) in [
        (examples::VEHICLE, "vehicle.toml"),
        (examples::SIM, "sim.toml"),
        (examples::TEST, "test.toml"),
    ] {
        let on_disk = std::fs::read_to_string(example_path(name)).unwrap();
        assert_eq!(text, on_disk, "{name}");
    }
}

#[test]
fn the_sim_example_spells_out_exactly_the_defaults() {
    let sim = Config::preset(Preset::Sim).unwrap();
    assert_eq!(sim, Config::default());
}

#[test]
fn an_empty_file_gives_the_defaults() {
    assert_eq!(Config::from_toml_str("").unwrap(), Config::default());
    assert_eq!(
        RawConfig::default().validate().unwrap(),
        Config::default(),
        "the raw defaults validate to the same settings"
    );
}

#[test]
fn the_defaults_are_the_documented_values() {
    let c = Config::default();
    assert_eq!(
        c.radar.address,
        "127.0.0.1:6317".parse::<SocketAddr>().unwrap()
    );
    assert_eq!(c.radar.connect_timeout.as_millis(), 3000);
    assert!(c.radar.tcp_nodelay);
    assert_eq!(c.radar.tcp_keepalive, None);
    assert_eq!(c.radar.recv_buffer_bytes.get(), 4 * 1024 * 1024);
    assert_eq!(c.radar.watchdog_timeout.as_millis(), 7000);
    assert_eq!(c.radar.reconnect_backoff.initial().as_millis(), 100);
    assert_eq!(c.radar.reconnect_backoff.max().as_millis(), 5000);
    assert_eq!(c.radar.reconnect_backoff.jitter.get(), 0.2);
    assert_eq!(c.radar.reconnect_max_attempts, ReconnectAttempts::Forever);
    assert_eq!(c.radar.start_fft_message_id(), 21);
    assert_eq!(c.radar.azimuth_channel_capacity.get(), 4096);
    assert_eq!(c.radar.rotation_channel_capacity.get(), 8);
    assert_eq!(c.radar.drop_policy, DropPolicy::DropNewest);
    assert_eq!(c.radar.max_held_mib.get(), 64);
    assert_eq!(
        c.odometry.source,
        OdometrySource::Tcp {
            // The documented default odometry address (a value, nothing binds it here).
            address: std::net::SocketAddr::from(([127, 0, 0, 1], 6318))
        }
    );
    assert!(
        matches!(c.odometry.motion_model, MotionModel::Paper { step_s } if step_s.get() == 0.05)
    );
    assert_eq!(c.odometry.stale_after.as_millis(), 500);
    assert_eq!(c.sim.max_clients.get(), 3);
    assert_eq!(c.sim.pacing, Pacing::Realtime);
    assert_eq!(c.sim.scene, SceneRef::Shipped("outdoor-field".into()));
    assert_eq!(c.sim.data_width.bits(), 8);
    assert!(!c.sim.faults.any());
    assert_eq!(c.model.beam_width_deg.get(), 1.8);
    assert_eq!(c.model.range_resolution_m.get(), 0.25);
    assert_eq!(c.model.sigma_range_m.get(), 0.1);
    let rolloff = c.model.rolloff.unwrap();
    assert_eq!((rolloff.corner_m.get(), rolloff.order.get()), (200.0, 4));
    assert!((c.model.sigma_power_db.get().powi(2) - 4.07).abs() < 1e-12);
    assert_eq!(c.detector.reference_cells.get(), 70);
    assert_eq!(c.detector.os_rank.get(), 53, "3/4 of 70 rounded up");
    assert_eq!(c.detector.tpp_alpha.get(), 0.1);
    assert_eq!(c.detector.tpp_detect.get(), 0.8);
    assert_eq!(c.detector.max_targets_per_beam.get(), 16);
    assert_eq!(
        c.filter.gate,
        config::filter::Gate::Probability(config::OpenProbability::new(0.99).unwrap())
    );
    assert_eq!(c.filter.confirm_after.get(), 2);
    assert_eq!(c.filter.retire_after_misses.get(), 5);
    assert_eq!(c.filter.max_features.get(), 1000);
    assert!(c.filter.use_power_in_observation);
    assert!(c.filter.first_estimate_jacobians);
    assert!(c.filter.repeat_look_decorrelation);
    assert_eq!(c.output.trajectory_path(), Path::new("out/trajectory.tum"));
    assert!(c.output.spectra && c.output.ground_truth);
}

#[test]
fn the_vehicle_example_points_at_the_real_radar() {
    let c = Config::preset(Preset::Vehicle).unwrap();
    assert_eq!(
        c.radar.address,
        "192.168.0.1:6317".parse::<SocketAddr>().unwrap()
    );
    assert_eq!(c.radar.drop_policy, DropPolicy::DropOldest);
    assert!(
        matches!(c.odometry.motion_model, MotionModel::Bicycle { wheelbase_m } if wheelbase_m.get() == 2.7)
    );
    assert_eq!(c.filter.association, config::filter::Association::Jcbb);
    // Nothing that grows with every rotation for as long as the vehicle runs.
    assert!(!c.output.spectra && !c.output.ground_truth);
}

#[test]
fn the_test_example_binds_ephemeral_loopback_ports_and_runs_as_fast_as_possible() {
    let c = Config::preset(Preset::Test).unwrap();
    // Every port the preset binds, the simulator's gyro and the live view included (their
    // defaults are the fixed 6319 and 8765, which a test must never take).
    for addr in [
        c.sim.bind,
        c.sim.odometry_bind,
        c.sim.gyro.bind,
        c.output.foxglove.bind,
    ] {
        assert!(addr.ip().is_loopback(), "{addr}");
        assert_eq!(addr.port(), 0, "{addr}");
    }
    assert_eq!(c.sim.pacing, Pacing::AsFastAsPossible);
    assert!(
        c.sim.keepalive_interval < c.radar.watchdog_timeout,
        "keep-alives must arrive well inside the watchdog"
    );
    assert!(matches!(
        c.radar.reconnect_max_attempts,
        ReconnectAttempts::AtMost(_)
    ));
    assert!(!c.output.progress);
}

#[test]
fn a_file_with_one_section_keeps_every_other_default() {
    let c = Config::from_toml_str("[detector]\nkind = \"tpp\"\n").unwrap();
    assert_eq!(c.detector.kind, config::detector::DetectorKind::Tpp);
    let mut expected = Config::default();
    expected.detector.kind = config::detector::DetectorKind::Tpp;
    assert_eq!(c, expected);
}

#[test]
fn load_names_the_file_in_its_errors() {
    let mut file = tempfile::NamedTempFile::new().unwrap();
    writeln!(file, "[filter]\nsigma_u = -1").unwrap();
    let err = Config::load(file.path()).unwrap_err();
    let text = err.to_string();
    assert!(
        text.starts_with(&file.path().display().to_string()),
        "{text}"
    );
    assert!(
        text.contains("filter.sigma_u must be >= 0, got -1"),
        "{text}"
    );
}

#[test]
fn load_of_a_missing_file_is_an_io_error_naming_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.toml");
    match Config::load(&missing) {
        Err(ConfigError::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("expected an IO error, got {other:?}"),
    }
}

#[test]
fn load_of_a_file_that_is_not_utf8_is_an_io_error() {
    let mut file = tempfile::NamedTempFile::new().unwrap();
    file.write_all(&[0x5b, 0xff, 0xfe, 0x5d]).unwrap();
    assert!(matches!(
        Config::load(file.path()),
        Err(ConfigError::Io { .. })
    ));
}

#[test]
fn load_refuses_a_file_larger_than_the_limit_without_reading_it_all() {
    let mut file = tempfile::NamedTempFile::new().unwrap();
    let comment = "#".repeat(1023) + "\n";
    for _ in 0..=config::MAX_CONFIG_BYTES / 1024 {
        file.write_all(comment.as_bytes()).unwrap();
    }
    match Config::load(file.path()) {
        Err(ConfigError::TooLarge { max_bytes, .. }) => {
            assert_eq!(max_bytes, config::MAX_CONFIG_BYTES)
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
}

#[test]
fn raw_settings_survive_a_round_trip_through_toml() {
    for preset in [Preset::Vehicle, Preset::Sim, Preset::Test] {
        let (text, _) = examples::text(preset);
        let raw = RawConfig::from_toml_str(text).unwrap();
        let printed = raw.to_toml_string().unwrap();
        let again = RawConfig::from_toml_str(&printed).unwrap();
        assert_eq!(raw, again, "{preset:?}:\n{printed}");
    }
}

#[test]
fn a_gain_table_and_a_scene_file_are_accepted() {
    let c = Config::from_toml_str(
        "[model]\ncompensation = \"table\"\ncompensation_table = [\n  { range_m = 1.0, gain_db = 0.0 },\n  { range_m = 10.0, gain_db = 60.0 },\n  { range_m = 200.0, gain_db = 130.0 },\n]\n[sim]\nscene = \"scenes/yard.toml\"\n",
    )
    .unwrap();
    match &c.model.compensation {
        config::model::Compensation::Table(t) => assert_eq!(t.points().len(), 3),
        other => panic!("expected a table, got {other:?}"),
    }
    assert_eq!(c.sim.scene, SceneRef::File("scenes/yard.toml".into()));
}

#[test]
fn odometry_from_a_file_and_a_fixed_chi2_gate_are_accepted() {
    let c = Config::from_toml_str(
        "[odometry]\nsource = \"file\"\npath = \"odo.txt\"\n[filter]\ngate_chi2 = 11.34\n[detector]\nthreshold_db = 12\n",
    )
    .unwrap();
    assert_eq!(
        c.odometry.source,
        OdometrySource::File {
            path: "odo.txt".into()
        }
    );
    assert_eq!(
        c.filter.gate,
        config::filter::Gate::Chi2(config::PositiveF64::new(11.34).unwrap())
    );
    assert!(
        matches!(c.detector.threshold, config::detector::Threshold::Db(db) if db.get() == 12.0)
    );
}

#[test]
fn radar_odometry_without_estimated_corrections_is_accepted() {
    // The measured motion updates the pose's change (stochastic cloning in the filter), so
    // it no longer needs the odometry corrections in the state.
    let c = Config::from_toml_str("[odometry]\nradar_odometry = true\n").unwrap();
    assert!(c.odometry.radar_odometry);
    assert_eq!(c.odometry.speed_scale_std.get(), 0.0);
    assert_eq!(c.odometry.steer_bias_std_rad.get(), 0.0);
}

#[test]
fn a_heading_outside_minus_pi_to_pi_is_wrapped() {
    let c = Config::from_toml_str("[filter]\ninitial_theta_rad = 7.0\n").unwrap();
    let theta = c.filter.initial_pose.theta_rad.get();
    assert!(
        (theta - (7.0 - 2.0 * std::f64::consts::PI)).abs() < 1e-12,
        "{theta}"
    );
    let c = Config::from_toml_str("[filter]\ninitial_theta_rad = -3.141592653589793\n").unwrap();
    assert_eq!(c.filter.initial_pose.theta_rad.get(), std::f64::consts::PI);
}

#[test]
fn a_roll_off_of_order_zero_is_none() {
    let c = Config::from_toml_str("[model]\nrolloff_order = 0\n").unwrap();
    assert_eq!(c.model.rolloff, None);
}

#[test]
fn non_contoured_data_is_requested_with_message_140() {
    let c = Config::from_toml_str("[radar]\nnon_contoured = true\n").unwrap();
    assert_eq!(c.radar.start_fft_message_id(), 140);
}

/// The reference file spells out every key: each key the defaults write is written in
/// `sim.toml` with its default value, and each key without a default (an optional one) is
/// named there in a comment (`# key = ...`).
#[test]
fn the_sim_example_writes_every_key() {
    let defaults = RawConfig::default().to_toml_string().unwrap();
    let every = config::written_keys(&defaults);
    let written = config::written_keys(examples::SIM);
    let missing: Vec<&String> = every.difference(&written).collect();
    assert!(
        missing.is_empty(),
        "sim.toml does not write these keys: {missing:?}"
    );
    // The optional keys: the raw settings' fields that serialise to nothing by default.
    let mut optional = Vec::new();
    for (section, keys) in [
        ("radar", &["tcp_keepalive_s", "record_path", "model"][..]),
        ("detector", &["pfa", "threshold_db", "os_rank"][..]),
        ("model", &["compensation_table"][..]),
        ("odometry", &["path", "wheelbase_m", "topic", "message"][..]),
        ("map", &["initial_pose", "file"][..]),
    ] {
        for key in keys {
            let named = examples::SIM.lines().any(|l| {
                l.trim_start()
                    .trim_start_matches('#')
                    .trim_start()
                    .starts_with(&format!("{key} ="))
            });
            if !named {
                optional.push(format!("{section}.{key}"));
            }
        }
    }
    assert!(
        optional.is_empty(),
        "sim.toml does not name these optional keys: {optional:?}"
    );
}
