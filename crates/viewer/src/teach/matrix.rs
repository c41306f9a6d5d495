//! The form-factor matrix view's data: the patch-level matrix `F_pq = Σ_{j∈q} F_pj` (patch
//! to patch, from the element rows the solver uses, [`RowCache::row`]) filled a row at a
//! time while the solver thread is idle, so the class sees it fill; and the column of the
//! current shooter as colours for the viewport (`log10 F_ij` per element).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use nusselt_core::mesh::PatchId;
use nusselt_core::solver::{Problem, RowCache};

use super::super::snapshot::Geometry;

/// Most patches the matrix view takes (the matrix is `patches²` floats, copied to the UI a
/// few times a second: 2,048 patches are 16 MB).
pub const MAX_PATCHES: usize = 2048;

/// The smallest form factor the log colour scale shows (darker is below it).
pub const LOG_FLOOR: f64 = 1e-6;

/// The patch matrix so far.
#[derive(Debug)]
pub struct MatrixDetail {
    pub patches: usize,
    pub elements: usize,
    /// `F_pq` row-major (`patches²`); rows not computed yet are NaN.
    pub patch_f: Vec<f32>,
    pub rows_done: usize,
    /// Non-zero entries among the rows done.
    pub nonzero: usize,
    /// The row and column drawn highlighted (the last shooter).
    pub shooter: Option<u32>,
    /// Colour per drawn vertex for `log10 F_ij` from the shooter (heat scale from
    /// [`LOG_FLOOR`] to `column_max`).
    pub column_colours: Option<Arc<Vec<[f32; 3]>>>,
    pub column_max: f64,
}

/// A shooter, its column `F_ij` as colours per drawn vertex, and the column's largest value.
type Column = (u32, Arc<Vec<[f32; 3]>>, f64);

/// The matrix being filled (on the solver thread).
pub struct MatrixWork {
    /// The mesh it is for (`Geometry::id`).
    pub geometry_id: u64,
    patch_f: Vec<f32>,
    /// The shooter's column as colours, and its largest `F_ij`.
    column: Option<Column>,
    done: Vec<bool>,
    rows_done: usize,
    nonzero: usize,
}

/// `F_pq` for every patch `q` from an element row `F_pj A_p / A_j` of shooter `p`.
pub fn patch_row(problem: &Problem, p: usize, row: &[f32]) -> Vec<f32> {
    let mesh = &problem.mesh;
    let area = mesh.patches[p].area;
    let mut out = vec![0f32; mesh.patches.len()];
    for (e, r) in mesh.elements.iter().zip(row) {
        out[e.patch.0 as usize] += (f64::from(*r) * e.area / area) as f32;
    }
    out
}

/// A heat colour (black, red, yellow, white) for `t` in 0…1.
pub fn heat(t: f64) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0) as f32;
    [
        (3.0 * t).min(1.0),
        (3.0 * t - 1.0).clamp(0.0, 1.0),
        (3.0 * t - 2.0).clamp(0.0, 1.0),
    ]
}

/// Where `f` falls on the log scale from [`LOG_FLOOR`] to `max` (0…1; 0 below the floor).
pub fn log_scale(f: f64, max: f64) -> f64 {
    if f <= LOG_FLOOR || max <= LOG_FLOOR {
        return 0.0;
    }
    (f / LOG_FLOOR).log10() / (max / LOG_FLOOR).log10()
}

impl MatrixWork {
    /// Refused (with the message for the user) past [`MAX_PATCHES`].
    pub fn new(problem: &Problem, geometry_id: u64) -> Result<MatrixWork, String> {
        let n = problem.mesh.patches.len();
        if n > MAX_PATCHES {
            return Err(format!(
                "the matrix view shows at most {MAX_PATCHES} patches, this mesh has {n}: \
                 use a larger element size"
            ));
        }
        Ok(MatrixWork {
            geometry_id,
            column: None,
            patch_f: vec![f32::NAN; n * n],
            done: vec![false; n],
            rows_done: 0,
            nonzero: 0,
        })
    }

    pub fn rows_done(&self) -> usize {
        self.rows_done
    }

    /// Whether every row is done (or the mesh changed under it).
    pub fn complete(&self, problem: &Problem) -> bool {
        self.done.len() != problem.mesh.patches.len() || self.rows_done == self.done.len()
    }

    /// Computes one more row (`first` first when it is not done). `false` when complete
    /// or cancelled.
    pub fn step(&mut self, problem: &Problem, first: Option<u32>, cancel: &AtomicBool) -> bool {
        if self.complete(problem) {
            return false;
        }
        let n = self.done.len();
        let Some(p) = first
            .map(|p| p as usize)
            .filter(|&p| p < n && !self.done[p])
            .or_else(|| self.done.iter().position(|d| !d))
        else {
            return false;
        };
        let Some(row) = RowCache::default().row(problem, PatchId(p as u32), cancel) else {
            return false;
        };
        let values = patch_row(problem, p, &row);
        self.nonzero += values.iter().filter(|v| **v > 0.0).count();
        self.patch_f[p * n..(p + 1) * n].copy_from_slice(&values);
        self.done[p] = true;
        self.rows_done += 1;
        true
    }

