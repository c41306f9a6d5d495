//! Line-by-line checks of OBJ/MTL text before `tobj` parses it, and geometry checks after.
//!
//! `tobj` panics on some malformed input (a one-number `Kd 0.5`) and reports others without a
//! line number, so every statement Nusselt relies on is checked here first and errors name
//! `file:line`. Parsing itself is `tobj`'s.
//! Specular statements are checked and turned into a [`Surface`] by [`super::specular`].

use std::collections::HashMap;
use std::io::BufReader;

use glam::{DVec2, DVec3};

use super::maps::{self, MapRequest, MapStatement, Slot};
use super::obj_scan::{ObjScan, check_numbers, material_key, parse_err, scan_obj, words};
use super::specular::{SpecularScan, surface};
use super::{
    CLAMPED_REFLECTANCE, Face, LoadOptions, MAX_REFLECTANCE, Material, MaterialId, Scene,
    SceneError, Surface, UvTransform, clamp_reflectance,
};
use crate::geometry::polygon;

/// Relative non-planarity (vertex distance from the best-fit plane over the face size)
/// above which a face is split into triangles. The published Cornell Box red wall is off
/// by 1.4e-3 and stays one face.
const NON_PLANAR_TOLERANCE: f64 = 2.5e-3;

/// `words` as `min..=max` finite numbers ([`check_numbers`]).
fn numbers(
    file: &str,
    line: usize,
    what: &str,
    words: &[&str],
    min: usize,
    max: usize,
) -> Result<Vec<f64>, SceneError> {
    check_numbers(file, line, what, words, min, max)?;
    Ok(words.iter().filter_map(|w| w.parse().ok()).collect())
}

fn statements(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines().enumerate().filter_map(|(i, raw)| {
        let words: Vec<&str> = words(raw).collect();
        (!words.is_empty()).then_some((i + 1, words))
    })
}

/// What the MTL pre-scan learned about one material.
#[derive(Default)]
struct MtlEntry {
    name: String,
    file: String,
    kd: Option<([f64; 3], usize)>,
    diffuse: Option<(MapStatement, usize)>,
    alpha: Option<(MapStatement, usize)>,
}

/// Checks a colour statement (`Kd`, `Ka`, `Ks`, `Ke`, `Tf`): three non-negative numbers.
fn colour(file: &str, line: usize, key: &str, args: &[&str]) -> Result<[f64; 3], SceneError> {
    if args
        .first()
        .is_some_and(|w| *w == "spectral" || *w == "xyz")
    {
        return Err(parse_err(
            file,
            line,
            format!("'{key} {}' is not supported; give r g b", args[0]),
        ));
    }
    if args.len() != 3 {
        let hint = if args.len() == 1 {
            format!("; write '{key} {0} {0} {0}' for grey", args[0])
        } else {
            String::new()
        };
        return Err(parse_err(
            file,
            line,
            format!(
                "'{key}' needs 3 numbers (r g b), found {}{hint}",
                args.len()
            ),
        ));
    }
    let v = numbers(file, line, key, args, 3, 3)?;
    if v.iter().any(|x| *x < 0.0) {
        return Err(parse_err(
            file,
            line,
            format!(
                "'{key}' values must not be negative, got {} {} {}",
                v[0], v[1], v[2]
            ),
        ));
    }
    Ok([v[0], v[1], v[2]])
}

/// Parses a `map_Kd`/`map_d` statement, warning about the options that are ignored.
fn map_statement(
    file: &str,
    line: usize,
    key: &str,
    args: &[&str],
    warnings: &mut Vec<String>,
) -> Result<MapStatement, SceneError> {
    let m = maps::parse_map(args).map_err(|e| parse_err(file, line, format!("'{key}': {e}")))?;
    if !m.ignored.is_empty() {
        warnings.push(format!(
            "{file}:{line}: '{key}' option(s) {} ignored (only -s and -o are applied)",
            m.ignored.join(", ")
        ));
    }
    Ok(m)
}

