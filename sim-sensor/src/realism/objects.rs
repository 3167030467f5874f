//! The expansion of the scene's extended and distributed objects (`[[objects]]`, described
//! in [`crate::scene::objects`]) into scatterers and occluding outlines.
//!
//! Every object becomes many point scatterers along its extent (surfaces) or through its
//! volume (foliage), each with:
//! - a mean cross section at normal incidence, split into a diffuse part that falls as
//!   `cos^2` of the incidence angle and a specular part in a narrow lobe about the surface
//!   normal (a flat surface returns most when the beam meets it square on);
//! - a Swerling class: 0 (steady), 1/3 (one draw per rotation), 2/4 (one draw per look);
//!   1/2 draw an exponential power (many comparable scatterers), 3/4 a chi-square of four
//!   degrees of freedom (one dominant scatterer);
//! - the outline it belongs to: a segment (a wall, a fence, a vehicle's side) or a disk (a
//!   trunk, a pole, a crown) with the one-way power transmission of one crossing. What
//!   stands behind an outline is seen through it (two-way, squared); an opaque outline
//!   hides it. Flat opaque outlines (building fronts, walls) are also multipath mirrors.
//!
//! Cross sections here are the simulator's choices, judged against the real scans by the
//! realism measurement (`--example realism`), not measurements of these objects.
//! Point features of the scene become one isotropic scatterer each (cross section
//! `rho x 200 m^2`, radar-model's calibration of eq. 13) with a small disk outline of
//! transmission `tau = 1 - rho - alpha`.

use crate::error::SceneError;
use crate::index::GridIndex;
use crate::scene::objects::{ObjectKind, ObjectSpec};
use crate::scene::{Feature, FeatureKind};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Largest number of scatterers one scene may expand into.
pub const MAX_SCATTERERS: usize = 2_000_000;
/// Cell size of the grid over the static scatterers, metres.
const SCATTERER_CELL_M: f64 = 10.0;
/// Largest number of objects one scene may hold.
pub const MAX_OBJECTS: usize = 200_000;
/// Transmission of an opaque outline (not exactly zero so logarithms stay finite).
pub const OPAQUE_TAU: f32 = 1e-6;
/// Half-width of a surface scatterer's specular lobe, radians (about 2 degrees: a 0.1 m
/// facet at 3.9 mm wavelength).
pub const SPECULAR_LOBE_RAD: f64 = 0.035;
/// Radar cross section per unit of a point feature's `rho` (radar-model's `A_I`), m^2.
pub const AREA_PER_RHO_M2: f64 = 200.0;

/// How a scatterer's power fluctuates between looks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Swerling {
    /// Steady.
    Zero,
    /// Exponential power, one draw per rotation.
    One,
    /// Exponential power, one draw per look.
    Two,
    /// Chi-square (4 degrees of freedom) power, one draw per rotation.
    Three,
    /// Chi-square (4 degrees of freedom) power, one draw per look.
    Four,
}

/// One point scatterer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scatterer {
    /// World position (static) or body-frame offset from its mover's centre.
    pub pos: [f64; 2],
    /// Diffuse cross section at normal incidence, m^2.
    pub diffuse_m2: f32,
    /// Specular cross section at normal incidence, m^2.
    pub specular_m2: f32,
    /// Unit surface normal (world, or body frame for a mover); zero = isotropic.
    pub normal: [f32; 2],
    /// Fluctuation class.
    pub swerling: Swerling,
    /// Index of the outline it belongs to (`u32::MAX`: none).
    pub outline: u32,
    /// Index of its mover (`u32::MAX`: static).
    pub mover: u32,
    /// How far below the radar the scatterer's return comes from, metres (0 for what
    /// stands as tall as the radar: fronts, poles, trees; 2 m for ground clutter, 0.8 m for
    /// a car's body): close in it is seen through the lower edge of the elevation beam
    /// ([`elevation_gain`]).
    pub drop_m: f32,
}

