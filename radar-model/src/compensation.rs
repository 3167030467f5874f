//! Receiver range compensation: the gain (dB) the radar's high-pass filter applies at each
//! range, so that measured (wire) power = uncompensated power + gain. Three curves:
//! 40 dB/decade (ideal: cancels the `R^-4` of the radar equation), the paper's 60 dB/decade
//! (its model of its unit's filter), or a measured gain table interpolated linearly in
//! `log10(range)`. A low-pass roll-off `-10 log10(1 + (R / R_c)^(2n))` (Butterworth
//! magnitude, corner `R_c`, order `n`) pulls power down near the end of the range.
//!
//! # Calibration
//!
//! [`Compensation::calibrated`] chooses the gain at the reference range so that a lone
//! target with `rho = 1` (RCS `A_I`) and `L = 0 dB` measures [`CALIBRATED_LEVEL_DB`] = 80 dB
//! there (before roll-off); under 40 dB/decade it measures 80 dB at every range, a 1 m^2
//! target (`rho = 0.005` with `A_I = 200 m^2`) 57 dB, both well inside the 8-bit wire's
//! 0 to 127.5 dB and above the target-absent floor (0 to 25 dB, see `noise`).

use crate::error::{finite, ModelError};
use crate::power::RadarConstants;

/// Wire level (dB) of a `rho = 1`, `L = 0` target at the reference range.
pub const CALIBRATED_LEVEL_DB: f64 = 80.0;
/// Default reference range (m) of the slope curves.
pub const DEFAULT_REFERENCE_RANGE_M: f64 = 10.0;
/// Ranges below this (m) are treated as this for the slope curves (the gain of a
/// high-pass filter does not go to minus infinity).
pub const MIN_COMPENSATION_RANGE_M: f64 = 0.25;

/// A measured gain table: gains (dB) at increasing ranges (m), interpolated linearly in
/// `log10(range)`, held flat beyond both ends.
#[derive(Debug, Clone, PartialEq)]
pub struct GainTable {
    log_range: Vec<f64>,
    gain_db: Vec<f64>,
}

impl GainTable {
    /// Builds a table from `(range_m, gain_db)` pairs.
    ///
    /// # Errors
    /// Fewer than two points, non-finite values, non-positive or non-increasing ranges.
    pub fn new(points: &[(f64, f64)]) -> Result<Self, ModelError> {
        if points.len() < 2 {
            return Err(ModelError::InvalidTable {
                reason: "needs at least two points",
            });
        }
        let mut log_range = Vec::with_capacity(points.len());
        let mut gain_db = Vec::with_capacity(points.len());
        for &(r, g) in points {
            if !(r.is_finite() && g.is_finite()) {
                return Err(ModelError::InvalidTable {
                    reason: "non-finite value",
                });
            }
            if r <= 0.0 {
                return Err(ModelError::InvalidTable {
                    reason: "ranges must be positive",
                });
            }
            let lr = r.log10();
            if log_range.last().is_some_and(|&last| lr <= last) {
                return Err(ModelError::InvalidTable {
                    reason: "ranges must increase strictly",
                });
            }
            log_range.push(lr);
            gain_db.push(g);
        }
        Ok(Self { log_range, gain_db })
    }

    /// Interpolated gain (dB) at `range_m`.
    pub fn gain_db(&self, range_m: f64) -> f64 {
        let lr = range_m.max(f64::MIN_POSITIVE).log10();
        let n = self.log_range.len();
        // partition_point: first index with log_range > lr.
        let hi = self.log_range.partition_point(|&x| x <= lr);
        match hi {
            0 => self.gain_db.first().copied().unwrap_or(0.0),
            h if h >= n => self.gain_db.last().copied().unwrap_or(0.0),
            h => {
                let (x0, x1) = (self.log_range[h - 1], self.log_range[h]);
                let (g0, g1) = (self.gain_db[h - 1], self.gain_db[h]);
                g0 + (g1 - g0) * (lr - x0) / (x1 - x0)
            }
        }
    }
}

/// The high-pass part of the compensation.
#[derive(Debug, Clone, PartialEq)]
pub enum GainCurve {
    /// `gain_at_reference_db + db_per_decade * log10(R / reference_range_m)`.
    Slope {
        /// 40 (ideal) or 60 (the paper's unit).
        db_per_decade: f64,
        /// Reference range (m).
        reference_range_m: f64,
        /// Gain at the reference range (dB).
        gain_at_reference_db: f64,
    },
    /// Measured gains.
    Table(GainTable),
}

/// Low-pass roll-off near the end of range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RollOff {
    /// Corner range (m) where the loss is 3 dB (about 200 m on the paper's unit).
    pub corner_m: f64,
    /// Filter order `n`.
    pub order: u8,
}

impl RollOff {
    /// Attenuation (dB, <= 0) at `range_m`: `-10 log10(1 + (R / R_c)^(2n))`, evaluated
    /// through `l = 2n ln(R / R_c)` so that no order or range overflows.
    pub fn gain_db(&self, range_m: f64) -> f64 {
        let l = 2.0 * f64::from(self.order) * (range_m.max(0.0) / self.corner_m).ln();
        let db = 10.0 / std::f64::consts::LN_10;
        if l > 40.0 {
            // ln(1 + e^l) = l + ln(1 + e^-l), and e^-40 is below f64 resolution of l.
            -db * l
        } else {
            -db * l.exp().ln_1p()
        }
    }
}

