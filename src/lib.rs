//! Nusselt: diffuse global illumination by the radiosity method.
//!
//! Core modules (`scene` … `render`) never depend on a GUI or GPU crate; `gpu` (the wgpu
//! hemicube, plugged into the core through `formfactor::hemicube::ItemBufferRaster`),
//! `viewer` and `cli` sit outside the core.
pub mod cli;
pub mod formfactor;
pub mod geometry;
pub mod gpu;
pub mod mesh;
pub mod render;
pub mod scene;
pub mod solver;
pub mod viewer;
