//! The end-of-run summary and the progress line, as text for a terminal.

use std::fmt::{self, Write as _};

use crate::daemon::mcap_replay::McapReplayCounts;
use crate::daemon::zenoh_odometry::ZenohOdometryCounts;
use crate::output::{FoxgloveSummary, LiveSummary, RecordingSummary};
use crate::pipeline::radar_odometry::ScanMatchCounts;
use crate::pipeline::scores::{MapScore, ObservationErrorStats, PoseErrorStats};
use crate::pipeline::submaps::SubmapSummary;
use crate::pipeline::{DaemonEkf, PipelineSummary, RunReport};
use crate::source::ReplayFigures;

use super::DaemonReport;

/// One progress line after a rotation.
pub fn progress_line(s: &PipelineSummary, ekf: &DaemonEkf) -> String {
    let pose = ekf.pose();
    let cov = ekf.pose_covariance();
    let mut line = format!(
        "t={:6.1} s  rotation {:4}  map {:3}  pose ({:7.2}, {:7.2}, {:6.1} deg) +-{:.2} m  {:.2} ms/rotation",
        s.stream_s(),
        s.rotations,
        ekf.feature_count(),
        pose.x,
        pose.y,
        pose.theta.to_degrees(),
        (cov[(0, 0)] + cov[(1, 1)]).max(0.0).sqrt(),
        s.mean_rotation_ms()
    );
    if s.current_submap > 0 {
        let _ = write!(
            line,
            "  (submap {}: pose and map in its frame)",
            s.current_submap
        );
    }
    let refused = s.refused.no_odometry + s.refused.stale_odometry;
    if refused > 0 {
        let _ = write!(line, "  refused beams (no/stale odometry) {refused}");
    }
    line
}

/// The summary printed when a run ends: its parts in order, each line only when its part
/// has something to say.
pub fn summary_text(r: &DaemonReport) -> String {
    let s = &r.run.summary;
    let mut t = String::new();
    // Writing into a String cannot fail.
    let mut put = |part: &dyn fmt::Display| {
        let _ = write!(t, "{part}");
    };
    put(&Header(r));
    put(&Counts(s));
    if let Some(d) = &r.driver {
        put(&DriverLine(d));
    }
    if let Some(p) = &s.pose {
        put(&PoseError(p));
    }
    if let Some(o) = &s.online {
        put(&DriftLine::Online(o));
    }
    if let Some(o) = &s.odometry_track {
        put(&DriftLine::Odometry(o));
    }
    if let Some(o) = &s.observation_errors {
        put(&ObservationErrors(o));
    }
    match s.map.as_ref().filter(|m| m.scene_features > 0) {
        Some(m) => {
            put(&ScoredMap(m));
            put(&Materials(m));
            put(&Associations(s));
        }
        None => put(&UnscoredMap(s)),
    }
    if let Some(c) = &s.odometry_corrections {
        put(&OdometryCorrections(c));
    }
    if let Some(m) = &s.scan_match {
        put(&RadarOdometry(m));
    }
    if let Some(g) = &s.gyro {
        put(&Gyro(g));
    }
    put(&Spectrum(s));
    put(&Landmarks(s));
    if let Some(sm) = &s.submaps {
        put(&Submaps(sm));
    }
    put(&Timing(s));
    put(&Refusals(&r.run));
    if let Some(rp) = &r.replay {
        put(&RecordedDrive { drive: rp, s });
    }
    put(&InputHealth(s));
    put(&Outputs(r));
    put(&SavedMapLine(r));
    if let Some(l) = &s.localise {
        put(&super::localise_report::Localisation(l));
    }
    if let Some(x) = &s.extend {
        put(&super::localise_report::Extension(x, s.submaps.as_ref()));
    }
    if let Some(c) = &r.mcap_replay {
        put(&McapReplay(c));
    }
    if let Some(z) = &r.zenoh_odometry {
        put(&ZenohSubscription(
            z,
            "odometry",
            "samples",
            "lost",
            "malformed",
        ));
    }
    if let Some(z) = &r.zenoh_prior {
        put(&ZenohSubscription(
            z,
            "prior poses",
            "priors",
            "refused",
            "malformed or not in the map frame",
        ));
    }
    if let Some(rec) = &r.writer.recording {
        put(&Recording(rec));
    }
    if let Some(e) = &r.writer.recording_error {
        put(&RecordingStopped(e));
    }
    if let Some(live) = &r.writer.live {
        put(&LivePublishing(live));
    }
    if let Some(f) = &r.writer.foxglove {
        put(&FoxglovePublishing(f));
    }
    t
}

/// The first line: the scene, the stream's length and the wall time it took.
struct Header<'a>(&'a DaemonReport);

impl fmt::Display for Header<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self.0;
        let scene = r.scene.as_deref().unwrap_or("live radar");
        writeln!(
            f,
            "slam-node summary ({scene}): {:.1} s of stream in {:.1} s wall",
            r.run.summary.stream_s(),
            r.run.wall_s
        )
    }
}

