//! The second renderer: icosahedral triangular CDLOD (`icosahedral-cdlod-planet-notes.txt`), on
//! the CPU side. An icosahedron's 20 faces are split into a quaternary triangle tree by distance
//! from the camera; every leaf draws one instanced triangular patch of `N + 1` vertices a side
//! (N = 2n segments) whose odd vertices morph onto the parent's lattice near the leaf's outer
//! distance, so neighbouring levels meet without cracks or pops. Heights and colours come from
//! the clipmaps (`shaders/cdlod.wesl` reads them as the clipmap renderer does), so a comparison
//! of the two renderers compares geometry, not data.
//!
//! - **Lattice.** A face is flat: `P(u, v) = c₀ + (c₁ − c₀)u + (c₂ − c₀)v` (the gnomonic
//!   icosahedral grid), every point of the tree a dyadic (u, v); a vertex is `P / |P|`. A leaf
//!   of level L is an "up" (σ = +1) or "down" (σ = −1) triangle of the face's level-L lattice;
//!   its patch vertex (i, j) is lattice point `corner·N + σ·(i, j)` at resolution 2^(L+p),
//!   N = 2^p. All of this is integer arithmetic, so two leaves that share a point compute it
//!   from the same integers.
//! - **Precision.** Per frame and face the CPU (f64) passes the face's edge vectors and an
//!   anchor lattice point near the viewer, scaled by 1/|P(anchor)| and in the clipmap's view
//!   frame (the viewer at +z); the vertex is `anchor + e₁Δu + e₂Δv` with Δ exact from integers,
//!   normalised without cancellation into the clipmap's vertex attributes (sin θ̃ cos ψ,
//!   sin θ̃ sin ψ, 1 − cos θ̃) — the same viewer-relative form, and the same precision.
//! - **No cracks.** A point on an edge or corner of the icosahedron is computed in the lowest
//!   numbered face holding it (`slots`); odd vertices snap to one end of their coarse edge (the
//!   face's rule inside a face, towards the lower numbered icosahedron vertex on its edges), so
//!   every leaf holding a vertex moves it to the same place.
//! - **Split and morph distances.** Level L splits where the camera is nearer than D_L to the
//!   leaf (a cone around the leaf's centre through its corners, on the sphere of the ground
//!   under the camera), D_L = D₀·2^−L: the notes' pixel rule (a patch triangle no larger than
//!   `pixel_error` pixels), but never under [`MIN_SPLIT_EDGES`] leaf edges — below that a
//!   leaf's parent reaches so far that the coarser neighbour would already morph where the finer
//!   one ends, or two levels would meet. A vertex of level L morphs from
//!   [`MORPH_START`]·D_{L−1} and is on its parent's lattice from [`MORPH_FULL`]·D_{L−1} (its own
//!   distance on that sphere, never less than its leaf's cone distance, so it is on the parent's
//!   lattice wherever a coarser leaf touches it; the coarser leaf's vertices there are nearer
//!   than D_{L−1} + 1.15 edges, under its own morph start when the split distance is at least
//!   1.15 / (2·MORPH_START − 1) ≈ 1.9 edges).
//! - **Culling.** Horizon: a per-level table of the largest angular radius of a leaf, against the
//!   horizon angle plus the notes' margin acos(R/(R + h_max)) for mountains beyond it; frustum:
//!   the leaf's volume (its corners at the lowest terrain and, raised so its top plane clears
//!   the highest, at the highest) against five planes, children of a leaf wholly inside not
//!   tested again.

use std::f64::consts::PI;
use std::sync::OnceLock;
use web_time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use super::{Drawn, GeometryCounts, GeometryFrame, GeometryInput, GeometryPlanner};
use sc_view_space::camera::Camera;
use sc_view_space::transform::{Viewer, angle, offsets_f64, ring_of};

/// Faces of the icosahedron.
pub const FACES: usize = 20;

/// The finest level of the tree (with patches of at most 16 segments the lattice has 2^30
/// points a face side: i32 in the shader).
pub const MAX_LEVEL: u32 = 26;

/// Where a vertex starts to morph, as a share of its parent level's split distance.
pub const MORPH_START: f64 = 0.8;

/// Where it is on the parent's lattice (a margin below 1 for f32 rounding).
pub const MORPH_FULL: f64 = 0.98;

/// A level's split distance is never under this many of its leaves' longest edge (1.9 would
/// do with [`MORPH_START`]; the rest is margin).
pub const MIN_SPLIT_EDGES: f64 = 2.5;

/// The lowest and highest terrain assumed by culling and splitting, metres (the ocean's deepest
/// trench and Everest, with margins).
pub const TERRAIN_RANGE_M: (f64, f64) = (-11_500.0, 9_000.0);

/// CDLOD's options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CdlodSpec {
    /// Segments of a patch side (a power of two, 2..=16; the notes' 2n).
    pub patch: u32,
    /// Largest size of a patch triangle on screen, pixels (the notes' maxTrianglePixels).
    pub pixel_error: f64,
}

/// The largest patch triangle on screen by default, pixels: with 8 the skyline over rough
/// terrain stays 2 px (p99) under the finest data's, with 4 at 1 px in most views, for 1.3–1.9×
/// the frame time on a CPU rasteriser (BENCHMARKS.md, "Skylines against the finest data").
pub const DEFAULT_PIXEL_ERROR: f64 = 4.0;

impl Default for CdlodSpec {
    /// Patches of 16 segments (17 vertices a side), triangles of at most
    /// [`DEFAULT_PIXEL_ERROR`] pixels.
    fn default() -> Self {
        Self {
            patch: 16,
            pixel_error: DEFAULT_PIXEL_ERROR,
        }
    }
}

impl CdlodSpec {
    /// Refuses options the renderer cannot draw, in words.
    pub fn check(&self) -> Result<(), String> {
        if !(2..=16).contains(&self.patch) || !self.patch.is_power_of_two() {
            return Err(format!(
                "the CDLOD patch must have 2, 4, 8 or 16 segments a side, found {}",
                self.patch
            ));
        }
        if !(self.pixel_error.is_finite() && (0.5..=64.0).contains(&self.pixel_error)) {
            return Err(format!(
                "the CDLOD pixel error must be in 0.5..64 pixels, found {}",
                self.pixel_error
            ));
        }
        Ok(())
    }

