//! The viewport's GPU side, after egui's `custom3d_wgpu` demo: the pipelines and buffers
//! live in egui-wgpu's callback resources; each frame a [`ViewportCallback`] carries the
//! latest snapshot (an `Arc`, no copy) and the uniforms; `prepare` uploads only what
//! changed since the last upload (mesh; radiance and display correction, by their ids) and
//! `paint` draws into egui's render pass, whose depth buffer eframe creates
//! (`NativeOptions::depth_buffer`).

use std::sync::Arc;

use eframe::egui;
use eframe::egui_wgpu::{self, wgpu};

use super::snapshot::Snapshot;

/// Depth format: must match `NativeOptions::depth_buffer = 32`.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// `NativeOptions::depth_buffer` for [`DEPTH_FORMAT`].
pub const DEPTH_BITS: u8 = 32;

pub const SHADER_SOURCE: &str = include_str!("../../../shaders/viewport.wgsl");

/// Matches `Uniforms` in `shaders/viewport.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Uniforms {
    pub view_proj: [[f32; 4]; 4],
    pub ambient_exposure: [f32; 4],
    pub ids: [u32; 4],
    pub element_line_color: [f32; 4],
    pub patch_line_color: [f32; 4],
    pub params: [f32; 4],
}

pub const NO_PATCH: u32 = u32::MAX;
pub const FLAG_SHOOTER: u32 = 1;
pub const FLAG_SELECTION: u32 = 2;

/// What to draw besides the surfaces.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Overlays {
    pub element_edges: bool,
    pub patch_outlines: bool,
}

/// GPU buffers of one snapshot.
struct MeshBuffers {
    geometry_id: u64,
    radiance_seq: u64,
    vertex_count: u32,
    index_count: u32,
    /// position (12 bytes) + patch id (4 bytes) per drawn vertex.
    positions: wgpu::Buffer,
    /// Three drawn vertices per triangle (u32).
    indices: wgpu::Buffer,
    /// The display correction (`Snapshot::correction`), scaled by the ambient uniform.
    correction: wgpu::Buffer,
    radiance: wgpu::Buffer,
    element_lines: wgpu::Buffer,
    element_line_count: u32,
    patch_lines: wgpu::Buffer,
    patch_line_count: u32,
}

/// Pipelines and buffers, stored in egui-wgpu's `callback_resources`.
pub struct ViewportResources {
    mesh_pipeline: wgpu::RenderPipeline,
    line_pipeline: wgpu::RenderPipeline,
    uniform_buffer: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    mesh: Option<MeshBuffers>,
    /// Bytes written by the last `prepare` (0 when nothing new arrived).
    pub last_upload_bytes: usize,
    /// Total uploads of radiance (one per new snapshot drawn).
    pub radiance_uploads: u64,
}

impl ViewportResources {
    /// Builds the pipelines and registers them with the renderer.
    pub fn install(render_state: &egui_wgpu::RenderState) {
        let resources = Self::new(&render_state.device, render_state.target_format);
        render_state
            .renderer
            .write()
            .callback_resources
            .insert(resources);
    }

