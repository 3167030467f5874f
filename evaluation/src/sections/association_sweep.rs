//! The paper's claim that power aids data association, swept over the conditions that
//! decide it: spacing between neighbouring features (1, 2, 3, 4 m) against contrast in
//! reflectivity and absorption (alike: trees next to trees; posts next to trees: the metal
//! lamp post's `rho 0.05, alpha 0.95` next to the tree's `0.02, 0.60`, the simulator's
//! material table), with odometry noisy enough that the pose alone does not say which of
//! two neighbours a return came from. Every cell is run with the full `(R, beta, P)`
//! innovation and with `(R, beta)` only, on the same seeds, through the filter alone
//! (`targets`: exact labels, missed pairings counted) and through the daemon's own
//! pipeline (`daemon`: spectra, detector, filter; the daemon's truth observer labels its
//! associations). Then the same comparison on the realistic street (`urban-street`, the
//! realistic renderer) through the daemon's front end for current units, with the
//! shipped and the noisy odometry; the shipped-odometry runs also give the daemon's
//! average NEES there against the chi-square band and its spectrum in-bound fraction.
//!
//! Scenes are built here ([`pairs_scene`]): pairs of features `spacing` apart along the
//! direction of travel, both sides of a straight 3 m/s drive, pair centres every 8 m and
//! 6, 10 or 14 m to the side, the paper's radar. Only the materials differ between the
//! contrasts, so the geometry of a spacing is the same in both.

use std::fmt::Write as _;

use sim_sensor::scene::{shipped, FeatureKind, Scene};
use sim_sensor::OdometryNoise;
use slam_node::pipeline::PipelineSettings;

use crate::error::EvalError;
use crate::metrics::{average_chi2_band, mean, rms};
use crate::report::{num, pct, table, Options, Section};
use crate::run::{matched_filter, run_many, Mode, RunOutcome, RunSpec};
use crate::world::World;

/// Spacings between the two features of a pair (m).
pub const SPACINGS_M: [f64; 4] = [1.0, 2.0, 3.0, 4.0];

/// The vehicle's speed in the pair scenes (m/s).
pub const SPEED_MPS: f64 = 3.0;

/// Distance between pair centres along the drive (m).
pub const PAIR_PITCH_M: f64 = 8.0;

/// Lateral offsets of the pair centres, cycled (m).
pub const LATERAL_M: [f64; 3] = [6.0, 10.0, 14.0];

/// The realistic street scene.
pub const STREET_SCENE: &str = "urban-street";

/// Longest drive a pair scene is built for (s): bounds its feature count.
pub const MAX_SECONDS: f64 = 600.0;

/// How the two features of a pair differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Contrast {
    /// Both trees: the same reflectivity and absorption; power cannot tell them apart.
    Alike,
    /// A metal lamp post next to a tree (`rho 0.05, alpha 0.95` against `0.02, 0.60`):
    /// 4 dB apart in reflected power, and the post hides what is behind it.
    PostsAndTrees,
    /// A corner reflector next to a tree (`rho 0.885` against `0.02`): 16 dB apart, the
    /// largest contrast in the material table; where the claim should hold if anywhere.
    ReflectorAndTree,
}

impl Contrast {
    /// Both contrasts, in table order.
    pub const ALL: [Contrast; 3] = [
        Contrast::Alike,
        Contrast::PostsAndTrees,
        Contrast::ReflectorAndTree,
    ];

    /// Name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Contrast::Alike => "alike (tree, tree)",
            Contrast::PostsAndTrees => "post next to tree",
            Contrast::ReflectorAndTree => "reflector next to tree",
        }
    }

    /// The kinds of a pair's two members (the scene's material table gives their
    /// `(rho, alpha)`: `FeatureKind::default_material`).
    pub fn kinds(self) -> [FeatureKind; 2] {
        match self {
            Contrast::Alike => [FeatureKind::Tree, FeatureKind::Tree],
            Contrast::PostsAndTrees => [FeatureKind::LampPost, FeatureKind::Tree],
            Contrast::ReflectorAndTree => [FeatureKind::Reflector, FeatureKind::Tree],
        }
    }
}

