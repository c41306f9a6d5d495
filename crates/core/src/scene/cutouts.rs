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

impl Scene {
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
        }
    }
}
