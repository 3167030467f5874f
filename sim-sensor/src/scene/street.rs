//! A seeded procedural street grid (the scene's `[street]` table): rectangular blocks
//! separated by streets, each block side lined with building fronts (random widths, set
//! backs and gaps), and along each kerb trees, poles and parked vehicles; moving vehicles
//! drive along the streets. The grid's streets run along x at `y = j x pitch` and along y
//! at `x = i x pitch` (`pitch = block_m + 2 x (carriageway_half_m + pavement_m)`), with
//! `y = 0` a street: a vehicle starting at `(0, 0)` facing +x drives down the middle of a
//! street.
//!
//! Poles and tree trunks become point features (so the ground truth lists them as
//! landmarks); crowns, building fronts and vehicles become objects.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use super::objects::{ObjectKind, ObjectSpec};
use super::FeatureKind;
use crate::error::SceneError;

/// The generator's settings.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct StreetSpec {
    /// Seed of the layout (independent of the scene's noise seed).
    pub seed: u64,
    /// Blocks along x.
    pub blocks_x: u32,
    /// Blocks along y (half above `y = 0`, half below).
    pub blocks_y: u32,
    /// Block length along x, metres.
    pub block_x_m: f64,
    /// Block length along y, metres.
    pub block_y_m: f64,
    /// x of the grid's first street crossing, metres.
    pub origin_x_m: f64,
    /// Half-width of the carriageway (kerb to centre line), metres.
    pub carriageway_half_m: f64,
    /// Pavement width (kerb to building line), metres.
    pub pavement_m: f64,
    /// Largest set-back of a building front behind the building line, metres.
    pub setback_max_m: f64,
    /// Probability of a gap (alley, drive) after a building front.
    pub gap_probability: f64,
    /// Mean distance between trees along a kerb, metres (0: none).
    pub tree_spacing_m: f64,
    /// Mean distance between poles along a kerb, metres (0: none).
    pub pole_spacing_m: f64,
    /// Share of 6 m kerb slots holding a parked vehicle.
    pub parked_fraction: f64,
    /// Moving vehicles.
    pub moving_vehicles: u32,
    /// Probability that a front garden hedge stands before a building front.
    pub hedge_probability: f64,
    /// Clutter scatterers per m^2 on the streets (road surface, kerbs, railings, bins).
    pub street_clutter_per_m2: f64,
    /// Clutter scatterers per m^2 inside the blocks (back buildings, gardens), seen
    /// through the gaps between fronts.
    pub block_clutter_per_m2: f64,
}

impl Default for StreetSpec {
    fn default() -> Self {
        Self {
            seed: 1,
            blocks_x: 3,
            blocks_y: 2,
            block_x_m: 100.0,
            block_y_m: 80.0,
            origin_x_m: -60.0,
            carriageway_half_m: 4.0,
            pavement_m: 3.0,
            setback_max_m: 2.0,
            gap_probability: 0.25,
            tree_spacing_m: 20.0,
            pole_spacing_m: 30.0,
            parked_fraction: 0.5,
            moving_vehicles: 4,
            hedge_probability: 0.2,
            street_clutter_per_m2: 0.05,
            block_clutter_per_m2: 0.05,
        }
    }
}

/// What the generator produced.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Street {
    /// Point features: poles (lamp posts) and tree trunks, `(kind, x, y)`.
    pub features: Vec<(FeatureKind, f64, f64)>,
    /// Extended objects.
    pub objects: Vec<ObjectSpec>,
}

fn object(kind: ObjectKind) -> ObjectSpec {
    ObjectSpec::of_kind(kind)
}