/// Rotations, azimuths, detections, observations and beams.
struct Counts<'a>(&'a PipelineSummary);

impl fmt::Display for Counts<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        writeln!(
            f,
            "  rotations {}, azimuths {} ({} malformed), detections {} ({:.1}/rotation), observations {}, beams to the filter {}",
            s.rotations,
            s.azimuths,
            s.bad_azimuths,
            s.detections,
            s.detections as f64 / s.rotations.max(1) as f64,
            s.observations,
            s.beams
        )
    }
}

/// The radar driver's counters.
struct DriverLine<'a>(&'a radar_driver::MetricsSnapshot);

impl fmt::Display for DriverLine<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = self.0;
        writeln!(
            f,
            "  driver: {} azimuths sent, {} dropped (these counts run until the driver stops, after the pipeline), {} reconnects, {} decode errors",
            d.azimuths_sent,
            d.azimuth_drops,
            d.reconnects,
            d.decode_errors.total()
        )
    }
}

/// The filter's pose against the true pose.
struct PoseError<'a>(&'a PoseErrorStats);

impl fmt::Display for PoseError<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.0;
        if p.samples == 0 {
            // Zeros here would read as a perfect run: say that nothing was scored.
            return writeln!(
                f,
                "  pose error vs truth: not scored: the filter estimated no pose against the truth (it never started, or no rotation had both; see the radar odometry and refused beams lines)"
            );
        }
        writeln!(
            f,
            "  pose error vs truth: RMS {:.3} m, max {:.3} m, final {:.3} m / {:.2} deg; inside own 3-sigma in {:.1}% of {} rotations; mean NEES {:.2} (3 dof), {}",
            p.rms_position_m(),
            p.max_position_m,
            p.final_position_m,
            p.final_heading_rad.to_degrees(),
            100.0 * p.inside_fraction(),
            p.samples,
            p.nees_sum / p.samples.max(1) as f64,
            p.nees_band
        )
    }
}

/// Associated observations against the true geometry; nothing until both range and
/// bearing have statistics.
struct ObservationErrors<'a>(&'a ObservationErrorStats);

impl fmt::Display for ObservationErrors<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let o = self.0;
        let (Some((rm, rs)), Some((bm, bs))) = (o.range_m(), o.bearing_rad()) else {
            return Ok(());
        };
        writeln!(
            f,
            "  associated observations vs true geometry ({}): range {:+.3} +- {:.3} m, bearing {:+.3} +- {:.3} deg (mean +- std)",
            o.samples,
            rm,
            rs,
            bm.to_degrees(),
            bs.to_degrees()
        )
    }
}

/// The map against a scene with true features.
struct ScoredMap<'a>(&'a MapScore);

impl fmt::Display for ScoredMap<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = self.0;
        writeln!(
            f,
            "  map: {} features mapped; scene has {} ({} came within range); {} mapped features match {} distinct scene features (mean error {:.2} m); {} unmatched",
            m.mapped,
            m.scene_features,
            m.scene_features_in_range,
            m.matched,
            m.distinct_scene_features_matched,
            m.mean_match_error_m,
            m.mapped.saturating_sub(m.matched)
        )
    }
}

/// The mapped features' materials against the true ones.
struct Materials<'a>(&'a MapScore);

impl fmt::Display for Materials<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = self.0;
        if m.matched == 0 {
            // No mapped feature matches a scene feature: nothing to compare.
            return writeln!(
                f,
                "  materials: not scored (no mapped feature matches a scene feature)"
            );
        }
        writeln!(
            f,
            "  materials: mean |rho - true| {:.3} (initial guess {:.3}), mean |alpha - true| {:.3} (initial {:.3}); L {:.2} dB (true {}); rho with the rho/L offset removed: mean error {}",
            m.mean_rho_error,
            m.initial_rho_error,
            m.mean_alpha_error,
            m.initial_alpha_error,
            m.loss_db,
            m.true_loss_db.map_or("unknown".into(), |l| format!("{l:.2} dB")),
            m.mean_rho_error_gauge_fixed.map_or("n/a".into(), |e| format!("{e:.3}"))
        )
    }
}

/// Associations to the wrong scene feature and to clutter.
struct Associations<'a>(&'a PipelineSummary);

impl fmt::Display for Associations<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        writeln!(
            f,
            "  associations {}: {} to the wrong scene feature ({:.2}%), {} of clutter",
            s.associations,
            s.association_errors,
            100.0 * s.association_errors as f64 / s.associations.max(1) as f64,
            s.clutter_associations
        )
    }
}

/// The map when there are no true features to compare with.
struct UnscoredMap<'a>(&'a PipelineSummary);

