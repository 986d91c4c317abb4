//! The pyramid's filters, in plain Rust (the CPU reference every faster path is tested against).
//!
//! **Isotropic level ℓ from level ℓ+1.** An output texel is the normalised sum of source samples
//! weighted by a kernel of their great-circle distance (unit: ℓ's isotropic spacing ρ = π/H) times
//! the samples' area. A naïve sum touches whole source rows near the poles (the kernel's circle
//! spans 1/cos(lat) more longitude there). The construction that bounds the cost:
//!
//! 1. Every source row is read at its *natural* longitude resolution: decimated by 2^a' with
//!    `2^a'·cos(lat') ≤ 1`, so its samples are still no farther apart on the ground than the
//!    source's isotropic spacing (it loses nothing the sphere can show at that level). The
//!    decimation halves longitude with a 12-tap Lanczos3 filter, starting from the coarsest stored
//!    anisotropic level (ℓ+1, a) with a ≤ a' — the cascade: a polar row is never read at full
//!    width. The error this makes: each halving attenuates the band it keeps by < 1 % below half
//!    its new Nyquist frequency, which is above anything the output keeps.
//! 2. Every output row is computed at its natural resolution too (`2^a_o·cos(lat) ≤ ½`, so the
//!    kernel's pass band sits below half the row's Nyquist), then interpolated to the stored width
//!    with Lanczos3 (error < 1 % in that band). Pole rows too: their centres lie half a row from
//!    the pole, and the kernel's circle reaches across it.
//! 3. Between a natural output row and a natural source row the sample spacings differ by a power
//!    of two, so the weights repeat along the row: one small table per (output row, source row,
//!    phase), great-circle distances evaluated once per table, not per texel.
//!
//! Each output sample thus costs ≈ π·(support·ρ)² / (source spacing)² taps, at every latitude.
//!
//! **Anisotropic level (ℓ, a) from (ℓ, a−1)**: longitude halved by the same 12-tap filter, only on
//! the tile rows the grid stores. Level ℓ is already band-limited to what the sphere supports, and
//! where (ℓ, a) is stored (2^a·cos(lat) ≤ 1 at the poleward edge) its longitude spacing is no
//! coarser than the isotropic one, so halving loses nothing there.
//!
//! Values travel premultiplied by coverage: `v·c` per channel and `c` (1 valid, 0 nodata; colour
//! alpha), so nodata gets zero weight and every step renormalises over valid samples.

use std::cell::RefCell;
use std::collections::HashMap;
use std::f64::consts::PI;
use std::rc::Rc;

use crate::{GridSpec, Kernel, KernelLut, LevelId};

/// Half-width of the halving filter in fine samples (12 taps).
pub const HALVE_R: i64 = 6;
/// Half-width of the Lanczos3 interpolator in coarse samples (6 taps).
const UP_R: i64 = 3;

/// Fraction of a footprint's positive weight that must fall on valid samples for a valid texel:
/// the one nodata rule of ingest and of the pyramid.
pub const MIN_COVERAGE: f64 = 0.5;

/// A window of a periodic row of `n` samples: `ch` channels of premultiplied values and the
/// coverage, for samples `first .. first + len` (indices taken modulo `n`).
#[derive(Debug, Clone, PartialEq)]
pub struct RowWindow {
    /// Samples in the whole row (the period).
    pub n: u64,
    /// Index of the window's first sample (may lie outside `0..n`; the row is periodic).
    pub first: i64,
    /// Channels.
    pub ch: usize,
    /// Premultiplied values, `len × ch`.
    pub v: Vec<f64>,
    /// Coverage per sample.
    pub c: Vec<f64>,
    /// Whether every coverage is exactly 1 (lets the filters skip coverage sums).
    pub full: bool,
}

impl RowWindow {
    /// A window with every sample zero (no coverage).
    pub fn empty(n: u64, first: i64, len: usize, ch: usize) -> Self {
        Self {
            n,
            first,
            ch,
            v: vec![0.0; len * ch],
            c: vec![0.0; len],
            full: false,
        }
    }

    /// Samples in the window.
    pub fn len(&self) -> usize {
        self.c.len()
    }

    /// Whether the window holds no sample.
    pub fn is_empty(&self) -> bool {
        self.c.is_empty()
    }

    /// Whether the window covers the whole period.
    pub fn is_whole(&self) -> bool {
        self.len() as u64 >= self.n
    }

    fn index(&self, m: i64) -> usize {
        if self.is_whole() {
            (m - self.first).rem_euclid(self.n as i64) as usize
        } else {
            let k = m - self.first;
            debug_assert!(
                k >= 0 && (k as usize) < self.len(),
                "sample {m} outside window"
            );
            k as usize
        }
    }

    /// The samples `m0..m1` as a contiguous window (periodic: a whole-row window serves any range).
    pub fn sub(&self, m0: i64, m1: i64) -> RowWindow {
        if m0 == self.first && (m1 - m0) as usize == self.len() {
            return self.clone();
        }
        let len = (m1 - m0).max(0) as usize;
        let ch = self.ch;
        let mut out = RowWindow {
            n: self.n,
            first: m0,
            ch,
            v: Vec::with_capacity(len * ch),
            c: Vec::with_capacity(len),
            full: self.full,
        };
        // copy in runs that do not wrap
        let mut m = m0;
        while m < m1 {
            let s = self.index(m);
            let run = if self.is_whole() {
                ((self.n as usize - s.min(self.n as usize)).min(self.len() - s)).max(1)
            } else {
                self.len() - s
            }
            .min((m1 - m) as usize);
            out.v.extend_from_slice(&self.v[s * ch..(s + run) * ch]);
            out.c.extend_from_slice(&self.c[s..s + run]);
            m += run as i64;
        }
        out
    }

