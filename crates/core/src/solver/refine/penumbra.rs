//! Shadow boundaries for adaptive meshing: elements that see a light in part (Cohen,
//! Greenberg, Immel & Brock 1986 refine "where a shooter is partly visible"), found with
//! shadow rays, so that a shadow edge falling between the element centroids, where the
//! radiance indicator sees nothing, is refined too.
//!
//! Rays go from the element's corners (pulled 1 % towards its centroid, so they lie on the
//! element) to the light patch's vertices (pulled the same way) and centroid; each corner
//! sees a fraction `v` of those points. The direct light then varies across the element by
//! about `(max v − min v) ρ E F` (`F` the unoccluded form factor at the centroid), and the
//! element is refined where that exceeds `tolerance` times its radiance (no less than 1/10
//! of the scene's mean), as the radiance indicator would if it could see between centroids.
//! Lights: the [`MAX_LIGHTS`] emitting patches of most power, each with at least 1 % of the
//! total.
//! Suns and point lights: one shadow ray from each corner (through windows at their
//! transmittance, as the solve sees them); where the direct light they give the corners
//! differs by more than `tolerance` times the element's radiance, a shadow edge crosses it.
//! Known error: a blocker passing between all 20 rays is missed (a sliver of shadow).

use rayon::prelude::*;

use glam::DVec3;

use crate::formfactor::contour::point_to_polygon_with_normal;
use crate::geometry::Ray;
use crate::mesh::PatchId;
use crate::scene::Rgb;

use super::super::{Problem, channel_sum};

/// Most light patches tested.
pub const MAX_LIGHTS: usize = 16;

/// Per base patch of `problem`'s mesh: true where a shadow boundary of a light that matters
/// there crosses one of its elements (see the module docs), for a solution `radiance`.
pub fn penumbra_bases(problem: &Problem, radiance: &[Rgb], tolerance: f64) -> Vec<bool> {
    let mesh = &problem.mesh;
    let bases = mesh.base_count();
    let mut lights: Vec<(f64, usize)> = mesh
        .patches
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let e = problem.material_of(PatchId(i as u32)).emission;
            (channel_sum(e) * p.area, i)
        })
        .filter(|l| l.0 > 0.0)
        .collect();
    let total: f64 = lights.iter().map(|l| l.0).sum();
    lights.sort_by(|a, b| b.0.total_cmp(&a.0));
    lights.retain(|l| l.0 >= 0.01 * total);
    lights.truncate(MAX_LIGHTS);
    let inward = |points: &[DVec3], centre: DVec3| -> Vec<DVec3> {
        points.iter().map(|&p| p + (centre - p) * 0.01).collect()
    };
    let lights: Vec<(usize, Vec<DVec3>)> = lights
        .into_iter()
        .map(|(_, i)| {
            let p = &mesh.patches[i];
            let mut points = inward(&p.polygon, p.centroid);
            points.push(p.centroid);
            (i, points)
        })
        .collect();
    // As the radiance indicator: against no less than 1/10 of the scene's mean.
    let (mut sum, mut area) = (0.0, 0.0);
    for (e, b) in mesh.elements.iter().zip(radiance) {
        sum += channel_sum(*b) * e.area;
        area += e.area;
    }
    let floor = 0.1 * sum / area.max(f64::MIN_POSITIVE);
    let crossed: Vec<bool> = mesh
        .elements
        .par_iter()
        .enumerate()
        .map(|(j, e)| {
            let own = mesh.patches[e.patch.0 as usize].occluder;
            let rho = problem.material_of(e.patch).reflectance;
            let shown = channel_sum(radiance[j]).max(floor);
            let corners = inward(e.corners(), e.centroid);
            lights.iter().any(|(i, points)| {
                let light = &mesh.patches[*i];
                let emission = problem.material_of(PatchId(*i as u32)).emission;
                let f = point_to_polygon_with_normal(
                    e.centroid,
                    e.normal,
                    &light.polygon,
                    light.normal,
                );
                let most = channel_sum(rho * emission) * f;
                if most < tolerance * shown {
                    return false;
                }
                // The visible fraction of the light's points from each corner.
                let (mut low, mut high) = (1.0f64, 0.0f64);
                for &x in &corners {
                    let origin = x + e.normal * problem.epsilon;
                    let (mut seen, mut tried) = (0u32, 0u32);
                    for &y in points {
                        let d = y - origin;
                        if d.dot(e.normal) <= 0.0 || d.dot(light.normal) >= 0.0 {
                            continue;
                        }
                        tried += 1;
                        let ray = Ray::new(origin, d);
                        if !problem.bvh.any_hit_except(
                            &ray,
                            1e-9,
                            1.0 - 1e-9,
                            [own, light.occluder],
                        ) {
                            seen += 1;
                        }
                    }
                    if tried > 0 {
                        let v = f64::from(seen) / f64::from(tried);
                        low = low.min(v);
                        high = high.max(v);
                    }
                }
                (high - low) * most > tolerance * shown
            }) || punctual_edge(problem, e, own, rho, tolerance * shown)
        })
        .collect();
    let mut out = vec![false; bases];
    for (e, c) in mesh.elements.iter().zip(crossed) {
        if c {
            out[mesh.base_patch[e.patch.0 as usize] as usize] = true;
        }
    }
    out
}