impl fmt::Display for UnscoredMap<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        let loss = s
            .map
            .as_ref()
            .map_or(String::new(), |m| format!("; L {:.2} dB", m.loss_db));
        writeln!(
            f,
            "  map: {} features (no true features to compare with); associations {}{loss}",
            s.map_size, s.associations
        )
    }
}

/// The estimated odometry corrections: `([k, b], [std k, std b])`.
struct OdometryCorrections<'a>(&'a ([f64; 2], [f64; 2]));

impl fmt::Display for OdometryCorrections<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let &([k, b], [sk, sb]) = self.0;
        writeln!(
            f,
            "  odometry corrections estimated: speed x {:.4} +- {:.4} (k {:+.4}), steering offset {:+.4} +- {:.4} rad",
            1.0 + k,
            sk,
            k,
            b,
            sb
        )
    }
}

/// The gyro of radar-only driving: its samples and the bias the filter estimated.
struct Gyro<'a>(&'a crate::pipeline::gyro::GyroSummary);

impl fmt::Display for Gyro<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = self.0.counts;
        write!(
            f,
            "  gyro: {} samples, {} applied, {} refused, {} dropped",
            c.received, c.applied, c.refused, c.dropped
        )?;
        match self.0.bias_rad_s {
            Some((b, sb)) => writeln!(f, "; bias estimated {b:+.5} +- {sb:.5} rad/s"),
            None => writeln!(f),
        }
    }
}

/// Radar odometry (scan registration), and its error against the true motion when known.
struct RadarOdometry<'a>(&'a ScanMatchCounts);

impl fmt::Display for RadarOdometry<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = self.0;
        let r = &m.registrations;
        let mean_nis = if m.applied > 0 {
            format!("{:.2}", m.nis_sum / m.applied as f64)
        } else {
            "-".to_string()
        };
        writeln!(
            f,
            "  radar odometry: {} registrations tried, {} failed, {} applied (mean NIS {mean_nis}, 3 dof), {} gated; {} retried from other headings (through a turn, or few pairs: {} more registrations; {} of them so few that they were also tried from starts along the track); {} run again on the cloud placed along the motion found (far from the estimate it was placed along: {} of them only in travel)",
            r.tried, r.failed, m.applied, m.gated, r.turned, r.retries, r.along, r.replaced, r.replaced_along
        )?;
        if r.onsets > 0 || r.probed > 0 {
            writeln!(
                f,
                "  radar odometry's turn probes: {} registrations taken from headings either side of the held motion (a turn's onset it missed), {} run again along a swept registration's turn",
                r.onsets, r.probed
            )?;
        }
        if r.crawled > 0 || r.searched_crawl_runs > 0 {
            writeln!(
                f,
                "  radar odometry at a crawl: {} rotations under {} m; their registrations started that short paired with the reference's surfaces only (not the ground's clutter), and {} runs of a searched one (no motion estimate) again from its result so",
                r.crawled,
                radar_odometry::matcher::CRAWL_SURFACES_ONLY_M,
                r.searched_crawl_runs
            )?;
        }
        if r.refined > 0 {
            writeln!(
                f,
                "  radar odometry ran {} registrations again from a registration's own result (`[odometry] radar_odometry_refine_runs`)",
                r.refined
            )?;
        }
        if r.softened > 0 {
            writeln!(
                f,
                "  radar odometry ran {} registrations again without hard pairs, each return weighted over its neighbours (`[odometry] radar_odometry_soft_kernel_m`)",
                r.softened
            )?;
        }
        if r.held > 0 {
            writeln!(
                f,
                "  radar odometry placed {} rotations with the turn their reference was placed with (held), not the odometry's (the two within {} rad)",
                r.held,
                radar_odometry::matcher::HELD_TURN_MAX_RAD
            )?;
        }
        if r.start_probed > 0 {
            // The thresholds from the library, so the line says what the code does.
            writeln!(
                f,
                "  radar odometry's start probes: {} registrations run again from headings {} mrad either side (every {}th after the first {}, while recent ones followed under {} of their start); they followed {:.2} of their start's heading on the mean; {} where the scene did not pin the heading (once the last ten or so followed more than {} of it on the average, until under {}: their heading and the motion across the track not used; found so within the first {}, the steering offset's variance put back to its prior); elsewhere the recent average share, at most {}, taken out of each registration's heading before the filter used it",
                r.start_probed,
                1000.0 * radar_odometry::matcher::START_PROBE_RAD,
                radar_odometry::matcher::START_PROBE_SPARSE_EVERY,
                radar_odometry::matcher::START_PROBE_DENSE_FIRST,
                radar_odometry::matcher::START_PROBE_SPARSE_BELOW,
                r.start_follow_permille as f64 / 1000.0 / r.start_probed as f64,
                r.start_unpinned,
                radar_odometry::matcher::START_FOLLOW_UNPINNED,
                radar_odometry::matcher::START_FOLLOW_PINNED,
                radar_odometry::matcher::START_FOLLOW_EARLY,
                radar_odometry::matcher::MAX_UNFOLLOWED_SHARE
            )?;
        }
        if m.drives {
            writeln!(
                f,
                "  radar only: radar odometry drove the prediction; {} registrations searched for the motion (no estimate), {} weakly constrained (the scene did not pin the motion in one direction: the pose's uncertainty grew along it), {} turned away from the held motion (a turn's onset or end: the heading's process noise widened), {} with no beam for the filter (its clock brought to the rotation's end by the motion held)",
                r.searched, r.weak, m.manoeuvres, m.still_clock
            )?;
            if r.tried > 0 && r.failed == r.tried {
                writeln!(
                    f,
                    "  radar only: NO POSE: every registration failed ({} of {}), so the filter never started and nothing was mapped; the returns did not repeat from rotation to rotation closely enough to pair (a scene of sparse point targets, an open field)",
                    r.failed, r.tried
                )?;
            }
        } else if r.weak > 0 {
            writeln!(
                f,
                "  radar odometry: {} registrations weakly constrained (the scene did not pin the motion in one direction)",
                r.weak
            )?;
        }
        if let Some([x, y, h]) = m.truth_error() {
            writeln!(
                f,
                "  radar odometry vs the true motion ({} registrations, mean +- std): x {:+.4} +- {:.4} m, y {:+.4} +- {:.4} m, heading {:+.5} +- {:.5} rad{}{}",
                m.truth_compared,
                x.0,
                x.1,
                y.0,
                y.1,
                h.0,
                h.1,
                m.truth_normalised_rms().map_or(String::new(), |[x, y, h]| format!(
                    "; each error over the std it was taken with, RMS: x {x:.2}, y {y:.2}, heading {h:.2} (1: as good as the filter was told; above 1: the filter was told better than it got)"
                )),
                m.heading_error_lag_one().map_or(String::new(), |r| format!(
                    "; consecutive heading errors correlated {r:+.2} (lag one; -0.5: each cloud's placement error, cancelling when chained)"
                ))
            )?;
        }
        if let Some(c) = m.chained {
            writeln!(
                f,
                "  radar odometry alone (each rotation's registered motion chained from the first, nothing fused): drift over 100-800 m segments {}",
                drift_figures(c.translation_percent, c.rotation_deg_per_100m, c.segments)
            )?;
        }
        Ok(())
    }
}

