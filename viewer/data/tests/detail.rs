//! Detail below the data's resolution, on a synthetic rough planet stored at level 2 (19.5 km
//! texels): a sum of 3-D plane waves on the sphere (seamless everywhere, a power law in
//! amplitude) north of 40° S, a constant plain south of 50° S.
//!
//! What a user relies on: the detail never changes what the data says at its own resolution
//! (filtered back it is the data), it has no seam (antimeridian, pole, tiles), it is the same
//! planet for the same seed, flat ground stays flat, and the colour over it keeps its mean.

use std::f64::consts::PI;
use std::path::Path;
use std::sync::Arc;

use sc_core::{GridSpec, Kernel, LevelId};
use sc_store::{StoreConfig, StoreReader, StoreWriter};
use sc_view_data::clipmap::{HeightSource, LevelWindow, StoreHeights};
use sc_view_data::detail::{Detail, DetailParams};
use sc_view_data::stream::{
    DetailColorTiles, FnColorTiles, GridId, StoreHeightTiles, TileData, TileKey, TileSource,
};

const RADIUS: f64 = 6_371_008.8;
const LEVEL: u32 = 2;

/// The rough field at a unit vector: 24 plane waves of wavelengths 40 … 3000 km, amplitude ∝
/// wavelength^0.6 (300 m at 40 km), faded out between 40° S and 50° S to a plain at 50 m.
fn field(u: [f64; 3]) -> f64 {
    let mut h = 0.0;
    for j in 0..24u32 {
        let t = f64::from(j) / 23.0;
        let wavelength = 40e3 * (3000e3f64 / 40e3).powf(t);
        // a fixed direction per wave (golden-angle spiral)
        let z = 1.0 - 2.0 * (f64::from(j) + 0.5) / 24.0;
        let a = 2.399_963 * f64::from(j);
        let r = (1.0 - z * z).sqrt();
        let k = [r * a.cos(), r * a.sin(), z];
        let phase = 2.0 * PI * (u[0] * k[0] + u[1] * k[1] + u[2] * k[2]) * RADIUS / wavelength;
        h += 300.0 * (wavelength / 40e3).powf(0.6) * (phase + f64::from(j)).sin();
    }
    let lat = u[2].asin().to_degrees();
    let m = ((lat + 50.0) / 10.0).clamp(0.0, 1.0);
    50.0 + m * h
}

fn unit(lon: f64, colat: f64) -> [f64; 3] {
    [
        colat.sin() * lon.cos(),
        colat.sin() * lon.sin(),
        colat.cos(),
    ]
}

/// The rough planet, stored at level 2 only.
fn rough_store(dir: &Path) -> StoreReader {
    let root = dir.join("rough.zarr");
    let grid = GridSpec::new(256).expect("grid");
    let w = StoreWriter::create(
        &root,
        StoreConfig {
            grid,
            ..StoreConfig::default()
        },
    )
    .expect("create");
    let id = LevelId::iso(LEVEL).expect("level");
    let (width, height) = (grid.width(id), grid.height(id));
    let t = u64::from(grid.tile_size());
    w.write_level::<f32>(id, 2, |tile| {
        Some(
            (0..t * t)
                .map(|k| {
                    let (i, j) = (tile.x * t + k % t, tile.y * t + k / t);
                    let lon = -PI + (i as f64 + 0.5) * 2.0 * PI / width as f64;
                    let colat = (j as f64 + 0.5) * PI / height as f64;
                    field(unit(lon, colat)) as f32
                })
                .collect(),
        )
    })
    .expect("write");
    w.commit(None).expect("commit");
    StoreReader::open(&root).expect("open")
}

/// The stored level's row spacing, metres.
fn d0_m() -> f64 {
    let grid = GridSpec::new(256).expect("grid");
    PI / grid.height(LevelId::iso(LEVEL).expect("level")) as f64 * RADIUS
}

/// A clipmap texel of `m` metres (square on the ground at colatitude `colat`).
fn texel(m: f64, colat: f64) -> LevelWindow {
    LevelWindow {
        texel_colat: m / RADIUS,
        texel_lon: m / RADIUS / colat.sin(),
    }
}

