//! Every field that can hold an invalid value is rejected with its full dotted path, and
//! every such field in the reference file has a case here.

use std::collections::BTreeSet;

use config::{Config, ConfigError};

/// (TOML text, the dotted path the error must name, text the message must contain).
/// Each text has exactly one thing wrong with it.
const CASES: &[(&str, &str, &str)] = &[
    // [radar]
    ("[radar]\naddress = \"localhost\"", "radar.address", "must be an address `ip:port`"),
    ("[radar]\naddress = \"10.0.0.1:99999\"", "radar.address", "got \"10.0.0.1:99999\""),
    ("[radar]\nconnect_timeout_ms = 0", "radar.connect_timeout_ms", "must be > 0, got 0"),
    ("[radar]\nconnect_timeout_ms = -1", "radar.connect_timeout_ms", "must be > 0, got -1"),
    ("[radar]\nconnect_timeout_ms = 86400001", "radar.connect_timeout_ms", "must be in [1, 86400000] ms"),
    ("[radar]\ntcp_keepalive_s = 0.0", "radar.tcp_keepalive_s", "must be > 0, got 0"),
    ("[radar]\ntcp_keepalive_s = nan", "radar.tcp_keepalive_s", "must be a finite number, got NaN"),
    ("[radar]\ntcp_keepalive_s = 1e9", "radar.tcp_keepalive_s", "must be in (0, 86400] s"),
    ("[radar]\nrecv_buffer_bytes = 0", "radar.recv_buffer_bytes", "must be in [1, 268435456], got 0"),
    ("[radar]\nrecv_buffer_bytes = 268435457", "radar.recv_buffer_bytes", "got 268435457"),
    ("[radar]\nwatchdog_timeout_ms = -7000", "radar.watchdog_timeout_ms", "must be > 0, got -7000"),
    ("[radar]\nreconnect_initial_backoff_ms = 0", "radar.reconnect_initial_backoff_ms", "must be > 0"),
    ("[radar]\nreconnect_initial_backoff_ms = 6000", "radar.reconnect_initial_backoff_ms", "must be <= the maximum backoff (5000 ms), got 6000 ms"),
    ("[radar]\nreconnect_max_backoff_ms = 0", "radar.reconnect_max_backoff_ms", "must be > 0"),
    ("[radar]\nreconnect_jitter = 1.5", "radar.reconnect_jitter", "must be in [0, 1], got 1.5"),
    ("[radar]\nreconnect_jitter = -0.1", "radar.reconnect_jitter", "must be in [0, 1], got -0.1"),
    ("[radar]\nreconnect_max_attempts = -1", "radar.reconnect_max_attempts", "must be in [0, 4294967295], got -1"),
    ("[radar]\nreconnect_max_attempts = 4294967296", "radar.reconnect_max_attempts", "got 4294967296"),
    ("[radar]\nazimuth_channel_capacity = 0", "radar.azimuth_channel_capacity", "must be in [1, 1048576], got 0"),
    ("[radar]\nrotation_channel_capacity = 1048577", "radar.rotation_channel_capacity", "got 1048577"),
    ("[radar]\nrecord_path = \"\"", "radar.record_path", "must not be empty"),
    // [odometry]
    ("[odometry]\naddress = \"nowhere\"", "odometry.address", "must be an address"),
    ("[odometry]\nsource = \"none\"\naddress = \"127.0.0.1:0\"", "odometry.address", "is only used with odometry.source = \"tcp\""),
    ("[odometry]\nsource = \"file\"", "odometry.path", "is required with odometry.source = \"file\""),
    ("[odometry]\nsource = \"file\"\npath = \"\"", "odometry.path", "must not be empty"),
    ("[odometry]\npath = \"odo.txt\"", "odometry.path", "is only used with odometry.source = \"file\""),
    ("[odometry]\nsource = \"zenoh\"\ntopic = \"odom\"", "odometry.topic", "must be an absolute ROS 2 topic name"),
    ("[odometry]\nsource = \"zenoh\"\ntopic = \"/odom/\"", "odometry.topic", "got \"/odom/\""),
    ("[odometry]\nsource = \"zenoh\"\ntopic = \"/vehicle/2odom\"", "odometry.topic", "got \"/vehicle/2odom\""),
    ("[odometry]\ntopic = \"/odom\"", "odometry.topic", "is only used with odometry.source = \"zenoh\""),
    ("[odometry]\nmessage = \"nav_msgs/msg/Odometry\"", "odometry.message", "is only used with odometry.source = \"zenoh\""),
    ("[odometry]\nstep_s = 0.0", "odometry.step_s", "must be > 0, got 0"),
    ("[odometry]\nmotion_model = \"bicycle\"\nstep_s = 0.1", "odometry.step_s", "is only used with odometry.motion_model = \"paper\""),
    ("[odometry]\nmotion_model = \"bicycle\"\nwheelbase_m = -2.7", "odometry.wheelbase_m", "must be > 0, got -2.7"),
    ("[odometry]\nwheelbase_m = 2.7", "odometry.wheelbase_m", "is only used with odometry.motion_model = \"bicycle\""),
    ("[odometry]\nsigma_speed_mps = -0.1", "odometry.sigma_speed_mps", "must be >= 0, got -0.1"),
    ("[odometry]\nsigma_steer_rad = nan", "odometry.sigma_steer_rad", "must be a finite number"),
    ("[odometry]\nspeed_scale_std = 0.5", "odometry.speed_scale_std", "must be < 0.5"),
    ("[odometry]\nspeed_scale_std = -0.01", "odometry.speed_scale_std", "must be >= 0"),
    ("[odometry]\nradar_odometry_sigma_m = 0.0", "odometry.radar_odometry_sigma_m", "must be > 0, got 0"),
    ("[odometry]\nradar_odometry_sigma_rad = -0.003", "odometry.radar_odometry_sigma_rad", "must be > 0"),
    ("[odometry]\nradar_odometry_placement_share = 0.5", "odometry.radar_odometry_placement_share", "must be in [0, 0.45], got 0.5"),
    ("[odometry]\nradar_odometry_placement_share = -0.1", "odometry.radar_odometry_placement_share", "got -0.1"),
    ("[odometry]\nsteer_bias_std_rad = inf", "odometry.steer_bias_std_rad", "must be a finite number"),
    ("[odometry]\nspeed_scale_walk_per_sqrt_s = -1e-4", "odometry.speed_scale_walk_per_sqrt_s", "must be >= 0"),
    ("[odometry]\nsteer_bias_walk_rad_per_sqrt_s = nan", "odometry.steer_bias_walk_rad_per_sqrt_s", "must be a finite number"),
    ("[odometry]\nstale_after_ms = 0", "odometry.stale_after_ms", "must be > 0, got 0"),
    ("[odometry]\nmax_speed_mps = 0.0", "odometry.max_speed_mps", "must be > 0, got 0"),
    ("[odometry]\nmax_steer_rad = -1.0", "odometry.max_steer_rad", "must be > 0, got -1"),
    ("[odometry]\nmax_accel_mps2 = nan", "odometry.max_accel_mps2", "must be a finite number"),
    // [sim]
    ("[sim]\nbind = \"127.0.0.1\"", "sim.bind", "must be an address"),
    ("[sim]\nodometry_bind = \":6318\"", "sim.odometry_bind", "must be an address"),
    ("[sim]\nmax_clients = 0", "sim.max_clients", "must be in [1, 64], got 0"),
    ("[sim]\nmax_clients = 65", "sim.max_clients", "must be in [1, 64], got 65"),
    ("[sim]\nkeepalive_interval_ms = 0", "sim.keepalive_interval_ms", "must be > 0"),
    ("[sim]\nscene = \"\"", "sim.scene", "must not be empty"),
    ("[sim]\ndata_width = 12", "sim.data_width", "must be 8 or 16, got 12"),
    ("[sim]\nseed = -1", "sim.seed", "got -1"),
    ("[sim]\nodometry_rate_hz = 0.0", "sim.odometry_rate_hz", "must be > 0, got 0"),
    ("[sim]\nodometry_rate_hz = 2000.0", "sim.odometry_rate_hz", "must be in (0, 1000], got 2000"),
    ("[sim]\nsigma_speed_mps = -1.0", "sim.sigma_speed_mps", "must be >= 0, got -1"),
    ("[sim]\nsigma_steer_rad = -inf", "sim.sigma_steer_rad", "must be a finite number, got -inf"),
    ("[sim]\nbias_speed_mps = nan", "sim.bias_speed_mps", "must be a finite number"),
    ("[sim]\nbias_steer_rad = inf", "sim.bias_steer_rad", "must be a finite number, got inf"),
    ("[sim]\nground_truth_path = \"\"", "sim.ground_truth_path", "must not be empty"),
    // [sim.faults]
    ("[sim.faults]\ndrop_after_messages = 0", "sim.faults.drop_after_messages", "must be in [1, 9223372036854775807], got 0"),
    ("[sim.faults]\ncut_frame_at_message = -1", "sim.faults.cut_frame_at_message", "got -1"),
    ("[sim.faults]\ncorrupt_every_n = 0", "sim.faults.corrupt_every_n", "got 0"),
    ("[sim.faults]\nskip_azimuth_every_n = 0", "sim.faults.skip_azimuth_every_n", "got 0"),
    ("[sim.faults]\nstall_after_messages = 0\nstall_ms = 100", "sim.faults.stall_after_messages", "got 0"),
    ("[sim.faults]\nstall_after_messages = 10\nstall_ms = 0", "sim.faults.stall_ms", "must be > 0, got 0"),
    ("[sim.faults]\nstall_after_messages = 10", "sim.faults.stall_ms", "is required with sim.faults.stall_after_messages"),
    ("[sim.faults]\nstall_ms = 100", "sim.faults.stall_after_messages", "is required with sim.faults.stall_ms"),
    ("[sim.faults]\noversized_at_message = 0", "sim.faults.oversized_at_message", "got 0"),
    ("[sim.faults]\nnoise_burst_after_ms = 5", "sim.faults.noise_burst_ms", "is required"),
    ("[sim.faults]\nnoise_burst_ms = 5", "sim.faults.noise_burst_after_ms", "is required"),
    ("[sim.faults]\nnoise_burst_after_ms = 5\nnoise_burst_ms = 0", "sim.faults.noise_burst_ms", "0"),
    // [model]
    ("[model]\ncompensation_table = [{ range_m = 1.0, gain_db = 0.0 }, { range_m = 2.0, gain_db = 1.0 }]", "model.compensation_table", "is only used with model.compensation = \"table\""),
    ("[model]\ncompensation = \"table\"", "model.compensation_table", "is required with model.compensation = \"table\""),
    ("[model]\ncompensation = \"table\"\ncompensation_table = [{ range_m = 1.0, gain_db = 0.0 }]", "model.compensation_table", "must hold between 2 and 4096 points, got 1"),
    ("[model]\ncompensation = \"table\"\ncompensation_table = [{ range_m = 2.0, gain_db = 0.0 }, { range_m = 2.0, gain_db = 1.0 }]", "model.compensation_table", "ranges must increase strictly, got 2 m then 2 m"),
    ("[model]\ncompensation = \"table\"\ncompensation_table = [{ range_m = -1.0, gain_db = 0.0 }, { range_m = 2.0, gain_db = 1.0 }]", "model.compensation_table[0].range_m", "must be > 0, got -1"),
    ("[model]\ncompensation = \"table\"\ncompensation_table = [{ range_m = 1.0, gain_db = 0.0 }, { range_m = 2.0, gain_db = nan }]", "model.compensation_table[1].gain_db", "must be a finite number"),
    ("[model]\nbeam_width_deg = 0.0", "model.beam_width_deg", "must be > 0, got 0"),
    ("[model]\nbeam_width_deg = 360.0", "model.beam_width_deg", "must be in (0, 360), got 360"),
    ("[model]\nrange_resolution_m = 0.0", "model.range_resolution_m", "must be > 0"),
    ("[model]\nsigma_bearing_deg = -1.0", "model.sigma_bearing_deg", "must be > 0, got -1"),
    ("[model]\nrolloff_corner_m = 0.0", "model.rolloff_corner_m", "must be > 0, got 0"),
    ("[model]\nrolloff_order = 17", "model.rolloff_order", "must be in [0, 16], got 17"),
    ("[model]\ndoppler_range_coupling_s = 1.5", "model.doppler_range_coupling_s", "must be in [-1, 1], got 1.5"),
    ("[model]\ndoppler_range_coupling_s = nan", "model.doppler_range_coupling_s", "must be a finite number"),
    ("[model]\nrolloff_order = -1", "model.rolloff_order", "must be in [0, 16], got -1"),
    ("[model]\nnoise_floor_near_range_m = 0.0", "model.noise_floor_near_range_m", "must be > 0"),
    ("[model]\nsigma_range_m = 0.0", "model.sigma_range_m", "must be > 0, got 0"),
    ("[model]\nsigma_power_db = inf", "model.sigma_power_db", "must be a finite number"),
    ("[model]\nnoise_floor_near_mean_db = nan", "model.noise_floor_near_mean_db", "must be a finite number"),
    ("[model]\nnoise_floor_near_variance_db2 = 0.0", "model.noise_floor_near_variance_db2", "must be > 0"),
    ("[model]\nnoise_floor_transition_m = -45.0", "model.noise_floor_transition_m", "must be > 0"),
    ("[model]\nnoise_floor_near_range_m = 50.0", "model.noise_floor_near_range_m", "must be in (0, noise_floor_transition_m = 45), got 50"),
    ("[model]\nnoise_floor_weibull_scale = 0.0", "model.noise_floor_weibull_scale", "must be > 0"),
    ("[model]\nnoise_floor_weibull_shape = -5.333", "model.noise_floor_weibull_shape", "must be > 0"),
    // [detector]
    ("[detector]\nreference_cells = 0", "detector.reference_cells", "must be in [1, 4096], got 0"),
    ("[detector]\nreference_cells = 4097", "detector.reference_cells", "got 4097"),
    ("[detector]\nguard_cells = -1", "detector.guard_cells", "must be in [0, 4096], got -1"),
    ("[detector]\npfa = 0.0", "detector.pfa", "must be in (0, 1), got 0"),
    ("[detector]\npfa = 1.0", "detector.pfa", "must be in (0, 1), got 1"),
    ("[detector]\nthreshold_db = inf", "detector.threshold_db", "must be a finite number"),
    ("[detector]\npfa = 1e-3\nthreshold_db = 12.0", "detector.threshold_db", "cannot be set together with detector.pfa"),
    ("[detector]\nos_rank = 0", "detector.os_rank", "must be in [1, 70], got 0"),
    ("[detector]\nos_rank = 71", "detector.os_rank", "must be in [1, 70], got 71"),
    ("[detector]\ntpp_alpha = 0.0", "detector.tpp_alpha", "must be in (0, 1), got 0"),
    ("[detector]\ntpp_detect = 1.1", "detector.tpp_detect", "must be in [0, 1], got 1.1"),
    ("[detector]\nmax_targets_per_beam = 0", "detector.max_targets_per_beam", "must be in [1, 1024], got 0"),
    ("[detector]\nmax_state_mib = 0", "detector.max_state_mib", "must be in [1, 16384], got 0"),
    ("[detector]\nmin_range_m = -1.0", "detector.min_range_m", "must be >= 0, got -1"),
    ("[detector]\nmax_range_m = 0.0", "detector.max_range_m", "must be > 0, got 0"),
    ("[detector]\nmin_range_m = 50.0\nmax_range_m = 50.0", "detector.min_range_m", "must be < detector.max_range_m (50), got 50"),
    // [filter]
    ("[filter]\ninitial_x_m = nan", "filter.initial_x_m", "must be a finite number"),
    ("[filter]\ninitial_y_m = inf", "filter.initial_y_m", "must be a finite number"),
    ("[filter]\ninitial_theta_rad = nan", "filter.initial_theta_rad", "must be a finite number"),
    ("[filter]\ninitial_sigma_x_m = -1.0", "filter.initial_sigma_x_m", "must be >= 0, got -1"),
    ("[filter]\ninitial_sigma_y_m = -1.0", "filter.initial_sigma_y_m", "must be >= 0, got -1"),
    ("[filter]\ninitial_sigma_theta_rad = -0.1", "filter.initial_sigma_theta_rad", "must be >= 0, got -0.1"),
    ("[filter]\nsigma_u = -1.0", "filter.sigma_u", "must be >= 0, got -1"),
    ("[filter]\nsigma_v = nan", "filter.sigma_v", "must be a finite number"),
    ("[filter]\nsigma_wander_m = -0.1", "filter.sigma_wander_m", "must be >= 0, got -0.1"),
    ("[filter]\nsigma_wander_m = inf", "filter.sigma_wander_m", "must be a finite number"),
    ("[filter]\nwander_length_m = 0.0", "filter.wander_length_m", "must be > 0, got 0"),
    ("[filter]\ninitial_loss_db = -inf", "filter.initial_loss_db", "must be a finite number"),
    ("[filter]\ninitial_sigma_loss_db = 0.0", "filter.initial_sigma_loss_db", "must be > 0, got 0"),
    ("[filter]\ngate_probability = 1.0", "filter.gate_probability", "must be in (0, 1), got 1"),
    ("[filter]\ngate_chi2 = 0.0", "filter.gate_chi2", "must be > 0, got 0"),
    ("[filter]\ngate_probability = 0.95\ngate_chi2 = 7.81", "filter.gate_chi2", "cannot be set together with filter.gate_probability"),
    ("[filter]\nconfirm_after = 0", "filter.confirm_after", "must be in [1, 1000], got 0"),
    ("[filter]\nretire_after_misses = 1001", "filter.retire_after_misses", "must be in [1, 1000], got 1001"),
    ("[filter]\nretire_unseen_after_s = -1.0", "filter.retire_unseen_after_s", "must be >= 0, got -1"),
    ("[filter]\nretire_unrepeatable_below = 1.5", "filter.retire_unrepeatable_below", "[0, 1]"),
    ("[filter]\nretire_unrepeatable_below = nan", "filter.retire_unrepeatable_below", "finite"),
    ("[filter]\nrepeatability_min_rotations = 0", "filter.repeatability_min_rotations", "must be in [1, 1000], got 0"),
    ("[filter]\nmax_features = 0", "filter.max_features", "must be in [1, 100000], got 0"),
    ("[filter]\nrepeat_look_max_factor = 0.5", "filter.repeat_look_max_factor", "must be at least 1"),
    ("[filter]\nrepeat_look_max_factor = nan", "filter.repeat_look_max_factor", "got NaN"),
    ("[filter]\nmax_features = 100001", "filter.max_features", "got 100001"),
    ("[radar]\nmax_held_mib = 0", "radar.max_held_mib", "must be in [1, 16384], got 0"),
    ("[radar]\nmax_held_mib = 16385", "radar.max_held_mib", "got 16385"),
    ("[radar]\nmax_held_mib = 1\nazimuth_channel_capacity = 8192", "radar.max_held_mib", "must be at least twice the channels' slots"),
    ("[sim]\nwrite_timeout_ms = 0", "sim.write_timeout_ms", "must be > 0, got 0"),
    ("[sim]\nwrite_timeout_ms = 3600001", "sim.write_timeout_ms", "got 3600001"),
    ("[sim]\nidle_timeout_ms = -5", "sim.idle_timeout_ms", "must be > 0, got -5"),
    ("[sim]\nidle_timeout_ms = 86400001", "sim.idle_timeout_ms", "got 86400001"),
    // [output]
    ("[output]\ndirectory = \"\"", "output.directory", "must not be empty"),
    ("[output]\ntrajectory = \"\"", "output.trajectory", "must not be empty"),
    ("[output]\nmap = \"/etc/map.csv\"", "output.map", "must be a relative path inside output.directory"),
    ("[output]\ndiagnostics = \"../diagnostics.csv\"", "output.diagnostics", "must be a relative path inside output.directory"),
    ("[output]\nmcap = \"/tmp/run.mcap\"", "output.mcap", "must be a relative path inside output.directory"),
    ("[output]\nmcap = \"run.bag\"", "output.mcap", "must end in .mcap"),
    // [output.zenoh]
    ("[output.zenoh]\nconnect = [\"udp/127.0.0.1:7447\"]", "output.zenoh.connect", "only TCP is built in"),
    ("[output.zenoh]\nconnect = [\"tcp/127.0.0.1\"]", "output.zenoh.connect", "must be a Zenoh endpoint `tcp/host:port`"),
    ("[output.zenoh]\nmode = \"client\"\nconnect = []", "output.zenoh.connect", "must name at least one endpoint with output.zenoh.mode = \"client\""),
    ("[output.zenoh]\nlisten = [\"tcp/127.0.0.1:70000\"]", "output.zenoh.listen", "got \"tcp/127.0.0.1:70000\""),
    ("[output.zenoh]\nnamespace = \"/robot1\"", "output.zenoh.namespace", "no leading or trailing slash"),
    ("[output.zenoh]\nnamespace = \"robot/*\"", "output.zenoh.namespace", "no wildcards"),
    ("[output.zenoh]\nqueue = 0", "output.zenoh.queue", "must be in [1, 4096], got 0"),
    ("[output.zenoh]\ndomain_id = 233", "output.zenoh.domain_id", "must be a ROS 2 domain id from 0 to 232, got 233"),
    ("[output.zenoh]\ndomain_id = -1", "output.zenoh.domain_id", "got -1"),
    // [output.foxglove]
    ("[output.foxglove]\nbind = \"localhost:8765\"", "output.foxglove.bind", "must be an address `ip:port`"),
    ("[output.foxglove]\nqueue = 0", "output.foxglove.queue", "must be in [1, 65536], got 0"),
    ("[output.foxglove]\nbacklog = 5000", "output.foxglove.backlog", "must be in [1, 4096], got 5000"),
    ("[output.foxglove]\nmax_clients = 0", "output.foxglove.max_clients", "must be in [1, 64], got 0"),
    ("[output.foxglove]\nimage_size = 8", "output.foxglove.image_size", "must be in [16, 2048], got 8"),
    ("[output.foxglove]\nimage_range_m = 0", "output.foxglove.image_range_m", "must be in [1, 10000], got 0"),
    ("[output.foxglove]\nwait_for_subscriber_s = -1", "output.foxglove.wait_for_subscriber_s", "must be in [0, 3600], got -1"),
    // [submaps]
    ("[submaps]\nmax_distance_m = 0.0", "submaps.max_distance_m", "got 0"),
    ("[submaps]\nmax_distance_m = -5.0", "submaps.max_distance_m", "got -5"),
    ("[submaps]\nmax_features = 0", "submaps.max_features", "must be in [1, 5000], got 0"),
    ("[submaps]\nmax_features = 5001", "submaps.max_features", "must be in [1, 5000], got 5001"),
    ("[submaps]\nmax_features = 1", "submaps.max_features", "must be at least submaps.min_matches (6): a submap closed with fewer features can never be matched in a loop closure, got 1"),
    ("[submaps]\nmax_features = 9\nmin_matches = 10", "submaps.max_features", "must be at least submaps.min_matches (10)"),
    ("[submaps]\nmin_matches = 2", "submaps.min_matches", "must be at least 3"),
    ("[submaps]\nmin_matches = 0", "submaps.min_matches", "must be in [1, 1000], got 0"),
    ("[submaps]\nmax_rival_ratio = 1.0", "submaps.max_rival_ratio", "got 1"),
    ("[submaps]\nmax_rival_ratio = 0.0", "submaps.max_rival_ratio", "got 0"),
    ("[submaps]\nsearch_sigmas = 0.0", "submaps.search_sigmas", "got 0"),
    ("[submaps]\nnear_links = -1", "submaps.near_links", "must be in [0, 8], got -1"),
    ("[submaps]\nnear_links = 9", "submaps.near_links", "must be in [0, 8], got 9"),
    ("[submaps]\nnear_link_covariance_scale = 0.5", "submaps.near_link_covariance_scale", "must be at least 1 (a link surer than its own registration), got 0.5"),
    ("[submaps]\nnear_link_covariance_scale = 0.0", "submaps.near_link_covariance_scale", "got 0"),
    ("[submaps]\nscan_smear = 1.5", "submaps.scan_smear", "got 1.5"),
    ("[submaps]\nscan_smear = -0.1", "submaps.scan_smear", "got -0.1"),
    ("[submaps]\nnear_link_covariance_scale = nan", "submaps.near_link_covariance_scale", "got NaN"),
    ("[map]\npath = \"\"", "map.path", "empty"),
    ("[map]\npath = \"/tmp/map.slmap\"", "map.path", "must be a relative path inside output.directory"),
    ("[map]\nsave_every_s = 0.5", "map.save_every_s", "at least 1 s, got 0.5"),
    ("[map]\nsave_every_s = -1.0", "map.save_every_s", "got -1"),
    ("[map]\nfile = \"\"", "map.file", "empty"),
    ("[map]\ninitial_pose = [0.0, nan, 0.0]", "map.initial_pose", "three finite numbers"),
    ("[map]\ninitial_sigma = [1.0, 1.0, 0.0]", "map.initial_sigma", "finite numbers > 0"),
    ("[map]\ninitial_pose_topic = \"/initialpose\"", "map.initial_pose_topic", "only read when localising"),
    ("[map]\nmode = \"localise\"\ninitial_pose_topic = \"initialpose\"", "map.initial_pose_topic", "absolute ROS 2 topic"),
    // the learned front end and the radar's model
    ("[detector]\nfloor_sigma = 0.0", "detector.floor_sigma", "got 0"),
    ("[detector]\nfloor_min_snr_db = -1.0", "detector.floor_min_snr_db", "got -1"),
    ("[detector]\npoint_max_extent_m = 0.0", "detector.point_max_extent_m", "got 0"),
    ("[detector]\npoint_max_width_beams = -1.0", "detector.point_max_width_beams", "got -1"),
    ("[detector]\npoint_min_snr_db = -3.0", "detector.point_min_snr_db", "got -3"),
    ("[radar]\nmodel = \"cts 350\"", "radar.model", "must be a radar model's name"),
    ("[radar]\nmodel = \"\"", "radar.model", "must not be empty"),
    ("[odometry]\nradar_odometry_keyframes = 9", "odometry.radar_odometry_keyframes", "must be in [0, 8], got 9"),
    ("[odometry]\nradar_odometry_keyframes = -1", "odometry.radar_odometry_keyframes", "must be in [0, 8], got -1"),
    ("[odometry]\nradar_odometry_refine_runs = 5", "odometry.radar_odometry_refine_runs", "must be in [0, 4], got 5"),
    ("[odometry]\nradar_odometry_refine_runs = -1", "odometry.radar_odometry_refine_runs", "must be in [0, 4], got -1"),
    ("[odometry]\nradar_odometry_soft_kernel_m = 0.6", "odometry.radar_odometry_soft_kernel_m", "must be in [0, 0.5], got 0.6"),
    ("[odometry]\nradar_odometry_soft_kernel_m = -0.1", "odometry.radar_odometry_soft_kernel_m", "must be in [0, 0.5], got -0.1"),
    ("[odometry]\nradar_odometry_soft_kernel_m = nan", "odometry.radar_odometry_soft_kernel_m", "must be in [0, 0.5], got NaN"),
    ("[odometry]\nradar_odometry_keyframe_spacing_m = -1.0", "odometry.radar_odometry_keyframe_spacing_m", "got -1"),
    // the gyro of radar-only driving, and the simulator's
    ("[gyro]\nsource = \"tcp\"", "gyro.source", "only used when the radar drives the filter"),
    ("[gyro]\naddress = \"127.0.0.1:0\"", "gyro.address", "is only used with gyro.source = \"tcp\""),
    ("[gyro]\npath = \"g.txt\"", "gyro.path", "is only used with gyro.source = \"file\""),
    ("[gyro]\nnoise_density_rad_s_per_sqrt_hz = -1.0", "gyro.noise_density_rad_s_per_sqrt_hz", "got -1"),
    ("[gyro]\nbias_std_rad_s = -1.0", "gyro.bias_std_rad_s", "got -1"),
    ("[gyro]\nbias_walk_rad_s_per_sqrt_s = -1.0", "gyro.bias_walk_rad_s_per_sqrt_s", "got -1"),
    ("[gyro]\nmax_yaw_rate_rad_s = 0.0", "gyro.max_yaw_rate_rad_s", "got 0"),
    ("[sim.gyro]\nbind = \":6319\"", "sim.gyro.bind", "must be an address"),
    ("[sim.gyro]\nrate_hz = 2000.0", "sim.gyro.rate_hz", "must be in (0, 1000], got 2000"),
    ("[sim.gyro]\nnoise_density_rad_s_per_sqrt_hz = -1.0", "sim.gyro.noise_density_rad_s_per_sqrt_hz", "got -1"),
    ("[sim.gyro]\nbias_rad_s = inf", "sim.gyro.bias_rad_s", "must be a finite number, got inf"),
];

