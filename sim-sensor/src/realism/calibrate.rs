//! Fitting the realistic receiver to real scans, and the fitted values the defaults use.
//!
//! The command is `cargo run --release -p sim-sensor --example calibrate` (reads
//! `../shared/data/oxford-radar-robotcar/radar/*.png` unless given a folder); it prints every
//! fitted value, and the `FITTED_*` constants (kept with the settings in
//! [`crate::scene::realism_spec`], re-exported here) are copied from its output. What it fits:
//!
//! 1. The output scale: the real unit's low levels take only the 8-bit values 0, 6, 9, 12,
//!    14, 15, 17, 18, 19, 20 ... = `round(c 20 log10 k)` for integer power `k`; `c` is the
//!    value in [0.95, 1.02] that puts the most of the observed low values on that lattice.
//! 2. The floor per range band: `k = floor(Y)`, `Y ~ Gamma(shape, mean / shape)`; per band
//!    the mean that best matches the observed shares of `k = 0..8` (conditional on `k <=
//!    8`, so targets, which sit higher, hardly bias it), with one shape for all bands
//!    chosen by the total squared error.
//! 3. The clip: the largest level observed.
//! 4. Peak widths: the median range and azimuth full widths at half power of isolated
//!    unclipped peaks ([`super::stats::peak_widths`]); the range kernel and the antenna
//!    pattern are given those widths.
//! 5. The receiver's signal gain with range: the simulated urban street's 99th percentile
//!    per band against the real one's, by least squares on `a + b log10(R / 10 m)`
//!    ([`fit_gain_correction`]), iterated by the example.

use std::path::{Path, PathBuf};

use statrs::distribution::{ContinuousCDF, Gamma};

use super::stats::{BandStats, Scans};
use crate::error::ReplayError;
use crate::replay::png::read_polar_png;
pub use crate::scene::realism_spec::{
    FITTED_BEAM_FWHM_DEG, FITTED_FLOOR_MEAN, FITTED_FLOOR_SHAPE, FITTED_HIGHPASS_M,
    FITTED_LOG_SCALE, FITTED_RANGE_FWHM_M, FITTED_SATURATION_DB, FITTED_SIGNAL_GAIN_DB,
    FITTED_SIGNAL_SLOPE_DB_PER_DECADE,
};

/// Range bands of the floor fit, metres.
pub const FLOOR_BAND_EDGES_M: [f64; 19] = [
    0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 80.0, 100.0,
    130.0, 165.0,
];

/// The default folder of the real scans, relative to the workspace root's parent: the
/// workspace is at `<root>/<name>`, the data at `<root>/shared/data/oxford-radar-robotcar`.
pub fn default_oxford_dir() -> PathBuf {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let workspace = manifest.parent().unwrap_or(manifest);
    for up in [
        workspace.parent(),
        workspace.parent().and_then(Path::parent),
    ]
    .into_iter()
    .flatten()
    {
        let candidate = up.join("shared/data/oxford-radar-robotcar");
        if candidate.is_dir() {
            return candidate;
        }
    }
    workspace.join("../shared/data/oxford-radar-robotcar")
}

/// Reads every polar PNG in `dir` (or `dir/radar`) in name order into scans of 400 x 3768
/// bins of 0.0438 m (other shapes are skipped).
pub fn load_polar_dir(dir: &Path) -> Result<Scans, ReplayError> {
    let folder = if dir.join("radar").is_dir() {
        dir.join("radar")
    } else {
        dir.to_path_buf()
    };
    let io = |source| ReplayError::Io {
        path: folder.clone(),
        source,
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&folder)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    files.sort();
    let mut scans = Scans::new(400, 3768, 0.0438);
    for f in files {
        let scan = read_polar_png(&f)?;
        scans.push_polar(&scan);
    }
    Ok(scans)
}

