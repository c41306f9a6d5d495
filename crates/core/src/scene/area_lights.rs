//! Area lights as a list: the emitting faces added by [`Scene::add_area_light`] (from
//! `--area`, a scene file's `area` lights, the default ceiling light or the viewer), read
//! back and replaced as a whole. Replacing them changes the scene's faces, so the mesh has
//! to be rebuilt afterwards (`Problem::remesh`); the other materials keep their ids.

use glam::DVec3;

use super::{MaterialId, Rgb, Scene};
use crate::geometry::polygon;

/// A planar convex emitter: its corners, counter-clockwise seen from the side it lights,
/// and its radiance (W m⁻² sr⁻¹).
#[derive(Clone, Debug, PartialEq)]
pub struct AreaLight {
    pub corners: Vec<DVec3>,
    pub radiance: Rgb,
}

/// Why an area light was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum AreaLightError {
    #[error("area light {0}: needs 3 or more finite corners spanning a non-zero area")]
    Shape(usize),
    #[error("area light {0}: the radiance must be finite and non-negative")]
    Radiance(usize),
}

/// The corners of a square of side `size` centred at `centre` facing unit `normal`,
/// counter-clockwise seen from the side `normal` points to.
pub fn square_corners(centre: DVec3, normal: DVec3, size: f64) -> Vec<DVec3> {
    let (t, b) = crate::geometry::sampling::basis(normal);
    let h = 0.5 * size;
    // t × b = normal, so this order is counter-clockwise seen from `normal`'s side.
    vec![
        centre - t * h - b * h,
        centre + t * h - b * h,
        centre + t * h + b * h,
        centre - t * h + b * h,
    ]
}

impl AreaLight {
    /// A square emitter; `None` when `normal` is zero or `size` is not a positive number.
    pub fn square(centre: DVec3, normal: DVec3, size: f64, radiance: Rgb) -> Option<AreaLight> {
        let n = normal.try_normalize()?;
        if !(size.is_finite() && size > 0.0 && centre.is_finite()) {
            return None;
        }
        Some(AreaLight {
            corners: square_corners(centre, n, size),
            radiance,
        })
    }

    /// The mean of the corners.
    pub fn centre(&self) -> DVec3 {
        let n = self.corners.len().max(1) as f64;
        self.corners.iter().copied().sum::<DVec3>() / n
    }

    /// The unit normal of the side it lights (`None` for a degenerate polygon).
    pub fn normal(&self) -> Option<DVec3> {
        polygon::normal(&self.corners)
    }

    /// The side of the square of the same area.
    pub fn side(&self) -> f64 {
        polygon::area(&self.corners).max(0.0).sqrt()
    }

    /// Refuses a light that could not be meshed or would emit nonsense (`k` numbers it in
    /// the message).
    pub fn check(&self, k: usize) -> Result<(), AreaLightError> {
        let finite = self.corners.iter().all(|c| c.is_finite());
        if self.corners.len() < 3 || !finite || self.normal().is_none() {
            return Err(AreaLightError::Shape(k));
        }
        if !self.radiance.is_finite() || self.radiance.min_element() < 0.0 {
            return Err(AreaLightError::Radiance(k));
        }
        Ok(())
    }
}

/// Name prefix of the materials [`Scene::add_area_light`] makes.
const AREA_PREFIX: &str = "area light";

impl Scene {
    /// Whether face `f` is an area light added by [`Scene::add_area_light`] (no OBJ line,
    /// an `area light` material).
    fn is_area_light_face(&self, f: usize) -> bool {
        let face = &self.faces[f];
        face.line == 0
            && self
                .materials
                .get(face.material.0 as usize)
                .is_some_and(|m| m.name.starts_with(AREA_PREFIX))
    }

    /// The area lights, in the order they were added.
    pub fn area_lights(&self) -> Vec<AreaLight> {
        (0..self.faces.len())
            .filter(|&f| self.is_area_light_face(f))
            .map(|f| AreaLight {
                corners: self.faces[f].vertices.clone(),
                radiance: self.materials[self.faces[f].material.0 as usize].emission,
            })
            .collect()
    }

    /// The material of each area light, in the order of [`Scene::area_lights`]: its
    /// radiance is that material's emission, so a change of radiance alone is a material
    /// edit (no new faces, no re-meshing).
    pub fn area_light_materials(&self) -> Vec<MaterialId> {
        (0..self.faces.len())
            .filter(|&f| self.is_area_light_face(f))
            .map(|f| self.faces[f].material)
            .collect()
    }