/// Height of the radar above the ground, metres (on a car's roof).
pub const RADAR_HEIGHT_M: f64 = 2.0;
/// Half-power half-width of the two-way elevation beam below the horizon, radians (about
/// 5.7 deg: the simulator's choice, between a 1.8 deg pencil and a cosec-squared fan).
pub const ELEVATION_HALF_RAD: f64 = 0.1;

/// How far below the radar a vehicle's body returns from, metres.
pub const VEHICLE_DROP_M: f32 = 0.8;
/// How far below the radar a hedge returns from, metres.
pub const HEDGE_DROP_M: f32 = 0.8;

/// Two-way elevation gain of a scatterer `drop_m` below the radar at range `r`: a
/// Gaussian two-way elevation pattern at the depression angle `atan(drop / r)`.
pub fn elevation_gain(drop_m: f64, r: f64) -> f64 {
    if drop_m <= 0.0 {
        return 1.0;
    }
    let dep = (drop_m / r.max(0.1)).atan();
    (-(dep / ELEVATION_HALF_RAD).powi(2) * std::f64::consts::LN_2).exp()
}

/// Entries of [`ElevationTable`] per unit of `drop / range`.
const ELEVATION_STEPS_PER_UNIT: f64 = 2048.0;
/// [`ElevationTable`] covers `drop / range` up to this (the gain is 0 beyond).
const ELEVATION_MAX_RATIO: f64 = 2.0;

/// [`elevation_gain`] tabulated against `drop / range` (the rendering's per-rotation loop
/// looks it up instead of calling `atan` and `exp` per scatterer).
#[derive(Debug, Clone)]
pub struct ElevationTable(Vec<f32>);

impl Default for ElevationTable {
    fn default() -> Self {
        let n = (ELEVATION_MAX_RATIO * ELEVATION_STEPS_PER_UNIT) as usize + 1;
        ElevationTable(
            (0..n)
                .map(|i| elevation_gain(i as f64 / ELEVATION_STEPS_PER_UNIT, 1.0) as f32)
                .collect(),
        )
    }
}

impl ElevationTable {
    /// The gain of a scatterer `drop_m` below the radar at range `r`.
    #[inline]
    pub fn gain(&self, drop_m: f32, r: f64) -> f32 {
        if drop_m <= 0.0 {
            return 1.0;
        }
        let i = (f64::from(drop_m) / r.max(0.1) * ELEVATION_STEPS_PER_UNIT).round() as usize;
        self.0.get(i).copied().unwrap_or(0.0)
    }
}

/// An outline's shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// A segment from `a` to `b`.
    Segment {
        /// One end.
        a: [f64; 2],
        /// The other end.
        b: [f64; 2],
    },
    /// A disk.
    Disk {
        /// Centre.
        c: [f64; 2],
        /// Radius, metres.
        r: f64,
    },
}

impl Shape {
    /// Centre and half-extent (metres).
    pub fn centre_and_reach(&self) -> ([f64; 2], f64) {
        match *self {
            Shape::Segment { a, b } => (
                [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])],
                0.5 * (b[0] - a[0]).hypot(b[1] - a[1]),
            ),
            Shape::Disk { c, r } => (c, r),
        }
    }
}

/// An occluding outline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outline {
    /// World shape (static) or body-frame shape (mover).
    pub shape: Shape,
    /// One-way power transmission of one crossing.
    pub tau: f32,
    /// A flat opaque reflector that forms multipath ghosts.
    pub mirror: bool,
    /// Index of its mover (`u32::MAX`: static).
    pub mover: u32,
}

/// A moving object's straight-line motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mover {
    /// Centre at time 0.
    pub origin: [f64; 2],
    /// Heading, radians counter-clockwise from +x.
    pub heading_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Distance after which it starts again at `origin`.
    pub travel_m: f64,
}

impl Mover {
    /// Centre and heading at `t_s` seconds after the scene's start.
    pub fn pose_at(&self, t_s: f64) -> ([f64; 2], f64) {
        let d = (self.speed_mps * t_s).rem_euclid(self.travel_m.max(1e-9));
        let (s, c) = self.heading_rad.sin_cos();
        (
            [self.origin[0] + d * c, self.origin[1] + d * s],
            self.heading_rad,
        )
    }