    fn new(device: &wgpu::Device, target: wgpu::TextureFormat) -> Self {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("nusselt viewport"),
            source: wgpu::ShaderSource::Wgsl(SHADER_SOURCE.into()),
        });
        let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("nusselt viewport"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: std::num::NonZeroU64::new(
                        std::mem::size_of::<Uniforms>() as u64
                    ),
                },
                count: None,
            }],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("nusselt viewport"),
            bind_group_layouts: &[Some(&bind_group_layout)],
            immediate_size: 0,
        });
        let depth = |write: bool| wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(write),
            depth_compare: Some(wgpu::CompareFunction::LessEqual),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        };
        let vec3 = |location| wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x3,
            offset: 0,
            shader_location: location,
        };
        let position_attrs = [
            vec3(0),
            wgpu::VertexAttribute {
                format: wgpu::VertexFormat::Uint32,
                offset: 12,
                shader_location: 1,
            },
        ];
        let correction_attrs = [vec3(2)];
        let radiance_attrs = [vec3(3)];
        let per_vertex = |stride: u64, attributes| {
            Some(wgpu::VertexBufferLayout {
                array_stride: stride,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes,
            })
        };
        let mesh_buffers = [
            per_vertex(16, &position_attrs[..]),
            per_vertex(12, &correction_attrs[..]),
            per_vertex(12, &radiance_attrs[..]),
        ];
        let mesh_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("nusselt mesh"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_mesh"),
                compilation_options: Default::default(),
                buffers: &mesh_buffers,
            },
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_mesh"),
                compilation_options: Default::default(),
                targets: &[Some(target.into())],
            }),
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                // Faces reflect on their front; from outside a closed room you see in.
                cull_mode: Some(wgpu::Face::Back),
                ..Default::default()
            },
            depth_stencil: Some(depth(true)),
            multisample: wgpu::MultisampleState::default(),
            multiview_mask: None,
            cache: None,
        });
        let line_attrs = [vec3(0)];
        let line_buffers = [per_vertex(12, &line_attrs[..])];
        let line_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("nusselt lines"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_line"),
                compilation_options: Default::default(),
                buffers: &line_buffers,
            },
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_line"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: target,
                    blend: Some(wgpu::BlendState::ALPHA_BLENDING),
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::LineList,
                ..Default::default()
            },
            depth_stencil: Some(depth(false)),
            multisample: wgpu::MultisampleState::default(),
            multiview_mask: None,
            cache: None,
        });
        let uniform_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("nusselt uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("nusselt viewport"),
            layout: &bind_group_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform_buffer.as_entire_binding(),
            }],
        });
        Self {
            mesh_pipeline,
            line_pipeline,
            uniform_buffer,
            bind_group,
            mesh: None,
            last_upload_bytes: 0,
            radiance_uploads: 0,
        }
    }

    fn vertex_buffer(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            // wgpu rejects empty vertex buffers in some backends: keep at least 16 bytes.
            size: bytes.max(16).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT),
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Uploads what differs from what is on the GPU.
    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, snap: &Snapshot) {
        let g = &snap.geometry;
        let mut bytes = 0usize;
        if self.mesh.as_ref().is_none_or(|m| m.geometry_id != g.id) {
            let n = g.positions.len() as u64;
            let mut packed: Vec<u8> = Vec::with_capacity(g.positions.len() * 16);
            for (p, id) in g.positions.iter().zip(&g.patch) {
                packed.extend_from_slice(bytemuck::cast_slice(p));
                packed.extend_from_slice(&id.to_ne_bytes());
            }
            let positions = Self::vertex_buffer(device, "nusselt positions", n * 16);
            queue.write_buffer(&positions, 0, &packed);
            let indices = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("nusselt indices"),
                size: (g.indices.len() as u64 * 4)
                    .max(16)
                    .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT),
                usage: wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            queue.write_buffer(&indices, 0, bytemuck::cast_slice(&g.indices));
            let element_lines = Self::vertex_buffer(
                device,
                "nusselt element lines",
                g.element_lines.len() as u64 * 12,
            );
            queue.write_buffer(&element_lines, 0, bytemuck::cast_slice(&g.element_lines));
            let patch_lines = Self::vertex_buffer(
                device,
                "nusselt patch lines",
                g.patch_lines.len() as u64 * 12,
            );
            queue.write_buffer(&patch_lines, 0, bytemuck::cast_slice(&g.patch_lines));
            bytes += packed.len()
                + g.indices.len() * 4
                + g.element_lines.len() * 12
                + g.patch_lines.len() * 12;
            self.mesh = Some(MeshBuffers {
                geometry_id: g.id,
                radiance_seq: u64::MAX,
                vertex_count: g.positions.len() as u32,
                index_count: g.indices.len() as u32,
                positions,
                indices,
                correction: Self::vertex_buffer(device, "nusselt correction", n * 12),
                radiance: Self::vertex_buffer(device, "nusselt radiance", n * 12),
                element_lines,
                element_line_count: g.element_lines.len() as u32,
                patch_lines,
                patch_line_count: g.patch_lines.len() as u32,
            });
        }
        let Some(m) = self.mesh.as_mut() else { return };
        let fits = |v: &Vec<[f32; 3]>| v.len() == m.vertex_count as usize;
        if m.radiance_seq != snap.seq && fits(&snap.radiance) && fits(&snap.correction) {
            queue.write_buffer(&m.correction, 0, bytemuck::cast_slice(&snap.correction));
            bytes += snap.correction.len() * 12;
            queue.write_buffer(&m.radiance, 0, bytemuck::cast_slice(&snap.radiance));
            m.radiance_seq = snap.seq;
            bytes += snap.radiance.len() * 12;
            self.radiance_uploads += 1;
        }
        self.last_upload_bytes = bytes;
    }

    fn paint(&self, pass: &mut wgpu::RenderPass<'static>, overlays: Overlays) {
        let Some(m) = &self.mesh else { return };
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&self.mesh_pipeline);
        pass.set_vertex_buffer(0, m.positions.slice(..));
        pass.set_vertex_buffer(1, m.correction.slice(..));
        pass.set_vertex_buffer(2, m.radiance.slice(..));
        pass.set_index_buffer(m.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..m.index_count, 0, 0..1);
        if overlays.element_edges && m.element_line_count > 0 {
            pass.set_pipeline(&self.line_pipeline);
            pass.set_vertex_buffer(0, m.element_lines.slice(..));
            pass.draw(0..m.element_line_count, 0..1);
        }
        if overlays.patch_outlines && m.patch_line_count > 0 {
            pass.set_pipeline(&self.line_pipeline);
            pass.set_vertex_buffer(0, m.patch_lines.slice(..));
            pass.draw(0..m.patch_line_count, 1..2);
        }
    }
}

/// One frame's draw of the viewport.
pub struct ViewportCallback {
    pub snapshot: Option<Arc<Snapshot>>,
    pub uniforms: Uniforms,
    pub overlays: Overlays,
}

impl egui_wgpu::CallbackTrait for ViewportCallback {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        _encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        if let Some(r) = resources.get_mut::<ViewportResources>() {
            queue.write_buffer(&r.uniform_buffer, 0, bytemuck::bytes_of(&self.uniforms));
            r.last_upload_bytes = 0;
            if let Some(s) = &self.snapshot {
                r.upload(device, queue, s);
            }
        }
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        pass: &mut wgpu::RenderPass<'static>,
        resources: &egui_wgpu::CallbackResources,
    ) {
        if let Some(r) = resources.get::<ViewportResources>() {
            r.paint(pass, self.overlays);
        }
    }
}
