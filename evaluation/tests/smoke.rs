//! Smoke test: the whole evaluation on its smallest budget writes a report whose numbers are
//! finite and whose figures exist.

use std::time::Duration;

use evaluation::report::{Budget, Options};

#[test]
fn the_tiny_evaluation_writes_a_report_with_finite_numbers_and_every_figure() {
    let dir = tempfile::tempdir().expect("temporary folder");
    let opts = Options {
        out_dir: dir.path().to_path_buf(),
        budget: Budget::tiny(),
        oxford_dir: Some(evaluation::sections::oxford::default_dir()),
        command: "cargo test -p evaluation --test smoke".into(),
        only: Vec::new(),
    };
    // Bounded: the evaluation runs on a worker; the test gives up after two minutes.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(evaluation::evaluate(&opts));
    });
    let outcome = rx
        .recv_timeout(Duration::from_secs(120))
        .expect("the tiny evaluation finished within two minutes")
        .expect("the evaluation ran");
    assert!(
        outcome.failed.is_empty(),
        "failed sections: {:?}",
        outcome.failed
    );
    let report = std::fs::read_to_string(&outcome.report_path).expect("report written");
    for key in evaluation::SECTION_KEYS {
        assert!(
            report.contains(&format!("_Section `{key}` took")),
            "section {key} missing"
        );
    }
    for bad in ["NaN", "inf |", "| inf", "FAILED"] {
        assert!(!report.contains(bad), "report contains {bad:?}");
    }
    // Every figure the report links to exists and is an SVG.
    let mut figures = 0;
    for part in report.split("](").skip(1) {
        let name = part.split(')').next().unwrap_or_default();
        if name.ends_with(".svg") {
            let text = std::fs::read_to_string(dir.path().join(name)).expect("figure written");
            assert!(text.contains("<svg"), "{name} is not an SVG");
            figures += 1;
        }
    }
    assert!(figures >= 5, "only {figures} figures linked");
}
