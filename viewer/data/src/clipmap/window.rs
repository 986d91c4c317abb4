//! Where a clipmap level lies in map space, and which of its texels change when it moves.

use std::f64::consts::PI;

use sc_view_space::transform::Viewer;
use sc_view_space::transform::level_outer;

/// Texels per side of a clipmap level (heights; tiles are this size).
pub const CLIPMAP_N: u32 = 512;

/// The most texels a side a height window gets ([`height_texels_for_picture`]): four tiles.
pub const MAX_HEIGHT_N: u32 = 4 * CLIPMAP_N;

/// How large a texel of the height windows may look half way across its ring, pixels: a
/// window of n texels holds, at arc θ̃ from the viewer, texels 2θ̃/n to 4θ̃/n across (seen from
/// near the ground, that many radians). Over the Alps (`tests/e2e/skyline.rs`) texels of up to
/// 1.5 px left the skylines of the clipmap and CDLOD at p99 2 px below the finest heights at 270
/// and 540 rows (a coarser level's heights lower narrow summits); at 1 px, p99 1 px.
pub const HEIGHT_TEXEL_PX: f64 = 1.0;

/// Texels a side of the height windows for a picture `height_px` pixels high with vertical
/// field of view `fov_rad`: the fewest, a power of two from [`CLIPMAP_N`] to [`MAX_HEIGHT_N`],
/// whose texels half way across their ring (8/(3n) radians seen from near the ground) span at
/// most [`HEIGHT_TEXEL_PX`] pixels: 512 up to 200 rows at 60°, 1024 up to 400, 2048 above.
pub fn height_texels_for_picture(height_px: u32, fov_rad: f64) -> u32 {
    let pixels_per_rad = f64::from(height_px.max(1)) / fov_rad.max(1e-6);
    let wanted = 8.0 / 3.0 * pixels_per_rad / HEIGHT_TEXEL_PX;
    (wanted.min(f64::from(MAX_HEIGHT_N)).ceil() as u32)
        .next_power_of_two()
        .clamp(CLIPMAP_N, MAX_HEIGHT_N)
}

/// Texels per side of a colour clipmap level: twice the heights', at half their texel size, so
/// that colour keeps one texel a pixel farther out from the point under the camera (and around a
/// pole, where a window spans the whole circle with this many texels of longitude). Level i's
/// colour texels are the grid level i + 1 has at [`CLIPMAP_N`]; a window overlaps up to 3 × 3
/// of its tiles.
pub const COLOR_N: u32 = 2 * CLIPMAP_N;

/// Where a clipmap level lies in map space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LevelWindow {
    /// Radians of colatitude per texel.
    pub texel_colat: f64,
    /// Radians of longitude per texel.
    pub texel_lon: f64,
}

/// The window of hemisphere level `i` for a viewer at colatitude `colat`, `n` texels a side.
pub fn level_window(i: u32, colat: f64, n: u32) -> LevelWindow {
    let outer = level_outer(i);
    let n = f64::from(n);
    let texel_colat = 2.0 * outer / n;
    let pole_dist = colat.min(PI - colat);
    let texel_lon = if outer >= pole_dist {
        2.0 * PI / n
    } else {
        // the ring's half-width in longitude where it is widest (its poleward edge)
        let half = (outer.sin() / (pole_dist - outer).sin().max(1e-12))
            .min(1.0)
            .asin();
        let k = (2.0 * PI / (2.0 * half)).log2().floor().max(0.0);
        2.0 * PI / (n * 2f64.powf(k))
    };
    LevelWindow {
        texel_colat,
        texel_lon,
    }
}