/// Multiples of the simulator's default odometry noise (0.1 m/s and 0.01 rad per 20 Hz
/// record) the sweep runs at.
///
/// 5x (0.5 m/s, 0.05 rad): per rotation of the paper's radar (0.4 s, 8 records) the unaided
/// pose spreads by about 0.07 m along the drive and 0.45 degrees in heading; the filter's
/// own pose standard deviation settles near 0.15 m and 0.6 degrees, so with the 1 degree
/// bearing noise a feature 10-20 m away is predicted to within 0.2-0.4 m across the beam
/// and a 1 m neighbour is inside the range-bearing gate. 20x (2 m/s, 0.2 rad): the filter's
/// pose standard deviation is 0.6-1 m and 2.4-3.7 degrees, a feature 15 m away is
/// predicted to within 0.6-1 m across the beam, and the 2-4 m neighbours are inside the
/// gate too: geometry alone is ambiguous at every spacing swept. The tables give the
/// filter's own pose standard deviations so the claim can be checked.
pub const NOISE_MULTIPLES: [f64; 2] = [5.0, 20.0];

/// The simulator's default odometry noise times `multiple` (biases left at zero).
pub fn noisy_odometry(multiple: f64) -> OdometryNoise {
    let d = OdometryNoise::default();
    OdometryNoise {
        sigma_speed_mps: multiple * d.sigma_speed_mps,
        sigma_steer_rad: multiple * d.sigma_steer_rad,
        ..d
    }
}

/// A scene of feature pairs `spacing_m` apart (see the module docs) for a drive of
/// `seconds`.
///
/// # Errors
/// A spacing outside (0, 20] m or a duration outside (0, [`MAX_SECONDS`]].
pub fn pairs_scene(spacing_m: f64, contrast: Contrast, seconds: f64) -> Result<Scene, EvalError> {
    if !(spacing_m.is_finite() && spacing_m > 0.0 && spacing_m <= 20.0) {
        return Err(EvalError::Setting(format!(
            "pair spacing {spacing_m} m: must be in (0, 20]"
        )));
    }
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= MAX_SECONDS) {
        return Err(EvalError::Setting(format!(
            "pair scene duration {seconds} s: must be in (0, {MAX_SECONDS}]"
        )));
    }
    let mut text = format!(
        "name = \"pairs-{spacing_m}m-{}\"\n\
         description = \"feature pairs {spacing_m} m apart, {}\"\n\
         seed = 1\n\
         [radar]\npreset = \"paper-200\"\n\
         [motion]\nmodel = \"bicycle\"\nwheelbase_m = 2.7\n\
         [start]\nx_m = 0.0\ny_m = 0.0\ntheta_deg = 0.0\n\
         [[control]]\nt_s = 0.0\nspeed_mps = {SPEED_MPS}\nsteer_rad = 0.0\n",
        match contrast {
            Contrast::Alike => "alike",
            Contrast::PostsAndTrees => "posts-trees",
            Contrast::ReflectorAndTree => "reflector-trees",
        },
        contrast.name(),
    );
    // Pairs from two pitches behind the start to three ahead of the end.
    let end_m = SPEED_MPS * seconds + 3.0 * PAIR_PITCH_M;
    let mut k = 0usize;
    let mut x = -2.0 * PAIR_PITCH_M;
    while x <= end_m {
        for side in [1.0, -1.0] {
            let y = side * LATERAL_M[k % LATERAL_M.len()];
            let kinds = contrast.kinds();
            // Which member comes first alternates, so neither kind always leads.
            let (a, b) = if k.is_multiple_of(2) {
                (kinds[0], kinds[1])
            } else {
                (kinds[1], kinds[0])
            };
            for (kind, dx) in [(a, -0.5 * spacing_m), (b, 0.5 * spacing_m)] {
                let _ = writeln!(
                    text,
                    "[[features]]\nkind = \"{}\"\nx_m = {:.3}\ny_m = {y:.3}",
                    kind.name(),
                    x + dx
                );
            }
            k += 1;
        }
        x += PAIR_PITCH_M;
    }
    Ok(Scene::from_toml_str("pairs", &text)?)
}

/// How much the sweep does.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepBudget {
    /// Seeds per cell and innovation (the same seeds with and without power).
    pub seeds: usize,
    /// Simulated seconds per pair-scene run.
    pub seconds: f64,
    /// Seeds per street setting.
    pub street_seeds: usize,
    /// Simulated seconds per street run.
    pub street_seconds: f64,
    /// Skip the street (the realistic renderer is slow in a debug build).
    pub skip_street: bool,
    /// Worker threads.
    pub jobs: usize,
    /// Multiples of the default odometry noise to run at (see [`NOISE_MULTIPLES`]).
    pub noise_multiples: Vec<f64>,
    /// Skip the pair scenes (street only).
    pub skip_pairs: bool,
    /// Multiplies the street filter's observation noise (range, bearing, power standard
    /// deviations) over the front end's landmark noise: 1 as shipped.
    pub street_noise_scale: f64,
    /// Drop the street's moving vehicles (a diagnosis of its NEES).
    pub street_static_only: bool,
}

