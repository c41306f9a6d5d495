//! Images of a solution from a camera, and an independent reference.
//!
//! [`render_solution`] casts `spp` stratified rays per pixel (box filter over the pixel) and
//! shades the first hit with the radiance interpolated from the mesh's display vertices;
//! emitters show their radiosity (`Ke` plus what they reflect). Every pass sees through
//! mirrors and glass ([`specular`]) when the scene has them. [`pathtrace::reference`] is an unbiased diffuse path tracer on
//! the same scene for measuring the image error (pbrt-v4's `--mse-reference-image` idea).

pub mod direct;
pub mod gather;
pub mod image;
pub mod optics;
pub mod pass;
pub mod pathtrace;
pub mod specular;
pub mod view;

pub use self::image::{Image, relative_rms};
pub use self::pass::Pass;
pub use crate::scene::Camera;

use glam::DVec3;
use rayon::prelude::*;

use crate::geometry::sampling::hash_seed;
use crate::geometry::{Bvh, Ray, Rng};
use crate::mesh::Mesh;
use crate::scene::{Rgb, Scene};

#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub camera: Camera,
    pub seed: u64,
    /// Extra stratified samples in each pixel whose first `spp` samples disagree by more
    /// than [`EDGE_CONTRAST`] of their mean: silhouettes, shadow and contact edges, where a
    /// pixel's value is the share of it each side covers and 16 samples estimate that share
    /// to about 1/8 of the contrast. 0: none. The path tracer and the final gather ignore it
    /// (their noisy samples always disagree).
    pub edge_spp: u32,
}

/// Edge samples (the `render` default of [`RenderSettings::edge_spp`]): on the Cornell
/// box at 16 spp about one pixel in ten is an edge, and 64 more there cost about a third of
/// the image's time while removing most of its stratification error (`docs/BENCHMARKS.md`).
pub const DEFAULT_EDGE_SPP: u32 = 64;

/// Spread of a pixel's first samples' luminance (max − min), relative to their mean, above
/// which the pixel gets [`RenderSettings::edge_spp`] more samples.
pub const EDGE_CONTRAST: f64 = 0.1;

/// Shading data for a solution: the mesh, per-vertex radiance and the BVH to find hits.
pub struct SolutionView<'a> {
    pub scene: &'a Scene,
    pub mesh: &'a Mesh,
    pub vertex_radiance: &'a [Rgb],
    pub bvh: &'a Bvh,
    /// Per element, the mean of its diffuse texture ([`crate::solver::Problem::element_texture`]);
    /// empty: untextured display.
    pub texture: &'a [Rgb],
}

impl SolutionView<'_> {
    /// The texel's colour at point `x` of element `e`, what the interpolated values
    /// of a textured view ([`per_unit_texture`]) are multiplied by to show the texture
    /// under the computed light, `E + ρ(x) H(x)` with `ρ(x) = Kd · texel(x)`. `None` where
    /// untextured.
    pub fn texel(&self, e: usize, x: glam::DVec3) -> Option<Rgb> {
        self.texture.get(e)?;
        let (texel, _alpha) = self.scene.texel(self.mesh.elements[e].face as usize, x)?;
        Some(texel).filter(|t| t.is_finite())
    }

    /// The vertex radiance interpolated at a hit on display triangle `triangle`. The hit's
    /// barycentrics can fall a rounding outside the triangle (`u + v` a few ulps above 1);
    /// they are clamped to it, so the value stays a convex mix of its vertices' (never
    /// below zero where they are not).
    pub fn interpolated(&self, triangle: u32, u: f64, v: f64) -> Rgb {
        let tri = self.mesh.triangles[triangle as usize];
        let [a, b, c] = tri.map(|i| self.vertex_radiance[i as usize]);
        let (u, v) = (u.max(0.0), v.max(0.0));
        a * (1.0 - u - v).max(0.0) + b * u + c * v
    }
}

/// A texture mean below which a channel is taken as black (left undivided).
const MEAN_FLOOR: f64 = 1e-9;

