//! A terrain renderer added from outside the viewer's crates: its geometry planner and its
//! renderer, registered with one call (`ClipmapPass::use_geometry`), draw the frame in place of
//! the built-in geometry, through the same pass, uniforms and depth test.

use sc_view_data::clipmap::{HeightSource, LevelWindow};
use sc_view_gpu::headless::Renderer;
use sc_view_gpu::terrain::{TerrainDraw, TerrainRenderer, TerrainSetup, TerrainStage};
use sc_view_plan::terrain::{Drawn, GeometryFrame, GeometryInput, GeometryPlanner};
use sc_view_space::camera::Camera;

const R: f64 = sc_core::EARTH_RADIUS_M;

struct FlatSea;

impl HeightSource for FlatSea {
    fn height(&mut self, _: f64, _: f64, _: LevelWindow) -> f32 {
        0.0
    }
}

/// The toy geometry's frame: the colour it fills the view with.
#[derive(Debug)]
struct ToyFrame {
    rgb: [f32; 3],
}

impl Drawn for ToyFrame {}

/// Plans the toy geometry: every frame one colour.
#[derive(Debug)]
struct ToyPlanner;

impl GeometryPlanner for ToyPlanner {
    fn plan(&mut self, _: &GeometryInput<'_>) -> GeometryFrame {
        GeometryFrame::new(ToyFrame {
            rgb: [1.0, 0.0, 1.0],
        })
    }
}

/// Draws the toy geometry: a triangle over the whole view, halfway into the depth range.
#[derive(Debug)]
struct ToyRenderer {
    pipeline: wgpu::RenderPipeline,
    drawn: bool,
}

const TOY_WGSL: &str = "
@vertex
fn toy_vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - vec2<f32>(1.0);
    return vec4<f32>(xy, 0.5, 1.0);
}

@fragment
fn fs_main() -> @location(0) vec4<f32> {
    return vec4<f32>(1.0, 0.0, 1.0, 1.0);
}
";

impl ToyRenderer {
    fn new(setup: &TerrainSetup<'_>) -> Self {
        let module = setup
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("toy"),
                source: wgpu::ShaderSource::Wgsl(TOY_WGSL.into()),
            });
        let layout = setup.pipeline_layout("toy", None);
        let (pipeline, _) = setup.pipelines(&TerrainStage {
            label: "toy",
            layout: &layout,
            module: &module,
            vertex_entry: "toy_vs",
            buffers: &[],
        });
        Self {
            pipeline,
            drawn: false,
        }
    }
}

impl TerrainRenderer for ToyRenderer {
    fn upload(&mut self, _: &wgpu::Device, _: &wgpu::Queue, frame: &GeometryFrame) -> bool {
        self.drawn = frame
            .get::<ToyFrame>()
            .is_some_and(|t| t.rgb == [1.0, 0.0, 1.0]);
        self.drawn
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, _: &TerrainDraw) {
        if self.drawn {
            pass.set_pipeline(&self.pipeline);
            pass.draw(0..3, 0..1);
        }
    }

    fn bytes(&self) -> u64 {
        0
    }
}

#[test]
fn a_renderer_registered_from_outside_draws_the_frame_instead_of_the_built_in_geometry() {
    let camera = Camera::parse("0,0,20000000,0,-90,40").expect("camera");
    let magenta =
        |img: &image::RgbaImage| img.pixels().filter(|p| p.0 == [255, 0, 255, 255]).count();
    let mut r = Renderer::headless(64, 36, R).expect("renderer");
    // the built-in hemisphere: the globe in space, no magenta
    let (img, _) = r.render(&mut FlatSea, None, &camera).expect("render");
    assert_eq!(magenta(&img), 0);
    r.pass_mut().use_geometry(Box::new(ToyPlanner), |setup| {
        Box::new(ToyRenderer::new(setup))
    });
    let (img, _) = r.render(&mut FlatSea, None, &camera).expect("render");
    assert_eq!(
        magenta(&img),
        64 * 36,
        "the toy renderer fills the view, the hemisphere is not drawn"
    );
    assert_eq!(
        r.pass_mut().geometry_bytes(),
        0,
        "the toy's memory is reported"
    );
}
