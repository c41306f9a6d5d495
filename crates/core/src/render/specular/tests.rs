//! Tests of the specular eye pass against exact cases and the path tracer.

use glam::DVec3;

use super::*;
use crate::mesh::MeshSpec;
use crate::render::pathtrace::PathTracer;
use crate::render::{Camera, direct, display_bvh};
use crate::scene::{LoadOptions, Scene};
use crate::solver::{Problem, SolverConfig, SolverKind, solve_to};

/// OBJ faces of the box `lo`–`hi` seen from outside, its vertices numbered from `first`.
fn cuboid(lo: DVec3, hi: DVec3, first: usize) -> String {
    let (a, b) = (lo, hi);
    let mut s = String::new();
    for (x, y, z) in [
        (a.x, a.y, a.z),
        (b.x, a.y, a.z),
        (b.x, b.y, a.z),
        (a.x, b.y, a.z),
        (a.x, a.y, b.z),
        (b.x, a.y, b.z),
        (b.x, b.y, b.z),
        (a.x, b.y, b.z),
    ] {
        s += &format!("v {x} {y} {z}\n");
    }
    for f in [
        [1, 2, 6, 5],
        [4, 8, 7, 3],
        [1, 4, 3, 2],
        [5, 6, 7, 8],
        [1, 5, 8, 4],
        [2, 3, 7, 6],
    ] {
        s += &format!("f {}\n", f.map(|k| (k + first - 1).to_string()).join(" "));
    }
    s
}

/// A shooting solve to a residual of 1e-6: the problem and its element radiance.
fn solve(scene: Scene, element_size: f64) -> (Problem, Vec<Rgb>) {
    let config = SolverConfig {
        mesh: MeshSpec::sized(element_size, element_size),
        ..Default::default()
    };
    let mut solver = SolverKind::Shooting
        .build(Problem::new(scene, config).expect("problem"))
        .expect("solver");
    solve_to(solver.as_mut(), 1e-6);
    let radiance = solver.radiosity().to_vec();
    (solver.into_parts().0, radiance)
}

/// The vertex pass (`render --pass vertex`) of a solution.
fn vertex_image(problem: &Problem, radiance: &[Rgb], settings: &RenderSettings) -> Image {
    crate::render::Pass::Vertex.render(problem, radiance, settings, 0)
}

/// `side`² pixels, 4 spp, seed 2, no edge samples, from the Cornell box's camera.
fn from_the_cornell_camera(side: u32) -> RenderSettings {
    RenderSettings {
        width: side,
        height: side,
        spp: 4,
        camera: Camera::cornell(),
        seed: 2,
        edge_spp: 0,
    }
}

/// `side`² pixels, 4 spp, from the middle of the unit gap between the wall (z = 0) and the
/// mirror (z = 1), looking at the mirror with a 30° field: every ray meets the mirror.
fn facing_the_mirror(side: u32) -> RenderSettings {
    RenderSettings {
        width: side,
        height: side,
        spp: 4,
        camera: Camera {
            eye: DVec3::new(0.5, 0.5, 0.5),
            target: DVec3::new(0.5, 0.5, 1.0),
            vfov_deg: 30.0,
        },
        seed: 5,
        edge_spp: 0,
    }
}

