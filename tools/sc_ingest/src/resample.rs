//! Resampling one source onto one output tile with an elliptical footprint that is a circle on the
//! sphere (see `sc_core::Footprint`): antialiasing where the source is finer than the output,
//! interpolation where it is coarser, the same world-space rule as the pyramid.
//!
//! Nodata never bleeds: invalid samples get zero weight and the rest are renormalised. An output
//! texel is nodata where the valid samples carry less than [`MIN_COVERAGE`] of the footprint's
//! positive weight (samples outside the raster count as invalid) — the pyramid's rule.

use sc_core::pyramid::MIN_COVERAGE;
use sc_core::{Footprint, GridSpec, Kernel, KernelLut, TileId};
use sc_raster::{RasterSource, Result, SourceInfo, Window};

/// Resampled samples of one source for one tile: `planes[p][k]` for texel k (row-major), NaN in
/// plane 0 where the source has nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct TileSamples {
    /// One plane for heights; R, G, B (linear) and alpha for colour.
    pub planes: Vec<Vec<f32>>,
    /// Texels of the tile whose centre lies inside the source raster (its footprint), valid
    /// or not.
    pub footprint: u32,
    /// Texels of the footprint that hold a valid value (texels just outside it may be valid
    /// too, where the kernel reaches in).
    pub covered: u32,
}

/// Anything resampling can read: where its pixels are ([`SourceInfo`]: a pixel-is-area affine
/// transform, wrapping, poles), lon/lat → pixel, and windows of planes with NaN for nodata.
/// Implemented by GDAL/EXR inputs ([`RasterSource`]) and by store levels (the pyramid builder).
pub trait PixelSource {
    /// Geometry and sample description.
    fn info(&self) -> &SourceInfo;
    /// Lon/lat degrees → fractional pixel coordinates, in place (NaN where it cannot).
    fn lonlat_to_pixel(&self, x: &mut [f64], y: &mut [f64]);
    /// Pixels `[c0, c0+w) × [r0, r0+h)`, wrapping and crossing poles as the source allows.
    fn read_region(&self, c0: i64, r0: i64, w: usize, h: usize) -> Result<Window>;
}

impl PixelSource for RasterSource {
    fn info(&self) -> &SourceInfo {
        RasterSource::info(self)
    }
    fn lonlat_to_pixel(&self, x: &mut [f64], y: &mut [f64]) {
        RasterSource::lonlat_to_pixel(self, x, y);
    }
    fn read_region(&self, c0: i64, r0: i64, w: usize, h: usize) -> Result<Window> {
        RasterSource::read_region(self, c0, r0, w, h)
    }
}

/// A texel's reach along x (source pixels): a texel of a wrapping source reaches at most half
/// the circle, and a pole texel the whole circle of longitudes, whatever its kernel's reach.
fn reach_x(hx: f64, period: Option<f64>, pole: bool) -> f64 {
    match period {
        Some(p) if pole => p / 2.0,
        Some(p) => hx.min(p / 2.0),
        None => hx,
    }
}

/// The source pixels a tile's footprints reach: the bounds of `[x − hx, x + hx] × [y − hy,
/// y + hy]` over its texels (infinite while none reaches the source).
struct Reach {
    cols: (f64, f64),
    rows: (f64, f64),
}

impl Default for Reach {
    fn default() -> Self {
        Self {
            cols: (f64::INFINITY, f64::NEG_INFINITY),
            rows: (f64::INFINITY, f64::NEG_INFINITY),
        }
    }
}

impl Reach {
    /// Texels at source x `x0..=x1` and source y `y` with reach `(hx, hy)`.
    fn add(&mut self, (x0, x1): (f64, f64), (hx, hy): (f64, f64), y: f64) {
        self.cols = (
            self.cols.0.min((x0 - hx).floor()),
            self.cols.1.max((x1 + hx).ceil()),
        );
        self.rows = (
            self.rows.0.min((y - hy).floor()),
            self.rows.1.max((y + hy).ceil()),
        );
    }

    /// Reads the window, clamped to one pixel beyond the edges the source does not wrap or
    /// cross; `None` where no footprint reaches the source.
    fn read(self, src: &dyn PixelSource) -> Result<Option<Window>> {
        let ((mut cmin, mut cmax), (mut rmin, mut rmax)) = (self.cols, self.rows);
        if !cmin.is_finite() {
            return Ok(None);
        }
        let info = src.info();
        let (w, h) = (info.width as f64, info.height as f64);
        if info.lon_period_px.is_none() {
            cmin = cmin.max(-1.0);
            cmax = cmax.min(w + 1.0);
        }
        if info.north_pole_y.is_none() {
            rmin = rmin.max(-1.0);
        }
        if info.south_pole_y.is_none() {
            rmax = rmax.min(h + 1.0);
        }
        src.read_region(
            cmin as i64,
            rmin as i64,
            (cmax - cmin + 1.0) as usize,
            (rmax - rmin + 1.0) as usize,
        )
        .map(Some)
    }
}

/// Per-texel geometry: source pixel position and footprint.
struct TexelMap {
    x: Vec<f64>,
    y: Vec<f64>,
    foot: Vec<Option<Footprint>>,
}

/// Longitudes (degrees) of the tile's texel columns with a one-texel margin: entry i is column
/// `origin − 1 + i`.
fn padded_lons(grid: GridSpec, tile: TileId) -> Vec<f64> {
    let (ox, _) = tile.origin_texel(grid);
    let (dlon_deg, _) = grid.texel_deg(tile.level);
    (0..grid.tile_size() as usize + 2)
        .map(|i| -180.0 + (ox as f64 + i as f64 - 0.5) * dlon_deg)
        .collect()
}

/// Latitudes (degrees) of the tile's texel rows with a one-texel margin: entry j is level row
/// `origin − 1 + j`, at its centre (the pole rows too: their centres lie half a row from the
/// pole, and a band-limited field varies along them).
fn padded_lats(grid: GridSpec, tile: TileId) -> Vec<f64> {
    let (_, oy) = tile.origin_texel(grid);
    let (_, dlat_deg) = grid.texel_deg(tile.level);
    (0..grid.tile_size() as usize + 2)
        .map(|j| 90.0 - (oy as f64 + j as f64 - 0.5) * dlat_deg)
        .collect()
}

/// The footprint of texels at latitude `lat_deg` over a lon/lat source with geotransform `gt`
/// (`None` where the Jacobian is not finite).
fn lonlat_footprint(gt: [f64; 6], lat_deg: f64, rho: f64) -> Option<Footprint> {
    let deg = 180.0 / std::f64::consts::PI;
    let coslat = lat_deg.to_radians().cos().max(1e-12);
    let jac = [[deg / gt[1] / coslat, 0.0], [0.0, deg / gt[5]]];
    jac.iter()
        .flatten()
        .all(|v| v.is_finite())
        .then(|| Footprint::new(jac, rho))
}