    /// A body-frame point in the world at centre `centre`, heading `heading`.
    pub fn to_world(centre: [f64; 2], heading: f64, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = heading.sin_cos();
        [
            centre[0] + c * p[0] - s * p[1],
            centre[1] + s * p[0] + c * p[1],
        ]
    }
}

/// Everything the realistic renderer draws: scatterers, outlines, movers, and grids over
/// the static ones.
#[derive(Debug, Clone)]
pub struct World {
    /// Every scatterer: the static ones in their grid's cell order, then the movers'.
    pub scatterers: Vec<Scatterer>,
    /// Every outline.
    pub outlines: Vec<Outline>,
    /// Every mover.
    pub movers: Vec<Mover>,
    /// Grid over the static scatterers (indices into `scatterers`).
    pub scatterer_grid: GridIndex,
    /// Indices of the static scatterers, in grid order.
    pub static_scatterers: Vec<u32>,
    /// Indices of movers' scatterers.
    pub moving_scatterers: Vec<u32>,
    /// Grid over the static outlines' centres (indices into `static_outlines`).
    pub outline_grid: GridIndex,
    /// Indices of the static outlines.
    pub static_outlines: Vec<u32>,
    /// Indices of the movers' outlines.
    pub moving_outlines: Vec<u32>,
    /// The largest half-extent of a static outline, metres.
    pub outline_reach_m: f64,
}

struct Builder {
    scatterers: Vec<Scatterer>,
    outlines: Vec<Outline>,
    movers: Vec<Mover>,
    rng: ChaCha8Rng,
}

fn invalid(field: String, reason: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        field,
        reason: reason.into(),
    }
}

fn point(field: &str, p: Option<[f64; 2]>) -> Result<[f64; 2], SceneError> {
    let p = p.ok_or_else(|| invalid(field.to_string(), "is required for this kind"))?;
    if p.iter().all(|v| v.is_finite() && v.abs() <= 1e6) {
        Ok(p)
    } else {
        Err(invalid(
            field.to_string(),
            "must be finite and within 1000 km",
        ))
    }
}

fn positive(field: &str, v: Option<f64>, default: f64, max: f64) -> Result<f64, SceneError> {
    let v = v.unwrap_or(default);
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        Err(invalid(
            field.to_string(),
            format!("must be in (0, {max}], got {v}"),
        ))
    }
}

impl Builder {
    fn check_room(&self, more: usize) -> Result<(), SceneError> {
        if self.scatterers.len().saturating_add(more) > MAX_SCATTERERS {
            return Err(invalid(
                "objects".into(),
                format!("the scene expands to more than {MAX_SCATTERERS} scatterers"),
            ));
        }
        Ok(())
    }

    fn outline(&mut self, shape: Shape, tau: f32, mirror: bool, mover: u32) -> u32 {
        self.outlines.push(Outline {
            shape,
            tau,
            mirror,
            mover,
        });
        u32::try_from(self.outlines.len() - 1).unwrap_or(u32::MAX)
    }

    /// Scatterers every `spacing` along a surface from `a` to `b` (jittered along it),
    /// `diffuse` and `specular` m^2 per metre.
    #[allow(clippy::too_many_arguments)]
    fn surface(
        &mut self,
        a: [f64; 2],
        b: [f64; 2],
        spacing: f64,
        diffuse_per_m: f64,
        specular_per_m: f64,
        swerling: Swerling,
        outline: u32,
        mover: u32,
    ) -> Result<(), SceneError> {
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let n = (len / spacing).ceil().max(1.0);
        if n > MAX_SCATTERERS as f64 {
            return Err(invalid("objects".into(), "a surface expands too far"));
        }
        let n = n as usize;
        self.check_room(n)?;
        let step = len / n as f64;
        let (ux, uy) = if len > 0.0 {
            ((b[0] - a[0]) / len, (b[1] - a[1]) / len)
        } else {
            (1.0, 0.0)
        };
        let normal = [-uy as f32, ux as f32];
        for k in 0..n {
            let s = (k as f64 + self.rng.gen_range(0.1..0.9)) * step;
            self.scatterers.push(Scatterer {
                pos: [a[0] + s * ux, a[1] + s * uy],
                diffuse_m2: (diffuse_per_m * step) as f32,
                specular_m2: (specular_per_m * step) as f32,
                normal,
                swerling,
                outline,
                mover,
                drop_m: 0.0,
            });
        }
        Ok(())
    }