/// Per element, the value to interpolate across a textured mesh: `E + (B − E) / t̄`, the
/// reflected light per unit of texture (`t̄` the texture's mean over the element, what the
/// solver multiplied `Kd` by), so that a pixel shows `E + (V(x) − E) · texel(x)`
/// ([`SolutionView::texel`]) with `V` interpolated smoothly from these values.
/// Interpolating `B` instead and dividing by each element's own mean makes the ratio jump
/// at every element edge: a block pattern where the texture's mean varies between
/// elements. Untextured elements (and `texture` empty) keep `B`, and so does a channel
/// whose mean is black (there `B = E`, whatever the texel).
pub fn per_unit_texture(scene: &Scene, mesh: &Mesh, texture: &[Rgb], radiance: &[Rgb]) -> Vec<Rgb> {
    if texture.is_empty() {
        return radiance.to_vec();
    }
    let divide = |b: f64, e: f64, m: f64| if m > MEAN_FLOOR { e + (b - e) / m } else { b };
    radiance
        .iter()
        .zip(&mesh.elements)
        .zip(texture)
        .map(|((b, el), m)| {
            let emission = scene.materials[mesh.patch(el.patch).material.0 as usize].emission;
            Rgb::new(
                divide(b.x, emission.x, m.x),
                divide(b.y, emission.y, m.y),
                divide(b.z, emission.z, m.z),
            )
        })
        .collect()
}

/// BVH over the mesh's display triangles (ids = display triangle index).
pub fn display_bvh(scene: &Scene, mesh: &Mesh) -> Bvh {
    mesh.display_bvh(scene, scene.two_sided)
}

/// What a camera ray sees first.
enum FirstHit {
    Background,
    Emitter(Rgb),
    Surface(Rgb),
}

fn shade(view: &SolutionView, ray: &Ray) -> FirstHit {
    let Some(hit) = view.bvh.closest_hit(ray, 0.0, f64::INFINITY) else {
        return FirstHit::Background;
    };
    let element = view.mesh.triangle_element[hit.id as usize];
    let patch = view
        .mesh
        .patch(view.mesh.elements[element.0 as usize].patch);
    let material = &view.scene.materials[patch.material.0 as usize];
    if !hit.front && !view.scene.two_sided {
        return FirstHit::Surface(Rgb::ZERO); // the unlit back of a one-sided face
    }
    let mut radiance = view.interpolated(hit.id, hit.u, hit.v);
    if let Some(texel) = view.texel(element.0 as usize, ray.at(hit.t)) {
        radiance = material.emission + (radiance - material.emission) * texel;
    }
    if material.is_emitter() {
        // An emitter that also reflects shows its radiosity `E + ρH` (its display group
        // holds faces of its own material only, so nothing else is interpolated into it);
        // a black one exactly its `Ke`.
        if material.reflectance == Rgb::ZERO {
            return FirstHit::Emitter(material.emission);
        }
        return FirstHit::Emitter(radiance);
    }
    FirstHit::Surface(radiance)
}

/// Pixel samples: an `m × m` jittered grid over the pixel (m² ≥ spp, m = ⌈√spp⌉).
pub(crate) fn pixel_samples(x: u32, y: u32, spp: u32, seed: u64, mut f: impl FnMut(f64, f64)) {
    let m = ((spp.max(1) as f64).sqrt().ceil() as u32).max(1);
    let mut rng = Rng::new(hash_seed(&[seed, x as u64, y as u64]), 7);
    for k in 0..spp.max(1) {
        let (a, b) = (k % m, (k / m) % m);
        let jx = (a as f64 + rng.next_f64()) / m as f64;
        let jy = (b as f64 + rng.next_f64()) / m as f64;
        f(x as f64 + jx, y as f64 + jy);
    }
}

