//! A seeded city for long drives (the scene's `[city]` table): a grid of rectangular blocks
//! separated by streets, point landmarks along every kerb and at the buildings' corners, each
//! block a building whose outline hides what lies behind it, and a route through the grid
//! driven by the bicycle model (the control schedule is generated; see [`route`]).
//!
//! Geometry: junction `(i, j)` (column `0..=blocks_x`, row `0..=blocks_y`) is the crossing of
//! the street along x at `y = j pitch_y` and the street along y at `x = i pitch_x`, with
//! `pitch = block + 2 (carriageway_half_m + pavement_m)`; junction `(0, 0)` is the origin.
//! Block `(i, j)` lies between junction columns `i, i + 1` and rows `j, j + 1`, its building
//! line `carriageway_half_m + pavement_m` from the street centre lines. The vehicle drives on
//! the centre lines (a single lane: the simulator has no traffic to keep right of).
//!
//! Landmarks (the radar's point features; every one is in the ground truth):
//!
//! | class | where | kind | rho (RCS) | alpha | tau |
//! |---|---|---|---|---|---|
//! | lamp post | kerb, 0.4 m in | lamp-post | 0.05 (10 m^2) | 0.25 | 0.70 |
//! | sign pole | kerb, 0.3 m in | lamp-post | 0.02 (4 m^2) | 0.18 | 0.80 |
//! | tree | kerb, 0.8 m in | tree | 0.02 (4 m^2) | 0.60 | 0.38 |
//! | bollard | kerb, 0.3 m in | wall | 0.015 (3 m^2) | 0.185 | 0.80 |
//! | parked car | its two street-side corners, 4.5 m apart, 1.8 m out from the kerb | reflector | 0.10 (20 m^2) | 0.40 | 0.50 |
//! | building corner | each block corner and recesses along the building line, 0.25 m out | wall | 0.30 (60 m^2) | 0.70 | 1e-6 (opaque) |
//!
//! The paper's model lets a feature take the whole beam; a pole of 10-20 cm fills a small
//! part of a 1.8 degree beam (about 1 m across at 30 m), so thin street furniture passes most
//! of the power on (tau 0.7-0.8) rather than being opaque as the `lamp-post` kind's default
//! is: otherwise, looking down a kerb at a grazing angle, the first pole would hide every
//! landmark behind it. A parked car passes about half (the realistic renderer's vehicle
//! transmission, 0.5: the roof-mounted radar sees partly over it).
//!
//! Kerb slots follow each other at `kerb_spacing_m` times a seeded factor in [0.7, 1.3]; the
//! class is drawn per slot (lamp post 25 %, sign pole 15 %, tree 30 %, bollard 10 %, parked
//! car 20 %). No landmark is placed within `min_spacing_m` of another (a candidate that would
//! be is dropped), so association is never hopeless by construction. With `repeated = true`
//! every block draws the same pattern (a block's draws are seeded by the layout seed alone,
//! not by its position): identical blocks on a regular grid, to tempt wrong loop closures.
//!
//! With the scene's `[realism]` and a `[city.dressing]` table the same grid and route are the
//! realistic city: the blocks and streets are lined as the street generator lines its street
//! ([`dressing`]) instead of the landmark table above. [`returns`] finds where a route comes
//! back to streets it drove, from the layout alone.
//!
//! IO: none.

pub mod dressing;
pub mod returns;
pub mod route;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use crate::error::SceneError;
use crate::scene::objects::{ObjectKind, ObjectSpec};
use crate::scene::FeatureKind;
use crate::schedule::ControlKey;

pub use dressing::DressingSpec;

/// Most blocks along either axis.
pub const MAX_BLOCKS: u32 = 64;
/// Most legs a route may have.
pub const MAX_ROUTE_LEGS: usize = 10_000;