/// The predicted spectrum against the measured one.
struct Spectrum<'a>(&'a PipelineSummary);

impl fmt::Display for Spectrum<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        let bound = match s.spectrum_bound_db {
            Some((lo, hi)) => {
                format!("the learned background's 3-sigma bound ({lo:.1}-{hi:.1} dB)")
            }
            None => "+-16.35 dB".to_string(),
        };
        match (s.spectrum.in_bound_fraction(), s.spectrum.bias_db()) {
            (Some(fr), Some(b)) => writeln!(
                f,
                "  spectrum prediction: {:.1}% of {} bins inside {bound} over {} beams with mapped features; bias (predicted - measured) {:+.2} dB{}",
                100.0 * fr,
                s.spectrum.bins,
                s.spectrum.beams,
                b,
                s.learned_gain_db_per_decade
                    .map_or(String::new(), |g| format!("; learned compensation {g:.1} dB/decade"))
            ),
            _ => writeln!(
                f,
                "  spectrum prediction: no beam with a mapped feature compared"
            ),
        }
    }
}

/// Extended returns, re-observation of mapped features and retired features; nothing
/// when there was no extended return and no mapped feature came into view again.
struct Landmarks<'a>(&'a PipelineSummary);

impl fmt::Display for Landmarks<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        if s.features_in_view == 0 && s.extended_returns == 0 {
            return Ok(());
        }
        writeln!(
            f,
            "  landmarks: {} extended returns kept out of the map ({:.1} per rotation); mapped features re-observed in {:.1}% of the later rotations with them in view ({} of {})",
            s.extended_returns,
            s.extended_returns as f64 / s.rotations.max(1) as f64,
            100.0 * s.features_reobserved as f64 / s.features_in_view.max(1) as f64,
            s.features_reobserved,
            s.features_in_view
        )?;
        if s.features_retired_unrepeatable > 0 {
            writeln!(
                f,
                "  unrepeatable features retired: {}",
                s.features_retired_unrepeatable
            )?;
        }
        Ok(())
    }
}

/// Submaps and the global layer, and the global trajectory against the truth when scored.
struct Submaps<'a>(&'a SubmapSummary);

