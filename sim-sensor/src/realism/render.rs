//! Rendering with the realistic model: per rotation, candidates, visibility and ghosts;
//! per azimuth, a range line of deposited returns, the range kernel, the floor and the
//! unit's quantisation.
//!
//! Per rotation (from the rotation's middle pose, as [`crate::render::beams`] does):
//! 1. the outlines near the vehicle (static from their grid, movers at the middle time)
//!    are rasterised into a polar transmission buffer of [`OCCLUSION_CELLS`] cells: each
//!    cell keeps the ranges at which its ray crosses an outline and the crossing's
//!    transmission;
//! 2. each scatterer within reach gets its incidence angle (diffuse `cos^2` plus the
//!    specular lobe), its two-way transmission through every outline in front of it in its
//!    cell (its own outline excepted), and, for Swerling 1 and 3, its draw for the rotation;
//!    a scatterer whose mean return cannot reach [`NEGLIGIBLE_POWER`] is dropped here (so
//!    what is hidden costs nothing per azimuth);
//! 3. ghosts: each strong scatterer (`ghost_min_rcs_m2`) within `ghost_range_m` mirrored in
//!    each mirror outline (building fronts, walls) within that range, where the mirror
//!    point lies on the outline and both radar and source are on its front side, becomes a
//!    scatterer at the image position with `reflectance^2` of the source's power;
//! 4. the candidates are split by how far off the beam's axis their sidelobes still matter
//!    (from their strength and the antenna's envelope) into tiers, each sorted by bearing.
//!
//! Per azimuth: the pose at the azimuth's own time; each candidate within its tier's
//! window (plus the margin the vehicle's motion during the rotation allows; near ones
//! always) gets its exact range and offset from the beam's axis from that pose (movers at
//! that time), its two-way antenna gain, its speckle draw (Swerling 2 and 4) and the
//! receiver's gain at its range, and is deposited into the range line (split linearly
//! between the two bins about it); the line is convolved with the range kernel (each
//! deposit only as far as its sidelobes matter); a floor draw is added to every bin, and the
//! sum is quantised as the unit does.

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use radar_model::geometry::{wrap_angle, Pose2};

use super::objects::{Mover, Shape, Swerling, World, SPECULAR_LOBE_RAD};
use super::receiver::{Receiver, NEGLIGIBLE_POWER};
use super::RealismSpec;
use crate::error::{SceneError, SimError};
use crate::radar::RadarParams;
use crate::render::azimuth_in_rotation;
use crate::trajectory::{Trajectory, TrajectoryCursor};

/// Cells of the polar transmission buffer (0.088 degrees each).
pub const OCCLUSION_CELLS: usize = 4096;
/// Candidates within this (plus twice the distance travelled in the rotation) are tested
/// on every azimuth.
const NEAR_RANGE_M: f64 = 5.0;
/// Random streams: rotation draws and the rotation's ghosts use streams above this.
const ROTATION_STREAM_BASE: u64 = 3 << 62;
/// Most ghosts formed in one rotation.
pub const MAX_GHOSTS: usize = 2048;
/// A crossing nearer than this in front of a scatterer is its own surface.
const SELF_MARGIN_M: f64 = 0.15;
/// Share of a surface's diffuse return left at grazing incidence (windows, doors, joints:
/// real facades are not smooth): diffuse `= sigma (f + (1 - f) cos^2 i)`.
pub const ROUGH_FLOOR: f64 = 0.2;
/// Cosine of five specular lobe widths.
const SPECULAR_COS_LIMIT: f64 = 0.984_7;
/// Poses sampled per rotation to bound the vehicle's motion during it.
const MOTION_SAMPLES: u64 = 8;

/// The realistic model of one scene: its world and its receiver.
#[derive(Debug, Clone)]
pub struct RealisticModel {
    /// Scatterers, outlines, movers.
    pub world: World,
    /// The tabulated receiver.
    pub receiver: Receiver,
    /// The settings.
    pub spec: RealismSpec,
    /// Elevation gains of scatterers below the radar.
    pub elevation: super::objects::ElevationTable,
}

