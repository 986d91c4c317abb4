//! CDLOD's vertex placement as the GPU runs it (`shaders/cdlod_geometry.wesl`, through the
//! probe) against its twins: every leaf that holds a point puts it at the same place bit for bit
//! over the whole sphere (watertight), and vertices are within the clipmap renderer's precision
//! of the f64 twin from 1.7 m to 1000 km.

use std::collections::HashMap;

use glam::DVec3;
use sc_view_gpu::probe::CdlodProbe;
use sc_view_plan::terrain::cdlod::{
    CdlodFrame, CdlodPlanner, CdlodSpec, LeafInstance, attributes, patch_border, vertex_f32,
    vertex_f64,
};
use sc_view_space::camera::Camera;
use sc_view_space::transform::{Viewer, visible_levels};

const R: f64 = sc_core::EARTH_RADIUS_M;

fn probe() -> CdlodProbe {
    CdlodProbe::new().unwrap_or_else(|e| {
        panic!("{e} — GPU tests need an adapter; `make test` installs mesa-vulkan-drivers")
    })
}

fn frame(planner: &CdlodPlanner, cam: &str, size: (u32, u32)) -> (Camera, CdlodFrame) {
    let cam = Camera::parse(cam).expect("camera");
    let (lo, hi) = visible_levels(R, cam.alt, 9000.0, cam.fov.to_radians(), size.1, 256, 26);
    let flat = vec![Some((0.0, 0.0)); 26];
    let f = planner.plan(&cam, size, R, (cam.alt, 0.0), (&flat, lo, hi));
    (cam, f)
}

#[test]
fn the_gpu_places_shared_points_identically_over_the_whole_sphere() {
    let p = probe();
    let spec = CdlodSpec::default();
    let mut planner = CdlodPlanner::new(spec);
    planner.cull = false;
    let ring = patch_border(spec.patch);
    for cam in [
        "46.5,8.0,1.7,30,-4,60",
        "-89.95,45,100,180,-6,70",
        "58.2825,90,300,0,-20,60",
    ] {
        let (c, f) = frame(&planner, cam, (320, 180));
        let list: Vec<(LeafInstance, [u32; 2])> = f
            .leaves
            .iter()
            .flat_map(|l| ring.iter().map(move |&ij| (*l, ij)))
            .collect();
        let pts = p
            .vertices(&f.uniform, (R as f32, c.alt as f32), &list)
            .expect("the GPU runs the probe");
        let bits: Vec<[u32; 3]> = pts.iter().map(|q| q.map(f32::to_bits)).collect();
        let mut segs: HashMap<([u32; 3], [u32; 3]), i32> = HashMap::new();
        let k = ring.len();
        for leaf in bits.chunks(k) {
            for e in 0..k {
                let (a, b) = (leaf[e], leaf[(e + 1) % k]);
                if a != b {
                    *segs.entry((a, b)).or_insert(0) += 1;
                }
            }
        }
        let open = segs
            .iter()
            .filter(|((a, b), n)| segs.get(&(*b, *a)) != Some(n))
            .count();
        assert_eq!(
            open,
            0,
            "{cam}: {open} of {} border segments without a twin",
            segs.len()
        );
        // and the CPU twin agrees with the GPU to a few units in the last place (of the largest
        // component: the GPU may fuse a multiply and an add)
        let mut worst = 0.0f64;
        for ((l, ij), g) in list.iter().zip(&pts).step_by(7) {
            let cpu = vertex_f32(&f.uniform, R as f32, c.alt as f32, l, *ij);
            let scale = cpu.iter().fold(1e-30f32, |m, v| m.max(v.abs()));
            for a in 0..3 {
                worst = worst.max(f64::from((cpu[a] - g[a]).abs() / scale));
            }
        }
        assert!(
            worst < 1e-5,
            "{cam}: GPU and CPU twin differ by {worst:.1e} relative"
        );
    }
}

#[test]
fn gpu_vertices_are_within_the_clipmap_renderers_precision_of_the_f64_twin() {
    let p = probe();
    let planner = CdlodPlanner::new(CdlodSpec::default());
    for (cam, alt) in [
        ("46.5,8.0,1.7,30,-4,60", 1.7),
        ("-33.0,151.0,100,200,-10,60", 100.0),
        ("89.9,10,10000,0,-30,60", 10_000.0),
        ("0,179.99,1000000,0,-60,60", 1_000_000.0),
    ] {
        let (c, f) = frame(&planner, cam, (640, 360));
        let viewer = Viewer::from_deg(c.lat_deg, c.lon_deg);
        let n = planner.spec.patch;
        let list: Vec<(LeafInstance, [u32; 2])> = f
            .leaves
            .iter()
            .flat_map(|l| (0..=n).flat_map(move |j| (0..=n - j).map(move |i| (*l, [i, j]))))
            .collect();
        let pts = p
            .vertices(&f.uniform, (R as f32, alt as f32), &list)
            .expect("the GPU runs the probe");
        let (mut near, mut rel) = (0.0f64, 0.0f64);
        let r = R as f32;
        for ((leaf, ij), g) in list.iter().zip(&pts) {
            let e = vertex_f64(&planner, &viewer, &f.uniform, (R, alt), leaf, *ij);
            let got = DVec3::new(
                f64::from(r * g[0]),
                f64::from(r * g[1]),
                f64::from(-(alt as f32) - r * g[2]),
            );
            let [ex, ey, ec] = attributes(e);
            let want = DVec3::new(R * ex, R * ey, -alt - R * ec);
            let err = (got - want).length();
            if want.length() < 30_000.0 {
                near = near.max(err);
            }
            rel = rel.max(err / want.length().max(1.0));
        }
        eprintln!(
            "{cam} on {}: {} vertices, {near:.2e} m within 30 km, {rel:.2e} of the distance",
            p.adapter(),
            list.len()
        );
        assert!(near <= 6.8e-3, "{cam}: {near} m within 30 km");
        assert!(rel <= 5e-7, "{cam}: {rel} of the distance");
    }
}
