//! The item-buffer hemicube (Cohen & Greenberg 1985) rasterised by a GPU through wgpu.
//!
//! Same method as the CPU hemicube (`crates/core/src/formfactor/hemicube.rs`), only the z-buffered id
//! raster moves to the GPU: the five faces are drawn into viewports of one `R32Uint` atlas
//! (`shaders/hemicube.wgsl`), the atlas is copied back, and the CPU sums each pixel's delta
//! form factor into its id in f64 in the CPU hemicube's order — so wherever both rasterise
//! the same ids the results are bit-identical. Known differences from the CPU rasteriser: the
//! GPU works in f32 (positions relative to the scene's centre, depth `near/D`) and fills a
//! pixel whose centre lies exactly on an edge by the top-left rule where the CPU fills it for
//! both polygons (nearest wins), so pixels along silhouettes can differ; the measured effect
//! is in docs/FORMFACTORS.md. Everything else (aliasing, point approximation) is the
//! hemicube's own error.
//!
//! One `GpuHemicube` owns its device; calls are serialised by a mutex (the solver computes
//! one row at a time). The geometry is uploaded once per mesh (`key`), each shot uploads
//! only the per-polygon ids and 5 face transforms, and reads back `3·res²` ids.

use std::sync::Mutex;

use glam::DVec3;
use wgpu;

use nusselt_core::formfactor::hemicube::{
    DeltaTable, HemicubeView, ItemBufferRaster, NONE, RasterError, SKIP,
};

mod setup;
mod targets;

use targets::{Chunk, Geometry, Target, face_rows};

/// The WGSL source (validated by `tests/viewer_shaders.rs` with naga).
pub const SHADER_SOURCE: &str = include_str!("../../../shaders/hemicube.wgsl");

/// Uniform stride per face (wgpu's minimum dynamic-offset alignment is at most 256).
const FACE_STRIDE: u64 = 256;

/// Polygons per culling chunk: each face draws only the chunks whose bounding sphere meets
/// its frustum (a mesh's elements are stored patch by patch, so chunks are compact).
const CHUNK_POLYGONS: usize = 32;

/// Setting up the GPU failed.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found (on a machine without a GPU install Mesa's lavapipe: apt-get install mesa-vulkan-drivers libvulkan1): {0}"
    )]
    NoAdapter(String),
    #[error("the GPU adapter '{0}' cannot read storage buffers in vertex shaders")]
    NoVertexStorage(String),
    #[error("could not open the GPU device: {0}")]
    Device(String),
    #[error(
        "the only GPU adapter is OpenGL ('{0}'), on which the GPU hemicube's item buffers come out empty (its depth remap to [-1, 1] most likely loses the near/D depths near 0): the GPU hemicube needs Vulkan, Metal or DX12 (on Linux without a GPU: apt-get install mesa-vulkan-drivers libvulkan1); the CPU hemicube gives the same form factors"
    )]
    OpenGl(String),
}

/// One face's transform, as the shader's `Face` struct.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FaceUniform {
    pub origin: [f32; 4],
    pub axis_u: [f32; 4],
    pub axis_v: [f32; 4],
    pub axis_w: [f32; 4],
    pub params: [u32; 4],
}

/// A wgpu hemicube rasteriser (see the module docs).
pub struct GpuHemicube {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: String,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    uniforms: wgpu::Buffer,
    state: Mutex<State>,
}

impl std::fmt::Debug for GpuHemicube {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuHemicube")
            .field("adapter", &self.adapter)
            .finish_non_exhaustive()
    }
}

#[derive(Default)]
struct State {
    geometry: Option<Geometry>,
    target: Option<Target>,
    /// Per-polygon ids (storage) and the bind group that uses it.
    ids: Option<(wgpu::Buffer, wgpu::BindGroup, u64)>,
}

