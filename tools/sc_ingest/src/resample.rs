//! Resampling one source onto one output tile with an elliptical footprint that is a circle on the
//! sphere (see `sc_core::Footprint`): antialiasing where the source is finer than the output,
//! interpolation where it is coarser, the same world-space rule as the pyramid.
//!
//! Nodata never bleeds: invalid samples get zero weight and the rest are renormalised. An output
//! texel is nodata where the valid samples carry less than [`MIN_COVERAGE`] of the footprint's
//! positive weight (samples outside the raster count as invalid).

use sc_core::{Footprint, GridSpec, Kernel, KernelLut, TileId};
use sc_raster::{RasterSource, Result, Window};

/// Fraction of the footprint's positive weight that valid samples must carry.
pub const MIN_COVERAGE: f64 = 0.5;

/// Resampled samples of one source for one tile: `planes[p][k]` for texel k (row-major), NaN in
/// plane 0 where the source has nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct TileSamples {
    /// One plane for heights; R, G, B (linear) and alpha for colour.
    pub planes: Vec<Vec<f32>>,
}

/// Per-texel geometry: source pixel position and footprint.
struct TexelMap {
    x: Vec<f64>,
    y: Vec<f64>,
    foot: Vec<Option<Footprint>>,
}

fn texel_map(src: &RasterSource, grid: GridSpec, tile: TileId, kernel: Kernel) -> TexelMap {
    let t = grid.tile_size() as usize;
    let info = src.info();
    let level = tile.level;
    let (ox, oy) = tile.origin_texel(grid);
    let (dlon_deg, dlat_deg) = grid.texel_deg(level);
    let rho = std::f64::consts::PI / grid.height(level) as f64;
    let n = t + 2;
    // texel centres with a one-texel margin, for finite-difference Jacobians
    let mut xs = Vec::with_capacity(n * n);
    let mut ys = Vec::with_capacity(n * n);
    let mut lats = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let lon = -180.0 + (ox as f64 + i as f64 - 0.5) * dlon_deg;
            let lat = 90.0 - (oy as f64 + j as f64 - 0.5) * dlat_deg;
            xs.push(lon);
            ys.push(lat.clamp(-90.0, 90.0));
            lats.push(lat);
        }
    }
    src.lonlat_to_pixel(&mut xs, &mut ys);
    let gt = info.geotransform;
    // unwrap geographic x around the tile centre, so the tile's footprints form one window
    if let (true, Some(p)) = (info.geographic, info.lon_period_px) {
        let c = xs[(n / 2) * n + n / 2];
        for x in xs.iter_mut() {
            *x = c + ((*x - c + p / 2.0).rem_euclid(p) - p / 2.0);
        }
    } else if info.geographic {
        // a regional geographic source: put x nearest to the raster
        let period = 360.0 / gt[1].abs();
        let w = info.width as f64;
        for x in xs.iter_mut() {
            if *x > w && *x - period > -w {
                *x -= period;
            }
        }
    }
    let mut map = TexelMap {
        x: Vec::with_capacity(t * t),
        y: Vec::with_capacity(t * t),
        foot: Vec::with_capacity(t * t),
    };
    let deg = 180.0 / std::f64::consts::PI;
    let at = |i: usize, j: usize| (xs[j * n + i], ys[j * n + i]);
    for j in 1..=t {
        for i in 1..=t {
            let (x, y) = at(i, j);
            map.x.push(x);
            map.y.push(y);
            if !x.is_finite() || !y.is_finite() {
                map.foot.push(None);
                continue;
            }
            if kernel == Kernel::Nearest {
                map.foot.push(None);
                continue;
            }
            let lat = lats[j * n + i];
            let coslat = lat.to_radians().cos().max(1e-12);
            let jac = if info.geographic {
                [[deg / gt[1] / coslat, 0.0], [0.0, deg / gt[5]]]
            } else {
                // central differences, one-sided where a neighbour failed to transform
                let diff = |a: (f64, f64), b: (f64, f64), c: (f64, f64), span: f64| -> (f64, f64) {
                    if a.0.is_finite() && b.0.is_finite() {
                        ((b.0 - a.0) / (2.0 * span), (b.1 - a.1) / (2.0 * span))
                    } else if b.0.is_finite() {
                        ((b.0 - c.0) / span, (b.1 - c.1) / span)
                    } else if a.0.is_finite() {
                        ((c.0 - a.0) / span, (c.1 - a.1) / span)
                    } else {
                        (f64::NAN, f64::NAN)
                    }
                };
                let c = (x, y);
                let (dxl, dyl) = diff(at(i - 1, j), at(i + 1, j), c, dlon_deg.to_radians());
                // rows go south: north = −j
                let (dxn, dyn_) = diff(at(i, j + 1), at(i, j - 1), c, dlat_deg.to_radians());
                [[dxl / coslat, dxn], [dyl / coslat, dyn_]]
            };
            if jac.iter().flatten().any(|v| !v.is_finite()) {
                map.foot.push(None);
                continue;
            }
            map.foot.push(Some(Footprint::new(jac, rho)));
        }
    }
    map
}

