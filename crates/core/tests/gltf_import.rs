//! glTF import: the four real scenes in `../shared/models/gltf/` (expected values from their
//! README and from the files' own bytes read here independently), small files built by the
//! tests (transforms, light units, texture orientation, errors), an OBJ/glTF equivalence,
//! and a fuzz run over mutated GLBs.

use std::path::{Path, PathBuf};

use glam::{DQuat, DVec3};
use nusselt_core::geometry::{Rng, polygon};
use nusselt_core::scene::gltf::{LUMENS_PER_WATT, from_slice};
use nusselt_core::scene::texture::srgb_to_linear;
use nusselt_core::scene::{Light, LoadOptions, Rgb, Scene, Surface};
use serde_json::{Value, json};

/// The shared models folder: `../shared/models` from the repository root. Missing is a
/// failure, not a skip.
fn model(rel: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/models/gltf")
        .join(rel);
    assert!(
        p.is_file(),
        "missing test model {} (see ../shared/models/README.md)",
        p.display()
    );
    p
}

fn load(rel: &str) -> Scene {
    let p = model(rel);
    Scene::load(&p, &LoadOptions::default()).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).abs().max_element() <= tol
}

fn material<'a>(s: &'a Scene, name: &str) -> &'a nusselt_core::scene::Material {
    s.materials
        .iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material {name}"))
}

/// The JSON chunk of a GLB file.
fn glb_json(bytes: &[u8]) -> Value {
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    serde_json::from_slice(&bytes[20..20 + len]).expect("json chunk")
}

