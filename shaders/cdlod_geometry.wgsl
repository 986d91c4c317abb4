// Icosahedral triangular CDLOD: where a patch vertex lies, morphed (viewer/plan/src/terrain/cdlod.rs,
// `vertex_f32`, operation for operation). A module including this declares the uniform `cdlod`.
// Lattice points are integers, so every leaf holding a point computes it from the same numbers;
// the position is viewer-relative (the clipmap's vertex attributes), f32 throughout.

struct CdlodFace {
    // the anchor's direction: x, y, 1 − z (view frame)
    a: vec4<f32>,
    // the face's edges c₁ − c₀, c₂ − c₀ over |P(anchor)|
    e1: vec4<f32>,
    e2: vec4<f32>,
    // what e1, e2 leave of their f64 values
    e1_lo: vec4<f32>,
    e2_lo: vec4<f32>,
    // the anchor lattice point at the finest resolution
    anchor: vec4<i32>,
    // corners 0..3 and edges 3..6: owner face, its corners 1 and 2 among ours, morph direction
    slots: array<vec4<u32>, 2>,
};

struct Cdlod {
    faces: array<CdlodFace, 20>,
    // per level: morph start (metres from the camera), 1 / morph range
    morph: array<vec4<f32>, 32>,
    // lowest and highest terrain (metres, scaled), 2^−(finest resolution), unused
    h_range: vec4<f32>,
    // patch segments N, log2 N, MAX_LEVEL + log2 N, MAX_LEVEL
    params: vec4<u32>,
};

fn cdlod_slot(f: u32, k: u32) -> u32 {
    return cdlod.faces[f].slots[k / 4u][k % 4u];
}

// The corner (0..3) or edge (3..6) of the face lattice point `ij` lies on; 6 inside.
fn cdlod_slot_index(ij: vec2<i32>, m: i32) -> u32 {
    if (ij.x == 0 && ij.y == 0) {
        return 0u;
    }
    if (ij.x == m && ij.y == 0) {
        return 1u;
    }
    if (ij.x == 0 && ij.y == m) {
        return 2u;
    }
    if (ij.y == 0) {
        return 3u;
    }
    if (ij.x == 0) {
        return 4u;
    }
    if (ij.x + ij.y == m) {
        return 5u;
    }
    return 6u;
}

// Point `ij` of face `f` (resolution m a side) in the lattice of the owner of `slot`:
// (face, i, j).
fn cdlod_remap(f: u32, slot: u32, ij: vec2<i32>, m: i32) -> vec3<i32> {
    if (slot == 6u) {
        return vec3<i32>(i32(f), ij);
    }
    let s = cdlod_slot(f, slot);
    var w = array<i32, 4>(m - ij.x - ij.y, ij.x, ij.y, 0);
    return vec3<i32>(i32(s & 0xffu), w[(s >> 8u) & 3u], w[(s >> 16u) & 3u]);
}

// Where an odd lattice point morphs to: one end of its coarse edge (the face's rule inside it,
// the edge's own direction on the icosahedron's edges); even points stay.
fn cdlod_target(f: u32, ij: vec2<i32>, m: i32) -> vec2<i32> {
    let oi = (ij.x & 1) != 0;
    let oj = (ij.y & 1) != 0;
    if (!oi && !oj) {
        return ij;
    }
    let slot = cdlod_slot_index(ij, m);
    if (slot >= 3u && slot <= 5u) {
        let sg = select(-1, 1, ((cdlod_slot(f, slot) >> 24u) & 1u) == 1u);
        if (slot == 3u) {
            return ij + vec2<i32>(sg, 0);
        }
        if (slot == 4u) {
            return ij + vec2<i32>(0, sg);
        }
        return ij + vec2<i32>(sg, -sg);
    }
    if (oi && !oj) {
        return ij + vec2<i32>(-1, 0);
    }
    if (!oi && oj) {
        return ij + vec2<i32>(0, 1);
    }
    return ij + vec2<i32>(1, -1);
}

