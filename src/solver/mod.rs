//! Progressive refinement radiosity with substructuring and the ambient term
//! (Cohen, Chen, Wallace, Greenberg 1988, "A progressive refinement approach to fast
//! radiosity image generation").
//!
//! Each shot takes the patch with the largest unshot power `|ΔB_i|·A_i` (channel sum) and
//! distributes it to every element: `ΔB_j = ρ_j ΔB_i F_ji`. Elements keep their *incident*
//! radiance `H_j = Σ ΔB_i F_ji` so that `B_j = E_j + ρ_j H_j`; a material edit then becomes a
//! (possibly negative) unshot delta and the solution adapts without restarting. The ambient
//! term `R · Σ ΔB_i A_i / Σ A_i`, `R = 1/(1 − ρ_avg)`, is for display only.
//!
//! All sums are `f64`. Rows of form factors are cached per shooting patch (up to a memory
//! budget), so a patch that shoots again costs one pass over the elements. Results depend
//! only on the scene, the settings and the seed, not on thread count or timing.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::formfactor::hemicube::ItemBufferRaster;
use crate::formfactor::{self, FormFactorMethod, FormFactorParams, RowContext};
use crate::geometry::Bvh;
use crate::mesh::{self, Mesh, MeshError, PatchId};
use crate::scene::{MaterialId, Rgb, Scene};

#[derive(Clone, Debug)]
pub struct SolverConfig {
    /// Element edge length; `None` = [`mesh::default_element_size`].
    pub element_size: Option<f64>,
    /// Patch (shooter) edge length; `None` = [`mesh::default_patch_size`].
    pub patch_size: Option<f64>,
    /// Element budget for the element size when `element_size` is `None`; `None` =
    /// [`mesh::default_element_size`].
    pub max_elements: Option<usize>,
    pub method: FormFactorMethod,
    pub formfactor: FormFactorParams,
    /// Memory for cached form-factor rows, in bytes.
    pub row_cache_bytes: usize,
    /// The rasteriser of `gpu-hemicube` rows (`crate::gpu::GpuHemicube`); required by that
    /// method, unused by the others.
    pub raster: Option<Arc<dyn ItemBufferRaster>>,
}

impl Default for SolverConfig {
    fn default() -> Self {
        Self {
            element_size: None,
            patch_size: None,
            max_elements: None,
            method: FormFactorMethod::Contour,
            formfactor: FormFactorParams::default(),
            row_cache_bytes: 512 << 20,
            raster: None,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum SolverError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("the gpu-hemicube method needs a GPU hemicube rasteriser, and none was set up")]
    NoRaster,
    #[error("material {0} does not exist")]
    NoSuchMaterial(u32),
    #[error("{what} must be finite and {range}, got {value:?}")]
    BadValue {
        what: &'static str,
        range: &'static str,
        value: [f64; 3],
    },
    #[error(
        "the emitted power (Σ Ke × area = {emitted:e}) is too large: with interreflection it would overflow to infinity; lower Ke or scale the model down"
    )]
    PowerOverflow { emitted: f64 },
}

/// Refuses materials whose light would overflow `f64` during a solve: the emitted power
/// `P = Σ |E| A` (channel sums), times `1/(1 − ρ_max)` for all its interreflections (the
/// most power a solve carries), over the smallest patch area (the largest unshot radiance
/// that power can become) must be finite; otherwise unshot fractions turn NaN and a solve
/// to a target never ends.
fn check_power(materials: &[crate::scene::Material], mesh: &Mesh) -> Result<(), SolverError> {
    let mut emitted = 0.0;
    let mut rho_max: f64 = 0.0;
    let mut min_area = f64::INFINITY;
    for p in &mesh.patches {
        let m = &materials[p.material.0 as usize];
        emitted += channel_sum(m.emission) * p.area;
        rho_max = rho_max.max(m.reflectance.max_element());
        if p.area > 0.0 {
            min_area = min_area.min(p.area);
        }
    }
    let carried = emitted / (1.0 - rho_max.min(crate::scene::MAX_REFLECTANCE));
    if !(carried.is_finite() && (carried / min_area.min(1.0)).is_finite()) {
        return Err(SolverError::PowerOverflow { emitted });
    }
    Ok(())
}

