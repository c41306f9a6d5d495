//! Line-by-line checks of OBJ/MTL text before `tobj` parses it, and geometry checks after.
//!
//! `tobj` panics on some malformed input (a one-number `Kd 0.5`) and reports others without a
//! line number, so every statement Nusselt relies on is checked here first and errors name
//! `file:line`. Parsing itself is `tobj`'s.
//! Specular statements are checked and turned into a [`Surface`] by [`super::specular`].

use std::collections::HashMap;
use std::io::BufReader;

use glam::DVec3;

use super::specular::{SpecularScan, surface};
use super::{Face, LoadOptions, MAX_REFLECTANCE, Material, MaterialId, Scene, SceneError, Surface};
use crate::geometry::polygon;

/// Relative non-planarity (vertex distance from the best-fit plane over the face size)
/// above which a face is split into triangles. The published Cornell Box red wall is off
/// by 1.4e-3 and stays one face.
const NON_PLANAR_TOLERANCE: f64 = 2.5e-3;

/// What the OBJ pre-scan learned.
struct ObjScan {
    face_lines: Vec<usize>,
    mtllibs: Vec<(String, usize)>,
    warnings: Vec<String>,
}

fn parse_err(file: &str, line: usize, message: impl Into<String>) -> SceneError {
    SceneError::Parse {
        file: file.to_string(),
        line,
        message: message.into(),
    }
}

fn numbers(
    file: &str,
    line: usize,
    what: &str,
    words: &[&str],
    min: usize,
    max: usize,
) -> Result<Vec<f64>, SceneError> {
    if words.len() < min || words.len() > max {
        let want = if min == max {
            format!("{min}")
        } else {
            format!("{min} to {max}")
        };
        return Err(parse_err(
            file,
            line,
            format!("'{what}' needs {want} numbers, found {}", words.len()),
        ));
    }
    words
        .iter()
        .map(|w| {
            let x: f64 = w
                .parse()
                .map_err(|_| parse_err(file, line, format!("'{what}': '{w}' is not a number")))?;
            if x.is_finite() {
                Ok(x)
            } else {
                Err(parse_err(
                    file,
                    line,
                    format!("'{what}': '{w}' is not a finite number"),
                ))
            }
        })
        .collect()
}

fn statements(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines().enumerate().filter_map(|(i, raw)| {
        let content = raw.split('#').next().unwrap_or("");
        let words: Vec<&str> = content.split_whitespace().collect();
        (!words.is_empty()).then_some((i + 1, words))
    })
}

fn scan_obj(file: &str, text: &str) -> Result<ObjScan, SceneError> {
    let (mut nv, mut nvt, mut nvn) = (0i64, 0i64, 0i64);
    let mut scan = ObjScan {
        face_lines: Vec::new(),
        mtllibs: Vec::new(),
        warnings: Vec::new(),
    };
    let mut unknown: HashMap<String, usize> = HashMap::new();
    for (line, words) in statements(text) {
        let args = &words[1..];
        match words[0] {
            "v" => {
                numbers(file, line, "v", args, 3, 4)?;
                nv += 1;
            }
            "vt" => {
                numbers(file, line, "vt", args, 1, 3)?;
                nvt += 1;
            }
            "vn" => {
                numbers(file, line, "vn", args, 3, 3)?;
                nvn += 1;
            }
            "f" => {
                if args.len() < 3 {
                    return Err(parse_err(
                        file,
                        line,
                        format!("a face needs at least 3 vertices, found {}", args.len()),
                    ));
                }
                for a in args {
                    let parts: Vec<&str> = a.split('/').collect();
                    if parts.len() > 3 || parts[0].is_empty() {
                        return Err(parse_err(file, line, format!("bad face vertex '{a}'")));
                    }
                    for (k, (p, count)) in parts.iter().zip([nv, nvt, nvn]).enumerate() {
                        if p.is_empty() && k > 0 {
                            continue;
                        }
                        let what = ["vertex", "texture coordinate", "normal"][k];
                        let i: i64 = p.parse().map_err(|_| {
                            parse_err(file, line, format!("bad {what} index '{p}' in '{a}'"))
                        })?;
                        let resolved = if i < 0 { count + i + 1 } else { i };
                        if i == 0 || resolved < 1 || resolved > count {
                            return Err(parse_err(
                                file,
                                line,
                                format!(
                                    "{what} index {i} is out of range (1..={count} defined so far)"
                                ),
                            ));
                        }
                    }
                }
                scan.face_lines.push(line);
            }
            "mtllib" => {
                if args.is_empty() {
                    return Err(parse_err(file, line, "'mtllib' needs a file name"));
                }
                scan.mtllibs.push((args.join(" "), line));
            }
            "usemtl" => {
                if args.is_empty() {
                    return Err(parse_err(file, line, "'usemtl' needs a material name"));
                }
            }
            "o" | "g" | "s" | "l" | "p" | "vp" | "cstype" | "deg" | "curv" | "surf" | "parm"
            | "end" | "mg" | "lod" | "usemap" | "maplib" | "bevel" | "c_interp" | "d_interp"
            | "shadow_obj" | "trace_obj" => {}
            other => *unknown.entry(other.to_string()).or_default() += 1,
        }
    }
    let mut unknown: Vec<_> = unknown.into_iter().collect();
    unknown.sort();
    for (k, n) in unknown {
        scan.warnings.push(format!(
            "{file}: ignored {n} line(s) with unknown statement '{k}'"
        ));
    }
    Ok(scan)
}