    /// This window itself when it covers `m0..m1` (with the offset of `m0`), else a copy.
    fn covering(&self, m0: i64, m1: i64) -> (std::borrow::Cow<'_, RowWindow>, usize) {
        if self.first <= m0 && m1 <= self.first + self.len() as i64 {
            (std::borrow::Cow::Borrowed(self), (m0 - self.first) as usize)
        } else {
            (std::borrow::Cow::Owned(self.sub(m0, m1)), 0)
        }
    }
}

/// A source row's window as [`RowAcc::add`] reads it, with its polyphase components made once
/// per decimation that asks for them: a source row serves a dozen output rows in a band.
#[derive(Debug)]
pub struct SourceRow {
    /// The window.
    pub win: RowWindow,
    split: RefCell<Vec<(usize, Rc<Split>)>>,
}

/// The `qs` polyphase components of a window: component r holds samples r, r + qs, r + 2·qs, …
/// of the values and of the coverage (none for a full window).
#[derive(Debug)]
struct Split {
    v: Vec<Vec<f64>>,
    c: Vec<Vec<f64>>,
}

impl SourceRow {
    /// The window, its components not made yet.
    pub fn new(win: RowWindow) -> Self {
        Self {
            win,
            split: RefCell::new(Vec::new()),
        }
    }

    /// The window's `qs` polyphase components (single channel).
    fn split(&self, qs: usize) -> Rc<Split> {
        if let Some((_, s)) = self.split.borrow().iter().find(|(q, _)| *q == qs) {
            return s.clone();
        }
        let comps = |x: &[f64]| -> Vec<Vec<f64>> {
            match qs {
                2 => deinterleave::<2>(x),
                4 => deinterleave::<4>(x),
                _ => (0..qs)
                    .map(|r| x.iter().skip(r).step_by(qs).copied().collect())
                    .collect(),
            }
        };
        let s = Rc::new(Split {
            v: comps(&self.win.v),
            c: if self.win.full {
                Vec::new()
            } else {
                comps(&self.win.c)
            },
        });
        self.split.borrow_mut().push((qs, s.clone()));
        s
    }
}

/// The `Q` polyphase components of `x`: component r holds `x[r]`, `x[r + Q]`, … (in loops over
/// fixed-size chunks, which the compiler vectorises; `step_by` goes element by element).
fn deinterleave<const Q: usize>(x: &[f64]) -> Vec<Vec<f64>> {
    let (whole, rest) = x.as_chunks::<Q>();
    (0..Q)
        .map(|r| {
            let mut comp = Vec::with_capacity(whole.len() + 1);
            comp.extend(whole.iter().map(|p| p[r]));
            comp.extend(rest.get(r));
            comp
        })
        .collect()
}

/// Lanczos3 at half-integer offsets, scaled ×2: the halving filter, normalised.
fn halving_taps() -> [f64; 2 * HALVE_R as usize] {
    let mut h = [0.0; 2 * HALVE_R as usize];
    for (u, w) in h.iter_mut().enumerate() {
        *w = Kernel::Lanczos3.weight((u as f64 - HALVE_R as f64 + 0.5) / 2.0);
    }
    let s: f64 = h.iter().sum();
    h.iter_mut().for_each(|w| *w /= s);
    h
}

/// Fine samples [`halve`] needs to make coarse samples `m0..m1`.
pub fn halve_needs(m0: i64, m1: i64) -> (i64, i64) {
    (2 * m0 - HALVE_R + 1, 2 * m1 + HALVE_R - 1)
}

/// Halves a periodic row (n even): coarse sample m (centre between fine 2m and 2m+1) for
/// `m0..m1`. `src` must cover [`halve_needs`]`(m0, m1)` or the whole row.
pub fn halve(src: &RowWindow, m0: i64, m1: i64) -> RowWindow {
    let h = halving_taps();
    let (f0, f1) = halve_needs(m0, m1);
    let (s, off) = src.covering(f0, f1);
    let ch = s.ch;
    let len = (m1 - m0).max(0) as usize;
    let mut out = RowWindow::empty(src.n / 2, m0, len, ch);
    out.full = s.full;
    let taps = h.len();
    for k in 0..len {
        let base = off + 2 * k; // fine index of tap 0 within s
        if ch == 1 {
            out.v[k] = dot(&h, &s.v[base..base + taps]);
        } else {
            for (u, &w) in h.iter().enumerate() {
                for q in 0..ch {
                    out.v[k * ch + q] += w * s.v[(base + u) * ch + q];
                }
            }
        }
        out.c[k] = if s.full {
            1.0
        } else {
            dot(&h, &s.c[base..base + taps])
        };
    }
    out
}

/// Coarse samples [`upsample`] by `u` needs to make fine samples `i0..i1`.
pub fn upsample_needs(u: u64, i0: i64, i1: i64) -> (i64, i64) {
    let x = |i: i64| ((2 * i + 1 - u as i64) as f64 / (2 * u) as f64).floor() as i64;
    (x(i0) - UP_R + 1, x(i1 - 1) + UP_R + 1)
}

