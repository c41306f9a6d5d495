//! The second pass's direct light (`render --pass direct`): at every visible point the
//! light sources' contribution is computed per pixel, and only the indirect rest is taken
//! from the radiosity solution.
//!
//! Constant elements smear a shadow edge over an element and miss the peak under a small
//! light; per pixel, the direct part is the exact point-to-polygon form factor of each
//! light ([`contour::point_to_polygon`]) where nothing blocks it; where up to 12 triangles
//! cut the point's pyramid to the light their shadows are clipped out of the light polygon
//! and the rest integrated exactly ([`exact::point_to_visible_polygon`], what the solver's
//! light rows do); behind more, the visible fraction is estimated by 16 shadow rays to
//! stratified points on the light weighted by the kernel `cos θ cos θ' / r²` (error 1/√n in
//! penumbrae only). The indirect part is the solution minus each
//! element's own direct share, `B_j − ρ_j Σ_l F_jl E_l`, with `F_jl` the solver's own
//! light rows (so what is subtracted is what the solve put in), interpolated over the mesh.
//! This is the "radiosity + ray tracing" split of the lecture (Wallace, Cohen & Greenberg
//! 1987; Shirley 1990 for direct light per pixel).
//!
//! [`contour::point_to_polygon`]: crate::formfactor::contour::point_to_polygon
//! [`exact::point_to_visible_polygon`]: crate::formfactor::exact::point_to_visible_polygon

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::DVec3;

use crate::formfactor::{self, FormFactorMethod, RowContext, exact};
use crate::geometry::bvh::{PACKET, ShadowRay};
use crate::geometry::sampling::triangle_point;
use crate::geometry::shaft::Shaft;
use crate::geometry::{Bvh, Ray, Rng, polygon};
use crate::mesh::PatchId;
use crate::scene::Rgb;

use super::{Image, RenderSettings, SolutionView};

mod many;
mod pixels;
pub use pixels::render;

/// Shadow rays per light per camera sample (stratified over the light), where too many
/// triangles cut the point's pyramid to the light for exact clipping.
const SHADOW_RAYS: usize = 16;
/// Most blocking triangles whose shadows are clipped out of the light exactly (as the
/// solver's light rows do, `FormFactorParams::exact_blockers`).
const EXACT_BLOCKERS: usize = 12;

/// One emitting face.
struct Light {
    polygon: Vec<DVec3>,
    normal: DVec3,
    emission: Rgb,
    /// Triangles and their cumulative areas, for sampling points.
    triangles: Vec<[DVec3; 3]>,
    cumulative: Vec<f64>,
    occluder: u32,
    convex: bool,
}

/// The scene's lights and the visibility structure of the solve.
pub struct DirectLight<'a> {
    /// Emitting faces evaluated one by one.
    lights: Vec<Light>,
    /// Connected emitting faces evaluated together ([`many`]).
    groups: Vec<many::FacetGroup>,
    /// The scene's suns and point lights, evaluated per pixel with one shadow ray each.
    punctual: Vec<crate::scene::Light>,
    /// Their light through windows, as the solve sees it.
    glass: &'a crate::formfactor::lights::GlassVisibility,
    /// The solver's blocker BVH (ids: occluder groups).
    blockers: &'a Bvh,
    epsilon: f64,
    /// Work done so far, in light evaluations ([`DirectLight::work`]).
    work: AtomicU64,
}

