//! Textured scenes loaded from files: maps found and read, their means and texels on
//! faces, the warnings, and the real models under `../shared/models`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DVec2, DVec3};

use super::{CLAMPED_REFLECTANCE, LoadOptions, Scene};

/// 4 × 4 checkerboard: texel (x, y) (y down from the top row) red when x + y is even, else
/// blue.
fn write_checker(path: &Path) {
    let img = image::RgbImage::from_fn(4, 4, |x, y| {
        if (x + y) % 2 == 0 {
            image::Rgb([255, 0, 0])
        } else {
            image::Rgb([0, 0, 255])
        }
    });
    img.save(path).expect("png");
}

/// 2 × 2 grey mask: left column 0 (transparent), right column 255.
fn write_mask(path: &Path) {
    let img = image::GrayImage::from_fn(2, 2, |x, _| image::Luma([if x == 0 { 0 } else { 255 }]));
    img.save(path).expect("tga");
}

const MTL: &str = "newmtl checker
Kd 1 1 1
map_Kd TEX\\Checker.PNG
newmtl scaled
Kd 0.5 0.5 0.5
map_Kd -s 2 2 1 -o 0.25 0 0 tex\\checker.png
newmtl gone
Kd 0.3 0.2 0.1
map_Kd nothere.png
newmtl cutout
Kd 0.5 0.5 0.5
map_Kd tex/checker.png
map_d -clamp on Mask.tga
newmtl bright
Kd 1.5 0.2 0.2
newmtl light
Kd 0 0 0
Ke 1 1 1
";

/// The unit square at height `y` with uv = (x, z), and a face with no uv at height 10.
fn square(y: usize, material: &str, vt: bool) -> String {
    let v = 4 * y;
    let f = if vt {
        format!("f {}/1 {}/2 {}/3 {}/4", v + 1, v + 2, v + 3, v + 4)
    } else {
        format!("f {} {} {} {}", v + 1, v + 2, v + 3, v + 4)
    };
    format!("v 0 {y} 0\nv 0 {y} 1\nv 1 {y} 1\nv 1 {y} 0\nusemtl {material}\n{f}\n",)
}

/// The scene: squares 0..=4 textured as `MTL` says, square 5 checker without uv, the
/// light; and its folder.
fn textured_scene() -> (Scene, tempfile::TempDir) {
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::create_dir(dir.path().join("tex")).expect("mkdir");
    write_checker(&dir.path().join("tex/checker.png"));
    write_mask(&dir.path().join("mask.tga"));
    std::fs::write(dir.path().join("scene.mtl"), MTL).expect("mtl");
    let mut obj = "mtllib scene.mtl\nvt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\n".to_string();
    for (i, m) in ["checker", "scaled", "gone", "cutout", "bright"]
        .iter()
        .enumerate()
    {
        obj += &square(i, m, true);
    }
    obj += &square(5, "checker", false);
    obj += &square(6, "light", false);
    let path = dir.path().join("scene.obj");
    std::fs::write(&path, obj).expect("obj");
    let scene = Scene::load_obj(&path, &LoadOptions::default()).expect("loads");
    (scene, dir)
}

/// The part x, z ∈ [0, s] of square `face`.
fn corner_patch(face: usize, s: f64) -> Vec<DVec3> {
    let y = face as f64;
    vec![
        DVec3::new(0.0, y, 0.0),
        DVec3::new(0.0, y, s),
        DVec3::new(s, y, s),
        DVec3::new(s, y, 0.0),
    ]
}

fn near(a: DVec3, b: DVec3) -> bool {
    (a - b).abs().max_element() < 1e-9
}

