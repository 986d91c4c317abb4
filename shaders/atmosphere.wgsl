// The atmosphere's lookup tables on the GPU (the CPU twins: sc_view_plan::atmosphere).
// Lengths in kilometres, coefficients per kilometre.

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

@group(0) @binding(0) var<uniform> atm: Atmosphere;
@group(0) @binding(1) var<storage, read_write> transmittance_out: array<vec4<f32>>;

const TRANSMITTANCE_W: u32 = 256u;
const TRANSMITTANCE_H: u32 = 64u;

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

fn unit_from_texcoord(u: f32, n: f32) -> f32 {
    return (u - 0.5 / n) / (1.0 - 1.0 / n);
}

// Each texel: the transmittance to the top of the atmosphere of its ray, by the trapezoidal rule.
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
    transmittance_out[id.y * TRANSMITTANCE_W + id.x] = vec4<f32>(exp(-tau), 1.0);
}

@group(0) @binding(2) var<storage, read_write> multiple_scattering_out: array<vec4<f32>>;

const MS_SIZE: u32 = 32u;
const MS_DIRECTIONS: u32 = 8u;
const MS_STEPS: u32 = 20u;
const PI: f32 = 3.14159265358979;

fn distance_to_bottom(r: f32, mu: f32) -> f32 {
    let bottom = atm.radii.x;
    let disc = r * r * (mu * mu - 1.0) + bottom * bottom;
    return max(0.0, -r * mu - sqrt(max(disc, 0.0)));
}

fn hits_ground(r: f32, mu: f32) -> bool {
    let bottom = atm.radii.x;
    return mu < 0.0 && r * r * (mu * mu - 1.0) + bottom * bottom >= 0.0;
}

fn texcoord_from_unit(x: f32, n: f32) -> f32 {
    return 0.5 / n + x * (1.0 - 1.0 / n);
}

// The transmittance table (as the transmittance pass wrote it) at the ray (r, mu), bilinear
// between texel centres like a sampler (and like the CPU twin's `sample`).
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
    let w = f32(TRANSMITTANCE_W);
    let h = f32(TRANSMITTANCE_H);
    let u = texcoord_from_unit(clamp(x_mu, 0.0, 1.0), w);
    let v = texcoord_from_unit(clamp(rho / big_h, 0.0, 1.0), h);
    let x = clamp(u * w - 0.5, 0.0, w - 1.0);
    let y = clamp(v * h - 0.5, 0.0, h - 1.0);
    let i0 = u32(floor(x));
    let j0 = u32(floor(y));
    let i1 = min(i0 + 1u, TRANSMITTANCE_W - 1u);
    let j1 = min(j0 + 1u, TRANSMITTANCE_H - 1u);
    let fx = x - f32(i0);
    let fy = y - f32(j0);
    let a = mix(transmittance_out[j0 * TRANSMITTANCE_W + i0].xyz, transmittance_out[j0 * TRANSMITTANCE_W + i1].xyz, fx);
    let b = mix(transmittance_out[j1 * TRANSMITTANCE_W + i0].xyz, transmittance_out[j1 * TRANSMITTANCE_W + i1].xyz, fx);
    return mix(a, b, fy);
}

fn scattering_at(h_in: f32) -> vec3<f32> {
    let h = max(h_in, 0.0);
    return atm.rayleigh.xyz * exp(-h / atm.rayleigh.w) + atm.mie_scattering.xyz * exp(-h / atm.mie_scattering.w);
}

// Each texel: Hillaire's Ψ = L₂ / (1 − f_ms) for its altitude and sun angle, over 8×8 directions.
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
    multiple_scattering_out[id.y * MS_SIZE + id.x] = vec4<f32>(l2 / (1.0 - f_ms), 1.0);
}

// x: the viewer's radius (km), y: cosine of the sun's zenith angle
struct SkyViewer {
    r_mu_s: vec4<f32>,
}

@group(0) @binding(3) var<uniform> sky_viewer: SkyViewer;
@group(0) @binding(4) var<storage, read_write> sky_view_out: array<vec4<f32>>;

const SKY_VIEW_W: u32 = 192u;
const SKY_VIEW_H: u32 = 108u;
const SKY_STEPS: u32 = 30u;

