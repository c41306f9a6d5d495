//! glTF 2.0 export of a [`BakedMesh`]: binary `.glb`, or `.gltf` JSON with the buffer
//! embedded as base64 (chosen by the file's extension), readable by Blender (File > Import >
//! glTF 2.0; the colours are the mesh's `Color` attribute), Godot, Bevy and any viewer.
//!
//! What is written (glTF 2.0 specification, Khronos 2021):
//! - one mesh, one primitive per material, each with its own welded vertices (`super::weld`);
//! - `COLOR_0` (FLOAT VEC3): the displayed radiance times the exposure, clamped to [0, 1],
//!   linear like every glTF colour (a viewer encodes it for the screen, as it does a
//!   texture), so a viewer shows what `nusselt render` writes to a PNG at that exposure;
//! - `_RADIANCE` (W·m⁻²·sr⁻¹) and `_IRRADIANCE` (W·m⁻²), FLOAT VEC3, unclamped and without the
//!   exposure: the solution itself, for an engine that lights by it (application-specific
//!   attributes start with `_`). `radiance = emission + reflectance × irradiance / π`;
//! - `POSITION` (scene units, with the min/max the specification requires), `NORMAL`, and
//!   `TEXCOORD_0` in the primitives whose material has a diffuse map (v flipped: glTF's v = 0
//!   is the image's top row);
//! - each material twice, as variants of `KHR_materials_variants`: the default,
//!   `radiosity`, is `KHR_materials_unlit` with base colour 1, so the colour seen is exactly
//!   `COLOR_0` (the texture is not in it: unlit base colour multiplies `COLOR_0`, and the
//!   radiance already holds the texture's mean); the variant `albedo` is a plain
//!   metallic-roughness material (metallic 0, roughness 1) with base colour `Kd` and the
//!   diffuse map as `baseColorTexture` (embedded PNG, sRGB 8-bit, alpha `MASK` at 0.5 where it
//!   has cut-outs), for an engine that shows `texture × irradiance` or lights the scene
//!   itself. Both carry `extras.nusselt` with `reflectance` and `emission` (`Kd`, `Ke`).
//!
//! Known limits: the baked colours are the solution's per-vertex values, so texture detail
//! below an element is not in them (only in the `albedo` variant); cut-out alpha is not
//! applied to the `radiosity` variant; positions are in the scene's own units (glTF assumes
//! metres; the Cornell box is in millimetres), not rescaled. 8-bit colour maps lose nothing
//! on the way back to sRGB; 16-bit and float maps are quantised to 8 bits.

use std::path::Path;
use std::sync::Arc;

use serde_json::{Value, json};

use super::weld::{self, Primitive};
use super::{BakedMesh, ExportError};
use crate::scene::{Material, Texture};

/// Binary `.glb` or JSON `.gltf`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GltfFormat {
    Glb,
    Gltf,
}

impl GltfFormat {
    /// The format a path's extension names (`.glb` or `.gltf`, any case).
    pub fn from_path(path: &Path) -> Result<GltfFormat, ExportError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("glb") => Ok(GltfFormat::Glb),
            Some("gltf") => Ok(GltfFormat::Gltf),
            _ => Err(ExportError::Extension(path.to_path_buf())),
        }
    }
}

/// What a glTF export reads.
#[derive(Clone, Copy, Debug)]
pub struct GltfInput<'a> {
    pub mesh: &'a BakedMesh,
    /// The scene's materials ([`BakedMesh::triangle_material`] indexes them).
    pub materials: &'a [Material],
    /// The scene's textures ([`Material::diffuse_map`] indexes them); a map missing here is
    /// left out.
    pub textures: &'a [Arc<Texture>],
    /// Multiplies the radiance in `COLOR_0` (the image's exposure).
    pub exposure: f64,
    /// The scene's name, for the mesh and node.
    pub name: &'a str,
}

/// What an export wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GltfStats {
    /// Welded vertices, over all primitives.
    pub vertices: usize,
    pub triangles: usize,
    pub bytes: usize,
}

