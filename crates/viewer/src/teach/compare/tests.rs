use super::*;
use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{GatherMethod, GatheringSolver, Solver, SolverConfig};

fn cornell() -> (Problem, Geometry) {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let problem = Problem::new(
        scene,
        SolverConfig {
            mesh: MeshSpec::element(100.0),
            ..SolverConfig::default()
        },
    )
    .expect("problem");
    let geometry = Geometry::from_mesh(1, &problem.mesh);
    (problem, geometry)
}

fn prepared(problem: &Problem, geometry: &Geometry) -> CompareWork {
    let mut w = CompareWork::new(problem, geometry, &Camera::cornell(), 0).expect("work");
    let never = AtomicBool::new(false);
    while !w.prepared() {
        assert!(w.work(problem, &never));
    }
    w
}

/// The reference is the solution the project's Gauss-Seidel solver converges to on the
/// same rows (patch averages, independent code: the stored sparse matrix of
/// `solver::gathering`), and both methods here converge to it.
#[test]
fn both_methods_converge_to_the_gathering_solvers_answer() {
    let (problem, geometry) = cornell();
    let mut w = prepared(&problem, &geometry);
    let n = w.n;
    // The solver's patch radiosity: area-weighted element averages.
    let scene = problem.scene.clone();
    let mut solver = GatheringSolver::new(
        Problem::with_mesh(scene, problem.config.clone(), problem.mesh.clone()).expect("problem"),
        GatherMethod::GaussSeidel,
    )
    .expect("solver");
    let never = AtomicBool::new(false);
    while solver.residual() > 1e-10 && solver.step(&never) {}
    let b = solver.radiosity();
    let expected: Vec<Rgb> = problem
        .mesh
        .patches
        .iter()
        .map(|p| {
            let r = p.elements.start as usize..p.elements.end as usize;
            problem.mesh.elements[r.clone()]
                .iter()
                .zip(&b[r])
                .fold(Rgb::ZERO, |acc, (e, b)| acc + *b * e.area)
                / p.area
        })
        .collect();
    let reference = w.reference.clone().expect("reference");
    assert!(w.error(&expected) < 1e-6, "{}", w.error(&expected));
    assert!(w.error(&reference) == 0.0);

    // Errors start equal (B = E for both), fall, and reach the reference.
    let first = w.curve[0];
    assert_eq!(first.shooting, first.gathering);
    w.apply(CompareCommand::Step);
    for _ in 0..200 * n {
        w.apply(CompareCommand::Step);
        w.work(&problem, &never);
        if w.done() {
            break;
        }
    }
    assert!(w.done(), "{:?}", w.curve.last());
}

/// The point of the lesson, as a property of the algorithms: after a tenth of a sweep's
/// worth of rows, shooting (which sends the lights' power first) is much closer to the
/// answer than gathering (which has only updated the first tenth of the patches), and
/// the ambient term brings it closer still.
#[test]
fn shooting_is_ahead_after_few_steps_and_the_ambient_term_helps() {
    let (problem, geometry) = cornell();
    let mut w = prepared(&problem, &geometry);
    let never = AtomicBool::new(false);
    for _ in 0..w.n / 10 {
        w.apply(CompareCommand::Step);
    }
    w.work(&problem, &never);
    let p = *w.curve.last().expect("point");
    assert_eq!(p.steps, w.n / 10);
    assert!(p.shooting < 0.5 * p.gathering, "{p:?}");
    assert!(p.shooting_ambient < p.shooting, "{p:?}");
    // Unshot power only falls: a patch's unshot is never negative here.
    assert!(w.unshot.iter().all(|u| u.min_element() >= 0.0));
}

/// Reset goes back to B = E and an empty history (the first point only).
#[test]
fn reset_returns_to_the_emission() {
    let (problem, geometry) = cornell();
    let mut w = prepared(&problem, &geometry);
    let never = AtomicBool::new(false);
    w.apply(CompareCommand::Step);
    w.work(&problem, &never);
    assert_eq!(w.steps, 1);
    w.apply(CompareCommand::Reset);
    assert_eq!(w.steps, 0);
    assert_eq!(w.curve.len(), 1);
    assert_eq!(w.shoot_b, w.emission);
    assert_eq!(w.gather_b, w.emission);
}
