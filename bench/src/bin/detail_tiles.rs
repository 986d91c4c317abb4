//! What detail below the data costs the tile workers: one 512² height tile of the default graph
//! of STORE, with detail and without, at clipmap levels 9 … 21 around a point (by default the
//! ground view in the Alps), on one thread; the median of REPS makings (each from a fresh
//! source, so no store tile is cached between them), and a checksum of the tile with detail
//! (FNV-1a of its heights' bits: a change that claims the same output keeps it). First, the
//! time of one noise evaluation, alone and in lanes.
//! Usage: `detail_tiles STORE [LAT LON] [REPS] [LEVELS]` (LEVELS: comma-separated, e.g. `11,15`).

use std::f64::consts::PI;
use std::time::Instant;

use sc_view_data::graph::Graph;
use sc_view_data::stream::{GridId, TileKey};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let Some(store) = args.get(1) else {
        return Err("usage: detail_tiles STORE [LAT LON] [REPS] [LEVELS]".into());
    };
    let lat: f64 = args.get(2).map(|a| a.parse()).transpose()?.unwrap_or(46.5);
    let lon: f64 = args.get(3).map(|a| a.parse()).transpose()?.unwrap_or(8.0);
    let reps: usize = args
        .get(4)
        .map(|a| a.parse())
        .transpose()?
        .unwrap_or(3)
        .max(1);
    let levels: Vec<u32> = match args.get(5) {
        Some(l) => l.split(',').map(str::parse).collect::<Result<_, _>>()?,
        None => vec![9, 11, 13, 15, 17, 19, 21],
    };
    let evals = 10_000_000u32;
    let t = Instant::now();
    let mut sum = 0.0;
    for i in 0..evals {
        let f = f64::from(i);
        sum += sc_view_data::detail::gradient_noise(
            [f * 1e-3 + 1e6, f * 7e-4 - 3e5, 2e4 + f * 1e-4],
            5,
        );
    }
    println!(
        "simplex noise: {:.1} ns an evaluation (checksum {sum:.3})",
        t.elapsed().as_secs_f64() * 1e9 / f64::from(evals)
    );
    let lanes = sc_view_data::detail::LANES as u32;
    let t = Instant::now();
    let mut sum = 0.0;
    for i in (0..evals).step_by(lanes as usize) {
        let q = std::array::from_fn(|l| {
            let f = f64::from(i + l as u32);
            [f * 1e-3 + 1e6, f * 7e-4 - 3e5, 2e4 + f * 1e-4]
        });
        sum += sc_view_data::detail::noise_lanes(&q, 5).iter().sum::<f64>();
    }
    println!(
        "simplex noise, {lanes} lanes at once: {:.1} ns an evaluation (checksum {sum:.3})",
        t.elapsed().as_secs_f64() * 1e9 / f64::from(evals)
    );
    let n = 512u32;
    println!(
        "{:<6} {:>10} {:>12} {:>12} {:>7} {:>18}",
        "level", "texel m", "without ms", "with ms", "ratio", "checksum"
    );
    for level in levels {
        let grid = GridId { level, k: level };
        let w = grid.window(n);
        let u = ((lon.to_radians() + PI) / w.texel_lon) as i64;
        let v = ((90.0 - lat).to_radians() / w.texel_colat) as i64;
        let time = |detail: bool| -> Result<(f64, u64), Box<dyn std::error::Error>> {
            let mut ms = Vec::new();
            let mut sum = 0xcbf2_9ce4_8422_2325u64;
            for _ in 0..reps {
                let g = Graph::for_store(&sc_store::Location::Local(store.into()))?;
                let source = if detail {
                    g.clipmaps.height
                } else {
                    g.without_detail.height
                };
                let key = TileKey::at(source, grid, u, v, n);
                let t = Instant::now();
                let tile = g.sources[source as usize].make(&key, n, &[])?;
                ms.push(t.elapsed().as_secs_f64() * 1e3);
                sum = 0xcbf2_9ce4_8422_2325;
                if let Some(h) = tile.heights() {
                    for &v in h {
                        sum = (sum ^ u64::from(v.to_bits())).wrapping_mul(0x100_0000_01b3);
                    }
                }
            }
            ms.sort_by(f64::total_cmp);
            Ok((ms[ms.len() / 2], sum))
        };
        let ((without, _), (with, sum)) = (time(false)?, time(true)?);
        println!(
            "{level:<6} {:>10.2} {without:>12.1} {with:>12.1} {:>7.1} {sum:>18x}",
            w.texel_colat * sc_core::EARTH_RADIUS_M,
            with / without
        );
    }
    Ok(())
}
