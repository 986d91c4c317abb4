//! The geometries that draw the planet, behind one interface: each is a [`GeometryPlanner`] that
//! turns what the frame planner knows (camera, levels drawn, heights the clipmaps hold, texel
//! sizes) into the [`GeometryFrame`] the GPU side draws (any [`Drawn`] type its renderer takes
//! back). All read the same clipmaps, so they show the same data. A geometry of the viewer: its
//! file here (planner and frame), a variant of [`Geometry`] (the choice users make) and its line
//! in [`planner_for`]; one from outside the crate: its planner, handed to
//! [`crate::frame::FramePlanner::use_geometry`].

pub mod cdlod;
pub mod clipmap;
pub mod warp;

use cdlod::CdlodSpec;
use sc_view_space::camera::Camera;
use warp::WarpSpec;

/// Which geometry draws the planet; all read the same clipmaps.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Geometry {
    /// Spherical geometry clipmaps (the static hemisphere around the viewer).
    #[default]
    Clipmap,
    /// Icosahedral triangular CDLOD (`crate::terrain::cdlod`).
    Cdlod(CdlodSpec),
    /// One mesh warped every frame to where the view needs vertices (`crate::terrain::warp`).
    Warp(WarpSpec),
}

/// What a geometry's planner makes of a frame for its renderer (CDLOD's leaves, the warped
/// mesh's lines, the hemisphere's fixed rings): any type, which the renderer takes back by
/// [`GeometryFrame::get`].
pub trait Drawn: std::any::Any + std::fmt::Debug + Send + Sync {
    /// What it draws, for the frame's statistics; `None`: the frame planner counts the
    /// hemisphere's rings of the levels drawn, whole.
    fn counts(&self) -> Option<GeometryCounts> {
        None
    }
}

/// What a geometry draws this frame (the hemisphere's, by default).
#[derive(Debug, Clone)]
pub struct GeometryFrame(std::sync::Arc<dyn Drawn>);

impl Default for GeometryFrame {
    fn default() -> Self {
        Self::new(clipmap::HemisphereFrame::default())
    }
}

/// What a geometry frame draws, for the frame's statistics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GeometryCounts {
    /// Triangles drawn.
    pub triangles: u32,
    /// CDLOD: leaves drawn, and tree nodes culled beyond the horizon and outside the frustum.
    pub leaves: u32,
    /// See `leaves`.
    pub culled_horizon: u32,
    /// See `leaves`.
    pub culled_frustum: u32,
}

impl GeometryFrame {
    /// A frame drawing `drawn`.
    pub fn new(drawn: impl Drawn) -> Self {
        Self(std::sync::Arc::new(drawn))
    }

    /// What the frame draws, if its planner made a `T` (the renderer of `T` draws it).
    pub fn get<T: Drawn>(&self) -> Option<&T> {
        let any: &dyn std::any::Any = &*self.0;
        any.downcast_ref()
    }

    /// What it draws, if its geometry counts it.
    pub fn counts(&self) -> Option<GeometryCounts> {
        self.0.counts()
    }
}

/// What every geometry is given each frame.
#[derive(Debug, Clone, Copy)]
pub struct GeometryInput<'a> {
    /// The camera.
    pub camera: &'a Camera,
    /// The target, pixels.
    pub size: (u32, u32),
    /// The sphere's radius, metres.
    pub radius: f64,
    /// The camera's height above the sphere as the frame draws it (exaggerated ground +
    /// altitude), metres.
    pub cam_height: f64,
    /// The coarsest and finest clipmap levels drawn.
    pub levels: (u32, u32),
    /// Per level, the lowest and highest height drawn (scaled), for the levels drawn.
    pub bounds: &'a [Option<(f64, f64)>],
    /// Per clipmap level, its texels per radian (longitude, colatitude) as drawn.
    pub texels_per_rad: &'a [[f32; 2]],
}

impl GeometryInput<'_> {
    /// The ground under the camera as drawn, metres.
    pub fn ground(&self) -> f64 {
        self.cam_height - self.camera.alt
    }
}

/// Plans a geometry frame by frame (keeping whatever it carries from one frame to the next).
pub trait GeometryPlanner: std::fmt::Debug + Send {
    /// This frame's geometry.
    fn plan(&mut self, input: &GeometryInput<'_>) -> GeometryFrame;
}

/// The planner of `geometry`: the one place that registers each geometry.
pub fn planner_for(geometry: Geometry) -> Box<dyn GeometryPlanner> {
    match geometry {
        Geometry::Clipmap => Box::new(clipmap::ClipmapGeometry),
        Geometry::Cdlod(spec) => Box::new(cdlod::CdlodGeometry::new(spec)),
        Geometry::Warp(spec) => Box::new(warp::WarpGeometry::new(spec)),
    }
}
