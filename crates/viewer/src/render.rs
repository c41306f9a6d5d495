//! The viewport's GPU side, after egui's `custom3d_wgpu` demo: the pipelines and buffers
//! live in egui-wgpu's callback resources; each frame a [`ViewportCallback`] carries the
//! latest snapshot (an `Arc`, no copy) and the uniforms; `prepare` uploads only what
//! changed since the last upload (mesh; radiance and display correction, by their ids) and
//! `paint` draws into egui's render pass, whose depth buffer eframe creates
//! (`NativeOptions::depth_buffer`).
//!
//! Diffuse maps: the scene's [`TextureLayers`] become one `Rgba16Float` 2-D texture array
//! (linear values, mip-mapped on the CPU, sampled with repeat wrap and trilinear
//! filtering), uploaded once per scene; per drawn vertex a buffer carries the texture
//! coordinates, the texture's mean over the vertex's elements and the layer, and another
//! the material's emission (rewritten after an edit), so the shader can show
//! `E + (B − E)·texel/mean` as `nusselt render` does.

use std::sync::Arc;

use eframe::egui;
use eframe::egui_wgpu::{self, wgpu};

use super::snapshot::Snapshot;
use super::textures::TextureLayers;

/// The texture array's format: linear half floats (never an sRGB format: the texels are
/// already linear).
pub const TEXTURE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
/// Bytes per drawn vertex of the texturing buffer: uv (2 × f32), mean (3 × f32), layer + 1
/// (u32).
pub const TEXTURING_STRIDE: u64 = 24;

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
    /// uv, mean, layer + 1 per drawn vertex (zeros, i.e. untextured, without textures).
    texturing: wgpu::Buffer,
    /// The material's emission per drawn vertex, and the `reflectance_rev` it is of.
    emission: wgpu::Buffer,
    emission_rev: u64,
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
    bind_group_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    bind_group: wgpu::BindGroup,
    mesh: Option<MeshBuffers>,
    /// The layers on the GPU (`None`: the 1 × 1 placeholder).
    textures: Option<Arc<TextureLayers>>,
    /// Bytes of the texture array on the GPU (0 with the placeholder).
    pub texture_bytes: usize,
    /// Bytes written by the last `prepare` (0 when nothing new arrived).
    pub last_upload_bytes: usize,
    /// Total uploads of radiance (one per new snapshot drawn).
    pub radiance_uploads: u64,
}

impl ViewportResources {
    /// Builds the pipelines and registers them with the renderer.
    pub fn install(render_state: &egui_wgpu::RenderState) {
        let resources = Self::new(
            &render_state.device,
            &render_state.queue,
            render_state.target_format,
        );
        render_state
            .renderer
            .write()
            .callback_resources
            .insert(resources);
    }

