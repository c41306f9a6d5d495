//! glTF metallic-roughness materials to Nusselt's Lambertian ones, with their textures.
//!
//! - reflectance: `baseColorFactor` (RGB, through [`clamp_reflectance`]) times the
//!   `baseColorTexture` (a diffuse map, sRGB-decoded); `metallicFactor` and `roughness` are
//!   ignored (a metal's diffuse part would be dark; the diffuse solve takes the base colour);
//! - cut-outs: `alphaMode` `MASK` (texel alpha × factor alpha ≥ `alphaCutoff`, default 0.5)
//!   and `BLEND` (≥ 0.5) with a base colour texture give the texture as the alpha map too,
//!   its alpha made 0 or 1 by that test; `OPAQUE` ignores the texture's alpha;
//! - glass: `KHR_materials_transmission` > 0, or `BLEND` with factor alpha < 1 and no texture,
//!   is [`Surface::Glass`] of `KHR_materials_ior` (default 1.5), with no diffuse part;
//! - emission: `emissiveFactor × KHR_materials_emissive_strength`, times the mean linear
//!   colour of the `emissiveTexture` when there is one (a patch emits one radiance, so the
//!   texture's pattern is averaged over the whole material, not over each patch).
//!
//! A texture that cannot be read or decoded is a warning naming its JSON path, and the
//! material keeps its factors, as for a missing `map_Kd`.

use std::collections::HashMap;
use std::sync::Arc;

use ::gltf::material::AlphaMode;
use glam::DVec3;
use image::DynamicImage;

use super::data::Source;
use crate::scene::texture::{Texture, TextureKind};
use crate::scene::{Material, MaterialId, Rgb, Surface, TextureId, UvTransform, clamp_reflectance};

/// The refractive index of glass without `KHR_materials_ior` (the extension's default).
pub const DEFAULT_IOR: f64 = 1.5;

/// How a base colour texture's alpha is read.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Alpha {
    /// Ignored: every texel opaque (`OPAQUE`).
    Ignored,
    /// Opaque where texel alpha × `factor` ≥ `cutoff`, else cut out.
    Cutoff { factor: f64, cutoff: f64 },
}

/// The scene's materials and textures built from a glTF document's.
pub(super) struct Materials {
    pub list: Vec<Material>,
    pub textures: Vec<Arc<Texture>>,
    /// Per material, whether it is `doubleSided`.
    pub double_sided: Vec<bool>,
    /// Per material, the texture-coordinate set of its base colour texture, if it has one.
    pub uv_set: Vec<Option<u32>>,
    /// glTF material index → scene material.
    by_index: Vec<MaterialId>,
    default: Option<MaterialId>,
    loaded: HashMap<(usize, AlphaKey), Option<TextureId>>,
}

type AlphaKey = Option<(u64, u64)>;

impl Materials {
    /// Every material of the document (textures read once each), with unique names.
    pub fn build(src: &Source, warnings: &mut Vec<String>) -> Materials {
        let mut ms = Materials {
            list: Vec::new(),
            textures: Vec::new(),
            double_sided: Vec::new(),
            uv_set: Vec::new(),
            by_index: Vec::new(),
            default: None,
            loaded: HashMap::new(),
        };
        for m in src.doc.materials() {
            let id = ms.add(src, &m, warnings);
            ms.by_index.push(id);
        }
        ms
    }

    /// The scene material of a primitive's material index (`None`: glTF's default
    /// material, added on first use as grey 0.5, as for an OBJ face without a material).
    pub fn of(&mut self, index: Option<usize>) -> MaterialId {
        if let Some(id) = index.and_then(|i| self.by_index.get(i)) {
            return *id;
        }
        *self.default.get_or_insert_with(|| {
            self.list.push(Material {
                name: unique_name(&self.list, "default".into()),
                reflectance: Rgb::splat(0.5),
                emission: Rgb::ZERO,
                surface: Surface::Diffuse,
                diffuse_map: None,
                alpha_map: None,
                diffuse_uv: UvTransform::default(),
                alpha_uv: UvTransform::default(),
            });
            self.double_sided.push(false);
            self.uv_set.push(None);
            MaterialId(self.list.len() as u32 - 1)
        })
    }