impl<'a> DirectLight<'a> {
    /// The emitting faces, suns and points of `problem`'s scene, seen through the solve's
    /// BVH ([`crate::solver::Problem::bvh`], ids `mesh.face_occluder`) and windows.
    pub fn new(problem: &'a crate::solver::Problem) -> Self {
        let (scene, mesh) = (&problem.scene, &problem.mesh);
        let emitting: Vec<usize> = (0..scene.faces.len())
            .filter(|&k| scene.materials[scene.faces[k].material.0 as usize].is_emitter())
            .collect();
        let faces: Vec<many::EmittingFace> = emitting
            .iter()
            .map(|&k| many::EmittingFace {
                vertices: &scene.faces[k].vertices,
                emission: scene.materials[scene.faces[k].material.0 as usize].emission,
                occluder: mesh.face_occluder[k],
            })
            .collect();
        let mut groups = Vec::new();
        let mut single = vec![false; scene.faces.len()];
        for members in many::group_faces(&faces) {
            if members.len() >= many::MANY_FACETS {
                let refs: Vec<&many::EmittingFace> = members.iter().map(|&i| &faces[i]).collect();
                groups.push(many::FacetGroup::new(&refs));
            } else {
                members.iter().for_each(|&i| single[emitting[i]] = true);
            }
        }
        let lights = scene
            .faces
            .iter()
            .enumerate()
            .filter_map(|(k, f)| {
                let m = &scene.materials[f.material.0 as usize];
                let normal = polygon::normal(&f.vertices)?;
                if !single[k] {
                    return None;
                }
                let triangles: Vec<[DVec3; 3]> = polygon::triangulate(&f.vertices)
                    .into_iter()
                    .map(|t| [f.vertices[t[0]], f.vertices[t[1]], f.vertices[t[2]]])
                    .collect();
                let mut total = 0.0;
                let cumulative = triangles
                    .iter()
                    .map(|t| {
                        total += polygon::area(t);
                        total
                    })
                    .collect();
                Some(Light {
                    polygon: f.vertices.clone(),
                    normal,
                    emission: m.emission,
                    triangles,
                    cumulative,
                    occluder: mesh.face_occluder[k],
                    convex: polygon::is_convex(&f.vertices),
                })
            })
            .collect();
        let punctual = crate::scene::lights::punctual(&scene.lights);
        let glass = if punctual.is_empty() {
            &crate::formfactor::lights::NO_GLASS
        } else {
            problem.glass()
        };
        Self {
            lights,
            groups,
            punctual,
            glass,
            blockers: &problem.bvh,
            epsilon: problem.epsilon,
            work: AtomicU64::new(0),
        }
    }

    /// The work of every [`DirectLight::incident`] so far, counted the same on any machine
    /// and under any load: per call, one unit per light's form factor, one per blocker
    /// clipped exactly, one per shadow ray (sampled lights, suns and points). A measure of
    /// time that is not a clock, so that `render --pass auto` chooses the same pass for
    /// the same input everywhere.
    pub fn work(&self) -> u64 {
        self.work.load(Ordering::Relaxed)
    }

    /// The suns' and point lights' part of [`DirectLight::incident`].
    fn punctual_incident(&self, p: DVec3, n: DVec3, own: u32, rng: &mut Rng) -> Rgb {
        if self.punctual.is_empty() {
            return Rgb::ZERO;
        }
        let origin = p + n * self.epsilon;
        let u = (rng.next_f64(), rng.next_f64());
        crate::scene::lights::punctual_incident(&self.punctual, p, n, u, &|d, t| {
            self.glass
                .visibility(self.blockers, &Ray::new(origin, d), t, [own, u32::MAX])
        })
    }

    /// `Σ_l E_l F(p → l) V_l` at a point `p` with normal `n` on a surface of occluder group
    /// `own`, plus the suns and point lights: the direct irradiance over π, what `ρ` turns
    /// into radiance. The sky is not in it (it stays in the interpolated solution).
    pub fn incident(&self, p: DVec3, n: DVec3, own: u32, rng: &mut Rng) -> Rgb {
        let mut work = self.punctual.len() as u64;
        let punctual = self.punctual_incident(p, n, own, rng);
        let sum = self.area_incident(punctual, p, n, own, rng, &mut work);
        self.work.fetch_add(work, Ordering::Relaxed);
        sum
    }

