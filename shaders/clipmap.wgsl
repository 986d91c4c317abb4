// Spherical clipmaps: vertex stage maps the static hemisphere around the viewer onto the height
// clipmap and displaces it; fragment stage colours it, and with the atmosphere seen through the
// aerial-perspective volume; the sky pass fills what the terrain left. Everything here is
// relative to the viewer: absolute positions live on the CPU in f64. The renderer prepends
// map_transform.wgsl (the map transform) and atmosphere_model.wgsl (the atmosphere's reads).

struct Frame {
    // map transform
    sin_v: f32,
    cos_v: f32,
    colat: f32,
    orient: f32,
    // camera: height above the sphere under the viewer, sphere radius (metres)
    cam_height: f32,
    radius: f32,
    // the finest level drawn this frame: vertices of finer rings (the fill disc) sample it
    level_hi: u32,
    // the coarsest level drawn (nothing coarser to blend into)
    level_lo: u32,
    // 1 when the colour clipmap holds data
    has_color: u32,
    // bit 0 tints each level (debug view); bit 1: unlit, colour exactly as stored
    flags: u32,
    // vertical scale of the heights
    exaggeration: f32,
    _p: u32,
    // view-space (viewer at the north pole, metres, relative to the camera) to clip space
    view_proj: mat4x4<f32>,
    // towards the sun, view space (fixed in the world: the CPU turns it with the viewer)
    sun: vec4<f32>,
};

// One clipmap level: where the viewer sits in it (texel coordinates, fractional) and how many
// texels per radian of longitude / colatitude it has.
struct Level {
    viewer_texel: vec2<f32>,
    texels_per_rad: vec2<f32>,
    // texture size for toroidal addressing, and the world texel of the texture's origin modulo it
    size: vec2<u32>,
    origin: vec2<u32>,
    // 0 … 1: how far the level has faded in since it was first drawn (over the coarser one)
    fade: f32,
    // sides of the colour window that are no edge: 1 round the whole circle, 2 its first row at
    // the north pole, 4 its last at the south pole
    color_open: u32,
    // the colour window: as above, twice the texels at half the size; a window round the whole
    // circle is 2N × N/2, its columns laid out in two strips one below the other (`color_at`)
    color_viewer_texel: vec2<f32>,
    color_texels_per_rad: vec2<f32>,
    color_size: vec2<u32>,
    color_origin: vec2<u32>,
    // to the 16-byte stride of a uniform array
    pad: vec2<u32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> levels: array<Level, MAX_RING + 1u>;
@group(0) @binding(2) var heights: texture_2d_array<f32>;
@group(0) @binding(3) var colors: texture_2d_array<f32>;

// the atmosphere's tables (group 1) and their reads: air_tables.wgsl, which comes first

struct VertexIn {
    @location(0) pxy: vec2<f32>,
    @location(1) one_minus_cos: f32,
    @location(2) seam: f32,
    @location(3) level: u32,
    // 0 on the level's outer ring … 1 at its inner edge
    @location(4) depth: f32,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) height: f32,
    @location(1) @interpolate(flat) level: u32,
    // the continuous level coordinate (level + depth in it): the fragment picks its clipmap
    // level and blend from it, the same on both sides of a level border
    @location(3) lvl: f32,
    // the point of the unit sphere (sin θ̃ cos ψ, sin θ̃ sin ψ, 1 − cos θ̃) and its seam flag:
    // interpolated, they give the fragment's own point, whose map offsets the fragment works
    // out itself (offsets interpolated across a triangle bend features near a pole, where
    // longitude is far from linear over a triangle)
    @location(2) p: vec3<f32>,
    @location(4) seam: f32,
    // the point, view space relative to the camera, metres
    @location(6) rel: vec3<f32>,
};

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

fn texel_of(l: u32, off: vec2<f32>) -> vec2<f32> {
    let lv = levels[l];
    return lv.viewer_texel + off * lv.texels_per_rad;
}

// Towards its outer edge a level blends into the next coarser one, so that the rings shared by
// two levels have the same height from both sides and detail fades in without popping.
fn blend_of(l: u32, depth: f32) -> f32 {
    if (l <= frame.level_lo) {
        return 1.0;
    }
    return smoothstep(0.0, 0.5, depth);
}

// A mesh point's height and the level it reads: ring level `level`, `depth` within it (0 on
// its outer ring … 1 at its inner edge), map offsets `off` from the viewer.
struct MeshPoint {
    h: f32,
    l: u32,
    depth: f32,
};

