//! GPU work, outside the core: the core (`scene` … `render`) never imports wgpu; it sees the
//! GPU hemicube only through [`ItemBufferRaster`](crate::formfactor::hemicube::ItemBufferRaster).
//! wgpu comes through `eframe::egui_wgpu::wgpu`, so the viewer and this module can never
//! use two different versions.

pub mod hemicube;

pub use hemicube::{GpuError, GpuHemicube};
