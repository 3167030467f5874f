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
//!    specular lobe) from where the radar is when its beam sweeps it (the rotation's
//!    motion samples at the azimuth of its bearing), its two-way transmission through
//!    every outline in front of it in its cell (its own outline excepted), and, for
//!    Swerling 1 and 3, its draw for the rotation; a scatterer whose mean return cannot
//!    reach [`NEGLIGIBLE_POWER`] is dropped here (so what is hidden costs nothing per
//!    azimuth);
//! 3. ghosts: each strong scatterer (`ghost_min_rcs_m2`) within `ghost_range_m` mirrored in
//!    each mirror outline (building fronts, walls) within that range, where the mirror
//!    point lies on the outline and both radar and source are on its front side, becomes a
//!    scatterer at the image position with `reflectance^2` of the source's power;
//! 4. the candidates are put into lists by how far off the beam's axis their sidelobes
//!    still matter (from their largest possible deposit and the antenna's envelope), by
//!    whether they move, and by range shell (the motion during the rotation moves the
//!    bearing of a candidate at range `r` by at most `turn + asin(shift / r)`); within a
//!    list they are grouped by bearing bucket with a counting sort. Candidates nearer than
//!    the first shell are tested on every azimuth.
//!
//! Per azimuth: the pose at the azimuth's own time; each candidate in its lists' buckets
//! within the window (the list's offset plus its shell's margin) gets its exact range and
//! offset from the beam's axis from that pose (movers at that time), its two-way antenna
//! gain, its speckle draw (Swerling 2 and 4) and the receiver's gain at its range (the
//! range read short by the radar's range-Doppler coupling times its closing speed), and is
//! deposited into the range line (split linearly between the two bins about it, which are
//! marked as touched); the touched bins are convolved with the range kernel (each deposit
//! only as far as its sidelobes matter, in loops of a few fixed lengths); a floor draw
//! (10 random bits, six to a 64-bit word) is added to every bin, and the sum is quantised
//! as the unit does, to its level and straight to the wire's value by table.

use protocol::BinWidth;
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

use radar_model::geometry::{wrap_angle, Pose2};

use super::objects::{Mover, Shape, Swerling, World, SPECULAR_LOBE_RAD};
use super::receiver::{Receiver, COPULA_REACH, DB_TABLE, FLOOR_QUANTILES, NEGLIGIBLE_POWER};
use crate::error::{SceneError, SimError};
use crate::radar::{azimuth_in_rotation, offset_ns, RadarParams};
use crate::scene::realism_spec::RealismSpec;
use crate::trajectory::{Trajectory, TrajectoryCursor};

/// Cells of the polar transmission buffer (0.088 degrees each).
pub const OCCLUSION_CELLS: usize = 4096;
/// Range shells of candidates: shell `k` starts at `2^k` times [`SHELL_START_SHIFTS`]
/// times the distance the motion can move a candidate in the rotation; candidates nearer
/// than shell 0 are tested on every azimuth.
const SHELLS: usize = 5;
/// Where shell 0 starts, in units of the distance the motion can move a candidate.
const SHELL_START_SHIFTS: f64 = 2.0;
/// The largest per-look speckle draw (the tables' top quantile, about 9 times the mean).
const SPECKLE_MAX: f32 = 9.0;
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
/// Independent stretches of a row the floor's recursions run in side by side (the
/// correlation restarts at their 7 joins, out of thousands of bins).
const FLOOR_LANES: usize = 8;

/// Smooths the standard normal draws `d` along the range with two first-order recursions
/// of coefficient `rho`, rescales them to unit variance and replaces each by the floor draw
/// at its normal probability (`floor_of_normal`, see `receiver`'s module docs). The row is
/// cut into [`FLOOR_LANES`] equal stretches whose recursions advance together (the last
/// few bins continue the last stretch), each started in its stationary distribution: the
/// recursions' latency is paid once for all of them.
fn correlate_floor(d: &mut [f32], rho: f32, floor_of_normal: &[f32]) {
    let n = d.len();
    let len = n / FLOOR_LANES;
    if len == 0 || floor_of_normal.is_empty() {
        return;
    }
    let c = (1.0 - rho * rho).sqrt();
    // Two stages of unit-variance input: the second's variance is (1 + rho^2) / (1 - rho^2).
    let second_sd = ((1.0 + rho * rho) / (1.0 - rho * rho)).sqrt();
    let mut s1: [f32; FLOOR_LANES] = std::array::from_fn(|k| d[k * len]);
    let mut s2 = s1.map(|v| v * second_sd);
    let (bulk, tail) = d.split_at_mut(len * FLOOR_LANES);
    for i in 0..len {
        for k in 0..FLOOR_LANES {
            let v = &mut bulk[k * len + i];
            s1[k] = rho * s1[k] + c * *v;
            s2[k] = rho * s2[k] + c * s1[k];
            *v = s2[k];
        }
    }
    let (mut t1, mut t2) = (s1[FLOOR_LANES - 1], s2[FLOOR_LANES - 1]);
    for v in tail.iter_mut() {
        t1 = rho * t1 + c * *v;
        t2 = rho * t2 + c * t1;
        *v = t2;
    }
    // To the floor's distribution: the nearest table entry, found by adding 2^23 (the sum's
    // low mantissa bits are the rounded index; the clamp keeps it in the table).
    let last = (floor_of_normal.len() - 1) as f32;
    let per = last / (2.0 * COPULA_REACH);
    let (a, b) = (per / second_sd, COPULA_REACH * per);
    for v in d.iter_mut() {
        let t = (*v * a + b).clamp(0.0, last) + 8_388_608.0;
        let index = (t.to_bits() & 0x007f_ffff) as usize;
        *v = floor_of_normal.get(index).copied().unwrap_or(1.0);
    }
}