impl GpuHemicube {
    /// Opens the first adapter wgpu finds (`WGPU_BACKEND` narrows the backends) other than
    /// OpenGL and builds the pipeline. OpenGL is refused ([`GpuError::OpenGl`]): on Mesa's
    /// llvmpipe GL the form factors came out zero wherever the near plane was 1e-9 (the
    /// occluder and Cornell tests) and right where it was about 1e-3 of the scene (the
    /// item-buffer test): most likely the depth remap `2z − 1` of a GL without clip control
    /// rounds the depths `near/D` to the cleared 0, so every polygon fails the depth test.
    pub fn new() -> Result<Self, GpuError> {
        let adapter = setup::request_adapter()?;
        let info = adapter.get_info();
        let name = format!("{} ({:?})", info.name, info.backend);
        if !adapter
            .get_downlevel_capabilities()
            .flags
            .contains(wgpu::DownlevelFlags::VERTEX_STORAGE)
        {
            return Err(GpuError::NoVertexStorage(name));
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("nusselt hemicube"),
            required_features: wgpu::Features::empty(),
            required_limits: adapter.limits(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| GpuError::Device(e.to_string()))?;
        let layout = setup::bind_group_layout(&device);
        let pipeline = setup::render_pipeline(&device, &layout);
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("nusselt hemicube faces"),
            size: 5 * FACE_STRIDE,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(Self {
            device,
            queue,
            adapter: name,
            pipeline,
            layout,
            uniforms,
            state: Mutex::new(State::default()),
        })
    }

    /// The adapter's name and backend (e.g. "llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan)").
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// Draws the hemicube and returns the raw item buffer, face by face (`res × res` top,
    /// then four `res/2 × res` sides, rows as in [`DeltaTable::deltas`]). For tests and
    /// [`ItemBufferRaster::form_factors`].
    pub fn item_buffer(
        &self,
        key: u64,
        polygons: &dyn Fn() -> Vec<Vec<DVec3>>,
        view: &HemicubeView,
        res: u32,
        ids: &[u32],
    ) -> Result<Vec<u32>, RasterError> {
        let res = res.max(2).div_ceil(2) * 2;
        let mut state = self
            .state
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let centre = self.prepare(&mut state, key, polygons, res, ids)?;
        self.write_faces(view, centre);
        let state = &*state;
        let target = state.target.as_ref().expect("prepared");
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("nusselt hemicube"),
            });
        self.draw_faces(&mut encoder, state, view, res, ids);
        copy_to_readback(&mut encoder, target, res);
        self.queue.submit(Some(encoder.finish()));
        self.read_back(target, res)
    }

    /// Makes `state` ready to draw: the geometry for `key` (uploaded when it changed), the
    /// atlas for `res` and `ids` in the storage buffer; checks `ids` against the polygons
    /// and `res` against the GPU. Returns the geometry's centre.
    fn prepare(
        &self,
        state: &mut State,
        key: u64,
        polygons: &dyn Fn() -> Vec<Vec<DVec3>>,
        res: u32,
        ids: &[u32],
    ) -> Result<DVec3, RasterError> {
        if state.geometry.as_ref().is_none_or(|g| g.key != key) {
            state.geometry = Some(self.upload_geometry(key, &polygons()));
            state.ids = None;
        }
        let geometry = state.geometry.as_ref().expect("just set");
        if ids.len() != geometry.polygon_count {
            return Err(RasterError(format!(
                "{} ids for {} polygons",
                ids.len(),
                geometry.polygon_count
            )));
        }
        let centre = geometry.centre;
        let max_dim = self.device.limits().max_texture_dimension_2d;
        if 3 * res > max_dim {
            return Err(RasterError(format!(
                "hemicube resolution {res} needs a {res}×{} texture; this GPU allows {max_dim}",
                3 * res
            )));
        }
        if state.target.as_ref().is_none_or(|t| t.res != res) {
            state.target = Some(self.make_target(res));
        }
        let id_bytes = (ids.len().max(1) * 4) as u64;
        if state
            .ids
            .as_ref()
            .is_none_or(|(_, _, size)| *size < id_bytes)
        {
            let (buffer, bind_group) = self.id_binding(id_bytes);
            state.ids = Some((buffer, bind_group, id_bytes));
        }
        let (id_buffer, _, _) = state.ids.as_ref().expect("just set");
        if !ids.is_empty() {
            self.queue
                .write_buffer(id_buffer, 0, bytemuck::cast_slice(ids));
        }
        Ok(centre)
    }

    /// A storage buffer for `size` bytes of ids, and the bind group that reads it with the
    /// face transforms.
    fn id_binding(&self, size: u64) -> (wgpu::Buffer, wgpu::BindGroup) {
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("nusselt hemicube ids"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("nusselt hemicube"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &self.uniforms,
                        offset: 0,
                        size: std::num::NonZeroU64::new(std::mem::size_of::<FaceUniform>() as u64),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: buffer.as_entire_binding(),
                },
            ],
        });
        (buffer, bind_group)
    }

    /// Uploads the five face transforms of `view`, relative to the geometry's `centre`.
    fn write_faces(&self, view: &HemicubeView, centre: DVec3) {
        let o = view.origin - centre;
        let v4 = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        let mut faces = vec![0u8; (5 * FACE_STRIDE) as usize];
        for f in 0..5u32 {
            let u = FaceUniform {
                origin: v4(o),
                axis_u: v4(view.axes[0]),
                axis_v: v4(view.axes[1]),
                axis_w: v4(view.axes[2]),
                params: [f, (view.near.max(1e-30) as f32).to_bits(), 0, 0],
            };
            let at = (f as u64 * FACE_STRIDE) as usize;
            faces[at..at + std::mem::size_of::<FaceUniform>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
        }
        self.queue.write_buffer(&self.uniforms, 0, &faces);
    }

    /// One render pass drawing the five faces into their viewports of the atlas (cleared
    /// to [`NONE`]), each with the chunks that may show on it.
    fn draw_faces(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        state: &State,
        view: &HemicubeView,
        res: u32,
        ids: &[u32],
    ) {
        let target = state.target.as_ref().expect("prepared");
        let geometry = state.geometry.as_ref().expect("prepared");
        let (_, bind_group, _) = state.ids.as_ref().expect("prepared");
        let color_view = target
            .ids
            .create_view(&wgpu::TextureViewDescriptor::default());
        let depth_view = target
            .depth
            .create_view(&wgpu::TextureViewDescriptor::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("nusselt hemicube"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: NONE as f64,
                        g: 0.0,
                        b: 0.0,
                        a: 0.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_vertex_buffer(0, geometry.vertices.slice(..));
        // Chunks with something to draw (not all SKIP), in order.
        let live: Vec<&Chunk> = geometry
            .chunks
            .iter()
            .filter(|c| ids[c.polygons.clone()].iter().any(|id| *id != SKIP))
            .collect();
        for f in 0..5u32 {
            let (y, rows) = face_rows(f, res);
            pass.set_viewport(0.0, y as f32, res as f32, rows as f32, 0.0, 1.0);
            pass.set_scissor_rect(0, y, res, rows);
            pass.set_bind_group(0, bind_group, &[(f as u64 * FACE_STRIDE) as u32]);
            draw_chunks(&mut pass, &live, f, view);
        }
    }

    /// Waits for the copied atlas and reads it back, row by row without the padding.
    fn read_back(&self, target: &Target, res: u32) -> Result<Vec<u32>, RasterError> {
        let (sender, receiver) = std::sync::mpsc::sync_channel(1);
        target
            .readback
            .map_async(wgpu::MapMode::Read, .., move |r| {
                // The receiver waits below; a full channel cannot happen (one message).
                let _ = sender.try_send(r);
            });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RasterError(format!("waiting for the GPU: {e}")))?;
        receiver
            .recv()
            .map_err(|_| RasterError("the GPU never answered the read-back".into()))?
            .map_err(|e| RasterError(format!("reading the hemicube back: {e}")))?;
        let mut out = Vec::with_capacity((3 * res * res) as usize);
        {
            let data = target
                .readback
                .get_mapped_range(..)
                .map_err(|e| RasterError(format!("reading the hemicube back: {e}")))?;
            for row in 0..(3 * res) as usize {
                let at = row * target.padded_row as usize;
                let bytes = &data[at..at + 4 * res as usize];
                out.extend(
                    bytes
                        .chunks_exact(4)
                        .map(|b| u32::from_ne_bytes([b[0], b[1], b[2], b[3]])),
                );
            }
        }
        target.readback.unmap();
        Ok(out)
    }
}

/// Draws the `live` chunks that may show on face `f`; consecutive ones merge into one draw
/// (order is kept, so depth ties resolve as on the CPU).
fn draw_chunks(pass: &mut wgpu::RenderPass<'_>, live: &[&Chunk], f: u32, view: &HemicubeView) {
    let mut run: Option<std::ops::Range<u32>> = None;
    for c in live.iter().filter(|c| c.may_show_on(f as usize, view)) {
        run = match run {
            Some(r) if r.end == c.vertices.start => Some(r.start..c.vertices.end),
            Some(r) => {
                pass.draw(r, 0..1);
                Some(c.vertices.clone())
            }
            None => Some(c.vertices.clone()),
        };
    }
    if let Some(r) = run {
        pass.draw(r, 0..1);
    }
}

/// Copies the drawn atlas into the read-back buffer (rows padded as wgpu requires).
fn copy_to_readback(encoder: &mut wgpu::CommandEncoder, target: &Target, res: u32) {
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: &target.ids,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &target.readback,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(target.padded_row),
                rows_per_image: Some(3 * res),
            },
        },
        wgpu::Extent3d {
            width: res,
            height: 3 * res,
            depth_or_array_layers: 1,
        },
    );
}

impl ItemBufferRaster for GpuHemicube {
    fn describe(&self) -> String {
        format!("GPU hemicube on {}", self.adapter)
    }

    fn form_factors(
        &self,
        key: u64,
        polygons: &dyn Fn() -> Vec<Vec<DVec3>>,
        view: &HemicubeView,
        table: &DeltaTable,
        ids: &[u32],
        n: usize,
    ) -> Result<Vec<f64>, RasterError> {
        let res = table.res() as u32;
        let buffer = self.item_buffer(key, polygons, view, res, ids)?;
        let mut out = vec![0.0; n];
        let mut at = 0usize;
        for f in 0..5usize {
            let len = table.deltas(f).len();
            table.accumulate_face(f, &buffer[at..at + len], &mut out);
            at += len;
        }
        Ok(out)
    }
}
