//! Form-factor rows, cached: `F_ji` from every element `j` to one shooting patch `i`,
//! computed on first use and kept up to a memory budget (rows past it are recomputed when
//! needed). Shooting reads a row per shot; gathering reads each row once per matrix.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use crate::formfactor;
use crate::mesh::{Mesh, PatchId};

use super::problem::Problem;

/// Scales a row so that a shot never delivers more power than it carries:
/// `Σ_j F_ji A_j ≤ A_i`. Form factors evaluated at element centroids are not exactly
/// reciprocal; where a small shooter lies close to a large receiving element's centroid
/// (contact, slivers, duplicated faces) `F_ji A_j` can exceed `A_i`, and repeated shots
/// between such a pair gain energy without bound. Exact rows satisfy the bound
/// (the row sum of a closed scene is 1 to the centroid rule's O(h²) error, ~1e-3 here, which
/// is left alone: clipping it would bias every closed scene dark), so this changes only
/// rows that break it grossly, and scales them back to delivering exactly the shot.
const MAX_ROW_GAIN: f64 = 1.01;

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

/// Rows by shooting patch, with a memory budget.
#[derive(Default)]
pub struct RowCache {
    rows: Vec<Option<Arc<[f32]>>>,
    cached_bytes: usize,
}

impl RowCache {
    /// Forgets every row (the mesh or the form-factor method changed).
    pub fn clear(&mut self) {
        self.rows.clear();
        self.cached_bytes = 0;
    }

    /// Memory held by cached rows, in bytes.
    pub fn bytes(&self) -> usize {
        self.cached_bytes
    }

    /// The row of `shooter`, from the cache or computed (then cached if it fits the
    /// budget). `None` when `cancel` was set during the computation.
    pub fn row(
        &mut self,
        problem: &Problem,
        shooter: PatchId,
        cancel: &AtomicBool,
    ) -> Option<Arc<[f32]>> {
        if self.rows.len() != problem.mesh.patches.len() {
            self.rows = vec![None; problem.mesh.patches.len()];
            self.cached_bytes = 0;
        }
        if let Some(r) = &self.rows[shooter.0 as usize] {
            return Some(r.clone());
        }
        let mut out = vec![0f32; problem.mesh.elements.len()];
        let ctx = problem.row_context();
        if !formfactor::compute_row(problem.config.method, &ctx, shooter, &mut out, cancel) {
            return None;
        }
        conserve_energy(&problem.mesh, shooter, &mut out);
        let row: Arc<[f32]> = out.into();
        let bytes = row.len() * 4;
        if self.cached_bytes + bytes <= problem.config.row_cache_bytes {
            self.cached_bytes += bytes;
            self.rows[shooter.0 as usize] = Some(row.clone());
        }
        Some(row)
    }
}