    /// `count` isotropic scatterers of `rcs` m^2 each, uniform in a disk.
    #[allow(clippy::too_many_arguments)]
    fn disk_volume(
        &mut self,
        c: [f64; 2],
        r: f64,
        count: usize,
        rcs: f64,
        swerling: Swerling,
        outline: u32,
    ) -> Result<(), SceneError> {
        self.check_room(count)?;
        for _ in 0..count {
            let rr = r * self.rng.gen::<f64>().sqrt();
            let a = self.rng.gen_range(0.0..std::f64::consts::TAU);
            self.scatterers.push(Scatterer {
                pos: [c[0] + rr * a.cos(), c[1] + rr * a.sin()],
                diffuse_m2: rcs as f32,
                specular_m2: 0.0,
                normal: [0.0, 0.0],
                swerling,
                outline,
                mover: u32::MAX,
                drop_m: 0.0,
            });
        }
        Ok(())
    }

    fn single(&mut self, p: [f64; 2], rcs: f64, swerling: Swerling, outline: u32, mover: u32) {
        self.scatterers.push(Scatterer {
            pos: p,
            diffuse_m2: rcs as f32,
            specular_m2: 0.0,
            normal: [0.0, 0.0],
            swerling,
            outline,
            mover,
            drop_m: 0.0,
        });
    }