impl SweepBudget {
    /// The sweep's share of an evaluation budget.
    pub fn from_options(opts: &Options) -> Self {
        let b = &opts.budget;
        Self {
            seeds: b.association_sweep_seeds,
            seconds: b.association_sweep_seconds,
            street_seeds: b.association_sweep_seeds,
            street_seconds: b.association_sweep_street_seconds,
            skip_street: b.skip_heavy,
            jobs: b.jobs,
            noise_multiples: NOISE_MULTIPLES.to_vec(),
            skip_pairs: false,
            street_noise_scale: 1.0,
            street_static_only: false,
        }
    }
}

/// What one run gives the tables.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RunFigures {
    /// Wrong pairings over all pairings.
    wrong: f64,
    /// `targets`: missed pairings over labelled targets; `daemon`: associations of
    /// observations with no true feature within 1.5 m over all associations.
    missed: Option<f64>,
    /// Pairings judged.
    pairings: u64,
    position_rmse_m: f64,
    heading_rmse_deg: f64,
    /// Mean of the filter's position standard deviation (m, larger axis of x and y).
    sigma_position_m: f64,
    /// Mean of the filter's heading standard deviation (deg).
    sigma_heading_deg: f64,
    /// Features in the map at the end.
    features: usize,
    /// Spectrum bins inside the prediction's bound (daemon runs that predicted spectra).
    spectrum_inside: Option<f64>,
}

fn figures(r: &RunOutcome) -> RunFigures {
    let (wrong, pairings, missed) = match &r.daemon {
        Some(d) => {
            // Wrong among the associations of observations that came from a true feature;
            // the rest (no true feature within 1.5 m: clutter, car corners, fronts) are
            // given as their share in the `missed` column's place.
            let labelled = d.associations.saturating_sub(d.clutter_associations);
            (
                d.association_errors,
                labelled,
                Some(d.clutter_associations as f64 / d.associations.max(1) as f64),
            )
        }
        None => {
            let a = &r.association;
            let pairings = a.correct + a.wrong;
            (
                a.wrong,
                pairings,
                Some(a.missed as f64 / a.labelled_targets.max(1) as f64),
            )
        }
    };
    RunFigures {
        wrong: wrong as f64 / pairings.max(1) as f64,
        missed,
        pairings,
        position_rmse_m: rms(r.rotations.iter().map(|x| x.position_error_m())),
        heading_rmse_deg: rms(r
            .rotations
            .iter()
            .map(|x| x.heading_error_rad().to_degrees())),
        sigma_position_m: mean(r.rotations.iter().map(|x| x.sigma[0].max(x.sigma[1]))),
        sigma_heading_deg: mean(r.rotations.iter().map(|x| x.sigma[2].to_degrees())),
        features: r.final_features,
        spectrum_inside: r
            .daemon
            .as_ref()
            .and_then(|d| d.spectrum.in_bound_fraction()),
    }
}

/// Mean and standard error of the mean (NaN for none; SE NaN for one value).
pub fn mean_se(values: &[f64]) -> (f64, f64) {
    let n = values.len();
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let m = values.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return (m, f64::NAN);
    }
    let var = values.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1) as f64;
    (m, (var / n as f64).sqrt())
}

fn pct_se(values: &[f64]) -> String {
    let (m, se) = mean_se(values);
    if se.is_finite() {
        format!("{} ± {}", pct(m), pct(se))
    } else {
        pct(m)
    }
}

fn num_se(values: &[f64], digits: usize) -> String {
    let (m, se) = mean_se(values);
    if se.is_finite() {
        format!("{} ± {}", num(m, digits), num(se, digits))
    } else {
        num(m, digits)
    }
}

/// Smallest paired difference in a wrong-pairing rate called a difference (0.5 points).
pub const MIN_RATE_EFFECT: f64 = 0.005;

/// Smallest paired difference in position RMSE called a difference (m).
pub const MIN_RMSE_EFFECT_M: f64 = 0.005;

/// The verdict on a paired difference (with power minus without) of a quantity where
/// lower is better: a difference only beyond two standard errors and `min_effect`.
fn verdict(diffs: &[f64], min_effect: f64) -> &'static str {
    let (m, se) = mean_se(diffs);
    if !m.is_finite() || !se.is_finite() {
        return "n/a (one seed)";
    }
    if m.abs() <= 2.0 * se || m.abs() < min_effect {
        "no difference"
    } else if m < 0.0 {
        "power better"
    } else {
        "power worse"
    }
}

