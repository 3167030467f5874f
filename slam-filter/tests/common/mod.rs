//! What the filter's whole-run tests share: the scene's features a beam sees.

use radar_model::geometry::{range_bearing, wrap_angle, Pose2};
use radar_model::observation::BeamFeature;

/// The features within `half_width` of the beam at `beam` (rad) and nearer than
/// `max_range_m`, seen from `truth`, in the order given.
pub fn in_beam(
    truth: &Pose2,
    features: &[BeamFeature],
    beam: f64,
    half_width: f64,
    max_range_m: f64,
) -> Vec<BeamFeature> {
    features
        .iter()
        .filter(|f| {
            let rb = range_bearing(truth, f.xy);
            wrap_angle(rb.bearing_rad - beam).abs() <= half_width && rb.range_m < max_range_m
        })
        .copied()
        .collect()
}

/// As [`in_beam`], nearest first.
pub fn in_beam_by_range(
    truth: &Pose2,
    features: &[BeamFeature],
    beam: f64,
    half_width: f64,
    max_range_m: f64,
) -> Vec<BeamFeature> {
    let mut v = in_beam(truth, features, beam, half_width, max_range_m);
    v.sort_by(|p, q| {
        range_bearing(truth, p.xy)
            .range_m
            .total_cmp(&range_bearing(truth, q.xy).range_m)
    });
    v
}
