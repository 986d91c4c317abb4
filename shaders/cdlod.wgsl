// Icosahedral triangular CDLOD's vertex stage: one instanced patch per leaf of the triangle tree
// (viewer/plan/src/terrain/cdlod.rs). The renderer appends this to clipmap.wgsl and cdlod_geometry.wgsl:
// heights come from the clipmaps as the clipmap mesh reads them at the same point, and the
// fragment stage is the clipmap renderer's (`fs_main`), so the two renderers differ in geometry
// only.

@group(2) @binding(0) var<uniform> cdlod: Cdlod;

struct PatchIn {
    @location(0) ij: vec2<u32>,
    @location(1) face: u32,
    @location(2) level: u32,
    @location(3) corner: vec2<i32>,
    @location(4) sigma: i32,
    // +1: the leaf straddles the meridian beyond the nearer pole
    @location(5) seam: f32,
};

@vertex
fn cdlod_vs(v: PatchIn) -> VertexOut {
    let p = cdlod_vertex(v.face, v.level, v.corner, v.sigma, v.ij, frame.radius, frame.cam_height);
    let view = ViewerConsts(frame.sin_v, frame.cos_v, frame.colat, frame.orient);
    // the height by the clipmap ring level of the point (a function of the point alone, so
    // every leaf holding it agrees)
    let off = map_offsets(view, p.x, p.y, p.z, 0.0);
    let rp = ring_of(p.z);
    let mp = mesh_height(rp.level, rp.depth, off);
    // the fragment's offsets continue across the seam beyond the pole within the leaf
    return vertex_out(p, mp, v.seam);
}