/// One cell's runs: the same seeds with and without power.
#[derive(Debug, Clone, Default)]
struct Cell {
    with: Vec<RunFigures>,
    without: Vec<RunFigures>,
    failed: Vec<String>,
}

impl Cell {
    fn paired<F: Fn(&RunFigures) -> Option<f64>>(&self, f: F) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let a: Vec<f64> = self.with.iter().filter_map(&f).collect();
        let b: Vec<f64> = self.without.iter().filter_map(&f).collect();
        let d = a.iter().zip(&b).map(|(x, y)| x - y).collect();
        (a, b, d)
    }

    fn pairings(&self) -> u64 {
        self.with
            .iter()
            .chain(&self.without)
            .map(|r| r.pairings)
            .sum()
    }
}

/// Runs `specs` (each run twice: with power, then without) and collects a cell. A run
/// that failed is named in the cell and left out of both sides (pairs stay paired).
fn run_cell(specs: &[RunSpec], jobs: usize) -> Cell {
    let mut both = Vec::with_capacity(2 * specs.len());
    for power in [true, false] {
        for s in specs {
            let mut s = s.clone();
            s.filter.use_power = power;
            both.push(s);
        }
    }
    let results = run_many(&both, jobs);
    let (with, without) = results.split_at(specs.len());
    let mut cell = Cell::default();
    for (a, b) in with.iter().zip(without) {
        match (a, b) {
            (Ok(a), Ok(b)) => {
                cell.with.push(figures(a));
                cell.without.push(figures(b));
            }
            (Err(e), _) | (_, Err(e)) => cell.failed.push(crate::error_chain(e)),
        }
    }
    cell
}

/// A run of a pair scene: `Targets` with the filter's own noise model, or the daemon as
/// shipped; the odometry and the filter's input noise both `odometry`.
fn pair_spec(
    scene: &Scene,
    seed: u64,
    seconds: f64,
    mode: &Mode,
    odometry: OdometryNoise,
) -> Result<RunSpec, EvalError> {
    let (filter, filter_power) = match mode {
        Mode::Targets => {
            let world = World::new(scene.clone(), seed, 0.5, odometry)?;
            (matched_filter(&world, &odometry, true), world.power)
        }
        Mode::Daemon(settings) => (settings.filter.clone(), settings.power),
    };
    Ok(RunSpec {
        filter,
        filter_power,
        scene: scene.clone(),
        seed,
        seconds,
        mode: mode.clone(),
        azimuth_stride: 1,
        beam_batch: 1,
        odometry,
        initial_sigma: [1e-3, 1e-3, 1e-4],
        health_every_rotations: None,
    })
}

/// The daemon's settings for the realistic street: the front end for current units
/// (the CTS350-X profile, `radar_model::profile::CTS350X`: learned floor and gain, only
/// point-like returns mapped, the landmark noise measured on the Oxford scans) with the
/// simulated radar's range-Doppler coupling, then the simulator's adjustments the
/// evaluation always makes (`crate::daemon::scene_settings`).
pub fn street_settings(scene: &Scene) -> Result<PipelineSettings, EvalError> {
    let bin_m = f64::from(scene.radar.range_gain) * scene.radar.bin_size_m();
    // The simulated CTS350-X renders its range-Doppler coupling; the daemon corrects it.
    let facts = slam_node::pipeline::SourceFacts {
        doppler_range_coupling_s: Some(scene.radar.doppler_range_coupling_s),
        peak_fwhm_m: Some(bin_m),
        no_radar_odometry: true,
        max_range_m: Some(scene.radar.max_range_m()),
        ..Default::default()
    };
    PipelineSettings::for_profile(&radar_model::profile::CTS350X, &facts)
        .map_err(|e| EvalError::Setting(format!("CTS350-X settings: {e}")))
}

fn street_spec(
    scene: &Scene,
    settings: &PipelineSettings,
    seed: u64,
    seconds: f64,
    odometry: OdometryNoise,
) -> RunSpec {
    RunSpec {
        filter: settings.filter.clone(),
        filter_power: settings.power,
        scene: scene.clone(),
        seed,
        seconds,
        mode: Mode::Daemon(Box::new(settings.clone())),
        azimuth_stride: 1,
        beam_batch: 1,
        odometry,
        initial_sigma: [1e-3, 1e-3, 1e-4],
        health_every_rotations: None,
    }
}

