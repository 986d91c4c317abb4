//! Procedural detail below the data's resolution (clipmap-data-synthesis §4: detail synthesizers
//! as sources of the image-source graph; geometry-image warping §4: band-limited noise octaves
//! from the first frequency the data cannot represent).
//!
//! - **The field.** Octave i is 3-D gradient noise of lattice spacing λᵢ = d₀·2⁻ⁱ (d₀: the row
//!   spacing of the finest store level with data at the point) evaluated at the point of the
//!   sphere in metres, so it has no seam anywhere: not at the antimeridian, a pole, a tile, shard
//!   or clipmap border. Each octave has its own rotation and offset of the lattice (nested
//!   lattices would otherwise all vanish on the same points) from the seed; the hash is of the
//!   integer lattice point, so the field never repeats (a 256-cell permutation table would, every
//!   2.56 m at 1 cm).
//! - **Amplitude.** Octave i has standard deviation a₀·2^(−H·i): H the Hurst exponent (the
//!   spectral slope β = 2H + 1 of a transect), a₀ from the data's own roughness at the point
//!   (the RMS residual of a plane fitted to each 3×3 data neighbourhood, at the four data texels
//!   around the point, bilinear between them so the amplitude is continuous), scaled by the
//!   ratio a self-similar field of the same noise shows between its next octave and that
//!   residual (`Detail::new` measures it once). Flat plains get none, mountains a lot.
//! - **Band.** A clipmap texel of ground size t carries octave i fully when λᵢ ≥ 4t, fades it in
//!   between 2t and 4t (the boundary octave: the mesh, which takes its heights from a coarser
//!   clipmap level, carries it partly, the per-pixel normals of the finer level fully), and
//!   leaves it out below 2t (it would alias). The split octave of geometry-image warping §4 comes
//!   from the clipmap itself: ring k's vertices read level k − 1, its fragments' normals the level
//!   whose texels match the pixel, so octaves the mesh cannot carry shade the pixels.
//! - **Colour.** A shade q = Σ wᵢ·aᵢ·nᵢ/λᵢ (each octave's relative height over its wavelength:
//!   a slope) drives a symmetric modulation 1 + c·tanh(q / 0.15) of the linear colour: bumps lighter,
//!   hollows darker, more so where the synthesized ground is steep; its mean is 1, so the
//!   colour's local mean stays what the data says.

use std::f64::consts::PI;

/// How detail is synthesized (the `detail` source of the graph; every key optional).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetailParams {
    /// Seeds the noise: the same seed makes the same planet.
    pub seed: u64,
    /// The Hurst exponent H of the octaves, 0.1 … 1 (a transect's power spectrum falls as
    /// f^−(2H+1)); default [`DEFAULT_HURST`]. `None`: the data's own at each point (from its
    /// roughness in two stored levels) — too noisy to drive the octaves: over ETOPO5's Alps it
    /// gives a spectrum of f^−2.17 twenty times too strong, where the data fall as f^−2.36
    /// (an exponent too low makes every finer octave too strong); the amplitude always comes
    /// from the data.
    pub hurst: Option<f64>,
    /// Scales the amplitude the data implies, 0 … 4.
    pub amplitude: f64,
    /// How much the colour follows the synthesized ground, 0 … 1.
    pub color: f64,
}

impl Default for DetailParams {
    fn default() -> Self {
        Self {
            seed: 1,
            hurst: Some(DEFAULT_HURST),
            amplitude: 1.0,
            color: 0.3,
        }
    }
}

impl DetailParams {
    /// Out-of-range settings, in words.
    pub fn check(&self) -> Result<(), String> {
        let ok = self.hurst.is_none_or(|h| (0.1..=1.0).contains(&h))
            && (0.0..=4.0).contains(&self.amplitude)
            && (0.0..=1.0).contains(&self.color);
        if ok {
            Ok(())
        } else {
            Err(format!(
                "detail settings out of range (hurst 0.1..1, amplitude 0..4, color 0..1): {self:?}"
            ))
        }
    }
}

/// The first octave's lattice spacing in units of the data's spacing d₀. Noise of lattice λ
/// holds most of its power at wavelengths λ … 2λ; at λ = d₀ (the data's own spacing) a third of
/// its amplitude passes the pyramid's kernel back into the data's band, at λ = d₀/2 under a tenth
/// (measured: `viewer/data/tests/detail.rs`).
pub const FIRST_LATTICE: f64 = 0.5;

