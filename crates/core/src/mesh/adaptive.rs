//! Error-driven refinement (Cohen, Greenberg, Immel & Brock 1986, "An efficient radiosity
//! approach for realistic image synthesis"): after a solve, elements are made smaller where
//! the radiance varies across them, and the scene is solved again on the refined mesh.
//!
//! The indicator of an element is how far the display vertices around it (averages of the
//! neighbouring elements, [`Mesh::vertex_values`]) are from its own constant value: where
//! radiance is smooth at the element's scale they agree; at shadow edges, contact lines and
//! under small lights they do not. It is measured relative to the element's own radiance,
//! but never against less than 1/10 of the scene's mean (a dark corner is not refined for
//! noise-sized differences). A patch of the unrefined mesh whose worst element exceeds the
//! tolerance is refined one level more: cut into four patches, each with elements half the
//! size ([`Mesh::build_refined`]); the patch size matters as much as the element size,
//! since a patch shoots its average unshot radiance from its polygon (`--adaptive TOL`,
//! `render`). A refined base patch where nothing varies any more (under [`COARSEN`] of the
//! tolerance: after a light was dimmed, or where an early solution's noise refined it) is
//! coarsened a level.

use crate::scene::Rgb;

use super::Mesh;

/// A refined base patch whose indicator is below this fraction of the tolerance goes back
/// a level. A smooth variation's indicator halves with the element size, so a patch
/// refined for exceeding the tolerance shows more than half of it one level down, and
/// coarsening only below a quarter cannot undo a refinement the next pass would redo.
/// A step (a shadow edge) does not halve, so it stays refined.
pub const COARSEN: f64 = 0.25;

