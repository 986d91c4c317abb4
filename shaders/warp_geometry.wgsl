// Geometry-image warping: where vertex k of the warped mesh lies (viewer/plan/src/terrain/warp.rs,
// `WarpFrame::vertex`, operation for operation). A module including this declares the uniform
// `warp` (x: cells along a ring, y: cells along a line of azimuth) and the storage array
// `warp_lines` (per ring (sin θ, 1 − cos θ, 0, 0), then per azimuth (cos ψ, sin ψ, seam, 0)).

// The attributes (sin θ cos ψ, sin θ sin ψ, 1 − cos θ) of vertex k (ring k / (around + 1),
// azimuth k mod (around + 1)) and its seam flag.
fn warp_point(k: u32) -> vec4<f32> {
    let w = warp.x + 1u;
    let ring = warp_lines[k / w];
    let col = warp_lines[warp.y + 1u + k % w];
    return vec4<f32>(ring.x * col.x, ring.x * col.y, ring.y, col.z);
}
