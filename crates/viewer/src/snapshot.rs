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
//!
//! Textured patches ([`VertexTextures`]) also split their drawn vertices where the texture
//! coordinates jump (a seam between two faces of one patch), so each drawn vertex has one
//! uv.

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use glam::{DVec3, Vec3};
use rustc_hash::FxHashMap;

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::geometry::Bvh;
use nusselt_core::geometry::bvh::TriangleInput;
use nusselt_core::mesh::{Mesh, PatchId};
use nusselt_core::scene::{Camera, Material, Rgb, Scene};
use nusselt_core::solver::{Problem, SolverKind};

/// Per drawn vertex, what the shader needs to draw a diffuse map under the solution.
#[derive(Debug, Default)]
pub struct VertexTextures {
    /// Texture coordinates (the face's `vt` at the vertex, with the material's `-s`/`-o`
    /// transform applied; OBJ convention, v = 0 at the image's bottom row).
    pub uv: Vec<[f32; 2]>,
    /// The mean of the texture over the vertex's elements: the mean of
    /// [`Problem::element_texture`] over the elements with a corner at the vertex (all in
    /// one patch, with this uv), weighted by their areas. The shader divides the texel by it, as the CPU passes divide by the
    /// element's own mean.
    pub mean: Vec<[f32; 3]>,
    /// Texture-array layer + 1 ([`crate::textures::diffuse_layers`]); 0 where untextured.
    pub layer: Vec<u32>,
}

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
    /// Texture coordinates, means and layers; `None` for an untextured problem.
    pub textures: Option<VertexTextures>,
    /// Element edges as line-list endpoints.
    pub element_lines: Vec<[f32; 3]>,
    /// Patch outlines as line-list endpoints.
    pub patch_lines: Vec<[f32; 3]>,
    /// Display triangles (ids = triangle index) for picking, built on first use
    /// ([`Geometry::bvh`]): the solver thread builds it after the first snapshot is out,
    /// so a large model's first lit frame does not wait for it.
    bvh: OnceLock<Bvh>,
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

/// What [`Geometry::build`] reads to texture the drawn vertices.
struct Texturing<'a> {
    scene: &'a Scene,
    element_texture: &'a [Rgb],
    layer_of: Vec<Option<u32>>,
}

impl Texturing<'_> {
    /// Layer + 1 and uv of mesh vertex `p` on element `e` of `mesh`; `None` where the
    /// element's material has no diffuse map on the GPU or its face has no `vt`.
    fn at(&self, mesh: &Mesh, e: usize, p: DVec3) -> Option<(u32, [f32; 2])> {
        let el = &mesh.elements[e];
        let material = mesh.patch(el.patch).material;
        let m = self.scene.materials.get(material.0 as usize)?;
        let layer = (*self.layer_of.get(m.diffuse_map?.0 as usize)?)?;
        let uv = self.scene.faces.get(el.face as usize)?.uv_at(p)?;
        let uv = m.diffuse_uv.apply(uv);
        Some((layer + 1, uv.as_vec2().to_array()))
    }
}

/// The same point of texture space (within rounding of the two faces' interpolation).
fn same_uv(a: [f32; 2], b: [f32; 2]) -> bool {
    let tol = |x: f32, y: f32| (x - y).abs() <= 1e-5 * x.abs().max(y.abs()).max(1.0);
    tol(a[0], b[0]) && tol(a[1], b[1])
}

/// The drawn vertices as [`Geometry::build`] makes them: one per (mesh vertex, patch,
/// uv), with the texture means gathered per drawn vertex.
struct DrawnVertices {
    positions: Vec<[f32; 3]>,
    patch: Vec<u32>,
    source_vertex: Vec<u32>,
    /// First drawn vertex of each (mesh vertex, patch); further ones (other uvs) chained
    /// through `next`.
    first: FxHashMap<(u32, u32), u32>,
    next: Vec<u32>,
    tex: Option<VertexTextures>,
    /// Per drawn vertex: Σ area × element mean, Σ area, Σ element mean, count (for a
    /// vertex of zero-area elements only), and the last element counted (an element's
    /// one or two display triangles are consecutive, so each counts once).
    mean_sum: Vec<(DVec3, f64, DVec3, u32)>,
    last_element: Vec<u32>,
}