/// Where clipmap level `i` lies for a viewer: its window, snapped to whole texels of the level's
/// world grid (so a move of less than a texel changes nothing), and where the viewer falls in it.
///
/// World texel (u, v) of the level has its centre at longitude (u + ½)·texel_lon − π and
/// colatitude (v + ½)·texel_colat (v < 0 or beyond π/texel_colat: past a pole). The window holds
/// u0 … u0+w−1, v0 … v0+h−1 (`size` = [w, h]); its texture stores world texel (u, v) at
/// (u mod w, v mod h) (toroidal addressing: a window that moves keeps the texels both windows
/// share in place). A window wider than high is laid out in [`Placement::strips`] strips of
/// its columns one below the other in a square texture ([`Placement::texture_regions`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Texel size.
    pub win: LevelWindow,
    /// Texels of the window: columns, rows.
    pub size: [u32; 2],
    /// First world column and row of the window.
    pub u0: i64,
    /// See `u0`.
    pub v0: i64,
    /// The viewer in texel coordinates relative to (u0, v0) (within [w/2, w/2 + 1) × [h/2,
    /// h/2 + 1) but where a round window's rows stop at a pole).
    pub viewer_texel: [f64; 2],
}

impl Placement {
    /// Level `i`'s placement around `viewer`, `n` texels a side.
    pub fn new(i: u32, viewer: &Viewer, n: u32) -> Self {
        Self::around(viewer, level_window(i, viewer.colat_rad, n), [n, n], None)
    }

    /// Level `i`'s placement around `viewer` for `n × n` texels, laid out round the circle where
    /// the window spans it: 2n columns (half the longitude texel) and n/2 rows (the colatitude
    /// texel kept), centred on the viewer but not past a pole, where rows would repeat the other
    /// side. The same texels hold twice the longitude detail that a round window needs within
    /// 20–60° of a pole, and cover half the colatitude of a square one (the next coarser
    /// level's window covers this level's ring whole). Otherwise as [`Placement::new`].
    pub fn round(i: u32, viewer: &Viewer, n: u32) -> Self {
        let win = level_window(i, viewer.colat_rad, n);
        if win.texel_lon < 2.0 * PI / f64::from(n) * (1.0 - 1e-9) || n < 4 {
            return Self::around(viewer, win, [n, n], None);
        }
        let win = LevelWindow {
            texel_lon: win.texel_lon / 2.0,
            ..win
        };
        let rows = (PI / win.texel_colat).round() as i64;
        Self::around(viewer, win, [2 * n, n / 2], Some(rows))
    }

    /// The window of `size` texels of `win` centred on `viewer`; with `pole_rows` (the rows
    /// from pole to pole), not past a pole.
    fn around(viewer: &Viewer, win: LevelWindow, size: [u32; 2], pole_rows: Option<i64>) -> Self {
        let u = (viewer.lon_rad + PI).rem_euclid(2.0 * PI) / win.texel_lon;
        let v = viewer.colat_rad / win.texel_colat;
        let [w, h] = size.map(i64::from);
        let u0 = u.floor() as i64 - w / 2;
        let mut v0 = v.floor() as i64 - h / 2;
        if let Some(rows) = pole_rows {
            v0 = v0.clamp(0, (rows - h).max(0));
        }
        Self {
            win,
            size,
            u0,
            v0,
            viewer_texel: [u - u0 as f64, v - v0 as f64],
        }
    }

    /// The texture's origin for toroidal addressing: (u0 mod w, v0 mod h).
    pub fn origin(&self) -> [u32; 2] {
        let [w, h] = self.size.map(i64::from);
        [self.u0.rem_euclid(w) as u32, self.v0.rem_euclid(h) as u32]
    }

    /// Longitude and colatitude of the centre of window texel (c, r).
    pub fn texel_centre(&self, c: u32, r: u32) -> (f64, f64) {
        (
            (self.u0 as f64 + f64::from(c) + 0.5) * self.win.texel_lon - PI,
            (self.v0 as f64 + f64::from(r) + 0.5) * self.win.texel_colat,
        )
    }

    /// How many strips of its columns the window's texture is laid out in: 1 for a square
    /// window, 2 for a round one (2n × n/2 texels in n × n).
    pub fn strips(&self) -> u32 {
        (self.size[0] / (2 * self.size[1]).max(1)).max(1)
    }

