//! GPU work, outside the core: the core (`scene` … `render`) never imports wgpu; it sees the
//! GPU hemicube only through [`ItemBufferRaster`](nusselt_core::formfactor::hemicube::ItemBufferRaster).
//! `wgpu` is a direct dependency pinned to the version egui-wgpu uses (the workspace's
//! `Cargo.toml`), so the viewer and this crate share one device type; the core's users get
//! the GPU hemicube without egui or eframe.

pub mod hemicube;

pub use hemicube::{GpuError, GpuHemicube};