    /// Replaces the area lights with `lights` (each checked first: on error nothing
    /// changes). Returns, per old material, its new id (`None`: an area light's, removed);
    /// the new lights' materials follow the kept ones.
    pub fn set_area_lights(
        &mut self,
        lights: &[AreaLight],
    ) -> Result<Vec<Option<MaterialId>>, AreaLightError> {
        for (k, l) in lights.iter().enumerate() {
            l.check(k + 1)?;
        }
        let keep_face: Vec<bool> = (0..self.faces.len())
            .map(|f| !self.is_area_light_face(f))
            .collect();
        let mut keep_face = keep_face.into_iter();
        self.faces.retain(|_| keep_face.next().unwrap_or(true));
        let mut used = vec![false; self.materials.len()];
        for f in &self.faces {
            if let Some(u) = used.get_mut(f.material.0 as usize) {
                *u = true;
            }
        }
        let mut next = 0u32;
        let remap: Vec<Option<MaterialId>> = self
            .materials
            .iter()
            .zip(&used)
            .map(|(m, &u)| {
                (u || !m.name.starts_with(AREA_PREFIX)).then(|| {
                    next += 1;
                    MaterialId(next - 1)
                })
            })
            .collect();
        let mut keep_material = remap.iter().map(Option::is_some);
        self.materials
            .retain(|_| keep_material.next().unwrap_or(true));
        for f in &mut self.faces {
            if let Some(Some(id)) = remap.get(f.material.0 as usize) {
                f.material = *id;
            }
        }
        for l in lights {
            self.add_area_light(l.corners.clone(), l.radiance);
        }
        Ok(remap)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Face, LoadOptions};

    /// What a face is, for comparing (faces have no `PartialEq`).
    fn shapes(faces: &[Face]) -> Vec<(Vec<DVec3>, MaterialId)> {
        faces
            .iter()
            .map(|f| (f.vertices.clone(), f.material))
            .collect()
    }

    fn light(y: f64, radiance: f64) -> AreaLight {
        AreaLight::square(
            DVec3::new(270.0, y, 270.0),
            DVec3::NEG_Y,
            100.0,
            Rgb::splat(radiance),
        )
        .unwrap()
    }

    /// Added, read back, replaced and removed: the model's own faces and materials keep
    /// their order and ids throughout.
    #[test]
    fn area_lights_are_read_back_and_replaced() {
        let mut scene = Scene::builtin("cornell", &LoadOptions::default()).unwrap();
        let (faces, materials) = (shapes(&scene.faces), scene.materials.clone());
        let a = light(500.0, 2.0);
        scene.add_area_light(a.corners.clone(), a.radiance);
        assert_eq!(scene.area_lights(), vec![a.clone()]);
        let (b, c) = (light(400.0, 3.0), light(300.0, 4.0));
        let remap = scene.set_area_lights(&[b.clone(), c.clone()]).unwrap();
        assert_eq!(remap.len(), materials.len() + 1);
        assert_eq!(remap.last(), Some(&None), "the old light's material goes");
        assert_eq!(scene.area_lights(), vec![b, c]);
        assert_eq!(scene.materials.len(), materials.len() + 2);
        assert_eq!(scene.materials.last().unwrap().name, "area light 2");
        let ids = scene.area_light_materials();
        assert_eq!(ids.len(), 2);
        assert_eq!(scene.materials[ids[1].0 as usize].emission, Rgb::splat(4.0));
        scene.set_area_lights(&[]).unwrap();
        assert!(scene.area_light_materials().is_empty());
        assert_eq!(shapes(&scene.faces), faces);
        assert_eq!(scene.materials, materials);
    }

    /// A degenerate or negative light is refused and the scene stays as it was.
    #[test]
    fn bad_area_lights_change_nothing() {
        let mut scene = Scene::builtin("cornell", &LoadOptions::default()).unwrap();
        let faces = shapes(&scene.faces);
        let flat = AreaLight {
            corners: vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0],
            radiance: Rgb::ONE,
        };
        let dark = AreaLight {
            radiance: Rgb::splat(-1.0),
            ..light(500.0, 1.0)
        };
        let good = light(500.0, 1.0);
        assert_eq!(
            scene.set_area_lights(&[good.clone(), flat]),
            Err(AreaLightError::Shape(2))
        );
        assert_eq!(
            scene.set_area_lights(&[dark]),
            Err(AreaLightError::Radiance(1))
        );
        assert_eq!(shapes(&scene.faces), faces);
        assert!(AreaLight::square(DVec3::ZERO, DVec3::ZERO, 1.0, Rgb::ONE).is_none());
        assert!(AreaLight::square(DVec3::ZERO, DVec3::Y, -1.0, Rgb::ONE).is_none());
    }

    #[test]
    fn a_square_faces_its_normal_with_its_centre_and_side() {
        let l = light(500.0, 1.0);
        assert!((l.centre() - DVec3::new(270.0, 500.0, 270.0)).length() < 1e-9);
        assert!((l.normal().unwrap() - DVec3::NEG_Y).length() < 1e-12);
        assert!((l.side() - 100.0).abs() < 1e-9);
    }
}
