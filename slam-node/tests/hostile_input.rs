//! Input a real radar, an odometry bridge or a clock can produce, through the pipeline (no
//! sockets): each case costs what it must and the daemon goes back to mapping.
//!
//! - one far-future azimuth timestamp: that azimuth only (it used to stop SLAM for good);
//! - one far-future odometry record: that record only (every later record used to be "out
//!   of order", so the map stopped);
//! - absurd but finite odometry: refused at the gate (the pose used to go to 1e199 m);
//! - an odometry gap past the filter's limit: bridged (every later sample used to fail),
//!   and the pose relocalised where it is before a beam is used again.

mod support;

use support::{still, still_radar_settings as settings};

use radar_driver::Azimuth;
use slam_filter::OdometrySample;
use slam_node::pipeline::{Pipeline, PipelineSummary};

const T0_NS: u64 = 1_700_000_000_000_000_000;
const T0: f64 = 1.7e9;
/// 2100-01-01 in Unix seconds.
const YEAR_2100_S: f64 = 4_102_444_800.0;

/// Runs `azimuths` with odometry every 50 ms up to each azimuth's true time `clock[i]`,
/// letting `odometry` change the k-th record; returns the summary and the pipeline.
fn run(
    azimuths: &[Azimuth],
    clock: &[f64],
    mut odometry: impl FnMut(usize, OdometrySample) -> OdometrySample,
) -> (PipelineSummary, Pipeline) {
    let mut p = Pipeline::new(settings(), Some(T0), None).unwrap();
    let mut events = Vec::new();
    let mut next_odo = T0;
    let mut k = 0;
    for (az, &now) in azimuths.iter().zip(clock) {
        while next_odo <= now {
            p.push_odometry(odometry(k, still(next_odo)));
            k += 1;
            next_odo += 0.05;
        }
        p.process_azimuth(az, &mut events).unwrap();
        events.clear();
    }
    let s = p.finish(&mut events);
    (s, p)
}

#[test]
fn one_far_future_azimuth_timestamp_costs_that_azimuth_only() {
    let mut az = support::still_radar_azimuths(10, T0_NS);
    let clock: Vec<f64> = az.iter().map(|a| a.timestamp_s).collect();
    let n = az.len();
    let (baseline, b) = run(&az, &clock, |_, o| o);
    az[n / 3].timestamp_s = YEAR_2100_S;
    let (s, p) = run(&az, &clock, |_, o| o);
    assert_eq!(s.clock_outliers, 1);
    assert_eq!(s.bad_azimuths, 1);
    assert_eq!(s.azimuths, baseline.azimuths - 1);
    assert!(
        s.beams + 5 >= baseline.beams,
        "beams {} against {} without the wild stamp",
        s.beams,
        baseline.beams
    );
    assert_eq!(p.ekf().feature_count(), b.ekf().feature_count());
    assert!(p.ekf().state().time_s() < T0 + 10.0);
}

#[test]
fn one_far_future_odometry_record_costs_that_record_only() {
    let az = support::still_radar_azimuths(10, T0_NS);
    let clock: Vec<f64> = az.iter().map(|a| a.timestamp_s).collect();
    let (_, b) = run(&az, &clock, |_, o| o);
    let (s, p) = run(&az, &clock, |k, o| {
        if k == 20 {
            OdometrySample {
                timestamp_s: YEAR_2100_S,
                ..o
            }
        } else {
            o
        }
    });
    assert_eq!(s.odometry_refused, 1);
    assert_eq!(s.refused.stale_odometry, 0, "odometry kept flowing");
    assert_eq!(p.ekf().feature_count(), b.ekf().feature_count());
}

