//! Uniform vs adaptive meshing, side by side (`--teach mesh`): the lecture's "small patches
//! where light rapidly changes (shadow boundaries, near light sources), large where it is
//! constant".
//!
//! Left, the uniform mesh the viewer uses; right, an adaptive one (Cohen, Greenberg, Immel
//! & Brock 1986, [`nusselt_core::mesh::adaptive`]): the scene meshed four times coarser, solved,
//! and refined twice where the radiance varies across an element by more than the
//! tolerance, so its smallest elements are the uniform mesh's size. Both are solved by
//! progressive shooting to 0.1 % unshot power and drawn flat, one colour per element, with
//! the element edges, and their element counts and solve times side by side.
//!
//! It takes seconds (three solves), so it runs on its own thread; the solver thread polls it.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::thread::JoinHandle;
use std::time::Instant;

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{Camera, Scene};
use nusselt_core::solver::{Problem, Solver, SolverConfig, SolverKind, StopCriteria, run_solver};

use super::item_image::ItemImage;

/// Side of each image, in pixels.
pub const IMAGE_SIDE: usize = 288;

/// The adaptive mesh starts this many times coarser than the uniform one (two levels of
/// refinement, each halving the element size, bring it back).
const COARSER: f64 = 4.0;

/// Refinement passes of the adaptive mesh.
const PASSES: u8 = 2;

/// Both solves stop at this unshot fraction.
const UNSHOT: f64 = 1e-3;

/// The default tolerance of the adaptive mesh (a fraction of an element's radiance).
pub const DEFAULT_TOLERANCE: f64 = 0.25;

/// One of the two meshes, solved.
#[derive(Debug)]
pub struct MeshSide {
    pub elements: usize,
    pub patches: usize,
    /// Smallest and largest element area.
    pub smallest: f64,
    pub largest: f64,
    /// Seconds to mesh and solve (the adaptive one: all its passes).
    pub seconds: f64,
    /// Radiance per element.
    pub radiance: Vec<[f32; 3]>,
    /// Area per element.
    pub area: Vec<f32>,
    pub image: ItemImage,
}

/// What the view shows.
#[derive(Debug)]
pub struct MeshDetail {
    /// The viewer's mesh it was computed for (`Geometry::id`).
    pub geometry_id: u64,
    pub tolerance: f64,
    pub uniform: MeshSide,
    pub adaptive: MeshSide,
}

/// The stage a running job is in, for the panel.
pub const STAGES: [&str; 4] = [
    "solving the uniform mesh",
    "solving the coarse mesh and refining it",
    "solving the adaptive mesh",
    "done",
];

/// The comparison being computed on its own thread.
pub struct MeshJob {
    /// The mesh of the viewer it was started for (`Geometry::id`).
    pub geometry_id: u64,
    pub tolerance: f64,
    stage: Arc<AtomicU8>,
    cancel: Arc<AtomicBool>,
    handle: Option<JoinHandle<Result<MeshDetail, String>>>,
}

impl MeshJob {
    /// Starts meshing `scene` both ways with the viewer's `config`.
    pub fn start(
        scene: Scene,
        config: SolverConfig,
        camera: Camera,
        geometry_id: u64,
        tolerance: f64,
    ) -> Result<MeshJob, String> {
        let stage = Arc::new(AtomicU8::new(0));
        let cancel = Arc::new(AtomicBool::new(false));
        let (s, c) = (stage.clone(), cancel.clone());
        let handle = std::thread::Builder::new()
            .name("nusselt-teach-mesh".into())
            .spawn(move || compute(scene, config, &camera, (geometry_id, tolerance), &s, &c))
            .map_err(|e| format!("cannot start the meshing view: {e}"))?;
        Ok(MeshJob {
            geometry_id,
            tolerance,
            stage,
            cancel,
            handle: Some(handle),
        })
    }

    /// What the job is doing ([`STAGES`]).
    pub fn stage(&self) -> &'static str {
        STAGES[(self.stage.load(Ordering::Relaxed) as usize).min(STAGES.len() - 1)]
    }

    pub fn finished(&self) -> bool {
        self.handle.as_ref().is_none_or(|h| h.is_finished())
    }

    /// The result (blocks until the job ends).
    pub fn join(mut self) -> Result<MeshDetail, String> {
        match self.handle.take().map(|h| h.join()) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err("the meshing view failed (a panic in its solve)".into()),
            None => Err("the meshing view was already collected".into()),
        }
    }
}