/// The binary buffer with its views and accessors.
#[derive(Default)]
struct Bin {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

impl Bin {
    /// A buffer view of `bytes`, starting on a 4-byte boundary.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.data.resize(self.data.len().next_multiple_of(4), 0);
        let mut v = json!({"buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.data.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    /// A FLOAT accessor of `N`-vectors (`kind`: VEC2, VEC3), with min/max when `bounds`.
    fn floats<const N: usize>(&mut self, values: &[[f32; N]], kind: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = values
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        let mut a = json!({"bufferView": view, "componentType": FLOAT, "count": values.len(), "type": kind});
        if bounds {
            let (mut lo, mut hi) = ([f32::INFINITY; N], [f32::NEG_INFINITY; N]);
            for v in values {
                for c in 0..N {
                    lo[c] = lo[c].min(v[c]);
                    hi[c] = hi[c].max(v[c]);
                }
            }
            a["min"] = json!(lo.iter().map(|&x| f64::from(x)).collect::<Vec<_>>());
            a["max"] = json!(hi.iter().map(|&x| f64::from(x)).collect::<Vec<_>>());
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn indices(&mut self, indices: &[u32]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        self.accessors.push(json!({
            "bufferView": view, "componentType": UNSIGNED_INT, "count": indices.len(), "type": "SCALAR"
        }));
        self.accessors.len() - 1
    }
}

/// A texture as an 8-bit sRGB RGBA PNG (alpha linear), top row first. Texels are read at
/// their centres, where the bilinear [`Texture::sample`] returns them exactly.
fn texture_png(t: &Texture, index: usize) -> Result<Vec<u8>, ExportError> {
    use crate::render::image::srgb8;
    use image::ImageEncoder as _;
    let (w, h) = (t.width, t.height);
    let mut rgba = Vec::with_capacity(w as usize * h as usize * 4);
    for y in 0..h {
        for x in 0..w {
            let uv = glam::DVec2::new(
                (x as f64 + 0.5) / w as f64,
                1.0 - (y as f64 + 0.5) / h as f64,
            );
            let s = t.sample(uv);
            rgba.extend([srgb8(s[0]), srgb8(s[1]), srgb8(s[2])]);
            rgba.push((s[3].clamp(0.0, 1.0) * 255.0).round() as u8);
        }
    }
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&rgba, w, h, image::ExtendedColorType::Rgba8)
        .map_err(|e| ExportError::Texture {
            index,
            message: e.to_string(),
        })?;
    Ok(png)
}

/// The textures the used materials name, each once: glTF texture index per scene texture.
fn write_textures(
    input: &GltfInput,
    used: &[u32],
    bin: &mut Bin,
    json: &mut Value,
) -> Result<Vec<Option<usize>>, ExportError> {
    let mut index = vec![None; input.textures.len()];
    let (mut images, mut textures) = (Vec::new(), Vec::new());
    for &m in used {
        let Some(id) = input.materials[m as usize].diffuse_map else {
            continue;
        };
        let id = id.0 as usize;
        if id >= input.textures.len() || index[id].is_some() {
            continue;
        }
        let view = bin.view(&texture_png(&input.textures[id], id)?, None);
        images.push(json!({"bufferView": view, "mimeType": "image/png"}));
        textures.push(json!({"source": images.len() - 1}));
        index[id] = Some(textures.len() - 1);
    }
    if !images.is_empty() {
        json["images"] = Value::Array(images);
        json["textures"] = Value::Array(textures);
    }
    Ok(index)
}

/// The `radiosity` (unlit) and `albedo` materials of scene material `m`.
fn material_pair(input: &GltfInput, m: u32, texture: Option<usize>) -> [Value; 2] {
    let mat = &input.materials[m as usize];
    let extras = json!({"nusselt": {
        "reflectance": mat.reflectance.to_array(),
        "emission": mat.emission.to_array(),
    }});
    let baked = json!({
        "name": mat.name,
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extensions": {"KHR_materials_unlit": {}},
        "extras": extras,
    });
    let r = mat.reflectance;
    let mut albedo = json!({
        "name": format!("{} (albedo)", mat.name),
        "pbrMetallicRoughness": {"baseColorFactor": [r.x, r.y, r.z, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extras": extras,
    });
    if let Some(t) = texture {
        albedo["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": t});
        let cutouts = mat
            .diffuse_map
            .and_then(|id| input.textures.get(id.0 as usize))
            .is_some_and(|t| t.has_cutouts());
        if cutouts {
            albedo["alphaMode"] = json!("MASK");
            albedo["alphaCutoff"] = json!(crate::scene::texture::OPAQUE_ALPHA);
        }
    }
    [baked, albedo]
}

/// The vertex attributes of one primitive.
fn attributes(input: &GltfInput, p: &Primitive, uv: bool, bin: &mut Bin) -> Value {
    let mesh = input.mesh;
    let pick =
        |a: &[[f32; 3]]| -> Vec<[f32; 3]> { p.source.iter().map(|&v| a[v as usize]).collect() };
    let exposure = input.exposure as f32;
    let colour: Vec<[f32; 3]> = p
        .source
        .iter()
        .map(|&v| mesh.radiance[v as usize].map(|c| (c * exposure).clamp(0.0, 1.0)))
        .map(|c| c.map(|x| if x.is_nan() { 0.0 } else { x }))
        .collect();
    let mut a = json!({
        "POSITION": bin.floats(&pick(&mesh.positions), "VEC3", true),
        "NORMAL": bin.floats(&pick(&mesh.normals), "VEC3", false),
        "COLOR_0": bin.floats(&colour, "VEC3", false),
        "_RADIANCE": bin.floats(&pick(&mesh.radiance), "VEC3", false),
        "_IRRADIANCE": bin.floats(&pick(&mesh.irradiance), "VEC3", false),
    });
    if let (true, Some(uvs)) = (uv, &mesh.uvs) {
        let flipped: Vec<[f32; 2]> = p
            .source
            .iter()
            .map(|&v| [uvs[v as usize][0], 1.0 - uvs[v as usize][1]])
            .collect();
        a["TEXCOORD_0"] = json!(bin.floats(&flipped, "VEC2", false));
    }
    a
}

/// The glTF JSON document and its binary buffer.
fn document(input: &GltfInput) -> Result<(Value, Vec<u8>, GltfStats), ExportError> {
    let mesh = input.mesh;
    mesh.check()?;
    if let Some(&m) = mesh
        .triangle_material
        .iter()
        .find(|&&m| m as usize >= input.materials.len())
    {
        return Err(ExportError::Inconsistent(format!(
            "material {m} of {} materials",
            input.materials.len()
        )));
    }
    let prims = weld::primitives(mesh);
    if prims.is_empty() {
        return Err(ExportError::Empty);
    }
    let mut json = json!({
        "asset": {"version": "2.0", "generator": "nusselt", "extras": {"nusselt": {
            "exposure": input.exposure,
            "radiance": "_RADIANCE, W m^-2 sr^-1",
            "irradiance": "_IRRADIANCE, W m^-2 (radiance = emission + reflectance * irradiance / pi)",
        }}},
        "extensionsUsed": ["KHR_materials_unlit", "KHR_materials_variants"],
        "extensions": {"KHR_materials_variants": {"variants": [{"name": "radiosity"}, {"name": "albedo"}]}},
        "scene": 0,
        "scenes": [{"name": input.name, "nodes": [0]}],
        "nodes": [{"name": input.name, "mesh": 0}],
    });
    let mut bin = Bin::default();
    let used: Vec<u32> = prims.iter().map(|p| p.material).collect();
    let texture_of = write_textures(input, &used, &mut bin, &mut json)?;
    let (mut materials, mut primitives) = (Vec::new(), Vec::new());
    for p in &prims {
        let texture = input.materials[p.material as usize]
            .diffuse_map
            .and_then(|id| texture_of.get(id.0 as usize).copied().flatten());
        let [baked, albedo] = material_pair(input, p.material, texture);
        materials.extend([baked, albedo]);
        let (b, a) = (materials.len() - 2, materials.len() - 1);
        let attributes = attributes(input, p, texture.is_some(), &mut bin);
        primitives.push(json!({
            "attributes": attributes,
            "indices": bin.indices(&p.indices),
            "material": b,
            "mode": 4,
            "extensions": {"KHR_materials_variants": {"mappings": [
                {"material": b, "variants": [0]},
                {"material": a, "variants": [1]},
            ]}},
        }));
    }
    json["materials"] = Value::Array(materials);
    json["meshes"] = json!([{"name": input.name, "primitives": primitives}]);
    let stats = GltfStats {
        vertices: prims.iter().map(|p| p.source.len()).sum(),
        triangles: mesh.triangle_count(),
        bytes: 0,
    };
    json["accessors"] = Value::Array(std::mem::take(&mut bin.accessors));
    json["bufferViews"] = Value::Array(std::mem::take(&mut bin.views));
    Ok((json, bin.data, stats))
}

/// Standard base64 (RFC 4648, with padding).
fn base64(data: &[u8]) -> String {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                s.push(ABC[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A GLB container: header, JSON chunk (padded with spaces), BIN chunk (padded with zeros).
fn glb(json: &[u8], bin: &[u8]) -> Result<Vec<u8>, ExportError> {
    let (jl, bl) = (
        json.len().next_multiple_of(4),
        bin.len().next_multiple_of(4),
    );
    let total = 12 + 8 + jl + 8 + bl;
    let too_large = |_| ExportError::TooLarge(total);
    let u32_of = |n: usize| u32::try_from(n).map_err(too_large);
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&u32_of(total)?.to_le_bytes());
    out.extend_from_slice(&u32_of(jl)?.to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(json);
    out.resize(20 + jl, b' ');
    out.extend_from_slice(&u32_of(bl)?.to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(bin);
    out.resize(total, 0);
    Ok(out)
}

/// The export as the bytes of a file of `format`.
pub fn gltf_bytes(
    input: &GltfInput,
    format: GltfFormat,
) -> Result<(Vec<u8>, GltfStats), ExportError> {
    let (mut json, bin, mut stats) = document(input)?;
    if u32::try_from(bin.len()).is_err() {
        return Err(ExportError::TooLarge(bin.len()));
    }
    let mut buffer = json!({"byteLength": bin.len()});
    if format == GltfFormat::Gltf {
        buffer["uri"] = json!(format!(
            "data:application/octet-stream;base64,{}",
            base64(&bin)
        ));
    }
    json["buffers"] = json!([buffer]);
    let text = serde_json::to_vec(&json).expect("a JSON value always serialises");
    let bytes = match format {
        GltfFormat::Glb => glb(&text, &bin)?,
        GltfFormat::Gltf => text,
    };
    stats.bytes = bytes.len();
    Ok((bytes, stats))
}

/// Writes the export to `path` (format from its extension), atomically: a failed write
/// leaves what was there.
pub fn write_gltf(path: &Path, input: &GltfInput) -> Result<GltfStats, ExportError> {
    let format = GltfFormat::from_path(path)?;
    let (bytes, stats) = gltf_bytes(input, format)?;
    crate::render::image::atomic_write(path, &bytes).map_err(|source| ExportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(stats)
}

#[cfg(test)]
#[path = "gltf_tests.rs"]
mod tests;