    /// log2 of the patch's segments.
    pub fn bits(&self) -> u32 {
        self.patch.trailing_zeros()
    }
}

/// The icosahedron: 12 unit vertices from three golden-ratio rectangles, 20 faces
/// counter-clockwise seen from outside.
#[derive(Debug, Clone)]
pub struct Icosahedron {
    /// Unit vertices, world frame (z north, x at longitude 0).
    pub vertices: [DVec3; 12],
    /// Each face's vertices.
    pub faces: [[usize; 3]; FACES],
}

impl Icosahedron {
    /// The icosahedron with a vertex at each pole's side as the three planes put them.
    pub fn new() -> Self {
        let phi = (1.0 + 5f64.sqrt()) / 2.0;
        let mut v = Vec::with_capacity(12);
        for a in [-1.0, 1.0] {
            for b in [-phi, phi] {
                v.push(DVec3::new(0.0, a, b));
                v.push(DVec3::new(a, b, 0.0));
                v.push(DVec3::new(b, 0.0, a));
            }
        }
        let vertices: [DVec3; 12] = std::array::from_fn(|k| v[k].normalize());
        // neighbours are the nearest pairs (2 apart before normalising)
        let edge = (0..12)
            .flat_map(|a| (0..12).map(move |b| (a, b)))
            .filter(|(a, b)| a != b)
            .map(|(a, b)| (v[a] - v[b]).length())
            .fold(f64::INFINITY, f64::min);
        let near = |a: usize, b: usize| ((v[a] - v[b]).length() - edge).abs() < 1e-9;
        let mut faces = Vec::new();
        for a in 0..12 {
            for b in a + 1..12 {
                for c in b + 1..12 {
                    if near(a, b) && near(b, c) && near(a, c) {
                        let (p, q, r) = (vertices[a], vertices[b], vertices[c]);
                        if (q - p).cross(r - p).dot(p) > 0.0 {
                            faces.push([a, b, c]);
                        } else {
                            faces.push([a, c, b]);
                        }
                    }
                }
            }
        }
        Self {
            vertices,
            faces: faces.try_into().expect("an icosahedron has 20 faces"),
        }
    }

    /// Face `f`'s slots: for its corners c₀, c₁, c₂ and its edges c₀c₁ (v = 0), c₀c₂ (u = 0)
    /// and c₁c₂ (u + v = 1), the lowest numbered face holding them (bits 0..8), where that
    /// face's corners 1 and 2 are among f's (bits 8..10, 16..18; 3: not among them), and for the
    /// edges whether odd vertices morph in f's positive lattice direction (bit 24: towards the
    /// lower numbered of the edge's two vertices).
    pub fn slots(&self, f: usize) -> [u32; 6] {
        let fc = self.faces[f];
        let pos = |vertex: usize| fc.iter().position(|&x| x == vertex).unwrap_or(3) as u32;
        let owner = |held: &[usize]| -> usize {
            (0..FACES)
                .find(|&g| held.iter().all(|x| self.faces[g].contains(x)))
                .expect("every corner and edge lies on a face")
        };
        let pack = |g: usize| -> u32 {
            let gc = self.faces[g];
            g as u32 | pos(gc[1]) << 8 | pos(gc[2]) << 16
        };
        let [c0, c1, c2] = fc;
        [
            pack(owner(&[c0])),
            pack(owner(&[c1])),
            pack(owner(&[c2])),
            // c₀c₁: +u goes to c₁
            pack(owner(&[c0, c1])) | u32::from(c1 < c0) << 24,
            // c₀c₂: +v goes to c₂
            pack(owner(&[c0, c2])) | u32::from(c2 < c0) << 24,
            // c₁c₂: (+u, −v) goes to c₁
            pack(owner(&[c1, c2])) | u32::from(c1 < c2) << 24,
        ]
    }
}

impl Default for Icosahedron {
    fn default() -> Self {
        Self::new()
    }
}

/// One leaf of the tree, as the vertex stage gets it (an instance).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct LeafInstance {
    /// The face.
    pub face: u32,
    /// The level.
    pub level: u32,
    /// The corner the patch's (0, 0) sits on, in the face's level lattice.
    pub corner: [i32; 2],
    /// +1: an up triangle (corner, corner + (1, 0), corner + (0, 1)); −1: a down one.
    pub sigma: i32,
    /// +1 when the leaf straddles the meridian beyond the nearer pole (Δφ unwrapped to one
    /// side, as the clipmap's seam vertices are), else 0.
    pub seam: f32,
}

/// One face's per-frame constants (`CdlodFace` of `shaders/cdlod.wesl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct FaceUniform {
    /// The anchor's direction in the view frame: x, y and 1 − z (exact for tiny offsets).
    pub a: [f32; 4],
    /// (c₁ − c₀) / |P(anchor)|, view frame.
    pub e1: [f32; 4],
    /// (c₂ − c₀) / |P(anchor)|, view frame.
    pub e2: [f32; 4],
    /// What `e1` leaves of the f64 value (e1 + e1_lo is exact to ~1e-15).
    pub e1_lo: [f32; 4],
    /// What `e2` leaves.
    pub e2_lo: [f32; 4],
    /// The anchor lattice point at the finest resolution (2^(MAX_LEVEL + p) a side).
    pub anchor: [i32; 4],
    /// [`Icosahedron::slots`], two unused.
    pub slots: [u32; 8],
}

/// The finest clipmap level.
const MAX_RING: u32 = sc_view_space::transform::LEVELS - 1;