/// The shade (a slope) at which the colour's modulation reaches tanh(1) of its strength: rocky
/// ground (15 %) is shaded clearly, gentle slopes barely.
pub const SHADE_SLOPE: f64 = 0.15;

/// The octaves' Hurst exponent by default: ETOPO5 over the Alps falls as f^−2.36 north–south
/// between 39 and 310 km (H ≈ 0.68); the synthesized heights there then fall as f^−2.52.
pub const DEFAULT_HURST: f64 = 0.7;

/// An octave enters a clipmap level at a lattice of this many texels and is whole at twice it.
pub const FADE_TEXELS: f64 = 2.0;

/// Most octaves a texel sums (d₀ / 2^MAX_OCTAVES is below a millimetre for SRTM1).
pub const MAX_OCTAVES: u32 = 24;

/// The standard deviation of [`gradient_noise`] over space (measured; a test checks it).
pub const NOISE_STD: f64 = 0.001_535;

#[inline(always)]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[inline(always)]
fn hash3(x: i64, y: i64, z: i64, seed: u64) -> u64 {
    mix(seed
        ^ (x as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (y as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
        ^ (z as u64).wrapping_mul(0x1656_67b1_9e37_79f9))
}

/// The dot product of `d` with Perlin's gradient number `h` (0..16): the twelve cube edges, four
/// of them twice, in his improved noise's order (`u ± v`, u and v two of d's components). By
/// selects and sign flips, not a table: eight lanes of a table lookup are a gather, which some
/// CPUs run slower than the whole of the arithmetic.
#[inline(always)]
fn gradient_dot(h: u64, d: [f64; 3]) -> f64 {
    let u = if h < 8 { d[0] } else { d[1] };
    let v = if h < 4 {
        d[1]
    } else if h == 12 || h == 14 {
        d[0]
    } else {
        d[2]
    };
    let u = f64::from_bits(u.to_bits() ^ ((h & 1) << 63));
    let v = f64::from_bits(v.to_bits() ^ ((h & 2) << 62));
    u + v
}

/// ⌊v⌋ as an integer, exact for |v| < 2⁵¹ (lattice coordinates are below 10¹²): v + 1.5·2⁵²
/// rounds v to an integer in the last place of the mantissa, which then is that integer. No libm
/// call where the target lacks SSE4.1's rounding, and no saturating conversion: eight lanes of it
/// vectorize.
#[inline(always)]
fn floor_i64(v: f64) -> i64 {
    const M: f64 = 6_755_399_441_055_744.0;
    let big = v + M;
    let r = big - M;
    (big.to_bits() as i64 - M.to_bits() as i64) - i64::from(r > v)
}

/// Simplex noise in 3-D (Perlin 2001, in Gustavson's formulation, with the kernel radius² ½
/// that makes it C² and a hashed lattice) at `p` in lattice units: zero at the lattice points,
/// mean 0, standard deviation [`NOISE_STD`]. Four corners a point (gradient noise on the cubic
/// lattice takes eight). Without branches, so that [`noise_lanes`] vectorizes it.
#[inline(always)]
pub fn gradient_noise(p: [f64; 3], seed: u64) -> f64 {
    const F3: f64 = 1.0 / 3.0;
    const G3: f64 = 1.0 / 6.0;
    let s = (p[0] + p[1] + p[2]) * F3;
    let [i, j, k] = [
        floor_i64(p[0] + s),
        floor_i64(p[1] + s),
        floor_i64(p[2] + s),
    ];
    let t = (i + j + k) as f64 * G3;
    let d0 = [
        p[0] - (i as f64 - t),
        p[1] - (j as f64 - t),
        p[2] - (k as f64 - t),
    ];
    // the simplex holding the point: the corners' offsets by the order of d0's components
    // (without branches: which comes first is a coin toss for the CPU)
    let xy = i64::from(d0[0] >= d0[1]);
    let yz = i64::from(d0[1] >= d0[2]);
    let xz = i64::from(d0[0] >= d0[2]);
    let o1 = [xy & xz, (1 - xy) & yz, (1 - xz) & (1 - yz)];
    let o2 = [xy | xz, (1 - xy) | yz, (1 - xz) | (1 - yz)];
    #[inline(always)]
    fn corner(d0: [f64; 3], c: [i64; 3], o: [i64; 3], g: f64, seed: u64) -> f64 {
        let d = [
            d0[0] - o[0] as f64 + g,
            d0[1] - o[1] as f64 + g,
            d0[2] - o[2] as f64 + g,
        ];
        let w = 0.5 - d[0] * d[0] - d[1] * d[1] - d[2] * d[2];
        let w2 = w * w;
        let h = hash3(c[0] + o[0], c[1] + o[1], c[2] + o[2], seed) >> 60;
        // (1 − 6r²) zeroes the kernel's first moment: a lattice point's bump has no mean slope,
        // so averages over many cells (the pyramid's kernel) cancel far better
        let r2 = 0.5 - w;
        let v = w2 * w2 * (1.0 + r2 * (-13.6 + r2 * 36.914_285_714)) * gradient_dot(h, d);
        if w > 0.0 { v } else { 0.0 }
    }
    let c = [i, j, k];
    let corner = |o: [i64; 3], g: f64| corner(d0, c, o, g, seed);
    corner([0, 0, 0], 0.0) + corner(o1, G3) + corner(o2, 2.0 * G3) + corner([1, 1, 1], 3.0 * G3)
}

/// Points [`noise_lanes`] takes at once.
pub const LANES: usize = 8;

/// [`gradient_noise`] at [`LANES`] points, the same values bit for bit, in the widest vectors
/// the CPU has (the same code compiled for AVX-512 or AVX2 where the CPU has them: IEEE
/// arithmetic lane by lane, never fused).
pub fn noise_lanes(q: &[[f64; 3]; LANES], seed: u64) -> [f64; LANES] {
    #[cfg(target_arch = "x86_64")]
    if let Some(n) = wide::noise_lanes(q, seed) {
        return n;
    }
    lanes(q, seed)
}

/// [`gradient_noise`] at each of the lanes: a plain loop, inlined into each caller with the
/// caller's target features (a closure, as in `array::from_fn`, is compiled once without them
/// and called lane by lane).
#[inline(always)]
fn lanes(q: &[[f64; 3]; LANES], seed: u64) -> [f64; LANES] {
    let mut n = [0.0; LANES];
    for (n, q) in n.iter_mut().zip(q) {
        *n = gradient_noise(*q, seed);
    }
    n
}

/// [`noise_lanes`] compiled for AVX-512 and for AVX2, each called only where the CPU has it.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod wide {
    use super::{LANES, lanes};

    /// The lanes in the widest vectors the CPU has; None where it has neither.
    pub(super) fn noise_lanes(q: &[[f64; 3]; LANES], seed: u64) -> Option<[f64; LANES]> {
        use std::arch::is_x86_feature_detected as has;
        if has!("avx512f") && has!("avx512dq") && has!("avx512vl") {
            // SAFETY: the CPU has every feature the function is compiled for
            return Some(unsafe { avx512(q, seed) });
        }
        if has!("avx2") {
            // SAFETY: as above
            return Some(unsafe { avx2(q, seed) });
        }
        None
    }

    #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2")]
    fn avx512(q: &[[f64; 3]; LANES], seed: u64) -> [f64; LANES] {
        lanes(q, seed)
    }

    #[target_feature(enable = "avx2")]
    fn avx2(q: &[[f64; 3]; LANES], seed: u64) -> [f64; LANES] {
        lanes(q, seed)
    }
}

/// A rotation and offset of one octave's lattice.
#[derive(Debug, Clone, Copy)]
struct Frame {
    rot: [[f64; 3]; 3],
    offset: [f64; 3],
    seed: u64,
}

impl Frame {
    fn new(seed: u64, octave: u32) -> Self {
        let s = mix(seed ^ mix(u64::from(octave) + 0x5851_f42d_4c95_7f2d));
        let u = |k: u64| (mix(s ^ k) >> 11) as f64 / (1u64 << 53) as f64;
        // a uniformly random rotation from a random unit quaternion (Shoemake)
        let (u1, u2, u3) = (u(1), 2.0 * PI * u(2), 2.0 * PI * u(3));
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        let (qx, qy, qz, qw) = (a * u2.sin(), a * u2.cos(), b * u3.sin(), b * u3.cos());
        let rot = [
            [
                1.0 - 2.0 * (qy * qy + qz * qz),
                2.0 * (qx * qy - qz * qw),
                2.0 * (qx * qz + qy * qw),
            ],
            [
                2.0 * (qx * qy + qz * qw),
                1.0 - 2.0 * (qx * qx + qz * qz),
                2.0 * (qy * qz - qx * qw),
            ],
            [
                2.0 * (qx * qz - qy * qw),
                2.0 * (qy * qz + qx * qw),
                1.0 - 2.0 * (qx * qx + qy * qy),
            ],
        ];
        Self {
            rot,
            offset: [u(4), u(5), u(6)],
            seed: mix(s ^ 7),
        }
    }

    /// The octave's noise at `p` (metres) with lattice spacing `lambda` (metres).
    #[inline]
    fn noise(&self, p: [f64; 3], lambda: f64) -> f64 {
        gradient_noise(self.lattice_point(p, lambda), self.seed) / NOISE_STD
    }

    /// `p` (metres) in the octave's lattice of spacing `lambda` (metres).
    #[inline]
    fn lattice_point(&self, p: [f64; 3], lambda: f64) -> [f64; 3] {
        let r = &self.rot;
        let k = 1.0 / lambda;
        std::array::from_fn(|i| {
            (r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2]) * k + self.offset[i]
        })
    }
}