impl DrawnVertices {
    /// Room for `n` drawn vertices (a mesh's display vertex count); texture coordinates
    /// kept when `textured`.
    fn new(n: usize, textured: bool) -> Self {
        DrawnVertices {
            positions: Vec::with_capacity(n),
            patch: Vec::with_capacity(n),
            source_vertex: Vec::with_capacity(n),
            first: FxHashMap::with_capacity_and_hasher(n, Default::default()),
            next: Vec::with_capacity(n),
            tex: textured.then(VertexTextures::default),
            mean_sum: Vec::new(),
            last_element: Vec::new(),
        }
    }

    /// The drawn vertex of mesh vertex `v` (at `p`) on patch `pid` with the texture layer
    /// and uv `here`; a new one when there is none yet.
    fn find_or_add(&mut self, v: u32, pid: u32, p: DVec3, here: Option<(u32, [f32; 2])>) -> u32 {
        let uv_of = |d: u32| {
            self.tex
                .as_ref()
                .and_then(|x| (x.layer[d as usize] != 0).then(|| x.uv[d as usize]))
        };
        let matches = |d: u32| match (uv_of(d), here) {
            (None, None) => true,
            (Some(a), Some((_, b))) => same_uv(a, b),
            _ => false,
        };
        let mut last = None;
        let mut at = self.first.get(&(v, pid)).copied();
        while let Some(d) = at {
            if matches(d) {
                return d;
            }
            last = Some(d);
            at = (self.next[d as usize] != u32::MAX).then(|| self.next[d as usize]);
        }
        let d = self.positions.len() as u32;
        self.positions.push(p.as_vec3().to_array());
        self.patch.push(pid);
        self.source_vertex.push(v);
        self.next.push(u32::MAX);
        match last {
            Some(l) => self.next[l as usize] = d,
            None => {
                self.first.insert((v, pid), d);
            }
        }
        if let Some(x) = self.tex.as_mut() {
            let (layer, uv) = here.unwrap_or((0, [0.0; 2]));
            x.layer.push(layer);
            x.uv.push(uv);
            self.mean_sum.push((DVec3::ZERO, 0.0, DVec3::ZERO, 0));
            self.last_element.push(u32::MAX);
        }
        d
    }

    /// Counts element `e` (texture mean `m`, `area`) toward drawn vertex `d`'s texture
    /// mean, once per element.
    fn count_mean(&mut self, d: u32, e: u32, m: Rgb, area: f64) {
        if self.last_element[d as usize] == e {
            return;
        }
        self.last_element[d as usize] = e;
        let s = &mut self.mean_sum[d as usize];
        s.0 += m * area;
        s.1 += area;
        s.2 += m;
        s.3 += 1;
    }

    /// The texture coordinates with each drawn vertex's mean, once every triangle is
    /// counted (area-weighted; plain for zero-area elements; 1 where none counted).
    fn texture_means(&mut self) -> Option<VertexTextures> {
        let mut tex = self.tex.take()?;
        tex.mean = self
            .mean_sum
            .iter()
            .map(|&(s, a, plain, k)| {
                let m = if a > 0.0 {
                    s / a
                } else if k > 0 {
                    plain / k as f64
                } else {
                    Rgb::ONE
                };
                m.as_vec3().to_array()
            })
            .collect();
        Some(tex)
    }
}

