//! Monte Carlo consistency of the pose a run published, over several runs of one drive:
//! at every rotation the pose NEES averaged over the runs, against the two-sided 95 % band
//! of the average of that many chi-square variables of 3 dof ([`average_chi2_band`];
//! Bar-Shalom, Li and Kirubarajan, "Estimation with Applications to Tracking and
//! Navigation", 5.4.2), and each run against the single-rotation band
//! ([`slam_filter::health::POSE_NEES_BAND_95`], as the daemon's summary gives it). A
//! consistent filter's ensemble NEES lies inside its band at 95 % of the rotations; below it
//! the covariance is larger than the errors (conservative), above smaller (optimistic).
//! Read from each run's `diagnostics.csv` (its `rotation` and `pose_nees` columns).

use std::collections::BTreeMap;
use std::path::Path;

use crate::city_realism::read_bounded_text;
use crate::error::EvalError;
use crate::metrics::average_chi2_band;
use slam_node::pipeline::scores::NeesBand;

/// Largest `diagnostics.csv` read, bytes (a row is about 300 bytes: days of 4 Hz rotations).
pub const MAX_DIAGNOSTICS_BYTES: u64 = 256 << 20;

/// One run's pose NEES by rotation.
pub type RunNees = BTreeMap<u64, f64>;

/// The pose NEES by rotation of one run's `diagnostics.csv`; rows without a NEES (no truth
/// at that rotation) are left out. Bounded and refusing non-regular files
/// ([`read_bounded_text`]); a row whose cells are not numbers is an error naming its line.
pub fn read_run(path: &Path) -> Result<RunNees, EvalError> {
    let text = read_bounded_text(path, MAX_DIAGNOSTICS_BYTES)?;
    let data = |line: usize, reason: String| EvalError::Data {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| data(1, "empty: no header".into()))?
        .split(',')
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| data(1, format!("no column {name}")))
    };
    let (rotation, nees) = (col("rotation")?, col("pose_nees")?);
    let mut out = RunNees::new();
    for (k, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').collect();
        let cell = |i: usize| cells.get(i).copied().unwrap_or("");
        if cell(nees).is_empty() {
            continue;
        }
        let r = cell(rotation).parse::<u64>().map_err(|_| {
            data(
                k + 2,
                format!("rotation {:?} is not a count", cell(rotation)),
            )
        })?;
        let v = cell(nees)
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| data(k + 2, format!("pose_nees {:?} is not a NEES", cell(nees))))?;
        out.insert(r, v);
    }
    Ok(out)
}

/// The ensemble test over `runs`.
#[derive(Debug, Clone, PartialEq)]
pub struct Ensemble {
    /// The band of the ensemble NEES for this many runs.
    pub band: (f64, f64),
    /// The ensemble NEES at each rotation every run scored, in rotation order.
    pub means: Vec<f64>,
    /// Those against the band.
    pub counts: NeesBand,
}

/// The ensemble NEES at each rotation every run scored, against its 95 % band. `None`
/// without runs or without a rotation common to all.
pub fn ensemble(runs: &[RunNees]) -> Option<Ensemble> {
    let first = runs.first()?;
    let band = average_chi2_band(runs.len(), 3, 0.95);
    let means: Vec<f64> = first
        .keys()
        .filter(|k| runs.iter().all(|r| r.contains_key(k)))
        .map(|k| runs.iter().map(|r| r[k]).sum::<f64>() / runs.len() as f64)
        .collect();
    if means.is_empty() {
        return None;
    }
    let counts = NeesBand::of(means.iter().copied(), band);
    Some(Ensemble {
        band,
        means,
        counts,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, rows: &str) -> std::path::PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, format!("rotation,timestamp_s,pose_nees\n{rows}")).unwrap();
        path
    }

    #[test]
    fn the_ensemble_averages_the_rotations_every_run_scored_against_the_runs_band() {
        let dir = tempfile::tempdir().unwrap();
        let a = read_run(&write(
            dir.path(),
            "a.csv",
            "0,0.0,\n1,0.25,3.0\n2,0.5,0.1\n3,0.75,20\n",
        ))
        .unwrap();
        let b = read_run(&write(
            dir.path(),
            "b.csv",
            "1,0.25,3.0\n2,0.5,0.2\n3,0.75,12\n4,1.0,3\n",
        ))
        .unwrap();
        assert_eq!(a.len(), 3, "the row without a NEES is left out");
        let e = ensemble(&[a, b]).unwrap();
        assert_eq!(e.band, average_chi2_band(2, 3, 0.95));
        assert_eq!(e.means, vec![3.0, 0.15000000000000002, 16.0]);
        assert_eq!(
            e.counts,
            NeesBand {
                below: 1,
                inside: 1,
                above: 1
            }
        );
        assert!(ensemble(&[]).is_none());
    }

    #[test]
    fn a_damaged_table_is_an_error_naming_its_line_and_a_fifo_is_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        let bad = write(dir.path(), "bad.csv", "1,0.25,3.0\n2,0.5,-1\n");
        let e = read_run(&bad).unwrap_err().to_string();
        assert!(e.contains("line 3") && e.contains("-1"), "{e}");
        let bad = write(dir.path(), "bad2.csv", "x,0.25,3.0\n");
        assert!(read_run(&bad).unwrap_err().to_string().contains("line 2"));
        std::fs::write(dir.path().join("nocol.csv"), "rotation,other\n1,2\n").unwrap();
        let e = read_run(&dir.path().join("nocol.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no column pose_nees"), "{e}");
        #[cfg(unix)]
        {
            let fifo = dir.path().join("fifo.csv");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                let e = read_run(&fifo).unwrap_err().to_string();
                assert!(e.contains("not a regular file"), "{e}");
            }
        }
    }
}