fn samplers(reader: &StoreReader, seed: u64) -> (StoreHeights, StoreHeights) {
    let detail = Arc::new(Detail::new(
        DetailParams {
            seed,
            ..DetailParams::default()
        },
        RADIUS,
    ));
    let plain = StoreHeights::new(reader.clone()).expect("heights");
    let with = StoreHeights::new(reader.clone())
        .expect("heights")
        .with_detail(Some(detail));
    (plain, with)
}

#[test]
fn filtered_back_to_the_data_level_the_detail_is_the_data() {
    let dir = tempfile::tempdir().expect("tempdir");
    let reader = rough_store(dir.path());
    let (mut plain, mut with) = samplers(&reader, 1);
    let d0 = d0_m();
    // samples of d0/16 over 16 × 16 data texels around 20° N 30° E (octaves of λ = d0 … d0/4
    // whole, d0/8 half)
    let step = d0 / 16.0;
    let (lon0, colat0) = (30f64.to_radians(), 70f64.to_radians());
    let win = texel(step, colat0);
    let n = 256;
    let mut residual = vec![0.0f64; n * n];
    for r in 0..n {
        let colat = colat0 + (r as f64 - n as f64 / 2.0) * step / RADIUS;
        let lons: Vec<f64> = (0..n)
            .map(|c| lon0 + (c as f64 - n as f64 / 2.0) * step / RADIUS / colat0.sin())
            .collect();
        let (mut a, mut b) = (Vec::new(), Vec::new());
        plain.fill_row(&lons, colat, win, &mut a);
        with.fill_row(&lons, colat, win, &mut b);
        for c in 0..n {
            residual[r * n + c] = f64::from(b[c]) - f64::from(a[c]);
        }
    }
    let rms = (residual.iter().map(|v| v * v).sum::<f64>() / (n * n) as f64).sqrt();
    assert!(rms > 1.0, "the rough ground gets detail: {rms} m RMS");
    // the pyramid's kernel (jinc-Lanczos3 of the distance in data texels) at data-texel
    // spacing, centred on the middle 4 × 4 data texels
    let k = Kernel::JincLanczos3;
    let mut filtered = Vec::new();
    for cy in -2..2 {
        for cx in -2..2 {
            let (x0, y0) = ((cx as f64 + 0.5) * 16.0, (cy as f64 + 0.5) * 16.0);
            let (mut s, mut w) = (0.0, 0.0);
            for r in 0..n {
                for c in 0..n {
                    let dx = (c as f64 - n as f64 / 2.0 - x0) / 16.0;
                    let dy = (r as f64 - n as f64 / 2.0 - y0) / 16.0;
                    let wt = k.weight((dx * dx + dy * dy).sqrt());
                    s += wt * residual[r * n + c];
                    w += wt;
                }
            }
            filtered.push(s / w);
        }
    }
    let back = (filtered.iter().map(|v| v * v).sum::<f64>() / filtered.len() as f64).sqrt();
    eprintln!("detail {rms:.2} m RMS; filtered back to the data level {back:.3} m RMS");
    assert!(
        back <= 0.1 * rms,
        "filtered back, the detail leaves {back} m of its {rms} m RMS"
    );
}