    /// `sum` plus the emitting faces' part of [`DirectLight::incident`], adding its work
    /// to `work`.
    fn area_incident(
        &self,
        mut sum: Rgb,
        p: DVec3,
        n: DVec3,
        own: u32,
        rng: &mut Rng,
        work: &mut u64,
    ) -> Rgb {
        let origin = p + n * self.epsilon;
        for l in &self.lights {
            *work += 1;
            let f = formfactor::contour::point_to_polygon_with_normal(p, n, &l.polygon, l.normal);
            if f <= 0.0 {
                continue;
            }
            if l.convex {
                let pyramid = Shaft::pyramid(origin, &l.polygon, self.epsilon);
                let mut cutting = Vec::new();
                let listed = self.blockers.collect_in_shaft(
                    &pyramid,
                    [own, l.occluder],
                    8 * EXACT_BLOCKERS,
                    &mut cutting,
                );
                if listed {
                    cutting
                        .retain(|&k| !pyramid.excludes_triangle(self.blockers.stored_triangle(k)));
                    if cutting.is_empty() {
                        sum += l.emission * f;
                        continue;
                    }
                    // A cut-out's holes are not in its triangle: its shadow is sampled.
                    if cutting.len() <= EXACT_BLOCKERS
                        && !cutting.iter().any(|&k| self.blockers.is_cut(k))
                    {
                        let blockers: Vec<Vec<DVec3>> = cutting
                            .iter()
                            .map(|&k| self.blockers.stored_triangle(k).to_vec())
                            .collect();
                        *work += blockers.len() as u64;
                        let visible =
                            exact::point_to_visible_polygon(origin, n, &l.polygon, &blockers);
                        sum += l.emission * visible.clamp(0.0, f);
                        continue;
                    }
                }
            }
            *work += SHADOW_RAYS as u64;
            let total = *l.cumulative.last().unwrap_or(&0.0);
            let mut all = 0.0;
            let mut samples = Vec::with_capacity(SHADOW_RAYS);
            let m = (SHADOW_RAYS as f64).sqrt().ceil() as usize;
            for k in 0..SHADOW_RAYS {
                let u = ((k % m) as f64 + rng.next_f64()) / m as f64;
                let v = ((k / m) as f64 + rng.next_f64()) / m as f64;
                let pick = u * total;
                let t = l
                    .cumulative
                    .partition_point(|&c| c < pick)
                    .min(l.triangles.len() - 1);
                let below = if t == 0 { 0.0 } else { l.cumulative[t - 1] };
                let span = (l.cumulative[t] - below).max(1e-300);
                let [a, b, c] = l.triangles[t];
                let y = triangle_point(a, b, c, ((pick - below) / span).clamp(0.0, 1.0), v);
                let d = y - origin;
                let r2 = d.length_squared();
                let cos_x = d.dot(n);
                let cos_y = -d.dot(l.normal);
                if r2 <= 0.0 || cos_x <= 0.0 || cos_y <= 0.0 {
                    continue;
                }
                let g = cos_x * cos_y / (r2 * r2);
                all += g;
                samples.push((
                    ShadowRay {
                        ray: Ray::new(origin, d),
                        ignore: [own, l.occluder],
                    },
                    g,
                ));
            }
            let seen = unblocked_weight(self.blockers, &samples);
            if all > 0.0 {
                sum += l.emission * (f * seen / all);
            }
        }
        let at = many::Receiver { p, n, origin, own };
        for g in &self.groups {
            sum += g.emission * g.visible_factor(&at, self.blockers, rng, work);
        }
        sum
    }
}

/// The summed weights of the shadow rays `samples` (ray, weight) that nothing in
/// `blockers` stops, in their order. The rays run from one point to one light, so they go
/// to the BVH four at a time ([`Bvh::any_hit_packet`]: each ray's answer is its own).
fn unblocked_weight(blockers: &Bvh, samples: &[(ShadowRay, f64)]) -> f64 {
    let mut seen = 0.0;
    for chunk in samples.chunks(PACKET) {
        let rays: [ShadowRay; PACKET] = std::array::from_fn(|k| chunk[k.min(chunk.len() - 1)].0);
        let hidden = blockers.any_hit_packet(&rays[..chunk.len()], 0.0, 1.0 - 1e-9);
        for (k, (_, g)) in chunk.iter().enumerate() {
            if hidden & (1 << k) == 0 {
                seen += g;
            }
        }
    }
    seen
}

