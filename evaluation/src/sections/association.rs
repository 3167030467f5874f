//! The paper's claim that reflectivity and absorption in the state aid data association:
//! the cluttered scene run with the full `(R, beta, P)` innovation and with `(R, beta)`
//! only, counting wrong and missed associations against the truth, with the pose error
//! each gives.

use std::fmt::Write as _;

use sim_sensor::scene::shipped;

use crate::error::EvalError;
use crate::metrics::{mean, rms};
use crate::report::{num, pct, table, Options, Section};
use crate::run::{run_many, AssociationCounts, Mode, RunOutcome};
use crate::sections::{shipped_daemon, shipped_spec};

/// The cluttered scene.
pub const SCENE: &str = "dense-clutter";

#[derive(Debug, Default)]
struct Totals {
    counts: AssociationCounts,
    position_rmse: Vec<f64>,
    heading_rmse_deg: Vec<f64>,
    nees: Vec<f64>,
    failed: usize,
    features: Vec<f64>,
}

impl Totals {
    fn add(&mut self, r: &Result<RunOutcome, EvalError>) {
        let Ok(r) = r else {
            self.failed += 1;
            return;
        };
        let c = &mut self.counts;
        if let Some(d) = &r.daemon {
            // The daemon's own truth observer: an association is wrong when the observation
            // came from another true feature than the mapped one stands for, or from clutter.
            let wrong = d.association_errors + d.clutter_associations;
            c.correct += d.associations.saturating_sub(wrong);
            c.wrong += wrong;
            c.labelled_targets += d.observations;
        }
        let a = &r.association;
        c.labelled_targets += a.labelled_targets;
        c.unlabelled_targets += a.unlabelled_targets;
        c.correct += a.correct;
        c.wrong += a.wrong;
        c.missed += a.missed;
        c.duplicates += a.duplicates;
        c.unlabelled_paired += a.unlabelled_paired;
        c.clutter_features += a.clutter_features;
        self.position_rmse
            .push(rms(r.rotations.iter().map(|x| x.position_error_m())));
        self.heading_rmse_deg.push(rms(r
            .rotations
            .iter()
            .map(|x| x.heading_error_rad().to_degrees())));
        self.nees
            .push(mean(r.rotations.iter().filter_map(|x| x.nees)));
        self.features.push(r.final_features as f64);
    }

    fn row(&self, mode: &str, power: bool, seeds: usize) -> Vec<String> {
        let c = &self.counts;
        let paired = (c.correct + c.wrong) as f64;
        vec![
            mode.to_string(),
            if power { "R, beta, P" } else { "R, beta" }.to_string(),
            format!(
                "{}{}",
                seeds - self.failed,
                if self.failed > 0 { " (failures)" } else { "" }
            ),
            c.labelled_targets.to_string(),
            c.correct.to_string(),
            format!("{} ({})", c.wrong, pct(c.wrong as f64 / paired.max(1.0))),
            format!(
                "{} ({})",
                c.missed,
                pct(c.missed as f64 / c.labelled_targets.max(1) as f64)
            ),
            c.duplicates.to_string(),
            format!("{} / {}", c.unlabelled_paired, c.unlabelled_targets),
            num(mean(self.features.iter().copied()), 1),
            num(mean(self.position_rmse.iter().copied()), 3),
            num(mean(self.heading_rmse_deg.iter().copied()), 3),
            num(mean(self.nees.iter().copied()), 2),
        ]
    }
}

/// Runs the section.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    let b = &opts.budget;
    let scene = shipped::load(SCENE)?;
    let mut rows = Vec::new();
    let mut wrong_rates = Vec::new();
    for (mode_name, mode) in [("targets", Mode::Targets), ("daemon", shipped_daemon()?)] {
        for power in [true, false] {
            let mut specs = Vec::new();
            for k in 0..b.association_seeds {
                let mut spec = shipped_spec(
                    scene.clone(),
                    300 + k as u64,
                    b.association_seconds,
                    mode.clone(),
                )?;
                spec.filter.use_power = power;
                specs.push(spec);
            }
            let mut totals = Totals::default();
            for r in run_many(&specs, b.jobs) {
                totals.add(&r);
            }
            let c = &totals.counts;
            wrong_rates.push((
                mode_name,
                power,
                c.wrong as f64 / (c.correct + c.wrong).max(1) as f64,
                mean(totals.position_rmse.iter().copied()),
                (c.correct + c.wrong) as f64,
            ));
            rows.push(totals.row(mode_name, power, b.association_seeds));
        }
    }
    let mut body = String::new();
    let _ = writeln!(
        body,
        "Scene `{SCENE}` (about 230 trees and posts at 2-4 m spacing), {} seeds x {} s per \
         setting. The same seeds are used with power in and out of the observation \
         (`FilterSettings::use_power`; with it off the gate and the update use range and \
         bearing only). A pairing is *correct* when the target came from the true feature \
         the filter's feature was created from; *wrong* otherwise (another feature, or a \
         feature made from clutter); *missed* when a target was left unpaired although a \
         feature made from its own true feature was a candidate in that beam; *duplicates* \
         are features created for a true feature that already had one. In `targets` mode the \
         labels are exact; in `daemon` mode the spectra go through the daemon's own front end \
         and filter, and its truth observer labels each associated observation with the true \
         feature within 1.5 m of where it points (else clutter); missed pairings and \
         duplicates are not counted there (0), and *labelled targets* are its observations.\n",
        b.association_seeds, b.association_seconds
    );
    body.push_str(&table(
        &[
            "observations",
            "innovation",
            "seeds",
            "labelled targets",
            "correct",
            "wrong (of pairings)",
            "missed (of labelled)",
            "duplicates",
            "clutter paired / clutter",
            "features (mean)",
            "position RMSE (m)",
            "heading RMSE (deg)",
            "mean NEES",
        ],
        &rows,
    ));
    body.push('\n');
    for mode in ["targets", "daemon"] {
        let with = wrong_rates.iter().find(|w| w.0 == mode && w.1);
        let without = wrong_rates.iter().find(|w| w.0 == mode && !w.1);
        if let (Some(a), Some(b)) = (with, without) {
            // Binomial standard error of the difference of the two wrong-pairing rates.
            let se = |rate: f64, n: f64| (rate * (1.0 - rate) / n.max(1.0)).sqrt();
            let diff_se = se(a.2, a.4).hypot(se(b.2, b.4));
            let verdict = if (a.2 - b.2).abs() <= 2.0 * diff_se {
                format!(
                    "no measurable difference in wrong pairings (the gap is within two \
                     standard errors, {})",
                    pct(2.0 * diff_se)
                )
            } else if a.2 < b.2 {
                "fewer wrong pairings with power".to_string()
            } else {
                "more wrong pairings with power".to_string()
            };
            let _ = writeln!(
                body,
                "- `{mode}`: {verdict} ({} with, {} without); position RMSE {} m with, {} m \
                 without.",
                pct(a.2),
                pct(b.2),
                num(a.3, 3),
                num(b.3, 3)
            );
        }
    }
    Ok(Section {
        title: "Does power aid data association? (paper's claim)".into(),
        body,
    })
}