/// Random bits of one floor draw (an index into the floor's quantile table).
const FLOOR_BITS: u32 = FLOOR_QUANTILES.trailing_zeros();
/// Floor draws taken from one 64-bit random word.
const FLOOR_DRAWS_PER_WORD: usize = (64 / FLOOR_BITS) as usize;
/// Poses sampled per rotation to bound the vehicle's motion during it.
const MOTION_SAMPLES: u64 = 8;
/// Integer powers are clamped here (the output clips far below it).
const CLAMP_POWER: f32 = 4.0e9;

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
    /// `(sin, cos)` of each occlusion cell's central direction.
    cell_dirs: Vec<(f64, f64)>,
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
            cell_dirs: (0..OCCLUSION_CELLS)
                .map(|c| cell_angle(c).sin_cos())
                .collect(),
        })
    }
}

#[derive(Debug, Clone, Copy, Default)]
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

/// The radar's position a fraction `f` (0 to 1) of the way through the rotation, linear
/// between the rotation's motion samples (`sampled`, [`MOTION_SAMPLES`] + 1 of them).
fn sweep_position(sampled: &[[f64; 2]; MOTION_SAMPLES as usize + 1], f: f64) -> [f64; 2] {
    let u = f.clamp(0.0, 1.0) * MOTION_SAMPLES as f64;
    let i = (u as usize).min(MOTION_SAMPLES as usize - 1);
    let w = u - i as f64;
    match (sampled.get(i), sampled.get(i + 1)) {
        (Some(a), Some(b)) => [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])],
        _ => sampled[0],
    }
}

/// `acos(c)^2` for `c` within [`SPECULAR_COS_LIMIT`] of one (angles under 10 degrees), by
/// its series in `x = 1 - c`: `acos(c) = sqrt(2 x) (1 + x / 12 + 3 x^2 / 160 + ...)`, good
/// to a relative 1e-7 there (the next term is `5 x^3 / 896`), without the arc cosine.
#[inline]
fn acos_squared_near_one(c: f64) -> f64 {
    let x = (1.0 - c).max(0.0);
    let k = 1.0 + x / 12.0 + 3.0 * x * x / 160.0;
    2.0 * x * k * k
}

/// A list of candidates of one strength (how far off the beam's axis they still matter),
/// one motion family (static or moving) and one range shell (how far the motion during
/// the rotation can move their bearing).
#[derive(Debug, Clone, Copy)]
struct Tier {
    /// Tangent of the largest offset from the beam's axis at which they still matter.
    half_tan: f64,
    /// Half-width of the bearing window an azimuth visits: the offset's angle plus the
    /// shell's margin for motion.
    half_rad: f64,
}

/// Bearing buckets of a list (0.35 degrees each).
const BEARING_BUCKETS: usize = 1024;

/// The bucket of a bearing in (-pi, pi].
fn bucket_of(bearing: f64) -> usize {
    let pi = std::f64::consts::PI;
    let u = (bearing + pi) / (2.0 * pi) * BEARING_BUCKETS as f64;
    (u.max(0.0) as usize).min(BEARING_BUCKETS - 1)
}

impl Tier {
    /// The buckets (inclusive) holding every bearing within `half_rad` of `bearing`: one
    /// span, or two when the window crosses the +/-pi seam.
    fn buckets(&self, bearing: f64) -> [(usize, usize); 2] {
        let pi = std::f64::consts::PI;
        let none = (1, 0);
        if self.half_rad >= pi {
            return [(0, BEARING_BUCKETS - 1), none];
        }
        let lo = bearing - self.half_rad;
        let hi = bearing + self.half_rad;
        if lo < -pi {
            [
                (0, bucket_of(hi)),
                (bucket_of(lo + 2.0 * pi), BEARING_BUCKETS - 1),
            ]
        } else if hi > pi {
            [
                (bucket_of(lo), BEARING_BUCKETS - 1),
                (0, bucket_of(hi - 2.0 * pi)),
            ]
        } else {
            [(bucket_of(lo), bucket_of(hi)), none]
        }
    }
}

/// One azimuth's pose and beam, for depositing candidates into its range line.
struct Deposit<'a> {
    rx: &'a Receiver,
    /// Seconds from the rotation's middle time (movers).
    dt: f64,
    x: f64,
    y: f64,
    /// The beam's world direction.
    cphi: f64,
    sphi: f64,
    /// The radar's range-Doppler coupling, seconds.
    coupling_s: f64,
    /// The coupling times the radar's world velocity, metres.
    ux: f64,
    uy: f64,
    inv_bin: f64,
    max_fb: f64,
}

impl Deposit<'_> {
    /// Deposits `c` into `line` if it lies within `max_tan` of the beam's axis and inside
    /// the range line; returns 1 if it did.
    #[inline(always)]
    fn deposit(
        &self,
        c: &Candidate,
        max_tan: f64,
        line: &mut Line<'_>,
        bits: &mut Bits,
        rng: &mut ChaCha8Rng,
    ) -> usize {
        let rx = self.rx;
        let px = c.pos[0] + c.vel[0] * self.dt - self.x;
        let py = c.pos[1] + c.vel[1] * self.dt - self.y;
        let along = px * self.cphi + py * self.sphi;
        let cross = (py * self.cphi - px * self.sphi).abs();
        // Behind the radar, or `cross / along >= max_tan`.
        if along <= 0.0 || cross >= max_tan * along {
            return 0;
        }
        let g = rx.pattern_at(cross / along);
        let r = (px * px + py * py).sqrt();
        // Range-Doppler coupling: the return reads `coupling x closing speed` short, the
        // closing speed being the relative velocity along the line of sight.
        let shift = ((self.ux - self.coupling_s * c.vel[0]) * px
            + (self.uy - self.coupling_s * c.vel[1]) * py)
            / r;
        let fb = (r - shift - rx.first_bin_m) * self.inv_bin;
        if g <= 0.0 || !(0.0..self.max_fb).contains(&fb) {
            return 0;
        }
        let b0 = fb as usize;
        let w = (fb - b0 as f64) as f32;
        let speckle = match c.per_look {
            2 => rx.exp_quantiles[bits.take(rng, 12)],
            4 => rx.chi4_quantiles[bits.take(rng, 12)],
            _ => 1.0,
        };
        let Some(&gain) = rx.signal_per_m2.get(b0) else {
            return 0;
        };
        let p = c.power * g * gain * speckle;
        if let Some([lo, hi, ..]) = line.power.get_mut(b0..) {
            *lo += p * (1.0 - w);
            *hi += p * w;
        }
        for b in [b0, b0 + 1] {
            if let Some(word) = line.touched.get_mut(b / 64) {
                *word |= 1 << (b % 64);
            }
        }
        1
    }
}

