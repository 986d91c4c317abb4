// The atmosphere's model and table reads, shared by the table passes (atmosphere.wgsl) and the
// renderer (clipmap.wgsl). Lengths in kilometres, coefficients per kilometre. The module that
// includes this file declares the tables it reads: `atm`, `atmo`, `transmittance_table`,
// `multiple_scattering_table`, `sky_view_table`, `aerial_inscatter`, `aerial_transmittance`,
// `irradiance_table`.
// The CPU twins: sc_view_space::atmosphere.

struct Atmosphere {
    // xyz: Rayleigh scattering, w: its scale height
    rayleigh: vec4<f32>,
    // xyz: Mie scattering, w: its scale height
    mie_scattering: vec4<f32>,
    // xyz: Mie extinction, w: phase asymmetry g
    mie_extinction: vec4<f32>,
    // xyz: ozone absorption at the peak, w: the peak's altitude
    ozone: vec4<f32>,
    // xyz: ground albedo, w: the ozone tent's width
    albedo: vec4<f32>,
    // x: bottom radius, y: top radius, z: steps along a transmittance ray
    radii: vec4<f32>,
}

// One frame's viewer (the twin: AtmosphereFrame). View space: camera at the origin, local up +z,
// the planet's centre at (0, 0, −camera.x).
struct AtmosphereFrame {
    inv_view_proj: mat4x4<f32>,
    // xyz: towards the sun, w: its illuminance
    sun: vec4<f32>,
    // x: camera radius, y: range of the aerial-perspective slices, z: exposure, w: 1 when drawn
    camera: vec4<f32>,
    // xy: target size in pixels, z: cosine of the sun's angular radius, w: the camera's altitude
    screen: vec4<f32>,
    // xyz: the colour of space, w: the angle a froxel row spans (radians)
    space: vec4<f32>,
}

// the tables' sizes and sampling: shaders/constants.wgsl, generated from the Rust twins
const PI: f32 = 3.14159265358979;

fn extinction_at(h_in: f32) -> vec3<f32> {
    let h = max(h_in, 0.0);
    let rayleigh = exp(-h / atm.rayleigh.w);
    let mie = exp(-h / atm.mie_scattering.w);
    let ozone = max(0.0, 1.0 - abs(h - atm.ozone.w) / (0.5 * atm.albedo.w));
    return atm.rayleigh.xyz * rayleigh + atm.mie_extinction.xyz * mie + atm.ozone.xyz * ozone;
}

fn distance_to_top(r: f32, mu: f32) -> f32 {
    let top = atm.radii.y;
    let disc = r * r * (mu * mu - 1.0) + top * top;
    return max(0.0, -r * mu + sqrt(max(disc, 0.0)));
}

fn distance_to_bottom(r: f32, mu: f32) -> f32 {
    let bottom = atm.radii.x;
    let disc = r * r * (mu * mu - 1.0) + bottom * bottom;
    return max(0.0, -r * mu - sqrt(max(disc, 0.0)));
}

fn hits_ground(r: f32, mu: f32) -> bool {
    let bottom = atm.radii.x;
    return mu < 0.0 && r * r * (mu * mu - 1.0) + bottom * bottom >= 0.0;
}

// Distance from altitude h (radius r) along cosine mu to the ground, or −1 when the ray misses
// it: the same as hits_ground and distance_to_bottom, written in h so that a camera a metre
// above the ground keeps its height (r in f32 kilometres rounds to half a metre).
fn ground_distance(r: f32, h: f32, mu: f32) -> f32 {
    let bottom = atm.radii.x;
    let disc = r * r * mu * mu - h * (2.0 * bottom + h);
    if mu >= 0.0 || disc < 0.0 {
        return -1.0;
    }
    return max(0.0, h * (2.0 * bottom + h) / (-r * mu + sqrt(disc)));
}

fn unit_from_texcoord(u: f32, n: f32) -> f32 {
    return (u - 0.5 / n) / (1.0 - 1.0 / n);
}