/// The drawn vertices of `mesh`'s display triangles and the index buffer over them.
fn drawn_vertices(mesh: &Mesh, texturing: Option<&Texturing>) -> (DrawnVertices, Vec<u32>) {
    let mut drawn = DrawnVertices::new(mesh.vertices.len(), texturing.is_some());
    let mut indices = Vec::with_capacity(mesh.triangles.len() * 3);
    for (t, e) in mesh.triangles.iter().zip(&mesh.triangle_element) {
        let pid = mesh.elements[e.0 as usize].patch.0;
        let corners = t.map(|v| mesh.vertices[v as usize]);
        let area = mesh.elements[e.0 as usize].area;
        for (&v, &p) in t.iter().zip(&corners) {
            let here = texturing.and_then(|x| x.at(mesh, e.0 as usize, p));
            let d = drawn.find_or_add(v, pid, p, here);
            if let Some(x) = texturing
                && let Some(m) = x.element_texture.get(e.0 as usize)
            {
                drawn.count_mean(d, e.0, *m, area);
            }
            indices.push(d);
        }
    }
    (drawn, indices)
}

/// Closed polygons as line-list endpoints (each edge once, the last back to the first).
fn outlines<P: AsRef<[DVec3]>>(polygons: impl Iterator<Item = P>) -> Vec<[f32; 3]> {
    let mut lines = Vec::new();
    for c in polygons {
        let c = c.as_ref();
        for k in 0..c.len() {
            lines.push(c[k].as_vec3().to_array());
            lines.push(c[(k + 1) % c.len()].as_vec3().to_array());
        }
    }
    lines
}

impl Geometry {
    /// Number of mesh display vertices the drawn vertices expand ([`Geometry::source_vertex`]).
    pub fn display_vertex_count(&self) -> usize {
        self.source_vertex
            .iter()
            .map(|&v| v as usize + 1)
            .max()
            .unwrap_or(0)
    }

    /// Untextured drawing arrays of a mesh.
    pub fn from_mesh(id: u64, mesh: &Mesh) -> Geometry {
        Self::build(id, mesh, None)
    }

    /// Drawing arrays of a problem's mesh, with its diffuse maps' texture coordinates and
    /// means when it has any ([`Problem::element_texture`] not empty).
    pub fn from_problem(id: u64, problem: &Problem) -> Geometry {
        let texturing = (!problem.element_texture().is_empty()).then(|| Texturing {
            scene: &problem.scene,
            element_texture: problem.element_texture(),
            layer_of: crate::textures::diffuse_layers(&problem.scene),
        });
        Self::build(id, &problem.mesh, texturing)
    }

