//! A first view of a model that has no camera of its own.
//!
//! A user's OBJ may face any way: a room exported from a modelling program usually opens
//! towards +z, so a fixed view from −z sees the outside of its back wall (black, culled in
//! the viewer). Instead, candidate views are scored by how many of a few hundred rays
//! through them hit a light or the lit front of a surface (one light sample each, through
//! the path tracer's own light sampling), scaled down when they land on fewer than a dozen
//! faces, with hits on the model's outer skin (a roof in the sun) counting a quarter, and
//! the best is taken: from outside along the six axes and eight diagonals,
//! framing the bounds, and, for a closed room or building whose outside shows only a few
//! walls or its outer skin, from near its upper corners and from its centre.

use glam::DVec3;

use super::pathtrace::PathTracer;
use crate::geometry::{Ray, Rng};
use crate::scene::{Camera, Scene};

/// Rays per candidate view (a grid `GRID_X × GRID_Y`).
const GRID_X: u32 = 24;
const GRID_Y: u32 = 18;

/// Inside views are tried only when no outside view has this fraction of its rays on lit
/// surface below the model's skin and shows [`VARIED_FACES`] lit faces: a model seen whole
/// from outside is the more natural first view, unless all that is seen from outside is a
/// few walls, or its outer skin (a building's roof and walls, the courtyard hidden).
const OUTSIDE_ENOUGH: f64 = 0.05;

/// The scene's own camera, or [`choose_camera`].
pub fn default_camera(scene: &Scene) -> Camera {
    scene.camera.unwrap_or_else(|| choose_camera(scene))
}

/// The candidate view that sees the most lit, front-facing surface (first of equals: the
/// view from +z looking along −z first).
pub fn choose_camera(scene: &Scene) -> Camera {
    let b = scene.bounds();
    let tracer = PathTracer::new(scene);
    let mut best: Option<(f64, bool, Camera)> = None;
    for (camera, inside) in candidates(b.min, b.max) {
        if inside && best.is_some_and(|(_, enough, _)| enough) {
            break;
        }
        let seen = score(&tracer, &camera, (b.min, b.max));
        let (score, enough) = (
            seen.lit * (seen.faces as f64 / VARIED_FACES as f64).min(1.0) * plan_weight(&camera),
            seen.faces >= VARIED_FACES && seen.deep >= OUTSIDE_ENOUGH,
        );
        if best.is_none_or(|(s, _, _)| score > s * (1.0 + TIE)) {
            best = Some((score, enough, camera));
        }
    }
    best.map(|(_, _, c)| c)
        .unwrap_or_else(|| Camera::framing(b.min, b.max))
}

/// What a view straight down (a plan) counts: it sees the floor and the tops of things, and
/// wins on lit fraction alone over the front of a box open towards the viewer (McGuire's
/// Cornell box with Suzanne under its added ceiling light), which is the view people
/// expect unless the plan is clearly better (a ground plane seen from above).
const PLAN_WEIGHT: f64 = 0.8;

fn plan_weight(camera: &Camera) -> f64 {
    let down = (camera.target - camera.eye)
        .try_normalize()
        .is_some_and(|d| d.y < -0.99);
    if down { PLAN_WEIGHT } else { 1.0 }
}

/// Distinct lit faces a view must show for its score to count in full: fewer, and it is
/// scaled down in proportion. The outside of a closed building under the sky (the
/// Dabrović atrium, the jeweller's shop) is one lit wall filling the frame; the view
/// inside, of arches, columns and floor, is the one a user wants first.
const VARIED_FACES: usize = 12;

/// How much a lit hit on the model's outer skin counts (see [`depth_in`]).
const SKIN_WEIGHT: f64 = 0.25;

/// Hits less than this fraction of the bounds' diagonal inside the bounds are on the
/// model's outer skin.
const SKIN_DEPTH: f64 = 0.02;

/// How far past its entry into the bounds `(min, max)` a ray from `eye` reaches `x`:
/// a roof or an outer wall seen from outside lies just inside, the rooms behind a door or
/// the floor of a courtyard deep inside. A building without lights of its own is lit by
/// the default sky and sun on its outside; counted in full, a view of its roof in the sun
/// would beat the view through its door into the rooms a user opened it for.
fn depth_in(eye: DVec3, x: DVec3, (min, max): (DVec3, DVec3)) -> f64 {
    let Some(dir) = (x - eye).try_normalize() else {
        return 0.0;
    };
    let mut entry: f64 = 0.0;
    for k in 0..3 {
        if dir[k] != 0.0 {
            let (t0, t1) = ((min[k] - eye[k]) / dir[k], (max[k] - eye[k]) / dir[k]);
            entry = entry.max(t0.min(t1));
        }
    }
    (x - eye).length() - entry
}

/// What a candidate view's rays see.
struct Seen {
    /// Fraction of the rays whose first hit is lit, those on the model's outer skin counted
    /// [`SKIN_WEIGHT`].
    lit: f64,
    /// Fraction of the rays whose first hit is lit and below the skin.
    deep: f64,
    /// Distinct faces the lit hits land on.
    faces: usize,
}

