// Composed by wesl from shaders/atmosphere.wesl (features: tables_written): do not edit.
// `SPHERECLIP_BLESS=1 cargo test -p sc_view_gpu --test shaders composed` rewrites it.

@compute @workgroup_size(8, 8)
fn irradiance_lut(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= IRRADIANCE_W || id.y >= IRRADIANCE_H {
        return;
    }
    let bottom = atm.radii.x;
    let top = atm.radii.y;
    let mu_s = -1.0 + 2.0 * (f32(id.x) + 0.5) / f32(IRRADIANCE_W);
    let r = bottom + (f32(id.y) + 0.5) / f32(IRRADIANCE_H) * (top - bottom);
    let sin_s = sqrt(max(1.0 - mu_s * mu_s, 0.0));
    let n = IRRADIANCE_DIRECTIONS;
    var e = vec3<f32>(0.0);
    for (var a = 0u; a < n; a++) {
        let mu = (f32(a) + 0.5) / f32(n);
        let sin_v = sqrt(1.0 - mu * mu);
        for (var b = 0u; b < n; b++) {
            let phi = 2.0 * PI * (f32(b) + 0.5) / f32(n);
            let nu = mu * mu_s + sin_v * sin_s * cos(phi);
            let l = sky_along(r, r - bottom, mu, mu_s, nu, 1e30, true).radiance;
            e += l * mu * 2.0 * PI / f32(n * n);
        }
    }
    irradiance_table[id.y * IRRADIANCE_W + id.x] = vec4<f32>(e, 1.0);
}

@compute @workgroup_size(8, 8)
fn multiple_scattering_lut(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= MS_SIZE || id.y >= MS_SIZE {
        return;
    }
    let bottom = atm.radii.x;
    let top = atm.radii.y;
    let mu_s = -1.0 + 2.0 * (f32(id.x) + 0.5) / f32(MS_SIZE);
    let r = bottom + (f32(id.y) + 0.5) / f32(MS_SIZE) * (top - bottom);
    let iso = 1.0 / (4.0 * PI);
    let sun = vec3<f32>(sqrt(max(1.0 - mu_s * mu_s, 0.0)), 0.0, mu_s);
    let count = f32(MS_DIRECTIONS * MS_DIRECTIONS);
    var l2 = vec3<f32>(0.0);
    var f_ms = vec3<f32>(0.0);
    for (var a = 0u; a < MS_DIRECTIONS; a++) {
        for (var b = 0u; b < MS_DIRECTIONS; b++) {
            let cos_t = 1.0 - 2.0 * (f32(a) + 0.5) / f32(MS_DIRECTIONS);
            let sin_t = sqrt(max(1.0 - cos_t * cos_t, 0.0));
            let phi = 2.0 * PI * (f32(b) + 0.5) / f32(MS_DIRECTIONS);
            let dir = vec3<f32>(sin_t * cos(phi), sin_t * sin(phi), cos_t);
            let ground = hits_ground(r, cos_t);
            var d = distance_to_top(r, cos_t);
            if ground {
                d = distance_to_bottom(r, cos_t);
            }
            let dt = d / f32(MS_STEPS);
            var throughput = vec3<f32>(1.0);
            var lum = vec3<f32>(0.0);
            var fms = vec3<f32>(0.0);
            for (var k = 0u; k < MS_STEPS; k++) {
                let t = (f32(k) + 0.5) * dt;
                let p = vec3<f32>(dir.x * t, dir.y * t, r + dir.z * t);
                let rp = length(p);
                let up = p / rp;
                let mu_sp = dot(up, sun);
                let s = scattering_at(rp - bottom);
                let ext = extinction_at(rp - bottom);
                var t_sun = vec3<f32>(0.0);
                if !hits_ground(rp, mu_sp) {
                    t_sun = transmittance_to_top(rp, mu_sp);
                }
                let step_t = exp(-ext * dt);
                let integral = select(vec3<f32>(dt), (1.0 - step_t) / ext, ext > vec3<f32>(0.0));
                lum += throughput * s * t_sun * iso * integral;
                fms += throughput * s * integral;
                throughput *= step_t;
            }
            if ground {
                let p = vec3<f32>(dir.x * d, dir.y * d, r + dir.z * d);
                let up = normalize(p);
                let mu_sp = dot(up, sun);
                let t_sun = transmittance_to_top(length(p), mu_sp);
                lum += throughput * t_sun * max(mu_sp, 0.0) * atm.albedo.xyz / PI;
            }
            l2 += lum * iso * 4.0 * PI / count;
            f_ms += fms * iso * 4.0 * PI / count;
        }
    }
    multiple_scattering_table[id.y * MS_SIZE + id.x] = vec4<f32>(l2 / (1.0 - f_ms), 1.0);
}