/// Per clipmap level i, the lowest and highest height that points within its cap can read: the
/// union of the ranges of levels i..=hi (within the levels drawn `lo..=hi`; a level unknown
/// makes it [`TERRAIN_RANGE_M`]), widened by a metre.
fn range_table(
    bounds: &[Option<(f64, f64)>],
    lo: u32,
    hi: u32,
) -> [(f64, f64); MAX_RING as usize + 1] {
    let mut out = [TERRAIN_RANGE_M; MAX_RING as usize + 1];
    let mut acc = Some((f64::INFINITY, f64::NEG_INFINITY));
    for i in (0..=MAX_RING.min(hi)).rev() {
        if i >= lo {
            acc = acc
                .zip(bounds.get(i as usize).copied().flatten())
                .map(|(a, b)| (a.0.min(b.0), a.1.max(b.1)));
        }
        out[i as usize] = match acc {
            Some((a, b)) if a <= b => (a - 1.0, b + 1.0),
            _ => TERRAIN_RANGE_M,
        };
    }
    // points finer than the finest level drawn read it
    for i in hi.min(MAX_RING) + 1..=MAX_RING {
        out[i as usize] = out[hi.min(MAX_RING) as usize];
    }
    out
}

/// Levels in the morph table.
pub const MORPH_LEVELS: usize = 32;

/// The per-frame uniform of `shaders/cdlod.wesl` (its layout is checked against the WGSL by the
/// GPU crate's tests).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct CdlodUniform {
    /// Every face's constants.
    pub faces: [FaceUniform; FACES],
    /// Per level: where its vertices start to morph (metres from the camera) and 1 / the
    /// distance over which they do (0: level 0, which has no parent).
    pub morph: [[f32; 4]; MORPH_LEVELS],
    /// Lowest and highest terrain (scaled by the exaggeration), 2^−(MAX_LEVEL + p), unused.
    pub h_range: [f32; 4],
    /// Patch segments N, p = log2 N, MAX_LEVEL + p, MAX_LEVEL.
    pub params: [u32; 4],
}

/// What the traversal did, for the panel and the benchmarks.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CdlodStats {
    /// Leaves drawn.
    pub leaves: u32,
    /// Nodes of the tree looked at.
    pub nodes: u32,
    /// Nodes culled because they lie beyond the horizon.
    pub culled_horizon: u32,
    /// Nodes culled because they lie outside the view frustum.
    pub culled_frustum: u32,
    /// The finest level drawn.
    pub finest: u32,
    /// Triangles drawn (leaves × N²).
    pub triangles: u32,
    /// CPU seconds of the traversal.
    pub cpu_s: f64,
}

/// One frame of CDLOD: the leaves to draw and the uniform.
#[derive(Debug, Clone)]
pub struct CdlodFrame {
    /// Instances.
    pub leaves: Vec<LeafInstance>,
    /// The uniform.
    pub uniform: CdlodUniform,
    /// Statistics.
    pub stats: CdlodStats,
}

/// Per-level tables that depend on the icosahedron only.
#[derive(Debug)]
struct LevelTables {
    /// Largest angular radius of a leaf (from its centre to a corner), radians.
    alpha: [f64; MAX_LEVEL as usize + 1],
    /// Longest edge of a leaf, radians of arc.
    edge: [f64; MAX_LEVEL as usize + 1],
}

/// Levels measured leaf by leaf; finer ones are extrapolated (halving, with a margin).
const MEASURED_LEVELS: u32 = 6;

fn tables() -> &'static LevelTables {
    static T: OnceLock<LevelTables> = OnceLock::new();
    T.get_or_init(|| {
        let ico = Icosahedron::new();
        let mut alpha = [0.0; MAX_LEVEL as usize + 1];
        let mut edge = [0.0; MAX_LEVEL as usize + 1];
        for f in 0..FACES {
            let [c0, c1, c2] = ico.faces[f].map(|k| ico.vertices[k]);
            let mut stack = vec![(0u32, 0i64, 0i64, 1i64)];
            while let Some((l, i, j, s)) = stack.pop() {
                let n = (1i64 << l) as f64;
                let p = |a: i64, b: i64| {
                    (c0 + (c1 - c0) * (a as f64 / n) + (c2 - c0) * (b as f64 / n)).normalize()
                };
                let k = [p(i, j), p(i + s, j), p(i, j + s)];
                let m = (k[0] + k[1] + k[2]).normalize();
                let li = l as usize;
                for q in 0..3 {
                    alpha[li] = f64::max(alpha[li], angle(m, k[q]));
                    edge[li] = f64::max(edge[li], angle(k[q], k[(q + 1) % 3]));
                }
                if l < MEASURED_LEVELS {
                    for c in children(i, j, s) {
                        stack.push((l + 1, c.0, c.1, c.2));
                    }
                }
            }
        }
        for l in MEASURED_LEVELS as usize + 1..=MAX_LEVEL as usize {
            alpha[l] = alpha[l - 1] * 0.5 * 1.02;
            edge[l] = edge[l - 1] * 0.5 * 1.02;
        }
        LevelTables { alpha, edge }
    })
}

/// The four children of the leaf at lattice `(i, j)`, orientation `s`, one level finer.
fn children(i: i64, j: i64, s: i64) -> [(i64, i64, i64); 4] {
    let (a, b) = (2 * i, 2 * j);
    [(a, b, s), (a + s, b, s), (a, b + s, s), (a + s, b + s, -s)]
}

/// The largest angular radius of a level-`l` leaf and its longest edge (radians).
pub fn level_extent(l: u32) -> (f64, f64) {
    let t = tables();
    let l = l.min(MAX_LEVEL) as usize;
    (t.alpha[l], t.edge[l])
}

/// A world direction (z north, x at longitude 0) in the view frame of the clipmap renderer:
/// the viewer at +z, ψ = 0 south (see [`sc_view_space::transform`]); a southern viewer's frame is
/// turned by π about z.
pub fn to_view(viewer: &Viewer, w: DVec3) -> DVec3 {
    let (sl, cl) = viewer.lon_rad.sin_cos();
    let (x, y) = (w.x * cl + w.y * sl, -w.x * sl + w.y * cl);
    let (s, k) = viewer.colat_rad.sin_cos();
    let o = viewer.orient();
    DVec3::new(o * (k * x - s * w.z), o * y, s * x + k * w.z)
}

