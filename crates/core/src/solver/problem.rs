//! What every solver works on: the scene, its mesh, the visibility hierarchy, and the
//! settings of the form factors. Built once per scene and mesh; solvers hold one.

use std::sync::Arc;

use crate::formfactor::hemicube::ItemBufferRaster;
use crate::formfactor::lights::{ExternalLight, GlassVisibility, NO_GLASS};
use crate::formfactor::{FormFactorMethod, RowContext};
use crate::geometry::Bvh;
use crate::mesh::{self, Mesh, MeshSpec, PatchId};
use crate::scene::{Light, Material, Rgb, Scene};

use super::{SolverConfig, SolverError, check_power};

/// Wall-clock seconds between named points of a setup.
struct PhaseClock {
    last: std::time::Instant,
    laps: Vec<(&'static str, f64)>,
}

impl PhaseClock {
    fn start() -> Self {
        Self {
            last: std::time::Instant::now(),
            laps: Vec::new(),
        }
    }

    fn lap(&mut self, name: &'static str) {
        let now = std::time::Instant::now();
        self.laps.push((name, (now - self.last).as_secs_f64()));
        self.last = now;
    }
}

/// Refuses, before meshing, a mesh whose estimated size ([`mesh::estimated_elements`]) does
/// not fit in the memory budget beside the scene's textures, naming the element size and
/// the budget that would fit.
fn check_mesh_budget(scene: &Scene, config: &SolverConfig) -> Result<(), SolverError> {
    let sides = if scene.two_sided { 2 } else { 1 };
    let (elements, size) = match config.mesh.element_size {
        Some(size) if size.is_finite() && size > 0.0 => {
            (mesh::estimated_elements(scene, size), size)
        }
        // A bad size is the mesher's error to report.
        Some(_) => return Ok(()),
        None => {
            let target = config.mesh.max_elements.unwrap_or(mesh::ELEMENT_BUDGET);
            let count = target.max(scene.faces.len() * sides) as f64;
            (count, mesh::element_size_for_budget(scene, target))
        }
    };
    let held = scene.texture_bytes;
    let fit = crate::budget::elements_within(config.memory_bytes, held);
    if elements <= fit as f64 {
        return Ok(());
    }
    let needed = held.saturating_add(crate::budget::mesh_bytes(elements as usize));
    let fitting = match config.mesh.element_size {
        // Element count falls as the size squared: the size whose count fits, 10 % spare.
        Some(_) => format!(
            "--element-size {:.4} or larger",
            size * (elements / (0.9 * fit.max(1) as f64)).sqrt()
        ),
        None => format!("--max-elements {} or fewer", fit * 9 / 10),
    };
    Err(SolverError::MeshOverBudget {
        elements: elements as usize,
        element_size: size,
        needed_mib: crate::budget::mib(needed),
        budget_mib: config.memory_bytes >> 20,
        held: if held > 0 {
            format!(", of which textures hold {} MiB", crate::budget::mib(held))
        } else {
            String::new()
        },
        fitting,
    })
}

/// A scene meshed for solving (see the module docs of [`crate::solver`]).
pub struct Problem {
    pub scene: Scene,
    pub config: SolverConfig,
    pub mesh: Mesh,
    pub bvh: Bvh,
    /// Offset of shadow-ray end points from their surfaces (scene units).
    pub epsilon: f64,
    /// What the sky, suns and point lights give each element (irradiance over π).
    pub external: ExternalLight,
    /// The windows of skies, suns and points (built when first asked for).
    glass: std::sync::OnceLock<GlassVisibility>,
    /// The same, area-averaged over each patch.
    patch_external: Vec<Rgb>,
    /// Per element, the mean colour of its material's diffuse texture over the element
    /// (what `Kd` is multiplied by); empty when no material has a texture.
    element_texture: Vec<Rgb>,
    /// Per element, the opaque fraction of a cut-out material (empty when none has holes).
    element_coverage: Vec<f64>,
    /// The same, area-averaged over each patch.
    patch_texture: Vec<Rgb>,
    /// Wall-clock seconds of each setup phase (meshing, BVH, textures, lights), in order.
    pub setup_seconds: Vec<(&'static str, f64)>,
}

impl Problem {
    /// Meshes `scene` by `config` (element size, budget, patch size) and builds the BVH.
    /// Refuses a light whose power would overflow ([`SolverError::PowerOverflow`]) and the
    /// GPU hemicube without a rasteriser.
    pub fn new(scene: Scene, config: SolverConfig) -> Result<Self, SolverError> {
        Self::new_alongside(scene, config, |_| ()).map(|(problem, ())| problem)
    }