/// The data's roughness at one data texel: the RMS residual of the plane fitted to its 3×3
/// neighbourhood (`h[row][column]`, rows and columns one texel apart).
pub fn plane_residual(h: [[f32; 3]; 3]) -> f64 {
    let mut m = 0.0;
    let (mut bx, mut by) = (0.0, 0.0);
    for (r, row) in h.iter().enumerate() {
        for (c, &v) in row.iter().enumerate() {
            let v = f64::from(v);
            m += v;
            bx += (c as f64 - 1.0) * v;
            by += (r as f64 - 1.0) * v;
        }
    }
    let (m, bx, by) = (m / 9.0, bx / 6.0, by / 6.0);
    let mut e2 = 0.0;
    for (r, row) in h.iter().enumerate() {
        for (c, &v) in row.iter().enumerate() {
            let e = f64::from(v) - m - bx * (c as f64 - 1.0) - by * (r as f64 - 1.0);
            e2 += e * e;
        }
    }
    (e2 / 9.0).sqrt()
}

/// The data's roughness at the four data texels around a point from the 4×4 texels around it
/// (`taps[row][column]`, the point between `[1..=2][1..=2]`): [`plane_residual`] at each, in
/// the order north-west, north-east, south-west, south-east. Each corner's value depends on its
/// own neighbourhood only, so [`bilinear_roughness`] is continuous across data texels, tiles and
/// levels.
pub fn corner_residuals(taps: &[[f32; 4]; 4]) -> [f64; 4] {
    let corner = |r0: usize, c0: usize| {
        plane_residual(std::array::from_fn(|r| {
            std::array::from_fn(|c| taps[r0 + r][c0 + c])
        }))
    };
    [corner(0, 0), corner(0, 1), corner(1, 0), corner(1, 1)]
}