/// The `[city]` table.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct CitySpec {
    /// Seed of the layout (independent of the scene's noise seed).
    pub seed: u64,
    /// Blocks along x, `[1, 64]`.
    pub blocks_x: u32,
    /// Blocks along y, `[1, 64]`.
    pub blocks_y: u32,
    /// Block length along x, building line to building line, metres.
    pub block_x_m: f64,
    /// Block length along y, metres.
    pub block_y_m: f64,
    /// Street centre line to kerb (the carriageway with its parking lane), metres.
    pub carriageway_half_m: f64,
    /// Kerb to building line, metres.
    pub pavement_m: f64,
    /// Mean distance between kerb slots, metres.
    pub kerb_spacing_m: f64,
    /// Mean distance between building corners (recesses) along a building line, metres; 0:
    /// only the blocks' own four corners.
    pub corner_spacing_m: f64,
    /// No two landmarks closer than this, metres.
    pub min_spacing_m: f64,
    /// Every block the same landmark pattern (with `dressing`: every block dressed alike,
    /// its fronts, gaps, hedges, fences, trees, poles and parked cars).
    pub repeated: bool,
    /// Each block is a building whose outline (four fronts on its building line) hides what
    /// lies behind it; the fronts are objects (drawn by the realistic renderer, occluders
    /// for the point-target renderer).
    pub buildings: bool,
    /// The junction `[column, row]` the drive starts from.
    pub start: [u32; 2],
    /// The route: legs `"<E|N|W|S><blocks>"` (E = +x, N = +y), e.g. `["E3", "N2"]`. Each
    /// turn is 90 degrees (no U-turns); the vehicle stops at the last junction. Empty: the
    /// vehicle stands at the start.
    pub route: Vec<String>,
    /// Speed on the straights, m/s.
    pub cruise_mps: f64,
    /// Speed through a turn, m/s.
    pub turn_mps: f64,
    /// Largest acceleration, m/s^2.
    pub accel_mps2: f64,
    /// Largest braking, m/s^2.
    pub decel_mps2: f64,
    /// Radius of the reference path round a corner, metres.
    pub turn_radius_m: f64,
    /// Largest steering angle, radians.
    pub max_steer_rad: f64,
    /// Largest steering rate, radians a second.
    pub steer_rate_rad_s: f64,
    /// Time between control keyframes, seconds (a multiple of the 10 ms integration step).
    pub control_step_s: f64,
    /// The realistic city (`[city.dressing]`, needs the scene's `[realism]`): the blocks
    /// and streets lined as the street generator lines them ([`dressing`]) instead of the
    /// point-landmark table above (`kerb_spacing_m`, `corner_spacing_m`, `min_spacing_m`
    /// and `buildings` are then unused).
    pub dressing: Option<DressingSpec>,
}

impl Default for CitySpec {
    fn default() -> Self {
        Self {
            seed: 1,
            blocks_x: 4,
            blocks_y: 3,
            block_x_m: 90.0,
            block_y_m: 70.0,
            carriageway_half_m: 5.0,
            pavement_m: 3.0,
            kerb_spacing_m: 7.0,
            corner_spacing_m: 30.0,
            min_spacing_m: 4.0,
            repeated: false,
            buildings: true,
            start: [0, 0],
            route: Vec::new(),
            cruise_mps: 10.0,
            turn_mps: 4.5,
            accel_mps2: 1.5,
            decel_mps2: 2.0,
            turn_radius_m: 8.0,
            max_steer_rad: 0.6,
            steer_rate_rad_s: 0.5,
            control_step_s: 0.1,
            dressing: None,
        }
    }
}

/// What a landmark is (decides its kind, material and place).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LandmarkClass {
    /// A metal lamp post on the kerb.
    LampPost,
    /// A thin metal sign pole on the kerb.
    SignPole,
    /// A street tree.
    Tree,
    /// A bollard.
    Bollard,
    /// One street-side corner of a parked car.
    CarCorner,
    /// A building's corner.
    BuildingCorner,
}