    fn add(
        &mut self,
        src: &Source,
        m: &::gltf::Material,
        warnings: &mut Vec<String>,
    ) -> MaterialId {
        let i = m.index().unwrap_or(0);
        let at = format!("materials[{i}]");
        let pbr = m.pbr_metallic_roughness();
        let f = pbr.base_color_factor().map(f64::from);
        let base = pbr.base_color_texture();
        let alpha = match m.alpha_mode() {
            AlphaMode::Opaque => Alpha::Ignored,
            AlphaMode::Mask => Alpha::Cutoff {
                factor: f[3],
                cutoff: m.alpha_cutoff().map_or(0.5, f64::from),
            },
            AlphaMode::Blend => Alpha::Cutoff {
                factor: f[3],
                cutoff: 0.5,
            },
        };
        let diffuse = base.as_ref().and_then(|info| {
            let at = format!("{at}.pbrMetallicRoughness.baseColorTexture");
            self.texture(src, &info.texture(), alpha, &at, warnings)
        });
        let transmission = m
            .transmission()
            .map_or(0.0, |t| f64::from(t.transmission_factor()));
        let glass = transmission > 0.0
            || (m.alpha_mode() == AlphaMode::Blend && f[3] < 1.0 && base.is_none());
        let ior = m.ior().map_or(DEFAULT_IOR, f64::from);
        let ior = if ior.is_finite() && ior > 0.0 {
            ior
        } else {
            warnings.push(format!(
                "{}: {at}: ior {ior} is not positive; using {DEFAULT_IOR}",
                src.file
            ));
            DEFAULT_IOR
        };
        let reflectance = if glass {
            Rgb::ZERO
        } else {
            DVec3::new(f[0], f[1], f[2]).map(clamp_reflectance)
        };
        // A file Nusselt exported: its own Kd and Ke, not the unlit base colour 1.
        let own = nusselt_extras(m);
        let reflectance = own.map_or(reflectance, |o| o.reflectance.map(clamp_reflectance));
        let name = m
            .name()
            .map_or_else(|| format!("material {i}"), str::to_string);
        self.list.push(Material {
            name: unique_name(&self.list, name),
            reflectance,
            emission: own.map_or_else(|| emission(src, m, &at, warnings), |o| o.emission),
            surface: if glass {
                Surface::Glass { ior }
            } else {
                Surface::Diffuse
            },
            diffuse_map: diffuse,
            alpha_map: diffuse.filter(|_| alpha != Alpha::Ignored),
            diffuse_uv: UvTransform::default(),
            alpha_uv: UvTransform::default(),
        });
        self.double_sided.push(m.double_sided());
        self.uv_set.push(base.as_ref().map(|b| b.tex_coord()));
        MaterialId(self.list.len() as u32 - 1)
    }

    /// The colour texture of `texture` read with its alpha as `alpha` says, once per
    /// (image, alpha rule); `None` with a warning when it cannot be read.
    fn texture(
        &mut self,
        src: &Source,
        texture: &::gltf::Texture,
        alpha: Alpha,
        at: &str,
        warnings: &mut Vec<String>,
    ) -> Option<TextureId> {
        let image = texture.source();
        let key = match alpha {
            Alpha::Ignored => None,
            Alpha::Cutoff { factor, cutoff } => Some((factor.to_bits(), cutoff.to_bits())),
        };
        if let Some(id) = self.loaded.get(&(image.index(), key)) {
            return *id;
        }
        let made = decode(src, &image)
            .map(|img| apply_alpha(img, alpha))
            .and_then(|img| Texture::from_image(&img, TextureKind::Color));
        let id = match made {
            Ok(t) => {
                self.textures.push(Arc::new(t));
                Some(TextureId(self.textures.len() as u32 - 1))
            }
            Err(e) => {
                warnings.push(format!(
                    "{}: {at} (images[{}]): {e}; the material keeps its baseColorFactor",
                    src.file,
                    image.index()
                ));
                None
            }
        };
        self.loaded.insert((image.index(), key), id);
        id
    }
}

/// `emissiveFactor × emissiveStrength`, times the emissive texture's mean colour.
/// The `Kd`/`Ke` that Nusselt's exporter writes in a material's `extras.nusselt`
/// ([`crate::export::gltf`]): a baked, unlit material's base colour is 1, not the surface's.
#[derive(Clone, Copy, Debug)]
struct OwnMaterial {
    reflectance: Rgb,
    emission: Rgb,
}

fn nusselt_extras(m: &::gltf::Material) -> Option<OwnMaterial> {
    #[derive(serde::Deserialize)]
    struct Own {
        reflectance: [f64; 3],
        emission: [f64; 3],
    }
    #[derive(serde::Deserialize)]
    struct Extras {
        nusselt: Own,
    }
    let raw = m.extras().as_ref()?;
    let own = serde_json::from_str::<Extras>(raw.get()).ok()?.nusselt;
    let own = OwnMaterial {
        reflectance: Rgb::from_array(own.reflectance),
        emission: Rgb::from_array(own.emission),
    };
    (own.reflectance.is_finite() && own.emission.is_finite() && own.emission.min_element() >= 0.0)
        .then_some(own)
}