/// Keys whose every parseable value is valid (booleans and choices; a misspelt choice is a
/// parse error, tested in `unknown_keys.rs`).
const ALWAYS_VALID_WHEN_PARSED: &[&str] = &[
    "submaps.enabled",
    "submaps.place_recognition",
    "submaps.scan_loop_closure",
    "submaps.loop_closure",
    "map.save",
    "map.mode",
    "map.localise_with",
    "radar.tcp_nodelay",
    "radar.non_contoured",
    "radar.drop_policy",
    "odometry.source",
    "odometry.motion_model",
    "odometry.radar_odometry",
    "odometry.radar_odometry_compose",
    "odometry.radar_odometry_place_held",
    "odometry.radar_odometry_probe_start",
    "odometry.speed_scale_from_landmarks",
    "odometry.steer_bias_from_landmarks",
    "detector.points_only",
    "detector.extended_reobserve",
    "sim.pacing",
    "sim.radar_preset",
    "sim.faults.no_keepalive",
    "model.spreading",
    "model.compensation",
    "detector.kind",
    "filter.association",
    "filter.use_power_in_observation",
    "filter.first_estimate_jacobians",
    "filter.repeat_look_decorrelation",
    "output.pictures",
    "output.progress",
    "output.spectra",
    "output.ground_truth",
    "output.zenoh.enabled",
    "output.zenoh.mode",
    "output.zenoh.multicast_scouting",
    "output.zenoh.convention",
    "output.foxglove.enabled",
    "output.view.enabled",
];

