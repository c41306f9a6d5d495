//! Textured surfaces: the solve sees each element's mean texture (so colour bleeding is that
//! of a flat surface of the mean colour), and the image shows the texel under the light.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use glam::DVec3;
use nusselt_core::render::{Camera, Pass, RenderSettings};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, StopCriteria};

/// A 16 × 16 checkerboard of 2 × 2 texels per cell (32 × 32 texels): `a` where the cell's
/// x + y is even (the top-left cell), `b` elsewhere, 8-bit sRGB. Two texels a cell leave a
/// plateau one texel wide in each cell's middle where bilinear filtering is the cell's colour.
fn write_checker(path: &Path, a: [u8; 3], b: [u8; 3]) {
    let img = image::RgbImage::from_fn(32, 32, |x, y| {
        image::Rgb(if (x / 2 + y / 2) % 2 == 0 { a } else { b })
    });
    img.save(path).expect("png");
}

/// A wall x, y ∈ [0, 1] at z = 0 facing +z (material `wall`, uv = (x, y)), a floor
/// x, z ∈ [0, 1] at y = 0 facing up (`floor`), and a light above the front of the floor.
fn scene(dir: &Path, wall_mtl: &str) -> Scene {
    let obj = "mtllib s.mtl\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl wall\nf 1/1 2/2 3/3 4/4\n\
        v 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0 0\nusemtl floor\nf 5 6 7 8\n\
        v 0 1 0.2\nv 1 1 0.2\nv 1 1 0.6\nv 0 1 0.6\nusemtl light\nf 9 10 11 12\n";
    let mtl =
        format!("{wall_mtl}\nnewmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 5 5 5\n");
    std::fs::write(dir.join("s.obj"), obj).expect("obj");
    std::fs::write(dir.join("s.mtl"), mtl).expect("mtl");
    Scene::load_obj(&dir.join("s.obj"), &LoadOptions::default()).expect("scene")
}

/// Converged with elements of 1/8: each holds 2 × 2 cells, so every element's texture mean
/// is the checkerboard's mean exactly.
fn solve(scene: Scene) -> ProgressiveSolver {
    let mut s = ProgressiveSolver::new(
        scene,
        SolverConfig {
            element_size: Some(0.125),
            patch_size: Some(0.125),
            ..Default::default()
        },
    )
    .expect("solver");
    let stop = StopCriteria {
        unshot: 1e-9,
        ..Default::default()
    };
    s.run(&stop, &AtomicBool::new(false), &mut |_| {});
    s
}

/// sRGB 188 is linear 0.5029 (the sRGB transfer function).
const SRGB_188: f64 = 0.502_886;

#[test]
fn a_textured_wall_bleeds_the_colour_of_its_mean() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_checker(&dir.path().join("c.png"), [188, 0, 0], [0, 0, 188]);
    let textured = solve(scene(
        dir.path(),
        "newmtl wall\nKd 0.8 0.8 0.8\nmap_Kd c.png",
    ));
    let mean = 0.8 * SRGB_188 / 2.0;
    let flat = solve(scene(
        dir.path(),
        &format!("newmtl wall\nKd {mean} 0 {mean}"),
    ));
    let (a, b) = (
        textured.element_radiance(false),
        flat.element_radiance(false),
    );
    assert_eq!(a.len(), b.len());
    let mut floor_red = 0.0;
    for ((x, y), e) in a.iter().zip(&b).zip(&textured.mesh().elements) {
        assert!(
            (*x - *y).abs().max_element() < 1e-6 * y.max_element().max(1e-3),
            "{x} vs {y}"
        );
        if e.normal.y > 0.5 {
            floor_red += x.x;
        }
    }
    assert!(floor_red > 0.0, "the floor sees red from the wall");
}

#[test]
fn the_image_shows_the_texel_under_the_computed_light() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_checker(&dir.path().join("c.png"), [255, 255, 255], [0, 0, 0]);
    let textured = solve(scene(
        dir.path(),
        "newmtl wall\nKd 0.8 0.8 0.8\nmap_Kd c.png",
    ));
    let flat = solve(scene(dir.path(), "newmtl wall\nKd 0.4 0.4 0.4"));
    // The wall fills the image: pixel (i, j) of 64 sees wall point (i/64, 1 − j/64), cell
    // (i/4, j/4) counted from the image's top-left; pixels 4k + 1 and 4k + 2 lie on the
    // cell's bilinear plateau.
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp: 4,
        camera: Camera {
            eye: DVec3::new(0.5, 0.5, 2.0),
            target: DVec3::new(0.5, 0.5, 0.0),
            vfov_deg: 2.0 * (0.25f64).atan().to_degrees(),
        },
        seed: 1,
        edge_spp: 0,
    };
    for pass in [Pass::Vertex, Pass::Direct, Pass::Gather] {
        let img = |s: &ProgressiveSolver| {
            pass.render(s.problem(), &s.element_radiance(false), &settings, 16)
        };
        let (t, f) = (img(&textured), img(&flat));
        let (mut white, mut black, mut sum_t, mut sum_f) = (0.0, 0.0f64, 0.0, 0.0);
        for j in 0..64u32 {
            for i in 0..64u32 {
                let (pt, pf) = (t.get(i, j).x, f.get(i, j).x);
                sum_t += pt;
                sum_f += pf;
                if i % 4 == 2 && j % 4 == 2 {
                    if (i / 4 + j / 4) % 2 == 0 {
                        white += pt / pf;
                    } else {
                        black = black.max(pt / pf);
                    }
                }
            }
        }
        // A white texel is twice the mean colour: twice the flat wall's radiance there
        // (each element's mean is the checker's, so its light is the flat wall's); a black
        // one shows nothing.
        let white = white / 128.0;
        assert!((white - 2.0).abs() < 0.02, "{pass:?}: white/flat {white}");
        assert!(black < 1e-9, "{pass:?}: black/flat {black}");
        assert!(
            (sum_t / sum_f - 1.0).abs() < 0.02,
            "{pass:?}: means {sum_t} {sum_f}"
        );
    }
}

