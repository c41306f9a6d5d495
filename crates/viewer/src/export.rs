//! Files the viewer writes: the solution as PLY, edited materials as MTL, screenshots as
//! PNG. Every write goes to a temporary file in the target's folder and is renamed over the
//! target, so a crash or a full disk never leaves a half-written file behind.

use std::path::{Path, PathBuf};

use nusselt_core::scene::{Material, Surface};

use super::snapshot::Snapshot;

#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("cannot write {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot encode {path}: {message}")]
    Encode { path: PathBuf, message: String },
}

/// Writes `bytes` to `path` atomically ([`nusselt_core::render::image::atomic_write`]: temp file in
/// the same folder + rename), with the path in the error.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    nusselt_core::render::image::atomic_write(path, bytes).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Linear radiance to an 8-bit sRGB value after exposure (the viewport's own transfer;
/// the encoding is the renderer's [`nusselt_core::render::image::srgb8`]).
pub fn srgb8(linear: f32, exposure: f32) -> u8 {
    nusselt_core::render::image::srgb8(f64::from(linear) * f64::from(exposure))
}

/// The solution as binary PLY: display vertices with float radiance (`radiance_r/g/b`,
/// ambient included when asked) and 8-bit sRGB colours (`red/green/blue`, after
/// `exposure`), and the display triangles.
pub fn ply_bytes(snapshot: &Snapshot, with_ambient: bool, exposure: f32) -> Vec<u8> {
    let g = &snapshot.geometry;
    let n = g.display_vertex_count();
    let mut position = vec![[0f32; 3]; n];
    let mut radiance = vec![[0f32; 3]; n];
    let ambient = if with_ambient { 1.0 } else { 0.0 };
    // Drawn vertices that share a display vertex (patch boundaries) hold the same values.
    for (k, &v) in g.source_vertex.iter().enumerate() {
        position[v as usize] = g.positions[k];
        let (b, g) = (snapshot.radiance[k], snapshot.correction[k]);
        radiance[v as usize] = [0, 1, 2].map(|c| b[c] + g[c] * ambient);
    }
    let triangles = g.indices.len() / 3;
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment nusselt radiosity solution: {}, {} solver, {} steps, radiance in W m^-2 sr^-1{}\ncomment red/green/blue are sRGB after exposure x{exposure}\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\nproperty float radiance_r\nproperty float radiance_g\nproperty float radiance_b\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face {triangles}\nproperty list uchar uint vertex_indices\nend_header\n",
        snapshot.scene_name,
        snapshot.stats.solver,
        snapshot.stats.steps,
        if with_ambient {
            ", ambient term included"
        } else {
            ""
        }
    )
    .into_bytes();
    out.reserve(n * 27 + triangles * 13);
    for (p, r) in position.iter().zip(&radiance) {
        for x in p.iter().chain(r) {
            out.extend_from_slice(&x.to_le_bytes());
        }
        for c in r {
            out.push(srgb8(*c, exposure));
        }
    }
    for t in g.indices.chunks_exact(3) {
        out.push(3);
        for &d in t {
            out.extend_from_slice(&g.source_vertex[d as usize].to_le_bytes());
        }
    }
    out
}

/// Formats a float so that it reads back exactly.
fn num(x: f64) -> String {
    format!("{x}")
}

/// Materials as MTL text (`Kd`, `Ke` for emitters, and the specular part: `Ks` and
/// `illum 3` for a mirror, with `Ns` when glossy; `Ni` and `illum 7` for glass).
pub fn mtl_text(materials: &[Material], comment: &str) -> String {
    let mut s = format!("# {comment}\n# Kd = reflectance, Ke = emitted radiance (W m^-2 sr^-1)\n");
    for m in materials {
        let c = |v: glam::DVec3| format!("{} {} {}", num(v.x), num(v.y), num(v.z));
        s.push_str(&format!("\nnewmtl {}\nKd {}\n", m.name, c(m.reflectance)));
        if m.is_emitter() {
            s.push_str(&format!("Ke {}\n", c(m.emission)));
        }
        match m.surface {
            Surface::Diffuse => {}
            Surface::Mirror { ks } => s.push_str(&format!("Ks {}\nillum 3\n", c(ks))),
            Surface::Glossy { ks, exponent } => {
                s.push_str(&format!("Ks {}\nNs {}\nillum 3\n", c(ks), num(exponent)))
            }
            Surface::Glass { ior } => s.push_str(&format!("Ni {}\nillum 7\n", num(ior))),
        }
    }
    s
}