impl LandmarkClass {
    /// The feature kind and `(rho, alpha)` (see the module table).
    pub fn material(self) -> (FeatureKind, f64, f64) {
        match self {
            LandmarkClass::LampPost => (FeatureKind::LampPost, 0.05, 0.25),
            LandmarkClass::SignPole => (FeatureKind::LampPost, 0.02, 0.18),
            LandmarkClass::Tree => {
                let (rho, alpha) = FeatureKind::Tree.default_material();
                (FeatureKind::Tree, rho, alpha)
            }
            LandmarkClass::Bollard => (FeatureKind::Wall, 0.015, 0.185),
            LandmarkClass::CarCorner => (FeatureKind::Reflector, 0.10, 0.40),
            LandmarkClass::BuildingCorner => {
                let (rho, alpha) = FeatureKind::Wall.default_material();
                (FeatureKind::Wall, rho, alpha)
            }
        }
    }
}

/// One generated landmark.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Landmark {
    /// What it is.
    pub class: LandmarkClass,
    /// World x, metres.
    pub x_m: f64,
    /// World y, metres.
    pub y_m: f64,
}

/// The city's geometry, kept with the scene for tests and evaluations (where the streets
/// are, which route was driven, how long the drive is).
#[derive(Debug, Clone, PartialEq)]
pub struct CityLayout {
    /// Blocks along x and y.
    pub blocks: [u32; 2],
    /// Junction spacing along x and y, metres.
    pub pitch_m: [f64; 2],
    /// Street centre line to kerb, metres.
    pub carriageway_half_m: f64,
    /// Kerb to building line, metres.
    pub pavement_m: f64,
    /// Every block the same landmark pattern (with `dressing`: every block dressed alike,
    /// its fronts, gaps, hedges, fences, trees, poles and parked cars).
    pub repeated: bool,
    /// The junctions the route passes where it turns (and its ends), world metres.
    pub route_corners: Vec<[f64; 2]>,
    /// Length of the route along the centre lines (junction to junction), metres.
    pub route_length_m: f64,
    /// Length of the reference path actually followed (corners rounded), metres.
    pub path_length_m: f64,
    /// Time the vehicle comes to rest at the end of the route, seconds after the start.
    pub drive_duration_s: f64,
}

impl CityLayout {
    /// Distance from `p` to the nearest street centre line of the grid (streets run the
    /// grid's whole extent), metres.
    pub fn distance_to_centre_line(&self, p: [f64; 2]) -> f64 {
        let [px, py] = self.pitch_m;
        let (w, h) = (
            f64::from(self.blocks[0]) * px,
            f64::from(self.blocks[1]) * py,
        );
        let clamp_x = p[0].clamp(0.0, w);
        let clamp_y = p[1].clamp(0.0, h);
        // Nearest street along y (x = i px) and along x (y = j py).
        let i = (p[0] / px).round().clamp(0.0, f64::from(self.blocks[0]));
        let j = (p[1] / py).round().clamp(0.0, f64::from(self.blocks[1]));
        let to_y_street = (p[0] - i * px).hypot(p[1] - clamp_y);
        let to_x_street = (p[1] - j * py).hypot(p[0] - clamp_x);
        to_y_street.min(to_x_street)
    }

    /// Whether `p` lies in a junction's square (within `carriageway_half_m` of a junction
    /// centre along both axes).
    pub fn in_junction(&self, p: [f64; 2]) -> bool {
        let [px, py] = self.pitch_m;
        let dx = p[0] - (p[0] / px).round() * px;
        let dy = p[1] - (p[1] / py).round() * py;
        dx.abs() <= self.carriageway_half_m && dy.abs() <= self.carriageway_half_m
    }
}

