//! Target detection in power-range spectra: every target down each beam, not only the
//! strongest, then one observation per target across neighbouring azimuths. No IO.
//!
//! Stages, one module each:
//! - [`cfar`]: cell-averaging and ordered-statistic CFAR thresholds;
//! - [`tpp`]: the authors' target presence probability (per-bin minimum tracking over
//!   scans, SNR test, recursive presence probability, alpha 0.1, detect at 0.8);
//! - [`peaks`]: clusters of detected bins, split at deep valleys, range by parabolic
//!   interpolation;
//! - [`grouping`]: detections in consecutive azimuths of one target become one
//!   observation (range, power-weighted bearing, power).
//!
//! The detectors run on the spectrum with the receiver's range compensation removed (the
//! caller subtracts the compensation gain bin by bin), so the peak powers they report are
//! the filter's uncompensated `P_i`.
//!
//! # Which detector is the default, and why
//!
//! Chosen by measurement on the simulator's scenes with `cargo test --release -p slam-node
//! --test detection_scoring -- --nocapture`, which renders rotations with known targets
//! through the simulator's own renderer and counts hits (a detection within two range cells of a true target
//! in its beam) and false alarms per rotation for each detector. The figures and the choice
//! are recorded in `slam-node/README.md` ("Detection").

pub mod cfar;
pub mod grouping;
pub mod learned;
pub mod line;
pub mod peaks;
pub mod tpp;

pub use grouping::{BeamDetection, Grouper, GroupingSettings, Observation};
pub use learned::{FloorSettings, GainLearner, GainSettings, LearnedFloor};
pub use line::{LineDetector, LinePeak, LineSettings};
pub use peaks::{Peak, PeakSettings};
pub use tpp::{Floor, Tpp, TppSettings};

use cfar::CfarWindow;

/// Which per-bin detector runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectorKind {
    /// Cell-averaging CFAR.
    CaCfar,
    /// Ordered-statistic CFAR.
    OsCfar,
    /// Target presence probability.
    Tpp,
    /// Line rate on the wire's 8-bit bins against the floor learned from the stream
    /// ([`learned`], [`line`]): for current units.
    Learned,
}

/// Which spectrum the per-bin detector looks at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectionDomain {
    /// As the radar sent it (range compensation applied).
    Measured,
    /// With the receiver's range compensation removed bin by bin.
    Uncompensated,
}

/// Everything that shapes detection in one beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorSettings {
    /// The per-bin detector.
    pub kind: DetectorKind,
    /// The spectrum it runs on.
    pub domain: DetectionDomain,
    /// CFAR window (both CFAR variants).
    pub window: CfarWindow,
    /// CA-CFAR threshold above the reference mean, dB.
    pub ca_scale_db: f64,
    /// OS-CFAR rank as a fraction of the reference cells.
    pub os_rank_fraction: f64,
    /// OS-CFAR threshold above the ranked cell, dB.
    pub os_scale_db: f64,
    /// TPP settings.
    pub tpp: TppSettings,
    /// Peak extraction.
    pub peaks: PeakSettings,
    /// Probability at which the floor's tail is set (see [`FloorProfile`]).
    pub floor_tail_pfa: f64,
    /// Detections nearer than this are ignored (antenna leakage), metres.
    pub min_range_m: f64,
    /// Detections farther than this are ignored (receiver roll-off), metres.
    pub max_range_m: f64,
    /// The learned floor ([`DetectorKind::Learned`]).
    pub floor: FloorSettings,
    /// The learned receiver gain ([`DetectorKind::Learned`]).
    pub gain: GainSettings,
    /// Which observations are landmarks.
    pub landmarks: LandmarkSettings,
}

/// Which observations may become point features: point-like returns only. A return
/// longer in range than `max_extent_m` down one beam (a wall or fence seen along it), or
/// wider than `max_width_beams` beam widths across azimuths (a wall seen face on), or the
/// continuation of such a group, is extended structure and is kept out of the map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandmarkSettings {
    /// Whether extended returns are kept out of the map (`false`: everything is offered).
    pub points_only: bool,
    /// Longest run in range down one beam that is still a point, metres.
    pub max_extent_m: f64,
    /// Widest group across azimuths that is still a point, beam widths.
    pub max_width_beams: f64,
    /// Weakest return over the floor that may become a point feature, dB; a weaker
    /// point-like return may still re-observe a mapped feature.
    pub min_snr_db: f64,
    /// A weaker point-like return is offered to the filter when it lies within this
    /// distance of a mapped feature (placed from the predicted pose), metres.
    pub reobserve_radius_m: f64,
    /// Whether an extended return within `reobserve_radius_m` of a mapped feature is
    /// offered too (its peak may re-observe the feature). Off by default: the peak of a
    /// wall, fence or car side is where the surface faces the radar, and it slides along the
    /// surface as the vehicle moves.
    pub extended_reobserve: bool,
}

