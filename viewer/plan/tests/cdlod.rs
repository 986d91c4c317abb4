//! CDLOD's tree and vertex stage on the CPU (the twin of `shaders/cdlod_geometry.wesl`): the
//! mesh is watertight across levels, faces and the icosahedron's corners, bit for bit; vertices
//! are where the f64 twin puts them within the clipmap renderer's precision bounds; culling
//! keeps what the camera sees.

use std::collections::HashMap;

use glam::DVec3;
use sc_view_plan::terrain::cdlod::{
    CdlodFrame, CdlodPlanner, CdlodSpec, LeafInstance, attributes, patch_border, vertex_f32,
    vertex_f64,
};
use sc_view_space::camera::Camera;
use sc_view_space::transform::{Viewer, visible_levels};

const R: f64 = sc_core::EARTH_RADIUS_M;

fn frame(planner: &CdlodPlanner, cam: &str, size: (u32, u32)) -> (Camera, CdlodFrame) {
    let cam = Camera::parse(cam).expect("camera");
    // a sea-level sphere drawn at the levels the clipmap renderer would draw
    let (lo, hi) = visible_levels(R, cam.alt, 9000.0, cam.fov.to_radians(), size.1, 256, 26);
    let flat = vec![Some((0.0, 0.0)); 26];
    let f = planner.plan(&cam, size, R, (cam.alt, 0.0), (&flat, lo, hi));
    (cam, f)
}

/// Directed border segments of every leaf after the morph, as bit patterns, zero-length ones
/// dropped.
fn segments(f: &CdlodFrame, cam_height: f32, n: u32) -> Vec<([u32; 3], [u32; 3], LeafInstance)> {
    let ring = patch_border(n);
    let mut out = Vec::new();
    for leaf in &f.leaves {
        let pts: Vec<[u32; 3]> = ring
            .iter()
            .map(|&ij| vertex_f32(&f.uniform, R as f32, cam_height, leaf, ij).map(f32::to_bits))
            .collect();
        for k in 0..pts.len() {
            let (a, b) = (pts[k], pts[(k + 1) % pts.len()]);
            if a != b {
                out.push((a, b, *leaf));
            }
        }
    }
    out
}

#[test]
fn the_whole_sphere_is_watertight_bit_for_bit_from_the_ground_to_orbit() {
    for spec in [
        CdlodSpec::default(),
        CdlodSpec {
            patch: 4,
            pixel_error: 3.0,
        },
    ] {
        let mut planner = CdlodPlanner::new(spec);
        planner.cull = false;
        for cam in [
            "46.5,8.0,1.7,30,-4,60",
            "89.99,0,500,0,-8,70",
            "-89.95,45,100,180,-6,70",
            "10,179.999,3000,90,-12,60",
            "20,-60,8000000,0,-90,40",
            // over an icosahedron vertex (five faces meet): (0, ±1, ±φ) normalised
            "58.2825,90,300,0,-20,60",
        ] {
            let (c, f) = frame(&planner, cam, (320, 180));
            let segs = segments(&f, c.alt as f32, spec.patch);
            let mut open: HashMap<([u32; 3], [u32; 3]), i32> = HashMap::new();
            for (a, b, _) in &segs {
                *open.entry((*a, *b)).or_insert(0) += 1;
            }
            let unmatched: Vec<_> = segs
                .iter()
                .filter(|(a, b, _)| open.get(&(*b, *a)).copied().unwrap_or(0) != open[&(*a, *b)])
                .collect();
            assert!(
                unmatched.is_empty(),
                "{cam} (patch {}): {} of {} border segments have no twin, e.g. leaf {:?}",
                spec.patch,
                unmatched.len(),
                segs.len(),
                unmatched.first().map(|u| u.2)
            );
            // neighbours differ by one level at most, so the finest level is reached gradually
            assert!(
                f.stats.finest > 0 && f.leaves.len() > 20,
                "{cam}: {:?}",
                f.stats
            );
        }
    }
}