impl fmt::Display for Submaps<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sm = self.0;
        let g = &sm.global;
        writeln!(
            f,
            "  submaps: {} (largest {} features when closed), {} features frozen in {:.1} kB; global layer: {} loop closures from {} candidates ({} dropped as conflicting, {} after the solve, {} closures held for the next submap (place jumps, prior slides) and {} of them unconfirmed, {} failed solves), {} solutions used, slowest join {:.1} ms; near links (each submap's scan against those two to `[submaps] near_links` back that the chain puts within 120 m, slam-graph's near_links) {} of {} tried ({} more verified but dropped after the solve, far outside their covariance)",
            sm.submaps,
            sm.largest_submap_features,
            sm.frozen_features,
            sm.frozen_bytes as f64 / 1e3,
            sm.loop_closures,
            g.candidates,
            g.conflicting,
            g.rejected_after_solve,
            g.held,
            g.unconfirmed,
            g.failed_solves,
            sm.solutions,
            g.max_add_ms,
            g.near_links,
            g.near_tried,
            g.near_dropped
        )?;
        if sm.optimised.as_ref().is_some_and(|o| o.poses < 2) {
            // The start pose alone (or nothing) scores zeros that would read as a perfect
            // trajectory.
            writeln!(
                f,
                "  global trajectory vs truth (trajectory.tum, final frames): not scored: no pose after the start pose had a true pose at its time"
            )?;
        } else if let Some(o) = &sm.optimised {
            writeln!(
                f,
                "  global trajectory vs truth (trajectory.tum, final frames): RMS {:.3} m, max {:.3} m, final {:.3} m / {:.2} deg, heading RMS {:.2} deg; mean NEES {:.2}, inside 99% bound {:.1}%, {}; drift over 100-800 m segments {} on {:.0} m driven; loop closures true {} / false {}",
                o.rms_m,
                o.max_m,
                o.final_m,
                o.final_heading_rad.to_degrees(),
                o.rms_heading_rad.to_degrees(),
                o.mean_nees,
                100.0 * o.inside_99,
                o.nees_band,
                drift_text(o),
                o.length_m,
                sm.loops_true,
                sm.loops_false
            )?;
        }
        if let Some(r) = &sm.revisits {
            let pct =
                |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{:.0}%", 100.0 * v));
            writeln!(
                f,
                "  true revisits (a submap's true origin within 10 m of the path of an earlier one, at least 300 m driven apart): {} pairs over {} revisiting submaps, {} closed (recall {}); {} of {} closures true (precision {}); candidates from place descriptors {}, closures {}",
                r.pairs,
                r.revisiting,
                r.closed,
                pct(r.recall()),
                r.correct,
                r.closures,
                pct(r.precision()),
                g.place_candidates,
                g.place_loops
            )?;
        }
        if let Some(e) = &sm.edges_vs_truth {
            writeln!(
                f,
                "  graph edges vs truth (each edge's error over the std it entered the graph with, RMS x / y / heading; mean NEES, 3 if honest; heading error RMS): chain {}; near links {}; loop closures {}",
                EdgeText(&e.chain),
                EdgeText(&e.links),
                EdgeText(&e.loops)
            )?;
        }
        Ok(())
    }
}

/// One kind of graph edge against the truth.
struct EdgeText<'a>(&'a crate::pipeline::submaps::EdgeScore);

impl fmt::Display for EdgeText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = self.0;
        match (e.normalised_rms(), e.mean_nees(), e.heading_rms_rad()) {
            (Some([x, y, h]), Some(nees), Some(rms)) => write!(
                f,
                "{} edges: {x:.2} / {y:.2} / {h:.2}, NEES {nees:.2}, heading {:.2} mrad",
                e.count,
                rms * 1e3
            ),
            _ => write!(f, "none"),
        }
    }
}

/// KITTI-style drift of a trajectory: translation and rotation over 100-800 m segments.
fn drift_text(o: &crate::pipeline::submaps::TrajectoryScore) -> String {
    match (o.drift_percent, o.drift_deg_per_100m) {
        (Some(t), Some(r)) => drift_figures(t, r, o.drift_segments),
        _ => "n/a (shorter drive)".to_string(),
    }
}

/// Drift over 100-800 m segments as every summary line gives it.
fn drift_figures(percent: f64, deg_per_100m: f64, segments: usize) -> String {
    format!("{percent:.2}% and {deg_per_100m:.3} deg/100 m ({segments} segments)")
}

/// A trajectory against the truth, as the radar odometry literature scores one: printed
/// when the drive is long enough to have 100 m segments. The pose published each rotation
/// (the online pose, with its RMS and max), or the odometry: the filter's pose chained
/// through the submaps' switch poses alone, the online pose without the global layer's
/// corrections, which arrive as jumps and count as drift in every segment across them.
enum DriftLine<'a> {
    Online(&'a crate::pipeline::submaps::TrajectoryScore),
    Odometry(&'a crate::pipeline::submaps::TrajectoryScore),
}

impl fmt::Display for DriftLine<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (Self::Online(o) | Self::Odometry(o)) = *self;
        if o.drift_percent.is_none() {
            return Ok(());
        }
        match self {
            Self::Online(_) => writeln!(
                f,
                "  online pose vs truth (as published each rotation): RMS {:.3} m, max {:.3} m; drift over 100-800 m segments {} on {:.0} m driven (KITTI / Boreas definition, slam_filter::drift)",
                o.rms_m,
                o.max_m,
                drift_text(o),
                o.length_m
            ),
            Self::Odometry(_) => writeln!(
                f,
                "  odometry vs truth (the online pose without the global layer's corrections): drift over 100-800 m segments {}",
                drift_text(o),
            ),
        }
    }
}