/// Each element's direct share `Σ_l F_jl E_l` from the light patches' form-factor rows,
/// computed as the solver computes them (same method, parameters and seeds).
pub fn element_direct(ctx: &RowContext, method: FormFactorMethod) -> Vec<Rgb> {
    let mesh = ctx.mesh;
    let mut direct = vec![Rgb::ZERO; mesh.elements.len()];
    let never = AtomicBool::new(false);
    let mut row = vec![0f32; mesh.elements.len()];
    for (i, p) in mesh.patches.iter().enumerate() {
        let e = ctx.scene.materials[p.material.0 as usize].emission;
        if e == Rgb::ZERO {
            continue;
        }
        row.iter_mut().for_each(|f| *f = 0.0);
        formfactor::compute_row(method, ctx, PatchId(i as u32), &mut row, &never);
        for (d, f) in direct.iter_mut().zip(&row) {
            *d += e * *f as f64;
        }
    }
    direct
}

/// The indirect part of `radiance` per element (a solution of `problem`) at the mesh's
/// display vertices: each element's value minus its direct share `ρ_j Σ_l F_jl E_l`
/// ([`element_direct`]) and its share of the suns and point lights, what [`render`] adds
/// the per-pixel direct light to; per unit of texture where textured
/// ([`super::per_unit_texture`]).
pub fn indirect_vertex_radiance(problem: &crate::solver::Problem, radiance: &[Rgb]) -> Vec<Rgb> {
    let direct = element_direct(&problem.row_context(), problem.config.formfactor.method);
    let rho = problem.element_reflectance();
    let punctual = &problem.external.punctual;
    let indirect: Vec<Rgb> = radiance
        .iter()
        .zip(&direct)
        .zip(&rho)
        .enumerate()
        .map(|(k, ((b, d), r))| *b - *r * (*d + punctual.get(k).copied().unwrap_or(Rgb::ZERO)))
        .collect();
    let values = super::per_unit_texture(
        &problem.scene,
        &problem.mesh,
        problem.element_texture(),
        &indirect,
    );
    problem.mesh.vertex_values(&values)
}

/// The whole second pass: `radiance` per element (a solution of `problem`, with or without
/// its display correction) rendered with the lights' direct part per pixel.
pub fn render_solution(
    problem: &crate::solver::Problem,
    radiance: &[Rgb],
    settings: &RenderSettings,
) -> Image {
    Prepared::new(problem, radiance).render(settings)
}

/// What the direct pass computes once per solution (the indirect vertex radiance, the display
/// BVH, the lights), so that several images of one solution (a probe, then the image) pay
/// for it once.
pub struct Prepared<'a> {
    problem: &'a crate::solver::Problem,
    vertex: Vec<Rgb>,
    bvh: Bvh,
    lights: DirectLight<'a>,
}

impl<'a> Prepared<'a> {
    pub fn new(problem: &'a crate::solver::Problem, radiance: &[Rgb]) -> Self {
        Self {
            problem,
            vertex: indirect_vertex_radiance(problem, radiance),
            bvh: super::display_bvh(&problem.scene, &problem.mesh),
            lights: DirectLight::new(problem),
        }
    }

    /// The per-pixel work of every image rendered so far ([`DirectLight::work`]).
    pub fn work(&self) -> u64 {
        self.lights.work()
    }

    /// The image [`render_solution`] makes.
    pub fn render(&self, settings: &RenderSettings) -> Image {
        let view = SolutionView {
            scene: &self.problem.scene,
            mesh: &self.problem.mesh,
            vertex_radiance: &self.vertex,
            bvh: &self.bvh,
            texture: self.problem.element_texture(),
        };
        render(&view, &self.lights, settings)
    }
}
