//! Time per rotation over the first and the last tenth of a run, from its diagnostics file:
//! the check of a daemon whose cost must not grow with the drive.
//!
//! ```sh
//! cargo run --release -p slam-node --example rotation_tenths -- out/diagnostics.csv
//! ```

use std::process::ExitCode;

fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    let k = ((v.len().saturating_sub(1)) as f64 * q).round() as usize;
    v.get(k).copied().unwrap_or(f64::NAN)
}

fn main() -> ExitCode {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: rotation_tenths DIAGNOSTICS.csv");
        return ExitCode::FAILURE;
    };
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("cannot read {path}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut lines = text.lines();
    let Some(header) = lines.next() else {
        eprintln!("{path} is empty");
        return ExitCode::FAILURE;
    };
    let Some(col) = header.split(',').position(|h| h == "total_ms") else {
        eprintln!("{path} has no total_ms column (a CSV diagnostics file is needed)");
        return ExitCode::FAILURE;
    };
    let ms: Vec<f64> = lines
        .filter_map(|l| l.split(',').nth(col)?.parse().ok())
        .collect();
    let n = ms.len();
    if n < 20 {
        eprintln!("{path}: {n} rotations, too few for tenths");
        return ExitCode::FAILURE;
    }
    let tenth = n / 10;
    let mut first = ms[..tenth].to_vec();
    let mut last = ms[n - tenth..].to_vec();
    let (m1, p1) = (quantile(&mut first, 0.5), quantile(&mut first, 0.99));
    let (m2, p2) = (quantile(&mut last, 0.5), quantile(&mut last, 0.99));
    println!(
        "{n} rotations; first tenth: median {m1:.2} ms, p99 {p1:.2} ms; last tenth: median {m2:.2} ms, p99 {p2:.2} ms; last p99 / first p99 = {:.2}",
        p2 / p1
    );
    ExitCode::SUCCESS
}