/// Refinement levels per base patch ([`Mesh::base_patch`]) after a solution `radiance`
/// (per element) on `mesh`, built with `current` levels: one more where the indicator
/// exceeds `tolerance` or a shadow boundary crosses the patch (`boundary`, per base patch,
/// shorter means false; the solver finds them, `solver::refine::penumbra`), at most
/// `max_level`; one less where the indicator is under [`COARSEN`] × `tolerance` and no
/// boundary crosses.
pub fn refine_levels(
    mesh: &Mesh,
    radiance: &[Rgb],
    current: &[u8],
    boundary: &[bool],
    tolerance: f64,
    max_level: u8,
) -> Vec<u8> {
    let vertex = mesh.vertex_values(radiance);
    let value = |c: Rgb| (c.x + c.y + c.z) / 3.0;
    let (mut sum, mut area) = (0.0, 0.0);
    for (e, b) in mesh.elements.iter().zip(radiance) {
        sum += value(*b) * e.area;
        area += e.area;
    }
    let floor = 0.1 * sum / area.max(1e-300);
    let bases = mesh.base_count();
    let level = |b: usize| current.get(b).copied().unwrap_or(0);
    let mut worst_of_base = vec![0.0f64; bases];
    for (p, patch) in mesh.patches.iter().enumerate() {
        let worst = (patch.elements.start..patch.elements.end)
            .map(|j| {
                let e = &mesh.elements[j as usize];
                let own = value(radiance[j as usize]);
                let spread = e
                    .vertex_ids()
                    .iter()
                    .map(|&v| (value(vertex[v as usize]) - own).abs())
                    .fold(0.0, f64::max);
                spread / own.max(floor).max(1e-300)
            })
            .fold(0.0, f64::max);
        let b = mesh.base_patch[p] as usize;
        worst_of_base[b] = worst_of_base[b].max(worst);
    }
    let crossed = |b: usize| boundary.get(b).copied().unwrap_or(false);
    (0..bases)
        .map(|b| {
            if (worst_of_base[b] > tolerance || crossed(b)) && level(b) < max_level {
                level(b) + 1
            } else if worst_of_base[b] < COARSEN * tolerance && level(b) > 0 && !crossed(b) {
                level(b) - 1
            } else {
                level(b)
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSpec;
    use crate::scene::{LoadOptions, Scene};

    fn cornell() -> Scene {
        Scene::builtin("cornell", &LoadOptions::default()).expect("cornell")
    }

    #[test]
    fn refined_patches_tile_their_base_patch_with_smaller_elements() {
        let scene = cornell();
        let base = Mesh::build(&scene, &MeshSpec::sized(60.0, 120.0)).expect("mesh");
        assert_eq!(
            base.base_patch,
            (0..base.patches.len() as u32).collect::<Vec<_>>()
        );
        let same = Mesh::build_refined(&scene, &MeshSpec::sized(60.0, 120.0), &[]).expect("mesh");
        assert_eq!(same.elements.len(), base.elements.len());
        // Refine every third base patch once.
        let levels: Vec<u8> = (0..base.patches.len())
            .map(|p| u8::from(p % 3 == 0))
            .collect();
        let fine =
            Mesh::build_refined(&scene, &MeshSpec::sized(60.0, 120.0), &levels).expect("mesh");
        let mut area = vec![0.0; base.patches.len()];
        let mut count = vec![0usize; base.patches.len()];
        for (p, patch) in fine.patches.iter().enumerate() {
            let b = fine.base_patch[p] as usize;
            area[b] += patch.area;
            count[b] += 1;
            let elements = (patch.elements.end - patch.elements.start) as usize;
            let largest = fine.elements[patch.elements.start as usize..patch.elements.end as usize]
                .iter()
                .map(|e| e.area)
                .fold(0.0, f64::max);
            let limit = if levels[b] == 1 { 30.0 } else { 60.0 };
            assert!(
                elements >= 1 && largest <= limit * limit * 1.0001,
                "patch {p}"
            );
        }
        // The published Cornell walls are not quite planar: pieces of a twisted quad sum to
        // its area only to ~1e-8.
        for (b, patch) in base.patches.iter().enumerate() {
            assert!(
                (area[b] - patch.area).abs() <= 1e-6 * patch.area,
                "base {b}: {} vs {}, {} pieces, level {}",
                area[b],
                patch.area,
                count[b],
                levels[b]
            );
            if levels[b] == 0 {
                assert_eq!(count[b], 1, "unrefined base {b} was cut");
            }
        }
        assert!(fine.patches.len() > base.patches.len());
    }

    #[test]
    fn only_patches_where_the_radiance_steps_are_refined() {
        let scene = cornell();
        let mesh = Mesh::build(&scene, &MeshSpec::sized(60.0, 120.0)).expect("mesh");
        // A step across the plane x = 278 (the box's middle), flat elsewhere.
        let radiance: Vec<Rgb> = mesh
            .elements
            .iter()
            .map(|e| Rgb::splat(if e.centroid.x < 278.0 { 1.0 } else { 0.5 }))
            .collect();
        let levels = refine_levels(&mesh, &radiance, &[], &[], 0.1, 2);
        for (p, patch) in mesh.patches.iter().enumerate() {
            let near = patch
                .bounds
                .iter()
                .any(|v| (v.x - 278.0).abs() <= 2.0 * 120.0);
            if levels[p] > 0 {
                assert!(near, "patch {p} refined away from the step");
            }
        }
        assert!(levels.iter().any(|&l| l > 0), "the step was not refined");
        assert!(
            levels.iter().filter(|&&l| l > 0).count() < mesh.patches.len() / 2,
            "refined far too much"
        );
        // A level already at the limit stays there where the radiance steps, and goes
        // back one where it is flat.
        let capped = refine_levels(&mesh, &radiance, &vec![2; mesh.patches.len()], &[], 0.1, 2);
        for (b, &l) in capped.iter().enumerate() {
            assert_eq!(l, if levels[b] > 0 { 2 } else { 1 }, "base {b}");
        }
    }

    #[test]
    fn where_nothing_varies_any_more_the_mesh_coarsens_a_level_at_a_time() {
        let scene = cornell();
        let base = Mesh::build(&scene, &MeshSpec::sized(60.0, 120.0)).expect("mesh");
        let levels = vec![2; base.patches.len()];
        let fine =
            Mesh::build_refined(&scene, &MeshSpec::sized(60.0, 120.0), &levels).expect("mesh");
        // Flat: every patch goes back a level (one per pass).
        let flat = vec![Rgb::ONE; fine.elements.len()];
        assert!(
            refine_levels(&fine, &flat, &levels, &[], 0.1, 3)
                .iter()
                .all(|&l| l == 1)
        );
        // Growing by 5 % per half element (7.5) along x: the floor varies by about half the
        // tolerance across its elements and stays; the side walls, at one x each, go back.
        let k = 0.05 / 7.5;
        let ramp: Vec<Rgb> = fine
            .elements
            .iter()
            .map(|e| Rgb::splat((k * e.centroid.x).exp()))
            .collect();
        let kept = refine_levels(&fine, &ramp, &levels, &[], 0.1, 3);
        let (mut floor, mut sides) = (0, 0);
        for (p, patch) in base.patches.iter().enumerate() {
            if patch.normal.y > 0.99 && patch.centroid.y < 1.0 {
                assert_eq!(kept[p], 2, "floor patch {p}");
                floor += 1;
            } else if patch.normal.x.abs() > 0.99
                && ((patch.centroid.x - 556.0).abs() < 10.0 || patch.centroid.x < 10.0)
            {
                assert_eq!(kept[p], 1, "side wall patch {p}");
                sides += 1;
            }
        }
        assert!(floor > 0 && sides > 0);
        // Unrefined patches have nowhere to go.
        assert!(
            refine_levels(
                &base,
                &vec![Rgb::ONE; base.elements.len()],
                &[],
                &[],
                0.1,
                3
            )
            .iter()
            .all(|&l| l == 0)
        );
    }
}
