//! Criterion benchmarks of the grid model's hot conversions.

use criterion::{Criterion, criterion_group, criterion_main};
use sc_core::{GridSpec, LevelId, LonLat};
use std::hint::black_box;

fn grid(c: &mut Criterion) {
    let g = GridSpec::default();
    let l = LevelId::iso(12).expect("valid");
    c.bench_function("texel_from_lonlat", |b| {
        let mut lon = -180.0;
        b.iter(|| {
            lon = if lon > 179.0 { -180.0 } else { lon + 0.37 };
            black_box(g.texel_from_lonlat(l, LonLat::new(black_box(lon), 51.5)))
        })
    });
    c.bench_function("wrap_texel_across_pole", |b| {
        let mut i = 0i64;
        b.iter(|| {
            i = (i + 7919) % 2_000_000;
            black_box(g.wrap_texel(l, black_box(i), black_box(-3)))
        })
    });
}

criterion_group!(benches, grid);
criterion_main!(benches);
