//! What the solver thread publishes and the UI draws: GPU-ready arrays built off the UI
//! thread, shared by `Arc` so that taking a snapshot never copies or waits.
//!
//! Drawn vertices are the mesh's display vertices, one per patch that uses them (a mesh
//! vertex on a patch boundary is drawn once per patch), indexed by the display triangles.
//! So every triangle's three vertices carry its patch id, which the shader reads as a flat
//! attribute to highlight the shooting and the selected patch, while radiance is sent once
//! per vertex instead of once per triangle corner (about 4× fewer bytes per snapshot; see
//! docs/VIEWER.md). Radiance is stored without the ambient term together with the
//! per-vertex display correction `ρ·G` (the solver's ambient term, regional for shooting:
//! `crates/core/src/solver/ambient.rs`), so the ambient toggle is a uniform multiplier of it.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

use glam::DVec3;

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::geometry::Bvh;
use nusselt_core::geometry::bvh::TriangleInput;
use nusselt_core::mesh::{Mesh, PatchId};
use nusselt_core::scene::{Camera, Material, Rgb};
use nusselt_core::solver::SolverKind;

/// Mesh arrays for drawing and picking; rebuilt only when the mesh changes.
#[derive(Debug)]
pub struct Geometry {
    /// Changes whenever the mesh does (new scene or re-mesh).
    pub id: u64,
    /// Per drawn vertex.
    pub positions: Vec<[f32; 3]>,
    /// Patch id per drawn vertex.
    pub patch: Vec<u32>,
    /// Mesh display vertex of each drawn vertex (to expand per-vertex values).
    pub source_vertex: Vec<u32>,
    /// Drawn vertices of the display triangles, three per triangle (the index buffer).
    pub indices: Vec<u32>,
    /// Element edges as line-list endpoints.
    pub element_lines: Vec<[f32; 3]>,
    /// Patch outlines as line-list endpoints.
    pub patch_lines: Vec<[f32; 3]>,
    /// Display triangles (ids = triangle index) for picking.
    pub bvh: Bvh,
    /// Element of each display triangle.
    pub triangle_element: Vec<u32>,
    /// Patch of each element.
    pub element_patch: Vec<u32>,
    /// Material of each patch.
    pub patch_material: Vec<u32>,
    pub bounds_min: DVec3,
    pub bounds_max: DVec3,
    pub elements: usize,
    pub patches: usize,
    pub element_size: f64,
}

impl Geometry {
    pub fn from_mesh(id: u64, mesh: &Mesh) -> Geometry {
        let n = mesh.vertices.len();
        let mut positions = Vec::with_capacity(n);
        let mut patch = Vec::with_capacity(n);
        let mut source_vertex = Vec::with_capacity(n);
        let mut indices = Vec::with_capacity(mesh.triangles.len() * 3);
        let mut drawn: HashMap<(u32, u32), u32> = HashMap::with_capacity(n);
        let mut inputs = Vec::with_capacity(mesh.triangles.len());
        for (i, (t, e)) in mesh
            .triangles
            .iter()
            .zip(&mesh.triangle_element)
            .enumerate()
        {
            let pid = mesh.elements[e.0 as usize].patch.0;
            for &v in t {
                let d = *drawn.entry((v, pid)).or_insert_with(|| {
                    positions.push(mesh.vertices[v as usize].as_vec3().to_array());
                    patch.push(pid);
                    source_vertex.push(v);
                    source_vertex.len() as u32 - 1
                });
                indices.push(d);
            }
            inputs.push(TriangleInput {
                vertices: t.map(|v| mesh.vertices[v as usize]),
                id: i as u32,
                // Matches the viewport, which culls back faces.
                cull_back: true,
            });
        }
        let mut element_lines = Vec::with_capacity(mesh.elements.len() * 8);
        for e in &mesh.elements {
            let c = e.corners();
            for k in 0..c.len() {
                element_lines.push(c[k].as_vec3().to_array());
                element_lines.push(c[(k + 1) % c.len()].as_vec3().to_array());
            }
        }
        let mut patch_lines = Vec::new();
        for p in &mesh.patches {
            let c = &p.polygon;
            for k in 0..c.len() {
                patch_lines.push(c[k].as_vec3().to_array());
                patch_lines.push(c[(k + 1) % c.len()].as_vec3().to_array());
            }
        }
        let b = mesh.bounds();
        Geometry {
            id,
            positions,
            patch,
            source_vertex,
            indices,
            element_lines,
            patch_lines,
            bvh: Bvh::build(&inputs),
            triangle_element: mesh.triangle_element.iter().map(|e| e.0).collect(),
            element_patch: mesh.elements.iter().map(|e| e.patch.0).collect(),
            patch_material: mesh.patches.iter().map(|p| p.material.0).collect(),
            bounds_min: b.min,
            bounds_max: b.max,
            elements: mesh.elements.len(),
            patches: mesh.patches.len(),
            element_size: mesh.element_size,
        }
    }