#[test]
fn the_cornell_box_glb_has_its_walls_and_emitter() {
    let s = load("CornellBox/CornellBox.glb");
    assert_eq!(s.faces.len(), 36);
    assert_eq!(s.materials.len(), 5);
    assert!(s.two_sided, "every material is doubleSided");
    assert_eq!(
        material(&s, "Emitter_Light_temp").emission,
        Rgb::splat(100.0)
    );
    for (name, rho) in [
        ("cbox.red.002", Rgb::new(0.5, 0.0, 0.0)),
        ("cbox.green.002", Rgb::new(0.0, 0.5, 0.0)),
        ("cbox.Material.002", Rgb::splat(0.4)),
        ("box.Material", Rgb::splat(0.5)),
    ] {
        let m = material(&s, name);
        assert!(close(m.reflectance, rho, 1e-6), "{name}: {}", m.reflectance);
        assert_eq!(m.emission, Rgb::ZERO);
    }
    let b = s.bounds();
    assert!(close(b.min, DVec3::new(-556.0, 0.0, -559.0), 1.0), "{b:?}");
    assert!(close(b.max, DVec3::new(0.0, 549.0, 0.0), 1.0), "{b:?}");
    assert!(s.lights.is_empty() && s.camera.is_none());
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn the_lights_glb_converts_its_four_lights() {
    let s = load("Lights/Lights.glb");
    assert_eq!(s.faces.len(), 12);
    assert!(!s.two_sided);
    assert!(close(s.materials[0].reflectance, Rgb::splat(0.8), 1e-6));
    let k = 1.0 / LUMENS_PER_WATT;
    let points: Vec<_> = s
        .lights
        .iter()
        .filter_map(|l| match *l {
            Light::Point {
                intensity, cone, ..
            } => Some((intensity, cone)),
            _ => None,
        })
        .collect();
    assert_eq!(points.len(), 3, "{:?}", s.lights);
    assert!(close(points[0].0, Rgb::new(5.0 * k, 0.0, 0.0), 1e-9));
    assert!(points[0].1.is_none());
    for ((i, cone), (colour, inner, outer)) in points[1..].iter().zip([
        (Rgb::new(0.0, 10.0 * k, 0.0), 0.334, 0.393),
        (Rgb::new(0.0, 0.0, 10.0 * k), 0.067, 0.079),
    ]) {
        assert!(close(*i, colour, 1e-9), "{i}");
        let c = cone.expect("a spot");
        assert!(
            (c.inner - inner).abs() < 1e-3 && (c.outer - outer).abs() < 1e-3,
            "{c:?}"
        );
        // The spots' nodes turn −Z down: they shine onto the cube below them.
        assert!(close(c.direction, DVec3::NEG_Y, 1e-6), "{}", c.direction);
    }
    let sun = s.lights.iter().find_map(|l| match *l {
        Light::Sun {
            irradiance,
            direction,
            ..
        } => Some((irradiance, direction)),
        _ => None,
    });
    let (e, d) = sun.expect("a sun");
    assert!(close(e, Rgb::new(0.0, k, k), 1e-9), "{e}");
    assert!((d.length() - 1.0).abs() < 1e-9);
    let cam = s.camera.expect("camera");
    // Blender's default camera at (7.36, 4.96, 6.93) looking at the cube at the origin.
    assert!(
        close(cam.eye, DVec3::new(7.359, 4.958, 6.926), 1e-3),
        "{cam:?}"
    );
    let f = (cam.target - cam.eye).normalize_or_zero();
    assert!(f.dot(-cam.eye.normalize_or_zero()) > 0.95, "{f}");
    assert!((cam.vfov_deg - 0.39959648f64.to_degrees()).abs() < 1e-4);
}

#[test]
fn the_textured_box_reads_its_external_buffer_and_png() {
    let s = load("BoxTextured/BoxTextured.gltf");
    assert_eq!(s.faces.len(), 12);
    assert_eq!(s.textures.len(), 1);
    assert_eq!((s.textures[0].width, s.textures[0].height), (211, 211));
    let m = &s.materials[0];
    assert!(m.diffuse_map.is_some() && m.alpha_map.is_none());
    assert!(
        close(m.reflectance, Rgb::splat(0.95), 1e-12),
        "factor 1 clamps like Kd 1"
    );
    assert!(
        s.faces
            .iter()
            .all(|f| f.uvs.as_ref().is_some_and(|uv| uv.len() == 3))
    );
    let b = s.bounds();
    assert!(close(b.min, DVec3::splat(-0.5), 1e-6) && close(b.max, DVec3::splat(0.5), 1e-6));
    // TEXCOORD_0 spans u 0..6, v 0..1 in glTF; flipped, v stays in [0, 1].
    let vs = s
        .faces
        .iter()
        .flat_map(|f| f.uvs.clone().unwrap())
        .map(|uv| uv.y);
    assert!(vs.clone().all(|v| (0.0..=1.0).contains(&v)));
    assert!(s.faces.iter().all(|f| polygon::area(&f.vertices) > 0.49));
}

#[test]
fn the_depth_of_field_scene_has_its_lava_and_sun() {
    let p = model("DepthOfFieldExample/DepthOfFieldExample.glb");
    let s = load("DepthOfFieldExample/DepthOfFieldExample.glb");
    let dropped: usize = s
        .warnings
        .iter()
        .filter_map(|w| {
            w.split("dropped ")
                .nth(1)?
                .split(' ')
                .next()?
                .parse::<usize>()
                .ok()
        })
        .sum();
    assert_eq!(s.faces.len() + dropped, 10_610, "{:?}", s.warnings);
    assert!(dropped < 10, "{dropped}");
    assert!(s.two_sided);
    // Two base colour textures (CircuitBoard, Lava) kept; the emissive one only averaged.
    assert_eq!(s.textures.len(), 2);
    // Lava: 20 × the emissive texture's mean linear colour, computed here from the PNG.
    let bytes = std::fs::read(&p).expect("read");
    let j = glb_json(&bytes);
    let tex = j["materials"][1]["emissiveTexture"]["index"]
        .as_u64()
        .unwrap() as usize;
    let img = j["textures"][tex]["source"].as_u64().unwrap() as usize;
    let view = &j["bufferViews"][j["images"][img]["bufferView"].as_u64().unwrap() as usize];
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let bin = 20 + json_len + 8;
    let off = bin + view["byteOffset"].as_u64().unwrap_or(0) as usize;
    let png = &bytes[off..off + view["byteLength"].as_u64().unwrap() as usize];
    let rgb = image::load_from_memory(png).expect("png").to_rgb8();
    let n = (rgb.width() * rgb.height()) as f64;
    let mut mean = Rgb::ZERO;
    for px in rgb.pixels() {
        mean += Rgb::from_array(px.0.map(|c| srgb_to_linear(c as f64 / 255.0))) / n;
    }
    let lava = material(&s, "Lava");
    assert!(
        close(lava.emission, mean * 20.0, 1e-4),
        "{} vs {}",
        lava.emission,
        mean * 20.0
    );
    assert!(lava.emission.max_element() > 0.5);
    let suns: Vec<_> = s
        .lights
        .iter()
        .filter_map(|l| match *l {
            Light::Sun {
                irradiance,
                direction,
                ..
            } => Some((irradiance, direction)),
            _ => None,
        })
        .collect();
    assert_eq!((suns.len(), s.lights.len()), (1, 1));
    // 6830 lux = 10 W/m² (a Blender sun of strength 10); it comes from the node's +Z.
    assert!(close(suns[0].0, Rgb::splat(10.0), 1e-9), "{}", suns[0].0);
    let q = DQuat::from_xyzw(
        -0.7903246879577637,
        -0.12885604798793793,
        0.1780683547258377,
        0.5719045400619507,
    );
    assert!(
        close(suns[0].1, q.normalize() * DVec3::Z, 1e-6),
        "{}",
        suns[0].1
    );
    assert!(suns[0].1.y > 0.5, "the sun is above the scene");
}

// ---- small files built here ----

fn b64(data: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A glTF document with one mesh of `positions` (and `uvs`, `indices` if given) in one
/// buffer, and the nodes, materials and extensions of `extra` merged into it.
fn document(
    positions: &[[f32; 3]],
    uvs: &[[f32; 2]],
    indices: &[u16],
    extra: Value,
) -> (Value, Vec<u8>) {
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let pos_len = bin.len();
    bin.extend(uvs.iter().flatten().flat_map(|x| x.to_le_bytes()));
    let uv_len = bin.len() - pos_len;
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let idx_len = bin.len() - pos_len - uv_len;
    // Room for the one-byte views left empty, padded to 4 bytes.
    bin.push(0);
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut attributes = json!({"POSITION": 0});
    let (lo, hi) = positions
        .iter()
        .fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
            (
                std::array::from_fn(|k| lo[k].min(p[k])),
                std::array::from_fn(|k| hi[k].max(p[k])),
            )
        });
    let mut accessors = vec![
        json!({"bufferView": 0, "componentType": 5126, "count": positions.len(),
        "type": "VEC3", "min": lo, "max": hi}),
    ];
    if !uvs.is_empty() {
        attributes["TEXCOORD_0"] = json!(1);
        accessors.push(
            json!({"bufferView": 1, "componentType": 5126, "count": uvs.len(), "type": "VEC2"}),
        );
    }
    let mut prim = json!({"attributes": attributes, "material": 0});
    if !indices.is_empty() {
        prim["indices"] = json!(accessors.len());
        accessors.push(json!({"bufferView": 2, "componentType": 5123, "count": indices.len(), "type": "SCALAR"}));
    }
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"name": "m", "primitives": [prim]}],
        "materials": [{"name": "white", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}}],
        "accessors": accessors,
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": pos_len},
            {"buffer": 0, "byteOffset": pos_len, "byteLength": uv_len.max(1)},
            {"buffer": 0, "byteOffset": pos_len + uv_len, "byteLength": idx_len.max(1)}
        ],
        "buffers": [{"byteLength": bin.len()}]
    });
    for (k, v) in extra.as_object().cloned().unwrap_or_default() {
        doc[k] = v;
    }
    (doc, bin)
}