    /// What the view shows: the matrix so far, and the column of `shooter` as colours
    /// (computed again only when the shooter changes).
    pub fn detail(
        &mut self,
        problem: &Problem,
        geometry: &Geometry,
        shooter: Option<u32>,
    ) -> MatrixDetail {
        let shooter = shooter.filter(|&s| (s as usize) < problem.mesh.patches.len());
        if self.column.as_ref().map(|c| c.0) != shooter {
            self.column = shooter.and_then(|s| self.column_of(problem, geometry, s));
        }
        let (column_colours, column_max) = match &self.column {
            Some((_, c, m)) => (Some(c.clone()), *m),
            None => (None, 0.0),
        };
        MatrixDetail {
            patches: self.done.len(),
            elements: problem.mesh.elements.len(),
            patch_f: self.patch_f.clone(),
            rows_done: self.rows_done,
            nonzero: self.nonzero,
            shooter,
            column_colours,
            column_max,
        }
    }

    fn column_of(&self, problem: &Problem, geometry: &Geometry, s: u32) -> Option<Column> {
        let row = RowCache::default().row(problem, PatchId(s), &AtomicBool::new(false))?;
        // F_ij = (F_ij A_i / A_j) A_j / A_i per element.
        let area = problem.mesh.patches[s as usize].area;
        let f: Vec<f64> = problem
            .mesh
            .elements
            .iter()
            .zip(row.iter())
            .map(|(e, r)| f64::from(*r) * e.area / area)
            .collect();
        let max = f.iter().copied().fold(0.0, f64::max);
        let colours: Vec<nusselt_core::scene::Rgb> = f
            .iter()
            .map(|&x| nusselt_core::scene::Rgb::from(heat(log_scale(x, max)).map(f64::from)))
            .collect();
        let per_vertex = problem.mesh.vertex_values(&colours);
        Some((s, Arc::new(geometry.expand(&per_vertex)), max))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nusselt_core::mesh::MeshSpec;
    use nusselt_core::scene::{LoadOptions, Scene};
    use nusselt_core::solver::SolverConfig;

    /// The patch matrix is the solver's rows summed by patch: each row sums to the
    /// element row's `Σ_j F_pj` (what the shooter sends into the scene, ≤ 1), the shooter
    /// does not see itself (planar patches), and reciprocity `A_p F_pq = A_q F_qp` holds
    /// over the matrix (a row stored without its `A_p/A_j` factor breaks it by the area
    /// ratios).
    #[test]
    fn the_patch_matrix_is_the_solvers_rows_summed_by_patch() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::sized(100.0, 200.0),
            // Exact area-to-area rows: reciprocity is then exact up to visibility sampling.
            formfactor: nusselt_core::solver::FormFactorConfig {
                method: nusselt_core::formfactor::FormFactorMethod::Exact,
                ..Default::default()
            },
            ..Default::default()
        };
        let problem = Problem::new(scene, config).expect("problem");
        let n = problem.mesh.patches.len();
        let mut work = MatrixWork::new(&problem, 1).expect("small enough");
        let never = AtomicBool::new(false);
        assert!(work.step(&problem, Some(3), &never));
        assert!(work.patch_f[3 * n..4 * n].iter().all(|f| f.is_finite()));
        assert!(
            work.patch_f[..n].iter().all(|f| f.is_nan()),
            "row 0 not done yet"
        );
        while work.step(&problem, None, &never) {}
        assert!(work.complete(&problem));
        assert_eq!(work.rows_done, n);
        let (mut mismatch, mut exchanged) = (0.0f64, 0.0f64);
        for p in 0..n {
            let row = RowCache::default()
                .row(&problem, PatchId(p as u32), &never)
                .expect("row");
            let area = problem.mesh.patches[p].area;
            let total: f64 = problem
                .mesh
                .elements
                .iter()
                .zip(row.iter())
                .map(|(e, r)| f64::from(*r) * e.area / area)
                .sum();
            let sum: f64 = work.patch_f[p * n..(p + 1) * n]
                .iter()
                .map(|f| f64::from(*f))
                .sum();
            assert!((sum - total).abs() < 1e-5, "row {p}: {sum} vs {total}");
            assert!(sum <= 1.0 + 1e-4, "row {p} sums to {sum}");
            assert_eq!(work.patch_f[p * n + p], 0.0, "patch {p} sees itself");
            for q in 0..n {
                let (fpq, fqp) = (work.patch_f[p * n + q], work.patch_f[q * n + p]);
                let (ap, aq) = (problem.mesh.patches[p].area, problem.mesh.patches[q].area);
                let (x, y) = (ap * f64::from(fpq), aq * f64::from(fqp));
                mismatch += (x - y).abs();
                exchanged += x;
            }
        }
        // Over the whole matrix: Σ|A_p F_pq − A_q F_qp| / Σ A_p F_pq (visibility is
        // sampled per element, so single pairs next to the blocks differ more).
        let reciprocity = mismatch / exchanged;
        eprintln!("reciprocity mismatch over the matrix: {reciprocity:.4}");
        assert!(reciprocity < 0.05, "reciprocity off by {reciprocity}");
        let d = work.detail(&problem, &Geometry::from_mesh(1, &problem.mesh), Some(0));
        assert_eq!(d.rows_done, n);
        assert!(d.column_max > 0.0 && d.column_colours.is_some());
    }

    #[test]
    fn the_log_scale_runs_from_the_floor_to_the_max() {
        assert_eq!(log_scale(0.0, 0.1), 0.0);
        assert_eq!(log_scale(LOG_FLOOR, 0.1), 0.0);
        assert!((log_scale(0.1, 0.1) - 1.0).abs() < 1e-12);
        assert!((log_scale(1e-3, 1e-1) - 0.6).abs() < 1e-12);
        assert_eq!(heat(0.0), [0.0; 3]);
        assert_eq!(heat(1.0), [1.0; 3]);
    }
}
