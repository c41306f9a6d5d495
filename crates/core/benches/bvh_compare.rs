//! Rays per second of our [`Bvh`] against the `obvhs` crate's compressed wide BVH8 (CWBVH,
//! Ylitie et al. 2017, built by PLOC with reinsertion) on the same rays, with one and two
//! threads. `obvhs` is a dev-dependency used here only: the product never links it.
//!
//! Both sides test the same `f32` triangles in the same normalised coordinates with the same
//! Möller–Trumbore test (a copy of ours below), and both closest hits are refined in `f64`
//! the same way, so the set-up can check that every ray gets the same answer: hit or miss
//! for shadow rays, the same triangle (or an `f32` tie) and distance for closest hits. What
//! differs is the hierarchy and its traversal, which is what is measured.
//!
//! Scenes: the built-in Cornell box meshed at 20 mm with the segments of the `bvh` group in
//! `benches/core.rs` (random pairs of element centroids, 100 000 rays), and Crytek Sponza
//! (`shared/models/crytek_sponza`, 263 k triangles; skipped with a line when missing, or
//! read from `NUSSELT_SPONZA`) with 200 000 such segments.
//!
//! `cargo bench -p nusselt-core --bench bvh_compare` (prints a table of rays/s; the best of
//! several timed runs of about 0.4 s each).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};
use nusselt_core::geometry::bvh::TriangleInput;
use nusselt_core::geometry::{Aabb, Bvh, Ray};
use nusselt_core::mesh::{Mesh, MeshSpec};
use nusselt_core::scene::{LoadOptions, Scene};
use obvhs::{BvhBuildParams, cwbvh::CwBvh, cwbvh::builder::build_cwbvh_from_tris};
use rayon::prelude::*;

mod common;
use common::segments;

/// Shadow rays stop this far (in ray parameter) short of both ends, as in `benches/core.rs`.
const EPS: f64 = 1e-6;

/// A stored triangle as ours stores it: `f32` corner and edges in normalised coordinates.
#[derive(Clone, Copy)]
struct Tri {
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
    /// Closest hits skip its back face (shadow rays never do).
    cull_back: bool,
}

/// The same triangles, hierarchy and normalisation as [`Bvh::build`], for `obvhs`.
struct Theirs {
    bvh: CwBvh,
    tris: Vec<Tri>,
    /// The input triangles' world corners (to tell which of ours is the same triangle).
    world: Vec<[DVec3; 3]>,
    origin: DVec3,
    scale: f64,
}

