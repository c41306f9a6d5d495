//! `nusselt render --export-gltf` through the command line: the file passes the Khronos glTF
//! Validator (`tools/gltf-validator`, node), reads back with the `gltf` crate, and holds the
//! solution: COLOR_0 = exposure × _RADIANCE clamped, `B = E + ρ·I/π` with the Cornell box's
//! own `Kd`/`Ke` (from `assets/cornell.mtl`), and the irradiance on the tall block's top
//! against the exact direct irradiance from the light. The viewer's export of a snapshot
//! passes the same checks. Without node or the validator the tests fail, naming the fix.

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use gltf::mesh::Semantic;
use nusselt_core::mesh::MeshSpec;

const MTL: &str = include_str!("../assets/cornell.mtl");

/// `Kd` and `Ke` by material name, read from the MTL text.
fn cornell_materials() -> HashMap<String, ([f64; 3], [f64; 3])> {
    let mut out = HashMap::new();
    let mut name = String::new();
    for line in MTL.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        let rgb = || [1, 2, 3].map(|i| w[i].parse::<f64>().expect("number"));
        match w.first() {
            Some(&"newmtl") => {
                name = w[1].to_string();
                out.insert(name.clone(), ([0.0; 3], [0.0; 3]));
            }
            Some(&"Kd") => out.get_mut(&name).expect("material").0 = rgb(),
            Some(&"Ke") => out.get_mut(&name).expect("material").1 = rgb(),
            _ => {}
        }
    }
    out
}

/// Runs the validator script; panics with the fix when node or the package is missing.
fn validate(path: &Path) -> String {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/gltf-validator/validate.js");
    let out = Command::new("node")
        .arg(&script)
        .arg(path)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "cannot run node ({e}): the glTF Validator needs Node.js (apt-get install nodejs npm), \
                 then `npm ci --prefix tools/gltf-validator`"
            )
        });
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_ne!(
        out.status.code(),
        Some(2),
        "the validator could not run: {err}\n(install it with `npm ci --prefix tools/gltf-validator`)"
    );
    eprintln!("glTF Validator on {}:\n{text}{err}", path.display());
    let result = text
        .lines()
        .find_map(|l| l.strip_prefix("RESULT "))
        .unwrap_or_else(|| panic!("no RESULT line from the validator: {text}{err}"));
    assert!(
        result.starts_with("errors=0 "),
        "validator: {result}\n{text}"
    );
    text
}

/// Per primitive: material name, positions, COLOR_0, _RADIANCE, _IRRADIANCE; and the
/// triangle count.
type Prim = (String, Vec<[f32; 3]>, [Vec<[f32; 3]>; 3]);

fn read_back(path: &Path) -> (Vec<Prim>, usize) {
    let (doc, buffers, _) = gltf::import(path).expect("the gltf crate reads the export");
    let mesh = doc.meshes().next().expect("one mesh");
    let mut prims = Vec::new();
    let mut triangles = 0;
    for p in mesh.primitives() {
        let read = |s: Semantic| -> Vec<[f32; 3]> {
            let a = p.get(&s).unwrap_or_else(|| panic!("{s:?} missing"));
            gltf::accessor::Iter::<[f32; 3]>::new(a, |b| Some(&buffers[b.index()].0[..]))
                .expect("readable")
                .collect()
        };
        let reader = p.reader(|b| Some(&buffers[b.index()].0[..]));
        triangles += reader.read_indices().expect("indexed").into_u32().count() / 3;
        let name = p.material().name().expect("named").to_string();
        let values = [
            read(Semantic::Colors(0)),
            read(Semantic::Extras("RADIANCE".into())),
            read(Semantic::Extras("IRRADIANCE".into())),
        ];
        prims.push((name, read(Semantic::Positions), values));
    }
    (prims, triangles)
}