fn score(tracer: &PathTracer, camera: &Camera, bounds: (DVec3, DVec3)) -> Seen {
    let mut rng = Rng::new(0x5eed, 7);
    let (mut lit, mut deep) = (0.0, 0.0);
    let mut faces = std::collections::BTreeSet::new();
    let diagonal = (bounds.1 - bounds.0).length();
    for j in 0..GRID_Y {
        for i in 0..GRID_X {
            let dir = camera.ray_dir(
                (i as f64 + 0.5) / GRID_X as f64 * 256.0,
                (j as f64 + 0.5) / GRID_Y as f64 * 256.0,
                256,
                256,
            );
            if let Some(hit) = tracer.first_lit_face(&Ray::new(camera.eye, dir), 2, &mut rng) {
                let skin = depth_in(camera.eye, hit.x, bounds) < SKIN_DEPTH * diagonal;
                lit += if skin { SKIN_WEIGHT } else { 1.0 };
                deep += if skin { 0.0 } else { 1.0 };
                faces.insert(hit.face);
            }
        }
    }
    let rays = (GRID_X * GRID_Y) as f64;
    Seen {
        lit: lit / rays,
        deep: deep / rays,
        faces: faces.len(),
    }
}

/// A later candidate must beat the best so far by this fraction of its score (sampling
/// noise): among equals the earlier, more natural view stays.
const TIE: f64 = 0.15;

/// The distance from `center` along `-dir` at which every corner of the box is inside a
/// square image of `vfov_deg`, with a small margin.
fn fit_distance(min: DVec3, max: DVec3, dir: DVec3, vfov_deg: f64) -> f64 {
    let center = (min + max) * 0.5;
    let probe = Camera {
        eye: center - dir,
        target: center,
        vfov_deg,
    };
    let Some((f, r, u)) = probe.basis() else {
        return (max - min).length();
    };
    let tan = (vfov_deg.to_radians() * 0.5).tan() / 1.05;
    let mut dist: f64 = 0.0;
    for i in 0..8 {
        let c = DVec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        );
        let d = c - center;
        let lateral = d.dot(r).abs().max(d.dot(u).abs());
        dist = dist.max(lateral / tan - d.dot(f));
    }
    dist.max(1e-9)
}