/// The roughness at fractions `fx`, `fy` between the four corners of [`corner_residuals`]:
/// bilinear in smoothstepped fractions, so that its gradient vanishes on the data's texel lines
/// (with plain bilinear weights the amplitude creases there, and lighting draws the data's grid
/// as lines across the synthesized ground).
pub fn bilinear_roughness([a, b, c, d]: [f64; 4], fx: f64, fy: f64) -> f64 {
    let (fx, fy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let top = a + (b - a) * fx;
    let bottom = c + (d - c) * fx;
    top + (bottom - top) * fy
}

/// The ratio between the amplitude of the first detail octave of a self-similar field made
/// of this noise and the mean plane residual the field's band-limited part shows on the
/// data's grid: data that continue like the noise get detail that continues them (on the same
/// power law). The data's part: the octaves of lattice ≥ 2 (the data's Nyquist wavelength);
/// the octave of lattice 1 lies between, filtered away by the data's kernel and left out by
/// the detail (it would leak into the data's band). Deterministic (a fixed set of points).
fn calibrate(h: f64) -> f64 {
    // spacing 1: octave j has lattice FIRST_LATTICE·2^j and amplitude 2^(H·j), the detail's
    // first octave being j = 0 (amplitude 1); the data hold j ≥ 2
    let frames: Vec<Frame> = (0..10).map(|j| Frame::new(0xca1b, j)).collect();
    let field = |x: f64, y: f64| -> f32 {
        let p = [x, y, 0.5];
        frames
            .iter()
            .enumerate()
            .map(|(j, f)| {
                let j = j as i32 + 2;
                2f64.powf(h * f64::from(j)) * f.noise(p, FIRST_LATTICE * 2f64.powi(j))
            })
            .sum::<f64>() as f32
    };
    let mut sum = 0.0;
    let count = 400;
    for k in 0..count {
        let (x0, y0) = (f64::from(k % 20) * 97.3, f64::from(k / 20) * 101.9);
        let taps: [[f32; 3]; 3] =
            std::array::from_fn(|r| std::array::from_fn(|c| field(x0 + c as f64, y0 + r as f64)));
        sum += plane_residual(taps);
    }
    f64::from(count) / sum
}

/// One point's detail: the height added and the colour's shade.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DetailSample {
    /// Metres added to the data's height.
    pub height_m: f64,
    /// Σ wᵢ·aᵢ·nᵢ/λᵢ (a slope), the colour's driver.
    pub shade: f64,
}