    fn object(&mut self, i: usize, o: &ObjectSpec) -> Result<(), SceneError> {
        let field = |name: &str| format!("objects[{i}].{name}");
        let scale = positive(&field("rcs_scale"), o.rcs_scale, 1.0, 1e6)?;
        let tau = |default: f64| -> Result<f32, SceneError> {
            let t = o.transmission.unwrap_or(default);
            if t.is_finite() && (0.0..1.0).contains(&t) {
                Ok((t as f32).max(OPAQUE_TAU))
            } else {
                Err(invalid(
                    field("transmission"),
                    format!("must be in [0, 1), got {t}"),
                ))
            }
        };
        if !(o.speed_mps.is_finite() && o.speed_mps.abs() <= 100.0) {
            return Err(invalid(field("speed_mps"), "must be within +/-100 m/s"));
        }
        if o.speed_mps != 0.0 && o.kind != ObjectKind::Vehicle {
            return Err(invalid(field("speed_mps"), "only vehicles move"));
        }
        if !o.heading_deg.is_finite() {
            return Err(invalid(field("heading_deg"), "must be finite"));
        }
        match o.kind {
            ObjectKind::BuildingFront | ObjectKind::Wall | ObjectKind::Fence => {
                let a = point(&field("from"), o.from)?;
                let b = point(&field("to"), o.to)?;
                let (diffuse, specular, spacing, t, mirror, sw) = match o.kind {
                    ObjectKind::BuildingFront => (1.0, 30.0, 0.15, tau(0.0)?, true, Swerling::Two),
                    ObjectKind::Wall => (0.5, 10.0, 0.15, tau(0.0)?, true, Swerling::Two),
                    _ => (0.15, 1.0, 0.2, tau(0.88)?, false, Swerling::Two),
                };
                let id = self.outline(Shape::Segment { a, b }, t, mirror, u32::MAX);
                self.surface(
                    a,
                    b,
                    spacing,
                    diffuse * scale,
                    specular * scale,
                    sw,
                    id,
                    u32::MAX,
                )?;
            }
            ObjectKind::Hedge => {
                let a = point(&field("from"), o.from)?;
                let b = point(&field("to"), o.to)?;
                let depth = positive(&field("depth_m"), o.depth_m, 1.0, 20.0)?;
                let id = self.outline(Shape::Segment { a, b }, tau(0.4)?, false, u32::MAX);
                let len = (b[0] - a[0]).hypot(b[1] - a[1]);
                let count = (len * depth * 4.0).ceil();
                if count > MAX_SCATTERERS as f64 {
                    return Err(invalid(field("depth_m"), "the hedge expands too far"));
                }
                let count = count as usize;
                self.check_room(count)?;
                let (ux, uy) = if len > 0.0 {
                    ((b[0] - a[0]) / len, (b[1] - a[1]) / len)
                } else {
                    (1.0, 0.0)
                };
                for _ in 0..count {
                    let s = self.rng.gen_range(0.0..=len);
                    let d = self.rng.gen_range(-0.5..=0.5) * depth;
                    let p = [a[0] + s * ux - d * uy, a[1] + s * uy + d * ux];
                    self.single(p, 0.08 * scale, Swerling::Two, id, u32::MAX);
                    if let Some(last) = self.scatterers.last_mut() {
                        last.drop_m = HEDGE_DROP_M;
                    }
                }
            }
            ObjectKind::Vehicle => {
                let at = point(&field("at"), o.at)?;
                let length = positive(&field("length_m"), o.length_m, 4.5, 30.0)?;
                let width = positive(&field("width_m"), o.width_m, 1.8, 5.0)?;
                let heading = o.heading_deg.to_radians();
                let moving = o.speed_mps != 0.0;
                let mover = if moving {
                    let travel = positive(&field("travel_m"), o.travel_m, 400.0, 1e5)?;
                    self.movers.push(Mover {
                        origin: at,
                        heading_rad: heading,
                        speed_mps: o.speed_mps,
                        travel_m: travel,
                    });
                    u32::try_from(self.movers.len() - 1).unwrap_or(u32::MAX)
                } else {
                    u32::MAX
                };
                // Body frame: x along the heading. A moving vehicle keeps body-frame
                // coordinates; a parked one is placed in the world now.
                let place = |p: [f64; 2]| {
                    if moving {
                        p
                    } else {
                        Mover::to_world(at, heading, p)
                    }
                };
                let first_scatterer = self.scatterers.len();
                let (hl, hw) = (0.5 * length, 0.5 * width);
                let corners = [[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]];
                for k in 0..4 {
                    let a = place(corners[k]);
                    let b = place(corners[(k + 1) % 4]);
                    let id = self.outline(Shape::Segment { a, b }, tau(0.5)?, false, mover);
                    self.surface(
                        a,
                        b,
                        0.25,
                        1.0 * scale,
                        40.0 * scale,
                        Swerling::Two,
                        id,
                        mover,
                    )?;
                    self.check_room(1)?;
                    // A corner (wheel arch, bumper, mirror): a strong, steady-ish scatterer.
                    self.single(place(corners[k]), 8.0 * scale, Swerling::Three, id, mover);
                }
                for s in self.scatterers.iter_mut().skip(first_scatterer) {
                    s.drop_m = VEHICLE_DROP_M;
                }
            }
            ObjectKind::Tree => {
                let at = point(&field("at"), o.at)?;
                let r = positive(&field("radius_m"), o.radius_m, 2.0, 30.0)?;
                let trunk =
                    self.outline(Shape::Disk { c: at, r: 0.2 }, OPAQUE_TAU, false, u32::MAX);
                self.check_room(1)?;
                self.single(at, 2.0 * scale, Swerling::Three, trunk, u32::MAX);
                let crown = self.outline(Shape::Disk { c: at, r }, tau(0.5)?, false, u32::MAX);
                let count = (std::f64::consts::PI * r * r * 2.0).ceil() as usize;
                self.disk_volume(at, r, count, 0.06 * scale, Swerling::Two, crown)?;
            }
            ObjectKind::Foliage => {
                let at = point(&field("at"), o.at)?;
                let r = positive(&field("radius_m"), o.radius_m, 2.0, 30.0)?;
                let crown = self.outline(Shape::Disk { c: at, r }, tau(0.5)?, false, u32::MAX);
                let count = (std::f64::consts::PI * r * r * 2.0).ceil() as usize;
                self.disk_volume(at, r, count, 0.06 * scale, Swerling::Two, crown)?;
            }
            ObjectKind::Clutter => {
                let a = point(&field("from"), o.from)?;
                let b = point(&field("to"), o.to)?;
                let density = positive(&field("density_per_m2"), o.density_per_m2, 0.05, 10.0)?;
                let (w, h) = ((b[0] - a[0]).abs(), (b[1] - a[1]).abs());
                let count = (w * h * density).round();
                if count > MAX_SCATTERERS as f64 {
                    return Err(invalid(
                        field("density_per_m2"),
                        "the clutter expands too far",
                    ));
                }
                let count = count as usize;
                self.check_room(count)?;
                let (x0, y0) = (a[0].min(b[0]), a[1].min(b[1]));
                for _ in 0..count {
                    let p = [
                        x0 + self.rng.gen::<f64>() * w,
                        y0 + self.rng.gen::<f64>() * h,
                    ];
                    let n: f64 = self.rng.sample(rand_distr::StandardNormal);
                    let rcs = 0.02 * scale * (1.2 * n).exp();
                    self.single(p, rcs, Swerling::Two, u32::MAX, u32::MAX);
                    if let Some(last) = self.scatterers.last_mut() {
                        last.drop_m = RADAR_HEIGHT_M as f32;
                    }
                }
            }
            ObjectKind::Pole => {
                let at = point(&field("at"), o.at)?;
                let id = self.outline(Shape::Disk { c: at, r: 0.1 }, OPAQUE_TAU, false, u32::MAX);
                self.check_room(1)?;
                self.single(at, 6.0 * scale, Swerling::Three, id, u32::MAX);
            }
        }
        Ok(())
    }
}

