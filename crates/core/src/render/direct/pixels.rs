//! The direct pass's pixel loop: which samples get their own exact direct light, and
//! which share a plane through a pixel's quadrants (see [`render`]).

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use crate::geometry::sampling::hash_seed;
use crate::geometry::{Ray, Rng};
use crate::render::{EDGE_CONTRAST, Image, RenderSettings, SolutionView, pixel_samples};
use crate::scene::Rgb;

use super::DirectLight;

/// Renders with direct light per pixel: `view.vertex_radiance` must hold the indirect part
/// (the solution minus each element's direct share, see the `direct` module docs).
///
/// The exact direct light is the costly part of a sample, and inside most pixels it is
/// smooth; so a pixel whose camera samples all land on one surface (at 9 or more samples)
/// evaluates it at one sample per quadrant and one near the middle, and when the four
/// agree within `QUADRANTS_AGREE` and the plane through them meets the fifth within
/// `PLANE_MISS` of what the pixel shows, the plane's mean stands for the direct light
/// of every sample. Pixels that see several surfaces, or a shadow edge the four disagree
/// on, get the direct light of every sample, and those that see several surfaces the edge
/// samples of [`RenderSettings::edge_spp`]. Scenes with mirrors or glass take the plain
/// path (every sample, through [`crate::render::specular`]).
pub fn render(view: &SolutionView, lights: &DirectLight, settings: &RenderSettings) -> Image {
    if view.scene.has_specular() || settings.spp < 9 {
        return crate::render::specular::render_pixels(view, settings, PASS_TAG, |ray, rng| {
            shade(view, lights, ray, rng)
        });
    }
    let (w, h) = (settings.width, settings.height);
    let cam = settings.camera;
    let spp = settings.spp;
    let m = (spp as f64).sqrt().ceil() as u32;
    // One sample per quadrant of the pixel's m × m strata (`pixel_samples`' order).
    let quadrants: Vec<usize> = [(0, 0), (1, 0), (0, 1), (1, 1)]
        .iter()
        .map(|&(qa, qb)| ((qb * m / 2 + m / 4) * m + qa * m / 2 + m / 4) as usize)
        .filter(|&k| k < spp as usize)
        .collect();
    // And one near the middle that is none of them, to check the plane against.
    let middle = ((m / 2) * m + m / 2) as usize;
    let check = (middle < spp as usize && !quadrants.contains(&middle)).then_some(middle);
    let shared = quadrants.len() == 4 && check.is_some();
    let mut img = Image::new(w, h);
    img.pixels
        .par_chunks_mut(w as usize)
        .enumerate()
        .for_each(|(y, row)| {
            let mut seen = Vec::with_capacity(spp as usize);
            let mut at = Vec::with_capacity(spp as usize);
            let mut known = Vec::with_capacity(spp as usize);
            for (x, px) in row.iter_mut().enumerate() {
                let (x, y) = (x as u32, y as u32);
                let mut rng =
                    Rng::new(hash_seed(&[settings.seed, x as u64, y as u64, PASS_TAG]), 5);
                seen.clear();
                at.clear();
                pixel_samples(x, y, spp, settings.seed, |sx, sy| {
                    seen.push(see(view, &Ray::new(cam.eye, cam.ray_dir(sx, sy, w, h))));
                    at.push(DVec2::new(sx, sy));
                });
                let sample = Sampled {
                    seen: &seen,
                    at: &at,
                };
                known.clear();
                known.resize(seen.len(), None);
                let pixel = match check {
                    Some(check) if shared => {
                        shade_pixel(lights, sample, &quadrants, check, &mut known, &mut rng)
                    }
                    _ => None,
                };
                *px = pixel.unwrap_or_else(|| {
                    all_samples(view, lights, settings, (x, y), sample, &known, &mut rng)
                });
            }
        });
    img
}

/// Stream tag of the direct pass's generators.
const PASS_TAG: u64 = 0xd1;

/// What a camera sample sees, before its direct light.
#[derive(Clone, Copy)]
enum Seen {
    Nothing,
    Emitter(Rgb),
    Surface {
        p: DVec3,
        n: DVec3,
        own: u32,
        rho: Rgb,
        indirect: Rgb,
    },
}

impl Seen {
    fn with_direct(&self, lights: &DirectLight, rng: &mut Rng) -> Rgb {
        match *self {
            Seen::Surface { p, n, own, .. } => self.shown(lights.incident(p, n, own, rng)),
            _ => self.shown(Rgb::ZERO),
        }
    }

    /// The sample's radiance given the direct irradiance (over π) at its point.
    fn shown(&self, direct: Rgb) -> Rgb {
        match *self {
            Seen::Nothing => Rgb::ZERO,
            Seen::Emitter(e) => e,
            Seen::Surface { rho, indirect, .. } => indirect.max(Rgb::ZERO) + rho * direct,
        }
    }

