//! What the solver thread publishes and the UI draws: GPU-ready arrays built off the UI
//! thread, shared by `Arc` so that taking a snapshot never copies or waits.
//!
//! Triangles are *expanded* (three corners each, no index buffer) so every corner can carry
//! its patch id as a flat attribute; the shader highlights the shooting and the selected
//! patch with it. Radiance is stored without the ambient term together with the per-corner
//! reflectance, so the ambient toggle is a uniform (`B + ρ·ambient`, exactly what
//! [`ProgressiveSolver::vertex_radiance`]`(true)` gives, since per-vertex averaging is linear
//! and a surface has one material).

use std::path::PathBuf;
use std::sync::Arc;

use glam::DVec3;

use crate::formfactor::FormFactorMethod;
use crate::geometry::Bvh;
use crate::geometry::bvh::TriangleInput;
use crate::mesh::{Mesh, PatchId};
use crate::scene::{Camera, Material, Rgb};
use crate::solver::ProgressiveSolver;

/// Mesh arrays for drawing and picking; rebuilt only when the mesh changes.
#[derive(Debug)]
pub struct Geometry {
    /// Changes whenever the mesh does (new scene or re-mesh).
    pub id: u64,
    /// Per triangle corner.
    pub positions: Vec<[f32; 3]>,
    /// Patch id per triangle corner.
    pub patch: Vec<u32>,
    /// Display vertex of each triangle corner (to expand per-vertex values).
    pub corner_vertex: Vec<u32>,
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
        let n = mesh.triangles.len() * 3;
        let mut positions = Vec::with_capacity(n);
        let mut patch = Vec::with_capacity(n);
        let mut corner_vertex = Vec::with_capacity(n);
        let mut inputs = Vec::with_capacity(mesh.triangles.len());
        for (i, (t, e)) in mesh
            .triangles
            .iter()
            .zip(&mesh.triangle_element)
            .enumerate()
        {
            let pid = mesh.elements[e.0 as usize].patch.0;
            for &v in t {
                positions.push(mesh.vertices[v as usize].as_vec3().to_array());
                patch.push(pid);
                corner_vertex.push(v);
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
            corner_vertex,
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

    /// Expands per-display-vertex values to per-corner values.
    pub fn expand(&self, per_vertex: &[Rgb]) -> Vec<[f32; 3]> {
        self.corner_vertex
            .iter()
            .map(|&v| per_vertex[v as usize].as_vec3().to_array())
            .collect()
    }

    /// The patch seen along a ray (front faces only, as drawn).
    pub fn pick(&self, origin: DVec3, dir: DVec3) -> Option<PatchId> {
        let ray = crate::geometry::Ray::new(origin, dir);
        let hit = self.bvh.closest_hit(&ray, 0.0, f64::INFINITY)?;
        let element = *self.triangle_element.get(hit.id as usize)?;
        self.element_patch
            .get(element as usize)
            .map(|&p| PatchId(p))
    }
}

/// One row of the convergence history.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HistoryPoint {
    /// Solve time in seconds since the last (re)start, pauses excluded.
    pub seconds: f64,
    pub shots: usize,
    pub unshot_fraction: f64,
    /// Channel mean of the ambient term.
    pub ambient: f64,
}

/// Counters shown in the stats panel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    pub elements: usize,
    pub patches: usize,
    pub shots: usize,
    /// Over the last second of solving.
    pub shots_per_second: f64,
    pub unshot_fraction: f64,
    /// Solve time since the last (re)start, pauses excluded.
    pub elapsed_seconds: f64,
    pub playing: bool,
    /// Nothing left to shoot above the stop threshold.
    pub converged: bool,
    /// Stopped at the scripted shot limit.
    pub limit_reached: bool,
    pub last_shooter: Option<u32>,
    pub next_shooter: Option<u32>,
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
    /// Radiance per triangle corner, without the ambient term.
    pub radiance: Arc<Vec<[f32; 3]>>,
    /// Reflectance per triangle corner.
    pub reflectance: Arc<Vec<[f32; 3]>>,
    /// Changes whenever `reflectance` does.
    pub reflectance_rev: u64,
    pub ambient: [f32; 3],
    pub stats: Stats,
    pub materials: Arc<Vec<Material>>,
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
}

/// Per-corner reflectance of the current materials.
pub(crate) fn corner_reflectance(geometry: &Geometry, solver: &ProgressiveSolver) -> Vec<[f32; 3]> {
    let mats = &solver.scene().materials;
    geometry
        .patch
        .iter()
        .map(|&p| {
            let m = geometry.patch_material[p as usize] as usize;
            mats[m].reflectance.as_vec3().to_array()
        })
        .collect()
}
