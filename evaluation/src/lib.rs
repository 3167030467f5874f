//! Measures the radar SLAM system against the truth and against the paper's claims:
//! filter consistency (NEES, NIS), accuracy per shipped scene, whether power in the
//! observation helps data association, predicted against measured spectra (paper and
//! textbook spreading, 40 and 60 dB/decade compensation), speed against error over the
//! knobs that trade them, the real Oxford Radar RobotCar scans, the realistic city driven on
//! the radar alone through the whole daemon, and numerical stability
//! over a million filter steps. Writes a Markdown report with SVG figures.
//!
//! **IO**: reads the Oxford scans from `../shared/data` (when present) and writes the
//! report folder; everything else runs in memory. Simulated spectra come from sim-sensor's
//! renderer directly (no sockets), so every figure is reproducible from the fixed seeds.
//! One binary opens sockets: `seed_one` runs the whole daemon against the simulator on
//! 127.0.0.1:0 (the end-to-end tests' harness).

pub mod city_realism;
pub mod daemon;
pub mod detections;
pub mod error;
pub mod metrics;
pub mod nees_ensemble;
pub mod plot;
pub mod record;
pub mod report;
pub mod run;
pub mod scan;
pub mod sections;
pub mod source;
pub mod truth_agreement;
pub mod world;

pub use error::EvalError;

use std::fmt::Write as _;
use std::time::Instant;

use report::{write_file, Options, Section};

/// Keys of the sections, in report order.
pub const SECTION_KEYS: [&str; 9] = [
    "consistency",
    "accuracy",
    "association",
    "association-sweep",
    "spectra",
    "sweep",
    "oxford",
    "realistic-city",
    "stability",
];

/// What a whole evaluation produced.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The report file.
    pub report_path: std::path::PathBuf,
    /// Sections that failed, with their errors (also written into the report).
    pub failed: Vec<(String, String)>,
    /// Wall time per section (s).
    pub timings: Vec<(String, f64)>,
}

fn run_section(key: &str, opts: &Options) -> Result<Section, EvalError> {
    match key {
        "consistency" => sections::consistency::section(opts),
        "accuracy" => sections::accuracy::section(opts),
        "association" => sections::association::section(opts),
        "association-sweep" => sections::association_sweep::section(opts),
        "spectra" => sections::spectra::section(opts),
        "sweep" => sections::sweep::section(opts),
        "oxford" => sections::oxford::section(opts),
        "realistic-city" => sections::realistic_city::section(opts),
        "stability" => sections::stability::section(opts),
        other => Err(EvalError::Setting(format!(
            "unknown section {other:?}; known: {}",
            SECTION_KEYS.join(", ")
        ))),
    }
}

/// Runs the evaluation and writes `README.md` (the report) and its SVG figures into
/// `opts.out_dir`. A section that fails is reported as failed in the report and in
/// [`Outcome::failed`]; the others still run.
///
/// # Errors
/// Unknown section names, or the report folder cannot be created or written.
pub fn evaluate(opts: &Options) -> Result<Outcome, EvalError> {
    for key in &opts.only {
        if !SECTION_KEYS.contains(&key.as_str()) {
            return Err(EvalError::Setting(format!(
                "unknown section {key:?}; known: {}",
                SECTION_KEYS.join(", ")
            )));
        }
    }
    std::fs::create_dir_all(&opts.out_dir).map_err(|source| EvalError::Io {
        path: opts.out_dir.clone(),
        source,
    })?;
    let mut failed = Vec::new();
    let mut timings = Vec::new();
    let mut doc = String::new();
    let _ = writeln!(doc, "# Evaluation report\n");
    let _ = writeln!(
        doc,
        "Produced by `{}` (budget: {:?}). Every figure below was measured by that command \
         from fixed seeds; numbers are as measured, including the disappointing ones. \
         Timings were taken on a shared 2-core machine and vary from run to run.\n",
        opts.command, opts.budget
    );
    let mut body = String::new();
    for key in SECTION_KEYS {
        if !opts.only.is_empty() && !opts.only.iter().any(|k| k == key) {
            continue;
        }
        let started = Instant::now();
        let result = run_section(key, opts);
        let secs = started.elapsed().as_secs_f64();
        timings.push((key.to_string(), secs));
        match result {
            Ok(section) => {
                let _ = writeln!(
                    body,
                    "## {}\n\n{}\n_Section `{key}` took {secs:.1} s._\n",
                    section.title, section.body
                );
            }
            Err(e) => {
                let chain = error_chain(&e);
                let _ = writeln!(body, "## Section `{key}`: FAILED\n\n{chain}\n");
                failed.push((key.to_string(), chain));
            }
        }
    }
    let _ = writeln!(
        doc,
        "Sections: {}.\n",
        timings
            .iter()
            .map(|(k, s)| format!("{k} ({s:.0} s)"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    doc.push_str(&body);
    let report_path = opts.out_dir.join("README.md");
    write_file(&report_path, &doc)?;
    Ok(Outcome {
        report_path,
        failed,
        timings,
    })
}

/// An error and its causes on one line, `outer: cause: root` (error texts do not repeat
/// their causes, so this is where the whole story is told).
pub fn error_chain(e: &(dyn std::error::Error + 'static)) -> String {
    radar_driver::ErrorChain(e).to_string()
}