/// A view-frame direction back in the world frame (the inverse of [`to_view`]).
pub fn from_view(viewer: &Viewer, v: DVec3) -> DVec3 {
    let o = viewer.orient();
    let (tx, ty) = (o * v.x, o * v.y);
    let (s, k) = viewer.colat_rad.sin_cos();
    let (x, z) = (k * tx + s * v.z, -s * tx + k * v.z);
    let (sl, cl) = viewer.lon_rad.sin_cos();
    DVec3::new(x * cl - ty * sl, x * sl + ty * cl, z)
}

/// The clipmap vertex attributes (sin θ̃ cos ψ, sin θ̃ sin ψ, 1 − cos θ̃) of a view-frame
/// direction `d` (any length), exact for directions near the viewer.
pub fn attributes(d: DVec3) -> [f64; 3] {
    let u = d.normalize();
    let rho2 = u.x * u.x + u.y * u.y;
    let c = if u.z > 0.0 {
        rho2 / (1.0 + u.z)
    } else {
        1.0 - u.z
    };
    [u.x, u.y, c]
}

/// The CPU side of CDLOD: the icosahedron in the view frame each frame, the tree traversal and
/// the per-frame uniform.
#[derive(Debug, Clone)]
pub struct CdlodPlanner {
    /// Options.
    pub spec: CdlodSpec,
    /// Cull beyond the horizon and outside the frustum (off: the whole sphere, for tests).
    pub cull: bool,
    ico: Icosahedron,
    slots: [[u32; 6]; FACES],
}

/// The camera in the view frame: where it is (the sphere's centre at the origin) and the
/// frustum's inward plane normals through it.
#[derive(Debug, Clone, Copy)]
struct Eye {
    /// Distance from the centre (on +z).
    rho: f64,
    planes: [DVec3; 5],
}

/// Where a node's volume lies against the frustum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Outside,
    Crossing,
    Inside,
}

struct Walk<'a> {
    cull: bool,
    eye: Eye,
    split: Vec<f64>,
    horizon_dot: Vec<f64>,
    /// Where splitting and morphing measure from: the sphere of the ground under the camera.
    rho_split: f64,
    radius: f64,
    /// [`range_table`].
    ranges: [(f64, f64); MAX_RING as usize + 1],
    lo: u32,
    viewer: &'a Viewer,
    corners: [DVec3; 12],
    faces: &'a [[usize; 3]; FACES],
    leaves: Vec<LeafInstance>,
    stats: CdlodStats,
}

impl CdlodPlanner {
    /// A planner with options `spec`.
    pub fn new(spec: CdlodSpec) -> Self {
        let ico = Icosahedron::new();
        let slots = std::array::from_fn(|f| ico.slots(f));
        Self {
            spec,
            cull: true,
            ico,
            slots,
        }
    }

    /// The icosahedron.
    pub fn icosahedron(&self) -> &Icosahedron {
        &self.ico
    }

    /// The split distance of level 0 for a `h`-pixel-high view of vertical field of view
    /// `fov_rad` on a sphere of `radius_m`, metres (D_L = D₀·2^−L).
    pub fn split_distance_0(&self, radius_m: f64, fov_rad: f64, h: u32) -> f64 {
        let (_, edge0) = level_extent(MEASURED_LEVELS);
        let edge = edge0 * f64::from(1u32 << MEASURED_LEVELS) * radius_m;
        let k = (self.spec.pixel_error * fov_rad / f64::from(h.max(1))).tan();
        (edge / f64::from(self.spec.patch) / k).max(MIN_SPLIT_EDGES * edge)
    }

    /// The frame from `camera` into a `w × h` view of the sphere of `radius_m`: the camera
    /// `cam_height_m` above the sphere, the ground under it at `ground_m` (both as drawn, the
    /// heights scaled). `bounds`: per clipmap level, the lowest and highest height its clipmap
    /// holds as drawn (None: not known), and the levels drawn `lo..=hi`.
    ///
    /// Leaves split and vertices morph by the camera's distance from the point at the height of
    /// the ground under it (the terrain's own height would tie a leaf's level to the heights of
    /// neighbouring levels' data); culling takes the heights the clipmaps hold, a level's range
    /// bounding what the points it covers read (they read it and the two coarser levels).
    pub fn plan(
        &self,
        camera: &Camera,
        (w, h): (u32, u32),
        radius_m: f64,
        (cam_height_m, ground_m): (f64, f64),
        (bounds, lo, hi): (&[Option<(f64, f64)>], u32, u32),
    ) -> CdlodFrame {
        let start = Instant::now();
        let viewer = Viewer::from_deg(camera.lat_deg, camera.lon_deg);
        let ranges = range_table(bounds, lo, hi);
        let (h_min, h_max) = ranges[lo.min(MAX_RING) as usize];
        let rho = radius_m + cam_height_m;
        let fov = camera.fov.to_radians();
        let eye = Eye {
            rho,
            planes: frustum_planes(&viewer, camera, w as f64 / h.max(1) as f64),
        };
        let d0 = self.split_distance_0(radius_m, fov, h);
        let split: Vec<f64> = (0..=MAX_LEVEL)
            .map(|l| d0 * 0.5f64.powi(l as i32))
            .collect();
        // the horizon of the lowest ground seen from the camera, plus the notes' margin for
        // mountains beyond it (as high as the highest terrain), plus a level's leaf radius
        let r_o = radius_m + h_min;
        let rho_max = radius_m + h_max;
        let beyond = (r_o / rho.max(r_o)).acos() + (r_o / rho_max).acos();
        let horizon_dot = (0..=MAX_LEVEL)
            .map(|l| {
                let a = beyond + level_extent(l).0;
                if a >= PI { -2.0 } else { a.cos() }
            })
            .collect();
        let corners = self.ico.vertices.map(|v| to_view(&viewer, v));
        let mut walk = Walk {
            cull: self.cull,
            eye,
            split,
            horizon_dot,
            rho_split: radius_m + ground_m,
            radius: radius_m,
            ranges,
            lo,
            viewer: &viewer,
            corners,
            faces: &self.ico.faces,
            leaves: Vec::new(),
            stats: CdlodStats::default(),
        };
        for f in 0..FACES {
            walk.visit(f, 0, 0, 0, 1, false);
        }
        let mut uniform = CdlodUniform::zeroed();
        let bits = self.spec.bits();
        let res = MAX_LEVEL + bits;
        for f in 0..FACES {
            uniform.faces[f] = self.face_uniform(f, &corners, res);
        }
        for l in 1..=MAX_LEVEL as usize {
            let parent = walk.split[l - 1];
            uniform.morph[l] = [
                (MORPH_START * parent) as f32,
                (1.0 / ((MORPH_FULL - MORPH_START) * parent)) as f32,
                0.0,
                0.0,
            ];
        }
        uniform.morph[0] = [f32::MAX, 0.0, 0.0, 0.0];
        uniform.h_range = [
            ground_m as f32,
            ground_m as f32,
            0.5f32.powi(res as i32),
            0.0,
        ];
        uniform.params = [self.spec.patch, bits, res, MAX_LEVEL];
        let mut stats = walk.stats;
        stats.leaves = walk.leaves.len() as u32;
        stats.triangles = stats.leaves * self.spec.patch * self.spec.patch;
        stats.cpu_s = start.elapsed().as_secs_f64();
        CdlodFrame {
            leaves: walk.leaves,
            uniform,
            stats,
        }
    }

