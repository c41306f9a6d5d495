//! Unbiased reference: a path tracer with next-event estimation and Russian roulette
//! (Kajiya 1986; Veach 1997 ch. 10; as in pbrt-v4's `PathIntegrator` restricted to Lambertian
//! surfaces, perfect and glossy (Phong) mirrors and smooth glass). It shares only the scene,
//! the BVH code and the Fresnel and Phong-lobe formulas ([`super::optics`], tested on their
//! own) with the radiosity path.
//!
//! Light at a camera-ray hit is `Le + ρ/π ∫ L cosθ dω` plus the specular part. Emitters are
//! sampled by power (area × channel sum of `Ke`), uniformly by area on the chosen face; light
//! found by BSDF sampling after a diffuse bounce is not counted (it was counted by NEE), so
//! each path is counted once. NEE cannot find a light through a mirror or glass (a shadow ray
//! is blocked by them; a delta lobe has zero probability of being sampled towards a point), so
//! emission reached by a specular bounce is counted when hit: at a surface with both parts one
//! lobe is chosen by its weight, and the next hit's `Ke` counts only after the specular lobe.
//! A glossy lobe is sampled the same way (its direction drawn from the lobe, no NEE: noisy
//! highlights of small lights, unbiased).
//! Glass picks reflection with the Fresnel probability, refraction otherwise (weight 1).
//! Caustics (light through glass or off a mirror onto a diffuse surface) are found only by
//! BSDF sampling and are noisy. Suns and point lights ([`crate::scene::lights`]) are
//! found by NEE only (one shadow ray each per vertex; a delta light cannot be hit); the sky
//! only when a ray leaves the model after a diffuse bounce (a camera ray that leaves it sees
//! the black background, as in the radiosity passes). Error: zero bias, noise ∝ 1/√spp.

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::{Image, RenderSettings, optics, pixel_samples};
use crate::geometry::bvh::TriangleInput;
use crate::geometry::sampling::{cosine_hemisphere, hash_seed, triangle_point};
use crate::geometry::{Bvh, Ray, Rng, polygon};
use crate::scene::{Rgb, Scene, Surface};

struct LightTri {
    vertices: [DVec3; 3],
    normal: DVec3,
    area: f64,
    emission: Rgb,
}

/// A lit first hit ([`PathTracer::first_lit_face`]).
#[derive(Clone, Copy, Debug)]
pub struct LitHit {
    /// The input face.
    pub face: usize,
    /// The point.
    pub x: DVec3,
}

/// The scene prepared for path tracing.
pub struct PathTracer<'a> {
    scene: &'a Scene,
    bvh: Bvh,
    /// Per BVH triangle id: (face index, unit normal).
    tri_face: Vec<(usize, DVec3)>,
    lights: Vec<LightTri>,
    light_cdf: Vec<f64>,
    epsilon: f64,
    /// The scene's suns and point lights, and its sky's radiance.
    punctual: Vec<crate::scene::Light>,
    /// The opaque faces alone and a pane's transmittance, when the scene has glass: a
    /// shadow ray to a sun or point light that only glass stops carries the transmittance,
    /// as in the solve ([`crate::formfactor::lights::GlassVisibility`]).
    windows: Option<(Bvh, f64)>,
    sky: Rgb,
    /// Whether light may pass a mirror or glass after a diffuse bounce (see
    /// [`PathTracer::without_caustics`]).
    caustics: bool,
}

