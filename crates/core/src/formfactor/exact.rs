//! Exact polygon-to-polygon form factors by the double contour integral (Stokes).
//!
//! `F_12 = 1/(2π A_1) ∮_{C1} ∮_{C2} ln r  dx_1·dx_2` (Sparrow 1963; Sparrow & Cess,
//! "Radiation Heat Transfer"). The contour is a sum over edge pairs `(a, b)` of
//! `(â·b̂) ∫∫ ln r ds dt`; perpendicular edges contribute nothing. Each pair is evaluated so that
//! it is exact for touching and edge-sharing polygons, where `ln r` is singular:
//!
//! * parallel edges (including collinear, shared edges, where `r → 0`): the double integral of
//!   `ln √(x² + h²)` has a closed form (second antiderivative
//!   `(x² − h²)/2 · ln √(x² + h²) − 3x²/4 + h x atan(x/h)`), evaluated at the four corners;
//! * other edges: the inner integral along `b` is analytic
//!   (`x ln √(x² + h²) − x + h atan(x/h)`), the outer one adaptive Gauss–Kronrod (7–15)
//!   to 1e-15 of the pair's size, which also resolves the integrable `s ln s` kink where
//!   two edges meet at a shared vertex.
//!
//! `ln r` is replaced by `ln(r/R)` with `R` the distance between the centroids: the constant
//! integrates to zero over closed contours, and the remaining terms are O(1) instead of
//! `ln R`, which keeps far pairs (F ≈ 3e-5 at distance 100) from cancelling catastrophically.
//! The same closed form for the parallel case is the one used by Schröder & Hanrahan (1993,
//! "On the form factor between two polygons") for their general formula.
//!
//! Measured error (tests/formfactor_methods.rs): ≤ 1e-12 relative on the polygon cases of the
//! reference catalogue, including perpendicular squares sharing an edge and parallel squares
//! 0.01 apart; reciprocity `A_1 F_12 = A_2 F_21` to ≤ 1e-13. The catalogue's disk values are
//! for true disks and its polygons are 128-gons: there the difference (≤ 2e-8) is the polygon
//! approximation, not this method's error.
//!
//! With occluders, [`point_to_visible_polygon`] gives the exact point-to-polygon value: the
//! occluders (convex pieces) are projected from the point onto the source's plane and
//! subtracted, and Lambert's formula is applied to what is left. Integrated over the
//! receiver adaptively (`nusselt_core::cases::integrate_over`, the case harness) it is the reference for occluded
//! cases; its error is then the cubature's on a function with kinks at penumbra boundaries.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::contour;
use super::row::{RowContext, ShotSetup, patch_slices};
use super::visibility::{part_above, part_sampler, patch_pair_unblocked, visibility_fraction};
use crate::geometry::sampling::hash_seed;
use crate::geometry::{Rng, polygon};
use crate::mesh::PatchId;

/// Form factor from polygon `a1` to polygon `a2` (both counter-clockwise seen from their
/// fronts), unoccluded. Exact up to round-off for any planar polygons, touching or not.
pub fn polygon_to_polygon(a1: &[DVec3], a2: &[DVec3]) -> f64 {
    polygon_to_polygon_tol(a1, a2, 1e-15)
}

/// [`polygon_to_polygon`] with the numerical edge pairs integrated to `rel` of their size
/// (the solver's rows use 1e-9: they are stored in `f32`).
pub fn polygon_to_polygon_tol(a1: &[DVec3], a2: &[DVec3], rel: f64) -> f64 {
    let area1 = polygon::area(a1);
    if area1 <= 0.0 || polygon::area(a2) <= 0.0 {
        return 0.0;
    }
    let r0 = (polygon::centroid(a1) - polygon::centroid(a2)).length();
    let scale = polygon_extent(a1).max(polygon_extent(a2));
    let ln_r0 = if r0 > 1e-3 * scale {
        r0.ln()
    } else {
        scale.ln()
    };
    let mut sum = 0.0;
    let n1 = a1.len();
    let n2 = a2.len();
    for i in 0..n1 {
        let (p0, p1) = (a1[i], a1[(i + 1) % n1]);
        for j in 0..n2 {
            let (q0, q1) = (a2[j], a2[(j + 1) % n2]);
            sum += edge_pair(p0, p1, q0, q1, ln_r0, rel);
        }
    }
    // Both contours counter-clockwise about fronts that face each other: the sum is positive.
    let f = sum / (2.0 * std::f64::consts::PI * area1);
    debug_assert!(f.is_finite());
    f.max(0.0)
}