const HEADERS: [&str; 13] = [
    "observations",
    "odometry noise",
    "spacing (m)",
    "contrast",
    "wrong, with P",
    "wrong, without P",
    "wrong: with - without",
    "missed (targets) / unlabelled (daemon), with P",
    "same, without P",
    "position RMSE with / without (m)",
    "RMSE: with - without (m)",
    "filter sigma (m / deg)",
    "pairings",
];

/// A table row: what the cell is (`label`: observations, odometry, spacing, contrast) and
/// its figures.
fn cell_row(label: [&str; 4], cell: &Cell) -> Vec<String> {
    let (wa, wb, wd) = cell.paired(|r| Some(r.wrong));
    let (ma, mb, _) = cell.paired(|r| r.missed);
    let (ra, rb, rd) = cell.paired(|r| Some(r.position_rmse_m));
    let (sp, _, _) = cell.paired(|r| Some(r.sigma_position_m));
    let (sh, _, _) = cell.paired(|r| Some(r.sigma_heading_deg));
    let missed = |v: &[f64]| {
        if v.is_empty() {
            "n/a".to_string()
        } else {
            pct_se(v)
        }
    };
    let failed = match cell.failed.first() {
        None => String::new(),
        Some(e) => format!(" ({} failed: {e})", cell.failed.len()),
    };
    vec![
        format!("{}{failed}", label[0]),
        label[1].to_string(),
        label[2].to_string(),
        label[3].to_string(),
        pct_se(&wa),
        pct_se(&wb),
        format!("{} ({})", pct_se(&wd), verdict(&wd, MIN_RATE_EFFECT)),
        missed(&ma),
        missed(&mb),
        format!("{} / {}", num_se(&ra, 3), num_se(&rb, 3)),
        format!("{} ({})", num_se(&rd, 3), verdict(&rd, MIN_RMSE_EFFECT_M)),
        format!("{} / {}", num(mean(sp), 2), num(mean(sh), 2)),
        cell.pairings().to_string(),
    ]
}

fn noise_label(multiple: f64) -> String {
    if multiple == 1.0 {
        "shipped (1x)".to_string()
    } else {
        format!("{multiple}x")
    }
}