fn texel_map(src: &dyn PixelSource, grid: GridSpec, tile: TileId, kernel: Kernel) -> TexelMap {
    let t = grid.tile_size() as usize;
    let info = src.info();
    if info.geographic {
        return lonlat_texel_map(&lonlat_axes(src, grid, tile), kernel);
    }
    let level = tile.level;
    let (dlon_deg, dlat_deg) = grid.texel_deg(level);
    let rho = std::f64::consts::PI / grid.height(level) as f64;
    let n = t + 2;
    // texel centres with a one-texel margin, for finite-difference Jacobians
    let (lons, lats) = (padded_lons(grid, tile), padded_lats(grid, tile));
    let lon_of = |i: usize| lons[i];
    let lat_of = |j: usize| lats[j];
    let mut xs = Vec::with_capacity(n * n);
    let mut ys = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            xs.push(lon_of(i));
            ys.push(lat_of(j).clamp(-90.0, 90.0));
        }
    }
    src.lonlat_to_pixel(&mut xs, &mut ys);
    // a position this far outside any raster (a nonsense geotransform) is no position at all
    for (x, y) in xs.iter_mut().zip(ys.iter_mut()) {
        if x.abs() > MAX_PIXEL_COORD || y.abs() > MAX_PIXEL_COORD {
            (*x, *y) = (f64::NAN, f64::NAN);
        }
    }
    let mut map = TexelMap {
        x: Vec::with_capacity(t * t),
        y: Vec::with_capacity(t * t),
        foot: Vec::with_capacity(t * t),
    };
    let coslats: Vec<f64> = (0..n)
        .map(|j| lat_of(j).to_radians().cos().max(1e-12))
        .collect();
    let at = |i: usize, j: usize| (xs[j * n + i], ys[j * n + i]);
    #[allow(clippy::needless_range_loop)] // j indexes the padded grid and coslats alike
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
            let coslat = coslats[j];
            let jac = {
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

/// The kernel of a run, tabulated for separable use (the 1-D shape the user chose) and for radial
/// use. A radial sinc is a poor 2-D low-pass (its spectrum peaks at the cutoff), so the Lanczos
/// kernels become the jinc-windowed jinc of the same order where a footprint is filtered radially.
#[derive(Debug, Clone)]
pub struct Kernels {
    separable: KernelLut,
    radial: KernelLut,
}

impl Kernels {
    /// Tables for `kernel`.
    pub fn new(kernel: Kernel) -> Self {
        let radial = match kernel {
            Kernel::Lanczos2 => Kernel::JincLanczos2,
            Kernel::Lanczos3 => Kernel::JincLanczos3,
            k => k,
        };
        Self {
            separable: KernelLut::new(kernel),
            radial: KernelLut::new(radial),
        }
    }
}

/// Resamples `src` onto `tile` with `kernels`. Returns `None` when the source contributes
/// nothing to the tile.
///
/// Lon/lat sources take [`resample_lonlat`]: there a texel's source column depends on its
/// column only, and its source row and footprint on its row only, so the separable filter runs
/// as two passes over whole rows. Other sources (rotated footprints) and the nearest kernel go
/// texel by texel.
pub fn resample_tile(
    src: &dyn PixelSource,
    grid: GridSpec,
    tile: TileId,
    kernels: &Kernels,
) -> Result<Option<TileSamples>> {
    match (src.info().geographic, kernels.separable.kernel()) {
        (true, Kernel::Nearest) => nearest_lonlat(src, grid, tile),
        (true, _) => resample_lonlat(src, grid, tile, kernels, Lanes::Where),
        (false, _) => resample_texels(src, grid, tile, kernels),
    }
}

/// [`resample_tile`] with the nearest kernel for a lon/lat source: each texel takes the source
/// pixel under its centre, found once per tile column and row. What [`resample_texels`] gives.
fn nearest_lonlat(
    src: &dyn PixelSource,
    grid: GridSpec,
    tile: TileId,
) -> Result<Option<TileSamples>> {
    let info = src.info();
    let t = grid.tile_size() as usize;
    let axes = lonlat_axes(src, grid, tile);
    let (w, h) = (info.width as f64, info.height as f64);
    let wraps_x = info.lon_period_px.is_some();
    let reaches_pole = info.north_pole_y.is_some() || info.south_pole_y.is_some();
    // a texel's reach is its own pixel (half a pixel each way); texels whose reach misses a
    // source that neither wraps nor crosses a pole take nothing from it
    let x_reaches = |x: f64| x.is_finite() && (wraps_x || (x + 0.5 >= 0.0 && x - 0.5 <= w));
    let y_reaches = |y: f64| y.is_finite() && (reaches_pole || (y + 0.5 >= 0.0 && y - 0.5 <= h));
    let (lo, hi) = axes
        .x
        .iter()
        .filter(|&&x| x_reaches(x))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let mut reach = Reach::default();
    if lo.is_finite() {
        for &y in axes.y.iter().filter(|&&y| y_reaches(y)) {
            reach.add((lo, hi), (0.5, 0.5), y);
        }
    }
    let Some(win) = reach.read(src)? else {
        return Ok(None);
    };
    let nplanes = win.planes.len();
    let mut out = vec![vec![f32::NAN; t * t]; nplanes];
    let mut inside = vec![false; t * t];
    // an averaged window's samples cover step×step pixels
    let step = win.step as i64;
    let index = |v: f64, origin: i64, len: usize| {
        let i = (floor(v) - origin).div_euclid(step);
        (0..len as i64).contains(&i).then_some(i as usize)
    };
    let cols: Vec<Option<usize>> = axes
        .x
        .iter()
        .map(|&x| index(x, win.c0, win.w).filter(|_| x_reaches(x)))
        .collect();
    let x_inside: Vec<bool> = axes
        .x
        .iter()
        .map(|&x| x.is_finite() && (wraps_x || (0.0..w).contains(&x)))
        .collect();
    for (j, &y) in axes.y.iter().enumerate() {
        if !y_reaches(y) {
            continue;
        }
        let row = j * t..(j + 1) * t;
        if (0.0..h).contains(&y) {
            for (flag, &xi) in inside[row.clone()].iter_mut().zip(&x_inside) {
                *flag = xi;
            }
        }
        let Some(r) = index(y, win.r0, win.h) else {
            continue;
        };
        let base = r * win.w;
        for (i, c) in cols.iter().enumerate() {
            let Some(c) = *c else { continue };
            if win.planes[0][base + c].is_nan() {
                continue;
            }
            for (o, p) in out.iter_mut().zip(&win.planes) {
                o[j * t + i] = p[base + c];
            }
        }
    }
    Ok(tile_samples(out, &inside))
}

/// [`resample_tile`] texel by texel, for any source and kernel.
fn resample_texels(
    src: &dyn PixelSource,
    grid: GridSpec,
    tile: TileId,
    kernels: &Kernels,
) -> Result<Option<TileSamples>> {
    let lut = &kernels.separable;
    let kernel = lut.kernel();
    let info = src.info();
    let t = grid.tile_size() as usize;
    let map = texel_map(src, grid, tile, kernel);
    let support = kernel.support().max(kernels.radial.kernel().support());
    let period = info.lon_period_px;
    let (w, h) = (info.width as f64, info.height as f64);
    // the source rectangle the whole tile needs
    let mut reach = Reach::default();
    // a filtering kernel takes the texels whose footprint reaches across a pole from rings
    let scale_y = |k: usize| {
        map.foot[k]
            .and_then(|f| f.axis_scales())
            .map_or(1.0, |s| s.1)
    };
    let ring_of = |k: usize| {
        (kernel != Kernel::Nearest)
            .then(|| ring_pole(info, map.y[k], scale_y(k), kernel.support()))
            .flatten()
    };
    let mut half = Vec::with_capacity(t * t);
    for k in 0..t * t {
        let (x, y) = (map.x[k], map.y[k]);
        if !x.is_finite() {
            half.push((0.0, 0.0));
            continue;
        }
        let (hx, hy) = match &map.foot[k] {
            Some(f) => f.half_extent(support),
            None => (0.5, 0.5),
        };
        let ring = ring_of(k).is_some();
        let hx = reach_x(hx, period, ring);
        let hy = if ring { Ring::reach_y(hy) } else { hy };
        half.push((hx, hy));
        // skip texels whose whole footprint misses a non-wrapping source
        let wraps_x = period.is_some();
        let reaches_pole = info.north_pole_y.is_some() || info.south_pole_y.is_some();
        if (!wraps_x && (x + hx < 0.0 || x - hx > w))
            || (!reaches_pole && (y + hy < 0.0 || y - hy > h))
        {
            continue;
        }
        reach.add((x, x), (hx, hy), y);
    }
    // no footprint reaches the source: no texel centre lies inside it either
    let Some(win) = reach.read(src)? else {
        return Ok(None);
    };
    let nplanes = win.planes.len();
    let mut out = vec![vec![f32::NAN; t * t]; nplanes];
    let mut acc = vec![0f64; nplanes];
    let mut mips = Mips::default();
    let mut rows = RowWeights::default();
    let mut rings: Vec<Option<Ring>> = (0..t).map(|_| None).collect();
    let mut inside = vec![false; t * t];
    for k in 0..t * t {
        let (x, y) = (map.x[k], map.y[k]);
        inside[k] =
            x.is_finite() && (period.is_some() || (0.0..w).contains(&x)) && (0.0..h).contains(&y);
        if let Some(north) = ring_of(k) {
            inside[k] = true;
            let ring = rings[k / t].get_or_insert_with(|| {
                Ring::new(&win, info, north, y, scale_y(k), &kernels.separable)
            });
            if let Some(v) = ring.at(x) {
                for (pl, val) in v.iter().enumerate() {
                    out[pl][k] = *val as f32;
                }
            }
            continue;
        }
        if !x.is_finite() {
            continue;
        }
        let texel = Texel {
            x,
            y,
            foot: map.foot[k].as_ref(),
            half: half[k],
        };
        if texel.filter(&win, &mut mips, kernels, &mut acc, &mut rows) {
            for p in 0..nplanes {
                out[p][k] = acc[p] as f32;
            }
        }
    }
    Ok(tile_samples(out, &inside))
}

/// One texel to filter: its source position, footprint and the half extents of its reach.
struct Texel<'a> {
    x: f64,
    y: f64,
    foot: Option<&'a Footprint>,
    half: (f64, f64),
}

impl Texel<'_> {
    /// Filters the texel into `acc` (one value per plane); false where the source holds too
    /// little valid data under its footprint.
    fn filter(
        &self,
        win: &Window,
        mips: &mut Mips,
        kernels: &Kernels,
        acc: &mut [f64],
        rows: &mut RowWeights,
    ) -> bool {
        let (x, y) = (self.x, self.y);
        match self.foot {
            None => nearest(win, x, y, acc),
            Some(f) => match f.axis_scales() {
                // axis-aligned footprints (every lon/lat source): separable, on a copy of the
                // window averaged 2^m× in x where the footprint is wide (towards the poles), so a
                // texel costs a bounded number of taps at any latitude
                Some((sx, sy)) => {
                    let step = win.step as f64;
                    let mip = mips.view(win, mip_level(sx / step), mip_level(sy / step), ALL);
                    separable(mip, &kernels.separable, x, y, (sx, sy), acc, rows)
                }
                None => {
                    let (hx, hy) = self.half;
                    let step = 8.0 * win.step as f64;
                    let mip = mips.view(win, mip_level(hx / step), mip_level(hy / step), ALL);
                    filtered(mip, f, &kernels.radial, x, y, self.half, acc)
                }
            },
        }
    }
}

/// Source x of each tile column and source y and footprint of each tile row of a lon/lat
/// source: the values [`texel_map`] gives each texel, found once per column and row.
struct LonLatAxes {
    /// Per column (NaN where it has no position), unwrapped as in [`texel_map`].
    x: Vec<f64>,
    /// Per row (NaN where it has no position).
    y: Vec<f64>,
    /// Per row.
    foot: Vec<Option<Footprint>>,
}

fn lonlat_axes(src: &dyn PixelSource, grid: GridSpec, tile: TileId) -> LonLatAxes {
    let t = grid.tile_size() as usize;
    let n = t + 2;
    let info = src.info();
    let gt = info.geotransform;
    let rho = std::f64::consts::PI / grid.height(tile.level) as f64;
    let lats = padded_lats(grid, tile);
    let mut x = padded_lons(grid, tile);
    src.lonlat_to_pixel(&mut x, &mut vec![0.0; n]);
    let mut y: Vec<f64> = lats.iter().map(|l| l.clamp(-90.0, 90.0)).collect();
    src.lonlat_to_pixel(&mut vec![0.0; n], &mut y);
    // a position this far outside any raster is no position at all
    let far = |v: f64| v.abs() > MAX_PIXEL_COORD;
    let centre_row_far = far(y[n / 2]);
    for v in x.iter_mut().chain(y.iter_mut()) {
        if far(*v) {
            *v = f64::NAN;
        }
    }
    if let Some(p) = info.lon_period_px {
        // unwrap around the tile centre, so the tile's footprints form one window
        let c = if centre_row_far { f64::NAN } else { x[n / 2] };
        for v in x.iter_mut() {
            *v = c + ((*v - c + p / 2.0).rem_euclid(p) - p / 2.0);
        }
    } else {
        // a regional source: put x nearest to the raster
        let period = 360.0 / gt[1].abs();
        let w = info.width as f64;
        for v in x.iter_mut() {
            if *v > w && *v - period > -w {
                *v -= period;
            }
        }
    }
    LonLatAxes {
        x: x[1..=t].to_vec(),
        y: y[1..=t].to_vec(),
        foot: lats[1..=t]
            .iter()
            .map(|&lat| lonlat_footprint(gt, lat, rho))
            .collect(),
    }
}

/// The per-texel map of a lon/lat source from its axes: a texel lacking either position has
/// neither, and the nearest kernel needs no footprint.
fn lonlat_texel_map(axes: &LonLatAxes, kernel: Kernel) -> TexelMap {
    let n = axes.x.len() * axes.y.len();
    let mut map = TexelMap {
        x: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
        foot: Vec::with_capacity(n),
    };
    for (&y, foot) in axes.y.iter().zip(&axes.foot) {
        for &x in &axes.x {
            let placed = x.is_finite() && y.is_finite();
            map.x.push(if placed { x } else { f64::NAN });
            map.y.push(if placed { y } else { f64::NAN });
            map.foot
                .push(foot.filter(|_| placed && kernel != Kernel::Nearest));
        }
    }
    map
}

/// Whether the row filter takes texels in lanes where it can, or one at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Lanes {
    Where,
    Never,
}

