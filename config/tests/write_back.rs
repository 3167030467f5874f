//! Settings written back out as TOML load back to the same settings.

use config::{Config, Preset, RawConfig};
use proptest::prelude::*;

fn round_trip(c: &Config) -> Config {
    let text = c.to_toml_string().unwrap();
    match Config::from_toml_str(&text) {
        Ok(again) => again,
        Err(e) => panic!("{e}\n{text}"),
    }
}

const EVERY_ALTERNATIVE: &str = r#"
[radar]
tcp_keepalive_s = 2.5
reconnect_max_attempts = 7
non_contoured = true
drop_policy = "drop-oldest"
record_path = "rec.colossus"
[odometry]
source = "file"
path = "odo.txt"
motion_model = "bicycle"
wheelbase_m = 3.1
[sim]
scene = "./yard"
radar_preset = "cts350x-400"
data_width = 16
seed = 9223372036854775807
ground_truth_path = "gt.csv"
[sim.faults]
drop_after_messages = 1
cut_frame_at_message = 2
corrupt_every_n = 3
skip_azimuth_every_n = 4
stall_after_messages = 5
stall_ms = 6
no_keepalive = true
oversized_at_message = 7
noise_burst_after_ms = 8
noise_burst_ms = 9
[model]
spreading = "textbook"
compensation = "table"
compensation_table = [{ range_m = 0.5, gain_db = -3.25 }, { range_m = 150.0, gain_db = 99.5 }]
rolloff_order = 0
[detector]
kind = "os-cfar"
threshold_db = 13.5
os_rank = 9
min_range_m = 0.0
[filter]
initial_theta_rad = -2.0
gate_chi2 = 7.81
association = "jcbb"
use_power_in_observation = false
first_estimate_jacobians = false
repeat_look_decorrelation = false
[output]
directory = "/tmp/run"
map = "maps/map.csv"
"#;

#[test]
fn every_preset_written_back_loads_to_the_same_settings() {
    for preset in [Preset::Vehicle, Preset::Sim, Preset::Test] {
        let c = Config::preset(preset).unwrap();
        assert_eq!(round_trip(&c), c, "{preset:?}");
    }
}

#[test]
fn every_alternative_written_back_loads_to_the_same_settings() {
    let c = Config::from_toml_str(EVERY_ALTERNATIVE).unwrap();
    assert_eq!(round_trip(&c), c);
    assert_eq!(RawConfig::from(&c).validate().unwrap(), c);
}

#[test]
fn a_scene_file_that_looks_like_a_name_is_written_as_a_path() {
    let mut c = Config::default();
    c.sim.scene = config::sim::SceneRef::File("yard".into());
    assert_eq!(
        round_trip(&c).sim.scene,
        config::sim::SceneRef::File("./yard".into())
    );
}

proptest! {
    #[test]
    fn any_valid_numbers_survive_being_written_back(
        jitter in 0.0..=1.0f64,
        keepalive_s in 0.001..1000.0f64,
        timeout_ms in 1i64..86_400_000,
        sigma in 0.0..1e3f64,
        positive in 1e-9..1e6f64,
        finite in -1e12..1e12f64,
        p in 1e-12..0.999_999f64,
        cells in 1i64..4096,
        theta in -1e3..1e3f64,
    ) {
        let text = format!(
            "[radar]\nreconnect_jitter = {jitter:?}\ntcp_keepalive_s = {keepalive_s:?}\nconnect_timeout_ms = {timeout_ms}\n\
             [odometry]\nsigma_steer_rad = {sigma:?}\nstep_s = {positive:?}\n\
             [sim]\nbias_speed_mps = {finite:?}\n\
             [model]\nsigma_power_db = {positive:?}\nnoise_floor_near_mean_db = {finite:?}\n\
             [detector]\npfa = {p:?}\nreference_cells = {cells}\n\
             [filter]\ngate_probability = {p:?}\ninitial_theta_rad = {theta:?}\ninitial_x_m = {finite:?}\n"
        );
        let c = Config::from_toml_str(&text).unwrap();
        prop_assert_eq!(round_trip(&c), c);
    }
}
