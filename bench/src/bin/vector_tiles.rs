//! What a vector layer costs per tile: 512² tiles drawn by `VectorLayer::render` over a layer
//! file, at three levels of the viewer's grid, median and p95 ms, one thread.
//!
//!     cargo run --release -p sc_bench --bin vector_tiles -- FILE [LON,LAT]
//!
//! Without a file argument of its own it also makes a synthetic road net of 10^6 segments (10^5
//! random walks of 10 segments over the Alps) and measures that.

use std::f64::consts::PI;
use std::time::Instant;

use rand::{Rng, SeedableRng};
use sc_vector::style::Unit;
use sc_vector::{Edges, Feature, Geometry, Rgba, Style, VectorLayer, Window};

fn tiles(layer: &VectorLayer, lon: f64, lat: f64) {
    let n = 512usize;
    for level in [2u32, 5, 8] {
        // the viewer's colour grid of hemisphere level L: colatitude texel π·2^−L/512
        let dcolat = PI * 0.5f64.powi(level as i32) / n as f64;
        let dlon = dcolat * 2.0;
        let mut ms = Vec::new();
        for (i, j) in [
            (-1i32, -1i32),
            (0, -1),
            (1, -1),
            (-1, 0),
            (0, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ] {
            let lon0 = lon.to_radians() - n as f64 * dlon / 2.0 + f64::from(i) * n as f64 * dlon;
            let colat0 = (90.0 - lat).to_radians() - n as f64 * dcolat / 2.0
                + f64::from(j) * n as f64 * dcolat;
            let win = Window {
                lon0,
                colat0,
                dlon,
                dcolat,
                w: n,
                h: n,
            };
            let t = Instant::now();
            let px = layer.render(&win, 1.0);
            ms.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(px);
        }
        ms.sort_by(f64::total_cmp);
        println!(
            "  level {level} (texel {:.0} m): median {:.1} ms, max {:.1} ms a 512² tile",
            dcolat * 6_371_000.0,
            ms[ms.len() / 2],
            ms[ms.len() - 1]
        );
    }
}

fn style() -> Style {
    Style {
        fill: Rgba([255, 200, 0, 80]),
        stroke: Rgba([255, 255, 255, 255]),
        width: 1.5,
        unit: Unit::Px,
        ..Style::default()
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let at = |s: Option<&String>| -> (f64, f64) {
        s.and_then(|s| {
            let mut p = s.split(',').map(|v| v.parse::<f64>());
            Some((p.next()?.ok()?, p.next()?.ok()?))
        })
        .unwrap_or((8.0, 46.5))
    };
    if let Some(file) = args.get(1) {
        let t = Instant::now();
        let f = sc_vector::read::read_file(std::path::Path::new(file)).expect("read");
        let layer = VectorLayer::new(f, style(), Edges::GreatCircle, 6_371_000.0).expect("layer");
        println!(
            "{file}: {} features, {} segments after densification, read and prepared in {:.0} ms",
            layer.features().len(),
            layer.segment_count(),
            t.elapsed().as_secs_f64() * 1e3
        );
        let (lon, lat) = at(args.get(2));
        tiles(&layer, lon, lat);
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut features = Vec::new();
    for _ in 0..100_000 {
        let mut p = [rng.random_range(5.0..11.0), rng.random_range(44.5..48.5)];
        let mut line = vec![p];
        for _ in 0..10 {
            p = [
                p[0] + rng.random_range(-0.01..0.01),
                p[1] + rng.random_range(-0.01..0.01),
            ];
            line.push(p);
        }
        features.push(Feature {
            geometry: Geometry::Lines(vec![line]),
            properties: Default::default(),
        });
    }
    let t = Instant::now();
    let layer =
        VectorLayer::new(features, style(), Edges::GreatCircle, 6_371_000.0).expect("layer");
    println!(
        "synthetic roads: 100000 lines, {} segments, prepared in {:.0} ms",
        layer.segment_count(),
        t.elapsed().as_secs_f64() * 1e3
    );
    tiles(&layer, 8.0, 46.5);
}