#[test]
fn absurd_but_finite_odometry_is_refused_at_the_gate() {
    let az = support::still_radar_azimuths(10, T0_NS);
    let clock: Vec<f64> = az.iter().map(|a| a.timestamp_s).collect();
    let (_, b) = run(&az, &clock, |_, o| o);
    let (s, p) = run(&az, &clock, |k, o| match k {
        30 => OdometrySample {
            speed_mps: 1e199,
            ..o
        },
        31 => OdometrySample {
            steer_rad: 1e100,
            ..o
        },
        32 => OdometrySample {
            steer_rad: 1000.0,
            ..o
        },
        _ => o,
    });
    assert_eq!(s.odometry_refused, 3);
    let pose = p.ekf().pose();
    assert!(
        pose.x.abs() < 0.5 && pose.y.abs() < 0.5,
        "pose ({}, {})",
        pose.x,
        pose.y
    );
    assert_eq!(p.ekf().feature_count(), b.ekf().feature_count());
}

#[test]
fn a_confirmed_radar_clock_jump_resynchronises_and_mapping_resumes() {
    let mut az = support::still_radar_azimuths(12, T0_NS);
    let n = az.len();
    // From a third of the way on, the radar's clock is an hour ahead (it was set).
    for a in az.iter_mut().skip(n / 3) {
        a.timestamp_s += 3600.0;
    }
    let clock: Vec<f64> = az.iter().map(|a| a.timestamp_s).collect();
    let (s, p) = run(&az, &clock, |_, o| o);
    assert_eq!(s.clock_jumps, 1);
    assert!(s.clock_outliers <= 16, "outliers {}", s.clock_outliers);
    // The odometry (generated against the radar's stamps here) follows the jump: beams
    // are taken again on the new clock.
    assert!(p.ekf().state().time_s() > T0 + 3600.0);
    assert!(p.ekf().feature_count() >= 4);
}

/// Issue 38 (Low): the summary's stream time is summed over the radar's clocks. Before, a
/// clock that jumped back an hour made it read "0.0 s of stream", and one that jumped
/// ahead an hour read an hour more than was streamed.
#[test]
fn the_stream_time_is_what_was_streamed_whichever_way_the_radar_clock_jumps() {
    for jump_s in [-3600.0, 3600.0] {
        let mut az = support::still_radar_azimuths(12, T0_NS);
        let n = az.len();
        let streamed_s = az[n - 1].timestamp_s - az[0].timestamp_s;
        for a in az.iter_mut().skip(n / 3) {
            a.timestamp_s += jump_s;
        }
        let clock: Vec<f64> = az.iter().map(|a| a.timestamp_s).collect();
        let (s, _) = run(&az, &clock, |_, o| o);
        assert_eq!(s.clock_jumps, 1, "jump {jump_s} s");
        // Less only the azimuths taken for outliers before the jump was confirmed.
        assert!(
            s.stream_s() <= streamed_s && s.stream_s() > streamed_s - 1.0,
            "jump {jump_s} s: {} s of stream, {streamed_s} s streamed",
            s.stream_s()
        );
    }
}

#[test]
fn contoured_azimuths_are_not_taken_for_empty_range() {
    let all = support::still_radar_azimuths(30, T0_NS);
    let per_rotation = all.len() / 30;
    let clock: Vec<f64> = all.iter().map(|a| a.timestamp_s).collect();
    // Ten whole rotations, then twenty (8 s) cut by a contour to their first 50 bins
    // (12.5 m): the reflector 11 m out is still seen (the filter's clock goes on), the three
    // 14 to 25 m out are beyond what the radar now looks at.
    let mut cut = all.clone();
    for a in cut.iter_mut().skip(10 * per_rotation) {
        a.bins = a.bins.slice(..50);
    }
    let (_, whole) = run(
        &all[..10 * per_rotation],
        &clock[..10 * per_rotation],
        |_, o| o,
    );
    let mapped = whole.ekf().feature_count();
    assert!(mapped >= 4, "{mapped} features mapped");
    let (s, p) = run(&cut, &clock, |_, o| o);
    assert_eq!(
        p.ekf().feature_count(),
        mapped,
        "features beyond the contour were retired as unseen ({} retired)",
        p.ekf().stats().retired
    );
    assert_eq!(s.filter_errors, 0);
}