    /// Face `f`'s constants: the anchor is the lattice point nearest to where the line of sight
    /// to the point under the viewer meets the face's plane (clamped to the face), for faces
    /// that face the viewer; the face's centre otherwise.
    fn face_uniform(&self, f: usize, corners: &[DVec3; 12], res: u32) -> FaceUniform {
        let [c0, c1, c2] = self.ico.faces[f].map(|k| corners[k]);
        let (e1, e2) = (c1 - c0, c2 - c0);
        let n = e1.cross(e2).normalize();
        let scale = f64::from(1u32 << res);
        let z = DVec3::Z;
        let (u, v) = if z.dot(n) > 0.25 {
            // the point of the plane in direction z, in face coordinates (least squares in 3-D)
            let p = z * (c0.dot(n) / z.dot(n)) - c0;
            let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
            let (d, e) = (p.dot(e1), p.dot(e2));
            let det = a * c - b * b;
            let (u, v) = ((c * d - b * e) / det, (a * e - b * d) / det);
            let u = u.clamp(0.0, 1.0);
            (u, v.clamp(0.0, 1.0 - u))
        } else {
            (1.0 / 3.0, 1.0 / 3.0)
        };
        let anchor = [(u * scale).round() as i64, (v * scale).round() as i64];
        let pa = c0 + e1 * (anchor[0] as f64 / scale) + e2 * (anchor[1] as f64 / scale);
        let len = pa.length();
        let [ax, ay, ac] = attributes(pa);
        let (e1, e2) = (e1 / len, e2 / len);
        let s = self.slots[f];
        let hi = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        let lo = |v: DVec3| {
            let h = hi(v);
            [
                (v.x - f64::from(h[0])) as f32,
                (v.y - f64::from(h[1])) as f32,
                (v.z - f64::from(h[2])) as f32,
                0.0,
            ]
        };
        FaceUniform {
            a: [ax as f32, ay as f32, ac as f32, 0.0],
            e1: hi(e1),
            e2: hi(e2),
            e1_lo: lo(e1),
            e2_lo: lo(e2),
            anchor: [anchor[0] as i32, anchor[1] as i32, 0, 0],
            slots: [s[0], s[1], s[2], s[3], s[4], s[5], 0, 0],
        }
    }
}

/// The view frustum's inward plane normals through the camera (left, right, bottom, top, near),
/// view frame, as `frame::view_projection` builds the view (widened by 2 %).
pub(super) fn frustum_planes(viewer: &Viewer, camera: &Camera, aspect: f64) -> [DVec3; 5] {
    let axes = viewer.camera_axes(camera.heading, camera.pitch);
    let f = axes.forward.normalize();
    let s = f.cross(axes.screen_up).normalize();
    let u = s.cross(f);
    let tv = (camera.fov.to_radians() / 2.0).tan() * 1.02;
    let th = tv * aspect;
    [s + f * th, f * th - s, u + f * tv, f * tv - u, f]
}

