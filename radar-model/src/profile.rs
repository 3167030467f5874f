//! Radar profiles: what a radar model *is* and what was measured on it, one place per model.
//!
//! A profile holds the facts of one Navtech model (azimuths, bins, bin size, range
//! resolution, beam, rotation rate, range-Doppler coupling), the noise of a landmark's look
//! on it, the landmark thresholds, the front end that suits it and the receiver compensation,
//! each value with where it comes from. The daemon picks a profile from what the radar
//! announces at connection ([`select`]) unless the configuration names one, and derives every
//! setting from the profile and the keys the configuration writes.
//!
//! No IO: the profiles are constants.

use std::fmt;

/// A value and where it comes from (a data sheet, a data set's documentation, a paper, or
/// the command that measured it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sourced<T> {
    /// The value.
    pub value: T,
    /// Where it comes from.
    pub source: &'static str,
}

const fn s<T>(value: T, source: &'static str) -> Sourced<T> {
    Sourced { value, source }
}

/// The front end that suits a radar.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrontEndFamily {
    /// The paper's unit: a fixed noise-floor model, the TPP detector on 0.25 m bins.
    PaperTpp,
    /// A current unit: noise floor and receiver gain learned from the stream, detection at
    /// line rate on the wire's bins, only point-like returns mapped.
    Learned,
}

/// The receiver's range compensation as the profile models it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CompensationSlope {
    /// 60 dB per decade (the paper's model of its unit's filter).
    Sixty,
    /// 40 dB per decade (the radar equation's R^-4 exactly).
    Forty,
}

/// What makes a return a landmark on this radar, and how long it must repeat.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandmarkThresholds {
    /// Only point-like returns start features.
    pub points_only: bool,
    /// Widest extent along range of a point-like return (m).
    pub point_max_extent_m: f64,
    /// Widest point-like return across azimuths (beam widths).
    pub point_max_width_beams: f64,
    /// Least SNR of a return that starts a feature (dB over the learned floor).
    pub point_min_snr_db: f64,
    /// Extended returns (walls, fences) may re-observe mapped features.
    pub extended_reobserve: bool,
    /// Looks in different rotations before a feature is mapped.
    pub confirm_after: u32,
    /// Least time between two looks that count separately (s).
    pub confirm_min_separation_s: f64,
}

/// The learned front end's floor settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LearnedFloor {
    /// Detection threshold in standard deviations of the learned floor.
    pub floor_sigma: f64,
    /// Least SNR over the learned floor (dB).
    pub floor_min_snr_db: f64,
}

/// One radar model: its facts and what was measured on it.
#[derive(Debug, Clone, PartialEq)]
pub struct RadarProfile {
    /// The name `[radar] model` takes.
    pub name: &'static str,
    /// The maker's model and where the profile's figures were taken.
    pub description: &'static str,
    /// Azimuths per rotation.
    pub azimuths: Sourced<u16>,
    /// Encoder counts per revolution.
    pub encoder_size: Sourced<u16>,
    /// Range bins per azimuth.
    pub range_bins: Sourced<u16>,
    /// Bin size (m).
    pub bin_size_m: Sourced<f64>,
    /// Range resolution c / 2B (m): the width of a point's peak in the power and noise models.
    pub range_resolution_m: Sourced<f64>,
    /// Horizontal beam width (degrees), the antenna's half-power width; the beam model is a
    /// flat beam of this width (`geometry`).
    pub beam_width_deg: Sourced<f64>,
    /// Rotations per second.
    pub rotation_hz: Sourced<f64>,
    /// FMCW range-Doppler coupling (s): a return closing at `v` m/s reads `v` times this short.
    pub doppler_range_coupling_s: Sourced<f64>,
    /// Range noise of a landmark's look (m).
    pub sigma_range_m: Sourced<f64>,
    /// Bearing noise of a landmark's look (degrees).
    pub sigma_bearing_deg: Sourced<f64>,
    /// Power noise of a landmark's look about its model (dB).
    pub sigma_power_db: Sourced<f64>,
    /// The landmark thresholds.
    pub landmarks: Sourced<LandmarkThresholds>,
    /// The front end that suits the radar.
    pub front_end: Sourced<FrontEndFamily>,
    /// The learned front end's floor (used when `front_end` is `Learned`).
    pub learned_floor: Sourced<LearnedFloor>,
    /// The receiver compensation the model assumes before any is learned.
    pub compensation: Sourced<CompensationSlope>,
    /// Radar odometry (rotations registered against each other) on by default.
    pub radar_odometry: Sourced<bool>,
}

