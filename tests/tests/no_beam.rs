//! A radar that gives the filter nothing for a while, with wheel odometry: the filter's
//! clock moved only when a beam took the odometry received up to its time, so rotations
//! with no beam for the filter left the pose where it was and published nothing new (a
//! straight road lined only with lamp posts: 18 beams in 561 rotations, 14 poses in 140 s).
//! Such a rotation's end is now reached with the odometry received.

use e2e_tests::on_the_lamp_post_road;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rotations_with_no_beam_still_move_the_pose_on_wheel_odometry() {
    let work = tempfile::tempdir().expect("a folder");
    let report = on_the_lamp_post_road(10.0, work.path()).await;
    let s = &report.run.summary;
    assert!(
        s.beams < s.rotations / 2,
        "the scene was meant to give the filter few beams: {} in {} rotations",
        s.beams,
        s.rotations
    );
    assert!(
        s.still_clock_caught_up + 5 >= s.rotations.saturating_sub(s.beams),
        "{} rotations caught up of {} rotations, {} beams",
        s.still_clock_caught_up,
        s.rotations,
        s.beams
    );
    // A pose a rotation, each later than the last.
    let times: Vec<f64> = std::fs::read_to_string(work.path().join("trajectory-online.tum"))
        .expect("the online trajectory")
        .lines()
        .filter(|l| !l.starts_with('#'))
        .filter_map(|l| l.split_whitespace().next()?.parse().ok())
        .collect();
    assert!(
        times.len() as u64 + 3 >= s.rotations,
        "{} poses in {} rotations",
        times.len(),
        s.rotations
    );
    assert!(
        times.windows(2).all(|w| w[1] > w[0]),
        "times not increasing"
    );
    // The pose follows the vehicle: 10 m/s for 10 s.
    let online = s.online.as_ref().expect("the online pose was scored");
    assert!(online.length_m > 80.0, "{} m driven", online.length_m);
    assert!(online.final_m < 10.0, "final error {} m", online.final_m);
}
