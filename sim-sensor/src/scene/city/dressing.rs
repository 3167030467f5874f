//! The realistic city (`[city.dressing]`, with the scene's `[realism]`): the city's grid
//! and route lined as the street generator lines its streets (see [`crate::scene::street`]),
//! for the realistic renderer instead of the point-landmark table.
//!
//! Every block side gets building fronts of random widths, set back up to
//! `setback_max_m` behind the building line, with gaps (alleys, drives), hedges and fences
//! in the front gardens and across the gaps; along every kerb trees (a trunk that is a point
//! feature and a crown of foliage), lamp posts (point features) and parked vehicles; inside
//! every block and along every street (junctions included) weak ground clutter; and moving
//! vehicles along whole streets, keeping left as in the UK (where the real scans were
//! recorded). Each block is drawn from its own random stream of the layout seed, so a
//! block's dressing does not depend on how many blocks came before it.
//!
//! IO: none.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use super::{invalid, CitySpec, MAX_BLOCKS};
use crate::error::SceneError;
use crate::scene::objects::{ObjectKind, ObjectSpec};
use crate::scene::street::{SideStyle, Street};

/// Most moving vehicles a city may hold.
pub const MAX_MOVING_VEHICLES: u32 = 10_000;

/// The `[city.dressing]` table. Defaults are the shipped `urban-street`'s values (fitted
/// against the real scans on that street; see the crate README, "Realistic rendering").
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct DressingSpec {
    /// Largest set-back of a front behind the building line, metres.
    pub setback_max_m: f64,
    /// Probability of a gap (alley, drive) after a front.
    pub gap_probability: f64,
    /// Probability of a hedge before a front set back more than 1.2 m.
    pub hedge_probability: f64,
    /// Probability of a fence before a front set back more than 1.2 m (when no hedge stands
    /// there), and across a gap.
    pub fence_probability: f64,
    /// Mean distance between trees along a kerb, metres (0: none).
    pub tree_spacing_m: f64,
    /// Mean distance between lamp posts along a kerb, metres (0: none).
    pub pole_spacing_m: f64,
    /// Share of 6 m kerb slots holding a parked vehicle.
    pub parked_fraction: f64,
    /// Each parked vehicle 3.7-5.3 m long, anywhere in its slot, up to 0.25 m off the
    /// parking lane's centre line and 3 degrees off the kerb (`street::PARKED_LENGTH_M` and
    /// after), as on a real street; off (the default, the urban street's), one 4.5 m car
    /// centred in every occupied slot: a comb of 6 m period that a street's scans align to
    /// one slot off as well as on.
    pub parked_variation: bool,
    /// Moving vehicles on the grid's streets.
    pub moving_vehicles: u32,
    /// Clutter scatterers per m^2 on the streets (road surface, kerbs, railings, bins).
    pub street_clutter_per_m2: f64,
    /// Clutter scatterers per m^2 inside the blocks (back buildings, gardens).
    pub block_clutter_per_m2: f64,
}

impl Default for DressingSpec {
    fn default() -> Self {
        Self {
            setback_max_m: 4.0,
            gap_probability: 0.4,
            hedge_probability: 0.2,
            fence_probability: 0.3,
            tree_spacing_m: 20.0,
            pole_spacing_m: 25.0,
            parked_fraction: 0.5,
            parked_variation: false,
            moving_vehicles: 60,
            street_clutter_per_m2: 1.0,
            block_clutter_per_m2: 1.0,
        }
    }
}