@compute @workgroup_size(8, 8)
fn sky_view_lut(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= SKY_VIEW_W || id.y >= SKY_VIEW_H {
        return;
    }
    let bottom = atm.radii.x;
    let r = max(atmo.camera.x, bottom);
    let mu_s = sun_dir().z;
    let u = (f32(id.x) + 0.5) / f32(SKY_VIEW_W);
    let v = (f32(id.y) + 0.5) / f32(SKY_VIEW_H);
    let v_horizon = sqrt(max(r * r - bottom * bottom, 0.0));
    let beta = acos(clamp(v_horizon / r, -1.0, 1.0));
    let zenith_horizon = PI - beta;
    var zenith = 0.0;
    if v < 0.5 {
        let c = 1.0 - 2.0 * v;
        zenith = zenith_horizon * (1.0 - c * c);
    }
    else {
        let c = 2.0 * v - 1.0;
        zenith = zenith_horizon + beta * c * c;
    }
    let mu = cos(zenith);
    let cos_az = -(u * u * 2.0 - 1.0);
    let sin_v = sqrt(max(1.0 - mu * mu, 0.0));
    let sin_s = sqrt(max(1.0 - mu_s * mu_s, 0.0));
    let nu = clamp(mu * mu_s + sin_v * sin_s * cos_az, -1.0, 1.0);
    sky_view_table[id.y * SKY_VIEW_W + id.x] = vec4<f32>(sky_along(r, atmo.screen.w, mu, mu_s, nu, 1e30, true).radiance, 1.0);
}

@compute @workgroup_size(8, 8)
fn transmittance_lut(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= TRANSMITTANCE_W || id.y >= TRANSMITTANCE_H {
        return;
    }
    let bottom = atm.radii.x;
    let top = atm.radii.y;
    let x_mu = unit_from_texcoord((f32(id.x) + 0.5) / f32(TRANSMITTANCE_W), f32(TRANSMITTANCE_W));
    let x_r = unit_from_texcoord((f32(id.y) + 0.5) / f32(TRANSMITTANCE_H), f32(TRANSMITTANCE_H));
    let big_h = sqrt(top * top - bottom * bottom);
    let rho = big_h * x_r;
    let r = sqrt(rho * rho + bottom * bottom);
    let d_min = top - r;
    let d_max = rho + big_h;
    let d_ray = d_min + x_mu * (d_max - d_min);
    var mu = 1.0;
    if d_ray > 0.0 {
        mu = clamp((big_h * big_h - rho * rho - d_ray * d_ray) / (2.0 * r * d_ray), -1.0, 1.0);
    }
    let d = distance_to_top(r, mu);
    let n = u32(atm.radii.z);
    let dx = d / f32(n);
    var tau = vec3<f32>(0.0);
    for (var i = 0u; i <= n; i++) {
        let t = f32(i) * dx;
        let ri = sqrt(t * t + 2.0 * r * mu * t + r * r);
        var w = 1.0;
        if i == 0u || i == n {
            w = 0.5;
        }
        tau += extinction_at(ri - bottom) * (w * dx);
    }
    transmittance_table[id.y * TRANSMITTANCE_W + id.x] = vec4<f32>(exp(-tau), 1.0);
}

