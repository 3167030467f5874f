//! `[detector]`: which detector finds the targets down each beam, and its parameters.

use serde::{Deserialize, Serialize};

use crate::check::Checker;
use crate::error::FieldErrors;
use crate::values::{
    Capacity, FiniteF64, NonNegativeF64, OpenProbability, PositiveF64, Probability, ValueError,
};

/// Most reference cells a CFAR window may have.
pub const MAX_REFERENCE_CELLS: usize = 4096;
/// Most guard cells.
pub const MAX_GUARD_CELLS: u64 = 4096;
/// Most targets kept per beam.
pub const MAX_TARGETS_PER_BEAM: usize = 1024;
/// Largest detector state budget, MiB.
pub const MAX_STATE_MIB: usize = 16_384;
/// Default CFAR false-alarm probability.
pub const DEFAULT_PFA: f64 = 1e-4;

/// The detector.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DetectorKind {
    /// Cell-averaging CFAR.
    CaCfar,
    /// Ordered-statistic CFAR (`os_rank`-th smallest reference cell).
    OsCfar,
    /// The authors' target presence probability.
    Tpp,
    /// For current units: detection at line rate on the wire's 8-bit bins against a noise
    /// floor and receiver gain learned from the stream (robust statistics over recent
    /// azimuths) instead of the paper unit's measured noise and compensation.
    Learned,
}

/// How the detection threshold is set: by a false-alarm probability or a fixed margin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Threshold {
    /// False-alarm probability, `(0, 1)`.
    Pfa(OpenProbability),
    /// Fixed margin over the noise estimate, dB.
    Db(FiniteF64),
}

/// `[detector]` as written in the file.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct RawDetector {
    /// `"ca-cfar"`, `"os-cfar"` or `"tpp"`. Default `"tpp"`: on the simulator's outdoor field it
    /// detected 0.977 of targets at 1.8 false alarms a rotation, against 0.921 at 7.7 for
    /// CA-CFAR and 0.951 at 10.6 for OS-CFAR, and it finds both targets of the penetration
    /// scene where CA-CFAR's 70-cell window misses the second (slam-node's `detection_scoring`).
    pub kind: DetectorKind,
    /// Reference cells (both sides together), `[1, 4096]`. Default 70 (book chapter).
    pub reference_cells: i64,
    /// Guard cells on each side, `[0, 4096]`. Default 2.
    pub guard_cells: i64,
    /// False-alarm probability in `(0, 1)`; set this or `threshold_db`, not both. Default
    /// 1e-4 when neither is set.
    pub pfa: Option<f64>,
    /// Fixed threshold over the noise estimate, dB; instead of `pfa`.
    pub threshold_db: Option<f64>,
    /// OS-CFAR rank, `[1, reference_cells]`. Default 3/4 of `reference_cells`, rounded.
    pub os_rank: Option<i64>,
    /// TPP recursive smoothing factor, `(0, 1)`. Default 0.1.
    pub tpp_alpha: f64,
    /// TPP presence probability at which a target is declared, `[0, 1]`. Default 0.8.
    pub tpp_detect: f64,
    /// Most targets kept per beam, `[1, 1024]`. Default 16.
    pub max_targets_per_beam: i64,
    /// Memory the detector may keep across rotations (TPP: 16 bytes per bin per azimuth),
    /// MiB in [1, 16384]. A radar whose announced geometry needs more is refused with a clear
    /// error instead of being allocated. Default 256 (a CTS350-X needs 23).
    pub max_state_mib: i64,
    /// Nearest range searched, m >= 0. Default 1.
    pub min_range_m: f64,
    /// Farthest range searched, m > `min_range_m`. Default 200.
    pub max_range_m: f64,
    /// `learned`: a bin is detected `floor_sigma` learned standard deviations above the
    /// learned floor's median, > 0. Default 4.
    pub floor_sigma: f64,
    /// `learned`: and at least this many dB above it, >= 0. Default 12.
    pub floor_min_snr_db: f64,
    /// Keep extended returns (walls, fences, hedges, parked cars) out of the map: only
    /// point-like returns may become features. Default false (the paper's unit and the
    /// point-target simulator); true in `config/examples/vehicle.toml` for current units.
    pub points_only: bool,
    /// Longest run over the threshold down one beam that is still point-like, m > 0.
    /// Default 0.5.
    pub point_max_extent_m: f64,
    /// Widest group across neighbouring azimuths that is still point-like, in beam widths
    /// (positive). Default 2.5.
    pub point_max_width_beams: f64,
    /// Weakest point-like return over the learned floor that may start a new feature, dB,
    /// at least 0; weaker point-like returns near a mapped feature only re-observe it. Default 0
    /// (every point-like return may start one); 32 for current units (the replay of real
    /// scans and `config/examples/vehicle.toml`).
    pub point_min_snr_db: f64,
    /// With `points_only`: an extended return near a mapped feature may re-observe it (its
    /// peak taken as the feature's). Default false: an extended return's peak is where the
    /// surface faces the radar, which slides along it as the vehicle moves, so it is kept
    /// out of the filter altogether (slam-node/README.md, "Landmarks, not clutter").
    pub extended_reobserve: bool,
}

