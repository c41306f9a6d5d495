//! What the stored-matrix solvers share: the patch-level matrix built from the elements'
//! rows ([`PatchMatrix`]), and [`MatrixSolver`], which builds it a row per step and then
//! runs an [`Iteration`] (Jacobi, Gauss-Seidel, SOR in [`super::gathering`], BiCGSTAB in
//! [`super::cg`]) on the patch radiosities, gathering the elements after each.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use rayon::prelude::*;

use crate::mesh::PatchId;
use crate::scene::{MaterialId, Rgb};

use super::problem::Problem;
use super::rows::RowCache;
use super::{Solver, SolverError, channel_sum};

/// The patch-level matrix, by receiver, built one shooter row at a time.
pub struct PatchMatrix {
    /// For each receiving patch `p`: `(i, F_pi)` for every shooter `i` it sees.
    pub by_receiver: Vec<Vec<(u32, f64)>>,
    /// The element rows, by shooter (kept for the element gather).
    pub rows: Vec<Arc<[f32]>>,
    cache: RowCache,
}

impl PatchMatrix {
    /// Refuses (before any work) rows that would not fit the memory budget.
    pub fn check(problem: &Problem, solver: &'static str) -> Result<(), SolverError> {
        let (patches, elements) = (problem.mesh.patches.len(), problem.mesh.elements.len());
        let needed = patches * elements * 4 + patches * patches * 12 / 2;
        if needed > problem.cache_bytes() {
            return Err(SolverError::MatrixTooLarge {
                solver,
                needed_mb: needed.div_ceil(1 << 20),
                limit_mb: problem.cache_bytes() >> 20,
                patches,
                elements,
            });
        }
        Ok(())
    }

    /// An empty matrix that takes its rows from `cache` where it has them (rows cached by
    /// another solver on the same problem).
    pub fn new(
        problem: &Problem,
        solver: &'static str,
        cache: RowCache,
    ) -> Result<Self, SolverError> {
        Self::check(problem, solver)?;
        let patches = problem.mesh.patches.len();
        Ok(Self {
            by_receiver: vec![Vec::new(); patches],
            rows: Vec::with_capacity(patches),
            cache,
        })
    }

    pub fn complete(&self, problem: &Problem) -> bool {
        self.rows.len() == problem.mesh.patches.len()
    }

    /// Computes the next shooter's row. `false` if `cancel` was set.
    pub fn build_next(&mut self, problem: &Problem, cancel: &AtomicBool) -> bool {
        let i = self.rows.len();
        let Some(row) = self.cache.row(problem, PatchId(i as u32), cancel) else {
            return false;
        };
        let mesh = &problem.mesh;
        for (p, patch) in mesh.patches.iter().enumerate() {
            let r = patch.elements.start as usize..patch.elements.end as usize;
            let f: f64 = row[r.clone()]
                .iter()
                .zip(&mesh.elements[r])
                .map(|(f, e)| *f as f64 * e.area)
                .sum::<f64>()
                / patch.area;
            if f > 0.0 && f.is_finite() {
                self.by_receiver[p].push((i as u32, f));
            }
        }
        self.rows.push(row);
        true
    }

    pub fn bytes(&self) -> usize {
        self.cache.bytes() + self.by_receiver.iter().map(|r| r.len() * 16).sum::<usize>()
    }

    /// `Σ_i F_pi B_i` for patch `p`.
    pub fn gather(&self, p: usize, b: &[Rgb]) -> Rgb {
        self.by_receiver[p]
            .iter()
            .fold(Rgb::ZERO, |acc, &(i, f)| acc + b[i as usize] * f)
    }