impl Drop for MeshJob {
    /// A job no longer wanted stops at its next step.
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}

fn side(
    mut solver: Box<dyn Solver>,
    camera: &Camera,
    start: Instant,
    cancel: &AtomicBool,
) -> Result<MeshSide, String> {
    let stop = StopCriteria {
        residual: UNSHOT,
        ..Default::default()
    };
    run_solver(solver.as_mut(), &stop, cancel, &mut |_, _| {});
    if cancel.load(Ordering::Relaxed) {
        return Err("cancelled".into());
    }
    let radiance = solver.radiosity();
    let problem = solver.problem();
    let mesh = &problem.mesh;
    let bvh = nusselt_core::render::display_bvh(&problem.scene, mesh);
    let triangle_element: Vec<u32> = mesh.triangle_element.iter().map(|e| e.0).collect();
    let image = ItemImage::trace(&bvh, &triangle_element, camera, IMAGE_SIDE, IMAGE_SIDE);
    let areas = mesh.elements.iter().map(|e| e.area);
    Ok(MeshSide {
        elements: mesh.elements.len(),
        patches: mesh.patches.len(),
        smallest: areas.clone().fold(f64::INFINITY, f64::min),
        largest: areas.fold(0.0, f64::max),
        seconds: start.elapsed().as_secs_f64(),
        radiance: radiance.iter().map(|c| c.as_vec3().to_array()).collect(),
        area: mesh.elements.iter().map(|e| e.area as f32).collect(),
        image,
    })
}

fn compute(
    scene: Scene,
    config: SolverConfig,
    camera: &Camera,
    (geometry_id, tolerance): (u64, f64),
    stage: &AtomicU8,
    cancel: &AtomicBool,
) -> Result<MeshDetail, String> {
    let start = Instant::now();
    let problem = Problem::new(scene.clone(), config.clone()).map_err(|e| e.to_string())?;
    let h = problem.mesh.element_size;
    let patch = problem.mesh.patch_size;
    let uniform = SolverKind::Shooting
        .build(problem)
        .map_err(|e| e.to_string())?;
    let uniform = side(uniform, camera, start, cancel)?;
    stage.store(1, Ordering::Relaxed);
    let start = Instant::now();
    let coarse = SolverConfig {
        mesh: MeshSpec {
            element_size: Some(h * COARSER),
            patch_size: Some(patch.max(h * COARSER)),
            max_elements: None,
            ..config.mesh
        },
        ..config
    };
    let problem = Problem::new(scene, coarse).map_err(|e| e.to_string())?;
    let refined = nusselt_core::solver::refine::refine_adaptively(
        problem,
        SolverKind::Shooting.into(),
        tolerance,
        PASSES,
        UNSHOT,
        cancel,
    )
    .map_err(|e| e.to_string())?
    .solver;
    if cancel.load(Ordering::Relaxed) {
        return Err("cancelled".into());
    }
    stage.store(2, Ordering::Relaxed);
    let adaptive = side(refined, camera, start, cancel)?;
    stage.store(3, Ordering::Relaxed);
    Ok(MeshDetail {
        geometry_id,
        tolerance,
        uniform,
        adaptive,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nusselt_core::scene::LoadOptions;

    /// On the Cornell box the adaptive mesh has fewer elements than the uniform one of its
    /// smallest size, and elements of more than one size (it refined somewhere, not
    /// everywhere); both images see the box.
    #[test]
    fn the_adaptive_mesh_is_smaller_and_graded() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::element(60.0),
            ..SolverConfig::default()
        };
        let job =
            MeshJob::start(scene, config, Camera::cornell(), 1, DEFAULT_TOLERANCE).expect("job");
        let d = job.join().expect("detail");
        let (u, a) = (&d.uniform, &d.adaptive);
        assert!(a.elements < u.elements, "{} vs {}", a.elements, u.elements);
        // Refinement quarters an element's area each level.
        assert!(a.largest > 3.0 * a.smallest, "{} {}", a.largest, a.smallest);
        for s in [u, a] {
            let seen = s.image.element.iter().filter(|&&e| e != u32::MAX).count();
            assert!(seen > s.image.element.len() / 2);
            assert_eq!(s.radiance.len(), s.elements);
            assert_eq!(s.area.len(), s.elements);
        }
    }
}
