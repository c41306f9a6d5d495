//! Teaching mode on the solver thread (`viewer::teach`): recording single steps, one step
//! back by replaying from dark, and keeping the hemicube view up to date.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use crate::viewer::teach::TeachCommand;
use crate::viewer::teach::hemicube;
use crate::viewer::teach::step::{Before, capture};

use super::worker::Worker;

impl Worker {
    pub(super) fn teach(&mut self, command: TeachCommand) {
        match command {
            TeachCommand::RecordSteps(on) => {
                self.record_steps = on;
                if !on {
                    self.step_detail = None;
                }
            }
            TeachCommand::Back => self.back(),
            TeachCommand::Hemicube(request) => {
                self.hemicube_request = request;
                if request.is_none() {
                    self.hemicube_detail = None;
                    self.hemicube_key = None;
                }
            }
        }
    }

    /// One step back: reset, then replay to one step before the current one (rows come
    /// from the cache and every solver here is deterministic, so this is the earlier
    /// state). The last replayed step is recorded, so its numbers show again. Pauses.
    fn back(&mut self) {
        let record = self.record_steps;
        let Some(solver) = self.solver.as_mut() else {
            return;
        };
        let target = solver.steps().saturating_sub(1);
        self.playing = false;
        self.steps = 0;
        solver.reset();
        // Not the shared cancel flag: a command arriving now must not leave a half replay.
        let never = AtomicBool::new(false);
        for _ in 1..target {
            if !solver.step(&never) {
                break;
            }
        }
        self.step_detail = None;
        if target > 0 {
            let before = record.then(|| Before::take(solver.as_ref())).flatten();
            if solver.step(&never)
                && let (Some(b), Some(g)) = (before, &self.geometry)
            {
                self.step_detail = capture(b, solver.as_ref(), g).map(Arc::new);
            }
        }
        let steps = solver.steps();
        Arc::make_mut(&mut self.history).retain(|p| p.steps <= steps);
    }

    /// Recomputes the hemicube asked for when its shooter or the mesh changed.
    pub(super) fn refresh_hemicube(&mut self) {
        let (Some(request), Some(solver), Some(geometry)) =
            (self.hemicube_request, &self.solver, &self.geometry)
        else {
            return;
        };
        let last = solver.last_shooter();
        let key = (request, last.map(|p| p.0), geometry.id);
        if self.hemicube_key == Some(key) {
            return;
        }
        self.hemicube_key = Some(key);
        self.hemicube_detail = hemicube::compute(solver.problem(), request, last).map(Arc::new);
    }
}
