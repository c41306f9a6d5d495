//! The specular second pass: the eye pass follows mirrors and glass and lands on the diffuse
//! radiosity solution (the radiosity + ray-tracing hybrid of Wallace, Cohen & Greenberg 1987
//! and Sillion & Puech 1989, restricted to its eye pass); glossy mirrors by sampling their
//! Phong lobe.
//!
//! Why: radiosity stores one radiance per element, which is exact only for Lambertian
//! surfaces; what a mirror or a glass block shows depends on the direction it is seen from.
//! So the solve stays diffuse (a specular surface takes part with its `Kd` only, its specular
//! part absorbs), and per camera sample this pass traces the view-dependent part: at a
//! mirror (`Ks`) the reflected ray, at a glossy mirror rays drawn from its Phong lobe
//! ([`optics::phong_lobe`], [`GLOSSY_SPLIT`]² stratified ones at the first bounce), at glass
//! the Fresnel-weighted reflected and refracted rays ([`super::optics`]; both followed for
//! the first [`SPLIT_DEPTH`] glass bounces, one chosen with its Fresnel probability after
//! that), up to [`MAX_DEPTH`] bounces. Where a ray lands on a diffuse surface, the selected
//! per-pixel pass (`--pass vertex|direct|gather`) shades it, weighted by the product of the
//! specular weights on the way; a specular surface's own diffuse part and emission are that
//! pass's too.
//!
//! Known error, besides the pass's own: light that reaches a diffuse surface through a mirror
//! or glass (caustics: the light's image on the floor beside a mirror, the bright spot under
//! a glass block, and everything lit by it) is not in the radiosity solution, where glass and
//! mirrors absorb what they do not reflect diffusely, so such a surface is darker than in the
//! path tracer ([`super::pathtrace`]), which follows those paths. Elsewhere the hybrid matches
//! it up to the pass's error. Out of scope by design. A ray still inside glass after
//! `MAX_DEPTH` bounces gets the pass's value of what it hits (a bias of the order of the
//! light that bounced that often, below 1e-3 for the built-in scene). A glossy lobe is
//! sampled, not integrated: what it reflects is noisy where it sees a small bright light
//! (the highlight), the noise falling as 1/√(spp · GLOSSY_SPLIT²). Scenes without a
//! specular material never come here: they render exactly as before.

use crate::geometry::{Ray, Rng};
use crate::scene::{Rgb, Surface};

use super::{Image, RenderSettings, SolutionView, optics};

/// Most specular bounces followed from the camera.
pub const MAX_DEPTH: u32 = 16;
/// A glossy lobe seen from the camera is sampled on a `GLOSSY_SPLIT`² stratified grid per
/// camera sample (deeper, once).
pub const GLOSSY_SPLIT: u32 = 2;
/// Glass bounces at which both the reflected and the refracted ray are traced (fewer
/// noisy pixels where the reflection is faint); deeper, one is chosen by its Fresnel weight.
pub const SPLIT_DEPTH: u32 = 2;

/// The eye pass over a solution's display mesh.
pub struct Hybrid<'a, 'b> {
    view: &'a SolutionView<'b>,
    epsilon: f64,
}

impl<'a, 'b> Hybrid<'a, 'b> {
    pub fn new(view: &'a SolutionView<'b>) -> Self {
        let epsilon = 1e-6 * view.scene.bounds().diagonal().max(1e-12);
        Self { view, epsilon }
    }

    /// Radiance along a camera ray: `base` (a per-pixel pass) where the ray lands on a
    /// diffuse surface, through any mirrors and glass on the way.
    pub fn radiance(&self, ray: &Ray, rng: &mut Rng, base: &dyn Fn(&Ray, &mut Rng) -> Rgb) -> Rgb {
        self.trace(ray, rng, base, 0)
    }

