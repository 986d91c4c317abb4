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
