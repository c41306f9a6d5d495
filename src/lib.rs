//! Nusselt: diffuse global illumination by the radiosity method.
//!
//! Core modules (`scene` … `render`) never depend on a GUI or GPU crate.
pub mod cli;
pub mod formfactor;
pub mod geometry;
pub mod mesh;
pub mod render;
pub mod scene;
pub mod solver;
pub mod viewer;
