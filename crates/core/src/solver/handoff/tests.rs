use std::sync::atomic::AtomicBool;

use super::*;
use crate::mesh::MeshSpec;
use crate::scene::{LoadOptions, Rgb, Scene};
use crate::solver::hierarchical::direct::emitters_direct;
use crate::solver::{SolverConfig, channel_sum};

fn cornell(mesh: MeshSpec) -> Problem {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let config = SolverConfig {
        mesh,
        ..Default::default()
    };
    Problem::new(scene, config).expect("problem")
}

/// Steps `solver` until its residual is at most `residual`; every step must make progress.
fn step_until<S: Solver + ?Sized>(solver: &mut S, residual: f64) {
    let cancel = AtomicBool::new(false);
    while solver.residual() > residual {
        assert!(
            solver.step(&cancel),
            "stopped at residual {}",
            solver.residual()
        );
    }
}

/// `Σ |a − b| A / Σ |b| A` over the elements of `problem` (channel sums).
fn distance(a: &[Rgb], b: &[Rgb], problem: &Problem) -> f64 {
    let (mut diff, mut sum) = (0.0, 0.0);
    for ((e, a), b) in problem.mesh.elements.iter().zip(a).zip(b) {
        diff += channel_sum((*a - *b).abs()) * e.area;
        sum += channel_sum(*b) * e.area;
    }
    diff / sum
}

/// Handed over, the hierarchy starts where the shots left off (the same radiosity, the
/// unshot fraction as its residual) and converges to the element-to-element solution
/// (shooting to a residual of 1e-6 on the same mesh, patches of one element) within the
/// hierarchy's own error at the default link tolerance: 3 %, the bound
/// `hierarchical::tests::converges_to_the_full_solution_as_the_tolerance_falls` holds from
/// the emission.
#[test]
fn the_hierarchy_goes_on_from_the_shots() {
    let mesh = MeshSpec::sized(50.0, 50.0);
    let mut full = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    step_until(full.as_mut(), 1e-6);
    let mut shots = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    step_until(shots.as_mut(), 0.3);
    let (radiosity, unshot) = (shots.radiosity().to_vec(), shots.residual());
    let mut s = hand_over(shots);
    assert_eq!(s.name(), "hierarchical");
    assert_eq!(s.steps(), 0);
    assert_eq!(s.radiosity(), &radiosity[..]);
    assert!(
        (s.residual() - unshot).abs() <= 1e-9 * unshot,
        "residual {} after handing over at {unshot}",
        s.residual()
    );
    step_until(s.as_mut(), 1e-6);
    let d = distance(s.radiosity(), full.radiosity(), full.problem());
    assert!(d < 0.03, "{d} from the full solution");
}

/// Only a scene `auto` solves hierarchically is handed over, and only once the unshot
/// fraction is down to [`HANDOFF_UNSHOT`]; a solver that is not shooting is left alone.
#[test]
fn only_large_scenes_are_handed_over_and_only_once_lit() {
    let small = cornell(MeshSpec {
        max_elements: Some(2_000),
        ..Default::default()
    });
    assert!(!ready(&small, 0.5 * HANDOFF_UNSHOT));
    let large = cornell(MeshSpec {
        max_elements: Some(2 * auto::HIERARCHICAL_FROM_ELEMENTS),
        ..Default::default()
    });
    assert!(ready(&large, HANDOFF_UNSHOT));
    assert!(!ready(&large, 2.0 * HANDOFF_UNSHOT));
    let gathering = SolverKind::Hierarchical.build(small).expect("hierarchical");
    assert!(!due(gathering.as_ref()));
    assert_eq!(hand_over(gathering).name(), "hierarchical");
}

/// The emitters' direct light taken from the rows is all the light they emit where
/// nothing escapes: in the closed unit cube lit by its ceiling (`E = 1`), the power that
/// reaches the other five faces, `Σ_j D_j A_j`, is the ceiling's `E · A = 1` (the
/// ceiling's form factors to the rest of the cube sum to 1). Its error is the rows':
/// centroid rules over elements of 1/10 the side, within 1 %, and a row never delivers
/// more than 1 % above its shot (`rows::MAX_ROW_GAIN`).
#[test]
fn the_direct_light_from_the_rows_is_the_emitted_power() {
    let scene = Scene::builtin("cube", &LoadOptions::default()).expect("cube");
    let config = SolverConfig {
        mesh: MeshSpec::sized(0.1, 0.1),
        ..Default::default()
    };
    let problem = Problem::new(scene, config).expect("problem");
    let never = AtomicBool::new(false);
    let direct = emitters_direct(&problem, &mut crate::solver::RowCache::default(), &never)
        .expect("not cancelled");
    let mesh = &problem.mesh;
    let (mut received, mut emitted) = (Rgb::ZERO, Rgb::ZERO);
    for (e, d) in mesh.elements.iter().zip(&direct) {
        received += *d * e.area;
        emitted += problem.material_of(e.patch).emission * e.area;
        if problem.material_of(e.patch).emission != Rgb::ZERO {
            assert_eq!(*d, Rgb::ZERO, "the ceiling does not light itself");
        }
    }
    assert!(
        (emitted.x - 1.0).abs() < 1e-9,
        "the ceiling emits {emitted}"
    );
    let ratio = received / emitted;
    assert!(
        (ratio - Rgb::ONE).abs().max_element() < 0.01,
        "{ratio} of the emitted power reached the walls"
    );
}