/// The document as a `.gltf` with its buffer in a data URI.
fn embedded(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut doc = doc.clone();
    doc["buffers"][0]["uri"] = json!(format!("data:application/octet-stream;base64,{}", b64(bin)));
    serde_json::to_vec(&doc).unwrap()
}

/// The document as a `.glb`.
fn glb(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(doc).unwrap();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend(((12 + 8 + j.len() + 8 + bin.len()) as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&j);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(bin);
    out
}

fn parse(bytes: &[u8]) -> Result<Scene, nusselt_core::scene::SceneError> {
    from_slice(bytes, "test.gltf", Path::new("."), &LoadOptions::default())
}

/// A triangle in z = 0, counter-clockwise seen from +z.
const TRI: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

fn normal_under(nodes: Value) -> DVec3 {
    let (doc, bin) = document(&TRI, &[], &[], json!({"nodes": nodes}));
    let s = parse(&embedded(&doc, &bin)).expect("loads");
    assert_eq!(s.faces.len(), 1);
    polygon::normal(&s.faces[0].vertices).expect("normal")
}

#[test]
fn a_mirroring_node_flips_the_winding_back() {
    // No transform: the front faces +z.
    assert!(close(normal_under(json!([{"mesh": 0}])), DVec3::Z, 1e-12));
    // Mirrored in x: the vertices alone would turn the front to −z; glTF keeps it at +z.
    let n = normal_under(json!([{"mesh": 0, "scale": [-1.0, 1.0, 1.0]}]));
    assert!(close(n, DVec3::Z, 1e-12), "{n}");
    // Mirrored in z: the vertices stay, the front turns to −z.
    let n = normal_under(json!([{"mesh": 0, "scale": [1.0, 1.0, -1.0]}]));
    assert!(close(n, DVec3::NEG_Z, 1e-12), "{n}");
    // Two mirrors down the tree (a matrix, then TRS) cancel; the translation composes.
    let nodes = json!([
        {"children": [1], "matrix": [-1,0,0,0, 0,1,0,0, 0,0,1,0, 5,0,0,1]},
        {"mesh": 0, "scale": [-1.0, 1.0, 1.0], "translation": [0.0, 2.0, 0.0]}
    ]);
    let (doc, bin) = document(&TRI, &[], &[], json!({"nodes": nodes}));
    let s = parse(&embedded(&doc, &bin)).expect("loads");
    let f = &s.faces[0];
    assert!(close(
        polygon::normal(&f.vertices).unwrap(),
        DVec3::Z,
        1e-12
    ));
    // x ↦ 5 − (−x) = 5 + x; y ↦ y + 2.
    assert!(
        close(f.vertices[1], DVec3::new(6.0, 2.0, 0.0), 1e-12),
        "{:?}",
        f.vertices
    );
}

/// 683 cd is 1 W/sr and 683 lux 1 W/m²; a Blender point of P W, exported as P/4π × 683 cd,
/// comes back as the intensity P/4π W/sr it radiates.
#[test]
fn photometric_lights_convert_at_683_lumens_per_watt() {
    let p_watts = 100.0;
    let blender_cd = p_watts / (4.0 * std::f64::consts::PI) * 683.0;
    let extra = json!({
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1.0, 0.5, 0.0], "intensity": 683.0},
            {"type": "directional", "intensity": 683.0},
            {"type": "point", "intensity": blender_cd, "range": 10.0}
        ]}},
        "nodes": [
            {"mesh": 0},
            {"translation": [0.0, 3.0, 0.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"extensions": {"KHR_lights_punctual": {"light": 1}}},
            {"extensions": {"KHR_lights_punctual": {"light": 2}}}
        ],
        "scenes": [{"nodes": [0, 1, 2, 3]}]
    });
    let (doc, bin) = document(&TRI, &[], &[], extra);
    let s = parse(&embedded(&doc, &bin)).expect("loads");
    let Light::Point {
        position,
        intensity,
        cone: None,
    } = s.lights[0]
    else {
        panic!("{:?}", s.lights[0]);
    };
    assert!(close(position, DVec3::new(0.0, 3.0, 0.0), 1e-12));
    assert!(
        close(intensity, Rgb::new(1.0, 0.5, 0.0), 1e-12),
        "{intensity}"
    );
    let Light::Sun {
        direction,
        irradiance,
        ..
    } = s.lights[1]
    else {
        panic!("{:?}", s.lights[1]);
    };
    assert!(close(irradiance, Rgb::ONE, 1e-12) && close(direction, DVec3::Z, 1e-12));
    let Light::Point { intensity, .. } = s.lights[2] else {
        panic!("{:?}", s.lights[2]);
    };
    let want = p_watts / (4.0 * std::f64::consts::PI);
    assert!(
        close(intensity, Rgb::splat(want), 1e-4),
        "{intensity} vs {want}"
    );
    assert!(
        s.warnings.iter().any(|w| w.contains("range")),
        "{:?}",
        s.warnings
    );
    // The same lights given by flags (`--point X,Y,Z,R,G,B`, `--sun X,Y,Z,R,G,B`) are the
    // same lights: 683 cd of orange at (0, 3, 0) is 1 W/sr, 683 lux from +z is 1 W/m².
    let by_flags = [
        Light::parse_point("0,3,0,1,0.5,0").expect("point"),
        Light::parse_sun("0,0,1,1,1,1").expect("sun"),
    ];
    for (flag, file) in by_flags.iter().zip(&s.lights) {
        assert_eq!(flag, file, "by flags {flag:?}, from the glTF file {file:?}");
    }
}