    /// `(occluder group, normal)` of a surface sample.
    fn surface_key(&self) -> Option<(u32, DVec3)> {
        match *self {
            Seen::Surface { own, n, .. } => Some((own, n)),
            _ => None,
        }
    }
}

/// Largest spread of the four quadrants' reflected direct light (max − min of the
/// luminance, over the mean luminance they show with the indirect part) for which a plane through them stands for the pixel's direct light.
const QUADRANTS_AGREE: f64 = 0.05;

/// Largest miss of the plane at the check sample, over the mean luminance shown: a light
/// that bulges across the pixel (four equal corners around a dip) is caught here.
const PLANE_MISS: f64 = 0.002;

/// A pixel's camera samples: what each sees and where on the image.
#[derive(Clone, Copy)]
struct Sampled<'a> {
    seen: &'a [Seen],
    at: &'a [DVec2],
}

/// The pixel from its quadrants' direct light, or `None` when the samples see more than
/// one surface, the quadrants disagree or the plane through them misses the light at
/// `check` (see [`render`]). The four values (at image positions `at`) are fitted by a
/// plane in least squares, and its mean over all the samples' positions is the pixel's
/// direct light: exact where the light varies linearly across the pixel.
fn shade_pixel(
    lights: &DirectLight,
    Sampled { seen, at }: Sampled,
    quadrants: &[usize],
    check: usize,
    known: &mut [Option<Rgb>],
    rng: &mut Rng,
) -> Option<Rgb> {
    let first = seen.first().and_then(Seen::surface_key)?;
    let one_surface = seen
        .iter()
        .all(|s| s.surface_key().is_some_and(|k| same_surface(k, first)));
    if !one_surface || quadrants.len() < 4 {
        return None;
    }
    let mut values = [Rgb::ZERO; 4];
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut shown = 0.0;
    for (v, &k) in values.iter_mut().zip(quadrants) {
        let Seen::Surface {
            p,
            n,
            own,
            rho,
            indirect,
        } = seen[k]
        else {
            return None;
        };
        *v = lights.incident(p, n, own, rng);
        known[k] = Some(*v);
        let reflected = rho * *v;
        let l = reflected.x + reflected.y + reflected.z;
        (lo, hi) = (lo.min(l), hi.max(l));
        let total = indirect.max(Rgb::ZERO) + reflected;
        shown += (total.x + total.y + total.z) / 4.0;
    }
    // Relative to what the pixel shows: in an umbra the direct light may vary by half
    // while the indirect light it sits on is a hundred times brighter.
    if hi - lo > QUADRANTS_AGREE * shown {
        return None;
    }
    let mean = values.iter().fold(Rgb::ZERO, |a, v| a + *v) / 4.0;
    // Least-squares plane v = mean + g · (q − c) through the quadrants (c their centroid),
    // evaluated at the centroid of all samples.
    let c = quadrants.iter().fold(DVec2::ZERO, |a, &k| a + at[k]) / 4.0;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    let (mut sxv, mut syv) = (Rgb::ZERO, Rgb::ZERO);
    for (v, &k) in values.iter().zip(quadrants) {
        let d = at[k] - c;
        (sxx, sxy, syy) = (sxx + d.x * d.x, sxy + d.x * d.y, syy + d.y * d.y);
        sxv += *v * d.x;
        syv += *v * d.y;
    }
    let det = sxx * syy - sxy * sxy;
    if det <= 1e-12 {
        return None;
    }
    let gx = (sxv * syy - syv * sxy) / det;
    let gy = (syv * sxx - sxv * sxy) / det;
    let plane = |q: DVec2| mean + gx * (q.x - c.x) + gy * (q.y - c.y);
    let Seen::Surface { p, n, own, rho, .. } = seen[check] else {
        return None;
    };
    let at_check = lights.incident(p, n, own, rng);
    known[check] = Some(at_check);
    let miss = rho * (at_check - plane(at[check]));
    if (miss.x + miss.y + miss.z).abs() > PLANE_MISS * shown {
        return None;
    }
    let all = at.iter().fold(DVec2::ZERO, |a, q| a + *q) / at.len() as f64;
    let direct = plane(all);
    let sum = seen.iter().fold(Rgb::ZERO, |acc, s| match *s {
        Seen::Surface { rho, indirect, .. } => acc + indirect.max(Rgb::ZERO) + rho * direct,
        _ => acc,
    });
    Some(sum / seen.len() as f64)
}