/// Time per rotation, and the pipeline thread's CPU time when measured.
struct Timing<'a>(&'a PipelineSummary);

impl fmt::Display for Timing<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        let n = s.rotations.max(1) as f64;
        writeln!(
            f,
            "  time per rotation: mean {:.2} ms (detection {:.2}, filter {:.2}, spectrum {:.2}), p50 {:.2}, p99 {:.2}, max {:.2} ms; real-time factor {:.1}x on one thread",
            s.mean_rotation_ms(),
            s.detect_ms / n,
            s.filter_ms / n,
            s.spectrum_ms / n,
            s.rotation_ms_percentile(50.0),
            s.rotation_ms_percentile(99.0),
            s.max_rotation_ms,
            s.real_time_factor()
        )?;
        if let Some(mean) = s.mean_cpu_ms() {
            writeln!(
                f,
                "  pipeline thread CPU per rotation (its own work, without waits for a core): mean {:.2} ms, p50 {:.2}, p99 {:.2} over {} rotations",
                mean,
                s.cpu_ms_percentile(50.0),
                s.cpu_ms_percentile(99.0),
                s.cpu_rotations
            )?;
            let tenths = s.cpu_ms_by_tenth();
            if tenths.len() == 10 {
                let each: Vec<String> = tenths
                    .iter()
                    .map(|[p50, p99]| format!("{p50:.1}/{p99:.1}"))
                    .collect();
                writeln!(
                    f,
                    "  the same by tenth of the run, p50/p99 ms (first to last): {}",
                    each.join(" ")
                )?;
            }
        }
        Ok(())
    }
}

/// Refused beams, filter errors, stalls, odometry errors and dropped output events.
struct Refusals<'a>(&'a RunReport);

impl fmt::Display for Refusals<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let run = self.0;
        let s = &run.summary;
        writeln!(
            f,
            "  refused beams: {} without odometry, {} with stale odometry, {} late; filter errors {}; radar stalls {}; odometry errors {}; output events dropped {}",
            s.refused.no_odometry,
            s.refused.stale_odometry,
            s.refused.late_beams,
            s.filter_errors,
            run.stalls,
            run.odometry_errors,
            run.output_drops
        )?;
        if s.burst_beams > 0 {
            writeln!(
                f,
                "  noise bursts: {} beams not used (targets far above the learned rate: the radar taken as blind)",
                s.burst_beams
            )?;
        }
        if s.still_clock_caught_up > 0 {
            writeln!(
                f,
                "  rotations with no beam for the filter: {} (their ends reached with the odometry received)",
                s.still_clock_caught_up
            )?;
        }
        if run.far_ahead_of_odometry > 0 {
            writeln!(
                f,
                "  azimuths stamped far ahead of the odometry (a radar clock in the future?): {}, processed without waiting for odometry",
                run.far_ahead_of_odometry
            )?;
        }
        Ok(())
    }
}

/// A replay of a recorded drive: the recording, the filter and dead reckoning against
/// the ground truth, and the map's density.
struct RecordedDrive<'a> {
    drive: &'a ReplayFigures,
    s: &'a PipelineSummary,
}

impl fmt::Display for RecordedDrive<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (rp, s) = (self.drive, self.s);
        let e = &rp.errors;
        let odometry = if rp.radar_only {
            "no odometry: radar only".to_string()
        } else {
            format!(
                "odometry from the ground truth x{:.3} speed, {:+.3} rad/s yaw rate, noise {:.3} m/s / {:.4} rad/s (seed {})",
                e.speed_scale, e.yaw_rate_bias_rps, e.sigma_speed_mps, e.sigma_yaw_rate_rps, e.seed
            )
        };
        writeln!(
            f,
            "  recorded drive ({}, {} scans, {} skipped as damaged): {}; {odometry}; ranges corrected for a range-Doppler coupling of {:.4} s",
            rp.format.unwrap_or("-"),
            rp.scans,
            rp.scans_skipped,
            if rp.ground_truth {
                format!("{:.1} m", rp.distance_m)
            } else {
                "distance unknown".to_string()
            },
            rp.doppler_range_coupling_s
        )?;
        if !rp.ground_truth {
            writeln!(
                f,
                "  no ground truth in the recording: the trajectory is not scored (no error, no drift, no NEES); the map and the counts below stand alone"
            )?;
        } else {
            let filter = s
                .pose
                .as_ref()
                .map(|p| (p.rms_position_m(), p.final_position_m));
            let reckoning = if rp.radar_only {
                "no odometry to dead-reckon with".to_string()
            } else {
                format!(
                    "dead reckoning with the same odometry RMS {:.3} m, final {:.3} m",
                    rp.dead_reckoning_rms_m, rp.dead_reckoning_final_m
                )
            };
            writeln!(
                f,
                "  against the ground truth: filter RMS {} m, final {} m; {reckoning}",
                filter.map_or("-".into(), |f| format!("{:.3}", f.0)),
                filter.map_or("-".into(), |f| format!("{:.3}", f.1)),
            )?;
        }
        writeln!(
            f,
            "  features in the map {} ({} per 100 m driven), detections {:.1} per rotation",
            s.map_size,
            if rp.ground_truth {
                format!("{:.0}", 100.0 * s.map_size as f64 / rp.distance_m.max(1e-9))
            } else {
                "-".to_string()
            },
            s.detections as f64 / s.rotations.max(1) as f64
        )
    }
}

