//! Form-factor rows, cached: `F_ji` from every element `j` to one shooting patch `i`,
//! computed on first use and kept up to a memory budget; past it the least recently used
//! rows are evicted (and recomputed if needed again). Shooting reads a row per shot, and
//! the patches it shoots again and again are the bright ones, so they stay; gathering
//! reads each row once per matrix and is refused a matrix over the budget, so it never
//! evicts.

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
/// A cut-out element intercepts only its opaque fraction of what reaches its outline (the
/// rest passes its holes and is in the row again, at what lies behind), so it counts at
/// that fraction of its area.
const MAX_ROW_GAIN: f64 = 1.01;

fn conserve_energy(problem: &Problem, shooter: PatchId, row: &mut [f32]) {
    let mesh = &problem.mesh;
    let area = mesh.patch(shooter).area;
    let delivered: f64 = row
        .iter()
        .zip(&mesh.elements)
        .enumerate()
        .map(|(j, (f, e))| f64::from(*f) * e.area * problem.element_coverage(j))
        .sum();
    if area > 0.0 && delivered > MAX_ROW_GAIN * area {
        let k = (area / delivered) as f32;
        row.iter_mut().for_each(|f| *f *= k);
        debug_assert!(k.is_finite());
    }
}

/// The power a unit shot radiance of the row's patch `i` delivers, `Σ_j F_ji A_j`.
pub(super) fn delivered(mesh: &Mesh, row: &[f32]) -> f64 {
    row.iter()
        .zip(&mesh.elements)
        .map(|(f, e)| f64::from(*f) * e.area)
        .sum()
}

/// Rows by shooting patch, with a memory budget and least-recently-used eviction.
#[derive(Default)]
pub struct RowCache {
    rows: Vec<Option<Arc<[f32]>>>,
    /// Per patch, the clock of its row's last use.
    last_use: Vec<u64>,
    clock: u64,
    cached_bytes: usize,
    evictions: usize,
}

impl RowCache {
    /// Forgets every row (the mesh or the form-factor method changed).
    pub fn clear(&mut self) {
        self.rows.clear();
        self.last_use.clear();
        self.cached_bytes = 0;
    }

    /// Rows evicted to stay within the budget so far.
    pub fn evictions(&self) -> usize {
        self.evictions
    }

    /// Whether the row of `shooter` is cached.
    pub fn contains(&self, shooter: PatchId) -> bool {
        self.rows
            .get(shooter.0 as usize)
            .is_some_and(|r| r.is_some())
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
            self.last_use = vec![0; problem.mesh.patches.len()];
            self.cached_bytes = 0;
        }
        self.clock += 1;
        let s = shooter.0 as usize;
        if let Some(r) = &self.rows[s] {
            self.last_use[s] = self.clock;
            return Some(r.clone());
        }
        let mut out = vec![0f32; problem.mesh.elements.len()];
        let ctx = problem.row_context();
        if !formfactor::compute_row(
            problem.config.formfactor.method,
            &ctx,
            shooter,
            &mut out,
            cancel,
        ) {
            return None;
        }
        conserve_energy(problem, shooter, &mut out);
        let row: Arc<[f32]> = out.into();
        let bytes = row.len() * 4;
        let budget = problem.cache_bytes();
        if bytes > budget {
            return Some(row);
        }
        while self.cached_bytes + bytes > budget {
            let oldest = (0..self.rows.len())
                .filter(|&k| self.rows[k].is_some())
                .min_by_key(|&k| self.last_use[k]);
            let Some(k) = oldest else { break };
            let freed = self.rows[k].take().map_or(0, |r| r.len() * 4);
            self.cached_bytes -= freed;
            self.evictions += 1;
        }
        self.cached_bytes += bytes;
        self.rows[s] = Some(row.clone());
        self.last_use[s] = self.clock;
        Some(row)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSpec;
    use crate::scene::{LoadOptions, Scene};
    use crate::solver::SolverConfig;

    /// A budget of two rows: the third row evicts the least recently used, the cache never
    /// holds more than the budget, and an evicted row comes back identical.
    #[test]
    fn the_least_recently_used_row_is_evicted() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let mut problem = Problem::new(
            scene,
            SolverConfig {
                mesh: MeshSpec::element(100.0),
                ..SolverConfig::default()
            },
        )
        .expect("problem");
        problem.config.memory_bytes = problem.resident_bytes()
            + (2.0 * (problem.mesh.elements.len() * 4) as f64 / crate::budget::CACHE_SHARE)
                as usize
            + 8;
        let never = AtomicBool::new(false);
        let mut cache = RowCache::default();
        let (a, b, c) = (PatchId(0), PatchId(1), PatchId(2));
        let first_a = cache.row(&problem, a, &never).expect("row");
        cache.row(&problem, b, &never).expect("row");
        cache.row(&problem, a, &never).expect("row"); // a is now the most recent
        cache.row(&problem, c, &never).expect("row");
        assert!(cache.contains(a) && cache.contains(c) && !cache.contains(b));
        assert_eq!(cache.evictions(), 1);
        assert!(cache.bytes() <= problem.cache_bytes());
        cache.row(&problem, b, &never).expect("row"); // evicts a
        assert!(!cache.contains(a));
        let again_a = cache.row(&problem, a, &never).expect("row");
        assert_eq!(&first_a[..], &again_a[..]);
        assert_eq!(cache.evictions(), 3);
    }
}