/// An emitting wall (z = 0, facing +z, `Ke` = 2) and a mirror facing it (z = 1), seen
/// from between them: every camera ray reflects onto the wall, so every pixel is exactly
/// `Kd·B_mirror + Ks·Ke`. With `Kd` = 0 that is `Ks·Ke` in both the hybrid and the path
/// tracer (no sampling at all); with `Kd` = 0.2 the mirror's diffuse part is the direct
/// light from the wall, exact per pixel in the direct pass and sampled by the path
/// tracer's lobe choice and NEE, so the two image means agree within the path tracer's
/// 4σ (no caustic: the wall reflects nothing).
#[test]
fn a_mirror_shows_ks_times_what_it_reflects() {
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl wall\nf 1 2 3 4\n\
        v 0 0 1\nv 0 1 1\nv 1 1 1\nv 1 0 1\nusemtl mirror\nf 5 6 7 8\n";
    let settings = facing_the_mirror(12);
    for kd in [0.0, 0.2] {
        let mtl = format!(
            "newmtl wall\nKd 0 0 0\nKe 2 2 2\nnewmtl mirror\nKd {kd} {kd} {kd}\nKs 0.7 0.7 0.7\nillum 3\n"
        );
        let scene = Scene::from_obj_str("m.obj", obj, &[("m.mtl", &mtl)], &LoadOptions::default())
            .expect("scene");
        let (problem, radiance) = solve(scene.clone(), 0.25);
        let hybrid = direct::render_solution(&problem, &radiance, &settings);
        let pt = PathTracer::new(&scene);
        let mut rng = Rng::new(9, 1);
        let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0);
        for y in 0..settings.height {
            for x in 0..settings.width {
                for k in 0..64 {
                    let (sx, sy) = (
                        x as f64 + (k % 8) as f64 / 8.0,
                        y as f64 + (k / 8) as f64 / 8.0,
                    );
                    let ray =
                        Ray::new(settings.camera.eye, settings.camera.ray_dir(sx, sy, 12, 12));
                    let l = pt.radiance(&ray, &mut rng).x;
                    sum += l;
                    sum2 += l * l;
                    n += 1;
                }
            }
        }
        let pt_mean = sum / n as f64;
        let sd = ((sum2 / n as f64 - pt_mean * pt_mean).max(0.0) / n as f64).sqrt();
        let hybrid_mean =
            hybrid.pixels.iter().map(|p| p.x).sum::<f64>() / hybrid.pixels.len() as f64;
        if kd == 0.0 {
            for p in &hybrid.pixels {
                assert!(
                    (p.x - 1.4).abs() < 1e-9,
                    "hybrid pixel {} against 0.7 × 2",
                    p.x
                );
            }
            assert!(
                (pt_mean - 1.4).abs() < 1e-9,
                "path tracer {pt_mean} against 1.4"
            );
        } else {
            // The diffuse part alone is Kd·Ke·F ≈ 0.2 · 2 · 0.4: a lost or doubled lobe
            // moves the mean by 0.1 or more.
            assert!(
                hybrid_mean > 1.4 + 0.05,
                "the mirror's own diffuse part is missing"
            );
            assert!(
                (hybrid_mean - pt_mean).abs() < 4.0 * sd + 1e-3,
                "hybrid {hybrid_mean} against path tracer {pt_mean} ± {sd}"
            );
        }
    }
}

/// A glossy mirror (`Kd` 0, `Ks` 0.7, `Ns` 20) facing an emitting wall (`Ke` 2) 40 times
/// wider than their distance, seen from between them within 15° of its normal: a lobe
/// ray misses the wall or falls below the mirror only beyond 72° from the mirror ray,
/// where the lobe holds cos²¹72° ≈ 2e-11 of its directions. So every pixel is exactly
/// `Ks·Ke` = 1.4 in the hybrid and in the path tracer, whatever the samples: a lost or
/// doubled `Ks`, or a lobe weighted like the modified Phong BRDF (`cos θ`), breaks it.
#[test]
fn a_glossy_mirror_shows_ks_times_a_wall_filling_its_lobe() {
    let obj = "mtllib m.mtl\nv -20 -20 0\nv 21 -20 0\nv 21 21 0\nv -20 21 0\n\
        usemtl wall\nf 1 2 3 4\n\
        v 0 0 1\nv 0 1 1\nv 1 1 1\nv 1 0 1\nusemtl glossy\nf 5 6 7 8\n";
    let mtl = "newmtl wall\nKd 0 0 0\nKe 2 2 2\n\
        newmtl glossy\nKd 0 0 0\nKs 0.7 0.7 0.7\nNs 20\nillum 3\n";
    let scene = Scene::from_obj_str("g.obj", obj, &[("m.mtl", mtl)], &LoadOptions::default())
        .expect("scene");
    assert!(matches!(
        scene.materials[1].surface,
        Surface::Glossy { exponent, .. } if exponent == 20.0
    ));
    let settings = facing_the_mirror(8);
    let (problem, radiance) = solve(scene.clone(), 4.0);
    let hybrid = direct::render_solution(&problem, &radiance, &settings);
    for p in &hybrid.pixels {
        assert!(
            (p.x - 1.4).abs() < 1e-9,
            "hybrid pixel {} against 0.7 × 2",
            p.x
        );
    }
    let pt = PathTracer::new(&scene);
    let mut rng = Rng::new(9, 1);
    for k in 0..256 {
        let (sx, sy) = ((k % 16) as f64 / 2.0, (k / 16) as f64 / 2.0);
        let ray = Ray::new(settings.camera.eye, settings.camera.ray_dir(sx, sy, 8, 8));
        let l = pt.radiance(&ray, &mut rng).x;
        assert!((l - 1.4).abs() < 1e-9, "path tracer {l} against 1.4");
    }
}