    fn build(id: u64, mesh: &Mesh, texturing: Option<Texturing>) -> Geometry {
        // The outlines are independent of the drawn vertices: built alongside them.
        let ((mut drawn, indices), (element_lines, patch_lines)) = rayon::join(
            || drawn_vertices(mesh, texturing.as_ref()),
            || {
                (
                    outlines(mesh.elements.iter().map(|e| e.corners())),
                    outlines(mesh.patches.iter().map(|p| &p.polygon)),
                )
            },
        );
        let textures = drawn.texture_means();
        let b = mesh.bounds();
        Geometry {
            id,
            positions: drawn.positions,
            patch: drawn.patch,
            source_vertex: drawn.source_vertex,
            indices,
            textures,
            element_lines,
            patch_lines,
            bvh: OnceLock::new(),
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
        use rayon::prelude::*;
        (self.source_vertex.par_iter())
            .with_min_len(4096)
            .map(|&v| per_vertex[v as usize].as_vec3().to_array())
            .collect()
    }

    /// The hierarchy over the drawn triangles (ids = triangle index; back faces culled, as
    /// the viewport culls them), built on the first call (about 0.3 s at 200 k triangles).
    pub fn bvh(&self) -> &Bvh {
        self.bvh.get_or_init(|| {
            let corner = |k: usize| Vec3::from_array(self.positions[self.indices[k] as usize]);
            let inputs: Vec<TriangleInput> = (0..self.indices.len() / 3)
                .map(|i| TriangleInput {
                    vertices: [0, 1, 2].map(|c| corner(3 * i + c).as_dvec3()),
                    id: i as u32,
                    cull_back: true,
                    cut: None,
                })
                .collect();
            Bvh::build(&inputs)
        })
    }

    /// The patch seen along a ray (front faces only, as drawn).
    pub fn pick(&self, origin: DVec3, dir: DVec3) -> Option<PatchId> {
        let element = self.pick_element(origin, dir)?;
        self.element_patch
            .get(element as usize)
            .map(|&p| PatchId(p))
    }

    /// The surface point seen along a ray and its unit normal on the side the ray came
    /// from (the display triangle's, from the drawn positions).
    pub fn pick_surface(&self, origin: DVec3, dir: DVec3) -> Option<(DVec3, DVec3)> {
        let ray = nusselt_core::geometry::Ray::new(origin, dir);
        let hit = self.bvh().closest_hit(&ray, 0.0, f64::INFINITY)?;
        let k = 3 * hit.id as usize;
        let corner = |i: usize| -> Option<DVec3> {
            let v = *self.indices.get(k + i)? as usize;
            Some(glam::Vec3::from_array(*self.positions.get(v)?).as_dvec3())
        };
        let (a, b, c) = (corner(0)?, corner(1)?, corner(2)?);
        let point = a + (b - a) * hit.u + (c - a) * hit.v;
        let n = (b - a).cross(c - a).try_normalize()?;
        Some((point, if n.dot(dir) > 0.0 { -n } else { n }))
    }

    /// The element seen along a ray (front faces only, as drawn).
    pub fn pick_element(&self, origin: DVec3, dir: DVec3) -> Option<u32> {
        let ray = nusselt_core::geometry::Ray::new(origin, dir);
        let hit = self.bvh().closest_hit(&ray, 0.0, f64::INFINITY)?;
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
    /// Memory held by stored form factors (cached rows, a matrix, links).
    pub matrix_bytes: usize,
    /// What the mesh and the textures hold of the budget (`Problem::resident_bytes`).
    pub resident_bytes: usize,
    /// The run's memory budget (`--max-memory`).
    pub memory_budget: usize,
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
    /// The display correction per drawn vertex (what `display_radiance()` adds to the
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
    /// The scene's area lights (emitting faces of their own), radiance as now.
    pub area_lights: Arc<Vec<nusselt_core::scene::AreaLight>>,
    /// Materials as loaded (for "reset edits" and showing what changed).
    pub loaded_materials: Arc<Vec<Material>>,
    pub history: Arc<Vec<HistoryPoint>>,
    pub scene_name: String,
    pub scene_source: Option<PathBuf>,
    /// Changes whenever a new scene is installed (not on re-mesh).
    pub scene_rev: u64,
    /// The scene's diffuse maps, for the GPU's texture array; `None` when it has none.
    pub textures: Option<Arc<crate::textures::TextureLayers>>,
    /// The scene's texture maps as loaded (what `materials`' map ids index), for exports.
    pub scene_textures: Vec<Arc<nusselt_core::scene::Texture>>,
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
    use nusselt_core::mesh::MeshSpec;
    use nusselt_core::scene::{LoadOptions, Scene};

    #[test]
    fn drawn_vertices_are_indexed_and_flat_per_patch() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        // Patches of 2×2 elements: many vertices lie on patch boundaries.
        let mesh = Mesh::build(&scene, &MeshSpec::sized(60.0, 120.0)).expect("mesh");
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

#[cfg(test)]
mod texture_tests {
    use super::*;
    use crate::textures::TextureLayers;
    use nusselt_core::mesh::MeshSpec;
    use nusselt_core::scene::{LoadOptions, Scene};
    use nusselt_core::solver::SolverConfig;

    /// 4 × 4 checkerboard, red where x + y is even (y down from the top row), else blue.
    fn write_checker(path: &std::path::Path) {
        image::RgbImage::from_fn(4, 4, |x, y| {
            if (x + y) % 2 == 0 {
                image::Rgb([255, 0, 0])
            } else {
                image::Rgb([0, 0, 255])
            }
        })
        .save(path)
        .expect("png");
    }

    /// The unit square y = 0 with vt = (x, z) (material `checker`, or `scaled` with
    /// `-s 2 2`), and an untextured square at y = 2 facing down; the problem at element
    /// size `size` with whole squares as patches (their elements share vertices).
    fn textured_problem(material: &str, size: f64) -> (Problem, tempfile::TempDir) {
        let dir = tempfile::tempdir().expect("temp dir");
        write_checker(&dir.path().join("checker.png"));
        std::fs::write(
            dir.path().join("s.mtl"),
            "newmtl checker\nKd 0.8 0.8 0.8\nmap_Kd checker.png\n\
             newmtl scaled\nKd 0.8 0.8 0.8\nmap_Kd -s 2 2 1 checker.png\n\
             newmtl light\nKd 0.5 0.5 0.5\nKe 1 1 1\n",
        )
        .expect("mtl");
        let obj = format!(
            "mtllib s.mtl\nvt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\n\
             v 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0 0\nusemtl {material}\nf 1/1 2/2 3/3 4/4\n\
             v 0 2 0\nv 1 2 0\nv 1 2 1\nv 0 2 1\nusemtl light\nf 5 6 7 8\n"
        );
        let path = dir.path().join("s.obj");
        std::fs::write(&path, obj).expect("obj");
        let scene = Scene::load_obj(&path, &LoadOptions::default()).expect("loads");
        let config = SolverConfig {
            mesh: MeshSpec::sized(size, 1.0),
            ..Default::default()
        };
        (Problem::new(scene, config).expect("problem"), dir)
    }

    fn close(a: [f32; 3], b: Rgb, tol: f64) -> bool {
        (0..3).all(|k| (a[k] as f64 - b[k]).abs() <= tol)
    }

    #[test]
    fn a_textured_quad_has_its_vt_and_its_mean_at_the_corners() {
        // One element over the whole square: the corners' uvs are the OBJ's vt, and the mean
        // is the element's (the whole checker's: half red, half blue).
        let (problem, _dir) = textured_problem("checker", 2.0);
        let g = Geometry::from_problem(1, &problem);
        let t = g.textures.as_ref().expect("textured");
        let textured: Vec<usize> = (0..g.positions.len())
            .filter(|&d| t.layer[d] == 1)
            .collect();
        assert_eq!(textured.len(), 4, "{:?}", t.layer);
        let e = problem
            .mesh
            .elements
            .iter()
            .position(|e| problem.scene.faces[e.face as usize].uvs.is_some())
            .expect("textured element");
        let mean = problem.element_texture()[e];
        assert!(
            (mean.x - mean.z).abs() < 1e-6 && mean.y.abs() < 1e-9,
            "{mean}"
        );
        for d in textured {
            let [x, _, z] = g.positions[d];
            assert_eq!(t.uv[d], [x, z], "vertex at {:?}", g.positions[d]);
            assert!(close(t.mean[d], mean, 1e-6), "{:?} vs {mean}", t.mean[d]);
        }
        // The light's square has no map.
        assert!(t.layer.iter().filter(|&&l| l == 0).count() >= 4);
    }

    #[test]
    fn shared_vertices_average_their_elements_means_by_area() {
        // Elements of a quarter: each covers one checker cell, so each element is pure red or
        // blue, and a vertex's mean is the area-weighted mean of the elements around it.
        let (problem, _dir) = textured_problem("checker", 0.25);
        let mesh = &problem.mesh;

        let g = Geometry::from_problem(1, &problem);
        let t = g.textures.as_ref().expect("textured");
        let tex = problem.element_texture();
        for e in mesh.elements.iter().zip(tex) {
            if mesh.patch(e.0.patch).material == mesh.patch(PatchId(0)).material {
                let m = *e.1;
                assert!(m.max_element() > 0.99 && m.min_element() < 1e-6, "{m}");
            }
        }
        let mut checked = 0;
        for d in 0..g.positions.len() {
            if t.layer[d] == 0 {
                continue;
            }
            let v = g.source_vertex[d] as usize;
            let p = mesh.vertices[v];
            assert_eq!(t.uv[d], [p.x as f32, p.z as f32]);
            // Independently: the elements of this patch with a corner at this vertex.
            let (mut sum, mut area) = (Rgb::ZERO, 0.0);
            for (element, m) in mesh.elements.iter().zip(tex) {
                if element.patch.0 == g.patch[d] && element.vertex_ids().contains(&(v as u32)) {
                    sum += *m * element.area;
                    area += element.area;
                }
            }
            assert!(close(t.mean[d], sum / area, 1e-6), "vertex {p}");
            checked += 1;
        }
        assert!(checked >= 25, "{checked} textured vertices");
        // An interior vertex between two red and two blue cells: purple.
        let centre = (0..g.positions.len())
            .find(|&d| t.layer[d] == 1 && g.positions[d] == [0.5, 0.0, 0.5])
            .expect("centre vertex");
        assert!(close(t.mean[centre], Rgb::new(0.5, 0.0, 0.5), 1e-6));
    }

    #[test]
    fn the_solver_thread_sends_the_texture_layers_after_the_scene() {
        // Built on their own thread: a later snapshot of the same scene carries them,
        // the same as built in place.
        use crate::solver_thread::{SolverHandle, ThreadConfig};
        use std::time::{Duration, Instant};
        let (problem, _dir) = textured_problem("checker", 0.25);
        let expected = TextureLayers::build(&problem.scene).expect("layers");
        let config = ThreadConfig {
            play: false,
            ..Default::default()
        };
        let mut h =
            SolverHandle::spawn(problem.scene.clone(), config, Box::new(|| {})).expect("spawn");
        let deadline = Instant::now() + Duration::from_secs(60);
        let layers = loop {
            if let Some(s) = h.take_snapshot()
                && let Some(t) = &s.textures
            {
                break t.clone();
            }
            assert!(Instant::now() < deadline, "no snapshot with textures");
            std::thread::sleep(Duration::from_millis(5));
        };
        assert_eq!(
            (layers.layers, layers.size, layers.mip_levels),
            (expected.layers, expected.size, expected.mip_levels)
        );
        assert_eq!(layers.mips(), expected.mips());
        assert!(h.shutdown(Duration::from_secs(10)));
    }

    #[test]
    fn the_layer_read_at_the_vertex_uv_is_the_cpu_texel() {
        // What the shader samples (layer texels top row first, at (u, 1 − v), repeating)
        // equals the core's texel at the element centres, with the material's `-s 2 2`.
        let (problem, _dir) = textured_problem("scaled", 0.25);
        let layers = TextureLayers::build(&problem.scene).expect("layers");
        assert_eq!((layers.layers, layers.size, layers.mip_levels), (1, 4, 3));
        assert_eq!(layers.gpu_bytes(), (16 + 4 + 1) * 8);
        let g = Geometry::from_problem(1, &problem);
        let t = g.textures.as_ref().expect("textured");
        // Bilinear with repeat at level 0, as the sampler magnifies.
        let mips = layers.mips();
        let texel = |uv: [f32; 2]| -> Rgb {
            let n = layers.size as i64;
            let read = |x: i64, y: i64| {
                let i = 4 * (y.rem_euclid(n) * n + x.rem_euclid(n)) as usize;
                let c = |k: usize| half::f16::from_bits(mips[0][i + k]).to_f64();
                Rgb::new(c(0), c(1), c(2))
            };
            let x = uv[0] as f64 * n as f64 - 0.5;
            let y = (1.0 - uv[1] as f64) * n as f64 - 0.5;
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            read(x0, y0) * (1.0 - fx) * (1.0 - fy)
                + read(x0 + 1, y0) * fx * (1.0 - fy)
                + read(x0, y0 + 1) * (1.0 - fx) * fy
                + read(x0 + 1, y0 + 1) * fx * fy
        };
        let mut checked = 0;
        for (tri, el) in g.indices.chunks_exact(3).zip(&g.triangle_element) {
            if tri.iter().any(|&d| t.layer[d as usize] == 0) {
                continue;
            }
            let uv = tri.iter().fold([0.0f32; 2], |a, &d| {
                let u = t.uv[d as usize];
                [a[0] + u[0] / 3.0, a[1] + u[1] / 3.0]
            });
            let e = &problem.mesh.elements[*el as usize];
            let c = tri.iter().fold(DVec3::ZERO, |a, &d| {
                a + glam::Vec3::from(g.positions[d as usize]).as_dvec3() / 3.0
            });
            let (want, _) = problem.scene.texel(e.face as usize, c).expect("texel");
            assert!((texel(uv) - want).abs().max_element() < 2e-3, "{c}: {want}");
            checked += 1;
        }
        assert!(checked >= 16);
    }

    #[test]
    fn a_uv_seam_splits_the_drawn_vertices() {
        // Two small triangles folded along their shared edge (one cluster patch, an element
        // each) whose vt differ along that edge: each triangle's corners keep their own uvs
        // there (two drawn vertices per end of the edge), elsewhere one.
        let dir = tempfile::tempdir().expect("temp dir");
        write_checker(&dir.path().join("checker.png"));
        std::fs::write(
            dir.path().join("s.mtl"),
            "newmtl checker\nKd 0.8 0.8 0.8\nmap_Kd checker.png\n",
        )
        .expect("mtl");
        let obj = "mtllib s.mtl\nvt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\nvt 3 3\nvt 5 5\n\
                   v 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0.3 0\nusemtl checker\n\
                   f 1/1 2/2 3/3\nf 1/5 3/6 4/4\n";
        let path = dir.path().join("s.obj");
        std::fs::write(&path, obj).expect("obj");
        let scene = Scene::load_obj(&path, &LoadOptions::default()).expect("loads");
        let config = SolverConfig {
            mesh: MeshSpec::sized(2.0, 2.0),
            ..Default::default()
        };
        let problem = Problem::new(scene, config).expect("problem");
        assert_eq!(problem.mesh.patches.len(), 1);
        assert_eq!(problem.mesh.elements.len(), 2);
        let g = Geometry::from_problem(1, &problem);
        let t = g.textures.as_ref().expect("textured");
        let uvs_at = |p: [f32; 3]| {
            let mut uv: Vec<[f32; 2]> = (0..g.positions.len())
                .filter(|&d| g.positions[d] == p)
                .map(|d| t.uv[d])
                .collect();
            uv.sort_by(|a, b| a.partial_cmp(b).expect("finite"));
            uv
        };
        assert_eq!(uvs_at([0.0, 0.0, 0.0]), vec![[0.0, 0.0], [3.0, 3.0]]);
        assert_eq!(uvs_at([1.0, 0.0, 1.0]), vec![[1.0, 1.0], [5.0, 5.0]]);
        assert_eq!(uvs_at([0.0, 0.0, 1.0]), vec![[0.0, 1.0]]);
        assert_eq!(uvs_at([1.0, 0.3, 0.0]), vec![[1.0, 0.0]]);
    }

    #[test]
    fn an_untextured_problem_has_no_texturing() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::element(120.0),
            ..Default::default()
        };
        let problem = Problem::new(scene, config).expect("problem");
        let g = Geometry::from_problem(1, &problem);
        assert!(g.textures.is_none());
        assert!(TextureLayers::build(&problem.scene).is_none());
        let plain = Geometry::from_mesh(1, &problem.mesh);
        assert_eq!(g.positions, plain.positions);
        assert_eq!(g.indices, plain.indices);
    }
}