fn polygon_extent(p: &[DVec3]) -> f64 {
    crate::geometry::Aabb::from_points(p.iter())
        .diagonal()
        .max(1e-300)
}

/// `(â·b̂) ∫∫ ln(r/R) ds dt` over the segments p0→p1 and q0→q1.
fn edge_pair(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3, ln_r0: f64, rel: f64) -> f64 {
    let (da, db) = (p1 - p0, q1 - q0);
    let (l1, l2) = (da.length(), db.length());
    if l1 <= 0.0 || l2 <= 0.0 {
        return 0.0;
    }
    let (a, b) = (da / l1, db / l2);
    let cos = a.dot(b);
    if cos.abs() < 1e-15 {
        return 0.0;
    }
    let sin = a.cross(b).length();
    if sin < 1e-12 {
        // Parallel (σ = ±1): x = c + s − σt along â, constant distance h.
        let sigma = cos.signum();
        let w = p0 - q0;
        let c = w.dot(a);
        let h = (w - a * c).length();
        let xs = [c + l1 - sigma * l2, c + l1, c - sigma * l2, c];
        return cos * -sigma * parallel_corners(xs, h, ln_r0);
    }
    // General: analytic inner integral along b, adaptive outer integral along a. The inner
    // integral is `[x ln(√(x²+h²)/R)] + h (atan((β+L2)/h) − atan(β/h)) − L2`; its constant
    // `−L2` is integrated exactly (`−L1 L2`), the rest, O(L2), by quadrature (keeping the
    // constant in would leave only round-off for far pairs, where the rest is tiny).
    let inner = |s: f64| {
        let p = p0 + a * s;
        let d = q0 - p;
        // Along b the foot of the perpendicular is at t = −β; x = β + t.
        let beta = d.dot(b);
        let h = d.cross(b).length();
        let xlog = |x: f64| {
            let r2 = x * x + h * h;
            if r2 > 0.0 && x != 0.0 {
                x * (0.5 * r2.ln() - ln_r0)
            } else {
                0.0
            }
        };
        let angle = if h > 0.0 {
            h * (l2 * h).atan2(h * h + beta * (beta + l2))
        } else {
            0.0
        };
        xlog(beta + l2) - xlog(beta) + angle
    };
    let tol = rel * l1 * l2;
    cos * (gauss_kronrod(&inner, 0.0, l1, tol, 40) - l1 * l2)
}

/// F from polygon `recv` (area `area`) to polygon `src`, each clipped to the other's front
/// half-space first (the double contour integral needs both wholly in front of each other).
pub fn clipped_polygon_to_polygon(recv: &[DVec3], src: &[DVec3], rel: f64) -> f64 {
    let (Some(nr), Some(ns)) = (polygon::normal(recv), polygon::normal(src)) else {
        return 0.0;
    };
    let area = polygon::area(recv);
    let size = polygon::area(src).sqrt().max(area.sqrt());
    if recv
        .iter()
        .all(|v| (*v - src[0]).dot(ns).abs() <= 1e-12 * size)
    {
        return 0.0; // Coplanar: they cannot see each other.
    }
    let r = polygon::clip_to_halfspace(recv, src[0], ns);
    if r.len() < 3 {
        return 0.0;
    }
    let s = polygon::clip_to_halfspace(src, recv[0], nr);
    if s.len() < 3 {
        return 0.0;
    }
    let ra = polygon::area(&r);
    if ra <= 0.0 || polygon::area(&s) <= 0.0 {
        return 0.0;
    }
    ra / area * polygon_to_polygon_tol(&r, &s, rel)
}