/// The 8-bit value the unit outputs for integer power `k` with output scale `c`.
pub fn raw_of_power(k: u64, c: f64) -> u8 {
    (c * 20.0 * (k.max(1) as f64).log10())
        .round()
        .clamp(0.0, 255.0) as u8
}

/// Fits the output scale on one histogram of 8-bit values (all bands pooled): the share
/// of the values 0..=20 that lie on the lattice `raw_of_power(k, c)`, `k = 1..=10`, is
/// largest over an interval of `c`; its middle is returned.
pub fn fit_log_scale(hist: &[u64; 256]) -> f64 {
    let below: u64 = hist.iter().take(21).sum();
    let score = |c: f64| {
        let mut lattice: Vec<u8> = (1..=10).map(|k| raw_of_power(k, c)).collect();
        lattice.dedup();
        let on: u64 = lattice.iter().map(|&v| hist[usize::from(v)]).sum();
        on as f64 / below.max(1) as f64
    };
    let grid: Vec<(f64, f64)> = (0..=140)
        .map(|i| {
            let c = 0.95 + 0.0005 * f64::from(i);
            (c, score(c))
        })
        .collect();
    let best = grid.iter().map(|g| g.1).fold(f64::NEG_INFINITY, f64::max);
    let good: Vec<f64> = grid
        .iter()
        .filter(|g| g.1 >= best - 1e-12)
        .map(|g| g.0)
        .collect();
    match (good.first(), good.last()) {
        (Some(lo), Some(hi)) => 0.5 * (lo + hi),
        _ => 1.0,
    }
}

/// Largest integer power whose share the floor fit uses.
const FIT_MAX_K: u64 = 8;
/// Shares fitted: `k <= 1` (both output 0), then `k = 2..=FIT_MAX_K`.
const SHARES: usize = FIT_MAX_K as usize;

/// Shares of `k = 0..=FIT_MAX_K` under the floor model (conditional on `k <= FIT_MAX_K`).
fn model_shares(mean: f64, shape: f64) -> Option<[f64; SHARES]> {
    let g = Gamma::new(shape, shape / mean).ok()?;
    let f = |x: f64| g.cdf(x);
    let total = f((FIT_MAX_K + 1) as f64);
    if total <= 0.0 {
        return None;
    }
    let mut out = [0.0; SHARES];
    out[0] = f(2.0) / total;
    for (i, slot) in out.iter_mut().enumerate().skip(1) {
        let k = (i + 1) as f64;
        *slot = (f(k + 1.0) - f(k)) / total;
    }
    Some(out)
}

/// The observed shares of the values of `k = 0..=FIT_MAX_K` in one histogram
/// (conditional).
fn observed_shares(hist: &[u64; 256], c: f64) -> Option<[f64; SHARES]> {
    let mut values = [0.0; SHARES];
    values[0] = hist[usize::from(raw_of_power(0, c))] as f64;
    for (i, slot) in values.iter_mut().enumerate().skip(1) {
        *slot = hist[usize::from(raw_of_power(i as u64 + 1, c))] as f64;
    }
    let total: f64 = values.iter().sum();
    (total > 0.0).then(|| values.map(|v| v / total))
}

/// Per-band histograms over [`FLOOR_BAND_EDGES_M`].
pub fn floor_histograms(scans: &Scans) -> Vec<[u64; 256]> {
    let mut h = vec![[0u64; 256]; FLOOR_BAND_EDGES_M.len() - 1];
    let band: Vec<Option<usize>> = (0..scans.bins)
        .map(|b| {
            let r = (b as f64 + 0.5) * scans.bin_m;
            FLOOR_BAND_EDGES_M
                .windows(2)
                .position(|w| r >= w[0] && r < w[1])
        })
        .collect();
    for rot in &scans.rotations {
        for row in rot.chunks_exact(scans.bins) {
            for (&v, k) in row.iter().zip(&band) {
                if let Some(hist) = k.and_then(|k| h.get_mut(k)) {
                    hist[usize::from(v)] += 1;
                }
            }
        }
    }
    h
}