/// The Cornell box with a slab of glass of index 1 in front of its open side.
fn cornell_with_slab() -> Scene {
    let base_obj = include_str!("../../../../../assets/cornell.obj");
    let vertices = base_obj.lines().filter(|l| l.starts_with("v ")).count();
    let slab = cuboid(
        DVec3::new(-100.0, -100.0, -300.0),
        DVec3::new(700.0, 700.0, -250.0),
        vertices + 1,
    );
    let obj = format!("{base_obj}\nusemtl slab\n{slab}");
    let mtl = format!(
        "{}\nnewmtl slab\nKd 0 0 0\nNi 1\nillum 7\n",
        include_str!("../../../../../assets/cornell.mtl")
    );
    let opts = LoadOptions::default();
    Scene::from_obj_str("cornell.obj", &obj, &[("cornell.mtl", &mtl)], &opts).expect("slab")
}

/// Seen through a glass slab of index 1 (no reflection, no bending) every camera ray
/// lands where it lands without the slab, with weight exactly 1: the eye pass, with a
/// "pass" that returns the point it is asked to shade, gives the same points as the
/// plain Cornell box's camera rays, up to the rays' offsets (1e-6 of the scene, twice).
#[test]
fn a_glass_slab_of_index_one_is_invisible() {
    let plain = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let slab = cornell_with_slab();
    assert!(slab.has_specular() && !plain.has_specular());
    let settings = from_the_cornell_camera(24);
    let points = |scene: &Scene| -> Image {
        let mesh = crate::mesh::Mesh::build(scene, &MeshSpec::element(140.0)).expect("mesh");
        let bvh = display_bvh(scene, &mesh);
        let zero = vec![Rgb::ZERO; mesh.vertices.len()];
        let view = SolutionView {
            scene,
            mesh: &mesh,
            vertex_radiance: &zero,
            bvh: &bvh,
            texture: &[],
        };
        let landed = |ray: &Ray, _: &mut Rng| {
            bvh.closest_hit(ray, 0.0, f64::INFINITY)
                .map_or(Rgb::splat(-1.0), |h| ray.at(h.t))
        };
        render_pixels(&view, &settings, 0, landed)
    };
    let (a, b) = (points(&plain), points(&slab));
    for (x, y) in a.pixels.iter().zip(&b.pixels) {
        assert!(
            (*x - *y).length() < 0.01,
            "{x} without the slab, {y} through it"
        );
    }
}

/// The path tracer through the same slab: every camera path crosses it twice, so the
/// image equals the plain box's within the sampling error (4σ of the image mean, 256
/// paths per pixel): a transmission weight other than 1, a bent ray, or the first
/// diffuse hit's NEE dropped after a specular bounce moves the mean by tens of percent.
#[test]
fn the_path_tracer_sees_through_a_slab_of_index_one() {
    let plain = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let slab = cornell_with_slab();
    let camera = Camera::cornell();
    let stats = |scene: &Scene| {
        let pt = PathTracer::new(scene);
        let mut rng = Rng::new(3, 4);
        let (mut sum, mut sum2, mut n) = (0.0, 0.0, 0.0);
        // Rows below the light, whose own pixels would dominate the noise.
        for y in 4..16 {
            for x in 0..16 {
                for k in 0..256 {
                    let sx = x as f64 + ((k % 16) as f64 + 0.5) / 16.0;
                    let sy = y as f64 + ((k / 16) as f64 + 0.5) / 16.0;
                    let ray = Ray::new(camera.eye, camera.ray_dir(sx, sy, 16, 16));
                    let l = pt.radiance(&ray, &mut rng).element_sum();
                    sum += l;
                    sum2 += l * l;
                    n += 1.0;
                }
            }
        }
        let mean = sum / n;
        (mean, ((sum2 / n - mean * mean).max(0.0) / n).sqrt())
    };
    let ((m0, s0), (m1, s1)) = (stats(&plain), stats(&slab));
    let sd = (s0 * s0 + s1 * s1).sqrt();
    assert!(
        (m0 - m1).abs() < 4.0 * sd,
        "{m0} ± {s0} without, {m1} ± {s1} through"
    );
    assert!(sd < 0.03 * m0, "too noisy to mean anything: {sd} of {m0}");
}