/// COLOR_0 is `exposure × radiance` clamped to [0, 1] (within 1/255), and every vertex
/// satisfies `B = E + ρ I/π` with the MTL's values (f32 rounding: 1e-4 relative).
fn check_values(prims: &[Prim], exposure: f64) {
    let mtl = cornell_materials();
    for (name, pos, [colour, radiance, irradiance]) in prims {
        let (kd, ke) = mtl[name.as_str()];
        for k in 0..pos.len() {
            for c in 0..3 {
                let b = f64::from(radiance[k][c]);
                let want = (b * exposure).clamp(0.0, 1.0);
                let got = f64::from(colour[k][c]);
                assert!(
                    (got - want).abs() <= 1.0 / 255.0,
                    "{name} {k}: {got} vs {want}"
                );
                let identity = ke[c] + kd[c] * f64::from(irradiance[k][c]) / std::f64::consts::PI;
                assert!(
                    (identity - b).abs() <= 1e-4 * b.max(1.0),
                    "{name} vertex {k} channel {c}: E + ρI/π = {identity}, radiance {b}"
                );
            }
        }
    }
}

/// Form factor from a point to a rectangle [0, a] × [0, b] in a parallel plane at height c
/// over a corner (Howell's catalogue, C-11; odd in a and in b, so signed sums tile any
/// rectangle).
fn corner_factor(a: f64, b: f64, c: f64) -> f64 {
    let (p, q) = ((a * a + c * c).sqrt(), (b * b + c * c).sqrt());
    (a / p * (b / p).atan() + b / q * (a / q).atan()) / (2.0 * std::f64::consts::PI)
}

/// The tall block's top (y = 330) sees all of the light (x 213–343, z 227–332 at y 548.8)
/// and only the ceiling and upper walls besides: its irradiance is the light's exact direct
/// irradiance π Ke F plus a smaller indirect part. A missing or doubled π, or irradiance
/// read from the wrong surface, falls outside [0.95, 1.6] × direct.
fn check_block_top(prims: &[Prim]) {
    let (x0, z0, c) = (368.5, 351.25, 548.8 - 330.0);
    let f = corner_factor(343.0 - x0, 332.0 - z0, c)
        - corner_factor(213.0 - x0, 332.0 - z0, c)
        - corner_factor(343.0 - x0, 227.0 - z0, c)
        + corner_factor(213.0 - x0, 227.0 - z0, c);
    let (_, ke) = cornell_materials()["light"];
    let direct = std::f64::consts::PI * ke[0] * f;
    let mut best: Option<(f64, f64)> = None;
    for (name, pos, [_, _, irradiance]) in prims {
        if name != "white" {
            continue;
        }
        for (p, i) in pos.iter().zip(irradiance) {
            let d = (f64::from(p[0]) - x0).hypot(f64::from(p[2]) - z0);
            if (f64::from(p[1]) - 330.0).abs() < 1e-3 && best.is_none_or(|b| d < b.0) {
                best = Some((d, f64::from(i[0])));
            }
        }
    }
    let (d, e) = best.expect("a vertex on the tall block's top");
    eprintln!(
        "tall block top: irradiance {e:.4} W/m² (red), direct {direct:.4}, {d:.1} mm from the centre"
    );
    assert!(d < 30.0, "nearest vertex {d} mm away");
    assert!(
        e > 0.95 * direct && e < 1.6 * direct,
        "irradiance {e} against the direct {direct}"
    );
}

fn nusselt(args: &[&str]) -> (String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(args)
        .output()
        .expect("run nusselt");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{args:?} failed: {stderr}");
    (String::from_utf8_lossy(&out.stdout).into_owned(), stderr)
}

