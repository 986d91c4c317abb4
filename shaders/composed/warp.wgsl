// Composed by wesl from shaders/warp.wesl (features: none): do not edit.
// `SPHERECLIP_BLESS=1 cargo test -p sc_view_gpu --test shaders composed` rewrites it.

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let view = ViewerConsts(frame.sin_v, frame.cos_v, frame.colat, frame.orient);
    let off = map_offsets(view, in.p.x, in.p.y, in.p.z, in.seam);
    let doff_x = wrap_lon(dpdx(off));
    let doff_y = wrap_lon(dpdy(off));
    var albedo: vec3<f32>;
    let t = clamp(in.height / (6000.0 * frame.exaggeration), -1.0, 1.0);
    let land = vec3<f32>(0.12 + 0.5 * t, 0.25 + 0.35 * t, 0.05 + 0.6 * t);
    let sea = vec3<f32>(0.02, 0.06 + 0.05 * (1.0 + t), 0.3);
    albedo = select(land, sea, t < 0.0);
    let lf = clamp(floor(in.lvl), f32(frame.level_lo), f32(frame.level_hi));
    let l = u32(lf);
    let a = blend_of(l, in.lvl - lf);
    let ring = select(lf, lf - 1.0 + a, l > frame.level_lo);
    let cap = level_cap(l, ring, off, false);
    let lc = lod_level(l, cap, footprint(levels[l].texels_per_rad, off, doff_x, doff_y).major);
    let l0 = u32(floor(lc));
    let f1 = lc - floor(lc);
    if (frame.has_color == 1u) {
        let fp = footprint(levels[l].color_texels_per_rad, off, doff_x, doff_y);
        let taps = aniso_taps(fp);
        let la = lod_level(l, level_cap(l, ring, off, true), fp.major / taps);
        var n = clamp(ceil(fp.major / exp2(f32(l) + LOD_BIAS - la)), 1.0, taps);
        var axis = fp.axis;
        let lt = min(u32(ceil(la)), frame.level_hi);
        if ((levels[lt].color_open & OPEN_ROUND) != 0u) {
            let tpr = levels[lt].color_texels_per_rad;
            let tx = length(doff_x * tpr);
            let ty = length(doff_y * tpr);
            let nt = clamp(ceil(max(tx, ty)), 1.0, MAX_ANISO);
            if (nt > n) {
                n = nt;
                axis = select(doff_y, doff_x, tx >= ty);
            }
        }
        var c = vec4<f32>(0.0);
        for (var i = 0.0; i < n; i = i + 1.0) {
            c = c + color_trilinear(la, off + axis * ((i + 0.5) / n - 0.5));
        }
        c = c / n;
        albedo = mix(albedo, c.rgb, clamp(c.a, 0.0, 1.0));
    }
    if ((frame.flags & FLAG_LEVEL_COLORS) != 0u) {
        albedo = mix(albedo, level_tint(l), 0.6);
    }
    if ((frame.flags & FLAG_UNLIT) != 0u) {
        return vec4<f32>(albedo, 1.0);
    }
    var slope = slope_at(l0, texel_of(l0, off));
    if (f1 > 0.0 && l0 < frame.level_hi) {
        slope = mix(slope, slope_at(l0 + 1u, texel_of(l0 + 1u, off)), f1);
    }
    let up = vec3<f32>(in.p.x, in.p.y, 1.0 - in.p.z);
    let n = surface_normal(up, slope, in.height);
    let sun = normalize(frame.sun.xyz);
    let day = smoothstep(-0.1, 0.1, dot(normalize(up), sun));
    let light = 0.04 + 0.16 * day + 0.8 * max(dot(n, sun), 0.0);
    if (atmo.camera.w == 0.0) {
        return vec4<f32>(albedo * light, 1.0);
    }
    return vec4<f32>(terrain_in_air(in.clip.xy, in.rel, albedo, n), 1.0);
}