/// `scene` against the path tracer without caustics (the same transport:
/// [`PathTracer::without_caustics`]), over the pixels whose centre sees a specular
/// surface: the means agree within the path tracer's 4σ (256 paths per pixel) plus 5 %,
/// the direct pass's own error on this coarse mesh (2 % at the default mesh in `nusselt
/// bench --only specular`).
fn assert_hybrid_matches_the_path_tracer_without_caustics(scene: Scene) {
    let (problem, radiance) = solve(scene.clone(), 70.0);
    let (w, h) = (16, 16);
    let settings = RenderSettings {
        width: w,
        height: h,
        spp: 16,
        camera: Camera::cornell(),
        seed: 4,
        edge_spp: 0,
    };
    let hybrid = direct::render_solution(&problem, &radiance, &settings);
    let pt = PathTracer::new(&scene).without_caustics();
    let bvh = display_bvh(&problem.scene, &problem.mesh);
    let camera = settings.camera;
    let mut rng = Rng::new(8, 2);
    let (mut h_sum, mut sum, mut sum2, mut n, mut pixels) = (0.0, 0.0, 0.0, 0.0, 0);
    for y in 0..h {
        for x in 0..w {
            let centre = Ray::new(
                camera.eye,
                camera.ray_dir(x as f64 + 0.5, y as f64 + 0.5, w, h),
            );
            let Some(hit) = bvh.closest_hit(&centre, 0.0, f64::INFINITY) else {
                continue;
            };
            let e = problem.mesh.triangle_element[hit.id as usize];
            let patch = problem
                .mesh
                .patch(problem.mesh.elements[e.0 as usize].patch);
            if !problem.scene.materials[patch.material.0 as usize].is_specular() {
                continue;
            }
            pixels += 1;
            h_sum += hybrid.pixels[(y * w + x) as usize].element_sum();
            for k in 0..256 {
                let sx = x as f64 + ((k % 16) as f64 + rng.next_f64()) / 16.0;
                let sy = y as f64 + ((k / 16) as f64 + rng.next_f64()) / 16.0;
                let ray = Ray::new(camera.eye, camera.ray_dir(sx, sy, w, h));
                let l = pt.radiance(&ray, &mut rng).element_sum();
                sum += l;
                sum2 += l * l;
                n += 1.0;
            }
        }
    }
    assert!(
        pixels >= 10,
        "only {pixels} pixels see the mirror or the glass"
    );
    let mean = sum / n;
    let sd = ((sum2 / n - mean * mean).max(0.0) / n).sqrt();
    let hybrid_mean = h_sum / pixels as f64;
    assert!(
        (hybrid_mean - mean).abs() < 4.0 * sd + 0.05 * mean,
        "hybrid {hybrid_mean} against the path tracer {mean} ± {sd} over {pixels} pixels"
    );
}

/// `cornell-specular` (a mirror block, a glass block): a lost reflection or refraction
/// moves the mean by half or more; a caustic counted would show in the path tracer, not
/// here.
#[test]
fn the_hybrid_matches_the_path_tracer_without_caustics() {
    let scene = Scene::builtin("cornell-specular", &LoadOptions::default()).expect("scene");
    assert_hybrid_matches_the_path_tracer_without_caustics(scene);
}