#[test]
fn maps_load_with_backslashes_and_the_wrong_case() {
    let (s, _dir) = textured_scene();
    // checker.png once (three materials share it) and the mask.
    assert_eq!(s.textures.len(), 2, "{:?}", s.warnings);
    assert_eq!(
        s.texture_bytes,
        s.textures.iter().map(|t| t.bytes()).sum::<usize>()
    );
    assert_eq!(s.texture_bytes, 21 * 16 + 5 * 16 + 5 * 4);
    let m = |name: &str| {
        s.materials
            .iter()
            .find(|m| m.name == name)
            .expect("material")
    };
    assert!(m("checker").diffuse_map.is_some());
    assert_eq!(m("scaled").diffuse_map, m("checker").diffuse_map);
    assert!(m("cutout").alpha_map.is_some());
    assert_eq!(m("scaled").diffuse_uv.scale, DVec2::new(2.0, 2.0));
    assert_eq!(s.faces[0].uvs.as_ref().map(Vec::len), Some(4));
    assert_eq!(s.faces[5].uvs, None);
}

#[test]
fn the_mean_over_a_face_and_over_one_texel() {
    let (s, _dir) = textured_scene();
    let whole = s.texture_mean(0, &s.faces[0].vertices).expect("textured");
    assert!(near(whole.rgb, DVec3::new(0.5, 0.0, 0.5)), "{whole:?}");
    assert_eq!(whole.coverage, 1.0);
    // uv [0, ¼]²: the bottom-left texel (x 0, y 3: blue), so v = 0 is the bottom row.
    let texel = s.texture_mean(0, &corner_patch(0, 0.25)).expect("textured");
    assert!(near(texel.rgb, DVec3::Z), "{texel:?}");
    // A triangle patch: half of that texel is still that texel.
    let tri = &corner_patch(0, 0.25)[..3];
    assert!(near(
        s.texture_mean(0, tri).expect("textured").rgb,
        DVec3::Z
    ));
    // -s 2 2 -o 0.25 0: uv [0, ⅛]² reads u ∈ [¼, ½], v ∈ [0, ¼]: texel (1, 3), red.
    let scaled = s
        .texture_mean(1, &corner_patch(1, 0.125))
        .expect("textured");
    assert!(near(scaled.rgb, DVec3::X), "{scaled:?}");
    // No vt: the texture's mean.
    let no_uv = s.texture_mean(5, &s.faces[5].vertices).expect("textured");
    assert!(near(no_uv.rgb, DVec3::new(0.5, 0.0, 0.5)));
    assert_eq!(s.texture_mean(4, &s.faces[4].vertices), None);
}

#[test]
fn an_alpha_map_gives_coverage_and_cutout_texels() {
    let (s, _dir) = textured_scene();
    let whole = s.texture_mean(3, &s.faces[3].vertices).expect("textured");
    assert!((whole.coverage - 0.5).abs() < 1e-9, "{whole:?}");
    // Texel centres of the mask's transparent left and opaque right column.
    let (rgb, alpha) = s.texel(3, DVec3::new(0.25, 3.0, 0.5)).expect("textured");
    assert_eq!(alpha, 0.0);
    assert!(rgb.max_element() <= 1.0);
    let (_, alpha) = s.texel(3, DVec3::new(0.75, 3.0, 0.5)).expect("textured");
    assert_eq!(alpha, 1.0);
    // Texel centre (0, 0) of the checker is at uv (⅛, ⅞): red.
    let (rgb, alpha) = s.texel(0, DVec3::new(0.125, 0.0, 0.875)).expect("textured");
    assert!(near(rgb, DVec3::X) && alpha == 1.0, "{rgb}");
    assert_eq!(s.texel(4, DVec3::new(0.5, 4.0, 0.5)), None);
}