fn scan_mtl(file: &str, text: &str, warnings: &mut Vec<String>) -> Result<(), SceneError> {
    let mut current: Option<String> = None;
    let mut specular = SpecularScan::default();
    for (line, words) in statements(text) {
        let args = &words[1..];
        let key = words[0];
        match key {
            "newmtl" => {
                if args.is_empty() {
                    return Err(parse_err(file, line, "'newmtl' needs a material name"));
                }
                specular.finish(file, warnings);
                current = Some(args.join(" "));
                specular = SpecularScan {
                    name: args.join(" "),
                    ..Default::default()
                };
            }
            "Kd" | "Ka" | "Ks" | "Ke" | "Tf" => {
                if current.is_none() {
                    return Err(parse_err(
                        file,
                        line,
                        format!("'{key}' before any 'newmtl'"),
                    ));
                }
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
                    return Err(parse_err(
                        file,
                        line,
                        format!(
                            "'{key}' needs 3 numbers (r g b), found {}{}",
                            args.len(),
                            if args.len() == 1 {
                                format!("; write '{key} {0} {0} {0}' for grey", args[0])
                            } else {
                                String::new()
                            }
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
                let name = current.clone().unwrap_or_default();
                if key == "Kd" {
                    if v.iter().any(|x| *x > MAX_REFLECTANCE) {
                        warnings.push(format!(
                            "{file}:{line}: reflectance of '{name}' clamped to {MAX_REFLECTANCE} (ρ ≥ 1 never converges)"
                        ));
                    }
                    specular.kd = Some([v[0], v[1], v[2]]);
                }
                if key == "Ks" {
                    specular.ks = Some(([v[0], v[1], v[2]], line));
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
    Ok(())
}

/// Returns (display name, text) of a named material library.
pub(super) type MtlReader<'a> = dyn FnMut(&str) -> Result<(String, String), SceneError> + 'a;

/// Loads OBJ text; `read_mtl` returns (display name, text) of a named material library.
pub(super) fn load(
    file: &str,
    text: &str,
    read_mtl: &mut MtlReader,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let scan = scan_obj(file, text)?;
    let mut warnings = scan.warnings;
    let mut mtl_texts: HashMap<String, String> = HashMap::new();
    for (lib, line) in &scan.mtllibs {
        let (mtl_file, mtl_text) = read_mtl(lib).map_err(|e| match e {
            SceneError::Io { path, source } => parse_err(
                file,
                *line,
                format!("cannot read material library {}: {source}", path.display()),
            ),
            other => other,
        })?;
        scan_mtl(&mtl_file, &mtl_text, &mut warnings)?;
        mtl_texts.insert(lib.clone(), mtl_text);
    }
    if scan.face_lines.is_empty() {
        return Err(SceneError::Invalid {
            file: file.to_string(),
            message: "no faces: the file is empty or has only points and lines".into(),
        });
    }

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
    let tmats = match materials {
        Ok(m) => m,
        Err(e) if scan.mtllibs.is_empty() => {
            let _ = e;
            Vec::new()
        }
        Err(e) => {
            return Err(SceneError::Invalid {
                file: file.to_string(),
                message: format!("material library error: {e}"),
            });
        }
    };

    let mut materials: Vec<Material> = tmats
        .iter()
        .map(|m| {
            let kd = m
                .diffuse
                .map_or(DVec3::splat(0.5), |d| DVec3::new(d[0], d[1], d[2]));
            let ke = m
                .emissive
                .map_or(DVec3::ZERO, |d| DVec3::new(d[0], d[1], d[2]));
            let reflectance = kd.clamp(DVec3::ZERO, DVec3::splat(MAX_REFLECTANCE));
            Material {
                name: m.name.clone(),
                reflectance,
                emission: ke,
                surface: surface(m, reflectance),
            }
        })
        .collect();
    let mut default_material: Option<MaterialId> = None;
    let mut faces = Vec::new();
    let mut source_face = 0usize;
    let mut no_material = 0usize;
    let mut dropped = 0usize;
    let mut split = 0usize;
    for model in &models {
        let mesh = &model.mesh;
        let material = match mesh.material_id.filter(|&i| i < materials.len()) {
            Some(i) => MaterialId(i as u32),
            None => {
                no_material += mesh.face_arities.len().max(usize::from(
                    mesh.face_arities.is_empty() && !mesh.indices.is_empty(),
                ));
                *default_material.get_or_insert_with(|| {
                    materials.push(Material {
                        name: "default".into(),
                        reflectance: DVec3::splat(0.5),
                        emission: DVec3::ZERO,
                        surface: Surface::Diffuse,
                    });
                    MaterialId(materials.len() as u32 - 1)
                })
            }
        };
        let arities: Vec<u32> = if mesh.face_arities.is_empty() {
            vec![3; mesh.indices.len() / 3]
        } else {
            mesh.face_arities.clone()
        };
        let mut at = 0usize;
        for arity in arities {
            let idx = &mesh.indices[at..at + arity as usize];
            at += arity as usize;
            let line = scan.face_lines.get(source_face).copied().unwrap_or(0);
            let mut verts: Vec<DVec3> = Vec::with_capacity(idx.len());
            for &i in idx {
                let k = i as usize * 3;
                let p = DVec3::new(
                    mesh.positions[k],
                    mesh.positions[k + 1],
                    mesh.positions[k + 2],
                );
                if verts.last() != Some(&p) {
                    verts.push(p);
                }
            }
            while verts.len() > 1 && verts.first() == verts.last() {
                verts.pop();
            }
            let this = source_face;
            source_face += 1;
            let scale = verts
                .iter()
                .map(|p| (*p - verts[0]).length())
                .fold(0.0, f64::max);
            if verts.len() < 3 || polygon::area(&verts) <= 1e-12 * scale * scale || scale == 0.0 {
                dropped += 1;
                continue;
            }
            if polygon::planarity_error(&verts) > NON_PLANAR_TOLERANCE * scale {
                split += 1;
                for t in polygon::triangulate(&verts) {
                    let tri = vec![verts[t[0]], verts[t[1]], verts[t[2]]];
                    if polygon::area(&tri) > 1e-12 * scale * scale {
                        faces.push(Face {
                            vertices: tri,
                            material,
                            source_face: this,
                            line,
                        });
                    }
                }
                continue;
            }
            faces.push(Face {
                vertices: verts,
                material,
                source_face: this,
                line,
            });
        }
    }
    if no_material > 0 {
        warnings.push(format!(
            "{file}: {no_material} face(s) have no known material; using grey reflectance 0.5"
        ));
    }
    if dropped > 0 {
        warnings.push(format!("{file}: dropped {dropped} zero-area face(s)"));
    }
    if split > 0 {
        warnings.push(format!(
            "{file}: split {split} non-planar face(s) into triangles"
        ));
    }
    if faces.is_empty() {
        return Err(SceneError::Invalid {
            file: file.to_string(),
            message: format!("no usable faces ({dropped} zero-area face(s) dropped)"),
        });
    }
    Ok(Scene {
        name: String::new(),
        faces,
        materials,
        two_sided: opts.two_sided,
        camera: None,
        warnings,
        source: None,
        lights: Vec::new(),
    })
}