/// Interpolates a periodic row `u` times finer (u a power of two) with Lanczos3: fine samples
/// `i0..i1`. `src` must cover [`upsample_needs`] or the whole row.
pub fn upsample(src: &RowWindow, u: u64, i0: i64, i1: i64) -> RowWindow {
    if u == 1 {
        return src.sub(i0, i1);
    }
    let (m0, m1) = upsample_needs(u, i0, i1);
    let s = src.sub(m0, m1);
    let ch = s.ch;
    let len = (i1 - i0).max(0) as usize;
    let mut out = RowWindow::empty(src.n * u, i0, len, ch);
    out.full = s.full;
    // weights per phase i mod u
    let phases: Vec<(i64, [f64; 2 * UP_R as usize])> = (0..u as i64)
        .map(|p| {
            let x = (2 * p + 1 - u as i64) as f64 / (2 * u) as f64;
            let fl = x.floor();
            let mut w = [0.0; 2 * UP_R as usize];
            for (t, wt) in w.iter_mut().enumerate() {
                let m = fl - UP_R as f64 + 1.0 + t as f64;
                *wt = Kernel::Lanczos3.weight(x - m);
            }
            let sum: f64 = w.iter().sum();
            w.iter_mut().for_each(|x| *x /= sum);
            (fl as i64 - UP_R + 1, w)
        })
        .collect();
    for (k, i) in (i0..i1).enumerate() {
        let (p, q) = (i.rem_euclid(u as i64), i.div_euclid(u as i64));
        let (off, w) = &phases[p as usize];
        let base = (q + off - m0) as usize;
        let mut c = 0.0;
        for (t, &wt) in w.iter().enumerate() {
            c += wt * s.c[base + t];
            for ch_i in 0..ch {
                out.v[k * ch + ch_i] += wt * s.v[(base + t) * ch + ch_i];
            }
        }
        out.c[k] = if s.full { 1.0 } else { c };
    }
    out
}

/// Natural decimation of a source row: the largest `a'` with `2^a'·cos(lat) ≤ 1` (at most
/// `max`).
pub fn source_natural_aniso(lat_rad: f64, max: u32) -> u32 {
    let c = lat_rad.cos();
    if c <= 0.0 {
        return max;
    }
    ((1.0 / c).log2().floor().max(0.0) as u32).min(max)
}

/// Natural decimation of an output row: the largest `a_o` with `2^a_o·cos(lat) ≤ ½` (0 where
/// cos(lat) > ½), at most `max`.
pub fn output_natural_aniso(lat_rad: f64, max: u32) -> u32 {
    let c = lat_rad.cos();
    if c <= 0.0 {
        return max;
    }
    ((0.5 / c).log2().floor().max(0.0) as u32).min(max)
}

/// Latitude (radians) of the centre of row `j` of a level with `h` rows.
pub fn row_lat(j: u64, h: u64) -> f64 {
    PI / 2.0 - (j as f64 + 0.5) * PI / h as f64
}

/// Area of a texel band of row `j` (of `h` rows) per radian of longitude, relative:
/// `sin(north) − sin(south)` over the band's angular height.
pub fn row_band_area(j: u64, h: u64) -> f64 {
    let d = PI / h as f64;
    let l = row_lat(j, h);
    ((l + d / 2.0).sin() - (l - d / 2.0).sin()) / d
}

fn hav(x: f64) -> f64 {
    let s = (x / 2.0).sin();
    s * s
}

/// One phase of the weights between an output row and a source row.
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    /// First source sample of output column `P·kk + phase`, minus `Qs·kk`.
    pub b: i64,
    /// Weights of consecutive source samples.
    pub w: Vec<f64>,
    /// Their sum.
    pub wsum: f64,
}

/// Weights of one source row for every column of one output row (natural resolutions): output
/// column `k = P·kk + ph` takes source samples `Qs·kk + b_ph + t`.
#[derive(Debug, Clone, PartialEq)]
pub struct PairTaps {
    /// Output columns per period of the weights.
    pub p: i64,
    /// Source samples per period.
    pub qs: i64,
    /// The phases.
    pub phases: Vec<Phase>,
}