/// What the generator produced.
#[derive(Debug, Clone, PartialEq)]
pub struct City {
    /// Point landmarks, in generation order (block by block).
    pub landmarks: Vec<Landmark>,
    /// Building fronts (empty without `buildings`).
    pub objects: Vec<ObjectSpec>,
    /// Start pose `[x, y, theta]` (theta counter-clockwise from +x).
    pub start: [f64; 3],
    /// The control schedule (linear interpolation between keyframes).
    pub control: Vec<ControlKey>,
    /// The geometry.
    pub layout: CityLayout,
    /// The realistic city's point features (lamp posts and tree trunks, with their kinds'
    /// default materials); empty without `dressing`.
    pub features: Vec<(FeatureKind, f64, f64)>,
}

fn invalid(field: &str, reason: String) -> SceneError {
    SceneError::Invalid {
        field: format!("city.{field}"),
        reason,
    }
}

/// A uniform hash of landmark positions for the spacing rule.
struct Spacing {
    cell_m: f64,
    cells: std::collections::HashMap<(i64, i64), Vec<[f64; 2]>>,
}

impl Spacing {
    fn new(min_m: f64) -> Self {
        Self {
            cell_m: min_m.max(0.1),
            cells: std::collections::HashMap::new(),
        }
    }

    fn key(&self, p: [f64; 2]) -> (i64, i64) {
        (
            (p[0] / self.cell_m).floor() as i64,
            (p[1] / self.cell_m).floor() as i64,
        )
    }

    /// Inserts `p` unless a point lies within the spacing; returns whether it was.
    fn try_insert(&mut self, p: [f64; 2]) -> bool {
        let (cx, cy) = self.key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                if let Some(points) = self.cells.get(&(cx + dx, cy + dy)) {
                    if points
                        .iter()
                        .any(|q| (q[0] - p[0]).hypot(q[1] - p[1]) < self.cell_m)
                    {
                        return false;
                    }
                }
            }
        }
        self.cells.entry((cx, cy)).or_default().push(p);
        true
    }
}

impl CitySpec {
    /// Junction spacing along x and y, metres.
    pub fn pitch_m(&self) -> [f64; 2] {
        let half = self.carriageway_half_m + self.pavement_m;
        [self.block_x_m + 2.0 * half, self.block_y_m + 2.0 * half]
    }