/// Receiver range compensation: measured dB = uncompensated dB + [`Compensation::gain_db`].
#[derive(Debug, Clone, PartialEq)]
pub struct Compensation {
    /// The high-pass curve.
    pub curve: GainCurve,
    /// Optional low-pass roll-off.
    pub rolloff: Option<RollOff>,
}

impl Default for Compensation {
    /// 40 dB/decade calibrated with the default constants, roll-off at 200 m, order 4.
    fn default() -> Self {
        Self::calibrated(40.0, &RadarConstants::default())
    }
}

impl Compensation {
    /// A slope curve calibrated as the module doc says, with the default roll-off
    /// (200 m, order 4).
    pub fn calibrated(db_per_decade: f64, constants: &RadarConstants) -> Self {
        let r = DEFAULT_REFERENCE_RANGE_M;
        let level_at_reference = constants.unit_level_dbm() - 40.0 * r.log10();
        Self {
            curve: GainCurve::Slope {
                db_per_decade,
                reference_range_m: r,
                gain_at_reference_db: CALIBRATED_LEVEL_DB - level_at_reference,
            },
            rolloff: Some(RollOff {
                corner_m: 200.0,
                order: 4,
            }),
        }
    }

    /// The paper's 60 dB/decade model of its unit, calibrated the same way.
    pub fn paper_sixty(constants: &RadarConstants) -> Self {
        Self::calibrated(60.0, constants)
    }

    /// Validates the settings.
    ///
    /// # Errors
    /// Non-finite slope or gain, non-positive reference or corner range, zero order.
    pub fn check(&self) -> Result<(), ModelError> {
        if let GainCurve::Slope {
            db_per_decade,
            reference_range_m,
            gain_at_reference_db,
        } = self.curve
        {
            finite(db_per_decade, "compensation slope")?;
            finite(gain_at_reference_db, "compensation gain")?;
            if !(reference_range_m.is_finite() && reference_range_m > 0.0) {
                return Err(ModelError::InvalidSetting {
                    what: "reference_range_m",
                    reason: "must be finite and positive",
                });
            }
        }
        if let Some(r) = self.rolloff {
            if !(r.corner_m.is_finite() && r.corner_m > 0.0) || r.order == 0 {
                return Err(ModelError::InvalidSetting {
                    what: "rolloff",
                    reason: "corner must be finite and positive, order at least 1",
                });
            }
        }
        Ok(())
    }

    /// Compensation gain (dB) at `range_m` (high-pass curve plus roll-off).
    pub fn gain_db(&self, range_m: f64) -> f64 {
        let high_pass = match &self.curve {
            GainCurve::Slope {
                db_per_decade,
                reference_range_m,
                gain_at_reference_db,
            } => {
                gain_at_reference_db
                    + db_per_decade
                        * (range_m.max(MIN_COMPENSATION_RANGE_M) / reference_range_m).log10()
            }
            GainCurve::Table(t) => t.gain_db(range_m),
        };
        high_pass + self.rolloff.map_or(0.0, |r| r.gain_db(range_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gain_table_interpolates_in_log_range_and_holds_its_ends() {
        let t = GainTable::new(&[(1.0, 0.0), (10.0, 40.0), (100.0, 100.0)]).unwrap();
        assert!((t.gain_db(10f64.sqrt()) - 20.0).abs() < 1e-12);
        assert!((t.gain_db(10.0) - 40.0).abs() < 1e-12);
        assert!((t.gain_db(31.622_776_601_683_8) - 70.0).abs() < 1e-9);
        assert_eq!(t.gain_db(0.1), 0.0);
        assert_eq!(t.gain_db(0.0), 0.0);
        assert_eq!(t.gain_db(1e6), 100.0);
    }

    #[test]
    fn the_roll_off_is_finite_for_any_order_and_range() {
        let r = RollOff {
            corner_m: 200.0,
            order: 255,
        };
        assert_eq!(r.gain_db(0.0), 0.0);
        assert!((r.gain_db(200.0) + 3.0103).abs() < 1e-4);
        assert!(r.gain_db(1e6).is_finite() && r.gain_db(1e6) < -1e4);
        let four = RollOff {
            corner_m: 200.0,
            order: 4,
        };
        // Eighth-order slope: -80 dB/decade past the corner.
        assert!((four.gain_db(20_000.0) - four.gain_db(2_000.0) + 80.0).abs() < 1e-6);
    }

    #[test]
    fn bad_gain_tables_are_refused() {
        assert!(GainTable::new(&[(1.0, 0.0)]).is_err());
        assert!(GainTable::new(&[(1.0, 0.0), (1.0, 3.0)]).is_err());
        assert!(GainTable::new(&[(2.0, 0.0), (1.0, 3.0)]).is_err());
        assert!(GainTable::new(&[(0.0, 0.0), (1.0, 3.0)]).is_err());
        assert!(GainTable::new(&[(1.0, f64::NAN), (2.0, 3.0)]).is_err());
    }

    #[test]
    fn a_table_compensation_adds_the_roll_off() {
        let c = Compensation {
            curve: GainCurve::Table(GainTable::new(&[(1.0, 10.0), (1000.0, 130.0)]).unwrap()),
            rolloff: Some(RollOff {
                corner_m: 200.0,
                order: 4,
            }),
        };
        assert!(c.check().is_ok());
        assert!((c.gain_db(200.0) - (10.0 + 120.0 * 200f64.log10() / 3.0 - 3.0103)).abs() < 1e-3);
    }
}