    /// Whether the window goes round the whole circle of latitude.
    pub fn is_round(&self) -> bool {
        (f64::from(self.size[0]) * self.win.texel_lon - 2.0 * PI).abs() < 1e-9
    }

    /// Region `r` of the window's texture split where it crosses from one strip into the next:
    /// each part with where it lies in the square texture the strips fill (strip s's texel
    /// (x, y) at (x − s·w/strips, y + s·h)).
    pub fn texture_regions(&self, r: Region) -> Vec<(Region, Region)> {
        let side = self.size[0] / self.strips();
        let mut out = Vec::new();
        let mut x = r.x;
        while x < r.x + r.w {
            let strip = x / side;
            let w = (r.x + r.w).min((strip + 1) * side) - x;
            let part = Region { x, w, ..r };
            let at = Region {
                x: x - strip * side,
                y: r.y + strip * self.size[1],
                w,
                h: r.h,
            };
            out.push((part, at));
            x += w;
        }
        out
    }
}

/// Fills a level's texture (its window's texels of `C` samples, toroidal order: see
/// [`Placement`]) by evaluating `f(lon, colat)` at every texel centre of the window.
pub fn fill_window<T: Copy + Default, const C: usize>(
    p: &Placement,
    mut f: impl FnMut(f64, f64) -> [T; C],
) -> Vec<T> {
    let [ox, oy] = p.origin();
    let [w, h] = p.size.map(|s| s as usize);
    let mut out = vec![T::default(); w * h * C];
    for r in 0..h {
        let row = (r + oy as usize) % h;
        for c in 0..w {
            let (lon, colat) = p.texel_centre(c as u32, r as u32);
            let k = (row * w + (c + ox as usize) % w) * C;
            out[k..k + C].copy_from_slice(&f(lon, colat));
        }
    }
    out
}

/// A rectangle of a clipmap texture, in texture texels: `x .. x + w`, `y .. y + h`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// First texture column.
    pub x: u32,
    /// First texture row.
    pub y: u32,
    /// Columns.
    pub w: u32,
    /// Rows.
    pub h: u32,
}

/// Along one axis: the texture intervals (start, length, changed) between the old and new wrap
/// positions, for a window moving from `old` to `new` (first world texel), `n` texels.
fn axis_intervals(old: i64, new: i64, n: u32) -> Vec<(u32, u32, bool)> {
    let nn = i64::from(n);
    let mut cuts = vec![0, old.rem_euclid(nn) as u32, new.rem_euclid(nn) as u32, n];
    cuts.sort_unstable();
    cuts.dedup();
    cuts.windows(2)
        .map(|w| {
            // texture texel t holds world texel w ≡ t (mod n) inside the window: the same world
            // texel before and after iff it lies in both windows
            let t = i64::from(w[0]);
            let world_old = old + (t - old).rem_euclid(nn);
            let world_new = new + (t - new).rem_euclid(nn);
            (w[0], w[1] - w[0], world_old != world_new)
        })
        .collect()
}

/// The texture regions whose texels change when a level's window moves from `old` to `new`
/// (paper §5: the texture split by the old and new wrap positions into up to 9 regions; only those
/// whose content changed are refilled). Empty for a move of less than a texel; the whole texture
/// when the texel size changes or the move is a window or more.
pub fn changed_regions(old: &Placement, new: &Placement) -> Vec<Region> {
    if old.win != new.win || old.size != new.size {
        return all_regions(new);
    }
    let xs = axis_intervals(old.u0, new.u0, new.size[0]);
    let ys = axis_intervals(old.v0, new.v0, new.size[1]);
    let mut out = Vec::new();
    for &(y, h, cy) in &ys {
        for &(x, w, cx) in &xs {
            if cx || cy {
                out.push(Region { x, y, w, h });
            }
        }
    }
    out
}