impl Default for LandmarkSettings {
    fn default() -> Self {
        // As `[detector]`'s defaults: off, and when turned on, the limits measured on the
        // real scans (see slam-node/README.md, "Landmarks").
        Self {
            points_only: false,
            max_extent_m: 0.5,
            max_width_beams: 2.5,
            min_snr_db: 0.0,
            reobserve_radius_m: 2.0,
            extended_reobserve: false,
        }
    }
}

impl Default for DetectorSettings {
    fn default() -> Self {
        Self {
            kind: DetectorKind::Tpp,
            domain: DetectionDomain::Uncompensated,
            window: CfarWindow {
                reference_cells: 24,
                guard_cells: 4,
                min_reference_cells: 16,
            },
            ca_scale_db: 24.0,
            os_rank_fraction: 0.75,
            os_scale_db: 24.0,
            tpp: TppSettings::paper(),
            peaks: PeakSettings {
                merge_gap_bins: 1,
                min_prominence_db: 6.0,
                max_peaks: 16,
            },
            floor_tail_pfa: 1e-3,
            min_range_m: 2.0,
            max_range_m: 1.0e4,
            floor: FloorSettings::default(),
            gain: GainSettings::default(),
            landmarks: LandmarkSettings::default(),
        }
    }
}

/// Where the bins of a spectrum lie in range: `range_m(b) = first_bin_m + b * bin_m`
/// (the bin's centre).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeAxis {
    /// Range of bin 0, metres (the radar's range offset).
    pub first_bin_m: f64,
    /// Bin spacing, metres (range gain x bin size).
    pub bin_m: f64,
}

impl RangeAxis {
    /// Range of a (fractional) bin position.
    pub fn range_m(&self, bin: f64) -> f64 {
        self.first_bin_m + bin * self.bin_m
    }
}

/// One detected target down one beam.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Interpolated range, metres.
    pub range_m: f64,
    /// Interpolated peak power of the uncompensated spectrum, dB.
    pub power_db: f64,
    /// Interpolated bin position.
    pub bin: f64,
    /// Extent of the return in range down the beam (first to last bin over the
    /// detection threshold), metres.
    pub extent_m: f64,
    /// Peak over the floor's level there, dB (what the detector measured it against).
    pub snr_db: f64,
}

/// Runs the configured detector and peak extraction on one spectrum at a time, keeping
/// the detector's memory (TPP) and scratch buffers between calls.
#[derive(Debug)]
pub struct BeamDetector {
    settings: DetectorSettings,
    tpp: Tpp,
    thresholds_db: Vec<f64>,
    flags: Vec<bool>,
    snr_db: Vec<f64>,
    peaks: Vec<Peak>,
    work_db: Vec<f64>,
    floor_work: Vec<f64>,
}

impl BeamDetector {
    /// A detector for rotations of `azimuths` spectra (TPP keeps one slot per azimuth).
    pub fn new(settings: DetectorSettings, azimuths: usize) -> Self {
        let slots = if settings.kind == DetectorKind::Tpp {
            azimuths
        } else {
            0
        };
        Self {
            settings,
            tpp: Tpp::new(settings.tpp, slots),
            thresholds_db: Vec::new(),
            flags: Vec::new(),
            snr_db: Vec::new(),
            peaks: Vec::new(),
            work_db: Vec::new(),
            floor_work: Vec::new(),
        }
    }

    /// The settings in force.
    pub fn settings(&self) -> &DetectorSettings {
        &self.settings
    }

    /// Per-bin detection flags of the last spectrum (for diagnostics and figures).
    pub fn last_flags(&self) -> &[bool] {
        &self.flags
    }