/// When to stop [`ProgressiveSolver::run`].
#[derive(Clone, Copy, Debug)]
pub struct StopCriteria {
    /// Remaining unshot power over emitted power.
    pub unshot: f64,
    pub max_shots: Option<usize>,
    pub max_seconds: Option<f64>,
}

impl Default for StopCriteria {
    fn default() -> Self {
        Self {
            unshot: 1e-4,
            max_shots: None,
            max_seconds: None,
        }
    }
}

/// One row of the convergence log.
#[derive(Clone, Copy, Debug)]
pub struct ShotRecord {
    pub shot: usize,
    pub seconds: f64,
    pub unshot_fraction: f64,
    /// Channel mean of the ambient term.
    pub ambient: f64,
    pub shooter: PatchId,
}

/// A progressive-refinement radiosity solution of one scene (see the module docs).
///
/// In the furnace (a closed unit cube, every wall emitting `E = 1` and reflecting `ρ`) the
/// exact radiosity is `E/(1 − ρ)` everywhere; the solver approaches it as the unshot power
/// falls. What is missing at an unshot fraction `u` is about `u·E·ρ/(1 − ρ)`, 5e-5 of the
/// answer here (measured: 6e-5 on this 1/4 mesh and on a 1/8 one), so 1e-3 leaves room
/// for the form factors' row sums without hiding a real error:
///
/// ```
/// use std::sync::atomic::AtomicBool;
///
/// use nusselt::scene::{LoadOptions, Scene};
/// use nusselt::solver::{ProgressiveSolver, SolverConfig, StopCriteria};
///
/// let rho = 0.5;
/// let scene = Scene::builtin("furnace", &LoadOptions { rho: Some(rho), ..Default::default() })?;
/// let config = SolverConfig { element_size: Some(0.25), ..Default::default() };
/// let mut solver = ProgressiveSolver::new(scene, config)?;
/// assert_eq!(solver.unshot_fraction(), 1.0); // Nothing shot yet.
///
/// let stop = StopCriteria { unshot: 1e-4, ..Default::default() };
/// solver.run(&stop, &AtomicBool::new(false), &mut |shot| {
///     assert!(shot.unshot_fraction.is_finite());
/// });
/// assert!(solver.unshot_fraction() <= 1e-4);
/// let exact = 1.0 / (1.0 - rho);
/// for b in solver.radiosity() {
///     assert!((b.x - exact).abs() < 1e-3 * exact, "{b} vs {exact}");
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct ProgressiveSolver {
    scene: Scene,
    config: SolverConfig,
    mesh: Mesh,
    bvh: Bvh,
    epsilon: f64,
    /// Per element.
    radiosity: Vec<Rgb>,
    /// Reflectance of each element's material (read on every shot).
    element_rho: Vec<Rgb>,
    incident: Vec<Rgb>,
    /// Per patch, radiance units.
    unshot: Vec<Rgb>,
    rows: Vec<Option<Arc<[f32]>>>,
    cached_bytes: usize,
    shots: usize,
    last_shooter: Option<PatchId>,
    total_area: f64,
    /// Σ |E_i| A_i (channel sum) at the last (re)start, the denominator of unshot fractions.
    emitted_power: f64,
}

fn channel_sum(c: Rgb) -> f64 {
    c.x.abs() + c.y.abs() + c.z.abs()
}