    fn trace(
        &self,
        ray: &Ray,
        rng: &mut Rng,
        base: &dyn Fn(&Ray, &mut Rng) -> Rgb,
        depth: u32,
    ) -> Rgb {
        let view = self.view;
        let Some(hit) = view.bvh.closest_hit(ray, 0.0, f64::INFINITY) else {
            return base(ray, rng); // nothing: the pass's background
        };
        let element = &view.mesh.elements[view.mesh.triangle_element[hit.id as usize].0 as usize];
        let material = &view.scene.materials[view.mesh.patch(element.patch).material.0 as usize];
        if material.surface == Surface::Diffuse || depth >= MAX_DEPTH {
            return base(ray, rng);
        }
        // The surface's own diffuse part and emission, as the pass shades them.
        let own = if material.reflectance.max_element() > 0.0 || material.is_emitter() {
            base(ray, rng)
        } else {
            Rgb::ZERO
        };
        let x = ray.at(hit.t);
        let Some(d) = ray.dir.try_normalize() else {
            return own;
        };
        match material.surface {
            Surface::Diffuse => own,
            Surface::Mirror { ks } => {
                if !hit.front && !view.scene.two_sided {
                    return own; // the back of a one-sided mirror
                }
                let n = if d.dot(element.normal) < 0.0 {
                    element.normal
                } else {
                    -element.normal
                };
                let reflected = Ray::new(x + n * self.epsilon, optics::reflect(d, n));
                own + ks * self.trace(&reflected, rng, base, depth + 1)
            }
            Surface::Glossy { ks, exponent } => {
                if !hit.front && !view.scene.two_sided {
                    return own;
                }
                let n = if d.dot(element.normal) < 0.0 {
                    element.normal
                } else {
                    -element.normal
                };
                let axis = optics::reflect(d, n);
                // Stratified lobe samples: several where the camera ray arrives, one deeper.
                let k = if depth == 0 { GLOSSY_SPLIT } else { 1 };
                let mut sum = Rgb::ZERO;
                for i in 0..k * k {
                    let u1 = ((i / k) as f64 + rng.next_f64()) / k as f64;
                    let u2 = ((i % k) as f64 + rng.next_f64()) / k as f64;
                    if let Some(dir) = optics::phong_lobe(axis, n, exponent, u1, u2) {
                        let lobe = Ray::new(x + n * self.epsilon, dir);
                        sum += self.trace(&lobe, rng, base, depth + 1);
                    }
                }
                own + ks * sum / (k * k) as f64
            }
            Surface::Glass { ior } => {
                let i = optics::dielectric(d, element.normal, hit.front, ior);
                let reflected = Ray::new(x + i.facing * self.epsilon, i.reflected);
                let Some(t) = i.refracted else {
                    return own + self.trace(&reflected, rng, base, depth + 1);
                };
                let refracted = Ray::new(x - i.facing * self.epsilon, t);
                let r = i.reflectance;
                if depth < SPLIT_DEPTH {
                    own + r * self.trace(&reflected, rng, base, depth + 1)
                        + (1.0 - r) * self.trace(&refracted, rng, base, depth + 1)
                } else if rng.next_f64() < r {
                    own + self.trace(&reflected, rng, base, depth + 1)
                } else {
                    own + self.trace(&refracted, rng, base, depth + 1)
                }
            }
        }
    }
}

/// [`super::render_pixels`] with `shade` (a per-pixel pass) seen through the scene's mirrors
/// and glass when it has any, else exactly `render_pixels(settings, tag, shade)`.
pub(crate) fn render_pixels(
    view: &SolutionView,
    settings: &RenderSettings,
    tag: u64,
    shade: impl Fn(&Ray, &mut Rng) -> Rgb + Sync,
) -> Image {
    if !view.scene.has_specular() {
        return super::render_pixels(settings, tag, shade);
    }
    let hybrid = Hybrid::new(view);
    super::render_pixels(settings, tag, |ray, rng| hybrid.radiance(ray, rng, &shade))
}

#[cfg(test)]
mod tests;
