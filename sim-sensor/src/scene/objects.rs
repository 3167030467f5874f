//! Extended and distributed objects as a scene describes them (the scene's `[[objects]]`,
//! and what the `[street]` and `[city]` generators lay out): what each is and where. The
//! realistic renderer expands them into scatterers and outlines
//! ([`crate::realism::objects`]); the point-target renderer lets the opaque ones hide
//! features. IO: none.

use serde::Deserialize;

/// What an object is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ObjectKind {
    /// A building's front (brick, concrete, glass): opaque, strong, a mirror. `from`, `to`.
    BuildingFront,
    /// A garden or boundary wall: opaque, a mirror. `from`, `to`.
    Wall,
    /// A wooden fence: weak, mostly transparent. `from`, `to`.
    Fence,
    /// A hedge: foliage through `depth_m` either side of `from`-`to`, partly transparent.
    Hedge,
    /// A vehicle: a metal box `length_m` x `width_m` about `at`, heading `heading_deg`,
    /// moving at `speed_mps` along its heading when that is not zero.
    Vehicle,
    /// A tree: a trunk at `at` and a crown of radius `radius_m` around it.
    Tree,
    /// Foliage alone (a crown whose trunk is a point feature): scatterers through a disk of
    /// radius `radius_m` about `at`, partly transparent.
    Foliage,
    /// A metal pole (lamp post, sign): one strong scatterer at `at`.
    Pole,
    /// Distributed clutter (ground, kerbs, railings, bins, back gardens): weak isotropic
    /// scatterers (log-normal cross sections about 0.02 m^2 times `rcs_scale`) scattered
    /// uniformly at `density_per_m2` over the rectangle with corners `from` and `to`.
    Clutter,
}

impl ObjectKind {
    /// The kind's name in scene files.
    pub fn name(self) -> &'static str {
        match self {
            ObjectKind::BuildingFront => "building-front",
            ObjectKind::Wall => "wall",
            ObjectKind::Fence => "fence",
            ObjectKind::Hedge => "hedge",
            ObjectKind::Vehicle => "vehicle",
            ObjectKind::Tree => "tree",
            ObjectKind::Foliage => "foliage",
            ObjectKind::Pole => "pole",
            ObjectKind::Clutter => "clutter",
        }
    }
}

/// One object as the scene file gives it.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// What it is.
    pub kind: ObjectKind,
    /// Start of a line object (building front, wall, fence, hedge).
    #[serde(default)]
    pub from: Option<[f64; 2]>,
    /// End of a line object.
    #[serde(default)]
    pub to: Option<[f64; 2]>,
    /// Position of a vehicle's centre, a tree's trunk or a pole.
    #[serde(default)]
    pub at: Option<[f64; 2]>,
    /// A vehicle's heading, degrees counter-clockwise from +x.
    #[serde(default)]
    pub heading_deg: f64,
    /// A vehicle's length (default 4.5 m).
    #[serde(default)]
    pub length_m: Option<f64>,
    /// A vehicle's width (default 1.8 m).
    #[serde(default)]
    pub width_m: Option<f64>,
    /// A tree's crown radius (default 2.0 m).
    #[serde(default)]
    pub radius_m: Option<f64>,
    /// A hedge's depth (default 1.0 m).
    #[serde(default)]
    pub depth_m: Option<f64>,
    /// A vehicle's speed along its heading (m/s); 0 = parked.
    #[serde(default)]
    pub speed_mps: f64,
    /// A moving vehicle goes back to `at` after this distance (default 400 m).
    #[serde(default)]
    pub travel_m: Option<f64>,
    /// Multiplies every scatterer's cross section (default 1).
    #[serde(default)]
    pub rcs_scale: Option<f64>,
    /// One-way power transmission of one crossing of the outline (default: the kind's).
    #[serde(default)]
    pub transmission: Option<f64>,
    /// Clutter scatterers per square metre (default 0.05).
    #[serde(default)]
    pub density_per_m2: Option<f64>,
}

impl ObjectSpec {
    /// An object of `kind` with every optional field unset (the kind's defaults apply).
    pub fn of_kind(kind: ObjectKind) -> ObjectSpec {
        ObjectSpec {
            kind,
            from: None,
            to: None,
            at: None,
            heading_deg: 0.0,
            length_m: None,
            width_m: None,
            radius_m: None,
            depth_m: None,
            speed_mps: 0.0,
            travel_m: None,
            rcs_scale: None,
            transmission: None,
            density_per_m2: None,
        }
    }

    /// A straight object of `kind` from `from` to `to`.
    pub fn segment(kind: ObjectKind, from: [f64; 2], to: [f64; 2]) -> ObjectSpec {
        ObjectSpec {
            from: Some(from),
            to: Some(to),
            ..ObjectSpec::of_kind(kind)
        }
    }
}
