//! The hemicube view's data: the hemicube at a patch (the shooter by default), drawn with
//! the core's CPU hemicube ([`nusselt_core::formfactor::hemicube`]) exactly as the `hemicube`
//! form-factor method draws a row: same orientation, same element ids, same delta table.
//! Kept: the item buffer of the five faces, each element's form factor (the sum of its
//! pixels' delta form factors), what each face sees, and for one receiver patch the
//! hemicube value beside the exact one (`formfactor::exact::point_to_visible_polygon`,
//! with the other patches as occluders).

use glam::DVec3;

use nusselt_core::formfactor::exact::point_to_visible_polygon;
use nusselt_core::formfactor::hemicube::{self, DeltaTable, Hemicube, Local, SKIP};
use nusselt_core::mesh::PatchId;
use nusselt_core::solver::Problem;

/// Most pixels across the top face the view draws.
pub const MAX_RES: u32 = 512;

/// Which hemicube to show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HemicubeRequest {
    /// Pixels across the top face (even, 2..=[`MAX_RES`]).
    pub res: u32,
    /// Where: this patch, or (`None`) the last shooter (before the first shot, the patch
    /// that emits the most power: the first shooter).
    pub patch: Option<u32>,
    /// The patch whose hemicube value is compared with the exact one (`None`: the one the
    /// hemicube sees most of).
    pub receiver: Option<u32>,
}

/// A receiver's form factor two ways.
#[derive(Clone, Copy, Debug)]
pub struct ReceiverValue {
    pub patch: u32,
    /// Σ of the delta form factors of the pixels that see it.
    pub hemicube: f64,
    /// `F(dA_i → A_j)` from the hemicube's centre, the visible part of `A_j` only.
    pub exact: f64,
}

/// One hemicube, ready to draw.
#[derive(Debug)]
pub struct HemicubeDetail {
    pub request: HemicubeRequest,
    /// Where it sits.
    pub patch: u32,
    /// Pixels across the top face (the table's, even).
    pub res: usize,
    /// Element id per pixel ([`hemicube::NONE`]: sees nothing or something that only blocks), face
    /// after face in the layout of [`DeltaTable::deltas`].
    pub item_buffer: Vec<u32>,
    /// `F_ij` per element `j`: what the `hemicube` method's row holds before reciprocity.
    pub element_ff: Vec<f64>,
    /// Σ delta form factors of the pixels of each face that see an element.
    pub face_sums: [f64; 5],
    /// Σ of all delta form factors (1 − O(res⁻²)).
    pub table_sum: f64,
    pub receiver: Option<ReceiverValue>,
}

/// The patch a teaching view looks from: `explicit`, the last shooter, or the brightest
/// emitter (power `Σ|E| A`: the first shooter).
pub fn teaching_patch(
    problem: &Problem,
    explicit: Option<u32>,
    last: Option<PatchId>,
) -> Option<u32> {
    let n = problem.mesh.patches.len() as u32;
    if let Some(p) = explicit.filter(|p| *p < n) {
        return Some(p);
    }
    if let Some(p) = last.filter(|p| p.0 < n) {
        return Some(p.0);
    }
    let power = |k: usize| {
        let p = &problem.mesh.patches[k];
        let e = problem.scene.materials[p.material.0 as usize].emission;
        (e.x + e.y + e.z) * p.area
    };
    (0..problem.mesh.patches.len())
        .filter(|&k| power(k) > 0.0)
        .max_by(|&a, &b| power(a).total_cmp(&power(b)))
        .map(|k| k as u32)
}

/// The hemicube of `request` on `problem` (`last`: the last shooter).
pub fn compute(
    problem: &Problem,
    request: HemicubeRequest,
    last: Option<PatchId>,
) -> Option<HemicubeDetail> {
    let patch = teaching_patch(problem, request.patch, last)?;
    let shooter = PatchId(patch);
    let res = request.res.clamp(2, MAX_RES);
    let table = DeltaTable::new(res);
    let ctx = problem.row_context();
    let mesh = &problem.mesh;
    let p = mesh.patch(shooter);
    let angle = hemicube::shot_angle(&ctx, shooter);
    let mut cube = Hemicube::new(&table, p.centroid, p.normal, angle, problem.epsilon);
    let polys: Vec<(Vec<Local>, u32)> = hemicube::element_ids(&ctx, shooter)
        .into_iter()
        .zip(&mesh.elements)
        .filter(|(id, _)| *id != SKIP)
        .map(|(id, e)| (e.corners().iter().map(|c| cube.local(*c)).collect(), id))
        .collect();
    cube.draw_many(&polys);
    let item_buffer = cube.item_buffer();
    let mut element_ff = vec![0.0; mesh.elements.len()];
    cube.accumulate(&mut element_ff);
    let mut face_sums = [0.0; 5];
    let mut offset = 0;
    for (f, sum) in face_sums.iter_mut().enumerate() {
        let deltas = table.deltas(f);
        let ids = &item_buffer[offset..offset + deltas.len()];
        *sum = ids
            .iter()
            .zip(deltas)
            .filter(|(id, _)| (**id as usize) < mesh.elements.len())
            .map(|(_, d)| d)
            .sum();
        offset += deltas.len();
    }
    let mut per_patch = vec![0.0; mesh.patches.len()];
    for (e, f) in mesh.elements.iter().zip(&element_ff) {
        per_patch[e.patch.0 as usize] += f;
    }
    let receiver = request
        .receiver
        .filter(|r| (*r as usize) < mesh.patches.len() && *r != patch)
        .or_else(|| {
            (0..per_patch.len())
                .filter(|&k| k != patch as usize && per_patch[k] > 0.0)
                .max_by(|&a, &b| per_patch[a].total_cmp(&per_patch[b]))
                .map(|k| k as u32)
        })
        .map(|r| ReceiverValue {
            patch: r,
            hemicube: per_patch[r as usize],
            exact: exact_to_patch(problem, patch, r),
        });
    Some(HemicubeDetail {
        request,
        patch,
        res: table.res(),
        item_buffer,
        element_ff,
        face_sums,
        table_sum: table.sum(),
        receiver,
    })
}

