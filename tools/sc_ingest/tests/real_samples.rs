//! Ingest of the bundled real samples: placement of known features, quirks of real files,
//! mosaics, nodata borders.

use std::path::{Path, PathBuf};
use std::process::Command;

use sc_core::{GridSpec, Kernel, LevelId, LonLat};
use sc_ingest::{Input, LevelChoice, Settings};
use sc_raster::SourceOptions;
use sc_store::{LayerKind, StoreConfig, StoreReader, TileRead};

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../samples")
        .join(name)
}

fn settings(layer: LayerKind, level: LevelChoice) -> Settings {
    Settings {
        layer,
        level,
        kernel: Kernel::Cubic,
        feather_texels: 0,
        new_store: StoreConfig::default(),
    }
}

fn input(name: &str) -> Input {
    Input {
        path: sample(name),
        options: SourceOptions::default(),
        priority: 0,
    }
}

fn ingest(root: &Path, inputs: &[Input], s: &Settings) -> sc_ingest::Summary {
    let existing = StoreReader::open(root).ok().map(|r| {
        let m = r.meta();
        (m.grid, m.shard_tiles, m.radius_m)
    });
    let plan = sc_ingest::plan(inputs, s, existing).expect("plan");
    sc_ingest::run(root, &plan, &|_, _| {}).expect("run")
}

/// The tiles a level holds, loaded sparsely (only tiles present), addressed by texel.
struct Level {
    w: usize,
    h: usize,
    t: usize,
    tiles: std::collections::HashMap<(usize, usize), Vec<f32>>,
}

impl Level {
    fn get(&self, i: usize, j: usize) -> f32 {
        self.tiles
            .get(&(i / self.t, j / self.t))
            .map_or(f32::NAN, |v| v[(j % self.t) * self.t + i % self.t])
    }

    fn values(&self) -> impl Iterator<Item = f32> + '_ {
        self.tiles
            .values()
            .flatten()
            .copied()
            .filter(|v| !v.is_nan())
    }
}

fn level_image(r: &StoreReader, level: LevelId) -> Level {
    let g = r.meta().grid;
    let t = g.tile_size() as usize;
    let mut tiles = std::collections::HashMap::new();
    for shard in r.shards_on_disk(LayerKind::Height, level).expect("shards") {
        for tile in shard.tiles(g, r.meta().shard_tiles) {
            let mut buf = vec![0f32; t * t];
            if r.read_tile(tile, &mut buf).expect("read") == TileRead::Present {
                tiles.insert((tile.x as usize, tile.y as usize), buf);
            }
        }
    }
    Level {
        w: g.width(level) as usize,
        h: g.height(level) as usize,
        t,
        tiles,
    }
}

fn texel_of(g: GridSpec, level: LevelId, lon: f64, lat: f64) -> (usize, usize) {
    let t = g
        .texel_from_lonlat(level, LonLat::new(lon, lat))
        .expect("on sphere");
    (
        t.x as usize,
        (t.y as usize).min(g.height(level) as usize - 1),
    )
}