/// Falling behind real time, untrusted input and duplicated odometry; each line only
/// when it happened.
struct InputHealth<'a>(&'a PipelineSummary);

impl fmt::Display for InputHealth<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        if s.rotations_behind > 0 {
            writeln!(
                f,
                "  behind real time: {} of {} rotations took longer to process than the radar took to send them",
                s.rotations_behind, s.rotations
            )?;
        }
        if s.odometry_refused + s.odometry_clock_jumps + s.clock_outliers + s.clock_jumps > 0 {
            writeln!(
                f,
                "  untrusted input: {} odometry records refused (physical limits or wild time), {} odometry clock jumps resynchronised, {} azimuths with wild timestamps dropped, {} radar clock jumps resynchronised",
                s.odometry_refused, s.odometry_clock_jumps, s.clock_outliers, s.clock_jumps
            )?;
        }
        if s.odometry_duplicates > 0 {
            writeln!(
                f,
                "  odometry sent again (a reconnected source replaying): {} records dropped as duplicates",
                s.odometry_duplicates
            )?;
        }
        Ok(())
    }
}

/// The output directory, the files written in it and the figures.
struct Outputs<'a>(&'a DaemonReport);

impl fmt::Display for Outputs<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self.0;
        let names: Vec<String> = r
            .writer
            .files
            .iter()
            .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect();
        writeln!(
            f,
            "  outputs in {}: {}{}",
            r.out_dir.display(),
            names.join(", "),
            if r.writer.figures.is_empty() {
                String::new()
            } else {
                format!(
                    ", {} figures (map.svg, spectrum_*.svg)",
                    r.writer.figures.len()
                )
            }
        )
    }
}

/// The saved map (`[map]`): what went in, its size, and per km of drive when the drive's
/// length is known.
struct SavedMapLine<'a>(&'a DaemonReport);

impl fmt::Display for SavedMapLine<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self.0;
        if let Some(e) = &r.writer.saved_map_error {
            writeln!(f, "  saved map NOT written: {e}")?;
        }
        let (Some(c), Some(bytes)) = (&r.run.summary.saved_map, r.writer.saved_map_bytes) else {
            return Ok(());
        };
        let s = &r.run.summary;
        let length_m = s
            .online
            .as_ref()
            .or(s.submaps.as_ref().and_then(|m| m.optimised.as_ref()))
            .map(|t| t.length_m)
            .filter(|l| *l > 100.0);
        let per_km = length_m.map_or(String::new(), |l| {
            format!(
                ", {:.2} MB per km over {:.2} km",
                bytes as f64 / 1e6 / (l / 1e3),
                l / 1e3
            )
        });
        writeln!(
            f,
            "  saved map: {} submaps, {} features, {} loop closures and near links{}; {} bytes{per_km} ({} saves, each built in {:.1} ms at most on the pipeline thread){}",
            c.submaps,
            c.features,
            c.loops,
            if c.drives > 1 {
                format!(", {} drives, {} joins", c.drives, c.joins)
            } else {
                String::new()
            },
            bytes,
            r.writer.saved_maps,
            c.max_build_ms,
            if c.scans > 0 {
                format!(
                    "; the scans of {} submaps kept, {} points",
                    c.scans, c.scan_points
                )
            } else {
                String::new()
            }
        )
    }
}

/// What a replay of an MCAP file read and refused.
struct McapReplay<'a>(&'a McapReplayCounts);