impl StreetSpec {
    fn validate(&self) -> Result<(), SceneError> {
        let bad = |field: &str, reason: String| {
            Err(SceneError::Invalid {
                field: format!("street.{field}"),
                reason,
            })
        };
        let in_range = |v: f64, lo: f64, hi: f64| v.is_finite() && v >= lo && v <= hi;
        if self.blocks_x == 0 || self.blocks_y == 0 || self.blocks_x > 64 || self.blocks_y > 64 {
            return bad(
                "blocks_x",
                "blocks_x and blocks_y must be in [1, 64]".into(),
            );
        }
        for (name, v, lo, hi) in [
            ("block_x_m", self.block_x_m, 10.0, 2000.0),
            ("block_y_m", self.block_y_m, 10.0, 2000.0),
            ("origin_x_m", self.origin_x_m, -1e5, 1e5),
            ("carriageway_half_m", self.carriageway_half_m, 1.0, 30.0),
            ("pavement_m", self.pavement_m, 0.5, 30.0),
            ("setback_max_m", self.setback_max_m, 0.0, 50.0),
            ("gap_probability", self.gap_probability, 0.0, 0.9),
            ("tree_spacing_m", self.tree_spacing_m, 0.0, 1e4),
            ("pole_spacing_m", self.pole_spacing_m, 0.0, 1e4),
            ("parked_fraction", self.parked_fraction, 0.0, 1.0),
            ("hedge_probability", self.hedge_probability, 0.0, 1.0),
            (
                "street_clutter_per_m2",
                self.street_clutter_per_m2,
                0.0,
                10.0,
            ),
            ("block_clutter_per_m2", self.block_clutter_per_m2, 0.0, 10.0),
        ] {
            if !in_range(v, lo, hi) {
                return bad(name, format!("must be in [{lo}, {hi}], got {v}"));
            }
        }
        if (self.tree_spacing_m > 0.0 && self.tree_spacing_m < 2.0)
            || (self.pole_spacing_m > 0.0 && self.pole_spacing_m < 2.0)
        {
            return bad(
                "tree_spacing_m",
                "spacings must be 0 or at least 2 m".into(),
            );
        }
        if self.moving_vehicles > 10_000 {
            return bad("moving_vehicles", "at most 10000".into());
        }
        Ok(())
    }

    /// How the generator lines each block side.
    fn side_style(&self) -> SideStyle {
        SideStyle {
            pavement_m: self.pavement_m,
            setback_max_m: self.setback_max_m,
            gap_probability: self.gap_probability,
            hedge_probability: self.hedge_probability,
            fence_probability: 0.0,
            tree_spacing_m: self.tree_spacing_m,
            pole_spacing_m: self.pole_spacing_m,
            parked_fraction: self.parked_fraction,
            parked_variation: false,
        }
    }

    /// Generates the grid.
    pub fn generate(&self) -> Result<Street, SceneError> {
        self.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ 0x7374_7265_6574_2121);
        let half_street = self.carriageway_half_m + self.pavement_m;
        let pitch_x = self.block_x_m + 2.0 * half_street;
        let pitch_y = self.block_y_m + 2.0 * half_street;
        let j0 = -i64::from(self.blocks_y / 2);
        let mut out = Street::default();
        for i in 0..i64::from(self.blocks_x) {
            for j in j0..j0 + i64::from(self.blocks_y) {
                let x0 = self.origin_x_m + i as f64 * pitch_x + half_street;
                let y0 = j as f64 * pitch_y + half_street;
                let x1 = x0 + self.block_x_m;
                let y1 = y0 + self.block_y_m;
                // Sides counter-clockwise; the outward normal points at the street.
                let corners = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]];
                if self.block_clutter_per_m2 > 0.0 {
                    let mut c = object(ObjectKind::Clutter);
                    c.from = Some([x0 + 1.0, y0 + 1.0]);
                    c.to = Some([x1 - 1.0, y1 - 1.0]);
                    c.density_per_m2 = Some(self.block_clutter_per_m2);
                    out.objects.push(c);
                }
                for k in 0..4 {
                    self.side_style()
                        .dress(&mut rng, corners[k], corners[(k + 1) % 4], &mut out);
                }
            }
        }
        // Moving vehicles on the streets along x (y = j pitch) and along y.
        let x_len = self.blocks_x as f64 * pitch_x;
        let y_len = self.blocks_y as f64 * pitch_y;
        if self.street_clutter_per_m2 > 0.0 {
            let x_start = self.origin_x_m;
            for j in j0..=j0 + i64::from(self.blocks_y) {
                let y = j as f64 * pitch_y;
                let mut c = object(ObjectKind::Clutter);
                c.from = Some([x_start - half_street, y - half_street]);
                c.to = Some([x_start + x_len + half_street, y + half_street]);
                c.density_per_m2 = Some(self.street_clutter_per_m2);
                out.objects.push(c);
            }
            for i in 0..=i64::from(self.blocks_x) {
                let x = x_start + i as f64 * pitch_x;
                for j in j0..j0 + i64::from(self.blocks_y) {
                    let mut c = object(ObjectKind::Clutter);
                    c.from = Some([x - half_street, j as f64 * pitch_y + half_street]);
                    c.to = Some([x + half_street, (j + 1) as f64 * pitch_y - half_street]);
                    c.density_per_m2 = Some(self.street_clutter_per_m2);
                    out.objects.push(c);
                }
            }
        }
        for _ in 0..self.moving_vehicles {
            let mut v = object(ObjectKind::Vehicle);
            let speed = rng.gen_range(6.0..12.0);
            let lane = 0.5 * self.carriageway_half_m;
            if rng.gen_bool(0.7) {
                let j = rng.gen_range(j0..=j0 + i64::from(self.blocks_y));
                let forward = rng.gen_bool(0.5);
                let y = j as f64 * pitch_y + if forward { lane } else { -lane };
                let x = self.origin_x_m + rng.gen_range(0.0..x_len);
                v.at = Some([x, y]);
                v.heading_deg = if forward { 0.0 } else { 180.0 };
                v.travel_m = Some(x_len.max(50.0));
            } else {
                let i = rng.gen_range(0..=i64::from(self.blocks_x));
                let forward = rng.gen_bool(0.5);
                let x = self.origin_x_m + i as f64 * pitch_x + if forward { -lane } else { lane };
                let y = j0 as f64 * pitch_y + rng.gen_range(0.0..y_len);
                v.at = Some([x, y]);
                v.heading_deg = if forward { 90.0 } else { -90.0 };
                v.travel_m = Some(y_len.max(50.0));
            }
            v.speed_mps = speed;
            out.objects.push(v);
        }
        Ok(out)
    }
}

