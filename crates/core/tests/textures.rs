//! Textured surfaces: the solve sees each element's mean texture (so colour bleeding is that
//! of a flat surface of the mean colour), and the image shows the texel under the light.
//! Cut-outs: a sheet whose alpha map (`map_d`) is half holes passes half the light to what
//! is behind it, reflects from its opaque half only, and shows what is behind it through its
//! holes in every pass; the path tracer sees the same holes.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use glam::DVec3;
use nusselt_core::mesh::MeshSpec;
use nusselt_core::render::pathtrace::PathTracer;
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
    load(dir, obj, &mtl)
}

/// `obj` and `mtl` written as `s.obj` and `s.mtl` in `dir`, and loaded.
fn load(dir: &Path, obj: &str, mtl: &str) -> Scene {
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
            mesh: MeshSpec::sized(0.125, 0.125),
            ..Default::default()
        },
    )
    .expect("solver");
    let stop = StopCriteria {
        residual: 1e-9,
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
    let (a, b) = (textured.radiosity().to_vec(), flat.radiosity().to_vec());
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
        let img = |s: &ProgressiveSolver| pass.render(s.problem(), s.radiosity(), &settings, 16);
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
            mesh: MeshSpec::sized(0.1, 0.2),
            ..Default::default()
        },
    )
    .expect("solver");
    let patches = s.mesh().patches.len();
    let stop = StopCriteria {
        residual: 1e-4,
        max_steps: Some(180 * patches),
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
    let b = s.display_radiance();
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
        let img = |s: &ProgressiveSolver| pass.render(s.problem(), s.radiosity(), &settings, 64);
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

/// A 64 × 64 checkerboard mask (one texel a cell), grey 8-bit: opaque (255) where x + y is
/// even. Every element of 1/8 covers 8 × 8 cells, so its opaque fraction is ½ exactly.
fn write_mask(path: &Path) {
    let img = image::GrayImage::from_fn(64, 64, |x, y| {
        image::Luma([if (x + y) % 2 == 0 { 255 } else { 0 }])
    });
    img.save(path).expect("png");
}

/// A floor x, z ∈ [-1, 2] at y = 0 facing up (Kd 0.5), a light x, z ∈ [0.4, 0.6] at y = 1
/// facing down, and between them a sheet x, z ∈ [-1, 2] at y = 0.5 facing up with uv =
/// (x, z) (material `sheet`, given by `sheet_mtl`). Rays from the light to the floor cross
/// y = 0.5 within x, z ∈ [-0.3, 1.3]: all of them meet the sheet.
fn sheet_scene(dir: &Path, sheet_mtl: &str) -> Scene {
    let obj = "mtllib s.mtl\nvt -1 -1\nvt 2 -1\nvt 2 2\nvt -1 2\n\
        v -1 0 -1\nv -1 0 2\nv 2 0 2\nv 2 0 -1\nusemtl floor\nf 1 2 3 4\n\
        v 0.4 1 0.4\nv 0.6 1 0.4\nv 0.6 1 0.6\nv 0.4 1 0.6\nusemtl light\nf 5 6 7 8\n\
        v -1 0.5 -1\nv -1 0.5 2\nv 2 0.5 2\nv 2 0.5 -1\nusemtl sheet\nf 9/1 10/4 11/3 12/2\n";
    let mtl =
        format!("{sheet_mtl}\nnewmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 5 5 5\n");
    load(dir, obj, &mtl)
}

/// Power reflected by the elements of material `name` (radiance × area, red channel).
fn power(s: &ProgressiveSolver, name: &str) -> f64 {
    let b = s.radiosity().to_vec();
    let scene = s.scene();
    s.mesh()
        .elements
        .iter()
        .zip(&b)
        .filter(|(e, _)| {
            let m = s.mesh().patch(e.patch).material;
            scene.materials[m.0 as usize].name == name
        })
        .map(|(e, b)| b.x * e.area)
        .sum()
}

#[test]
fn a_sheet_half_holes_passes_half_the_light_and_reflects_from_its_opaque_half() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_mask(&dir.path().join("m.png"));
    let cut = solve(sheet_scene(
        dir.path(),
        "newmtl sheet\nKd 0 0 0\nmap_d m.png",
    ));
    // The same sheet without holes: the floor gets nothing.
    let solid = solve(sheet_scene(dir.path(), "newmtl sheet\nKd 0 0 0"));
    assert!(power(&solid, "floor") < 1e-12, "{}", power(&solid, "floor"));
    // No sheet at all.
    let without = {
        let mut bare = sheet_scene(dir.path(), "newmtl sheet\nKd 0 0 0");
        let sheet = bare.materials.iter().position(|m| m.name == "sheet");
        bare.faces.retain(|f| Some(f.material.0 as usize) != sheet);
        solve(bare)
    };
    // Through the holes: half the floor's light of the scene without the sheet. Each floor
    // element's visibility is estimated from its 16 shadow rays through 1/64 cells; over the
    // floor's 576 elements the estimate's spread is about 1 %, so 0.05 is well clear of
    // noise. The sheet intercepting the whole light over its outline as well (a row that
    // delivers 1.3 times the shot, scaled back by the energy guard) gave 0.39.
    let ratio = power(&cut, "floor") / power(&without, "floor");
    assert!(
        (ratio - 0.5).abs() < 0.05,
        "floor behind the sheet: {ratio}"
    );

    // Reflection from the opaque half only: each sheet element's reflectance is Kd times
    // its opaque fraction, exactly ½ here (whole cells).
    let white_cut = solve(sheet_scene(
        dir.path(),
        "newmtl sheet\nKd 0.8 0.8 0.8\nmap_d m.png",
    ));
    for e in 0..white_cut.mesh().elements.len() {
        let m = white_cut
            .mesh()
            .patch(white_cut.mesh().elements[e].patch)
            .material;
        if white_cut.scene().materials[m.0 as usize].name == "sheet" {
            let rho = white_cut.problem().element_rho(e).x;
            assert!((rho - 0.4).abs() < 1e-9, "element {e}: ρ {rho}");
        }
    }
}