/// A 2 × 2 PNG, top row red and bottom row blue, on a unit quad with glTF's uv (0, 0) at the
/// image's top-left: the quad's top (y = 1, glTF v = 0) reads red. The points read are the
/// texel centres (y = 0.75 and 0.25), where the bilinear sample is the texel itself.
#[test]
fn texture_coordinates_follow_gltfs_top_left_origin() {
    let mut png = Vec::new();
    let img = image::RgbaImage::from_fn(2, 2, |_, y| {
        if y == 0 {
            image::Rgba([255, 0, 0, 255])
        } else {
            image::Rgba([0, 0, 255, 40])
        }
    });
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let quad = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let uvs = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let material = |mode: &str| {
        json!([{
            "alphaMode": mode,
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}
        }])
    };
    for mode in ["OPAQUE", "MASK"] {
        let extra = json!({
            "materials": material(mode),
            "textures": [{"source": 0}],
            "images": [{"uri": format!("data:image/png;base64,{}", b64(&png))}]
        });
        let (doc, bin) = document(&quad, &uvs, &[0, 1, 2, 0, 2, 3], extra);
        let s = parse(&glb(&doc, &bin)).expect("loads");
        assert_eq!(s.faces.len(), 2);
        let top = s
            .faces
            .iter()
            .position(|f| f.vertices.iter().any(|v| v.x == 0.0 && v.y == 1.0))
            .unwrap();
        let (colour, alpha) = s.texel(top, DVec3::new(0.25, 0.75, 0.0)).expect("textured");
        assert!(colour.x > 0.9 && colour.z < 0.1, "{mode}: {colour}");
        assert_eq!(alpha, 1.0);
        let (colour, alpha) = s.texel(top, DVec3::new(0.25, 0.25, 0.0)).expect("textured");
        assert!(colour.z > 0.9 && colour.x < 0.1, "{mode}: {colour}");
        // The bottom row's alpha 40/255 counts only under MASK.
        assert_eq!(alpha, if mode == "MASK" { 0.0 } else { 1.0 }, "{mode}");
        assert_eq!(s.materials[0].alpha_map.is_some(), mode == "MASK");
    }
}