#[test]
fn cornell_export_validates_and_holds_the_solution() {
    let dir = tempfile::tempdir().expect("tempdir");
    let glb = dir.path().join("cornell.glb");
    let png = dir.path().join("cornell.png");
    let (p, g) = (png.to_str().expect("utf-8"), glb.to_str().expect("utf-8"));
    let (_, stderr) = nusselt(&[
        "render",
        "--builtin",
        "cornell",
        "--seconds",
        "5",
        "--width",
        "32",
        "--height",
        "32",
        "--spp",
        "1",
        "--pass",
        "vertex",
        "--exposure",
        "1.5",
        "--out",
        p,
        "--export-gltf",
        g,
    ]);
    let line = stderr
        .lines()
        .find(|l| l.starts_with("exported "))
        .unwrap_or_else(|| panic!("no export line: {stderr}"));
    eprintln!("{line}");
    let number = |unit: &str| -> usize {
        let w: Vec<&str> = line.split([' ', ',']).filter(|w| !w.is_empty()).collect();
        let at = w.iter().position(|x| *x == unit).expect(unit);
        w[at - 1].parse().expect("count")
    };
    let bytes = std::fs::metadata(&glb).expect("written").len() as usize;
    assert_eq!(number("bytes"), bytes);
    validate(&glb);
    let (prims, triangles) = read_back(&glb);
    assert_eq!(number("triangles"), triangles);
    let vertices: usize = prims.iter().map(|p| p.1.len()).sum();
    assert_eq!(number("vertices"), vertices);
    assert!(
        vertices < triangles * 3 / 2,
        "welded: {vertices} vertices for {triangles} triangles"
    );
    let names: Vec<&str> = prims.iter().map(|p| p.0.as_str()).collect();
    assert_eq!(names.len(), 4, "one primitive per material: {names:?}");
    check_values(&prims, 1.5);
    check_block_top(&prims);
}

/// `.gltf` (JSON, buffer embedded as base64) from a short, coarse solve.
#[test]
fn gltf_json_export_validates() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("c.gltf");
    let png = dir.path().join("c.png");
    nusselt(&[
        "render",
        "--builtin",
        "cornell",
        "--element-size",
        "60",
        "--shots",
        "40",
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "1",
        "--pass",
        "vertex",
        "--quiet",
        "--out",
        png.to_str().expect("utf-8"),
        "--export-gltf",
        out.to_str().expect("utf-8"),
    ]);
    let text = std::fs::read_to_string(&out).expect("JSON text");
    assert!(text.contains("data:application/octet-stream;base64,"));
    validate(&out);
    let (prims, _) = read_back(&out);
    check_values(&prims, 1.0);
}

#[test]
fn a_bad_export_path_fails_before_any_work() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("c.png");
    let png = png.to_str().expect("utf-8");
    for (path, message) in [
        (dir.path().join("c.obj"), "expected .glb or .gltf"),
        (dir.path().join("no/such/c.glb"), "does not exist"),
    ] {
        let start = Instant::now();
        let out = Command::new(env!("CARGO_BIN_EXE_nusselt"))
            .args([
                "render",
                "--builtin",
                "cornell",
                "--out",
                png,
                "--export-gltf",
            ])
            .arg(&path)
            .output()
            .expect("run nusselt");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(stderr.contains(message), "{path:?}: {stderr}");
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "refused before the solve"
        );
    }
}