    fn validate(&self) -> Result<(), SceneError> {
        if !(1..=MAX_BLOCKS).contains(&self.blocks_x) || !(1..=MAX_BLOCKS).contains(&self.blocks_y)
        {
            return Err(invalid(
                "blocks_x",
                format!("blocks_x and blocks_y must be in [1, {MAX_BLOCKS}]"),
            ));
        }
        for (name, v, lo, hi) in [
            ("block_x_m", self.block_x_m, 20.0, 2000.0),
            ("block_y_m", self.block_y_m, 20.0, 2000.0),
            ("carriageway_half_m", self.carriageway_half_m, 2.5, 30.0),
            ("pavement_m", self.pavement_m, 1.0, 30.0),
            ("kerb_spacing_m", self.kerb_spacing_m, 2.0, 1e4),
            ("corner_spacing_m", self.corner_spacing_m, 0.0, 1e4),
            ("min_spacing_m", self.min_spacing_m, 0.0, 100.0),
            ("cruise_mps", self.cruise_mps, 0.5, 40.0),
            ("turn_mps", self.turn_mps, 0.5, 40.0),
            ("accel_mps2", self.accel_mps2, 0.1, 10.0),
            ("decel_mps2", self.decel_mps2, 0.1, 10.0),
            ("turn_radius_m", self.turn_radius_m, 2.0, 500.0),
            ("max_steer_rad", self.max_steer_rad, 0.05, 1.2),
            ("steer_rate_rad_s", self.steer_rate_rad_s, 0.01, 10.0),
            ("control_step_s", self.control_step_s, 0.01, 1.0),
        ] {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(invalid(name, format!("must be in [{lo}, {hi}], got {v}")));
            }
        }
        if self.corner_spacing_m > 0.0 && self.corner_spacing_m < 2.0 {
            return Err(invalid(
                "corner_spacing_m",
                format!("must be 0 or at least 2 m, got {}", self.corner_spacing_m),
            ));
        }
        if self.turn_mps > self.cruise_mps {
            return Err(invalid(
                "turn_mps",
                format!(
                    "must not exceed cruise_mps ({}), got {}",
                    self.cruise_mps, self.turn_mps
                ),
            ));
        }
        let steps = self.control_step_s / 0.01;
        if (steps - steps.round()).abs() > 1e-6 {
            return Err(invalid(
                "control_step_s",
                format!("must be a multiple of 0.01 s, got {}", self.control_step_s),
            ));
        }
        let [px, py] = self.pitch_m();
        if self.turn_radius_m > 0.5 * px.min(py) {
            return Err(invalid(
                "turn_radius_m",
                format!(
                    "must be at most half the shorter junction spacing ({} m), got {}",
                    0.5 * px.min(py),
                    self.turn_radius_m
                ),
            ));
        }
        if self.start[0] > self.blocks_x || self.start[1] > self.blocks_y {
            return Err(invalid(
                "start",
                format!(
                    "junction {:?} is outside the grid's junctions [0, {}] x [0, {}]",
                    self.start, self.blocks_x, self.blocks_y
                ),
            ));
        }
        if self.route.len() > MAX_ROUTE_LEGS {
            return Err(invalid(
                "route",
                format!("at most {MAX_ROUTE_LEGS} legs, got {}", self.route.len()),
            ));
        }
        Ok(())
    }

    /// Generates the city and its drive; `wheelbase_m` is the bicycle model's.
    ///
    /// # Errors
    /// A setting out of range, a route leaving the grid or turning back on itself, or a route
    /// the controller cannot follow within the carriageway with these turn settings.
    pub fn generate(&self, wheelbase_m: f64) -> Result<City, SceneError> {
        self.validate()?;
        let corners = route::parse_route(self)?;
        let [px, py] = self.pitch_m();
        let (landmarks, objects, features) = match &self.dressing {
            Some(dressing) => {
                let dressed = dressing.dress(self)?;
                (Vec::new(), dressed.objects, dressed.features)
            }
            None => {
                let (landmarks, objects) = self.landmark_table();
                (landmarks, objects, Vec::new())
            }
        };
        let drive = route::drive(self, &corners, wheelbase_m)?;
        let route_length_m = corners
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).abs() + (w[1][1] - w[0][1]).abs())
            .sum();
        Ok(City {
            landmarks,
            objects,
            start: drive.start,
            control: drive.keys,
            layout: CityLayout {
                blocks: [self.blocks_x, self.blocks_y],
                pitch_m: [px, py],
                carriageway_half_m: self.carriageway_half_m,
                pavement_m: self.pavement_m,
                repeated: self.repeated,
                route_corners: corners,
                route_length_m,
                path_length_m: drive.path_length_m,
                drive_duration_s: drive.duration_s,
            },
            features,
        })
    }

    /// The point-landmark city: every block's landmarks (see the module table) and, with
    /// `buildings`, its four fronts.
    fn landmark_table(&self) -> (Vec<Landmark>, Vec<ObjectSpec>) {
        let mut landmarks = Vec::new();
        let mut objects = Vec::new();
        let mut spacing = Spacing::new(self.min_spacing_m);
        let [px, py] = self.pitch_m();
        let half = self.carriageway_half_m + self.pavement_m;
        for j in 0..self.blocks_y {
            for i in 0..self.blocks_x {
                let x0 = f64::from(i) * px + half;
                let y0 = f64::from(j) * py + half;
                let block_index = u64::from(j) * u64::from(MAX_BLOCKS) + u64::from(i);
                let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ 0x6369_7479_2121_2121);
                if !self.repeated {
                    rng.set_stream(block_index + 1);
                }
                self.block(&mut rng, [x0, y0], &mut spacing, &mut landmarks);
                if self.buildings {
                    let c = [
                        [x0, y0],
                        [x0 + self.block_x_m, y0],
                        [x0 + self.block_x_m, y0 + self.block_y_m],
                        [x0, y0 + self.block_y_m],
                    ];
                    for k in 0..4 {
                        objects.push(front(c[k], c[(k + 1) % 4]));
                    }
                }
            }
        }
        (landmarks, objects)
    }

    /// One block's landmarks: its building corners, then round its four sides (counter-
    /// clockwise, the street to the right) recess corners and kerb slots.
    fn block(
        &self,
        rng: &mut ChaCha8Rng,
        origin: [f64; 2],
        spacing: &mut Spacing,
        out: &mut Vec<Landmark>,
    ) {
        let (w, h) = (self.block_x_m, self.block_y_m);
        let corners = [
            [origin[0], origin[1]],
            [origin[0] + w, origin[1]],
            [origin[0] + w, origin[1] + h],
            [origin[0], origin[1] + h],
        ];
        let mut push = |class: LandmarkClass, p: [f64; 2], spacing: &mut Spacing| {
            if spacing.try_insert(p) {
                out.push(Landmark {
                    class,
                    x_m: p[0],
                    y_m: p[1],
                });
            }
        };
        // The block's corners, 0.25 m out along the diagonal.
        let centre = [origin[0] + 0.5 * w, origin[1] + 0.5 * h];
        for c in corners {
            let out_dir = [(c[0] - centre[0]).signum(), (c[1] - centre[1]).signum()];
            push(
                LandmarkClass::BuildingCorner,
                [c[0] + 0.25 * out_dir[0], c[1] + 0.25 * out_dir[1]],
                spacing,
            );
        }
        for k in 0..4 {
            let a = corners[k];
            let b = corners[(k + 1) % 4];
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            let u = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
            // Outward (street side): right of the direction round the block.
            let n = [u[1], -u[0]];
            let at =
                |s: f64, off: f64| [a[0] + s * u[0] + off * n[0], a[1] + s * u[1] + off * n[1]];
            if self.corner_spacing_m > 0.0 {
                let mut s = self.corner_spacing_m * rng.gen_range(0.5..1.5);
                while s < len - 3.0 {
                    push(LandmarkClass::BuildingCorner, at(s, 0.25), spacing);
                    s += self.corner_spacing_m * rng.gen_range(0.5..1.5);
                }
            }
            let kerb = self.pavement_m;
            let mut s = 2.0 + self.kerb_spacing_m * rng.gen_range(0.0..0.5);
            while s < len - 2.0 {
                let draw: f64 = rng.gen_range(0.0..1.0);
                let step = self.kerb_spacing_m * rng.gen_range(0.7..1.3);
                if draw < 0.25 {
                    push(LandmarkClass::LampPost, at(s, kerb - 0.4), spacing);
                } else if draw < 0.40 {
                    push(LandmarkClass::SignPole, at(s, kerb - 0.3), spacing);
                } else if draw < 0.70 {
                    push(LandmarkClass::Tree, at(s, kerb - 0.8), spacing);
                } else if draw < 0.80 {
                    push(LandmarkClass::Bollard, at(s, kerb - 0.3), spacing);
                } else if s + 4.5 < len - 2.0 {
                    push(LandmarkClass::CarCorner, at(s, kerb + 1.8), spacing);
                    push(LandmarkClass::CarCorner, at(s + 4.5, kerb + 1.8), spacing);
                    s += 4.5;
                }
                s += step;
            }
        }
    }
}

fn front(from: [f64; 2], to: [f64; 2]) -> ObjectSpec {
    ObjectSpec::segment(ObjectKind::BuildingFront, from, to)
}

#[cfg(test)]
mod tests;