impl Walk<'_> {
    /// Visits the node of face `f`, level `l`, lattice corner (i, j), orientation `s`.
    fn visit(&mut self, f: usize, l: u32, i: i64, j: i64, s: i64, inside: bool) {
        self.stats.nodes += 1;
        let [c0, c1, c2] = self.faces[f].map(|k| self.corners[k]);
        let n = (1i64 << l) as f64;
        let p = |a: i64, b: i64| c0 + (c1 - c0) * (a as f64 / n) + (c2 - c0) * (b as f64 / n);
        let k = [p(i, j), p(i + s, j), p(i, j + s)].map(|q| q.normalize());
        let m = (k[0] + k[1] + k[2]).normalize();
        // the horizon: the camera is on +z
        if self.cull && m.z < self.horizon_dot[l as usize] {
            self.stats.culled_horizon += 1;
            return;
        }
        let mut inside = inside || !self.cull;
        let alpha = k.iter().map(|&q| angle(m, q)).fold(0.0, f64::max);
        if !inside {
            match self.frustum(&k, m, alpha) {
                Side::Outside => {
                    self.stats.culled_frustum += 1;
                    return;
                }
                Side::Inside => inside = true,
                Side::Crossing => {}
            }
        }
        if l < MAX_LEVEL && self.cone_distance(m, alpha) < self.split[l as usize] {
            for (ci, cj, cs) in children(i, j, s) {
                self.visit(f, l + 1, ci, cj, cs, inside);
            }
            return;
        }
        let seam = self.straddles_seam(&k, m);
        self.stats.finest = self.stats.finest.max(l);
        self.leaves.push(LeafInstance {
            face: f as u32,
            level: l,
            corner: [i as i32, j as i32],
            sigma: s as i32,
            seam: if seam { 1.0 } else { 0.0 },
        });
    }

    /// The camera's least distance from the cone of half-angle `alpha` around `m` at the
    /// sphere splitting measures from.
    fn cone_distance(&self, m: DVec3, alpha: f64) -> f64 {
        let beta = angle(DVec3::Z, m) - alpha;
        let rho = self.eye.rho;
        let r = self.rho_split;
        if beta <= 0.0 {
            return (rho - r).abs();
        }
        let half = (beta / 2.0).sin();
        ((r - rho).powi(2) + 4.0 * r * rho * half * half).sqrt()
    }

    /// The leaf's volume (corners `k`, unit; centre `m`, radius `alpha`) against the frustum:
    /// the terrain there lies within the heights of the clipmap levels it reads.
    fn frustum(&self, k: &[DVec3; 3], m: DVec3, alpha: f64) -> Side {
        let far = angle(DVec3::Z, m) + alpha;
        let ring = if far >= PI / 2.0 {
            0
        } else {
            (ring_of(far) as u32).min(MAX_RING)
        };
        let (h_min, h_max) =
            self.ranges[ring.saturating_sub(2).max(self.lo).min(MAX_RING) as usize];
        let (rho_min, rho_max) = (self.radius + h_min, self.radius + h_max);
        let n = (k[1] - k[0]).cross(k[2] - k[0]).normalize();
        let d0 = k[0].dot(n).max(1e-9);
        let eye = DVec3::new(0.0, 0.0, self.eye.rho);
        let points: [DVec3; 6] = [
            k[0] * rho_min - eye,
            k[1] * rho_min - eye,
            k[2] * rho_min - eye,
            k[0] * (rho_max / d0) - eye,
            k[1] * (rho_max / d0) - eye,
            k[2] * (rho_max / d0) - eye,
        ];
        let mut all_in = true;
        for plane in &self.eye.planes {
            let inside = points.iter().filter(|p| p.dot(*plane) >= 0.0).count();
            if inside == 0 {
                return Side::Outside;
            }
            all_in &= inside == 6;
        }
        if all_in { Side::Inside } else { Side::Crossing }
    }

    /// Whether the leaf (corners `k`, centre `m`) spans the meridian beyond the nearer pole,
    /// where Δφ jumps by 2π.
    fn straddles_seam(&self, k: &[DVec3; 3], m: DVec3) -> bool {
        let lon = |d: DVec3| {
            let [px, py, c] = attributes(d);
            offsets_f64(self.viewer, px, py, c, 0.0).dlon
        };
        let l: Vec<f64> = k
            .iter()
            .chain(std::iter::once(&m))
            .map(|&d| lon(d))
            .collect();
        let (lo, hi) = l
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        hi - lo > PI
    }
}

/// Lattice point (I, J) of face `f` at resolution `m` a side, as computed canonically: the face
/// holding it with the lowest number, and the point in that face's lattice.
fn canonical(slots: &[u32; 8], f: u32, ij: [i32; 2], m: i32) -> (u32, [i32; 2]) {
    remap(slots, f, slot_index(ij, m), ij, m)
}

/// Which slot (corner 0..3, edge 3..6) lattice point `ij` lies on, 6 inside the face.
pub fn slot_index([i, j]: [i32; 2], m: i32) -> u32 {
    if i == 0 && j == 0 {
        0
    } else if i == m && j == 0 {
        1
    } else if i == 0 && j == m {
        2
    } else if j == 0 {
        3
    } else if i == 0 {
        4
    } else if i + j == m {
        5
    } else {
        6
    }
}

/// Point `ij` of face `f` in the lattice of the owner of `slot`.
fn remap(slots: &[u32; 8], f: u32, slot: u32, [i, j]: [i32; 2], m: i32) -> (u32, [i32; 2]) {
    if slot == 6 {
        return (f, [i, j]);
    }
    let s = slots[slot as usize];
    let w = [m - i - j, i, j, 0];
    (
        s & 0xff,
        [w[((s >> 8) & 3) as usize], w[((s >> 16) & 3) as usize]],
    )
}

/// Where an odd vertex of the level-resolution lattice morphs to (itself when even).
pub fn morph_target(slots: &[u32; 8], [i, j]: [i32; 2], m: i32) -> [i32; 2] {
    let (oi, oj) = (i & 1 != 0, j & 1 != 0);
    if !oi && !oj {
        return [i, j];
    }
    let slot = slot_index([i, j], m);
    if (3..=5).contains(&slot) {
        let sg = if (slots[slot as usize] >> 24) & 1 == 1 {
            1
        } else {
            -1
        };
        return match slot {
            3 => [i + sg, j],
            4 => [i, j + sg],
            _ => [i + sg, j - sg],
        };
    }
    match (oi, oj) {
        (true, false) => [i - 1, j],
        (false, true) => [i, j + 1],
        _ => [i + 1, j - 1],
    }
}

/// The clipmap vertex attributes (px, py, 1 − cos θ̃) in f32 of the face point `anchor + e₁Δu +
/// e₂Δv` (`cdlod_point` in `shaders/cdlod_geometry.wesl`, operation for operation): with
/// ρ² = x² + y², 1 − z/|d| = ρ² / (|d|(|d| + z)), free of cancellation even where the face is
/// tilted against the view (z then changes linearly along it), and x/|d| = x − x·t with
/// t = 1 − 1/|d| formed from |d|² − 1 (|d| itself rounds to 6e-8, which x/|d| would keep).
pub fn point_f32(face: &FaceUniform, du: f32, dv: f32) -> [f32; 3] {
    let (a, e1, e2, l1, l2) = (face.a, face.e1, face.e2, face.e1_lo, face.e2_lo);
    let dx = a[0] + (e1[0] * du + e2[0] * dv) + (l1[0] * du + l2[0] * dv);
    let dy = a[1] + (e1[1] * du + e2[1] * dv) + (l1[1] * du + l2[1] * dv);
    let dz = (e1[2] * du + e2[2] * dv) - a[2];
    let rho2 = dx * dx + dy * dy;
    // |d|² = 1 + w; 1 − 1/|d| = w / (|d|(|d| + 1)), small and exact to f32
    let w = dz * (2.0 + dz) + rho2;
    let len = (1.0 + w).sqrt();
    let t = w / (len * (len + 1.0));
    let z = 1.0 + dz;
    let c = if z > 0.0 {
        rho2 / (len * (len + z))
    } else {
        1.0 - z / len
    };
    [dx - dx * t, dy - dy * t, c]
}

