//! Lights for a model that brings none. Models found on the web rarely carry `Ke`: their
//! authors lit them in a renderer. Such a model opens lit: under a uniform sky and a sun
//! where rays can leave it (an atrium, a street, a box open at the front), else by an area
//! light under the top of its interior.

use glam::DVec3;

use super::{Light, Rgb, Scene};
use crate::geometry::bvh::TriangleInput;
use crate::geometry::sampling::{cosine_hemisphere, hash_seed};
use crate::geometry::{Bvh, Ray, Rng, polygon};

/// How to change what was added, for the message that says so.
pub const DEFAULT_LIGHTS_HINT: &str = "give your own with --sky R,G,B, --sun X,Y,Z,R,G,B or \
     --point X,Y,Z,R,G,B (or in the Lights panel); --no-default-lights refuses an unlit model";

/// Cosine-weighted fraction of the model's surface from which rays escape above which it
/// is lit by a sky and a sun.
const OPEN_FRACTION: f64 = 0.01;
/// Faces sampled for the escape fraction (evenly spread in file order) and rays per face.
const SAMPLED_FACES: usize = 4096;
const RAYS_PER_FACE: usize = 8;

/// The default sky's radiance: an unoccluded floor of ρ = 0.5 shows 0.25 from it alone.
pub const DEFAULT_SKY: f64 = 0.5;
/// The default sun's irradiance on a surface facing it, and its elevation and azimuth: a
/// white (ρ 0.95) wall facing +z shows about 0.54 under this sun and sky, short of white.
pub const DEFAULT_SUN: f64 = 2.0;
const SUN_ELEVATION_DEG: f64 = 55.0;
const SUN_AZIMUTH_DEG: f64 = 30.0;

/// The default sun's direction (+y up): elevation 55°, azimuth 30° from +z towards +x.
pub fn default_sun_direction() -> DVec3 {
    let (e, a) = (SUN_ELEVATION_DEG.to_radians(), SUN_AZIMUTH_DEG.to_radians());
    DVec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
}

fn face_bvh(scene: &Scene) -> Bvh {
    let mut input = Vec::new();
    let mut faces = Vec::new();
    for (i, f) in scene.faces.iter().enumerate() {
        for t in polygon::triangulate(&f.vertices) {
            input.push(TriangleInput {
                vertices: [f.vertices[t[0]], f.vertices[t[1]], f.vertices[t[2]]],
                id: input.len() as u32,
                cull_back: false,
                cut: None,
            });
            faces.push(i);
        }
    }
    let cuts = scene.cutouts();
    cuts.mark(scene, &mut input, |i| faces[i]);
    cuts.bvh(&input)
}

/// Area-weighted fraction of cosine-distributed rays from the faces' lit sides that hit
/// nothing (deterministic: seeded per face).
fn escape_fraction(scene: &Scene, bvh: &Bvh, epsilon: f64) -> f64 {
    let stride = scene.faces.len().div_ceil(SAMPLED_FACES).max(1);
    let (mut escaped, mut total) = (0.0, 0.0);
    for (k, f) in scene.faces.iter().enumerate().step_by(stride) {
        let Some(n) = polygon::normal(&f.vertices) else {
            continue;
        };
        let area = polygon::area(&f.vertices);
        let c = polygon::centroid(&f.vertices);
        let sides: &[f64] = if scene.two_sided {
            &[1.0, -1.0]
        } else {
            &[1.0]
        };
        for &side in sides {
            let n = n * side;
            let mut rng = Rng::new(hash_seed(&[k as u64, side as u64]), 3);
            for _ in 0..RAYS_PER_FACE {
                let d = cosine_hemisphere(n, rng.next_f64(), rng.next_f64());
                let ray = Ray::new(c + n * epsilon, d);
                total += area;
                if bvh.closest_hit(&ray, 0.0, f64::INFINITY).is_none() {
                    escaped += area;
                }
            }
        }
    }
    if total > 0.0 { escaped / total } else { 0.0 }
}

/// Distance to the first face along `dir` from `p`, or `fallback`.
fn distance(bvh: &Bvh, p: DVec3, dir: DVec3, fallback: f64) -> f64 {
    bvh.closest_hit(&Ray::new(p, dir), 0.0, f64::INFINITY)
        .map_or(fallback, |h| h.t)
}

