//! Unknown keys, misspelt choices, wrong types and broken TOML: each is a typed error that
//! names the key and where it is written.

use std::io::Write;

use config::{Config, ConfigError, Location};

fn unknown_key(text: &str) -> (String, Location, String) {
    match Config::from_toml_str(text) {
        Err(e @ ConfigError::UnknownKey { .. }) => {
            let shown = e.to_string();
            let ConfigError::UnknownKey {
                key_path, location, ..
            } = e
            else {
                unreachable!()
            };
            (key_path, location, shown)
        }
        other => panic!("expected an unknown-key error for\n{text}\ngot {other:?}"),
    }
}

#[test]
fn a_misspelt_key_in_every_section_is_named_with_its_line_and_column() {
    for (text, key_path, line, column) in [
        ("[radar]\naddres = \"127.0.0.1:0\"\n", "radar.addres", 2, 1),
        (
            "[odometry]\n\nsigma_sped_mps = 0.1\n",
            "odometry.sigma_sped_mps",
            3,
            1,
        ),
        ("[sim]\n  pacng = \"realtime\"\n", "sim.pacng", 2, 3),
        ("[sim.faults]\nstal_ms = 3\n", "sim.faults.stal_ms", 2, 1),
        ("[model]\nbeam_width = 1.8\n", "model.beam_width", 2, 1),
        (
            "[detector]\nreference_cels = 70\n",
            "detector.reference_cels",
            2,
            1,
        ),
        (
            "# a comment\n[filter]\nsigma_u = 1.0\nsigma_rnage_m = 2\n",
            "filter.sigma_rnage_m",
            4,
            1,
        ),
        (
            "[output]\ntrajectry = \"t.tum\"\n",
            "output.trajectry",
            2,
            1,
        ),
    ] {
        let (path, location, shown) = unknown_key(text);
        assert_eq!(path, key_path, "{shown}");
        assert_eq!(location, Location { line, column }, "{shown}");
        assert!(
            shown.contains(&format!("line {line}, column {column}")),
            "{shown}"
        );
        assert!(
            shown.contains(&format!("unknown key `{key_path}`")),
            "{shown}"
        );
        assert!(
            shown.contains("expected one of"),
            "lists the known keys: {shown}"
        );
    }
}

#[test]
fn an_unknown_section_is_named() {
    let (path, location, shown) = unknown_key("[radar]\n[radr]\naddress = \"x\"\n");
    assert_eq!(path, "radr", "{shown}");
    assert_eq!(location.line, 2);
}

#[test]
fn a_misspelt_dotted_key_is_named_in_full() {
    let (path, location, _) = unknown_key("radar.adress = \"127.0.0.1:0\"\n");
    assert_eq!(path, "radar.adress");
    assert_eq!(location.line, 1);
}

#[test]
fn a_misspelt_key_inside_an_inline_table_is_named() {
    let (path, location, _) = unknown_key(
        "[model]\ncompensation = \"table\"\ncompensation_table = [{ range_m = 1.0, gian_db = 0.0 }]\n",
    );
    assert_eq!(path, "model.compensation_table.gian_db");
    assert_eq!(location.line, 3);
}

#[test]
fn an_unknown_key_in_a_file_names_the_file() {
    let mut file = tempfile::NamedTempFile::new().unwrap();
    write!(file, "[radar]\nwatchdog_ms = 7000\n").unwrap();
    let err = Config::load(file.path()).unwrap_err();
    let shown = err.to_string();
    assert!(
        shown.starts_with(&format!(
            "{}: line 2, column 1: unknown key `radar.watchdog_ms`",
            file.path().display()
        )),
        "{shown}"
    );
}

#[test]
fn a_misspelt_choice_names_the_key_and_the_valid_choices() {
    for (text, key_path, choice) in [
        (
            "[radar]\ndrop_policy = \"drop-newst\"",
            "radar.drop_policy",
            "drop-newest",
        ),
        ("[odometry]\nsource = \"udp\"", "odometry.source", "tcp"),
        (
            "[odometry]\nmotion_model = \"ackermann\"",
            "odometry.motion_model",
            "bicycle",
        ),
        (
            "[sim]\npacing = \"fast\"",
            "sim.pacing",
            "as-fast-as-possible",
        ),
        (
            "[sim]\nradar_preset = \"cts350x\"",
            "sim.radar_preset",
            "cts350x-400",
        ),
        (
            "[model]\nspreading = \"radar-equation\"",
            "model.spreading",
            "textbook",
        ),
        (
            "[model]\ncompensation = \"50db\"",
            "model.compensation",
            "60db",
        ),
        ("[detector]\nkind = \"cfar\"", "detector.kind", "ca-cfar"),
        (
            "[filter]\nassociation = \"nn\"",
            "filter.association",
            "nearest-neighbour",
        ),
    ] {
        match Config::from_toml_str(text) {
            Err(e @ ConfigError::Parse { .. }) => {
                let shown = e.to_string();
                assert!(shown.contains(&format!("key `{key_path}`")), "{shown}");
                assert!(shown.contains("line 2"), "{shown}");
                assert!(shown.contains("unknown variant"), "{shown}");
                assert!(shown.contains(choice), "{shown}");
            }
            other => panic!("expected a parse error for {text:?}, got {other:?}"),
        }
    }
}

#[test]
fn a_value_of_the_wrong_type_names_the_key() {
    for (text, key_path) in [
        (
            "[radar]\nconnect_timeout_ms = \"3s\"",
            "radar.connect_timeout_ms",
        ),
        (
            "[radar]\nconnect_timeout_ms = 3.5",
            "radar.connect_timeout_ms",
        ),
        ("[radar]\ntcp_nodelay = 1", "radar.tcp_nodelay"),
        ("[output]\nground_truth = \"no\"", "output.ground_truth"),
        ("[filter]\nsigma_u = \"small\"", "filter.sigma_u"),
        ("[sim]\nseed = 1e3", "sim.seed"),
        ("radar = 5", "radar"),
    ] {
        match Config::from_toml_str(text) {
            Err(ConfigError::Parse {
                key_path: Some(path),
                location: Some(_),
                message,
                ..
            }) => {
                assert_eq!(path, key_path, "{message}");
                assert!(message.contains("invalid type"), "{message}");
            }
            other => panic!("expected a typed parse error for {text:?}, got {other:?}"),
        }
    }
}

#[test]
fn text_that_is_not_toml_is_a_parse_error_with_a_location() {
    for (text, line) in [
        ("[radar\n", 1),
        ("[radar]\naddress = \n", 2),
        ("[radar]\n[radar]\n", 2),
        ("[sim]\nseed = 1\nseed = 2\n", 3),
    ] {
        match Config::from_toml_str(text) {
            Err(ConfigError::Parse {
                location: Some(location),
                message,
                ..
            }) => {
                assert_eq!(location.line, line, "{text:?}: {message}");
                assert!(!message.contains('\n'), "one line: {message:?}");
            }
            other => panic!("expected a parse error for {text:?}, got {other:?}"),
        }
    }
}

#[test]
fn a_huge_integer_is_a_parse_error_not_a_panic() {
    assert!(matches!(
        Config::from_toml_str("[sim]\nseed = 99999999999999999999999"),
        Err(ConfigError::Parse { .. })
    ));
}