#[test]
fn transmission_and_blend_make_glass_and_mixed_sides_get_back_faces() {
    let extra = json!({
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior"],
        "materials": [
            {"extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.33}}, "doubleSided": true},
            {"alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.3]}}
        ],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0}, "material": 0},
            {"attributes": {"POSITION": 0}, "material": 1},
            {"attributes": {"POSITION": 0}, "material": 1, "mode": 1}
        ]}]
    });
    let (doc, bin) = document(&TRI, &[], &[], extra);
    let s = parse(&embedded(&doc, &bin)).expect("loads");
    assert_eq!(
        s.materials[0].surface,
        Surface::Glass {
            ior: f64::from(1.33_f32)
        }
    );
    assert_eq!(s.materials[1].surface, Surface::Glass { ior: 1.5 });
    assert!(!s.two_sided);
    // The double-sided material's triangle and its reversed copy, and the other's.
    assert_eq!(s.faces.len(), 3);
    let n = |k: usize| polygon::normal(&s.faces[k].vertices).unwrap();
    assert!(close(n(2), -n(0), 1e-12) && s.faces[2].material == s.faces[0].material);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("meshes[0].primitives[2]") && w.contains("Lines")),
        "{:?}",
        s.warnings
    );
}

// ---- OBJ and glTF agree ----

