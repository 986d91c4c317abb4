// Spherical clipmaps: vertex stage maps the static hemisphere around the viewer onto the height
// clipmap and displaces it; fragment stage colours it. Everything here is relative to the viewer:
// absolute positions live on the CPU in f64 (see viewer/src/transform.rs, whose `offsets_f32` is
// this file's `map_offsets`, operation for operation).

struct Frame {
    // map transform
    sin_v: f32,
    cos_v: f32,
    colat: f32,
    orient: f32,
    // camera: height above the sphere under the viewer, sphere radius (metres)
    cam_height: f32,
    radius: f32,
    level_count: u32,
    _pad: u32,
    // view-space (viewer at the north pole, metres, relative to the camera) to clip space
    view_proj: mat4x4<f32>,
};

// One clipmap level: where the viewer sits in it (texel coordinates, fractional) and how many
// texels per radian of longitude / colatitude it has.
struct Level {
    viewer_texel: vec2<f32>,
    texels_per_rad: vec2<f32>,
    // texture size for toroidal addressing, and the world texel of the texture's origin modulo it
    size: vec2<u32>,
    origin: vec2<u32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> levels: array<Level>;
@group(0) @binding(2) var heights: texture_2d_array<f32>;

struct VertexIn {
    @location(0) pxy: vec2<f32>,
    @location(1) one_minus_cos: f32,
    @location(2) seam: f32,
    @location(3) level: u32,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) height: f32,
    @location(1) @interpolate(flat) level: u32,
};

const TAU: f32 = 6.283185307179586;

// Δφ, Δθ of a vertex from the viewer (see transform.rs).
fn map_offsets(px: f32, py: f32, c: f32, seam: f32) -> vec2<f32> {
    // mirrored to the nearer pole (see transform.rs)
    let tx = px;
    let ty = frame.orient * py;
    let tz = 1.0 - c;
    let wx = frame.cos_v * tx + frame.sin_v * tz;
    let wy = ty;
    let rho = sqrt(wx * wx + wy * wy);
    var dcolat: f32;
    if (wx > 0.0) {
        let q = wy * wy / (rho + wx);
        dcolat = atan2(tx + frame.cos_v * q, tz + frame.sin_v * q);
    } else {
        let wz = -frame.sin_v * tx + frame.cos_v * tz;
        dcolat = atan2(rho, wz) - frame.colat;
    }
    dcolat = frame.orient * dcolat;
    var dlon = atan2(wy, wx);
    if (wx < 0.0) {
        let s = seam * frame.orient;
        if (s < 0.0 && dlon > 0.0) {
            dlon = dlon - TAU;
        } else if (s > 0.0 && dlon < 0.0) {
            dlon = dlon + TAU;
        }
    }
    return vec2<f32>(dlon, dcolat);
}

// Height at fractional texel t of level l: bilinear from four textureLoads (GL cannot filter
// R32Float), toroidal addressing.
fn height_at(l: u32, t: vec2<f32>) -> f32 {
    let lv = levels[l];
    let base = floor(t - vec2<f32>(0.5));
    let f = t - vec2<f32>(0.5) - base;
    var h = array<f32, 4>();
    for (var k = 0u; k < 4u; k = k + 1u) {
        let o = vec2<f32>(f32(k & 1u), f32(k >> 1u));
        let p = vec2<i32>(base + o);
        let size = vec2<i32>(lv.size);
        let wrapped = ((p + vec2<i32>(lv.origin)) % size + size) % size;
        h[k] = textureLoad(heights, wrapped, i32(l), 0).x;
    }
    return mix(mix(h[0], h[1], f.x), mix(h[2], h[3], f.x), f.y);
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let off = map_offsets(v.pxy.x, v.pxy.y, v.one_minus_cos, v.seam);
    let l = min(v.level, frame.level_count - 1u);
    let lv = levels[l];
    let texel = lv.viewer_texel + off * lv.texels_per_rad;
    let h = height_at(l, texel);
    // view space relative to the camera: (R + h)·p̃ − (0, 0, R + h_cam), with
    // (R + h)(1 − c) − R − h_cam = h − h_cam − (R + h)·c (no large cancellation)
    let r = frame.radius + h;
    let sin_t = length(v.pxy);
    let rel = vec3<f32>(
        r * v.pxy.x,
        r * v.pxy.y,
        h - frame.cam_height - r * v.one_minus_cos,
    );
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(rel, 1.0);
    out.height = h + 0.0 * sin_t;
    out.level = l;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    // a simple height ramp until the colour clipmap is bound
    let t = clamp(in.height / 6000.0, -1.0, 1.0);
    let land = vec3<f32>(0.3 + 0.5 * t, 0.5 + 0.3 * t, 0.2 + 0.6 * t);
    let sea = vec3<f32>(0.1, 0.2 + 0.2 * (1.0 + t), 0.6);
    return vec4<f32>(select(land, sea, t < 0.0), 1.0);
}