/// Max/min of the image over a lon/lat box.
fn box_stats(
    g: GridSpec,
    level: LevelId,
    img: &Level,
    w_: f64,
    s_: f64,
    e_: f64,
    n_: f64,
) -> (f32, f32) {
    let (i0, j0) = texel_of(g, level, w_, n_);
    let (i1, j1) = texel_of(g, level, e_, s_);
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for j in j0..=j1 {
        for i in i0..=i1 {
            let v = img.get(i, j);
            if !v.is_nan() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    (lo, hi)
}

#[test]
fn etopo5_lands_in_the_right_texels_with_its_poles_and_a_seamless_antimeridian() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("e.zarr");
    let level = LevelId::iso(3).expect("valid");
    let s = ingest(
        &root,
        &[input("etopo5.cdf.gz")],
        &settings(LayerKind::Height, LevelChoice::Fixed(level)),
    );
    assert_eq!(s.coverage, 1.0, "a global grid covers everything");
    let r = StoreReader::open(&root).expect("open");
    let g = r.meta().grid;
    let img = level_image(&r, level);
    let (w, h) = (img.w, img.h);
    // Everest area ≈ 6 km (ETOPO5 node: 6096 m); at 0.088° spacing a little is smoothed away
    let (_, everest) = box_stats(g, level, &img, 86.4, 27.5, 87.4, 28.5);
    assert!(
        (5500.0..=6600.0).contains(&everest),
        "Everest area max {everest}"
    );
    // Karakoram holds the global maximum 7833 m; nothing higher anywhere (cubic may ring a bit)
    let global_max = img.values().fold(f32::NEG_INFINITY, f32::max);
    let (_, karakoram) = box_stats(g, level, &img, 74.5, 35.8, 75.6, 36.8);
    assert_eq!(
        karakoram, global_max,
        "the global maximum is in the Karakoram"
    );
    assert!((7000.0..=8100.0).contains(&global_max), "{global_max}");
    // Mariana Trench minimum ≈ −10.4 km near 11.33 °N 142.33 °E
    let (mariana, _) = box_stats(g, level, &img, 141.8, 10.8, 142.9, 11.9);
    let global_min = img.values().fold(f32::INFINITY, f32::min);
    // at 0.088° the trench's narrow floor is smoothed to within a few hundred metres of the
    // deepest smoothed trench (ETOPO5's −10376 m node itself is 1/12° wide)
    assert!((-10800.0..=-9800.0).contains(&mariana), "{mariana}");
    assert!(
        mariana - global_min < 300.0,
        "Mariana {mariana} vs global minimum {global_min}"
    );
    // Greenland ice 72.6 °N 38.5 °W → 3185 m
    let (gx, gy) = texel_of(g, level, -38.5, 72.6);
    let green = img.get(gx, gy);
    assert!((green - 3185.0).abs() < 150.0, "Greenland {green}");
    // the pole rows hold the values at their own centres, 0.044° from the pole: within what
    // ETOPO5 holds within 0.1° of the pole (north −4301…−4094 m, south 2774…2865 m; gdal_translate
    // -of XYZ of its first and last rows), and not one value: the Arctic floor varies by 200 m
    // around the first ring of nodes
    for (row, (lo_data, hi_data)) in [(0, (-4301.0f32, -4094.0)), (h - 1, (2774.0, 2865.0))] {
        let vals: Vec<f32> = (0..w).map(|i| img.get(i, row)).collect();
        let (lo, hi) = vals
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        assert!(
            lo >= lo_data - 10.0 && hi <= hi_data + 10.0,
            "row {row}: {lo}..{hi} vs data {lo_data}..{hi_data}"
        );
        if row == 0 {
            assert!(hi - lo > 10.0, "row {row} is one value: {lo}..{hi}");
        }
    }
    // antimeridian: the step across it is like any other step between neighbours
    let mut seam = 0.0f64;
    let mut inner = 0.0f64;
    for j in 0..h {
        let row: Vec<f32> = (0..w).map(|i| img.get(i, j)).collect();
        seam += f64::from((row[w - 1] - row[0]).abs());
        inner += f64::from((row[w / 2] - row[w / 2 + 1]).abs())
            + f64::from((row[1] - row[0]).abs())
            + f64::from((row[w - 2] - row[w - 1]).abs());
    }
    assert!(
        seam <= inner / 3.0 * 2.0,
        "seam {seam} vs typical {}",
        inner / 3.0
    );
}

fn gdal_value(file: &Path, lon: f64, lat: f64) -> f64 {
    let o = Command::new("gdallocationinfo")
        .args(["-valonly", "-wgs84"])
        .arg(file)
        .args([lon.to_string(), lat.to_string()])
        .output()
        .expect("gdallocationinfo (gdal-bin) runs");
    String::from_utf8_lossy(&o.stdout)
        .trim()
        .parse()
        .expect("a value")
}

#[test]
fn srtm_tiles_match_gdal_and_override_etopo_only_inside_their_squares() {
    let dir = tempfile::tempdir().expect("tempdir");
    let fine = dir.path().join("srtm.zarr");
    // auto level for 3″ data
    let s = ingest(
        &fine,
        &[input("N57E011.hgt.zip"), input("n07_w006_3arc_v2.tif")],
        &settings(LayerKind::Height, LevelChoice::Auto),
    );
    assert_eq!(
        s.levels,
        vec!["10".to_string()],
        "3″ = 0.00083° → level 10 (0.00069°)"
    );
    let r = StoreReader::open(&fine).expect("open");
    let level = LevelId::iso(10).expect("valid");
    let g = r.meta().grid;
    let t = g.tile_size() as usize;
    let value_at = |lon: f64, lat: f64| -> (f32, f32) {
        let (i, j) = texel_of(g, level, lon, lat);
        let tile = g.tile_of_texel(level, i as u64, j as u64);
        let mut buf = vec![0f32; t * t];
        assert_eq!(
            r.read_tile(tile, &mut buf).expect("read"),
            TileRead::Present,
            "{lon} {lat}"
        );
        let (ox, oy) = tile.origin_texel(g);
        let v = buf[(j - oy as usize) * t + (i - ox as usize)];
        // local variation around the texel, as the tolerance of resampling
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for dj in -2i64..=2 {
            for di in -2i64..=2 {
                let (ii, jj) = (i as i64 + di - ox as i64, j as i64 + dj - oy as i64);
                if (0..t as i64).contains(&ii) && (0..t as i64).contains(&jj) {
                    let u = buf[jj as usize * t + ii as usize];
                    lo = lo.min(u);
                    hi = hi.max(u);
                }
            }
        }
        (v, hi - lo)
    };
    for (file, pts) in [
        (
            "N57E011.hgt.zip",
            [
                (11.5, 57.5),
                (11.02, 57.02),
                (11.98, 57.98),
                (11.02, 57.98),
                (11.98, 57.02),
            ],
        ),
        (
            "n07_w006_3arc_v2.tif",
            [
                (-5.5, 7.5),
                (-5.98, 7.02),
                (-5.02, 7.98),
                (-5.98, 7.98),
                (-5.02, 7.02),
            ],
        ),
    ] {
        for (lon, lat) in pts {
            let (ours, spread) = value_at(lon, lat);
            let gdal = gdal_value(&sample(file), lon, lat);
            assert!(
                (f64::from(ours) - gdal).abs() <= f64::from(spread) + 1.0,
                "{file} at {lon},{lat}: ours {ours}, gdal {gdal}, local spread {spread}"
            );
        }
    }
    // together with ETOPO at one level: SRTM replaces ETOPO inside its square only
    let l5 = LevelId::iso(4).expect("valid");
    let mixed = dir.path().join("mixed.zarr");
    let etopo_only = dir.path().join("etopo.zarr");
    let srtm_only = dir.path().join("srtm5.zarr");
    let fixed = settings(LayerKind::Height, LevelChoice::Fixed(l5));
    ingest(
        &mixed,
        &[input("etopo5.cdf.gz"), input("N57E011.hgt.zip")],
        &fixed,
    );
    ingest(&etopo_only, &[input("etopo5.cdf.gz")], &fixed);
    ingest(&srtm_only, &[input("N57E011.hgt.zip")], &fixed);
    let (m, e, so) = (
        level_image(&StoreReader::open(&mixed).expect("open"), l5),
        level_image(&StoreReader::open(&etopo_only).expect("open"), l5),
        level_image(&StoreReader::open(&srtm_only).expect("open"), l5),
    );

    let (mut inside, mut outside) = (0, 0);
    for (lon, lat) in [
        (11.5, 57.5),
        (11.2, 57.8),
        (11.8, 57.2),
        (10.5, 57.5),
        (12.5, 57.5),
        (11.5, 56.5),
        (11.5, 58.5),
        (-30.0, 10.0),
    ] {
        let (i, j) = texel_of(GridSpec::default(), l5, lon, lat);

        if (11.0..12.0).contains(&lon) && (57.0..58.0).contains(&lat) {
            assert_eq!(
                m.get(i, j).to_bits(),
                so.get(i, j).to_bits(),
                "inside the square SRTM wins at {lon},{lat}"
            );
            inside += 1;
        } else {
            assert_eq!(
                m.get(i, j).to_bits(),
                e.get(i, j).to_bits(),
                "outside the square ETOPO stays at {lon},{lat}"
            );
            outside += 1;
        }
    }
    assert!(inside == 3 && outside == 5);
}

#[test]
fn projected_scenes_land_where_gdaltransform_says() {
    for (file, layer) in [
        ("landsat7_etm_utm25s.tif", LayerKind::Color),
        ("aletsch_dhm200_lv95.tif", LayerKind::Height),
    ] {
        let dir = tempfile::tempdir().expect("tempdir");
        let root = dir.path().join("p.zarr");
        let s = ingest(&root, &[input(file)], &settings(layer, LevelChoice::Auto));
        let level: LevelId = s.levels[0].parse().expect("level");
        let r = StoreReader::open(&root).expect("open");
        let g = r.meta().grid;
        // the corners' lon/lat according to GDAL
        let out = Command::new("gdalinfo")
            .arg("-json")
            .arg(sample(file))
            .output()
            .expect("gdalinfo");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        let ring = v["wgs84Extent"]["coordinates"][0]
            .as_array()
            .expect("polygon")
            .clone();
        let xs: Vec<f64> = ring.iter().map(|p| p[0].as_f64().expect("x")).collect();
        let ys: Vec<f64> = ring.iter().map(|p| p[1].as_f64().expect("y")).collect();
        let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let wgs = [min(&xs), min(&ys), max(&xs), max(&ys)];
        // the bounding box of valid texels in our level
        let (w, h) = (g.width(level), g.height(level));
        let t = g.tile_size() as u64;
        let (mut imin, mut imax, mut jmin, mut jmax) = (u64::MAX, 0, u64::MAX, 0);
        let n = t as usize * t as usize * layer.channels();
        for shard in r.shards_on_disk(layer, level).expect("shards") {
            for tile in shard.tiles(g, r.meta().shard_tiles) {
                let (tx, ty) = (tile.x, tile.y);
                let valid: Vec<bool> = match layer {
                    LayerKind::Height => {
                        let mut b = vec![0f32; n];
                        if r.read_tile(tile, &mut b).expect("read") == TileRead::Missing {
                            continue;
                        }
                        b.iter().map(|v| !v.is_nan()).collect()
                    }
                    LayerKind::Color => {
                        let mut b = vec![0u8; n];
                        if r.read_tile(tile, &mut b).expect("read") == TileRead::Missing {
                            continue;
                        }
                        b.chunks_exact(4).map(|p| p[3] > 0).collect()
                    }
                };
                for (k, ok) in valid.into_iter().enumerate() {
                    if ok {
                        let (i, j) = (tx * t + k as u64 % t, ty * t + k as u64 / t);
                        imin = imin.min(i);
                        imax = imax.max(i);
                        jmin = jmin.min(j);
                        jmax = jmax.max(j);
                    }
                }
            }
        }
        assert!(imin <= imax, "{file}: no data written");
        let (dx, dy) = g.texel_deg(level);
        let ours = [
            -180.0 + imin as f64 * dx,
            90.0 - (jmax + 1) as f64 * dy,
            -180.0 + (imax + 1) as f64 * dx,
            90.0 - jmin as f64 * dy,
        ];
        // within one texel (plus the half texel of the coverage threshold)
        let tol = [1.5 * dx, 1.5 * dy, 1.5 * dx, 1.5 * dy];
        for k in 0..4 {
            assert!(
                (ours[k] - wgs[k]).abs() <= tol[k],
                "{file} edge {k}: ours {} vs gdal {} (texel {dx}x{dy}); w {w} h {h}",
                ours[k],
                wgs[k]
            );
        }
    }
}

#[test]
fn luxembourg_keeps_its_border_without_a_halo() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("l.zarr");
    let s = ingest(
        &root,
        &[input("terra_elev_luxembourg.tif")],
        &settings(LayerKind::Height, LevelChoice::Auto),
    );
    let level: LevelId = s.levels[0].parse().expect("level");
    let r = StoreReader::open(&root).expect("open");
    let g = r.meta().grid;
    let img = level_image(&r, level);
    // every valid value is a plausible Luxembourg height: no −32768 bleeding in, no ringing halo
    let (lo, hi) = box_stats(g, level, &img, 5.6, 49.3, 6.7, 50.3);
    assert!(
        lo >= 130.0 && hi <= 560.0,
        "values {lo}..{hi} (source 141..547)"
    );
    // the valid area matches the source's valid fraction (4608 of 8550 pixels) within 10 %
    let (i0, j0) = texel_of(g, level, 5.7416667, 50.1916667);
    let (i1, j1) = texel_of(g, level, 6.5333333, 49.4416667);
    let mut valid = 0usize;
    let mut all = 0usize;
    for j in j0..=j1 {
        for i in i0..=i1 {
            all += 1;
            valid += usize::from(!img.get(i, j).is_nan());
        }
    }
    let frac = valid as f64 / all as f64;
    assert!(
        (frac - 4608.0 / 8550.0).abs() < 0.06,
        "valid fraction {frac}"
    );
    // a point outside the border (France, south-west corner) stays nodata
    let (i, j) = texel_of(g, level, 5.76, 49.45);
    assert!(img.get(i, j).is_nan());
}