/// The direct light is taken from the shots only until the sources change: after the
/// light's emission is doubled, the hierarchy sends the emission over its links again and
/// converges to the edited scene's element-to-element solution (shooting to 1e-6), within
/// the hierarchy's own 3 % (as above). A direct light kept stale would leave it at the old
/// brightness; one kept beside the linked emission would count the direct light twice.
#[test]
fn after_an_edit_the_emission_goes_over_the_links_again() {
    let mesh = MeshSpec::sized(50.0, 50.0);
    let cancel = AtomicBool::new(false);
    let light = |p: &Problem| {
        (p.scene.materials.iter())
            .position(|m| m.emission != Rgb::ZERO)
            .expect("a light")
    };
    let mut shots = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    step_until(shots.as_mut(), 0.3);
    let mut s = hand_over(shots);
    assert!(s.step(&cancel));
    let id = light(s.problem());
    let m = s.problem().scene.materials[id].clone();
    let edit = |s: &mut dyn Solver| {
        s.set_material(
            crate::scene::MaterialId(id as u32),
            m.reflectance,
            m.emission * 2.0,
        )
        .expect("edit")
    };
    edit(s.as_mut());
    step_until(s.as_mut(), 1e-6);
    let mut full = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    edit(full.as_mut());
    step_until(full.as_mut(), 1e-6);
    let d = distance(s.radiosity(), full.radiosity(), full.problem());
    assert!(d < 0.03, "{d} from the full solution");
}

/// From dark, the lights shot by rows and the rest linked converges to the
/// element-to-element solution (shooting to 1e-6) within the hierarchy's 3 % (as above);
/// its first step already holds the direct light, so its first image is not the emission
/// alone.
#[test]
fn the_lights_shot_by_rows_then_linked_converge_to_the_full_solution() {
    let mesh = MeshSpec::sized(50.0, 50.0);
    let cancel = AtomicBool::new(false);
    let mut full = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    step_until(full.as_mut(), 1e-6);
    let mut s = HierarchicalSolver::lights_by_rows(cornell(mesh));
    assert!(s.step(&cancel));
    let lit = |s: &HierarchicalSolver| {
        let mesh = &s.problem().mesh;
        (mesh.elements.iter().zip(s.radiosity()))
            .filter(|(e, b)| s.problem().material_of(e.patch).emission == Rgb::ZERO && b.x > 0.0)
            .count()
    };
    assert!(
        lit(&s) > s.problem().mesh.elements.len() / 2,
        "the first step lit {} elements",
        lit(&s)
    );
    step_until(&mut s, 1e-6);
    let d = distance(s.radiosity(), full.radiosity(), full.problem());
    assert!(d < 0.03, "{d} from the full solution");
}

/// Handed over, the links carry only the light not yet shot
/// (`hierarchical::remainder`): the answer is the shots' radiosity plus `ρ K x`, where
/// `x = U + ρ K x` is the unshot light `U` and its reflections. Handed over with almost
/// nothing unshot (`10⁻⁴` of the power), the converged answer is the shots' within that
/// light and its bounces: `Σ|x|A ≤ Σ|U|A / (1 − 1.25 ρ̄)`-ish, so well within 10⁻³ in this
/// box (ρ̄ about 0.5, the conservation gain at most 1.25). Re-solving all the reflected
/// light over the links (the handover before) converged to the hierarchy's own answer,
/// about 0.7 % from the shots' on this mesh; counting the shot light twice (a node sending
/// its whole radiosity) would double the reflected light.
#[test]
fn handed_over_with_nothing_unshot_the_answer_is_the_shots() {
    let mesh = MeshSpec::sized(50.0, 50.0);
    let mut shots = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    step_until(shots.as_mut(), 1e-4);
    let radiosity = shots.radiosity().to_vec();
    let mut s = hand_over(shots);
    step_until(s.as_mut(), 1e-7);
    let d = distance(s.radiosity(), &radiosity, s.problem());
    assert!(d < 1e-3, "{d} from the shots' radiosity");
}