/// Runs the sweep and returns its Markdown (tables and findings).
///
/// # Errors
/// A scene that cannot be built or loaded, or the shipped settings failing to convert.
/// Failed runs are reported in the tables, not as errors.
pub fn sweep(b: &SweepBudget) -> Result<String, EvalError> {
    let seeds = b.seeds.max(1);
    let mut body = String::new();
    let d = OdometryNoise::default();
    let _ = writeln!(
        body,
        "Pairs of features 1-4 m apart along a straight {SPEED_MPS} m/s drive (pair centres every \
         {PAIR_PITCH_M} m, 6, 10 or 14 m to either side; the paper's radar); only the \
         materials differ between contrasts: alike (tree, tree), a lamp post next to a tree \
         (`rho 0.05, alpha 0.95` against `0.02, 0.60`, the simulator's material table: 4 dB \
         apart), and a corner reflector next to a tree (`rho 0.885`: 16 dB apart, the \
         table's extreme). {seeds} seed(s) x {} s per cell and innovation, the same seeds with \
         power (`R, beta, P`) and without (`R, beta`). Odometry noise: multiples of the \
         simulator's default ({} m/s and {} rad per {} Hz record), the filter told the same. \
         At 5x the filter's pose standard deviation is about 0.15 m and 0.6 degrees, which \
         with the 1 degree bearing noise leaves a 1 m neighbour inside the range-bearing \
         gate; at 20x it is 0.6-1 m and 2.4-3.7 degrees, so a feature 15 m away is predicted \
         to within 0.6-1 m across the beam and every spacing swept is ambiguous to geometry \
         alone (the filter's own mean pose standard deviations are in the last column but \
         one). `targets`: the filter fed every feature in the beam with its own noise model \
         (exact labels: each filter feature keeps the identity of the target it was made \
         from; *missed*: a labelled target left unpaired although a feature made from its \
         own true feature was a candidate). `daemon`: the daemon's pipeline as shipped on \
         the simulator's wire frames; its truth observer takes the true feature within \
         1.5 m of the observation (placed from the true pose) and the true feature within \
         2 m of the mapped feature's estimate, and calls the association wrong when they \
         differ; *unlabelled* is the share of associations whose observation has no true \
         feature within 1.5 m (clutter, sidelobes, or on the street car corners and \
         fronts), left out of the wrong rate. Because the observer judges the mapped \
         feature by where it now lies, a map that has drifted by a metre or more is counted \
         as wrong pairings in the daemon's rows (at 20x that is part of what they show); the \
         `targets` rows are free of that. Each figure is the \
         mean over seeds ± its standard error; *with - without* is the paired difference per \
         seed, called a difference only beyond two standard errors and beyond 0.5 points \
         (wrong pairings) or 5 mm (RMSE).\n",
        b.seconds, d.sigma_speed_mps, d.sigma_steer_rad, d.rate_hz
    );
    let mut rows = Vec::new();
    let mut findings = Vec::new();
    let daemon = crate::sections::shipped_daemon()?;
    let modes = if b.skip_pairs {
        Vec::new()
    } else {
        vec![("targets", Mode::Targets), ("daemon", daemon)]
    };
    for (mode_name, mode) in modes {
        for &multiple in &b.noise_multiples {
            let odometry = noisy_odometry(multiple);
            for contrast in Contrast::ALL {
                for spacing in SPACINGS_M {
                    let scene = pairs_scene(spacing, contrast, b.seconds)?;
                    let specs = (0..seeds)
                        .map(|k| pair_spec(&scene, 900 + k as u64, b.seconds, &mode, odometry))
                        .collect::<Result<Vec<_>, _>>()?;
                    let cell = run_cell(&specs, b.jobs);
                    let (_, _, wd) = cell.paired(|r| Some(r.wrong));
                    let (_, _, rd) = cell.paired(|r| Some(r.position_rmse_m));
                    for (what, diffs, v) in [
                        ("wrong pairings", &wd, verdict(&wd, MIN_RATE_EFFECT)),
                        ("position RMSE", &rd, verdict(&rd, MIN_RMSE_EFFECT_M)),
                    ] {
                        if v == "power better" || v == "power worse" {
                            let change = if what == "wrong pairings" {
                                pct_se(diffs)
                            } else {
                                format!("{} m", num_se(diffs, 3))
                            };
                            findings.push(format!(
                                "{mode_name}, {} odometry, {spacing} m, {}: {v} in {what} \
                                 ({change})",
                                noise_label(multiple),
                                contrast.name(),
                            ));
                        }
                    }
                    rows.push(cell_row(
                        [
                            mode_name,
                            &noise_label(multiple),
                            &num(spacing, 0),
                            contrast.name(),
                        ],
                        &cell,
                    ));
                }
            }
        }
    }
    if !rows.is_empty() {
        body.push_str(&table(&HEADERS, &rows));
        body.push('\n');
    }
    if !rows.is_empty() && findings.is_empty() {
        let _ = writeln!(
            body,
            "- In no cell does power change the wrong-pairing rate or the position RMSE beyond \
             two standard errors and the minimum effect.\n"
        );
    } else if !rows.is_empty() {
        let _ = writeln!(
            body,
            "Cells where power made a difference beyond two standard errors and the minimum \
             effect (every other cell: none):\n"
        );
        for f in &findings {
            let _ = writeln!(body, "- {f}");
        }
        body.push('\n');
    }
    if b.skip_street {
        let _ = writeln!(
            body,
            "The realistic street was skipped in this budget (it renders the CTS350-X-like \
             unit's 400 x 3768 bins with the realistic renderer).\n"
        );
        return Ok(body);
    }
    body.push_str(&street(b, b.street_seeds.max(1))?);
    Ok(body)
}

/// The daemon's own figures of a street run that the realism comparison uses.
#[derive(Debug, Clone, Copy, Default)]
struct StreetFigures {
    detections_per_rotation: f64,
    extended_per_rotation: f64,
    spectrum_inside: Option<f64>,
    spectrum_bias_db: Option<f64>,
    reobserved: f64,
}

fn street_figures(r: &RunOutcome) -> StreetFigures {
    let Some(d) = &r.daemon else {
        return StreetFigures::default();
    };
    let rotations = d.rotations.max(1) as f64;
    StreetFigures {
        detections_per_rotation: d.detections as f64 / rotations,
        extended_per_rotation: d.extended_returns as f64 / rotations,
        spectrum_inside: d.spectrum.in_bound_fraction(),
        spectrum_bias_db: d.spectrum.bias_db(),
        reobserved: d.features_reobserved as f64 / d.features_in_view.max(1) as f64,
    }
}