/// The fitted floor: shape, and `(band centre, mean)` per band.
#[derive(Debug, Clone, PartialEq)]
pub struct FloorFit {
    /// Gamma shape.
    pub shape: f64,
    /// `(range_m, mean)` per band.
    pub means: Vec<(f64, f64)>,
    /// Total squared error of the shares.
    pub error: f64,
}

fn sq_err(a: &[f64; SHARES], b: &[f64; SHARES]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

fn best_mean(obs: &[f64; SHARES], shape: f64) -> (f64, f64) {
    let mut best = (f64::INFINITY, 1.0);
    for i in 0..=400 {
        let mean = 0.2 * 1.02f64.powi(i);
        if let Some(m) = model_shares(mean, shape) {
            let e = sq_err(obs, &m);
            if e < best.0 {
                best = (e, mean);
            }
        }
    }
    best
}

/// Fits the floor (see the module doc).
pub fn fit_floor(scans: &Scans, c: f64) -> FloorFit {
    let hists = floor_histograms(scans);
    let mut best = FloorFit {
        shape: 1.0,
        means: Vec::new(),
        error: f64::INFINITY,
    };
    for shape in [
        0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.15, 1.3, 1.5, 1.75, 2.0, 2.5, 3.0, 4.0,
    ] {
        let mut error = 0.0;
        let mut means = Vec::new();
        for (k, h) in hists.iter().enumerate() {
            let centre = 0.5 * (FLOOR_BAND_EDGES_M[k] + FLOOR_BAND_EDGES_M[k + 1]);
            if let Some(obs) = observed_shares(h, c) {
                let (e, mean) = best_mean(&obs, shape);
                error += e;
                means.push((centre, mean));
            }
        }
        if error < best.error {
            best = FloorFit {
                shape,
                means,
                error,
            };
        }
    }
    best
}

/// Least-squares correction `(d_gain_db, d_slope_db_per_decade)` that moves the simulated
/// bands' 99th percentiles onto the real ones, over bands from 5 m on (closer in, the
/// antenna's leakage dominates).
pub fn fit_gain_correction(real: &[BandStats], sim: &[BandStats]) -> (f64, f64) {
    let pts: Vec<(f64, f64)> = real
        .iter()
        .zip(sim)
        .filter(|(r, _)| r.range_m.0 >= 2.0)
        .map(|(r, s)| {
            let centre = (r.range_m.0 * r.range_m.1).sqrt();
            ((centre / 10.0).log10(), r.p99_db - s.p99_db)
        })
        .filter(|(_, d)| d.is_finite())
        .collect();
    let n = pts.len() as f64;
    if n < 2.0 {
        return (0.0, 0.0);
    }
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (my - b * mx, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_output_lattice_of_small_powers_is_the_real_units() {
        let v: Vec<u8> = (1..=10).map(|k| raw_of_power(k, 0.985)).collect();
        assert_eq!(v, vec![0, 6, 9, 12, 14, 15, 17, 18, 19, 20]);
    }

    #[test]
    fn the_floor_fit_recovers_the_mean_of_a_synthetic_floor() {
        use rand::SeedableRng;
        use rand_distr::Distribution;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let g = rand_distr::Gamma::<f64>::new(1.5, 4.0 / 1.5).expect("gamma");
        let mut scans = Scans::new(10, 3768, 0.0438);
        let row: Vec<u8> = (0..10 * 3768)
            .map(|_| raw_of_power(g.sample(&mut rng).floor() as u64, 0.985))
            .collect();
        scans.rotations.push(row);
        let fit = fit_floor(&scans, 0.985);
        assert!((fit.shape - 1.5).abs() <= 0.3, "shape {}", fit.shape);
        for (r, m) in &fit.means {
            assert!((m - 4.0).abs() < 1.0, "mean {m} at {r} m");
        }
    }
}