/// One point of [`Detail::sample_many`]: the arguments of [`Detail::sample_at`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetailPoint {
    /// The point ([`Detail::point_m`]).
    pub p: [f64; 3],
    /// The data's row spacing there, metres.
    pub d0_m: f64,
    /// The data's roughness there, metres.
    pub residual_m: f64,
    /// The data's Hurst exponent there, if known.
    pub data_hurst: Option<f64>,
    /// The clipmap texel's ground size, metres.
    pub texel_m: f64,
}

/// Where a point's octaves stand: the next one's lattice and amplitude, and the amplitude's
/// ratio from octave to octave.
#[derive(Debug, Clone, Copy)]
struct Octaves {
    lambda: f64,
    a: f64,
    step: f64,
}

impl Octaves {
    /// Adds the octave of weight `w` whose noise there is `g` ([`gradient_noise`]) to `out`,
    /// and moves on to the next.
    #[inline]
    fn add(&mut self, out: &mut DetailSample, w: f64, g: f64) {
        let n = w * self.a * (g / NOISE_STD);
        out.height_m += n;
        out.shade += n / self.lambda;
        self.lambda *= 0.5;
        self.a *= self.step;
    }
}

/// The detail synthesizer of one planet (see the module documentation).
#[derive(Debug, Clone)]
pub struct Detail {
    params: DetailParams,
    radius_m: f64,
    frames: Vec<Frame>,
    /// a₀ per metre of the data's plane residual, for H = 0.1, 0.2 … 1.0.
    gains: [f64; 10],
    /// With the settings' Hurst exponent H: (2^−H, a₀ per metre of residual).
    fixed: Option<(f64, f64)>,
}

impl Detail {
    /// The synthesizer for a planet of `radius_m` metres.
    pub fn new(params: DetailParams, radius_m: f64) -> Self {
        let frames = (0..MAX_OCTAVES)
            .map(|i| Frame::new(params.seed, i))
            .collect();
        let gains = std::array::from_fn(|i| calibrate(0.1 * (i + 1) as f64));
        let mut d = Self {
            params,
            radius_m,
            frames,
            gains,
            fixed: None,
        };
        d.fixed = params.hurst.map(|h| {
            let h = h.clamp(0.1, 1.0);
            (2f64.powf(-h), d.gain(h))
        });
        d
    }

    /// a₀ per metre of the data's plane residual for Hurst exponent `h` (0.1 … 1, linear between
    /// the calibrated tenths).
    pub fn gain(&self, h: f64) -> f64 {
        let x = (h.clamp(0.1, 1.0) * 10.0 - 1.0).clamp(0.0, 9.0);
        let i = (x.floor() as usize).min(8);
        let t = x - i as f64;
        self.gains[i] + (self.gains[i + 1] - self.gains[i]) * t
    }