#[test]
fn each_invalid_field_is_rejected_with_its_dotted_path_and_reason() {
    for (text, path, reason) in CASES {
        let err = match Config::from_toml_str(text) {
            Err(err) => err,
            Ok(_) => panic!("accepted:\n{text}"),
        };
        let errors = err.field_errors();
        assert_eq!(errors.len(), 1, "one error expected for\n{text}\ngot {err}");
        let e = &errors[0];
        assert_eq!(e.path, *path, "for\n{text}");
        let shown = e.to_string();
        assert!(shown.starts_with(&format!("{path} ")), "{shown}");
        assert!(shown.contains(reason), "{shown:?} lacks {reason:?}");
        assert!(err.to_string().contains(&shown), "{err}");
    }
}

#[test]
fn every_field_of_the_reference_file_has_a_rejection_case_or_cannot_be_invalid() {
    // Every key written (or commented out) in the sim example, with its table.
    let mut keys = BTreeSet::new();
    let mut table = String::new();
    for line in config::examples::SIM.lines() {
        let line = line.trim().trim_start_matches('#').trim();
        if let Some(header) = line.strip_prefix('[') {
            table = header.split(']').next().unwrap_or("").to_owned();
        } else if let Some((key, _)) = line.split_once('=') {
            let key = key.trim();
            if !key.is_empty()
                && key
                    .chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
            {
                keys.insert(format!("{table}.{key}"));
            }
        }
    }
    assert!(
        keys.len() > 90,
        "the reference file lists every key: {keys:?}"
    );
    let covered: BTreeSet<String> = CASES
        .iter()
        .map(|(_, path, _)| path.split('[').next().unwrap_or(path).to_owned())
        .chain(ALWAYS_VALID_WHEN_PARSED.iter().map(|k| k.to_string()))
        .collect();
    let missing: Vec<_> = keys.difference(&covered).collect();
    assert!(missing.is_empty(), "no rejection case for {missing:?}");
}

