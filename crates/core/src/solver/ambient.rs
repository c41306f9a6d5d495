//! A regional ambient term: the display correction of progressive shooting estimated from
//! where the unshot light can actually go.
//!
//! The classic ambient term (Cohen et al. 1988) adds `ρ_j · R · Σ U_i A_i / Σ A_i` to every
//! element: it assumes the unshot power spreads evenly over the whole scene. Where the
//! scene is not one room that is wrong: in two rooms joined by a door left ajar (the
//! `tworooms` built-in) the unlit room shows about three times too bright mid-solve,
//! because the unshot light in the lit room cannot reach it.
//!
//! Here the patches are grouped into *regions* (a grid cell of the scene's bounds and one
//! of six normal directions, so the two faces of a wall never share one) and the transport
//! between regions is sampled once with cosine-weighted rays: `F_cd` = the fraction of
//! region `c`'s rays whose first hit is a front face in region `d` (rays that leave an
//! open scene or hit a back face are lost, as the light would be). The light still to
//! arrive per unit reflectance then solves the coarse system
//!
//! `G_c = Σ_d F_cd (Ū_d + ρ̄_d G_d)`
//!
//! (`Ū`, `ρ̄`: area means of the unshot radiance and the reflectance over a region), and an
//! element shows `B_j + ρ_j G_c(j)`. In a closed scene of one reflectance with uniform
//! unshot radiance this is exactly the classic term (`G = U / (1 − ρ)`); where regions see
//! each other only through a gap, little of one's unshot light shows in the other. Its
//! error is the coarse transport's: the sampling noise of `F_cd` (1/√rays per region,
//! ≤ 10 % here) and the spread of `U` and `ρ` inside a region; it vanishes with the unshot
//! power, so the converged answer is untouched.

use std::collections::HashMap;

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::sampling::{Rng, cosine_hemisphere, triangle_point};
use crate::geometry::{Bvh, Ray};
use crate::mesh::Mesh;
use crate::scene::Rgb;

use super::problem::Problem;

/// Grid cells along the longest axis of the scene's bounds.
const GRID_CELLS: f64 = 16.0;
/// Rays for all regions together (at least [`MIN_RAYS`] per region).
const TOTAL_RAYS: usize = 200_000;
const MIN_RAYS: usize = 128;
/// Fixed-point iterations of the coarse system before its tail is extrapolated (the
/// viewer evaluates it on every publish).
const MAX_ITERATIONS: usize = 50;

/// The regions of a mesh and the sampled transport between them (see the module docs).
pub struct RegionalAmbient {
    /// Region of each patch.
    patch_region: Vec<u32>,
    region_area: Vec<f64>,
    /// For each region `c`: `(d, F_cd)`, sorted by `d`.
    links: Vec<Vec<(u32, f64)>>,
}

impl RegionalAmbient {
    /// Groups the patches and samples the transport (deterministic: seeded per region).
    pub fn build(problem: &Problem) -> Self {
        let mesh = &problem.mesh;
        let (patch_region, region_count) = regions(mesh);
        let mut region_area = vec![0.0; region_count];
        for (p, r) in mesh.patches.iter().zip(&patch_region) {
            region_area[*r as usize] += p.area;
        }
        let mut region_elements: Vec<Vec<u32>> = vec![Vec::new(); region_count];
        for (j, e) in mesh.elements.iter().enumerate() {
            if e.area > 0.0 {
                region_elements[patch_region[e.patch.0 as usize] as usize].push(j as u32);
            }
        }
        let bvh = mesh.display_bvh(&problem.scene, problem.scene.two_sided);
        let rays = (TOTAL_RAYS / region_count.max(1)).max(MIN_RAYS);
        let epsilon = problem.epsilon;
        let links = region_elements
            .par_iter()
            .enumerate()
            .map(|(c, elements)| {
                sample_region(mesh, &bvh, &patch_region, elements, c as u64, rays, epsilon)
            })
            .collect();
        Self {
            patch_region,
            region_area,
            links,
        }
    }

    pub fn region_count(&self) -> usize {
        self.region_area.len()
    }

    /// The region of each patch.
    pub fn patch_regions(&self) -> &[u32] {
        &self.patch_region
    }

    /// `G` per patch (the light still to arrive per unit reflectance, radiance units),
    /// from the unshot radiance and the reflectance of each patch.
    pub fn incoming(&self, patch_area: &[f64], unshot: &[Rgb], reflectance: &[Rgb]) -> Vec<Rgb> {
        let n = self.region_count();
        let mut u = vec![Rgb::ZERO; n];
        let mut rho = vec![Rgb::ZERO; n];
        for (p, &r) in self.patch_region.iter().enumerate() {
            let a = patch_area[p];
            u[r as usize] += unshot[p] * a;
            rho[r as usize] += reflectance[p] * a;
        }
        for c in 0..n {
            if self.region_area[c] > 0.0 {
                u[c] /= self.region_area[c];
                rho[c] /= self.region_area[c];
            }
        }
        let g = self.solve(&u, &rho);
        self.patch_region.iter().map(|&r| g[r as usize]).collect()
    }