impl Theirs {
    fn build(input: &[TriangleInput]) -> Theirs {
        // Normalised exactly as `Bvh::build_with_masks` does (bounding-box centre, diagonal).
        let mut all = Aabb::EMPTY;
        for t in input {
            for v in &t.vertices {
                if v.is_finite() {
                    all.grow(*v);
                }
            }
        }
        let (origin, scale) = (all.center(), all.diagonal());
        let tris: Vec<Tri> = input
            .iter()
            .map(|t| {
                let v = t.vertices.map(|v| ((v - origin) / scale).as_vec3());
                Tri {
                    v0: v[0],
                    e1: v[1] - v[0],
                    e2: v[2] - v[0],
                    cull_back: t.cull_back,
                }
            })
            .collect();
        let a = |v: Vec3| obvhs_glam::Vec3A::from_array(v.to_array());
        let otris: Vec<obvhs::triangle::Triangle> = tris
            .iter()
            .map(|t| obvhs::triangle::Triangle {
                v0: a(t.v0),
                v1: a(t.v0 + t.e1),
                v2: a(t.v0 + t.e2),
            })
            .collect();
        let bvh = build_cwbvh_from_tris(
            &otris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        Theirs {
            bvh,
            tris,
            world: input.iter().map(|t| t.vertices).collect(),
            origin,
            scale,
        }
    }

    fn ray(&self, a: DVec3, p: DVec3, t_min: f64, t_max: f64) -> obvhs::ray::Ray {
        let o = ((a - self.origin) / self.scale).as_vec3();
        let d = ((p - a) / self.scale).as_vec3();
        // The exact inverse: `obvhs::ray::Ray::new` clamps direction components under
        // f32::EPSILON to 1/EPSILON, which is wrong for our unnormalised segments (a
        // component of 1e-8 made boxes end too early and missed hits ours finds). A zero
        // component gets the largest finite inverse, so that 0 × it stays 0, not NaN.
        let inv = d.recip();
        let inv = Vec3::select(inv.is_finite_mask(), inv, Vec3::splat(f32::MAX).copysign(d));
        let a3 = |v: Vec3| obvhs_glam::Vec3A::from_array(v.to_array());
        obvhs::ray::Ray {
            origin: a3(o),
            direction: a3(d),
            inv_direction: a3(inv),
            tmin: t_min as f32,
            tmax: t_max as f32,
        }
    }

    fn tri(&self, id: usize) -> &Tri {
        &self.tris[self.bvh.primitive_indices[id] as usize]
    }

    fn any_hit(&self, a: DVec3, p: DVec3) -> bool {
        let ray = self.ray(a, p, EPS, 1.0 - EPS);
        !self
            .bvh
            .ray_traverse_miss(ray, |r, id| test(self.tri(id), false, r))
    }

    /// Closest hit: the stored triangle's index and the `f64` ray parameter.
    fn closest_hit(&self, a: DVec3, p: DVec3) -> Option<(u32, f32, f64)> {
        let ray = self.ray(a, p, EPS, f64::INFINITY);
        let mut hit = obvhs::ray::RayHit::none();
        if !self.bvh.ray_traverse(ray, &mut hit, |r, id| {
            let tri = self.tri(id);
            test(tri, tri.cull_back, r)
        }) {
            return None;
        }
        let k = self.bvh.primitive_indices[hit.primitive_id as usize];
        let (o64, d64) = ((a - self.origin) / self.scale, (p - a) / self.scale);
        let t = refine(&self.tris[k as usize], o64, d64).unwrap_or(hit.t as f64);
        Some((k, hit.t, t))
    }
}

/// Our Möller–Trumbore test (`bvh.rs` `intersect`), as `obvhs` wants it: the ray
/// parameter, or infinity for a miss.
#[inline]
fn test(tri: &Tri, cull_back: bool, r: &obvhs::ray::Ray) -> f32 {
    let o = Vec3::from_array(r.origin.to_array());
    let d = Vec3::from_array(r.direction.to_array());
    let p = d.cross(tri.e2);
    let det = tri.e1.dot(p);
    if det.abs() < 1e-20 || (cull_back && det < 0.0) {
        return f32::INFINITY;
    }
    let inv_det = 1.0 / det;
    let s = o - tri.v0;
    let u = s.dot(p) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return f32::INFINITY;
    }
    let q = s.cross(tri.e1);
    let v = d.dot(q) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return f32::INFINITY;
    }
    let t = tri.e2.dot(q) * inv_det;
    if t > r.tmin && t < r.tmax {
        t
    } else {
        f32::INFINITY
    }
}

/// Our `f64` refinement of a hit's ray parameter (`bvh.rs` `refine`).
fn refine(tri: &Tri, o: DVec3, d: DVec3) -> Option<f64> {
    let (v0, e1, e2) = (tri.v0.as_dvec3(), tri.e1.as_dvec3(), tri.e2.as_dvec3());
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let q = (o - v0).cross(e1);
    Some(e2.dot(q) / det)
}

/// Brute force over every triangle: whether the segment is blocked, and the closest hit's
/// `f32` distance (the judge where the two hierarchies disagree).
fn brute(theirs: &Theirs, a: DVec3, p: DVec3) -> (bool, Option<f32>) {
    let shadow = theirs.ray(a, p, EPS, 1.0 - EPS);
    let closest = theirs.ray(a, p, EPS, f64::INFINITY);
    let blocked = theirs
        .tris
        .iter()
        .any(|t| test(t, false, &shadow).is_finite());
    let t = theirs
        .tris
        .iter()
        .map(|t| test(t, t.cull_back, &closest))
        .fold(f32::INFINITY, f32::min);
    (blocked, t.is_finite().then_some(t))
}