#[test]
fn a_missing_map_warns_with_its_line_and_keeps_kd() {
    let (s, dir) = textured_scene();
    let gone = s.materials.iter().find(|m| m.name == "gone").expect("gone");
    assert_eq!(gone.reflectance, DVec3::new(0.3, 0.2, 0.1));
    assert_eq!(gone.diffuse_map, None);
    assert_eq!(s.texture_mean(2, &s.faces[2].vertices), None);
    let mtl = dir.path().join("scene.mtl").display().to_string();
    let w: Vec<&String> = s
        .warnings
        .iter()
        .filter(|w| w.contains("nothere.png"))
        .collect();
    assert_eq!(w.len(), 1, "{:?}", s.warnings);
    assert!(w[0].starts_with(&format!("{mtl}:9: map_Kd")), "{}", w[0]);
    let tried = dir.path().join("nothere.png").display().to_string();
    assert!(w[0].contains(&format!("tried {tried}")), "{}", w[0]);
    assert!(w[0].contains("keeps its Kd"), "{}", w[0]);
    let clamp = s.warnings.iter().filter(|w| w.contains("-clamp")).count();
    assert_eq!(clamp, 1, "{:?}", s.warnings);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.starts_with(&format!("{mtl}:13: 'map_d' option(s) -clamp ignored")))
    );
}

#[test]
fn kd_of_one_is_clamped_with_one_warning_naming_placeholders() {
    let (s, dir) = textured_scene();
    let mtl = dir.path().join("scene.mtl").display().to_string();
    let w: Vec<&String> = s
        .warnings
        .iter()
        .filter(|w| w.contains("never converges"))
        .collect();
    assert_eq!(w.len(), 1, "{:?}", s.warnings);
    assert!(w[0].starts_with(&format!("{mtl}: ")), "{}", w[0]);
    assert!(
        w[0].contains("clamped to 0.95 in 'bright' (line 15)"),
        "{}",
        w[0]
    );
    assert!(
        w[0].contains("probably a placeholder for a texture, clamped to 0.95 (the texture multiplies it) in 'checker' (line 2)"),
        "{}",
        w[0]
    );
    let m = |name: &str| {
        s.materials
            .iter()
            .find(|m| m.name == name)
            .expect("material")
    };
    assert_eq!(m("checker").reflectance, DVec3::splat(CLAMPED_REFLECTANCE));
    assert_eq!(m("bright").reflectance, DVec3::new(0.95, 0.2, 0.2));
    // Below 1 is kept, so a furnace at 0.99 still is one; 0.9995 goes to 0.999.
    let furnace = Scene::builtin(
        "furnace",
        &LoadOptions {
            rho: Some(0.99),
            ..Default::default()
        },
    )
    .expect("furnace");
    assert_eq!(furnace.materials[0].reflectance, DVec3::splat(0.99));
    assert!(furnace.warnings.is_empty(), "{:?}", furnace.warnings);
    let near_one = in_memory("Kd 0.9995 0.5 0.5");
    assert_eq!(
        near_one.materials[0].reflectance,
        DVec3::new(0.999, 0.5, 0.5)
    );
    assert!(
        near_one.warnings[0].contains("m.mtl: reflectance of 1 or more never converges")
            && near_one.warnings[0].ends_with("Kd lowered to 0.999 in 'a' (line 2)"),
        "{:?}",
        near_one.warnings
    );
}

/// A triangle of material `a` (given by `mtl_a`) and a light, from text.
fn in_memory(mtl_a: &str) -> Scene {
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nusemtl a\nf 1/1 2/2 3/3\n\
        v 0 0 1\nv 1 0 1\nv 1 1 1\nusemtl light\nf 4 5 6\n";
    let mtl = format!("newmtl a\n{mtl_a}\nnewmtl light\nKd 0 0 0\nKe 1 1 1\n");
    Scene::from_obj_str("t.obj", obj, &[("m.mtl", &mtl)], &LoadOptions::default()).expect("loads")
}

#[test]
fn in_memory_scenes_read_no_maps() {
    let s = in_memory("Kd 0.5 0.5 0.5\nmap_Kd wall.png");
    assert!(s.textures.is_empty());
    assert_eq!(s.materials[0].diffuse_map, None);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.starts_with("m.mtl:3: 1 texture map(s) not read")),
        "{:?}",
        s.warnings
    );
    assert_eq!(
        s.faces[0].uvs.as_deref(),
        Some(&[DVec2::ZERO, DVec2::X, DVec2::ONE][..])
    );
    assert!(in_memory("Kd 0.5 0.5 0.5").warnings.is_empty());
}

