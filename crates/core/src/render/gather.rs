//! The second pass's final gather (`render --pass gather`): at every visible point the
//! lights' direct part per pixel ([`super::direct`]) and one bounce gathered from the
//! radiosity solution by cosine-weighted rays, `L = E + ρ (D + (1/N) Σ_k B'(x_k))`, where
//! `x_k` is what the k-th ray hits and `B' = B − E` the solution's reflected radiosity there
//! (the emitted part is the direct term's), interpolated over the mesh.
//!
//! Why: the solution's error (constant elements, a shadow smeared over an element) shows
//! directly in the vertex pass; seen through one more bounce it is averaged over the
//! hemisphere, so what remains is the solution's mean error over what the point sees plus
//! the gather's noise, `σ/√N` with `N` rays per pixel (Reichert 1992; Lischinski, Smits &
//! Greenberg 1994 use the same split). A furnace is exact: every ray sees the same `B'`.

use crate::geometry::sampling::cosine_hemisphere;
use crate::geometry::{Ray, Rng};
use crate::scene::Rgb;

use super::direct::DirectLight;
use super::{Image, RenderSettings, SolutionView};

/// Gather rays per pixel, shared among its camera samples.
pub const GATHER_RAYS_PER_PIXEL: u32 = 64;

/// The final-gather pass of `radiance` per element (a solution of `problem`).
pub fn render_solution(
    problem: &crate::solver::Problem,
    radiance: &[Rgb],
    settings: &RenderSettings,
    rays_per_pixel: u32,
) -> Image {
    // Only the faces' own emission is the direct term's; the sky's, suns' and points' first
    // bounce off a surface is reflected light that the gather rays see.
    let reflected: Vec<Rgb> = radiance
        .iter()
        .zip(&problem.mesh.elements)
        .map(|(b, e)| (*b - problem.material_of(e.patch).emission).max(Rgb::ZERO))
        .collect();
    let sky = crate::scene::lights::sky_radiance(&problem.scene.lights);
    let vertex = problem.mesh.vertex_values(&reflected);
    let bvh = super::display_bvh(&problem.scene, &problem.mesh);
    let view = SolutionView {
        scene: &problem.scene,
        mesh: &problem.mesh,
        vertex_radiance: &vertex,
        bvh: &bvh,
        texture: problem.element_texture(),
    };
    let lights = DirectLight::new(problem);
    let per_sample = (rays_per_pixel / settings.spp.max(1)).max(1);
    // No edge samples: a few gather rays per sample make every pixel's samples disagree,
    // and the contrast test would send each pixel `edge_spp` more.
    let settings = &RenderSettings {
        edge_spp: 0,
        ..*settings
    };
    super::specular::render_pixels(&view, settings, 0x9a, |ray, rng| {
        shade(&view, &lights, ray, per_sample, problem.epsilon, sky, rng)
    })
}

/// The reflected radiosity `B'` the ray sees (zero for the unlit back of a one-sided face,
/// the sky's radiance for nothing).
fn seen(view: &SolutionView, ray: &Ray, sky: Rgb) -> Rgb {
    let Some(hit) = view.bvh.closest_hit(ray, 0.0, f64::INFINITY) else {
        return sky;
    };
    if !hit.front && !view.scene.two_sided {
        return Rgb::ZERO;
    }
    view.interpolated(hit.id, hit.u, hit.v)
}

fn shade(
    view: &SolutionView,
    lights: &DirectLight,
    ray: &Ray,
    rays: u32,
    epsilon: f64,
    sky: Rgb,
    rng: &mut Rng,
) -> Rgb {
    let Some(hit) = view.bvh.closest_hit(ray, 0.0, f64::INFINITY) else {
        return Rgb::ZERO;
    };
    if !hit.front && !view.scene.two_sided {
        return Rgb::ZERO;
    }
    let element = &view.mesh.elements[view.mesh.triangle_element[hit.id as usize].0 as usize];
    let patch = view.mesh.patch(element.patch);
    let material = &view.scene.materials[patch.material.0 as usize];
    let n = if hit.front {
        element.normal
    } else {
        -element.normal
    };
    let p = ray.at(hit.t);
    let direct = lights.incident(p, n, patch.occluder, rng);
    // Stratified over an m × m grid of the unit square.
    let m = ((rays as f64).sqrt().ceil() as u32).max(1);
    let mut gathered = Rgb::ZERO;
    for k in 0..rays {
        let (a, b) = (k % m, (k / m) % m);
        let u1 = (a as f64 + rng.next_f64()) / m as f64;
        let u2 = (b as f64 + rng.next_f64()) / m as f64;
        let d = cosine_hemisphere(n, u1.min(1.0 - 1e-12), u2);
        gathered += seen(view, &Ray::new(p + n * epsilon, d), sky);
    }
    let e = view.mesh.triangle_element[hit.id as usize].0 as usize;
    let rho = match view.texel(e, p) {
        Some(texel) => material.reflectance * texel,
        None => material.reflectance,
    };
    material.emission + rho * (direct + gathered / rays as f64)
}

#[cfg(test)]
mod tests {

    use super::*;
    use crate::scene::{LoadOptions, Scene};
    use crate::solver::{Problem, SolverConfig, SolverKind, solve_to};

    /// In a furnace (a closed box, every face emitting 1 with reflectance ρ) every point's
    /// radiance is `1/(1 − ρ)`: the direct term is `E` (the whole box), every gather ray
    /// sees `B' = ρ/(1 − ρ)`, so `E + ρ (E + B')` is exact whatever the rays' directions;
    /// what is left is the solve's residual (1e-6). A missing ρ, the emission counted
    /// twice, or a ray escaping through the surface it starts on moves it by 10 % or more.
    /// The interpolated and the direct pass must show the same: every face is a light
    /// that also reflects, and showing only its `Ke` (as both once did) gives 1, not 2.5.
    #[test]
    fn a_furnace_renders_its_exact_radiance_in_every_pass() {
        let rho = 0.6;
        let opts = LoadOptions {
            rho: Some(rho),
            ..LoadOptions::default()
        };
        let scene = Scene::builtin("furnace", &opts).expect("furnace");
        let camera = crate::render::view::default_camera(&scene);
        let problem = Problem::new(scene, SolverConfig::default()).expect("problem");
        let mut solver = SolverKind::Shooting.build(problem).expect("solver");
        solve_to(solver.as_mut(), 1e-6);
        let settings = RenderSettings {
            width: 12,
            height: 12,
            spp: 2,
            camera,
            seed: 3,
            edge_spp: 0,
        };
        let radiance = solver.radiosity().to_vec();
        let problem = solver.problem();
        let vertex = problem.mesh.vertex_values(&radiance);
        let bvh = crate::render::display_bvh(&problem.scene, &problem.mesh);
        let view = SolutionView {
            scene: &problem.scene,
            mesh: &problem.mesh,
            vertex_radiance: &vertex,
            bvh: &bvh,
            texture: &[],
        };
        // 16 samples, so that the direct pass shares a plane through its quadrants.
        let sixteen = RenderSettings {
            spp: 16,
            ..settings
        };
        let images = [
            ("gather", render_solution(problem, &radiance, &settings, 8)),
            ("vertex", crate::render::render_solution(&view, &settings)),
            (
                "direct",
                crate::render::direct::render_solution(problem, &radiance, &sixteen),
            ),
        ];
        let want = 1.0 / (1.0 - rho);
        for (pass, image) in &images {
            for p in &image.pixels {
                assert!(
                    (p.x - want).abs() < 2e-3 * want,
                    "{pass}: pixel {} against {want}",
                    p.x
                );
            }
        }
    }
}