/// Checks that both give the same answer on every ray, or that ours gives the brute-force
/// answer on each ray where they differ (panics otherwise); prints what differed.
fn check(name: &str, ours: &Bvh, theirs: &Theirs, segs: &[(DVec3, DVec3)]) {
    let (mut blocked, mut hits, mut ties, mut worst) = (0usize, 0usize, 0usize, 0f64);
    let mut differ = Vec::new();
    for (i, &(a, p)) in segs.iter().enumerate() {
        let mine = ours.any_hit(&Ray::new(a, p - a), EPS, 1.0 - EPS);
        let other = theirs.any_hit(a, p);
        if mine != other {
            differ.push((i, format!("any hit: ours {mine}, obvhs {other}")));
        }
        blocked += mine as usize;
        let mine = ours.closest_hit(&Ray::new(a, p - a), EPS, f64::INFINITY);
        let other = theirs.closest_hit(a, p);
        match (mine, other) {
            (None, None) => {}
            (Some(h), Some((k, t32, t))) => {
                hits += 1;
                let same = ours
                    .stored_triangle(h.triangle)
                    .iter()
                    .zip(&theirs.world[k as usize])
                    .all(|(a, b)| a.distance(*b) <= 1e-6 * theirs.scale);
                // Otherwise two triangles hit at the same f32 distance (a shared edge):
                // either is the closest hit, by the order the hierarchy visits them.
                let rel = if same {
                    (h.t - t).abs() / h.t.abs().max(1e-300)
                } else {
                    ((h.t - t32 as f64) / h.t).abs()
                };
                if same && rel <= 1e-9 {
                    worst = worst.max(rel);
                } else if !same && rel <= 1e-6 {
                    ties += 1;
                } else {
                    differ.push((
                        i,
                        format!("closest hit: ours t {:.3e}, obvhs t {t:.3e}", h.t),
                    ));
                }
            }
            (m, o) => differ.push((
                i,
                format!(
                    "closest hit: ours t {:?}, obvhs t {:?}",
                    m.map(|h| h.t),
                    o.map(|h| h.2)
                ),
            )),
        }
    }
    println!(
        "{name}: {} rays: {blocked} shadow rays blocked, {hits} closest hits ({ties} ties \
         between triangles at the same f32 distance; worst relative t difference on the same \
         triangle {worst:.1e}); answers differ on {} rays ({} shadow rays, {} closest hits)",
        segs.len(),
        differ.len(),
        differ.iter().filter(|(_, d)| d.starts_with("any")).count(),
        differ
            .iter()
            .filter(|(_, d)| d.starts_with("closest"))
            .count(),
    );
    // Where they differ, brute force over every triangle says which is right.
    let wrong: Vec<usize> = differ
        .par_iter()
        .filter(|(i, _)| {
            let (a, p) = segs[*i];
            let (b, t) = brute(theirs, a, p);
            let c = ours.closest_hit(&Ray::new(a, p - a), EPS, f64::INFINITY);
            let close = match (c, t) {
                (None, None) => true,
                // The brute force's t is f32 (absolute error about 1e-7 of the
                // origin's distance over the direction's length); ours is refined in f64.
                (Some(h), Some(t)) => (h.t - t as f64).abs() <= 1e-5 * h.t.max(0.1),
                _ => false,
            };
            ours.any_hit(&Ray::new(a, p - a), EPS, 1.0 - EPS) != b || !close
        })
        .map(|(i, _)| *i)
        .collect();
    let near = differ
        .iter()
        .filter_map(|(i, _)| {
            let (a, p) = segs[*i];
            ours.closest_hit(&Ray::new(a, p - a), EPS, f64::INFINITY)
                .map(|h| h.t)
        })
        .fold(0f64, f64::max);
    for (i, d) in differ.iter().take(4) {
        println!("  ray {i}: {d}");
    }
    if !differ.is_empty() {
        println!(
            "  ours gives the brute-force answer on {} of these {} rays; their closest hits \
             by ours lie at t <= {near:.1e} (of the segment's length)",
            differ.len() - wrong.len(),
            differ.len()
        );
    }
    assert!(
        wrong.is_empty(),
        "{name}: ours differs from brute force on rays {:?}",
        &wrong[..wrong.len().min(10)]
    );
}

