//! Nusselt: diffuse global illumination by the radiosity method.
//!
//! The pipeline: load a [`scene::Scene`] (an OBJ file, OBJ text, or a built-in), mesh its
//! faces into shooting patches and receiving elements ([`mesh::Mesh`]), solve by
//! progressive refinement ([`solver::ProgressiveSolver`], with form factors from
//! [`formfactor`]), and render the solution from a camera ([`render::render_solution`]) or
//! export it, lit, as glTF ([`export::gltf`]).
//!
//! This crate is the core: it never depends on a GUI, GPU or command-line crate (its
//! dependencies are glam, rayon, tobj, image, exr, serde and thiserror), so an engine or a
//! tool can embed the solver alone. The GPU hemicube (`nusselt-gpu`, plugged in through
//! [`formfactor::hemicube::ItemBufferRaster`]), the viewer (`nusselt-viewer`) and the
//! `nusselt` binary (CLI and bench harness) are crates of their own on top of it.
//!
//! # The whole pipeline
//!
//! The built-in Cornell box, coarsely meshed, 30 shots, a 32 × 32 image: its left wall is
//! red and its right wall green, as in the published photograph.
//!
//! ```
//! use std::sync::atomic::AtomicBool;
//!
//! use nusselt_core::mesh::MeshSpec;
//! use nusselt_core::render::{self, RenderSettings, SolutionView};
//! use nusselt_core::scene::{LoadOptions, Scene};
//! use nusselt_core::solver::{ProgressiveSolver, SolverConfig, StopCriteria};
//!
//! let scene = Scene::builtin("cornell", &LoadOptions::default())?;
//! let coarse = scene.bounds().diagonal() / 20.0; // the default is 1/80
//! let config = SolverConfig { mesh: MeshSpec::element(coarse), ..Default::default() };
//! let mut solver = ProgressiveSolver::new(scene, config)?;
//! let stop = StopCriteria { residual: 0.0, max_steps: Some(30), max_seconds: None, tolerance: None };
//! solver.run(&stop, &AtomicBool::new(false), &mut |_shot| {});
//! assert_eq!(solver.shots(), 30);
//!
//! // Radiance per display vertex (ambient term included), then ray-cast pixels.
//! let vertex = solver.mesh().vertex_values(&solver.display_radiance());
//! let bvh = render::display_bvh(solver.scene(), solver.mesh());
//! let view = SolutionView {
//!     scene: solver.scene(),
//!     mesh: solver.mesh(),
//!     vertex_radiance: &vertex,
//!     bvh: &bvh,
//!     texture: &[],
//! };
//! let camera = render::view::default_camera(solver.scene()); // the scene's own, here
//! let settings = RenderSettings { width: 32, height: 32, spp: 1, camera, seed: 1, edge_spp: 0 };
//! let image = render::render_solution(&view, &settings);
//!
//! // Mean colour of a column band of the middle rows.
//! let band = |x0: u32, x1: u32| {
//!     let mut sum = glam::DVec3::ZERO;
//!     for y in 12..20 {
//!         for x in x0..x1 {
//!             sum += image.get(x, y);
//!         }
//!     }
//!     sum
//! };
//! let (left, right) = (band(0, 3), band(29, 32));
//! assert!(left.x > 2.0 * left.y, "left wall red: {left}");
//! assert!(right.y > 2.0 * right.x, "right wall green: {right}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Loading a scene and meshing it
//!
//! OBJ text with its MTL library in memory ([`scene::Scene::from_obj_str`]; files go
//! through [`scene::Scene::load_obj`], the built-ins through [`scene::Scene::builtin`]):
//! a 1 × 1 floor under a 0.5 × 0.5 ceiling light. [`mesh::Mesh::build`] cuts every face into
//! elements of about the given size, grouped into shooting patches; the elements cover
//! the faces exactly.
//!
//! ```
//! use nusselt_core::mesh::{Mesh, MeshSpec};
//! use nusselt_core::scene::{LoadOptions, Scene};
//!
//! let obj = "mtllib room.mtl
//! v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1
//! v 0.25 1 0.25\nv 0.75 1 0.25\nv 0.75 1 0.75\nv 0.25 1 0.75
//! usemtl floor\nf 1 4 3 2
//! usemtl light\nf 5 6 7 8\n";
//! let mtl = "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 10 10 10\n";
//! let scene = Scene::from_obj_str("room.obj", obj, &[("room.mtl", mtl)], &LoadOptions::default())?;
//! assert_eq!(scene.faces.len(), 2);
//! assert!(scene.materials.iter().any(|m| m.name == "light" && m.is_emitter()));
//!
//! let mesh = Mesh::build(&scene, &MeshSpec::element(0.125))?;
//! let area: f64 = mesh.elements.iter().map(|e| e.area).sum();
//! assert!((area - 1.25).abs() < 1e-12, "{area}");
//! assert!(mesh.elements.len() >= (1.25 / (0.125 * 0.125)) as usize / 2);
//! assert!(mesh.patches.len() < mesh.elements.len());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
pub mod budget;
pub mod cases;
pub mod export;
pub mod formfactor;
pub mod geometry;
pub mod mesh;
pub mod render;
pub mod scene;
pub mod solver;