/// The range line being deposited into, and which of its bins were touched (a bit per
/// bin).
struct Line<'a> {
    power: &'a mut [f32],
    touched: &'a mut [u64],
}

/// Kernel half-lengths (bins) spread by fixed-length loops; longer reaches by a general one.
const KERNEL_CLASSES: [usize; 5] = [4, 8, 16, 32, 64];

/// `dst += p src` over `N` bins.
#[inline(always)]
fn add_scaled<const N: usize>(dst: &mut [f32], src: &[f32], p: f32) {
    if let (Ok(dst), Ok(src)) = (<&mut [f32; N]>::try_from(dst), <&[f32; N]>::try_from(src)) {
        for (d, &k) in dst.iter_mut().zip(src) {
            *d += p * k;
        }
    }
}

/// Adds a deposit of `p` at bin `b`, convolved with the range kernel, to `signal`: at
/// least as far either side as the kernel's sidelobes keep it above
/// [`NEGLIGIBLE_POWER`] (rounded up to a [`KERNEL_CLASSES`] length, so most deposits take
/// a loop of fixed length), never beyond the kernel.
#[inline]
fn spread(signal: &mut [f32], rx: &Receiver, b: usize, p: f32) {
    let h = rx.kernel_half;
    let reach = rx.kernel_reach(p).min(h);
    let class = KERNEL_CLASSES.iter().copied().find(|&c| c >= reach);
    if let Some(c) = class.filter(|&c| c <= h && b >= c && b + c < signal.len()) {
        let (dst, ker) = (&mut signal[b - c..=b + c], &rx.kernel[h - c..=h + c]);
        match c {
            4 => add_scaled::<9>(dst, ker, p),
            8 => add_scaled::<17>(dst, ker, p),
            16 => add_scaled::<33>(dst, ker, p),
            32 => add_scaled::<65>(dst, ker, p),
            _ => add_scaled::<129>(dst, ker, p),
        }
        return;
    }
    let lo = b.saturating_sub(reach);
    let hi = (b + reach + 1).min(signal.len());
    let k0 = h + lo - b;
    let (Some(dst), Some(ker)) = (signal.get_mut(lo..hi), rx.kernel.get(k0..k0 + (hi - lo))) else {
        return;
    };
    for (d, &k) in dst.iter_mut().zip(ker) {
        *d += p * k;
    }
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
    /// Candidates so close that the vehicle's motion can move them anywhere: every
    /// azimuth tests them.
    always: Vec<Candidate>,
    /// The others' lists, by motion family (static, moving), range shell and strength.
    lists: Vec<Tier>,
    /// The others, by list and, within a list, by bearing bucket.
    sorted: Vec<Candidate>,
    /// `sorted[starts[l B + k]..starts[l B + k + 1]]`: list `l`'s bucket `k`.
    starts: Vec<u32>,
    /// Each candidate's list and bucket (`l B + k`; `u32::MAX` for `always`).
    keys: Vec<u32>,
    /// The rotation's candidates before sorting.
    all: Vec<Candidate>,
    /// Tests only: every candidate is tested on every azimuth, as far off the beam's axis
    /// as the antenna table reaches.
    test_every_candidate: bool,
    ghosts: usize,
    crossings: Vec<Crossing>,
    /// Scratch for sorting the crossings by cell.
    by_cell: Vec<Crossing>,
    cell_starts: Vec<u32>,
    found: Vec<usize>,
    line: Vec<f32>,
    signal: Vec<f32>,
    touched: Vec<u64>,
    power: Vec<u32>,
    /// The floor's random words of one azimuth.
    words: Vec<u64>,
    /// The floor's standard draws of one azimuth, a bin each.
    draws: Vec<f32>,
    mirrors: Vec<([f64; 2], [f64; 2], u32)>,
    sources: Vec<(usize, u32)>,
}

/// `floor(y)` for `0 <= y < 2^22` (`u32::MAX` from there up, and for NaN), in operations
/// the compiler can vectorise (a saturating `as` conversion it cannot): adding `2^23`
/// rounds to the nearest integer, which is one too many when it rounded up.
#[inline(always)]
fn floor_below_2_22(y: f32) -> u32 {
    const LIMIT: f32 = 4_194_304.0;
    const MAGIC: f32 = 8_388_608.0;
    let c = y.clamp(0.0, LIMIT);
    let nearest = (c + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits());
    let floor = nearest - u32::from(nearest as i32 as f32 > c);
    if y < LIMIT {
        floor
    } else {
        u32::MAX
    }
}

/// `floor(y)` for the powers [`floor_below_2_22`] leaves (non-negative; clamped far above
/// the output's clip).
#[inline(never)]
fn floor_large(y: f32) -> u32 {
    y.min(CLAMP_POWER) as u32
}