/// [`resample_tile`] for a lon/lat source, a row of texels at a time: one footprint, one
/// averaged level and one set of row weights per row, the rows of the source combined once per
/// source column (vertical pass), then each texel's columns (horizontal pass). The same sums as
/// [`separable`], added in another order.
fn resample_lonlat(
    src: &dyn PixelSource,
    grid: GridSpec,
    tile: TileId,
    kernels: &Kernels,
    lanes: Lanes,
) -> Result<Option<TileSamples>> {
    let lut = &kernels.separable;
    let info = src.info();
    let t = grid.tile_size() as usize;
    let axes = lonlat_axes(src, grid, tile);
    let support = lut
        .kernel()
        .support()
        .max(kernels.radial.kernel().support());
    let period = info.lon_period_px;
    let (w, h) = (info.width as f64, info.height as f64);
    // rows whose footprint reaches across a pole are filtered on rings
    let scale_y = |j: usize| {
        axes.foot[j]
            .and_then(|f| f.axis_scales())
            .map_or(1.0, |s| s.1)
    };
    let ring_of = |j: usize| ring_pole(info, axes.y[j], scale_y(j), lut.kernel().support());
    let wraps_x = period.is_some();
    let reaches_pole = info.north_pole_y.is_some() || info.south_pole_y.is_some();
    // each row's reach, and the source rectangle the whole tile needs
    let mut half = Vec::with_capacity(t);
    let mut reach = Reach::default();
    for j in 0..t {
        let y = axes.y[j];
        let (hx, hy) = axes.foot[j].map_or((0.5, 0.5), |f| f.half_extent(support));
        let ring = ring_of(j).is_some();
        let hx = reach_x(hx, period, ring);
        let hy = if ring { Ring::reach_y(hy) } else { hy };
        half.push((hx, hy));
        if !y.is_finite() || (!reaches_pole && (y + hy < 0.0 || y - hy > h)) {
            continue;
        }
        // the row's columns whose footprint reaches a non-wrapping source
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &x in &axes.x {
            if x.is_finite() && (wraps_x || (x + hx >= 0.0 && x - hx <= w)) {
                lo = lo.min(x);
                hi = hi.max(x);
            }
        }
        if lo.is_finite() {
            reach.add((lo, hi), (hx, hy), y);
        }
    }
    // no footprint reaches the source: no texel centre lies inside it either
    let Some(win) = reach.read(src)? else {
        return Ok(None);
    };
    let nplanes = win.planes.len();
    let mut out = vec![vec![f32::NAN; t * t]; nplanes];
    // an opaque colour source (every valid sample has alpha 1) needs no alpha filtered
    let opaque = nplanes == 4
        && win.planes[0]
            .iter()
            .zip(&win.planes[3])
            .all(|(v, a)| v.is_nan() || *a == 1.0);
    let filtered = if opaque { 3 } else { nplanes };
    let mut inside = vec![false; t * t];
    let mut mips = Mips::default();
    let mut pass = RowPass {
        scalar: lanes == Lanes::Never,
        ..RowPass::default()
    };
    let mut acc = vec![0f64; nplanes];
    let mut rows = RowWeights::default();
    // the span of the tile's source columns (the same for every row)
    let span = axes
        .x
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    for j in 0..t {
        let y = axes.y[j];
        let row = j * t..(j + 1) * t;
        if let Some(north) = ring_of(j) {
            inside[row.clone()].fill(true);
            let ring = Ring::new(&win, info, north, y, scale_y(j), lut);
            for (i, &x) in axes.x.iter().enumerate() {
                if let Some(v) = ring.at(x) {
                    for (plane, val) in out.iter_mut().zip(v.iter()) {
                        plane[j * t + i] = *val as f32;
                    }
                }
            }
            continue;
        }
        if !y.is_finite() {
            continue;
        }
        let y_inside = (0.0..h).contains(&y);
        for (flag, &x) in inside[row.clone()].iter_mut().zip(&axes.x) {
            *flag = y_inside && x.is_finite() && (wraps_x || (0.0..w).contains(&x));
        }
        match axes.foot[j].as_ref().and_then(|f| f.axis_scales()) {
            Some(scales) => {
                let row = TexelRow {
                    xs: &axes.x,
                    span,
                    y,
                    scales,
                };
                pass.filter_row(&mut mips, &win, lut, &row, &mut out[..filtered], j * t);
            }
            None => {
                for (i, &x) in axes.x.iter().enumerate() {
                    if !x.is_finite() {
                        continue;
                    }
                    let texel = Texel {
                        x,
                        y,
                        foot: axes.foot[j].as_ref(),
                        half: half[j],
                    };
                    if texel.filter(&win, &mut mips, kernels, &mut acc, &mut rows) {
                        for (plane, a) in out.iter_mut().zip(&acc) {
                            plane[j * t + i] = *a as f32;
                        }
                    }
                }
            }
        }
    }
    if opaque {
        let (colour, alpha) = out.split_at_mut(3);
        for (a, v) in alpha[0].iter_mut().zip(&colour[0]) {
            if !v.is_nan() {
                *a = 1.0;
            }
        }
    }
    Ok(tile_samples(out, &inside))
}

/// The samples of a tile from its filtered planes and which texel centres lie inside the
/// source; `None` when the source gave the tile nothing.
fn tile_samples(planes: Vec<Vec<f32>>, inside: &[bool]) -> Option<TileSamples> {
    let footprint = inside.iter().filter(|&&i| i).count() as u32;
    let covered = inside
        .iter()
        .zip(&planes[0])
        .filter(|(i, v)| **i && !v.is_nan())
        .count() as u32;
    let any = planes[0].iter().any(|v| !v.is_nan());
    (any || footprint > 0).then_some(TileSamples {
        planes,
        footprint,
        covered,
    })
}

/// Buffers of the two-pass separable filter of one row of texels.
#[derive(Debug, Default)]
struct RowPass {
    wy: Vec<f64>,
    /// Per source column of the row's span and plane: Σ wy·value over valid samples.
    sums: Vec<Vec<f64>>,
    /// Per source column: Σ wy over valid samples.
    weights: Vec<f64>,
    /// Per source column: Σ max(wy, 0) over valid samples.
    positive: Vec<f64>,
    /// Texels one at a time only (the lanes' reference in tests).
    scalar: bool,
}

/// One row of texels of a lon/lat source: the source x of each texel (NaN where it has none)
/// and their span, the row's source y and its footprint's scales along x and y.
struct TexelRow<'a> {
    xs: &'a [f64],
    span: (f64, f64),
    y: f64,
    scales: (f64, f64),
}

impl RowPass {
    /// Filters one row of texels on the averaged level of `win` its footprint's scales call for
    /// (made as far as the row reaches), into `out[p][base + i]`; texels without enough valid
    /// data stay NaN.
    fn filter_row(
        &mut self,
        mips: &mut Mips,
        win: &Window,
        lut: &KernelLut,
        row: &TexelRow<'_>,
        out: &mut [Vec<f32>],
        base: usize,
    ) {
        let (xs, y, (sx, sy)) = (row.xs, row.y, row.scales);
        let s = lut.kernel().support();
        let (mx, my) = (
            mip_level(sx / win.step as f64),
            mip_level(sy / win.step as f64),
        );
        let (step, mw, mh) = Mips::shape(win, mx, my);
        let (mw, mh) = (mw as i64, mh as i64);
        let (c0, r0) = (win.c0 as f64, win.r0 as f64);
        let v = (y - r0) / step.1;
        let sv = sy / step.1;
        let (r0, r1) = (ceil(v - 0.5 - s * sv), floor(v - 0.5 + s * sv));
        let nr = (r1 - r0 + 1).max(0) as usize;
        if nr == 0 || nr > SEP_MAX {
            return;
        }
        self.wy.clear();
        self.wy
            .extend((0..nr).map(|j| lut.weight(((r0 + j as i64) as f64 + 0.5 - v) / sv)));
        let wy_pos: f64 = self.wy.iter().map(|w| w.max(0.0)).sum();
        let su = sx / step.0;
        let reach = s * su;
        let col = |x: f64| (x - c0) / step.0;
        // the source columns the row needs, within the samples
        let (lo, hi) = row.span;
        if lo > hi {
            return;
        }
        let ca = ceil(col(lo) - 0.5 - reach).max(0);
        let cb = floor(col(hi) - 0.5 + reach).min(mw - 1);
        if ca > cb {
            return;
        }
        let mip = mips.view(win, mx, my, (r0..r1 + 1, ca..cb + 1));
        let nc = (cb - ca + 1) as usize;
        let nplanes = out.len().min(mip.nplanes);
        self.sums.resize_with(nplanes, Vec::new);
        self.sums.truncate(nplanes);
        for v in self
            .sums
            .iter_mut()
            .chain([&mut self.weights, &mut self.positive])
        {
            v.clear();
            v.resize(nc, 0.0);
        }
        // vertical pass: the rows under the footprint, weighted, per source column
        for (j, &wy) in self.wy.iter().enumerate() {
            let r = r0 + j as i64;
            if wy == 0.0 || r < 0 || r >= mh {
                continue;
            }
            let span = ca as usize..ca as usize + nc;
            let row0 = &mip.row(0, r as usize)[span.clone()];
            let (s0, rest) = self.sums.split_first_mut().expect("one plane at least");
            column_sums::first(s0, &mut self.weights, &mut self.positive, row0, wy);
            for (p, sp) in rest.iter_mut().enumerate() {
                let rowp = &mip.row(p + 1, r as usize)[span.clone()];
                column_sums::other(sp, rowp, row0, wy);
            }
        }
        // horizontal pass: each texel's columns. Where no sample of the span is missing, every
        // column carries the same weight sums, so only the values need a dot product
        let (whole_w, whole_p) = (self.weights[0], self.positive[0]);
        let whole = self.weights.iter().all(|&w| w == whole_w)
            && self.positive.iter().all(|&p| p == whole_p);
        let taps = Taps {
            lut,
            c0,
            step: step.0,
            reach,
            inv_su: 1.0 / su,
            span: (ca, cb),
            wy_pos,
        };
        // at most this many taps a texel: ceil(a)..=floor(a + 2·reach)
        let most = (2.0 * reach).floor() as usize + 1;
        let columns = if whole {
            Columns::Whole(whole_w, whole_p)
        } else {
            Columns::Each {
                weights: &self.weights,
                positive: &self.positive,
            }
        };
        // lanes only where every column carries the same weight sums
        let lanes = (!self.scalar && whole && most <= SEP_MAX && self.sums.len() <= 4)
            .then_some((whole_w, whole_p));
        for (chunk, xs) in xs.chunks(LANES).enumerate() {
            let base = base + chunk * LANES;
            if let Some(whole) = lanes
                && let Ok(xs) = <&[f64; LANES]>::try_from(xs)
                && let Some((vals, ok)) = lanes::texels(&taps, &self.sums, xs, most, whole)
            {
                for (plane, vals) in out.iter_mut().zip(&vals) {
                    for (l, v) in vals.iter().enumerate() {
                        if ok[l] {
                            plane[base + l] = *v;
                        }
                    }
                }
                continue;
            }
            for (l, &x) in xs.iter().enumerate() {
                if let Some(vals) = taps.filter(&self.sums, x, columns) {
                    for (plane, v) in out.iter_mut().zip(vals) {
                        plane[base + l] = v;
                    }
                }
            }
        }
    }
}