impl PairTaps {
    /// Weights between output row at latitude `lat` with `n_out` samples and source row at `lat_s`
    /// with `n_src` samples (row counts are powers of two times the same base, or `n_out` = 1 for
    /// a pole), for a kernel of unit `rho` radians. `area` is the source row's relative band area.
    /// `None` when the source row is out of reach.
    pub fn new(
        lut: &KernelLut,
        rho: f64,
        (lat, n_out): (f64, u64),
        (lat_s, n_src): (f64, u64),
        area: f64,
    ) -> Option<Self> {
        let reach = lut.support2().sqrt() * rho;
        let dphi = (lat - lat_s).abs();
        if dphi >= reach {
            return None;
        }
        let cc = lat.cos().max(0.0) * lat_s.cos().max(0.0);
        let ratio = if cc <= 1e-300 {
            2.0
        } else {
            (hav(reach) - hav(dphi)) / cc
        };
        let whole = ratio >= 1.0;
        let dlon_max = if whole { PI } else { 2.0 * ratio.sqrt().asin() };
        let (p, qs) = if n_src >= n_out {
            (1, (n_src / n_out) as i64)
        } else {
            ((n_out / n_src) as i64, 1)
        };
        let step = 2.0 * PI / n_src as f64;
        let per_sample = area / n_src as f64;
        let phases = (0..p)
            .map(|ph| {
                // centre of output column ph (kk = 0) in source sample coordinates
                let o = (ph as f64 + 0.5) * n_src as f64 / n_out as f64 - 0.5;
                let (b, len) = if whole {
                    let b = (o - n_src as f64 / 2.0).ceil() as i64;
                    (b, n_src as i64)
                } else {
                    let r = dlon_max / step;
                    let b = (o - r).ceil() as i64;
                    let e = (o + r).floor() as i64;
                    (b, (e - b + 1).clamp(0, n_src as i64))
                };
                let w: Vec<f64> = (0..len)
                    .map(|t| {
                        let dlon = (b + t) as f64 - o;
                        let h = hav(dphi) + cc * hav(dlon * step);
                        let d = 2.0 * h.clamp(0.0, 1.0).sqrt().asin();
                        lut.weight(d / rho) * per_sample
                    })
                    .collect();
                let wsum = w.iter().sum();
                Phase { b, w, wsum }
            })
            .collect::<Vec<Phase>>();
        // every phase gives the row the same total weight (the kernel's integral along the
        // parallel, sampled at different offsets, varies slightly): otherwise a field that
        // depends on latitude only would pick up a longitude pattern of period P
        let mut phases = phases;
        let mean = phases.iter().map(|p| p.wsum).sum::<f64>() / phases.len() as f64;
        for ph in &mut phases {
            if ph.wsum.abs() > 1e-300 && ph.wsum != mean {
                let f = mean / ph.wsum;
                ph.w.iter_mut().for_each(|w| *w *= f);
                ph.wsum = ph.w.iter().sum();
            }
        }
        Some(Self { p, qs, phases })
    }

    /// Source samples needed for output columns `k0..k1`.
    pub fn needs(&self, k0: i64, k1: i64) -> (i64, i64) {
        let mut lo = i64::MAX;
        let mut hi = i64::MIN;
        for k in (k0..k1)
            .take(self.p as usize)
            .chain((k0..k1).rev().take(self.p as usize))
        {
            let ph = &self.phases[k.rem_euclid(self.p) as usize];
            let s = self.qs * k.div_euclid(self.p) + ph.b;
            lo = lo.min(s);
            hi = hi.max(s + ph.w.len() as i64);
        }
        (lo, hi.max(lo))
    }
}

/// Sums of one natural output row being filtered: premultiplied values, coverage and weight.
#[derive(Debug, Clone)]
pub struct RowAcc {
    /// Output columns `first..first + len` of a row of `n`.
    pub n: u64,
    /// First column.
    pub first: i64,
    /// Channels.
    pub ch: usize,
    v: Vec<f64>,
    c: Vec<f64>,
    w: Vec<f64>,
}

impl RowAcc {
    /// Empty sums for columns `k0..k1` of a row of `n`.
    pub fn new(n: u64, k0: i64, k1: i64, ch: usize) -> Self {
        let len = (k1 - k0).max(0) as usize;
        Self {
            n,
            first: k0,
            ch,
            v: vec![0.0; len * ch],
            c: vec![0.0; len],
            w: vec![0.0; len],
        }
    }

    /// Adds one source row (`src` must cover `taps.needs(first, first + len)`).
    pub fn add(&mut self, taps: &PairTaps, src: &SourceRow) {
        let ch = self.ch;
        let (k0, k1) = (self.first, self.first + self.w.len() as i64);
        let (m0, m1) = taps.needs(k0, k1);
        if taps.p == 1 && ch == 1 {
            let win = &src.win;
            if win.first <= m0 && m1 <= win.first + win.len() as i64 {
                self.add_polyphase(taps, src, win.first);
            } else {
                self.add_polyphase(taps, &SourceRow::new(win.sub(m0, m1)), m0);
            }
            return;
        }
        // a window that covers what is needed is used in place (offset), others are copied
        let (s, off) = src.win.covering(m0, m1);
        let off = off as i64;
        for (k, kx) in (k0..k1).enumerate() {
            let ph = &taps.phases[kx.rem_euclid(taps.p) as usize];
            let base = (taps.qs * kx.div_euclid(taps.p) + ph.b - m0 + off) as usize;
            let n = ph.w.len();
            self.w[k] += ph.wsum;
            if ch == 1 {
                self.v[k] += dot(&ph.w, &s.v[base..base + n]);
            } else {
                for (t, &wt) in ph.w.iter().enumerate() {
                    for q in 0..ch {
                        self.v[k * ch + q] += wt * s.v[(base + t) * ch + q];
                    }
                }
            }
            self.c[k] += if s.full {
                ph.wsum
            } else {
                dot(&ph.w, &s.c[base..base + n])
            };
        }
    }

