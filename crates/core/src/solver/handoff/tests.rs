use std::sync::atomic::AtomicBool;

use super::*;
use crate::mesh::MeshSpec;
use crate::scene::{LoadOptions, Scene};
use crate::solver::{SolverConfig, channel_sum};

fn cornell(mesh: MeshSpec) -> Problem {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let config = SolverConfig {
        mesh,
        ..Default::default()
    };
    Problem::new(scene, config).expect("problem")
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
    let cancel = AtomicBool::new(false);
    let mut full = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    while full.residual() > 1e-6 {
        assert!(full.step(&cancel));
    }
    let mut shots = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    while shots.residual() > 0.3 {
        assert!(shots.step(&cancel));
    }
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
    while s.residual() > 1e-6 {
        assert!(s.step(&cancel), "stopped at residual {}", s.residual());
    }
    let mesh = &full.problem().mesh;
    let (mut diff, mut sum) = (0.0, 0.0);
    for ((e, a), b) in (mesh.elements.iter())
        .zip(s.radiosity())
        .zip(full.radiosity())
    {
        diff += channel_sum((*a - *b).abs()) * e.area;
        sum += channel_sum(*b) * e.area;
    }
    assert!(diff / sum < 0.03, "{} from the full solution", diff / sum);
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

/// The first refinement after the handover links by the emission, as from dark (linking
/// by the shot light would make the second refinement's links at once and delay the first
/// image): one step from the shots makes exactly the links one step from dark makes.
#[test]
fn the_first_refinement_links_by_the_emission() {
    let mesh = MeshSpec::sized(100.0, 100.0);
    let cancel = AtomicBool::new(false);
    let mut dark = HierarchicalSolver::new(cornell(mesh));
    assert!(dark.step(&cancel));
    let mut shots = SolverKind::Shooting.build(cornell(mesh)).expect("shooting");
    while shots.residual() > 0.3 {
        assert!(shots.step(&cancel));
    }
    let unshot = shots.shooting().expect("shooting").unshot().to_vec();
    let radiosity = shots.radiosity().to_vec();
    let mut seeded = HierarchicalSolver::new(shots.into_parts().0);
    seeded.continue_from(&radiosity, &unshot);
    assert!(seeded.step(&cancel));
    assert!(dark.link_count() > 0);
    assert_eq!(seeded.link_count(), dark.link_count());
}