/// The vertical pass's sums over one source row, in loops without a branch: adding +0 where a
/// sample is missing leaves a sum as it is (a sum that starts at +0 is never −0 when rounding to
/// nearest). With AVX2 the same loops run four columns at a time, each operation the scalar one.
mod column_sums {
    /// Plane 0 of a row (`v0`, NaN where a sample is missing) into its sums, and `wy` into the
    /// weight sums and its positive part into the positive sums, where `v0` holds a sample.
    #[allow(unsafe_code)]
    pub(super) fn first(s: &mut [f64], w: &mut [f64], p: &mut [f64], v0: &[f32], wy: f64) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, all the function is compiled for
            return unsafe { first_avx2(s, w, p, v0, wy) };
        }
        first_scalar(s, w, p, v0, wy)
    }

    /// Another plane's row `v` into its sums, where plane 0's `v0` holds a sample.
    #[allow(unsafe_code)]
    pub(super) fn other(s: &mut [f64], v: &[f32], v0: &[f32], wy: f64) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, all the function is compiled for
            return unsafe { other_avx2(s, v, v0, wy) };
        }
        other_scalar(s, v, v0, wy)
    }

    #[inline(always)]
    fn first_scalar(s: &mut [f64], w: &mut [f64], p: &mut [f64], v0: &[f32], wy: f64) {
        let wp = wy.max(0.0);
        for (((s, w), p), &v0) in s.iter_mut().zip(w).zip(p).zip(v0) {
            let ok = !v0.is_nan();
            *s += if ok { wy * f64::from(v0) } else { 0.0 };
            *w += if ok { wy } else { 0.0 };
            *p += if ok { wp } else { 0.0 };
        }
    }

    #[inline(always)]
    fn other_scalar(s: &mut [f64], v: &[f32], v0: &[f32], wy: f64) {
        for ((s, &v), &v0) in s.iter_mut().zip(v).zip(v0) {
            *s += if v0.is_nan() { 0.0 } else { wy * f64::from(v) };
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn first_avx2(s: &mut [f64], w: &mut [f64], p: &mut [f64], v0: &[f32], wy: f64) {
        first_scalar(s, w, p, v0, wy)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn other_avx2(s: &mut [f64], v: &[f32], v0: &[f32], wy: f64) {
        other_scalar(s, v, v0, wy)
    }

    #[cfg(test)]
    mod tests {
        #[test]
        fn vector_sums_are_the_scalar_sums() {
            let n = 37;
            let v0: Vec<f32> = (0..n)
                .map(|i| {
                    if i % 5 == 3 {
                        f32::NAN
                    } else {
                        i as f32 * 0.37 - 3.0
                    }
                })
                .collect();
            let v: Vec<f32> = (0..n).map(|i| (i as f32).sin() * 1e3).collect();
            for wy in [0.3, -0.07] {
                let start: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
                let (mut a, mut b) = (
                    [start.clone(), start.clone(), start.clone()],
                    [start.clone(), start.clone(), start.clone()],
                );
                let [s, w, p] = &mut a;
                super::first(s, w, p, &v0, wy);
                let mut o = start.clone();
                super::other(&mut o, &v, &v0, wy);
                let [s2, w2, p2] = &mut b;
                super::first_scalar(s2, w2, p2, &v0, wy);
                let mut o2 = start.clone();
                super::other_scalar(&mut o2, &v, &v0, wy);
                let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                for (x, y) in a.iter().zip(&b).chain([(&o, &o2)]) {
                    assert_eq!(bits(x), bits(y));
                }
                // a missing sample adds nothing, a present one adds its weighted value
                assert_eq!(a[0][3], start[3]);
                assert_eq!(a[1][3], start[3]);
                assert_eq!(o[3], start[3]);
                assert_eq!(a[0][4], start[4] + wy * f64::from(v0[4]));
                assert_eq!(a[2][4], start[4] + wy.max(0.0));
            }
        }
    }
}

/// Texels filtered in lanes of this many (along one row): four f64 in AVX2's 256 bits.
const LANES: usize = 4;

/// What the horizontal pass of one row of texels shares: the kernel, the averaged level's
/// column origin and step, the footprint's reach and inverse scale in its samples, the span of
/// columns the vertical pass summed and the row's positive weight along y.
struct Taps<'a> {
    lut: &'a KernelLut,
    c0: f64,
    step: f64,
    reach: f64,
    inv_su: f64,
    span: (i64, i64),
    wy_pos: f64,
}

/// One texel's taps: its first column, their number (0 where it has none) and the first one's
/// distance from the texel in kernel units.
struct TexelTaps {
    c0: i64,
    n: usize,
    d0: f64,
}

impl Taps<'_> {
    #[inline]
    fn of(&self, x: f64) -> TexelTaps {
        let u = (x - self.c0) / self.step;
        let (c0, c1) = (ceil(u - 0.5 - self.reach), floor(u - 0.5 + self.reach));
        let n = c1 - c0 + 1;
        if !x.is_finite() || n <= 0 || n > SEP_MAX as i64 {
            return TexelTaps { c0, n: 0, d0: 0.0 };
        }
        let d0 = (c0 as f64 + 0.5 - u) * self.inv_su;
        TexelTaps {
            c0,
            n: n as usize,
            d0,
        }
    }

    /// The value of the texel at source x: Σ wx·sums over its taps inside the span, divided by
    /// the weight of the valid samples; `None` where they carry too little of the footprint.
    /// `columns`: the vertical pass's sums of the weights and of the positive weights.
    fn filter(&self, sums: &[Vec<f64>], x: f64, columns: Columns<'_>) -> Option<[f32; 4]> {
        let TexelTaps { c0, n, d0 } = self.of(x);
        if n == 0 {
            return None;
        }
        let mut wx = [0f64; SEP_MAX];
        self.lut.weights_into(d0, self.inv_su, &mut wx[..n]);
        let wx_pos: f64 = wx[..n].iter().map(|w| w.max(0.0)).sum();
        // the taps inside the span (all of them but near the samples' edges)
        let (ca, cb) = self.span;
        let (k0, k1) = (
            (ca - c0).max(0) as usize,
            ((cb - c0 + 1).max(0) as usize).min(n),
        );
        if k0 >= k1 {
            return None;
        }
        let (q0, taps) = ((c0 + k0 as i64 - ca) as usize, &wx[k0..k1]);
        let dot = |v: &[f64]| -> f64 { taps.iter().zip(&v[q0..]).map(|(w, v)| w * v).sum() };
        let (wsum, wpos_valid) = match columns {
            Columns::Whole(whole_w, whole_p) => {
                // the taps' sums, with every tap inside the span (all but near its edges)
                let (sum, pos) = if k1 - k0 == n {
                    (taps.iter().sum::<f64>(), wx_pos)
                } else {
                    (taps.iter().sum(), taps.iter().map(|w| w.max(0.0)).sum())
                };
                (whole_w * sum, whole_p * pos)
            }
            Columns::Each { weights, positive } => {
                let pos: f64 = taps
                    .iter()
                    .zip(&positive[q0..])
                    .map(|(w, p)| w.max(0.0) * p)
                    .sum();
                (dot(weights), pos)
            }
        };
        if !enough(wx_pos * self.wy_pos, wsum, wpos_valid) {
            return None;
        }
        let mut vals = [f32::NAN; 4];
        for (v, sp) in vals.iter_mut().zip(sums) {
            *v = (dot(sp) / wsum) as f32;
        }
        Some(vals)
    }
}

/// The vertical pass's sums of the weights and of the positive weights of the valid samples:
/// per column, or one value for every column (no sample of the span missing).
#[derive(Clone, Copy)]
enum Columns<'a> {
    Each {
        weights: &'a [f64],
        positive: &'a [f64],
    },
    Whole(f64, f64),
}

/// Whether valid samples of weight sum `wsum` and positive weight `wpos_valid` carry enough of a
/// footprint of positive weight `wpos_all`.
#[inline]
fn enough(wpos_all: f64, wsum: f64, wpos_valid: f64) -> bool {
    !(wpos_all <= 0.0 || wpos_valid < MIN_COVERAGE * wpos_all || wsum.abs() < 1e-6 * wpos_all)
}

/// The horizontal pass for [`LANES`] texels at once where no sample of the span is missing: the
/// same operations in the same order as [`Taps::filter`], each texel's taps padded to the row's
/// largest count with taps that are not added, in AVX2 vectors where the CPU has them.
mod lanes {
    use super::{LANES, Taps};

    /// Values per plane of [`LANES`] texels.
    pub(super) type Planes = [[f32; LANES]; 4];

    /// The texels at `xs` (`None` unless every one has all its taps, at most `most`, inside the
    /// span, or without AVX2): their values per plane and which of them have enough valid data.
    #[allow(unsafe_code)]
    pub(super) fn texels(
        taps: &Taps<'_>,
        sums: &[Vec<f64>],
        xs: &[f64; LANES],
        most: usize,
        whole: (f64, f64),
    ) -> Option<(Planes, [bool; LANES])> {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, all the function is compiled for
            return unsafe { avx2::texels(taps, sums, xs, most, whole) };
        }
        let _ = (taps, sums, xs, most, whole);
        None
    }

    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)]
    mod avx2 {
        use super::super::{LANES, Taps, enough};
        use super::Planes;
        use sc_core::Kernel;
        use std::arch::x86_64::*;

        const _: () = assert!(LANES == 4, "four f64 lanes in 256 bits");

        #[target_feature(enable = "avx2")]
        fn lanes(v: __m256d) -> [f64; LANES] {
            let mut out = [0f64; LANES];
            // SAFETY: `out` holds four f64, unaligned stores are allowed
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
            out
        }

        #[target_feature(enable = "avx2")]
        fn select(if_true: __m256d, if_false: __m256d, mask: __m256d) -> __m256d {
            _mm256_blendv_pd(if_false, if_true, mask)
        }

        /// Keys' cubic as `KernelLut::weight` evaluates it for `Kernel::Cubic` (sc_core's
        /// `keys_cubic` of `|d|`), operation for operation.
        #[target_feature(enable = "avx2")]
        fn cubic(d: __m256d) -> __m256d {
            const A: f64 = -0.5;
            let c = _mm256_set1_pd;
            let d = _mm256_andnot_pd(c(-0.0), d);
            let near = _mm256_add_pd(
                _mm256_mul_pd(
                    _mm256_mul_pd(_mm256_sub_pd(_mm256_mul_pd(c(A + 2.0), d), c(A + 3.0)), d),
                    d,
                ),
                c(1.0),
            );
            let far = _mm256_sub_pd(
                _mm256_mul_pd(
                    _mm256_add_pd(
                        _mm256_mul_pd(_mm256_sub_pd(_mm256_mul_pd(c(A), d), c(5.0 * A)), d),
                        c(8.0 * A),
                    ),
                    d,
                ),
                c(4.0 * A),
            );
            let beyond = select(
                far,
                _mm256_setzero_pd(),
                _mm256_cmp_pd::<_CMP_LT_OQ>(d, c(2.0)),
            );
            select(near, beyond, _mm256_cmp_pd::<_CMP_LE_OQ>(d, c(1.0)))
        }

        /// The tent as `KernelLut::weight` evaluates it for `Kernel::Bilinear` (sc_core's
        /// `Kernel::weight`: 1 − |d| inside the support, 0 from it on).
        #[target_feature(enable = "avx2")]
        fn tent(d: __m256d) -> __m256d {
            let c = _mm256_set1_pd;
            let d = _mm256_andnot_pd(c(-0.0), d);
            select(
                _mm256_sub_pd(c(1.0), d),
                _mm256_setzero_pd(),
                _mm256_cmp_pd::<_CMP_LT_OQ>(d, c(1.0)),
            )
        }

        #[target_feature(enable = "avx2")]
        pub(super) fn texels(
            taps: &Taps<'_>,
            sums: &[Vec<f64>],
            xs: &[f64; LANES],
            most: usize,
            (whole_w, whole_p): (f64, f64),
        ) -> Option<(Planes, [bool; LANES])> {
            let c = _mm256_set1_pd;
            let (ca, cb) = (taps.span.0 as f64, taps.span.1 as f64);
            // `Taps::of` with the floors held in f64 (exact integers within ±2^52)
            let x = _mm256_set_pd(xs[3], xs[2], xs[1], xs[0]);
            let u = _mm256_div_pd(_mm256_sub_pd(x, c(taps.c0)), c(taps.step));
            let centre = _mm256_sub_pd(u, c(0.5));
            let lo = _mm256_ceil_pd(_mm256_sub_pd(centre, c(taps.reach)));
            let hi = _mm256_floor_pd(_mm256_add_pd(centre, c(taps.reach)));
            let n = _mm256_add_pd(_mm256_sub_pd(hi, lo), c(1.0));
            // every texel has taps, at most `most`, all inside the span (the scalar path's
            // k0 = 0, k1 = n); ordered comparisons, so false for a NaN or infinite x
            let fits = _mm256_and_pd(
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(n, c(1.0)),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(n, c(most as f64)),
                ),
                _mm256_and_pd(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(lo, c(ca)),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(hi, c(cb)),
                ),
            );
            if _mm256_movemask_pd(fits) != 0b1111 {
                return None;
            }
            let inv_su = c(taps.inv_su);
            let d0 = _mm256_mul_pd(_mm256_sub_pd(_mm256_add_pd(lo, c(0.5)), u), inv_su);
            let first = lanes(_mm256_sub_pd(lo, c(ca))).map(|f| f as usize);
            let span = sums.first().map_or(0, Vec::len);
            // padded taps read the span's last column (and are not added)
            let last = span.checked_sub(1)?;
            let kernel = taps.lut.kernel();
            let zero = c(-0.0);
            let (mut wsum, mut wpos) = (zero, zero);
            let mut acc = [zero; 4];
            for k in 0..most {
                let kf = c(k as f64);
                let d = _mm256_add_pd(d0, _mm256_mul_pd(kf, inv_su));
                let w = match kernel {
                    Kernel::Cubic => cubic(d),
                    Kernel::Bilinear => tent(d),
                    _ => {
                        let w = lanes(d).map(|d| taps.lut.weight(d));
                        _mm256_set_pd(w[3], w[2], w[1], w[0])
                    }
                };
                let on = _mm256_cmp_pd::<_CMP_LT_OQ>(kf, n);
                wsum = select(_mm256_add_pd(wsum, w), wsum, on);
                let pos = _mm256_max_pd(w, _mm256_setzero_pd());
                wpos = select(_mm256_add_pd(wpos, pos), wpos, on);
                let at = first.map(|f| (f + k).min(last));
                for (a, sp) in acc.iter_mut().zip(sums) {
                    let sp = &sp[..=last];
                    let v = _mm256_set_pd(sp[at[3]], sp[at[2]], sp[at[1]], sp[at[0]]);
                    *a = select(_mm256_add_pd(*a, _mm256_mul_pd(w, v)), *a, on);
                }
            }
            // the valid samples' weight sum as the scalar path multiplies it: whole_w · Σ wx
            let sum = _mm256_mul_pd(c(whole_w), wsum);
            let (sum_l, wpos) = (lanes(sum), lanes(wpos));
            let mut ok = [false; LANES];
            let mut out = [[f32::NAN; LANES]; 4];
            for (l, ok) in ok.iter_mut().enumerate() {
                *ok = enough(wpos[l] * taps.wy_pos, sum_l[l], whole_p * wpos[l]);
            }
            for (o, a) in out.iter_mut().zip(&acc).take(sums.len()) {
                *o = lanes(_mm256_div_pd(*a, sum)).map(|v| v as f32);
            }
            Some((out, ok))
        }
    }
}