impl fmt::Display for McapReplay<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = self.0;
        writeln!(
            f,
            "  MCAP replay: {} messages, {} configurations, {} rotations, {} azimuths, {} odometry samples; {} on other topics; refused {} (unknown schema {}, wrong encoding {}, malformed {}, before a configuration {}){}{}",
            c.messages,
            c.configurations,
            c.rotations,
            c.azimuths,
            c.odometry,
            c.ignored,
            c.refused(),
            c.unknown_schema,
            c.wrong_encoding,
            c.malformed,
            c.before_configuration,
            c.file_error
                .as_ref()
                .map_or(String::new(), |e| format!("; replayed up to where the file is cut or corrupt: {e}")),
            if c.stopped {
                "; stopped on request before the file's end"
            } else {
                ""
            }
        )
    }
}

/// What a Zenoh subscription (odometry, prior poses) received and lost: its counts, what it
/// carries, what its messages are called, the word for those not taken and for those that
/// did not decode.
struct ZenohSubscription<'a>(
    &'a ZenohOdometryCounts,
    &'static str,
    &'static str,
    &'static str,
    &'static str,
);

impl fmt::Display for ZenohSubscription<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ZenohSubscription(z, what, items, lost, malformed) = self;
        writeln!(
            f,
            "  Zenoh {what} on {}: {} {items} received, {} taken; {lost} {} ({malformed} {}, another type {}, queue full {})",
            z.key,
            z.received,
            z.decoded,
            z.lost(),
            z.malformed,
            z.wrong_type,
            z.dropped
        )
    }
}

/// The MCAP recording's line ([`recording_line`]).
struct Recording<'a>(&'a RecordingSummary);

impl fmt::Display for Recording<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}", recording_line(self.0))
    }
}

/// Why the MCAP recording stopped early.
struct RecordingStopped<'a>(&'a str);

impl fmt::Display for RecordingStopped<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "  MCAP recording stopped early: {}", self.0)
    }
}

/// What was published live over Zenoh.
struct LivePublishing<'a>(&'a LiveSummary);

impl fmt::Display for LivePublishing<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let live = self.0;
        writeln!(
            f,
            "  Zenoh: {} messages published on {} keys, {} events dropped (queue full), {} failed",
            live.total(),
            live.published.len(),
            live.dropped,
            live.failed
        )
    }
}

/// What the Foxglove live view served.
struct FoxglovePublishing<'a>(&'a FoxgloveSummary);

impl fmt::Display for FoxglovePublishing<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = self.0;
        let address = s.address.map_or("-".into(), |a| a.to_string());
        writeln!(
            f,
            "  Foxglove at ws://{address}: {} messages on {} channels to subscribers, {:.1} kB/s sent over {:.1} s; {} events dropped (queue full), {} azimuths not drawn; {} connections, {} subscriptions, {} to unknown channels, {} refused (too many), {} bad requests, {} cut off (sending too much), {} pages",
            s.total(),
            s.published.len(),
            s.bytes_per_s() / 1e3,
            s.served_s,
            s.dropped,
            s.failed,
            s.connections,
            s.subscriptions,
            s.unknown_subscriptions,
            s.refused,
            s.bad_requests,
            s.cut_off,
            s.pages,
        )
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let at = ((s.len() as f64 - 1.0) * q).round().max(0.0) as usize;
    s.get(at).copied().unwrap_or(0.0)
}

/// The recording's size and cost: messages, MB per minute of stream, write time per
/// rotation against the rotation's processing time.
pub fn recording_line(rec: &crate::output::RecordingSummary) -> String {
    format!(
        "  MCAP {}: {} messages on {} topics, {} rotations, {:.2} MB ({} MB per minute of stream); write {:.2} ms per rotation (p95 {:.2}, max {:.2}) against {:.2} ms processing",
        rec.path.display(),
        rec.total_messages(),
        rec.messages.len(),
        rec.rotations,
        rec.bytes as f64 / 1e6,
        rec.mb_per_minute()
            .map_or("-".into(), |m| format!("{m:.1}")),
        mean(&rec.write_ms),
        quantile(&rec.write_ms, 0.95),
        rec.write_ms.iter().copied().fold(0.0, f64::max),
        mean(&rec.processing_ms),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run whose filter never started must not read as a perfect one.
    #[test]
    fn a_run_with_no_pose_says_so_instead_of_printing_zeros() {
        let text = PoseError(&PoseErrorStats::default()).to_string();
        assert!(text.contains("not scored"), "{text}");
        assert!(!text.contains("RMS 0.000"), "{text}");

        let counts = ScanMatchCounts {
            drives: true,
            registrations: radar_odometry::MatcherCounts {
                tried: 40,
                failed: 40,
                ..Default::default()
            },
            ..ScanMatchCounts::default()
        };
        let text = RadarOdometry(&counts).to_string();
        assert!(text.contains("NO POSE"), "{text}");
        let working = ScanMatchCounts {
            registrations: radar_odometry::MatcherCounts {
                failed: 1,
                ..counts.registrations
            },
            applied: 39,
            ..counts
        };
        assert!(!RadarOdometry(&working).to_string().contains("NO POSE"));
    }
}
