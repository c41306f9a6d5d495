//! A panic in the solver does not take the viewer's solver thread down (defence in
//! depth): it is reported as "solver failed on <scene>: <message>", nothing more is
//! published for the broken solve (the UI keeps its last image), and the thread still
//! loads another scene and shoots it. The panic is injected through the hidden
//! `Command::PanicOnNextShot`, which panics inside the shot, where a solver bug would.

use std::time::{Duration, Instant};

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::SolverConfig;
use nusselt_viewer::snapshot::Snapshot;
use nusselt_viewer::solver_thread::{Command, Event, SolverHandle, ThreadConfig};

fn cornell() -> Scene {
    Scene::builtin("cornell", &LoadOptions::default()).expect("cornell")
}

fn send(h: &SolverHandle, mut c: Command, deadline: Instant) {
    loop {
        match h.send(c) {
            Ok(()) => return,
            Err(back) => {
                assert!(Instant::now() < deadline, "channel stayed full");
                c = back;
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
}

/// Snapshots and events until `done` holds for an event (or the deadline passes).
fn wait_for_event(
    h: &SolverHandle,
    deadline: Instant,
    snapshots: &mut Vec<std::sync::Arc<Snapshot>>,
    done: impl Fn(&Event) -> bool,
) -> Event {
    loop {
        assert!(Instant::now() < deadline, "no matching event in time");
        if let Some(s) = h.take_snapshot() {
            snapshots.push(s);
        }
        if let Some(e) = h.try_event() {
            if done(&e) {
                return e;
            }
        } else {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

#[test]
fn a_panic_in_a_shot_is_reported_and_the_thread_loads_the_next_scene() {
    let (mut h, deadline) = (
        SolverHandle::spawn(
            cornell(),
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
        .expect("spawn"),
        Instant::now() + Duration::from_secs(120),
    );
    let mut seen = Vec::new();
    wait_for_event(
        &h,
        deadline,
        &mut seen,
        |e| matches!(e, Event::Loaded { name, .. } if name == "cornell"),
    );

    send(
        &h,
        Command::PanicOnNextShot("injected bug".into()),
        deadline,
    );
    send(&h, Command::Step, deadline);
    let failed = wait_for_event(&h, deadline, &mut seen, |e| matches!(e, Event::Failed(_)));
    assert_eq!(
        failed,
        Event::Failed("solver failed on cornell: injected bug".into())
    );
    assert!(h.is_alive(), "the solver thread died with the solver");

    // Nothing is published for the broken solve: the UI keeps the last image, which was
    // taken before the shot that panicked.
    send(&h, Command::Play, deadline);
    std::thread::sleep(Duration::from_millis(300));
    if let Some(s) = h.take_snapshot() {
        seen.push(s);
    }
    assert!(!seen.is_empty(), "the scene was published before the panic");
    assert!(
        seen.iter().all(|s| s.stats.steps == 0),
        "a snapshot after the panicking shot: {:?}",
        seen.iter().map(|s| s.stats.steps).collect::<Vec<_>>()
    );
    let rev = seen.last().map(|s| s.scene_rev).expect("a snapshot");

    // The thread takes the next scene and solves it.
    send(&h, Command::LoadScene(Box::new(cornell())), deadline);
    send(&h, Command::Play, deadline);
    wait_for_event(&h, deadline, &mut seen, |e| {
        matches!(e, Event::Loaded { .. })
    });
    let shot = loop {
        assert!(Instant::now() < deadline, "the new scene never shot");
        if let Some(s) = h.take_snapshot()
            && s.scene_rev > rev
            && s.stats.steps > 0
        {
            break s;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    assert!(shot.radiance.iter().flatten().all(|x| x.is_finite()));
    assert!(
        h.shutdown(Duration::from_secs(30)),
        "the thread must quit cleanly (it did not panic)"
    );
}
