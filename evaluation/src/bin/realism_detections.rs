//! Detections per rotation with the daemon's detector (`slam_node::detect`) on the real
//! Oxford scans and on the simulated `urban-street` scene (the realistic renderer), the
//! same detector settings and the same per-bin gain (none removed) for both: the
//! detection figure of the realism comparison (`cargo run --release -p sim-sensor
//! --example realism` gives the others).
//!
//! Run: `cargo run --release -p evaluation --bin realism_detections [-- SCENE]` (SCENE: a
//! shipped scene's name or a scene file; `urban-street` by default).
//!
//! Rows: the daemon's default detector (TPP), and the front end for current units
//! (`[detector] kind = "learned"`, with the settings `slam-node --replay-dir` uses):
//! every target it finds, and the point-like ones. Then the learned front end's extended
//! targets by range extent, its targets by SNR band with their median range extent, and
//! the strong point-like targets that may start a feature (the replay's landmark test).
//!
//! The detector's default (TPP) keeps a per-bin minimum over scans, so the first two
//! rotations of each set are warm-up and are not counted.
//!
//! Then which simulated objects make the learned front end's targets, by removal: the
//! street rendered again without one kind of object at a time (ground clutter on the
//! streets, clutter inside the blocks, hedges, crowns, parked and moving vehicles,
//! building fronts, the point features, and the multipath ghosts, which are no object but
//! which the fronts form as mirrors), and the targets that go with it. Removing an
//! occluder (a front, a hedge, a vehicle) also uncovers what it hid, so its row is what it
//! makes less what it hides.

use sim_sensor::realism::calibrate::{default_oxford_dir, load_polar_dir};
use sim_sensor::realism::stats::Scans;
use sim_sensor::realism::{ObjectKind, ObjectSpec};
use sim_sensor::render::render_scans;
use sim_sensor::scene::{shipped, Scene};
use slam_node::detect::{
    BeamDetector, DetectorKind, DetectorSettings, LearnedFloor, LineDetector, LineSettings,
    RangeAxis,
};

/// Mean detections per rotation over the rotations after `warmup`.
fn per_rotation(scans: &Scans, settings: DetectorSettings, warmup: usize) -> f64 {
    let mut detector = BeamDetector::new(settings, scans.azimuths);
    let gain = vec![0.0; scans.bins];
    let axis = RangeAxis {
        first_bin_m: 0.0,
        bin_m: scans.bin_m,
    };
    let mut out = Vec::new();
    let mut counted = 0usize;
    let mut total = 0usize;
    let mut row_db = vec![0.0; scans.bins];
    for (r, rot) in scans.rotations.iter().enumerate() {
        for (a, row) in rot.chunks_exact(scans.bins).enumerate() {
            for (d, &v) in row_db.iter_mut().zip(row) {
                *d = f64::from(v) / 2.0;
            }
            out.clear();
            detector.detect(a, &row_db, &gain, None, &axis, &mut out);
            if r >= warmup {
                total += out.len();
            }
        }
        if r >= warmup {
            counted += 1;
        }
    }
    total as f64 / counted.max(1) as f64
}

/// Range extents (m) of extended targets: the upper edges of [`extent_histogram`]'s bins.
const EXTENT_EDGES_M: [f64; 5] = [1.0, 2.0, 4.0, 8.0, f64::INFINITY];

/// What the learned front end finds over the rotations after the warm-up
/// ([`learned_with_extents`]).
struct LearnedTargets {
    /// Targets per rotation.
    all: f64,
    /// Point-like ones (at most the landmark extent in range) per rotation.
    points: f64,
    /// Extended targets per rotation by range extent (`EXTENT_EDGES_M`).
    extended: [f64; 5],
    /// Every target's SNR (dB) and range extent (m).
    snr_extent: Vec<(f64, f64)>,
    /// Rotations counted.
    rotations: usize,
    /// The learned floor at the end: per bin, its median and spread (dB).
    floor_median_db: Vec<f64>,
    /// Its per-bin spread (dB).
    floor_sigma_db: Vec<f64>,
}

