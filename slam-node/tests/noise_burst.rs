//! A noise burst through the daemon's pipeline (issue 38, item 11): a parked radar looking
//! at four reflectors, every bin of every azimuth random for 6 s (a swamped receiver). The
//! filter's burst guard learned the burst as its norm within about 3 s; then the noise
//! started features until the map was full (1000), re-observed the reflectors from inside
//! their gates and missed them until they were retired, and the parked vehicle's heading
//! ended 38 degrees off for the rest of the run, the map re-made around it.

mod support;

use rand::{Rng, SeedableRng};
use slam_node::pipeline::Pipeline;
use support::{assert_reflectors_mapped, still, still_radar_azimuths, still_radar_settings};

/// Unix time of the first azimuth, nanoseconds.
const T0_NS: u64 = 1_700_000_000_000_000_000;
/// The burst, seconds after the start.
const BURST: (f64, f64) = (6.0, 12.0);

#[test]
fn six_seconds_of_noise_leave_the_map_and_the_parked_vehicle_as_they_were() {
    let t0 = T0_NS as f64 * 1e-9;
    let mut azimuths = still_radar_azimuths(50, T0_NS); // 20 s
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    for az in &mut azimuths {
        if (BURST.0..BURST.1).contains(&(az.timestamp_s - t0)) {
            let noise: Vec<u8> = (0..az.bins.len()).map(|_| rng.gen()).collect();
            az.bins = noise.into();
        }
    }
    let settings = still_radar_settings();
    let limit = settings.filter.max_features;
    let mut p = Pipeline::new(settings, None, None).expect("the pipeline");
    let mut events = Vec::new();
    let mut next_odometry = t0;
    // (time after the start, heading in degrees, features)
    let mut track = Vec::new();
    for az in &azimuths {
        while next_odometry <= az.timestamp_s + 0.1 {
            p.push_odometry(still(next_odometry));
            next_odometry += 0.05;
        }
        p.process_azimuth(az, &mut events).expect("processed");
        events.clear();
        let ekf = p.ekf();
        track.push((
            az.timestamp_s - t0,
            ekf.pose().theta.to_degrees(),
            ekf.feature_count(),
        ));
    }
    let summary = p.finish(&mut events);
    // Counted in the summary (and warned about while it lasts).
    assert!(summary.burst_beams > 1000, "{}", summary.burst_beams);
    let most = track.iter().map(|t| t.2).max().unwrap_or(0);
    assert!(most <= 8, "the map grew to {most} features (limit {limit})");
    // The reflectors stayed mapped through the burst (a parked radar's map churns: one of
    // the four may be between retirement and re-mapping).
    let fewest_in_burst = track
        .iter()
        .filter(|t| t.0 > BURST.0 + 1.0 && t.0 < BURST.1)
        .map(|t| t.2)
        .min()
        .unwrap_or(0);
    assert!(
        fewest_in_burst >= 3,
        "{fewest_in_burst} features left in the burst"
    );
    let worst_heading = track
        .iter()
        .filter(|t| t.0 > BURST.0)
        .map(|t| t.1.abs())
        .fold(0.0, f64::max);
    assert!(
        worst_heading < 3.0,
        "heading off by up to {worst_heading:.1} degrees"
    );
    assert_reflectors_mapped(p.ekf());
    let features = p.ekf().features();
    assert!(
        features.len() <= 6,
        "{} features for 4 reflectors",
        features.len()
    );
}
