// The atmosphere's lookup tables as compute passes (the CPU twins: sc_view_space::atmosphere);
// atmosphere_model.wgsl, which comes first, has the model, and air_table_reads.wgsl the tables'
// reads from the buffers declared here. Each pass writes
// one table from the ones before it: transmittance, multiple scattering, the sky's irradiance
// (once per atmosphere), then per frame the sky-view table and the aerial-perspective volume of
// the frame's viewer.

@group(0) @binding(0) var<uniform> atm: Atmosphere;
@group(0) @binding(1) var<storage, read_write> transmittance_table: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> multiple_scattering_table: array<vec4<f32>>;
@group(0) @binding(3) var<uniform> atmo: AtmosphereFrame;
@group(0) @binding(4) var<storage, read_write> sky_view_table: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> aerial_inscatter: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> aerial_transmittance: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> irradiance_table: array<vec4<f32>>;

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
    transmittance_table[id.y * TRANSMITTANCE_W + id.x] = vec4<f32>(exp(-tau), 1.0);
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
    multiple_scattering_table[id.y * MS_SIZE + id.x] = vec4<f32>(l2 / (1.0 - f_ms), 1.0);
}

// Each texel: the sky in its direction for the frame's viewer (the twin: SkyViewLut).
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
    } else {
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

// Each froxel column (a screen point) and slice: the light scattered towards the camera and the
// transmittance from where its ray enters the atmosphere to the slice's end (the twin:
// AerialPerspectiveLut).
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

// Each texel: the sky's irradiance on a horizontal surface at its altitude and sun angle, over
// 8×8 directions of the upper hemisphere (the twin: IrradianceLut).
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