/// Most samples per unit of a footprint's scale: an averaged level keeps the scale between
/// `MIP_SCALE / 2` and `MIP_SCALE` of its samples. Averaging blocks is a weak low-pass: with 4 or
/// more samples per unit what it folds back lies where the kernel stops it (with 1–2, waves at
/// 3× the level's Nyquist came back at 15–19 % of their amplitude).
const MIP_SCALE: f64 = 8.0;

/// The averaging level for a footprint scale `sx` (source pixels): 2^m source pixels per
/// sample so that the scale in averaged samples is at most [`MIP_SCALE`].
fn mip_level(sx: f64) -> u32 {
    let mut m = 0;
    while sx / f64::from(1u32 << m) > MIP_SCALE && m < 20 {
        m += 1;
    }
    m
}

/// A window's planes averaged over blocks of 2^mx × 2^my pixels: sample (q, p) covers window
/// columns [q·bx, (q+1)·bx) and rows [p·by, (p+1)·by). Each level is made from the next finer one
/// by averaging pairs along one axis, weighted by their valid coverage; a sample is exposed as
/// invalid (NaN in plane 0) where less than half of its block is valid, so nodata borders stay
/// where they are. Filtering these is the kernel applied to box-prefiltered data: a bounded number
/// of taps however wide the footprint (near the poles, or a fine source onto a coarse level).
#[derive(Debug)]
struct Mip {
    step: (f64, f64),
    c0: f64,
    r0: f64,
    w: usize,
    h: usize,
    /// Rows made so far (in part).
    rows: Vec<Option<MipRow>>,
}

/// One row of an averaged level: `[planes as filtering sees them (plane 0 NaN where coverage
/// < ½) | means of the valid pixels of each block (NaN only where none is valid) | fraction of
/// each block that is valid]`, `w` samples per part, made over the columns `made`.
#[derive(Debug, Clone)]
struct MipRow {
    data: Vec<f32>,
    made: std::ops::Range<usize>,
}

/// A borrowed view of a window or one of its averaged levels.
#[derive(Debug, Clone, Copy)]
struct MipView<'a> {
    step: (f64, f64),
    c0: f64,
    r0: f64,
    w: usize,
    h: usize,
    nplanes: usize,
    data: MipData<'a>,
}

#[derive(Debug, Clone, Copy)]
enum MipData<'a> {
    /// The window itself: planes row-major.
    Window(&'a [Vec<f32>]),
    /// An averaged level: the rows and columns asked for are made.
    Rows(&'a [Option<MipRow>]),
}

impl<'a> MipView<'a> {
    /// Row `r` of plane `p` (made: the caller asked for it).
    fn row(&self, p: usize, r: usize) -> &'a [f32] {
        let w = self.w;
        match self.data {
            MipData::Window(planes) => &planes[p][r * w..(r + 1) * w],
            MipData::Rows(rows) => match &rows[r] {
                Some(row) => &row.data[p * w..(p + 1) * w],
                None => unreachable!("row {r} of an averaged level read before it was made"),
            },
        }
    }
}

/// The averaged levels of one window, made on demand row by row (a tile's rows near a pole
/// need coarse levels, the others fine ones); level (0, 0) is the window itself.
#[derive(Debug, Default)]
struct Mips {
    levels: Vec<Option<Mip>>,
}

const MIP_SIDE: usize = 24;

/// Every sample of a level.
const ALL: (std::ops::Range<i64>, std::ops::Range<i64>) = (0..i64::MAX, 0..i64::MAX);

impl Mips {
    /// Level (mx, my) of `win` with columns `cols` of rows `rows` (clamped to the level) made.
    fn view<'a>(
        &'a mut self,
        win: &'a Window,
        mx: u32,
        my: u32,
        (rows, cols): (std::ops::Range<i64>, std::ops::Range<i64>),
    ) -> MipView<'a> {
        let (mx, my) = (mx.min(MIP_SIDE as u32 - 1), my.min(MIP_SIDE as u32 - 1));
        let nplanes = win.planes.len();
        if mx == 0 && my == 0 {
            return MipView {
                step: (win.step as f64, win.step as f64),
                c0: win.c0 as f64,
                r0: win.r0 as f64,
                w: win.w,
                h: win.h,
                nplanes,
                data: MipData::Window(&win.planes),
            };
        }
        let (w, h) = {
            let m = self.level(win, mx, my);
            (m.w as i64, m.h as i64)
        };
        let (p0, p1) = (rows.start.clamp(0, h), rows.end.clamp(0, h));
        let (q0, q1) = (cols.start.clamp(0, w), cols.end.clamp(0, w));
        if p0 < p1 && q0 < q1 {
            self.make(
                win,
                mx,
                my,
                p0 as usize..p1 as usize,
                q0 as usize..q1 as usize,
            );
        }
        let m = self.levels[mx as usize * MIP_SIDE + my as usize]
            .as_ref()
            .expect("made above");
        MipView {
            step: m.step,
            c0: m.c0,
            r0: m.r0,
            w: m.w,
            h: m.h,
            nplanes,
            data: MipData::Rows(&m.rows),
        }
    }

    /// The sample spacing (source pixels along x and y), width and height of level (mx, my)
    /// of `win` (clamped like [`Self::view`]): halved along x from (mx − 1, my), else along y
    /// from (0, my − 1).
    fn shape(win: &Window, mx: u32, my: u32) -> ((f64, f64), usize, usize) {
        let (mut w, mut h, mut step) = (win.w, win.h, (win.step as f64, win.step as f64));
        for _ in 0..my.min(MIP_SIDE as u32 - 1) {
            (h, step.1) = ((h / 2).max(1), step.1 * 2.0);
        }
        for _ in 0..mx.min(MIP_SIDE as u32 - 1) {
            (w, step.0) = ((w / 2).max(1), step.0 * 2.0);
        }
        (step, w, h)
    }

    /// The level's geometry, its rows not made yet.
    fn level(&mut self, win: &Window, mx: u32, my: u32) -> &Mip {
        if self.levels.is_empty() {
            self.levels.resize_with(MIP_SIDE * MIP_SIDE, || None);
        }
        let k = mx as usize * MIP_SIDE + my as usize;
        if self.levels[k].is_none() {
            let (step, w, h) = Self::shape(win, mx, my);
            self.levels[k] = Some(Mip {
                step,
                c0: win.c0 as f64,
                r0: win.r0 as f64,
                w,
                h,
                rows: vec![None; h],
            });
        }
        self.levels[k].as_ref().expect("made above")
    }

    /// Makes columns `cols` of rows `rows` of level (mx, my) > (0, 0), and the samples of the
    /// finer levels they come from.
    fn make(
        &mut self,
        win: &Window,
        mx: u32,
        my: u32,
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
    ) {
        let k = mx as usize * MIP_SIDE + my as usize;
        let w = self.level(win, mx, my).w;
        let cols = cols.start.min(w)..cols.end.min(w);
        if cols.is_empty() {
            return;
        }
        // per row, the columns still to make: what the row lacks of `cols` (the row's made
        // columns stay one interval: the hull)
        let mut todo = Vec::new();
        {
            let m = self.levels[k].as_ref().expect("made above");
            for p in rows {
                let made = m.rows[p].as_ref().map_or(0..0, |r| r.made.clone());
                let hull = if made.is_empty() {
                    cols.clone()
                } else {
                    made.start.min(cols.start)..made.end.max(cols.end)
                };
                // (with nothing made, `made` is 0..0 and the second part is the hull)
                let parts: Vec<_> = [
                    hull.start..made.start.max(hull.start),
                    made.end.max(hull.start)..hull.end,
                ]
                .into_iter()
                .filter(|r| !r.is_empty())
                .collect();
                if !parts.is_empty() {
                    todo.push((p, hull, parts));
                }
            }
        }
        let (Some(first), Some(last)) = (todo.first(), todo.last()) else {
            return;
        };
        let (first, last) = (first.0, last.0);
        let (qa, qb) = todo
            .iter()
            .flat_map(|(_, _, parts)| parts)
            .fold((usize::MAX, 0), |(a, b), r| (a.min(r.start), b.max(r.end)));
        // from the next finer level along x if mx > 0, else along y
        let (pmx, pmy, along_x) = if mx > 0 {
            (mx - 1, my, true)
        } else {
            (mx, my - 1, false)
        };
        let parent_at_origin = pmx == 0 && pmy == 0;
        let (pw, ph) = if parent_at_origin {
            (win.w, win.h)
        } else {
            let m = self.level(win, pmx, pmy);
            (m.w, m.h)
        };
        if !parent_at_origin {
            let (need_rows, need_cols) = if along_x {
                (first..last + 1, 2 * qa..(2 * qb).min(pw))
            } else {
                (2 * first..(2 * last + 2).min(ph), qa..qb)
            };
            self.make(win, pmx, pmy, need_rows, need_cols);
        }
        let np = win.planes.len();
        let mut made = Vec::with_capacity(todo.len());
        {
            let parent = (!parent_at_origin)
                .then(|| self.levels[pmx as usize * MIP_SIDE + pmy as usize].as_ref())
                .flatten();
            // the finer level's raw means of plane `pl` in row r (level 0: the window) and
            // their coverage (level 0: 1 or 0)
            let raw = |pl: usize, r: usize| -> &[f32] {
                match parent {
                    None => &win.planes[pl][r * pw..(r + 1) * pw],
                    Some(m) => {
                        let row = &m.rows[r].as_ref().expect("made above").data;
                        &row[(np + pl) * pw..(np + pl + 1) * pw]
                    }
                }
            };
            let cov = |r: usize| -> Option<&[f32]> {
                parent.map(|m| &m.rows[r].as_ref().expect("made above").data[2 * np * pw..])
            };
            let m = self.levels[k].as_ref().expect("made above");
            for (p, hull, parts) in todo {
                let mut row = match &m.rows[p] {
                    Some(r) => r.data.clone(),
                    None => vec![f32::NAN; (2 * np + 1) * w],
                };
                // the two finer rows each sample comes from (the same row along x)
                let (ra, rb) = if along_x {
                    (p, p)
                } else {
                    (2 * p, (2 * p + 1).min(ph - 1))
                };
                let (cov_a, cov_b) = (cov(ra), cov(rb));
                let coverage = |c: Option<&[f32]>, plane0: &[f32], i: usize| match c {
                    Some(c) => c[i],
                    None => f32::from(u8::from(!plane0[i].is_nan())),
                };
                let raws: Vec<(&[f32], &[f32])> =
                    (0..np).map(|pl| (raw(pl, ra), raw(pl, rb))).collect();
                let (out, covs) = row.split_at_mut(2 * np * w);
                for q in parts.into_iter().flatten() {
                    let (ia, ib) = if along_x {
                        (2 * q, (2 * q + 1).min(pw - 1))
                    } else {
                        (q, q)
                    };
                    let (ca, cb) = (
                        coverage(cov_a, raws[0].0, ia),
                        coverage(cov_b, raws[0].1, ib),
                    );
                    let c = 0.5 * (ca + cb);
                    covs[q] = c;
                    if ca + cb <= 0.0 {
                        continue;
                    }
                    for (pl, (a, b)) in raws.iter().enumerate() {
                        let (va, vb) = (a[ia], b[ib]);
                        let v = match (ca > 0.0, cb > 0.0) {
                            (true, true) => (va * ca + vb * cb) / (ca + cb),
                            (true, false) => va,
                            _ => vb,
                        };
                        out[(np + pl) * w + q] = v;
                        if c >= 0.5 {
                            out[pl * w + q] = v;
                        }
                    }
                }
                made.push((
                    p,
                    MipRow {
                        data: row,
                        made: hull,
                    },
                ));
            }
        }
        let m = self.levels[k].as_mut().expect("made above");
        for (p, row) in made {
            m.rows[p] = Some(row);
        }
    }
}

