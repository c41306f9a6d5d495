//! What the GPU hemicube keeps between shots: the mesh's polygons uploaded once per key
//! (positions relative to their centre, in chunks with bounding spheres so that a face's
//! draw skips what cannot show on it) and the render target (the `R32Uint` id atlas, its
//! depth buffer and the read-back buffer), and where each hemicube face lies in the atlas.

use glam::DVec3;
use wgpu;

use super::{CHUNK_POLYGONS, GpuHemicube};
use nusselt_core::formfactor::hemicube::{HemicubeView, to_face};

pub(super) struct Geometry {
    pub(super) key: u64,
    pub(super) vertices: wgpu::Buffer,
    pub(super) polygon_count: usize,
    /// Vertex positions are stored relative to this point (f32 precision near the scene).
    pub(super) centre: DVec3,
    pub(super) chunks: Vec<Chunk>,
}

/// A run of consecutive polygons with its bounding sphere.
pub(super) struct Chunk {
    pub(super) polygons: std::ops::Range<usize>,
    pub(super) vertices: std::ops::Range<u32>,
    pub(super) centre: DVec3,
    pub(super) radius: f64,
}

impl Chunk {
    /// Whether the sphere may cover pixels of face `f` of `view` (conservative).
    pub(super) fn may_show_on(&self, f: usize, view: &HemicubeView) -> bool {
        let d = self.centre - view.origin;
        let local = [
            d.dot(view.axes[0]),
            d.dot(view.axes[1]),
            d.dot(view.axes[2]),
        ];
        let [x, y, depth] = to_face(f, &local);
        let r = self.radius;
        let slanted = r * std::f64::consts::SQRT_2;
        let below = if f == 0 { y + depth < -slanted } else { y < -r };
        !(depth + r < view.near
            || x + depth < -slanted
            || depth - x < -slanted
            || depth - y < -slanted
            || below)
    }
}

pub(super) struct Target {
    pub(super) res: u32,
    pub(super) ids: wgpu::Texture,
    pub(super) depth: wgpu::Texture,
    pub(super) readback: wgpu::Buffer,
    pub(super) padded_row: u32,
}

impl GpuHemicube {
    pub(super) fn upload_geometry(&self, key: u64, polygons: &[Vec<DVec3>]) -> Geometry {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in polygons.iter().flatten() {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let centre = if lo.x.is_finite() {
            (lo + hi) * 0.5
        } else {
            DVec3::ZERO
        };
        let mut bytes: Vec<u8> = Vec::new();
        let mut push = |p: DVec3, k: u32| {
            let q = p - centre;
            bytes.extend_from_slice(bytemuck::cast_slice(&[q.x as f32, q.y as f32, q.z as f32]));
            bytes.extend_from_slice(&k.to_ne_bytes());
        };
        let mut vertex_count = 0u32;
        let mut chunks = Vec::new();
        for first in (0..polygons.len()).step_by(CHUNK_POLYGONS) {
            let range = first..(first + CHUNK_POLYGONS).min(polygons.len());
            let start = vertex_count;
            let (mut clo, mut chi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
            for k in range.clone() {
                let poly = &polygons[k];
                // Convex polygons: a fan.
                for i in 1..poly.len().saturating_sub(1) {
                    push(poly[0], k as u32);
                    push(poly[i], k as u32);
                    push(poly[i + 1], k as u32);
                    vertex_count += 3;
                }
                for p in poly {
                    clo = clo.min(*p);
                    chi = chi.max(*p);
                }
            }
            if clo.x.is_finite() {
                let c = (clo + chi) * 0.5;
                let radius = range
                    .clone()
                    .flat_map(|k| polygons[k].iter())
                    .map(|p| (*p - c).length())
                    .fold(0.0, f64::max);
                chunks.push(Chunk {
                    polygons: range,
                    vertices: start..vertex_count,
                    centre: c,
                    // f32 positions: a little room.
                    radius: radius * (1.0 + 1e-5) + 1e-6 * (c - centre).length(),
                });
            }
        }
        let size = (bytes.len() as u64).max(16);
        let vertices = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("nusselt hemicube vertices"),
            size: size.next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT),
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        if !bytes.is_empty() {
            self.queue.write_buffer(&vertices, 0, &bytes);
        }
        Geometry {
            key,
            vertices,
            polygon_count: polygons.len(),
            centre,
            chunks,
        }
    }

    pub(super) fn make_target(&self, res: u32) -> Target {
        let size = wgpu::Extent3d {
            width: res,
            height: 3 * res,
            depth_or_array_layers: 1,
        };
        let texture = |label, format, usage| {
            self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let ids = texture(
            "nusselt hemicube ids",
            wgpu::TextureFormat::R32Uint,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth = texture(
            "nusselt hemicube depth",
            wgpu::TextureFormat::Depth32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let padded_row = (4 * res).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("nusselt hemicube read-back"),
            size: padded_row as u64 * 3 * res as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Target {
            res,
            ids,
            depth,
            readback,
            padded_row,
        }
    }
}

/// First atlas row and row count of face `f`.
pub(super) fn face_rows(f: u32, res: u32) -> (u32, u32) {
    if f == 0 {
        (0, res)
    } else {
        (res + (f - 1) * (res / 2), res / 2)
    }
}
