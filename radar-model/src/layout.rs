//! The beam-local layout of a beam's stacked observation (eq. 14) and its Jacobian, defined
//! once for the model and the filter.
//!
//! For `k` features in a beam (in the caller's order):
//!
//! | rows | what |
//! |---|---|
//! | `3 i + 0` | `R_i`, eq. 3 |
//! | `3 i + 1` | `beta_i`, eq. 4 |
//! | `3 i + 2` | `P_i`, eq. 13 |
//!
//! | columns | what |
//! |---|---|
//! | `0..3` | pose `x, y, theta` |
//! | `3 + 4 i .. 3 + 4 i + 4` | feature `i`'s `x, y, u, v` |
//! | `3 + 4 k` | radar loss `L` |

/// Columns of the pose at the start of the Jacobian: `x, y, theta`.
pub const POSE_COLUMNS: usize = 3;
/// Columns per feature: `x, y, u, v`.
pub const FEATURE_COLUMNS: usize = 4;
/// Rows per feature: range, bearing, power.
pub const ROWS_PER_FEATURE: usize = 3;

/// One component of a target's observation `[R, beta, P]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Component {
    /// Range `R` (m), eq. 3.
    Range,
    /// Bearing `beta` (rad), eq. 4: an angle, so differences are wrapped.
    Bearing,
    /// Received power `P` (dB), eq. 13.
    Power,
}

impl Component {
    /// The three components in row order.
    pub const ALL: [Component; ROWS_PER_FEATURE] =
        [Component::Range, Component::Bearing, Component::Power];

    /// The component's position in `[R, beta, P]`.
    pub const fn offset(self) -> usize {
        match self {
            Component::Range => 0,
            Component::Bearing => 1,
            Component::Power => 2,
        }
    }

    /// Picks this component out of `[R, beta, P]` (or of per-component values such as noise
    /// variances).
    pub fn of(self, values: &[f64; ROWS_PER_FEATURE]) -> f64 {
        values[self.offset()]
    }
}

/// One row of a beam's stacked observation: component `component` of beam-local feature
/// `feature`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ObservationRow {
    /// The feature's position in the beam (the caller's order).
    pub feature: usize,
    /// Which component.
    pub component: Component,
}

impl ObservationRow {
    /// The row `component` of beam-local feature `feature`.
    pub const fn new(feature: usize, component: Component) -> Self {
        Self { feature, component }
    }

    /// Its index in the stacked observation and the Jacobian's rows.
    pub const fn index(self) -> usize {
        ROWS_PER_FEATURE * self.feature + self.component.offset()
    }

    /// The rows of one feature used in an update: range and bearing, and power when
    /// `with_power`.
    pub fn of_feature(feature: usize, with_power: bool) -> impl Iterator<Item = ObservationRow> {
        let n = if with_power { 3 } else { 2 };
        Component::ALL
            .into_iter()
            .take(n)
            .map(move |c| ObservationRow::new(feature, c))
    }
}

/// Rows of the observation of `k` features.
pub const fn rows(k: usize) -> usize {
    ROWS_PER_FEATURE * k
}

/// Columns of the Jacobian of `k` features: pose, four per feature, `L`.
pub const fn columns(k: usize) -> usize {
    POSE_COLUMNS + FEATURE_COLUMNS * k + 1
}

/// Column of feature `i`'s `x` (then `y`, `u`, `v`).
pub const fn feature_column(i: usize) -> usize {
    POSE_COLUMNS + FEATURE_COLUMNS * i
}

/// Column of `L` for a beam of `k` features.
pub const fn loss_column(k: usize) -> usize {
    POSE_COLUMNS + FEATURE_COLUMNS * k
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_and_columns_follow_the_table() {
        assert_eq!(ObservationRow::new(0, Component::Range).index(), 0);
        assert_eq!(ObservationRow::new(2, Component::Bearing).index(), 7);
        assert_eq!(ObservationRow::new(2, Component::Power).index(), 8);
        assert_eq!(rows(3), 9);
        assert_eq!(columns(3), 16);
        assert_eq!(feature_column(2), 11);
        assert_eq!(loss_column(3), 15);
        let without: Vec<usize> = ObservationRow::of_feature(1, false)
            .map(ObservationRow::index)
            .collect();
        assert_eq!(without, vec![3, 4]);
        let with: Vec<usize> = ObservationRow::of_feature(1, true)
            .map(ObservationRow::index)
            .collect();
        assert_eq!(with, vec![3, 4, 5]);
        assert_eq!(Component::Bearing.of(&[1.0, 2.0, 3.0]), 2.0);
    }
}
