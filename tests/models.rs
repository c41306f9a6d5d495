//! The model corpus (tests/data/models/, written by scripts/make_models.py),
//! a large generated model, and a property test on random triangle soups.
//!
//! Every model must load with the default options, converge to `--unshot 1e-3`, have no
//! NaN or negative radiance, balance its power where it is closed, and be shown by the
//! default view. The scale series must give the same image at scale 1e-3, 1 and 1e4.
//!
//! Solves use explicit coarse sizes (element diagonal/25, patch diagonal/8): the point is
//! robustness on real-shaped input, not the default density, and the suite runs in a debug
//! build. Each solve has a wall-clock budget; one that has not converged by then fails with
//! what it reached (no silent skips, no hangs).

mod common;

use common::{assert_sane, unshot_power};

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use nusselt_core::mesh::MeshSpec;
use nusselt_core::render::{self, Image, RenderSettings, SolutionView};
use nusselt_core::scene::{Camera, LoadOptions, Rgb, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, StopCriteria};
use proptest::prelude::*;

fn model(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/models")
        .join(name)
}

fn load(path: &Path) -> Scene {
    let scene = Scene::load_obj(path, &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{}: load failed: {e}", path.display()));
    for w in &scene.warnings {
        eprintln!("{}: warning: {w}", path.display());
    }
    scene
}

fn coarse_solver(scene: Scene) -> ProgressiveSolver {
    let d = scene.bounds().diagonal();
    let name = scene.name.clone();
    ProgressiveSolver::new(
        scene,
        SolverConfig {
            mesh: MeshSpec::sized(d / 25.0, d / 8.0),
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{name}: solver: {e}"))
}

fn converge(s: &mut ProgressiveSolver, unshot: f64) -> f64 {
    common::converge_to(s, unshot)
}

/// Closed: emitted = absorbed + unshot, to the row-sum error of the form factors (1 %:
/// midpoint rule at element centroids, O(h²); the built-in furnace is within 1e-3 at
/// h = 0.25 in tests/solver.rs). Open: light may escape, but none may be created:
/// absorbed + unshot ≤ emitted, with the same 1 %.
fn assert_power(s: &ProgressiveSolver, closed: bool) {
    let (emitted, absorbed) = s.power_balance();
    let unshot = unshot_power(s);
    let scene_emitted = s.scene().emitted_power();
    for c in 0..3 {
        let e = emitted[c];
        assert!(
            (e - scene_emitted[c]).abs() <= 1e-9 * scene_emitted[c],
            "{}: the mesh emits {e}, the scene's faces {}",
            s.scene().name,
            scene_emitted[c]
        );
        let gap = (e - absorbed[c] - unshot[c]) / e;
        if closed {
            assert!(
                gap.abs() <= 1e-2,
                "{}: channel {c}: emitted {e}, absorbed {}, unshot {}: imbalance {gap:.3e}",
                s.scene().name,
                absorbed[c],
                unshot[c]
            );
        } else {
            assert!(
                gap >= -1e-2,
                "{}: channel {c}: absorbed {} + unshot {} exceed emitted {e}",
                s.scene().name,
                absorbed[c],
                unshot[c]
            );
        }
    }
}

fn image_of(s: &ProgressiveSolver, camera: Camera, width: u32, height: u32, spp: u32) -> Image {
    let vertex = s.mesh().vertex_values(&s.display_radiance());
    let bvh = render::display_bvh(s.scene(), s.mesh());
    let view = SolutionView {
        scene: s.scene(),
        mesh: s.mesh(),
        vertex_radiance: &vertex,
        bvh: &bvh,
        texture: s.problem().element_texture(),
    };
    render::render_solution(
        &view,
        &RenderSettings {
            width,
            height,
            spp,
            camera,
            seed: 1,
            edge_spp: 0,
        },
    )
}

fn check_image(name: &str, img: &Image) {
    for (i, p) in img.pixels.iter().enumerate() {
        assert!(
            p.is_finite() && p.min_element() >= 0.0,
            "{name}: pixel {i} is {p}"
        );
    }
}

/// Load, converge, check radiance and power.
fn corpus_model(file: &str, closed: bool) {
    let path = model(file);
    let mut s = coarse_solver(load(&path));
    converge(&mut s, 1e-3);
    assert_sane(&s);
    assert_power(&s, closed);
    let img = image_of(
        &s,
        nusselt_core::render::view::default_camera(s.scene()),
        32,
        24,
        1,
    );
    check_image(file, &img);
}

/// Every corpus model except the scale series (which only repeats a room), for the tests
/// that loop over the corpus.
const CORPUS: [&str; 8] = [
    "icosphere_room.obj",
    "lathe_teapot.obj",
    "head_quads.obj",
    "blender_open_box.obj",
    "slivers.obj",
    "tjunctions.obj",
    "degenerate.obj",
    "winding.obj",
];

/// The first view of a model without a camera shows it: at least half of the default
/// view's pixels see a front face. With the ambient term every front face with ρ > 0 is
/// non-black before any shot, while the back of a one-sided face and the background are
/// black, so a non-black pixel is a front face (or a light). The rooms are closed (the view
/// must be from inside) and the Blender-style box is open towards +z.
#[test]
fn default_view_shows_every_model() {
    let mut bad = Vec::new();
    for file in CORPUS {
        let scene = load(&model(file));
        let d = scene.bounds().diagonal();
        // Coarse mesh: only which faces are seen matters here.
        let s = ProgressiveSolver::new(
            scene,
            SolverConfig {
                mesh: MeshSpec::sized(d / 8.0, d / 8.0),
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("{file}: solver: {e}"));
        let camera = nusselt_core::render::view::default_camera(s.scene());
        let img = image_of(&s, camera, 64, 48, 1);
        check_image(file, &img);
        let lit = img.pixels.iter().filter(|p| p.max_element() > 0.0).count();
        let frac = lit as f64 / img.pixels.len() as f64;
        eprintln!(
            "{file}: default view eye {} target {}: {:.0} % front faces",
            camera.eye,
            camera.target,
            frac * 100.0
        );
        if frac < 0.5 {
            bad.push(format!(
                "{file}: eye {}, target {}: {:.0} % of pixels see a front face",
                camera.eye,
                camera.target,
                frac * 100.0
            ));
        }
    }
    assert!(
        bad.is_empty(),
        "default views that do not show the model:\n{}",
        bad.join("\n")
    );
}

#[test]
fn icosphere_room() {
    corpus_model("icosphere_room.obj", true);
}

#[test]
fn lathe_teapot() {
    corpus_model("lathe_teapot.obj", true);
}

#[test]
fn head_of_non_planar_quads() {
    corpus_model("head_quads.obj", true);
}

#[test]
fn blender_open_box_facing_plus_z() {
    corpus_model("blender_open_box.obj", false);
}

#[test]
fn slivers() {
    corpus_model("slivers.obj", true);
}

#[test]
fn t_junctions() {
    corpus_model("tjunctions.obj", true);
}

#[test]
fn duplicate_and_zero_area_triangles() {
    corpus_model("degenerate.obj", true);
}

#[test]
fn inconsistent_winding() {
    // A reversed face shows its back to the room, so the scene is not closed for a
    // one-sided solve: only "no power created" is asserted.
    corpus_model("winding.obj", false);
}

#[test]
fn every_corpus_file_is_what_the_script_writes() {
    // The corpus is generated; a hand edit (or a stale file) would make the tests test
    // something else than the script documents.
    let out = Command::new("python3")
        .arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scripts/make_models.py"))
        .arg("--check")
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "scripts/make_models.py --check: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// `nusselt render` with default flags on every model, 10 shots: it exits 0, or with an
/// error message that names the model; never with a panic (the issue: a panic in the solver
/// becomes an error naming the scene).
#[test]
fn cli_renders_every_model_with_default_flags_without_panicking() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.pfm");
    let mut bad = Vec::new();
    for file in CORPUS {
        let path = model(file);
        let start = Instant::now();
        let run = Command::new(env!("CARGO_BIN_EXE_nusselt"))
            .args(["render", path.to_str().expect("path"), "--out"])
            .arg(&out)
            .args([
                "--shots", "10", "--width", "32", "--height", "24", "--spp", "1",
            ])
            .args(["--json", "--quiet"])
            .output()
            .expect("run nusselt");
        let stderr = String::from_utf8_lossy(&run.stderr);
        eprintln!(
            "{file}: exit {:?} in {:.1} s: {}",
            run.status.code(),
            start.elapsed().as_secs_f64(),
            String::from_utf8_lossy(&run.stdout).trim()
        );
        if stderr.contains("panicked") || run.status.code() == Some(101) {
            bad.push(format!("{file}: panicked: {}", stderr.trim()));
        } else if !run.status.success() && !stderr.contains(file) {
            bad.push(format!(
                "{file}: error without the model's name: {}",
                stderr.trim()
            ));
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

// ---------------------------------------------------------------------------------------
// The scale series, through the CLI

fn nusselt(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(args)
        .output()
        .expect("run nusselt");
    assert!(
        out.status.success(),
        "nusselt {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

/// The same scene at scale 1e-3, 1 and 1e4 (coordinates multiplied), rendered by
/// `nusselt render` with element size, patch size and camera multiplied by the same factor,
/// gives the same image to 1e-6 relative: radiance and form factors are dimensionless in
/// the unit, so only a tolerance or offset that is not relative to the scene could make them
/// differ. 1e-6 leaves room for f32 form-factor rows (6e-8) accumulated over the shots.
#[test]
fn scale_series_renders_the_same_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut images = Vec::new();
    for (tag, s) in [("1", 1.0), ("1e-3", 1e-3), ("1e4", 1e4)] {
        let obj = model(&format!("scaled_{tag}.obj"));
        let out = dir.path().join(format!("{tag}.pfm"));
        // Inside the 4 × 3 × 4 room, looking at the box and the ball.
        let cam = [2.0, 1.6, 3.8, 2.0, 0.8, 1.0, 60.0];
        let cam: Vec<String> = cam
            .iter()
            .enumerate()
            .map(|(i, v)| format!("{}", if i < 6 { v * s } else { *v }))
            .collect();
        let diag = (4f64 * 4.0 + 3.0 * 3.0 + 4.0 * 4.0).sqrt();
        let json = nusselt(&[
            "render",
            obj.to_str().expect("path"),
            "--out",
            out.to_str().expect("path"),
            "--unshot",
            "1e-3",
            "--json",
            "--quiet",
            "--element-size",
            &format!("{}", diag / 25.0 * s),
            "--patch-size",
            &format!("{}", diag / 8.0 * s),
            "--camera",
            &cam.join(","),
            "--width",
            "64",
            "--height",
            "48",
            "--spp",
            "4",
            // One pass at every scale: `auto` chooses by the time it measures.
            "--pass",
            "vertex",
        ]);
        let v: serde_json::Value = serde_json::from_str(json.trim()).expect("json summary");
        eprintln!("scale {tag}: {v}");
        let unshot = v["unshot_fraction"].as_f64().expect("unshot_fraction");
        assert!(unshot <= 1e-3, "scale {tag}: unshot {unshot}");
        let img = Image::load_pfm(&out).expect("pfm");
        check_image(tag, &img);
        images.push((tag, v, img));
    }
    let (_, v1, reference) = &images[0];
    let peak = reference
        .pixels
        .iter()
        .map(|p| p.max_element())
        .fold(0.0, f64::max);
    assert!(peak > 0.0, "the scale-1 image is black");
    for (tag, v, img) in &images[1..] {
        assert_eq!(
            v["elements"], v1["elements"],
            "scale {tag}: element count differs from scale 1"
        );
        let mut worst = (0.0, 0);
        for (i, (a, b)) in img.pixels.iter().zip(&reference.pixels).enumerate() {
            let d = (*a - *b).abs().max_element() / b.max_element().max(1e-3 * peak);
            if d > worst.0 {
                worst = (d, i);
            }
        }
        assert!(
            worst.0 <= 1e-6,
            "scale {tag}: pixel {} is {} against {} at scale 1 ({:.2e} relative)",
            worst.1,
            img.pixels[worst.1],
            reference.pixels[worst.1],
            worst.0
        );
    }
}

/// The scale series through the library: the same patches shoot in the same order at
/// every scale, to `--unshot 1e-3`, and the unshot fraction follows the same path (to 1e-9
/// relative, far above the 1e-16 round-off of the coordinates, far below what one shot
/// changes). Symmetric patches have equal unshot powers up to round-off, so a choice that
/// breaks their ties by the last bit diverged after 4 shots at scale 1e-3 and at the first
/// shot at scale 1e4 (and then stopped after another number of shots).
#[test]
fn scale_series_shoots_the_same_patches_in_the_same_order() {
    let diag = (4f64 * 4.0 + 3.0 * 3.0 + 4.0 * 4.0).sqrt();
    let run = |tag: &str, scale: f64| {
        let scene = Scene::load_obj(
            &model(&format!("scaled_{tag}.obj")),
            &LoadOptions::default(),
        )
        .unwrap_or_else(|e| panic!("scaled_{tag}: {e}"));
        let mut s = ProgressiveSolver::new(
            scene,
            SolverConfig {
                mesh: MeshSpec::sized(diag / 25.0 * scale, diag / 8.0 * scale),
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("scaled_{tag}: {e}"));
        let cancel = AtomicBool::new(false);
        let mut path = Vec::new();
        while s.unshot_fraction() > 1e-3 && path.len() < 10_000 {
            let fraction = s.unshot_fraction();
            let shooter = s.shoot(&cancel).expect("power left to shoot");
            path.push((shooter.0, fraction));
        }
        path
    };
    let one = run("1", 1.0);
    for (tag, scale) in [("1e-3", 1e-3), ("1e4", 1e4)] {
        let other = run(tag, scale);
        assert_eq!(other.len(), one.len(), "scale {tag}: shot count");
        for (n, (a, b)) in one.iter().zip(&other).enumerate() {
            assert_eq!(
                a.0, b.0,
                "scale {tag}: shot {n} from patch {} vs {}",
                b.0, a.0
            );
            assert!(
                (a.1 - b.1).abs() <= 1e-9 * a.1,
                "scale {tag}: shot {n}: unshot fraction {} vs {}",
                b.1,
                a.1
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// A large generated model

/// A closed 4 × 3 × 4 room whose floor is a smooth terrain of `n × n` cells (2n² triangles,
/// vertex normals, heights 0 at the walls so the room stays closed), lit by the centre
/// ninth of the ceiling. Returns the OBJ path.
// Long by design: writes the OBJ and MTL text in order (vertices, normals, faces, walls).
fn write_terrain(dir: &Path, n: usize) -> PathBuf {
    use std::fmt::Write as _;
    let (sx, sy, sz) = (4.0, 3.0, 4.0);
    let height = |x: f64, z: f64| {
        let (u, v) = (x / sx, z / sz);
        let edge = (std::f64::consts::PI * u).sin() * (std::f64::consts::PI * v).sin();
        0.4 * edge * (1.0 + 0.5 * (7.0 * u).sin() * (5.0 * v).cos())
    };
    let mut obj = String::from("mtllib terrain.mtl\n");
    for i in 0..=n {
        for j in 0..=n {
            let (x, z) = (sx * i as f64 / n as f64, sz * j as f64 / n as f64);
            let _ = writeln!(obj, "v {x} {} {z}", height(x, z));
            let e = 1e-4;
            let dx = (height(x + e, z) - height(x - e, z)) / (2.0 * e);
            let dz = (height(x, z + e) - height(x, z - e)) / (2.0 * e);
            let l = (dx * dx + 1.0 + dz * dz).sqrt();
            let _ = writeln!(obj, "vn {} {} {}", -dx / l, 1.0 / l, -dz / l);
        }
    }
    obj.push_str("usemtl ground\n");
    let id = |i: usize, j: usize| i * (n + 1) + j + 1;
    for i in 0..n {
        for j in 0..n {
            // Normal +y: (i, j) (i, j+1) (i+1, j+1) runs counter-clockwise seen from above.
            let (a, b, c, d) = (id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j));
            let _ = writeln!(obj, "f {a}//{a} {b}//{b} {c}//{c}");
            let _ = writeln!(obj, "f {a}//{a} {c}//{c} {d}//{d}");
        }
    }
    let base = (n + 1) * (n + 1);
    let corners = [
        (0.0, 0.0, 0.0),
        (sx, 0.0, 0.0),
        (sx, sy, 0.0),
        (0.0, sy, 0.0),
        (0.0, 0.0, sz),
        (sx, 0.0, sz),
        (sx, sy, sz),
        (0.0, sy, sz),
    ];
    for (x, y, z) in corners {
        let _ = writeln!(obj, "v {x} {y} {z}");
    }
    // Walls: each wall's bottom edge is the terrain's border (height 0), written as one
    // polygon through the terrain's border vertices so the room is watertight.
    let c = |k: usize| base + k + 1;
    obj.push_str("usemtl wall\n");
    // back z=0 (normal +z): bottom edge from x=sx to x=0 along the terrain, then up.
    let back: Vec<usize> = (0..=n).map(|i| id(i, 0)).collect();
    let front: Vec<usize> = (0..=n).map(|i| id(i, n)).collect();
    let left: Vec<usize> = (0..=n).map(|j| id(0, j)).collect();
    let right: Vec<usize> = (0..=n).map(|j| id(n, j)).collect();
    let poly = |bottom: &[usize], top: [usize; 2], reverse: bool| {
        // `bottom` runs from the corner below top[1] to the corner below top[0].
        let mut v: Vec<usize> = bottom.to_vec();
        v.push(top[0]);
        v.push(top[1]);
        if reverse {
            v.reverse();
        }
        let words: Vec<String> = v.iter().map(|k| k.to_string()).collect();
        format!("f {}\n", words.join(" "))
    };
    // back z=0: x from 0 to sx along the bottom, then (sx,sy,0) (0,sy,0): normal -z if
    // counter-clockwise seen from -z; reversed to face +z.
    obj.push_str(&poly(&back, [c(2), c(3)], false));
    obj.push_str(&poly(&front, [c(6), c(7)], true));
    obj.push_str(&poly(&left, [c(7), c(3)], true));
    obj.push_str(&poly(&right, [c(6), c(2)], false));
    // Ceiling y=sy facing -y: a 3 × 3 grid, the centre cell the light.
    let mut k = base + 9;
    let ts = [0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0];
    let mut grid = [[0usize; 4]; 4];
    for (i, u) in ts.iter().enumerate() {
        for (j, w) in ts.iter().enumerate() {
            let _ = writeln!(obj, "v {} {sy} {}", u * sx, w * sz);
            grid[i][j] = k;
            k += 1;
        }
    }
    for i in 0..3 {
        for j in 0..3 {
            let m = if i == 1 && j == 1 { "light" } else { "wall" };
            let _ = writeln!(
                obj,
                "usemtl {m}\nf {} {} {} {}",
                grid[i][j],
                grid[i + 1][j],
                grid[i + 1][j + 1],
                grid[i][j + 1]
            );
        }
    }
    let path = dir.join("terrain.obj");
    std::fs::write(&path, obj).expect("write terrain.obj");
    std::fs::write(
        dir.join("terrain.mtl"),
        "newmtl ground\nKd 0.5 0.45 0.4\nnewmtl wall\nKd 0.7 0.7 0.7\nnewmtl light\nKd 0.7 0.7 0.7\nKe 10 10 10\n",
    )
    .expect("write terrain.mtl");
    path
}

/// Terrain cells per side in the debug-build test: 2 · 100² = 20,000 triangles, the issue's
/// "model <= 20,000 triangles" class. The 100,000-triangle model (n = 224) is too
/// slow for a debug build; scripts/bench_large_model.sh times it in release with default
/// flags (same construction, written by scripts/make_models.py --terrain).
const LARGE_N: usize = 100;

#[test]
// Default mesh: at the coarse test mesh (elements d/25, patches d/8) the centroid rule's
// O(h) non-reciprocity next to corners and terrain folds lost 3.8 % of the power (rows of
// corner shooters summing to 0.74); at the default sizes the balance holds to 1 %. A
// 20,000-triangle model is at least 20,000 elements, minutes in a debug build: this test
// runs in release (`.ci/run` runs it after the README's command).
#[cfg_attr(
    debug_assertions,
    ignore = "20,000-triangle model, release only: cargo nextest run --release --run-ignored all --test models large_terrain"
)]
fn large_terrain_model_converges() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = write_terrain(dir.path(), LARGE_N);
    let start = Instant::now();
    let scene = load(&path);
    let tris: usize = scene.faces.iter().map(|f| f.vertices.len() - 2).sum();
    assert!(tris >= 2 * LARGE_N * LARGE_N, "{tris} triangles");
    let mut s = ProgressiveSolver::new(scene, SolverConfig::default()).expect("solver");
    let load_mesh = start.elapsed().as_secs_f64();
    eprintln!(
        "terrain {tris} triangles: load + mesh {load_mesh:.1} s, {} patches",
        s.mesh().patches.len()
    );
    // The issue: shooters grow much slower than the triangle count.
    assert!(
        s.mesh().patches.len() <= tris / 4,
        "{} shooting patches for {tris} triangles",
        s.mesh().patches.len()
    );
    converge(&mut s, 1e-3);
    assert_sane(&s);
    assert_power(&s, true);
}

// ---------------------------------------------------------------------------------------
// Random triangle soups

/// A face of a soup: three vertex indices, an optional fourth (a quad, usually
/// non-planar on the lattice), and a material.
type SoupFace = (usize, usize, usize, Option<usize>, u8);

fn soup_obj(points: &[(i8, i8, i8)], faces: &[SoupFace]) -> String {
    use std::fmt::Write as _;
    let mut obj = String::from("mtllib m.mtl\n");
    for (x, y, z) in points {
        // Coordinates on a coarse lattice (many coincident and collinear points), with a
        // few tiny offsets so near-degenerate cases appear too.
        let f = |c: i8| c as f64 * 0.25 + if c % 7 == 0 { 1e-7 } else { 0.0 };
        let _ = writeln!(obj, "v {} {} {}", f(*x), f(*y), f(*z));
    }
    let n = points.len();
    for (a, b, c, d, m) in faces {
        let mat = ["light", "grey", "dark"][*m as usize % 3];
        let _ = write!(
            obj,
            "usemtl {mat}\nf {} {} {}",
            a % n + 1,
            b % n + 1,
            c % n + 1
        );
        if let Some(d) = d {
            let _ = write!(obj, " {}", d % n + 1);
        }
        obj.push('\n');
    }
    obj
}

const SOUP_MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 5 5 5\nnewmtl grey\nKd 0.8 0.8 0.8\nnewmtl dark\nKd 0.1 0.2 0.3\n";

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 48,
        // Failures are reported in the test output (with the minimal soup); no files
        // written into the source tree.
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Any soup of triangles and (mostly non-planar) quads: loading may refuse it with an
    /// error, but nothing panics; what loads meshes, takes 20 shots and renders a small image
    /// with finite, non-negative values.
    #[test]
    fn random_triangle_soups_never_panic(
        points in prop::collection::vec((-8i8..8, -8i8..8, -8i8..8), 3..24),
        faces in prop::collection::vec(
            (0usize..64, 0usize..64, 0usize..64, prop::option::of(0usize..64), 0u8..3),
            1..40,
        ),
        two_sided in any::<bool>(),
    ) {
        prop_assert_eq!(soup_problem(&points, &faces, two_sided), None);
    }
}

/// Loads a soup (two-sided or not), takes 20 shots and renders a 16 × 12 image: `None`
/// where that works or loading refuses the soup, else what was wrong (a radiance or a
/// pixel that is not finite or is negative).
fn soup_problem(points: &[(i8, i8, i8)], faces: &[SoupFace], two_sided: bool) -> Option<String> {
    let obj = soup_obj(points, faces);
    let opts = LoadOptions {
        two_sided,
        ..Default::default()
    };
    let scene = Scene::from_obj_str("soup.obj", &obj, &[("m.mtl", SOUP_MTL)], &opts).ok()?;
    let d = scene.bounds().diagonal();
    let config = SolverConfig {
        mesh: MeshSpec::sized((d / 10.0).max(1e-3), (d / 4.0).max(1e-3)),
        ..Default::default()
    };
    let mut s = ProgressiveSolver::new(scene, config).ok()?;
    s.run(
        &StopCriteria {
            residual: 0.0,
            max_steps: Some(20),
            max_seconds: None,
            tolerance: None,
        },
        &AtomicBool::new(false),
        &mut |_| {},
    );
    let bad = |p: &Rgb| !(p.is_finite() && p.min_element() >= 0.0);
    if let Some(b) = s.display_radiance().iter().find(|b| bad(b)) {
        return Some(format!("radiance {b}"));
    }
    let camera = nusselt_core::render::view::default_camera(s.scene());
    let img = image_of(&s, camera, 16, 12, 1);
    img.pixels
        .iter()
        .find(|p| bad(p))
        .map(|p| format!("pixel {p}"))
}

/// A soup the fuzzer once found: a pixel came out at -4e-17 (a hit's barycentrics a
/// rounding outside its triangle).
#[test]
fn a_found_soup_renders_no_negative_pixel() {
    let points = [(2, 0, 6), (4, 1, 4), (6, 4, -7)];
    let faces: [SoupFace; 4] = [
        (0, 2, 0, None, 0),
        (43, 31, 8, Some(15), 0),
        (46, 9, 2, None, 1),
        (3, 10, 11, None, 0),
    ];
    assert_eq!(soup_problem(&points, &faces, true), None);
}

/// The first view of two shared models that open the wrong way if the chooser counts lit
/// pixels alone: the jeweller's shop (no lights; under the default sky and sun its roof
/// fills the view from above) and McGuire's Cornell box with Suzanne and its added ceiling
/// light (a plan view into the box). Both are seen from +z, through their open fronts.
#[test]
fn shared_models_open_on_what_they_hold() {
    for model in [
        "bijoutier/BOUTIQUEbijoutier.obj",
        "cornell_variants/CornellBox-Suzanne-lit.obj",
    ] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/models")
            .join(model);
        let mut scene = Scene::load(&path, &LoadOptions::default()).unwrap_or_else(|e| {
            panic!(
                "{} (the shared models must be present): {e}",
                path.display()
            )
        });
        scene.add_default_lights();
        let camera = nusselt_core::render::view::default_camera(&scene);
        let look = (camera.target - camera.eye).normalize_or_zero();
        assert!(
            look.z < -0.9 && camera.eye.z > scene.bounds().max.z,
            "{model}: {camera:?}"
        );
    }
    // The Dabrović atrium, also unlit: from outside under the sky only its roof and outer
    // walls show, so it opens inside, in its courtyard.
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/models/dabrovic_sponza/sponza.obj");
    let mut scene =
        Scene::load(&path, &LoadOptions::default()).expect("the shared models must be present");
    scene.add_default_lights();
    let camera = nusselt_core::render::view::default_camera(&scene);
    let b = scene.bounds();
    assert!(
        camera.eye.cmpgt(b.min).all() && camera.eye.cmplt(b.max).all(),
        "Dabrović: {camera:?}"
    );
}