    /// Element radiosity from patch radiosity: `B_j = E_j + ρ_j Σ_i F_ji B_i`.
    pub fn element_radiosity(&self, problem: &Problem, rho: &[Rgb], patch_b: &[Rgb]) -> Vec<Rgb> {
        let mesh = &problem.mesh;
        let mut out = vec![Rgb::ZERO; mesh.elements.len()];
        const CHUNK: usize = 2048;
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                let first = c * CHUNK;
                for (i, row) in self.rows.iter().enumerate() {
                    let b = patch_b[i];
                    for (k, h) in chunk.iter_mut().enumerate() {
                        let f = row[first + k];
                        if f != 0.0 {
                            *h += b * f as f64;
                        }
                    }
                }
                for (k, h) in chunk.iter_mut().enumerate() {
                    let j = first + k;
                    *h = problem.element_source(j) + rho[j] * *h;
                }
            });
        out
    }

    /// Relative residual of the patch system at `b`: `Σ|E + ρFB − B|A / emitted`.
    pub fn residual(&self, problem: &Problem, b: &[Rgb], emitted: f64) -> f64 {
        let r: f64 = problem
            .mesh
            .patches
            .iter()
            .enumerate()
            .map(|(p, patch)| {
                channel_sum(
                    problem.patch_source(p) + problem.patch_rho(p) * self.gather(p, b) - b[p],
                ) * patch.area
            })
            .sum();
        relative(r, emitted)
    }
}

pub fn relative(r: f64, emitted: f64) -> f64 {
    if emitted > 0.0 {
        r / emitted
    } else if r > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// One iterative method on the patch system `(I − ρF) B = E`.
pub trait Iteration: Send {
    /// `jacobi`, `gauss-seidel`, `sor` or `cg`.
    fn name(&self) -> &'static str;
    /// One iteration on `b` (patch radiosities). `false` when the method has nothing more
    /// to gain (it has converged to rounding or broken down); `b` is then unchanged.
    fn iterate(&mut self, problem: &Problem, matrix: &PatchMatrix, b: &mut [Rgb]) -> bool;
    /// Called with each new residual after an iteration.
    fn observe(&mut self, _residual: f64) {}
    /// Forget any state tied to the old materials or start (a material edit, a reset).
    fn restart(&mut self);
    /// A line for the summary.
    fn report(&self, iterations: usize) -> String;
}

/// A stored-matrix solver: the matrix a row per step, then one [`Iteration`] per step.
pub struct MatrixSolver<I: Iteration> {
    problem: Problem,
    matrix: PatchMatrix,
    iteration: I,
    /// Per patch.
    patch_b: Vec<Rgb>,
    /// Per element (gathered after each iteration).
    radiosity: Vec<Rgb>,
    element_rho: Vec<Rgb>,
    steps: usize,
    iterations: usize,
    residual: f64,
    /// The iteration has nothing more to gain.
    stalled: bool,
    emitted: f64,
}

impl<I: Iteration> MatrixSolver<I> {
    /// Refuses (before any row) a matrix over the memory budget. Rows already in `rows`
    /// are not computed again.
    pub fn with_iteration(
        problem: Problem,
        iteration: I,
        rows: RowCache,
    ) -> Result<Self, SolverError> {
        let matrix = PatchMatrix::new(&problem, iteration.name(), rows)?;
        let mut s = Self {
            problem,
            matrix,
            iteration,
            patch_b: Vec::new(),
            radiosity: Vec::new(),
            element_rho: Vec::new(),
            steps: 0,
            iterations: 0,
            residual: 1.0,
            stalled: false,
            emitted: 0.0,
        };
        Solver::reset(&mut s);
        Ok(s)
    }

    /// Iterations (sweeps) done since the matrix was complete.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    pub fn iteration(&self) -> &I {
        &self.iteration
    }

    /// After an edit of materials or lights: the reflectances, the emitted power and the
    /// residual anew; the iteration continues from the current solution.
    fn sources_changed(&mut self) {
        self.element_rho = self.problem.element_reflectance();
        self.emitted = self.problem.emitted_power().max(f64::MIN_POSITIVE);
        self.iteration.restart();
        self.stalled = false;
        if self.matrix.complete(&self.problem) {
            self.residual = self
                .matrix
                .residual(&self.problem, &self.patch_b, self.emitted);
        }
    }
}

