//! A [`BakedMesh`] from a solved [`Problem`]: the display triangles with per-vertex radiance
//! and irradiance interpolated from the elements ([`crate::mesh::Mesh::vertex_values`]).
//!
//! Irradiance is not stored by every solver, so it is recovered from the radiance: per
//! element `H = (B − E)/ρ` (what `B = E + ρH` leaves; `ρ` = `Kd` × the texture's mean over the
//! element), written as `π H` in W·m⁻². A channel an element does not reflect (`ρ` below
//! [`MIN_REFLECTANCE`]) has no irradiance in the solution and is written 0. Both fields
//! are interpolated with the same weights, which sum to 1 within a display group of one
//! material, so the identity holds at every vertex too, except where the interpolation's
//! clamp at 0 cuts a negative extrapolation (boundary vertices of a nearly black surface).

use glam::DVec3;

use super::BakedMesh;
use crate::scene::Rgb;
use crate::solver::Problem;

/// Reflectance below which a channel's irradiance is not recovered from its radiance.
pub const MIN_REFLECTANCE: f64 = 1e-6;

/// Per element, the irradiance (W·m⁻²) that `radiance = E + ρ H` implies, `π H`.
fn element_irradiance(problem: &Problem, radiance: &[Rgb]) -> Vec<Rgb> {
    (0..problem.mesh.elements.len())
        .map(|e| {
            let emission = problem.material_of(problem.mesh.elements[e].patch).emission;
            let rho = problem.element_rho(e);
            let b = radiance[e];
            let h = |c: usize| {
                if rho[c] > MIN_REFLECTANCE {
                    (std::f64::consts::PI * (b[c] - emission[c]) / rho[c]).max(0.0)
                } else {
                    0.0
                }
            };
            Rgb::new(h(0), h(1), h(2))
        })
        .collect()
}

/// Per display vertex, the unit mean of the normals of the elements at it, weighted by area;
/// `None` where they disagree (the two sides of a face sharing a vertex, a sharp crease).
fn vertex_normals(problem: &Problem) -> Vec<Option<DVec3>> {
    let mesh = &problem.mesh;
    let mut sum = vec![(DVec3::ZERO, 0.0); mesh.vertices.len()];
    for e in &mesh.elements {
        for &v in e.vertex_ids() {
            sum[v as usize].0 += e.normal * e.area;
            sum[v as usize].1 += e.area;
        }
    }
    sum.into_iter()
        .map(|(n, a)| (a > 0.0 && n.length() >= 0.5 * a).then(|| n.normalize_or_zero()))
        .collect()
}

fn f32x3(v: DVec3) -> [f32; 3] {
    v.as_vec3().to_array()
}

impl BakedMesh {
    /// The mesh of `problem` lit by `element_radiance` (one value per element, in
    /// W·m⁻²·sr⁻¹, the ambient term included if it is to be shown). Three vertices per
    /// display triangle, unwelded (the writers weld).
    pub fn from_solution(problem: &Problem, element_radiance: &[Rgb]) -> BakedMesh {
        let mesh = &problem.mesh;
        let scene = &problem.scene;
        let radiance = mesh.vertex_values(element_radiance);
        let irradiance = mesh.vertex_values(&element_irradiance(problem, element_radiance));
        let normals = vertex_normals(problem);
        let textured = !problem.element_texture().is_empty();
        let mut out = BakedMesh {
            uvs: textured.then(Vec::new),
            ..BakedMesh::default()
        };
        for (t, e) in mesh.triangles.iter().zip(&mesh.triangle_element) {
            let element = &mesh.elements[e.0 as usize];
            let material = mesh.patch(element.patch).material;
            let m = &scene.materials[material.0 as usize];
            let own = element.normal.try_normalize().unwrap_or(DVec3::Z);
            for &v in t {
                let p = mesh.vertices[v as usize];
                out.indices.push(out.positions.len() as u32);
                out.positions.push(f32x3(p));
                out.normals.push(f32x3(normals[v as usize].unwrap_or(own)));
                out.radiance.push(f32x3(radiance[v as usize]));
                out.irradiance.push(f32x3(irradiance[v as usize]));
                if let Some(uvs) = out.uvs.as_mut() {
                    let uv = m
                        .diffuse_map
                        .and_then(|_| scene.faces.get(element.face as usize)?.uv_at(p))
                        .map(|uv| m.diffuse_uv.apply(uv))
                        .filter(|uv| uv.is_finite())
                        .unwrap_or_default();
                    uvs.push(uv.as_vec2().to_array());
                }
            }
            out.triangle_material.push(material.0);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSpec;
    use crate::scene::{LoadOptions, Scene};
    use crate::solver::SolverConfig;

    /// A uniform field: every element shows E + ρ·H for H = 2 (radiance units), so the
    /// baked irradiance is 2π W·m⁻² everywhere and the radiance E + 2ρ, whatever the mesh.
    #[test]
    fn irradiance_is_pi_times_what_the_radiance_implies() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::element(120.0),
            ..Default::default()
        };
        let problem = Problem::new(scene, config).expect("problem");
        let field: Vec<Rgb> = (0..problem.mesh.elements.len())
            .map(|e| {
                let m = problem.material_of(problem.mesh.elements[e].patch);
                m.emission + problem.element_rho(e) * 2.0
            })
            .collect();
        let baked = BakedMesh::from_solution(&problem, &field);
        baked.check().expect("consistent");
        assert_eq!(baked.triangle_count(), problem.mesh.triangles.len());
        assert!(baked.uvs.is_none());
        let two_pi = (2.0 * std::f64::consts::PI) as f32;
        for (k, (h, b)) in baked.irradiance.iter().zip(&baked.radiance).enumerate() {
            let m = &problem.scene.materials[baked.triangle_material[k / 3] as usize];
            for c in 0..3 {
                assert!((h[c] - two_pi).abs() < 1e-4, "vertex {k}: {h:?}");
                let expect = m.emission[c] + m.reflectance[c] * 2.0;
                assert!((f64::from(b[c]) - expect).abs() < 1e-4, "vertex {k}: {b:?}");
            }
        }
        for n in &baked.normals {
            let len = glam::Vec3::from_array(*n).length();
            assert!((len - 1.0).abs() < 1e-5, "{n:?}");
        }
    }
}
