//! The end-of-run summary and the progress line, as text for a terminal.

use std::fmt::Write as _;

use crate::pipeline::{DaemonEkf, PipelineSummary};

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

/// The summary printed when a run ends.
pub fn summary_text(r: &DaemonReport) -> String {
    let s = &r.run.summary;
    let mut t = String::new();
    let scene = r.scene.as_deref().unwrap_or("live radar");
    let _ = writeln!(
        t,
        "slam-node summary ({scene}): {:.1} s of stream in {:.1} s wall",
        s.stream_s(),
        r.run.wall_s
    );
    let _ = writeln!(
        t,
        "  rotations {}, azimuths {} ({} malformed), detections {} ({:.1}/rotation), observations {}, beams to the filter {}",
        s.rotations,
        s.azimuths,
        s.bad_azimuths,
        s.detections,
        s.detections as f64 / s.rotations.max(1) as f64,
        s.observations,
        s.beams
    );
    if let Some(d) = &r.driver {
        let _ = writeln!(
            t,
            "  driver: {} azimuths sent, {} dropped (these counts run until the driver stops, after the pipeline), {} reconnects, {} decode errors",
            d.azimuths_sent,
            d.azimuth_drops,
            d.reconnects,
            d.decode_errors.total()
        );
    }
    if let Some(p) = &s.pose {
        let _ = writeln!(
            t,
            "  pose error vs truth: RMS {:.3} m, max {:.3} m, final {:.3} m / {:.2} deg; inside own 3-sigma in {:.1}% of {} rotations; mean NEES {:.2} (3 dof)",
            p.rms_position_m(),
            p.max_position_m,
            p.final_position_m,
            p.final_heading_rad.to_degrees(),
            100.0 * p.inside_fraction(),
            p.samples,
            p.nees_sum / p.samples.max(1) as f64
        );
    }
    if let Some(o) = &s.observation_errors {
        if let (Some((rm, rs)), Some((bm, bs))) = (o.range_m(), o.bearing_rad()) {
            let _ = writeln!(
                t,
                "  associated observations vs true geometry ({}): range {:+.3} +- {:.3} m, bearing {:+.3} +- {:.3} deg (mean +- std)",
                o.samples,
                rm,
                rs,
                bm.to_degrees(),
                bs.to_degrees()
            );
        }
    }
    if let Some(m) = s.map.as_ref().filter(|m| m.scene_features > 0) {
        let _ = writeln!(
            t,
            "  map: {} features mapped; scene has {} ({} came within range); {} mapped features match {} distinct scene features (mean error {:.2} m); {} unmatched",
            m.mapped,
            m.scene_features,
            m.scene_features_in_range,
            m.matched,
            m.distinct_scene_features_matched,
            m.mean_match_error_m,
            m.mapped.saturating_sub(m.matched)
        );
        let _ = writeln!(
            t,
            "  materials: mean |rho - true| {:.3} (initial guess {:.3}), mean |alpha - true| {:.3} (initial {:.3}); L {:.2} dB (true {}); rho with the rho/L offset removed: mean error {}",
            m.mean_rho_error,
            m.initial_rho_error,
            m.mean_alpha_error,
            m.initial_alpha_error,
            m.loss_db,
            m.true_loss_db.map_or("unknown".into(), |l| format!("{l:.2} dB")),
            m.mean_rho_error_gauge_fixed.map_or("n/a".into(), |e| format!("{e:.3}"))
        );
        let _ = writeln!(
            t,
            "  associations {}: {} to the wrong scene feature ({:.2}%), {} of clutter",
            s.associations,
            s.association_errors,
            100.0 * s.association_errors as f64 / s.associations.max(1) as f64,
            s.clutter_associations
        );
    } else {
        let loss = s
            .map
            .as_ref()
            .map_or(String::new(), |m| format!("; L {:.2} dB", m.loss_db));
        let _ = writeln!(
            t,
            "  map: {} features (no true features to compare with); associations {}{loss}",
            s.map_size, s.associations
        );
    }
    if let Some(([k, b], [sk, sb])) = s.odometry_corrections {
        let _ = writeln!(
            t,
            "  odometry corrections estimated: speed x {:.4} +- {:.4} (k {:+.4}), steering offset {:+.4} +- {:.4} rad",
            1.0 + k,
            sk,
            k,
            b,
            sb
        );
    }
    if let Some(m) = s.scan_match {
        let mean_nis = if m.applied > 0 {
            format!("{:.2}", m.nis_sum / m.applied as f64)
        } else {
            "-".to_string()
        };
        let _ = writeln!(
            t,
            "  radar odometry: {} registrations tried, {} failed, {} applied (mean NIS {mean_nis}, 3 dof), {} gated",
            m.tried, m.failed, m.applied, m.gated
        );
        if let Some([x, y, h]) = m.truth_error() {
            let _ = writeln!(
                t,
                "  radar odometry vs the true motion ({} registrations, mean +- std): x {:+.4} +- {:.4} m, y {:+.4} +- {:.4} m, heading {:+.5} +- {:.5} rad",
                m.truth_compared, x.0, x.1, y.0, y.1, h.0, h.1
            );
        }
    }
    let bound = match s.spectrum_bound_db {
        Some((lo, hi)) => format!("the learned background's 3-sigma bound ({lo:.1}-{hi:.1} dB)"),
        None => "+-16.35 dB".to_string(),
    };
    match (s.spectrum.in_bound_fraction(), s.spectrum.bias_db()) {
        (Some(f), Some(b)) => {
            let _ = writeln!(
                t,
                "  spectrum prediction: {:.1}% of {} bins inside {bound} over {} beams with mapped features; bias (predicted - measured) {:+.2} dB{}",
                100.0 * f,
                s.spectrum.bins,
                s.spectrum.beams,
                b,
                s.learned_gain_db_per_decade
                    .map_or(String::new(), |g| format!("; learned compensation {g:.1} dB/decade"))
            );
        }
        _ => {
            let _ = writeln!(
                t,
                "  spectrum prediction: no beam with a mapped feature compared"
            );
        }
    }
    if s.features_in_view > 0 || s.extended_returns > 0 {
        let _ = writeln!(
            t,
            "  landmarks: {} extended returns kept out of the map ({:.1} per rotation); mapped features re-observed in {:.1}% of the later rotations with them in view ({} of {})",
            s.extended_returns,
            s.extended_returns as f64 / s.rotations.max(1) as f64,
            100.0 * s.features_reobserved as f64 / s.features_in_view.max(1) as f64,
            s.features_reobserved,
            s.features_in_view
        );
        if s.features_retired_unrepeatable > 0 {
            let _ = writeln!(
                t,
                "  unrepeatable features retired: {}",
                s.features_retired_unrepeatable
            );
        }
    }
    if let Some(sm) = &s.submaps {
        let g = &sm.global;
        let _ = writeln!(
            t,
            "  submaps: {} (largest {} features when closed), {} features frozen in {:.1} kB; global layer: {} loop closures from {} candidates ({} dropped as conflicting, {} after the solve, {} failed solves), {} solutions used, slowest join {:.1} ms",
            sm.submaps,
            sm.largest_submap_features,
            sm.frozen_features,
            sm.frozen_bytes as f64 / 1e3,
            sm.loop_closures,
            g.candidates,
            g.conflicting,
            g.rejected_after_solve,
            g.failed_solves,
            sm.solutions,
            g.max_add_ms
        );
        if let Some(o) = &sm.optimised {
            let _ = writeln!(
                t,
                "  global trajectory vs truth (trajectory.tum, final frames): RMS {:.3} m, max {:.3} m, final {:.3} m / {:.2} deg, heading RMS {:.2} deg; mean NEES {:.2}, inside 99% bound {:.1}%; drift over 100-800 m segments {} on {:.0} m driven; loop closures true {} / false {}",
                o.rms_m,
                o.max_m,
                o.final_m,
                o.final_heading_rad.to_degrees(),
                o.rms_heading_rad.to_degrees(),
                o.mean_nees,
                100.0 * o.inside_99,
                o.drift_percent.map_or("n/a (shorter drive)".to_string(), |d| format!("{d:.2}%")),
                o.length_m,
                sm.loops_true,
                sm.loops_false
            );
        }
    }
    let n = s.rotations.max(1) as f64;
    let _ = writeln!(
        t,
        "  time per rotation: mean {:.2} ms (detection {:.2}, filter {:.2}, spectrum {:.2}), p50 {:.2}, p99 {:.2}, max {:.2} ms; real-time factor {:.1}x on one thread",
        s.mean_rotation_ms(),
        s.detect_ms / n,
        s.filter_ms / n,
        s.spectrum_ms / n,
        s.rotation_ms_percentile(50.0),
        s.rotation_ms_percentile(99.0),
        s.max_rotation_ms,
        s.real_time_factor()
    );
    if let Some(mean) = s.mean_cpu_ms() {
        let _ = writeln!(
            t,
            "  pipeline thread CPU per rotation (its own work, without waits for a core): mean {:.2} ms, p50 {:.2}, p99 {:.2} over {} rotations",
            mean,
            s.cpu_ms_percentile(50.0),
            s.cpu_ms_percentile(99.0),
            s.cpu_rotations
        );
    }
    let _ = writeln!(
        t,
        "  refused beams: {} without odometry, {} with stale odometry, {} late; filter errors {}; radar stalls {}; odometry errors {}; output events dropped {}",
        s.refused.no_odometry,
        s.refused.stale_odometry,
        s.refused.late_beams,
        s.filter_errors,
        r.run.stalls,
        r.run.odometry_errors,
        r.run.output_drops
    );
    #[cfg(feature = "sim")]
    if let Some(rp) = &r.replay {
        let e = &rp.errors;
        let _ = writeln!(
            t,
            "  recorded drive ({}, {} scans, {} skipped as damaged): {:.1} m; odometry from the ground truth x{:.3} speed, {:+.3} rad/s yaw rate, noise {:.3} m/s / {:.4} rad/s (seed {}); ranges corrected for a range-Doppler coupling of {:.4} s",
            rp.format.map_or("-", |f| f.name()), rp.scans, rp.scans_skipped,
            rp.distance_m, e.speed_scale, e.yaw_rate_bias_rps, e.sigma_speed_mps, e.sigma_yaw_rate_rps, e.seed,
            rp.doppler_range_coupling_s
        );
        let filter = s
            .pose
            .as_ref()
            .map(|p| (p.rms_position_m(), p.final_position_m));
        let _ = writeln!(
            t,
            "  against the ground truth: filter RMS {} m, final {} m; dead reckoning with the same odometry RMS {:.3} m, final {:.3} m",
            filter.map_or("-".into(), |f| format!("{:.3}", f.0)),
            filter.map_or("-".into(), |f| format!("{:.3}", f.1)),
            rp.dead_reckoning_rms_m,
            rp.dead_reckoning_final_m
        );
        let _ = writeln!(
            t,
            "  features in the map {} ({:.0} per 100 m driven), detections {:.1} per rotation",
            s.map_size,
            100.0 * s.map_size as f64 / rp.distance_m.max(1e-9),
            s.detections as f64 / s.rotations.max(1) as f64
        );
    }
    if s.rotations_behind > 0 {
        let _ = writeln!(
            t,
            "  behind real time: {} of {} rotations took longer to process than the radar took to send them",
            s.rotations_behind, s.rotations
        );
    }
    if s.odometry_refused + s.odometry_clock_jumps + s.clock_outliers + s.clock_jumps > 0 {
        let _ = writeln!(
            t,
            "  untrusted input: {} odometry records refused (physical limits or wild time), {} odometry clock jumps resynchronised, {} azimuths with wild timestamps dropped, {} radar clock jumps resynchronised",
            s.odometry_refused, s.odometry_clock_jumps, s.clock_outliers, s.clock_jumps
        );
    }
    if s.odometry_duplicates > 0 {
        let _ = writeln!(
            t,
            "  odometry sent again (a reconnected source replaying): {} records dropped as duplicates",
            s.odometry_duplicates
        );
    }
    let names: Vec<String> = r
        .writer
        .files
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    let _ = writeln!(
        t,
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
    );
    if let Some(c) = &r.mcap_replay {
        let _ = writeln!(
            t,
            "  MCAP replay: {} messages, {} configurations, {} rotations, {} azimuths, {} odometry samples; {} on other topics; refused {} (unknown schema {}, wrong encoding {}, malformed {}, before a configuration {}){}",
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
                .map_or(String::new(), |e| format!("; the file ended early: {e}"))
        );
    }
    if let Some(z) = &r.zenoh_odometry {
        let _ = writeln!(
            t,
            "  Zenoh odometry on {}: {} samples received, {} taken; lost {} (malformed {}, another type {}, queue full {})",
            z.key,
            z.received,
            z.decoded,
            z.lost(),
            z.malformed,
            z.wrong_type,
            z.dropped
        );
    }
    if let Some(rec) = &r.writer.recording {
        let _ = writeln!(t, "{}", recording_line(rec));
    }
    if let Some(e) = &r.writer.recording_error {
        let _ = writeln!(t, "  MCAP recording stopped early: {e}");
    }
    if let Some(live) = &r.writer.live {
        let _ = writeln!(
            t,
            "  Zenoh: {} messages published on {} keys, {} events dropped (queue full), {} failed",
            live.total(),
            live.published.len(),
            live.dropped,
            live.failed
        );
    }
    t
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