/// Scales a row so that a shot never delivers more power than it carries:
/// `Σ_j F_ji A_j ≤ A_i`. Form factors evaluated at element centroids are not exactly
/// reciprocal; where a small shooter lies close to a large receiving element's centroid
/// (contact, slivers, duplicated faces) `F_ji A_j` can exceed `A_i`, and repeated shots
/// between such a pair gain energy without bound. Exact rows satisfy the bound
/// (the row sum of a closed scene is 1 to the centroid rule's O(h²) error, ~1e-3 here, which
/// is left alone: clipping it would bias every closed scene dark), so this changes only
/// rows that break it grossly, and scales them back to delivering exactly the shot.
const MAX_ROW_GAIN: f64 = 1.01;

/// Patches whose unshot powers are within this relative difference are tied for the next
/// shot and the first in index order wins. Symmetric patches have equal powers up to the
/// round-off of their coordinates, which differs with the scene's unit: breaking such ties
/// by that round-off made the same scene at scale 1, 1e-3 and 1e4 shoot in different orders
/// (issue 11: a different shot count at `--unshot 1e-3` and images 1.8e-4 apart).
const SHOOTER_TIE: f64 = 1e-9;

fn conserve_energy(mesh: &Mesh, shooter: PatchId, row: &mut [f32]) {
    let area = mesh.patch(shooter).area;
    let delivered: f64 = row
        .iter()
        .zip(&mesh.elements)
        .map(|(f, e)| *f as f64 * e.area)
        .sum();
    if area > 0.0 && delivered > MAX_ROW_GAIN * area {
        let k = (area / delivered) as f32;
        row.iter_mut().for_each(|f| *f *= k);
        debug_assert!(k.is_finite());
    }
}

impl ProgressiveSolver {
    pub fn new(scene: Scene, config: SolverConfig) -> Result<Self, SolverError> {
        if config.method == FormFactorMethod::GpuHemicube && config.raster.is_none() {
            return Err(SolverError::NoRaster);
        }
        let mesh = match config.element_size {
            Some(size) => {
                let patch = config
                    .patch_size
                    .unwrap_or_else(|| mesh::default_patch_size(size))
                    .max(size);
                Mesh::build_with(&scene, size, patch)?
            }
            None => Mesh::build_for_budget(&scene, config.max_elements, config.patch_size)?,
        };
        check_power(&scene.materials, &mesh)?;
        let bvh = Bvh::build(&mesh.blocker_triangles(&scene));
        let epsilon = 1e-6 * mesh.bounds().diagonal().max(1e-12);
        let mut s = Self {
            scene,
            config,
            mesh,
            bvh,
            epsilon,
            radiosity: Vec::new(),
            element_rho: Vec::new(),
            incident: Vec::new(),
            unshot: Vec::new(),
            rows: Vec::new(),
            cached_bytes: 0,
            shots: 0,
            last_shooter: None,
            total_area: 0.0,
            emitted_power: 0.0,
        };
        s.reset();
        Ok(s)
    }

    /// Back to the dark start: only emitters have radiance, nothing has been shot.
    /// Cached form factors are kept (the geometry did not change).
    pub fn reset(&mut self) {
        let n = self.mesh.elements.len();
        self.incident = vec![Rgb::ZERO; n];
        self.element_rho = self.element_reflectance();
        self.radiosity = self
            .mesh
            .elements
            .iter()
            .map(|e| self.material_of(e.patch).emission)
            .collect();
        self.unshot = self
            .mesh
            .patches
            .iter()
            .map(|p| self.scene.materials[p.material.0 as usize].emission)
            .collect();
        if self.rows.len() != self.mesh.patches.len() {
            self.rows = vec![None; self.mesh.patches.len()];
            self.cached_bytes = 0;
        }
        self.shots = 0;
        self.last_shooter = None;
        self.total_area = self.mesh.patches.iter().map(|p| p.area).sum();
        self.emitted_power = self.current_emitted_power();
    }

    fn current_emitted_power(&self) -> f64 {
        self.mesh
            .patches
            .iter()
            .map(|p| channel_sum(self.scene.materials[p.material.0 as usize].emission) * p.area)
            .sum()
    }