fn mesh_height(level: u32, depth_in: f32, off: vec2<f32>) -> MeshPoint {
    let l = min(level, frame.level_hi);
    let depth = select(depth_in, 1.0, level > frame.level_hi);
    // the mesh carries the heights of the next coarser level (its texels are about as far apart
    // as the ring's vertices; the level's own texels, twice as fine, go into the shading), with
    // that level's blend into the one coarser still towards the ring's outer edge
    let lv = max(l, frame.level_lo + 1u) - 1u;
    // a ring drawn for the first time fades in from the heights the coarser level gave it
    let a = select(blend_of(l, depth) * levels[l].fade, 1.0, lv <= frame.level_lo);
    var h = height_at(lv, texel_of(lv, off));
    if (a < 1.0) {
        h = mix(height_at(lv - 1u, texel_of(lv - 1u, off)), h, a);
    }
    return MeshPoint(h * frame.exaggeration, l, depth);
}

// The clipmap ring level of the sphere point with 1 − cos θ̃ = `one_minus_cos` (level i spans θ̃
// from π/2·2^−i in to π/2·2^−(i+1)) and how deep in it the point lies, not coarser than the
// coarsest level drawn: where the meshes that are not the hemisphere's (CDLOD's, the warped
// one) take their heights, a function of the point alone.
struct RingPoint {
    level: u32,
    depth: f32,
};

fn ring_of(one_minus_cos: f32) -> RingPoint {
    let theta = 2.0 * asin(sqrt(0.5 * one_minus_cos));
    let lam = log2(1.5707964 / max(theta, 1e-30));
    let ring = clamp(floor(lam), 0.0, f32(MAX_RING));
    if (u32(ring) < frame.level_lo) {
        return RingPoint(frame.level_lo, 0.0);
    }
    return RingPoint(u32(ring), clamp(lam - ring, 0.0, 1.0));
}

// The vertex stage's output for the point of the sphere with attributes `p` (sin θ̃ cos ψ,
// sin θ̃ sin ψ, 1 − cos θ̃), its height and level `mp`, the seam flag its fragments' map
// offsets take (see `map_offsets`).
fn vertex_out(p: vec3<f32>, mp: MeshPoint, seam: f32) -> VertexOut {
    let h = mp.h;
    // view space relative to the camera: (R + h)·p̃ − (0, 0, R + h_cam), with
    // (R + h)(1 − c) − R − h_cam = h − h_cam − (R + h)·c (no large cancellation)
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

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let view = ViewerConsts(frame.sin_v, frame.cos_v, frame.colat, frame.orient);
    let off = map_offsets(view, v.pxy.x, v.pxy.y, v.one_minus_cos, v.seam);
    let mp = mesh_height(v.level, v.depth, off);
    return vertex_out(vec3<f32>(v.pxy, v.one_minus_cos), mp, v.seam);
}

// The colour window's fractional texel of level l at map offsets `off`.
fn color_texel_of(l: u32, off: vec2<f32>) -> vec2<f32> {
    let lv = levels[l];
    return lv.color_viewer_texel + off * lv.color_texels_per_rad;
}

// Colour at fractional texel t of level l's colour window: bilinear in linear light. A window
// wider than high lies in strips of its columns, each as wide as the texture, one below the other
// (sc_view_plan's `Placement::texture_regions`).
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

// The height gradient at fractional texel t of level l, metres per radian of (Δφ, Δθ): central
// differences over one texel.
fn slope_at(l: u32, t: vec2<f32>) -> vec2<f32> {
    let dx = height_at(l, t + vec2<f32>(1.0, 0.0)) - height_at(l, t - vec2<f32>(1.0, 0.0));
    let dy = height_at(l, t + vec2<f32>(0.0, 1.0)) - height_at(l, t - vec2<f32>(0.0, 1.0));
    return 0.5 * frame.exaggeration * vec2<f32>(dx, dy) * levels[l].texels_per_rad;
}