impl RealisticModel {
    /// Builds the receiver for `radar` and keeps `world`.
    pub fn new(
        world: World,
        spec: RealismSpec,
        radar: &RadarParams,
    ) -> Result<RealisticModel, SceneError> {
        let bin_m = f64::from(radar.range_gain) * radar.bin_size_m();
        let receiver = Receiver::new(
            &spec,
            usize::from(radar.range_bins),
            bin_m,
            f64::from(radar.range_offset_m),
        )?;
        Ok(RealisticModel {
            world,
            receiver,
            spec,
            elevation: super::objects::ElevationTable::default(),
        })
    }
}

#[derive(Debug, Clone, Copy)]
struct Candidate {
    bearing_mid: f64,
    /// World position at the rotation's middle time.
    pos: [f64; 2],
    /// World velocity (movers), m/s.
    vel: [f64; 2],
    /// Mean power factor: effective cross section x visibility x the rotation's draw.
    power: f32,
    /// Draw per look: 0 none, 2 exponential, 4 chi-square(4).
    per_look: u8,
}

#[derive(Debug, Default)]
struct Tier {
    half_tan: f64,
    half_rad: f64,
    list: Vec<Candidate>,
}

#[derive(Debug, Clone, Copy)]
struct Crossing {
    cell: u32,
    range: f32,
    tau: f32,
    outline: u32,
}

/// What one rendered azimuth held.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AzimuthCounts {
    /// Candidates deposited into the range line.
    pub deposited: usize,
    /// Ghosts among the rotation's candidates.
    pub ghosts: usize,
}

/// One client's realistic rendering state (no allocation per azimuth once warm).
#[derive(Debug, Default)]
pub struct RealisticCursor {
    rotation: Option<u64>,
    mid_offset_s: f64,
    near: Vec<Candidate>,
    tiers: Vec<Tier>,
    margin_rad: f64,
    ghosts: usize,
    crossings: Vec<Crossing>,
    cell_starts: Vec<u32>,
    found: Vec<usize>,
    line: Vec<f32>,
    signal: Vec<f32>,
    mirrors: Vec<([f64; 2], [f64; 2])>,
    sources: Vec<(usize, f32)>,
}

fn cell_of(angle: f64) -> usize {
    let a = angle.rem_euclid(std::f64::consts::TAU);
    ((a / std::f64::consts::TAU * OCCLUSION_CELLS as f64) as usize).min(OCCLUSION_CELLS - 1)
}

fn cell_angle(cell: usize) -> f64 {
    (cell as f64 + 0.5) / OCCLUSION_CELLS as f64 * std::f64::consts::TAU
}

/// Range along the ray of world angle `phi` from `o` to segment `a`-`b`, if it crosses.
fn ray_segment(o: [f64; 2], phi: f64, a: [f64; 2], b: [f64; 2]) -> Option<f64> {
    let (s, c) = phi.sin_cos();
    let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
    let (ax, ay) = (a[0] - o[0], a[1] - o[1]);
    let det = ex * s - ey * c;
    if det.abs() < 1e-12 {
        return None;
    }
    let t = (ex * ay - ey * ax) / det;
    let u = (c * ay - s * ax) / det;
    (t > 0.0 && (-1e-9..=1.0 + 1e-9).contains(&u)).then_some(t)
}

