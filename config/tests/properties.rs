//! Property tests: the value types accept exactly their domains, and no input text, however
//! malformed, makes loading panic.

use config::values::{self, Capacity, NonNegativeF64, OpenProbability, PositiveF64, Probability};
use config::{Config, ConfigError};
use proptest::prelude::*;

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>(),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(0.0),
        Just(-0.0),
        Just(1.0),
        -2.0..2.0f64,
    ]
}

proptest! {
    #[test]
    fn positive_accepts_exactly_finite_values_above_zero(x in any_f64()) {
        prop_assert_eq!(PositiveF64::new(x).is_ok(), x.is_finite() && x > 0.0);
    }

    #[test]
    fn non_negative_accepts_exactly_finite_values_from_zero(x in any_f64()) {
        let v = NonNegativeF64::new(x);
        prop_assert_eq!(v.is_ok(), x.is_finite() && x >= 0.0);
        if let Ok(v) = v {
            prop_assert!(v.get().is_sign_positive(), "no negative zero");
        }
    }

    #[test]
    fn probability_accepts_exactly_the_closed_unit_interval(x in any_f64()) {
        prop_assert_eq!(Probability::new(x).is_ok(), (0.0..=1.0).contains(&x));
    }

    #[test]
    fn open_probability_excludes_zero_and_one(x in any_f64()) {
        prop_assert_eq!(OpenProbability::new(x).is_ok(), x > 0.0 && x < 1.0);
    }

    #[test]
    fn capacity_accepts_exactly_one_to_its_bound(n in any::<i64>(), max in 1usize..1_000_000) {
        let ok = n >= 1 && (n as i128) <= max as i128;
        let c = Capacity::new(n, max);
        prop_assert_eq!(c.is_ok(), ok);
        if let Ok(c) = c {
            prop_assert_eq!(c.get() as i64, n);
        }
    }

    #[test]
    fn durations_come_from_positive_milliseconds_up_to_a_day(ms in any::<i64>()) {
        let d = values::duration_from_ms(ms);
        prop_assert_eq!(d.is_ok(), (1..=86_400_000).contains(&ms));
        if let Ok(d) = d {
            prop_assert_eq!(d.as_millis() as i64, ms);
        }
    }

    #[test]
    fn any_text_is_loaded_or_refused_without_panicking(text in ".{0,200}") {
        let _ = Config::from_toml_str(&text);
    }

    #[test]
    fn any_bytes_in_a_section_are_loaded_or_refused_without_panicking(
        section in prop::sample::select(vec!["radar", "odometry", "sim", "sim.faults", "model", "detector", "filter", "output"]),
        body in "[a-z_ =\"0-9.\\-\\[\\]{},\n]{0,120}",
    ) {
        let _ = Config::from_toml_str(&format!("[{section}]\n{body}"));
    }

    #[test]
    fn any_number_for_a_numeric_field_is_accepted_or_rejected_by_name(
        field in prop::sample::select(vec![
            ("radar", "reconnect_jitter"), ("radar", "tcp_keepalive_s"),
            ("odometry", "sigma_speed_mps"), ("odometry", "step_s"),
            ("sim", "odometry_rate_hz"), ("sim", "bias_steer_rad"),
            ("model", "beam_width_deg"), ("model", "sigma_power_db"),
            ("detector", "pfa"), ("detector", "tpp_alpha"), ("detector", "max_range_m"),
            ("filter", "gate_probability"), ("filter", "initial_sigma_loss_db"), ("filter", "initial_theta_rad"),
        ]),
        x in any_f64(),
    ) {
        let (section, key) = field;
        let literal = if x.is_nan() { "nan".to_owned() } else if x.is_infinite() { if x > 0.0 { "inf".into() } else { "-inf".into() } } else { format!("{x:?}") };
        match Config::from_toml_str(&format!("[{section}]\n{key} = {literal}\n")) {
            Ok(_) => {}
            Err(ConfigError::Invalid { errors, .. }) => {
                // The field itself, or a rule across fields whose message names it.
                let path = format!("{section}.{key}");
                prop_assert!(
                    errors.as_slice().iter().all(|e| e.path == path || e.to_string().contains(&path)),
                    "{}", errors
                );
                prop_assert!(errors.to_string().len() < 400, "short messages: {}", errors);
            }
            Err(other) => prop_assert!(false, "unexpected {other}"),
        }
    }

    #[test]
    fn any_integer_for_a_count_is_accepted_or_rejected_by_name(
        field in prop::sample::select(vec![
            ("radar", "connect_timeout_ms"), ("radar", "recv_buffer_bytes"), ("radar", "reconnect_max_attempts"),
            ("sim", "max_clients"), ("sim", "data_width"), ("sim", "seed"),
            ("sim.faults", "corrupt_every_n"), ("detector", "reference_cells"), ("detector", "os_rank"),
            ("filter", "max_features"),
        ]),
        n in any::<i64>(),
    ) {
        let (section, key) = field;
        match Config::from_toml_str(&format!("[{section}]\n{key} = {n}\n")) {
            Ok(_) => {}
            Err(ConfigError::Invalid { errors, .. }) => {
                let path = format!("{section}.{key}");
                prop_assert!(
                    errors.as_slice().iter().all(|e| e.path == path || e.to_string().contains(&path)),
                    "{}", errors
                );
            }
            Err(other) => prop_assert!(false, "unexpected {other}"),
        }
    }
}