/// Whether a sun or point light lights the corners of element `e` differently, by more than
/// `threshold` in reflected radiance (channel sum).
fn punctual_edge(
    problem: &Problem,
    e: &crate::mesh::Element,
    own: u32,
    rho: Rgb,
    threshold: f64,
) -> bool {
    let lights = crate::scene::lights::punctual(&problem.scene.lights);
    if lights.is_empty() {
        return false;
    }
    let glass = problem.glass();
    let corners: Vec<DVec3> = e
        .corners()
        .iter()
        .map(|&p| p + (e.centroid - p) * 0.01)
        .collect();
    lights.iter().any(|light| {
        let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
        for &x in &corners {
            let origin = x + e.normal * problem.epsilon;
            let lit = crate::scene::lights::punctual_incident(
                std::slice::from_ref(light),
                origin,
                e.normal,
                (0.5, 0.5),
                &|d, t| glass.visibility(&problem.bvh, &Ray::new(origin, d), t, [own, own]),
            );
            let shown = channel_sum(rho * lit);
            low = low.min(shown);
            high = high.max(shown);
        }
        high - low > threshold
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSpec;
    use crate::scene::{LoadOptions, Scene};
    use crate::solver::{Problem, SolverConfig, SolverKind, solve_to};

    /// Solves `scene` (floor at z = 0, patches of 1, elements of ½) and checks
    /// [`penumbra_bases`]: every floor patch that spans x = `edge` is marked, every one
    /// wholly left of `left` or right of `right` is not, and there are at least four of each.
    fn check_marks(scene: Scene, edge: f64, left: f64, right: f64) {
        let config = SolverConfig {
            mesh: MeshSpec::sized(0.5, 1.0),
            ..Default::default()
        };
        let mut solver = SolverKind::Shooting
            .build(Problem::new(scene, config).expect("problem"))
            .expect("solver");
        solve_to(solver.as_mut(), 1e-3);
        let radiance = solver.radiosity().to_vec();
        let problem = solver.problem();
        let crossed = penumbra_bases(problem, &radiance, 0.1);
        let mesh = &problem.mesh;
        let (mut on_edge, mut off_edge) = (0, 0);
        for (p, patch) in mesh.patches.iter().enumerate() {
            if patch.normal.z < 0.99 || patch.centroid.z > 1e-9 {
                continue;
            }
            let (lo, hi) = patch
                .polygon
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                    (l.min(v.x), h.max(v.x))
                });
            let b = mesh.base_patch[p] as usize;
            if lo < edge && hi > edge {
                assert!(
                    crossed[b],
                    "floor patch {p} ({lo}..{hi}) holds the shadow edge"
                );
                on_edge += 1;
            } else if lo >= right || hi <= left {
                assert!(
                    !crossed[b],
                    "floor patch {p} ({lo}..{hi}) is all lit or all shaded"
                );
                off_edge += 1;
            }
        }
        assert!(
            on_edge >= 4 && off_edge >= 4,
            "{on_edge} on, {off_edge} off"
        );
    }

    /// A 4 × 4 floor lit by a 0.2-wide light 2 above its middle, half shaded by a plate 1
    /// above it whose edge (x = 1.625) casts the shadow edge at x = 1.25 ± 0.1: through the
    /// middle of the elements 1–1.5, whose centroids all sit on the edge.
    #[test]
    fn a_shadow_edge_between_centroids_marks_the_patches_it_crosses() {
        let obj = "mtllib s.mtl\n\
            v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nusemtl floor\nf 1 2 3 4\n\
            v 1.9 1.9 2\nv 1.9 2.1 2\nv 2.1 2.1 2\nv 2.1 1.9 2\nusemtl light\nf 5 6 7 8\n\
            v -1 -1 1\nv -1 5 1\nv 1.625 5 1\nv 1.625 -1 1\nusemtl plate\nf 9 10 11 12\n";
        let mtl = "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 50 50 50\n\
            newmtl plate\nKd 0 0 0\n";
        let scene = Scene::from_obj_str("s.obj", obj, &[("s.mtl", mtl)], &LoadOptions::default())
            .expect("scene");
        check_marks(scene, 1.25, 1.0, 2.0);
    }

    /// The same floor and plate under a sun (no emitting face) from direction (0.3, 0, 1):
    /// the plate's edge at x = 1.625, 1 above the floor, casts the sun's shadow edge at
    /// x = 1.325, inside the patches 0.8125–1.625 (the mesher cuts the floor under the
    /// plate's edge); the patches it crosses are marked, those wholly lit or shaded are not.
    #[test]
    fn a_suns_shadow_edge_marks_the_patches_it_crosses() {
        let obj = "mtllib s.mtl\n\
            v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nusemtl floor\nf 1 2 3 4\n\
            v -1 -1 1\nv -1 5 1\nv 1.625 5 1\nv 1.625 -1 1\nusemtl plate\nf 5 6 7 8\n";
        let mtl = "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl plate\nKd 0 0 0\n";
        let mut scene =
            Scene::from_obj_str("s.obj", obj, &[("s.mtl", mtl)], &LoadOptions::default())
                .expect("scene");
        scene.lights.push(crate::scene::Light::Sun {
            direction: DVec3::new(0.3, 0.0, 1.0).normalize_or_zero(),
            irradiance: Rgb::splat(3.0),
            angular_radius: 0.0,
        });
        check_marks(scene, 1.325, 1.0, 1.625);
    }
}