/// Separable filtering with per-axis scales: weights `k(dx/sx)·k(dy/sy)`, on samples averaged
/// `mip.step`× along x (the scale along x shrinks by the same factor).
/// The y weights of the last texel: texels of one output row share them (lon/lat sources).
#[derive(Debug)]
struct RowWeights {
    key: (f64, f64, f64),
    r0: i64,
    nr: usize,
    wy: [f64; SEP_MAX],
    wy_pos: f64,
}

impl Default for RowWeights {
    fn default() -> Self {
        Self {
            key: (0.0, 0.0, 0.0),
            r0: 0,
            nr: 0,
            wy: [0.0; SEP_MAX],
            wy_pos: 0.0,
        }
    }
}

/// Most taps along one axis: a footprint's scale is at most [`MIP_SCALE`] samples (the widest
/// kernel, Lanczos3, reaches 3 scales either side).
const SEP_MAX: usize = 6 * MIP_SCALE as usize + 1;

fn separable(
    mip: MipView<'_>,
    lut: &KernelLut,
    x: f64,
    y: f64,
    (sx, sy): (f64, f64),
    acc: &mut [f64],
    rows: &mut RowWeights,
) -> bool {
    const MAX: usize = SEP_MAX;
    let s = lut.kernel().support();
    let u = (x - mip.c0) / mip.step.0;
    let su = sx / mip.step.0;
    let v = (y - mip.r0) / mip.step.1;
    let sv = sy / mip.step.1;
    let (c0, c1) = (ceil(u - 0.5 - s * su), floor(u - 0.5 + s * su));
    let nc = (c1 - c0 + 1).max(0) as usize;
    if rows.key != (v, sv, mip.step.1) {
        let (r0, r1) = (ceil(v - 0.5 - s * sv), floor(v - 0.5 + s * sv));
        rows.key = (v, sv, mip.step.1);
        rows.r0 = r0;
        rows.nr = (r1 - r0 + 1).max(0) as usize;
        rows.wy_pos = 0.0;
        if rows.nr <= MAX {
            for j in 0..rows.nr {
                rows.wy[j] = lut.weight(((r0 + j as i64) as f64 + 0.5 - v) / sv);
                rows.wy_pos += rows.wy[j].max(0.0);
            }
        }
    }
    let (r0, nr, wy_pos) = (rows.r0, rows.nr, rows.wy_pos);
    if nc == 0 || nr == 0 || nc > MAX || nr > MAX {
        return false;
    }
    let wy = &rows.wy;
    let mut wx = [0f64; MAX];
    let mut wx_pos = 0.0;
    for (i, w) in wx.iter_mut().enumerate().take(nc) {
        *w = lut.weight(((c0 + i as i64) as f64 + 0.5 - u) / su);
        wx_pos += w.max(0.0);
    }
    acc.iter_mut().for_each(|a| *a = 0.0);
    let (mut wsum, mut wpos_valid) = (0.0, 0.0);
    let (mw, mh) = (mip.w as i64, mip.h as i64);
    // the columns inside the samples, once for all rows
    let i0 = (-c0).max(0) as usize;
    let i1 = ((mw - c0).max(0) as usize).min(nc);
    if i0 >= i1 {
        return false;
    }
    let nplanes = mip.nplanes;
    for (j, &wyj) in wy.iter().enumerate().take(nr) {
        if wyj == 0.0 {
            continue;
        }
        let r = r0 + j as i64;
        if r < 0 || r >= mh {
            continue;
        }
        // c0 + i ≥ 0 for i ≥ i0, so every index below is in the row
        let at = |i: usize| (c0 + i as i64) as usize;
        let row0 = &mip.row(0, r as usize)[at(i0)..at(i1)];
        // one horizontal pass per row, then weight the row by wy
        let (mut sv, mut sw, mut sp) = (0.0f64, 0.0f64, 0.0f64);
        let mut sv_other = [0.0f64; 3];
        for i in i0..i1 {
            let v0 = row0[i - i0];
            if v0.is_nan() {
                continue;
            }
            let w = wx[i];
            sv += w * f64::from(v0);
            sw += w;
            sp += w.max(0.0);
            for (p, acc_p) in sv_other.iter_mut().enumerate().take(nplanes - 1) {
                *acc_p += w * f64::from(mip.row(p + 1, r as usize)[at(i)]);
            }
        }
        acc[0] += wyj * sv;
        for p in 1..nplanes {
            acc[p] += wyj * sv_other[p - 1];
        }
        wsum += wyj * sw;
        wpos_valid += wyj.max(0.0) * sp;
    }
    let wpos_all = wx_pos * wy_pos;
    if wpos_all <= 0.0 || wpos_valid < MIN_COVERAGE * wpos_all || wsum.abs() < 1e-6 * wpos_all {
        return false;
    }
    acc.iter_mut().for_each(|a| *a /= wsum);
    true
}

/// Which pole a texel's footprint reaches across (true: north), for a wrapping source that
/// reaches that pole: such texels are filtered on rings ([`Ring`]). `y` is the texel's source
/// row, `sy` its footprint's scale in rows, `support` the separable kernel's.
fn ring_pole(info: &SourceInfo, y: f64, sy: f64, support: f64) -> Option<bool> {
    info.lon_period_px?;
    let reach = support * sy;
    if !y.is_finite() || reach.is_nan() || reach <= 0.0 {
        return None;
    }
    if let Some(p) = info.north_pole_y
        && (0.0..reach).contains(&(y - p))
    {
        return Some(true);
    }
    if let Some(p) = info.south_pole_y
        && (0.0..reach).contains(&(p - y))
    {
        return Some(false);
    }
    None
}

/// A row of texels whose footprints reach across a pole, filtered as every other texel of a
/// lon/lat source is, with the separable kernel along east and north, but in a frame that is
/// right there: near a pole a footprint is no rectangle in longitude and latitude but a square
/// on the ground that reaches across the pole. Offsets are taken in the pole's azimuthal
/// equidistant plane (exact along the meridians, off by θ²/6 across them: < 1 % within a
/// level-0 footprint). Texel centres spaced at most half the kernel's scale around the ring
/// (16 at least) are filtered over the source rows within reach (each row averaged into bins no
/// wider than an eighth of the scale on the ground, weighted by their area), and texels between
/// them take the ring's trigonometric interpolation: a band-limited field has few harmonics
/// along a circle that small.
struct Ring {
    /// Per ring sample: the planes, `None` without enough valid data.
    samples: Vec<Option<Vec<f64>>>,
    /// Fourier coefficients (cos, sin) of each plane for harmonics 0..=n/2 when every sample is
    /// valid.
    harmonics: Option<Vec<Vec<(f64, f64)>>>,
    period: f64,
}

impl Ring {
    /// The rows a ring texel with footprint half-height `hy` reads: its square's corners and
    /// one more row.
    fn reach_y(hy: f64) -> f64 {
        hy * std::f64::consts::SQRT_2 + 1.0
    }

    /// The ring of texels at source row `y` (near the north pole when `north`), kernel scale
    /// `sy` source rows, from `win` (which holds a whole period of the rows within reach).
    fn new(win: &Window, info: &SourceInfo, north: bool, y: f64, sy: f64, lut: &KernelLut) -> Self {
        let period = info.lon_period_px.unwrap_or(f64::NAN);
        let pole_y = if north {
            info.north_pole_y
        } else {
            info.south_pole_y
        };
        let samples = match pole_y {
            Some(pole_y) if period.is_finite() && period > 0.0 && sy > 0.0 => {
                let colat = (y - pole_y).abs();
                let n = ((4.0 * std::f64::consts::PI * colat / sy).ceil() as usize)
                    .next_power_of_two()
                    .clamp(16, 1024);
                Self::filter(win, period, (pole_y, north), (y, n), sy, lut)
            }
            _ => vec![None; 16],
        };
        let n = samples.len();
        let np = samples.first().and_then(|s| s.as_ref()).map_or(0, Vec::len);
        let harmonics = samples.iter().all(Option::is_some).then(|| {
            (0..np)
                .map(|p| {
                    (0..=n / 2)
                        .map(|m| {
                            let (mut a, mut b) = (0.0, 0.0);
                            for (k, s) in samples.iter().enumerate() {
                                let v = s.as_ref().map_or(0.0, |s| s[p]);
                                let ph = std::f64::consts::TAU * ((m * k) % n) as f64 / n as f64;
                                a += v * ph.cos();
                                b += v * ph.sin();
                            }
                            // the mean and the Nyquist harmonic count once, the others twice
                            let f = if m == 0 || m == n / 2 { 1.0 } else { 2.0 };
                            (a * f / n as f64, b * f / n as f64)
                        })
                        .collect()
                })
                .collect()
        });
        Self {
            samples,
            harmonics,
            period,
        }
    }

