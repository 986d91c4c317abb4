// Composed by wesl from shaders/transform_probe.wesl (features: probe): do not edit.
// `SPHERECLIP_BLESS=1 cargo test -p sc_view_gpu --test shaders composed` rewrites it.

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&vertices)) {
        return;
    }
    let v = vertices[i];
    offsets[i] = map_offsets(viewer, v.x, v.y, v.z, v.w);
}

@group(0) @binding(0)
var<uniform> viewer: ViewerConsts;

@group(0) @binding(1)
var<storage, read> vertices: array<vec4<f32>>;

@group(0) @binding(2)
var<storage, read_write> offsets: array<vec2<f32>>;

const TAU: f32 = 6.283185307179586;

fn atan2_precise(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    if (ax == 0.0 && ay == 0.0) {
        return 0.0;
    }
    let swap = ay > ax;
    let z = select(ay / ax, ax / ay, swap);
    var r: f32;
    if (z > 0.41421356) {
        r = 0.7853981633974483 + atan_series((z - 1.0) / (z + 1.0));
    }
    else {
        r = atan_series(z);
    }
    if (swap) {
        r = 1.5707963267948966 - r;
    }
    if (x < 0.0) {
        r = 3.141592653589793 - r;
    }
    return select(r, -r, y < 0.0);
}

fn atan_series(z: f32) -> f32 {
    let z2 = z * z;
    return z * (1.0 + z2 * (-1.0 / 3.0 + z2 * (1.0 / 5.0 + z2 * (-1.0 / 7.0 + z2 * (1.0 / 9.0 + z2 * (-1.0 / 11.0 + z2 * (1.0 / 13.0 - z2 / 15.0)))))));
}

fn map_offsets(v: ViewerConsts, px: f32, py: f32, c: f32, seam: f32) -> vec2<f32> {
    let tx = px;
    let ty = v.orient * py;
    let tz = 1.0 - c;
    let wx = v.cos_v * tx + v.sin_v * tz;
    let wy = ty;
    let rho = sqrt(wx * wx + wy * wy);
    var dcolat: f32;
    if (wx > 0.0) {
        let q = wy * wy / (rho + wx);
        dcolat = atan2_precise(tx + v.cos_v * q, tz + v.sin_v * q);
    }
    else {
        let wz = -v.sin_v * tx + v.cos_v * tz;
        dcolat = atan2_precise(rho, wz) - v.colat;
    }
    dcolat = v.orient * dcolat;
    var dlon = atan2_precise(wy, wx);
    if (wx < 0.0) {
        let s = seam * v.orient;
        if (s < 0.0 && dlon > 0.0) {
            dlon = dlon - TAU;
        }
        else if (s > 0.0 && dlon < 0.0) {
            dlon = dlon + TAU;
        }
    }
    return vec2<f32>(dlon, dcolat);
}

struct ViewerConsts {
    sin_v: f32,
    cos_v: f32,
    colat: f32,
    orient: f32
}
