//! Choosing the solver over the viewer's solver thread: a switch to Gauss-Seidel keeps the
//! mesh, restarts from dark and converges to what a direct shooting solve gives; a switch
//! the solver would refuse (a matrix over the memory budget, ω out of range) leaves the
//! current solver running and reports an error event.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, SolverKind, StopCriteria};
use nusselt_viewer::snapshot::{Geometry, Snapshot};
use nusselt_viewer::solver_thread::{Command, Event, SolverHandle, ThreadConfig};

fn cornell() -> Scene {
    Scene::builtin("cornell", &LoadOptions::default()).expect("cornell")
}

fn coarse_config() -> SolverConfig {
    SolverConfig {
        mesh: MeshSpec::sized(60.0, 120.0),
        ..Default::default()
    }
}

/// What the coarse Cornell mesh holds of a memory budget (textures and elements).
fn coarse_resident_bytes() -> usize {
    nusselt_core::solver::Problem::new(cornell(), coarse_config())
        .expect("problem")
        .resident_bytes()
}

fn spawn(config: ThreadConfig) -> SolverHandle {
    SolverHandle::spawn(cornell(), config, Box::new(|| {})).expect("spawn")
}

/// Sends, retrying while the channel is full (the test may wait; the UI never does).
fn send(h: &SolverHandle, mut c: Command, deadline: Instant) {
    loop {
        match h.send(c) {
            Ok(()) => return,
            Err(back) => {
                assert!(Instant::now() < deadline, "channel stayed full: deadlock?");
                c = back;
                std::thread::sleep(Duration::from_micros(200));
            }
        }
    }
}