    /// [`Problem::new`], running `beside` on the scene while it is meshed (meshing is
    /// mostly serial: a second core can choose a camera meanwhile). `beside` runs only
    /// once the problem's checks have passed.
    pub fn new_alongside<T: Send>(
        scene: Scene,
        config: SolverConfig,
        beside: impl FnOnce(&Scene) -> T + Send,
    ) -> Result<(Self, T), SolverError> {
        if config.formfactor.method == FormFactorMethod::GpuHemicube
            && config.formfactor.raster.is_none()
        {
            return Err(SolverError::NoRaster);
        }
        check_mesh_budget(&scene, &config)?;
        let start = std::time::Instant::now();
        // The faces' hierarchy needs only the scene: it is built beside the mesh, which
        // keeps one thread busy for most of its time (on the 263 k-triangle atrium, 0.3 s
        // less before the first view).
        let ((mesh, meshing), (side, faces)) = rayon::join(
            || {
                let mesh = Mesh::build(&scene, &config.mesh);
                (mesh, start.elapsed().as_secs_f64())
            },
            || (beside(&scene), Mesh::face_bvh(&scene)),
        );
        let mesh = mesh?;
        let mut problem = Self::assemble(scene, config, mesh, Some(faces))?;
        problem.setup_seconds.insert(0, ("mesh", meshing));
        Ok((problem, side))
    }

    /// Bytes of the memory budget the run holds besides its caches: the textures and the
    /// mesh at [`crate::budget::ELEMENT_BYTES`] an element.
    pub fn resident_bytes(&self) -> usize {
        self.scene
            .texture_bytes
            .saturating_add(crate::budget::mesh_bytes(self.mesh.elements.len()))
    }

    /// What the memory budget leaves for cached rows, a stored matrix or links.
    pub fn cache_bytes(&self) -> usize {
        self.config
            .memory_bytes
            .saturating_sub(self.resident_bytes())
    }

    /// A problem on a mesh already built for `scene`.
    pub fn with_mesh(scene: Scene, config: SolverConfig, mesh: Mesh) -> Result<Self, SolverError> {
        Self::assemble(scene, config, mesh, None)
    }

    /// [`Problem::with_mesh`], with the scene's [`Mesh::face_bvh`] where it was built
    /// beforehand (the "bvh" lap is then only its relabelling).
    fn assemble(
        scene: Scene,
        config: SolverConfig,
        mesh: Mesh,
        faces: Option<Bvh>,
    ) -> Result<Self, SolverError> {
        check_power(&scene.materials, &mesh)?;
        let mut clock = PhaseClock::start();
        // The blockers' hierarchy (one thread) and the textures' means (all of them) side
        // by side: a quarter of a second less before a 200 k-triangle model's first view.
        let ((bvh, bvh_seconds), textures) = rayon::join(
            || {
                let start = std::time::Instant::now();
                let bvh = match faces {
                    Some(faces) => mesh.blocker_bvh_from(faces),
                    None => mesh.blocker_bvh(&scene),
                };
                (bvh, start.elapsed().as_secs_f64())
            },
            || TextureMeans::of(&scene, &mesh),
        );
        // The laps add up to the time taken: "textures" is what the pair took beyond
        // the hierarchy.
        clock.lap("textures");
        let both = clock.laps.pop().map_or(0.0, |l| l.1);
        clock.laps.push(("bvh", bvh_seconds.min(both)));
        clock.laps.push(("textures", (both - bvh_seconds).max(0.0)));
        let epsilon = 1e-6 * mesh.bounds().diagonal().max(1e-12);
        let mut problem = Self {
            scene,
            config,
            mesh,
            bvh,
            epsilon,
            external: ExternalLight::default(),
            glass: std::sync::OnceLock::new(),
            patch_external: Vec::new(),
            element_texture: Vec::new(),
            element_coverage: Vec::new(),
            patch_texture: Vec::new(),
            setup_seconds: Vec::new(),
        };
        problem.set_texture_means(textures);
        problem.light_elements();
        clock.lap("lights");
        problem.setup_seconds = clock.laps;
        Ok(problem)
    }

    /// Recomputes the elements' and patches' texture means ([`TextureMeans`]).
    fn texture_elements(&mut self) {
        let means = TextureMeans::of(&self.scene, &self.mesh);
        self.set_texture_means(means);
    }

    fn set_texture_means(&mut self, means: TextureMeans) {
        self.element_texture = means.element_texture;
        self.element_coverage = means.element_coverage;
        self.patch_texture = means.patch_texture;
    }