    /// The `n` ring samples at source row `y`; sample k lies at source x = k·period/n.
    fn filter(
        win: &Window,
        period: f64,
        (pole_y, north): (f64, bool),
        (y, n): (f64, usize),
        sy: f64,
        lut: &KernelLut,
    ) -> Vec<Option<Vec<f64>>> {
        let step = win.step as f64;
        let n_period = (period / step).round() as usize;
        let np = win.planes.len();
        if n_period == 0 || n_period > win.w {
            return vec![None; n];
        }
        // colatitudes in source rows; the kernel's unit is `sy` rows
        let colat_t = (y - pole_y).abs();
        let reach = lut.kernel().support() * sy * std::f64::consts::SQRT_2;
        let rad = std::f64::consts::TAU / period;
        // per row within reach: (colatitude, area weight of one bin, bins (x, planes, valid share))
        let mut rows = Vec::new();
        for q in 0..win.h {
            let yc = win.r0 as f64 + (q as f64 + 0.5) * step;
            let colat = if north { yc - pole_y } else { pole_y - yc };
            if colat < 0.0 || colat >= colat_t + reach + step {
                continue;
            }
            // the row's band on the sphere, in radians (one source row = `rad` radians when the
            // pixels are square in degrees; the band's area is what matters, and its ratio
            // between rows)
            let (top, bot) = (
                (colat - step / 2.0).max(0.0) * rad,
                (colat + step / 2.0) * rad,
            );
            let area = top.cos() - bot.cos();
            // at most one bin a sample: every bin holds one or more
            let nb = ((16.0 * std::f64::consts::PI * bot.sin() / (sy * rad)).ceil() as usize)
                .clamp(1, n_period);
            let base = q * win.w;
            let mut bins = Vec::with_capacity(nb);
            for b in 0..nb {
                let (s0, s1) = (b * n_period / nb, (b + 1) * n_period / nb);
                let mut sums = vec![0f64; np];
                let mut n = 0usize;
                for c in s0..s1 {
                    if win.planes[0][base + c].is_nan() {
                        continue;
                    }
                    n += 1;
                    for (sum, plane) in sums.iter_mut().zip(&win.planes) {
                        *sum += f64::from(plane[base + c]);
                    }
                }
                let xc = win.c0 as f64 + (s0 + s1) as f64 / 2.0 * step;
                let share = n as f64 / (s1 - s0) as f64;
                if n > 0 {
                    sums.iter_mut().for_each(|v| *v /= n as f64);
                }
                bins.push(((xc * rad).sin_cos(), sums, share));
            }
            rows.push((colat * rad, area / nb as f64, bins));
        }
        let (ct, scale) = (colat_t * rad, sy * rad);
        (0..n)
            .map(|k| {
                let (sk, ck) = (std::f64::consts::TAU * k as f64 / n as f64).sin_cos();
                let mut acc = vec![0f64; np];
                let (mut wsum, mut wpos_all, mut wpos_valid) = (0.0, 0.0, 0.0);
                for (colat, area, bins) in &rows {
                    for ((sc, cc), vals, share) in bins {
                        // the source point in the plane, the texel at (θt, 0), north towards
                        // the pole; its azimuth from the texel's is the difference of the two
                        let (sin, cos) = (sc * ck - cc * sk, cc * ck + sc * sk);
                        let (east, north) = (colat * sin, ct - colat * cos);
                        let w = lut.weight(east / scale) * lut.weight(north / scale) * area;
                        if w == 0.0 {
                            continue;
                        }
                        wpos_all += w.max(0.0);
                        if *share == 0.0 {
                            continue;
                        }
                        let wv = w * share;
                        wpos_valid += wv.max(0.0);
                        wsum += wv;
                        for (a, v) in acc.iter_mut().zip(vals) {
                            *a += wv * v;
                        }
                    }
                }
                (wpos_all > 0.0
                    && wpos_valid >= MIN_COVERAGE * wpos_all
                    && wsum.abs() >= 1e-6 * wpos_all)
                    .then(|| acc.into_iter().map(|a| a / wsum).collect())
            })
            .collect()
    }

    /// The planes at source x `x` (`None` where the nearest ring sample has too little data).
    fn at(&self, x: f64) -> Option<Vec<f64>> {
        if !x.is_finite() {
            return None;
        }
        let n = self.samples.len();
        let turn = (x / self.period).rem_euclid(1.0);
        let nearest = ((turn * n as f64).round() as usize) % n;
        let Some(h) = &self.harmonics else {
            return self.samples[nearest].clone();
        };
        // cos and sin of m·phase for every harmonic by the angle-addition recurrence, restarted
        // from a direct evaluation every 32 steps (its error then stays at a few ulps)
        let (s1, c1) = (std::f64::consts::TAU * turn).sin_cos();
        let mut out = vec![0f64; h.len()];
        let (mut cm, mut sm) = (1.0, 0.0);
        for m in 0..h.first().map_or(0, Vec::len) {
            if m > 0 && m % 32 == 0 {
                (sm, cm) = (std::f64::consts::TAU * turn * m as f64).sin_cos();
            }
            for (o, c) in out.iter_mut().zip(h) {
                let (a, b) = c[m];
                *o += a * cm + b * sm;
            }
            (cm, sm) = (cm * c1 - sm * s1, sm * c1 + cm * s1);
        }
        Some(out)
    }
}

/// Largest pixel coordinate a texel may map to: far beyond any raster GDAL opens (2^21 pixels a
/// side at most, `sc_raster::MAX_SIDE`), far inside i64.
const MAX_PIXEL_COORD: f64 = (1u64 << 40) as f64;

/// `floor` without a libm call (saturating; the values here are within ±2^40 plus a footprint).
#[inline]
fn floor(v: f64) -> i64 {
    let i = v as i64;
    i.saturating_sub(i64::from((i as f64) > v))
}

/// `ceil` without a libm call (saturating).
#[inline]
fn ceil(v: f64) -> i64 {
    let i = v as i64;
    i.saturating_add(i64::from((i as f64) < v))
}

/// Sample of `win` at (c, r): source pixel coordinates for a full window, or
/// `c0 + sample index` for an averaged one (see `nearest`).
fn sample(win: &Window, c: i64, r: i64, p: usize) -> f32 {
    let (cc, rr) = (c - win.c0, r - win.r0);
    if cc < 0 || rr < 0 || cc >= win.w as i64 || rr >= win.h as i64 {
        return f32::NAN;
    }
    win.planes[p][rr as usize * win.w + cc as usize]
}

fn nearest(win: &Window, x: f64, y: f64, acc: &mut [f64]) -> bool {
    // in source pixels; an averaged window's samples cover step×step pixels
    let k = win.step as i64;
    let (c, r) = (
        win.c0 + (floor(x) - win.c0).div_euclid(k),
        win.r0 + (floor(y) - win.r0).div_euclid(k),
    );
    if sample(win, c, r, 0).is_nan() {
        return false;
    }
    for (p, a) in acc.iter_mut().enumerate() {
        *a = f64::from(sample(win, c, r, p));
    }
    true
}

