//! What the lights that are not faces ([`crate::scene::lights`]) give each element: the
//! "form factor" of a sky, a sun or a point light to an element, with its visibility.
//!
//! These lights are shot first, as emitting patches are in step 1 of progressive
//! refinement: an element's share `ρ · h` (h = irradiance over π) becomes part of its
//! initial radiosity and unshot radiance, and its reflected light is shot on from there.
//!
//! - Suns and points: the mean of [`crate::scene::lights::punctual_incident`] over
//!   [`POINTS`] stratified points of the element, one shadow ray each (a soft sun draws its
//!   direction in its cone per point). Exact where the element is wholly lit or shadowed;
//!   on a shadow edge the lit fraction is known to 1/[`POINTS`] (the direct pass then
//!   evaluates these lights per pixel, so the image's shadow edge is sharp).
//! - Sky: `L · f`, `f` the fraction of cosine-distributed rays from the element that hit
//!   nothing, on a jittered `k × k` grid of the hemisphere's (u₁, u₂) square from the same
//!   points. The error of `f` is below the binomial `√(f(1 − f)/k²)` (stratification).

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::sampling::{cosine_hemisphere, hash_seed, triangle_point};
use crate::geometry::{Bvh, Ray, Rng};
use crate::mesh::{Element, Mesh};
use crate::scene::lights::{has_punctual, punctual_incident, sky_radiance};
use crate::scene::{Light, Rgb, Scene, Surface};

/// Windows for the light of skies, suns and points: faces of glass materials are thin
/// panes whose visibility is their transmittance. A ray the solve's blockers stop is tested
/// again against the opaque faces alone; if only glass stopped it, it carries the thin
/// slab's transmittance `(1 − R)² / (1 − R²)`, `R = ((n − 1)/(n + 1))²` at normal incidence
/// (0.923 for n = 1.5), whatever the number of panes and the angle (both err high: two
/// panes or a grazing ray let through less).
#[derive(Default)]
pub struct GlassVisibility {
    opaque: Option<Bvh>,
    transmittance: f64,
}

/// No windows: glass blocks as every face does.
pub static NO_GLASS: GlassVisibility = GlassVisibility {
    opaque: None,
    transmittance: 0.0,
};

/// A thin pane's transmittance at normal incidence with its two surfaces' interreflections.
pub fn slab_transmittance(ior: f64) -> f64 {
    let r = ((ior - 1.0) / (ior + 1.0)).powi(2);
    (1.0 - r) * (1.0 - r) / (1.0 - r * r)
}

impl GlassVisibility {
    /// The opaque faces of `scene` as `mesh` groups them; nothing if there is no glass.
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        let Some(ior) = scene.materials.iter().find_map(|m| match m.surface {
            Surface::Glass { ior } => Some(ior),
            _ => None,
        }) else {
            return Self::default();
        };
        let opaque = mesh.blocker_bvh_where(scene, |f| {
            !matches!(
                scene.materials[f.material.0 as usize].surface,
                Surface::Glass { .. }
            )
        });
        Self {
            opaque: Some(opaque),
            transmittance: slab_transmittance(ior),
        }
    }

    /// The fraction of light along `ray` up to `t_max` that `blockers` (all faces) and the
    /// windows let through.
    pub fn visibility(&self, blockers: &Bvh, ray: &Ray, t_max: f64, ignore: [u32; 2]) -> f64 {
        if !blockers.any_hit_except(ray, 0.0, t_max, ignore) {
            return 1.0;
        }
        match &self.opaque {
            Some(opaque) if !opaque.any_hit_except(ray, 0.0, t_max, ignore) => self.transmittance,
            _ => 0.0,
        }
    }
}

/// Points per element at which suns and point lights are evaluated.
pub const POINTS: usize = 4;
/// Sky rays per element, `k²`: as many as fit in this many rays for the whole mesh, with
/// `k` between [`SKY_MIN_SIDE`] and [`SKY_MAX_SIDE`].
const SKY_RAY_BUDGET: f64 = 4.0e6;
const SKY_MIN_SIDE: usize = 4;
const SKY_MAX_SIDE: usize = 8;

/// Irradiance over π that each element receives from the sky and from suns and points.
#[derive(Clone, Debug, Default)]
pub struct ExternalLight {
    /// The sky's radiance.
    pub sky_radiance: Rgb,
    /// Per element, the cosine-weighted fraction of visible sky; empty until a sky is on
    /// (then kept: it depends on the geometry only).
    pub sky_fraction: Vec<f64>,
    /// Per element; empty when the scene has no sun or point light.
    pub punctual: Vec<Rgb>,
}