#[test]
fn vertices_are_within_the_clipmap_renderers_precision_of_the_f64_twin() {
    let planner = CdlodPlanner::new(CdlodSpec::default());
    // the clipmap renderer's bound (viewer/gpu/tests/precision.rs): ≤ 6.8 mm within 30 km of
    // the viewer
    for (cam, alt) in [
        ("46.5,8.0,1.7,30,-4,60", 1.7),
        ("-33.0,151.0,100,200,-10,60", 100.0),
        ("89.9,10,10000,0,-30,60", 10_000.0),
        ("0,179.99,1000000,0,-60,60", 1_000_000.0),
    ] {
        let (c, f) = frame(&planner, cam, (640, 360));
        let viewer = Viewer::from_deg(c.lat_deg, c.lon_deg);
        let (mut near, mut rel) = (0.0f64, 0.0f64);
        let n = planner.spec.patch;
        let mut count = 0;
        for leaf in &f.leaves {
            for j in 0..=n {
                for i in 0..=n - j {
                    let p = vertex_f32(&f.uniform, R as f32, alt as f32, leaf, [i, j]);
                    let e = vertex_f64(&planner, &viewer, &f.uniform, (R, alt), leaf, [i, j]);
                    // positions relative to the camera, metres, as the vertex stage makes them
                    let r = R as f32;
                    let got = DVec3::new(
                        f64::from(r * p[0]),
                        f64::from(r * p[1]),
                        f64::from(-(alt as f32) - r * p[2]),
                    );
                    let [ex, ey, ec] = attributes(e);
                    let want = DVec3::new(R * ex, R * ey, -alt - R * ec);
                    let err = (got - want).length();
                    let dist = want.length();
                    if dist < 30_000.0 {
                        near = near.max(err);
                    }
                    rel = rel.max(err / dist.max(1.0));
                    count += 1;
                }
            }
        }
        eprintln!("{cam}: {count} vertices, {near:.2e} m within 30 km, {rel:.2e} of the distance");
        assert!(count > 1000, "{cam}: {count} vertices");
        assert!(near <= 6.8e-3, "{cam}: {near} m within 30 km");
        // f32 resolves 6e-8 of a number; a few roundings of the face's constants
        assert!(rel <= 5e-7, "{cam}: {rel} of the distance");
    }
}

#[test]
fn culling_keeps_what_the_camera_sees_and_drops_the_rest() {
    let spec = CdlodSpec::default();
    let culled = CdlodPlanner::new(spec);
    let mut all = CdlodPlanner::new(spec);
    all.cull = false;
    // on the ground the frustum sees a sixth of the way round; from 8000 km the visible cap is
    // a fifth of the sphere, and the leaves across its rim are large
    for (cam, keep) in [
        ("46.5,8.0,1.7,30,-4,60", 0.3),
        ("20,-60,8000000,0,-90,40", 0.6),
    ] {
        let (_, a) = frame(&all, cam, (320, 180));
        let (_, c) = frame(&culled, cam, (320, 180));
        assert!(
            (c.leaves.len() as f64) < keep * a.leaves.len() as f64,
            "{cam}: culling keeps {} of {}",
            c.leaves.len(),
            a.leaves.len()
        );
        // the traversal's budget (BENCHMARKS.md: under a millisecond here): at 1280×720 it
        // looks at a few thousand nodes from orbit to the ground
        let (_, big) = frame(&culled, cam, (1280, 720));
        eprintln!("{cam}: {:?}, at 1280x720 {:?}", c.stats, big.stats);
        assert!(big.stats.nodes < 20_000, "{cam}: {:?}", big.stats);
        assert!(
            c.stats.culled_frustum > 0 && c.stats.culled_horizon > 0,
            "{cam}: {:?}",
            c.stats
        );
    }
}
