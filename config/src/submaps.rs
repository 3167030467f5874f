//! `[submaps]`: local submaps of bounded size joined by a global pose graph with loop
//! closures (slam-filter's `submap`, slam-graph). Off, the filter is one dense map for the
//! whole drive, whose cost grows with the square of everything mapped.

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{Capacity, OpenProbability, PositiveF64, Probability};

/// The most features one submap may be set to hold.
pub const MAX_SUBMAP_FEATURES: usize = 5000;

/// The most submaps back a near link may reach (`[submaps] near_links`): each costs a scan
/// registration a submap on the global layer's thread.
pub const MAX_NEAR_LINKS: u64 = 8;

/// `[submaps]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawSubmaps {
    /// Run the filter on local submaps. Default false (one dense map).
    pub enabled: bool,
    /// Close a submap after the vehicle has driven this far in it (m). Default 100.
    pub max_distance_m: f64,
    /// Close a submap once it holds this many features. Default 150.
    pub max_features: i64,
    /// Look for loop closures between submaps. Default true.
    pub loop_closure: bool,
    /// Fewest features matched to accept a loop closure. Default 6.
    pub min_matches: i64,
    /// A rival transform explaining at least this share of the best's matches refuses the
    /// closure (repeated structure). Default 0.6.
    pub max_rival_ratio: f64,
    /// Earlier submaps are loop-closure candidates within this many standard deviations of
    /// the relative position. Default 3.
    pub search_sigmas: f64,
    /// Earlier submaps are also loop-closure candidates when their place descriptor matches
    /// the new one's (slam-graph's `places`), however far the pose estimate puts them; the
    /// verifier decides either way. Default true.
    pub place_recognition: bool,
    /// Each submap also keeps its scan (radar odometry's registered returns, walls and
    /// fences included, one per metre cell), and loop closures between two submaps with
    /// scans are verified by registering the scans (slam-graph's `scans`) rather than by
    /// the few point features a city of extended objects leaves. Needs radar odometry;
    /// without it the features verify as before. Default true.
    pub scan_loop_closure: bool,
    /// Each submap's scan is also registered against the scans of the submaps two to this
    /// many before it, where the chain puts them within 120 m, and each registration that
    /// agrees with the chain is an edge of the global graph (a near link, not a loop
    /// closure): the heading the chain gathers through a junction, where a rotation's
    /// registration pairs few returns, is measured over the whole street. Needs
    /// `scan_loop_closure`. 0 or 1: none. Default 3.
    pub near_links: i64,
    /// A near link enters the graph with the registration's covariance times this (at
    /// least 1): the registration's covariance counts every paired return as independent,
    /// and a link's error against the truth is larger than it says (the summary's `graph
    /// edges vs truth` line). Default 1.
    pub near_link_covariance_scale: f64,
    /// A near link, or a loop closure verified by the scans, registers two submaps' scans,
    /// each its rotations placed by the filter, whose placement error grows along the
    /// submap to the end pose's: the edge's covariance adds this share of each submap's
    /// end covariance (1/3: the mean of a random walk), the error the registration's own
    /// covariance does not hold. In [0, 1]; 0: the registration's alone. Default 1/3.
    pub scan_smear: f64,
}

impl Default for RawSubmaps {
    fn default() -> Self {
        Self {
            enabled: false,
            max_distance_m: 100.0,
            max_features: 150,
            loop_closure: true,
            min_matches: 6,
            max_rival_ratio: 0.6,
            search_sigmas: 3.0,
            place_recognition: true,
            scan_loop_closure: true,
            near_links: 3,
            near_link_covariance_scale: 1.0,
            scan_smear: 1.0 / 3.0,
        }
    }
}

/// `[submaps]`, validated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubmapSettings {
    /// Run on submaps.
    pub enabled: bool,
    /// Distance limit (m).
    pub max_distance_m: PositiveF64,
    /// Feature limit.
    pub max_features: Capacity,
    /// Loop closure on.
    pub loop_closure: bool,
    /// Fewest matches (at least 3: a 2-D transform has 3 degrees of freedom).
    pub min_matches: Capacity,
    /// Rival ratio, in (0, 1).
    pub max_rival_ratio: OpenProbability,
    /// Search width in standard deviations.
    pub search_sigmas: PositiveF64,
    /// Candidates from place descriptors too.
    pub place_recognition: bool,
    /// Loop closures verified by the submaps' scans where they have them.
    pub scan_loop_closure: bool,
    /// Near links: submaps back (0 or 1: none).
    pub near_links: u64,
    /// A near link's covariance over its registration's (at least 1).
    pub near_link_covariance_scale: PositiveF64,
    /// Share of each submap's end covariance a scan edge adds, in [0, 1].
    pub scan_smear: Probability,
}