/// The whole texture of a level placed at `p`, as the ≤ 4 regions its wrap position cuts it into
/// (each holds texels of one tile of the level's grid: see `stream`).
pub fn all_regions(p: &Placement) -> Vec<Region> {
    let [ox, oy] = p.origin();
    let cuts = |o: u32, n: u32| {
        if o == 0 {
            vec![(0, n)]
        } else {
            vec![(0, o), (o, n - o)]
        }
    };
    let mut out = Vec::new();
    for (y, h) in cuts(oy, p.size[1]) {
        for &(x, w) in &cuts(ox, p.size[0]) {
            out.push(Region { x, y, w, h });
        }
    }
    out
}

/// Fills one texture region of a level placed at `p` (`C` samples a texel, row-major within the
/// region) by evaluating `f(lon, colat)` at the centres of the world texels it holds.
pub fn fill_region<T: Copy + Default, const C: usize>(
    p: &Placement,
    region: Region,
    mut f: impl FnMut(f64, f64) -> [T; C],
) -> Vec<T> {
    let [ox, oy] = p.origin();
    let [w, h] = p.size;
    let mut out = Vec::with_capacity((region.w * region.h) as usize * C);
    for ty in region.y..region.y + region.h {
        let r = (ty + h - oy) % h;
        for tx in region.x..region.x + region.w {
            let c = (tx + w - ox) % w;
            let (lon, colat) = p.texel_centre(c, r);
            out.extend_from_slice(&f(lon, colat));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn height_windows_are_the_fewest_texels_that_keep_a_texel_within_the_bound() {
        let fov = 60f64.to_radians();
        for (rows, n) in [
            (135, 512),
            (200, 512),
            (270, 1024),
            (400, 1024),
            (540, 2048),
            (1080, 2048),
        ] {
            assert_eq!(height_texels_for_picture(rows, fov), n, "{rows} rows");
        }
        // a narrower view magnifies: the same rows need more texels, up to the most there are
        assert_eq!(height_texels_for_picture(270, 30f64.to_radians()), 2048);
        assert_eq!(height_texels_for_picture(2160, fov), MAX_HEIGHT_N);
        let mid_ring_px =
            |rows: u32, fov: f64, n: u32| 8.0 / (3.0 * f64::from(n)) * f64::from(rows) / fov;
        for rows in [100, 270, 300, 540, 600, 900, 1080, 1200] {
            for fov_deg in [20.0f64, 45.0, 60.0, 90.0] {
                let fov = fov_deg.to_radians();
                let n = height_texels_for_picture(rows, fov);
                assert!(n == MAX_HEIGHT_N || mid_ring_px(rows, fov, n) <= HEIGHT_TEXEL_PX);
                assert!(n == CLIPMAP_N || mid_ring_px(rows, fov, n / 2) > HEIGHT_TEXEL_PX);
            }
        }
    }

    #[test]
    fn windows_snap_to_texels_and_keep_shared_texels_in_place() {
        let n = 64;
        let v = Viewer::from_deg(46.5, 8.0);
        let p = Placement::new(12, &v, n);
        // less than a texel: nothing to refill
        let nudged = Viewer {
            lon_rad: v.lon_rad + 0.2 * p.win.texel_lon * (1.0 - p.viewer_texel[0].fract()),
            ..v
        };
        assert_eq!(Placement::new(12, &nudged, n).u0, p.u0);
        // three texels east, two south: the texels both windows hold sit at the same index
        let moved = Viewer {
            lon_rad: v.lon_rad + 3.0 * p.win.texel_lon,
            colat_rad: v.colat_rad + 2.0 * p.win.texel_colat,
        };
        let q = Placement::new(12, &moved, n);
        assert_eq!((q.u0 - p.u0, q.v0 - p.v0), (3, 2));
        let at = |p: &Placement| fill_window(p, |lon, colat| [(lon, colat)]);
        let (a, b) = (at(&p), at(&q));
        let mut shared = 0;
        for (k, (x, y)) in a.iter().zip(&b).enumerate() {
            let (c, r) = ((k as u32 % n) as i64, (k as u32 / n) as i64);
            // window column of texture column c in each placement
            let in_p = (c - p.origin()[0] as i64).rem_euclid(n as i64) + p.u0;
            let in_q = (c - q.origin()[0] as i64).rem_euclid(n as i64) + q.u0;
            let row_p = (r - p.origin()[1] as i64).rem_euclid(n as i64) + p.v0;
            let row_q = (r - q.origin()[1] as i64).rem_euclid(n as i64) + q.v0;
            if in_p == in_q && row_p == row_q {
                assert_eq!(x, y);
                shared += 1;
            }
        }
        assert_eq!(shared, (n as usize - 3) * (n as usize - 2));
    }

    /// Moves a window (`place`d, `n`) 200 times from `base` by a fraction of a texel up to more
    /// than a window (the viewer's colatitude kept within `colat`), refilling the changed
    /// regions of a texture laid out as the window's strips: the texture always equals a full
    /// rebuild, and only what changed was touched.
    fn refill_moving_window(
        base: Viewer,
        n: u32,
        colat: (f64, f64),
        place: impl Fn(&Viewer) -> Placement,
    ) {
        let f = |lon: f64, colat: f64| [(lon * 1e6).round() as i64, (colat * 1e6).round() as i64];
        let p0 = place(&base);
        let side = p0.size[0] / p0.strips();
        // the square texture the strips fill, from the window's own (logical) texture
        let lay = |p: &Placement, logical: &[i64]| {
            let mut tex = vec![0i64; (side * side * 2) as usize];
            let all = Region {
                x: 0,
                y: 0,
                w: p.size[0],
                h: p.size[1],
            };
            for (part, at) in p.texture_regions(all) {
                for y in 0..part.h {
                    for x in 0..part.w {
                        let src = (((part.y + y) * p.size[0] + part.x + x) * 2) as usize;
                        let dst = (((at.y + y) * side + at.x + x) * 2) as usize;
                        tex[dst..dst + 2].copy_from_slice(&logical[src..src + 2]);
                    }
                }
            }
            tex
        };
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 33) % 1000) as f64 / 1000.0
        };
        let mut cur = p0;
        let mut tex = lay(&cur, &fill_window(&cur, f));
        for step in 0..200 {
            let scale = [0.3, 2.0, 9.0, 40.0][step % 4];
            let v = Viewer {
                lon_rad: base.lon_rad
                    + (rnd() - 0.3) * scale * cur.win.texel_lon * (step as f64).sqrt(),
                colat_rad: (base.colat_rad + (rnd() - 0.5) * scale * cur.win.texel_colat)
                    .clamp(colat.0, colat.1),
            };
            let next = place(&v);
            assert_eq!(next.size, p0.size, "step {step}");
            let regions = changed_regions(&cur, &next);
            assert!(regions.len() <= 9);
            // each region of a window the tiles' size holds texels of one tile of the grid (so
            // it copies from one tile)
            let [ox, oy] = next.origin();
            let [w, h] = next.size;
            let n64 = i64::from(n);
            for r in regions.iter().filter(|_| next.size == [n, n]) {
                let tile = |tx: u32, ty: u32| {
                    let c = i64::from((tx + w - ox) % w);
                    let row = i64::from((ty + h - oy) % h);
                    (
                        (next.u0 + c).div_euclid(n64),
                        (next.v0 + row).div_euclid(n64),
                    )
                };
                let t0 = tile(r.x, r.y);
                assert_eq!(tile(r.x + r.w - 1, r.y + r.h - 1), t0, "{r:?}");
            }
            let mut touched = 0;
            for r in &regions {
                let data = fill_region(&next, *r, f);
                for (part, at) in next.texture_regions(*r) {
                    for y in 0..part.h {
                        for x in 0..part.w {
                            let src = ((y * r.w + part.x - r.x + x) * 2) as usize;
                            let dst = (((at.y + y) * side + at.x + x) * 2) as usize;
                            tex[dst..dst + 2].copy_from_slice(&data[src..src + 2]);
                        }
                    }
                }
                touched += r.w * r.h;
            }
            // the partial update equals a full rebuild, and touched only what changed
            assert_eq!(tex, lay(&next, &fill_window(&next, f)), "step {step}");
            let (du, dv) = (
                (next.u0 - cur.u0).unsigned_abs(),
                (next.v0 - cur.v0).unsigned_abs(),
            );
            let keep = u64::from(w).saturating_sub(du) * u64::from(h).saturating_sub(dv);
            assert_eq!(u64::from(touched), u64::from(w * h) - keep, "step {step}");
            cur = next;
        }
        // less than a texel: nothing
        let nudge = Viewer {
            lon_rad: base.lon_rad + 0.01 * p0.win.texel_lon * (1.0 - p0.viewer_texel[0].fract()),
            ..base
        };
        assert!(changed_regions(&p0, &place(&nudge)).is_empty());
    }

    #[test]
    fn moved_windows_refill_exactly_the_changed_regions() {
        // across the antimeridian: the viewer starts at 170°E
        refill_moving_window(Viewer::from_deg(60.0, 170.0), 32, (0.0, PI), |v| {
            Placement::new(9, v, 32)
        });
    }

    #[test]
    fn round_windows_fold_into_strips_and_refill_exactly_the_changed_regions() {
        // level 2 reaches the pole from 80°N: round, 2n × n/2 in two strips
        let n = 32;
        let p = Placement::round(2, &Viewer::from_deg(80.0, 10.0), n);
        assert_eq!((p.size, p.strips()), ([64, 16], 2));
        assert!(p.is_round());
        let square = Placement::new(2, &Viewer::from_deg(80.0, 10.0), n);
        assert_eq!(p.win.texel_lon * 2.0, square.win.texel_lon);
        assert_eq!(p.win.texel_colat, square.win.texel_colat);
        // its rows stop at the pole: the first is the pole's
        assert_eq!(p.v0, 0);
        // the strips tile the square texture exactly once
        let mut hit = vec![0u8; (n * n) as usize];
        let all = Region {
            x: 0,
            y: 0,
            w: 64,
            h: 16,
        };
        for (part, at) in p.texture_regions(all) {
            assert_eq!((part.w, part.h), (at.w, at.h));
            for y in at.y..at.y + at.h {
                for x in at.x..at.x + at.w {
                    hit[(y * n + x) as usize] += 1;
                }
            }
        }
        assert!(hit.iter().all(|&h| h == 1));
        // a level away from the poles stays square
        let eq = Placement::round(9, &Viewer::from_deg(10.0, 10.0), n);
        assert_eq!((eq.size, eq.strips()), ([n, n], 1));
        // within the level's reach of a pole (outer 22.5°, 45°): round wherever the viewer goes
        let reach = |deg: f64| deg.to_radians();
        refill_moving_window(Viewer::from_deg(84.0, 170.0), n, (1e-6, reach(22.0)), |v| {
            Placement::round(2, v, n)
        });
        refill_moving_window(
            Viewer::from_deg(-70.0, -30.0),
            n,
            (PI - reach(44.0), PI - 1e-6),
            |v| Placement::round(1, v, n),
        );
    }

    #[test]
    fn windows_widen_in_longitude_towards_the_poles_in_power_of_two_steps() {
        let n = 256;
        let eq = level_window(10, PI / 2.0, n);
        let north = level_window(10, 0.2, n);
        assert!(north.texel_lon > eq.texel_lon);
        let k = (2.0 * PI / (f64::from(n) * north.texel_lon)).log2();
        assert!((k - k.round()).abs() < 1e-9, "2π / 2^k texel rows: {k}");
        // a level that reaches the pole covers the whole circle
        let pole = level_window(2, 0.1, n);
        assert!((pole.texel_lon - 2.0 * PI / f64::from(n)).abs() < 1e-15);
    }
}