/// The street comparison, NEES and the realism figures.
fn street(b: &SweepBudget, seeds: usize) -> Result<String, EvalError> {
    let mut scene = shipped::load(STREET_SCENE)?;
    if b.street_static_only {
        scene.objects.retain(|o| o.speed_mps == 0.0);
    }
    let mut settings = street_settings(&scene)?;

    let k = b.street_noise_scale;
    if !(k.is_finite() && k > 0.0) {
        return Err(EvalError::Setting(format!(
            "street noise scale {k}: must be positive"
        )));
    }
    settings.filter.range_std_m *= k;
    settings.filter.bearing_std_rad *= k;
    settings.filter.power_std_db *= k;
    let mut body = String::new();
    let (poles, trees) = scene
        .features
        .iter()
        .fold((0, 0), |(p, t), f| match f.kind {
            FeatureKind::LampPost => (p + 1, t),
            FeatureKind::Tree => (p, t + 1),
            _ => (p, t),
        });
    let _ = writeln!(
        body,
        "**The realistic street** (`{STREET_SCENE}`: building fronts, {poles} lamp posts and \
         {trees} trees as point features, parked and moving cars, speckle, sidelobes, the \
         receiver fitted to the Oxford scans; 9 m/s), {seeds} seed(s) x {} s per setting, \
         through the daemon's front end for current units (as `--replay-dir` runs it: floor \
         and gain learned, only point-like returns mapped, landmark noise 0.35 m / 1.3 deg / \
         3.5 dB, four looks to confirm){}{}, with the shipped odometry noise and the sweep's.\n",
        b.street_seconds,
        if b.street_static_only {
            "; moving vehicles removed"
        } else {
            ""
        },
        if k == 1.0 {
            String::new()
        } else {
            format!(
                "; the filter's observation noise scaled by {k} (range {} m, bearing {} deg, \
                 power {} dB)",
                num(settings.filter.range_std_m, 2),
                num(settings.filter.bearing_std_rad.to_degrees(), 2),
                num(settings.filter.power_std_db, 2)
            )
        }
    );
    let mut rows = Vec::new();
    let mut nees_runs: Vec<RunOutcome> = Vec::new();
    let mut realism: Vec<StreetFigures> = Vec::new();
    let mut multiples = vec![1.0];
    multiples.extend(b.noise_multiples.iter().copied().filter(|m| *m != 1.0));
    for multiple in multiples {
        let odometry = noisy_odometry(multiple);
        let specs: Vec<RunSpec> = (0..seeds)
            .map(|k| {
                street_spec(
                    &scene,
                    &settings,
                    700 + k as u64,
                    b.street_seconds,
                    odometry,
                )
            })
            .collect();
        // Both sides in one batch; the with-power outcomes are kept whole (NEES).
        let mut both = specs.clone();
        for s in &specs {
            let mut s = s.clone();
            s.filter.use_power = false;
            both.push(s);
        }
        let results = run_many(&both, b.jobs);
        let (with, without) = results.split_at(specs.len());
        let mut cell = Cell::default();
        for (a, bb) in with.iter().zip(without) {
            match (a, bb) {
                (Ok(a), Ok(bb)) => {
                    cell.with.push(figures(a));
                    cell.without.push(figures(bb));
                    if multiple == 1.0 {
                        nees_runs.push(a.clone());
                        realism.push(street_figures(a));
                    }
                }
                (Err(e), _) | (_, Err(e)) => cell.failed.push(crate::error_chain(e)),
            }
        }
        rows.push(cell_row(
            [
                "daemon, street",
                &noise_label(multiple),
                "street",
                "its own (posts, trees)",
            ],
            &cell,
        ));
    }
    body.push('\n');
    body.push_str(&table(&HEADERS, &rows));
    body.push('\n');
    if !nees_runs.is_empty() {
        let series = crate::sections::consistency::average_nees(&nees_runs);
        let band = average_chi2_band(nees_runs.len(), 3, 0.95);
        let values: Vec<f64> = series
            .iter()
            .map(|x| x.1)
            .filter(|v| v.is_finite())
            .collect();
        let inside = values
            .iter()
            .filter(|v| **v >= band.0 && **v <= band.1)
            .count() as f64
            / values.len().max(1) as f64;
        let per_run: Vec<f64> = nees_runs
            .iter()
            .map(|r| mean(r.rotations.iter().filter_map(|x| x.nees)))
            .collect();
        let features: Vec<f64> = nees_runs.iter().map(|r| r.final_features as f64).collect();
        let _ = writeln!(
            body,
            "NEES on the realistic street (shipped odometry, power on, {} runs of {} s): the \
             time-mean of the average pose NEES is {} against the 95 % band [{}, {}], {} of \
             the rotations inside the band; per run {}. Features in the map at the end: {}.\n",
            nees_runs.len(),
            b.street_seconds,
            num(mean(values.iter().copied()), 2),
            num(band.0, 2),
            num(band.1, 2),
            pct(inside),
            per_run
                .iter()
                .map(|v| num(*v, 2))
                .collect::<Vec<_>>()
                .join(", "),
            num_se(&features, 1),
        );
        let det: Vec<f64> = realism.iter().map(|r| r.detections_per_rotation).collect();
        let ext: Vec<f64> = realism.iter().map(|r| r.extended_per_rotation).collect();
        let inb: Vec<f64> = realism.iter().filter_map(|r| r.spectrum_inside).collect();
        let bias: Vec<f64> = realism.iter().filter_map(|r| r.spectrum_bias_db).collect();
        let reob: Vec<f64> = realism.iter().map(|r| r.reobserved).collect();
        let _ = writeln!(
            body,
            "The same runs through the front end for current units (for the realism \
             comparison against `slam-node --replay-dir` on the Oxford scans): {} detections \
             per rotation, {} of them extended returns kept out of the map; spectrum bins \
             inside the prediction's bound {}, bias {} dB; mapped features re-observed in \
             later rotations in view {}.\n",
            num_se(&det, 0),
            num_se(&ext, 0),
            pct_se(&inb),
            num_se(&bias, 2),
            pct_se(&reob),
        );
    }
    Ok(body)
}