@compute @workgroup_size(8, 8, 1)
fn aerial_perspective_lut(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= AERIAL || id.y >= AERIAL || id.z >= AERIAL {
        return;
    }
    let uv = (vec2<f32>(id.xy) + vec2<f32>(0.5)) / f32(AERIAL);
    let d = view_direction(uv);
    let s = sun_dir();
    let e = enter(d, s);
    var l = vec3<f32>(0.0);
    var t = vec3<f32>(1.0);
    if e.t >= 0.0 {
        let sc = sky_along(e.r, e.h, e.mu, e.mu_s, dot(d, s), slice_end(id.z, column_path(e)), false);
        l = sc.radiance;
        t = sc.transmittance;
    }
    let at = (id.z * AERIAL + id.y) * AERIAL + id.x;
    aerial_inscatter[at] = vec4<f32>(l, 1.0);
    aerial_transmittance[at] = vec4<f32>(t, 1.0);
}

@group(0) @binding(0)
var<uniform> atm: Atmosphere;

@group(0) @binding(1)
var<storage, read_write> transmittance_table: array<vec4<f32>>;

@group(0) @binding(2)
var<storage, read_write> multiple_scattering_table: array<vec4<f32>>;

@group(0) @binding(3)
var<uniform> atmo: AtmosphereFrame;

@group(0) @binding(4)
var<storage, read_write> sky_view_table: array<vec4<f32>>;

@group(0) @binding(5)
var<storage, read_write> aerial_inscatter: array<vec4<f32>>;

@group(0) @binding(6)
var<storage, read_write> aerial_transmittance: array<vec4<f32>>;

@group(0) @binding(7)
var<storage, read_write> irradiance_table: array<vec4<f32>>;

const AERIAL: u32 = 32u;

const FLAG_LEVEL_COLORS: u32 = 1u;

const FLAG_UNLIT: u32 = 2u;

const IRRADIANCE_DIRECTIONS: u32 = 8u;

const IRRADIANCE_H: u32 = 16u;

const IRRADIANCE_W: u32 = 64u;

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

fn ground_distance(r: f32, h: f32, mu: f32) -> f32 {
    let bottom = atm.radii.x;
    let disc = r * r * mu * mu - h * (2.0 * bottom + h);
    if mu >= 0.0 || disc < 0.0 {
        return -1.0;
    }
    return max(0.0, h * (2.0 * bottom + h) / (-r * mu + sqrt(disc)));
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

fn sun_dir() -> vec3<f32> {
    return normalize(atmo.sun.xyz);
}

fn sunlight(r: f32, mu_s: f32) -> vec3<f32> {
    if hits_ground(r, mu_s) {
        return vec3<f32>(0.0);
    }
    return transmittance_to_top(r, mu_s);
}

fn taps(u: f32, v: f32, w: u32, h: u32) -> Taps {
    let x = clamp(u * f32(w) - 0.5, 0.0, f32(w) - 1.0);
    let y = clamp(v * f32(h) - 0.5, 0.0, f32(h) - 1.0);
    let i0 = u32(floor(x));
    let j0 = u32(floor(y));
    return Taps(i0, min(i0 + 1u, w - 1u), j0, min(j0 + 1u, h - 1u), vec2<f32>(x - f32(i0), y - f32(j0)));
}

fn texcoord_from_unit(x: f32, n: f32) -> f32 {
    return 0.5 / n + x * (1.0 - 1.0 / n);
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

fn view_direction(uv: vec2<f32>) -> vec3<f32> {
    let p = atmo.inv_view_proj * vec4<f32>(2.0 * uv.x - 1.0, 1.0 - 2.0 * uv.y, 1.0, 1.0);
    return normalize(p.xyz / p.w);
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

struct Scatter {
    radiance: vec3<f32>,
    transmittance: vec3<f32>
}

struct Taps {
    i0: u32,
    i1: u32,
    j0: u32,
    j1: u32,
    f: vec2<f32>
}
