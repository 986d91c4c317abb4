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