impl Default for RawDetector {
    fn default() -> Self {
        Self {
            kind: DetectorKind::Tpp,
            reference_cells: 70,
            guard_cells: 2,
            pfa: None,
            threshold_db: None,
            os_rank: None,
            tpp_alpha: 0.1,
            tpp_detect: 0.8,
            max_targets_per_beam: 16,
            max_state_mib: 256,
            min_range_m: 1.0,
            max_range_m: 200.0,
            floor_sigma: 4.0,
            floor_min_snr_db: 12.0,
            points_only: false,
            point_max_extent_m: 0.5,
            point_max_width_beams: 2.5,
            point_min_snr_db: 0.0,
            extended_reobserve: false,
        }
    }
}

/// The ranges searched: `min_m < max_m` always holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeWindow {
    min_m: NonNegativeF64,
    max_m: PositiveF64,
}

impl RangeWindow {
    /// A window; `min_m` must be below `max_m`.
    pub fn new(min_m: NonNegativeF64, max_m: PositiveF64) -> Result<Self, ValueError> {
        if min_m.get() < max_m.get() {
            Ok(Self { min_m, max_m })
        } else {
            Err(ValueError::Rule(format!(
                "must be < detector.max_range_m ({max_m}), got {min_m}"
            )))
        }
    }
    /// Nearest range, m.
    pub fn min_m(&self) -> f64 {
        self.min_m.get()
    }
    /// Farthest range, m.
    pub fn max_m(&self) -> f64 {
        self.max_m.get()
    }
}

/// `[detector]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectorSettings {
    /// Detector.
    pub kind: DetectorKind,
    /// Reference cells, both sides together.
    pub reference_cells: Capacity,
    /// Guard cells per side.
    pub guard_cells: usize,
    /// Threshold.
    pub threshold: Threshold,
    /// OS-CFAR rank, `1..=reference_cells`.
    pub os_rank: Capacity,
    /// TPP smoothing factor.
    pub tpp_alpha: OpenProbability,
    /// TPP detection probability.
    pub tpp_detect: Probability,
    /// Most targets per beam.
    pub max_targets_per_beam: Capacity,
    /// Memory the detector may keep, MiB.
    pub max_state_mib: Capacity,
    /// Ranges searched.
    pub range: RangeWindow,
    /// Learned floor: sigmas above the median for a detection.
    pub floor_sigma: PositiveF64,
    /// Learned floor: least SNR for a detection, dB.
    pub floor_min_snr_db: NonNegativeF64,
    /// Only point-like returns become features.
    pub points_only: bool,
    /// Longest point-like run in range, m.
    pub point_max_extent_m: PositiveF64,
    /// Widest point-like group, beam widths.
    pub point_max_width_beams: PositiveF64,
    /// Weakest point-like return that may start a feature, dB.
    pub point_min_snr_db: NonNegativeF64,
    /// Extended returns near a mapped feature may re-observe it.
    pub extended_reobserve: bool,
}

impl Default for DetectorSettings {
    fn default() -> Self {
        let mut c = Checker::new();
        let settings = RawDetector::default().check(&mut c);
        debug_assert!(c.is_clean(), "the [detector] defaults must be valid");
        settings
    }
}

impl RawDetector {
    /// Validates this section alone; errors name `detector.<field>`.
    pub fn validate(&self) -> Result<DetectorSettings, FieldErrors> {
        let mut c = Checker::new();
        let settings = self.check(&mut c);
        c.finish(settings)
    }