/// `out[j] = F_ji`: the exact element-to-patch form factor (unoccluded) × the weighted
/// visible fraction of stratified shadow rays from the element's centroid
/// ([`visibility_fraction`], through the whole BVH; with the 4-ray probe and the patch-pair
/// shortcut for non-emitting shooters). Unlike the contour row it neither culls blockers by
/// the pair's shaft nor subtracts light sources' shadows exactly, so its visibility error
/// is that of sampled rays everywhere, lights included.
pub fn row(ctx: &RowContext, shooter: PatchId, out: &mut [f32], cancel: &AtomicBool) -> bool {
    let setup = ShotSetup::new(ctx, shooter);
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    patch_slices(mesh, out)
        .into_par_iter()
        .for_each(|(k, slice)| {
            if cancel.load(Ordering::Relaxed) {
                return;
            }
            let receiver = &mesh.patches[k];
            if k == shooter.0 as usize {
                slice.fill(0.0);
                return;
            }
            let ignore = [receiver.occluder, patch.occluder];
            let all_visible =
                setup.probe && patch_pair_unblocked(ctx, receiver, patch, shooter, k, ignore);
            let first = receiver.elements.start as usize;
            for (i, f) in slice.iter_mut().enumerate() {
                let j = first + i;
                let e = &mesh.elements[j];
                let value = clipped_polygon_to_polygon(e.corners(), &patch.polygon, 1e-9);
                if value <= 0.0 || all_visible {
                    *f = value as f32;
                    continue;
                }
                let mut rng =
                    Rng::new(hash_seed(&[ctx.params.seed, shooter.0 as u64, j as u64]), 0);
                let part = part_above(&patch.polygon, e.centroid, e.normal);
                let sampler = part_sampler(&part, &setup.sampler);
                let v = visibility_fraction(
                    ctx.bvh,
                    e.centroid,
                    e.normal,
                    &sampler,
                    setup.m,
                    setup.probe,
                    ctx.epsilon,
                    ignore,
                    &mut rng,
                );
                *f = (value * v) as f32;
            }
        });
    !cancel.load(Ordering::Relaxed)
}

/// `F2(x0) − F2(x1) − F2(x2) + F2(x3)` for the antiderivative of
/// [`first_antiderivative`] in `x`,
/// `F2(x) = (x² − h²)/2 · ln(√(x²+h²)/R) − 3x²/4 + h x atan(x/h)`.
/// The `−h²/2 · ln` part is evaluated as differences of logarithms (`ln_1p`): for far
/// pairs `h²` is large and the plain sum would lose `h²` times the logarithms' round-off.
fn parallel_corners(xs: [f64; 4], h: f64, ln_r0: f64) -> f64 {
    let signs = [1.0, -1.0, -1.0, 1.0];
    let h2 = h * h;
    let f_r = |x: f64| {
        let r2 = x * x + h2;
        if r2 > 0.0 { 0.5 * r2.ln() - ln_r0 } else { 0.0 }
    };
    let mut rest = 0.0;
    for (x, s) in xs.iter().zip(signs) {
        let x = *x;
        let xlog = if x != 0.0 { 0.5 * x * x * f_r(x) } else { 0.0 };
        let at = if h > 0.0 { h * x * (x / h).atan() } else { 0.0 };
        rest += s * (xlog - 0.75 * x * x + at);
    }
    if h2 == 0.0 {
        return rest;
    }
    // ln √(a² + h²) − ln √(b² + h²) = ½ ln(1 + (a − b)(a + b)/(b² + h²)).
    let dlog = |a: f64, b: f64| {
        let q = (a - b) * (a + b) / (b * b + h2);
        if q.abs() < 0.5 {
            0.5 * q.ln_1p()
        } else {
            0.5 * ((a * a + h2) / (b * b + h2)).ln()
        }
    };
    let second = dlog(xs[0], xs[1]) - dlog(xs[2], xs[3]);
    rest - 0.5 * h2 * second
}