impl RealisticCursor {
    /// Renders azimuth `index` into `out_db` (the unit's output levels, dB).
    #[allow(clippy::too_many_arguments)]
    pub fn render(
        &mut self,
        model: &RealisticModel,
        trajectory: &Trajectory,
        cursor: &mut TrajectoryCursor,
        radar: &RadarParams,
        seed: u64,
        index: u64,
        out_db: &mut [f64],
    ) -> Result<(Pose2, AzimuthCounts), SimError> {
        let n = u64::from(radar.azimuths.max(1));
        let rotation = index / n;
        if self.rotation != Some(rotation) {
            self.prepare_rotation(model, trajectory, cursor, radar, seed, rotation)?;
        }
        let offset_ns = crate::render::offset_ns(radar, index);
        let pose = trajectory.pose_with(cursor, offset_ns)?;
        let dt = offset_ns as f64 * 1e-9 - self.mid_offset_s;
        let bearing =
            wrap_angle(radar.angle_of_encoder(radar.encoder_of(azimuth_in_rotation(radar, index))));
        let phi = pose.theta - bearing;
        let (sphi, cphi) = phi.sin_cos();
        let rx = &model.receiver;
        let bins = out_db.len();
        self.line.clear();
        self.line.resize(bins, 0.0);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(index);
        let mut bits = Bits::default();
        let mut deposited = 0usize;
        let max_fb = (bins as f64 - 1.0).max(0.0);
        let inv_bin = 1.0 / rx.bin_m;
        let mut deposit = |c: &Candidate, max_tan: f64, line: &mut [f32], bits: &mut Bits| {
            let px = c.pos[0] + c.vel[0] * dt - pose.x;
            let py = c.pos[1] + c.vel[1] * dt - pose.y;
            let along = px * cphi + py * sphi;
            if along <= 0.0 {
                return;
            }
            let cross = (py * cphi - px * sphi).abs();
            let t = cross / along;
            if t >= max_tan {
                return;
            }
            let g = rx.pattern_at(t);
            if g <= 0.0 {
                return;
            }
            let r = (px * px + py * py).sqrt();
            let fb = (r - rx.first_bin_m) * inv_bin;
            if !(0.0..max_fb).contains(&fb) {
                return;
            }
            let b0 = fb as usize;
            let w = (fb - b0 as f64) as f32;
            let speckle = match c.per_look {
                2 => rx.exp_quantiles[bits.take(&mut rng, 12)],
                4 => rx.chi4_quantiles[bits.take(&mut rng, 12)],
                _ => 1.0,
            };
            let p = c.power * g * rx.signal_per_m2[b0] * speckle;
            if let [lo, hi, ..] = &mut line[b0..] {
                *lo += p * (1.0 - w);
                *hi += p * w;
            }
            deposited += 1;
        };
        for c in &self.near {
            deposit(c, rx.pattern_max_tan, &mut self.line, &mut bits);
        }
        for tier in &self.tiers {
            let half = tier.half_rad + self.margin_rad;
            for_each_in_window(&tier.list, bearing, half, |c| {
                deposit(c, tier.half_tan.max(1e-9), &mut self.line, &mut bits)
            });
        }
        // Range kernel.
        self.signal.clear();
        self.signal.resize(bins, 0.0);
        let h = rx.kernel_half;
        for (b, &p) in self.line.iter().enumerate() {
            if p <= NEGLIGIBLE_POWER * 0.01 {
                continue;
            }
            let reach = rx.kernel_reach(p).min(h);
            let lo = b.saturating_sub(reach);
            let hi = (b + reach + 1).min(bins);
            let k0 = h + lo - b;
            let (Some(dst), Some(ker)) = (
                self.signal.get_mut(lo..hi),
                rx.kernel.get(k0..k0 + (hi - lo)),
            ) else {
                continue;
            };
            for (d, &k) in dst.iter_mut().zip(ker) {
                *d += p * k;
            }
        }
        // Floor and quantisation.
        for ((out, &s), &mean) in out_db.iter_mut().zip(&self.signal).zip(&rx.floor_mean) {
            let y = mean * rx.floor_quantiles[bits.take(&mut rng, 10)];
            // Non-negative: truncation is the floor.
            *out = rx.db_of(f64::from((y + s) as u32));
        }
        Ok((
            pose,
            AzimuthCounts {
                deposited,
                ghosts: self.ghosts,
            },
        ))
    }

