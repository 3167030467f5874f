//! The summary lines of a run that localised in a saved map, and of one that extended it.

use std::fmt;

use crate::pipeline::extend::ExtendSummary;
use crate::pipeline::localise::LocaliseSummary;
use crate::pipeline::submaps::SubmapSummary;

/// Localisation in a saved map: the map, the fix, and the published poses against the
/// truth when it is known.
pub(super) struct Localisation<'a>(pub &'a LocaliseSummary);

impl fmt::Display for Localisation<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let l = self.0;
        writeln!(
            f,
            "  localisation in {}: {} submaps, {} features, {} scan points, {} places; by its {}; {}",
            l.path,
            l.map_submaps,
            l.map_features,
            l.map_scan_points,
            l.places,
            l.by,
            if l.prior {
                "started from the prior pose"
            } else {
                "started without a prior (place recognition)"
            }
        )?;
        match l.time_to_fix_s {
            Some(t) if !l.prior => writeln!(
                f,
                "  first fix after {t:.1} s ({} rotations, {} search attempts, {} refused as places alike)",
                l.rotations_to_fix, l.attempts, l.ambiguous
            )?,
            Some(_) => {}
            None => writeln!(
                f,
                "  NO FIX: not localised in the map ({} search attempts, {} refused as places alike); no pose was published in the map's frame",
                l.attempts, l.ambiguous
            )?,
        }
        if l.by == "scans" {
            writeln!(
                f,
                "  the map against itself: {} pairs of submaps of different passes over the same streets, {} aligned scan to scan; their passes {:.2} m apart (median), {:.2} m at most; added to the published covariance where the vehicle is ({:.0} ms at load)",
                l.map_pairs_compared,
                l.map_pairs_aligned,
                l.map_offset_p50_m,
                l.map_offset_max_m,
                l.map_check_ms
            )?;
        }
        if l.priors_received > 0 {
            writeln!(
                f,
                "  prior poses from the topic: {} received, {} started tracking, {} refused (stamped outside the last {} s of poses kept); the first fix {}",
                l.priors_received,
                l.priors_applied,
                l.priors_refused,
                crate::pipeline::localise::RECENT_S,
                match l.time_to_fix_s {
                    Some(t) => format!("after {t:.1} s"),
                    None => "not taken".to_owned(),
                }
            )?;
        }
        if l.attempts > 0 {
            writeln!(
                f,
                "  place search on its own thread: {} attempts, wall time per attempt p50 {:.1} ms, max {:.1} ms (the pipeline thread never waits for it in real time)",
                l.attempts, l.search_ms_p50, l.search_ms_max
            )?;
        }
        if l.by == "scans" {
            writeln!(
                f,
                "  tracking by scans: {} rotations published in the map's frame; {} fixes, {} lost (no registration against the map's scans for 12 rotations); registrations fused {}, none found {}, outside the gate {} (re-anchored on agreeing ones {} times)",
                l.published, l.fixes, l.lost, l.track_fused, l.track_unregistered, l.track_gated, l.track_reanchored
            )?;
        } else {
            writeln!(
                f,
                "  tracking: {} rotations published in the map's frame; {} fixes, {} lost (no map feature seen for 12 rotations); map features put into the filter {}, taken out {}, refused {}",
                l.published, l.fixes, l.lost, l.inserted, l.removed, l.refused
            )?;
        }
        if let Some(s) = &l.score {
            writeln!(
                f,
                "  localisation vs truth over {} published poses: RMS along track {:.3} m, across {:.3} m, heading {:.3} deg; max {:.2} m; consistency score sqrt(e' inv(P) e / 3) mean {:.2} (Boreas; 1 = honest covariance); the first published pose off by {:.2} m, {:.2} deg",
                s.poses,
                s.along_rms_m,
                s.across_rms_m,
                s.heading_rms_rad.to_degrees(),
                s.max_m,
                s.consistency,
                s.first_error_m,
                s.first_heading_rad.to_degrees()
            )?;
        }
        Ok(())
    }
}

/// Extending a saved map: when mapping started, the join, and what the new drive added.
pub(super) struct Extension<'a>(pub &'a ExtendSummary, pub Option<&'a SubmapSummary>);

impl fmt::Display for Extension<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        let (Some(t), Some(k), Some(j), Some(sd)) =
            (x.mapping_after_s, x.joined_to, x.join, x.join_sigma)
        else {
            return writeln!(
                f,
                "  extend: NOT EXTENDED{} ({} saved submaps, {} loop closures, {} drives); no map saved",
                x.error
                    .as_ref()
                    .map_or(String::new(), |e| format!(": {e}")),
                x.saved_submaps,
                x.saved_loops,
                x.saved_drives
            );
        };
        writeln!(
            f,
            "  extend: mapping from {t:.1} s in the map's frame, joined to saved submap {k} at ({:.2} m, {:.2} m, {:.2} deg) +- ({:.3} m, {:.3} m, {:.3} deg); saved map {} submaps, {} loop closures, {} drives",
            j[0],
            j[1],
            j[2].to_degrees(),
            sd[0],
            sd[1],
            sd[2].to_degrees(),
            x.saved_submaps,
            x.saved_loops,
            x.saved_drives
        )?;
        if let Some(sm) = self.1 {
            writeln!(
                f,
                "  extend: {} new submaps; loop closures from new submaps to saved ones {}, in all {} (saved {})",
                sm.submaps.saturating_sub(x.saved_submaps),
                sm.loops_to_saved,
                sm.loop_closures,
                x.saved_loops
            )?;
        }
        Ok(())
    }
}