fn scan_mtl(
    file: &str,
    text: &str,
    warnings: &mut Vec<String>,
    entries: &mut HashMap<String, MtlEntry>,
) -> Result<(), SceneError> {
    let mut current: Option<MtlEntry> = None;
    let mut specular = SpecularScan::default();
    let mut done: Vec<MtlEntry> = Vec::new();
    for (line, words) in statements(text) {
        let args = &words[1..];
        let key = words[0];
        if key != "newmtl" && current.is_none() && is_material_statement(key) {
            return Err(parse_err(
                file,
                line,
                format!("'{key}' before any 'newmtl'"),
            ));
        }
        match key {
            "newmtl" => {
                if args.is_empty() {
                    return Err(parse_err(file, line, "'newmtl' needs a material name"));
                }
                specular.finish(file, warnings);
                done.extend(current.take());
                let name = args.join(" ");
                current = Some(MtlEntry {
                    name: name.clone(),
                    file: file.to_string(),
                    ..Default::default()
                });
                specular = SpecularScan {
                    name,
                    ..Default::default()
                };
            }
            "Kd" | "Ka" | "Ks" | "Ke" | "Tf" => {
                let v = colour(file, line, key, args)?;
                if key == "Kd" {
                    specular.kd = Some(v);
                    if let Some(m) = current.as_mut() {
                        m.kd = Some((v, line));
                    }
                }
                if key == "Ks" {
                    specular.ks = Some((v, line));
                }
            }
            k if k.eq_ignore_ascii_case("map_Kd") || k == "map_d" => {
                let m = map_statement(file, line, key, args, warnings)?;
                if let Some(entry) = current.as_mut() {
                    if k == "map_d" {
                        entry.alpha = Some((m, line));
                    } else {
                        entry.diffuse = Some((m, line));
                    }
                }
            }
            "Ns" | "Ni" | "d" | "Tr" | "illum" | "sharpness" => {
                let x = numbers(file, line, key, args, 1, 1)?[0];
                specular
                    .number(key, x, line)
                    .map_err(|message| parse_err(file, line, message))?;
            }
            _ => {}
        }
    }
    specular.finish(file, warnings);
    done.extend(current.take());
    warnings.extend(clamp_warning(file, &done));
    for m in done {
        entries.insert(material_key(&m.name), m);
    }
    Ok(())
}

/// Statements that belong to a material and so need a `newmtl` before them.
fn is_material_statement(key: &str) -> bool {
    matches!(key, "Kd" | "Ka" | "Ks" | "Ke" | "Tf")
}

/// One warning for a file's materials whose `Kd` was lowered (see [`clamp_reflectance`]).
fn clamp_warning(file: &str, materials: &[MtlEntry]) -> Option<String> {
    let (mut clamped, mut placeholder, mut lowered) = (Vec::new(), Vec::new(), Vec::new());
    for m in materials {
        let Some((kd, line)) = m.kd else { continue };
        let named = format!("'{}' (line {line})", m.name);
        if kd == [1.0; 3] && m.diffuse.is_some() {
            placeholder.push(named);
        } else if kd.iter().any(|&x| x >= 1.0) {
            clamped.push(named);
        } else if kd.iter().any(|&x| x > MAX_REFLECTANCE) {
            lowered.push(named);
        }
    }
    let mut parts = Vec::new();
    if !clamped.is_empty() {
        parts.push(format!(
            "Kd channels >= 1 clamped to {CLAMPED_REFLECTANCE} in {}",
            clamped.join(", ")
        ));
    }
    if !placeholder.is_empty() {
        parts.push(format!(
            "Kd 1 1 1 with a map_Kd, probably a placeholder for a texture, clamped to {CLAMPED_REFLECTANCE} (the texture multiplies it) in {}",
            placeholder.join(", ")
        ));
    }
    if !lowered.is_empty() {
        parts.push(format!(
            "Kd lowered to {MAX_REFLECTANCE} in {}",
            lowered.join(", ")
        ));
    }
    (!parts.is_empty()).then(|| {
        format!(
            "{file}: reflectance of 1 or more never converges (the surface would reflect all the light it gets): {}",
            parts.join("; ")
        )
    })
}