    /// One phase, one channel: tap by tap over all columns (`acc[k] += w_t·src[qs·k + b + t]`),
    /// on the source's `qs` polyphase components so that every tap is a contiguous,
    /// vectorisable multiply-add. `first` is the source index of `src`'s first sample. Same sums
    /// in the same order as the per-column loop's partial sums would not be: results differ from
    /// it in the last bits, but are the same on every machine and thread count.
    fn add_polyphase(&mut self, taps: &PairTaps, src: &SourceRow, first: i64) {
        let ph = &taps.phases[0];
        let qs = taps.qs as usize;
        let len = self.w.len();
        let base0 = (taps.qs * self.first + ph.b - first) as usize;
        for w in &mut self.w {
            *w += ph.wsum;
        }
        let s = &src.win;
        let split = (qs > 1).then(|| src.split(qs));
        // tap t reads sample base0 + t + qs·k for column k: in component (base0 + t) mod qs
        fn tap_sources<'a>(
            w: &[f64],
            (base0, qs, len): (usize, usize, usize),
            whole: &'a [f64],
            comps: Option<&'a [Vec<f64>]>,
        ) -> Vec<(f64, &'a [f64])> {
            w.iter()
                .enumerate()
                .map(|(t, &w)| {
                    let i = base0 + t;
                    let x = match comps {
                        None => &whole[i..i + len],
                        Some(c) => &c[i % qs][i / qs..i / qs + len],
                    };
                    (w, x)
                })
                .collect()
        }
        let at = (base0, qs, len);
        lanes::taps_into(
            &mut self.v,
            &tap_sources(&ph.w, at, &s.v, split.as_ref().map(|x| x.v.as_slice())),
        );
        if s.full {
            for c in &mut self.c {
                *c += ph.wsum;
            }
        } else {
            lanes::taps_into(
                &mut self.c,
                &tap_sources(&ph.w, at, &s.c, split.as_ref().map(|x| x.c.as_slice())),
            );
        }
    }

    /// The filtered row: premultiplied values and coverage divided by the weight (a column with
    /// no weight has no coverage), in the sums' own buffers.
    pub fn finish(mut self) -> RowWindow {
        let ch = self.ch;
        let mut full = true;
        for (k, &w) in self.w.iter().enumerate() {
            let (v, c) = (&mut self.v[k * ch..(k + 1) * ch], &mut self.c[k]);
            if w.abs() > 1e-300 {
                v.iter_mut().for_each(|x| *x /= w);
                *c /= w;
            } else {
                v.fill(0.0);
                *c = 0.0;
            }
            full &= *c == 1.0;
        }
        RowWindow {
            n: self.n,
            first: self.first,
            ch,
            v: self.v,
            c: self.c,
            full,
        }
    }
}

/// The filters' multiply-adds over many taps, compiled again for AVX-512 and AVX2 and chosen at
/// run time. Multiplications and additions stay separate operations in the same order, so every
/// version gives the same bits.
#[allow(unsafe_code)]
mod lanes {
    /// `acc[k] += w·x[k]` for each `(w, x)` of `taps` in turn (each `x` at least as long as
    /// `acc`): the rounding of one pass over `acc` per tap, with blocks of `acc` held in registers
    /// across the taps.
    pub(super) fn taps_into(acc: &mut [f64], taps: &[(f64, &[f64])]) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            if has!("avx512f") {
                // SAFETY: the CPU has every feature the function is compiled for
                return unsafe { avx512(acc, taps) };
            }
            if has!("avx2") {
                // SAFETY: as above
                return unsafe { avx2(acc, taps) };
            }
        }
        blocks::<8>(acc, taps);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2")]
    fn avx512(acc: &mut [f64], taps: &[(f64, &[f64])]) {
        blocks::<32>(acc, taps);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn avx2(acc: &mut [f64], taps: &[(f64, &[f64])]) {
        blocks::<16>(acc, taps);
    }

    #[inline(always)]
    fn blocks<const B: usize>(acc: &mut [f64], taps: &[(f64, &[f64])]) {
        let len = acc.len();
        let mut k0 = 0;
        while k0 + B <= len {
            let mut a = [0.0f64; B];
            a.copy_from_slice(&acc[k0..k0 + B]);
            for &(w, x) in taps {
                let x = &x[k0..k0 + B];
                for i in 0..B {
                    a[i] += w * x[i];
                }
            }
            acc[k0..k0 + B].copy_from_slice(&a);
            k0 += B;
        }
        for &(w, x) in taps {
            for (a, x) in acc[k0..].iter_mut().zip(&x[k0..len]) {
                *a += w * x;
            }
        }
    }
}

/// Dot product in four interleaved partial sums (a fixed order: results do not depend on the
/// machine or the thread count).
#[inline]
fn dot(w: &[f64], x: &[f64]) -> f64 {
    let mut s = [0.0f64; 4];
    let (wc, wr) = w.split_at(w.len() / 4 * 4);
    let (xc, xr) = x.split_at(wc.len());
    for (a, b) in wc.chunks_exact(4).zip(xc.chunks_exact(4)) {
        s[0] += a[0] * b[0];
        s[1] += a[1] * b[1];
        s[2] += a[2] * b[2];
        s[3] += a[3] * b[3];
    }
    let mut r = (s[0] + s[1]) + (s[2] + s[3]);
    for (a, b) in wr.iter().zip(xr) {
        r += a * b;
    }
    r
}

/// Where the rows of one level come from: the stored representations of a level (isotropic and
/// anisotropic), read as windows of periodic rows.
pub trait StoredRows {
    /// Error of reading.
    type Error;
    /// Rows of the level.
    fn height(&self) -> u64;
    /// Samples in a row of anisotropy `a`.
    fn width(&self, a: u32) -> u64;
    /// The largest stored anisotropy ≤ `a` that holds row `j`.
    fn best_stored(&self, j: u64, a: u32) -> u32;
    /// Samples `m0..m1` (periodic) of row `j` of stored anisotropy `a`.
    fn read(&mut self, j: u64, a: u32, m0: i64, m1: i64) -> Result<RowWindow, Self::Error>;
}