#[test]
fn blue_marble_and_exr_with_bounds() {
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path().join("c.zarr");
    let mut bm = input("bluemarble_5400x2700.jpg");
    bm.options.bounds = Some([-180.0, -90.0, 180.0, 90.0]);
    let level = LevelId::iso(1).expect("valid");
    let s = ingest(
        &root,
        &[bm],
        &settings(LayerKind::Color, LevelChoice::Fixed(level)),
    );
    assert_eq!(s.coverage, 1.0);
    let r = StoreReader::open(&root).expect("open");
    let g = r.meta().grid;
    let t = g.tile_size() as usize;
    let rgba = |lon: f64, lat: f64| -> [u8; 4] {
        let (i, j) = texel_of(g, level, lon, lat);
        let tile = g.tile_of_texel(level, i as u64, j as u64);
        let mut b = vec![0u8; t * t * 4];
        r.read_tile(tile, &mut b).expect("read");
        let (ox, oy) = tile.origin_texel(g);
        let k = ((j - oy as usize) * t + i - ox as usize) * 4;
        [b[k], b[k + 1], b[k + 2], b[k + 3]]
    };
    let sahara = rgba(13.0, 24.0);
    assert!(
        sahara[0] > sahara[2] + 40 && sahara[3] == 255,
        "Sahara is sand: {sahara:?}"
    );
    let pacific = rgba(-150.0, 0.0);
    assert!(
        pacific[2] > pacific[0] + 20,
        "the Pacific is blue: {pacific:?}"
    );
    // an EXR heightmap: h = 100·lat + lon over a 10°×10° box, placed by --bounds
    use exr::prelude::*;
    let (w, h) = (200usize, 200usize);
    let vals: Vec<f32> = (0..w * h)
        .map(|k| {
            let lon = 10.0 + (k % w) as f64 * 0.05 + 0.025;
            let lat = 50.0 - (k / w) as f64 * 0.05 - 0.025;
            (100.0 * lat + lon) as f32
        })
        .collect();
    let exr_path = dir.path().join("h.exr");
    let ch = AnyChannels::sort(vec![AnyChannel::new("Y", FlatSamples::F32(vals))].into());
    Image::from_layer(Layer::new(
        (w, h),
        LayerAttributes::named("h"),
        Encoding::FAST_LOSSLESS,
        ch,
    ))
    .write()
    .to_file(&exr_path)
    .expect("write exr");
    let hroot = dir.path().join("h.zarr");
    let mut inp = Input {
        path: exr_path,
        options: SourceOptions::default(),
        priority: 0,
    };
    inp.options.bounds = Some([10.0, 40.0, 20.0, 50.0]);
    let l6 = LevelId::iso(6).expect("valid");
    ingest(
        &hroot,
        &[inp],
        &settings(LayerKind::Height, LevelChoice::Fixed(l6)),
    );
    let rr = StoreReader::open(&hroot).expect("open");
    let img = level_image(&rr, l6);
    for (lon, lat) in [(15.0, 45.0), (11.0, 49.0), (19.0, 41.0)] {
        let (i, j) = texel_of(GridSpec::default(), l6, lon, lat);
        let c = GridSpec::default().texel_centre(l6, i as u64, j as u64);
        let expect = 100.0 * c.lat_deg + c.lon_deg;
        let got = f64::from(img.get(i, j));
        assert!(
            (got - expect).abs() < 0.5,
            "EXR at {lon},{lat}: {got} vs {expect}"
        );
    }
}