    /// `G = F (Ū + ρ̄ G)` by fixed-point iteration (a Neumann series: it converges as
    /// `ρ̄ < 1`), then the remaining terms extrapolated geometrically from the ratio of the
    /// last two increments.
    fn solve(&self, u: &[Rgb], rho: &[Rgb]) -> Vec<Rgb> {
        let transport = |x: &[Rgb]| -> Vec<Rgb> {
            self.links
                .iter()
                .map(|row| row.iter().map(|&(d, f)| x[d as usize] * f).sum())
                .collect()
        };
        let mut g = transport(u);
        let mut increment = g.clone();
        let scale = g.iter().map(|v| v.abs().max_element()).fold(0.0, f64::max);
        if scale == 0.0 {
            return g;
        }
        let mut last_norm = f64::INFINITY;
        let mut ratio = f64::NAN;
        for _ in 0..MAX_ITERATIONS {
            let weighted: Vec<Rgb> = increment.iter().zip(rho).map(|(x, r)| *x * *r).collect();
            increment = transport(&weighted);
            let norm = increment
                .iter()
                .map(|v| v.abs().max_element())
                .fold(0.0, f64::max);
            g.iter_mut().zip(&increment).for_each(|(a, b)| *a += *b);
            if norm <= 1e-6 * scale {
                return g;
            }
            ratio = (norm / last_norm).min(0.9999);
            last_norm = norm;
            if norm <= 1e-3 * scale {
                break;
            }
        }
        // The rest of the series, `increment · (r + r² + …)`, from the last ratio (high
        // reflectance reaches the iteration cap first: this keeps a display call cheap).
        if ratio.is_finite() {
            let tail = ratio / (1.0 - ratio);
            g.iter_mut()
                .zip(&increment)
                .for_each(|(a, b)| *a += *b * tail);
        }
        debug_assert!(g.iter().all(|v| v.is_finite()));
        g
    }
}

/// The region of each patch and the region count: a cell of a grid of
/// [`GRID_CELLS`] along the bounds' longest axis, times the dominant axis of the normal.
fn regions(mesh: &Mesh) -> (Vec<u32>, usize) {
    let bounds = mesh.bounds();
    let extent = (bounds.max - bounds.min).max_element().max(1e-300);
    let cell = extent / GRID_CELLS;
    let mut ids: HashMap<(i64, i64, i64, u8), u32> = HashMap::new();
    let patch_region = mesh
        .patches
        .iter()
        .map(|p| {
            let g = ((p.centroid - bounds.min) / cell).floor();
            let key = (g.x as i64, g.y as i64, g.z as i64, normal_bin(p.normal));
            let next = ids.len() as u32;
            *ids.entry(key).or_insert(next)
        })
        .collect();
    (patch_region, ids.len())
}

/// One of six: the dominant axis of `n` and its sign.
fn normal_bin(n: DVec3) -> u8 {
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    axis * 2 + u8::from(n[axis as usize] < 0.0)
}

/// `F_cd` for one region `c` by `rays` cosine-weighted rays from area-sampled points of
/// its elements.
fn sample_region(
    mesh: &Mesh,
    bvh: &Bvh,
    patch_region: &[u32],
    elements: &[u32],
    region: u64,
    rays: usize,
    epsilon: f64,
) -> Vec<(u32, f64)> {
    if elements.is_empty() {
        return Vec::new();
    }
    let mut cumulative = Vec::with_capacity(elements.len());
    let mut total = 0.0;
    for &j in elements {
        total += mesh.elements[j as usize].area;
        cumulative.push(total);
    }
    let mut rng = Rng::new(0x5eed_a4b1, region);
    let mut counts: HashMap<u32, usize> = HashMap::new();
    for _ in 0..rays {
        let pick = rng.next_f64() * total;
        let k = cumulative
            .partition_point(|&c| c < pick)
            .min(elements.len() - 1);
        let e = &mesh.elements[elements[k] as usize];
        let c = e.corners();
        let (a, b, d) = if c.len() == 4 {
            let first = crate::geometry::polygon::area(&[c[0], c[1], c[2]]);
            if rng.next_f64() * e.area.max(1e-300) < first {
                (c[0], c[1], c[2])
            } else {
                (c[0], c[2], c[3])
            }
        } else {
            (c[0], c[1], c[2])
        };
        let origin = triangle_point(a, b, d, rng.next_f64(), rng.next_f64());
        let dir = cosine_hemisphere(e.normal, rng.next_f64(), rng.next_f64());
        let ray = Ray::new(origin + e.normal * epsilon, dir);
        let Some(hit) = bvh.closest_hit(&ray, 0.0, f64::INFINITY) else {
            continue;
        };
        if !hit.front {
            continue;
        }
        let element = mesh.triangle_element[hit.id as usize];
        let patch = mesh.elements[element.0 as usize].patch;
        *counts.entry(patch_region[patch.0 as usize]).or_default() += 1;
    }
    let mut links: Vec<(u32, f64)> = counts
        .into_iter()
        .map(|(d, n)| (d, n as f64 / rays as f64))
        .collect();
    links.sort_by_key(|l| l.0);
    links
}