@fragment
fn sky_fs(in: SkyOut) -> @location(0) vec4<f32> {
    let d = view_direction(in.clip.xy / atmo.screen.xy);
    let s = sun_dir();
    let r = atmo.camera.x;
    let nu = dot(d, s);
    var l = vec3<f32>(0.0);
    var through = vec3<f32>(1.0);
    if (r < atm.radii.y) {
        var cos_az = 1.0;
        let dh = length(d.xy);
        let sh = length(s.xy);
        if (dh > 1e-6 && sh > 1e-6) {
            cos_az = dot(d.xy, s.xy) / (dh * sh);
        }
        l = sky_view_at(r, d.z, cos_az);
        through = select(transmittance_to_top(r, d.z), vec3<f32>(0.0), ground_distance(r, atmo.screen.w, d.z) >= 0.0);
    }
    else {
        let e = enter(d, s);
        if (e.t >= 0.0) {
            let sc = sky_along(e.r, e.h, e.mu, e.mu_s, nu, 1e30, true);
            l = sc.radiance;
            through = select(sc.transmittance, vec3<f32>(0.0), hits_ground(e.r, e.mu));
        }
    }
    let alpha2 = 2.0 * (1.0 - atmo.screen.z);
    let disc = select(0.0, atmo.sun.w / (PI * alpha2), nu > atmo.screen.z);
    let c = tone_map(l * atmo.sun.w + through * disc) + atmo.space.xyz * through;
    return vec4<f32>(c, 1.0);
}

@group(0) @binding(0)
var<uniform> frame: Frame;

@group(0) @binding(1)
var<uniform> levels: array<Level, MAX_RING + 1u>;

@group(0) @binding(2)
var heights: texture_2d_array<f32>;

@group(0) @binding(3)
var colors: texture_2d_array<f32>;

@group(1) @binding(0)
var<uniform> atm: Atmosphere;

@group(1) @binding(1)
var<storage, read> transmittance_table: array<vec4<f32>>;

@group(1) @binding(2)
var<storage, read> multiple_scattering_table: array<vec4<f32>>;

@group(1) @binding(3)
var<uniform> atmo: AtmosphereFrame;

@group(1) @binding(4)
var<storage, read> sky_view_table: array<vec4<f32>>;

@group(1) @binding(5)
var<storage, read> aerial_inscatter: array<vec4<f32>>;

@group(1) @binding(6)
var<storage, read> aerial_transmittance: array<vec4<f32>>;

@group(1) @binding(7)
var<storage, read> irradiance_table: array<vec4<f32>>;

@group(2) @binding(0)
var<uniform> warp: vec4<u32>;

@group(2) @binding(1)
var<storage, read> warp_lines: array<vec4<f32>>;

@vertex
fn sky_vs(@builtin(vertex_index) i: u32) -> SkyOut {
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - vec2<f32>(1.0);
    var out: SkyOut;
    out.clip = vec4<f32>(xy, 0.0, 1.0);
    return out;
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let on_inner = v.column.w > 0.5;
    let ring = select(v.outer, v.inner, on_inner);
    let level = select(v.rings.x, v.rings.y, on_inner);
    let pxy = ring.x * v.column.xy;
    let view = ViewerConsts(frame.sin_v, frame.cos_v, frame.colat, frame.orient);
    let off = map_offsets(view, pxy.x, pxy.y, ring.y, v.column.z);
    let mp = mesh_height(level, ring.z, off);
    return vertex_out(vec3<f32>(pxy, ring.y), mp, v.column.z);
}

@vertex
fn warp_vs(@builtin(vertex_index) k: u32) -> VertexOut {
    let q = warp_point(k);
    let p = q.xyz;
    let view = ViewerConsts(frame.sin_v, frame.cos_v, frame.colat, frame.orient);
    let off = map_offsets(view, p.x, p.y, p.z, 0.0);
    let rp = ring_of(p.z);
    let mp = mesh_height(rp.level, rp.depth, off);
    return vertex_out(p, mp, q.w);
}

const AERIAL: u32 = 32u;

const FLAG_LEVEL_COLORS: u32 = 1u;

const FLAG_UNLIT: u32 = 2u;

const IRRADIANCE_DIRECTIONS: u32 = 8u;

const IRRADIANCE_H: u32 = 16u;

const IRRADIANCE_W: u32 = 64u;

const LOD_BIAS: f32 = 0.5;

const MAX_ANISO: f32 = 4.0;

const MAX_RING: u32 = 25u;

const MS_DIRECTIONS: u32 = 8u;

const MS_SIZE: u32 = 32u;

const MS_STEPS: u32 = 20u;

const OPEN_NORTH: u32 = 2u;

const OPEN_ROUND: u32 = 1u;

const OPEN_SOUTH: u32 = 4u;

const PI: f32 = 3.14159265358979;

const SKY_STEPS: u32 = 30u;