/// `uv_at` interpolates in the triangle holding the point: affine on a triangle, piecewise on
/// a quad whose uvs are not an affine image of it; the uvs follow a dropped repeated
/// vertex and a non-planar face split into triangles.
#[test]
fn uv_at_interpolates_and_uvs_follow_the_vertices() {
    let s = in_memory("Kd 0.5 0.5 0.5");
    let uv = s.faces[0].uv_at(DVec3::new(0.75, 0.25, 0.0)).expect("uv");
    assert!((uv - DVec2::new(0.75, 0.25)).length() < 1e-12, "{uv}");
    // Off the plane: projected along the normal.
    let uv = s.faces[0].uv_at(DVec3::new(0.75, 0.25, 3.0)).expect("uv");
    assert!((uv - DVec2::new(0.75, 0.25)).length() < 1e-12, "{uv}");
    let obj = "v 0 0 0\nv 2 0 0\nv 1 1 0\nv 0 1 0\nv 3 0 0\nv 4 0 1\nv 4 1 0\nv 3 1 0\n\
        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 0.5 0.5\n\
        usemtl light\nf 1/1 2/2 2/5 3/3 4/4\nf 5/1 6/2 7/3 8/4\n";
    let mtl = "newmtl light\nKd 0.5 0.5 0.5\nKe 1 1 1\n";
    let obj = format!("mtllib m.mtl\n{obj}");
    let s = Scene::from_obj_str("t.obj", &obj, &[("m.mtl", mtl)], &LoadOptions::default())
        .expect("loads");
    let trapezoid = &s.faces[0];
    assert_eq!(trapezoid.vertices.len(), 4);
    let want = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
    assert_eq!(trapezoid.uvs.as_deref(), Some(&want[..]));
    for (p, uv) in trapezoid.vertices.iter().zip(want) {
        assert!((trapezoid.uv_at(*p).expect("uv") - uv).length() < 1e-12);
    }
    // Midpoint of the slanted edge (1.5, 0.5): halfway between uv (1, 0) and (1, 1).
    let mid = trapezoid.uv_at(DVec3::new(1.5, 0.5, 0.0)).expect("uv");
    assert!((mid - DVec2::new(1.0, 0.5)).length() < 1e-12, "{mid}");
    assert!(
        s.warnings.iter().any(|w| w.contains("split 1 non-planar")),
        "{:?}",
        s.warnings
    );
    for f in &s.faces[1..] {
        let uvs = f.uvs.as_ref().expect("uvs");
        for (p, uv) in f.vertices.iter().zip(uvs) {
            let at = f.uv_at(*p).expect("uv");
            assert!((at - *uv).length() < 1e-12, "{at} {uv}");
        }
    }
}

fn models() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/models")
}

/// Loads an OBJ of `models()` that has no emitter, by a copy next to a light whose MTL
/// library is named by its absolute path (so its maps resolve in its own folder).
fn with_a_light(obj: &Path, dir: &Path) -> Scene {
    let folder = obj
        .parent()
        .expect("folder")
        .canonicalize()
        .expect("models folder");
    let text = std::fs::read_to_string(obj).expect("obj");
    let mut out = String::from("mtllib light.mtl\n");
    for line in text.lines() {
        match line.trim().strip_prefix("mtllib ") {
            Some(lib) => out += &format!("mtllib {}\n", folder.join(lib.trim()).display()),
            None => out += &format!("{line}\n"),
        }
    }
    out += "v 0 100 0\nv 1 100 0\nv 0 100 1\nusemtl nusselt_light\nf -3 -2 -1\n";
    std::fs::write(
        dir.join("light.mtl"),
        "newmtl nusselt_light\nKd 0 0 0\nKe 1 1 1\n",
    )
    .expect("mtl");
    let path = dir.join("lit.obj");
    std::fs::write(&path, out).expect("obj");
    Scene::load_obj(&path, &LoadOptions::default()).expect("loads")
}