const PAPER: &str = "Jose and Adams (the paper)";
const CHAPTER: &str = "the book chapter's measured noise (radar-model noise.rs)";
const SIM_ASSUMED: &str = "not given by the paper: sim-sensor's assumption (radar.rs)";
const OXFORD_SDK: &str = "the Oxford Radar RobotCar documentation: 400 azimuths (0.9 degrees), 3768 bins, 4.38 cm, to 163 m (the SDK's radar.py uses 0.0432 m)";
const NAVTECH_BEAM: &str = "1.8 degrees, as the paper's unit and RADIATE's CTS350-X (radiate_sdk README); no Navtech data sheet at hand";
const OXFORD_MEASURED: &str = "measured on the Oxford scans: nearest point-like look within 2 m of each mapped feature, 90 pairs (slam-node/README.md, 'The front end for current units'; cargo run --release -p slam-node -- --replay-dir ../shared/data/oxford-radar-robotcar --fast)";
const CTS_LANDMARKS: &str = "chosen on the Oxford scans: at most a tenth of the raw detections become features, re-observed in most later rotations (slam-node/README.md, 'The front end for current units')";
const CTS_FRONT_END: &str =
    "slam-node/README.md, 'The front end for current units' (cargo bench -p slam-node --bench detect_line_rate)";
const NOT_MEASURED_HERE: &str =
    "not measured on this unit: the CTS350-X's (same maker, same front-end chain)";
const CTS_ODOMETRY: &str = "slam-node/README.md, 'Radar odometry': on the Oxford scans with odometry 5 % fast, final error 0.17 m against dead reckoning's 0.85 m";

/// The unit of Jose and Adams: 77 GHz FMCW, 1.8 degree steps and beam, 0.25 m bins.
pub const PAPER_2006: RadarProfile = RadarProfile {
    name: "paper-2006",
    description: "the Navtech 77 GHz FMCW unit of Jose and Adams (2006)",
    azimuths: s(200, "the paper: 1.8 degree azimuth steps"),
    encoder_size: s(5600, SIM_ASSUMED),
    range_bins: s(800, "200 m at 0.25 m: sim-sensor's paper-200 preset"),
    bin_size_m: s(0.25, "the paper: c / 2B with B = 600 MHz"),
    range_resolution_m: s(0.25, "the paper: c / 2B with B = 600 MHz"),
    beam_width_deg: s(1.8, PAPER),
    rotation_hz: s(2.5, SIM_ASSUMED),
    doppler_range_coupling_s: s(0.0, "the paper models none"),
    sigma_range_m: s(
        0.1,
        "assumed (radar-model's RangeSpread phase-noise jitter; the paper gives none)",
    ),
    sigma_bearing_deg: s(1.0, CHAPTER),
    sigma_power_db: s(
        2.017_424_100_183_201_4,
        "the book chapter: target-present variance 4.07 dB^2 (its square root)",
    ),
    landmarks: s(
        LandmarkThresholds {
            points_only: false,
            point_max_extent_m: 0.5,
            point_max_width_beams: 2.5,
            point_min_snr_db: 0.0,
            extended_reobserve: false,
            confirm_after: 2,
            confirm_min_separation_s: 0.1,
        },
        "the paper maps every detection; two looks (slam-filter's defaults)",
    ),
    front_end: s(
        FrontEndFamily::PaperTpp,
        "TPP, scored on the simulator's scenes (cargo test --release -p slam-node --test detection_scoring -- --ignored --nocapture)",
    ),
    learned_floor: s(
        LearnedFloor {
            floor_sigma: 4.0,
            floor_min_snr_db: 12.0,
        },
        "unused by this front end: the learned front end's defaults",
    ),
    compensation: s(CompensationSlope::Sixty, "the paper: 60 dB per decade"),
    radar_odometry: s(false, "the paper uses odometry alone"),
};