/// The unit box as 12 triangles, the top two a second material: the same faces written as
/// OBJ and as glTF (shifted by a node's translation) load to the same areas, normals and
/// reflectances.
#[test]
fn the_same_box_as_obj_and_gltf_loads_the_same() {
    let corners: Vec<[f32; 3]> = (0..8)
        .map(|i| [(i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2 & 1) as f32])
        .collect();
    // Outward counter-clockwise quads (indices into corners), the last one the top (+y).
    let quads = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [2, 6, 7, 3],
    ];
    let tris: Vec<[u16; 3]> = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    let shift = [1.0f32, 2.0, 3.0];
    let mut obj = String::from("mtllib box.mtl\n");
    for c in &corners {
        obj += &format!(
            "v {} {} {}\n",
            c[0] + shift[0],
            c[1] + shift[1],
            c[2] + shift[2]
        );
    }
    for (k, t) in tris.iter().enumerate() {
        if k == 0 || k == 10 {
            obj += if k == 0 {
                "usemtl grey\n"
            } else {
                "usemtl red\n"
            };
        }
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    let mtl = "newmtl grey\nKd 0.5 0.5 0.5\nnewmtl red\nKd 0.7 0.1 0.1\n";
    let o = Scene::from_obj_str(
        "box.obj",
        &obj,
        &[("box.mtl", mtl)],
        &LoadOptions::default(),
    )
    .expect("obj");
    let idx: Vec<u16> = tris.iter().flatten().copied().collect();
    let extra = json!({
        "nodes": [{"mesh": 0, "translation": shift}],
        "materials": [
            {"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}},
            {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.1, 0.1, 1]}}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]},
            {"bufferView": 2, "componentType": 5123, "count": 30, "type": "SCALAR"},
            {"bufferView": 2, "byteOffset": 60, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0}, "indices": 1, "material": 0},
            {"attributes": {"POSITION": 0}, "indices": 2, "material": 1}
        ]}]
    });
    let (doc, bin) = document(&corners, &[], &idx, extra);
    let g = parse(&glb(&doc, &bin)).expect("gltf");
    assert_eq!((o.faces.len(), g.faces.len()), (12, 12));
    for (a, b) in o.faces.iter().zip(&g.faces) {
        let (na, nb) = (
            polygon::normal(&a.vertices).unwrap(),
            polygon::normal(&b.vertices).unwrap(),
        );
        assert!(close(na, nb, 1e-12), "{na} vs {nb}");
        assert!((polygon::area(&a.vertices) - polygon::area(&b.vertices)).abs() < 1e-12);
        assert!(close(
            polygon::centroid(&a.vertices),
            polygon::centroid(&b.vertices),
            1e-6
        ));
        let (ma, mb) = (
            &o.materials[a.material.0 as usize],
            &g.materials[b.material.0 as usize],
        );
        assert_eq!(ma.name, mb.name);
        assert!(close(ma.reflectance, mb.reflectance, 1e-7), "{}", ma.name);
    }
    // Outward: every normal points away from the box's centre.
    let c = DVec3::new(1.5, 2.5, 3.5);
    assert!(g.faces.iter().all(|f| {
        (polygon::centroid(&f.vertices) - c).dot(polygon::normal(&f.vertices).unwrap()) > 0.0
    }));
}