impl DressingSpec {
    fn validate(&self) -> Result<(), SceneError> {
        for (name, v, lo, hi) in [
            ("setback_max_m", self.setback_max_m, 0.0, 50.0),
            ("gap_probability", self.gap_probability, 0.0, 0.9),
            ("hedge_probability", self.hedge_probability, 0.0, 1.0),
            ("fence_probability", self.fence_probability, 0.0, 1.0),
            ("tree_spacing_m", self.tree_spacing_m, 0.0, 1e4),
            ("pole_spacing_m", self.pole_spacing_m, 0.0, 1e4),
            ("parked_fraction", self.parked_fraction, 0.0, 1.0),
            (
                "street_clutter_per_m2",
                self.street_clutter_per_m2,
                0.0,
                10.0,
            ),
            ("block_clutter_per_m2", self.block_clutter_per_m2, 0.0, 10.0),
        ] {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(invalid(
                    &format!("dressing.{name}"),
                    format!("must be in [{lo}, {hi}], got {v}"),
                ));
            }
        }
        if (self.tree_spacing_m > 0.0 && self.tree_spacing_m < 2.0)
            || (self.pole_spacing_m > 0.0 && self.pole_spacing_m < 2.0)
        {
            return Err(invalid(
                "dressing.tree_spacing_m",
                "spacings must be 0 or at least 2 m".into(),
            ));
        }
        if self.moving_vehicles > MAX_MOVING_VEHICLES {
            return Err(invalid(
                "dressing.moving_vehicles",
                format!("at most {MAX_MOVING_VEHICLES}"),
            ));
        }
        Ok(())
    }

    /// Lines the city's blocks and streets (`city` gives the grid and the layout seed).
    pub fn dress(&self, city: &CitySpec) -> Result<Street, SceneError> {
        self.validate()?;
        let style = SideStyle {
            pavement_m: city.pavement_m,
            setback_max_m: self.setback_max_m,
            gap_probability: self.gap_probability,
            hedge_probability: self.hedge_probability,
            fence_probability: self.fence_probability,
            tree_spacing_m: self.tree_spacing_m,
            pole_spacing_m: self.pole_spacing_m,
            parked_fraction: self.parked_fraction,
            parked_variation: self.parked_variation,
        };
        let [px, py] = city.pitch_m();
        let half = city.carriageway_half_m + city.pavement_m;
        let (w, h) = (f64::from(city.blocks_x) * px, f64::from(city.blocks_y) * py);
        let seed = city.seed ^ 0x6472_6573_7365_6421;
        let mut out = Street::default();
        for j in 0..city.blocks_y {
            for i in 0..city.blocks_x {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                // `repeated`: every block dressed from the same stream, alike to the last
                // post (a city built to tempt wrong loop closures and wrong fixes).
                rng.set_stream(if city.repeated {
                    1
                } else {
                    u64::from(j) * u64::from(MAX_BLOCKS) + u64::from(i) + 1
                });
                let x0 = f64::from(i) * px + half;
                let y0 = f64::from(j) * py + half;
                let (x1, y1) = (x0 + city.block_x_m, y0 + city.block_y_m);
                if self.block_clutter_per_m2 > 0.0 {
                    out.objects.push(clutter(
                        [x0 + 1.0, y0 + 1.0],
                        [x1 - 1.0, y1 - 1.0],
                        self.block_clutter_per_m2,
                    ));
                }
                // Sides counter-clockwise; the street lies to the right of each.
                let c = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
                for k in 0..4 {
                    style.dress(&mut rng, c[k], c[(k + 1) % 4], &mut out);
                }
            }
        }
        if self.street_clutter_per_m2 > 0.0 {
            // Streets along x the grid's whole length (junctions included), then the
            // streets along y between them.
            for j in 0..=city.blocks_y {
                let y = f64::from(j) * py;
                out.objects.push(clutter(
                    [-half, y - half],
                    [w + half, y + half],
                    self.street_clutter_per_m2,
                ));
            }
            for i in 0..=city.blocks_x {
                let x = f64::from(i) * px;
                for j in 0..city.blocks_y {
                    out.objects.push(clutter(
                        [x - half, f64::from(j) * py + half],
                        [x + half, f64::from(j + 1) * py - half],
                        self.street_clutter_per_m2,
                    ));
                }
            }
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(0);
        // Lane centres half-way between the centre line and the kerb, keeping left.
        let lane = 0.5 * city.carriageway_half_m;
        for _ in 0..self.moving_vehicles {
            let mut v = ObjectSpec::of_kind(ObjectKind::Vehicle);
            v.speed_mps = rng.gen_range(6.0..12.0);
            let forward = rng.gen_bool(0.5);
            // Starts somewhere along its street and drives to the street's end, then
            // starts again where it began.
            let along = rng.gen_range(0.0..0.8);
            if rng.gen_bool(0.5) {
                let y = f64::from(rng.gen_range(0..=city.blocks_y)) * py;
                let (x, heading, lane_y) = if forward {
                    (along * w, 0.0, y + lane)
                } else {
                    (w - along * w, 180.0, y - lane)
                };
                v.at = Some([x, lane_y]);
                v.heading_deg = heading;
                v.travel_m = Some((w * (1.0 - along)).max(50.0));
            } else {
                let x = f64::from(rng.gen_range(0..=city.blocks_x)) * px;
                let (y, heading, lane_x) = if forward {
                    (along * h, 90.0, x - lane)
                } else {
                    (h - along * h, -90.0, x + lane)
                };
                v.at = Some([lane_x, y]);
                v.heading_deg = heading;
                v.travel_m = Some((h * (1.0 - along)).max(50.0));
            }
            out.objects.push(v);
        }
        Ok(out)
    }
}

fn clutter(from: [f64; 2], to: [f64; 2], density: f64) -> ObjectSpec {
    ObjectSpec {
        density_per_m2: Some(density),
        ..ObjectSpec::segment(ObjectKind::Clutter, from, to)
    }
}