impl<I: Iteration> Solver for MatrixSolver<I> {
    fn name(&self) -> &'static str {
        self.iteration.name()
    }
    fn problem(&self) -> &Problem {
        &self.problem
    }
    fn step(&mut self, cancel: &AtomicBool) -> bool {
        if !self.matrix.complete(&self.problem) {
            if !self.matrix.build_next(&self.problem, cancel) {
                return false;
            }
        } else {
            if self.residual == 0.0 || self.stalled {
                return false;
            }
            if !self
                .iteration
                .iterate(&self.problem, &self.matrix, &mut self.patch_b)
            {
                self.stalled = true;
                return false;
            }
            self.iterations += 1;
            self.residual = self
                .matrix
                .residual(&self.problem, &self.patch_b, self.emitted);
            self.iteration.observe(self.residual);
            self.radiosity =
                self.matrix
                    .element_radiosity(&self.problem, &self.element_rho, &self.patch_b);
            debug_assert!(self.radiosity.iter().all(|b| b.is_finite()));
        }
        self.steps += 1;
        true
    }
    fn steps(&self) -> usize {
        self.steps
    }
    fn radiosity(&self) -> &[Rgb] {
        &self.radiosity
    }
    fn residual(&self) -> f64 {
        self.residual
    }
    /// The radiosity: no estimate of the light still to arrive (until the first iteration
    /// only the lights show).
    fn display_radiance(&self) -> Vec<Rgb> {
        self.radiosity.clone()
    }
    /// Continues from the current solution with the new materials.
    fn set_material(
        &mut self,
        id: MaterialId,
        reflectance: Rgb,
        emission: Rgb,
    ) -> Result<(), SolverError> {
        self.problem
            .set_material(id.0 as usize, reflectance, emission)?;
        self.sources_changed();
        Ok(())
    }
    /// Continues from the current solution with the new sources.
    fn set_lights(&mut self, lights: Vec<crate::scene::Light>) {
        self.problem.set_lights(lights);
        self.sources_changed();
    }
    fn reset(&mut self) {
        let p = &self.problem;
        self.patch_b = p.patch_emission();
        self.element_rho = p.element_reflectance();
        self.radiosity = p.element_emission();
        self.emitted = p.emitted_power();
        self.residual = if self.emitted > 0.0 { 1.0 } else { 0.0 };
        self.steps = 0;
        self.iterations = 0;
        self.stalled = false;
        self.iteration.restart();
    }
    fn matrix_bytes(&self) -> usize {
        self.matrix.bytes()
    }
    /// `max|r| / (1 − ρ_max)` over each patch's radiosity: the error `e = (I − ρF)⁻¹ r`
    /// is bounded so where the rows sum to at most 1. Infinite while the matrix is built.
    fn error_estimate(&self) -> f64 {
        if !self.matrix.complete(&self.problem) {
            return f64::INFINITY;
        }
        let problem = &self.problem;
        let mut r_max: f64 = 0.0;
        let mut rho_max: f64 = 0.0;
        for p in 0..problem.mesh.patches.len() {
            let r = problem.patch_source(p)
                + problem.patch_rho(p) * self.matrix.gather(p, &self.patch_b)
                - self.patch_b[p];
            r_max = r_max.max(r.abs().max_element());
            rho_max = rho_max.max(problem.patch_rho(p).max_element());
        }
        super::residual_error_estimate(problem, &self.radiosity, &self.patch_b, r_max, rho_max)
    }
    fn into_parts(self: Box<Self>) -> (Problem, Option<RowCache>) {
        (self.problem, Some(self.matrix.cache))
    }
    fn report(&self) -> String {
        self.iteration.report(self.iterations)
    }
}