/// Outside views first, then inside ones (`true`): from near the upper corners looking at
/// the centre (the usual view of a room), then from the centre.
fn candidates(min: DVec3, max: DVec3) -> Vec<(Camera, bool)> {
    let center = (min + max) * 0.5;
    let radius = ((max - min).length() * 0.5).max(1e-9);
    let outside_fov: f64 = 40.0;
    // Directions *towards which* the camera looks. Straight up or down is tilted a little
    // (the camera's up is +y).
    let mut dirs = vec![
        DVec3::NEG_Z,
        DVec3::Z,
        DVec3::NEG_X,
        DVec3::X,
        DVec3::new(0.0, -1.0, -0.02),
        DVec3::new(0.0, 1.0, -0.02),
    ];
    for sx in [-1.0, 1.0] {
        for sz in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                dirs.push(DVec3::new(sx, sy * 0.8, sz));
            }
        }
    }
    let mut out = Vec::new();
    for d in &dirs {
        let Some(d) = d.try_normalize() else { continue };
        let dist = fit_distance(min, max, d, outside_fov);
        out.push((
            Camera {
                eye: center - d * dist,
                target: center,
                vfov_deg: outside_fov,
            },
            false,
        ));
    }
    for sy in [1.0, -1.0] {
        for (sx, sz) in [(-1.0, 1.0), (1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)] {
            let corner = DVec3::new(
                if sx < 0.0 { min.x } else { max.x },
                if sy < 0.0 { min.y } else { max.y },
                if sz < 0.0 { min.z } else { max.z },
            );
            out.push((
                Camera {
                    eye: center + (corner - center) * 0.85,
                    target: center,
                    vfov_deg: 70.0,
                },
                true,
            ));
        }
    }
    for d in [
        DVec3::NEG_Z,
        DVec3::Z,
        DVec3::NEG_X,
        DVec3::X,
        DVec3::new(1.0, 0.0, 1.0),
        DVec3::new(-1.0, 0.0, 1.0),
        DVec3::new(1.0, 0.0, -1.0),
        DVec3::new(-1.0, 0.0, -1.0),
    ] {
        let Some(d) = d.try_normalize() else { continue };
        out.push((
            Camera {
                eye: center,
                target: center + d * radius,
                vfov_deg: 75.0,
            },
            true,
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LoadOptions;

    /// An open box (no wall at +z), light on the ceiling inside.
    fn open_box(open_towards_positive_z: bool) -> Scene {
        let mut obj = String::from("mtllib m.mtl\nusemtl w\n");
        let s = |z: f64| if open_towards_positive_z { z } else { -z };
        let v = [
            (0.0, 0.0, 0.0),
            (1.0, 0.0, 0.0),
            (1.0, 1.0, 0.0),
            (0.0, 1.0, 0.0),
            (0.0, 0.0, 1.0),
            (1.0, 0.0, 1.0),
            (1.0, 1.0, 1.0),
            (0.0, 1.0, 1.0),
        ];
        for (x, y, z) in v {
            obj += &format!("v {x} {y} {}\n", s(z));
        }
        // Inward-facing walls (the back wall at z = 0, floor, ceiling, left, right).
        let faces = ["1 2 3 4", "1 5 6 2", "4 3 7 8", "1 4 8 5", "2 6 7 3"];
        for f in faces {
            let f = if open_towards_positive_z {
                f.to_string()
            } else {
                f.split(' ').rev().collect::<Vec<_>>().join(" ")
            };
            obj += &format!("f {f}\n");
        }
        obj += "usemtl l\nv 0.4 0.99 0.4\nv 0.6 0.99 0.4\nv 0.6 0.99 0.6\nv 0.4 0.99 0.6\n";
        let l = if open_towards_positive_z {
            "9 10 11 12"
        } else {
            "12 11 10 9"
        };
        obj += &format!("f {l}\n");
        if !open_towards_positive_z {
            obj = obj.replace("v 0.4 0.99 0.4", "v 0.4 0.99 -0.4").replace(
                "v 0.6 0.99 0.4\nv 0.6 0.99 0.6\nv 0.4 0.99 0.6",
                "v 0.6 0.99 -0.4\nv 0.6 0.99 -0.6\nv 0.4 0.99 -0.6",
            );
        }
        let mtl = "newmtl w\nKd 0.5 0.5 0.5\nnewmtl l\nKe 5 5 5\n";
        Scene::from_obj_str("box.obj", &obj, &[("m.mtl", mtl)], &LoadOptions::default())
            .expect("scene")
    }

    #[test]
    fn an_open_box_is_seen_through_its_open_side() {
        for open_pz in [true, false] {
            let scene = open_box(open_pz);
            let cam = choose_camera(&scene);
            let look = cam.target - cam.eye;
            // The camera must be on the open side looking in: from +z looking along −z
            // for a box open towards +z, and the reverse.
            let ok = if open_pz {
                look.z < 0.0 && cam.eye.z > 1.0
            } else {
                look.z > 0.0 && cam.eye.z < -1.0
            };
            assert!(
                ok,
                "open towards {}z: camera {cam:?}",
                if open_pz { "+" } else { "-" }
            );
            let tracer = PathTracer::new(&scene);
            let b = scene.bounds();
            let lit = score(&tracer, &cam, (b.min, b.max)).lit;
            assert!(lit > 0.3, "{lit}");
        }
    }

    /// A shop: a box of inward-facing walls open towards +z, under a flat roof that faces
    /// up, lit only by a sky and a sun. From above the sunlit roof fills more of the frame
    /// than the rooms seen through the opening, which a user opened the model for.
    #[test]
    fn a_building_is_seen_through_its_door_not_from_its_roof() {
        // Each surface a 4 × 4 grid of quads (as many faces as the jeweller's shop's roof
        // shows from above), facing `u × v`.
        let mut obj = String::from("mtllib m.mtl\nusemtl w\n");
        let mut vertices = 0;
        let mut grid = |o: DVec3, u: DVec3, v: DVec3| {
            for i in 0..4 {
                for j in 0..4 {
                    let c = o + u * (i as f64 / 4.0) + v * (j as f64 / 4.0);
                    for p in [c, c + u / 4.0, c + (u + v) / 4.0, c + v / 4.0] {
                        obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
                    }
                    let k = vertices + 1;
                    obj += &format!("f {} {} {} {}\n", k, k + 1, k + 2, k + 3);
                    vertices += 4;
                }
            }
        };
        let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
        grid(DVec3::ZERO, x, y); // back wall
        grid(DVec3::ZERO, z, x); // floor
        grid(y, x, z); // ceiling
        grid(DVec3::ZERO, y, z); // left wall
        grid(x, z, y); // right wall
        // The roof, a little above the ceiling and wider than the walls, facing up.
        grid(DVec3::new(-0.1, 1.02, -0.1), z * 1.2, x * 1.2);
        let mtl = "newmtl w\nKd 0.5 0.5 0.5\n";
        let mut scene =
            Scene::from_obj_str("shop.obj", &obj, &[("m.mtl", mtl)], &LoadOptions::default())
                .expect("scene");
        scene.lights.push(crate::scene::Light::Sky {
            radiance: DVec3::splat(0.5),
        });
        scene.lights.push(crate::scene::Light::Sun {
            direction: crate::scene::default_sun_direction(),
            irradiance: DVec3::splat(2.0),
            angular_radius: 0.0,
        });
        let cam = choose_camera(&scene);
        let look = cam.target - cam.eye;
        assert!(look.z < 0.0 && cam.eye.z > 1.0, "{cam:?}");
    }

    #[test]
    fn a_closed_room_is_seen_from_inside() {
        let scene = Scene::builtin("furnace", &LoadOptions::default()).expect("furnace");
        let cam = choose_camera(&Scene {
            camera: None,
            ..scene
        });
        let inside = |p: DVec3| p.cmpge(DVec3::ZERO).all() && p.cmple(DVec3::ONE).all();
        assert!(inside(cam.eye), "{cam:?}");
    }
}
