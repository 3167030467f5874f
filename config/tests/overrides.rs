//! `path=value` overrides as a binary's `--set` would pass them.

use std::path::Path;

use config::sim::Pacing;
use config::{Config, ConfigError, Override, Preset};

fn o(text: &str) -> Override {
    text.parse().unwrap()
}

#[test]
fn overrides_replace_values_of_every_type_and_are_validated_with_the_file() {
    let c = Config::resolve(
        None,
        Preset::Sim,
        &[
            o("radar.address=10.0.0.2:6317"),
            o("sim.pacing=as-fast-as-possible"),
            o("sim.faults.stall_after_messages=10"),
            o("sim.faults.stall_ms=250"),
            o("filter.use_power_in_observation=false"),
            o("model.sigma_range_m = 0.5"),
            o("radar.tcp_keepalive_s=5"),
        ],
    )
    .unwrap();
    assert_eq!(c.radar.address, "10.0.0.2:6317".parse().unwrap());
    assert_eq!(c.sim.pacing, Pacing::AsFastAsPossible);
    let stall = c.sim.faults.stall.unwrap();
    assert_eq!(
        (stall.after_messages.get(), stall.duration.as_millis()),
        (10, 250)
    );
    assert!(!c.filter.use_power_in_observation);
    assert_eq!(c.model.sigma_range_m.get(), 0.5);
    assert_eq!(c.radar.tcp_keepalive.map(|d| d.as_secs()), Some(5));
}

#[test]
fn without_overrides_resolve_gives_the_preset_or_the_file() {
    assert_eq!(
        Config::resolve(None, Preset::Test, &[]).unwrap(),
        Config::preset(Preset::Test).unwrap()
    );
    let vehicle = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/vehicle.toml");
    assert_eq!(
        Config::resolve(Some(&vehicle), Preset::Sim, &[]).unwrap(),
        Config::preset(Preset::Vehicle).unwrap()
    );
}

#[test]
fn the_last_override_of_a_key_wins() {
    let c = Config::resolve(None, Preset::Sim, &[o("sim.seed=1"), o("sim.seed=7")]).unwrap();
    assert_eq!(c.sim.seed, 7);
}

#[test]
fn an_invalid_override_value_is_a_field_error() {
    let err = Config::resolve(None, Preset::Sim, &[o("filter.sigma_u=-1")]).unwrap_err();
    assert_eq!(
        err.to_string(),
        "config/examples/sim.toml: invalid settings: filter.sigma_u must be >= 0, got -1"
    );
}

#[test]
fn an_override_of_an_unknown_key_names_the_override() {
    for text in [
        "radar.adress=1.2.3.4:5",
        "radr.address=1.2.3.4:5",
        "sim.faults.stal_ms=3",
    ] {
        match Config::resolve(None, Preset::Sim, &[o(text)]) {
            Err(e @ ConfigError::Override { .. }) => {
                let shown = e.to_string();
                assert!(shown.starts_with(&format!("override `{text}`")), "{shown}");
                assert!(shown.contains("unknown field"), "{shown}");
            }
            other => panic!("{text}: expected an override error, got {other:?}"),
        }
    }
}

#[test]
fn an_override_of_the_wrong_type_names_the_override() {
    let err = Config::resolve(None, Preset::Sim, &[o("radar.tcp_nodelay=maybe")]).unwrap_err();
    assert!(matches!(err, ConfigError::Override { .. }), "{err}");
    assert!(err.to_string().contains("radar.tcp_nodelay"), "{err}");
}

#[test]
fn malformed_overrides_are_refused() {
    for text in [
        "radar.address",
        "=5",
        "radar..address=1",
        "radar.address x=1",
        "a.b.c.d.e.f.g.h.i=1",
        "sim.seed=1\nsim.pacing=\"realtime\"",
    ] {
        assert!(
            matches!(text.parse::<Override>(), Err(ConfigError::Override { .. })),
            "{text:?}"
        );
    }
}

#[test]
fn an_override_into_a_value_is_refused() {
    let err = Config::resolve(None, Preset::Sim, &[o("sim.seed.x=1")]).unwrap_err();
    assert!(
        err.to_string()
            .contains("`sim.seed` is a value, not a table"),
        "{err}"
    );
}

#[test]
fn a_quoted_override_value_is_a_string_and_a_table_value_is_parsed() {
    assert_eq!(o("sim.scene=\"yard\"").value().as_str(), Some("yard"));
    assert_eq!(o("sim.scene=yard").value().as_str(), Some("yard"));
    let c = Config::resolve(
        None,
        Preset::Sim,
        &[
            o("model.compensation=table"),
            o("model.compensation_table=[{ range_m = 1.0, gain_db = 0.0 }, { range_m = 9.0, gain_db = 40.0 }]"),
        ],
    )
    .unwrap();
    assert!(matches!(
        c.model.compensation,
        config::model::Compensation::Table(_)
    ));
}