/// Renders a solution (see module docs): `spp` stratified rays per pixel, each shaded with
/// the radiance interpolated from the mesh's display vertices.
///
/// A 1 × 1 floor (ρ = 0.5) under a 0.5 × 0.5 light (`Ke` = 10) at height 1, after the
/// light's one shot: the floor's radiosity is `ρ Ke F(x)`, largest at the centre, where
/// `F` is four corner rectangles of Howell's B-3 (see [`point_to_polygon`]). The brightest
/// pixel, seen from above at an angle, is that peak lowered only by the vertex
/// interpolation of element centroids (`h/√2` = 0.044 off the centre) and the pixel's
/// footprint (about 0.1 across): `F` falls about `2r²` there, so within 5 %.
///
/// [`point_to_polygon`]: crate::formfactor::contour::point_to_polygon
///
/// ```
/// use std::sync::atomic::AtomicBool;
///
/// use glam::DVec3;
/// use nusselt_core::mesh::MeshSpec;
/// use nusselt_core::render::{self, Camera, RenderSettings, SolutionView};
/// use nusselt_core::scene::{LoadOptions, Scene};
/// use nusselt_core::solver::{ProgressiveSolver, SolverConfig};
///
/// let obj = "mtllib room.mtl
/// v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1
/// v 0.25 1 0.25\nv 0.75 1 0.25\nv 0.75 1 0.75\nv 0.25 1 0.75
/// usemtl floor\nf 1 4 3 2
/// usemtl light\nf 5 6 7 8\n";
/// let mtl = "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 10 10 10\n";
/// let scene = Scene::from_obj_str("room.obj", obj, &[("room.mtl", mtl)], &LoadOptions::default())?;
/// // Patches of 0.5: the light is one shooter.
/// let config = SolverConfig { mesh: MeshSpec::sized(0.0625, 0.5), ..Default::default() };
/// let mut solver = ProgressiveSolver::new(scene, config)?;
/// solver.shoot(&AtomicBool::new(false)).expect("the light shoots");
///
/// let vertex = solver.mesh().vertex_values(solver.radiosity());
/// let bvh = render::display_bvh(solver.scene(), solver.mesh());
/// let view = SolutionView {
///     scene: solver.scene(),
///     mesh: solver.mesh(),
///     vertex_radiance: &vertex,
///     bvh: &bvh,
///     texture: &[],
/// };
/// let camera = Camera {
///     eye: DVec3::new(0.5, 1.5, 2.0),
///     target: DVec3::new(0.5, 0.0, 0.5),
///     vfov_deg: 40.0,
/// };
/// let settings = RenderSettings { width: 16, height: 16, spp: 4, camera, seed: 1, edge_spp: 0 };
/// let image = render::render_solution(&view, &settings);
/// let brightest = image.pixels.iter().map(|p| p.x).fold(0.0, f64::max);
///
/// let corner = |a: f64, b: f64| {
///     let (sa, sb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
///     (a / sa * (b / sa).atan() + b / sb * (a / sb).atan()) / (2.0 * std::f64::consts::PI)
/// };
/// let peak = 0.5 * 10.0 * 4.0 * corner(0.25, 0.25);
/// assert!(brightest <= peak && brightest > 0.95 * peak, "{brightest} vs {peak}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn render_solution(view: &SolutionView, settings: &RenderSettings) -> Image {
    specular::render_pixels(view, settings, 0, |ray, _| match shade(view, ray) {
        FirstHit::Background => Rgb::ZERO,
        FirstHit::Emitter(e) | FirstHit::Surface(e) => e,
    })
}

/// The seed of a pixel's second (edge) sample grid.
pub(crate) fn edge_seed(seed: u64) -> u64 {
    hash_seed(&[seed, 0xed9e])
}