const SKY_VIEW_H: u32 = 108u;

const SKY_VIEW_W: u32 = 192u;

const TAU: f32 = 6.283185307179586;

const TRANSMITTANCE_H: u32 = 64u;

const TRANSMITTANCE_W: u32 = 256u;

fn above_air() -> bool {
    return atmo.camera.x > atm.radii.y;
}

fn aerial_at(uv: vec2<f32>, s_in: f32, path: f32) -> Scatter {
    let n = f32(AERIAL);
    let s = max(s_in, 0.0);
    let c = taps(uv.x, uv.y, AERIAL, AERIAL);
    let q = min(slice_index(s, path), n - 1.0);
    var k0 = 0u;
    var k1 = 0u;
    var fz = 0.0;
    var near = 1.0;
    if q < 0.0 {
        near = s / max(slice_end(0u, path), 1e-6);
    }
    else {
        k0 = u32(floor(q));
        k1 = min(k0 + 1u, AERIAL - 1u);
        fz = q - f32(k0);
    }
    let a = aerial_slice(k0, c);
    let b = aerial_slice(k1, c);
    let l = mix(a[0], b[0], fz);
    let t = mix(a[1], b[1], fz);
    return Scatter(l * near, mix(vec3<f32>(1.0), t, near));
}

fn aerial_inscatter_at(i: u32) -> vec3<f32> {
    return aerial_inscatter[i].xyz;
}

fn aerial_slice(k: u32, c: Taps) -> array<vec3<f32>, 2> {
    let n = AERIAL;
    let a = k * n * n + c.j0 * n;
    let b = k * n * n + c.j1 * n;
    let f = c.f;
    let l = mix(mix(aerial_inscatter_at(a + c.i0), aerial_inscatter_at(a + c.i1), f.x), mix(aerial_inscatter_at(b + c.i0), aerial_inscatter_at(b + c.i1), f.x), f.y);
    let t = mix(mix(aerial_transmittance_at(a + c.i0), aerial_transmittance_at(a + c.i1), f.x), mix(aerial_transmittance_at(b + c.i0), aerial_transmittance_at(b + c.i1), f.x), f.y);
    return array<vec3<f32>, 2>(l, t);
}

fn aerial_transmittance_at(i: u32) -> vec3<f32> {
    return aerial_transmittance[i].xyz;
}

fn aniso_taps(fp: Footprint) -> f32 {
    return clamp(ceil(fp.major / max(fp.minor, 1e-12)), 1.0, MAX_ANISO);
}

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

fn blend_of(l: u32, depth: f32) -> f32 {
    if (l <= frame.level_lo) {
        return 1.0;
    }
    return smoothstep(0.0, 0.5, depth);
}

fn color_at(l: u32, t: vec2<f32>) -> vec4<f32> {
    let lv = levels[l];
    let base = floor(t - vec2<f32>(0.5));
    let f = t - vec2<f32>(0.5) - base;
    let size = vec2<i32>(lv.color_size);
    let side = size.x / max(size.x / (2 * size.y), 1);
    var c = array<vec4<f32>, 4>();
    for (var k = 0u; k < 4u; k = k + 1u) {
        let o = vec2<f32>(f32(k & 1u), f32(k >> 1u));
        let p = vec2<i32>(base + o);
        let wrapped = ((p + vec2<i32>(lv.color_origin)) % size + size) % size;
        let strip = wrapped.x / side;
        let at = vec2<i32>(wrapped.x - strip * side, wrapped.y + strip * size.y);
        c[k] = textureLoad(colors, at, i32(l), 0);
    }
    return mix(mix(c[0], c[1], f.x), mix(c[2], c[3], f.x), f.y);
}

fn color_texel_of(l: u32, off: vec2<f32>) -> vec2<f32> {
    let lv = levels[l];
    return lv.color_viewer_texel + off * lv.color_texels_per_rad;
}

fn color_trilinear(lc: f32, off: vec2<f32>) -> vec4<f32> {
    let l0 = u32(floor(lc));
    let f1 = lc - floor(lc);
    var c = color_at(l0, color_texel_of(l0, off));
    if (f1 > 0.0 && l0 < frame.level_hi) {
        c = mix(c, color_at(l0 + 1u, color_texel_of(l0 + 1u, off)), f1);
    }
    return c;
}