/// Reads rows of a [`StoredRows`] at any anisotropy, halving from the best stored one; whole rows
/// made on the way are kept (a polar row is made once per reader).
#[derive(Debug)]
pub struct RowReader<S> {
    /// The stored rows.
    pub src: S,
    whole: HashMap<(u64, u32), Rc<RowWindow>>,
}

impl<S: StoredRows> RowReader<S> {
    /// A reader over `src`.
    pub fn new(src: S) -> Self {
        Self {
            src,
            whole: HashMap::new(),
        }
    }

    /// Forgets whole rows above row `j` (call as a band moves south).
    pub fn forget_rows_before(&mut self, j: u64) {
        self.whole.retain(|&(r, _), _| r >= j);
    }

    /// Samples `m0..m1` of row `j` at anisotropy `a`.
    pub fn window(&mut self, j: u64, a: u32, m0: i64, m1: i64) -> Result<RowWindow, S::Error> {
        let a_s = self.src.best_stored(j, a);
        if a_s >= a {
            return self.src.read(j, a_s, m0, m1);
        }
        let n = self.src.width(a);
        if (m1 - m0) as u64 >= n {
            let w = self.whole_row(j, a)?;
            return Ok(w.sub(m0, m1));
        }
        let (f0, f1) = halve_needs(m0, m1);
        let fine = self.window(j, a - 1, f0, f1)?;
        Ok(halve(&fine, m0, m1))
    }

    fn whole_row(&mut self, j: u64, a: u32) -> Result<Rc<RowWindow>, S::Error> {
        if let Some(w) = self.whole.get(&(j, a)) {
            return Ok(w.clone());
        }
        let n = self.src.width(a) as i64;
        let (f0, f1) = halve_needs(0, n);
        let fine = self.window(j, a - 1, f0, f1)?;
        let w = Rc::new(halve(&fine, 0, n));
        self.whole.insert((j, a), w.clone());
        Ok(w)
    }
}

/// The filter from isotropic level ℓ+1 onto isotropic level ℓ.
#[derive(Debug, Clone)]
pub struct LevelFilter {
    grid: GridSpec,
    to: LevelId,
    lut: KernelLut,
    rho: f64,
    reach: f64,
}

impl LevelFilter {
    /// The filter onto isotropic level `to` (from `to + 1`) with `kernel`.
    pub fn new(grid: GridSpec, to: u32, kernel: Kernel) -> Self {
        let to = LevelId {
            level: to,
            aniso: 0,
        };
        let rho = PI / grid.height(to) as f64;
        Self {
            grid,
            to,
            lut: KernelLut::new(kernel),
            rho,
            reach: kernel.support() * rho,
        }
    }

    /// Output rows `r0..r1`, columns `c0..c1` of the full-width level (periodic), as filtered
    /// rows (premultiplied, coverage), from `src` rows of level ℓ+1.
    pub fn filter_band<S: StoredRows>(
        &self,
        src: &mut RowReader<S>,
        ch: usize,
        (r0, r1): (u64, u64),
        (c0, c1): (i64, i64),
    ) -> Result<Vec<RowWindow>, S::Error> {
        let h = self.grid.height(self.to);
        let w = self.grid.width(self.to);
        let hs = src.src.height();
        let ws = src.src.width(0);
        let max_out = w.trailing_zeros().saturating_sub(3);
        let max_src = ws.trailing_zeros().saturating_sub(2);
        let mut rows = Vec::with_capacity((r1 - r0) as usize);
        // source rows serve ~2·reach/ρ' consecutive output rows with the same window: keep the
        // rows of the current reach
        let mut recent: HashMap<(u64, u32), Rc<SourceRow>> = HashMap::new();
        for j in r0..r1 {
            // every row at its centre, the pole rows too (the kernel's circle reaches across
            // the pole: a source row's taps span all its longitudes there)
            let lat = row_lat(j, h);
            let (n_nat, u) = {
                let a = output_natural_aniso(lat, max_out);
                (w >> a, 1u64 << a)
            };
            let (k0, k1) = if u == 1 {
                (c0, c1)
            } else {
                let (k0, k1) = upsample_needs(u, c0, c1);
                if (k1 - k0) as u64 >= n_nat {
                    (0, n_nat as i64)
                } else {
                    (k0, k1)
                }
            };
            let mut acc = RowAcc::new(n_nat, k0, k1, ch);
            // source rows within reach in latitude
            let js0 = (((PI / 2.0 - (lat + self.reach)) / (PI / hs as f64))
                .floor()
                .max(0.0)) as u64;
            let js1 =
                ((((PI / 2.0 - (lat - self.reach)) / (PI / hs as f64)).ceil()) as u64).min(hs);
            // rows go south: the rows north of this reach serve no later output row
            recent.retain(|&(r, _), _| r >= js0);
            for js in js0..js1 {
                let lat_s = row_lat(js, hs);
                let a_s = source_natural_aniso(lat_s, max_src);
                let n_src = ws >> a_s;
                let Some(taps) = PairTaps::new(
                    &self.lut,
                    self.rho,
                    (lat, n_nat),
                    (lat_s, n_src),
                    row_band_area(js, hs),
                ) else {
                    continue;
                };
                let (m0, m1) = taps.needs(k0, k1);
                if m1 <= m0 {
                    continue;
                }
                let win = match recent.get(&(js, a_s)) {
                    Some(w) if w.win.first <= m0 && m1 <= w.win.first + w.win.len() as i64 => {
                        w.clone()
                    }
                    _ => {
                        // a little wider than this pair needs: the next rows' reach differs by
                        // a few samples
                        let pad = 8 + (m1 - m0) / 16;
                        let w = Rc::new(SourceRow::new(src.window(js, a_s, m0 - pad, m1 + pad)?));
                        recent.insert((js, a_s), w.clone());
                        w
                    }
                };
                acc.add(&taps, &win);
            }
            let nat = acc.finish();
            rows.push(
                if u == 1 && nat.first == c0 && nat.len() as i64 == c1 - c0 {
                    // the natural row is the stored one
                    nat
                } else {
                    upsample(&nat, u, c0, c1)
                },
            );
        }
        Ok(rows)
    }
}

