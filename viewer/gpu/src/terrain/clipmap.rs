//! Spherical geometry clipmaps: the static hemisphere around the viewer (paper §3.4), its fill
//! disc and rings drawn from the finest level drawn outwards (near ground first, so that the
//! depth test spares the shading of far ground it hides).

use bytemuck::{Pod, Zeroable};
use sc_view_plan::terrain::GeometryFrame;
use sc_view_plan::terrain::clipmap::{Hemisphere, HemisphereFrame, HemisphereSpec, LevelDraw};
use wgpu::util::DeviceExt;

use super::{TerrainDraw, TerrainRenderer, TerrainSetup, TerrainStage, pipeline_of};

/// A column of the band: cos ψ, sin ψ, the seam flag, and 0 on the outer ring or 1 on the inner.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuColumn([f32; 4]);

/// A band instance: per ring (outer, inner) sin θ̃, 1 − cos θ̃ and depth, then both rings' levels.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct GpuBand {
    outer: [f32; 3],
    inner: [f32; 3],
    levels: [u32; 2],
}

/// The band's buffers and pipelines.
#[derive(Debug)]
pub struct HemisphereRenderer {
    pipeline: wgpu::RenderPipeline,
    wire: Option<wgpu::RenderPipeline>,
    columns: wgpu::Buffer,
    bands: wgpu::Buffer,
    indices: wgpu::Buffer,
    /// The hemisphere the buffers hold (its index and instance ranges).
    hemi: Hemisphere,
    /// What the frame last taken draws.
    draws: Vec<LevelDraw>,
    /// Rings of the fill disc the frame last taken draws.
    fill_rings: u32,
    /// The spec the hemisphere was built from.
    spec: HemisphereSpec,
}

/// A hemisphere's column, instance and index buffers.
fn buffers(device: &wgpu::Device, hemi: &Hemisphere) -> [wgpu::Buffer; 3] {
    let columns: Vec<GpuColumn> = hemi
        .columns
        .iter()
        .map(|c| GpuColumn([c.cos_psi, c.sin_psi, c.seam, c.inner]))
        .collect();
    let bands: Vec<GpuBand> = hemi
        .bands
        .iter()
        .map(|b| GpuBand {
            outer: [b.outer.sin, b.outer.one_minus_cos, b.outer.depth],
            inner: [b.inner.sin, b.inner.one_minus_cos, b.inner.depth],
            levels: [b.outer.level, b.inner.level],
        })
        .collect();
    let make = |label, contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
    };
    [
        make(
            "hemisphere columns",
            bytemuck::cast_slice(&columns),
            wgpu::BufferUsages::VERTEX,
        ),
        make(
            "hemisphere bands",
            bytemuck::cast_slice(&bands),
            wgpu::BufferUsages::VERTEX,
        ),
        make(
            "hemisphere indices",
            bytemuck::cast_slice(&hemi.indices),
            wgpu::BufferUsages::INDEX,
        ),
    ]
}

impl HemisphereRenderer {
    /// The hemisphere of `setup` on its device.
    pub fn new(setup: &TerrainSetup<'_>) -> Self {
        let hemi = Hemisphere::new(setup.hemisphere);
        let device = setup.device;
        let [columns, bands, indices] = buffers(device, &hemi);
        let layout = setup.pipeline_layout("clipmap", None);
        let buffers = [
            wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<GpuColumn>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x4],
            },
            wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<GpuBand>() as u64,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &wgpu::vertex_attr_array![1 => Float32x3, 2 => Float32x3, 3 => Uint32x2],
            },
        ];
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
            columns,
            bands,
            indices,
            hemi,
            draws: Vec::new(),
            fill_rings: u32::MAX,
            spec: setup.hemisphere,
        }
    }
}

impl TerrainRenderer for HemisphereRenderer {
    /// Takes the hemisphere's frame; makes the buffers anew when the picture asks for another
    /// hemisphere (a new size or field of view).
    fn upload(&mut self, device: &wgpu::Device, _: &wgpu::Queue, frame: &GeometryFrame) -> bool {
        let Some(f) = frame.get::<HemisphereFrame>() else {
            return false;
        };
        if f.spec != self.spec {
            self.spec = f.spec;
            self.hemi = Hemisphere::new(f.spec);
            [self.columns, self.bands, self.indices] = buffers(device, &self.hemi);
        }
        self.draws.clone_from(&f.draws);
        self.fill_rings = f.fill_rings;
        true
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, how: &TerrainDraw) {
        let (lo, hi) = how.levels;
        let hemi = &self.hemi;
        pass.set_pipeline(pipeline_of(how.wireframe, &self.pipeline, &self.wire));
        pass.set_vertex_buffer(0, self.columns.slice(..));
        pass.set_vertex_buffer(1, self.bands.slice(..));
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        // nearest first: the fill disc, then the rings from the finest level outwards
        let all = hemi.cells(&(0..hemi.spec.n));
        pass.draw_indexed(all.clone(), 0, hemi.fill(hi, self.fill_rings));
        if self.draws.is_empty() {
            pass.draw_indexed(all, 0, hemi.level_bands(hi).start..hemi.level_bands(lo).end);
            return;
        }
        for d in &self.draws {
            for cols in &d.columns {
                pass.draw_indexed(hemi.cells(cols), 0, hemi.level_bands(d.level));
            }
        }
    }

    fn bytes(&self) -> u64 {
        self.columns.size() + self.bands.size() + self.indices.size()
    }
}