    #[allow(clippy::too_many_arguments)]
    fn prepare_rotation(
        &mut self,
        model: &RealisticModel,
        trajectory: &Trajectory,
        cursor: &mut TrajectoryCursor,
        radar: &RadarParams,
        seed: u64,
        rotation: u64,
    ) -> Result<(), SimError> {
        let n = u64::from(radar.azimuths.max(1));
        let first = rotation.saturating_mul(n);
        let mid_ns = crate::render::offset_ns(radar, first + n / 2);
        let mid = trajectory.pose_with(cursor, mid_ns)?;
        let mid_t = mid_ns as f64 * 1e-9;
        self.mid_offset_s = mid_t;
        let mut travel_m: f64 = 0.0;
        let mut turn_rad: f64 = 0.0;
        for s in 0..=MOTION_SAMPLES {
            let k = first + n.saturating_sub(1) * s / MOTION_SAMPLES;
            let p = trajectory.pose_with(cursor, crate::render::offset_ns(radar, k))?;
            travel_m = travel_m.max((p.x - mid.x).hypot(p.y - mid.y));
            turn_rad = turn_rad.max(wrap_angle(p.theta - mid.theta).abs());
        }
        // Movers move too: pad by the fastest one's travel in half a rotation.
        let half_rot_s = 0.5 / radar.rotation_hz().max(1e-3);
        let fastest = model
            .world
            .movers
            .iter()
            .map(|m| m.speed_mps.abs())
            .fold(0.0, f64::max);
        travel_m = travel_m * 1.25 + 0.05;
        turn_rad = turn_rad * 1.25 + 1e-3;
        let near_m = NEAR_RANGE_M + 2.0 * (travel_m + fastest * half_rot_s);
        self.margin_rad =
            turn_rad + ((travel_m + fastest * half_rot_s) / near_m).min(1.0).asin() + 1e-6;
        let reach = radar.max_range_m() + travel_m + 1.0;
        let o = [mid.x, mid.y];
        let w = &model.world;
        let rx = &model.receiver;
        let spec = &model.spec;

        // 1. Outlines into the polar transmission buffer.
        self.crossings.clear();
        let mover_pose: Vec<([f64; 2], f64)> = w.movers.iter().map(|m| m.pose_at(mid_t)).collect();
        let world_shape = |shape: Shape, mover: u32| -> Shape {
            let Some(&(c, h)) = mover_pose.get(mover as usize) else {
                return shape;
            };
            match shape {
                Shape::Segment { a, b } => Shape::Segment {
                    a: Mover::to_world(c, h, a),
                    b: Mover::to_world(c, h, b),
                },
                Shape::Disk { c: d, r } => Shape::Disk {
                    c: Mover::to_world(c, h, d),
                    r,
                },
            }
        };
        self.mirrors.clear();
        if spec.occlusion || spec.multipath {
            self.found.clear();
            let found = &mut self.found;
            w.outline_grid
                .for_each_near(o, reach + w.outline_reach_m, |i| found.push(i));
            let statics = self
                .found
                .iter()
                .filter_map(|&i| w.static_outlines.get(i).copied());
            let ids: Vec<u32> = statics.chain(w.moving_outlines.iter().copied()).collect();
            for id in ids {
                let Some(outline) = w.outlines.get(id as usize) else {
                    continue;
                };
                let shape = world_shape(outline.shape, outline.mover);
                if spec.multipath && outline.mirror {
                    if let Shape::Segment { a, b } = shape {
                        let (c, half) = shape.centre_and_reach();
                        if (c[0] - o[0]).hypot(c[1] - o[1]) - half <= spec.ghost_range_m {
                            self.mirrors.push((a, b));
                        }
                    }
                }
                if spec.occlusion {
                    rasterise(&mut self.crossings, o, shape, outline.tau, id, reach);
                }
            }
        }
        self.crossings
            .sort_unstable_by(|a, b| a.cell.cmp(&b.cell).then(a.range.total_cmp(&b.range)));
        self.cell_starts.clear();
        self.cell_starts.resize(OCCLUSION_CELLS + 1, 0);
        for c in &self.crossings {
            if let Some(s) = self.cell_starts.get_mut(c.cell as usize + 1) {
                *s += 1;
            }
        }
        for i in 1..self.cell_starts.len() {
            self.cell_starts[i] += self.cell_starts[i - 1];
        }

        // 2. Candidates.
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(ROTATION_STREAM_BASE | rotation);
        let mut bits = Bits::default();
        self.near.clear();
        let mut all: Vec<Candidate> = Vec::new();
        self.sources.clear();
        self.found.clear();
        let found = &mut self.found;
        w.scatterer_grid.for_each_near(o, reach, |i| found.push(i));
        self.found.sort_unstable();
        let statics = self
            .found
            .iter()
            .filter_map(|&i| w.static_scatterers.get(i).copied());
        let ids: Vec<u32> = statics.chain(w.moving_scatterers.iter().copied()).collect();
        let max_gain = rx.signal_per_m2.iter().copied().fold(0.0f32, f32::max);
        for id in ids {
            let Some(s) = w.scatterers.get(id as usize) else {
                continue;
            };
            let (pos, vel, normal) = match mover_pose.get(s.mover as usize) {
                Some(&(c, h)) => {
                    let m = &w.movers[s.mover as usize];
                    let (sh, ch) = h.sin_cos();
                    let nx = f64::from(s.normal[0]);
                    let ny = f64::from(s.normal[1]);
                    (
                        Mover::to_world(c, h, s.pos),
                        [m.speed_mps * ch, m.speed_mps * sh],
                        [ch * nx - sh * ny, sh * nx + ch * ny],
                    )
                }
                None => (
                    s.pos,
                    [0.0, 0.0],
                    [f64::from(s.normal[0]), f64::from(s.normal[1])],
                ),
            };
            let dx = pos[0] - o[0];
            let dy = pos[1] - o[1];
            let r = dx.hypot(dy);
            if r > reach || r < 1e-3 {
                continue;
            }
            let mut sigma = f64::from(s.diffuse_m2);
            if normal != [0.0, 0.0] {
                let cos_i = ((normal[0] * dx + normal[1] * dy) / r).abs().min(1.0);
                sigma *= ROUGH_FLOOR + (1.0 - ROUGH_FLOOR) * cos_i * cos_i;
                // The specular lobe is below 1e-10 of its peak beyond 5 widths.
                if s.specular_m2 > 0.0 && cos_i > SPECULAR_COS_LIMIT {
                    let inc = cos_i.acos();
                    sigma += f64::from(s.specular_m2) * (-(inc / SPECULAR_LOBE_RAD).powi(2)).exp();
                }
            }
            sigma *= f64::from(model.elevation.gain(s.drop_m, r));
            let world_angle = dy.atan2(dx);
            let vis = if spec.occlusion {
                self.transmission(cell_of(world_angle), r, s.outline)
            } else {
                1.0
            };
            let (draw, per_look) = if !spec.speckle {
                (1.0, 0)
            } else {
                match s.swerling {
                    Swerling::Zero => (1.0, 0),
                    Swerling::One => (rx.exp_quantiles[bits.take(&mut rng, 12)], 0),
                    Swerling::Three => (rx.chi4_quantiles[bits.take(&mut rng, 12)], 0),
                    Swerling::Two => (1.0, 2),
                    Swerling::Four => (1.0, 4),
                }
            };
            let mean = sigma as f32 * vis;
            let power = mean * draw;
            // The largest this can ever deposit (speckle tables top out near 9x the mean).
            if power * max_gain * 9.0 < NEGLIGIBLE_POWER {
                continue;
            }
            if spec.multipath
                && f64::from(s.diffuse_m2) >= spec.ghost_min_rcs_m2
                && r <= spec.ghost_range_m
                && self.sources.len() < MAX_GHOSTS
            {
                self.sources.push((all.len(), vis));
            }
            all.push(Candidate {
                bearing_mid: wrap_angle(mid.theta - world_angle),
                pos,
                vel,
                power,
                per_look,
            });
        }

        // 3. Ghosts.
        let mut ghosts = 0;
        let r2 = spec.ghost_reflectance * spec.ghost_reflectance;
        'sources: for &(ci, _) in &self.sources {
            let src = all[ci];
            for &(a, b) in &self.mirrors {
                if ghosts >= MAX_GHOSTS {
                    break 'sources;
                }
                let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
                let len2 = ex * ex + ey * ey;
                if len2 < 1e-6 {
                    continue;
                }
                let side = |p: [f64; 2]| ex * (p[1] - a[1]) - ey * (p[0] - a[0]);
                let (so, ss) = (side(o), side(src.pos));
                if so * ss <= 0.0 || ss.abs() < 1e-6 {
                    continue;
                }
                // Mirror image of the source.
                let t = ((src.pos[0] - a[0]) * ex + (src.pos[1] - a[1]) * ey) / len2;
                let foot = [a[0] + t * ex, a[1] + t * ey];
                let img = [2.0 * foot[0] - src.pos[0], 2.0 * foot[1] - src.pos[1]];
                let phi_g = (img[1] - o[1]).atan2(img[0] - o[0]);
                if ray_segment(o, phi_g, a, b).is_none() {
                    continue;
                }
                let rg = (img[0] - o[0]).hypot(img[1] - o[1]);
                if rg > reach {
                    continue;
                }
                all.push(Candidate {
                    bearing_mid: wrap_angle(mid.theta - phi_g),
                    pos: img,
                    vel: [0.0, 0.0],
                    power: src.power * r2 as f32,
                    per_look: src.per_look,
                });
                ghosts += 1;
            }
        }
        self.ghosts = ghosts;