#[test]
fn flat_ground_stays_flat_and_rough_ground_gets_rougher_with_finer_texels() {
    let dir = tempfile::tempdir().expect("tempdir");
    let reader = rough_store(dir.path());
    let (mut plain, mut with) = samplers(&reader, 1);
    let d0 = d0_m();
    let lons: Vec<f64> = (0..400).map(|c| 0.1 + c as f64 * 1e-4).collect();
    // the plain south of 50° S: not a millimetre
    let colat = 150f64.to_radians();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    plain.fill_row(&lons, colat, texel(d0 / 64.0, colat), &mut a);
    with.fill_row(&lons, colat, texel(d0 / 64.0, colat), &mut b);
    assert_eq!(a, b, "the plain stays flat");
    // the rough north: finer texels carry more octaves
    let colat = 60f64.to_radians();
    let mut rms = Vec::new();
    for div in [8.0, 32.0, 128.0] {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        plain.fill_row(&lons, colat, texel(d0 / div, colat), &mut a);
        with.fill_row(&lons, colat, texel(d0 / div, colat), &mut b);
        let d: Vec<f64> = a
            .iter()
            .zip(&b)
            .map(|(x, y)| f64::from(*y) - f64::from(*x))
            .collect();
        rms.push((d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt());
    }
    assert!(
        rms[0] > 0.5 && rms[0] < rms[1] && rms[1] < rms[2],
        "{rms:?}"
    );
}

#[test]
fn the_detail_has_no_seam_at_the_antimeridian_a_pole_or_a_tile_border() {
    let dir = tempfile::tempdir().expect("tempdir");
    let reader = rough_store(dir.path());
    let (_, mut with) = samplers(&reader, 7);
    let d0 = d0_m();
    // the same points from both sides of the antimeridian
    let colat = 80f64.to_radians();
    let win = texel(d0 / 32.0, colat);
    for k in 0..50 {
        let e = (k as f64 - 25.0) * 1e-5;
        let a = with.height(PI + e, colat, win);
        let b = with.height(-PI + e, colat, win);
        assert!(
            (a - b).abs() <= 2e-4 * a.abs().max(1.0),
            "{a} vs {b} at {e}"
        );
    }
    // and from both sides of the north pole: colatitude −c at longitude λ is c at λ + π
    let win = texel(d0 / 32.0, 0.05);
    for k in 0..50 {
        let c = 0.02 + k as f64 * 1e-4;
        let a = with.height(1.0, -c, win);
        let b = with.height(1.0 + PI, c, win);
        assert!(
            (a - b).abs() <= 2e-4 * a.abs().max(1.0),
            "{a} vs {b} at {c}"
        );
    }
    // tiles: a tile's texels are the point samples at their centres, and the heights go on
    // smoothly into the next tile
    let detail = Arc::new(Detail::new(DetailParams::default(), RADIUS));
    let tiles = StoreHeightTiles::new(reader.clone()).with_detail(detail.clone());
    let mut points = StoreHeights::new(reader.clone())
        .expect("heights")
        .with_detail(Some(detail));
    let grid = GridId { level: 9, k: 8 };
    let n = 64;
    let w = grid.window(n);
    let (u, v) = (
        ((30f64.to_radians() + PI) / w.texel_lon) as i64,
        ((70f64).to_radians() / w.texel_colat) as i64,
    );
    let left = TileKey::at(0, grid, u, v, n);
    let right = TileKey {
        x: left.x + 1,
        ..left
    };
    let get = |key: &TileKey| {
        let t = tiles.make(key, n, &[]).expect("tile");
        t.heights().expect("heights").to_vec()
    };
    let (a, b) = (get(&left), get(&right));
    let mut inside = 0.0f32;
    let mut across = 0.0f32;
    for r in 0..n as usize {
        let (lon, colat) = left.texel_centre(n - 1, r as u32, n);
        assert_eq!(
            a[r * n as usize + n as usize - 1].to_bits(),
            points.height(lon, colat, w).to_bits(),
            "tile texel = point sample"
        );
        let row = &a[r * n as usize..(r + 1) * n as usize];
        for c in 1..n as usize {
            inside = inside.max((row[c] - row[c - 1]).abs());
        }
        across = across.max((b[r * n as usize] - row[n as usize - 1]).abs());
    }
    assert!(
        across <= 1.5 * inside,
        "across the border {across} m, inside {inside} m"
    );
}

#[test]
fn the_same_seed_makes_the_same_planet() {
    let dir = tempfile::tempdir().expect("tempdir");
    let reader = rough_store(dir.path());
    let key = TileKey {
        source: 0,
        grid: GridId { level: 10, k: 9 },
        x: 70,
        y: 60,
    };
    let make = |seed: u64| {
        let d = Arc::new(Detail::new(
            DetailParams {
                seed,
                ..DetailParams::default()
            },
            RADIUS,
        ));
        StoreHeightTiles::new(reader.clone())
            .with_detail(d)
            .make(&key, 128, &[])
            .expect("tile")
    };
    let (a, b, c) = (make(3), make(3), make(4));
    assert_eq!(a, b);
    assert_ne!(a, c);
}

/// A tile of 19 m texels over the rough north (64° N) of [`rough_store`].
const ROUGH_NORTH: TileKey = TileKey {
    source: 0,
    grid: GridId { level: 12, k: 11 },
    x: 1800,
    y: 600,
};

/// [`ROUGH_NORTH`] in one grey, `n` texels a side.
fn grey_tile(n: u32) -> Arc<TileData> {
    let grey = FnColorTiles(|_: f64, _: f64| [120u8, 110, 100, 255]);
    Arc::new(grey.make(&ROUGH_NORTH, n, &[]).expect("colour"))
}

#[test]
fn the_colour_follows_the_ground_but_keeps_its_mean() {
    let dir = tempfile::tempdir().expect("tempdir");
    let reader = rough_store(dir.path());
    let detail = Arc::new(Detail::new(DetailParams::default(), RADIUS));
    let heights = StoreHeightTiles::new(reader.clone()).with_detail(detail);
    let shaded = DetailColorTiles::new(0, 1, &heights).expect("a detail over heights");
    // made after its heights as the streamer makes it
    let (key, n) = (ROUGH_NORTH, 256);
    let colour = grey_tile(n);
    let h = Arc::new(heights.make(&key, n, &[]).expect("heights"));
    let TileData::Color(c) = shaded.make(&key, n, &[colour, h]).expect("shaded") else {
        unreachable!("colour")
    };
    let lin = |v: u8| f64::from(sc_core::color::srgb_byte_to_linear(v));
    for ch in 0..3 {
        let want = lin([120u8, 110, 100][ch]);
        let vals: Vec<f64> = c.chunks_exact(4).map(|p| lin(p[ch])).collect();
        let mean = vals.iter().sum::<f64>() / vals.len() as f64;
        let spread = vals.iter().map(|v| (v - mean).abs()).sum::<f64>() / vals.len() as f64;
        assert!(
            (mean / want - 1.0).abs() < 0.02,
            "channel {ch}: mean {mean} for {want}"
        );
        assert!(
            spread > 0.01 * want,
            "channel {ch}: the colour follows the ground: {spread}"
        );
    }
    assert!(c.chunks_exact(4).all(|p| p[3] == 255), "alpha kept");
}

/// The shade a colour detail needs travels in its heights' tile: a colour source in another
/// thread or process (a web worker other than the one that made the heights) shades from the
/// tile alone, as the heights' own process would; the shade is the tile's, not made again.
#[test]
fn the_shade_comes_with_the_heights_tile() {
    let dir = tempfile::tempdir().expect("tempdir");
    let reader = rough_store(dir.path());
    let detail = || Arc::new(Detail::new(DetailParams::default(), RADIUS));
    let heights = StoreHeightTiles::new(reader.clone()).with_detail(detail());
    let here = DetailColorTiles::new(0, 1, &heights).expect("a detail over heights");
    let (key, n) = (ROUGH_NORTH, 128);
    let colour = grey_tile(n);
    let made = heights.make(&key, n, &[]).expect("heights");
    let TileData::ShadedHeight { heights: h, shade } = &made else {
        panic!("heights wanted for a colour detail carry their shade")
    };
    assert_eq!(shade.len(), h.len());
    assert!(shade.iter().any(|&q| q != 0.0));
    let shaded = |by: &DetailColorTiles, h: TileData| {
        by.make(&key, n, &[colour.clone(), Arc::new(h)])
            .expect("shaded")
    };
    let want = shaded(&here, made.clone());
    // another process's colour detail, over its own heights source
    let elsewhere_heights = StoreHeightTiles::new(reader).with_detail(detail());
    let elsewhere = DetailColorTiles::new(0, 1, &elsewhere_heights).expect("detail");
    assert_eq!(shaded(&elsewhere, made.clone()), want);
    // plain heights (made before the shade was wanted): the shade is made again, the same
    assert_eq!(shaded(&elsewhere, TileData::Height(h.clone())), want);
    // the tile's shade is the one used: none at all leaves the colour as it was
    let flat = TileData::ShadedHeight {
        heights: h.clone(),
        shade: vec![0.0; shade.len()],
    };
    assert_eq!(shaded(&elsewhere, flat), *colour);
    assert_ne!(want, *colour);
}