/// The CTS350-X of the Oxford Radar RobotCar data set.
pub const CTS350X: RadarProfile = RadarProfile {
    name: "cts350x",
    description: "Navtech CTS350-X (Oxford Radar RobotCar)",
    azimuths: s(400, OXFORD_SDK),
    encoder_size: s(5600, "the Oxford scans' encoder column (radar/<us>.png metadata)"),
    range_bins: s(3768, OXFORD_SDK),
    bin_size_m: s(0.0438, OXFORD_SDK),
    range_resolution_m: s(
        0.0438,
        "the bin size: a point's peak is about one bin wide on the Oxford scans",
    ),
    beam_width_deg: s(1.8, NAVTECH_BEAM),
    rotation_hz: s(4.0, OXFORD_SDK),
    doppler_range_coupling_s: s(
        0.0488,
        "Burnett et al., RA-L 2021 ('Do we need to compensate for motion distortion and Doppler effects in spinning radar navigation?'), on these scans",
    ),
    sigma_range_m: s(0.35, OXFORD_MEASURED),
    sigma_bearing_deg: s(1.3, OXFORD_MEASURED),
    sigma_power_db: s(3.5, OXFORD_MEASURED),
    landmarks: s(
        LandmarkThresholds {
            points_only: true,
            point_max_extent_m: 0.5,
            point_max_width_beams: 2.5,
            point_min_snr_db: 32.0,
            extended_reobserve: false,
            confirm_after: 4,
            confirm_min_separation_s: 0.2,
        },
        CTS_LANDMARKS,
    ),
    front_end: s(FrontEndFamily::Learned, CTS_FRONT_END),
    learned_floor: s(
        LearnedFloor {
            floor_sigma: 4.0,
            floor_min_snr_db: 12.0,
        },
        CTS_FRONT_END,
    ),
    compensation: s(
        CompensationSlope::Sixty,
        "a starting curve only: the learned front end learns the receiver's gain from the stream",
    ),
    radar_odometry: s(true, CTS_ODOMETRY),
};

/// The CTS350-X's look noise, for a unit it was not measured on.
const BORROWED_SIGMA_RANGE: Sourced<f64> = s(CTS350X.sigma_range_m.value, NOT_MEASURED_HERE);
/// The same for the bearing.
const BORROWED_SIGMA_BEARING: Sourced<f64> = s(CTS350X.sigma_bearing_deg.value, NOT_MEASURED_HERE);
/// The same for the power.
const BORROWED_SIGMA_POWER: Sourced<f64> = s(CTS350X.sigma_power_db.value, NOT_MEASURED_HERE);

/// The Navtech unit of the RADIATE data set: a CTS350-X set to 0.17 m bins and 100 m.
pub const CTS350X_RADIATE: RadarProfile = RadarProfile {
    name: "cts350x-radiate",
    description: "Navtech CTS350-X set to 576 bins of 0.1736 m (RADIATE; radiate_sdk README names the model)",
    azimuths: s(400, "radiate_sdk config.yaml: 400 azimuths of 0.9 degrees"),
    encoder_size: s(
        5600,
        "RADIATE carries no encoder values: the Navtech encoder size assumed",
    ),
    range_bins: s(576, "radiate_sdk config.yaml: 576 range rows"),
    bin_size_m: s(0.173611, "radiate_sdk config.yaml: range resolution 0.173611 m"),
    range_resolution_m: s(0.173611, "radiate_sdk config.yaml"),
    beam_width_deg: s(
        1.8,
        "radiate_sdk README: 1.8 degrees azimuth and elevation resolution",
    ),
    rotation_hz: s(
        4.0,
        "radiate_sdk: frames 0.25 s apart (the SDK's demo steps dt = 0.25)",
    ),
    doppler_range_coupling_s: s(
        0.0,
        "not published for this chirp: not corrected (slam-node/README.md, 'Range-Doppler coupling')",
    ),
    sigma_range_m: BORROWED_SIGMA_RANGE,
    sigma_bearing_deg: BORROWED_SIGMA_BEARING,
    sigma_power_db: BORROWED_SIGMA_POWER,
    // The front end, landmark thresholds, compensation and radar odometry of the CTS350-X.
    ..CTS350X
};

