use std::sync::Arc;

use super::*;
use crate::scene::{LoadOptions, Scene, TextureId};
use gltf::mesh::Semantic;

/// RFC 4648's test vectors.
#[test]
fn base64_matches_the_rfc() {
    for (plain, coded) in [
        ("", ""),
        ("f", "Zg=="),
        ("fo", "Zm8="),
        ("foo", "Zm9v"),
        ("foob", "Zm9vYg=="),
        ("fooba", "Zm9vYmE="),
        ("foobar", "Zm9vYmFy"),
    ] {
        assert_eq!(base64(plain.as_bytes()), coded, "{plain}");
    }
}

/// A unit square of material 0 (two triangles, six unwelded corners) and a triangle of
/// material 1 beside it; radiance per corner from its x, y; material 0 textured.
fn two_material_mesh() -> BakedMesh {
    let corners = [
        [0.0, 0.0],
        [1.0, 0.0],
        [1.0, 1.0],
        [0.0, 0.0],
        [1.0, 1.0],
        [0.0, 1.0],
        [2.0, 0.0],
        [3.0, 0.0],
        [2.0, 1.0],
    ];
    let mut m = BakedMesh {
        uvs: Some(Vec::new()),
        ..BakedMesh::default()
    };
    for (k, &[x, y]) in corners.iter().enumerate() {
        m.positions.push([x, y, -1.0]);
        m.normals.push([0.0, 0.0, 1.0]);
        m.radiance.push([x + 0.25, y * 3.0, 0.5]);
        m.irradiance.push([2.0 * x, 2.0 * y, 1.0]);
        m.uvs.as_mut().expect("uvs").push([x * 0.5, y * 0.25]);
        m.indices.push(k as u32);
    }
    m.triangle_material = vec![0, 0, 1];
    m
}

fn materials() -> Vec<Material> {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let mut mats = scene.materials[..2].to_vec();
    mats[0].diffuse_map = Some(TextureId(0));
    mats
}

/// 2 × 1 texture of 8-bit sRGB values (188 is linear 0.5029; IEC 61966-2-1), with a
/// cut-out texel (alpha 0.2).
fn texture() -> Arc<Texture> {
    let img =
        image::RgbaImage::from_raw(2, 1, vec![188, 0, 255, 255, 10, 128, 250, 51]).expect("2 × 1");
    let t = Texture::from_image(
        &image::DynamicImage::ImageRgba8(img),
        crate::scene::texture::TextureKind::Color,
    );
    Arc::new(t.expect("texture"))
}

fn export(format: GltfFormat) -> (Vec<u8>, GltfStats) {
    let mesh = two_material_mesh();
    let (mats, tex) = (materials(), [texture()]);
    let input = GltfInput {
        mesh: &mesh,
        materials: &mats,
        textures: &tex,
        exposure: 0.5,
        name: "test",
    };
    gltf_bytes(&input, format).expect("export")
}

fn floats<const N: usize>(
    p: &gltf::Primitive,
    s: Semantic,
    buffers: &[gltf::buffer::Data],
) -> Vec<[f32; N]>
where
    [f32; N]: gltf::accessor::Item,
{
    let a = p.get(&s).unwrap_or_else(|| panic!("{s:?} missing"));
    gltf::accessor::Iter::<[f32; N]>::new(a, |b| Some(&buffers[b.index()].0[..]))
        .expect("readable")
        .collect()
}