/// Every pixel the mean of `shade` over its camera samples ([`pixel_samples`]), plus
/// edge samples where the first disagree ([`edge_samples`]); rows in parallel; `shade`
/// gets a generator seeded by the pixel and `tag` (one stream per pass).
pub(crate) fn render_pixels(
    settings: &RenderSettings,
    tag: u64,
    shade: impl Fn(&Ray, &mut Rng) -> Rgb + Sync,
) -> Image {
    let (w, h) = (settings.width, settings.height);
    let cam = settings.camera;
    // First pass: each pixel's sum, and whether its samples disagree.
    let first: Vec<(Rgb, bool, Rng)> = (0..(w as usize * h as usize))
        .into_par_iter()
        .with_min_len(w as usize)
        .map(|k| {
            let (x, y) = ((k % w as usize) as u32, (k / w as usize) as u32);
            let mut rng = Rng::new(hash_seed(&[settings.seed, x as u64, y as u64, tag]), 5);
            let mut sum = DVec3::ZERO;
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            pixel_samples(x, y, settings.spp, settings.seed, |sx, sy| {
                let ray = Ray::new(cam.eye, cam.ray_dir(sx, sy, w, h));
                let c = shade(&ray, &mut rng);
                let l = c.x + c.y + c.z;
                (lo, hi) = (lo.min(l), hi.max(l));
                sum += c;
            });
            let mean = (sum.x + sum.y + sum.z) / settings.spp.max(1) as f64;
            (sum, hi - lo > EDGE_CONTRAST * mean, rng)
        })
        .collect();
    let edges = first.iter().filter(|p| p.1).count();
    let extra = edge_samples(settings, edges);
    let edge_seed = edge_seed(settings.seed);
    let pixels = first
        .into_par_iter()
        .enumerate()
        .with_min_len(w as usize)
        .map(|(k, (mut sum, edge, mut rng))| {
            let mut count = settings.spp.max(1);
            if edge && extra > 0 {
                // A second jittered grid: both are unbiased estimates of the pixel's
                // box-filtered integral, so their samples average together.
                let (x, y) = ((k % w as usize) as u32, (k / w as usize) as u32);
                pixel_samples(x, y, extra, edge_seed, |sx, sy| {
                    let ray = Ray::new(cam.eye, cam.ray_dir(sx, sy, w, h));
                    sum += shade(&ray, &mut rng);
                });
                count += extra;
            }
            sum / count as f64
        })
        .collect();
    Image {
        width: w,
        height: h,
        pixels,
    }
}

/// Edge samples per disagreeing pixel: [`RenderSettings::edge_spp`], but together no more
/// than the first pass's samples, so edge sampling at most doubles a pass's time. On the
/// Cornell box one pixel in ten is an edge and gets all 64; on a textured or finely detailed
/// model most pixels disagree (the atrium: 80 samples a pixel, 4.2 s instead of 0.9 s at
/// 256²) and each gets fewer, the same number for all (a count fixed by the image, not by
/// time, so the same command gives the same image).
fn edge_samples(settings: &RenderSettings, edges: usize) -> u32 {
    if edges == 0 {
        return 0;
    }
    let budget = settings.spp.max(1) as usize * settings.width as usize * settings.height as usize;
    settings.edge_spp.min((budget / edges) as u32)
}