/// The Navtech unit of the Boreas data set until its upgrade of 2021-09-21 (pyboreas names
/// it the CIR204; the Boreas paper's abstract names a CIR304-H).
pub const CIR204H: RadarProfile = RadarProfile {
    name: "cir204h",
    description: "Navtech CIR204-H (Boreas until 2021-09-21: 3360 bins of 0.0596 m; the Boreas paper names a CIR304-H)",
    azimuths: s(400, "pyboreas DATA_REFERENCE.md: 400 azimuths, 0.9 degrees"),
    encoder_size: s(5600, "pyboreas DATA_REFERENCE.md: encoder of 5600 counts"),
    range_bins: s(
        3360,
        "pyboreas DATA_REFERENCE.md: 200.256 m at 0.0596 m a bin",
    ),
    bin_size_m: s(
        0.0596,
        "pyboreas utils/radar.py: 0.0596 m before upgrade_time (2021-09-21), 0.04381 m after",
    ),
    range_resolution_m: s(0.0596, "the bin size, as the CTS350-X's"),
    beam_width_deg: s(1.8, NAVTECH_BEAM),
    rotation_hz: s(4.0, "pyboreas DATA_REFERENCE.md: 4 Hz"),
    doppler_range_coupling_s: s(
        0.049,
        "Burnett's code for Boreas' CIR204 data (steam_icp boreas_navtech.hpp: beta 0.049)",
    ),
    sigma_range_m: BORROWED_SIGMA_RANGE,
    sigma_bearing_deg: BORROWED_SIGMA_BEARING,
    sigma_power_db: BORROWED_SIGMA_POWER,
    // The front end, landmark thresholds, compensation and radar odometry of the CTS350-X.
    ..CTS350X
};

/// The Navtech unit of the Boreas data set from its upgrade of 2021-09-21 (the Boreas
/// paper's CIR304-H; Navtech's RAS6 family): 0.04381 m bins.
pub const CIR304H: RadarProfile = RadarProfile {
    name: "cir304h",
    description: "Navtech CIR304-H / RAS6 (Boreas from 2021-09-21: 0.04381 m bins)",
    azimuths: s(400, "pyboreas DATA_REFERENCE.md: 400 azimuths, 0.9 degrees"),
    encoder_size: s(5600, "pyboreas DATA_REFERENCE.md: encoder of 5600 counts"),
    range_bins: s(
        6848,
        "assumed (about 300 m at 0.04381 m); not confirmed by a public source: a unit announcing another count gets this profile with a WARN naming it",
    ),
    bin_size_m: s(
        0.04381,
        "pyboreas utils/radar.py: 0.04381 m after upgrade_time (2021-09-21)",
    ),
    range_resolution_m: s(0.04381, "the bin size, as the CTS350-X's"),
    beam_width_deg: s(1.8, NAVTECH_BEAM),
    rotation_hz: s(4.0, "pyboreas DATA_REFERENCE.md: 4 Hz"),
    doppler_range_coupling_s: s(
        0.049,
        "assumed the CIR204's (Burnett's code: beta 0.049); not measured on this unit",
    ),
    sigma_range_m: BORROWED_SIGMA_RANGE,
    sigma_bearing_deg: BORROWED_SIGMA_BEARING,
    sigma_power_db: BORROWED_SIGMA_POWER,
    // The front end, landmark thresholds, compensation and radar odometry of the CTS350-X.
    ..CTS350X
};

/// The simulator's CTS350-X-like unit (sim-sensor's `cts350x-400` preset): a CTS350-X's
/// azimuths, bins, beam and range-Doppler coupling, its returns rendered with the paper
/// unit's noise (ideal points), so the paper unit's look noise, landmarks and front end.
/// Named by the embedded simulator; a stream over TCP announcing these facts is a real
/// CTS350-X's to a daemon, which chooses [`CTS350X`].
pub const SIM_CTS350X: RadarProfile = RadarProfile {
    name: "sim-cts350x",
    description:
        "the simulator's CTS350-X-like unit (sim-sensor preset cts350x-400, point returns)",
    azimuths: s(400, "sim-sensor radar.rs, preset cts350x-400"),
    encoder_size: s(5600, "sim-sensor radar.rs, preset cts350x-400"),
    range_bins: s(3768, "sim-sensor radar.rs, preset cts350x-400"),
    bin_size_m: s(0.0438, "sim-sensor radar.rs, preset cts350x-400"),
    range_resolution_m: s(
        0.0438,
        "sim-sensor's renderer: the power model's resolution is the bin (render/mod.rs)",
    ),
    beam_width_deg: s(1.8, "sim-sensor radar.rs, preset cts350x-400"),
    rotation_hz: s(4.0, "sim-sensor radar.rs, preset cts350x-400"),
    doppler_range_coupling_s: s(0.049, "sim-sensor radar.rs: rendered 0.049 s"),
    ..PAPER_2006
};