    /// Per element, the mean of its diffuse texture (empty when nothing is textured).
    pub fn element_texture(&self) -> &[Rgb] {
        &self.element_texture
    }

    /// The opaque fraction of element `e` (1 unless its material has cut-outs): the share
    /// of the light arriving over its outline that it intercepts; the rest passes its holes.
    pub fn element_coverage(&self, e: usize) -> f64 {
        self.element_coverage.get(e).copied().unwrap_or(1.0)
    }

    /// Reflectance of patch `p`: its material's `Kd` times its texture's mean.
    pub fn patch_rho(&self, p: usize) -> Rgb {
        let m = &self.scene.materials[self.mesh.patches[p].material.0 as usize];
        match self.patch_texture.get(p) {
            Some(t) => m.reflectance * *t,
            None => m.reflectance,
        }
    }

    /// Reflectance of element `e`: its material's `Kd` times its texture's mean.
    pub fn element_rho(&self, e: usize) -> Rgb {
        let m = self.material_of(self.mesh.elements[e].patch);
        match self.element_texture.get(e) {
            Some(t) => m.reflectance * *t,
            None => m.reflectance,
        }
    }

    /// Computes what the lights that are not faces give each element and patch.
    fn light_elements(&mut self) {
        if self.external.sky_fraction.len() != self.mesh.elements.len() {
            self.external = ExternalLight::default();
        }
        let glass = if self.scene.lights.iter().any(Light::is_on) {
            self.glass
                .get_or_init(|| GlassVisibility::new(&self.scene, &self.mesh))
        } else {
            &NO_GLASS
        };
        self.external.update(
            &self.scene.lights,
            glass,
            &self.mesh,
            &self.bvh,
            self.epsilon,
        );
        self.patch_external = if self.external.is_empty() {
            Vec::new()
        } else {
            let at: Vec<Rgb> = (0..self.mesh.elements.len())
                .map(|e| self.external.at(e))
                .collect();
            self.mesh.patch_means(&at)
        };
    }

    /// The windows of skies, suns and points on this mesh
    /// ([`GlassVisibility`], built on first use).
    pub fn glass(&self) -> &GlassVisibility {
        self.glass
            .get_or_init(|| GlassVisibility::new(&self.scene, &self.mesh))
    }

    /// Replaces the lights that are not faces and recomputes what they give.
    pub fn set_lights(&mut self, lights: Vec<Light>) {
        self.scene.lights = lights;
        self.light_elements();
    }

    /// What patch `p` sends before any reflection: its `Ke` plus the reflected share of
    /// the sky, suns and point lights (which are shot first, as emitters are).
    pub fn patch_source(&self, p: usize) -> Rgb {
        let m = &self.scene.materials[self.mesh.patches[p].material.0 as usize];
        match self.patch_external.get(p) {
            Some(h) => m.emission + self.patch_rho(p) * *h,
            None => m.emission,
        }
    }

    /// What element `e` sends before any reflection (see [`Problem::patch_source`]).
    pub fn element_source(&self, e: usize) -> Rgb {
        let m = self.material_of(self.mesh.elements[e].patch);
        m.emission + self.element_rho(e) * self.external.at(e)
    }

    /// Rebuilds the mesh with a new element size (and the BVH's visibility groups).
    pub fn remesh(&mut self, element_size: f64) -> Result<(), SolverError> {
        let spec = MeshSpec {
            element_size: Some(element_size),
            ..self.config.mesh
        };
        let mesh = Mesh::build(&self.scene, &spec)?;
        check_power(&self.scene.materials, &mesh)?;
        self.bvh = mesh.blocker_bvh(&self.scene);
        self.mesh = mesh;
        self.config.mesh = spec;
        self.external = ExternalLight::default();
        self.glass = std::sync::OnceLock::new();
        self.texture_elements();
        self.light_elements();
        Ok(())
    }

    pub fn material_of(&self, patch: PatchId) -> &Material {
        &self.scene.materials[self.mesh.patch(patch).material.0 as usize]
    }

    /// What each patch sends before any reflection ([`Problem::patch_source`]): the unshot
    /// (or gathered) radiance of a dark start.
    pub fn patch_emission(&self) -> Vec<Rgb> {
        (0..self.mesh.patches.len())
            .map(|p| self.patch_source(p))
            .collect()
    }

    /// Reflectance of each patch's material.
    pub fn patch_reflectance(&self) -> Vec<Rgb> {
        (0..self.mesh.patches.len())
            .map(|k| self.patch_rho(k))
            .collect()
    }