    fn new(device: &wgpu::Device, queue: &wgpu::Queue, target: wgpu::TextureFormat) -> Self {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("nusselt viewport"),
            source: wgpu::ShaderSource::Wgsl(SHADER_SOURCE.into()),
        });
        let bind_group_layout = bind_group_layout(device);
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("nusselt viewport"),
            bind_group_layouts: &[Some(&bind_group_layout)],
            immediate_size: 0,
        });
        let mesh_pipeline = mesh_pipeline(device, &layout, &shader, target);
        let line_pipeline = line_pipeline(device, &layout, &shader, target);
        let uniform_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("nusselt uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("nusselt diffuse maps"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            address_mode_w: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });
        let placeholder = placeholder_texture(device, queue);
        let bind_group = Self::bind_group(
            device,
            &bind_group_layout,
            &uniform_buffer,
            &placeholder,
            &sampler,
        );
        Self {
            mesh_pipeline,
            line_pipeline,
            uniform_buffer,
            bind_group_layout,
            sampler,
            bind_group,
            mesh: None,
            textures: None,
            texture_bytes: 0,
            last_upload_bytes: 0,
            radiance_uploads: 0,
        }
    }

    fn bind_group(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        uniforms: &wgpu::Buffer,
        texture: &wgpu::Texture,
        sampler: &wgpu::Sampler,
    ) -> wgpu::BindGroup {
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("nusselt diffuse maps"),
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("nusselt viewport"),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniforms.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(sampler),
                },
            ],
        })
    }

    /// Uploads the scene's texture layers when they are not the ones on the GPU; returns
    /// the bytes written. Layers the device cannot hold leave the placeholder (untextured).
    fn upload_textures(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        layers: Option<&Arc<TextureLayers>>,
    ) -> usize {
        let same = match (&self.textures, layers) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        };
        if same {
            return 0;
        }
        self.textures = layers.cloned();
        let Some(t) = layers else {
            // Back to the placeholder: the old array is dropped with its bind group.
            let placeholder = placeholder_texture(device, queue);
            self.bind_group = Self::bind_group(
                device,
                &self.bind_group_layout,
                &self.uniform_buffer,
                &placeholder,
                &self.sampler,
            );
            self.texture_bytes = 0;
            return 0;
        };
        let limits = device.limits();
        if t.size > limits.max_texture_dimension_2d || t.layers > limits.max_texture_array_layers {
            eprintln!(
                "viewer: {} texture layers of {}² exceed this GPU's limits ({} layers of {}²); drawing untextured",
                t.layers, t.size, limits.max_texture_array_layers, limits.max_texture_dimension_2d
            );
            return 0;
        }
        let mips = t.take_mips();
        if mips.len() != t.mip_levels as usize {
            // Taken by an earlier upload of this same array (not expected: the solver
            // thread makes a new array for each scene).
            eprintln!("viewer: the texture layers were already uploaded once; drawing untextured");
            return 0;
        }
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("nusselt diffuse maps"),
            size: wgpu::Extent3d {
                width: t.size,
                height: t.size,
                depth_or_array_layers: t.layers,
            },
            mip_level_count: t.mip_levels,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: TEXTURE_FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        // Each level's texels are freed once queued (wgpu has copied them).
        for (k, texels) in mips.into_iter().enumerate() {
            let side = (t.size >> k).max(1);
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: k as u32,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                bytemuck::cast_slice(&texels),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(side * super::textures::TEXEL_BYTES as u32),
                    rows_per_image: Some(side),
                },
                wgpu::Extent3d {
                    width: side,
                    height: side,
                    depth_or_array_layers: t.layers,
                },
            );
        }
        self.bind_group = Self::bind_group(
            device,
            &self.bind_group_layout,
            &self.uniform_buffer,
            &texture,
            &self.sampler,
        );
        self.texture_bytes = t.gpu_bytes();
        eprintln!(
            "viewer: uploaded {} texture layers of {}² ({} mips): {:.1} MB on the GPU",
            t.layers,
            t.size,
            t.mip_levels,
            self.texture_bytes as f64 / 1e6
        );
        self.texture_bytes
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
        let mut bytes = self.upload_textures(device, queue, snap.textures.as_ref());
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
            // Zero-initialised (untextured) unless the geometry has textures.
            let texturing = Self::vertex_buffer(device, "nusselt texturing", n * TEXTURING_STRIDE);
            if let Some(t) = &g.textures {
                let mut packed: Vec<u8> = Vec::with_capacity(t.uv.len() * 24);
                for ((uv, mean), layer) in t.uv.iter().zip(&t.mean).zip(&t.layer) {
                    packed.extend_from_slice(bytemuck::cast_slice(uv));
                    packed.extend_from_slice(bytemuck::cast_slice(mean));
                    packed.extend_from_slice(&layer.to_ne_bytes());
                }
                queue.write_buffer(&texturing, 0, &packed);
                bytes += packed.len();
            }
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
                texturing,
                emission: Self::vertex_buffer(device, "nusselt emission", n * 12),
                emission_rev: u64::MAX,
                element_lines,
                element_line_count: g.element_lines.len() as u32,
                patch_lines,
                patch_line_count: g.patch_lines.len() as u32,
            });
        }
        let Some(m) = self.mesh.as_mut() else { return };
        // Only the textured path reads the emission (`E + (B − E)·texel/mean`).
        if g.textures.is_some() && m.emission_rev != snap.reflectance_rev {
            let emission: Vec<[f32; 3]> = g
                .patch
                .iter()
                .map(|&p| {
                    let mat = g.patch_material[p as usize] as usize;
                    snap.materials
                        .get(mat)
                        .map_or([0.0; 3], |m| m.emission.as_vec3().to_array())
                })
                .collect();
            queue.write_buffer(&m.emission, 0, bytemuck::cast_slice(&emission));
            m.emission_rev = snap.reflectance_rev;
            bytes += emission.len() * 12;
        }
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
        pass.set_vertex_buffer(3, m.texturing.slice(..));
        pass.set_vertex_buffer(4, m.emission.slice(..));
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