impl<'a> PathTracer<'a> {
    pub fn new(scene: &'a Scene) -> Self {
        let mut input = Vec::new();
        let mut tri_face = Vec::new();
        let mut lights = Vec::new();
        for (fi, f) in scene.faces.iter().enumerate() {
            let Some(n) = polygon::normal(&f.vertices) else {
                continue;
            };
            let m = &scene.materials[f.material.0 as usize];
            for t in polygon::triangulate(&f.vertices) {
                let v = [f.vertices[t[0]], f.vertices[t[1]], f.vertices[t[2]]];
                input.push(TriangleInput {
                    vertices: v,
                    id: tri_face.len() as u32,
                    cull_back: false,
                    cut: None,
                });
                tri_face.push((fi, n));
                if m.is_emitter() {
                    lights.push(LightTri {
                        vertices: v,
                        normal: n,
                        area: polygon::area(&v),
                        emission: m.emission,
                    });
                }
            }
        }
        let mut acc = 0.0;
        let mut light_cdf: Vec<f64> = lights
            .iter()
            .map(|l| {
                acc += l.area * (l.emission.x + l.emission.y + l.emission.z);
                acc
            })
            .collect();
        if acc > 0.0 {
            light_cdf.iter_mut().for_each(|c| *c /= acc);
        }
        let epsilon = 1e-6 * scene.bounds().diagonal().max(1e-12);
        // Cut-outs are holes for every path's rays, as for the solve's.
        let cuts = scene.cutouts();
        cuts.mark(scene, &mut input, |i| tri_face[i].0);
        let glass_of =
            |i: &usize| match scene.materials[scene.faces[*i].material.0 as usize].surface {
                Surface::Glass { ior } => Some(ior),
                _ => None,
            };
        let windows = tri_face.iter().find_map(|(fi, _)| glass_of(fi)).map(|ior| {
            let opaque: Vec<TriangleInput> = input
                .iter()
                .zip(&tri_face)
                .filter(|(_, (fi, _))| glass_of(fi).is_none())
                .map(|(t, _)| *t)
                .collect();
            (
                cuts.bvh(&opaque),
                crate::formfactor::lights::slab_transmittance(ior),
            )
        });
        PathTracer {
            scene,
            bvh: cuts.bvh(&input),
            windows,
            tri_face,
            lights,
            light_cdf,
            epsilon,
            punctual: crate::scene::lights::punctual(&scene.lights),
            sky: crate::scene::lights::sky_radiance(&scene.lights),
            caustics: true,
        }
    }

    /// The light transport the radiosity + eye-pass hybrid computes: after the first diffuse
    /// bounce, glass absorbs and a mirror reflects only its `Kd` part (as in the radiosity
    /// solve), so no caustic is found. A reference for the hybrid's own error, the caustics
    /// set aside.
    pub fn without_caustics(mut self) -> Self {
        self.caustics = false;
        self
    }

    /// Radiance along a camera ray.
    pub fn radiance(&self, ray: &Ray, rng: &mut Rng) -> Rgb {
        let mut throughput = Rgb::ONE;
        let mut result = Rgb::ZERO;
        let mut ray = *ray;
        let two_sided = self.scene.two_sided;
        // The camera, or a specular bounce: the next hit's emission is not found by NEE.
        let mut count_emission = true;
        // Whether a diffuse bounce came before: only then does a ray that leaves see the sky.
        let mut bounced = false;
        for depth in 0..10_000 {
            let Some(hit) = self.bvh.closest_hit(&ray, 0.0, f64::INFINITY) else {
                if bounced {
                    result += throughput * self.sky;
                }
                break;
            };
            let (face, geometric) = self.tri_face[hit.id as usize];
            let m = &self.scene.materials[self.scene.faces[face].material.0 as usize];
            let x = ray.at(hit.t);
            // ρ(x) = Kd · texel(x) where the material has a diffuse texture.
            let rho = match self.scene.texel(face, x) {
                Some((texel, _)) => m.reflectance * texel,
                None => m.reflectance,
            };
            let d = ray.dir.try_normalize().unwrap_or(DVec3::Z);
            // After a diffuse bounce, without caustics: glass absorbs, a mirror is its Kd.
            let diffuse_only = !self.caustics && !count_emission;
            if diffuse_only && matches!(m.surface, Surface::Glass { .. }) {
                break;
            }
            if let Surface::Glass { ior } = m.surface {
                // Both sides of glass are live: inside is the back.
                let i = optics::dielectric(d, geometric, hit.front, ior);
                ray = match i.refracted {
                    Some(t) if rng.next_f64() >= i.reflectance => {
                        Ray::new(x - i.facing * self.epsilon, t)
                    }
                    _ => Ray::new(x + i.facing * self.epsilon, i.reflected),
                };
                count_emission = true;
                if depth >= 64 {
                    break; // a ray trapped by total internal reflection
                }
                continue;
            }
            let mut n = geometric;
            if !hit.front {
                if !two_sided {
                    break; // the unlit back of a one-sided face absorbs
                }
                n = -n;
            }
            if count_emission {
                result += throughput * m.emission;
            }
            // Next-event estimation.
            result += throughput * rho * self.direct(x, n, rng);
            let specular_lobe = match m.surface {
                Surface::Mirror { ks } => Some((ks, None)),
                Surface::Glossy { ks, exponent } => Some((ks, Some(exponent))),
                _ => None,
            };
            if let Some((ks, exponent)) = specular_lobe
                && !diffuse_only
            {
                // One lobe, chosen by its weight.
                let (wd, ws) = (rho.max_element(), ks.max_element());
                if rng.next_f64() * (wd + ws) < ws {
                    let mirror = optics::reflect(d, n);
                    let dir = match exponent {
                        None => mirror,
                        Some(e) => {
                            let (u1, u2) = (rng.next_f64(), rng.next_f64());
                            match optics::phong_lobe(mirror, n, e, u1, u2) {
                                Some(dir) => dir,
                                None => break, // below the surface: the lobe's lost part
                            }
                        }
                    };
                    throughput *= ks * ((wd + ws) / ws);
                    if throughput.max_element() <= 0.0 || depth >= 64 {
                        break;
                    }
                    count_emission = true;
                    ray = Ray::new(x + n * self.epsilon, dir);
                    continue;
                }
                if wd <= 0.0 {
                    break;
                }
                throughput *= (wd + ws) / wd;
            }
            count_emission = false;
            bounced = true;
            // Continue.
            throughput *= rho;
            if depth >= 3 {
                let q = throughput.max_element().min(0.95);
                if q <= 0.0 || rng.next_f64() >= q {
                    break;
                }
                throughput /= q;
            }
            if throughput.max_element() <= 0.0 {
                break;
            }
            let dir = cosine_hemisphere(n, rng.next_f64(), rng.next_f64());
            ray = Ray::new(x + n * self.epsilon, dir);
        }
        debug_assert!(result.is_finite());
        result
    }