/// Every profile of a real radar, the paper's unit first: the ones an announcement is
/// matched against.
pub const PROFILES: [&RadarProfile; 5] =
    [&PAPER_2006, &CTS350X, &CTS350X_RADIATE, &CIR204H, &CIR304H];

/// Profiles of simulated radars: chosen by name only.
pub const SIMULATED: [&RadarProfile; 1] = [&SIM_CTS350X];

/// Looks a profile up by name (`[radar] model`), ignoring case, `-` and `_`.
pub fn by_name(name: &str) -> Option<&'static RadarProfile> {
    let squash = |t: &str| {
        t.chars()
            .filter(|c| *c != '-' && *c != '_')
            .flat_map(char::to_lowercase)
            .collect::<String>()
    };
    let wanted = squash(name);
    PROFILES
        .into_iter()
        .chain(SIMULATED)
        .find(|p| squash(p.name) == wanted)
}

/// The names `[radar] model` takes.
pub fn names() -> Vec<&'static str> {
    PROFILES
        .iter()
        .chain(SIMULATED.iter())
        .map(|p| p.name)
        .collect()
}

/// What a radar announces at connection (its configuration message).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Announced {
    /// Azimuths per rotation.
    pub azimuths: u16,
    /// Encoder counts per revolution.
    pub encoder_size: u16,
    /// Bins per azimuth.
    pub range_bins: u16,
    /// Bin size (m), the range gain applied.
    pub bin_size_m: f64,
    /// Rotations per second.
    pub rotation_hz: f64,
}

impl fmt::Display for Announced {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} azimuths, encoder {}, {} bins of {} m, {:.3} Hz",
            self.azimuths, self.encoder_size, self.range_bins, self.bin_size_m, self.rotation_hz
        )
    }
}

impl RadarProfile {
    /// What this radar announces.
    pub fn announced(&self) -> Announced {
        Announced {
            azimuths: self.azimuths.value,
            encoder_size: self.encoder_size.value,
            range_bins: self.range_bins.value,
            bin_size_m: self.bin_size_m.value,
            rotation_hz: self.rotation_hz.value,
        }
    }

    /// Where `announced` differs from this radar: one phrase per field, empty when it matches
    /// (bin size within 1 %, rotation rate within 10 %).
    pub fn differences(&self, announced: &Announced) -> Vec<String> {
        let mut out = Vec::new();
        let own = self.announced();
        if own.azimuths != announced.azimuths {
            out.push(format!(
                "azimuths {} (profile {})",
                announced.azimuths, own.azimuths
            ));
        }
        if own.encoder_size != announced.encoder_size {
            out.push(format!(
                "encoder {} (profile {})",
                announced.encoder_size, own.encoder_size
            ));
        }
        if own.range_bins != announced.range_bins {
            out.push(format!(
                "bins {} (profile {})",
                announced.range_bins, own.range_bins
            ));
        }
        if !within(announced.bin_size_m, own.bin_size_m, 0.01) {
            out.push(format!(
                "bin size {} m (profile {} m)",
                announced.bin_size_m, own.bin_size_m
            ));
        }
        if !within(announced.rotation_hz, own.rotation_hz, 0.10) {
            out.push(format!(
                "rotation {:.3} Hz (profile {} Hz)",
                announced.rotation_hz, own.rotation_hz
            ));
        }
        out
    }

    /// How far `announced` is from this radar: relative differences, the bin size and the
    /// azimuth count weighing most (they decide the front end and the beam).
    fn distance(&self, announced: &Announced) -> f64 {
        let own = self.announced();
        let rel = |a: f64, b: f64| {
            if a.is_finite() && b.is_finite() && a.abs().max(b.abs()) > 0.0 {
                ((a - b).abs() / a.abs().max(b.abs())).min(1.0)
            } else {
                1.0
            }
        };
        4.0 * rel(announced.bin_size_m, own.bin_size_m)
            + 2.0 * rel(f64::from(announced.azimuths), f64::from(own.azimuths))
            + rel(f64::from(announced.range_bins), f64::from(own.range_bins))
            + rel(announced.rotation_hz, own.rotation_hz)
            + 0.5
                * rel(
                    f64::from(announced.encoder_size),
                    f64::from(own.encoder_size),
                )
    }
}