// The attributes (sin θ̃ cos ψ, sin θ̃ sin ψ, 1 − cos θ̃) of face g's point anchor + e₁Δu + e₂Δv,
// normalised without cancellation: 1 − z/|d| = ρ² / (|d|(|d| + z)), ρ² = x² + y², and
// x/|d| = x − x·t, t = 1 − 1/|d| from |d|² − 1 (|d| itself rounds to 6e-8).
fn cdlod_point(g: u32, du: f32, dv: f32) -> vec3<f32> {
    let face = cdlod.faces[g];
    let dx = face.a.x + (face.e1.x * du + face.e2.x * dv) + (face.e1_lo.x * du + face.e2_lo.x * dv);
    let dy = face.a.y + (face.e1.y * du + face.e2.y * dv) + (face.e1_lo.y * du + face.e2_lo.y * dv);
    let dz = (face.e1.z * du + face.e2.z * dv) - face.a.z;
    let rho2 = dx * dx + dy * dy;
    // |d|² = 1 + w; 1 − 1/|d| = w / (|d|(|d| + 1)), small and exact to f32
    let w = dz * (2.0 + dz) + rho2;
    let len = sqrt(1.0 + w);
    let t = w / (len * (len + 1.0));
    let z = 1.0 + dz;
    var c = 1.0 - z / len;
    if (z > 0.0) {
        c = rho2 / (len * (len + z));
    }
    return vec3<f32>(dx - dx * t, dy - dy * t, c);
}

fn cdlod_at(g: u32, p: vec2<i32>, step: i32) -> vec3<f32> {
    let anchor = cdlod.faces[g].anchor;
    let du = f32(p.x * step - anchor.x) * cdlod.h_range.z;
    let dv = f32(p.y * step - anchor.y) * cdlod.h_range.z;
    return cdlod_point(g, du, dv);
}

// The camera's distance from the terrain's radial segment in a direction of 1 − cos θ̃ = c.
fn cdlod_distance(radius: f32, cam_height: f32, c: f32) -> f32 {
    let rc = radius + cam_height;
    let h = clamp(cam_height - rc * c, cdlod.h_range.x, cdlod.h_range.y);
    return sqrt((h - cam_height) * (h - cam_height) + 2.0 * (radius + h) * rc * c);
}

// Patch vertex `pij` of the leaf (face, level, corner, sigma), morphed towards its parent's
// lattice by the camera's distance.
fn cdlod_vertex(f: u32, level: u32, corner: vec2<i32>, sigma: i32, pij: vec2<u32>, radius: f32, cam_height: f32) -> vec3<f32> {
    let n = i32(cdlod.params.x);
    let m = 1 << (level + cdlod.params.y);
    let ij = corner * n + sigma * vec2<i32>(pij);
    let step = 1 << (cdlod.params.w - level);
    let c0 = cdlod_remap(f, cdlod_slot_index(ij, m), ij, m);
    let unmorphed = cdlod_at(u32(c0.x), c0.yz, step);
    let t = cdlod_target(f, ij, m);
    if (all(t == ij)) {
        return unmorphed;
    }
    let mr = cdlod.morph[level];
    let k = clamp((cdlod_distance(radius, cam_height, unmorphed.z) - mr.x) * mr.y, 0.0, 1.0);
    if (k <= 0.0) {
        return unmorphed;
    }
    if (k >= 1.0) {
        let ct = cdlod_remap(f, cdlod_slot_index(t, m), t, m);
        return cdlod_at(u32(ct.x), ct.yz, step);
    }
    let tt = cdlod_remap(f, cdlod_slot_index(ij, m), t, m);
    let g = u32(c0.x);
    let anchor = cdlod.faces[g].anchor;
    let du = f32(c0.y * step - anchor.x) + k * f32((tt.y - c0.y) * step);
    let dv = f32(c0.z * step - anchor.y) + k * f32((tt.z - c0.z) * step);
    return cdlod_point(g, du * cdlod.h_range.z, dv * cdlod.h_range.z);
}