        // 4. Tiers by how far off axis each candidate still matters.
        let main_tan = (1.5 * spec.beam_fwhm_deg.to_radians()).tan();
        let mid_tan = (5.0 * spec.beam_fwhm_deg.to_radians()).tan();
        let tier_tans = [main_tan, mid_tan, rx.pattern_max_tan];
        if self.tiers.len() != tier_tans.len() {
            self.tiers = tier_tans.iter().map(|_| Tier::default()).collect();
        }
        for (tier, &t) in self.tiers.iter_mut().zip(&tier_tans) {
            tier.list.clear();
            tier.half_tan = t;
            tier.half_rad = t.atan();
        }
        for c in all {
            let r = (c.pos[0] - o[0]).hypot(c.pos[1] - o[1]);
            if r < near_m {
                self.near.push(c);
                continue;
            }
            let fb = ((r - rx.first_bin_m) / rx.bin_m).max(0.0) as usize;
            let gain = rx.signal_per_m2.get(fb).copied().unwrap_or(0.0);
            let reach_tan = rx.pattern_reach_tan(c.power * gain * 9.0);
            let k = tier_tans
                .iter()
                .position(|&t| reach_tan <= t)
                .unwrap_or(tier_tans.len() - 1);
            self.tiers[k].list.push(c);
        }
        for tier in &mut self.tiers {
            tier.list
                .sort_by(|a, b| a.bearing_mid.total_cmp(&b.bearing_mid));
        }
        self.rotation = Some(rotation);
        Ok(())
    }

    /// Two-way transmission to range `r` in `cell` through every outline but `own`.
    fn transmission(&self, cell: usize, r: f64, own: u32) -> f32 {
        let (Some(&lo), Some(&hi)) = (self.cell_starts.get(cell), self.cell_starts.get(cell + 1))
        else {
            return 1.0;
        };
        let mut t = 1.0f32;
        for c in self
            .crossings
            .get(lo as usize..hi as usize)
            .unwrap_or_default()
        {
            if f64::from(c.range) >= r - SELF_MARGIN_M {
                break;
            }
            if c.outline != own {
                t *= c.tau;
            }
        }
        t * t
    }

    /// Ghosts formed in the current rotation.
    pub fn ghosts(&self) -> usize {
        self.ghosts
    }
}