fn within(a: f64, b: f64, tolerance: f64) -> bool {
    a.is_finite() && (a - b).abs() <= tolerance * b.abs()
}

/// How a profile was chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum Chosen {
    /// `[radar] model` named it.
    Named,
    /// The radar's announcement matches it.
    Matched,
    /// No profile matches: the nearest, with what differs.
    Nearest(Vec<String>),
    /// The source knows its radar (the embedded simulator).
    Declared(&'static str),
}

/// A profile and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Choice {
    /// The profile.
    pub profile: &'static RadarProfile,
    /// Why it was chosen.
    pub how: Chosen,
}

impl fmt::Display for Choice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.profile;
        match &self.how {
            Chosen::Named => write!(f, "{} ({}), named by [radar] model", p.name, p.description),
            Chosen::Matched => write!(
                f,
                "{} ({}), matching what the radar announced",
                p.name, p.description
            ),
            Chosen::Declared(who) => {
                write!(f, "{} ({}), declared by {who}", p.name, p.description)
            }
            Chosen::Nearest(d) => write!(
                f,
                "{} ({}), the nearest profile; the radar differs: {}",
                p.name,
                p.description,
                d.join(", ")
            ),
        }
    }
}

/// A `[radar] model` that names no profile.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("[radar] model {name:?} names no radar profile; known: {known}")]
pub struct UnknownModel {
    /// The name given.
    pub name: String,
    /// The known names, comma-separated.
    pub known: String,
}

/// The profile for a radar that announced `announced`: the one `named` names, else the one
/// whose facts it matches, else the nearest (with what differs).
pub fn select(named: Option<&str>, announced: &Announced) -> Result<Choice, UnknownModel> {
    if let Some(name) = named {
        return by_name(name)
            .map(|profile| Choice {
                profile,
                how: Chosen::Named,
            })
            .ok_or_else(|| UnknownModel {
                name: name.to_owned(),
                known: names().join(", "),
            });
    }
    if let Some(profile) = PROFILES
        .into_iter()
        .find(|p| p.differences(announced).is_empty())
    {
        return Ok(Choice {
            profile,
            how: Chosen::Matched,
        });
    }
    let mut nearest = &PAPER_2006;
    for p in PROFILES {
        if p.distance(announced) < nearest.distance(announced) {
            nearest = p;
        }
    }
    Ok(Choice {
        profile: nearest,
        how: Chosen::Nearest(nearest.differences(announced)),
    })
}

/// The profile of the simulator's radar announcing `announced`, unless `named`. Its
/// CTS350-X-like unit rendering ideal points is [`SIM_CTS350X`]; rendering a realistic scene
/// (`realistic`: extended returns, speckle, the receiver fitted to the Oxford scans) it is a
/// [`CTS350X`]; both declared by the simulator. Any other unit is chosen as a real radar's
/// would be.
pub fn simulated(
    named: Option<&str>,
    announced: &Announced,
    realistic: bool,
) -> Result<Choice, UnknownModel> {
    if named.is_none() && SIM_CTS350X.differences(announced).is_empty() {
        return Ok(Choice {
            profile: if realistic { &CTS350X } else { &SIM_CTS350X },
            how: Chosen::Declared(if realistic {
                "the embedded simulator (realistic rendering)"
            } else {
                "the embedded simulator (point returns)"
            }),
        });
    }
    select(named, announced)
}