/// Returns (display name, text) of a named material library.
pub(super) type MtlReader<'a> = dyn FnMut(&str) -> Result<(String, String), SceneError> + 'a;

/// Loads OBJ text; `read_mtl` returns (display name, text) of a named material library.
/// Also returns the texture maps the materials in use ask for (not read here).
pub(super) fn load<T: Send>(
    file: &str,
    text: &str,
    read_mtl: &mut MtlReader,
    opts: &LoadOptions,
    beside: impl FnOnce(Vec<MapRequest>) -> T + Send,
) -> Result<(Scene, Vec<MapRequest>, T), SceneError> {
    let scan = scan_obj(file, text)?;
    let mut warnings = scan.warnings.clone();
    let mut mtl_texts: HashMap<String, String> = HashMap::new();
    let mut entries: HashMap<String, MtlEntry> = HashMap::new();
    for (lib, line) in &scan.mtllibs {
        let (mtl_file, mtl_text) = read_mtl(lib).map_err(|e| match e {
            SceneError::Io { path, source } => parse_err(
                file,
                *line,
                format!("cannot read material library {}: {source}", path.display()),
            ),
            other => other,
        })?;
        scan_mtl(&mtl_file, &mtl_text, &mut warnings, &mut entries)?;
        mtl_texts.insert(lib.clone(), mtl_text);
    }
    if scan.face_lines.is_empty() {
        return Err(SceneError::Invalid {
            file: file.to_string(),
            message: "no faces: the file is empty or has only points and lines".into(),
        });
    }
    // The maps of the materials `usemtl` names are known before the faces are: `beside`
    // (the file loader reads them) runs while the faces are parsed.
    let ahead = ahead_requests(&scan.usemtl, &entries);
    let (side, parsed) = rayon::join(|| beside(ahead), || parse(file, text, &scan, &mtl_texts));
    let (models, tmats) = parsed?;
    let mut materials: Vec<Material> = tmats
        .iter()
        .map(|m| material(m, entries.get(&material_key(&m.name))))
        .collect();
    let built = build_faces(&models, &scan, &mut materials);
    warnings.extend(built.warnings(file));
    if built.faces.is_empty() {
        return Err(SceneError::Invalid {
            file: file.to_string(),
            message: format!(
                "no usable faces ({} zero-area face(s) dropped)",
                built.dropped
            ),
        });
    }
    let requests = map_requests(&tmats, &entries, &built.faces);
    let scene = Scene {
        name: String::new(),
        faces: built.faces,
        materials,
        two_sided: opts.two_sided,
        camera: None,
        warnings,
        source: None,
        textures: Vec::new(),
        texture_bytes: 0,
        lights: Vec::new(),
    };
    Ok((scene, requests, side))
}

/// The maps of the MTL materials in `used` (before the faces say which are used, so
/// `material` is not yet an index: `usize::MAX`).
fn ahead_requests(
    used: &std::collections::HashSet<String>,
    entries: &HashMap<String, MtlEntry>,
) -> Vec<MapRequest> {
    (entries.iter())
        .filter(|(k, _)| used.contains(*k))
        .flat_map(|(_, e)| entry_requests(e, usize::MAX))
        .collect()
}

/// The maps (diffuse, then alpha) MTL entry `e` asks for, as requests of `material`.
fn entry_requests(e: &MtlEntry, material: usize) -> impl Iterator<Item = MapRequest> + '_ {
    [(Slot::Diffuse, &e.diffuse), (Slot::Alpha, &e.alpha)]
        .into_iter()
        .filter_map(move |(slot, map)| {
            map.as_ref().map(|(statement, line)| MapRequest {
                material,
                slot,
                name: statement.name.clone(),
                mtl_file: e.file.clone(),
                line: *line,
            })
        })
}