/// A whole level in memory (row-major, `ch` channels premultiplied + coverage), as stored rows:
/// the in-memory twin of the store-backed builder, for tests and analytic signals.
#[derive(Debug, Clone)]
pub struct MemLevels {
    grid: GridSpec,
    level: u32,
    ch: usize,
    /// anisotropy → rows (one window per row; empty windows for rows not stored)
    data: HashMap<u32, Vec<RowWindow>>,
}

impl MemLevels {
    /// Isotropic level `level` of `values` (row-major, `ch` channels, NaN = nodata).
    pub fn from_values(grid: GridSpec, level: u32, ch: usize, values: &[f64]) -> Self {
        let l = LevelId { level, aniso: 0 };
        let (w, h) = (grid.width(l) as usize, grid.height(l) as usize);
        assert_eq!(values.len(), w * h * ch, "level size");
        let rows = (0..h)
            .map(|j| {
                let mut r = RowWindow::empty(w as u64, 0, w, ch);
                let mut full = true;
                for i in 0..w {
                    let px = &values[(j * w + i) * ch..(j * w + i + 1) * ch];
                    if px.iter().all(|x| x.is_finite()) {
                        r.v[i * ch..(i + 1) * ch].copy_from_slice(px);
                        r.c[i] = 1.0;
                    } else {
                        full = false;
                    }
                }
                r.full = full;
                r
            })
            .collect();
        Self {
            grid,
            level,
            ch,
            data: HashMap::from([(0, rows)]),
        }
    }

    /// Builds the anisotropic levels (level, 1..=max) by halving, on the rows the grid stores.
    pub fn build_aniso(&mut self) {
        for a in LevelId::aniso_levels_of(self.level) {
            let id = a;
            let h = self.grid.height(id);
            let w = self.grid.width(id) as i64;
            let t = u64::from(self.grid.tile_size());
            let rows: Vec<RowWindow> = (0..h)
                .map(|j| {
                    if self.grid.level_has_tile_row(id, j / t) {
                        let (f0, f1) = halve_needs(0, w);
                        let fine = self.data[&(id.aniso - 1)][j as usize].sub(f0, f1);
                        halve(&fine, 0, w)
                    } else {
                        RowWindow::empty(w as u64, 0, 0, self.ch)
                    }
                })
                .collect();
            self.data.insert(id.aniso, rows);
        }
    }

    /// The next coarser level, filtered with `kernel`, its anisotropic levels built.
    pub fn coarser(&self, kernel: Kernel) -> MemLevels {
        let to = self.level - 1;
        let f = LevelFilter::new(self.grid, to, kernel);
        let l = LevelId {
            level: to,
            aniso: 0,
        };
        let (w, h) = (self.grid.width(l), self.grid.height(l));
        let mut reader = RowReader::new(self);
        let rows = match f.filter_band(&mut reader, self.ch, (0, h), (0, w as i64)) {
            Ok(r) => r,
            Err(e) => match e {},
        };
        let mut out = MemLevels {
            grid: self.grid,
            level: to,
            ch: self.ch,
            data: HashMap::from([(0, rows)]),
        };
        out.build_aniso();
        out
    }

    /// The level.
    pub fn level(&self) -> u32 {
        self.level
    }

    /// Values of anisotropic level `a` (row-major, NaN for nodata and for rows not stored),
    /// heights' rule: valid where coverage ≥ [`MIN_COVERAGE`].
    pub fn values(&self, a: u32) -> Vec<f64> {
        let id = LevelId {
            level: self.level,
            aniso: a,
        };
        let (w, h) = (self.grid.width(id) as usize, self.grid.height(id) as usize);
        let mut out = vec![f64::NAN; w * h * self.ch];
        for (j, r) in self.data[&a].iter().enumerate().take(h) {
            for i in 0..r.len() {
                if r.c[i] >= MIN_COVERAGE {
                    for q in 0..self.ch {
                        out[(j * w + i) * self.ch + q] = r.v[i * self.ch + q] / r.c[i];
                    }
                }
            }
        }
        out
    }
}

impl StoredRows for &MemLevels {
    type Error = std::convert::Infallible;

    fn height(&self) -> u64 {
        self.grid.height(LevelId {
            level: self.level,
            aniso: 0,
        })
    }