/// Gauss–Kronrod 7–15 nodes on [−1, 1] (non-negative half) and weights.
const XGK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
const WGK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_2,
    0.140_653_259_715_525_9,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_728_8,
];
/// Gauss 7-point weights for the Kronrod nodes 1, 3, 5, 7 (index into XGK).
const WG: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

fn gk15(f: &dyn Fn(f64) -> f64, a: f64, b: f64) -> (f64, f64, f64) {
    let c = 0.5 * (a + b);
    let h = 0.5 * (b - a);
    let fc = f(c);
    let mut k = fc * WGK[7];
    let mut g = fc * WG[3];
    let mut abs = fc.abs() * WGK[7];
    for i in 0..7 {
        let x = h * XGK[i];
        let (l, r) = (f(c - x), f(c + x));
        let s = l + r;
        k += WGK[i] * s;
        abs += WGK[i] * (l.abs() + r.abs());
        if i % 2 == 1 {
            g += WG[i / 2] * s;
        }
    }
    (k * h, ((k - g) * h).abs(), abs * h.abs())
}

/// Adaptive Gauss–Kronrod: bisects until each interval's estimate is within its share of
/// `tol`, or within the round-off of its values (50 ε ∫|f|, as QUADPACK), or `depth` runs
/// out; at most 400 rule evaluations in all (a budget that only a noisy integrand reaches).
pub fn gauss_kronrod(f: &dyn Fn(f64) -> f64, a: f64, b: f64, tol: f64, depth: u32) -> f64 {
    let mut budget = 400u32;
    gk_rec(f, a, b, tol, depth, &mut budget)
}

fn gk_rec(f: &dyn Fn(f64) -> f64, a: f64, b: f64, tol: f64, depth: u32, budget: &mut u32) -> f64 {
    let (k, err, abs) = gk15(f, a, b);
    *budget = budget.saturating_sub(1);
    if err <= tol
        || err <= 50.0 * f64::EPSILON * abs
        || depth == 0
        || *budget < 2
        || (b - a).abs() < 1e-300
    {
        return k;
    }
    let m = 0.5 * (a + b);
    gk_rec(f, a, m, 0.5 * tol, depth - 1, budget) + gk_rec(f, m, b, 0.5 * tol, depth - 1, budget)
}

/// Exact form factor from the differential area at `p` (unit normal `n`) to the part of
/// `source` that is not hidden by `occluders` (any planar polygons; non-convex ones are
/// split into triangles). The source's front emits; the receiver sees its upper hemisphere.
pub fn point_to_visible_polygon(
    p: DVec3,
    n: DVec3,
    source: &[DVec3],
    occluders: &[Vec<DVec3>],
) -> f64 {
    let Some(sn) = polygon::normal(source) else {
        return 0.0;
    };
    let height = (p - source[0]).dot(sn);
    if height <= 0.0 {
        return 0.0;
    }
    // Visible pieces: convex polygons in the source's plane, counter-clockwise about `sn`.
    let mut pieces: Vec<Vec<DVec3>> = convex_pieces(source)
        .into_iter()
        .map(|t| polygon::clip_to_halfspace(&t, p, n))
        .filter(|t| t.len() >= 3)
        .collect();
    for occ in occluders {
        for tri in convex_pieces(occ) {
            for piece in std::mem::take(&mut pieces) {
                let Some(shadow) = shadow_on_piece(p, &piece, sn, height, &tri) else {
                    pieces.push(piece);
                    continue;
                };

                pieces.extend(subtract_convex(&piece, &shadow, sn));
            }
        }
    }
    pieces
        .iter()
        .filter(|q| q.len() >= 3)
        .map(|q| contour::lambert(p, n, q))
        .sum()
}

/// A polygon as convex pieces: itself when convex, else its triangles.
fn convex_pieces(poly: &[DVec3]) -> Vec<Vec<DVec3>> {
    if polygon::is_convex(poly) {
        return vec![poly.to_vec()];
    }
    polygon::triangulate(poly)
        .into_iter()
        .map(|t| vec![poly[t[0]], poly[t[1]], poly[t[2]]])
        .collect()
}