/// The pixel with the direct light of every sample (`known`: those [`shade_pixel`] already
/// computed), plus the edge samples where the samples disagree (as
/// [`crate::render::render_pixels`] does).
fn all_samples(
    view: &SolutionView,
    lights: &DirectLight,
    settings: &RenderSettings,
    (x, y): (u32, u32),
    Sampled { seen, at }: Sampled,
    known: &[Option<Rgb>],
    rng: &mut Rng,
) -> Rgb {
    let mut sum = Rgb::ZERO;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut direct = Vec::with_capacity(seen.len());
    for (s, known) in seen.iter().zip(known) {
        let d = match (*s, known) {
            (_, Some(d)) => *d,
            (Seen::Surface { p, n, own, .. }, None) => lights.incident(p, n, own, rng),
            _ => Rgb::ZERO,
        };
        direct.push(d);
        let c = s.shown(d);
        let l = c.x + c.y + c.z;
        (lo, hi) = (lo.min(l), hi.max(l));
        sum += c;
    }
    let mut count = seen.len().max(1) as u32;
    let mean = (sum.x + sum.y + sum.z) / count as f64;
    // Edge samples where the samples see several surfaces (silhouettes, contacts): they
    // are for how much of the pixel each covers, and on a surface already sampled the
    // direct light of the nearest sample there serves (it varies little across a pixel on
    // one surface). A shadow edge within one surface gets none: its base samples each
    // have their exact direct light, and the soft penumbrae of area lights need no more
    // (on the Cornell box they left the error unchanged at 1.78 % and 0.99 % and cost
    // 0.6 s of 1.4).
    let surfaces = seen.iter().filter_map(Seen::surface_key).fold(
        Vec::new(),
        |mut keys: Vec<(u32, DVec3)>, k| {
            if !keys.iter().any(|&q| same_surface(q, k)) {
                keys.push(k);
            }
            keys
        },
    );
    let emitter = seen.iter().any(|s| matches!(s, Seen::Emitter(_)));
    let nothing = seen.iter().any(|s| matches!(s, Seen::Nothing));
    let several = surfaces.len() + usize::from(emitter) + usize::from(nothing) > 1;
    if settings.edge_spp > 0 && several && hi - lo > EDGE_CONTRAST * mean {
        let (w, h) = (settings.width, settings.height);
        let cam = settings.camera;
        let edge_seed = crate::render::edge_seed(settings.seed);
        pixel_samples(x, y, settings.edge_spp, edge_seed, |sx, sy| {
            let ray = Ray::new(cam.eye, cam.ray_dir(sx, sy, w, h));
            let s = see(view, &ray);
            let near = s.surface_key().and_then(|key| {
                (0..seen.len())
                    .filter(|&k| seen[k].surface_key().is_some_and(|q| same_surface(q, key)))
                    .min_by(|&a, &b| {
                        let q = DVec2::new(sx, sy);
                        (at[a] - q)
                            .length_squared()
                            .total_cmp(&(at[b] - q).length_squared())
                    })
            });
            sum += match near {
                Some(k) => s.shown(direct[k]),
                None => s.with_direct(lights, rng),
            };
        });
        count += settings.edge_spp;
    }
    sum / count as f64
}

/// Whether two samples' `(occluder group, normal)` are one surface.
fn same_surface(a: (u32, DVec3), b: (u32, DVec3)) -> bool {
    a.0 == b.0 && a.1.dot(b.1) > 0.999_999
}

fn see(view: &SolutionView, ray: &Ray) -> Seen {
    let Some(hit) = view.bvh.closest_hit(ray, 0.0, f64::INFINITY) else {
        return Seen::Nothing;
    };
    let element = &view.mesh.elements[view.mesh.triangle_element[hit.id as usize].0 as usize];
    let patch = view.mesh.patch(element.patch);
    let material = &view.scene.materials[patch.material.0 as usize];
    if !hit.front && !view.scene.two_sided {
        return Seen::Emitter(Rgb::ZERO); // the unlit back of a one-sided face
    }
    // An emitter that also reflects is shaded as a surface: its indirect part (the solution
    // minus its direct share) holds its emission.
    if material.is_emitter() && material.reflectance == Rgb::ZERO {
        return Seen::Emitter(material.emission);
    }
    let p = ray.at(hit.t);
    let mut indirect = view.interpolated(hit.id, hit.u, hit.v);
    let mut rho = material.reflectance;
    let e = view.mesh.triangle_element[hit.id as usize].0 as usize;
    if let Some(texel) = view.texel(e, p) {
        // ρ(x) = Kd · texel(x); the reflected light, interpolated per unit of texture,
        // follows the texel too.
        rho *= texel;
        indirect = material.emission + (indirect - material.emission) * texel;
    }
    Seen::Surface {
        p,
        n: element.normal,
        own: patch.occluder,
        rho,
        indirect,
    }
}

fn shade(view: &SolutionView, lights: &DirectLight, ray: &Ray, rng: &mut Rng) -> Rgb {
    see(view, ray).with_direct(lights, rng)
}