/// Targets the learned front end finds (`[detector] kind = "learned"`: the floor learned
/// from the stream, the line-rate detector) over the rotations after `warmup`: all of them
/// and the point-like ones per rotation (at most the landmark extent in range, the others
/// being what the daemon keeps out of the map as extended), the extended ones by range
/// extent, every target's SNR and extent, and the learned floor.
fn learned_with_extents(
    scans: &Scans,
    settings: &DetectorSettings,
    warmup: usize,
) -> LearnedTargets {
    let mut hist = [0usize; 5];
    let mut snr_extent = Vec::new();
    let mut floor = LearnedFloor::new(settings.floor, scans.bins);
    let mut line = LineDetector::new();
    let axis = RangeAxis {
        first_bin_m: 0.0,
        bin_m: scans.bin_m,
    };
    let line_settings = LineSettings {
        merge_gap_bins: settings.peaks.merge_gap_bins,
        max_peaks: settings.peaks.max_peaks,
        min_range_m: settings.min_range_m,
        max_range_m: settings.max_range_m,
    };
    let mut peaks = Vec::new();
    let (mut all, mut points, mut counted) = (0usize, 0usize, 0usize);
    for (r, rot) in scans.rotations.iter().enumerate() {
        for row in rot.chunks_exact(scans.bins) {
            line.detect(row, &mut floor, &axis, &line_settings, &mut peaks);
            if r >= warmup {
                all += peaks.len();
                for p in &peaks {
                    let extent = p.extent_bins as f64 * scans.bin_m;
                    snr_extent.push((p.snr_db, extent));
                    if extent <= settings.landmarks.max_extent_m {
                        points += 1;
                    } else if let Some(h) = EXTENT_EDGES_M
                        .iter()
                        .position(|&e| extent <= e)
                        .and_then(|k| hist.get_mut(k))
                    {
                        *h += 1;
                    }
                }
            }
        }
        if r >= warmup {
            counted += 1;
        }
    }
    let n = counted.max(1) as f64;
    LearnedTargets {
        all: all as f64 / n,
        points: points as f64 / n,
        extended: hist.map(|h| h as f64 / n),
        snr_extent,
        rotations: counted,
        floor_median_db: floor.median_db().to_vec(),
        floor_sigma_db: floor.sigma_db().to_vec(),
    }
}

/// Lower edges of the SNR bands (dB) of the extent-by-SNR table; the last is open.
const SNR_EDGES_DB: [f64; 9] = [12.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0];

/// Per SNR band: targets, median range extent (m) and the share longer than `point_m`.
fn extent_by_snr(targets: &[(f64, f64)], point_m: f64) -> Vec<(usize, f64, f64)> {
    SNR_EDGES_DB
        .iter()
        .enumerate()
        .map(|(k, &lo)| {
            let hi = SNR_EDGES_DB.get(k + 1).copied().unwrap_or(f64::INFINITY);
            let mut e: Vec<f64> = targets
                .iter()
                .filter(|(s, _)| *s >= lo && *s < hi)
                .map(|&(_, x)| x)
                .collect();
            e.sort_by(f64::total_cmp);
            let median = e.get(e.len() / 2).copied().unwrap_or(f64::NAN);
            let long = e.iter().filter(|&&x| x > point_m).count();
            (e.len(), median, long as f64 / e.len().max(1) as f64)
        })
        .collect()
}