/// The viewer's solver thread on `scene`, run until its step limit (`config.max_shots`):
/// the snapshot it publishes then.
fn snapshot_at_limit(
    scene: nusselt_core::scene::Scene,
    config: nusselt_viewer::solver_thread::ThreadConfig,
) -> std::sync::Arc<nusselt_viewer::snapshot::Snapshot> {
    let limit = config.max_shots;
    let mut h = nusselt_viewer::solver_thread::SolverHandle::spawn(scene, config, Box::new(|| {}))
        .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(120);
    let snapshot = loop {
        if let Some(s) = h.take_snapshot().filter(|s| s.stats.limit_reached) {
            break s;
        }
        assert!(
            Instant::now() < deadline,
            "no snapshot after {limit:?} shots"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    h.shutdown(Duration::from_secs(30));
    snapshot
}

/// The viewer's "Export lit mesh (glTF)" on a snapshot of a short solve: valid, and the same
/// identities hold (radiance with the ambient term, at exposure 2).
#[test]
fn viewer_snapshot_export_validates() {
    use nusselt_core::scene::{LoadOptions, Scene};
    use nusselt_core::solver::SolverConfig;
    use nusselt_viewer::solver_thread::ThreadConfig;
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let config = ThreadConfig {
        solver: SolverConfig {
            mesh: MeshSpec::sized(60.0, 120.0),
            ..Default::default()
        },
        max_shots: Some(20),
        ..Default::default()
    };
    let snapshot = snapshot_at_limit(scene, config);
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("viewer.glb");
    let stats = nusselt_viewer::export_gltf::write_snapshot_gltf(&snapshot, &path, true, 2.0)
        .expect("export");
    assert_eq!(stats.triangles * 3, snapshot.geometry.indices.len());
    validate(&path);
    let (prims, triangles) = read_back(&path);
    assert_eq!(triangles, stats.triangles);
    check_values(&prims, 2.0);
}

/// The viewer's export of a textured model (the Khronos BoxTextured sample, 12 triangles and
/// a PNG): valid, with TEXCOORD_0 on its primitive and the map embedded in the `albedo`
/// variant, texture coordinates within the model's own range.
#[test]
fn viewer_export_of_a_textured_model_keeps_its_map() {
    use nusselt_core::scene::{LoadOptions, Scene};
    use nusselt_viewer::solver_thread::ThreadConfig;
    let model = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/models/gltf/BoxTextured/BoxTextured.gltf");
    let mut scene = Scene::load(&model, &LoadOptions::default()).unwrap_or_else(|e| {
        panic!(
            "{} (the shared models must be present): {e}",
            model.display()
        )
    });
    // Unlit, as the file comes: the sky and sun that `view` adds.
    assert!(scene.add_default_lights().is_some());
    let config = ThreadConfig {
        max_shots: Some(5),
        ..Default::default()
    };
    let snapshot = snapshot_at_limit(scene, config);
    assert!(
        snapshot.geometry.textures.is_some(),
        "the model is textured"
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("box.glb");
    nusselt_viewer::export_gltf::write_snapshot_gltf(&snapshot, &path, true, 1.0).expect("export");
    validate(&path);
    let (doc, buffers, images) = gltf::import(&path).expect("the gltf crate reads the export");
    assert_eq!(images.len(), 1, "one embedded map");
    // The model's own texture-coordinate range (its accessor's min/max: 0–6 by 0–1, the
    // logo repeated), which the export's must keep (v flipped on import, back on export).
    let (src, src_buffers, _) = gltf::import(&model).expect("the model reads");
    let mut lo = [f32::INFINITY; 2];
    let mut hi = [f32::NEG_INFINITY; 2];
    for p in src
        .meshes()
        .flat_map(|m| m.primitives().collect::<Vec<_>>())
    {
        let r = p.reader(|b| Some(&src_buffers[b.index()]));
        for uv in r.read_tex_coords(0).expect("the model has uvs").into_f32() {
            for k in 0..2 {
                lo[k] = lo[k].min(uv[k]);
                hi[k] = hi[k].max(uv[k]);
            }
        }
    }
    let mut textured = 0;
    for mesh in doc.meshes() {
        for p in mesh.primitives() {
            let r = p.reader(|b| Some(&buffers[b.index()]));
            if let Some(uv) = r.read_tex_coords(0) {
                textured += 1;
                for [u, v] in uv.into_f32() {
                    assert!(
                        (lo[0] - 1e-4..=hi[0] + 1e-4).contains(&u)
                            && (lo[1] - 1e-4..=hi[1] + 1e-4).contains(&v),
                        "uv {u} {v} outside the model's {lo:?}..{hi:?}"
                    );
                }
            }
        }
    }
    assert_eq!(textured, 1, "the box's primitive carries TEXCOORD_0");
}