    fn element_reflectance(&self) -> Vec<Rgb> {
        self.mesh
            .elements
            .iter()
            .map(|e| self.material_of(e.patch).reflectance)
            .collect()
    }

    fn material_of(&self, patch: PatchId) -> &crate::scene::Material {
        &self.scene.materials[self.mesh.patch(patch).material.0 as usize]
    }

    /// Rebuilds the mesh with a new element size and restarts from dark.
    pub fn remesh(&mut self, element_size: f64) -> Result<(), SolverError> {
        let patch = self
            .config
            .patch_size
            .unwrap_or_else(|| mesh::default_patch_size(element_size))
            .max(element_size);
        let mesh = Mesh::build_with(&self.scene, element_size, patch)?;
        check_power(&self.scene.materials, &mesh)?;
        self.bvh = Bvh::build(&mesh.blocker_triangles(&self.scene));
        self.mesh = mesh;
        self.config.element_size = Some(element_size);
        self.rows.clear();
        self.reset();
        Ok(())
    }

    /// Switches the form-factor method (clears cached rows, restarts from dark). Refused
    /// (nothing changes) for `gpu-hemicube` without a rasteriser ([`set_raster`](Self::set_raster)).
    pub fn set_method(&mut self, method: FormFactorMethod) -> Result<(), SolverError> {
        if method == FormFactorMethod::GpuHemicube && self.config.raster.is_none() {
            return Err(SolverError::NoRaster);
        }
        self.config.method = method;
        self.rows.clear();
        self.reset();
        Ok(())
    }