    /// Its settings.
    pub fn params(&self) -> &DetailParams {
        &self.params
    }

    /// The ground size of a clipmap texel (radians of colatitude and longitude) at colatitude
    /// `colat`: the larger side, metres.
    pub fn texel_m(&self, texel_colat: f64, texel_lon: f64, colat: f64) -> f64 {
        (texel_colat.max(texel_lon * colat.sin().abs())) * self.radius_m
    }

    /// The point of the sphere at (`lon`, `colat`), metres (colatitudes beyond a pole are the
    /// other side: the same point from both sides).
    pub fn point_m(&self, lon: f64, colat: f64) -> [f64; 3] {
        self.point_from(colat.sin_cos(), lon.sin_cos())
    }

    /// [`Self::point_m`] from the sine and cosine of the colatitude and of the longitude (a row
    /// of points shares the first).
    #[inline]
    pub fn point_from(&self, (st, ct): (f64, f64), (sl, cl): (f64, f64)) -> [f64; 3] {
        [
            self.radius_m * st * cl,
            self.radius_m * st * sl,
            self.radius_m * ct,
        ]
    }

    /// The weight of octave `i` (lattice `lambda_m`) in a texel of `texel_m`: 1 at λ ≥ 4t,
    /// 0 at λ ≤ 2t, log-linear between.
    pub fn octave_weight(lambda_m: f64, texel_m: f64) -> f64 {
        ((lambda_m / (FADE_TEXELS * texel_m)).log2()).clamp(0.0, 1.0)
    }

    /// The detail at (`lon`, `colat`) over data of row spacing `d0_m` whose roughness there is
    /// `residual_m` ([`bilinear_roughness`]) and whose spectral slope gives the Hurst exponent
    /// `data_hurst` (if known; the settings' own, if set, wins), for a clipmap texel of ground
    /// size `texel_m`.
    pub fn sample(
        &self,
        lon: f64,
        colat: f64,
        d0_m: f64,
        residual_m: f64,
        data_hurst: Option<f64>,
        texel_m: f64,
    ) -> DetailSample {
        let p = self.point_m(lon, colat);
        self.sample_at(p, d0_m, residual_m, data_hurst, texel_m)
    }

    /// [`Self::sample`] at the point `p` of [`Self::point_m`].
    pub fn sample_at(
        &self,
        p: [f64; 3],
        d0_m: f64,
        residual_m: f64,
        data_hurst: Option<f64>,
        texel_m: f64,
    ) -> DetailSample {
        let Some(mut o) = self.first_octave(d0_m, residual_m, data_hurst, texel_m) else {
            return DetailSample::default();
        };
        let mut out = DetailSample::default();
        for f in &self.frames {
            let w = Self::weight(o.lambda, texel_m);
            if w <= 0.0 {
                break;
            }
            o.add(
                &mut out,
                w,
                gradient_noise(f.lattice_point(p, o.lambda), f.seed),
            );
        }
        out
    }

    /// [`Self::sample_at`] at many points, the same values bit for bit: each octave's noise
    /// [`LANES`] points at a time ([`noise_lanes`]).
    pub fn sample_many(&self, points: &[DetailPoint]) -> Vec<DetailSample> {
        let mut out = vec![DetailSample::default(); points.len()];
        let mut live: Vec<(usize, Octaves)> = points
            .iter()
            .enumerate()
            .filter_map(|(k, t)| {
                self.first_octave(t.d0_m, t.residual_m, t.data_hurst, t.texel_m)
                    .map(|o| (k, o))
            })
            .collect();
        let mut weights = Vec::with_capacity(live.len());
        for f in &self.frames {
            weights.clear();
            live.retain(|(k, o)| {
                let w = Self::weight(o.lambda, points[*k].texel_m);
                if w > 0.0 {
                    weights.push(w);
                }
                w > 0.0
            });
            if live.is_empty() {
                break;
            }
            for (chunk, ws) in live.chunks_mut(LANES).zip(weights.chunks(LANES)) {
                // a short last chunk repeats its last point in the lanes it leaves
                let q = std::array::from_fn(|l| {
                    let (k, o) = &chunk[l.min(chunk.len() - 1)];
                    f.lattice_point(points[*k].p, o.lambda)
                });
                let noise = noise_lanes(&q, f.seed);
                for (((k, o), &w), g) in chunk.iter_mut().zip(ws).zip(noise) {
                    o.add(&mut out[*k], w, g);
                }
            }
        }
        out
    }

