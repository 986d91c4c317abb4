// Composed by wesl from shaders/cdlod_probe.wesl (features: probe): do not edit.
// `SPHERECLIP_BLESS=1 cargo test -p sc_view_gpu --test shaders composed` rewrites it.

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x + 65535u * 64u * id.y;
    if (k >= arrayLength(&probe_out)) {
        return;
    }
    let a = probe_in[2u * k];
    let b = probe_in[2u * k + 1u];
    let p = cdlod_vertex(u32(a.x), u32(a.y), a.zw, b.x, vec2<u32>(b.yz), probe_frame.x, probe_frame.y);
    probe_out[k] = vec4<f32>(p, 0.0);
}

@group(0) @binding(0)
var<uniform> cdlod: Cdlod;

@group(0) @binding(1)
var<uniform> probe_frame: vec4<f32>;

@group(0) @binding(2)
var<storage, read> probe_in: array<vec4<i32>>;

@group(0) @binding(3)
var<storage, read_write> probe_out: array<vec4<f32>>;

fn cdlod_at(g: u32, p: vec2<i32>, step: i32) -> vec3<f32> {
    let anchor = cdlod.faces[g].anchor;
    let du = f32(p.x * step - anchor.x) * cdlod.h_range.z;
    let dv = f32(p.y * step - anchor.y) * cdlod.h_range.z;
    return cdlod_point(g, du, dv);
}

fn cdlod_distance(radius: f32, cam_height: f32, c: f32) -> f32 {
    let rc = radius + cam_height;
    let h = clamp(cam_height - rc * c, cdlod.h_range.x, cdlod.h_range.y);
    return sqrt((h - cam_height) * (h - cam_height) + 2.0 * (radius + h) * rc * c);
}

fn cdlod_point(g: u32, du: f32, dv: f32) -> vec3<f32> {
    let face = cdlod.faces[g];
    let dx = face.a.x + (face.e1.x * du + face.e2.x * dv) + (face.e1_lo.x * du + face.e2_lo.x * dv);
    let dy = face.a.y + (face.e1.y * du + face.e2.y * dv) + (face.e1_lo.y * du + face.e2_lo.y * dv);
    let dz = (face.e1.z * du + face.e2.z * dv) - face.a.z;
    let rho2 = dx * dx + dy * dy;
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

fn cdlod_remap(f: u32, slot: u32, ij: vec2<i32>, m: i32) -> vec3<i32> {
    if (slot == 6u) {
        return vec3<i32>(i32(f), ij);
    }
    let s = cdlod_slot(f, slot);
    var w = array<i32, 4>(m - ij.x - ij.y, ij.x, ij.y, 0);
    return vec3<i32>(i32(s & 255u), w[(s >> 8u) & 3u], w[(s >> 16u) & 3u]);
}

fn cdlod_slot(f: u32, k: u32) -> u32 {
    return cdlod.faces[f].slots[k / 4u][k % 4u];
}

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

struct Cdlod {
    faces: array<CdlodFace, 20>,
    morph: array<vec4<f32>, 32>,
    h_range: vec4<f32>,
    params: vec4<u32>
}

struct CdlodFace {
    a: vec4<f32>,
    e1: vec4<f32>,
    e2: vec4<f32>,
    e1_lo: vec4<f32>,
    e2_lo: vec4<f32>,
    anchor: vec4<i32>,
    slots: array<vec4<u32>, 2>
}