// The surface normal in view space from the height gradient (metres per radian of Δφ, Δθ) at the
// point of the sphere in direction `up` (view space), height h. Worked in the viewer's frame
// mirrored to the nearer pole (map_transform.wgsl): that pole lies at P = (−sin θv, 0, cos θv),
// ∂u/∂φ = P × u and sin θ'·∂u/∂θ = orient·((u·P)u − P), θ' the angle from P.
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
    // the tangent gradient: ∂h/∂(south)·ŝ + ∂h/∂(east)·ê, with ŝ = sc/sin θ', ê = e/sin θ'
    let g = (slope.y * sc * sqrt(s2) + slope.x * e) / ((frame.radius + h) * s2);
    let n = normalize(u - g);
    return vec3<f32>(n.x, o * n.y, n.z);
}

// A colour per level for the level view.
fn level_tint(l: u32) -> vec3<f32> {
    let k = f32(l % 6u);
    return vec3<f32>(0.5 + 0.5 * cos(1.05 * k), 0.5 + 0.5 * cos(1.05 * k + 2.1), 0.5 + 0.5 * cos(1.05 * k + 4.2));
}

// Most colour samples a fragment takes along its footprint's longer axis.
const MAX_ANISO: f32 = 4.0;

// A pixel's footprint in the map: the screen derivatives of the map offsets, measured in a
// window's colatitude texels (`tpr`: its texels per radian; a longitude texel counted at its
// ground size, sin θ of its angle): its shorter axis `minor` (texels) and its longer axis
// `axis` (map offsets) with length `major`.
struct Footprint {
    minor: f32,
    major: f32,
    axis: vec2<f32>,
};

fn footprint(tpr: vec2<f32>, off: vec2<f32>, doff_x: vec2<f32>, doff_y: vec2<f32>) -> Footprint {
    let s = abs(sin(frame.colat + frame.orient * off.y));
    let k = vec2<f32>(tpr.y * s, tpr.y);
    let ax = length(doff_x * k);
    let ay = length(doff_y * k);
    return Footprint(min(ax, ay), max(ax, ay), select(doff_y, doff_x, ax >= ay));
}

// How many colour samples a footprint takes along its longer axis (anisotropic filtering): as
// many as the axes' ratio, at most MAX_ANISO; each covers major/n of it.
fn aniso_taps(fp: Footprint) -> f32 {
    return clamp(ceil(fp.major / max(fp.minor, 1e-12)), 1.0, MAX_ANISO);
}

// Levels finer than one texel a pixel that a footprint takes (up to 2^LOD_BIAS texels a pixel):
// against the twin's box over the pixel at 8 × 8 rays, 0.5 matches its sharpness (1.00) where 1
// was sharper (1.06) and 0.75 between.
const LOD_BIAS: f32 = 0.5;

// The continuous clipmap level at which one texel covers about one pixel here: the ring's level
// `l` less log2 of the footprint `rho` in l's colatitude texels (the longer axis over the
// samples taken along it), plus LOD_BIAS, within `cap` and the levels drawn. Across a ring
// border both sides agree: l's texels are half l−1's.
fn lod_level(l: u32, cap: f32, rho: f32) -> f32 {
    let fine = f32(l) + LOD_BIAS - log2(max(rho, 1e-6));
    return clamp(min(cap, fine), f32(frame.level_lo), f32(frame.level_hi));
}

// The colour at map offsets `off` from continuous level `lc`: trilinear between two clipmap
// levels.
fn color_trilinear(lc: f32, off: vec2<f32>) -> vec4<f32> {
    let l0 = u32(floor(lc));
    let f1 = lc - floor(lc);
    var c = color_at(l0, color_texel_of(l0, off));
    if (f1 > 0.0 && l0 < frame.level_hi) {
        c = mix(c, color_at(l0 + 1u, color_texel_of(l0 + 1u, off)), f1);
    }
    return c;
}

// How far inside level k's window (its colour window with `color`, else its heights') map
// offsets `off` lie: 0 within 4 texels of an edge, fading in to 1 over the next 16; sides that
// are no edge (a round colour window's longitude sides, its rows at a pole) do not count.
fn window_inside(k: u32, off: vec2<f32>, color: bool) -> f32 {
    var t = texel_of(k, off);
    var size = vec2<f32>(levels[k].size);
    var open = 0u;
    if (color) {
        t = color_texel_of(k, off);
        size = vec2<f32>(levels[k].color_size);
        open = levels[k].color_open;
    }
    let far = 1e9;
    let ex = select(min(t.x, size.x - t.x), far, (open & OPEN_ROUND) != 0u);
    let top = select(t.y, far, (open & OPEN_NORTH) != 0u);
    let bottom = select(size.y - t.y, far, (open & OPEN_SOUTH) != 0u);
    let edge = min(ex, min(top, bottom));
    return clamp((edge - 4.0) / 16.0, 0.0, 1.0);
}