impl Default for SubmapSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let s = RawSubmaps::default().check(&mut c);
        debug_assert!(c.is_clean(), "the defaults must be valid");
        s
    }
}

impl RawSubmaps {
    /// Validates this section alone; errors name `submaps.<field>`.
    pub fn validate(&self) -> Result<SubmapSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> SubmapSettings {
        let min_matches = c.check("submaps.min_matches", Capacity::new(self.min_matches, 1000));
        if (1..3).contains(&self.min_matches) {
            c.fail(
                "submaps.min_matches",
                crate::values::ValueError::Rule("must be at least 3".into()),
            );
        }
        let max_features = c.check(
            "submaps.max_features",
            Capacity::new(self.max_features, MAX_SUBMAP_FEATURES),
        );
        // A submap closed with fewer features than a loop closure must match can never be
        // matched, and one of a feature or two closes at nearly every rotation (issue 38:
        // `max_features = 1` was taken without a word). Checked only when both fields are
        // valid on their own, so a mistake is reported once.
        if Capacity::new(self.max_features, MAX_SUBMAP_FEATURES).is_ok()
            && self.min_matches >= 3
            && Capacity::new(self.min_matches, 1000).is_ok()
            && self.max_features < self.min_matches
        {
            c.fail(
                "submaps.max_features",
                crate::values::ValueError::Rule(format!(
                    "must be at least submaps.min_matches ({}): a submap closed with fewer \
                     features can never be matched in a loop closure, got {}",
                    self.min_matches, self.max_features
                )),
            );
        }
        let near_link_covariance_scale = c.check(
            "submaps.near_link_covariance_scale",
            PositiveF64::new(self.near_link_covariance_scale),
        );
        if self.near_link_covariance_scale > 0.0 && self.near_link_covariance_scale < 1.0 {
            c.fail(
                "submaps.near_link_covariance_scale",
                crate::values::ValueError::Rule(format!(
                    "must be at least 1 (a link surer than its own registration), got {}",
                    self.near_link_covariance_scale
                )),
            );
        }
        SubmapSettings {
            enabled: self.enabled,
            max_distance_m: c.check(
                "submaps.max_distance_m",
                PositiveF64::new(self.max_distance_m),
            ),
            max_features,
            loop_closure: self.loop_closure,
            min_matches,
            max_rival_ratio: c.check(
                "submaps.max_rival_ratio",
                OpenProbability::new(self.max_rival_ratio),
            ),
            search_sigmas: c.check(
                "submaps.search_sigmas",
                PositiveF64::new(self.search_sigmas),
            ),
            place_recognition: self.place_recognition,
            scan_loop_closure: self.scan_loop_closure,
            near_links: c.check(
                "submaps.near_links",
                crate::values::count(self.near_links, MAX_NEAR_LINKS),
            ),
            near_link_covariance_scale,
            scan_smear: c.check("submaps.scan_smear", Probability::new(self.scan_smear)),
        }
    }
}

impl From<&SubmapSettings> for RawSubmaps {
    fn from(s: &SubmapSettings) -> Self {
        Self {
            enabled: s.enabled,
            max_distance_m: s.max_distance_m.get(),
            max_features: s.max_features.get() as i64,
            loop_closure: s.loop_closure,
            min_matches: s.min_matches.get() as i64,
            max_rival_ratio: s.max_rival_ratio.get(),
            search_sigmas: s.search_sigmas.get(),
            place_recognition: s.place_recognition,
            near_links: s.near_links as i64,
            near_link_covariance_scale: s.near_link_covariance_scale.get(),
            scan_smear: s.scan_smear.get(),
            scan_loop_closure: s.scan_loop_closure,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_submap_settings_are_named() {
        let raw = RawSubmaps {
            max_distance_m: -1.0,
            max_features: 0,
            min_matches: 2,
            max_rival_ratio: 1.5,
            search_sigmas: f64::NAN,
            ..RawSubmaps::default()
        };
        let errors = raw.validate().unwrap_err().to_string();
        for field in [
            "submaps.max_distance_m",
            "submaps.max_features",
            "submaps.min_matches",
            "submaps.max_rival_ratio",
            "submaps.search_sigmas",
        ] {
            assert!(errors.contains(field), "{field} missing from {errors}");
        }
    }

    #[test]
    fn defaults_round_trip() {
        let s = SubmapSettings::default();
        assert_eq!(RawSubmaps::from(&s).validate().unwrap(), s);
        assert!(!s.enabled);
    }
}