/// Where "Save MTL" writes for a model: the library the OBJ names when it names exactly
/// one (so reopening the model picks the edits up), otherwise `<stem>.mtl` next to it.
pub fn mtl_path_for(obj: &Path) -> PathBuf {
    let dir = obj.parent().map(Path::to_path_buf).unwrap_or_default();
    let libs: Vec<String> = std::fs::read_to_string(obj)
        .map(|text| {
            text.lines()
                .filter_map(|l| l.trim().strip_prefix("mtllib "))
                .map(|n| n.trim().to_string())
                .filter(|n| !n.is_empty())
                .collect()
        })
        .unwrap_or_default();
    match libs.as_slice() {
        [one] => dir.join(one),
        _ => {
            let stem = obj
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".into());
            dir.join(format!("{stem}.mtl"))
        }
    }
}

/// Encodes an RGBA8 image as PNG and writes it atomically.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<(), ExportError> {
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(rgba, width, height, image::ExtendedColorType::Rgba8)
        .map_err(|e| ExportError::Encode {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    atomic_write(path, &bytes)
}

/// Writes an egui image (a window screenshot, or a region of one) as PNG, atomically.
pub fn write_color_image(path: &Path, image: &eframe::egui::ColorImage) -> Result<(), ExportError> {
    let rgba: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    write_png(path, image.size[0] as u32, image.size[1] as u32, &rgba)
}

use image::ImageEncoder as _;

#[cfg(test)]
mod tests {
    use super::*;
    use nusselt_core::scene::{LoadOptions, Scene};

    /// Reflectance, emission and the specular part (mirror, glossy mirror, glass) read back
    /// as written: saving a model's edits keeps its mirrors and glass.
    #[test]
    fn mtl_round_trips_through_the_loader() {
        let mut s = Scene::builtin("cornell-specular", &LoadOptions::default()).expect("cornell");
        s.materials[1].reflectance = glam::DVec3::new(0.1, 0.2, 0.3);
        s.materials[1].emission = glam::DVec3::new(0.0, 0.0, 1.0 / 3.0);
        s.materials[2].surface = Surface::Glossy {
            ks: glam::DVec3::new(0.2, 0.3, 0.1),
            exponent: 37.5,
        };
        let kinds = |m: &[Material]| {
            let k: std::collections::HashSet<_> = m
                .iter()
                .map(|m| std::mem::discriminant(&m.surface))
                .collect();
            k.len()
        };
        assert!(
            kinds(&s.materials) >= 4,
            "diffuse, mirror, glossy and glass"
        );
        let text = mtl_text(&s.materials, "test");
        let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n";
        let back = Scene::from_obj_str("t.obj", obj, &[("m.mtl", &text)], &LoadOptions::default())
            .expect("reload");
        for m in &s.materials {
            let b = back
                .materials
                .iter()
                .find(|b| b.name == m.name)
                .unwrap_or_else(|| panic!("{} missing", m.name));
            assert_eq!(b.reflectance, m.reflectance, "{}", m.name);
            assert_eq!(b.emission, m.emission, "{}", m.name);
            assert_eq!(b.surface, m.surface, "{}", m.name);
        }
    }

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("a.mtl");
        std::fs::write(&p, "old").expect("write");
        atomic_write(&p, b"new").expect("atomic");
        assert_eq!(std::fs::read_to_string(&p).expect("read"), "new");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .expect("dir")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        assert!(atomic_write(&dir.path().join("no/such/dir/x"), b"x").is_err());
    }

    #[test]
    fn mtl_path_follows_the_obj_library() {
        let dir = tempfile::tempdir().expect("tempdir");
        let obj = dir.path().join("room.obj");
        std::fs::write(&obj, "mtllib lib.mtl\nv 0 0 0\n").expect("write");
        assert_eq!(mtl_path_for(&obj), dir.path().join("lib.mtl"));
        std::fs::write(&obj, "v 0 0 0\n").expect("write");
        assert_eq!(mtl_path_for(&obj), dir.path().join("room.mtl"));
    }

    #[test]
    fn srgb_encoding_matches_the_standard() {
        assert_eq!(srgb8(0.0, 1.0), 0);
        assert_eq!(srgb8(1.0, 1.0), 255);
        assert_eq!(srgb8(0.5, 2.0), 255);
        // 0.18 linear is about 118 in sRGB.
        assert_eq!(srgb8(0.18, 1.0), 118);
        assert_eq!(srgb8(f32::NAN, 1.0), 0);
    }
}
