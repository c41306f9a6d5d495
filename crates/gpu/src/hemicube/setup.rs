//! Opening the GPU and building the hemicube's render pipeline (one `R32Uint` id target
//! with a `Depth32Float` depth test; per-face transforms as a dynamic-offset uniform and
//! per-polygon ids in a storage buffer read by the vertex shader).

use wgpu;

use super::{FaceUniform, GpuError, SHADER_SOURCE};

/// The first adapter wgpu finds (`WGPU_BACKEND` narrows the backends) other than OpenGL;
/// when OpenGL is all there is, [`GpuError::OpenGl`] says so (see [`super::GpuHemicube::new`]).
pub(super) fn request_adapter() -> Result<wgpu::Adapter, GpuError> {
    let from_env = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    let allowed = from_env.backends;
    let options = wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: None,
        apply_limit_buckets: false,
    };
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: allowed - wgpu::Backends::GL,
        ..from_env
    });
    match pollster::block_on(instance.request_adapter(&options)) {
        Ok(adapter) => Ok(adapter),
        Err(e) => {
            // Say so when OpenGL is what there is.
            if allowed.contains(wgpu::Backends::GL) {
                let gl = wgpu::Instance::new(wgpu::InstanceDescriptor {
                    backends: wgpu::Backends::GL,
                    ..wgpu::InstanceDescriptor::new_without_display_handle_from_env()
                });
                if let Ok(a) = pollster::block_on(gl.request_adapter(&options)) {
                    return Err(GpuError::OpenGl(a.get_info().name));
                }
            }
            Err(GpuError::NoAdapter(e.to_string()))
        }
    }
}

/// Binding 0: the face transforms (dynamic offset, one [`FaceUniform`] per face);
/// binding 1: the per-polygon ids.
pub(super) fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("nusselt hemicube"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: std::num::NonZeroU64::new(
                        std::mem::size_of::<FaceUniform>() as u64
                    ),
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only: true },
                    has_dynamic_offset: false,
                    min_binding_size: std::num::NonZeroU64::new(4),
                },
                count: None,
            },
        ],
    })
}

/// The id raster: positions (xyz) and the polygon index per vertex, ids written to an
/// `R32Uint` target, the nearer polygon kept by the depth test.
pub(super) fn render_pipeline(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
) -> wgpu::RenderPipeline {
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("nusselt hemicube"),
        source: wgpu::ShaderSource::Wgsl(SHADER_SOURCE.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("nusselt hemicube"),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    let attributes = [
        wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x3,
            offset: 0,
            shader_location: 0,
        },
        wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Uint32,
            offset: 12,
            shader_location: 1,
        },
    ];
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("nusselt hemicube"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &shader,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: 16,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &attributes,
            })],
        },
        fragment: Some(wgpu::FragmentState {
            module: &shader,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: wgpu::TextureFormat::R32Uint,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            // Depth is near/D: the nearer polygon has the greater value; ties keep the
            // first drawn, like the CPU's strict test.
            depth_compare: Some(wgpu::CompareFunction::Greater),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        multiview_mask: None,
        cache: None,
    })
}
