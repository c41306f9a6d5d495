//! What the ray-traced view renders (`viewer::raytrace`), taken from the solver: the scene,
//! the mesh and the element radiance, copied when the solution changed, at most every
//! [`RUNNING_INTERVAL`] while the solve runs (a copy of the mesh each time) and at once
//! when it stops.

use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::raytrace::RenderInput;

use super::worker::Worker;

/// While the solver steps, the view follows the solution this often.
const RUNNING_INTERVAL: Duration = Duration::from_secs(2);

/// The ray-traced view's input: whether the view is on, the last input taken, and for
/// what (steps, mesh, materials) and when.
#[derive(Default)]
pub(super) struct RayInput {
    on: bool,
    pub(super) input: Option<Arc<RenderInput>>,
    key: Option<(usize, u64, u64)>,
    at: Option<Instant>,
}

impl RayInput {
    /// The view turned on or off; off drops its input.
    pub(super) fn set_on(&mut self, on: bool) {
        self.on = on;
        if !on {
            self.input = None;
            self.key = None;
        }
    }
}

impl Worker {
    pub(super) fn refresh_ray_input(&mut self) {
        let (true, Some(solver), Some(geometry)) = (self.ray.on, &self.solver, &self.geometry)
        else {
            return;
        };
        let key = (solver.steps(), geometry.id, self.reflectance_rev);
        if self.ray.key == Some(key) {
            return;
        }
        if self.wants_to_step() && self.ray.at.is_some_and(|t| t.elapsed() < RUNNING_INTERVAL) {
            return;
        }
        let problem = solver.problem();
        self.ray.input = Some(Arc::new(RenderInput {
            seq: self.published.seq + 1,
            scene: problem.scene.clone(),
            config: problem.config.clone(),
            mesh: problem.mesh.clone(),
            radiance: solver.display_radiance(),
        }));
        self.ray.key = Some(key);
        self.ray.at = Some(Instant::now());
    }
}