/// Rasterises one outline into the crossings of the polar buffer about `o`.
fn rasterise(out: &mut Vec<Crossing>, o: [f64; 2], shape: Shape, tau: f32, id: u32, reach: f64) {
    match shape {
        Shape::Segment { a, b } => {
            let aa = (a[1] - o[1]).atan2(a[0] - o[0]);
            let ab = (b[1] - o[1]).atan2(b[0] - o[0]);
            let span = wrap_angle(ab - aa);
            let start = if span >= 0.0 { aa } else { ab };
            let span = span.abs();
            let c0 = cell_of(start);
            let cells = (span / std::f64::consts::TAU * OCCLUSION_CELLS as f64).ceil() as usize + 1;
            for k in 0..cells.min(OCCLUSION_CELLS) {
                let cell = (c0 + k) % OCCLUSION_CELLS;
                if let Some(range) = ray_segment(o, cell_angle(cell), a, b) {
                    if range <= reach {
                        out.push(Crossing {
                            cell: cell as u32,
                            range: range as f32,
                            tau,
                            outline: id,
                        });
                    }
                }
            }
        }
        Shape::Disk { c, r } => {
            let d = (c[0] - o[0]).hypot(c[1] - o[1]);
            if d <= r || d - r > reach {
                return;
            }
            let centre = (c[1] - o[1]).atan2(c[0] - o[0]);
            let half = (r / d).asin();
            let c0 = cell_of(centre - half);
            let cells =
                (2.0 * half / std::f64::consts::TAU * OCCLUSION_CELLS as f64).ceil() as usize + 1;
            for k in 0..cells.min(OCCLUSION_CELLS) {
                let cell = (c0 + k) % OCCLUSION_CELLS;
                let delta = wrap_angle(cell_angle(cell) - centre);
                let s = d * delta.sin();
                if s.abs() >= r {
                    continue;
                }
                let range = d * delta.cos() - (r * r - s * s).sqrt();
                out.push(Crossing {
                    cell: cell as u32,
                    range: range.max(0.0) as f32,
                    tau,
                    outline: id,
                });
            }
        }
    }
}