#[test]
fn a_parked_vehicle_stays_put_across_two_odometry_gaps() {
    // Odometry stops for 6 s twice (past the filter's 5 s limit) while the radar goes on:
    // each gap is bridged and the pose relocalised where it is.
    let az = support::still_radar_azimuths(70, T0_NS);
    let gaps = [(T0 + 4.0, T0 + 10.0), (T0 + 14.0, T0 + 20.0)];
    let mut p = Pipeline::new(settings(), Some(T0), None).unwrap();
    let mut events = Vec::new();
    let mut next_odo = T0;
    let mut worst = 0.0f64;
    for a in &az {
        while next_odo <= a.timestamp_s {
            if !gaps.iter().any(|&(s, e)| next_odo > s && next_odo < e) {
                p.push_odometry(still(next_odo));
            }
            next_odo += 0.05;
        }
        p.process_azimuth(a, &mut events).unwrap();
        events.clear();
        let pose = p.ekf().pose();
        worst = worst.max(pose.x.hypot(pose.y));
    }
    p.finish(&mut events);
    let stats = p.ekf().stats();
    assert_eq!(stats.bridged_gaps, 2);
    assert_eq!(stats.relocalisations, 2, "{stats:?}");
    assert!(
        worst < 0.5,
        "the parked vehicle's estimate went {worst:.2} m off"
    );
    assert!(p.ekf().feature_count() >= 4);
}

/// Runs a parked vehicle's radar with odometry pushed `lead_s` ahead of each azimuth (as
/// the simulator paced as fast as possible delivers it, the sockets and queues holding the
/// radar back), leaving out the records stamped inside `hole`.
fn run_ahead(azimuths: &[Azimuth], lead_s: f64, hole: Option<(f64, f64)>) -> PipelineSummary {
    let mut p = Pipeline::new(settings(), Some(T0), None).unwrap();
    let mut events = Vec::new();
    let mut k = 0u32;
    for a in azimuths {
        loop {
            let t = T0 + 0.05 * f64::from(k);
            if t > a.timestamp_s + lead_s {
                break;
            }
            if !hole.is_some_and(|(s, e)| t > s && t < e) {
                p.push_odometry(still(t));
            }
            k += 1;
        }
        p.process_azimuth(a, &mut events).unwrap();
        events.clear();
    }
    p.finish(&mut events)
}

#[test]
fn odometry_missing_for_a_few_seconds_ahead_of_the_radar_costs_those_seconds_only() {
    // 3 s of odometry lost (a link dropped with records in flight) while the odometry ran
    // 10 s ahead of the radar: the clock steps forward past its limit, the following records
    // confirm it, and the odometry already queued for the 10 s before the hole is kept;
    // before, the resynchronisation dropped it and every beam up to the hole was refused.
    let az = support::still_radar_azimuths(40, T0_NS);
    let undisturbed = run_ahead(&az, 10.0, None);
    assert_eq!(undisturbed.refused.stale_odometry, 0);
    let s = run_ahead(&az, 10.0, Some((T0 + 8.0, T0 + 11.0)));
    assert_eq!(s.odometry_clock_jumps, 1);
    let per_s = undisturbed.beams as f64 / 16.0;
    eprintln!(
        "{} beams refused as stale, {} taken ({} undisturbed)",
        s.refused.stale_odometry, s.beams, undisturbed.beams
    );
    assert!(
        s.refused.stale_odometry > 0 && (s.refused.stale_odometry as f64) < 3.5 * per_s,
        "{} beams refused as stale ({per_s:.1} beams a second)",
        s.refused.stale_odometry
    );
    assert!(s.beams + s.refused.stale_odometry >= undisturbed.beams - 10);
}