/// `y.atan2(x)` to within 1e-9 rad, in a fifth of libm's instructions (one per scatterer
/// per rotation): the argument is folded to `[0, tan(pi / 12)]` and the series taken to
/// its 13th power. `(0, 0)` gives 0.
#[inline]
fn atan2_fast(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_6, PI};
    const TAN_PI_12: f64 = 0.267_949_192_431_122_7;
    const SQRT_3: f64 = 1.732_050_807_568_877_2;
    let (ax, ay) = (x.abs(), y.abs());
    let (num, den, swap) = if ay > ax {
        (ax, ay, true)
    } else {
        (ay, ax, false)
    };
    if den == 0.0 || !den.is_finite() || !num.is_finite() {
        return y.atan2(x);
    }
    let t = num / den;
    let (t, base) = if t > TAN_PI_12 {
        ((t * SQRT_3 - 1.0) / (t + SQRT_3), FRAC_PI_6)
    } else {
        (t, 0.0)
    };
    let t2 = t * t;
    let series = t
        * (1.0
            + t2 * (-1.0 / 3.0
                + t2 * (1.0 / 5.0
                    + t2 * (-1.0 / 7.0
                        + t2 * (1.0 / 9.0 + t2 * (-1.0 / 11.0 + t2 * (1.0 / 13.0)))))));
    let mut a = base + series;
    if swap {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 {
        -a
    } else {
        a
    }
}

/// Where range shell `k` starts for candidates the motion can move by `shift_m`, metres.
fn shell_start_m(shift_m: f64, k: usize) -> f64 {
    (SHELL_START_SHIFTS * shift_m).max(0.5) * f64::from(1u32 << k.min(16))
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
    ray_segment_dir(o, phi.sin_cos(), a, b)
}