    /// Detects the targets in one measured spectrum (dB, as the radar sent it) of azimuth
    /// slot `slot`, with `gain_db` the receiver's compensation gain per bin (same length)
    /// and `floor` the expected target-absent level of the measured spectrum per bin and its
    /// tail when known (TPP uses them, see [`Tpp::process`]); appends the targets to `out` in range
    /// order with their uncompensated powers.
    pub fn detect(
        &mut self,
        slot: usize,
        measured_db: &[f64],
        gain_db: &[f64],
        floor: Option<Floor<'_>>,
        axis: &RangeAxis,
        out: &mut Vec<Detection>,
    ) {
        let s = self.settings;
        let n = measured_db.len().min(gain_db.len());
        self.work_db.clear();
        match s.domain {
            DetectionDomain::Measured => self.work_db.extend(measured_db.iter().take(n)),
            DetectionDomain::Uncompensated => self
                .work_db
                .extend(measured_db.iter().zip(gain_db).map(|(m, g)| m - g)),
        }
        if let Some(floor) = floor.map(|f| f.mean_db) {
            self.floor_work.clear();
            match s.domain {
                DetectionDomain::Measured => self.floor_work.extend(floor.iter().take(n)),
                DetectionDomain::Uncompensated => self
                    .floor_work
                    .extend(floor.iter().zip(gain_db).take(n).map(|(f, g)| f - g)),
            }
        }
        let floor_work = floor.map(|f| Floor {
            mean_db: self.floor_work.as_slice(),
            tail_db: f.tail_db.get(..n).unwrap_or_default(),
        });
        let work = &self.work_db;
        match s.kind {
            DetectorKind::CaCfar => {
                cfar::ca_cfar_thresholds(work, &s.window, s.ca_scale_db, &mut self.thresholds_db)
            }
            DetectorKind::OsCfar => cfar::os_cfar_thresholds(
                work,
                &s.window,
                s.os_rank_fraction,
                s.os_scale_db,
                &mut self.thresholds_db,
            ),
            // The learned detector runs in the front end on the wire's bins; handed f64
            // spectra here it falls back to TPP.
            DetectorKind::Tpp | DetectorKind::Learned => {
                self.tpp
                    .process(slot, work, floor_work, &mut self.flags, &mut self.snr_db);
            }
        }
        if !matches!(s.kind, DetectorKind::Tpp | DetectorKind::Learned) {
            self.flags.clear();
            self.flags
                .extend(work.iter().zip(&self.thresholds_db).map(|(p, t)| p > t));
        }
        // Blank the bins outside the usable range interval.
        for (b, f) in self.flags.iter_mut().enumerate() {
            let r = axis.range_m(b as f64);
            if r < s.min_range_m || r > s.max_range_m {
                *f = false;
            }
        }
        self.peaks.clear();
        peaks::extract_peaks(work, &self.flags, &s.peaks, &mut self.peaks);
        out.extend(self.peaks.iter().map(|p| {
            let power_db = match s.domain {
                DetectionDomain::Uncompensated => p.power_db,
                DetectionDomain::Measured => p.power_db - interpolate(gain_db, p.bin),
            };
            Detection {
                range_m: axis.range_m(p.bin),
                power_db,
                bin: p.bin,
                extent_m: (p.last_bin + 1 - p.first_bin.min(p.last_bin)) as f64 * axis.bin_m,
                snr_db: f64::INFINITY,
            }
        }));
    }
}

/// The floor's mean and tail per bin of a spectrum model: `tail = Q(1 - pfa) - mean`,
/// `Q` the target-absent floor's quantile at the bin's range (radar-model's noise model).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FloorProfile {
    /// Mean floor, dB (measured domain).
    pub mean_db: Vec<f64>,
    /// Tail above the mean, dB.
    pub tail_db: Vec<f64>,
}

impl FloorProfile {
    /// Tabulates the floor of `model` with the tail at per-bin probability `pfa`.
    pub fn new(
        model: &radar_model::spectrum::SpectrumModel,
        absent: &radar_model::noise::TargetAbsentNoise,
        pfa: f64,
    ) -> Self {
        let g = model.geometry();
        let e = -pfa.clamp(1e-300, 1.0).ln();
        let mean_db = model.floor_mean_db().to_vec();
        let tail_db = (0..g.bins)
            .zip(&mean_db)
            .map(|(b, m)| absent.distribution_at(g.bin_range_m(b)).from_exp1(e) - m)
            .collect();
        Self { mean_db, tail_db }
    }

    /// The first `n` bins as a [`Floor`].
    pub fn floor(&self, n: usize) -> Option<Floor<'_>> {
        Some(Floor {
            mean_db: self.mean_db.get(..n)?,
            tail_db: self.tail_db.get(..n)?,
        })
    }
}

/// Linear interpolation of a per-bin table at a fractional bin (clamped to the table; a
/// non-finite bin reads bin 0).
pub(crate) fn interpolate(table: &[f64], bin: f64) -> f64 {
    let last = table.len().saturating_sub(1);
    let b = if bin.is_finite() {
        bin.clamp(0.0, last as f64)
    } else {
        0.0
    };
    let lo = b.floor() as usize;
    let hi = (lo + 1).min(last);
    let f = b - lo as f64;
    match (table.get(lo), table.get(hi)) {
        (Some(a), Some(c)) => a + f * (c - a),
        _ => 0.0,
    }
}