/// How one block side is lined: the street generator's, and the realistic city's
/// (`[city.dressing]`), which adds fences.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideStyle {
    /// Kerb to building line, metres.
    pub pavement_m: f64,
    /// Largest set-back of a front behind the building line, metres.
    pub setback_max_m: f64,
    /// Probability of a gap after a front.
    pub gap_probability: f64,
    /// Probability of a hedge before a front set back more than 1.2 m.
    pub hedge_probability: f64,
    /// Probability of a fence on the building line before a front set back more than 1.2 m
    /// without a hedge, and across a gap (0: none, and no random draw for it, so the
    /// street generator's layouts are what they were).
    pub fence_probability: f64,
    /// Mean distance between trees along the kerb, metres (0: none).
    pub tree_spacing_m: f64,
    /// Mean distance between poles along the kerb, metres (0: none).
    pub pole_spacing_m: f64,
    /// Share of 6 m kerb slots holding a parked vehicle.
    pub parked_fraction: f64,
    /// Parked vehicles as a real street's (see [`PARKED_LENGTH_M`]) rather than one 4.5 m
    /// car centred in every occupied slot. Drawn from a stream of their own, so the rest of
    /// the layout is the same either way.
    pub parked_variation: bool,
}

/// With [`SideStyle::parked_variation`], a parked vehicle's length (m), drawn uniformly: a
/// small hatchback to an estate or a van.
pub const PARKED_LENGTH_M: [f64; 2] = [3.7, 5.3];
/// ... its offset from the parking lane's centre line, at most (m) ...
pub const PARKED_LATERAL_M: f64 = 0.25;
/// ... and its heading off the kerb's, at most (degrees); it stands anywhere in its slot.
pub const PARKED_SKEW_DEG: f64 = 3.0;