/// `F(dA_i → A_j)` from patch `i`'s centre to the part of patch `j` no other patch hides.
fn exact_to_patch(problem: &Problem, i: u32, j: u32) -> f64 {
    let mesh = &problem.mesh;
    let (pi, pj) = (&mesh.patches[i as usize], &mesh.patches[j as usize]);
    // Lifted off the surface as the hemicube's near plane is, so its own plane does not
    // count as an occluder.
    let origin: DVec3 = pi.centroid + pi.normal * problem.epsilon;
    let occluders: Vec<Vec<DVec3>> = mesh
        .patches
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != i as usize && *k != j as usize)
        .map(|(_, q)| q.polygon.clone())
        .collect();
    point_to_visible_polygon(origin, pi.normal, &pj.polygon, &occluders)
}

/// Unfolded layout of the five faces (a cross `2·res` wide): for face `f` and its pixel
/// (`i` across, `j` up from the horizon on the sides), the image pixel `(x, y)`. The top
/// face is in the middle; each side is folded out from the top's edge it shares, horizon
/// outwards, so neighbouring pixels across a cube edge are neighbours in the image.
pub fn unfolded(f: usize, i: usize, j: usize, res: usize) -> (usize, usize) {
    let half = res / 2;
    match f {
        0 => (half + i, half + j),
        // +u: X = v, Y = w; shares the top's right edge (u = 1).
        1 => (half + res + (half - 1 - j), half + i),
        // −u: X = −v; shares the top's left edge.
        2 => (j, half + (res - 1 - i)),
        // +v: X = −u; shares the top's bottom edge (v = 1, rows grow with v).
        3 => (half + (res - 1 - i), half + res + (half - 1 - j)),
        // −v: X = u; shares the top's top edge.
        _ => (half + i, j),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nusselt_core::mesh::MeshSpec;
    use nusselt_core::scene::{LoadOptions, Scene};
    use nusselt_core::solver::SolverConfig;
    use std::sync::atomic::AtomicBool;

    fn cornell() -> Problem {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::sized(60.0, 120.0),
            ..Default::default()
        };
        Problem::new(scene, config).expect("problem")
    }

    /// The view's numbers are the solver's: per element, the sum of the delta form
    /// factors of its pixels is the `hemicube` method's `F_ij` for that shooter and
    /// resolution; the face sums add up to the row's total; all deltas sum to 1 − O(res⁻²);
    /// and the hemicube value of the most-seen receiver approaches the exact one as the
    /// resolution grows (the view's "aliasing vanishes" point).
    #[test]
    fn face_sums_are_the_hemicube_form_factors() {
        let problem = cornell();
        let ctx = problem.row_context();
        let mut errors = Vec::new();
        for res in [8, 32, 128] {
            let request = HemicubeRequest {
                res,
                patch: None,
                receiver: None,
            };
            let d = compute(&problem, request, None).expect("a light to start from");
            let light = problem.mesh.patch(PatchId(d.patch));
            let emission = problem.scene.materials[light.material.0 as usize].emission;
            assert!(
                emission.max_element() > 0.0,
                "the first hemicube is on the light"
            );
            let table = DeltaTable::new(res);
            let want =
                hemicube::element_values(&ctx, PatchId(d.patch), &table, &AtomicBool::new(false))
                    .expect("row");
            assert_eq!(d.element_ff, want, "res {res}: not the solver's hemicube");
            let total: f64 = d.element_ff.iter().sum();
            let faces: f64 = d.face_sums.iter().sum();
            assert!(
                (total - faces).abs() <= 1e-12,
                "res {res}: {total} vs {faces}"
            );
            assert_eq!(d.item_buffer.len(), d.res * d.res + 4 * d.res * d.res / 2);
            assert!((d.table_sum - 1.0).abs() < 2.0 / (res * res) as f64);
            // The light looks down into the box: most of its hemicube sees surfaces (near
            // the horizon it sees the ceiling's back, which only blocks).
            assert!(total > 0.5 && total <= d.table_sum + 1e-12, "{total}");
            let r = d.receiver.expect("a receiver");
            errors.push((r.hemicube - r.exact).abs() / r.exact);
        }
        eprintln!("hemicube vs exact, relative: {errors:?}");
        assert!(errors[2] < 0.01, "{errors:?}");
        assert!(errors[2] <= errors[0], "{errors:?}");
    }

    /// Every pixel of the unfolded cross is written once and none is outside it.
    #[test]
    fn the_unfolded_faces_do_not_overlap() {
        let res = 8;
        let mut seen = vec![0u8; 4 * res * res];
        for f in 0..5 {
            let rows = if f == 0 { res } else { res / 2 };
            for j in 0..rows {
                for i in 0..res {
                    let (x, y) = unfolded(f, i, j, res);
                    assert!(x < 2 * res && y < 2 * res, "face {f} ({i}, {j})");
                    seen[y * 2 * res + x] += 1;
                }
            }
        }
        assert!(seen.iter().all(|&n| n <= 1));
        assert_eq!(
            seen.iter().filter(|&&n| n == 1).count(),
            res * res + 2 * res * res
        );
    }
}