fn first_snapshot(
    h: &SolverHandle,
    deadline: Instant,
    want: impl Fn(&Snapshot) -> bool,
) -> Arc<Snapshot> {
    loop {
        assert!(Instant::now() < deadline, "no matching snapshot in time");
        if let Some(s) = h.take_snapshot()
            && want(&s)
        {
            return s;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Events since the last call, but for the notices of a scene loaded.
fn events(h: &SolverHandle) -> Vec<Event> {
    std::iter::from_fn(|| h.try_event())
        .filter(|e| !matches!(e, Event::Loaded { .. }))
        .collect()
}

/// Area-weighted relative L2 difference of per-vertex radiance over the triangle corners.
fn rel_l2(a: &[[f32; 3]], b: &[[f32; 3]], g: &Geometry) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for t in g.indices.chunks_exact(3) {
        let p = |k: usize| glam::DVec3::from(g.positions[t[k] as usize].map(f64::from));
        let area = (p(1) - p(0)).cross(p(2) - p(0)).length() * 0.5;
        for &v in t {
            let x = glam::DVec3::from(a[v as usize].map(f64::from));
            let y = glam::DVec3::from(b[v as usize].map(f64::from));
            num += (x - y).length_squared() * area;
            den += y.length_squared() * area;
        }
    }
    (num / den).sqrt()
}

/// Shooting for a while, then Gauss-Seidel over the thread: the mesh stays (same geometry),
/// the solve restarts from dark (steps and history from 0; the matrix rows first, then
/// sweeps), the stats name the solver and its residual, and the converged image equals a
/// direct shooting solve's. Each stops at a residual `r` (relative to the emitted power);
/// its error is then at most about `r / (1 − ρ_max)` relative, so the two differ by at most
/// that summed over both; the bound allows 10 times it (measured: 2e-8 against a bound of
/// 6e-6) and still catches a gathering that solves another system (a transposed matrix, a
/// lost emission term: errors at the percent level).
#[test]
fn gauss_seidel_over_the_thread_converges_to_the_shooting_answer() {
    let stop = 1e-7;
    let mut h = spawn(ThreadConfig {
        solver: coarse_config(),
        stop_unshot: stop,
        ..Default::default()
    });
    let deadline = Instant::now() + Duration::from_secs(240);
    let shooting = first_snapshot(&h, deadline, |s| s.stats.steps >= 10);
    assert_eq!(shooting.stats.solver, "shooting");
    assert_eq!(shooting.solver_kind, SolverKind::Shooting);
    assert!(shooting.stats.report.contains("shots"));
    send(&h, Command::SetSolver(SolverKind::GaussSeidel), deadline);
    let done = first_snapshot(&h, deadline, |s| {
        s.stats.solver == "gauss-seidel" && s.stats.converged
    });
    let errors = events(&h);
    assert!(errors.is_empty(), "unexpected events: {errors:?}");
    h.shutdown(Duration::from_secs(30));

    assert_eq!(done.solver_kind, SolverKind::GaussSeidel);
    assert_eq!(
        done.geometry.id, shooting.geometry.id,
        "the switch must keep the mesh"
    );
    let patches = done.geometry.patches;
    assert!(
        done.stats.residual <= stop,
        "stopped at residual {}",
        done.stats.residual
    );
    // Restarted: a row per patch, then sweeps, all counted from 0.
    assert!(
        done.stats.steps > patches && done.stats.steps < patches + 1000,
        "{} steps for {patches} patches",
        done.stats.steps
    );
    assert_eq!(done.history.first().map(|p| p.steps), Some(1));
    assert!(done.history.iter().all(|p| p.ambient == 0.0));
    assert_eq!(done.ambient, [0.0; 3], "Gauss-Seidel has no ambient term");
    assert!(
        done.stats.report.contains("sweeps"),
        "{}",
        done.stats.report
    );
    assert!(done.stats.matrix_bytes > 0);

    let mut direct = ProgressiveSolver::new(cornell(), coarse_config()).expect("solver");
    direct.run(
        &StopCriteria {
            residual: stop,
            ..Default::default()
        },
        &AtomicBool::new(false),
        &mut |_| {},
    );
    assert_eq!(direct.mesh().elements.len(), done.geometry.elements);
    let want = done
        .geometry
        .expand(&direct.mesh().vertex_values(direct.radiosity()));
    let rel = rel_l2(&done.radiance, &want, &done.geometry);
    let rho_max = done
        .materials
        .iter()
        .map(|m| m.reflectance.max_element())
        .fold(0.0, f64::max);
    let tolerance = 10.0 * (done.stats.residual + direct.unshot_fraction()) / (1.0 - rho_max);
    eprintln!(
        "gauss-seidel: {} steps, residual {:.1e}; vs direct shooting {rel:.2e} (tolerance {tolerance:.1e})",
        done.stats.steps, done.stats.residual
    );
    assert!(rel < tolerance, "gauss-seidel vs shooting differ by {rel}");
}

/// A switch the new solver would refuse leaves the current one running: with 64 KB of
/// budget beside the mesh the Cornell matrix does not fit, so Gauss-Seidel is refused with an error event
/// naming the solver and the memory; a bad ω for SOR likewise; shooting goes on (steps
/// count on from where they were) and converges.
#[test]
fn a_refused_switch_keeps_the_solver_and_reports_an_error() {
    let mut h = spawn(ThreadConfig {
        solver: SolverConfig {
            memory_bytes: coarse_resident_bytes() + (64 << 10),
            ..coarse_config()
        },
        play: false,
        stop_unshot: 1e-3,
        ..Default::default()
    });
    let deadline = Instant::now() + Duration::from_secs(240);
    for _ in 0..3 {
        send(&h, Command::Step, deadline);
    }
    let before = first_snapshot(&h, deadline, |s| s.stats.steps == 3);
    send(&h, Command::SetSolver(SolverKind::GaussSeidel), deadline);
    send(&h, Command::SetSolver(SolverKind::Sor(Some(2.5))), deadline);
    send(&h, Command::Step, deadline);
    let after = first_snapshot(&h, deadline, |s| s.stats.steps == 4);
    assert_eq!(after.stats.solver, "shooting");
    assert_eq!(after.solver_kind, SolverKind::Shooting);
    assert_eq!(after.geometry.id, before.geometry.id);
    assert_eq!(after.scene_rev, before.scene_rev);
    let errors: Vec<String> = events(&h)
        .into_iter()
        .map(|e| match e {
            Event::Error(m) => m,
            other => panic!("not an error event: {other:?}"),
        })
        .collect();
    assert_eq!(errors.len(), 2, "{errors:?}");
    assert!(
        errors[0].contains("gauss-seidel") && errors[0].contains("MB"),
        "{}",
        errors[0]
    );
    assert!(
        errors[1].contains("sor") && errors[1].contains("omega"),
        "{}",
        errors[1]
    );
    send(&h, Command::Play, deadline);
    let done = first_snapshot(&h, deadline, |s| s.stats.converged);
    assert_eq!(done.stats.solver, "shooting");
    assert!(done.stats.steps > 4 && done.stats.residual <= 1e-3);
    assert!(h.shutdown(Duration::from_secs(30)));
}

/// Re-meshing and changing the form-factor method keep the chosen solver (rebuilt on the
/// new problem from dark), and a solver chosen at start (`--solver`) is the one that runs.
#[test]
fn the_chosen_solver_survives_a_remesh_and_a_method_change() {
    let mut h = spawn(ThreadConfig {
        solver: coarse_config(),
        kind: SolverKind::Jacobi,
        play: false,
        ..Default::default()
    });
    let deadline = Instant::now() + Duration::from_secs(240);
    let first = first_snapshot(&h, deadline, |_| true);
    assert_eq!(first.stats.solver, "jacobi");
    assert_eq!(first.stats.steps, 0);
    send(&h, Command::Remesh(80.0), deadline);
    send(&h, Command::Step, deadline);
    let remeshed = first_snapshot(&h, deadline, |s| s.stats.steps == 1);
    assert_ne!(remeshed.geometry.id, first.geometry.id);
    assert_eq!(remeshed.stats.solver, "jacobi");
    send(
        &h,
        Command::SetMethod(nusselt_core::formfactor::FormFactorMethod::Exact),
        deadline,
    );
    send(&h, Command::Step, deadline);
    let method = first_snapshot(&h, deadline, |s| {
        s.method == nusselt_core::formfactor::FormFactorMethod::Exact && s.stats.steps == 1
    });
    assert_eq!(method.stats.solver, "jacobi");
    assert_eq!(method.geometry.id, remeshed.geometry.id);
    // A nonsense size is refused without taking the solver apart: the step count goes on.
    send(&h, Command::Remesh(f64::NAN), deadline);
    send(&h, Command::Step, deadline);
    let kept = first_snapshot(&h, deadline, |s| s.stats.steps == 2);
    assert_eq!(kept.geometry.id, method.geometry.id);
    let errors = events(&h);
    assert!(
        matches!(errors.as_slice(), [Event::Error(m)] if m.contains("re-mesh")),
        "{errors:?}"
    );
    assert!(h.shutdown(Duration::from_secs(30)));
}

/// Hierarchical radiosity chosen over the thread: it keeps the mesh, reports its links and
/// their memory, converges, and shows exactly what the same solver run directly computes
/// (its accuracy is tested in `crates/core/src/solver/hierarchical`; here, that the thread runs it
/// unchanged: deterministic links, the same values to f32 round-off).
#[test]
fn hierarchical_over_the_thread_matches_a_direct_run() {
    multilevel_over_the_thread_matches_a_direct_run(SolverKind::Hierarchical);
}

/// The same for wavelet radiosity (flatlet blocks).
#[test]
fn wavelet_over_the_thread_matches_a_direct_run() {
    multilevel_over_the_thread_matches_a_direct_run(SolverKind::Wavelet);
}

fn multilevel_over_the_thread_matches_a_direct_run(kind: SolverKind) {
    let stop = 1e-5;
    let mut h = spawn(ThreadConfig {
        solver: coarse_config(),
        stop_unshot: stop,
        ..Default::default()
    });
    let deadline = Instant::now() + Duration::from_secs(240);
    let shooting = first_snapshot(&h, deadline, |s| s.stats.steps >= 5);
    send(&h, Command::SetSolver(kind), deadline);
    let done = first_snapshot(&h, deadline, |s| {
        s.stats.solver == kind.name() && s.stats.converged
    });
    let errors = events(&h);
    assert!(errors.is_empty(), "unexpected events: {errors:?}");
    h.shutdown(Duration::from_secs(30));

    assert_eq!(done.solver_kind, kind);
    assert_eq!(
        done.geometry.id, shooting.geometry.id,
        "the switch keeps the mesh"
    );
    assert!(
        done.stats.residual <= stop,
        "residual {}",
        done.stats.residual
    );
    assert!(done.stats.report.contains("links"), "{}", done.stats.report);
    assert!(done.stats.matrix_bytes > 0);

    let problem = nusselt_core::solver::Problem::new(cornell(), coarse_config()).expect("problem");
    let mut direct = kind.build(problem).expect("solver");
    nusselt_core::solver::run_solver(
        direct.as_mut(),
        &StopCriteria {
            residual: stop,
            ..Default::default()
        },
        &AtomicBool::new(false),
        &mut |_, _| {},
    );
    assert_eq!(direct.steps(), done.stats.steps);
    let want = done
        .geometry
        .expand(&direct.problem().mesh.vertex_values(direct.radiosity()));
    let rel = rel_l2(&done.radiance, &want, &done.geometry);
    assert!(rel < 1e-5, "thread and direct run differ by {rel}");
}