fn emission(src: &Source, m: &::gltf::Material, at: &str, warnings: &mut Vec<String>) -> Rgb {
    let strength = m.emissive_strength().map_or(1.0, f64::from);
    let e = Rgb::from_array(m.emissive_factor().map(f64::from)) * strength;
    let e = if e.is_finite() {
        e.max(Rgb::ZERO)
    } else {
        Rgb::ZERO
    };
    let Some(info) = m.emissive_texture().filter(|_| e.max_element() > 0.0) else {
        return e;
    };
    let image = info.texture().source();
    match decode(src, &image).and_then(|img| Texture::from_image(&img, TextureKind::Color)) {
        Ok(t) => {
            let [r, g, b, _] = t.mean();
            e * Rgb::new(r, g, b)
        }
        Err(err) => {
            warnings.push(format!(
                "{}: {at}.emissiveTexture (images[{}]): {err}; the material emits its emissiveFactor",
                src.file,
                image.index()
            ));
            e
        }
    }
}

/// An image decoded (format from its bytes); a decoder panic is an error too.
fn decode(src: &Source, image: &::gltf::Image) -> Result<DynamicImage, String> {
    let bytes = src.image_bytes(image)?;
    std::panic::catch_unwind(|| image::load_from_memory(&bytes))
        .map_err(|_| "the image decoder failed on this image".to_string())?
        .map_err(|e| format!("cannot decode the image: {e}"))
}

/// The image with its alpha read as `alpha` says: dropped, or made 0 or 1 by the cutoff test.
fn apply_alpha(img: DynamicImage, alpha: Alpha) -> DynamicImage {
    if !img.color().has_alpha() {
        return img;
    }
    match alpha {
        Alpha::Ignored => match img {
            DynamicImage::ImageRgba32F(_) => DynamicImage::ImageRgb32F(img.to_rgb32f()),
            DynamicImage::ImageLumaA16(_) | DynamicImage::ImageRgba16(_) => {
                DynamicImage::ImageRgb16(img.to_rgb16())
            }
            _ => DynamicImage::ImageRgb8(img.to_rgb8()),
        },
        Alpha::Cutoff { factor, cutoff } => {
            let mut rgba = img.to_rgba8();
            for p in rgba.pixels_mut() {
                let opaque = f64::from(p.0[3]) / 255.0 * factor >= cutoff;
                p.0[3] = if opaque { 255 } else { 0 };
            }
            DynamicImage::ImageRgba8(rgba)
        }
    }
}

/// `name`, or `name (2)`, `name (3)`… when a material already has it (scene files and the
/// viewer find materials by name).
fn unique_name(list: &[Material], name: String) -> String {
    let taken = |n: &str| list.iter().any(|m| m.name == n);
    if !taken(&name) {
        return name;
    }
    (2..)
        .map(|k| format!("{name} ({k})"))
        .find(|n| !taken(n))
        .unwrap_or(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alpha_is_dropped_or_thresholded() {
        let img = DynamicImage::ImageRgba8(image::RgbaImage::from_fn(2, 1, |x, _| {
            image::Rgba([200, 100, 50, if x == 0 { 100 } else { 200 }])
        }));
        let opaque = apply_alpha(img.clone(), Alpha::Ignored);
        assert!(!opaque.color().has_alpha());
        let cut = apply_alpha(
            img.clone(),
            Alpha::Cutoff {
                factor: 1.0,
                cutoff: 0.5,
            },
        )
        .to_rgba8();
        assert_eq!(
            [cut.get_pixel(0, 0).0[3], cut.get_pixel(1, 0).0[3]],
            [0, 255]
        );
        // A factor alpha of 0.5 halves 200/255 to 0.39, below the cutoff.
        let cut = apply_alpha(
            img,
            Alpha::Cutoff {
                factor: 0.5,
                cutoff: 0.5,
            },
        )
        .to_rgba8();
        assert_eq!(cut.get_pixel(1, 0).0[3], 0);
        assert_eq!(cut.get_pixel(1, 0).0[..3], [200, 100, 50]);
    }

    #[test]
    fn names_are_made_unique() {
        let m = |name: &str| Material {
            name: name.into(),
            reflectance: Rgb::ZERO,
            emission: Rgb::ZERO,
            surface: Surface::Diffuse,
            diffuse_map: None,
            alpha_map: None,
            diffuse_uv: UvTransform::default(),
            alpha_uv: UvTransform::default(),
        };
        let list = vec![m("wall"), m("wall (2)")];
        assert_eq!(unique_name(&list, "wall".into()), "wall (3)");
        assert_eq!(unique_name(&list, "floor".into()), "floor");
    }
}