    /// The first octave at a point: its lattice λ₀ = [`FIRST_LATTICE`]·d₀ and amplitude a₀, and
    /// the amplitude's ratio from octave to octave; None where the point gets no detail.
    fn first_octave(
        &self,
        d0_m: f64,
        residual_m: f64,
        data_hurst: Option<f64>,
        texel_m: f64,
    ) -> Option<Octaves> {
        let (gain, step) = match self.fixed {
            Some((step, gain)) => (gain, step),
            None => {
                let hurst = data_hurst.unwrap_or(DEFAULT_HURST).clamp(0.1, 1.0);
                (self.gain(hurst), 2f64.powf(-hurst))
            }
        };
        let a0 = gain * residual_m * self.params.amplitude;
        if a0 <= 0.0 || !a0.is_finite() || FIRST_LATTICE * d0_m < FADE_TEXELS * texel_m {
            return None;
        }
        Some(Octaves {
            lambda: FIRST_LATTICE * d0_m,
            a: a0,
            step,
        })
    }

    /// The weight of the octave of lattice `lambda` in a texel of `texel_m`: whole at λ ≥ 4t
    /// (no log to take), else [`Self::octave_weight`].
    #[inline]
    fn weight(lambda: f64, texel_m: f64) -> f64 {
        if lambda >= 2.0 * FADE_TEXELS * texel_m {
            1.0
        } else {
            Self::octave_weight(lambda, texel_m)
        }
    }