fn texcoord_from_unit(x: f32, n: f32) -> f32 {
    return 0.5 / n + x * (1.0 - 1.0 / n);
}

// The four texels a bilinear read of a w × h table at (u, v) in 0..1 takes, between texel
// centres and clamped at the edges like a sampler (the twin: `bilinear`), and the weights.
struct Taps {
    i0: u32,
    i1: u32,
    j0: u32,
    j1: u32,
    f: vec2<f32>,
}

fn taps(u: f32, v: f32, w: u32, h: u32) -> Taps {
    let x = clamp(u * f32(w) - 0.5, 0.0, f32(w) - 1.0);
    let y = clamp(v * f32(h) - 0.5, 0.0, f32(h) - 1.0);
    let i0 = u32(floor(x));
    let j0 = u32(floor(y));
    return Taps(i0, min(i0 + 1u, w - 1u), j0, min(j0 + 1u, h - 1u), vec2<f32>(x - f32(i0), y - f32(j0)));
}

// The transmittance table at the ray (r, mu), bilinear between texel centres like a sampler
// (and like the CPU twin's `sample`).
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

// Sunlight reaching radius r with the sun at cosine mu_s: none where the planet is in the way.
fn sunlight(r: f32, mu_s: f32) -> vec3<f32> {
    if hits_ground(r, mu_s) {
        return vec3<f32>(0.0);
    }
    return transmittance_to_top(r, mu_s);
}

fn scattering_at(h_in: f32) -> vec3<f32> {
    let h = max(h_in, 0.0);
    return atm.rayleigh.xyz * exp(-h / atm.rayleigh.w) + atm.mie_scattering.xyz * exp(-h / atm.mie_scattering.w);
}

// Ψ from the multiple-scattering table, bilinear between texel centres (the twin's `sample`).
fn multiple_scattering_at(r: f32, mu_s: f32) -> vec3<f32> {
    let k = taps((mu_s + 1.0) / 2.0, (r - atm.radii.x) / (atm.radii.y - atm.radii.x), MS_SIZE, MS_SIZE);
    let n = MS_SIZE;
    let a = mix(multiple_scattering_table_at(k.j0 * n + k.i0), multiple_scattering_table_at(k.j0 * n + k.i1), k.f.x);
    let b = mix(multiple_scattering_table_at(k.j1 * n + k.i0), multiple_scattering_table_at(k.j1 * n + k.i1), k.f.x);
    return mix(a, b, k.f.y);
}

// The sky's irradiance on a horizontal surface at radius r, the sun at mu_s (the twin:
// `IrradianceLut::sample`).
fn irradiance_at(r: f32, mu_s: f32) -> vec3<f32> {
    let k = taps((mu_s + 1.0) / 2.0, (r - atm.radii.x) / (atm.radii.y - atm.radii.x), IRRADIANCE_W, IRRADIANCE_H);
    let w = IRRADIANCE_W;
    let a = mix(irradiance_table_at(k.j0 * w + k.i0), irradiance_table_at(k.j0 * w + k.i1), k.f.x);
    let b = mix(irradiance_table_at(k.j1 * w + k.i0), irradiance_table_at(k.j1 * w + k.i1), k.f.x);
    return mix(a, b, k.f.y);
}

fn rayleigh_phase(nu: f32) -> f32 {
    return 3.0 / (16.0 * PI) * (1.0 + nu * nu);
}

fn mie_phase(g: f32, nu: f32) -> f32 {
    let k = 3.0 / (8.0 * PI) * (1.0 - g * g) / (2.0 + g * g);
    return k * (1.0 + nu * nu) / pow(1.0 + g * g - 2.0 * g * nu, 1.5);
}

struct Scatter {
    radiance: vec3<f32>,
    transmittance: vec3<f32>,
}

