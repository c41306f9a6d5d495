//! Hard cases (scenes in tests/data/hard/, written by scripts/make_models.py).
//!
//! Each case asserts: no NaN or negative radiance, the power balance (closed scenes:
//! emitted = absorbed + still-unshot power; open ones: emitted = absorbed + unshot +
//! escaped, with the escaped part known), and an error against an answer that does not come
//! from the code under test: the furnace identity, closed-form form factors, a bound from
//! the geometry, or the same scene written another way. Tolerances are derived next to
//! each assertion.
//!
//! Solves use explicit, coarse element and patch sizes (the point is robustness, not the
//! default density) and a wall-clock budget: a solve that has not reached `--unshot 1e-3`
//! by then fails with what it reached, instead of hanging CI.

mod common;

use common::{assert_sane, unshot_power};

use std::path::PathBuf;

use glam::DVec3;
use nusselt_core::mesh::{Mesh, MeshSpec};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig};

fn hard(name: &str) -> PathBuf {
    common::repo_root().join("tests/data/hard").join(name)
}

fn load(name: &str) -> Scene {
    Scene::load_obj(&hard(name), &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{name}: load failed: {e}"))
}

fn solver(scene: Scene, element: f64, patch: f64) -> ProgressiveSolver {
    let name = scene.name.clone();
    ProgressiveSolver::new(
        scene,
        SolverConfig {
            mesh: MeshSpec::sized(element, patch),
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{name}: solver: {e}"))
}

/// Shoots to `unshot`; fails with what was reached otherwise.
fn converge(s: &mut ProgressiveSolver, unshot: f64) {
    common::converge_to(s, unshot);
}

/// Closed scene: every shot lands, so `absorbed + unshot = emitted` at every step, up to
/// the error of the form-factor row sums (Σ_j F_ij = 1 in an enclosure). The contour
/// method evaluates F at element centroids (midpoint rule, O(h²)); on the built-in furnace
/// at h = 0.25 the whole solution is within 1e-3 (tests/solver.rs), so 1 % is a 10× margin,
/// while a face counted twice or light lost through a contact is tens of percent.
fn assert_closed_balance(s: &ProgressiveSolver) {
    let (emitted, absorbed) = s.power_balance();
    let unshot = unshot_power(s);
    let scene_emitted = s.scene().emitted_power();
    for c in 0..3 {
        let e = emitted[c];
        assert!(
            (e - scene_emitted[c]).abs() <= 1e-9 * scene_emitted[c],
            "{}: the mesh emits {e}, the scene's faces {}",
            s.scene().name,
            scene_emitted[c]
        );
        assert!(
            (e - absorbed[c] - unshot[c]).abs() <= 1e-2 * e,
            "{}: channel {c}: emitted {e}, absorbed {}, unshot {} (imbalance {:.3e} of emitted)",
            s.scene().name,
            absorbed[c],
            unshot[c],
            (e - absorbed[c] - unshot[c]) / e
        );
    }
}

fn material_name(s: &ProgressiveSolver, element: usize) -> &str {
    let p = s.mesh().patch(s.mesh().elements[element].patch);
    &s.scene().materials[p.material.0 as usize].name
}

/// Area-weighted mean of `values` over the elements `pick` selects, and their total area.
fn mean_over(
    s: &ProgressiveSolver,
    values: &[DVec3],
    pick: impl Fn(usize) -> bool,
) -> (DVec3, f64) {
    let mut sum = DVec3::ZERO;
    let mut area = 0.0;
    for (j, e) in s.mesh().elements.iter().enumerate() {
        if pick(j) {
            sum += values[j] * e.area;
            area += e.area;
        }
    }
    (sum / area.max(f64::MIN_POSITIVE), area)
}

// ---------------------------------------------------------------------------------------
// Contact and gaps

/// Box footprints of the contact scenes (x0, z0, x1, z1), as in scripts/make_models.py.
const FOOTPRINTS: [[f64; 4]; 2] = [[0.15, 0.15, 0.45, 0.45], [0.55, 0.5, 0.85, 0.8]];

/// Distance from (x, z) inside a footprint to its border; `None` outside every footprint.
fn depth_inside(x: f64, z: f64) -> Option<f64> {
    FOOTPRINTS.iter().find_map(|f| {
        let d = (x - f[0]).min(f[2] - x).min(z - f[1]).min(f[3] - z);
        // An element corner on a footprint line is outside at every scale (not inside by
        // the last bit of a coordinate divided by the scale).
        (d > 1e-9).then_some(d)
    })
}

const CONTACT_H: f64 = 0.05;
const CONTACT_PATCH: f64 = 0.1;

fn contact_solve(file: &str, scale: f64) -> ProgressiveSolver {
    contact_solve_with(file, scale, CONTACT_PATCH)
}

fn contact_solve_with(file: &str, scale: f64, patch: f64) -> ProgressiveSolver {
    let mut s = solver(load(file), CONTACT_H * scale, patch * scale);
    converge(&mut s, 1e-3);
    assert_sane(&s);
    assert_closed_balance(&s);
    s
}

/// Light under a box lifted by `gap`, at a floor point at depth `d` inside its footprint
/// (d > gap). Directly, the point sees the room only through the slit between floor and
/// box, at elevations below atan(gap/d) < 45°; the cosine-weighted solid angle of that band
/// is (1/π)∫dφ sin²θ/2 ≤ (gap/d)², and what it shows there is a wall, a box side or the
/// far floor (the ceiling light is above 45° from every point under a box), so at most
/// L_max, the largest radiance of a non-emitting surface. Indirectly, light comes from the
/// box's bottom (ρ = 0.5), lit the same way; its bright rim (depth < gap) is seen from depth
/// d through the parallel-plate kernel gap²/(π r⁴) ≤ gap²/(π d⁴), negligible, and the rest
/// of it obeys the same (gap/d')² bound, so the floor–bottom inter-reflections add at most a
/// factor 1/(1 − ρ) = 2: H(point) ≤ 2 (gap/d)² · L_max. At contact (gap 0) that is 0.
///
/// `scale` is the factor the scene's coordinates were multiplied by (the footprints and
/// `gap` are given at scale 1).
fn dark_under_boxes(s: &ProgressiveSolver, gap: f64, scale: f64) -> Result<(), String> {
    let name = &s.scene().name;
    let radiance = s.radiosity().to_vec();
    let l_max = s
        .mesh()
        .elements
        .iter()
        .enumerate()
        .filter(|(j, _)| material_name(s, *j) != "light")
        .map(|(j, _)| radiance[j].max_element())
        .fold(0.0, f64::max);
    let (floor_mean, _) = mean_over(s, s.incident(), |j| material_name(s, j) == "floor");
    let floor_mean = floor_mean.max_element();
    let mut checked = 0;
    let mut bad = 0;
    let mut worst: Option<(f64, String)> = None;
    let (mut power, mut area) = (0.0, 0.0);
    for (j, e) in s.mesh().elements.iter().enumerate() {
        let m = material_name(s, j);
        let floor = m == "floor";
        // The boxes' bottom faces (normal −y) see only the floor under them and the slit.
        let bottom = m == "block" && e.normal.y < -0.99;
        if !floor && !bottom {
            continue;
        }
        // Elements wholly inside a footprint (every corner inside, centroid at depth d).
        let inside = e
            .corners()
            .iter()
            .all(|c| depth_inside(c.x / scale, c.z / scale).is_some());
        let Some(d) = depth_inside(e.centroid.x / scale, e.centroid.z / scale) else {
            continue;
        };
        if !inside {
            continue;
        }
        checked += 1;
        let h = s.incident()[j].max_element();
        power += h * e.area;
        area += e.area;
        // The slit bound, plus 1e-6 of the floor's mean for round-off in a correct solve.
        let bound = 2.0 * (gap / d).powi(2) * l_max + 1e-6 * floor_mean;
        if h > bound {
            bad += 1;
            let excess = h / bound;
            if worst.as_ref().is_none_or(|w| excess > w.0) {
                worst = Some((
                    excess,
                    format!(
                        "{} element at ({:.3}, {:.3}), depth {d:.3}: incident {h:.4e} = {:.1} % \
                         of the floor's mean {floor_mean:.4e}, bound {bound:.3e}",
                        if floor { "floor" } else { "box bottom" },
                        e.centroid.x / scale,
                        e.centroid.z / scale,
                        100.0 * h / floor_mean,
                    ),
                ));
            }
        }
    }
    let mean_pct = 100.0 * power / area.max(f64::MIN_POSITIVE) / floor_mean;
    eprintln!(
        "{name}: {checked} hidden elements, mean incident {mean_pct:.2} % of the floor's mean, \
         {bad} over the slit bound"
    );
    if checked < 16 {
        return Err(format!(
            "{name}: only {checked} elements lie under the boxes"
        ));
    }
    match worst {
        None => Ok(()),
        Some((_, w)) => Err(format!(
            "{name} (gap {gap}): {bad} of {checked} hidden elements get more light than the \
             slit lets in (mean {mean_pct:.2} % of the floor's); worst: {w}"
        )),
    }
}

#[test]
fn boxes_resting_on_the_floor_leave_it_dark_underneath() {
    let s = contact_solve("contact_0.obj", 1.0);
    if let Err(e) = dark_under_boxes(&s, 0.0, 1.0) {
        panic!("{e}");
    }
}

#[test]
// Was 19.7 % of the floor's mean under the boxes for all three gaps: floor patches
// straddling the footprints shot their area-mean radiance into the box bottoms
// (crates/core/src/mesh/footprint.rs now cuts the floor along the footprints).
fn gaps_under_boxes_let_in_only_what_the_slit_allows() {
    let mut failures = Vec::new();
    for (file, gap) in [
        ("contact_1e-2.obj", 1e-2),
        ("contact_1e-4.obj", 1e-4),
        ("contact_1e-6.obj", 1e-6),
    ] {
        let s = contact_solve(file, 1.0);
        if let Err(e) = dark_under_boxes(&s, gap, 1.0) {
            failures.push(e);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The same slit bound with shooting patches one element in size (0.05): every patch edge
/// then lies on the footprints' lines (0.15, 0.45, 0.5, 0.55, 0.8, 0.85 are multiples of
/// 0.05), so no patch has part of its area under a box and part outside. This isolates the
/// form factors and their visibility (the rows between the floor and a box's bottom, the
/// slit's shadows) from the patch averaging that the ignored test above trips on: light
/// through a blocker, a shaft that drops the box, or a lifted ray end point slipping under
/// the bottom face would all put light here.
#[test]
fn gaps_under_boxes_are_dark_when_patches_follow_the_footprints() {
    let mut failures = Vec::new();
    for (file, gap) in [
        ("contact_1e-2.obj", 1e-2),
        ("contact_1e-4.obj", 1e-4),
        ("contact_1e-6.obj", 1e-6),
    ] {
        let s = contact_solve_with(file, 1.0, CONTACT_H);
        if let Err(e) = dark_under_boxes(&s, gap, 1.0) {
            failures.push(e);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A box 1e-6 above the floor is, to the light, a box on it: the slit passes (1e-6/d)² ≈
/// 1e-10 of the view. So the visible surfaces (floor outside the footprints, walls, the
/// boxes' sides) must match between the two solves: a contact that leaks light out along the
/// contact line (or a gap treated differently from a contact) shows up as a difference.
/// Same element layout in both files (the boxes only move by 1e-6), so the per-region means
/// can differ only by the 1e-6 move (≪ 1e-3) plus the solves' own unshot remainder: each is
/// within 1e-3 of its converged value in power, and region means of power are within
/// ρ/(1 − ρ) · 1e-3 · (total area / region area) of it; 1 % covers regions ≥ 1/5 of the total.
#[test]
fn contact_and_a_gap_of_1e_6_agree_on_every_visible_surface() {
    let a = contact_solve("contact_0.obj", 1.0);
    let b = contact_solve("contact_1e-6.obj", 1.0);
    let ra = a.display_radiance();
    let rb = b.display_radiance();
    let outside_floor = |s: &ProgressiveSolver, j: usize| {
        let c = s.mesh().elements[j].centroid;
        material_name(s, j) == "floor" && depth_inside(c.x, c.z).is_none()
    };
    // The floor in a band 0.1 wide around each footprint: where light leaking out of the
    // contact would land.
    let band = |s: &ProgressiveSolver, j: usize| {
        let c = s.mesh().elements[j].centroid;
        material_name(s, j) == "floor"
            && depth_inside(c.x, c.z).is_none()
            && FOOTPRINTS.iter().any(|f| {
                c.x > f[0] - 0.1 && c.x < f[2] + 0.1 && c.z > f[1] - 0.1 && c.z < f[3] + 0.1
            })
    };
    for (what, pick_a, pick_b) in [
        (
            "floor outside the boxes",
            &(|j| outside_floor(&a, j)) as &dyn Fn(usize) -> bool,
            &(|j| outside_floor(&b, j)) as &dyn Fn(usize) -> bool,
        ),
        ("floor band around the boxes", &|j| band(&a, j), &|j| {
            band(&b, j)
        }),
        ("walls", &|j| material_name(&a, j) == "wall", &|j| {
            material_name(&b, j) == "wall"
        }),
    ] {
        let (ma, area_a) = mean_over(&a, &ra, pick_a);
        let (mb, area_b) = mean_over(&b, &rb, pick_b);
        eprintln!("{what}: contact {ma}, gap 1e-6 {mb} (areas {area_a:.4}, {area_b:.4})");
        assert!(area_a > 0.0 && area_b > 0.0, "{what}: no elements");
        let rel = (ma - mb).abs().max_element() / mb.max_element();
        assert!(
            rel <= 1e-2,
            "{what}: contact {ma} vs gap 1e-6 {mb}: {:.2} % apart",
            rel * 100.0
        );
    }
}

/// Radiance does not depend on the unit: the same contact scene at scale 1e-3 and 1e4, with
/// element and patch sizes scaled, must give the same element radiance. Form factors are
/// dimensionless; the only scale-dependent quantities are tolerances, which must be relative.
/// 1e-6 relative allows f32 row storage (6e-8) summed over a few thousand shots.
#[test]
fn contact_scene_radiance_is_the_same_at_scale_1e_3_and_1e4() {
    let one = contact_solve("contact_0.obj", 1.0);
    let reference = one.radiosity().to_vec();
    for (file, scale) in [
        ("contact_0_scale_1e-3.obj", 1e-3),
        ("contact_0_scale_1e4.obj", 1e4),
    ] {
        let s = contact_solve(file, scale);
        let r = s.radiosity().to_vec();
        assert_eq!(
            r.len(),
            reference.len(),
            "{file}: {} elements at scale {scale}, {} at scale 1",
            r.len(),
            reference.len()
        );
        assert_eq!(s.shots(), one.shots(), "{file}: shots differ");
        let scale_max = reference
            .iter()
            .map(|b| b.max_element())
            .fold(0.0, f64::max);
        for (j, (a, b)) in r.iter().zip(&reference).enumerate() {
            let d = (*a - *b).abs().max_element();
            assert!(
                d <= 1e-6 * b.max_element().max(1e-3 * scale_max),
                "{file}: element {j}: {a} at scale {scale} vs {b} at scale 1"
            );
        }
        if let Err(e) = dark_under_boxes(&s, 0.0, scale) {
            panic!("{file}: {e}");
        }
    }
}

// ---------------------------------------------------------------------------------------
// Coincident and overlapping coplanar faces

/// The same room written three ways: floor cut into a ring and a rug (reference), the
/// same with the rug and a floor quad written twice (coincident), and the whole floor plus
/// the rug on top of it (overlapping). All three describe the same surfaces, so: the
/// floor's meshed area is 1 m² (a duplicate or overlap counted twice adds 0.16–0.46 m²),
/// power balances, and each surface's mean radiance matches the reference. Those means
/// are over whole faces (floor, walls, ceiling), whose borders every mesh follows, so two
/// meshes of size h differ only by the midpoint rule, O(h²) ≈ 0.25 % at h = 0.05 for a
/// field varying on the room's scale; 1 % is the tolerance.
#[test]
fn coincident_and_overlapping_coplanar_faces_count_once() {
    let solve = |file: &str| {
        let mut s = solver(load(file), 0.05, 0.1);
        converge(&mut s, 1e-3);
        assert_sane(&s);
        s
    };
    let reference = solve("coplanar_ref.obj");
    assert_closed_balance(&reference);
    let rr = reference.display_radiance();
    for file in ["coplanar_dup.obj", "coplanar_overlap.obj"] {
        let s = solve(file);
        let (_, floor_area) = mean_over(&s, s.incident(), |j| material_name(&s, j) == "floor");
        assert!(
            (floor_area - 1.0).abs() <= 1e-9,
            "{file}: the floor is meshed into {floor_area} m² of elements, the room's floor is 1 m²"
        );
        assert_closed_balance(&s);
        let r = s.display_radiance();
        for m in ["floor", "wall", "ceiling"] {
            let (a, _) = mean_over(&s, &r, |j| material_name(&s, j) == m);
            let (b, _) = mean_over(&reference, &rr, |j| material_name(&reference, j) == m);
            let rel = (a - b).abs().max_element() / b.max_element();
            assert!(
                rel <= 1e-2,
                "{file}: mean {m} radiance {a} vs {b} in the reference ({:.2} % apart)",
                rel * 100.0
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// Sliver furnaces

/// A closed furnace where every face emits E = 1 with ρ = 0.5 has radiance E/(1 − ρ) = 2
/// everywhere, however its walls are cut. Converged to unshot 1e-4·(1 − ρ) as the built-in
/// furnace test (tests/solver.rs) is, the same 1e-3 per-element tolerance applies: the
/// remaining unshot power adds at most ρ/(1−ρ)·5e-5 = 5e-5 on average, and the row sums of
/// an enclosure are 1 to the midpoint rule's accuracy.
fn sliver_furnace(file: &str) {
    let mut s = solver(load(file), 0.1, 0.25);
    // The criterion first: --unshot 1e-3 within the budget.
    converge(&mut s, 1e-3);
    assert_sane(&s);
    assert_closed_balance(&s);
    converge(&mut s, 1e-4 * 0.5);
    let exact = 2.0;
    let mut worst = (0.0, 0usize);
    for (j, b) in s.radiosity().iter().enumerate() {
        let e = (*b - DVec3::splat(exact)).abs().max_element() / exact;
        if e > worst.0 {
            worst = (e, j);
        }
    }
    let e = &s.mesh().elements[worst.1];
    assert!(
        worst.0 <= 1e-3,
        "{file}: element {} (area {:.2e}, centroid {}) has radiance {} instead of {exact} \
         ({:.3e} relative)",
        worst.1,
        e.area,
        e.centroid,
        s.radiosity()[worst.1],
        worst.0
    );
}

#[test]
fn furnace_with_100_to_1_slivers_keeps_the_furnace_identity() {
    sliver_furnace("furnace_slivers_100.obj");
}

#[test]
fn furnace_with_1000_to_1_slivers_keeps_the_furnace_identity() {
    sliver_furnace("furnace_slivers_1000.obj");
}

// ---------------------------------------------------------------------------------------
// A tiny very bright light and a huge dim one

/// Form factor from a floor point (normal +y) to a downward-facing rectangle
/// [x0, x1] × [z0, z1] at height c above it: the corner formula for a rectangle whose
/// corner is above the point (Howell's catalogue, B-3),
/// F(a, b) = 1/(2π) [X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²))], X = a/c,
/// Y = b/c, which is odd in each of a and b, summed with signs over the four corners.
fn point_to_parallel_rect(px: f64, pz: f64, c: f64, rect: [f64; 4]) -> f64 {
    let corner = |a: f64, b: f64| {
        let (x, y) = (a / c, b / c);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI)
    };
    let [x0, z0, x1, z1] = rect;
    corner(x1 - px, z1 - pz) - corner(x0 - px, z1 - pz) - corner(x1 - px, z0 - pz)
        + corner(x0 - px, z0 - pz)
}

/// The mean of `f` over an element, by 8 × 8 midpoint samples of each of its triangles
/// (a fan from corner 0), independent of how the solver samples it.
fn element_mean(corners: &[DVec3], f: &dyn Fn(DVec3) -> f64) -> f64 {
    let mut sum = 0.0;
    let mut area = 0.0;
    for k in 1..corners.len() - 1 {
        let (a, b, c) = (corners[0], corners[k], corners[k + 1]);
        let ta = 0.5 * (b - a).cross(c - a).length();
        let n = 8;
        let mut s = 0.0;
        // Midpoints of the n² sub-triangles of a regular split.
        for i in 0..n {
            for j in 0..n - i {
                let (u, v) = (
                    (i as f64 + 1.0 / 3.0) / n as f64,
                    (j as f64 + 1.0 / 3.0) / n as f64,
                );
                s += f(a + (b - a) * u + (c - a) * v);
                if i + j + 1 < n {
                    let (u, v) = (
                        (i as f64 + 2.0 / 3.0) / n as f64,
                        (j as f64 + 2.0 / 3.0) / n as f64,
                    );
                    s += f(a + (b - a) * u + (c - a) * v);
                }
            }
        }
        sum += s / (n * n) as f64 * ta;
        area += ta;
    }
    sum / area
}

/// Black room (walls and ceiling Kd 0), floor Kd 0.5: nothing but the light reaches the
/// floor, so a floor element's incident radiance is Ke · F(point → light), in closed form.
/// The solver may evaluate it at the element's centroid (midpoint rule) or average it over
/// the element; the tolerance is the difference between those two (computed here
/// independently) plus 1e-6 relative (f32 storage of form-factor rows, 6e-8).
fn direct_light_case(file: &str, ke: f64, light: [f64; 4]) {
    let mut s = solver(load(file), 0.05, 0.1);
    converge(&mut s, 1e-3);
    assert_sane(&s);
    assert_closed_balance(&s);
    let mut worst = 0.0f64;
    let mut n = 0;
    for (j, e) in s.mesh().elements.iter().enumerate() {
        if material_name(&s, j) != "floor" {
            continue;
        }
        n += 1;
        let f = |p: DVec3| ke * point_to_parallel_rect(p.x, p.z, 1.0, light);
        let at_centroid = f(e.centroid);
        let mean = element_mean(e.corners(), &f);
        let h = s.incident()[j];
        let tol = (at_centroid - mean).abs() + 1e-6 * mean;
        let err = (h.x - mean).abs();
        worst = worst.max(err / mean);
        assert!(
            err <= tol && (h.y - h.x).abs() <= 1e-9 * h.x && (h.z - h.x).abs() <= 1e-9 * h.x,
            "{file}: floor element at {} gets {h}, the closed form gives {mean:.6e} \
             (centroid {at_centroid:.6e}); error {:.3e} relative, tolerance {:.3e}",
            e.centroid,
            err / mean,
            tol / mean
        );
    }
    assert!(n >= 100, "{file}: only {n} floor elements");
    eprintln!("{file}: worst floor element error {worst:.3e} relative");
}

#[test]
fn tiny_bright_light_matches_the_closed_form_direct_light() {
    // The 1 mm light of scripts/make_models.py: the centre cell of a 3 × 3 ceiling grid.
    direct_light_case("light_tiny.obj", 1e6, [0.4995, 0.4995, 0.5005, 0.5005]);
}

#[test]
fn huge_dim_light_matches_the_closed_form_direct_light() {
    direct_light_case("light_huge.obj", 1.0, [0.0, 0.0, 1.0, 1.0]);
}

/// The same total power (E·A = 1) from a 1e-6 m² light or from the whole ceiling, in a
/// closed room of uniform ρ = 0.5: every watt is absorbed (emitted = absorbed), and the
/// total radiosity Σ B·A = E·A / (1 − ρ) = 2 whatever the light's shape (each watt leaves
/// surfaces 1 + ρ + ρ² + … times). With the ambient term this holds at every step up to
/// the row-sum error (1 %, see assert_closed_balance).
#[test]
fn tiny_and_huge_lights_of_equal_power_give_equal_total_radiosity() {
    for file in ["light_tiny_grey.obj", "light_huge_grey.obj"] {
        let mut s = solver(load(file), 0.05, 0.1);
        converge(&mut s, 1e-3);
        assert_sane(&s);
        assert_closed_balance(&s);
        let r = s.display_radiance();
        let total: DVec3 = r
            .iter()
            .zip(&s.mesh().elements)
            .map(|(b, e)| *b * e.area)
            .sum();
        let emitted = s.scene().emitted_power();
        assert!(
            (emitted.x - 1.0).abs() <= 1e-6,
            "{file}: the light's power E·A is {emitted}, the file says 1"
        );
        assert!(
            (total - DVec3::splat(2.0)).abs().max_element() <= 2e-2,
            "{file}: Σ B·A = {total}, expected 2 = E·A / (1 − ρ)"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Open scene

/// Directly opposed parallel squares of side a at distance c (Howell's catalogue, C-11).
fn opposed_squares(a: f64, c: f64) -> f64 {
    let x = a / c;
    let y = a / c;
    let (x2, y2) = (x * x, y * y);
    2.0 / (std::f64::consts::PI * x * y)
        * ((((1.0 + x2) * (1.0 + y2)) / (1.0 + x2 + y2)).sqrt().ln()
            + x * (1.0 + y2).sqrt() * (x / (1.0 + y2).sqrt()).atan()
            + y * (1.0 + x2).sqrt() * (y / (1.0 + x2).sqrt()).atan()
            - x * x.atan()
            - y * y.atan())
}

/// Two parallel unit squares 1 apart, the lower emitting (E = 1, ρ = 0), the upper with
/// reflectance ρ, nothing else. Of the emitted E·A = 1, F12 reaches the upper plate, which
/// absorbs (1 − ρ)·F12 and reflects ρ·F12; of that, the fraction that returns to the black
/// emitter (and is absorbed there) is the reflected-radiance-weighted mean of the point →
/// emitter form factor, between its corner and centre values (closed form). The rest
/// escapes. So emitted = absorbed + escaped with every term bounded independently.
/// The upper plate's incident radiance at an element is F(point → emitter) exactly
/// (unoccluded), tolerance as in direct_light_case; its total by the midpoint rule over
/// h = 0.05 elements is within (h²/24)·|∇²F|/F ≈ 2e-4 of F12; 1e-3 is the tolerance.
#[test]
fn open_plates_account_for_the_escaped_power() {
    let f12 = opposed_squares(1.0, 1.0);
    // Point → unit square form factors at distance 1: under a corner and under the centre.
    let f_corner = point_to_parallel_rect(0.0, 0.0, 1.0, [0.0, 0.0, 1.0, 1.0]);
    let f_centre = point_to_parallel_rect(0.5, 0.5, 1.0, [0.0, 0.0, 1.0, 1.0]);
    assert!((f12 - 0.19982).abs() < 1e-4, "catalogue value F12 = {f12}");
    for (file, rho) in [
        ("open_plates_black.obj", 0.0),
        ("open_plates_grey.obj", 0.5),
    ] {
        let mut s = solver(load(file), 0.05, 0.1);
        converge(&mut s, 1e-3);
        assert_sane(&s);
        let (emitted, absorbed) = s.power_balance();
        let unshot = unshot_power(&s).x;
        assert!((emitted.x - 1.0).abs() < 1e-9, "{file}: emitted {emitted}");
        // Per element of the upper plate: the direct light in closed form.
        let mut plate_h = 0.0;
        let mut emitter_h = 0.0;
        for (j, e) in s.mesh().elements.iter().enumerate() {
            let h = s.incident()[j].x;
            if material_name(&s, j) == "plate" {
                let f = |p: DVec3| point_to_parallel_rect(p.x, p.z, 1.0, [0.0, 0.0, 1.0, 1.0]);
                let mean = element_mean(e.corners(), &f);
                let tol = (f(e.centroid) - mean).abs() + 1e-6 * mean;
                assert!(
                    (h - mean).abs() <= tol,
                    "{file}: plate element at {}: incident {h:.6e}, closed form {mean:.6e}",
                    e.centroid
                );
                plate_h += h * e.area;
            } else {
                emitter_h += h * e.area;
            }
        }
        assert!(
            (plate_h - f12).abs() <= 1e-3 * f12,
            "{file}: the plate receives {plate_h:.6e} of the emitted 1, F12 = {f12:.6e}"
        );
        let plate_absorbed = (1.0 - rho) * plate_h;
        // What returns to the emitter: ρ F12 times the mean point → emitter form factor,
        // which lies between the corner and centre values; at unshot f, up to f less.
        let lo = rho * f12 * f_corner - unshot;
        let hi = rho * f12 * f_centre;
        assert!(
            emitter_h >= lo - 1e-9 && emitter_h <= hi * (1.0 + 1e-3) + 1e-12,
            "{file}: the emitter gets back {emitter_h:.6e}, expected in [{lo:.6e}, {hi:.6e}]"
        );
        assert!(
            (absorbed.x - plate_absorbed - emitter_h).abs() <= 1e-9,
            "{file}: absorbed {} is not plate {plate_absorbed} + emitter {emitter_h}",
            absorbed.x
        );
        // Escaped: everything that left a surface and did not land on one.
        let escaped = emitted.x - absorbed.x - unshot;
        let escaped_lo = (1.0 - f12) + rho * f12 * (1.0 - f_centre) - 1e-3;
        let escaped_hi = (1.0 - f12) + rho * f12 * (1.0 - f_corner) + 1e-3;
        eprintln!(
            "{file}: emitted 1, plate absorbs {plate_absorbed:.5}, emitter {emitter_h:.5}, \
             unshot {unshot:.2e}, escaped {escaped:.5} (bounds {escaped_lo:.5}..{escaped_hi:.5})"
        );
        assert!(
            escaped >= escaped_lo && escaped <= escaped_hi,
            "{file}: escaped {escaped:.6} outside [{escaped_lo:.6}, {escaped_hi:.6}]"
        );
    }
}

/// The mesh alone, at the default sizes: every hard case meshes without panicking and
/// into a number of elements that follows the scene's area, not its triangle count (the
/// issue's 76,800-element cube). Budget from the issue: 20–30 k elements for a scene;
/// 40,000 is the bound here.
#[test]
fn hard_cases_mesh_at_default_size_within_the_budget() {
    let mut files: Vec<_> = std::fs::read_dir(hard(""))
        .expect("tests/data/hard")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    files.sort();
    assert!(files.len() >= 17, "{} hard-case files", files.len());
    let mut report = Vec::new();
    for p in &files {
        let scene = Scene::load_obj(p, &LoadOptions::default())
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        let size = nusselt_core::mesh::default_element_size(&scene);
        let patch = nusselt_core::mesh::default_patch_size(size);
        let faces = scene.faces.len();
        match Mesh::build(&scene, &MeshSpec::sized(size, patch.max(size))) {
            Ok(m) => report.push((p.clone(), faces, m.elements.len(), m.patches.len())),
            Err(e) => {
                eprintln!("{}: {e}", p.display());
                report.push((p.clone(), faces, usize::MAX, 0));
            }
        }
    }
    let mut bad = Vec::new();
    for (p, faces, elements, patches) in &report {
        let name = p.file_name().unwrap_or_default().to_string_lossy();
        eprintln!("{name}: {faces} faces, {patches} patches, {elements} elements");
        if *elements > 40_000 {
            bad.push(format!("{name}: {elements} elements"));
        }
    }
    assert!(
        bad.is_empty(),
        "meshes over 40,000 elements at the default size: {bad:?}"
    );
}

/// Found by fuzzing (`fuzz/`, target `obj_solve`, 2026-12-04): the corpus's head of
/// non-planar quads with one vertex moved from z = 2.09 to z = 2880, so a few of its quads
/// are convex slivers 1,400 times longer than the head. Meshed at the default size, their
/// bilinear grids were long both ways: about 10⁹ elements from a few square units, and
/// `nusselt render` on it was killed by the kernel at 24 GB. Now such a quad is cut by its
/// area; the mesh stays near the default element budget.
#[test]
fn a_vertex_stretched_far_out_meshes_within_the_element_budget() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/fuzz/stretched_vertex.obj");
    let scene = nusselt_core::scene::Scene::load_obj(&path, &Default::default()).expect("loads");
    let mesh = nusselt_core::mesh::Mesh::build(&scene, &MeshSpec::default()).expect("meshes");
    let budget = nusselt_core::mesh::ELEMENT_BUDGET;
    assert!(
        mesh.elements.len() <= 2 * budget,
        "{} elements at the default size (budget {budget})",
        mesh.elements.len()
    );
}

/// Found by fuzzing (`fuzz/`, target `gltf_solve`, 2026-12-05): a GLB whose positions are
/// near 1e32 with a few tiny triangles among large ones. The T-vertex search used cells of
/// the median element's side, so every long edge walked millions of cells (and sorted
/// them): `nusselt render` on it with default flags spent 32 s meshing 16 k elements in
/// release, minutes in a debug build. The cells now grow until the walks are short. What
/// is checked is what the fuzz target checks, at the default mesh: it loads, meshes, and
/// shoots 3 times with finite, non-negative radiance. (Speed is not asserted: 0.5 s here
/// in a debug build, 10 s with the cells left at the median side; a return of the walks
/// shows as this test taking minutes.)
#[test]
fn a_huge_scale_glb_meshes_and_shoots() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/fuzz/huge_scale.glb");
    let scene = nusselt_core::scene::Scene::load(&path, &Default::default()).expect("loads");
    let d = scene.bounds().diagonal();
    assert!(d > 1e30, "the scale that made it slow: {d}");
    let config = nusselt_core::solver::SolverConfig::default();
    let mut s = nusselt_core::solver::ProgressiveSolver::new(scene, config).expect("meshes");
    s.run(
        &nusselt_core::solver::StopCriteria {
            residual: 0.0,
            max_steps: Some(3),
            ..Default::default()
        },
        &std::sync::atomic::AtomicBool::new(false),
        &mut |_| {},
    );
    let radiance = s.display_radiance();
    assert!(
        radiance
            .iter()
            .all(|b| b.is_finite() && b.min_element() >= 0.0)
    );
}