#[test]
fn feathering_fades_a_regional_source_into_what_is_there() {
    use exr::prelude::*;
    let dir = tempfile::tempdir().expect("tempdir");
    // a flat 1000 m base over 10..13 °E, 56..59 °N (an EXR heightmap placed with --bounds)
    let base_exr = dir.path().join("base.exr");
    let ch = AnyChannels::sort(
        vec![AnyChannel::new(
            "Y",
            FlatSamples::F32(vec![1000.0; 300 * 300]),
        )]
        .into(),
    );
    Image::from_layer(Layer::new(
        (300, 300),
        LayerAttributes::named("b"),
        Encoding::FAST_LOSSLESS,
        ch,
    ))
    .write()
    .to_file(&base_exr)
    .expect("write exr");
    let mut base = Input {
        path: base_exr,
        options: SourceOptions::default(),
        priority: 0,
    };
    base.options.bounds = Some([10.0, 56.0, 13.0, 59.0]);
    let l = LevelId::iso(6).expect("valid");
    let fixed = settings(LayerKind::Height, LevelChoice::Fixed(l));
    let mut feathered = fixed.clone();
    feathered.feather_texels = 4;
    let (hard, soft) = (dir.path().join("hard.zarr"), dir.path().join("soft.zarr"));
    for (root, s) in [(&hard, &fixed), (&soft, &feathered)] {
        ingest(root, &[base.clone()], &fixed);
        ingest(root, &[input("N57E011.hgt.zip")], s);
    }
    let (h, s) = (
        level_image(&StoreReader::open(&hard).expect("open"), l),
        level_image(&StoreReader::open(&soft).expect("open"), l),
    );
    let g = GridSpec::default();
    let dx = g.texel_deg(l).0;
    // deep inside the square (more than 4 texels from its edges) feathering changes nothing
    let (i, j) = texel_of(g, l, 11.5, 57.5);
    assert_eq!(s.get(i, j).to_bits(), h.get(i, j).to_bits());
    // one texel inside the west edge: hard edges take SRTM, feathering lies between it and 1000 m
    let (i, j) = texel_of(g, l, 11.0 + 1.5 * dx, 57.5);
    let (sv, hv) = (s.get(i, j), h.get(i, j));
    assert!(hv < 500.0, "SRTM heights here are low: {hv}");
    let t = (sv - 1000.0) / (hv - 1000.0);
    assert!(
        t > 0.05 && t < 0.8,
        "feathered {sv} between base 1000 and srtm {hv}: t = {t}"
    );
    // outside the square both keep the base
    let (i, j) = texel_of(g, l, 10.5, 57.5);
    assert_eq!((s.get(i, j), h.get(i, j)), (1000.0, 1000.0));
}

#[test]
fn a_raster_too_fine_for_one_read_is_read_averaged() {
    // Luxembourg blown up to 12000×12000 pixels (144 M, more than one window may hold) onto
    // level 2, where one texel covers the whole country
    let dir = tempfile::tempdir().expect("tempdir");
    let big = dir.path().join("big.tif");
    let o = Command::new("gdal_translate")
        .args([
            "-q",
            "-outsize",
            "12000",
            "12000",
            "-r",
            "nearest",
            "-co",
            "COMPRESS=DEFLATE",
            "-co",
            "TILED=YES",
        ])
        .arg(sample("terra_elev_luxembourg.tif"))
        .arg(&big)
        .output()
        .expect("gdal_translate runs");
    assert!(o.status.success());
    let root = dir.path().join("b.zarr");
    let l = LevelId::iso(2).expect("valid");
    let mut inp = input("terra_elev_luxembourg.tif");
    inp.path = big;
    let s = ingest(
        &root,
        &[inp],
        &settings(LayerKind::Height, LevelChoice::Fixed(l)),
    );
    let (lo, hi) = s.value_range.expect("data written");
    assert!(lo >= 141.0 && hi <= 547.0, "{lo}..{hi}");
}