impl Scene {
    /// Adds default lights when nothing in the scene gives light, and says in one line what
    /// it added and how to change it; `None` when the scene was lit already.
    pub fn add_default_lights(&mut self) -> Option<String> {
        if self.has_light() {
            return None;
        }
        let bvh = face_bvh(self);
        let b = self.bounds();
        let epsilon = 1e-6 * b.diagonal().max(1e-12);
        let open = escape_fraction(self, &bvh, epsilon);
        let added = if open > OPEN_FRACTION {
            self.lights.push(Light::Sky {
                radiance: Rgb::splat(DEFAULT_SKY),
            });
            self.lights.push(Light::Sun {
                direction: default_sun_direction(),
                irradiance: Rgb::splat(DEFAULT_SUN),
                angular_radius: 0.0,
            });
            format!(
                "added a {} and a {} (rays leave the model from {:.0} % of its surface)",
                self.lights[0].describe(),
                self.lights[1].describe(),
                open * 100.0
            )
        } else {
            self.add_ceiling_light(&bvh)
        };
        Some(format!(
            "no light in the model: {added}; {DEFAULT_LIGHTS_HINT}"
        ))
    }

    /// A square emitter facing down just under whatever is above the centre of the bounds,
    /// a quarter of the room's narrower width on a side, bright enough that the floor
    /// straight below gets an irradiance of about π (radiance ρ).
    fn add_ceiling_light(&mut self, bvh: &Bvh) -> String {
        let b = self.bounds();
        let c = b.center();
        let size = b.max - b.min;
        let up = distance(bvh, c, DVec3::Y, size.y * 0.5);
        let down = distance(bvh, c, -DVec3::Y, size.y * 0.5);
        let height = up + down;
        let y = c.y + up - 0.02 * height;
        let q = DVec3::new(c.x, y, c.z);
        let span = |axis: DVec3, full: f64| {
            distance(bvh, q, axis, full * 0.5) + distance(bvh, q, -axis, full * 0.5)
        };
        let width = span(DVec3::X, size.x).min(span(DVec3::Z, size.z));
        let h = (0.125 * width).max(1e-6 * b.diagonal());
        // Counter-clockwise seen from below: the light faces −y.
        let corners = vec![
            DVec3::new(q.x - h, y, q.z - h),
            DVec3::new(q.x + h, y, q.z - h),
            DVec3::new(q.x + h, y, q.z + h),
            DVec3::new(q.x - h, y, q.z + h),
        ];
        let drop = (0.98 * height).max(h);
        let radiance = std::f64::consts::PI * drop * drop / (4.0 * h * h);
        self.add_area_light(corners, Rgb::splat(radiance));
        format!(
            "added an area light of radiance {radiance:.3} and side {:.3} under the ceiling \
             at {:.3},{:.3},{:.3} (no ray leaves the model)",
            2.0 * h,
            q.x,
            q.y,
            q.z
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LoadOptions;

    const BOX: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
        f 1 2 3 4\nf 5 8 7 6\nf 1 5 6 2\nf 4 3 7 8\nf 1 4 8 5\nf 2 6 7 3\n";

    #[test]
    fn a_closed_box_gets_a_ceiling_light_facing_down() {
        let mut s = Scene::from_obj_str("box.obj", BOX, &[], &LoadOptions::default()).unwrap();
        assert!(s.check_lit().is_err());
        let msg = s.add_default_lights().expect("lights added");
        assert!(msg.contains("area light"), "{msg}");
        assert!(s.lights.is_empty());
        let light = s.faces.last().unwrap();
        let n = polygon::normal(&light.vertices).unwrap();
        assert!(n.y < -0.999, "{n}");
        assert!(light.vertices.iter().all(|v| v.y > 0.9 && v.y < 1.0));
        assert!(s.check_lit().is_ok());
        assert_eq!(s.add_default_lights(), None);
    }

    #[test]
    fn an_open_floor_gets_a_sky_and_a_sun() {
        let floor = "v 0 0 0\nv 0 0 1\nv 1 0 1\nv 1 0 0\nf 1 2 3 4\n";
        let mut s = Scene::from_obj_str("f.obj", floor, &[], &LoadOptions::default()).unwrap();
        let msg = s.add_default_lights().expect("lights added");
        assert!(msg.contains("sky") && msg.contains("sun"), "{msg}");
        assert_eq!(s.lights.len(), 2);
        assert!(default_sun_direction().y > 0.8);
    }
}