/// The camera's distance from the radial segment (the terrain's range) in a direction of
/// 1 − cos θ̃ = `c` (`cdlod_distance` in the shader).
pub fn distance_f32(u: &CdlodUniform, radius: f32, cam_height: f32, c: f32) -> f32 {
    let rc = radius + cam_height;
    let h = (cam_height - rc * c).clamp(u.h_range[0], u.h_range[1]);
    ((h - cam_height) * (h - cam_height) + 2.0 * (radius + h) * rc * c).sqrt()
}

/// Patch vertex (i, j) of `leaf` after its morph, in f32 as the vertex stage computes it
/// (`cdlod_vertex` in `shaders/cdlod.wesl`): the clipmap vertex attributes (px, py, 1 − cos θ̃).
pub fn vertex_f32(
    u: &CdlodUniform,
    radius: f32,
    cam_height: f32,
    leaf: &LeafInstance,
    [pi, pj]: [u32; 2],
) -> [f32; 3] {
    let [n, bits, _, lmax] = u.params;
    let m = 1i32 << (leaf.level + bits);
    let ij = [
        leaf.corner[0] * n as i32 + leaf.sigma * pi as i32,
        leaf.corner[1] * n as i32 + leaf.sigma * pj as i32,
    ];
    let f = leaf.face;
    let slots = &u.faces[f as usize].slots;
    let step = 1i32 << (lmax - leaf.level);
    let scale = u.h_range[2];
    let at = |g: u32, p: [i32; 2]| -> [f32; 3] {
        let face = &u.faces[g as usize];
        let du = (p[0] * step - face.anchor[0]) as f32 * scale;
        let dv = (p[1] * step - face.anchor[1]) as f32 * scale;
        point_f32(face, du, dv)
    };
    let (g, p0) = canonical(slots, f, ij, m);
    let unmorphed = at(g, p0);
    let t = morph_target(slots, ij, m);
    if t == ij {
        return unmorphed;
    }
    let mr = u.morph[leaf.level as usize];
    let k = ((distance_f32(u, radius, cam_height, unmorphed[2]) - mr[0]) * mr[1]).clamp(0.0, 1.0);
    if k <= 0.0 {
        return unmorphed;
    }
    if k >= 1.0 {
        let (gt, pt) = canonical(slots, f, t, m);
        return at(gt, pt);
    }
    let (_, tt) = remap(slots, f, slot_index(ij, m), t, m);
    let face = &u.faces[g as usize];
    let du = (p0[0] * step - face.anchor[0]) as f32 + k * ((tt[0] - p0[0]) * step) as f32;
    let dv = (p0[1] * step - face.anchor[1]) as f32 + k * ((tt[1] - p0[1]) * step) as f32;
    point_f32(face, du * scale, dv * scale)
}

/// The same vertex exactly (f64): the face point normalised, morphed by the exact distance;
/// the twin the f32 form is tested against. Returns the unit direction in the view frame.
pub fn vertex_f64(
    planner: &CdlodPlanner,
    viewer: &Viewer,
    u: &CdlodUniform,
    (radius, cam_height): (f64, f64),
    leaf: &LeafInstance,
    [pi, pj]: [u32; 2],
) -> DVec3 {
    let [n, bits, _, _] = u.params;
    let m = 1i32 << (leaf.level + bits);
    let ij = [
        leaf.corner[0] * n as i32 + leaf.sigma * pi as i32,
        leaf.corner[1] * n as i32 + leaf.sigma * pj as i32,
    ];
    let ico = planner.icosahedron();
    let [c0, c1, c2] = ico.faces[leaf.face as usize].map(|k| to_view(viewer, ico.vertices[k]));
    let at = |p: [f64; 2]| c0 + (c1 - c0) * (p[0] / m as f64) + (c2 - c0) * (p[1] / m as f64);
    let p0 = [f64::from(ij[0]), f64::from(ij[1])];
    let slots = &u.faces[leaf.face as usize].slots;
    let t = morph_target(slots, ij, m);
    let d = at(p0);
    if t == ij {
        return d.normalize();
    }
    let c = attributes(d)[2];
    let (lo, hi) = (f64::from(u.h_range[0]), f64::from(u.h_range[1]));
    let rc = radius + cam_height;
    let h = (cam_height - rc * c).clamp(lo, hi);
    let dist = ((h - cam_height).powi(2) + 2.0 * (radius + h) * rc * c).sqrt();
    let parent = planner_split(u, leaf.level);
    let k = ((dist - MORPH_START * parent) / ((MORPH_FULL - MORPH_START) * parent)).clamp(0.0, 1.0);
    let pt = [f64::from(t[0]), f64::from(t[1])];
    at([p0[0] + k * (pt[0] - p0[0]), p0[1] + k * (pt[1] - p0[1])]).normalize()
}

/// The parent's split distance of level `l`, from the uniform's morph table (f64 of its f32).
fn planner_split(u: &CdlodUniform, l: u32) -> f64 {
    f64::from(u.morph[l as usize][0]) / MORPH_START
}

