//! Adaptive refinement in the viewer's solver thread (`Command::Adapt`, `view --adaptive`),
//! without a window: the mesh grows pass by pass (each published with its own geometry),
//! only where the radiance varies (fewer elements than refining everywhere), the solution
//! is carried onto each refined mesh (not solved again from dark), the solve then
//! converges on the last mesh, and the snapshot says converged only then.

use std::time::{Duration, Instant};

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::SolverConfig;
use nusselt_viewer::solver_thread::{Command, SolverHandle, ThreadConfig};

#[test]
fn the_mesh_grows_where_the_light_varies_then_converges() {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let mut h = SolverHandle::spawn(
        scene,
        ThreadConfig {
            solver: SolverConfig {
                mesh: MeshSpec::element(80.0),
                ..Default::default()
            },
            play: false,
            stop_unshot: 1e-4,
            ..Default::default()
        },
        Box::new(|| {}),
    )
    .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(240);
    let first = loop {
        assert!(Instant::now() < deadline);
        if let Some(s) = h.take_snapshot() {
            break s;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    let start_elements = first.stats.elements;
    h.send(Command::Adapt(Some(0.25))).expect("queue");
    let mut sizes = vec![start_elements];
    let mut steps = first.stats.steps;
    let done = loop {
        assert!(
            Instant::now() < deadline,
            "no converged refined mesh: {sizes:?}"
        );
        if let Some(s) = h.take_snapshot() {
            if sizes.last() != Some(&s.stats.elements) {
                sizes.push(s.stats.elements);
                // Carried onto the refined mesh, not solved again from dark: the shots
                // go on counting.
                assert!(
                    s.stats.steps >= steps,
                    "{} shots after refining, {steps} before",
                    s.stats.steps
                );
            }
            steps = s.stats.steps;
            if s.stats.converged {
                break s;
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    eprintln!("elements per pass: {sizes:?}");
    assert!(sizes.len() >= 2, "never refined: {sizes:?}");
    assert!(sizes.windows(2).all(|w| w[1] > w[0]), "{sizes:?}");
    // Three levels everywhere (the most it refines) would be 4³ = 64 times the elements;
    // refining only where the light varies takes at most half of that.
    let last = *sizes.last().expect("sizes");
    assert!(last < 32 * start_elements, "{sizes:?}");
    assert_eq!(done.stats.elements, last);
    assert!(done.stats.residual <= 1e-4);
    assert!(
        !done.stats.report.contains("adaptive"),
        "{}",
        done.stats.report
    );
    assert!(h.shutdown(Duration::from_secs(30)));
}