impl SideStyle {
    /// Lines one block side from `a` to `b` (counter-clockwise round the block: the street
    /// lies to the right): building fronts with set-backs and gaps, hedges and fences in
    /// front of them, trees, poles and parked vehicles along the kerb.
    pub fn dress(&self, rng: &mut ChaCha8Rng, a: [f64; 2], b: [f64; 2], out: &mut Street) {
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        if len.is_nan() || len <= 0.0 {
            return;
        }
        let u = [(b[0] - a[0]) / len, (b[1] - a[1]) / len];
        // Outward (street side) normal: right of the direction of travel.
        let n = [u[1], -u[0]];
        let at = |s: f64, off: f64| [a[0] + s * u[0] + off * n[0], a[1] + s * u[1] + off * n[1]];
        let fence = |rng: &mut ChaCha8Rng| {
            self.fence_probability > 0.0 && rng.gen_bool(self.fence_probability)
        };
        // Building fronts: the block edge is the building line; set back inwards.
        let mut s = rng.gen_range(0.0..3.0);
        while s < len - 2.0 {
            let w = rng.gen_range(6.0f64..25.0).min(len - s);
            let back = rng.gen_range(0.0..=self.setback_max_m);
            let mut f = object(ObjectKind::BuildingFront);
            f.from = Some(at(s, -back));
            f.to = Some(at(s + w, -back));
            out.objects.push(f);
            if back > 1.2 && rng.gen_bool(self.hedge_probability) {
                let mut h = object(ObjectKind::Hedge);
                h.from = Some(at(s + 0.5, -0.5));
                h.to = Some(at(s + w - 0.5, -0.5));
                h.depth_m = Some(0.8);
                out.objects.push(h);
            } else if back > 1.2 && fence(rng) {
                out.objects.push(ObjectSpec::segment(
                    ObjectKind::Fence,
                    at(s + 0.2, -0.2),
                    at(s + w - 0.2, -0.2),
                ));
            }
            s += w;
            if rng.gen_bool(self.gap_probability) {
                let gap = rng.gen_range(2.0..12.0);
                if fence(rng) {
                    // A fence (or gate) across the drive, a little way in.
                    let e = (s + gap).min(len);
                    out.objects.push(ObjectSpec::segment(
                        ObjectKind::Fence,
                        at(s, -1.0),
                        at(e, -1.0),
                    ));
                }
                s += gap;
            }
        }
        // Along the kerb (pavement_m out from the building line).
        let kerb = self.pavement_m;
        let place = |spacing: f64, rng: &mut ChaCha8Rng, f: &mut dyn FnMut(f64)| {
            if spacing <= 0.0 {
                return;
            }
            let mut s = rng.gen_range(0.0..spacing);
            while s < len {
                f(s);
                s += spacing * rng.gen_range(0.5..1.5);
            }
        };
        place(self.tree_spacing_m, rng, &mut |s| {
            let p = at(s, kerb - 0.6);
            out.features.push((FeatureKind::Tree, p[0], p[1]));
            let mut crown = object(ObjectKind::Foliage);
            crown.at = Some(p);
            crown.radius_m = Some(1.5);
            out.objects.push(crown);
        });
        place(self.pole_spacing_m, rng, &mut |s| {
            let p = at(s, kerb - 0.3);
            out.features.push((FeatureKind::LampPost, p[0], p[1]));
        });
        // Parked vehicles in 6 m slots in the parking lane. A slot's occupancy is drawn from
        // the layout's stream; with `parked_variation` the vehicle's length and place in its
        // slot from a stream of their own (the same side's state, another stream), so the
        // layout after it is unchanged and identically dressed blocks stay identical.
        let slots = (len / 6.0).floor() as usize;
        let heading = u[1].atan2(u[0]).to_degrees() + 180.0;
        let mut own = rng.clone();
        own.set_stream(!rng.get_stream());
        for k in 0..slots {
            if rng.gen_bool(self.parked_fraction) {
                let mut v = object(ObjectKind::Vehicle);
                let (mut along, mut off) = (k as f64 * 6.0 + 3.0, kerb + 1.1);
                v.heading_deg = heading;
                if self.parked_variation {
                    let length = own.gen_range(PARKED_LENGTH_M[0]..=PARKED_LENGTH_M[1]);
                    let room = 0.5 * (6.0 - length).max(0.0);
                    along += own.gen_range(-room..=room);
                    off += own.gen_range(-PARKED_LATERAL_M..=PARKED_LATERAL_M);
                    v.heading_deg += own.gen_range(-PARKED_SKEW_DEG..=PARKED_SKEW_DEG);
                    v.length_m = Some(length);
                }
                v.at = Some(at(along, off));
                out.objects.push(v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One block side 300 m long, dressed from `seed` with or without parked variation.
    fn side(variation: bool, seed: u64) -> Street {
        let style = SideStyle {
            pavement_m: 3.5,
            setback_max_m: 2.0,
            gap_probability: 0.3,
            hedge_probability: 0.2,
            fence_probability: 0.3,
            tree_spacing_m: 20.0,
            pole_spacing_m: 25.0,
            parked_fraction: 0.85,
            parked_variation: variation,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(7);
        let mut out = Street::default();
        style.dress(&mut rng, [0.0, 0.0], [300.0, 0.0], &mut out);
        out
    }

    #[test]
    fn parked_variation_moves_and_sizes_the_cars_in_their_slots_and_leaves_the_rest_alone() {
        let (comb, real) = (side(false, 3), side(true, 3));
        assert_eq!(comb.features, real.features);
        let others = |s: &Street| -> Vec<ObjectSpec> {
            s.objects
                .iter()
                .filter(|o| o.kind != ObjectKind::Vehicle)
                .cloned()
                .collect()
        };
        assert_eq!(others(&comb), others(&real));
        let cars = |s: &Street| -> Vec<ObjectSpec> {
            s.objects
                .iter()
                .filter(|o| o.kind == ObjectKind::Vehicle)
                .cloned()
                .collect()
        };
        let (a, b) = (cars(&comb), cars(&real));
        assert_eq!(a.len(), b.len());
        assert!(a.len() > 30, "{} cars", a.len());
        let mut along_off_slot = Vec::new();
        for (c, r) in a.iter().zip(&b) {
            // The comb: one default-length car centred in its slot.
            let [cx, cy] = c.at.expect("placed");
            assert_eq!(c.length_m, None);
            assert!(((cx - 3.0) / 6.0 - ((cx - 3.0) / 6.0).round()).abs() < 1e-9);
            // The street: the same slot, a length in range, wholly inside its slot.
            let [rx, ry] = r.at.expect("placed");
            let length = r.length_m.expect("a drawn length");
            assert!((PARKED_LENGTH_M[0]..=PARKED_LENGTH_M[1]).contains(&length));
            assert!(rx - 0.5 * length >= cx - 3.0 - 1e-9 && rx + 0.5 * length <= cx + 3.0 + 1e-9);
            assert!((ry - cy).abs() <= PARKED_LATERAL_M + 1e-9);
            assert!((r.heading_deg - c.heading_deg).abs() <= PARKED_SKEW_DEG + 1e-9);
            along_off_slot.push(rx - cx);
        }
        // Not a comb any more: the cars' offsets in their slots spread over most of the
        // room there is (a comb's are all 0).
        let n = along_off_slot.len() as f64;
        let mean = along_off_slot.iter().sum::<f64>() / n;
        let sd = (along_off_slot
            .iter()
            .map(|d| (d - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!(sd > 0.25, "offsets' spread {sd} m");
        assert_eq!(real, side(true, 3), "the same seed, the same street");
    }

    #[test]
    fn the_same_seed_gives_the_same_grid_and_another_seed_another() {
        let spec = StreetSpec::default();
        let a = spec.generate().expect("grid");
        let b = spec.generate().expect("grid");
        assert_eq!(a, b);
        let c = StreetSpec { seed: 2, ..spec }.generate().expect("grid");
        assert_ne!(a, c);
    }

    #[test]
    fn the_street_at_y_0_is_clear_of_buildings_and_lined_by_them() {
        let street = StreetSpec::default().generate().expect("grid");
        let fronts: Vec<&ObjectSpec> = street
            .objects
            .iter()
            .filter(|o| o.kind == ObjectKind::BuildingFront)
            .collect();
        assert!(fronts.len() > 20, "{}", fronts.len());
        let spec = StreetSpec::default();
        let half = spec.carriageway_half_m + spec.pavement_m;
        for f in &fronts {
            for p in [f.from, f.to].into_iter().flatten() {
                assert!(p[1].abs() >= half - 1e-9, "front at {p:?} in the street");
            }
        }
        // Fronts on both sides of the street at y = 0 near the origin.
        let near = |sign: f64| {
            fronts.iter().any(|f| {
                let p = f.from.unwrap_or_default();
                p[0].abs() < 40.0 && p[1] * sign > 0.0 && p[1].abs() < half + 3.0
            })
        };
        assert!(near(1.0) && near(-1.0));
        assert!(street.objects.iter().any(|o| o.speed_mps != 0.0));
    }

    #[test]
    fn a_grid_of_impossible_size_is_a_named_error() {
        let err = StreetSpec {
            blocks_x: 0,
            ..StreetSpec::default()
        }
        .generate()
        .expect_err("no blocks");
        assert!(err.to_string().contains("street.blocks_x"), "{err}");
    }
}