/// Rays per second of `trace` over `segs` in a pool of `threads`: the best of several runs.
fn rate(
    threads: usize,
    segs: &[(DVec3, DVec3)],
    trace: impl Fn(DVec3, DVec3) -> usize + Sync,
) -> f64 {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("bvh-compare-{i}"))
        .build()
        .expect("thread pool");
    let run = || {
        let t = Instant::now();
        let n: usize = pool.install(|| {
            segs.par_chunks(256)
                .map(|c| c.iter().map(|&(a, p)| trace(a, p)).sum::<usize>())
                .sum()
        });
        std::hint::black_box(n);
        t.elapsed().as_secs_f64()
    };
    let first = run();
    let runs = ((2.0 / first.max(1e-6)) as usize).clamp(3, 50);
    let best = (0..runs).map(|_| run()).fold(first, f64::min);
    segs.len() as f64 / best
}

fn compare(name: &str, input: &[TriangleInput], segs: &[(DVec3, DVec3)]) {
    let t = Instant::now();
    let ours = Bvh::build(input);
    let ours_build = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let theirs = Theirs::build(input);
    let theirs_build = t.elapsed().as_secs_f64();
    println!(
        "{name}: {} triangles, {} rays; build: ours {ours_build:.3} s, obvhs CWBVH \
         {theirs_build:.3} s (one thread)",
        input.len(),
        segs.len()
    );
    // `BVH_COMPARE_NO_CHECK=1` skips the check (for timing one change against another).
    if std::env::var_os("BVH_COMPARE_NO_CHECK").is_none() {
        check(name, &ours, &theirs, segs);
    }
    println!("| scene | query | threads | ours (Mrays/s) | obvhs (Mrays/s) | ours / obvhs |");
    println!("|---|---|---|---|---|---|");
    for threads in [1, 2] {
        let a = rate(threads, segs, |a, p| {
            ours.any_hit(&Ray::new(a, p - a), EPS, 1.0 - EPS) as usize
        });
        let b = rate(threads, segs, |a, p| theirs.any_hit(a, p) as usize);
        println!(
            "| {name} | any hit | {threads} | {:.2} | {:.2} | {:.2} |",
            a / 1e6,
            b / 1e6,
            a / b
        );
        let a = rate(threads, segs, |a, p| {
            ours.closest_hit(&Ray::new(a, p - a), EPS, f64::INFINITY)
                .map_or(0, |h| h.id as usize)
        });
        let b = rate(threads, segs, |a, p| {
            theirs.closest_hit(a, p).map_or(0, |h| h.0 as usize)
        });
        println!(
            "| {name} | closest hit | {threads} | {:.2} | {:.2} | {:.2} |",
            a / 1e6,
            b / 1e6,
            a / b
        );
    }
}

fn sponza_path() -> PathBuf {
    std::env::var_os("NUSSELT_SPONZA")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../../shared/models/crytek_sponza/sponza.obj")
        })
}

fn main() {
    let opts = LoadOptions::default();
    let cornell = Scene::builtin("cornell", &opts).expect("cornell");
    let mesh = Mesh::build(&cornell, &MeshSpec::element(20.0)).expect("mesh");
    compare(
        "cornell",
        &mesh.blocker_triangles(&cornell),
        &segments(&mesh, 100_000),
    );

    let path = sponza_path();
    if !path.exists() {
        println!("sponza: skipped ({} not found)", path.display());
        return;
    }
    let t = Instant::now();
    let scene = match Scene::load(&path, &opts) {
        Ok(s) => s,
        Err(e) => {
            println!("sponza: skipped ({e})");
            return;
        }
    };
    let mesh = Mesh::build(&scene, &MeshSpec::default()).expect("sponza mesh");
    println!(
        "sponza: loaded and meshed in {:.1} s ({} elements)",
        t.elapsed().as_secs_f64(),
        mesh.elements.len()
    );
    compare(
        "sponza",
        &mesh.blocker_triangles(&scene),
        &segments(&mesh, 200_000),
    );
}
