//! The Teach panel's controls, driven through egui_kittest (AccessKit queries and pointer
//! clicks, no window): each control changes the panel's state or asks the solver thread
//! for the right thing. The snapshots come from a real solver thread on a coarse Cornell
//! box, so the panels draw what they draw in the viewer.

use std::sync::Arc;
use std::time::{Duration, Instant};

use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT, Queryable};

use super::compare::CompareCommand;
use super::{TeachCommand, TeachState, TeachView, leave_views, teach_panel};
use crate::panels::Action;
use crate::snapshot::Snapshot;
use crate::solver_thread::{Command, SolverHandle, ThreadConfig};
use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::SolverConfig;

/// What the harness holds: the panel's state, the snapshot it draws, the actions of the
/// last frames.
struct Panel {
    state: TeachState,
    snapshot: Option<Arc<Snapshot>>,
    actions: Vec<Action>,
}

fn harness(view: TeachView, snapshot: Option<Arc<Snapshot>>) -> Harness<'static, Panel> {
    let mut h = Harness::builder()
        .with_size(egui::vec2(420.0, 900.0))
        .build_ui_state(
            |ui, p: &mut Panel| {
                teach_panel(
                    ui,
                    &mut p.state,
                    p.snapshot.as_deref(),
                    None,
                    &mut p.actions,
                );
                // As the app does after the panel.
                leave_views(&mut p.state, &mut p.actions);
            },
            Panel {
                state: TeachState::new(view),
                snapshot,
                actions: Vec::new(),
            },
        );
    h.run();
    h
}

/// A solver thread on a coarse Cornell box (60 mm elements), paused.
pub(crate) fn coarse_cornell_thread() -> SolverHandle {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    SolverHandle::spawn(
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
    .expect("spawn")
}

/// The first snapshot of `h` matching `want` (within 120 s).
pub(crate) fn wait_for(h: &mut SolverHandle, want: impl Fn(&Snapshot) -> bool) -> Arc<Snapshot> {
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        assert!(Instant::now() < deadline, "no matching snapshot");
        if let Some(s) = h.take_snapshot()
            && want(&s)
        {
            return s;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// A solver thread on a coarse Cornell box (paused) and its first snapshot matching `want`
/// after `commands`.
pub(crate) fn snapshot_after(
    commands: Vec<Command>,
    want: impl Fn(&Snapshot) -> bool,
) -> Arc<Snapshot> {
    let mut h = coarse_cornell_thread();
    for c in commands {
        h.send(c).expect("queue");
    }
    let s = wait_for(&mut h, want);
    assert!(h.shutdown(Duration::from_secs(30)));
    s
}

/// The view buttons switch views; choosing a view asks the thread for its data, and
/// leaving it drops that again.
#[test]
fn view_buttons_switch_and_ask_for_their_data() {
    let snap = snapshot_after(Vec::new(), |_| true);
    let mut h = harness(TeachView::Step, Some(snap));
    h.get_by_label("compare").click();
    h.run();
    assert_eq!(h.state().state.view, TeachView::Compare);
    assert!(
        h.state().actions.iter().any(|a| matches!(
            a,
            Action::Teach(TeachCommand::Compare(CompareCommand::On { steps: 0 }))
        )),
        "{:?}",
        h.state().actions
    );
    h.state_mut().actions.clear();
    h.get_by_label("mesh").click();
    h.run();
    let actions = &h.state().actions;
    assert_eq!(h.state().state.view, TeachView::Mesh);
    assert!(
        actions
            .iter()
            .any(|a| matches!(a, Action::Teach(TeachCommand::Compare(CompareCommand::Off)))),
        "{actions:?}"
    );
    assert!(
        actions
            .iter()
            .any(|a| matches!(a, Action::Teach(TeachCommand::Mesh(Some(t))) if *t == super::meshing::DEFAULT_TOLERANCE)),
        "{actions:?}"
    );
    h.state_mut().actions.clear();
    h.get_by_label("step").click();
    h.run();
    assert!(
        h.state()
            .actions
            .iter()
            .any(|a| matches!(a, Action::Teach(TeachCommand::Mesh(None)))),
        "leaving the mesh view drops its job: {:?}",
        h.state().actions
    );
}

/// Step mode: "Shoot once" asks for one step, "Back" is disabled before the first shot,
/// "show what the last shot added" and "projector" toggle the panel's state.
#[test]
fn step_mode_controls() {
    let snap = snapshot_after(Vec::new(), |_| true);
    assert_eq!(snap.stats.steps, 0);
    let mut h = harness(TeachView::Step, Some(snap));
    assert!(h.get_by_label("Back").accesskit_node().is_disabled());
    h.get_by_label("Shoot once").click();
    h.run();
    assert!(
        h.state()
            .actions
            .iter()
            .any(|a| matches!(a, Action::Solver(Command::Step)))
    );
    assert!(!h.state().state.show_received);
    h.get_by_label("show what the last shot added (ΔB_j) instead of B")
        .click();
    h.run();
    assert!(h.state().state.show_received);
    assert!(!h.state().state.projector);
    h.get_by_label("projector").click();
    h.run();
    assert!(h.state().state.projector);
}

/// The comparison's controls, once its rows are ready: Step, Play and Reset send their
/// commands; the ambient toggle changes what the shooting image shows.
#[test]
fn compare_controls() {
    let snap = snapshot_after(
        vec![Command::Teach(TeachCommand::Compare(CompareCommand::On {
            steps: 2,
        }))],
        |s| s.teach_compare.as_ref().is_some_and(|d| d.steps == 2),
    );
    let mut state = TeachState::new(TeachView::Compare);
    state.compare_on = true;
    let mut h = harness(TeachView::Compare, Some(snap));
    h.state_mut().state = state;
    h.run();
    for (label, want) in [
        ("Step", CompareCommand::Step),
        ("Play", CompareCommand::Play(true)),
        ("Reset", CompareCommand::Reset),
    ] {
        h.state_mut().actions.clear();
        h.get_by_label(label).click();
        h.run();
        assert!(
            h.state()
                .actions
                .iter()
                .any(|a| matches!(a, Action::Teach(TeachCommand::Compare(c)) if *c == want)),
            "{label}: {:?}",
            h.state().actions
        );
    }
    assert!(h.state().state.compare_ambient);
    h.get_by_label("show shooting with the ambient term")
        .click();
    h.run();
    assert!(!h.state().state.compare_ambient);
}
