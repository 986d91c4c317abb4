//! Spherical geometry clipmaps: the static hemisphere around the viewer (paper §3.4), its fill
//! disc and rings drawn from the finest level drawn outwards (near ground first, so that the
//! depth test spares the shading of far ground it hides).

use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use sc_view_plan::terrain::GeometryFrame;
use sc_view_plan::terrain::clipmap::{Hemisphere, HemisphereFrame, HemisphereSpec};
use wgpu::util::DeviceExt;

use super::{TerrainDraw, TerrainRenderer, TerrainSetup, TerrainStage, pipeline_of};

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuVertex {
    pxy: [f32; 2],
    one_minus_cos: f32,
    seam: f32,
    level: u32,
    depth: f32,
}

/// The hemisphere's vertices and indices and its pipelines.
#[derive(Debug)]
pub struct HemisphereRenderer {
    pipeline: wgpu::RenderPipeline,
    wire: Option<wgpu::RenderPipeline>,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    /// Per level, the indices of its rings and of its fill disc.
    level_ranges: Vec<Range<u32>>,
    fill_ranges: Vec<Range<u32>>,
    /// Which hemisphere the buffers hold.
    spec: HemisphereSpec,
}

/// A hemisphere's vertex and index buffers.
fn buffers(device: &wgpu::Device, hemi: &Hemisphere) -> (wgpu::Buffer, wgpu::Buffer) {
    let verts: Vec<GpuVertex> = hemi
        .vertices
        .iter()
        .map(|v| GpuVertex {
            pxy: [v.px, v.py],
            one_minus_cos: v.one_minus_cos,
            seam: v.seam,
            level: v.level,
            depth: v.depth,
        })
        .collect();
    let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("hemisphere vertices"),
        contents: bytemuck::cast_slice(&verts),
        usage: wgpu::BufferUsages::VERTEX,
    });
    let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("hemisphere indices"),
        contents: bytemuck::cast_slice(&hemi.indices),
        usage: wgpu::BufferUsages::INDEX,
    });
    (vertices, indices)
}

impl HemisphereRenderer {
    /// The hemisphere of `setup` on its device.
    pub fn new(setup: &TerrainSetup<'_>) -> Self {
        let hemi = &Hemisphere::new(setup.hemisphere);
        let device = setup.device;
        let (vertices, indices) = buffers(device, hemi);
        let layout = setup.pipeline_layout("clipmap", None);
        let buffers = [wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<GpuVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x2, 1 => Float32, 2 => Float32, 3 => Uint32, 4 => Float32],
        }];
        let (pipeline, wire) = setup.pipelines(&TerrainStage {
            label: "clipmap",
            layout: &layout,
            module: setup.clipmap_shader,
            vertex_entry: "vs_main",
            buffers: &buffers,
        });
        Self {
            pipeline,
            wire,
            vertices,
            indices,
            level_ranges: hemi.level_ranges.clone(),
            fill_ranges: hemi.fill_ranges.clone(),
            spec: hemi.spec,
        }
    }
}

impl TerrainRenderer for HemisphereRenderer {
    /// Takes the hemisphere's frame; makes the buffers anew when the picture asks for another
    /// hemisphere (a new size or field of view).
    fn upload(&mut self, device: &wgpu::Device, _: &wgpu::Queue, frame: &GeometryFrame) -> bool {
        let Some(&HemisphereFrame(spec)) = frame.get::<HemisphereFrame>() else {
            return false;
        };
        if spec != self.spec {
            let hemi = Hemisphere::new(spec);
            (self.vertices, self.indices) = buffers(device, &hemi);
            self.level_ranges = hemi.level_ranges;
            self.fill_ranges = hemi.fill_ranges;
            self.spec = spec;
        }
        true
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, how: &TerrainDraw) {
        let (lo, hi) = (how.levels.0 as usize, how.levels.1 as usize);
        pass.set_pipeline(pipeline_of(how.wireframe, &self.pipeline, &self.wire));
        pass.set_vertex_buffer(0, self.vertices.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        // nearest first: the fill disc, then the rings from the finest level outwards
        pass.draw_indexed(self.fill_ranges[hi].clone(), 0, 0..1);
        pass.draw_indexed(
            self.level_ranges[hi].start..self.level_ranges[lo].end,
            0,
            0..1,
        );
    }

    fn bytes(&self) -> u64 {
        self.vertices.size() + self.indices.size()
    }
}