    pub(crate) fn check(&self, c: &mut Checker) -> DetectorSettings {
        let reference_cells = c.check_ok(
            "detector.reference_cells",
            Capacity::new(self.reference_cells, MAX_REFERENCE_CELLS),
        );
        let threshold = match (self.pfa, self.threshold_db) {
            (Some(_), Some(_)) => {
                c.fail(
                    "detector.threshold_db",
                    ValueError::Rule("cannot be set together with detector.pfa".into()),
                );
                Threshold::Pfa(OpenProbability::HALF)
            }
            (None, Some(db)) => Threshold::Db(c.check("detector.threshold_db", FiniteF64::new(db))),
            (pfa, None) => Threshold::Pfa(c.check(
                "detector.pfa",
                OpenProbability::new(pfa.unwrap_or(DEFAULT_PFA)),
            )),
        };
        // The rank is checked against the window only when the window itself is valid.
        let os_rank = match (reference_cells, self.os_rank) {
            (Some(cells), None) => Capacity::new(
                i64::try_from((cells.get() * 3).div_ceil(4)).unwrap_or(1),
                cells.get(),
            )
            .unwrap_or(Capacity::ONE),
            (Some(cells), Some(rank)) => {
                c.check("detector.os_rank", Capacity::new(rank, cells.get()))
            }
            (None, Some(rank)) => {
                c.check("detector.os_rank", Capacity::new(rank, MAX_REFERENCE_CELLS))
            }
            (None, None) => Capacity::ONE,
        };
        let min = c.check_ok(
            "detector.min_range_m",
            NonNegativeF64::new(self.min_range_m),
        );
        let max = c.check_ok("detector.max_range_m", PositiveF64::new(self.max_range_m));
        let fallback = RangeWindow {
            min_m: NonNegativeF64::ZERO,
            max_m: PositiveF64::ONE,
        };
        let range = match (min, max) {
            (Some(min), Some(max)) => c
                .check_ok("detector.min_range_m", RangeWindow::new(min, max))
                .unwrap_or(fallback),
            _ => fallback,
        };
        DetectorSettings {
            kind: self.kind,
            reference_cells: reference_cells.unwrap_or(Capacity::ONE),
            guard_cells: c.check(
                "detector.guard_cells",
                crate::values::count(self.guard_cells, MAX_GUARD_CELLS)
                    .map(|v| usize::try_from(v).unwrap_or(0)),
            ),
            threshold,
            os_rank,
            tpp_alpha: c.check("detector.tpp_alpha", OpenProbability::new(self.tpp_alpha)),
            tpp_detect: c.check("detector.tpp_detect", Probability::new(self.tpp_detect)),
            max_targets_per_beam: c.check(
                "detector.max_targets_per_beam",
                Capacity::new(self.max_targets_per_beam, MAX_TARGETS_PER_BEAM),
            ),
            max_state_mib: c.check(
                "detector.max_state_mib",
                Capacity::new(self.max_state_mib, MAX_STATE_MIB),
            ),
            range,
            floor_sigma: c.check("detector.floor_sigma", PositiveF64::new(self.floor_sigma)),
            floor_min_snr_db: c.check(
                "detector.floor_min_snr_db",
                NonNegativeF64::new(self.floor_min_snr_db),
            ),
            points_only: self.points_only,
            point_max_extent_m: c.check(
                "detector.point_max_extent_m",
                PositiveF64::new(self.point_max_extent_m),
            ),
            point_max_width_beams: c.check(
                "detector.point_max_width_beams",
                PositiveF64::new(self.point_max_width_beams),
            ),
            point_min_snr_db: c.check(
                "detector.point_min_snr_db",
                NonNegativeF64::new(self.point_min_snr_db),
            ),
            extended_reobserve: self.extended_reobserve,
        }
    }
}

impl From<&DetectorSettings> for RawDetector {
    /// The settings written back out.
    fn from(s: &DetectorSettings) -> Self {
        let (pfa, threshold_db) = match s.threshold {
            Threshold::Pfa(p) => (Some(p.get()), None),
            Threshold::Db(db) => (None, Some(db.get())),
        };
        Self {
            kind: s.kind,
            reference_cells: crate::values::as_i64(s.reference_cells.get()),
            guard_cells: crate::values::as_i64(s.guard_cells),
            pfa,
            threshold_db,
            os_rank: Some(crate::values::as_i64(s.os_rank.get())),
            tpp_alpha: s.tpp_alpha.get(),
            tpp_detect: s.tpp_detect.get(),
            max_targets_per_beam: crate::values::as_i64(s.max_targets_per_beam.get()),
            max_state_mib: crate::values::as_i64(s.max_state_mib.get()),
            min_range_m: s.range.min_m(),
            max_range_m: s.range.max_m(),
            floor_sigma: s.floor_sigma.get(),
            floor_min_snr_db: s.floor_min_snr_db.get(),
            points_only: s.points_only,
            point_max_extent_m: s.point_max_extent_m.get(),
            point_max_width_beams: s.point_max_width_beams.get(),
            point_min_snr_db: s.point_min_snr_db.get(),
            extended_reobserve: s.extended_reobserve,
        }
    }
}