#[test]
fn a_closed_room_of_white_placeholders_converges() {
    // Kd 1 1 1 everywhere (as in models whose colour lives in textures): clamped to 0.95 with
    // one warning, so the closed box converges; plain shooting needs about
    // ln(1e-4)/ln(0.95) ≈ 180 sweeps' worth of shots at most, the overshooting far fewer.
    let dir = tempfile::tempdir().expect("temp dir");
    let obj = "mtllib w.mtl\nusemtl white\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
        f 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 1 4 8 5\nf 2 6 7 3\nusemtl light\nf 4 3 7 8\n";
    std::fs::write(dir.path().join("w.obj"), obj).expect("obj");
    std::fs::write(
        dir.path().join("w.mtl"),
        "newmtl white\nKd 1 1 1\nnewmtl light\nKd 1 1 1\nKe 1 1 1\n",
    )
    .expect("mtl");
    let scene = Scene::load_obj(&dir.path().join("w.obj"), &LoadOptions::default()).expect("box");
    let warning = scene.warnings.join("\n");
    assert!(warning.contains("clamped to 0.95"), "{warning}");
    assert!(
        scene
            .materials
            .iter()
            .all(|m| m.reflectance == DVec3::splat(0.95))
    );
    let mut s = ProgressiveSolver::new(
        scene,
        SolverConfig {
            element_size: Some(0.1),
            patch_size: Some(0.2),
            ..Default::default()
        },
    )
    .expect("solver");
    let patches = s.mesh().patches.len();
    let stop = StopCriteria {
        unshot: 1e-4,
        max_shots: Some(180 * patches),
        ..Default::default()
    };
    s.run(&stop, &AtomicBool::new(false), &mut |_| {});
    assert!(
        s.unshot_fraction() <= 1e-4,
        "unshot {}",
        s.unshot_fraction()
    );
    // Closed: Σ B A = Σ E A / (1 − ρ) = 20 over the 6 faces. Rows that miss a fraction ε of
    // the enclosure (the form factors' error, ≤ 1 % here) lower it to 1/(1 − ρ(1 − ε)): at
    // most 16 % below; nothing can raise it.
    let b = s.element_radiance(true);
    let area: f64 = s.mesh().elements.iter().map(|e| e.area).sum();
    let mean: f64 = b
        .iter()
        .zip(&s.mesh().elements)
        .map(|(b, e)| b.x * e.area)
        .sum::<f64>()
        / area;
    let exact = 20.0 / 6.0;
    assert!(
        mean <= exact * 1.001 && mean >= exact * 0.84,
        "mean radiance {mean} vs {exact}"
    );
}

/// sRGB 8-bit to linear (the sRGB transfer function), the reference for decoded texels.
fn srgb_to_linear(v: u8) -> f64 {
    let c = f64::from(v) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// A texture whose mean differs from element to element (8 grey columns, one per element
/// column, 8 texels each) must show its steps where the texture has them: across a step,
/// the image changes by the ratio of the two greys (times the light's own change, measured
/// on an untextured wall). Interpolating the radiance and dividing by each element's mean
/// smooths the step into the interpolation instead (a ratio near 1 at every step, and a
/// block pattern on real textures).
#[test]
fn a_step_between_elements_shows_as_the_texture_has_it() {
    let greys: [u8; 8] = [60, 200, 110, 255, 40, 160, 230, 90];
    let dir = tempfile::tempdir().expect("temp dir");
    let img = image::RgbImage::from_fn(64, 64, |x, _| {
        let g = greys[(x / 8) as usize];
        image::Rgb([g, g, g])
    });
    img.save(dir.path().join("steps.png")).expect("png");
    let textured = solve(scene(
        dir.path(),
        "newmtl wall\nKd 0.8 0.8 0.8\nmap_Kd steps.png",
    ));
    let flat = solve(scene(dir.path(), "newmtl wall\nKd 0.4 0.4 0.4"));
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp: 1,
        camera: Camera {
            eye: DVec3::new(0.5, 0.5, 2.0),
            target: DVec3::new(0.5, 0.5, 0.0),
            vfov_deg: 2.0 * (0.25f64).atan().to_degrees(),
        },
        seed: 1,
        edge_spp: 0,
    };
    for pass in [Pass::Vertex, Pass::Direct, Pass::Gather] {
        let img = |s: &ProgressiveSolver| {
            pass.render(s.problem(), &s.element_radiance(false), &settings, 64)
        };
        let (t, f) = (img(&textured), img(&flat));
        let mut worst = 0.0f64;
        for j in [12u32, 32, 52] {
            for k in 0..7usize {
                // Two texels inside each side of the step between columns k and k + 1.
                let (l, r) = (8 * k as u32 + 5, 8 * k as u32 + 10);
                let seen = (t.get(r, j).x / t.get(l, j).x) / (f.get(r, j).x / f.get(l, j).x);
                let want = srgb_to_linear(greys[k + 1]) / srgb_to_linear(greys[k]);
                worst = worst.max((seen / want - 1.0).abs());
            }
        }
        // The light changes smoothly over 5 texels (measured on the flat wall); what is
        // left is the textured wall's slightly different interreflection, well under 3 %
        // (the gather's 64 rays a pixel add their noise).
        let tolerance = if pass == Pass::Gather { 0.06 } else { 0.03 };
        assert!(worst < tolerance, "{pass:?}: step ratio off by {worst}");
    }
}