/// Radial (EWA) filtering for rotated footprints, on block-averaged samples whose centres are
/// measured in source pixels.
fn filtered(
    mip: MipView<'_>,
    f: &Footprint,
    lut: &KernelLut,
    x: f64,
    y: f64,
    half: (f64, f64),
    acc: &mut [f64],
) -> bool {
    let (hx, hy) = half;
    let (bx, by) = mip.step;
    // sample index range covering [x − hx, x + hx] × [y − hy, y + hy]
    let (q0, q1) = (floor((x - hx - mip.c0) / bx), floor((x + hx - mip.c0) / bx));
    let (p0, p1) = (floor((y - hy - mip.r0) / by), floor((y + hy - mip.r0) / by));
    let s2 = lut.support2();
    acc.iter_mut().for_each(|a| *a = 0.0);
    let (mut wsum, mut wpos_all, mut wpos_valid) = (0.0, 0.0, 0.0);
    for p in p0..=p1 {
        let dy = mip.r0 + (p as f64 + 0.5) * by - y;
        let row_ok = p >= 0 && p < mip.h as i64;
        for q in q0..=q1 {
            let dx = mip.c0 + (q as f64 + 0.5) * bx - x;
            let d2 = f.dist2(dx, dy);
            if d2 >= s2 {
                continue;
            }
            let wgt = lut.weight_d2(d2);
            if wgt > 0.0 {
                wpos_all += wgt;
            }
            if !row_ok || q < 0 || q >= mip.w as i64 {
                continue;
            }
            let (row, col) = (p as usize, q as usize);
            let v0 = mip.row(0, row)[col];
            if v0.is_nan() {
                continue;
            }
            if wgt > 0.0 {
                wpos_valid += wgt;
            }
            wsum += wgt;
            acc[0] += wgt * f64::from(v0);
            for (k, a) in acc.iter_mut().enumerate().skip(1) {
                *a += wgt * f64::from(mip.row(k, row)[col]);
            }
        }
    }
    if wpos_all <= 0.0 || wpos_valid < MIN_COVERAGE * wpos_all || wsum.abs() < 1e-6 * wpos_all {
        return false;
    }
    acc.iter_mut().for_each(|a| *a /= wsum);
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use sc_core::{LevelId, LonLat};
    use std::path::PathBuf;

    /// A lon/lat raster in memory: `w×h` pixels over `[lon0, lon0 + w·d] × [lat0 − h·d, lat0]`,
    /// a smooth field with a rectangle of nodata, wrapping and reaching both poles when global.
    struct Synthetic {
        info: SourceInfo,
        planes: Vec<Vec<f32>>,
    }

    impl Synthetic {
        fn new(w: usize, h: usize, lon0: f64, lat0: f64, d: f64, nplanes: usize) -> Self {
            let planes = (0..nplanes)
                .map(|p| {
                    (0..w * h)
                        .map(|k| {
                            let (c, r) = ((k % w) as f64, (k / w) as f64);
                            let hole = (w / 3..w / 3 + w / 8).contains(&(k % w))
                                && (h / 2..h / 2 + h / 6).contains(&(k / w));
                            if hole && p == 0 {
                                f32::NAN
                            } else {
                                (1000.0 * (c * 0.37 + p as f64).sin() * (r * 0.23).cos()
                                    + 17.0 * ((c * r) % 7.0)) as f32
                            }
                        })
                        .collect()
                })
                .collect();
            Self::with_planes(w, h, lon0, lat0, d, planes)
        }

        /// A raster of `planes` (`w×h` each) over `[lon0, lon0 + w·d] × [lat0 − h·d, lat0]`.
        fn with_planes(
            w: usize,
            h: usize,
            lon0: f64,
            lat0: f64,
            d: f64,
            planes: Vec<Vec<f32>>,
        ) -> Self {
            let global = (w as f64 * d - 360.0).abs() < 1e-9 && (h as f64 * d - 180.0).abs() < 1e-9;
            let info = SourceInfo {
                path: PathBuf::from("synthetic"),
                width: w,
                height: h,
                geotransform: [lon0, d, 0.0, lat0, 0.0, -d],
                geographic: true,
                crs: "EPSG:4326".into(),
                bands: (1..=planes.len()).collect(),
                data_type: "Float32".into(),
                nodata: None,
                lon_period_px: global.then_some(w as f64),
                north_pole_y: global.then_some(0.0),
                south_pole_y: global.then_some(h as f64),
                warnings: Vec::new(),
                stretch: Vec::new(),
            };
            Self { info, planes }
        }
    }

    impl Synthetic {
        fn opaque(mut self) -> Self {
            let valid: Vec<bool> = self.planes[0].iter().map(|v| !v.is_nan()).collect();
            for (a, ok) in self.planes[3].iter_mut().zip(valid) {
                *a = if ok { 1.0 } else { f32::NAN };
            }
            self
        }
    }

    impl PixelSource for Synthetic {
        fn info(&self) -> &SourceInfo {
            &self.info
        }
        fn lonlat_to_pixel(&self, x: &mut [f64], y: &mut [f64]) {
            let gt = self.info.geotransform;
            for (lon, lat) in x.iter_mut().zip(y.iter_mut()) {
                *lon = (*lon - gt[0]).rem_euclid(360.0) / gt[1];
                *lat = (*lat - gt[3]) / gt[5];
            }
        }
        fn read_region(&self, c0: i64, r0: i64, w: usize, h: usize) -> Result<Window> {
            let (sw, sh) = (self.info.width as i64, self.info.height as i64);
            let wraps = self.info.lon_period_px.is_some();
            let mut planes = vec![vec![f32::NAN; w * h]; self.planes.len()];
            for r in 0..h as i64 {
                for c in 0..w as i64 {
                    let (mut sr, mut sc) = (r0 + r, c0 + c);
                    if wraps && (sr < 0 || sr >= sh) {
                        // across a pole: the mirrored row on the opposite meridian
                        sr = if sr < 0 { -sr - 1 } else { 2 * sh - sr - 1 };
                        sc += sw / 2;
                    }
                    if wraps {
                        sc = sc.rem_euclid(sw);
                    }
                    if !(0..sh).contains(&sr) || !(0..sw).contains(&sc) {
                        continue;
                    }
                    for (out, src) in planes.iter_mut().zip(&self.planes) {
                        out[(r * w as i64 + c) as usize] = src[(sr * sw + sc) as usize];
                    }
                }
            }
            Ok(Window {
                c0,
                r0,
                w,
                h,
                step: 1,
                planes,
                memory: None,
            })
        }
    }

    impl Synthetic {
        /// A global lon/lat raster of `w × h` pixels holding `f(pixel centre)`.
        fn global_fn(w: usize, h: usize, f: &(dyn Fn(LonLat) -> f64 + Sync)) -> Self {
            let d = 360.0 / w as f64;
            let plane = (0..w * h)
                .map(|k| {
                    let (c, r) = ((k % w) as f64, (k / w) as f64);
                    f(LonLat::new(-180.0 + (c + 0.5) * d, 90.0 - (r + 0.5) * d)) as f32
                })
                .collect();
            Self::with_planes(w, h, -180.0, 90.0, d, vec![plane])
        }
    }

    /// Every texel of isotropic `level` resampled from `src` (row-major, NaN = nodata).
    fn whole_level(src: &Synthetic, grid: GridSpec, level: LevelId, kernel: Kernel) -> Vec<f64> {
        let (w, t) = (grid.width(level) as usize, grid.tile_size() as usize);
        let mut out = vec![f64::NAN; w * grid.height(level) as usize];
        let kernels = Kernels::new(kernel);
        for y in 0..grid.tiles_y(level) {
            for x in 0..grid.tiles_x(level) {
                let tile = TileId { level, x, y };
                let Some(s) = resample_tile(src, grid, tile, &kernels).expect("resample") else {
                    continue;
                };
                let (ox, oy) = tile.origin_texel(grid);
                for (k, v) in s.planes[0].iter().enumerate() {
                    out[(oy as usize + k / t) * w + ox as usize + k % t] = f64::from(*v);
                }
            }
        }
        out
    }

    /// Plane waves on the sphere ingested by every resampling onto levels 1–3, compared with the
    /// analytic signal at every texel centre, latitude band by band, the pole rows included.
    /// Cubic and Lanczos keep a wave at 0.1× the level's Nyquist (error ≤ 1 %) and remove one at
    /// 6× (residual ≤ 3 %). Bilinear filters with a tent, which is softer: its response is
    /// sinc²(f·ρ), 4.5 % at the 1.5 cycles per texel a 6× wave has at 60°, so its pass band is
    /// checked at 0.05× Nyquist and its stop band at ≤ 6 %. Nearest point-samples (it aliases by
    /// design): from a source whose pixels are the level's texels it must give every texel its
    /// own centre's value.
    #[test]
    fn plane_waves_keep_their_values_at_every_texel_centre_to_the_poles() {
        use sc_core::signal::{
            PlaneWaves, QUALITY_BANDS, Wave, nyquist, pass_band_error, stop_band_residual,
        };
        let grid = GridSpec::new(32).expect("tile size");
        // (kernel, pass-band fraction of Nyquist, pass limit, stop limit)
        let kernels = [
            (Kernel::Nearest, 0.1, 1e-6, None),
            (Kernel::Bilinear, 0.05, 0.01, Some(0.06)),
            (Kernel::Cubic, 0.1, 0.01, Some(0.03)),
            (Kernel::Lanczos2, 0.1, 0.01, Some(0.03)),
            (Kernel::Lanczos3, 0.1, 0.01, Some(0.03)),
        ];
        let mut worst = Vec::new();
        for level in 1..=3 {
            let id = LevelId::iso(level).expect("level");
            let (w, h) = (grid.width(id) as usize, grid.height(id) as usize);
            let nyq = nyquist(grid, id);
            for (kernel, fraction, limit, _) in kernels {
                let pass = PlaneWaves::at_fraction_of_nyquist(grid, id, fraction);
                // filters read a source 4× finer than the level; nearest one on its texels
                let k = if kernel == Kernel::Nearest { 1 } else { 4 };
                let src = Synthetic::global_fn(k * w, k * h, &|p| pass.eval(p));
                let v = whole_level(&src, grid, id, kernel);
                let holes = v.iter().filter(|v| v.is_nan()).count();
                assert_eq!(holes, 0, "{kernel:?} level {level}: texels without data");
                for b in pass_band_error(grid, id, &v, &pass, &QUALITY_BANDS) {
                    worst.push((
                        b.rms / limit,
                        format!("{kernel:?} L{level} pass band: {b:?}"),
                    ));
                }
            }
            // one wave at a time at 6× the level's Nyquist, the source 8× finer
            for dir in [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
                let wave = Wave {
                    dir,
                    omega: 6.0 * nyq,
                    phase: 0.3,
                    amp: 1.0,
                };
                let stop = PlaneWaves { waves: vec![wave] };
                let src = Synthetic::global_fn(8 * w, 8 * h, &|p| stop.eval(p));
                for (kernel, _, _, limit) in kernels {
                    let Some(limit) = limit else { continue };
                    let v = whole_level(&src, grid, id, kernel);
                    let reach = kernel.support() * std::f64::consts::PI / nyq * 1.2;
                    for b in stop_band_residual(grid, id, &v, &wave, reach, &QUALITY_BANDS) {
                        worst.push((
                            b.rms / limit,
                            format!("{kernel:?} L{level} stop band, wave along {dir:?}: {b:?}"),
                        ));
                    }
                }
            }
        }
        // the pole rows were measured
        assert!(worst.iter().any(|(_, w)| w.contains("lat0: 89.5")));
        worst.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (r, w) in worst
            .iter()
            .filter(|w| !w.1.starts_with("Bilinear"))
            .take(4)
        {
            eprintln!("{r:.2}× the limit: {w}");
        }
        let (ratio, what) = worst
            .into_iter()
            .fold((0.0, String::new()), |a, b| if b.0 > a.0 { b } else { a });
        assert!(ratio <= 1.0, "{ratio:.2}× the limit: {what}");
    }

    /// Every `step`-th tile of each row of levels 1, 3, (3, 2) and 5.
    fn test_tiles(grid: GridSpec, step: usize) -> Vec<TileId> {
        let mut tiles = Vec::new();
        for (level, aniso) in [(1, 0), (3, 0), (3, 2), (5, 0)] {
            let level = LevelId::new(level, aniso).expect("level");
            for y in 0..grid.tiles_y(level) {
                for x in (0..grid.tiles_x(level)).step_by(step) {
                    tiles.push(TileId { level, x, y });
                }
            }
        }
        tiles
    }

    /// The row-by-row path gives what the texel-by-texel path gives: the same texels with data,
    /// the same values up to the order of the additions, for sources finer and coarser than the
    /// level, global ones across the poles and regional ones at their edges.
    #[test]
    fn rows_filter_like_texels() {
        let grid = GridSpec::new(64).expect("tile size");
        let sources = [
            // global, coarser than level 3 (magnified) and finer than level 1 (minified)
            Synthetic::new(720, 360, -180.0, 90.0, 0.5, 1),
            Synthetic::new(360, 180, -180.0, 90.0, 1.0, 4),
            // an opaque colour source (alpha 1 wherever it has data): alpha is not filtered
            Synthetic::new(360, 180, -180.0, 90.0, 1.0, 4).opaque(),
            // regional, with edges inside tiles
            Synthetic::new(300, 200, 10.3, 60.7, 0.07, 1),
        ];
        let mut compared = 0;
        for src in &sources {
            for kernel in [Kernel::Bilinear, Kernel::Cubic, Kernel::Lanczos3] {
                let kernels = Kernels::new(kernel);
                for tile in test_tiles(grid, 3) {
                    let rows =
                        resample_lonlat(src, grid, tile, &kernels, Lanes::Where).expect("rows");
                    let texels = resample_texels(src, grid, tile, &kernels).expect("texels");
                    let (Some(a), Some(b)) = (&rows, &texels) else {
                        assert_eq!(rows.is_some(), texels.is_some(), "{tile:?}");
                        continue;
                    };
                    assert_eq!((a.footprint, a.covered), (b.footprint, b.covered));
                    for (pa, pb) in a.planes.iter().zip(&b.planes) {
                        for (k, (va, vb)) in pa.iter().zip(pb).enumerate() {
                            let same = (va.is_nan() && vb.is_nan())
                                || (va - vb).abs() <= 1e-4 * (1.0 + vb.abs());
                            assert!(same, "{kernel:?} {tile:?} texel {k}: {va} vs {vb}");
                        }
                    }
                    compared += 1;
                }
            }
        }
        assert!(compared > 100, "{compared} tiles compared");
    }

    /// The nearest kernel by tile axes picks what the texel-by-texel path picks, bit for bit, in
    /// and out of regional sources and across the poles of global ones.
    #[test]
    fn nearest_by_axes_picks_what_each_texel_picks() {
        let grid = GridSpec::new(64).expect("tile size");
        let sources = [
            Synthetic::new(720, 360, -180.0, 90.0, 0.5, 1),
            Synthetic::new(360, 180, -180.0, 90.0, 1.0, 4),
            Synthetic::new(300, 200, 10.3, 60.7, 0.07, 1),
            Synthetic::new(300, 200, 170.1, -70.2, 0.11, 1),
        ];
        let kernels = Kernels::new(Kernel::Nearest);
        let (mut tiles, mut texels) = (0, 0);
        for src in &sources {
            for tile in test_tiles(grid, 1) {
                let a = nearest_lonlat(src, grid, tile).expect("axes");
                let b = resample_texels(src, grid, tile, &kernels).expect("texels");
                let (Some(a), Some(b)) = (&a, &b) else {
                    assert_eq!(a.is_some(), b.is_some(), "{tile:?}");
                    continue;
                };
                assert_eq!(
                    (a.footprint, a.covered),
                    (b.footprint, b.covered),
                    "{tile:?}"
                );
                for (pa, pb) in a.planes.iter().zip(&b.planes) {
                    for (k, (va, vb)) in pa.iter().zip(pb).enumerate() {
                        assert_eq!(va.to_bits(), vb.to_bits(), "{tile:?} texel {k}");
                    }
                }
                tiles += 1;
                texels += a.covered;
            }
        }
        assert!(
            tiles > 100 && texels > 100_000,
            "{tiles} tiles, {texels} texels"
        );
    }

    /// Texels filtered in lanes are the texels filtered one at a time, bit for bit: the same
    /// operations in the same order, the padded taps not added.
    #[test]
    fn lanes_filter_as_one_texel_at_a_time() {
        let grid = GridSpec::new(64).expect("tile size");
        let sources = [
            Synthetic::new(720, 360, -180.0, 90.0, 0.5, 1),
            Synthetic::new(360, 180, -180.0, 90.0, 1.0, 4).opaque(),
            Synthetic::new(300, 200, 10.3, 60.7, 0.07, 1),
        ];
        let mut texels = 0usize;
        for src in &sources {
            for kernel in [Kernel::Cubic, Kernel::Lanczos3, Kernel::Bilinear] {
                let kernels = Kernels::new(kernel);
                for tile in test_tiles(grid, 5) {
                    let run =
                        |lanes| resample_lonlat(src, grid, tile, &kernels, lanes).expect("rows");
                    let (a, b) = (run(Lanes::Where), run(Lanes::Never));
                    let (Some(a), Some(b)) = (&a, &b) else {
                        assert_eq!(a.is_some(), b.is_some(), "{tile:?}");
                        continue;
                    };
                    for (pa, pb) in a.planes.iter().zip(&b.planes) {
                        for (k, (va, vb)) in pa.iter().zip(pb).enumerate() {
                            assert_eq!(
                                va.to_bits(),
                                vb.to_bits(),
                                "{kernel:?} {tile:?} texel {k}: {va} vs {vb}"
                            );
                        }
                    }
                    texels += a.planes[0].len();
                }
            }
        }
        assert!(texels > 100_000, "{texels} texels compared");
    }
}