// Ψ from the multiple-scattering table, bilinear between texel centres (the twin's `sample`).
fn multiple_scattering_at(r: f32, mu_s: f32) -> vec3<f32> {
    let n = f32(MS_SIZE);
    let u = (mu_s + 1.0) / 2.0;
    let v = (r - atm.radii.x) / (atm.radii.y - atm.radii.x);
    let x = clamp(u * n - 0.5, 0.0, n - 1.0);
    let y = clamp(v * n - 0.5, 0.0, n - 1.0);
    let i0 = u32(floor(x));
    let j0 = u32(floor(y));
    let i1 = min(i0 + 1u, MS_SIZE - 1u);
    let j1 = min(j0 + 1u, MS_SIZE - 1u);
    let a = mix(multiple_scattering_out[j0 * MS_SIZE + i0].xyz, multiple_scattering_out[j0 * MS_SIZE + i1].xyz, x - f32(i0));
    let b = mix(multiple_scattering_out[j1 * MS_SIZE + i0].xyz, multiple_scattering_out[j1 * MS_SIZE + i1].xyz, x - f32(i0));
    return mix(a, b, y - f32(j0));
}

fn rayleigh_phase(nu: f32) -> f32 {
    return 3.0 / (16.0 * PI) * (1.0 + nu * nu);
}

fn mie_phase(g: f32, nu: f32) -> f32 {
    let k = 3.0 / (8.0 * PI) * (1.0 - g * g) / (2.0 + g * g);
    return k * (1.0 + nu * nu) / pow(1.0 + g * g - 2.0 * g * nu, 1.5);
}

// The sky along a view ray (the twin: `Atmosphere::sky` without a distance limit).
fn sky_radiance(r: f32, mu: f32, mu_s: f32, nu: f32) -> vec3<f32> {
    let bottom = atm.radii.x;
    let sin_v = sqrt(max(1.0 - mu * mu, 0.0));
    let view = vec3<f32>(sin_v, 0.0, mu);
    var sx = sqrt(max(1.0 - mu_s * mu_s, 0.0));
    if sin_v > 1e-6 {
        sx = (nu - mu * mu_s) / sin_v;
    }
    let sun = vec3<f32>(sx, sqrt(max(1.0 - mu_s * mu_s - sx * sx, 0.0)), mu_s);
    var d = distance_to_top(r, mu);
    if hits_ground(r, mu) {
        d = distance_to_bottom(r, mu);
    }
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
        var t_sun = vec3<f32>(0.0);
        if !hits_ground(rp, mu_sp) {
            t_sun = transmittance_to_top(rp, mu_sp);
        }
        let psi = multiple_scattering_at(rp, mu_sp);
        let s = sr * (pr * t_sun + psi) + sm * (pm * t_sun + psi);
        let step_t = exp(-ext * dt);
        let integral = select(vec3<f32>(dt), (1.0 - step_t) / ext, ext > vec3<f32>(0.0));
        radiance += throughput * s * integral;
        throughput *= step_t;
    }
    return radiance;
}

// Each texel: the sky in its direction for the viewer of `sky_viewer` (the twin: SkyViewLut).
@compute @workgroup_size(8, 8)
fn sky_view_lut(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= SKY_VIEW_W || id.y >= SKY_VIEW_H {
        return;
    }
    let bottom = atm.radii.x;
    let r = max(sky_viewer.r_mu_s.x, bottom);
    let mu_s = sky_viewer.r_mu_s.y;
    let u = (f32(id.x) + 0.5) / f32(SKY_VIEW_W);
    let v = (f32(id.y) + 0.5) / f32(SKY_VIEW_H);
    let v_horizon = sqrt(max(r * r - bottom * bottom, 0.0));
    let beta = acos(clamp(v_horizon / r, -1.0, 1.0));
    let zenith_horizon = PI - beta;
    var zenith = 0.0;
    if v < 0.5 {
        let c = 1.0 - 2.0 * v;
        zenith = zenith_horizon * (1.0 - c * c);
    } else {
        let c = 2.0 * v - 1.0;
        zenith = zenith_horizon + beta * c * c;
    }
    let mu = cos(zenith);
    let cos_az = -(u * u * 2.0 - 1.0);
    let sin_v = sqrt(max(1.0 - mu * mu, 0.0));
    let sin_s = sqrt(max(1.0 - mu_s * mu_s, 0.0));
    let nu = clamp(mu * mu_s + sin_v * sin_s * cos_az, -1.0, 1.0);
    sky_view_out[id.y * SKY_VIEW_W + id.x] = vec4<f32>(sky_radiance(r, mu, mu_s, nu), 1.0);
}