// The light scattered towards a viewer at radius r (altitude h) looking along cosine mu, the sun
// at mu_s and nu the cosine between view and sun, up to max_d or where the ray leaves the
// atmosphere or (with stop_at_ground) meets the ground, and the transmittance along it (the
// twin: `Atmosphere::sky_segment`).
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

// Where the view ray along d (view space) from the camera enters the atmosphere, with the sun
// towards s: the distance t (0 inside, −1 when it passes outside) and the ray there, r, its
// altitude h, mu and mu_s. From outside the ray's distance from the centre comes from d's
// horizontal part, not from 1 − mu² (which f32 loses for a camera far away), and the entry's mu
// from the same root (the twin: `Atmosphere::enter`).
struct Entry {
    t: f32,
    r: f32,
    h: f32,
    mu: f32,
    mu_s: f32,
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

// The unit view-space direction through the screen point uv (0..1, v down).
fn view_direction(uv: vec2<f32>) -> vec3<f32> {
    let p = atmo.inv_view_proj * vec4<f32>(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 1.0, 1.0);
    return normalize(p.xyz / p.w);
}

fn sun_dir() -> vec3<f32> {
    return normalize(atmo.sun.xyz);
}

// Whether the camera is above the air: then the volume's slices divide each column's own path.
fn above_air() -> bool {
    return atmo.camera.x > atm.radii.y;
}

// The path a column's slices divide for a camera above the air: from where its ray enters the
// air to the ground, or through the shell when it misses the ground (the twin: `column_path`).
fn column_path(e: Entry) -> f32 {
    let g = ground_distance(e.r, e.h, e.mu);
    return select(distance_to_top(e.r, e.mu), g, g >= 0.0);
}

// End of aerial-perspective slice k, kilometres beyond where the ray enters the air: from inside
// the air quadratic in the frame's range (short slices near the camera); from above it a share
// of the column's path, quadratic towards its end (short slices near the ground, where the air
// is) (the twin: `AtmosphereFrame::slice_end_m`).
fn slice_end(k: u32, path: f32) -> f32 {
    let x = (f32(k) + 1.0) / f32(AERIAL);
    if above_air() {
        return path * (1.0 - (1.0 - x) * (1.0 - x));
    }
    return atmo.camera.y * x * x;
}

// The continuous slice index of a point s beyond the entry (slice k ends at index k).
fn slice_index(s: f32, path: f32) -> f32 {
    let n = f32(AERIAL);
    if above_air() {
        let f = clamp(s / max(path, 1e-6), 0.0, 1.0);
        return n * (1.0 - sqrt(1.0 - f)) - 1.0;
    }
    return n * sqrt(s / atmo.camera.y) - 1.0;
}

// The sky-view table in direction (mu, cos_az) of a viewer at radius r: bilinear between texel
// centres, clamped at the edges (the twin: `sky_view_ray_to_uv`, `SkyViewLut::sample`).
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
    } else {
        v = 0.5 * (1.0 + sqrt(max((zenith - zenith_horizon) / beta, 0.0)));
    }
    let k = taps(sqrt((1.0 - clamp(cos_az, -1.0, 1.0)) / 2.0), v, SKY_VIEW_W, SKY_VIEW_H);
    let w = SKY_VIEW_W;
    let a = mix(sky_view_table_at(k.j0 * w + k.i0), sky_view_table_at(k.j0 * w + k.i1), k.f.x);
    let b = mix(sky_view_table_at(k.j1 * w + k.i0), sky_view_table_at(k.j1 * w + k.i1), k.f.x);
    return mix(a, b, k.f.y);
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

// In-scattering and transmittance at screen point uv for a surface s km beyond where its ray
// enters the atmosphere (path: its column path, above the air): bilinear between froxel columns,
// linear between slices in their index, from nothing at the entry to the first slice (the twin:
// `AerialPerspectiveLut::sample`).
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
    } else {
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

// The tone curve (the twin: `tone_map`): radiance to linear display values.
fn tone_map(l: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(1.0) - exp(-atmo.camera.z * l);
}