/// Both formats read back with the gltf crate to the same mesh: one primitive per
/// material, corners welded, COLOR_0 = exposure × radiance clamped, the raw values kept,
/// v flipped, the texture's 8-bit texels back unchanged, and the two material variants.
#[test]
fn the_export_reads_back_as_written() {
    for format in [GltfFormat::Glb, GltfFormat::Gltf] {
        let (bytes, stats) = export(format);
        assert_eq!(stats.bytes, bytes.len());
        assert_eq!((stats.vertices, stats.triangles), (4 + 3, 3), "{format:?}");
        let (doc, buffers, images) = gltf::import_slice(&bytes).expect("valid glTF");
        assert_eq!(doc.as_json().asset.generator.as_deref(), Some("nusselt"));
        let used: Vec<&str> = doc.extensions_used().collect();
        assert!(used.contains(&"KHR_materials_unlit"), "{used:?}");
        let mesh = doc.meshes().next().expect("a mesh");
        let prims: Vec<_> = mesh.primitives().collect();
        assert_eq!(prims.len(), 2);
        let square = &prims[0];
        let pos = floats::<3>(square, Semantic::Positions, &buffers);
        assert_eq!(pos.len(), 4, "the diagonal's two corners are shared");
        let bounds = square.bounding_box();
        assert_eq!(
            (bounds.min, bounds.max),
            ([0.0, 0.0, -1.0], [1.0, 1.0, -1.0])
        );
        let colour = floats::<3>(square, Semantic::Colors(0), &buffers);
        let radiance = floats::<3>(square, Semantic::Extras("RADIANCE".into()), &buffers);
        let irradiance = floats::<3>(square, Semantic::Extras("IRRADIANCE".into()), &buffers);
        let uv = floats::<2>(square, Semantic::TexCoords(0), &buffers);
        for k in 0..4 {
            let [x, y, _] = pos[k];
            assert_eq!(radiance[k], [x + 0.25, y * 3.0, 0.5]);
            assert_eq!(irradiance[k], [2.0 * x, 2.0 * y, 1.0]);
            let expect = [(x + 0.25) * 0.5, (y * 1.5).min(1.0), 0.25];
            assert_eq!(colour[k], expect, "vertex at {x} {y}");
            assert_eq!(uv[k], [x * 0.5, 1.0 - y * 0.25]);
        }
        assert!(square.material().unlit());
        assert_eq!(
            square
                .material()
                .pbr_metallic_roughness()
                .base_color_factor(),
            [1.0; 4]
        );
        assert!(
            square
                .material()
                .pbr_metallic_roughness()
                .base_color_texture()
                .is_none()
        );
        let albedo = square
            .mappings()
            .find(|m| m.variants() == [1])
            .expect("albedo");
        let albedo = albedo.material();
        assert!(!albedo.unlit());
        assert_eq!(albedo.alpha_mode(), gltf::material::AlphaMode::Mask);
        let tex = albedo
            .pbr_metallic_roughness()
            .base_color_texture()
            .expect("map");
        let img = &images[tex.texture().source().index()];
        assert_eq!((img.width, img.height), (2, 1));
        assert_eq!(img.pixels, vec![188, 0, 255, 255, 10, 128, 250, 51]);
        // The triangle's material has no map: no texture coordinates.
        assert!(prims[1].get(&Semantic::TexCoords(0)).is_none());
        assert_eq!(
            floats::<3>(&prims[1], Semantic::Positions, &buffers).len(),
            3
        );
    }
}

/// GLB: the header's length is the file's, both chunks are 4-byte aligned, and every
/// buffer view starts on a 4-byte boundary.
#[test]
fn glb_chunks_and_views_are_aligned() {
    let (bytes, _) = export(GltfFormat::Glb);
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(word(4), 2);
    assert_eq!(word(8) as usize, bytes.len());
    let json_len = word(12) as usize;
    assert_eq!(json_len % 4, 0);
    let bin_at = 20 + json_len;
    assert_eq!(&bytes[bin_at + 4..bin_at + 8], b"BIN\0");
    assert_eq!(word(bin_at) % 4, 0);
    assert_eq!(bin_at + 8 + word(bin_at) as usize, bytes.len());
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..bin_at]).expect("json");
    for v in json["bufferViews"].as_array().expect("views") {
        assert_eq!(v["byteOffset"].as_u64().expect("offset") % 4, 0, "{v}");
    }
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let (mats, tex) = (materials(), [texture()]);
    let input = |mesh| GltfInput {
        mesh,
        materials: &mats,
        textures: &tex,
        exposure: 1.0,
        name: "t",
    };
    let empty = BakedMesh::default();
    let e = gltf_bytes(&input(&empty), GltfFormat::Glb).expect_err("empty");
    assert!(matches!(e, ExportError::Empty), "{e}");
    let mut wrong = two_material_mesh();
    wrong.triangle_material[2] = 7;
    let e = gltf_bytes(&input(&wrong), GltfFormat::Glb).expect_err("material 7");
    assert!(e.to_string().contains("material 7"), "{e}");
    let mut short = two_material_mesh();
    short.normals.pop();
    assert!(gltf_bytes(&input(&short), GltfFormat::Gltf).is_err());
    let mut past = two_material_mesh();
    past.indices[0] = 99;
    assert!(gltf_bytes(&input(&past), GltfFormat::Gltf).is_err());
    let e = GltfFormat::from_path(Path::new("out.obj")).expect_err("obj");
    assert!(e.to_string().contains("out.obj"), "{e}");
    assert_eq!(
        GltfFormat::from_path(Path::new("a.GLB")).expect("glb"),
        GltfFormat::Glb
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let e = write_gltf(
        &dir.path().join("no/such/dir/a.glb"),
        &input(&two_material_mesh()),
    );
    assert!(matches!(e, Err(ExportError::Io { .. })), "{e:?}");
}