/// `tobj`'s parse of the checked text: the models and the materials.
fn parse(
    file: &str,
    text: &str,
    scan: &ObjScan,
    mtl_texts: &HashMap<String, String>,
) -> Result<(Vec<tobj::Model>, Vec<tobj::Material>), SceneError> {
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let loader = |p: &std::path::Path| {
        let key = p.to_string_lossy().into_owned();
        match mtl_texts.get(&key) {
            Some(t) => tobj::load_mtl_buf(&mut BufReader::new(t.as_bytes())),
            None => Err(tobj::LoadError::OpenFileFailed),
        }
    };
    // The pre-scan rejects the input tobj is known to panic on; this is a second net.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut BufReader::new(text.as_bytes()), &options, loader)
    }))
    .map_err(|_| SceneError::Invalid {
        file: file.to_string(),
        message: "the OBJ parser failed on this file (malformed input)".into(),
    })?;
    let (models, materials) = parsed.map_err(|e| SceneError::Invalid {
        file: file.to_string(),
        message: format!("OBJ parse error: {e}"),
    })?;
    match materials {
        Ok(m) => Ok((models, m)),
        Err(_) if scan.mtllibs.is_empty() => Ok((models, Vec::new())),
        Err(e) => Err(SceneError::Invalid {
            file: file.to_string(),
            message: format!("material library error: {e}"),
        }),
    }
}

/// A material from `tobj`'s and the pre-scan's view of it. Without `Kd`, a textured
/// material reflects its texture (times [`CLAMPED_REFLECTANCE`]), an untextured one grey 0.5.
fn material(m: &tobj::Material, entry: Option<&MtlEntry>) -> Material {
    let textured = entry.is_some_and(|e| e.diffuse.is_some());
    let default_kd = if textured { CLAMPED_REFLECTANCE } else { 0.5 };
    let kd = m
        .diffuse
        .map_or(DVec3::splat(default_kd), |d| DVec3::new(d[0], d[1], d[2]));
    let ke = m
        .emissive
        .map_or(DVec3::ZERO, |d| DVec3::new(d[0], d[1], d[2]));
    let reflectance = DVec3::from_array(kd.to_array().map(clamp_reflectance));
    let transform =
        |map: Option<&(MapStatement, usize)>| map.map_or(UvTransform::default(), |m| m.0.transform);
    Material {
        name: m.name.clone(),
        reflectance,
        emission: ke,
        surface: surface(m, reflectance),
        diffuse_map: None,
        alpha_map: None,
        diffuse_uv: transform(entry.and_then(|e| e.diffuse.as_ref())),
        alpha_uv: transform(entry.and_then(|e| e.alpha.as_ref())),
    }
}

/// The maps of the materials some face uses, in material order.
fn map_requests(
    tmats: &[tobj::Material],
    entries: &HashMap<String, MtlEntry>,
    faces: &[Face],
) -> Vec<MapRequest> {
    let mut used = vec![false; tmats.len()];
    for f in faces {
        if let Some(u) = used.get_mut(f.material.0 as usize) {
            *u = true;
        }
    }
    let mut out = Vec::new();
    for (i, m) in tmats.iter().enumerate().filter(|(i, _)| used[*i]) {
        if let Some(e) = entries.get(&material_key(&m.name)) {
            out.extend(entry_requests(e, i));
        }
    }
    out
}

/// The faces built from `tobj`'s meshes, and what was dropped or split on the way.
#[derive(Default)]
struct BuiltFaces {
    faces: Vec<Face>,
    no_material: usize,
    dropped: usize,
    split: usize,
}

impl BuiltFaces {
    fn warnings(&self, file: &str) -> Vec<String> {
        let mut w = Vec::new();
        if self.no_material > 0 {
            w.push(format!(
                "{file}: {} face(s) have no known material; using grey reflectance 0.5",
                self.no_material
            ));
        }
        if self.dropped > 0 {
            w.push(format!(
                "{file}: dropped {} zero-area face(s)",
                self.dropped
            ));
        }
        if self.split > 0 {
            w.push(format!(
                "{file}: split {} non-planar face(s) into triangles",
                self.split
            ));
        }
        w
    }

