//! The scene's cut-outs for ray queries: which faces have an alpha map (`map_d`, else the
//! diffuse map's alpha) with holes in it, and their texture coordinates, turned into the
//! [`CutOut`]s of a [`Bvh`] (see [`crate::geometry::alpha_mask`]).
//!
//! A face without texture coordinates reads its map's mean coverage for the solve
//! ([`Scene::texture_mean`]) and is opaque to rays: it has no point-wise mapping to test.

use std::sync::Arc;

use glam::DVec3;

use super::Scene;
use crate::geometry::bvh::TriangleInput;
use crate::geometry::{AlphaMask, Bvh, CutOut};

/// The masks of a scene's cut-out materials and which material reads which.
pub struct CutOuts {
    masks: Arc<[AlphaMask]>,
    /// Per material: its mask's index, when its alpha source has holes.
    material_mask: Vec<Option<u32>>,
    /// Glass materials as seen by the solve ([`Scene::solve_cutouts`]): the mask index of
    /// the pane's dither and the world length of one of its texels; `None` elsewhere.
    glass: Option<(u32, f64)>,
}

/// Texels on a side of the glass dither (repeating).
const DITHER_SIDE: u32 = 256;

/// A pane of transmittance `t` as a random mask: each texel a hole with probability `t`
/// (a fixed hash, so every run sees the same pane).
fn glass_dither(t: f64) -> AlphaMask {
    AlphaMask::new(DITHER_SIDE, DITHER_SIDE, |x, y| {
        let h = crate::geometry::sampling::hash_seed(&[u64::from(x), u64::from(y), 0x91a55]);
        (h >> 11) as f64 / (1u64 << 53) as f64 >= t
    })
}

impl CutOuts {
    /// Whether no material has a hole.
    pub fn is_empty(&self) -> bool {
        self.masks.is_empty()
    }

    /// The cut-out of the triangle `vertices` (on face `face` of `scene`), if its material
    /// has holes and the face has texture coordinates.
    pub fn of(&self, scene: &Scene, face: usize, vertices: [DVec3; 3]) -> Option<CutOut> {
        let f = scene.faces.get(face)?;
        if let Some((mask, texel)) = self.glass
            && matches!(
                scene.materials[f.material.0 as usize].surface,
                super::Surface::Glass { .. }
            )
        {
            return Some(CutOut {
                mask,
                uv: pane_uv(vertices, texel * f64::from(DITHER_SIDE)),
            });
        }
        let mask = (*self.material_mask.get(f.material.0 as usize)?)?;
        let m = &scene.materials[f.material.0 as usize];
        let transform = if m.alpha_map.is_some() {
            m.alpha_uv
        } else {
            m.diffuse_uv
        };
        let mut uv = [glam::Vec2::ZERO; 3];
        for (k, v) in vertices.iter().enumerate() {
            uv[k] = transform.apply(f.uv_at(*v)?).as_vec2();
        }
        Some(CutOut { mask, uv })
    }

    /// Fills the `cut` of each input triangle; `face_of(i)` is the scene face of input `i`.
    pub fn mark(
        &self,
        scene: &Scene,
        input: &mut [TriangleInput],
        face_of: impl Fn(usize) -> usize,
    ) {
        if self.is_empty() {
            return;
        }
        for (i, t) in input.iter_mut().enumerate() {
            t.cut = self.of(scene, face_of(i), t.vertices);
        }
    }

    /// The hierarchy over `input` (already [`CutOuts::mark`]ed) with these masks.
    pub fn bvh(&self, input: &[TriangleInput]) -> Bvh {
        Bvh::build_with_masks(input, self.masks.clone())
    }
}

/// Texture coordinates of a triangle in its own plane, in units of `period` (world length):
/// the dither's texels keep one world size whatever the triangle.
fn pane_uv(vertices: [DVec3; 3], period: f64) -> [glam::Vec2; 3] {
    let n = (vertices[1] - vertices[0])
        .cross(vertices[2] - vertices[0])
        .normalize_or_zero();
    let (a, b) = crate::geometry::sampling::basis(if n == DVec3::ZERO { DVec3::Z } else { n });
    vertices.map(|v| glam::Vec2::new((v.dot(a) / period) as f32, (v.dot(b) / period) as f32))
}

impl Scene {
    /// [`Scene::cutouts`] as the radiosity solve sees the scene: glass faces (MTL
    /// `illum` 4/6/7, `d` < 1) are thin panes that let the fraction `t` of the light through
    /// (the slab transmittance, `formfactor::lights::slab_transmittance`), as a fine random
    /// mask of holes: a ray crossing a pane passes with probability `t`, so a visibility
    /// estimated from many rays carries `t` per pane crossed, for light between patches as
    /// for the lights' rays. The dither's texels are 1/4096 of the scene's diagonal. The eye
    /// passes and the path tracer use [`Scene::cutouts`], where glass is glass.
    pub fn solve_cutouts(&self) -> CutOuts {
        let mut cuts = self.cutouts();
        let Some(ior) = self.materials.iter().find_map(|m| match m.surface {
            super::Surface::Glass { ior } => Some(ior),
            _ => None,
        }) else {
            return cuts;
        };
        let t = crate::formfactor::lights::slab_transmittance(ior);
        let mut masks: Vec<AlphaMask> = cuts.masks.to_vec();
        masks.push(glass_dither(t));
        cuts.glass = Some((
            masks.len() as u32 - 1,
            self.bounds().diagonal().max(f64::MIN_POSITIVE) / 4096.0,
        ));
        cuts.masks = masks.into();
        cuts
    }

    /// The masks of the materials whose alpha source (`map_d`, else the diffuse map) has
    /// texels below [`super::texture::OPAQUE_ALPHA`]. Built anew on each call (one bit per
    /// texel of those maps).
    pub fn cutouts(&self) -> CutOuts {
        let mut masks = Vec::new();
        let mut texture_mask = vec![None; self.textures.len()];
        let material_mask = self
            .materials
            .iter()
            .map(|m| {
                let id = m.alpha_map.or(m.diffuse_map)?.0 as usize;
                if texture_mask.get(id)?.is_none() {
                    let mask = self.textures[id].alpha_mask()?;
                    masks.push(mask);
                    texture_mask[id] = Some(masks.len() as u32 - 1);
                }
                texture_mask[id]
            })
            .collect();
        CutOuts {
            masks: masks.into(),
            material_mask,
            glass: None,
        }
    }
}