/// `cornell-specular` with its mirror made glossy (`Ns` 20: a lobe about 20° wide): the
/// hybrid's lobe sampling against the path tracer's, through the whole scene (the lobe
/// itself is checked against quadrature in `optics`, its weight by
/// `a_glossy_mirror_shows_ks_times_a_wall_filling_its_lobe`).
#[test]
fn a_glossy_mirror_matches_the_path_tracer_without_caustics() {
    let mut scene = Scene::builtin("cornell-specular", &LoadOptions::default()).expect("scene");
    let mut glossy = 0;
    for m in &mut scene.materials {
        if let Surface::Mirror { ks } = m.surface {
            m.surface = Surface::Glossy { ks, exponent: 20.0 };
            glossy += 1;
        }
    }
    assert_eq!(glossy, 1);
    assert_hybrid_matches_the_path_tracer_without_caustics(scene);
}

/// A glossy lobe of exponent 10⁶ (about 0.1° wide) shows what the perfect mirror shows:
/// its rays leave within 3.7e-3 rad of the mirror ray (u ≥ 1e-6), moving the reflected
/// point by a few millimetres on 140-mm elements, so the vertex pass through it is the
/// mirror's within 1 % wherever the reflection is smooth: the image means within 0.5 %,
/// and 80 % of the pixels that see the mirror within 1 % (the rest straddle an edge of
/// what the mirror reflects, or see the glass block in it, whose Fresnel choices draw
/// from the random stream the lobe also draws from). A lobe about the normal, or the
/// modified Phong BRDF's `cos θ` weight, changes most of them by 10 % or more.
#[test]
fn a_narrow_glossy_lobe_is_the_mirror() {
    let mirror = Scene::builtin("cornell-specular", &LoadOptions::default()).expect("scene");
    let mut narrow = mirror.clone();
    for m in &mut narrow.materials {
        if let Surface::Mirror { ks } = m.surface {
            m.surface = Surface::Glossy { ks, exponent: 1e6 };
        }
    }
    let settings = from_the_cornell_camera(24);
    let (problem, radiance) = solve(mirror, 140.0);
    let a = vertex_image(&problem, &radiance, &settings);
    let mut problem = problem;
    problem.scene = narrow;
    let b = vertex_image(&problem, &radiance, &settings);
    let mean = |i: &Image| i.pixels.iter().map(|p| p.element_sum()).sum::<f64>();
    let (ma, mb) = (mean(&a), mean(&b));
    assert!((ma - mb).abs() < 5e-3 * ma, "means {ma} and {mb}");
    // The pixels that see the mirror: any lobe sample moves them a little.
    let touched: Vec<(f64, f64)> = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(p, q)| p != q)
        .map(|(p, q)| (p.element_sum(), q.element_sum()))
        .collect();
    let close = touched
        .iter()
        .filter(|(p, q)| (p - q).abs() <= 1e-2 * p)
        .count();
    assert!(
        touched.len() >= 20,
        "only {} pixels see the mirror",
        touched.len()
    );
    assert!(
        close * 5 >= touched.len() * 4,
        "{close} of the mirror's {} pixels agree",
        touched.len()
    );
}

/// On a scene without mirrors or glass the eye pass is the pass itself, pixel for
/// pixel: the hybrid called directly on the Cornell box gives the same image, bit for
/// bit, as the vertex pass.
#[test]
fn diffuse_scenes_render_exactly_as_before() {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let (problem, radiance) = solve(scene, 140.0);
    let vertex = problem.mesh.vertex_values(&radiance);
    let bvh = display_bvh(&problem.scene, &problem.mesh);
    let view = SolutionView {
        scene: &problem.scene,
        mesh: &problem.mesh,
        vertex_radiance: &vertex,
        bvh: &bvh,
        texture: &[],
    };
    let settings = from_the_cornell_camera(16);
    let before = vertex_image(&problem, &radiance, &settings);
    let hybrid = Hybrid::new(&view);
    let base = |ray: &Ray, _: &mut Rng| match super::super::shade(&view, ray) {
        super::super::FirstHit::Background => Rgb::ZERO,
        super::super::FirstHit::Emitter(e) | super::super::FirstHit::Surface(e) => e,
    };
    let after =
        super::super::render_pixels(&settings, 0, |ray, rng| hybrid.radiance(ray, rng, &base));
    assert_eq!(before.pixels, after.pixels);
}