/// The patch: vertices (i, j), i + j ≤ N, row by row, and its N² triangles (counter-clockwise
/// in (i, j)).
pub fn patch_mesh(n: u32) -> (Vec<[u32; 2]>, Vec<u32>) {
    let mut vertices = Vec::new();
    let mut row_start = Vec::new();
    for j in 0..=n {
        row_start.push(vertices.len() as u32);
        for i in 0..=n - j {
            vertices.push([i, j]);
        }
    }
    let at = |i: u32, j: u32| row_start[j as usize] + i;
    let mut indices = Vec::new();
    for j in 0..n {
        for i in 0..n - j {
            indices.extend_from_slice(&[at(i, j), at(i + 1, j), at(i, j + 1)]);
            if i + j + 2 <= n {
                indices.extend_from_slice(&[at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }
    (vertices, indices)
}

/// The border of a patch of `n` segments, counter-clockwise: (i, j) along j = 0, the diagonal,
/// then i = 0.
pub fn patch_border(n: u32) -> Vec<[u32; 2]> {
    let along = (0..n).map(|i| [i, 0]);
    let diagonal = (0..n).map(|k| [n - k, k]);
    let back = (0..n).map(|k| [0, n - k]);
    along.chain(diagonal).chain(back).collect()
}

impl Drawn for CdlodFrame {
    fn counts(&self) -> Option<GeometryCounts> {
        Some(GeometryCounts {
            triangles: self.stats.triangles,
            leaves: self.stats.leaves,
            culled_horizon: self.stats.culled_horizon,
            culled_frustum: self.stats.culled_frustum,
        })
    }
}

/// Icosahedral triangular CDLOD: the tree traversed per frame.
#[derive(Debug)]
pub struct CdlodGeometry {
    tree: CdlodPlanner,
}

impl CdlodGeometry {
    /// With `spec`'s patch and pixel error.
    pub fn new(spec: CdlodSpec) -> Self {
        Self {
            tree: CdlodPlanner::new(spec),
        }
    }
}

impl GeometryPlanner for CdlodGeometry {
    fn plan(&mut self, input: &GeometryInput<'_>) -> GeometryFrame {
        let (lo, hi) = input.levels;
        let f = self.tree.plan(
            input.camera,
            input.size,
            input.radius,
            (input.cam_height, input.ground()),
            (input.bounds, lo, hi),
        );
        GeometryFrame::new(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_icosahedron_has_twelve_vertices_twenty_faces_and_thirty_shared_edges() {
        let ico = Icosahedron::new();
        let mut edges = std::collections::HashMap::new();
        for f in &ico.faces {
            let [a, b, c] = f.map(|k| ico.vertices[k]);
            assert!(
                (b - a).cross(c - a).dot(a) > 0.0,
                "counter-clockwise from outside"
            );
            for (x, y) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                *edges.entry((x.min(y), x.max(y))).or_insert(0) += 1;
            }
        }
        assert_eq!(edges.len(), 30);
        assert!(edges.values().all(|&k| k == 2));
    }

    #[test]
    fn patch_has_n_squared_triangles_covering_it_once() {
        for n in [2, 4, 16] {
            let (v, i) = patch_mesh(n);
            assert_eq!(v.len() as u32, (n + 1) * (n + 2) / 2);
            assert_eq!(i.len() as u32, 3 * n * n);
            // signed area in (i, j) adds up to the patch's n²/2, every triangle positive
            let mut area = 0.0;
            for t in i.chunks(3) {
                let [a, b, c] = [t[0], t[1], t[2]].map(|k| v[k as usize].map(f64::from));
                let s = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                assert!(s > 0.0);
                area += s / 2.0;
            }
            assert_eq!(area, f64::from(n * n) / 2.0);
        }
    }

    #[test]
    fn the_level_tables_bound_every_leaf() {
        // random deep leaves: their radius and edges stay within the extrapolated tables
        let ico = Icosahedron::new();
        let mut seed = 12345u64;
        let mut rnd = |k: u64| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) % k
        };
        for _ in 0..2000 {
            let f = rnd(20) as usize;
            let l = 7 + rnd(18) as u32;
            let (mut i, mut j, mut s) = (0i64, 0i64, 1i64);
            for _ in 0..l {
                let c = children(i, j, s)[rnd(4) as usize];
                (i, j, s) = c;
            }
            let [c0, c1, c2] = ico.faces[f].map(|k| ico.vertices[k]);
            let n = (1i64 << l) as f64;
            let p = |a: i64, b: i64| {
                (c0 + (c1 - c0) * (a as f64 / n) + (c2 - c0) * (b as f64 / n)).normalize()
            };
            let k = [p(i, j), p(i + s, j), p(i, j + s)];
            let m = (k[0] + k[1] + k[2]).normalize();
            let (alpha, edge) = level_extent(l);
            for q in 0..3 {
                assert!(angle(m, k[q]) <= alpha, "level {l}");
                assert!(angle(k[q], k[(q + 1) % 3]) <= edge, "level {l}");
            }
        }
    }

    #[test]
    fn to_view_puts_the_viewer_on_z_and_inverts_the_map_transform() {
        for (lat, lon) in [(45.0, 10.0), (-30.0, 179.9), (89.9, -60.0), (-89.9, 0.0)] {
            let v = Viewer::from_deg(lat, lon);
            let w = |lat: f64, lon: f64| {
                let (la, lo) = (f64::to_radians(lat), f64::to_radians(lon));
                DVec3::new(la.cos() * lo.cos(), la.cos() * lo.sin(), la.sin())
            };
            let at = to_view(&v, w(lat, lon));
            assert!((at - DVec3::Z).length() < 1e-12, "{lat},{lon}: {at}");
            let q = w(lat * 0.3, lon - 40.0);
            assert!((from_view(&v, to_view(&v, q)) - q).length() < 1e-12);
            let dlat = if lat > 0.0 { -0.05 } else { 0.05 };
            let (lat2, lon2) = (lat + dlat, lon + 0.2);
            let [px, py, c] = attributes(to_view(&v, w(lat2, lon2)));
            let o = offsets_f64(&v, px, py, c, 0.0);
            assert!(
                (o.dlon - 0.2f64.to_radians()).abs() < 1e-9,
                "{lat},{lon}: {o:?}"
            );
            assert!(
                (o.dcolat + dlat.to_radians()).abs() < 1e-9,
                "{lat},{lon}: {o:?}"
            );
        }
    }
}
