//! The learned front end allocates nothing per azimuth in steady state: the floor's
//! histograms and tables and the detector's buffers are sized from the radar's geometry
//! once. Counted by a counting global allocator (`allocation-counter`, per thread) installed
//! in this test binary only; counts, not timings, so they are deterministic.

use slam_node::detect::{FloorSettings, LearnedFloor, LineDetector, LineSettings, RangeAxis};

const BINS: usize = 3768;

/// A deterministic CTS350-X-like azimuth: a speckled floor and a few strong returns.
fn azimuth(a: usize, seed: &mut u64) -> Vec<u8> {
    (0..BINS)
        .map(|b| {
            *seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let speckle = ((*seed >> 58) & 0xF) as u8;
            let target = if (b + 37 * a) % 397 < 3 { 70 } else { 0 };
            6u8.saturating_add(speckle).saturating_add(target)
        })
        .collect()
}

#[test]
fn detection_on_the_learned_floor_allocates_nothing_per_azimuth_in_steady_state() {
    let axis = RangeAxis {
        first_bin_m: 0.0,
        bin_m: 0.0438,
    };
    let settings = LineSettings {
        merge_gap_bins: 1,
        max_peaks: 16,
        min_range_m: 1.0,
        max_range_m: 200.0,
    };
    let mut seed = 7;
    let rotation: Vec<Vec<u8>> = (0..400).map(|a| azimuth(a, &mut seed)).collect();
    let mut floor = LearnedFloor::new(FloorSettings::default(), BINS);
    let mut det = LineDetector::new();
    let mut out = Vec::with_capacity(64);
    // Warm up: the floor becomes ready and the buffers take their size.
    for bins in rotation.iter().chain(&rotation) {
        det.detect(bins, &mut floor, &axis, &settings, &mut out);
    }
    assert!(floor.is_ready());
    let mut detections = 0;
    let info = allocation_counter::measure(|| {
        for bins in &rotation {
            det.detect(bins, &mut floor, &axis, &settings, &mut out);
            detections += out.len();
        }
    });
    println!(
        "one rotation: {detections} detections, {} allocations, {} bytes",
        info.count_total, info.bytes_total
    );
    assert!(detections > 400, "{detections} detections");
    assert_eq!(info.count_total, 0, "allocations in one rotation");
}
