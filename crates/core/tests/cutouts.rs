//! Cut-outs: a sheet whose alpha map (`map_d`) is half holes passes half the light to what
//! is behind it, reflects from its opaque half only, and shows what is behind it through its
//! holes in every pass; the path tracer sees the same holes.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use glam::DVec3;
use nusselt_core::render::pathtrace::PathTracer;
use nusselt_core::render::{Camera, Pass, RenderSettings};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, StopCriteria};

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
fn scene(dir: &Path, sheet_mtl: &str) -> Scene {
    let obj = "mtllib s.mtl\nvt -1 -1\nvt 2 -1\nvt 2 2\nvt -1 2\n\
        v -1 0 -1\nv -1 0 2\nv 2 0 2\nv 2 0 -1\nusemtl floor\nf 1 2 3 4\n\
        v 0.4 1 0.4\nv 0.6 1 0.4\nv 0.6 1 0.6\nv 0.4 1 0.6\nusemtl light\nf 5 6 7 8\n\
        v -1 0.5 -1\nv -1 0.5 2\nv 2 0.5 2\nv 2 0.5 -1\nusemtl sheet\nf 9/1 10/4 11/3 12/2\n";
    let mtl =
        format!("{sheet_mtl}\nnewmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 5 5 5\n");
    std::fs::write(dir.join("s.obj"), obj).expect("obj");
    std::fs::write(dir.join("s.mtl"), mtl).expect("mtl");
    Scene::load_obj(&dir.join("s.obj"), &LoadOptions::default()).expect("scene")
}

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

/// Power reflected by the elements of material `name` (radiance × area, red channel).
fn power(s: &ProgressiveSolver, name: &str) -> f64 {
    let b = s.element_radiance(false);
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
    let cut = solve(scene(dir.path(), "newmtl sheet\nKd 0 0 0\nmap_d m.png"));
    // The same sheet without holes: the floor gets nothing.
    let solid = solve(scene(dir.path(), "newmtl sheet\nKd 0 0 0"));
    assert!(power(&solid, "floor") < 1e-12, "{}", power(&solid, "floor"));
    // No sheet at all.
    let without = {
        let mut bare = scene(dir.path(), "newmtl sheet\nKd 0 0 0");
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
    let white_cut = solve(scene(
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
    let s = solve(scene(dir.path(), "newmtl sheet\nKd 0 0 0\nmap_d m.png"));
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
        let img = pass.render(s.problem(), &s.element_radiance(false), &settings, 16);
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