/// Binding 0: the uniforms; 1: the diffuse maps (a texture array); 2: their sampler.
fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("nusselt viewport"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
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
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: true },
                    view_dimension: wgpu::TextureViewDimension::D2Array,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 2,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
        ],
    })
}

/// The depth test both pipelines use; only the mesh writes depth.
fn depth_state(write: bool) -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: DEPTH_FORMAT,
        depth_write_enabled: Some(write),
        depth_compare: Some(wgpu::CompareFunction::LessEqual),
        stencil: wgpu::StencilState::default(),
        bias: wgpu::DepthBiasState::default(),
    }
}

/// A `vec3<f32>` at the start of its buffer.
fn vec3_attribute(location: u32) -> wgpu::VertexAttribute {
    wgpu::VertexAttribute {
        format: wgpu::VertexFormat::Float32x3,
        offset: 0,
        shader_location: location,
    }
}

/// A per-vertex buffer of `stride` bytes holding `attributes`.
fn per_vertex(
    stride: u64,
    attributes: &[wgpu::VertexAttribute],
) -> Option<wgpu::VertexBufferLayout<'_>> {
    Some(wgpu::VertexBufferLayout {
        array_stride: stride,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes,
    })
}

/// The mesh: position and patch id, display correction, radiance, texturing and emission
/// in five buffers; back faces culled, depth written.
fn mesh_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    shader: &wgpu::ShaderModule,
    target: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let position_attrs = [
        vec3_attribute(0),
        wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Uint32,
            offset: 12,
            shader_location: 1,
        },
    ];
    let correction_attrs = [vec3_attribute(2)];
    let radiance_attrs = [vec3_attribute(3)];
    let texturing_attrs = [
        wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x2,
            offset: 0,
            shader_location: 4,
        },
        wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x3,
            offset: 8,
            shader_location: 5,
        },
        wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Uint32,
            offset: 20,
            shader_location: 6,
        },
    ];
    let emission_attrs = [vec3_attribute(7)];
    let mesh_buffers = [
        per_vertex(16, &position_attrs[..]),
        per_vertex(12, &correction_attrs[..]),
        per_vertex(12, &radiance_attrs[..]),
        per_vertex(TEXTURING_STRIDE, &texturing_attrs[..]),
        per_vertex(12, &emission_attrs[..]),
    ];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("nusselt mesh"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some("vs_mesh"),
            compilation_options: Default::default(),
            buffers: &mesh_buffers,
        },
        fragment: Some(wgpu::FragmentState {
            module: shader,
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
        depth_stencil: Some(depth_state(true)),
        multisample: wgpu::MultisampleState::default(),
        multiview_mask: None,
        cache: None,
    })
}

/// Element edges and patch outlines: alpha-blended lines, depth tested but not written.
fn line_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::PipelineLayout,
    shader: &wgpu::ShaderModule,
    target: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let line_attrs = [vec3_attribute(0)];
    let line_buffers = [per_vertex(12, &line_attrs[..])];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("nusselt lines"),
        layout: Some(layout),
        vertex: wgpu::VertexState {
            module: shader,
            entry_point: Some("vs_line"),
            compilation_options: Default::default(),
            buffers: &line_buffers,
        },
        fragment: Some(wgpu::FragmentState {
            module: shader,
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
        depth_stencil: Some(depth_state(false)),
        multisample: wgpu::MultisampleState::default(),
        multiview_mask: None,
        cache: None,
    })
}

/// The 1 × 1 texture bound while the scene has no diffuse maps (every vertex then has layer
/// 0, whose texel the shader does not show) or before its maps arrive: opaque white, so
/// that a textured vertex drawn meanwhile shows its mean colour and is no cut-out hole.
fn placeholder_texture(device: &wgpu::Device, queue: &wgpu::Queue) -> wgpu::Texture {
    use wgpu::util::DeviceExt;
    let one = half::f16::from_f32(1.0).to_bits().to_ne_bytes();
    let texel: Vec<u8> = one.iter().copied().cycle().take(8).collect();
    device.create_texture_with_data(
        queue,
        &wgpu::TextureDescriptor {
            label: Some("nusselt no diffuse maps"),
            size: wgpu::Extent3d {
                width: 1,
                height: 1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: TEXTURE_FORMAT,
            usage: wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        &texel,
    )
}