/// Pixels that count for the image error: no ray of an 8×8 grid over the pixel or over its
/// eight neighbours hits the background or a light source. The one-pixel margin keeps out
/// pixels that a light covers by a sliver too thin for the grid, whose value would be
/// dominated by the light's radiance.
pub fn error_mask(scene: &Scene, camera: &Camera, width: u32, height: u32) -> Vec<bool> {
    // The scene's own faces, not a mesh: the mask is the same whatever the mesh of the
    // image (`render --reference` and `compare` agree to the pixel).
    let mut triangles = Vec::new();
    for (k, f) in scene.faces.iter().enumerate() {
        for t in crate::geometry::polygon::triangulate(&f.vertices) {
            triangles.push(crate::geometry::bvh::TriangleInput {
                vertices: [f.vertices[t[0]], f.vertices[t[1]], f.vertices[t[2]]],
                id: k as u32,
                cull_back: false,
                cut: None,
            });
        }
    }
    let bvh = Bvh::build(&triangles);
    let (w, h) = (width as usize, height as usize);
    let mut surface_only = vec![false; w * h];
    surface_only
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, m) in row.iter_mut().enumerate() {
                *m = (0..64).all(|k| {
                    let sx = x as f64 + ((k % 8) as f64 + 0.5) / 8.0;
                    let sy = y as f64 + ((k / 8) as f64 + 0.5) / 8.0;
                    let ray = Ray::new(camera.eye, camera.ray_dir(sx, sy, width, height));
                    bvh.closest_hit(&ray, 0.0, f64::INFINITY)
                        .is_some_and(|hit| {
                            let face = &scene.faces[hit.id as usize];
                            !scene.materials[face.material.0 as usize].is_emitter()
                        })
                });
            }
        });
    let mut mask = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            mask[y * w + x] = (y.saturating_sub(1)..(y + 2).min(h)).all(|yy| {
                (x.saturating_sub(1)..(x + 2).min(w)).all(|xx| surface_only[yy * w + xx])
            });
        }
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight edge (1 on one side, 0 on the other) through a 64² image: where a pixel's
    /// first 16 samples agree it gets no more and keeps its value; where the edge crosses
    /// it, the 64 edge samples must bring the coverage error down as stratified sampling
    /// predicts. For an m × m jittered grid only the ~m strata the edge cuts are random,
    /// each with variance ≤ 1/(4m⁴), so the error is at most 0.5·m^-1.5: 0.0625 for 16
    /// samples, and for 16 + 64 averaged by count (weights 1/5 and 4/5)
    /// √((0.0625/5)² + (0.8 · 0.5 · 8^-1.5)²) = 0.037. The exact coverage comes from a
    /// 256 × 256 grid of the same rays (over the pixels whose first samples disagree).
    #[test]
    fn edge_samples_cut_the_coverage_error_of_edge_pixels() {
        let camera = Camera {
            eye: DVec3::ZERO,
            target: DVec3::NEG_Z,
            vfov_deg: 40.0,
        };
        let inside = |d: DVec3| d.x / -d.z > 0.31 * (d.y / -d.z) + 0.011;
        let shade = |ray: &Ray, _: &mut Rng| {
            if inside(ray.dir) {
                DVec3::ONE
            } else {
                DVec3::ZERO
            }
        };
        let (w, h) = (64u32, 64u32);
        let base = RenderSettings {
            width: w,
            height: h,
            spp: 16,
            camera,
            seed: 3,
            edge_spp: 0,
        };
        let plain = render_pixels(&base, 0, shade);
        let edged = render_pixels(
            &RenderSettings {
                edge_spp: 64,
                ..base
            },
            0,
            shade,
        );
        let (mut plain_sq, mut edged_sq, mut n) = (0.0, 0.0, 0);
        for y in 0..h {
            for x in 0..w {
                let k = (y * w + x) as usize;
                let (p, e) = (plain.pixels[k].x, edged.pixels[k].x);
                if p == 0.0 || p == 1.0 {
                    assert_eq!(e, p, "pixel ({x}, {y}): its samples agreed");
                    continue;
                }
                const GRID: u32 = 256;
                let covered = (0..GRID * GRID)
                    .filter(|&g| {
                        let sx = x as f64 + ((g % GRID) as f64 + 0.5) / GRID as f64;
                        let sy = y as f64 + ((g / GRID) as f64 + 0.5) / GRID as f64;
                        inside(camera.ray_dir(sx, sy, w, h))
                    })
                    .count() as f64
                    / (GRID * GRID) as f64;
                if covered > 0.05 && covered < 0.95 {
                    plain_sq += (p - covered).powi(2);
                    edged_sq += (e - covered).powi(2);
                    n += 1;
                }
            }
        }
        assert!(n >= 40, "the edge crosses {n} pixels");
        let (plain_rms, edged_rms) = ((plain_sq / n as f64).sqrt(), (edged_sq / n as f64).sqrt());
        assert!(
            edged_rms <= 0.037 && edged_rms < 0.6 * plain_rms,
            "coverage error over {n} edge pixels: {edged_rms:.4} with edge samples, \
             {plain_rms:.4} without"
        );
    }
}