impl ExternalLight {
    /// Sky plus suns and points at element `e`.
    pub fn at(&self, e: usize) -> Rgb {
        self.sky(e) + self.punctual.get(e).copied().unwrap_or(Rgb::ZERO)
    }

    /// The sky's part at element `e`.
    pub fn sky(&self, e: usize) -> Rgb {
        self.sky_fraction
            .get(e)
            .map_or(Rgb::ZERO, |f| self.sky_radiance * *f)
    }

    pub fn is_empty(&self) -> bool {
        (self.sky_fraction.is_empty() || self.sky_radiance == Rgb::ZERO) && self.punctual.is_empty()
    }

    /// Recomputes for new `lights` on the same mesh: the sky fractions only the first time
    /// a sky is on, the suns and points every time (a few shadow rays per element). `bvh`
    /// is the solve's blocker BVH (ids: occluder groups), `glass` its windows, `epsilon`
    /// the offset of ray origins.
    pub fn update(
        &mut self,
        lights: &[Light],
        glass: &GlassVisibility,
        mesh: &Mesh,
        bvh: &Bvh,
        epsilon: f64,
    ) {
        let n = mesh.elements.len();
        let at = |k: usize| Probe {
            element: &mesh.elements[k],
            own: mesh.patch(mesh.elements[k].patch).occluder,
            bvh,
            glass,
            epsilon,
            seed: hash_seed(&[k as u64, 0x11647]),
        };
        self.sky_radiance = sky_radiance(lights);
        if self.sky_radiance.max_element() > 0.0 && self.sky_fraction.len() != n {
            let side = ((SKY_RAY_BUDGET / n.max(1) as f64).sqrt() as usize)
                .clamp(SKY_MIN_SIDE, SKY_MAX_SIDE);
            self.sky_fraction = (0..n)
                .into_par_iter()
                .map(|k| at(k).sky_fraction(side))
                .collect();
        }
        self.punctual = if has_punctual(lights) {
            (0..n)
                .into_par_iter()
                .map(|k| at(k).punctual(lights))
                .collect()
        } else {
            Vec::new()
        };
    }
}

/// One element seen from the lights.
struct Probe<'a> {
    element: &'a Element,
    own: u32,
    bvh: &'a Bvh,
    glass: &'a GlassVisibility,
    epsilon: f64,
    seed: u64,
}

impl Probe<'_> {
    /// Stratified point `k` of [`POINTS`] on the element (the centres of its 2 × 2 grid).
    fn point(&self, k: usize) -> DVec3 {
        let c = self.element.corners();
        let (s, t) = (
            0.25 + 0.5 * (k % 2) as f64,
            0.25 + 0.5 * ((k / 2) % 2) as f64,
        );
        if c.len() == 4 {
            let a = c[0].lerp(c[1], s);
            let b = c[3].lerp(c[2], s);
            a.lerp(b, t)
        } else {
            triangle_point(c[0], c[1], c[2], s, t)
        }
    }

    /// What a ray from `x` along `dir` lets through before `t_max` (windows included).
    fn visible(&self, x: DVec3, dir: DVec3, t_max: f64) -> f64 {
        let ray = Ray::new(x + self.element.normal * self.epsilon, dir);
        self.glass
            .visibility(self.bvh, &ray, t_max, [self.own, u32::MAX])
    }

    fn punctual(&self, lights: &[Light]) -> Rgb {
        let mut rng = Rng::new(self.seed, 1);
        let n = self.element.normal;
        let mut sum = Rgb::ZERO;
        for k in 0..POINTS {
            let x = self.point(k);
            let u = (rng.next_f64(), rng.next_f64());
            sum += punctual_incident(lights, x, n, u, &|d, t| self.visible(x, d, t));
        }
        sum / POINTS as f64
    }

    /// Fraction of `side²` stratified cosine rays that hit nothing.
    fn sky_fraction(&self, side: usize) -> f64 {
        let mut rng = Rng::new(self.seed, 2);
        let n = self.element.normal;
        let mut escaped = 0.0;
        for i in 0..side {
            for j in 0..side {
                let u1 = (i as f64 + rng.next_f64()) / side as f64;
                let u2 = (j as f64 + rng.next_f64()) / side as f64;
                let x = self.point((i * side + j) % POINTS);
                let d = cosine_hemisphere(n, u1, u2);
                escaped += self.visible(x, d, f64::INFINITY);
            }
        }
        escaped / (side * side) as f64
    }
}
