//! Gathering with a stored matrix (the lecture's "full matrix" radiosity; Cohen & Wallace
//! 1993, ch. 5): Jacobi, Gauss-Seidel and successive over-relaxation on the patch system
//! `B_p = E_p + ρ_p Σ_i F_pi B_i`, `F_pi = Σ_{j∈p} A_j F_ji / A_p` from the elements' rows,
//! then every element gathered from the patch solution, `B_j = E_j + ρ_j Σ_i F_ji B_i`.
//! The patch averages of that element field solve the patch system exactly (one material
//! per patch), so this is the same answer the shooting solver converges to on the same
//! rows.
//!
//! The matrix is built a row per step (each row is one shooter's form factors to every
//! element, the same rows shooting uses) and stored sparse: a receiver keeps only the
//! shooters it sees. Every row is kept for the element gather, so the rows must fit in
//! [`Problem::cache_bytes`](super::Problem::cache_bytes); a larger mesh is refused with
//! [`SolverError::MatrixTooLarge`] before any work.
//!
//! SOR without a given ω estimates it (Young's formula for consistently ordered systems):
//! after three Gauss-Seidel sweeps the residual ratio μ estimates the Gauss-Seidel
//! convergence factor `μ_J²`, and `ω = 2 / (1 + √(1 − μ))`.

use crate::scene::Rgb;

use super::SolverError;
use super::matrix::{Iteration, MatrixSolver, PatchMatrix};
use super::problem::Problem;
use super::rows::RowCache;

/// Which gathering iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GatherMethod {
    Jacobi,
    GaussSeidel,
    /// `None`: ω estimated from the first sweeps.
    Sor(Option<f64>),
}

/// Jacobi, Gauss-Seidel or SOR sweeps (see the module docs).
pub struct Relaxation {
    method: GatherMethod,
    /// ω in use (SOR), estimated or given.
    omega: Option<f64>,
    residuals: Vec<f64>,
}

/// Jacobi, Gauss-Seidel or SOR on a stored matrix.
pub type GatheringSolver = MatrixSolver<Relaxation>;

impl MatrixSolver<Relaxation> {
    /// Refuses ω outside (0, 2) and a matrix over the memory budget.
    pub fn new(problem: Problem, method: GatherMethod) -> Result<Self, SolverError> {
        Self::with_rows(problem, method, RowCache::default())
    }

    /// As [`new`](Self::new), reusing rows cached on the same problem.
    pub fn with_rows(
        problem: Problem,
        method: GatherMethod,
        rows: RowCache,
    ) -> Result<Self, SolverError> {
        check_omega(method)?;
        let relaxation = Relaxation {
            method,
            omega: None,
            residuals: Vec::new(),
        };
        Self::with_iteration(problem, relaxation, rows)
    }

    /// The relaxation factor in use (SOR only; `None` while still estimating).
    pub fn omega(&self) -> Option<f64> {
        self.iteration().omega
    }
}

/// Refuses ω outside (0, 2).
pub(crate) fn check_omega(method: GatherMethod) -> Result<(), SolverError> {
    if let GatherMethod::Sor(Some(w)) = method
        && !(w > 0.0 && w < 2.0)
    {
        return Err(SolverError::BadValue {
            what: "--omega",
            range: "in (0, 2)",
            value: [w; 3],
        });
    }
    Ok(())
}

impl Iteration for Relaxation {
    fn name(&self) -> &'static str {
        match self.method {
            GatherMethod::Jacobi => "jacobi",
            GatherMethod::GaussSeidel => "gauss-seidel",
            GatherMethod::Sor(_) => "sor",
        }
    }

    fn iterate(&mut self, p: &Problem, matrix: &PatchMatrix, b: &mut [Rgb]) -> bool {
        match self.method {
            GatherMethod::Jacobi => {
                let old = b.to_vec();
                for (k, bk) in b.iter_mut().enumerate() {
                    *bk = p.patch_source(k) + p.patch_rho(k) * matrix.gather(k, &old);
                }
            }
            GatherMethod::GaussSeidel | GatherMethod::Sor(_) => {
                let w = match self.method {
                    GatherMethod::Sor(_) => self.omega.unwrap_or(1.0),
                    _ => 1.0,
                };
                for k in 0..b.len() {
                    let gs = p.patch_source(k) + p.patch_rho(k) * matrix.gather(k, b);
                    b[k] = b[k] * (1.0 - w) + gs * w;
                }
            }
        }
        true
    }

    fn observe(&mut self, residual: f64) {
        self.residuals.push(residual);
        if matches!(self.method, GatherMethod::Sor(None))
            && self.omega.is_none()
            && self.residuals.len() >= 3
        {
            let h = &self.residuals;
            let mu = (h[h.len() - 1] / h[h.len() - 2]).clamp(0.0, 0.999_999);
            self.omega = Some(2.0 / (1.0 + (1.0 - mu).sqrt()));
        }
    }

    fn restart(&mut self) {
        self.residuals.clear();
        if let GatherMethod::Sor(w) = self.method {
            self.omega = w;
        }
    }

    fn report(&self, sweeps: usize) -> String {
        match (self.method, self.omega) {
            (GatherMethod::Sor(None), Some(w)) => {
                format!("{sweeps} sweeps, omega {w:.3} (estimated)")
            }
            (GatherMethod::Sor(Some(w)), _) => format!("{sweeps} sweeps, omega {w:.3}"),
            _ => format!("{sweeps} sweeps"),
        }
    }
}
