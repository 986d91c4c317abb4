//! The f32 map transform the shaders evaluate against its f64 twin, from 1.7 m above the ground to
//! 1000 km, at the poles, the antimeridian and elsewhere (same f32 vertex attributes into both).

use sc_view_gpu::probe::TransformProbe;
use sc_view_plan::terrain::clipmap::{Hemisphere, HemisphereSpec};
use sc_view_space::transform::level_outer;
use sc_view_space::transform::{Viewer, offsets_f32, offsets_f64, visible_levels};

const R: f64 = sc_core::EARTH_RADIUS_M;

/// (largest ground error in metres, largest error in texels of the vertex's level, for vertices
/// within `near` metres) and the same over all visible vertices.
fn errors(
    v: &Viewer,
    h: f64,
    hemi: &Hemisphere,
    near: f64,
    gpu: Option<&TransformProbe>,
) -> ((f64, f64), (f64, f64)) {
    let (lo, hi) = visible_levels(
        R,
        h,
        9000.0,
        60f64.to_radians(),
        1280,
        hemi.spec.n,
        hemi.spec.levels,
    );
    let u = v.uniforms();
    let m = f64::from(hemi.spec.m);
    let (mut near_max, mut all_max) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
    let vertices = hemi.vertices();
    let visible: Vec<_> = vertices
        .iter()
        .filter(|x| x.level >= lo && x.level <= hi)
        .collect();
    // the shader's transform: run on the GPU, or its f32 CPU twin
    let computed: Vec<[f32; 2]> = match gpu {
        Some(p) => p
            .offsets(
                &u,
                &visible
                    .iter()
                    .map(|x| [x.px, x.py, x.one_minus_cos, x.seam])
                    .collect::<Vec<_>>(),
            )
            .expect("the GPU runs the probe"),
        None => visible
            .iter()
            .map(|x| {
                let g = offsets_f32(&u, x.px, x.py, x.one_minus_cos, x.seam);
                [g.dlon, g.dcolat]
            })
            .collect(),
    };
    for (x, g) in visible.iter().zip(&computed) {
        let e = offsets_f64(
            v,
            f64::from(x.px),
            f64::from(x.py),
            f64::from(x.one_minus_cos),
            f64::from(x.seam),
        );
        let colat = v.colat_rad + e.dcolat;
        let dy = (f64::from(g[1]) - e.dcolat).abs() * R;
        let dx = (f64::from(g[0]) - e.dlon).abs() * R * colat.sin().abs();
        let ground = dx.hypot(dy);
        // a level's texels are about as far apart as its rings
        let texel = level_outer(x.level) * (1.0 - 2f64.powf(-1.0 / m)) * R;
        let t = ground / texel;
        all_max = (all_max.0.max(ground), all_max.1.max(t));
        if f64::from(x.theta) * R <= near {
            near_max = (near_max.0.max(ground), near_max.1.max(t));
        }
    }
    (near_max, all_max)
}

fn check(gpu: Option<&TransformProbe>, what: &str) {
    let hemi = Hemisphere::new(HemisphereSpec::default());
    let places = [
        (0.0, 0.0),
        (27.9881, 86.925),
        (45.0, 179.99999),
        (-45.0, -180.0),
        (89.99999, 30.0),
        (90.0, 0.0),
        (-89.99999, -120.0),
        (-90.0, 0.0),
        (60.0, -179.999999),
    ];
    // f32 carries ~2e-7 of a vertex's distance: 1 cm out to ~45 km from the viewer, and far
    // below a texel of the level drawn there everywhere
    let near = 30_000.0;
    for h in [1.7, 100.0, 1.0e4, 1.0e6] {
        for &(lat, lon) in &places {
            let v = Viewer::from_deg(lat, lon);
            let ((near_m, _), (_, texel)) = errors(&v, h, &hemi, near, gpu);
            eprintln!(
                "{what}: altitude {h} m at {lat},{lon}: ≤ {near_m:.2e} m within 30 km, ≤ {texel:.2e} texel"
            );
            assert!(
                near_m <= 0.01,
                "{what}: altitude {h} at {lat},{lon}: {near_m} m within 30 km"
            );
            assert!(
                texel <= 0.05,
                "{what}: altitude {h} at {lat},{lon}: {texel} texel"
            );
        }
    }
}

#[test]
fn f32_transform_matches_f64_from_the_ground_to_orbit_everywhere() {
    check(None, "CPU twin");
}

/// The same on the GPU (lavapipe in CI): `shaders/map_transform.wesl` run by a compute pass.
#[test]
fn gpu_transform_matches_f64_from_the_ground_to_orbit_everywhere() {
    let probe = TransformProbe::new().unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    });
    check(Some(&probe), probe.adapter());
}