    /// The colour factor (linear light) for a shade: 1 + c·tanh(q / [`SHADE_SLOPE`]), mean 1
    /// over symmetric q.
    pub fn color_factor(&self, shade: f64) -> f64 {
        1.0 + self.params.color * (shade / SHADE_SLOPE).tanh()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_noise_has_the_stated_spread_and_no_mean() {
        let (mut s, mut s2) = (0.0, 0.0);
        let n = 200_000;
        for k in 0..n {
            let k = f64::from(k);
            let v = gradient_noise([k * 0.618_034, k * 0.414_214 + 3.1, k * 0.732_051], 9);
            s += v;
            s2 += v * v;
        }
        let mean = s / f64::from(n);
        let std = (s2 / f64::from(n) - mean * mean).sqrt();
        assert!(mean.abs() < 0.005, "mean {mean}");
        assert!((std / NOISE_STD - 1.0).abs() < 0.03, "std {std}");
    }

    #[test]
    fn a_plane_has_no_roughness() {
        let h: [[f32; 3]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|c| 100.0 + 3.0 * c as f32 - 7.0 * r as f32)
        });
        assert!(plane_residual(h) < 1e-5);
        let taps: [[f32; 4]; 4] =
            std::array::from_fn(|r| std::array::from_fn(|c| 2.0 * (r + c) as f32));
        assert!(bilinear_roughness(corner_residuals(&taps), 0.3, 0.8) < 1e-5);
        let d = Detail::new(DetailParams::default(), 6.371e6);
        assert_eq!(
            d.sample(0.1, 1.0, 90.0, 0.0, None, 0.01),
            DetailSample::default()
        );
    }

    /// The old floor: truncation corrected downwards (a saturating conversion, which does not
    /// vectorize).
    fn floor_by_truncation(v: f64) -> i64 {
        let i = v as i64;
        i - i64::from((i as f64) > v)
    }

    #[test]
    fn the_fast_floor_is_the_floor() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let specials = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            -1.5,
            2.5,
            -2.5,
            1.0 - 1e-16,
            -1e-300,
            1e12,
        ];
        let random = (0..100_000).map(|_| {
            let m = (next() >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            m * 10f64.powi((next() % 13) as i32)
        });
        for v in specials.into_iter().chain(random) {
            let f = v.floor();
            assert_eq!(floor_i64(v), f as i64, "floor of {v}");
            assert_eq!(floor_i64(v), floor_by_truncation(v), "{v}");
            // on the lattice's own integers and just below them
            assert_eq!(floor_i64(f), f as i64, "{f}");
            assert_eq!(floor_i64(f.next_down()), f as i64 - 1, "{f}");
        }
    }

    #[test]
    fn the_gradients_are_perlins_twelve_edges() {
        // his improved noise's table: the cube's edges, (1,1,0), (−1,1,0), (0,−1,1), (0,−1,−1)
        // twice
        const TABLE: [[f64; 3]; 16] = [
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
            [1.0, -1.0, 0.0],
            [-1.0, -1.0, 0.0],
            [1.0, 0.0, 1.0],
            [-1.0, 0.0, 1.0],
            [1.0, 0.0, -1.0],
            [-1.0, 0.0, -1.0],
            [0.0, 1.0, 1.0],
            [0.0, -1.0, 1.0],
            [0.0, 1.0, -1.0],
            [0.0, -1.0, -1.0],
            [1.0, 1.0, 0.0],
            [0.0, -1.0, 1.0],
            [-1.0, 1.0, 0.0],
            [0.0, -1.0, -1.0],
        ];
        let d = [0.37, -0.141, 0.29];
        for (h, g) in TABLE.iter().enumerate() {
            let want = g[0] * d[0] + g[1] * d[1] + g[2] * d[2];
            assert_eq!(gradient_dot(h as u64, d), want, "gradient {h}");
        }
    }

    #[test]
    fn eight_lanes_give_the_noise_bit_for_bit() {
        for step in [1e-3, 0.05, 0.7, 13.0] {
            for start in [0.0, -5e9, 7e11] {
                let q: [[f64; 3]; LANES] = std::array::from_fn(|l| {
                    let t = start + step * l as f64;
                    [t * 0.9 + 0.1, t * -0.43 + 7.7, t * 0.21 - 1e4]
                });
                let lanes = noise_lanes(&q, 77);
                for (l, v) in lanes.iter().enumerate() {
                    assert_eq!(
                        v.to_bits(),
                        gradient_noise(q[l], 77).to_bits(),
                        "{q:?} lane {l}"
                    );
                }
            }
        }
    }

    #[test]
    fn many_points_are_sampled_as_one_is() {
        let d = Detail::new(DetailParams::default(), 6.371e6);
        let free = DetailParams {
            hurst: None,
            ..DetailParams::default()
        };
        let free = Detail::new(free, 6.371e6);
        // a row's points: some without detail, some fading, some with many octaves
        let points: Vec<DetailPoint> = (0..203u32)
            .map(|i| {
                let k = f64::from(i);
                DetailPoint {
                    p: d.point_m(0.14 + k * 1e-7, 0.8),
                    d0_m: if k < 5.0 { 0.01 } else { 90.0 },
                    residual_m: if i.is_multiple_of(17) {
                        0.0
                    } else {
                        3.0 + k * 0.01
                    },
                    data_hurst: (!i.is_multiple_of(3)).then_some(0.5 + k * 0.002),
                    texel_m: 0.01 * (1.0 + k * 0.37),
                }
            })
            .collect();
        for d in [&d, &free] {
            let many = d.sample_many(&points);
            let mut with_detail = 0;
            for (t, m) in points.iter().zip(&many) {
                let one = d.sample_at(t.p, t.d0_m, t.residual_m, t.data_hurst, t.texel_m);
                assert_eq!(m.height_m.to_bits(), one.height_m.to_bits(), "{t:?}");
                assert_eq!(m.shade.to_bits(), one.shade.to_bits(), "{t:?}");
                with_detail += usize::from(one.height_m != 0.0);
            }
            assert!(
                with_detail > 150,
                "{with_detail} of {} with detail",
                points.len()
            );
        }
    }

    #[test]
    fn the_gain_is_stable() {
        for h in [0.3, 0.5, 0.8, 1.0] {
            let d = Detail::new(DetailParams::default(), 6.371e6);
            let g = d.gain(h);
            assert!(g > 0.05 && g < 5.0, "H {h}: gain {g}");
            assert!(
                (g - calibrate(h)).abs() < 1e-12 * g,
                "H {h}: the table's {g}"
            );
        }
    }
}