    /// Per-display-vertex values to per-drawn-vertex values.
    pub fn expand(&self, per_vertex: &[Rgb]) -> Vec<[f32; 3]> {
        self.source_vertex
            .iter()
            .map(|&v| per_vertex[v as usize].as_vec3().to_array())
            .collect()
    }

    /// The patch seen along a ray (front faces only, as drawn).
    pub fn pick(&self, origin: DVec3, dir: DVec3) -> Option<PatchId> {
        let element = self.pick_element(origin, dir)?;
        self.element_patch
            .get(element as usize)
            .map(|&p| PatchId(p))
    }

    /// The element seen along a ray (front faces only, as drawn).
    pub fn pick_element(&self, origin: DVec3, dir: DVec3) -> Option<u32> {
        let ray = nusselt_core::geometry::Ray::new(origin, dir);
        let hit = self.bvh.closest_hit(&ray, 0.0, f64::INFINITY)?;
        self.triangle_element.get(hit.id as usize).copied()
    }
}

/// One row of the convergence history.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HistoryPoint {
    /// Solve time in seconds since the last (re)start, pauses excluded.
    pub seconds: f64,
    /// Steps of the solver (shots; matrix rows, then sweeps) since the last (re)start.
    pub steps: usize,
    /// The solver's relative residual (for shooting, the unshot fraction).
    pub residual: f64,
    /// Channel mean of the ambient term (0 for solvers without one).
    pub ambient: f64,
}

/// Counters shown in the stats panel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    /// The solver's name (`shooting`, `jacobi`, `gauss-seidel`, `sor`, `cg`).
    pub solver: &'static str,
    /// The solver's own line (shots and overshooting, sweeps and ω, …).
    pub report: String,
    /// Memory held by stored form factors.
    pub matrix_bytes: usize,
    pub elements: usize,
    pub patches: usize,
    /// Steps since the last (re)start: shots, or matrix rows and then sweeps.
    pub steps: usize,
    /// Over the last second of solving.
    pub steps_per_second: f64,
    /// Relative residual `Σ|r_i|A_i / Σ|E_i|A_i`; for shooting, the unshot fraction.
    pub residual: f64,
    /// Solve time since the last (re)start, pauses excluded.
    pub elapsed_seconds: f64,
    pub playing: bool,
    /// The residual is below the stop threshold, or the solver has nothing left to do.
    pub converged: bool,
    /// Stopped at the scripted step limit.
    pub limit_reached: bool,
    /// The patch the last shot came from (shooting only).
    pub last_shooter: Option<u32>,
}