// The finest continuous level whose data a fragment of ring `l` (continuous ring level `ring`)
// may show: the ring's own, or up to two finer levels where their windows reach the fragment
// (a ring's points east and west of the viewer often lie in the next finer window, whose
// longitude span is rounded up), fading in over 16 texels inside a window's edge — the colour
// windows (`color`) or the heights'; each level capped by how far it has faded in since it was
// first drawn.
fn level_cap(l: u32, ring: f32, off: vec2<f32>, color: bool) -> f32 {
    var cap = min(ring, f32(l) - 1.0 + levels[l].fade);
    // a round colour window covers half a square one's colatitude: beyond it, the next coarser
    // level's (which covers the ring)
    if (color && (levels[l].color_open & OPEN_ROUND) != 0u && l > frame.level_lo) {
        cap = min(cap, f32(l) - 1.0 + window_inside(l, off, true));
    }
    // level k only where k − 1 is wholly available
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

// The lit terrain seen through the air: sunlight reaching the point (reddened, none in the
// planet's shadow) and the sky's irradiance there (the table), then the
// aerial perspective between camera and point (the volume, or next to the limb seen from above
// the air the pixel's own march); tone-mapped.
fn terrain_in_air(frag: vec2<f32>, rel: vec3<f32>, albedo: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let p = rel * 1e-3;
    let t = length(p);
    let d = p / t;
    let r_c = atmo.camera.x;
    let q = p + vec3<f32>(0.0, 0.0, r_c);
    let r = length(q);
    let s = sun_dir();
    let mu_s = dot(q / r, s);
    // light as at the sea-level sphere for ground under it (a coarse mesh's chords, the sea
    // floor): from below the sphere the tables would read a longer path through the ground;
    // the sky's share a tilted surface sees, (1 + n·up)/2
    let r_lit = max(r, atm.radii.x);
    let sky = irradiance_at(r_lit, mu_s) * 0.5 * (1.0 + dot(n, q / r));
    let lit = albedo * (sunlight(r_lit, mu_s) * max(dot(n, s), 0.0) + sky);
    let e = enter(d, s);
    // no air below the sea-level sphere: terrain under it (the sea floor, or a coarse mesh's
    // chord) is seen through the air down to the sphere
    var s_air = t - max(e.t, 0.0);
    let g = ground_distance(e.r, e.h, e.mu);
    if (g >= 0.0) {
        s_air = min(s_air, g);
    }
    let path = column_path(e);
    var ap = aerial_at(frag / atmo.screen.xy, s_air, path);
    // from above the air, within a froxel row of the limb a column's path changes faster than
    // the volume's columns resolve: the pixel marches its own ray there, blended into the
    // volume over one more
    let below = asin(min(atm.radii.x / r_c, 1.0)) - acos(clamp(-d.z, -1.0, 1.0));
    let band = atmo.space.w;
    let own = select(0.0, 1.0 - smoothstep(band, 2.0 * band, below), above_air());
    if (own > 0.0 && e.t >= 0.0) {
        let m = sky_along(e.r, e.h, e.mu, e.mu_s, dot(d, s), s_air, false);
        ap = Scatter(mix(ap.radiance, m.radiance, own), mix(ap.transmittance, m.transmittance, own));
    }
    return tone_map(lit * ap.transmittance + ap.radiance * atmo.sun.w);
}

// A difference of map offsets with its longitude part in (−π, π].
fn wrap_lon(d: vec2<f32>) -> vec2<f32> {
    return vec2<f32>(d.x - TAU * round(d.x / TAU), d.y);
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    // the fragment's map offsets from its own point; derivatives first, in uniform control flow
    let view = ViewerConsts(frame.sin_v, frame.cos_v, frame.colat, frame.orient);
    let off = map_offsets(view, in.p.x, in.p.y, in.p.z, in.seam);
    // a 2 × 2 quad next to the seam meridian may reach across it (near the viewer triangles are
    // thin wedges): longitude differences are taken the short way round
    let doff_x = wrap_lon(dpdx(off));
    let doff_y = wrap_lon(dpdy(off));
    var albedo: vec3<f32>;
    let t = clamp(in.height / (6000.0 * frame.exaggeration), -1.0, 1.0);
    let land = vec3<f32>(0.12 + 0.5 * t, 0.25 + 0.35 * t, 0.05 + 0.6 * t);
    let sea = vec3<f32>(0.02, 0.06 + 0.05 * (1.0 + t), 0.3);
    albedo = select(land, sea, t < 0.0);
    // the fragment's level and its blend into the next coarser one, as in the vertex stage
    let lf = clamp(floor(in.lvl), f32(frame.level_lo), f32(frame.level_hi));
    let l = u32(lf);
    let a = blend_of(l, in.lvl - lf);
    // the texture level by the pixel's footprint, trilinear between two clipmap levels; a level
    // drawn for the first time fades in over the coarser one (`level_cap`). Normals from the
    // height clipmap at the level whose texels match the pixel:
    let ring = select(lf, lf - 1.0 + a, l > frame.level_lo);
    let cap = level_cap(l, ring, off, false);
    let lc = lod_level(l, cap, footprint(levels[l].texels_per_rad, off, doff_x, doff_y).major);
    let l0 = u32(floor(lc));
    let f1 = lc - floor(lc);
    if (frame.has_color == 1u) {
        let fp = footprint(levels[l].color_texels_per_rad, off, doff_x, doff_y);
        let taps = aniso_taps(fp);
        // anisotropic: samples spread along the longer axis, each from the level whose texels
        // match its share of it (the shorter axis); where that level is not at hand (capped),
        // only as many as the level's texels fill the axis with (more would only blur)
        let la = lod_level(l, level_cap(l, ring, off, true), fp.major / taps);
        var n = clamp(ceil(fp.major / exp2(f32(l) + LOD_BIAS - la)), 1.0, taps);
        var axis = fp.axis;
        // a round window's longitude texels are finer than its colatitude ones near the pole
        // (2π/2N at every level): as many samples as the pixel covers of them, along its axis
        // that crosses the most
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
    // smooth normals from the height clipmap (blended between levels like the heights)
    var slope = slope_at(l0, texel_of(l0, off));
    if (f1 > 0.0 && l0 < frame.level_hi) {
        slope = mix(slope, slope_at(l0 + 1u, texel_of(l0 + 1u, off)), f1);
    }
    // the local up direction (view space)
    let up = vec3<f32>(in.p.x, in.p.y, 1.0 - in.p.z);
    let n = surface_normal(up, slope, in.height);
    let sun = normalize(frame.sun.xyz);
    // Lambert under a sun fixed in the world, a little sky light; the night side is dark
    // (the sky light fades out with the sun's elevation over the sphere there)
    let day = smoothstep(-0.1, 0.1, dot(normalize(up), sun));
    let light = 0.04 + 0.16 * day + 0.8 * max(dot(n, sun), 0.0);
    if (atmo.camera.w == 0.0) {
        return vec4<f32>(albedo * light, 1.0);
    }
    return vec4<f32>(terrain_in_air(in.clip.xy, in.rel, albedo, n), 1.0);
}

struct SkyOut {
    @builtin(position) clip: vec4<f32>,
};

// A triangle over the whole screen at the far plane (depth 0, reversed Z): drawn where the
// terrain left the depth cleared.
@vertex
fn sky_vs(@builtin(vertex_index) i: u32) -> SkyOut {
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - vec2<f32>(1.0);
    var out: SkyOut;
    out.clip = vec4<f32>(xy, 0.0, 1.0);
    return out;
}

// The sky towards a pixel: from inside the atmosphere the sky-view table, from outside a march
// from where the ray enters it; the sun's disc seen through it; space behind (the twins:
// SkyViewLut::sample, Atmosphere::sky).
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
    } else {
        let e = enter(d, s);
        if (e.t >= 0.0) {
            let sc = sky_along(e.r, e.h, e.mu, e.mu_s, nu, 1e30, true);
            l = sc.radiance;
            through = select(sc.transmittance, vec3<f32>(0.0), hits_ground(e.r, e.mu));
        }
    }
    // the disc: the sun's radiance (illuminance over its solid angle) where it shows
    let alpha2 = 2.0 * (1.0 - atmo.screen.z);
    let disc = select(0.0, atmo.sun.w / (PI * alpha2), nu > atmo.screen.z);
    let c = tone_map(l * atmo.sun.w + through * disc) + atmo.space.xyz * through;
    return vec4<f32>(c, 1.0);
}
