//! The one run loop of every solver ([`run_solver`]) and its stop rules ([`StopCriteria`]).

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use super::Solver;

/// When to stop [`run_solver`]: at the first rule met.
#[derive(Clone, Copy, Debug)]
pub struct StopCriteria {
    /// The relative residual to reach ([`Solver::residual`]; for shooting the unshot
    /// fraction of the emitted power): `--unshot`.
    pub residual: f64,
    /// Steps at most ([`Solver::steps`]: shots, matrix rows and sweeps): `--shots`.
    pub max_steps: Option<usize>,
    /// Seconds of solving at most.
    pub max_seconds: Option<f64>,
    /// Stop when the solver's estimate of the remaining relative error of every element
    /// ([`Solver::error_estimate`]) falls to this (`--tolerance`).
    pub tolerance: Option<f64>,
}

impl Default for StopCriteria {
    fn default() -> Self {
        Self {
            residual: 1e-4,
            max_steps: None,
            max_seconds: None,
            tolerance: None,
        }
    }
}

impl StopCriteria {
    /// To a residual of `residual`, with no other rule.
    pub fn residual(residual: f64) -> Self {
        Self {
            residual,
            ..Default::default()
        }
    }
}

/// One row of a run's log.
#[derive(Clone, Copy, Debug)]
pub struct StepRecord {
    pub step: usize,
    pub seconds: f64,
    pub residual: f64,
}

/// [`run_solver`] to a residual of `residual`, uncancelled and unwatched: for batch runs,
/// benches and tests.
pub fn solve_to(solver: &mut dyn Solver, residual: f64) {
    run_solver(
        solver,
        &StopCriteria::residual(residual),
        &AtomicBool::new(false),
        &mut |_, _| {},
    );
}

/// Steps `solver` until a rule of `stop` is met, `cancel` is set or the solver has nothing
/// left to do; calls `on_step` after each step. `tolerance` is checked after 10 % more steps
/// each time (the estimate costs about a sweep), so a run may overshoot it by that many. A
/// NaN residual stops the run instead of stepping forever.
pub fn run_solver(
    solver: &mut dyn Solver,
    stop: &StopCriteria,
    cancel: &AtomicBool,
    on_step: &mut dyn FnMut(&StepRecord, &dyn Solver),
) {
    let start = Instant::now();
    let mut next_check = solver.steps();
    loop {
        let residual = solver.residual();
        let tolerance_met = stop.tolerance.is_some_and(|t| {
            solver.steps() >= next_check && {
                next_check = solver.steps() + solver.steps() / 10 + 1;
                solver.error_estimate() <= t
            }
        });
        if residual.is_nan()
            || tolerance_met
            || residual <= stop.residual
            || stop.max_steps.is_some_and(|n| solver.steps() >= n)
            || stop
                .max_seconds
                .is_some_and(|s| start.elapsed().as_secs_f64() >= s)
        {
            return;
        }
        if !solver.step(cancel) {
            return;
        }
        let record = StepRecord {
            step: solver.steps(),
            seconds: start.elapsed().as_secs_f64(),
            residual: solver.residual(),
        };
        on_step(&record, solver);
    }
}
