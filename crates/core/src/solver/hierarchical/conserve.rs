//! Per-receiver conservation of the link kernels.
//!
//! A link's kernel is estimated from a few points (a leaf sender's exact point-to-polygon
//! factor, a cluster's projected area, four sub-sources of a planar inner node, 4–16
//! shadow rays), so the kernels an element reads through its own and its ancestors' links
//! do not sum to its form-factor sum `Σ_j F_ij`: in the closed furnace box at 2,400
//! elements they summed to 0.95–1.05, and every element's radiosity erred by as much
//! (the exact answer `E/(1 − ρ)` needs a sum of exactly 1). Here each element's gathered
//! light is scaled by `T_i / S_i`, as clustering methods renormalise a receiver's links
//! (Smits, Arvo & Greenberg 1994, §4; Gibson & Hubbold 1996): `S_i` is the kernel sum it
//! reads (one gather and push of `B ≡ 1` over the links, recomputed when they change) and
//! `T_i` the cosine-weighted fraction of its hemisphere that surfaces cover (stratified
//! rays, once per mesh), which is `Σ_j F_ij` exactly in a scene without back faces.
//!
//! Error: in a closed scene every ray hits, `T_i = 1` exactly, and the furnace identity
//! holds to the solver's residual. Where the hemisphere is partly open, `T_i` carries the
//! sampling error of `k²` rays (`k` 4–8), larger than the links' own error (about 3 %):
//! there the target is the inverse-variance weighted mean of `S_i` and `T_i`
//! ([`combined_sum`]), with `T_i`'s variance the binomial `T(1 − T)/k²` (an upper bound
//! for stratified rays) and `S_i`'s measured on the elements whose rays all hit (where the
//! truth is 1; the median, as elements hidden under a box see its inside and no link). A ray that hits a surface's back counts as covered though the kernel of a
//! one-sided surface seen from behind is zero; the correction is kept within
//! [`MIN_GAIN`, `MAX_GAIN`] so such elements, and receivers whose links the memory budget
//! cut short, are not lifted without bound.

use rayon::prelude::*;

use crate::geometry::sampling::{cosine_hemisphere, hash_seed};
use crate::geometry::{Bvh, Ray, Rng};
use crate::mesh::{Element, Mesh};

/// The smallest factor the gathered light of an element is scaled by.
pub const MIN_GAIN: f64 = 0.8;
/// The largest (see the module docs).
pub const MAX_GAIN: f64 = 1.25;

/// Rays for the whole mesh; each element gets `k²` with `k` in [`MIN_SIDE`, `MAX_SIDE`].
const RAY_BUDGET: f64 = 4.0e6;
const MIN_SIDE: usize = 4;
const MAX_SIDE: usize = 8;

/// Link kernels' spread about the true form-factor sum assumed where no element's rays
/// all hit (so it cannot be measured): the furnace's at 2,400 elements.
const DEFAULT_SUM_VARIANCE: f64 = 0.03 * 0.03;

/// What the rays found: per element the cosine-weighted fraction of its hemisphere in
/// which a ray from it meets a surface, and the rays each element cast.
pub struct Coverage {
    pub fraction: Vec<f64>,
    pub rays: usize,
}

impl Coverage {
    /// Casts the rays (`bvh`: the solve's blockers, ids the occluder groups).
    pub fn measure(mesh: &Mesh, bvh: &Bvh, epsilon: f64) -> Coverage {
        let n = mesh.elements.len();
        let side = ((RAY_BUDGET / n.max(1) as f64).sqrt() as usize).clamp(MIN_SIDE, MAX_SIDE);
        let fraction = (0..n)
            .into_par_iter()
            .map(|k| {
                let e = &mesh.elements[k];
                let own = mesh.patch(e.patch).occluder;
                covered(e, own, bvh, epsilon, side, hash_seed(&[k as u64, 0xc0fe]))
            })
            .collect();
        Coverage {
            fraction,
            rays: side * side,
        }
    }

    /// Per element, the factor on its gathered light, given the kernel sums it reads.
    pub fn gains(&self, sums: &[f64]) -> Vec<f64> {
        // From the median square (robust: an element hidden under a box casts rays that
        // all hit the box's inside, while no link reaches it); the median of a χ²₁ is 0.455.
        let mut squares: Vec<f64> = self
            .fraction
            .iter()
            .zip(sums)
            .filter(|(t, _)| **t == 1.0)
            .map(|(_, s)| (s - 1.0) * (s - 1.0))
            .collect();
        let var_sum = if squares.len() >= 16 {
            let mid = squares.len() / 2;
            let (_, median, _) = squares.select_nth_unstable_by(mid, f64::total_cmp);
            (*median / 0.455).max(1e-8)
        } else {
            DEFAULT_SUM_VARIANCE
        };
        self.fraction
            .iter()
            .zip(sums)
            .map(|(&t, &s)| {
                let var_t = t * (1.0 - t) / self.rays as f64;
                gain(combined_sum(s, var_sum, t, var_t), s)
            })
            .collect()
    }
}

/// The inverse-variance weighted mean of the kernel sum `s` (variance `var_s`) and the
/// covered fraction `t` (variance `var_t`): `t` itself where its variance is 0.
pub fn combined_sum(s: f64, var_s: f64, t: f64, var_t: f64) -> f64 {
    if var_t <= 0.0 {
        return t;
    }
    (s / var_s + t / var_t) / (1.0 / var_s + 1.0 / var_t)
}

fn covered(e: &Element, own: u32, bvh: &Bvh, epsilon: f64, side: usize, seed: u64) -> f64 {
    let mut rng = Rng::new(seed, 3);
    let mut hits = 0usize;
    for i in 0..side {
        for j in 0..side {
            let u1 = (i as f64 + rng.next_f64()) / side as f64;
            let u2 = (j as f64 + rng.next_f64()) / side as f64;
            let x = e.point_at(rng.next_f64(), rng.next_f64());
            let ray = Ray::new(x + e.normal * epsilon, cosine_hemisphere(e.normal, u1, u2));
            if bvh.any_hit_except(&ray, 0.0, f64::INFINITY, [own, u32::MAX]) {
                hits += 1;
            }
        }
    }
    hits as f64 / (side * side) as f64
}

/// The factor that brings kernel sum `sum` to `target`, within [`MIN_GAIN`, `MAX_GAIN`];
/// 1 where no link reaches the element.
pub fn gain(target: f64, sum: f64) -> f64 {
    if sum > 1e-9 {
        (target / sum).clamp(MIN_GAIN, MAX_GAIN)
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_exact_covered_fraction_wins_and_a_noisy_one_is_weighed() {
        assert_eq!(combined_sum(0.9, 1e-3, 1.0, 0.0), 1.0);
        // Equal variances: the midpoint.
        assert!((combined_sum(0.8, 1e-3, 0.6, 1e-3) - 0.7).abs() < 1e-12);
        // A 9x noisier fraction moves the sum a tenth of the way.
        assert!((combined_sum(0.8, 1e-3, 0.6, 9e-3) - 0.78).abs() < 1e-12);
    }

    #[test]
    fn the_gain_is_the_ratio_within_its_bounds() {
        assert_eq!(gain(1.0, 0.95), 1.0 / 0.95);
        assert_eq!(gain(1.0, 0.5), MAX_GAIN);
        assert_eq!(gain(0.5, 1.0), MIN_GAIN);
        assert_eq!(gain(1.0, 0.0), 1.0);
    }
}