/// The latest state of the solve, ready to draw.
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// Increases with every publish.
    pub seq: u64,
    /// When the solver thread published it.
    pub published: std::time::Instant,
    /// When the first snapshot after the latest material edit was published.
    pub edit_published: Option<std::time::Instant>,
    pub geometry: Arc<Geometry>,
    /// Radiance per drawn vertex, without the ambient term.
    pub radiance: Arc<Vec<[f32; 3]>>,
    /// The display correction per drawn vertex (what `element_radiance(true)` adds to the
    /// radiosity: the ambient term times the reflectance), drawn when the toggle is on.
    pub correction: Arc<Vec<[f32; 3]>>,
    /// Reflectance per drawn vertex.
    pub reflectance: Arc<Vec<[f32; 3]>>,
    /// Changes whenever `reflectance` does.
    pub reflectance_rev: u64,
    /// The solver's global ambient term (channel values), for display of its size.
    pub ambient: [f32; 3],
    pub stats: Stats,
    pub materials: Arc<Vec<Material>>,
    /// The scene's skies, suns and point lights.
    pub lights: Arc<Vec<nusselt_core::scene::Light>>,
    /// Materials as loaded (for "reset edits" and showing what changed).
    pub loaded_materials: Arc<Vec<Material>>,
    pub history: Arc<Vec<HistoryPoint>>,
    pub scene_name: String,
    pub scene_source: Option<PathBuf>,
    /// Changes whenever a new scene is installed (not on re-mesh).
    pub scene_rev: u64,
    /// The scene's own camera, or one that frames it.
    pub scene_camera: Camera,
    pub two_sided: bool,
    pub method: FormFactorMethod,
    pub solver_kind: SolverKind,
    /// Teaching mode: what the last single shot did (while steps are recorded).
    pub teach_step: Option<Arc<crate::teach::step::StepDetail>>,
    /// Teaching mode: the hemicube asked for.
    pub teach_hemicube: Option<Arc<crate::teach::hemicube::HemicubeDetail>>,
    /// Teaching mode: the Nusselt analogue asked for.
    pub teach_nusselt: Option<Arc<crate::teach::nusselt::NusseltDetail>>,
    /// Teaching mode: the form-factor matrix so far and the shooter's column.
    pub teach_matrix: Option<Arc<crate::teach::matrix::MatrixDetail>>,
    /// Shooting vs gathering (`--teach compare`).
    pub teach_compare: Option<Arc<crate::teach::compare::CompareDetail>>,
    /// Uniform vs adaptive meshing (`--teach mesh`).
    pub teach_mesh: Option<Arc<crate::teach::meshing::MeshDetail>>,
    /// What the meshing view's job is doing while it runs.
    pub teach_mesh_stage: Option<&'static str>,
    /// What the ray-traced view renders, while it is on.
    pub ray_input: Option<Arc<crate::raytrace::RenderInput>>,
}

/// Per-drawn-vertex reflectance of the current materials.
pub(crate) fn vertex_reflectance(geometry: &Geometry, mats: &[Material]) -> Vec<[f32; 3]> {
    geometry
        .patch
        .iter()
        .map(|&p| {
            let m = geometry.patch_material[p as usize] as usize;
            mats[m].reflectance.as_vec3().to_array()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nusselt_core::scene::{LoadOptions, Scene};

    #[test]
    fn drawn_vertices_are_indexed_and_flat_per_patch() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        // Patches of 2×2 elements: many vertices lie on patch boundaries.
        let mesh = Mesh::build_with(&scene, 60.0, 120.0).expect("mesh");
        let g = Geometry::from_mesh(1, &mesh);
        assert_eq!(g.indices.len(), 3 * mesh.triangles.len());
        assert_eq!(g.positions.len(), g.patch.len());
        assert_eq!(g.positions.len(), g.source_vertex.len());
        for (t, (tri, e)) in g
            .indices
            .chunks_exact(3)
            .zip(mesh.triangles.iter().zip(&mesh.triangle_element))
        {
            let pid = mesh.elements[e.0 as usize].patch.0;
            for (&d, &v) in t.iter().zip(tri) {
                // The flat patch id is right whichever corner the GPU takes it from.
                assert_eq!(g.patch[d as usize], pid);
                assert_eq!(g.source_vertex[d as usize], v);
                assert_eq!(
                    g.positions[d as usize],
                    mesh.vertices[v as usize].as_vec3().to_array()
                );
            }
        }
        // Each (vertex, patch) pair is drawn once: fewer vertices than corners, and at most
        // one per pair.
        let mut pairs: Vec<(u32, u32)> = g
            .source_vertex
            .iter()
            .copied()
            .zip(g.patch.iter().copied())
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        assert_eq!(pairs.len(), g.positions.len());
        assert!(
            g.positions.len() < g.indices.len() / 2,
            "{} vertices, {} corners",
            g.positions.len(),
            g.indices.len()
        );
    }
}