/// [`ray_segment`] along the direction `(sin, cos)`.
fn ray_segment_dir(o: [f64; 2], (s, c): (f64, f64), a: [f64; 2], b: [f64; 2]) -> Option<f64> {
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
    /// Renders azimuth `index` (`bins` bins) into `out_wire`: the unit's output levels as
    /// the wire's bins of `width`, little-endian (what `protocol::encode_fft_frame_from_db`
    /// would make of the levels in dB, which [`Self::levels_db`] gives).
    #[allow(clippy::too_many_arguments)]
    pub fn render(
        &mut self,
        model: &RealisticModel,
        trajectory: &Trajectory,
        cursor: &mut TrajectoryCursor,
        radar: &RadarParams,
        seed: u64,
        index: u64,
        width: BinWidth,
        bins: usize,
        out_wire: &mut Vec<u8>,
    ) -> Result<(Pose2, AzimuthCounts), SimError> {
        let n = u64::from(radar.azimuths.max(1));
        let rotation = index / n;
        if self.rotation != Some(rotation) {
            self.prepare_rotation(model, trajectory, cursor, radar, seed, rotation)?;
        }
        let offset_ns = offset_ns(radar, index);
        let pose = trajectory.pose_with(cursor, offset_ns)?;
        let dt = offset_ns as f64 * 1e-9 - self.mid_offset_s;
        let bearing =
            wrap_angle(radar.angle_of_encoder(radar.encoder_of(azimuth_in_rotation(radar, index))));
        let phi = pose.theta - bearing;
        let (sphi, cphi) = phi.sin_cos();
        // The radar moves forward at the scene's speed at this time.
        let coupling_s = radar.doppler_range_coupling_s;
        let forward = coupling_s * trajectory.controls_at(offset_ns).0;
        let (sth, cth) = pose.theta.sin_cos();
        let rx = &model.receiver;
        // The line, the signal and the touched-bin marks are left zeroed by the azimuth
        // before: only a new size clears them.
        if self.line.len() != bins || self.signal.len() != bins {
            self.line = vec![0.0; bins];
            self.signal = vec![0.0; bins];
            self.touched = vec![0; bins.div_ceil(64) + 1];
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(index);
        let mut bits = Bits::default();
        let at = Deposit {
            rx,
            dt,
            x: pose.x,
            y: pose.y,
            cphi,
            sphi,
            coupling_s,
            ux: forward * cth,
            uy: forward * sth,
            inv_bin: 1.0 / rx.bin_m,
            max_fb: (bins as f64 - 1.0).max(0.0),
        };
        let deposited = self.deposit_candidates(&at, bearing, &mut bits, &mut rng);
        self.spread_line(rx);
        self.floor_and_quantise(rx, &mut rng, width, bins, out_wire)?;
        Ok((
            pose,
            AzimuthCounts {
                deposited,
                ghosts: self.ghosts,
            },
        ))
    }

    /// Deposits the candidates near the beam into the range line; returns how many.
    #[inline(never)]
    fn deposit_candidates(
        &mut self,
        at: &Deposit<'_>,
        bearing: f64,
        bits: &mut Bits,
        rng: &mut ChaCha8Rng,
    ) -> usize {
        let rx = at.rx;
        let mut deposited = 0usize;
        let mut line = Line {
            power: &mut self.line,
            touched: &mut self.touched,
        };
        for c in &self.always {
            deposited += at.deposit(c, rx.pattern_max_tan, &mut line, bits, rng);
        }
        for (l, list) in self.lists.iter().enumerate() {
            let base = l * BEARING_BUCKETS;
            for (first, last) in list.buckets(bearing) {
                if first > last {
                    continue;
                }
                let (Some(&a), Some(&b)) = (
                    self.starts.get(base + first),
                    self.starts.get(base + last + 1),
                ) else {
                    continue;
                };
                for c in self.sorted.get(a as usize..b as usize).unwrap_or_default() {
                    deposited += at.deposit(c, list.half_tan, &mut line, bits, rng);
                }
            }
        }
        deposited
    }

    /// Convolves the touched bins of the range line with the range kernel into the signal
    /// (the line zeroed as it is read).
    #[inline(never)]
    fn spread_line(&mut self, rx: &Receiver) {
        // Range kernel: each deposit spread as far as its sidelobes matter, in bin order;
        // the line is zeroed as it is read.
        for (w, word) in self.touched.iter_mut().enumerate() {
            let mut marks = std::mem::take(word);
            while marks != 0 {
                let b = w * 64 + marks.trailing_zeros() as usize;
                marks &= marks - 1;
                let Some(cell) = self.line.get_mut(b) else {
                    continue;
                };
                let p = std::mem::take(cell);
                if p > NEGLIGIBLE_POWER * 0.01 {
                    spread(&mut self.signal, rx, b, p);
                }
            }
        }
    }

    /// Adds the floor to the signal (zeroed as it is read) and quantises the sum.
    #[inline(never)]
    fn floor_and_quantise(
        &mut self,
        rx: &Receiver,
        rng: &mut ChaCha8Rng,
        width: BinWidth,
        bins: usize,
        out_wire: &mut Vec<u8>,
    ) -> Result<(), SimError> {
        // Floor and quantisation: the unit's integer power `k = floor(floor draw + signal)`
        // per bin (the signal zeroed as it is read), then its level and wire value by
        // table. The floor's random words are drawn in one call (the same words, in the
        // same order, as one `next_u64` a word).
        if self.power.len() != bins {
            self.power = vec![0; bins];
        }
        let quantiles: &[f32; FLOOR_QUANTILES] = rx
            .floor_quantiles
            .as_slice()
            .try_into()
            .map_err(|_| SimError::Model("floor quantile table of the wrong size".into()))?;
        let n = bins.min(rx.floor_mean.len());
        self.words.resize(n.div_ceil(FLOOR_DRAWS_PER_WORD), 0);
        rng.fill(self.words.as_mut_slice());
        // The draws first (a table lookup a bin), then `k` in a loop the compiler can
        // vectorise.
        let mask = (FLOOR_QUANTILES - 1) as u64;
        let correlated = rx.floor_rho > 0.0;
        // Correlated: the words index standard normal draws, smoothed and mapped below.
        let table: &[f32; FLOOR_QUANTILES] = if correlated {
            rx.normal_quantiles
                .as_slice()
                .try_into()
                .map_err(|_| SimError::Model("normal quantile table of the wrong size".into()))?
        } else {
            quantiles
        };
        self.draws.resize(n, 0.0);
        let mut d6 = self.draws.chunks_exact_mut(FLOOR_DRAWS_PER_WORD);
        for (d, &word) in (&mut d6).zip(&self.words) {
            for (j, d) in d.iter_mut().enumerate() {
                *d = table[((word >> (j as u32 * FLOOR_BITS)) & mask) as usize];
            }
        }
        if let Some(&word) = self.words.last() {
            for (j, d) in d6.into_remainder().iter_mut().enumerate() {
                *d = table[((word >> (j as u32 * FLOOR_BITS)) & mask) as usize];
            }
        }
        if correlated {
            correlate_floor(&mut self.draws, rx.floor_rho, &rx.floor_of_normal);
        }
        for ((k, s), (&m, d)) in self.power[..n]
            .iter_mut()
            .zip(&mut self.signal[..n])
            .zip(rx.floor_mean[..n].iter().zip(&mut self.draws))
        {
            let y = m * *d + std::mem::take(s);
            *d = y;
            *k = floor_below_2_22(y);
        }
        self.signal[n..].fill(0.0);
        self.power[n..].fill(0);
        match width {
            BinWidth::Eight => {
                let wire_table: &[u8; DB_TABLE] = rx
                    .wire8_of_power
                    .as_slice()
                    .try_into()
                    .map_err(|_| SimError::Model("output table of the wrong size".into()))?;
                out_wire.resize(bins, 0);
                for ((k, w), &y) in self.power.iter_mut().zip(out_wire).zip(&self.draws) {
                    let i = *k as usize;
                    *w = if i < DB_TABLE {
                        wire_table[i]
                    } else {
                        *k = floor_large(y);
                        // An 8-bit value.
                        rx.quantise(*k, false).1 as u8
                    };
                }
            }
            BinWidth::Sixteen => {
                let wire_table: &[u16; DB_TABLE] = rx
                    .wire16_of_power
                    .as_slice()
                    .try_into()
                    .map_err(|_| SimError::Model("output table of the wrong size".into()))?;
                out_wire.resize(2 * bins, 0);
                for ((k, w), &y) in self
                    .power
                    .iter_mut()
                    .zip(out_wire.chunks_exact_mut(2))
                    .zip(&self.draws)
                {
                    let i = *k as usize;
                    let wire = if i < DB_TABLE {
                        wire_table[i]
                    } else {
                        *k = floor_large(y);
                        rx.quantise(*k, true).1
                    };
                    w.copy_from_slice(&wire.to_le_bytes());
                }
            }
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
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
        let mid_ns = offset_ns(radar, first + n / 2);
        let mid = trajectory.pose_with(cursor, mid_ns)?;
        let mid_t = mid_ns as f64 * 1e-9;
        self.mid_offset_s = mid_t;
        let mut travel_m: f64 = 0.0;
        let mut turn_rad: f64 = 0.0;
        let mut speed_mps: f64 = 0.0;
        // The radar's position at each motion sample (azimuth `(n - 1) s / MOTION_SAMPLES`
        // of the rotation): where it is when its beam sweeps a scatterer, for the incidence.
        let mut sampled = [[0.0f64; 2]; MOTION_SAMPLES as usize + 1];
        for s in 0..=MOTION_SAMPLES {
            let k = first + n.saturating_sub(1) * s / MOTION_SAMPLES;
            let offset_ns = offset_ns(radar, k);
            let p = trajectory.pose_with(cursor, offset_ns)?;
            if let Some(slot) = sampled.get_mut(s as usize) {
                *slot = [p.x, p.y];
            }
            travel_m = travel_m.max((p.x - mid.x).hypot(p.y - mid.y));
            turn_rad = turn_rad.max(wrap_angle(p.theta - mid.theta).abs());
            speed_mps = speed_mps.max(trajectory.controls_at(offset_ns).0.abs());
        }
        // Movers move too: their candidates' bearings are bounded with the fastest one's
        // travel in half a rotation added.
        let half_rot_s = 0.5 / radar.rotation_hz().max(1e-3);
        let fastest = model
            .world
            .movers
            .iter()
            .map(|m| m.speed_mps.abs())
            .fold(0.0, f64::max);
        travel_m = travel_m * 1.25 + 0.05;
        turn_rad = turn_rad * 1.25 + 1e-3;
        let shift_m = [travel_m, travel_m + fastest * half_rot_s];
        // How far the range-Doppler coupling can move a return in range (the controls are
        // piecewise constant between the samples, near enough: padded as the travel is).
        let coupling_m = radar.doppler_range_coupling_s.abs() * 1.25;
        let range_shift_m = [
            shift_m[0] + coupling_m * speed_mps,
            shift_m[1] + coupling_m * (speed_mps + fastest),
        ];
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
                            self.mirrors.push((a, b, id));
                        }
                    }
                }
                if spec.occlusion {
                    rasterise(
                        &mut self.crossings,
                        &model.cell_dirs,
                        o,
                        shape,
                        outline.tau,
                        id,
                        reach,
                    );
                }
            }
        }
        // By cell (a counting sort), then by range within each cell.
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
        self.by_cell.clear();
        self.by_cell.resize(
            self.crossings.len(),
            Crossing {
                cell: 0,
                range: 0.0,
                tau: 1.0,
                outline: u32::MAX,
            },
        );
        for c in &self.crossings {
            if let Some(slot) = self.cell_starts.get_mut(c.cell as usize) {
                if let Some(dst) = self.by_cell.get_mut(*slot as usize) {
                    *dst = *c;
                }
                *slot += 1;
            }
        }
        self.cell_starts.rotate_right(1);
        if let Some(first) = self.cell_starts.first_mut() {
            *first = 0;
        }
        std::mem::swap(&mut self.crossings, &mut self.by_cell);
        for cell in self.cell_starts.windows(2) {
            if let Some(group) = self.crossings.get_mut(cell[0] as usize..cell[1] as usize) {
                group.sort_unstable_by(|a, b| a.range.total_cmp(&b.range));
            }
        }

        // 2. Candidates.
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(ROTATION_STREAM_BASE | rotation);
        let mut bits = Bits::default();
        let mut all = std::mem::take(&mut self.all);
        all.clear();
        self.sources.clear();
        self.found.clear();
        let found = &mut self.found;
        w.scatterer_grid.for_each_near(o, reach, |i| found.push(i));
        let statics = self
            .found
            .iter()
            .filter_map(|&i| w.static_scatterers.get(i).copied());
        let ids: Vec<u32> = statics.chain(w.moving_scatterers.iter().copied()).collect();
        // Each mover's centre, heading's sine and cosine, and speed.
        let mover_frame: Vec<([f64; 2], f64, f64, f64)> = mover_pose
            .iter()
            .zip(&w.movers)
            .map(|(&(c, h), m)| {
                let (sh, ch) = h.sin_cos();
                (c, sh, ch, m.speed_mps)
            })
            .collect();
        let max_gain = rx.signal_per_m2.iter().copied().fold(0.0f32, f32::max);
        for id in ids {
            let Some(s) = w.scatterers.get(id as usize) else {
                continue;
            };
            let (pos, vel, normal) = match mover_frame.get(s.mover as usize) {
                Some(&(c, sh, ch, speed)) => {
                    let nx = f64::from(s.normal[0]);
                    let ny = f64::from(s.normal[1]);
                    let [px, py] = s.pos;
                    (
                        [c[0] + ch * px - sh * py, c[1] + sh * px + ch * py],
                        [speed * ch, speed * sh],
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
            let r = (dx * dx + dy * dy).sqrt();
            if r > reach || r < 1e-3 {
                continue;
            }
            let world_angle = atan2_fast(dy, dx);
            // Hidden: what the outlines in front let through cannot lift even the largest
            // cross section this scatterer can show (incidence, elevation and a steady
            // draw all at most 1) to a deposit that matters, so it is dropped exactly
            // where the test below would drop it; the walk along the outlines stops as
            // soon as that is certain. Scatterers drawn once a rotation (Swerling 1 and 3)
            // still take their draw, so every later draw is the one it was.
            let vis = if spec.occlusion {
                let steady =
                    !spec.speckle || !matches!(s.swerling, Swerling::One | Swerling::Three);
                let largest = 2.0 * (s.diffuse_m2 + s.specular_m2) * max_gain * 9.0;
                let floor = if steady && largest > 0.0 {
                    NEGLIGIBLE_POWER / largest
                } else {
                    0.0
                };
                match self.transmission_above(cell_of(world_angle), r, s.outline, floor) {
                    Some(t) => t,
                    None if steady => continue,
                    None => 0.0,
                }
            } else {
                1.0
            };
            let bearing_mid = wrap_angle(mid.theta - world_angle);
            let mut sigma = f64::from(s.diffuse_m2);
            if normal != [0.0, 0.0] {
                // The incidence from where the radar is when its beam sweeps the scatterer
                // (the azimuth of its bearing from the middle pose), not from the middle
                // pose: a front's specular flash lights square to the radar, a quarter
                // rotation (0.6 m at 10 m/s) from the middle for the azimuths abeam.
                let f = bearing_mid.rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU;
                let [sx, sy] = sweep_position(&sampled, f);
                let t_off = (f - 0.5) * 2.0 * half_rot_s;
                let ex = pos[0] + vel[0] * t_off - sx;
                let ey = pos[1] + vel[1] * t_off - sy;
                let re = (ex * ex + ey * ey).sqrt().max(1e-9);
                let cos_i = ((normal[0] * ex + normal[1] * ey) / re).abs().min(1.0);
                sigma *= ROUGH_FLOOR + (1.0 - ROUGH_FLOOR) * cos_i * cos_i;
                // The specular lobe is below 1e-10 of its peak beyond 5 widths.
                if s.specular_m2 > 0.0 && cos_i > SPECULAR_COS_LIMIT {
                    let inc2 = acos_squared_near_one(cos_i);
                    sigma += f64::from(s.specular_m2)
                        * (-inc2 / (SPECULAR_LOBE_RAD * SPECULAR_LOBE_RAD)).exp();
                }
            }
            sigma *= f64::from(model.elevation.gain(s.drop_m, r));
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
                self.sources.push((all.len(), s.outline));
            }
            all.push(Candidate {
                bearing_mid,
                pos,
                vel,
                power,
                per_look,
            });
        }

        // 3. Ghosts.
        let mut ghosts = 0;
        let r2 = spec.ghost_reflectance * spec.ghost_reflectance;
        'sources: for &(ci, source_outline) in &self.sources {
            let src = all[ci];
            for &(a, b, mirror_id) in &self.mirrors {
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
                let phi_g = atan2_fast(img[1] - o[1], img[0] - o[0]);
                let Some(rm) = ray_segment(o, phi_g, a, b) else {
                    continue;
                };
                let rg = (img[0] - o[0]).hypot(img[1] - o[1]);
                if rg > reach {
                    continue;
                }
                // The mirror point must be in view: the two-way transmission of the outlines
                // in front of it along the ghost's ray, but for the source's own (the leg
                // from the mirror to the source is not traced).
                let mirror_vis = if spec.occlusion {
                    self.transmission_but(cell_of(phi_g), rm, [mirror_id, source_outline])
                } else {
                    1.0
                };
                let power = src.power * r2 as f32 * mirror_vis;
                if power * max_gain * 9.0 < NEGLIGIBLE_POWER {
                    continue;
                }
                all.push(Candidate {
                    bearing_mid: wrap_angle(mid.theta - phi_g),
                    pos: img,
                    vel: [0.0, 0.0],
                    power,
                    per_look: src.per_look,
                });
                ghosts += 1;
            }
        }
        self.ghosts = ghosts;

        // 4. Lists by how far off the beam's axis each candidate still matters (its largest
        // deposit: its power, the receiver's largest gain within the distance the motion
        // and the range-Doppler coupling can move it in range, the largest speckle draw), by whether it moves, and by
        // range shell: the bearing of a candidate at range `r` from the middle pose moves
        // by at most `turn + asin(shift / r)` during the rotation. Within a list the
        // candidates are grouped by bearing bucket (a counting sort, no comparisons).
        let main_tan = (1.5 * spec.beam_fwhm_deg.to_radians()).tan();
        let mid_tan = (5.0 * spec.beam_fwhm_deg.to_radians()).tan();
        let tier_tans = [main_tan, mid_tan, rx.pattern_max_tan];
        let lists = tier_tans.len() * shift_m.len() * SHELLS;
        self.lists.clear();
        for &shift in &shift_m {
            for shell in 0..SHELLS {
                let r_lo = shell_start_m(shift, shell);
                let margin = turn_rad + (shift / r_lo).min(1.0).asin() + 1e-6;
                for &t in &tier_tans {
                    self.lists.push(Tier {
                        half_tan: t,
                        half_rad: t.atan() + margin,
                    });
                }
            }
        }
        // A deposit of `power` (integer units on the beam's axis) stays negligible beyond
        // a tier's tangent when `power < threshold`.
        let thresholds = tier_tans.map(|t| rx.pattern_threshold(t));
        let envelopes = range_shift_m.map(|shift| rx.gain_envelope(shift));
        self.always.clear();
        self.keys.clear();
        self.starts.clear();
        self.starts.resize(lists * BEARING_BUCKETS + 1, 0);
        for c in &all {
            let family = usize::from(c.vel != [0.0, 0.0]);
            let shift = shift_m[family];
            let r = ((c.pos[0] - o[0]).powi(2) + (c.pos[1] - o[1]).powi(2)).sqrt();
            let shell = (0..SHELLS).rev().find(|&k| r >= shell_start_m(shift, k));
            let Some(shell) = shell.filter(|_| !self.test_every_candidate) else {
                self.always.push(*c);
                self.keys.push(u32::MAX);
                continue;
            };
            let fb = ((r - rx.first_bin_m) / rx.bin_m).max(0.0) as usize;
            let gain = envelopes[family]
                .get(fb)
                .or(envelopes[family].last())
                .copied()
                .unwrap_or(0.0);
            let speckle_max = if c.per_look == 0 { 1.0 } else { SPECKLE_MAX };
            let largest = c.power * gain * speckle_max;
            let strength = thresholds
                .iter()
                .position(|&th| largest < th)
                .unwrap_or(tier_tans.len() - 1);
            let list = (family * SHELLS + shell) * tier_tans.len() + strength;
            let key = list * BEARING_BUCKETS + bucket_of(c.bearing_mid);
            self.keys.push(key as u32);
            if let Some(count) = self.starts.get_mut(key + 1) {
                *count += 1;
            }
        }
        for i in 1..self.starts.len() {
            self.starts[i] += self.starts[i - 1];
        }
        self.sorted.clear();
        self.sorted.resize(
            self.starts.last().map_or(0, |&n| n as usize),
            Candidate::default(),
        );
        // Scatter: `starts[key]` walks through its key's slots, ending at the next key's
        // start; shifting by one then restores the starts.
        for (c, &key) in all.iter().zip(&self.keys) {
            if let Some(slot) = self.starts.get_mut(key as usize) {
                if let Some(dst) = self.sorted.get_mut(*slot as usize) {
                    *dst = *c;
                }
                *slot += 1;
            }
        }
        self.starts.rotate_right(1);
        if let Some(first) = self.starts.first_mut() {
            *first = 0;
        }
        self.all = all;
        self.rotation = Some(rotation);
        Ok(())
    }

    /// Two-way transmission to range `r` in `cell` through every outline but `own`, or
    /// `None` as soon as it is certain to fall below `floor` (0: never). When it is `Some`,
    /// it is exactly [`Self::transmission_but`]'s figure.
    fn transmission_above(&self, cell: usize, r: f64, own: u32, floor: f32) -> Option<f32> {
        let (Some(&lo), Some(&hi)) = (self.cell_starts.get(cell), self.cell_starts.get(cell + 1))
        else {
            return Some(1.0);
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
                if t * t < floor {
                    return None;
                }
            }
        }
        Some(t * t)
    }

    /// [`Self::transmission`] leaving out two outlines (a ghost's mirror and source).
    fn transmission_but(&self, cell: usize, r: f64, own: [u32; 2]) -> f32 {
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
            if c.outline != own[0] && c.outline != own[1] {
                t *= c.tau;
            }
        }
        t * t
    }

    /// Tests only: test every candidate on every azimuth (the reference the windowed
    /// lists are checked against).
    #[cfg(test)]
    pub(crate) fn test_every_candidate(&mut self) {
        self.test_every_candidate = true;
        self.rotation = None;
    }

    /// The last rendered azimuth's output levels (dB) into `out` (as many bins as both
    /// have).
    pub fn levels_db(&self, rx: &Receiver, out: &mut [f64]) {
        for (&k, out) in self.power.iter().zip(out) {
            *out = rx.quantise(k, false).0;
        }
    }

    /// Ghosts formed in the current rotation.
    pub fn ghosts(&self) -> usize {
        self.ghosts
    }
}