fn column_path(e: Entry) -> f32 {
    let g = ground_distance(e.r, e.h, e.mu);
    return select(distance_to_top(e.r, e.mu), g, g >= 0.0);
}

fn distance_to_bottom(r: f32, mu: f32) -> f32 {
    let bottom = atm.radii.x;
    let disc = r * r * (mu * mu - 1.0) + bottom * bottom;
    return max(0.0, -r * mu - sqrt(max(disc, 0.0)));
}

fn distance_to_top(r: f32, mu: f32) -> f32 {
    let top = atm.radii.y;
    let disc = r * r * (mu * mu - 1.0) + top * top;
    return max(0.0, -r * mu + sqrt(max(disc, 0.0)));
}

fn enter(d: vec3<f32>, s: vec3<f32>) -> Entry {
    let r = atmo.camera.x;
    let top = atm.radii.y;
    if r <= top {
        return Entry(0.0, r, atmo.screen.w, d.z, s.z);
    }
    let disc = top * top - r * r * dot(d.xy, d.xy);
    if disc < 0.0 || d.z >= 0.0 {
        return Entry(-1.0, r, atmo.screen.w, d.z, s.z);
    }
    let q = sqrt(disc);
    let t = max(0.0, -r * d.z - q);
    return Entry(t, top, top - atm.radii.x, -q / top, (r * s.z + t * dot(d, s)) / top);
}

fn extinction_at(h_in: f32) -> vec3<f32> {
    let h = max(h_in, 0.0);
    let rayleigh = exp(-h / atm.rayleigh.w);
    let mie = exp(-h / atm.mie_scattering.w);
    let ozone = max(0.0, 1.0 - abs(h - atm.ozone.w) / (0.5 * atm.albedo.w));
    return atm.rayleigh.xyz * rayleigh + atm.mie_extinction.xyz * mie + atm.ozone.xyz * ozone;
}

fn footprint(tpr: vec2<f32>, off: vec2<f32>, doff_x: vec2<f32>, doff_y: vec2<f32>) -> Footprint {
    let s = abs(sin(frame.colat + frame.orient * off.y));
    let k = vec2<f32>(tpr.y * s, tpr.y);
    let ax = length(doff_x * k);
    let ay = length(doff_y * k);
    return Footprint(min(ax, ay), max(ax, ay), select(doff_y, doff_x, ax >= ay));
}

fn ground_distance(r: f32, h: f32, mu: f32) -> f32 {
    let bottom = atm.radii.x;
    let disc = r * r * mu * mu - h * (2.0 * bottom + h);
    if mu >= 0.0 || disc < 0.0 {
        return -1.0;
    }
    return max(0.0, h * (2.0 * bottom + h) / (-r * mu + sqrt(disc)));
}

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

fn hits_ground(r: f32, mu: f32) -> bool {
    let bottom = atm.radii.x;
    return mu < 0.0 && r * r * (mu * mu - 1.0) + bottom * bottom >= 0.0;
}

fn irradiance_at(r: f32, mu_s: f32) -> vec3<f32> {
    let k = taps((mu_s + 1.0) / 2.0, (r - atm.radii.x) / (atm.radii.y - atm.radii.x), IRRADIANCE_W, IRRADIANCE_H);
    let w = IRRADIANCE_W;
    let a = mix(irradiance_table_at(k.j0 * w + k.i0), irradiance_table_at(k.j0 * w + k.i1), k.f.x);
    let b = mix(irradiance_table_at(k.j1 * w + k.i0), irradiance_table_at(k.j1 * w + k.i1), k.f.x);
    return mix(a, b, k.f.y);
}

fn irradiance_table_at(i: u32) -> vec3<f32> {
    return irradiance_table[i].xyz;
}

fn level_cap(l: u32, ring: f32, off: vec2<f32>, color: bool) -> f32 {
    var cap = min(ring, f32(l) - 1.0 + levels[l].fade);
    if (color && (levels[l].color_open & OPEN_ROUND) != 0u && l > frame.level_lo) {
        cap = min(cap, f32(l) - 1.0 + window_inside(l, off, true));
    }
    for (var k = l + 1u; k <= min(l + 2u, frame.level_hi); k = k + 1u) {
        let inside = min(window_inside(k, off, color), levels[k].fade);
        if (inside <= 0.0) {
            break;
        }
        cap = max(cap, f32(k) - 1.0 + inside);
        if (inside < 1.0) {
            break;
        }
    }
    return cap;
}