fn main() -> anyhow::Result<()> {
    let dir = default_oxford_dir();
    if !dir.is_dir() {
        println!("no real scans at {}: nothing to compare", dir.display());
        return Ok(());
    }
    let real = load_polar_dir(&dir)?;
    let name = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "urban-street".into());
    let scene = if shipped::NAMES.contains(&name.as_str()) {
        shipped::load(&name)?
    } else {
        Scene::load(std::path::Path::new(&name))?
    };
    let sim = render_scans(&scene, None, 4, real.rotations.len() as u64)?;
    println!("| detector | real detections / rotation | simulated | sim / real |");
    println!("|---|---|---|---|");
    // The daemon's default detector (TPP); two rotations of warm-up.
    let settings = DetectorSettings {
        kind: DetectorKind::Tpp,
        ..DetectorSettings::default()
    };
    let (r, s) = (
        per_rotation(&real, settings, 2),
        per_rotation(&sim, settings, 2),
    );
    println!(
        "| TPP (the daemon's default) | {r:.0} | {s:.0} | {:.2} |",
        s / r
    );
    // The front end for current units, with the settings the replay runs it with.
    // Run once on each set: the counts, the extents and the floor all come from this.
    let learned = |scans: &Scans| {
        let facts = slam_node::pipeline::SourceFacts {
            max_range_m: Some(scans.bins as f64 * scans.bin_m),
            peak_fwhm_m: Some(scans.bin_m),
            ..Default::default()
        };
        let settings = slam_node::pipeline::PipelineSettings::for_profile(
            &radar_model::profile::CTS350X,
            &facts,
        )
        .expect("the CTS350-X profile's settings");
        (
            learned_with_extents(scans, &settings.detector, 2),
            settings.detector.landmarks,
        )
    };
    let ((rt, landmarks), (st, _)) = (learned(&real), learned(&sim));
    let ((ra, rp), (sa, sp)) = ((rt.all, rt.points), (st.all, st.points));
    println!(
        "| learned front end (current units), every target | {ra:.0} | {sa:.0} | {:.2} |",
        sa / ra
    );
    println!(
        "| learned front end, point-like targets (extent <= 0.5 m) | {rp:.0} | {sp:.0} | {:.2} |",
        sp / rp
    );
    println!("\n| extended targets by range extent (m) | real / rotation | simulated |");
    println!("|---|---|---|");
    let mut lower = 0.5;
    for ((edge, r), s) in EXTENT_EDGES_M.iter().zip(rt.extended).zip(st.extended) {
        println!("| {lower}-{edge} | {r:.0} | {s:.0} |");
        lower = *edge;
    }
    // How long a target is in range against how strong it is: what decides whether a
    // strong return is point-like enough to start a feature.
    let point_m = landmarks.max_extent_m;
    println!(
        "\n| SNR (dB) | real targets / rotation | median range extent (m) | longer than {point_m} m | simulated targets / rotation | median extent | longer than {point_m} m |"
    );
    println!("|---|---|---|---|---|---|---|");
    let per = |t: &LearnedTargets, n: usize| n as f64 / t.rotations.max(1) as f64;
    for (k, (r, s)) in extent_by_snr(&rt.snr_extent, point_m)
        .into_iter()
        .zip(extent_by_snr(&st.snr_extent, point_m))
        .enumerate()
    {
        let lo = SNR_EDGES_DB[k];
        let band = SNR_EDGES_DB
            .get(k + 1)
            .map_or(format!("{lo:.0}+"), |hi| format!("{lo:.0}-{hi:.0}"));
        println!(
            "| {band} | {:.0} | {:.2} | {:.0} % | {:.0} | {:.2} | {:.0} % |",
            per(&rt, r.0),
            r.1,
            100.0 * r.2,
            per(&st, s.0),
            s.1,
            100.0 * s.2
        );
    }
    // The detection threshold sits at the learned median plus the larger of k sigma and
    // the minimum SNR: the per-bin spread decides how long a strong return's run is.
    println!(
        "\n| range (m) | real floor median / sigma (dB, median over the band's bins) | simulated |"
    );
    println!("|---|---|---|");
    // The median over the bins of `lo..hi` m of a per-bin table on `bin_m` bins.
    let band = |v: &[f64], bin_m: f64, lo: f64, hi: f64| {
        let mut x: Vec<f64> = v
            .iter()
            .enumerate()
            .filter(|&(i, _)| (lo..hi).contains(&(i as f64 * bin_m)))
            .map(|(_, &y)| y)
            .collect();
        x.sort_by(f64::total_cmp);
        x.get(x.len() / 2).copied().unwrap_or(f64::NAN)
    };
    for (lo, hi) in [
        (2.0, 5.0),
        (5.0, 10.0),
        (10.0, 20.0),
        (20.0, 30.0),
        (30.0, 45.0),
        (45.0, 60.0),
        (60.0, 80.0),
        (80.0, 130.0),
    ] {
        println!(
            "| {lo:.0}-{hi:.0} | {:.1} / {:.1} | {:.1} / {:.1} |",
            band(&rt.floor_median_db, real.bin_m, lo, hi),
            band(&rt.floor_sigma_db, real.bin_m, lo, hi),
            band(&st.floor_median_db, sim.bin_m, lo, hi),
            band(&st.floor_sigma_db, sim.bin_m, lo, hi)
        );
    }
    let starts = |t: &LearnedTargets| {
        let n = t
            .snr_extent
            .iter()
            .filter(|&&(snr, x)| snr >= landmarks.min_snr_db && x <= point_m)
            .count();
        per(t, n)
    };
    let (rs, ss) = (starts(&rt), starts(&st));
    println!(
        "\nstrong point-like targets (SNR >= {} dB, extent <= {point_m} m: what may start a feature) per rotation: real {rs:.0}, simulated {ss:.0} ({:.2})",
        landmarks.min_snr_db,
        ss / rs.max(f64::MIN_POSITIVE)
    );
    // Attribution by removal.
    println!("\n| simulated street without | every target / rotation | point-like | extended | extended less than the whole street |");
    println!("|---|---|---|---|---|");
    let extended_all = sa - sp;
    let rows: [(&str, &Removed); 8] = [
        ("(nothing removed)", &|_| false),
        ("ground clutter on the streets", &|o| is_clutter(o, true)),
        ("clutter inside the blocks", &|o| is_clutter(o, false)),
        ("hedges", &|o| o.kind == ObjectKind::Hedge),
        ("crowns (foliage)", &|o| o.kind == ObjectKind::Foliage),
        ("parked vehicles", &|o| {
            o.kind == ObjectKind::Vehicle && o.speed_mps == 0.0
        }),
        ("moving vehicles", &|o| {
            o.kind == ObjectKind::Vehicle && o.speed_mps != 0.0
        }),
        ("building fronts", &|o| o.kind == ObjectKind::BuildingFront),
    ];
    let mut variants: Vec<(String, Scene)> = rows
        .iter()
        .map(|(name, drop)| {
            let mut s = scene.clone();
            s.objects.retain(|o| !drop(o));
            (name.to_string(), s)
        })
        .collect();
    let mut points = scene.clone();
    points.features.clear();
    variants.push(("point features (trunks, lamp posts)".into(), points));
    // Not an object: the multipath ghosts, which the fronts and walls form as mirrors (so
    // the fronts' row above includes them).
    let mut no_ghosts = scene.clone();
    if let Some(realism) = no_ghosts.realism.as_mut() {
        realism.multipath = false;
        variants.push(("multipath ghosts (`multipath = false`)".into(), no_ghosts));
    }
    for (name, variant) in &variants {
        let scans = render_scans(variant, None, 4, real.rotations.len() as u64)?;
        let (t, _) = learned(&scans);
        let (a, p) = (t.all, t.points);
        println!(
            "| {name} | {a:.0} | {p:.0} | {:.0} | {:.0} |",
            a - p,
            extended_all - (a - p)
        );
    }
    Ok(())
}

/// Which objects a row of the attribution removes.
type Removed = dyn Fn(&ObjectSpec) -> bool;

/// Ground clutter the street generator laid along a street (`street`: a rectangle less
/// than 20 m across, the street's width) or inside a block (wider).
fn is_clutter(o: &ObjectSpec, street: bool) -> bool {
    if o.kind != ObjectKind::Clutter {
        return false;
    }
    let (Some(a), Some(b)) = (o.from, o.to) else {
        return false;
    };
    let narrow = (b[0] - a[0]).abs().min((b[1] - a[1]).abs());
    (narrow < 20.0) == street
}
