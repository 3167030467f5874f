//! The evaluation measures the pipeline the daemon runs: the settings it runs the daemon's
//! pipeline with are the daemon's own, except for the two things it sets on purpose (the
//! filter's odometry noise matched to the simulator's odometry, a small initial pose
//! uncertainty). If the daemon's settings change and the evaluation's do not follow, this
//! fails.

use evaluation::daemon::{scene_settings, shipped_settings};
use evaluation::run::Mode;
use evaluation::world::World;
use sim_sensor::scene::shipped;
use sim_sensor::OdometryNoise;
use slam_node::daemon::embedded::embedded_settings;
use slam_node::pipeline::{PipelineSettings, SettingsRecipe};

fn daemon_settings() -> PipelineSettings {
    PipelineSettings::from_config(&config::Config::default()).unwrap()
}

#[test]
fn the_evaluation_starts_from_the_daemons_shipped_settings() {
    assert_eq!(shipped_settings().unwrap(), daemon_settings());
    let Mode::Daemon(mode) = evaluation::sections::shipped_daemon().unwrap() else {
        panic!("the shipped daemon mode is not the daemon's pipeline");
    };
    assert_eq!(*mode, daemon_settings());
}

#[test]
fn on_every_shipped_scene_the_evaluation_runs_the_daemons_front_end_and_filter_settings() {
    let odometry = OdometryNoise::default();
    for name in shipped::NAMES {
        let scene = shipped::load(name).unwrap();
        let world = World::new(scene.clone(), 1, 1.0, odometry).unwrap();
        let recipe = SettingsRecipe::from_config(config::Config::default());
        let daemon = embedded_settings(&recipe, &scene, false).unwrap().settings;
        let eval = scene_settings(shipped_settings().unwrap(), &scene, &world, &odometry);
        assert_eq!(eval.front_end(), daemon.front_end(), "{name}: front end");
        assert_eq!(eval.power, daemon.power, "{name}: power model");
        assert_eq!(eval.noise, daemon.noise, "{name}: noise model");
        assert_eq!(eval.motion, daemon.motion, "{name}: motion model");
        assert_eq!(eval.initial_pose, daemon.initial_pose, "{name}: start pose");
        // The filter: the daemon's, but for the odometry noise matched to the simulator's.
        let mut filter = eval.filter.clone();
        filter.speed_std_mps = daemon.filter.speed_std_mps;
        filter.steer_std_rad = daemon.filter.steer_std_rad;
        filter.input_noise_correlation_s = daemon.filter.input_noise_correlation_s;
        assert_eq!(filter, daemon.filter, "{name}: filter");
        let mut rest = eval.clone();
        rest.filter = daemon.filter.clone();
        rest.initial_pose_std = daemon.initial_pose_std;
        // The radar profile's name recorded in a saved map: the daemon's is the scene's
        // profile; the evaluation writes no map.
        rest.map_save = daemon.map_save.clone();
        assert_eq!(rest, daemon, "{name}: anything else");
    }
}