/// The Swerling class a point feature of `kind` fluctuates with.
pub fn feature_swerling(kind: FeatureKind) -> Swerling {
    match kind {
        FeatureKind::Reflector => Swerling::Zero,
        FeatureKind::LampPost => Swerling::Three,
        FeatureKind::Tree | FeatureKind::WoodenFence | FeatureKind::PerspexSheet => Swerling::Two,
        FeatureKind::Wall => Swerling::Four,
    }
}

impl World {
    /// Expands the scene's point features and objects; `seed` places the scatterers.
    pub fn build(
        features: &[Feature],
        objects: &[ObjectSpec],
        seed: u64,
    ) -> Result<World, SceneError> {
        if objects.len() > MAX_OBJECTS {
            return Err(invalid(
                "objects".into(),
                format!(
                    "{} objects; a scene holds at most {MAX_OBJECTS}",
                    objects.len()
                ),
            ));
        }
        let mut b = Builder {
            scatterers: Vec::new(),
            outlines: Vec::new(),
            movers: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x6f62_6a65_6374_7321),
        };
        for f in features {
            let tau = (1.0 - f.rho - f.alpha).clamp(f64::from(OPAQUE_TAU), 1.0) as f32;
            let id = b.outline(
                Shape::Disk {
                    c: [f.x_m, f.y_m],
                    r: 0.15,
                },
                tau,
                false,
                u32::MAX,
            );
            b.check_room(1)?;
            b.single(
                [f.x_m, f.y_m],
                f.rho * AREA_PER_RHO_M2,
                feature_swerling(f.kind),
                id,
                u32::MAX,
            );
        }
        for (i, o) in objects.iter().enumerate() {
            b.object(i, o)?;
        }
        Ok(World::index(b.scatterers, b.outlines, b.movers))
    }

    fn index(scatterers: Vec<Scatterer>, outlines: Vec<Outline>, movers: Vec<Mover>) -> World {
        let to_u32 = |i: usize| u32::try_from(i).unwrap_or(u32::MAX);
        // The static scatterers are stored in the grid's cell order (then the movers'), so
        // that a rotation's gather reads them from memory nearly in sequence. A grid cell
        // keeps its points in their order, so the gather visits the same scatterers in the
        // same order as over the unsorted list.
        let (statics, moving): (Vec<Scatterer>, Vec<Scatterer>) =
            scatterers.into_iter().partition(|s| s.mover == u32::MAX);
        let positions: Vec<[f64; 2]> = statics.iter().map(|s| s.pos).collect();
        let sorting = GridIndex::new(&positions, SCATTERER_CELL_M);
        let mut scatterers: Vec<Scatterer> = sorting
            .cell_order()
            .iter()
            .filter_map(|&i| statics.get(i as usize).copied())
            .collect();
        let static_count = scatterers.len();
        scatterers.extend(moving);
        let static_scatterers: Vec<u32> = (0..static_count).map(to_u32).collect();
        let moving_scatterers = (static_count..scatterers.len()).map(to_u32).collect();
        let positions: Vec<[f64; 2]> = scatterers[..static_count].iter().map(|s| s.pos).collect();
        let static_outlines: Vec<u32> = (0..outlines.len())
            .filter(|&i| outlines[i].mover == u32::MAX)
            .map(to_u32)
            .collect();
        let moving_outlines = (0..outlines.len())
            .filter(|&i| outlines[i].mover != u32::MAX)
            .map(to_u32)
            .collect();
        let outline_reach_m = static_outlines
            .iter()
            .map(|&i| outlines[i as usize].shape.centre_and_reach().1)
            .fold(0.0, f64::max);
        let centres: Vec<[f64; 2]> = static_outlines
            .iter()
            .map(|&i| outlines[i as usize].shape.centre_and_reach().0)
            .collect();
        World {
            scatterer_grid: GridIndex::new(&positions, SCATTERER_CELL_M),
            outline_grid: GridIndex::new(&centres, 10.0),
            scatterers,
            outlines,
            movers,
            static_scatterers,
            moving_scatterers,
            static_outlines,
            moving_outlines,
            outline_reach_m,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall(from: [f64; 2], to: [f64; 2]) -> ObjectSpec {
        ObjectSpec::segment(ObjectKind::Wall, from, to)
    }

    #[test]
    fn a_wall_expands_into_scatterers_along_its_extent_with_its_normal() {
        let w = World::build(&[], &[wall([0.0, 5.0], [10.0, 5.0])], 1).expect("world");
        assert!(w.scatterers.len() >= 60, "{}", w.scatterers.len());
        assert!(w
            .scatterers
            .iter()
            .all(|s| (0.0..=10.0).contains(&s.pos[0]) && s.pos[1] == 5.0));
        assert!(w.scatterers.iter().all(|s| s.normal[1].abs() == 1.0));
        assert_eq!(w.outlines.len(), 1);
        assert!(w.outlines[0].mirror);
    }

    #[test]
    fn a_line_object_without_its_ends_is_a_named_error() {
        let mut o = wall([0.0, 0.0], [1.0, 0.0]);
        o.to = None;
        let err = World::build(&[], &[o], 1).expect_err("no end");
        assert!(err.to_string().contains("objects[0].to"), "{err}");
    }

    #[test]
    fn a_moving_vehicle_is_a_mover_with_body_frame_scatterers() {
        let mut o = wall([0.0, 0.0], [1.0, 0.0]);
        o.kind = ObjectKind::Vehicle;
        o.at = Some([100.0, 0.0]);
        o.speed_mps = 10.0;
        let w = World::build(&[], &[o], 1).expect("world");
        assert_eq!(w.movers.len(), 1);
        assert!(w.static_scatterers.is_empty());
        assert!(w.scatterers.iter().all(|s| s.pos[0].abs() <= 2.25 + 1e-9));
        let (c, _) = w.movers[0].pose_at(1.5);
        assert!((c[0] - 115.0).abs() < 1e-9);
    }
}