    /// Whether a camera ray's first hit is a light or the lit front of a surface (direct
    /// light from one of `samples` light samples arrives): the score of a candidate view.
    pub fn first_hit_is_lit(&self, ray: &Ray, samples: u32, rng: &mut Rng) -> bool {
        self.first_lit_face(ray, samples, rng).is_some()
    }

    /// The ray's first hit when that point is lit
    /// ([`first_hit_is_lit`](Self::first_hit_is_lit)): the input face it lies on and the
    /// point.
    pub fn first_lit_face(&self, ray: &Ray, samples: u32, rng: &mut Rng) -> Option<LitHit> {
        let hit = self.bvh.closest_hit(ray, 0.0, f64::INFINITY)?;
        let (face, mut n) = self.tri_face[hit.id as usize];
        if !hit.front {
            if !self.scene.two_sided {
                return None;
            }
            n = -n;
        }
        let x = ray.at(hit.t);
        let lit = LitHit { face, x };
        if self.scene.materials[self.scene.faces[face].material.0 as usize].is_emitter() {
            return Some(lit);
        }
        (0..samples)
            .any(|_| {
                let d = cosine_hemisphere(n, rng.next_f64(), rng.next_f64());
                let sky = self.sky.max_element() > 0.0
                    && self
                        .bvh
                        .closest_hit(&Ray::new(x + n * self.epsilon, d), 0.0, f64::INFINITY)
                        .is_none();
                sky || self.direct(x, n, rng).max_element() > 0.0
            })
            .then_some(lit)
    }

    /// Direct irradiance term `(1/π) ∫ Le cosθ dω` at `x` (to be multiplied by ρ): one
    /// sample of the emitting faces, and every sun and point light.
    fn direct(&self, x: DVec3, n: DVec3, rng: &mut Rng) -> Rgb {
        self.punctual_direct(x, n, rng) + self.face_direct(x, n, rng)
    }

    /// The suns' and point lights' part of [`PathTracer::direct`].
    fn punctual_direct(&self, x: DVec3, n: DVec3, rng: &mut Rng) -> Rgb {
        if self.punctual.is_empty() {
            return Rgb::ZERO;
        }
        let origin = x + n * self.epsilon;
        let u = (rng.next_f64(), rng.next_f64());
        crate::scene::lights::punctual_incident(&self.punctual, x, n, u, &|d, t| {
            let ray = Ray::new(origin, d);
            if !self.bvh.any_hit(&ray, 1e-9, t) {
                return 1.0;
            }
            match &self.windows {
                Some((opaque, transmittance)) if !opaque.any_hit(&ray, 1e-9, t) => *transmittance,
                _ => 0.0,
            }
        })
    }