/// Rasterises one outline into the crossings of the polar buffer about `o` (`dirs`: each
/// cell's direction, `(sin, cos)`).
#[allow(clippy::too_many_arguments)]
fn rasterise(
    out: &mut Vec<Crossing>,
    dirs: &[(f64, f64)],
    o: [f64; 2],
    shape: Shape,
    tau: f32,
    id: u32,
    reach: f64,
) {
    match shape {
        Shape::Segment { a, b } => {
            let aa = atan2_fast(a[1] - o[1], a[0] - o[0]);
            let ab = atan2_fast(b[1] - o[1], b[0] - o[0]);
            let span = wrap_angle(ab - aa);
            let start = if span >= 0.0 { aa } else { ab };
            let span = span.abs();
            let c0 = cell_of(start);
            let cells = (span / std::f64::consts::TAU * OCCLUSION_CELLS as f64).ceil() as usize + 1;
            for k in 0..cells.min(OCCLUSION_CELLS) {
                let cell = (c0 + k) % OCCLUSION_CELLS;
                let Some(&dir) = dirs.get(cell) else {
                    continue;
                };
                if let Some(range) = ray_segment_dir(o, dir, a, b) {
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
            let d = ((c[0] - o[0]).powi(2) + (c[1] - o[1]).powi(2)).sqrt();
            if d <= r || d - r > reach {
                return;
            }
            let centre = atan2_fast(c[1] - o[1], c[0] - o[0]);
            let (s_c, c_c) = ((c[1] - o[1]) / d, (c[0] - o[0]) / d);
            let half = (r / d).asin();
            let c0 = cell_of(centre - half);
            let cells =
                (2.0 * half / std::f64::consts::TAU * OCCLUSION_CELLS as f64).ceil() as usize + 1;
            for k in 0..cells.min(OCCLUSION_CELLS) {
                let cell = (c0 + k) % OCCLUSION_CELLS;
                let Some(&(s_k, c_k)) = dirs.get(cell) else {
                    continue;
                };
                // sin and cos of the cell's direction less the centre's.
                let s = d * (s_k * c_c - c_k * s_c);
                if s.abs() >= r {
                    continue;
                }
                let range = d * (c_k * c_c + s_k * s_c) - (r * r - s * s).sqrt();
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_arc_cosines_square_near_one_agrees_with_libm() {
        let mut c = SPECULAR_COS_LIMIT;
        while c <= 1.0 {
            let exact = c.acos().powi(2);
            let got = acos_squared_near_one(c);
            assert!(
                (got - exact).abs() <= 1e-7 * exact + 1e-15,
                "{c}: {got} vs {exact}"
            );
            c += 1e-6;
        }
    }

    #[test]
    fn the_fast_arctangent_agrees_with_libm_to_a_nanoradian() {
        let mut worst: f64 = 0.0;
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for i in 0..200_000u32 {
            // Every direction, at ranges from millimetres to kilometres, and the axes.
            let a = f64::from(i) / 200_000.0 * std::f64::consts::TAU;
            let r = 10f64.powf(f64::from(rng.next_u32() % 7000) / 1000.0 - 3.0);
            let (y, x) = (r * a.sin(), r * a.cos());
            for (y, x) in [(y, x), (y, 0.0), (0.0, x), (x, x), (-x, x)] {
                let d = wrap_angle(atan2_fast(y, x) - y.atan2(x)).abs();
                worst = worst.max(d);
            }
        }
        assert!(worst < 1e-9, "worst {worst:e} rad");
        assert_eq!(atan2_fast(0.0, 0.0), 0.0);
    }

    #[test]
    fn the_vector_floor_is_the_floor() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for i in 0..1_000_000u32 {
            let y = match i % 4 {
                0 => (rng.next_u32() >> 8) as f32 / 64.0,
                1 => f32::from_bits(rng.next_u32() & 0x4aff_ffff),
                2 => (i / 4) as f32,
                _ => (i / 4) as f32 - f32::EPSILON * (i / 4) as f32,
            };
            let fast = floor_below_2_22(y);
            if y < 4_194_304.0 {
                assert_eq!(fast, y as u32, "{y}");
            } else {
                assert_eq!(fast, u32::MAX, "{y}");
            }
        }
        assert_eq!(floor_below_2_22(f32::NAN), u32::MAX);
        assert_eq!(floor_below_2_22(4_194_303.5), 4_194_303);
        assert_eq!(floor_below_2_22(0.999_999_94), 0);
    }
}