    /// What each element sends before any reflection: the radiosity of a dark start.
    pub fn element_emission(&self) -> Vec<Rgb> {
        (0..self.mesh.elements.len())
            .map(|e| self.element_source(e))
            .collect()
    }

    /// Reflectance of each element's material.
    pub fn element_reflectance(&self) -> Vec<Rgb> {
        (0..self.mesh.elements.len())
            .map(|k| self.element_rho(k))
            .collect()
    }

    /// Σ |S_i| A_i over patches (channel sums) of the sources [`Problem::patch_source`]:
    /// the power the lights put in.
    pub fn emitted_power(&self) -> f64 {
        self.mesh
            .patches
            .iter()
            .enumerate()
            .map(|(k, p)| super::channel_sum(self.patch_source(k)) * p.area)
            .sum()
    }

    /// What a form-factor row sees (scene, mesh, BVH, parameters, offset, rasteriser).
    pub fn row_context(&self) -> RowContext<'_> {
        RowContext {
            scene: &self.scene,
            mesh: &self.mesh,
            bvh: &self.bvh,
            params: &self.config.formfactor.params,
            epsilon: self.epsilon,
            raster: self.config.formfactor.raster.as_deref(),
        }
    }

    /// Installs the rasteriser used by `gpu-hemicube` rows.
    pub fn set_raster(&mut self, raster: Option<Arc<dyn ItemBufferRaster>>) {
        self.config.formfactor.raster = raster;
    }

    /// Checks a new reflectance and emission for material `idx` and installs them.
    pub fn set_material(
        &mut self,
        idx: usize,
        reflectance: Rgb,
        emission: Rgb,
    ) -> Result<(), SolverError> {
        if idx >= self.scene.materials.len() {
            return Err(SolverError::NoSuchMaterial(idx as u32));
        }
        let max = crate::scene::MAX_REFLECTANCE;
        if !reflectance.is_finite()
            || reflectance.min_element() < 0.0
            || reflectance.max_element() > max
        {
            return Err(SolverError::BadValue {
                what: "reflectance",
                range: "in [0, 0.999]",
                value: reflectance.to_array(),
            });
        }
        if !emission.is_finite() || emission.min_element() < 0.0 {
            return Err(SolverError::BadValue {
                what: "emission",
                range: ">= 0",
                value: emission.to_array(),
            });
        }
        let mut candidate = self.scene.materials.clone();
        candidate[idx].reflectance = reflectance;
        candidate[idx].emission = emission;
        check_power(&candidate, &self.mesh)?;
        self.scene.materials = candidate;
        Ok(())
    }
}

/// Each element's and patch's mean texture colour (Kd's multiplier): the texture's mean
/// over the element's area, in texture space, times the element's opaque fraction where
/// its material has cut-outs. A cut-out element keeps its whole outline as a receiver
/// (rays through its holes reach what is behind it) but reflects and sends only from its
/// opaque part: the power it sends, `ρ H A c`, is what an element of area `c A` would
/// send, and the display divides by this same mean, so an opaque pixel shows
/// `Kd · texel · H`. All empty when nothing is textured.
struct TextureMeans {
    element_texture: Vec<Rgb>,
    /// Empty unless some element is not wholly opaque.
    element_coverage: Vec<f64>,
    patch_texture: Vec<Rgb>,
}

impl TextureMeans {
    fn of(scene: &Scene, mesh: &Mesh) -> Self {
        use rayon::prelude::*;
        let textured =
            (scene.materials.iter()).any(|m| m.diffuse_map.is_some() || m.alpha_map.is_some());
        if !textured {
            return Self {
                element_texture: Vec::new(),
                element_coverage: Vec::new(),
                patch_texture: Vec::new(),
            };
        }
        let means: Vec<(Rgb, f64)> = (mesh.elements.par_iter())
            .map(|e| {
                // A degenerate element's mean can be undefined: it keeps its Kd.
                scene
                    .texture_mean(e.face as usize, e.corners())
                    .map(|t| (t.rgb * t.coverage, t.coverage))
                    .filter(|(t, c)| t.is_finite() && c.is_finite())
                    .unwrap_or((Rgb::ONE, 1.0))
            })
            .collect();
        let element_texture: Vec<Rgb> = means.iter().map(|m| m.0).collect();
        let element_coverage = if means.iter().any(|m| m.1 < 1.0) {
            means.iter().map(|m| m.1).collect()
        } else {
            Vec::new()
        };
        Self {
            patch_texture: mesh.patch_means(&element_texture),
            element_texture,
            element_coverage,
        }
    }
}