    /// Installs the rasteriser used by `gpu-hemicube` rows (takes effect from the next row).
    pub fn set_raster(&mut self, raster: Option<Arc<dyn ItemBufferRaster>>) {
        self.config.raster = raster;
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }
    pub fn config(&self) -> &SolverConfig {
        &self.config
    }
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }
    pub fn shots(&self) -> usize {
        self.shots
    }
    pub fn last_shooter(&self) -> Option<PatchId> {
        self.last_shooter
    }
    /// Radiosity (radiance units) per element, without the ambient term.
    pub fn radiosity(&self) -> &[Rgb] {
        &self.radiosity
    }

    /// Unshot radiance per patch.
    pub fn unshot(&self) -> &[Rgb] {
        &self.unshot
    }

    /// Remaining unshot power over emitted power (channel sums).
    pub fn unshot_fraction(&self) -> f64 {
        let remaining: f64 = self
            .unshot
            .iter()
            .zip(&self.mesh.patches)
            .map(|(u, p)| channel_sum(*u) * p.area)
            .sum();
        if self.emitted_power > 0.0 {
            remaining / self.emitted_power
        } else if remaining > 0.0 {
            f64::INFINITY
        } else {
            0.0
        }
    }

    /// The ambient term (Cohen et al. 1988): an estimate of the light not yet shot.
    pub fn ambient(&self) -> Rgb {
        if self.total_area <= 0.0 {
            return Rgb::ZERO;
        }
        let mut rho = Rgb::ZERO;
        let mut unshot = Rgb::ZERO;
        for (p, u) in self.mesh.patches.iter().zip(&self.unshot) {
            rho += self.scene.materials[p.material.0 as usize].reflectance * p.area;
            unshot += *u * p.area;
        }
        let rho_avg = rho / self.total_area;
        let r = Rgb::ONE / (Rgb::ONE - rho_avg).max(Rgb::splat(1e-6));
        r * unshot / self.total_area
    }

    /// Per-element radiance for display: `B_j + ρ_j · ambient` when `with_ambient`.
    pub fn element_radiance(&self, with_ambient: bool) -> Vec<Rgb> {
        let ambient = if with_ambient {
            self.ambient()
        } else {
            Rgb::ZERO
        };
        self.mesh
            .elements
            .iter()
            .zip(&self.radiosity)
            .map(|(e, b)| *b + self.material_of(e.patch).reflectance * ambient)
            .collect()
    }

    /// The patch with the largest unshot power, if any power is left.
    pub fn next_shooter(&self) -> Option<PatchId> {
        let mut best: Option<(f64, usize)> = None;
        for (i, (u, p)) in self.unshot.iter().zip(&self.mesh.patches).enumerate() {
            let power = channel_sum(*u) * p.area;
            if power > 0.0 && best.is_none_or(|b| power > b.0 * (1.0 + SHOOTER_TIE)) {
                best = Some((power, i));
            }
        }
        best.map(|b| PatchId(b.1 as u32))
    }

    /// What a form-factor row of this solver sees (its scene, mesh, BVH, parameters, shadow-ray
    /// offset and rasteriser), for computing rows outside [`shoot`](Self::shoot).
    pub fn row_context(&self) -> RowContext<'_> {
        RowContext {
            scene: &self.scene,
            mesh: &self.mesh,
            bvh: &self.bvh,
            params: &self.config.formfactor,
            epsilon: self.epsilon,
            raster: self.config.raster.as_deref(),
        }
    }

    fn row(&mut self, shooter: PatchId, cancel: &AtomicBool) -> Option<Arc<[f32]>> {
        if let Some(r) = &self.rows[shooter.0 as usize] {
            return Some(r.clone());
        }
        let mut out = vec![0f32; self.mesh.elements.len()];
        let ctx = self.row_context();
        if !formfactor::compute_row(self.config.method, &ctx, shooter, &mut out, cancel) {
            return None;
        }
        conserve_energy(&self.mesh, shooter, &mut out);
        let row: Arc<[f32]> = out.into();
        let bytes = row.len() * 4;
        if self.cached_bytes + bytes <= self.config.row_cache_bytes {
            self.cached_bytes += bytes;
            self.rows[shooter.0 as usize] = Some(row.clone());
        }
        Some(row)
    }

    /// One shot from the patch with the most unshot power. Returns the shooter, or `None`
    /// when nothing is left to shoot or `cancel` was set (then nothing changed).
    pub fn shoot(&mut self, cancel: &AtomicBool) -> Option<PatchId> {
        let shooter = self.next_shooter()?;
        let row = self.row(shooter, cancel)?;
        if cancel.load(Ordering::Relaxed) {
            return None;
        }
        let delta = self.unshot[shooter.0 as usize];
        self.unshot[shooter.0 as usize] = Rgb::ZERO;
        // Receiving patches in parallel: each owns its elements' slices (elements are
        // stored patch by patch).
        let mesh = &self.mesh;
        let rho = &self.element_rho;
        let mut jobs = Vec::with_capacity(mesh.patches.len());
        let (mut radiosity, mut incident) = (&mut self.radiosity[..], &mut self.incident[..]);
        for p in &mesh.patches {
            let n = (p.elements.end - p.elements.start) as usize;
            let (b, rest_b) = std::mem::take(&mut radiosity).split_at_mut(n);
            let (h, rest_h) = std::mem::take(&mut incident).split_at_mut(n);
            radiosity = rest_b;
            incident = rest_h;
            jobs.push((p.elements.start as usize, b, h));
        }
        let gained: Vec<Rgb> = jobs
            .into_par_iter()
            .with_min_len(32)
            .map(|(first, b, h)| {
                let mut gained = Rgb::ZERO;
                for (k, (b, h)) in b.iter_mut().zip(h.iter_mut()).enumerate() {
                    let j = first + k;
                    let f = row[j] as f64;
                    if f == 0.0 {
                        continue;
                    }
                    let dh = delta * f;
                    *h += dh;
                    let db = rho[j] * dh;
                    *b += db;
                    gained += db * mesh.elements[j].area;
                }
                gained
            })
            .collect();
        for ((u, g), p) in self.unshot.iter_mut().zip(&gained).zip(&self.mesh.patches) {
            *u += *g / p.area;
        }
        debug_assert!(self.radiosity.iter().all(|b| b.is_finite()));
        self.shots += 1;
        self.last_shooter = Some(shooter);
        Some(shooter)
    }

    /// Shoots until `stop` is met; calls `on_shot` after each shot.
    pub fn run(
        &mut self,
        stop: &StopCriteria,
        cancel: &AtomicBool,
        on_shot: &mut dyn FnMut(&ShotRecord),
    ) {
        let start = Instant::now();
        loop {
            // A NaN fraction stops too instead of shooting forever.
            let fraction = self.unshot_fraction();
            if fraction.is_nan()
                || fraction <= stop.unshot
                || stop.max_shots.is_some_and(|n| self.shots >= n)
                || stop
                    .max_seconds
                    .is_some_and(|s| start.elapsed().as_secs_f64() >= s)
            {
                return;
            }
            let Some(shooter) = self.shoot(cancel) else {
                return;
            };
            let ambient = self.ambient();
            on_shot(&ShotRecord {
                shot: self.shots,
                seconds: start.elapsed().as_secs_f64(),
                unshot_fraction: self.unshot_fraction(),
                ambient: (ambient.x + ambient.y + ambient.z) / 3.0,
                shooter,
            });
        }
    }

    /// Changes a material's reflectance and emission; the difference becomes unshot
    /// radiance, so shooting continues from the current state instead of from dark.
    pub fn set_material(
        &mut self,
        id: MaterialId,
        reflectance: Rgb,
        emission: Rgb,
    ) -> Result<(), SolverError> {
        let idx = id.0 as usize;
        if idx >= self.scene.materials.len() {
            return Err(SolverError::NoSuchMaterial(id.0));
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
        self.element_rho = self.element_reflectance();
        let mut gained = vec![Rgb::ZERO; self.mesh.patches.len()];
        for (j, e) in self.mesh.elements.iter().enumerate() {
            let p = &self.mesh.patches[e.patch.0 as usize];
            if p.material != id {
                continue;
            }
            let new = emission + reflectance * self.incident[j];
            gained[e.patch.0 as usize] += (new - self.radiosity[j]) * e.area;
            self.radiosity[j] = new;
        }
        for ((u, g), p) in self.unshot.iter_mut().zip(&gained).zip(&self.mesh.patches) {
            *u += *g / p.area;
        }
        self.emitted_power = self.current_emitted_power().max(f64::MIN_POSITIVE);
        Ok(())
    }

    /// Incident radiance per element, `H_j = Σ ΔB_i F_ji` over all shots.
    pub fn incident(&self) -> &[Rgb] {
        &self.incident
    }

    /// Emitted power Σ E·A and absorbed power Σ (1 − ρ)·H·A over elements. In a closed
    /// enclosure they are equal at convergence.
    pub fn power_balance(&self) -> (Rgb, Rgb) {
        let mut emitted = Rgb::ZERO;
        let mut absorbed = Rgb::ZERO;
        for (e, h) in self.mesh.elements.iter().zip(&self.incident) {
            let m = self.material_of(e.patch);
            emitted += m.emission * e.area;
            absorbed += (Rgb::ONE - m.reflectance) * *h * e.area;
        }
        (emitted, absorbed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LoadOptions;

    #[test]
    fn a_nan_unshot_fraction_stops_the_run_instead_of_shooting_forever() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let mut s = ProgressiveSolver::new(scene, SolverConfig::default()).expect("solver");
        // What an overflow used to leave: inf/inf somewhere in the unshot power.
        s.unshot[0] = Rgb::splat(f64::NAN);
        assert!(s.unshot_fraction().is_nan());
        let stop = StopCriteria {
            unshot: 1e-4,
            max_shots: None,
            // Only so that a regression fails in bounded time; the run must not get here.
            max_seconds: Some(20.0),
        };
        s.run(&stop, &AtomicBool::new(false), &mut |_| {});
        assert_eq!(s.shots(), 0, "shot on with a NaN unshot fraction");
    }
}