impl fmt::Display for RadarProfile {
    /// The profile as a table: each value with its source.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}: {}", self.name, self.description)?;
        let mut row = |what: &str, value: String, source: &str| {
            writeln!(f, "  {what:<28} {value:<34} {source}")
        };
        row(
            "azimuths",
            self.azimuths.value.to_string(),
            self.azimuths.source,
        )?;
        row(
            "encoder size",
            self.encoder_size.value.to_string(),
            self.encoder_size.source,
        )?;
        row(
            "range bins",
            self.range_bins.value.to_string(),
            self.range_bins.source,
        )?;
        row(
            "bin size (m)",
            self.bin_size_m.value.to_string(),
            self.bin_size_m.source,
        )?;
        row(
            "range resolution (m)",
            self.range_resolution_m.value.to_string(),
            self.range_resolution_m.source,
        )?;
        row(
            "beam width (deg)",
            self.beam_width_deg.value.to_string(),
            self.beam_width_deg.source,
        )?;
        row(
            "rotation (Hz)",
            self.rotation_hz.value.to_string(),
            self.rotation_hz.source,
        )?;
        row(
            "range-Doppler coupling (s)",
            self.doppler_range_coupling_s.value.to_string(),
            self.doppler_range_coupling_s.source,
        )?;
        row(
            "look noise: range (m)",
            self.sigma_range_m.value.to_string(),
            self.sigma_range_m.source,
        )?;
        row(
            "look noise: bearing (deg)",
            self.sigma_bearing_deg.value.to_string(),
            self.sigma_bearing_deg.source,
        )?;
        row(
            "look noise: power (dB)",
            self.sigma_power_db.value.to_string(),
            self.sigma_power_db.source,
        )?;
        let l = self.landmarks.value;
        row(
            "landmarks",
            format!(
                "{}SNR >= {} dB, {} looks {} s apart",
                if l.points_only { "points only, " } else { "" },
                l.point_min_snr_db,
                l.confirm_after,
                l.confirm_min_separation_s
            ),
            self.landmarks.source,
        )?;
        row(
            "front end",
            match self.front_end.value {
                FrontEndFamily::PaperTpp => "TPP on a modelled floor".to_owned(),
                FrontEndFamily::Learned => format!(
                    "learned floor ({} sigma, {} dB)",
                    self.learned_floor.value.floor_sigma, self.learned_floor.value.floor_min_snr_db
                ),
            },
            self.front_end.source,
        )?;
        row(
            "receiver compensation",
            match self.compensation.value {
                CompensationSlope::Sixty => "60 dB/decade".to_owned(),
                CompensationSlope::Forty => "40 dB/decade".to_owned(),
            },
            self.compensation.source,
        )?;
        row(
            "radar odometry",
            if self.radar_odometry.value {
                "on"
            } else {
                "off"
            }
            .to_owned(),
            self.radar_odometry.source,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_profile_is_chosen_by_what_it_announces() {
        for p in PROFILES {
            let choice = select(None, &p.announced()).unwrap();
            assert_eq!(choice.profile.name, p.name);
            assert_eq!(choice.how, Chosen::Matched);
        }
    }

    #[test]
    fn a_radar_that_matches_none_gets_the_nearest_with_what_differs() {
        // A CTS350-X set to 2000 bins and a 5 Hz rotation.
        let announced = Announced {
            range_bins: 2000,
            rotation_hz: 5.0,
            ..CTS350X.announced()
        };
        let choice = select(None, &announced).unwrap();
        assert_eq!(choice.profile.name, "cts350x");
        let Chosen::Nearest(d) = &choice.how else {
            panic!("{choice}")
        };
        assert_eq!(d.len(), 2, "{d:?}");
        assert!(choice.to_string().contains("bins 2000 (profile 3768)"));
    }

    #[test]
    fn a_named_model_wins_and_an_unknown_name_is_refused_listing_the_known() {
        let choice = select(Some("CTS350-X"), &PAPER_2006.announced()).unwrap();
        assert_eq!(choice.profile.name, "cts350x");
        assert_eq!(choice.how, Chosen::Named);
        let err = select(Some("ras9"), &PAPER_2006.announced()).unwrap_err();
        assert!(err
            .to_string()
            .contains("paper-2006, cts350x, cts350x-radiate, cir204h, cir304h, sim-cts350x"));
    }

    #[test]
    fn garbage_announcements_choose_a_profile_without_panicking() {
        let announced = Announced {
            azimuths: 0,
            encoder_size: 0,
            range_bins: 0,
            bin_size_m: f64::NAN,
            rotation_hz: f64::INFINITY,
        };
        let choice = select(None, &announced).unwrap();
        assert!(matches!(choice.how, Chosen::Nearest(_)));
    }

    #[test]
    fn every_value_has_a_source_and_the_table_prints_them() {
        for p in PROFILES.into_iter().chain(SIMULATED) {
            let text = p.to_string();
            assert!(text.lines().count() >= 16, "{text}");
            assert!(!p.sigma_range_m.source.is_empty());
        }
    }
}