    /// Adds one input polygon: dropped when degenerate, split into triangles when not planar.
    fn push(&mut self, face: Face) {
        let verts = &face.vertices;
        let scale = verts
            .iter()
            .map(|p| (*p - verts[0]).length())
            .fold(0.0, f64::max);
        if verts.len() < 3 || polygon::area(verts) <= 1e-12 * scale * scale || scale == 0.0 {
            self.dropped += 1;
            return;
        }
        if polygon::planarity_error(verts) <= NON_PLANAR_TOLERANCE * scale {
            self.faces.push(face);
            return;
        }
        self.split += 1;
        for t in polygon::triangulate(verts) {
            let tri = Face {
                vertices: t.map(|i| verts[i]).to_vec(),
                uvs: face.uvs.as_ref().map(|uv| t.map(|i| uv[i]).to_vec()),
                ..face.clone()
            };
            if polygon::area(&tri.vertices) > 1e-12 * scale * scale {
                self.faces.push(tri);
            }
        }
    }
}

/// The material of a mesh, adding the grey default material when it has none.
fn mesh_material(
    mesh: &tobj::Mesh,
    materials: &mut Vec<Material>,
    default: &mut Option<MaterialId>,
) -> (MaterialId, bool) {
    if let Some(i) = mesh.material_id.filter(|&i| i < materials.len()) {
        return (MaterialId(i as u32), false);
    }
    let id = *default.get_or_insert_with(|| {
        materials.push(Material {
            name: "default".into(),
            reflectance: DVec3::splat(0.5),
            emission: DVec3::ZERO,
            surface: Surface::Diffuse,
            diffuse_map: None,
            alpha_map: None,
            diffuse_uv: UvTransform::default(),
            alpha_uv: UvTransform::default(),
        });
        MaterialId(materials.len() as u32 - 1)
    });
    (id, true)
}

fn build_faces(
    models: &[tobj::Model],
    scan: &ObjScan,
    materials: &mut Vec<Material>,
) -> BuiltFaces {
    let mut built = BuiltFaces::default();
    let mut default_material: Option<MaterialId> = None;
    let mut source_face = 0usize;
    for model in models {
        let mesh = &model.mesh;
        let (material, is_default) = mesh_material(mesh, materials, &mut default_material);
        if is_default {
            built.no_material += mesh.face_arities.len().max(usize::from(
                mesh.face_arities.is_empty() && !mesh.indices.is_empty(),
            ));
        }
        let arities: Vec<u32> = if mesh.face_arities.is_empty() {
            vec![3; mesh.indices.len() / 3]
        } else {
            mesh.face_arities.clone()
        };
        let mut at = 0usize;
        for arity in arities {
            let range = at..at + arity as usize;
            at += arity as usize;
            let with_uv = scan.face_uv.get(source_face).copied().unwrap_or(false);
            let (vertices, uvs) = polygon_of(mesh, range, with_uv);
            built.push(Face {
                vertices,
                uvs,
                material,
                source_face,
                line: scan.face_lines.get(source_face).copied().unwrap_or(0),
            });
            source_face += 1;
        }
    }
    built
}

/// The vertices (and texture coordinates) of one face of a mesh, repeated vertices dropped.
fn polygon_of(
    mesh: &tobj::Mesh,
    range: std::ops::Range<usize>,
    with_uv: bool,
) -> (Vec<DVec3>, Option<Vec<DVec2>>) {
    let with_uv = with_uv && mesh.texcoord_indices.len() == mesh.indices.len();
    let mut verts: Vec<DVec3> = Vec::with_capacity(range.len());
    let mut uvs: Vec<DVec2> = Vec::with_capacity(range.len());
    for k in range {
        let i = mesh.indices[k] as usize * 3;
        let p = DVec3::new(
            mesh.positions[i],
            mesh.positions[i + 1],
            mesh.positions[i + 2],
        );
        if verts.last() == Some(&p) {
            continue;
        }
        verts.push(p);
        if with_uv {
            let t = mesh.texcoord_indices[k] as usize * 2;
            let uv = mesh
                .texcoords
                .get(t..t + 2)
                .map_or(DVec2::ZERO, |c| DVec2::new(c[0], c[1]));
            uvs.push(uv);
        }
    }
    while verts.len() > 1 && verts.first() == verts.last() {
        verts.pop();
        uvs.pop();
    }
    (verts, with_uv.then_some(uvs))
}