/// The distinct `map_Kd` file names of an MTL file, read naively.
fn diffuse_map_names(mtl: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(mtl).expect("mtl");
    let mut names: Vec<String> = text
        .lines()
        .filter_map(|l| l.trim().strip_prefix("map_Kd "))
        .map(|n| n.trim().to_string())
        .collect();
    names.sort();
    names.dedup();
    names
}

/// Every `map_Kd` of Crytek Sponza (TGAs named with backslashes), the bijoutier (PNGs, CRLF)
/// and Šibenik is found, and each one a face uses is read.
#[test]
fn the_real_models_find_every_diffuse_map() {
    let dir = tempfile::tempdir().expect("temp dir");
    let root = models();
    for (mtl, count) in [
        ("crytek_sponza/sponza.mtl", 24),
        ("bijoutier/BOUTIQUEbijoutier.mtl", 19),
        ("sibenik/untitled.mtl", 3),
    ] {
        let mtl = root.join(mtl);
        let names = diffuse_map_names(&mtl);
        assert_eq!(names.len(), count, "{names:?}");
        let folder = mtl.parent().expect("folder");
        for n in &names {
            assert!(
                super::resolve_texture_path(folder, n).is_some(),
                "{}: {n}",
                mtl.display()
            );
        }
    }
    let t = Instant::now();
    let sponza = Scene::load_obj(
        &root.join("crytek_sponza/sponza.obj"),
        &LoadOptions::default(),
    )
    .expect("sponza loads");
    let sponza_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let bijoutier = with_a_light(&root.join("bijoutier/BOUTIQUEbijoutier.obj"), dir.path());
    let bijoutier_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let sibenik_dir = tempfile::tempdir().expect("temp dir");
    let sibenik = with_a_light(&root.join("sibenik/sibenik.obj"), sibenik_dir.path());
    let sibenik_s = t.elapsed().as_secs_f64();
    // Sponza's vase_plant.tga belongs to a material no face uses.
    for (name, s, seconds, textures) in [
        ("crytek_sponza", &sponza, sponza_s, 23),
        ("bijoutier", &bijoutier, bijoutier_s, 19),
        ("sibenik", &sibenik, sibenik_s, 3),
    ] {
        let missing: Vec<&String> = s
            .warnings
            .iter()
            .filter(|w| w.contains("map_Kd of"))
            .collect();
        assert!(missing.is_empty(), "{name}: {missing:?}");
        assert_eq!(s.textures.len(), textures, "{name}: {:?}", s.warnings);
        report(name, s, seconds);
    }
    // Kd 0.588 times a texture.
    let floor = sponza
        .materials
        .iter()
        .find(|m| m.name == "floor")
        .expect("floor");
    assert!(floor.diffuse_map.is_some() && (floor.reflectance.x - 0.588).abs() < 1e-6);
}

/// Prints what a loaded model holds and how long its means take.
fn report(name: &str, s: &Scene, seconds: f64) {
    let textured = s
        .materials
        .iter()
        .filter(|m| m.diffuse_map.is_some())
        .count();
    println!(
        "{name}: {} textures, {:.1} MB, {textured} textured materials, {} faces, loaded in {seconds:.2} s",
        s.textures.len(),
        s.texture_bytes as f64 / 1e6,
        s.faces.len()
    );
    for w in &s.warnings {
        println!("  warning: {w}");
    }
    let t = Instant::now();
    let means = (0..s.faces.len())
        .filter_map(|f| s.texture_mean(f, &s.faces[f].vertices))
        .count();
    println!(
        "  texture_mean of {means} faces in {:.2} s",
        t.elapsed().as_secs_f64()
    );
}