/// Runs the section.
pub fn section(opts: &Options) -> Result<Section, EvalError> {
    Ok(Section {
        title: "Where could power aid association? (the claim swept)".into(),
        body: sweep(&SweepBudget::from_options(opts))?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pair_scene_puts_each_pair_spacing_apart_with_the_contrast_s_materials() {
        let scene = pairs_scene(2.0, Contrast::PostsAndTrees, 10.0).expect("scene");
        assert!(scene.features.len() >= 20);
        assert_eq!(scene.features.len() % 2, 0);
        for pair in scene.features.chunks_exact(2) {
            let d = (pair[0].x_m - pair[1].x_m).hypot(pair[0].y_m - pair[1].y_m);
            assert!((d - 2.0).abs() < 1e-6, "{d}");
            let mut kinds = [pair[0].kind, pair[1].kind];
            kinds.sort_by_key(|k| k.name());
            assert_eq!(kinds, [FeatureKind::LampPost, FeatureKind::Tree]);
        }
        let alike = pairs_scene(2.0, Contrast::Alike, 10.0).expect("scene");
        assert!(alike.features.iter().all(|f| f.kind == FeatureKind::Tree));
        let same_places = alike
            .features
            .iter()
            .zip(&scene.features)
            .all(|(a, b)| a.x_m == b.x_m && a.y_m == b.y_m);
        assert!(same_places, "only the materials differ between contrasts");
    }

    #[test]
    fn a_pair_scene_refuses_a_spacing_or_duration_out_of_range() {
        for (s, t) in [
            (0.0, 10.0),
            (f64::NAN, 10.0),
            (30.0, 10.0),
            (1.0, 0.0),
            (1.0, 1e9),
        ] {
            assert!(pairs_scene(s, Contrast::Alike, t).is_err(), "{s} {t}");
        }
    }

    #[test]
    fn mean_and_standard_error_are_those_of_the_sample() {
        let (m, se) = mean_se(&[1.0, 2.0, 3.0, 4.0]);
        assert!((m - 2.5).abs() < 1e-12);
        // sd = sqrt(5/3), se = sd / 2.
        assert!((se - (5.0f64 / 3.0).sqrt() / 2.0).abs() < 1e-12);
        assert!(mean_se(&[1.0]).1.is_nan());
        assert!(mean_se(&[]).0.is_nan());
    }

    #[test]
    fn a_difference_within_two_standard_errors_or_below_the_minimum_effect_is_no_difference() {
        assert_eq!(verdict(&[0.01, -0.01, 0.02, -0.02], 0.0), "no difference");
        assert_eq!(verdict(&[-0.05, -0.06, -0.04, -0.05], 0.0), "power better");
        assert_eq!(verdict(&[0.05, 0.06, 0.04, 0.05], 0.0), "power worse");
        assert_eq!(verdict(&[0.05], 0.0), "n/a (one seed)");
        // Beyond two standard errors but below the minimum effect.
        assert_eq!(verdict(&[0.001, 0.0011, 0.0009], 0.005), "no difference");
    }
}