    /// One light sample of the emitting faces, chosen by power.
    fn face_direct(&self, x: DVec3, n: DVec3, rng: &mut Rng) -> Rgb {
        if self.lights.is_empty() {
            return Rgb::ZERO;
        }
        let u = rng.next_f64();
        let k = self
            .light_cdf
            .partition_point(|c| *c <= u)
            .min(self.lights.len() - 1);
        let pk = self.light_cdf[k] - if k == 0 { 0.0 } else { self.light_cdf[k - 1] };
        let l = &self.lights[k];
        let [a, b, c] = l.vertices;
        let y = triangle_point(a, b, c, rng.next_f64(), rng.next_f64());
        let d = y - x;
        let r2 = d.length_squared();
        if r2 <= 0.0 || pk <= 0.0 {
            return Rgb::ZERO;
        }
        let r = r2.sqrt();
        let w = d / r;
        let cos_x = n.dot(w);
        let mut cos_y = -l.normal.dot(w);
        if self.scene.two_sided {
            cos_y = cos_y.abs();
        }
        if cos_x <= 0.0 || cos_y <= 0.0 {
            return Rgb::ZERO;
        }
        let origin = x + n * self.epsilon;
        let target = y + l.normal * self.epsilon * if -l.normal.dot(w) > 0.0 { 1.0 } else { -1.0 };
        if self
            .bvh
            .any_hit(&Ray::new(origin, target - origin), 1e-9, 1.0 - 1e-9)
        {
            return Rgb::ZERO;
        }
        let pdf_area = pk / l.area;
        l.emission * (cos_x * cos_y / (std::f64::consts::PI * r2 * pdf_area))
    }
}

/// Renders a reference image with `settings.spp` paths per pixel (all cores).
/// `progress` is called with the number of finished rows.
pub fn reference(
    scene: &Scene,
    settings: &RenderSettings,
    progress: &(dyn Fn(usize) + Sync),
) -> Image {
    PathTracer::new(scene).render(settings, progress)
}

impl PathTracer<'_> {
    /// Renders an image with `settings.spp` paths per pixel (all cores), as [`reference()`].
    pub fn render(&self, settings: &RenderSettings, progress: &(dyn Fn(usize) + Sync)) -> Image {
        let pt = self;
        let (w, h) = (settings.width, settings.height);
        let cam = settings.camera;
        let mut img = Image::new(w, h);
        let done = AtomicUsize::new(0);
        img.pixels
            .par_chunks_mut(w as usize)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, px) in row.iter_mut().enumerate() {
                    let mut rng =
                        Rng::new(hash_seed(&[settings.seed, x as u64, y as u64, 0x9a7]), 3);
                    let mut sum = Rgb::ZERO;
                    pixel_samples(x as u32, y as u32, settings.spp, settings.seed, |sx, sy| {
                        let ray = Ray::new(cam.eye, cam.ray_dir(sx, sy, w, h));
                        sum += pt.radiance(&ray, &mut rng);
                    });
                    *px = sum / settings.spp.max(1) as f64;
                }
                progress(done.fetch_add(1, Ordering::Relaxed) + 1);
            });
        img
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LoadOptions;

    #[test]
    fn furnace_path_tracer_returns_e_over_one_minus_rho() {
        for rho in [0.5, 0.8] {
            let scene = Scene::builtin(
                "furnace",
                &LoadOptions {
                    rho: Some(rho),
                    ..Default::default()
                },
            )
            .expect("furnace");
            let pt = PathTracer::new(&scene);
            let mut rng = Rng::new(11, 0);
            let n = 20_000;
            let mut sum = 0.0;
            let mut sum2 = 0.0;
            for i in 0..n {
                // Rays from inside the cube in many directions.
                let dir = crate::geometry::sampling::cosine_hemisphere(
                    if i % 2 == 0 { DVec3::Z } else { DVec3::NEG_Y },
                    rng.next_f64(),
                    rng.next_f64(),
                );
                let l = pt.radiance(&Ray::new(DVec3::splat(0.5), dir), &mut rng).x;
                sum += l;
                sum2 += l * l;
            }
            let mean = sum / n as f64;
            let sd = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
            let exact = 1.0 / (1.0 - rho);
            assert!(
                (mean - exact).abs() < 4.0 * sd + 1e-9,
                "rho {rho}: {mean} ± {sd} vs {exact}"
            );
            assert!(
                sd < 0.02 * exact,
                "noise too large to make the test meaningful"
            );
        }
    }
}