/// Looking down through the sheet at the floor: the holes show the lit floor, the opaque
/// cells the black sheet, in every pass; half the pixels each.
#[test]
fn the_holes_show_what_is_behind_the_sheet() {
    let dir = tempfile::tempdir().expect("temp dir");
    write_mask(&dir.path().join("m.png"));
    let s = solve(sheet_scene(
        dir.path(),
        "newmtl sheet\nKd 0 0 0\nmap_d m.png",
    ));
    // From under the light (y = 1), the sheet x, z ∈ [0.25, 0.75] fills the image: 64
    // pixels over 32 cells, 2 a cell.
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp: 1,
        camera: Camera {
            eye: DVec3::new(0.5, 0.9, 0.5001),
            target: DVec3::new(0.5, 0.5, 0.5),
            vfov_deg: 2.0 * (0.25f64 / 0.4).atan().to_degrees(),
        },
        seed: 1,
        edge_spp: 0,
    };
    for pass in [Pass::Vertex, Pass::Direct, Pass::Gather] {
        let img = pass.render(s.problem(), s.radiosity(), &settings, 16);
        let lit = (0..64u32)
            .flat_map(|j| (0..64u32).map(move |i| (i, j)))
            .filter(|&(i, j)| img.get(i, j).x > 1e-6)
            .count();
        // A pixel's one eye ray lands in a hole half the time; over 4096 pixels of 2 × 2
        // per cell the count is within a few per cent of half.
        let fraction = lit as f64 / 4096.0;
        assert!(
            (fraction - 0.5).abs() < 0.1,
            "{pass:?}: {fraction} of the pixels see the floor"
        );
    }
    // The path tracer: the light reaches the floor through the holes only, and an eye ray
    // through a hole sees it.
    let tracer = PathTracer::new(s.scene());
    let img = tracer.render(&RenderSettings { spp: 4, ..settings }, &|_| {});
    let lit = (0..64u32)
        .flat_map(|j| (0..64u32).map(move |i| (i, j)))
        .filter(|&(i, j)| img.get(i, j).x > 1e-6)
        .count() as f64
        / 4096.0;
    assert!(
        lit > 0.3 && lit < 0.6,
        "path tracer: {lit} of the pixels lit"
    );
}