/// Resamples `src` onto `tile` with `lut`'s kernel. Returns `None` when the source contributes
/// nothing to the tile.
pub fn resample_tile(src: &RasterSource, grid: GridSpec, tile: TileId, lut: &KernelLut) -> Result<Option<TileSamples>> {
    let kernel = lut.kernel();
    let info = src.info();
    let t = grid.tile_size() as usize;
    let map = texel_map(src, grid, tile, kernel);
    let support = kernel.support();
    let period = info.lon_period_px;
    let (w, h) = (info.width as f64, info.height as f64);
    // the source rectangle the whole tile needs
    let (mut cmin, mut cmax, mut rmin, mut rmax) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    let mut half = Vec::with_capacity(t * t);
    for k in 0..t * t {
        let (x, y) = (map.x[k], map.y[k]);
        if !x.is_finite() {
            half.push((0.0, 0.0));
            continue;
        }
        let (mut hx, hy) = match &map.foot[k] {
            Some(f) => f.half_extent(support),
            None => (0.5, 0.5),
        };
        if let Some(p) = period {
            hx = hx.min(p / 2.0);
        }
        half.push((hx, hy));
        // skip texels whose whole footprint misses a non-wrapping source
        let wraps_x = period.is_some();
        let reaches_pole = info.north_pole_y.is_some() || info.south_pole_y.is_some();
        if (!wraps_x && (x + hx < 0.0 || x - hx > w)) || (!reaches_pole && (y + hy < 0.0 || y - hy > h)) {
            continue;
        }
        cmin = cmin.min((x - hx).floor());
        cmax = cmax.max((x + hx).ceil());
        rmin = rmin.min((y - hy).floor());
        rmax = rmax.max((y + hy).ceil());
    }
    if !cmin.is_finite() {
        return Ok(None);
    }
    if period.is_none() {
        cmin = cmin.max(-1.0);
        cmax = cmax.min(w + 1.0);
    }
    if info.north_pole_y.is_none() {
        rmin = rmin.max(-1.0);
    }
    if info.south_pole_y.is_none() {
        rmax = rmax.min(h + 1.0);
    }
    let win = src.read_region(cmin as i64, rmin as i64, (cmax - cmin + 1.0) as usize, (rmax - rmin + 1.0) as usize)?;
    let nplanes = win.planes.len();
    let mut out = vec![vec![f32::NAN; t * t]; nplanes];
    let mut any = false;
    let mut acc = vec![0f64; nplanes];
    for k in 0..t * t {
        let (x, y) = (map.x[k], map.y[k]);
        if !x.is_finite() {
            continue;
        }
        let done = match &map.foot[k] {
            None => nearest(&win, x, y, &mut acc),
            Some(f) => filtered(&win, f, lut, x, y, half[k], &mut acc),
        };
        if done {
            for p in 0..nplanes {
                out[p][k] = acc[p] as f32;
            }
            any = true;
        }
    }
    Ok(any.then_some(TileSamples { planes: out }))
}

fn sample(win: &Window, c: i64, r: i64, p: usize) -> f32 {
    let (cc, rr) = (c - win.c0, r - win.r0);
    if cc < 0 || rr < 0 || cc >= win.w as i64 || rr >= win.h as i64 {
        return f32::NAN;
    }
    win.planes[p][rr as usize * win.w + cc as usize]
}

fn nearest(win: &Window, x: f64, y: f64, acc: &mut [f64]) -> bool {
    let (c, r) = (x.floor() as i64, y.floor() as i64);
    if sample(win, c, r, 0).is_nan() {
        return false;
    }
    for (p, a) in acc.iter_mut().enumerate() {
        *a = f64::from(sample(win, c, r, p));
    }
    true
}

fn filtered(win: &Window, f: &Footprint, lut: &KernelLut, x: f64, y: f64, half: (f64, f64), acc: &mut [f64]) -> bool {
    let (hx, hy) = half;
    let (c0, c1) = ((x - hx).floor() as i64, (x + hx).ceil() as i64);
    let (r0, r1) = ((y - hy).floor() as i64, (y + hy).ceil() as i64);
    let s2 = lut.support2();
    acc.iter_mut().for_each(|a| *a = 0.0);
    let (mut wsum, mut wpos_all, mut wpos_valid) = (0.0, 0.0, 0.0);
    for r in r0..=r1 {
        let dy = r as f64 + 0.5 - y;
        let rr = r - win.r0;
        let row_ok = rr >= 0 && rr < win.h as i64;
        for c in c0..=c1 {
            let dx = c as f64 + 0.5 - x;
            let d2 = f.dist2(dx, dy);
            if d2 >= s2 {
                continue;
            }
            let wgt = lut.weight_d2(d2);
            if wgt > 0.0 {
                wpos_all += wgt;
            }
            let cc = c - win.c0;
            if !row_ok || cc < 0 || cc >= win.w as i64 {
                continue;
            }
            let idx = rr as usize * win.w + cc as usize;
            let v0 = win.planes[0][idx];
            if v0.is_nan() {
                continue;
            }
            if wgt > 0.0 {
                wpos_valid += wgt;
            }
            wsum += wgt;
            acc[0] += wgt * f64::from(v0);
            for (p, a) in acc.iter_mut().enumerate().skip(1) {
                *a += wgt * f64::from(win.planes[p][idx]);
            }
        }
    }
    if wpos_all <= 0.0 || wpos_valid < MIN_COVERAGE * wpos_all || wsum.abs() < 1e-6 * wpos_all {
        return false;
    }
    acc.iter_mut().for_each(|a| *a /= wsum);
    true
}