#[test]
fn all_invalid_fields_are_reported_together() {
    let text = "[radar]\nreconnect_jitter = 2.0\n[filter]\nsigma_u = -1.0\nmax_features = 0\n";
    let err = Config::from_toml_str(text).unwrap_err();
    let paths: Vec<_> = err.field_errors().iter().map(|e| e.path.as_str()).collect();
    assert_eq!(
        paths,
        [
            "radar.reconnect_jitter",
            "filter.sigma_u",
            "filter.max_features"
        ]
    );
    assert_eq!(
        err.to_string(),
        "<string>: invalid settings: radar.reconnect_jitter must be in [0, 1], got 2; \
         filter.sigma_u must be >= 0, got -1; filter.max_features must be in [1, 100000], got 0"
    );
}

#[test]
fn a_section_can_be_validated_alone() {
    let raw = config::RawFilter {
        sigma_u: -1.0,
        ..Default::default()
    };
    let errors = raw.validate().unwrap_err();
    assert_eq!(
        errors.for_path("filter.sigma_u").map(ToString::to_string),
        Some("filter.sigma_u must be >= 0, got -1".to_owned())
    );
    assert!(config::RawRadar::default().validate().is_ok());
}

#[test]
fn a_validation_error_is_a_typed_variant() {
    assert!(matches!(
        Config::from_toml_str("[sim]\nmax_clients = 0"),
        Err(ConfigError::Invalid { .. })
    ));
}

#[test]
fn a_mistake_in_one_field_of_a_cross_field_rule_is_reported_once() {
    for (text, path) in [
        ("[detector]\nmax_range_m = 0.0", "detector.max_range_m"),
        (
            "[detector]\nmin_range_m = nan\nmax_range_m = 0.5",
            "detector.min_range_m",
        ),
        (
            "[detector]\nreference_cells = 0\nos_rank = 60",
            "detector.reference_cells",
        ),
        (
            "[radar]\nreconnect_max_backoff_ms = 0",
            "radar.reconnect_max_backoff_ms",
        ),
        (
            "[radar]\nreconnect_initial_backoff_ms = -5",
            "radar.reconnect_initial_backoff_ms",
        ),
    ] {
        let err = Config::from_toml_str(text).unwrap_err();
        let paths: Vec<_> = err.field_errors().iter().map(|e| e.path.as_str()).collect();
        assert_eq!(paths, [path], "{err}");
    }
}