    fn width(&self, a: u32) -> u64 {
        self.grid.width(LevelId {
            level: self.level,
            aniso: 0,
        }) >> a
    }

    fn best_stored(&self, j: u64, a: u32) -> u32 {
        let t = u64::from(self.grid.tile_size());
        (0..=a)
            .rev()
            .find(|&x| {
                x == 0
                    || (self.data.contains_key(&x)
                        && LevelId::new(self.level, x)
                            .is_ok_and(|id| self.grid.level_has_tile_row(id, j / t)))
            })
            .unwrap_or(0)
    }

    fn read(&mut self, j: u64, a: u32, m0: i64, m1: i64) -> Result<RowWindow, Self::Error> {
        Ok(self.data[&a][j as usize].sub(m0, m1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> GridSpec {
        GridSpec::new(16).expect("valid")
    }

    #[test]
    fn halving_and_upsampling_keep_constants_and_low_frequencies() {
        let n = 64u64;
        let mut r = RowWindow::empty(n, 0, n as usize, 1);
        for i in 0..n as usize {
            let x = 2.0 * PI * (i as f64 + 0.5) / n as f64;
            r.v[i] = 5.0 + (3.0 * x).cos();
            r.c[i] = 1.0;
        }
        r.full = true;
        let h = halve(&r, 0, 32);
        for (k, v) in h.v.iter().enumerate() {
            let x = 2.0 * PI * (k as f64 + 0.5) / 32.0;
            assert!((v - 5.0 - (3.0 * x).cos()).abs() < 0.01, "{k}: {v}");
        }
        let u = upsample(&h, 4, -5, 200);
        for (k, v) in u.v.iter().enumerate() {
            let i = k as i64 - 5;
            let x = 2.0 * PI * (i as f64 + 0.5) / 128.0;
            assert!((v - 5.0 - (3.0 * x).cos()).abs() < 0.01, "{i}: {v}");
        }
    }

    #[test]
    fn pair_tap_weights_sum_to_the_covered_area_and_are_symmetric() {
        let lut = KernelLut::new(Kernel::JincLanczos3);
        let rho = PI / 64.0;
        for (lat, lat_s) in [(0.1, 0.12), (1.3, 1.32), (1.5, 1.53)] {
            let t = PairTaps::new(&lut, rho, (lat, 128), (lat_s, 256), 1.0).expect("reach");
            assert_eq!(t.p, 1);
            let w = &t.phases[0].w;
            for k in 0..w.len() {
                assert!((w[k] - w[w.len() - 1 - k]).abs() < 1e-12);
            }
        }
        // out of reach
        assert!(PairTaps::new(&lut, rho, (0.0, 128), (0.5, 256), 1.0).is_none());
    }

    #[test]
    fn polyphase_components_take_every_qth_sample() {
        for len in 0..11 {
            let x: Vec<f64> = (0..len).map(|i| i as f64 * 1.5 - 2.0).collect();
            let by_step = |q: usize| -> Vec<Vec<f64>> {
                (0..q)
                    .map(|r| x.iter().skip(r).step_by(q).copied().collect())
                    .collect()
            };
            assert_eq!(deinterleave::<2>(&x), by_step(2), "{len} samples");
            assert_eq!(deinterleave::<4>(&x), by_step(4), "{len} samples");
        }
    }

    #[test]
    fn taps_in_lanes_give_the_bits_of_one_pass_per_tap() {
        let mut state = 7u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        // lengths around every block size, few and many taps, values of mixed magnitude
        for len in [0, 1, 7, 8, 9, 15, 16, 17, 31, 32, 33, 63, 100, 257] {
            for ntaps in [1, 2, 12, 41] {
                let xs: Vec<Vec<f64>> = (0..ntaps)
                    .map(|_| (0..len + 3).map(|_| next() * 1e4).collect())
                    .collect();
                let ws: Vec<f64> = (0..ntaps).map(|_| next()).collect();
                let start: Vec<f64> = (0..len).map(|_| next() * 1e-3).collect();
                let mut want = start.clone();
                for (w, x) in ws.iter().zip(&xs) {
                    for (a, x) in want.iter_mut().zip(x) {
                        *a += w * x;
                    }
                }
                let mut got = start;
                let taps: Vec<(f64, &[f64])> =
                    ws.iter().zip(&xs).map(|(&w, x)| (w, &x[..])).collect();
                lanes::taps_into(&mut got, &taps);
                assert!(
                    want.iter()
                        .zip(&got)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{len} columns, {ntaps} taps"
                );
            }
        }
    }

    #[test]
    fn constants_stay_exact_on_every_row_and_level() {
        let g = grid();
        let l = LevelId::iso(3).expect("valid");
        let (w, h) = (g.width(l) as usize, g.height(l) as usize);
        let vals: Vec<f64> = (0..w * h).map(|_| 1234.5678f32 as f64).collect();
        let mut m = MemLevels::from_values(g, 3, 1, &vals);
        m.build_aniso();
        let mut cur = m;
        while cur.level() > 0 {
            cur = cur.coarser(Kernel::JincLanczos3);
            for a in 0..=cur.level().min(crate::ANISO_MAX) {
                for v in cur.values(a).iter().filter(|v| !v.is_nan()) {
                    assert_eq!(*v as f32, 1234.5678f32, "level {} a {a}", cur.level());
                }
            }
        }
    }
}