fn level_tint(l: u32) -> vec3<f32> {
    let k = f32(l % 6u);
    return vec3<f32>(0.5 + 0.5 * cos(1.05 * k), 0.5 + 0.5 * cos(1.05 * k + 2.1), 0.5 + 0.5 * cos(1.05 * k + 4.2));
}

fn lod_level(l: u32, cap: f32, rho: f32) -> f32 {
    let fine = f32(l) + LOD_BIAS - log2(max(rho, 1e-6));
    return clamp(min(cap, fine), f32(frame.level_lo), f32(frame.level_hi));
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

fn mesh_height(level: u32, depth_in: f32, off: vec2<f32>) -> MeshPoint {
    let l = min(level, frame.level_hi);
    let depth = select(depth_in, 1.0, level > frame.level_hi);
    let a = select(blend_of(l, depth) * levels[l].fade, 1.0, l <= frame.level_lo);
    var h = height_at(l, texel_of(l, off));
    if (a < 1.0) {
        h = mix(height_at(l - 1u, texel_of(l - 1u, off)), h, a);
    }
    return MeshPoint(h * frame.exaggeration, l, depth);
}

fn mie_phase(g: f32, nu: f32) -> f32 {
    let k = 3.0 / (8.0 * PI) * (1.0 - g * g) / (2.0 + g * g);
    return k * (1.0 + nu * nu) / pow(1.0 + g * g - 2.0 * g * nu, 1.5);
}

fn multiple_scattering_at(r: f32, mu_s: f32) -> vec3<f32> {
    let k = taps((mu_s + 1.0) / 2.0, (r - atm.radii.x) / (atm.radii.y - atm.radii.x), MS_SIZE, MS_SIZE);
    let n = MS_SIZE;
    let a = mix(multiple_scattering_table_at(k.j0 * n + k.i0), multiple_scattering_table_at(k.j0 * n + k.i1), k.f.x);
    let b = mix(multiple_scattering_table_at(k.j1 * n + k.i0), multiple_scattering_table_at(k.j1 * n + k.i1), k.f.x);
    return mix(a, b, k.f.y);
}

fn multiple_scattering_table_at(i: u32) -> vec3<f32> {
    return multiple_scattering_table[i].xyz;
}

fn rayleigh_phase(nu: f32) -> f32 {
    return 3.0 / (16.0 * PI) * (1.0 + nu * nu);
}

fn ring_of(one_minus_cos: f32) -> RingPoint {
    let theta = 2.0 * asin(sqrt(0.5 * one_minus_cos));
    let lam = log2(1.5707964 / max(theta, 1e-30));
    let ring = clamp(floor(lam), 0.0, f32(MAX_RING));
    if (u32(ring) < frame.level_lo) {
        return RingPoint(frame.level_lo, 0.0);
    }
    return RingPoint(u32(ring), clamp(lam - ring, 0.0, 1.0));
}

fn scattering_at(h_in: f32) -> vec3<f32> {
    let h = max(h_in, 0.0);
    return atm.rayleigh.xyz * exp(-h / atm.rayleigh.w) + atm.mie_scattering.xyz * exp(-h / atm.mie_scattering.w);
}

fn sky_along(r: f32, h0: f32, mu: f32, mu_s: f32, nu: f32, max_d: f32, stop_at_ground: bool) -> Scatter {
    let bottom = atm.radii.x;
    let sin_v = sqrt(max(1.0 - mu * mu, 0.0));
    let view = vec3<f32>(sin_v, 0.0, mu);
    var sx = sqrt(max(1.0 - mu_s * mu_s, 0.0));
    if sin_v > 1e-6 {
        sx = (nu - mu * mu_s) / sin_v;
    }
    let sun = vec3<f32>(sx, sqrt(max(1.0 - mu_s * mu_s - sx * sx, 0.0)), mu_s);
    var d = distance_to_top(r, mu);
    let g = ground_distance(r, h0, mu);
    if stop_at_ground && g >= 0.0 {
        d = g;
    }
    d = min(d, max_d);
    let dt = d / f32(SKY_STEPS);
    let pr = rayleigh_phase(nu);
    let pm = mie_phase(atm.mie_extinction.w, nu);
    var throughput = vec3<f32>(1.0);
    var radiance = vec3<f32>(0.0);
    for (var k = 0u; k < SKY_STEPS; k++) {
        let t = (f32(k) + 0.5) * dt;
        let p = vec3<f32>(view.x * t, view.y * t, r + view.z * t);
        let rp = length(p);
        let h = max(rp - bottom, 0.0);
        let up = p / rp;
        let mu_sp = dot(up, sun);
        let sr = atm.rayleigh.xyz * exp(-h / atm.rayleigh.w);
        let sm = atm.mie_scattering.xyz * exp(-h / atm.mie_scattering.w);
        let ext = extinction_at(h);
        let t_sun = sunlight(rp, mu_sp);
        let psi = multiple_scattering_at(rp, mu_sp);
        let s = sr * (pr * t_sun + psi) + sm * (pm * t_sun + psi);
        let step_t = exp(-ext * dt);
        let integral = select(vec3<f32>(dt), (1.0 - step_t) / ext, ext > vec3<f32>(0.0));
        radiance += throughput * s * integral;
        throughput *= step_t;
    }
    return Scatter(radiance, throughput);
}

fn sky_view_at(r_in: f32, mu: f32, cos_az: f32) -> vec3<f32> {
    let bottom = atm.radii.x;
    let r = max(r_in, bottom);
    let v_horizon = sqrt(max(r * r - bottom * bottom, 0.0));
    let beta = acos(clamp(v_horizon / r, -1.0, 1.0));
    let zenith_horizon = PI - beta;
    let zenith = acos(clamp(mu, -1.0, 1.0));
    var v = 0.0;
    if zenith < zenith_horizon {
        v = 0.5 * (1.0 - sqrt(max(1.0 - zenith / zenith_horizon, 0.0)));
    }
    else {
        v = 0.5 * (1.0 + sqrt(max((zenith - zenith_horizon) / beta, 0.0)));
    }
    let k = taps(sqrt((1.0 - clamp(cos_az, -1.0, 1.0)) / 2.0), v, SKY_VIEW_W, SKY_VIEW_H);
    let w = SKY_VIEW_W;
    let a = mix(sky_view_table_at(k.j0 * w + k.i0), sky_view_table_at(k.j0 * w + k.i1), k.f.x);
    let b = mix(sky_view_table_at(k.j1 * w + k.i0), sky_view_table_at(k.j1 * w + k.i1), k.f.x);
    return mix(a, b, k.f.y);
}

fn sky_view_table_at(i: u32) -> vec3<f32> {
    return sky_view_table[i].xyz;
}

fn slice_end(k: u32, path: f32) -> f32 {
    let x = (f32(k) + 1.0) / f32(AERIAL);
    if above_air() {
        return path * (1.0 - (1.0 - x) * (1.0 - x));
    }
    return atmo.camera.y * x * x;
}

fn slice_index(s: f32, path: f32) -> f32 {
    let n = f32(AERIAL);
    if above_air() {
        let f = clamp(s / max(path, 1e-6), 0.0, 1.0);
        return n * (1.0 - sqrt(1.0 - f)) - 1.0;
    }
    return n * sqrt(s / atmo.camera.y) - 1.0;
}

fn slope_at(l: u32, t: vec2<f32>) -> vec2<f32> {
    let dx = height_at(l, t + vec2<f32>(1.0, 0.0)) - height_at(l, t - vec2<f32>(1.0, 0.0));
    let dy = height_at(l, t + vec2<f32>(0.0, 1.0)) - height_at(l, t - vec2<f32>(0.0, 1.0));
    return 0.5 * frame.exaggeration * vec2<f32>(dx, dy) * levels[l].texels_per_rad;
}

fn sun_dir() -> vec3<f32> {
    return normalize(atmo.sun.xyz);
}

fn sunlight(r: f32, mu_s: f32) -> vec3<f32> {
    if hits_ground(r, mu_s) {
        return vec3<f32>(0.0);
    }
    return transmittance_to_top(r, mu_s);
}

fn surface_normal(up: vec3<f32>, slope: vec2<f32>, h: f32) -> vec3<f32> {
    let o = frame.orient;
    let u = normalize(vec3<f32>(up.x, o * up.y, up.z));
    let pole = vec3<f32>(-frame.sin_v, 0.0, frame.cos_v);
    let e = cross(pole, u);
    let s2 = dot(e, e);
    if (s2 < 1e-12) {
        return up;
    }
    let sc = o * (dot(u, pole) * u - pole);
    let g = (slope.y * sc * sqrt(s2) + slope.x * e) / ((frame.radius + h) * s2);
    let n = normalize(u - g);
    return vec3<f32>(n.x, o * n.y, n.z);
}

fn taps(u: f32, v: f32, w: u32, h: u32) -> Taps {
    let x = clamp(u * f32(w) - 0.5, 0.0, f32(w) - 1.0);
    let y = clamp(v * f32(h) - 0.5, 0.0, f32(h) - 1.0);
    let i0 = u32(floor(x));
    let j0 = u32(floor(y));
    return Taps(i0, min(i0 + 1u, w - 1u), j0, min(j0 + 1u, h - 1u), vec2<f32>(x - f32(i0), y - f32(j0)));
}

fn terrain_in_air(frag: vec2<f32>, rel: vec3<f32>, albedo: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let p = rel * 0.001;
    let t = length(p);
    let d = p / t;
    let r_c = atmo.camera.x;
    let q = p + vec3<f32>(0.0, 0.0, r_c);
    let r = length(q);
    let s = sun_dir();
    let mu_s = dot(q / r, s);
    let r_lit = max(r, atm.radii.x);
    let sky = irradiance_at(r_lit, mu_s) * 0.5 * (1.0 + dot(n, q / r));
    let lit = albedo * (sunlight(r_lit, mu_s) * max(dot(n, s), 0.0) + sky);
    let e = enter(d, s);
    var s_air = t - max(e.t, 0.0);
    let g = ground_distance(e.r, e.h, e.mu);
    if (g >= 0.0) {
        s_air = min(s_air, g);
    }
    let path = column_path(e);
    var ap = aerial_at(frag / atmo.screen.xy, s_air, path);
    let below = asin(min(atm.radii.x / r_c, 1.0)) - acos(clamp(-d.z, -1.0, 1.0));
    let band = atmo.space.w;
    let own = select(0.0, 1.0 - smoothstep(band, 2.0 * band, below), above_air());
    if (own > 0.0 && e.t >= 0.0) {
        let m = sky_along(e.r, e.h, e.mu, e.mu_s, dot(d, s), s_air, false);
        ap = Scatter(mix(ap.radiance, m.radiance, own), mix(ap.transmittance, m.transmittance, own));
    }
    return tone_map(lit * ap.transmittance + ap.radiance * atmo.sun.w);
}

fn texcoord_from_unit(x: f32, n: f32) -> f32 {
    return 0.5 / n + x * (1.0 - 1.0 / n);
}

fn texel_of(l: u32, off: vec2<f32>) -> vec2<f32> {
    let lv = levels[l];
    return lv.viewer_texel + off * lv.texels_per_rad;
}

fn tone_map(l: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(1.0) - exp(-atmo.camera.z * l);
}

fn transmittance_table_at(i: u32) -> vec3<f32> {
    return transmittance_table[i].xyz;
}

fn transmittance_to_top(r: f32, mu: f32) -> vec3<f32> {
    let bottom = atm.radii.x;
    let top = atm.radii.y;
    let big_h = sqrt(top * top - bottom * bottom);
    let rho = sqrt(max(r * r - bottom * bottom, 0.0));
    let d = distance_to_top(r, mu);
    let d_min = top - r;
    let d_max = rho + big_h;
    var x_mu = 0.0;
    if d_max > d_min {
        x_mu = (d - d_min) / (d_max - d_min);
    }
    let u = texcoord_from_unit(clamp(x_mu, 0.0, 1.0), f32(TRANSMITTANCE_W));
    let v = texcoord_from_unit(clamp(rho / big_h, 0.0, 1.0), f32(TRANSMITTANCE_H));
    let k = taps(u, v, TRANSMITTANCE_W, TRANSMITTANCE_H);
    let w = TRANSMITTANCE_W;
    let a = mix(transmittance_table_at(k.j0 * w + k.i0), transmittance_table_at(k.j0 * w + k.i1), k.f.x);
    let b = mix(transmittance_table_at(k.j1 * w + k.i0), transmittance_table_at(k.j1 * w + k.i1), k.f.x);
    return mix(a, b, k.f.y);
}

fn unit_from_texcoord(u: f32, n: f32) -> f32 {
    return (u - 0.5 / n) / (1.0 - 1.0 / n);
}

fn vertex_out(p: vec3<f32>, mp: MeshPoint, seam: f32) -> VertexOut {
    let h = mp.h;
    let r = frame.radius + h;
    let rel = vec3<f32>(r * p.x, r * p.y, h - frame.cam_height - r * p.z);
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(rel, 1.0);
    out.height = h;
    out.level = mp.l;
    out.p = p;
    out.seam = seam;
    out.lvl = f32(mp.l) + mp.depth;
    out.rel = rel;
    return out;
}

fn view_direction(uv: vec2<f32>) -> vec3<f32> {
    let p = atmo.inv_view_proj * vec4<f32>(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 1.0, 1.0);
    return normalize(p.xyz / p.w);
}

fn warp_point(k: u32) -> vec4<f32> {
    let w = warp.x + 1u;
    let ring = warp_lines[k / w];
    let col = warp_lines[warp.y + 1u + k % w];
    return vec4<f32>(ring.x * col.x, ring.x * col.y, ring.y, col.z);
}

fn window_inside(k: u32, off: vec2<f32>, color: bool) -> f32 {
    var t = texel_of(k, off);
    var size = vec2<f32>(levels[k].size);
    var open = 0u;
    if (color) {
        t = color_texel_of(k, off);
        size = vec2<f32>(levels[k].color_size);
        open = levels[k].color_open;
    }
    let far = 1000000000.0;
    let ex = select(min(t.x, size.x - t.x), far, (open & OPEN_ROUND) != 0u);
    let top = select(t.y, far, (open & OPEN_NORTH) != 0u);
    let bottom = select(size.y - t.y, far, (open & OPEN_SOUTH) != 0u);
    let edge = min(ex, min(top, bottom));
    return clamp((edge - 4.0) / 16.0, 0.0, 1.0);
}

fn wrap_lon(d: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(d.x - TAU * round(d.x / TAU), d.y);
}

struct Atmosphere {
    rayleigh: vec4<f32>,
    mie_scattering: vec4<f32>,
    mie_extinction: vec4<f32>,
    ozone: vec4<f32>,
    albedo: vec4<f32>,
    radii: vec4<f32>
}

struct AtmosphereFrame {
    inv_view_proj: mat4x4<f32>,
    sun: vec4<f32>,
    camera: vec4<f32>,
    screen: vec4<f32>,
    space: vec4<f32>
}

struct Entry {
    t: f32,
    r: f32,
    h: f32,
    mu: f32,
    mu_s: f32
}

struct Footprint {
    minor: f32,
    major: f32,
    axis: vec2<f32>
}

struct Frame {
    sin_v: f32,
    cos_v: f32,
    colat: f32,
    orient: f32,
    cam_height: f32,
    radius: f32,
    level_hi: u32,
    level_lo: u32,
    has_color: u32,
    flags: u32,
    exaggeration: f32,
    _p: u32,
    view_proj: mat4x4<f32>,
    sun: vec4<f32>
}

struct Level {
    viewer_texel: vec2<f32>,
    texels_per_rad: vec2<f32>,
    size: vec2<u32>,
    origin: vec2<u32>,
    fade: f32,
    color_open: u32,
    color_viewer_texel: vec2<f32>,
    color_texels_per_rad: vec2<f32>,
    color_size: vec2<u32>,
    color_origin: vec2<u32>,
    pad: vec2<u32>
}

struct MeshPoint {
    h: f32,
    l: u32,
    depth: f32
}

struct RingPoint {
    level: u32,
    depth: f32
}

struct Scatter {
    radiance: vec3<f32>,
    transmittance: vec3<f32>
}

struct SkyOut {
    @builtin(position)
    clip: vec4<f32>
}

struct Taps {
    i0: u32,
    i1: u32,
    j0: u32,
    j1: u32,
    f: vec2<f32>
}

struct VertexIn {
    @location(0)
    column: vec4<f32>,
    @location(1)
    outer: vec3<f32>,
    @location(2)
    inner: vec3<f32>,
    @location(3)
    rings: vec2<u32>
}

struct VertexOut {
    @builtin(position)
    clip: vec4<f32>,
    @location(0)
    height: f32,
    @location(1) @interpolate(flat)
    level: u32,
    @location(3)
    lvl: f32,
    @location(2)
    p: vec3<f32>,
    @location(4)
    seam: f32,
    @location(6)
    rel: vec3<f32>
}

struct ViewerConsts {
    sin_v: f32,
    cos_v: f32,
    colat: f32,
    orient: f32
}