/// The part of convex `piece` (in the source plane, normal `sn`, `p` at `height` above it)
/// hidden by convex occluder `occ`: the occluder is clipped to the cone from `p` through
/// the piece and to the slab between `p` and the plane, then projected from `p`.
fn shadow_on_piece(
    p: DVec3,
    piece: &[DVec3],
    sn: DVec3,
    height: f64,
    occ: &[DVec3],
) -> Option<Vec<DVec3>> {
    let plane_point = piece[0];
    // Between the plane (d ≥ 0) and the point (d < height).
    let mut o = polygon::clip_to_halfspace(occ, plane_point, sn);
    if o.len() < 3 {
        return None;
    }
    o = polygon::clip_to_halfspace(&o, p - sn * (1e-12 * height), -sn);
    if o.len() < 3 {
        return None;
    }
    // Inside the cone through each edge of the piece (counter-clockwise about sn, p above).
    let k = piece.len();
    for i in 0..k {
        let (a, b) = (piece[i], piece[(i + 1) % k]);
        let inward = (b - a).cross(p - a);
        // The piece's interior lies on the side of the plane (p, a, b) that `sn × edge` points to.
        let side = sn.cross(b - a);
        let normal = if inward.dot(side) >= 0.0 {
            inward
        } else {
            -inward
        };
        o = polygon::clip_to_halfspace(&o, p, normal);
        if o.len() < 3 {
            return None;
        }
    }
    let projected: Vec<DVec3> = o
        .iter()
        .map(|v| {
            let d = (*v - plane_point).dot(sn);
            let t = height / (height - d);
            p + (*v - p) * t
        })
        .collect();
    let nn = polygon::newell(&projected);
    if nn.length() <= 1e-300 {
        return None;
    }
    let mut projected = projected;
    if nn.dot(sn) < 0.0 {
        projected.reverse();
    }
    Some(projected)
}

/// A hole whose doubled area is at most this times the piece's longest edge squared is
/// none: leaving it out changes the visible area by at most that fraction.
const DEGENERATE_HOLE: f64 = 1e-12;

/// `piece` minus convex `hole` (both convex, in one plane, counter-clockwise about `sn`):
/// up to one convex piece per edge of the hole.
///
/// Tolerances are relative to the piece (the hole lies inside it): a hole of no area (a
/// point or a segment left by clipping a shadow that only touches the piece) hides nothing
/// and is not subtracted, since its edges have no reliable outward side. Measured against
/// the hole's own size instead, a point-like shadow (all edges ~1e-12 of the piece) kept
/// its edges, their outward sides pointed anywhere, and the "outside" parts overlapped: the
/// piece came back up to 3 times over (a light's exact row at scale 1e4 was twice
/// the value at scale 1, 0.000555 vs 0.000287, the same blockers in other rounding).
fn subtract_convex(piece: &[DVec3], hole: &[DVec3], sn: DVec3) -> Vec<Vec<DVec3>> {
    let k = hole.len();
    let m = piece.len();
    let size = (0..m)
        .map(|i| (piece[(i + 1) % m] - piece[i]).length())
        .fold(0.0, f64::max);
    if k < 3 || polygon::newell(hole).dot(sn) <= DEGENERATE_HOLE * size * size {
        return vec![piece.to_vec()];
    }
    let mut out = Vec::new();
    let mut rest = piece.to_vec();
    for i in 0..k {
        if rest.len() < 3 {
            break;
        }
        let (a, b) = (hole[i], hole[(i + 1) % k]);
        // A degenerate edge (repeated vertex, left by clipping) has no outward side: with
        // a zero normal every point would count as outside and the hole itself would be
        // kept as visible.
        if (b - a).length() <= 1e-9 * size {
            continue;
        }
        // Outward normal of the hole's edge, in the plane.
        let outward = (b - a).cross(sn);
        let outside = polygon::clip_to_halfspace(&rest, a, outward);
        if outside.len() >= 3 && polygon::area(&outside) > 0.0 {
            out.push(outside);
        }
        rest = polygon::clip_to_halfspace(&rest, a, -outward);
    }
    out
}

#[cfg(test)]
mod tests;
