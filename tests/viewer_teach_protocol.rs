//! Teaching mode over the solver thread, without a window: recorded single steps, one step
//! back (the replay gives exactly the earlier image and numbers), the hemicube kept at the
//! shooter, and the form-factor matrix filled while the solver is idle (and refused, with
//! an error event, on a mesh too large for it).

use std::sync::Arc;
use std::time::{Duration, Instant};

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::SolverConfig;
use nusselt_viewer::snapshot::Snapshot;
use nusselt_viewer::solver_thread::{Command, SolverHandle, ThreadConfig};
use nusselt_viewer::teach::TeachCommand;
use nusselt_viewer::teach::hemicube::HemicubeRequest;

fn send(h: &SolverHandle, mut c: Command, deadline: Instant) {
    loop {
        match h.send(c) {
            Ok(()) => return,
            Err(back) => {
                assert!(Instant::now() < deadline, "channel stayed full");
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

#[test]
fn steps_back_hemicube_and_matrix_over_the_thread() {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let mut h = SolverHandle::spawn(
        scene,
        ThreadConfig {
            solver: SolverConfig {
                mesh: MeshSpec::sized(60.0, 120.0),
                ..Default::default()
            },
            play: false,
            ..Default::default()
        },
        Box::new(|| {}),
    )
    .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(240);
    send(
        &h,
        Command::Teach(TeachCommand::RecordSteps(true)),
        deadline,
    );
    send(&h, Command::Step, deadline);
    send(&h, Command::Step, deadline);
    let two = first_snapshot(&h, deadline, |s| s.stats.steps == 2);
    let d2 = two.teach_step.clone().expect("the second shot recorded");
    assert_eq!(d2.step, 2);
    assert_eq!(two.stats.last_shooter, Some(d2.shooter));
    send(&h, Command::Step, deadline);
    let three = first_snapshot(&h, deadline, |s| s.stats.steps == 3);
    assert_eq!(three.teach_step.as_ref().map(|d| d.step), Some(3));
    assert_ne!(three.radiance, two.radiance);

    // Back: exactly the state after two shots, and its numbers again.
    send(&h, Command::Teach(TeachCommand::Back), deadline);
    let back = first_snapshot(&h, deadline, |s| s.seq > three.seq && s.stats.steps == 2);
    assert_eq!(back.radiance, two.radiance, "back is not the earlier image");
    assert_eq!(back.stats.last_shooter, two.stats.last_shooter);
    let db = back.teach_step.clone().expect("the replayed shot recorded");
    assert_eq!((db.step, db.shooter), (2, d2.shooter));
    assert_eq!(db.received, d2.received);
    assert!(back.history.iter().all(|p| p.steps <= 2));

    // The hemicube follows the shooter.
    let request = HemicubeRequest {
        res: 16,
        patch: None,
        receiver: None,
    };
    send(
        &h,
        Command::Teach(TeachCommand::Hemicube(Some(request))),
        deadline,
    );
    send(&h, Command::Step, deadline);
    let cube = first_snapshot(&h, deadline, |s| {
        s.stats.steps == 3
            && s.teach_hemicube
                .as_ref()
                .is_some_and(|d| Some(d.patch) == s.stats.last_shooter)
    });
    let d = cube.teach_hemicube.clone().expect("hemicube");
    assert_eq!(d.res, 16);
    assert_eq!(d.request, request);

    // The matrix fills while the solver is idle (paused), shooter's row first.
    send(&h, Command::Teach(TeachCommand::Matrix(true)), deadline);
    let full = first_snapshot(&h, deadline, |s| {
        s.teach_matrix
            .as_ref()
            .is_some_and(|d| d.rows_done == d.patches)
    });
    let m = full.teach_matrix.clone().expect("matrix");
    assert_eq!(m.patches, full.geometry.patches);
    assert!(m.patch_f.iter().all(|f| f.is_finite() && *f >= 0.0));
    assert_eq!(m.shooter, full.stats.last_shooter);
    assert!(
        m.column_colours
            .as_ref()
            .is_some_and(|c| c.len() == full.geometry.positions.len())
    );
    assert_eq!(
        full.stats.steps, 3,
        "filling the matrix must not step the solver"
    );
    assert!(h.shutdown(Duration::from_secs(30)));
}

/// The matrix view refuses a mesh whose patch matrix would be too large to copy to the UI
/// (an error event saying why), and the solver goes on.
#[test]
fn the_matrix_view_refuses_too_many_patches() {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let mut h = SolverHandle::spawn(
        scene,
        ThreadConfig {
            solver: SolverConfig {
                mesh: MeshSpec::sized(20.0, 20.0),
                ..Default::default()
            },
            play: false,
            ..Default::default()
        },
        Box::new(|| {}),
    )
    .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(240);
    let first = first_snapshot(&h, deadline, |_| true);
    assert!(first.geometry.patches > nusselt_viewer::teach::matrix::MAX_PATCHES);
    send(&h, Command::Teach(TeachCommand::Matrix(true)), deadline);
    send(&h, Command::Step, deadline);
    let after = first_snapshot(&h, deadline, |s| s.stats.steps == 1);
    assert!(after.teach_matrix.is_none());
    let errors: Vec<_> = std::iter::from_fn(|| h.try_event())
        .filter_map(|e| match e {
            nusselt_viewer::solver_thread::Event::Error(m) => Some(m),
            _ => None,
        })
        .collect();
    assert!(
        errors.iter().any(|m| m.contains("at most 2048 patches")),
        "{errors:?}"
    );
    assert!(h.shutdown(Duration::from_secs(30)));
}

/// Shooting vs gathering and uniform vs adaptive meshing over the thread: the comparison
/// computes its rows while the viewer's solver stays paused, then takes the steps asked
/// for, one of each method per step, and plays at its rate until paused; the meshing view
/// arrives from its own thread with the adaptive mesh smaller than the uniform one.
#[test]
fn compare_and_mesh_views_over_the_thread() {
    use nusselt_viewer::teach::compare::CompareCommand;
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let mut h = SolverHandle::spawn(
        scene,
        ThreadConfig {
            solver: SolverConfig {
                mesh: MeshSpec::sized(60.0, 120.0),
                ..Default::default()
            },
            play: false,
            ..Default::default()
        },
        Box::new(|| {}),
    )
    .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(240);
    send(
        &h,
        Command::Teach(TeachCommand::Compare(CompareCommand::On { steps: 4 })),
        deadline,
    );
    let four = first_snapshot(&h, deadline, |s| {
        s.teach_compare
            .as_ref()
            .is_some_and(|d| d.rows_done == d.patches && d.steps == 4)
    });
    let d = four.teach_compare.clone().expect("comparison");
    assert_eq!(four.stats.steps, 0, "the viewer's solver must not step");
    assert_eq!(d.patches, four.geometry.patches);
    assert_eq!(d.curve.len(), 5, "a point per step and the start");
    assert_eq!(d.last_gatherer, Some(3), "Gauss-Seidel goes in patch order");
    assert!(d.last_shooter.is_some());
    // Play at a high rate: steps go on without commands, and stop on pause.
    send(
        &h,
        Command::Teach(TeachCommand::Compare(CompareCommand::Rate(500.0))),
        deadline,
    );
    send(
        &h,
        Command::Teach(TeachCommand::Compare(CompareCommand::Play(true))),
        deadline,
    );
    let played = first_snapshot(&h, deadline, |s| {
        s.teach_compare.as_ref().is_some_and(|d| d.steps >= 40)
    });
    send(
        &h,
        Command::Teach(TeachCommand::Compare(CompareCommand::Play(false))),
        deadline,
    );
    let paused = first_snapshot(&h, deadline, |s| {
        s.seq > played.seq && s.teach_compare.as_ref().is_some_and(|d| !d.playing)
    });
    let at = paused.teach_compare.as_ref().map(|d| d.steps);
    std::thread::sleep(Duration::from_millis(300));

    send(&h, Command::Teach(TeachCommand::Mesh(Some(0.25))), deadline);
    let meshed = first_snapshot(&h, deadline, |s| s.teach_mesh.is_some());
    // Paused stays paused while the meshing view runs.
    assert_eq!(meshed.teach_compare.as_ref().map(|d| d.steps), at);
    let m = meshed.teach_mesh.clone().expect("meshes");
    assert_eq!(m.tolerance, 0.25);
    assert!(m.adaptive.elements < m.uniform.elements);
    assert!(meshed.teach_mesh_stage.is_none(), "the job is collected");
    assert!(h.shutdown(Duration::from_secs(30)));
}
