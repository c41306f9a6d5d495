//! `--solver auto` in the viewer: shooting, handed over to hierarchical radiosity on a
//! large scene once most of the light is spread (`nusselt_core::solver::handoff`, whose
//! module docs say why and give the measurements). The solve goes on: its clock, history
//! and image carry over, and the panel shows the new solver.

use nusselt_core::solver::{SolverKind, handoff};

use super::Event;
use super::worker::Worker;

impl Worker {
    /// Hands a running auto solve over when it is due. Not while the solve is scripted
    /// (a shot count), stepped by hand, taught or refined adaptively: those read shots.
    pub(super) fn handoff_once(&mut self) {
        let Some(solver) = self.solver.as_ref() else {
            return;
        };
        let scripted = self.max_shots.is_some() || !self.playing || self.teach.record_steps;
        if !self.handoff || scripted || self.adapting.is_some() || !handoff::due(solver.as_ref()) {
            return;
        }
        let Some(solver) = self.solver.take() else {
            return;
        };
        let (shots, unshot) = (solver.steps(), solver.residual());
        let start = std::time::Instant::now();
        self.solver = Some(handoff::hand_over(solver));
        self.elapsed += start.elapsed();
        self.kind = SolverKind::Hierarchical;
        self.send_event(Event::Notice(format!(
            "auto: {shots} shots left {:.1} % of the light unshot; hierarchical radiosity goes on from there (on this many elements each further shot costs a row to every element)",
            100.0 * unshot
        )));
        self.dirty = true;
    }
}
