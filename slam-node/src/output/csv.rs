//! CSV forms of the map and the diagnostics, for `[output] map = "map.csv"` and
//! `diagnostics = "diagnostics.csv"`.
//!
//! Map: two `#` comment lines (`# slam-node-map v1` and `# timestamp_s=.. loss_db=..
//! loss_var_db2=..`), a header row, then one feature a row: `id, x_m, y_m, rho, alpha, tau,
//! observations` and the upper triangle of the 4x4 covariance over `(x, y, rho, alpha)`:
//! `c_x_x, c_x_y, c_x_rho, c_x_alpha, c_y_y, c_y_rho, c_y_alpha, c_rho_rho, c_rho_alpha,
//! c_alpha_alpha`. Diagnostics: a header row of the [`RotationDiagnostics`] field names, one
//! rotation a row, empty cells for values not known.

use std::fmt::Write as _;
use std::io::{self, Write};

use super::diagnostics::RotationDiagnostics;
use super::map::MapSnapshot;

/// The map CSV's header row.
pub const MAP_HEADER: &str = "id,x_m,y_m,rho,alpha,tau,observations,c_x_x,c_x_y,c_x_rho,c_x_alpha,c_y_y,c_y_rho,c_y_alpha,c_rho_rho,c_rho_alpha,c_alpha_alpha";

/// The diagnostics CSV's header row.
pub const DIAGNOSTICS_HEADER: &str = "rotation,timestamp_s,azimuths,skipped_azimuths,detections,observations,associated,new_features,tentative,retired,rejected,map_size,mean_nis,spectrum_in_bound_fraction,spectrum_bias_db,detect_ms,filter_ms,spectrum_ms,total_ms,association_errors,pose_error_x_m,pose_error_y_m,pose_error_theta_rad,pose_sigma_x_m,pose_sigma_y_m,pose_sigma_theta_rad,pose_nees";

/// Writes a map snapshot as CSV.
pub fn write_map<W: Write>(m: &MapSnapshot, mut w: W) -> io::Result<()> {
    writeln!(w, "# {}", m.format)?;
    writeln!(
        w,
        "# timestamp_s={:.9} loss_db={} loss_var_db2={}",
        m.timestamp_s, m.loss_db, m.loss_var_db2
    )?;
    writeln!(w, "{MAP_HEADER}")?;
    for f in &m.features {
        let c = &f.covariance;
        let mut line = format!(
            "{},{},{},{},{},{},{}",
            f.id, f.x_m, f.y_m, f.rho, f.alpha, f.tau, f.observations
        );
        for r in 0..4 {
            for k in r..4 {
                let v = c
                    .get(r)
                    .and_then(|row| row.get(k))
                    .copied()
                    .unwrap_or(f64::NAN);
                let _ = write!(line, ",{v}");
            }
        }
        writeln!(w, "{line}")?;
    }
    Ok(())
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or_else(String::new, |x| x.to_string())
}

/// One diagnostics row.
pub fn diagnostics_row(d: &RotationDiagnostics) -> String {
    format!(
        "{},{:.9},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{},{},{},{},{},{},{},{}",
        d.rotation,
        d.timestamp_s,
        d.azimuths,
        d.skipped_azimuths,
        d.detections,
        d.observations,
        d.associated,
        d.new_features,
        d.tentative,
        d.retired,
        d.rejected,
        d.map_size,
        opt(d.mean_nis),
        opt(d.spectrum_in_bound_fraction),
        opt(d.spectrum_bias_db),
        d.detect_ms,
        d.filter_ms,
        d.spectrum_ms,
        d.total_ms,
        opt(d.association_errors),
        opt(d.pose_error_x_m),
        opt(d.pose_error_y_m),
        opt(d.pose_error_theta_rad),
        opt(d.pose_sigma_x_m),
        opt(d.pose_sigma_y_m),
        opt(d.pose_sigma_theta_rad),
        opt(d.pose_nees)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::map::MapFeature;

    #[test]
    fn map_rows_have_as_many_cells_as_the_header() {
        let m = MapSnapshot {
            format: MapSnapshot::FORMAT.into(),
            timestamp_s: 1.0,
            loss_db: 0.5,
            loss_var_db2: 0.1,
            features: vec![MapFeature {
                id: 4,
                x_m: 1.0,
                y_m: 2.0,
                rho: 0.1,
                alpha: 0.2,
                tau: 0.7,
                covariance: [[1.0; 4]; 4],
                observations: 3,
            }],
            global: None,
        };
        let mut buf = Vec::new();
        write_map(&m, &mut buf).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let rows: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(rows.len(), 2);
        let n = MAP_HEADER.split(',').count();
        assert!(rows.iter().all(|r| r.split(',').count() == n));
    }

    #[test]
    fn a_diagnostics_row_matches_the_header_with_empty_cells_for_unknowns() {
        let row = diagnostics_row(&RotationDiagnostics::default());
        assert_eq!(
            row.split(',').count(),
            DIAGNOSTICS_HEADER.split(',').count()
        );
        assert!(
            row.ends_with(','),
            "unknown association errors leave the cell empty"
        );
    }
}