/// Random bits drawn a few at a time from 64-bit words.
#[derive(Debug, Default)]
struct Bits {
    word: u64,
    left: u32,
}

impl Bits {
    #[inline]
    fn take(&mut self, rng: &mut ChaCha8Rng, n: u32) -> usize {
        if self.left < n {
            self.word = rng.next_u64();
            self.left = 64;
        }
        let v = (self.word & ((1u64 << n) - 1)) as usize;
        self.word >>= n;
        self.left -= n;
        v
    }
}

/// Visits the candidates (sorted by `bearing_mid` in (-pi, pi]) within `half` of
/// `bearing`, across the +/-pi seam.
fn for_each_in_window(
    candidates: &[Candidate],
    bearing: f64,
    half: f64,
    mut visit: impl FnMut(&Candidate),
) {
    let pi = std::f64::consts::PI;
    if half >= pi {
        candidates.iter().for_each(visit);
        return;
    }
    let lo = bearing - half;
    let hi = bearing + half;
    let mut range = |a: f64, b: f64| {
        let start = candidates.partition_point(|c| c.bearing_mid < a);
        let end = candidates.partition_point(|c| c.bearing_mid <= b);
        if let Some(slice) = candidates.get(start..end.max(start)) {
            slice.iter().for_each(&mut visit);
        }
    };
    range(lo.max(-pi), hi.min(pi));
    if lo < -pi {
        range(lo + 2.0 * pi, pi);
    }
    if hi > pi {
        range(-pi, hi - 2.0 * pi);
    }
}
