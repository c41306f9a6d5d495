//! `KHR_lights_punctual` lights and the first perspective camera, placed by their nodes.
//!
//! Units: glTF gives point and spot lights in candela (lm/sr) and directional lights in
//! lux (lm/m²); Nusselt's point light is an intensity in W/sr and its sun an irradiance in
//! W/m². The conversion is Blender's (io_scene_gltf2, lighting mode "Standard", `SPEC`), so
//! that a scene made in Blender keeps its brightness through a glTF file:
//! - Blender's exporter (`blender/exp/lights.py`, `__gather_intensity`) writes a sun of
//!   strength `S` W/m² as `S × 683` lux, and a point or spot of power `P` W as
//!   `P / 4π × 683` cd (`PBR_WATTS_TO_LUMENS = 683`, from `blender/com/conversion.py`);
//! - its importer (`blender/imp/light.py`, `calc_energy_directional`,
//!   `calc_energy_pointlike`) inverts that: `S = lux / 683`, `P = cd × 4π / 683`.
//!
//! A point light of power `P` W radiates `P / 4π` W/sr (Blender's spots are specified "as if
//! they're points"), so **intensity [W/sr] = cd / 683** and **irradiance [W/m²] = lux / 683**,
//! per channel times the light's `color`: [`LUMENS_PER_WATT`].
//!
//! Directions: glTF lights and cameras look along their node's −Z. A directional light
//! therefore arrives from +Z, Nusselt's sun `direction` (which points towards the sun); a
//! spot shines along −Z. `range` is ignored (lights fall off with the inverse square to any
//! distance). The camera keeps its position, view direction and vertical field of view; its
//! roll is lost, since Nusselt's camera keeps +y up.

use glam::{DMat4, DVec3};

use super::data::Source;
use super::mesh::Instance;
use crate::scene::{Camera, Light, Rgb, SpotCone};

/// Blender's `PBR_WATTS_TO_LUMENS`: lumens per watt (the luminous efficacy at 555 nm) by
/// which glTF's photometric light units are divided to give Nusselt's radiometric ones.
pub const LUMENS_PER_WATT: f64 = 683.0;

/// The lights of the placed nodes, and warnings for those that cannot be used.
pub(super) fn lights(
    src: &Source,
    instances: &[Instance],
    warnings: &mut Vec<String>,
) -> Vec<Light> {
    let nodes: Vec<::gltf::Node> = src.doc.nodes().collect();
    let mut out = Vec::new();
    let mut ranged = 0;
    for inst in instances {
        let Some(light) = nodes[inst.node].light() else {
            continue;
        };
        let at = format!(
            "nodes[{}] (KHR_lights_punctual.lights[{}])",
            inst.node,
            light.index()
        );
        ranged += usize::from(light.range().is_some());
        let colour = Rgb::from_array(light.color().map(f64::from));
        let power = colour * (f64::from(light.intensity()) / LUMENS_PER_WATT);
        if !power.is_finite() || power.min_element() < 0.0 {
            warnings.push(format!("{}: {at}: colour × intensity {power} is not finite and non-negative; light skipped", src.file));
            continue;
        }
        match place(light.kind(), inst.world, power) {
            Some(l) => out.push(l),
            None => warnings.push(format!(
                "{}: {at}: its node's transform gives no direction; light skipped",
                src.file
            )),
        }
    }
    if ranged > 0 {
        warnings.push(format!(
            "{}: the 'range' of {ranged} light(s) is ignored: lights fall off with the inverse square to any distance",
            src.file
        ));
    }
    out
}

/// A light of `kind` and radiometric strength `power` at the node transform `world`.
fn place(kind: ::gltf::khr_lights_punctual::Kind, world: DMat4, power: Rgb) -> Option<Light> {
    use ::gltf::khr_lights_punctual::Kind;
    let position = world.transform_point3(DVec3::ZERO);
    let forward = world.transform_vector3(DVec3::NEG_Z).try_normalize();
    Some(match kind {
        Kind::Directional => Light::Sun {
            direction: -forward?,
            irradiance: power,
            angular_radius: 0.0,
        },
        Kind::Point => Light::Point {
            position,
            intensity: power,
            cone: None,
        },
        Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => {
            let outer = f64::from(outer_cone_angle).clamp(0.0, std::f64::consts::FRAC_PI_2);
            Light::Point {
                position,
                intensity: power,
                cone: Some(SpotCone {
                    direction: forward?,
                    inner: f64::from(inner_cone_angle).clamp(0.0, outer),
                    outer,
                }),
            }
        }
    })
}

/// The first perspective camera of the placed nodes, if one gives a usable view.
pub(super) fn camera(
    src: &Source,
    instances: &[Instance],
    warnings: &mut Vec<String>,
) -> Option<Camera> {
    let nodes: Vec<::gltf::Node> = src.doc.nodes().collect();
    for inst in instances {
        let Some(cam) = nodes[inst.node].camera() else {
            continue;
        };
        let ::gltf::camera::Projection::Perspective(p) = cam.projection() else {
            continue;
        };
        let eye = inst.world.transform_point3(DVec3::ZERO);
        let forward = inst.world.transform_vector3(DVec3::NEG_Z).try_normalize();
        let c = forward.map(|f| Camera {
            eye,
            target: eye + f,
            vfov_deg: f64::from(p.yfov()).to_degrees(),
        });
        match c.filter(|c| c.vfov_deg > 0.0 && c.vfov_deg < 180.0 && c.basis().is_some()) {
            Some(c) => return Some(c),
            None => warnings.push(format!(
                "{}: nodes[{}] (cameras[{}]): no usable view (zero direction, straight up or down, or a field of view outside 0–180°); camera ignored",
                src.file,
                inst.node,
                cam.index()
            )),
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use ::gltf::khr_lights_punctual::Kind;

    /// A node rotated 90° about x: its −Z axis points down (−y), so a directional light
    /// on it shines down and Nusselt's sun lies straight up.
    #[test]
    fn lights_look_along_their_nodes_minus_z() {
        let world = DMat4::from_rotation_x(-std::f64::consts::FRAC_PI_2);
        let Some(Light::Sun { direction, .. }) = place(Kind::Directional, world, Rgb::ONE) else {
            panic!("not a sun");
        };
        assert!((direction - DVec3::Y).length() < 1e-12, "{direction}");
        let at = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0)) * world;
        let spot = Kind::Spot {
            inner_cone_angle: 0.1,
            outer_cone_angle: 0.3,
        };
        let Some(Light::Point {
            position,
            cone: Some(c),
            ..
        }) = place(spot, at, Rgb::ONE)
        else {
            panic!("not a spot");
        };
        assert!((position - DVec3::new(1.0, 2.0, 3.0)).length() < 1e-12);
        assert!((c.direction - DVec3::NEG_Y).length() < 1e-12);
        assert!((c.inner - 0.1).abs() < 1e-7 && (c.outer - 0.3).abs() < 1e-7);
    }
}