// ---- bad files ----

#[track_caller]
fn error(bytes: &[u8]) -> String {
    parse(bytes).map(|_| ()).expect_err("refused").to_string()
}

#[test]
fn bad_files_are_errors_naming_the_file_and_json_path() {
    let (doc, bin) = document(&TRI, &[], &[0, 1, 2], json!({}));
    let good = glb(&doc, &bin);
    assert!(parse(&good).is_ok());
    let e = error(&good[..good.len() - 6]);
    assert!(e.starts_with("test.gltf: "), "{e}");
    let e = error(b"{\"asset\": {\"version\": \"2.0\"");
    assert!(e.contains("test.gltf") && e.contains("glTF"), "{e}");
    // A buffer file that is not there.
    let mut d = doc.clone();
    d["buffers"][0]["uri"] = json!("missing.bin");
    let e = error(&serde_json::to_vec(&d).unwrap());
    assert!(
        e.contains("buffers[0].uri") && e.contains("missing.bin"),
        "{e}"
    );
    // An index past the last vertex.
    let (d, b) = document(&TRI, &[], &[0, 1, 7], json!({}));
    let e = error(&embedded(&d, &b));
    assert!(
        e.contains("meshes[0].primitives[0].indices") && e.contains("index 7"),
        "{e}"
    );
    // TEXCOORD_0 with fewer elements than POSITION (a textured material asks for it).
    let extra = json!({"materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0}], "images": [{"uri": "none.png"}]});
    let (mut d, b) = document(&TRI, &[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], &[], extra);
    d["accessors"][1]["count"] = json!(2);
    let e = error(&embedded(&d, &b));
    assert!(
        e.contains("meshes[0].primitives[0].attributes.TEXCOORD_0") && e.contains("has 2 elements"),
        "{e}"
    );
    // An accessor longer than its view.
    let mut d = doc.clone();
    d["accessors"][0]["count"] = json!(4);
    let e = error(&embedded(&d, &bin));
    assert!(
        e.contains("meshes[0].primitives[0].attributes.POSITION") && e.contains("run past"),
        "{e}"
    );
    // A NaN position.
    let (d, b) = document(
        &[[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[],
        &[],
        json!({}),
    );
    let e = error(&embedded(&d, &b));
    assert!(
        e.contains("meshes[0].primitives[0].attributes.POSITION") && e.contains("vertex 1"),
        "{e}"
    );
    // An out-of-range reference, caught by the parser's validation with its path.
    let mut d = doc.clone();
    d["meshes"][0]["primitives"][0]["material"] = json!(9);
    let e = error(&embedded(&d, &bin));
    assert!(e.contains("meshes[0].primitives[0].material"), "{e}");
    // POSITION naming an accessor that is not there.
    let mut d = doc.clone();
    d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(5);
    let e = error(&embedded(&d, &bin));
    assert!(
        e.contains("meshes[0].primitives[0].attributes.POSITION: accessors[5] does not exist"),
        "{e}"
    );
    // A node that is its own grandchild.
    let mut d = doc.clone();
    d["nodes"] = json!([{"children": [1]}, {"mesh": 0, "children": [0]}]);
    let e = error(&embedded(&d, &bin));
    assert!(e.contains("nodes["), "{e}");
    // Only lines: nothing left to load.
    let mut d = doc.clone();
    d["meshes"][0]["primitives"][0]["mode"] = json!(1);
    let e = error(&embedded(&d, &bin));
    assert!(e.contains("no triangles"), "{e}");
    // An unknown extension.
    let e = Scene::load(Path::new("model.fbx"), &LoadOptions::default())
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("model.fbx") && e.contains(".gltf") && e.contains(".obj"),
        "{e}"
    );
}

/// Hundreds of truncated and byte-flipped versions of a small GLB (seeded): every one loads
/// or is refused, none panics.
#[test]
fn mutated_glbs_load_or_are_refused_without_panicking() {
    let quad = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let uvs = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
    let extra = json!({"materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "alphaMode": "MASK"}],
        "textures": [{"source": 0}], "images": [{"bufferView": 2, "mimeType": "image/png"}]});
    let (doc, bin) = document(&quad, &uvs, &[0, 1, 2, 0, 2, 3], extra);
    let good = glb(&doc, &bin);
    assert!(parse(&good).is_ok());
    let mut rng = Rng::new(2024, 0);
    let (mut ok, mut refused) = (0, 0);
    for k in 0..400 {
        let mut m = good.clone();
        if k % 4 == 0 {
            m.truncate((rng.next_f64() * good.len() as f64) as usize);
        } else {
            for _ in 0..1 + k % 5 {
                let i = (rng.next_f64() * m.len() as f64) as usize % m.len();
                m[i] ^= 1 << (rng.next_u32() % 8);
            }
        }
        match parse(&m) {
            Ok(_) => ok += 1,
            Err(_) => refused += 1,
        }
    }
    eprintln!("mutated GLBs: {ok} loaded, {refused} refused");
    assert!(refused > 100 && ok > 10, "{ok} {refused}");
}

/// A scene file whose model is a glTF: saved from the loaded scene and opened again, it has
/// the model's four lights once (not added twice) with the spots' cones kept.
#[test]
fn a_saved_scene_of_a_gltf_model_keeps_its_lights_once() {
    use nusselt_core::scene::SceneFile;
    let s = load("Lights/Lights.glb");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("lights.json");
    let file = SceneFile::describe(&s, None, &path);
    assert!(file.replaces_model_lights);
    file.save(&path).expect("save");
    let again = SceneFile::read(&path)
        .expect("read")
        .load(&path)
        .expect("load");
    assert_eq!(again.lights.len(), 4);
    for (a, b) in s.lights.iter().zip(&again.lights) {
        match (a, b) {
            (
                Light::Point {
                    cone: Some(x),
                    intensity: i,
                    ..
                },
                Light::Point {
                    cone: Some(y),
                    intensity: j,
                    ..
                },
            ) => {
                assert!(close(x.direction, y.direction, 1e-9) && (x.outer - y.outer).abs() < 1e-9);
                assert!(close(*i, *j, 1e-12));
            }
            (a, b) => assert_eq!(std::mem::discriminant(a), std::mem::discriminant(b)),
        }
    }
    // Written by hand, without the flag, the file's lights add to the model's.
    let hand = format!(
        r#"{{"model": {:?}, "lights": [{{"type": "point", "position": [0, 3, 0], "intensity": [1, 1, 1],
            "spot": {{"direction": [0, -1, 0], "inner_cone_deg": 10, "outer_cone_deg": 20}}}}]}}"#,
        model("Lights/Lights.glb").display().to_string()
    );
    std::fs::write(&path, hand).expect("write");
    let added = SceneFile::read(&path)
        .expect("read")
        .load(&path)
        .expect("load");
    assert_eq!(added.lights.len(), 5);
    let Light::Point { cone: Some(c), .. } = added.lights[4] else {
        panic!("{:?}", added.lights[4])
    };
    assert!(
        (c.outer - 20f64.to_radians()).abs() < 1e-12 && close(c.direction, DVec3::NEG_Y, 1e-12)
    );
}

/// Found by fuzzing (`fuzz/`, target `gltf_solve`, 2026-12-04): a GLB whose chunk lengths
/// overflow the gltf crate's header arithmetic (it panics on `attempt to subtract with
/// overflow` where overflow checks are on). The importer catches it: an error naming the
/// file, never a panic.
#[test]
fn a_glb_whose_header_overflows_is_an_error() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/fuzz/glb_header_overflow.glb");
    let bytes = std::fs::read(&path).expect("fuzz input");
    let dir = tempfile::tempdir().expect("temp dir");
    let err = from_slice(&bytes, "overflow.glb", dir.path(), &LoadOptions::default())
        .expect_err("a malformed GLB");
    assert!(err.to_string().contains("overflow.glb"), "{err}");
}
