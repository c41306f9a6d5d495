//! The viewer's solver-thread protocol, without a window: random command sequences (every
//! solver among them) never panic, deadlock or publish non-finite values, and an edit made while it runs converges
//! to the same solution as a fresh solve of the edited scene.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::geometry::Rng;
use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, MaterialId, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, SolverKind, StopCriteria};
use nusselt_viewer::snapshot::Snapshot;
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

fn check_finite(s: &Snapshot) {
    assert!(s.radiance.iter().flatten().all(|x| x.is_finite()));
    assert!(s.reflectance.iter().flatten().all(|x| x.is_finite()));
    assert!(s.ambient.iter().all(|x| x.is_finite()));
    assert_eq!(s.radiance.len(), s.geometry.positions.len());
    assert_eq!(s.reflectance.len(), s.geometry.positions.len());
    assert!(s.stats.residual.is_finite() || s.stats.residual == f64::INFINITY);
    assert!(
        s.history
            .iter()
            .all(|p| p.ambient.is_finite() && p.seconds.is_finite())
    );
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

fn spawn(scene: Scene, config: ThreadConfig) -> (SolverHandle, Arc<AtomicUsize>) {
    let wakes = Arc::new(AtomicUsize::new(0));
    let w = wakes.clone();
    let h = SolverHandle::spawn(
        scene,
        config,
        Box::new(move || {
            w.fetch_add(1, Ordering::Relaxed);
        }),
    )
    .expect("spawn");
    (h, wakes)
}

// Long by design: one random walk over every command, with the invariant checked after each.
#[test]
fn random_command_sequences_never_panic_or_deadlock() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nf 1 2 9\n").expect("write");
    let (mut h, wakes) = spawn(
        cornell(),
        ThreadConfig {
            solver: coarse_config(),
            ..Default::default()
        },
    );
    let mut rng = Rng::new(2024, 7);
    let deadline = Instant::now() + Duration::from_secs(240);
    let mut snapshots = 0;
    let mut errors = 0;
    let mut last_seq = 0;
    let n_commands = 1200;
    for i in 0..n_commands {
        let r = rng.next_f64();
        let c = match (rng.next_u32() % 14, r) {
            (0, _) => Command::Play,
            (1, _) => Command::Pause,
            (2 | 3, _) => Command::Step,
            (4, _) => Command::Reset,
            // Sizes from coarse to fine-ish, and sometimes nonsense.
            (5, r) if r < 0.1 => Command::Remesh(-1.0),
            (5, r) if r < 0.15 => Command::Remesh(f64::NAN),
            (5, r) => Command::Remesh(40.0 + 120.0 * r),
            (6..=8, r) => Command::SetMaterial {
                material: MaterialId(rng.next_u32() % 5),
                reflectance: [r * 0.99, rng.next_f64() * 0.99, 0.5],
                emission: if rng.next_f64() < 0.3 {
                    [2.0 * r, 1.0, 0.0]
                } else {
                    [0.0; 3]
                },
            },
            (9, r) if r < 0.5 => Command::SetMaterial {
                material: MaterialId(0),
                reflectance: [f64::NAN, 0.5, 1.5],
                emission: [-1.0, 0.0, 0.0],
            },
            (9, _) => Command::ResetMaterials,
            (10, _) => Command::SetMethod(
                FormFactorMethod::ALL[rng.next_u32() as usize % FormFactorMethod::ALL.len()],
            ),
            (11, r) if r < 0.3 => Command::LoadPath(bad.clone()),
            (11, r) if r < 0.5 => Command::LoadScene(Box::new(cornell())),
            (11, _) => Command::SetStopThreshold(1e-3),
            // Every solver, and an ω the solver refuses.
            (12, r) => Command::SetSolver(match (r * 6.0) as usize {
                0 => SolverKind::Shooting,
                1 => SolverKind::Jacobi,
                2 => SolverKind::GaussSeidel,
                3 => SolverKind::Sor(None),
                4 => SolverKind::Sor(Some(2.5)),
                _ => SolverKind::Cg,
            }),
            _ => Command::Play,
        };
        send(&h, c, deadline);
        // Sometimes let it shoot a little, mid-shot or between shots.
        if rng.next_f64() < 0.05 {
            std::thread::sleep(Duration::from_millis(rng.next_u32() as u64 % 5));
        }
        if let Some(s) = h.take_snapshot() {
            check_finite(&s);
            assert!(s.seq > last_seq, "snapshots only move forward");
            last_seq = s.seq;
            snapshots += 1;
        }
        while let Some(e) = h.try_event() {
            if let Event::Error(_) = e {
                errors += 1;
            }
        }
        assert!(h.is_alive(), "solver thread died at command {i}");
    }
    // It still answers: play to a loose threshold and see shots happen.
    send(&h, Command::SetStopThreshold(1e-2), deadline);
    send(&h, Command::Play, deadline);
    let mut progressed = false;
    while Instant::now() < deadline {
        if let Some(s) = h.take_snapshot() {
            check_finite(&s);
            if s.stats.steps > 0 {
                progressed = true;
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(progressed, "no shot after the random sequence");
    assert!(errors > 0, "bad loads and bad edits must report errors");
    assert!(snapshots > 0);
    assert!(
        wakes.load(Ordering::Relaxed) > 0,
        "the waker was never called"
    );
    assert!(
        h.shutdown(Duration::from_secs(30)),
        "the thread did not quit"
    );
    eprintln!("{n_commands} commands, {snapshots} snapshots seen, {errors} errors reported");
}

/// Area-weighted relative L2 difference of per-vertex radiance over the triangle corners.
fn rel_l2(a: &[[f32; 3]], b: &[[f32; 3]], g: &nusselt_viewer::snapshot::Geometry) -> f64 {
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

/// A solver thread shooting the coarse Cornell box until `stop` unshot.
fn spawn_shooting(stop: f64) -> SolverHandle {
    let (h, _) = spawn(
        cornell(),
        ThreadConfig {
            solver: coarse_config(),
            play: true,
            stop_unshot: stop,
            max_shots: None,
            shot_threads: None,
            handoff: false,
            kind: SolverKind::Shooting,
        },
    );
    h
}

/// `scene` solved afresh to `stop`, and the relative L2 distance of `converged`'s radiance
/// from it.
fn against_fresh_solve(converged: &Snapshot, scene: Scene, stop: f64) -> (f64, ProgressiveSolver) {
    let mut fresh = ProgressiveSolver::new(scene, coarse_config()).expect("solver");
    let never = std::sync::atomic::AtomicBool::new(false);
    fresh.run(
        &StopCriteria {
            residual: stop,
            ..Default::default()
        },
        &never,
        &mut |_| {},
    );
    let fresh_corners = converged
        .geometry
        .expand(&fresh.mesh().vertex_values(fresh.radiosity()));
    let rel = rel_l2(&converged.radiance, &fresh_corners, &converged.geometry);
    (rel, fresh)
}

#[test]
fn an_edit_while_running_converges_to_a_fresh_solve() {
    let stop = 1e-7;
    let mut h = spawn_shooting(stop);
    let deadline = Instant::now() + Duration::from_secs(240);
    let red = cornell()
        .materials
        .iter()
        .position(|m| m.name == "red")
        .map(|i| MaterialId(i as u32))
        .expect("red");
    let (rho, ke) = ([0.8, 0.2, 0.1], [0.0, 0.0, 2.0]);
    // Let it shoot a while, then edit mid-run.
    let mut before_edit = 0;
    while before_edit < 20 {
        assert!(Instant::now() < deadline);
        if let Some(s) = h.take_snapshot() {
            before_edit = s.stats.steps;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    send(
        &h,
        Command::SetMaterial {
            material: red,
            reflectance: rho,
            emission: ke,
        },
        deadline,
    );
    let converged = loop {
        assert!(Instant::now() < deadline, "did not converge in time");
        if let Some(s) = h.take_snapshot() {
            check_finite(&s);
            let edited = s.materials[red.0 as usize].emission == glam::DVec3::from(ke);
            if edited && s.stats.converged {
                break s;
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    assert!(
        converged.stats.steps > before_edit,
        "the edit must not restart from dark: {} shots after, {} before",
        converged.stats.steps,
        before_edit
    );
    assert!(converged.stats.residual <= stop);
    h.shutdown(Duration::from_secs(30));

    let mut scene = cornell();
    scene.materials[red.0 as usize].reflectance = rho.into();
    scene.materials[red.0 as usize].emission = ke.into();
    let (rel, _) = against_fresh_solve(&converged, scene, stop);
    eprintln!(
        "edit at shot {before_edit}, converged after {} shots; edited vs fresh: {rel:.2e}",
        converged.stats.steps
    );
    assert!(rel < 5e-3, "edited vs fresh solve differ by {rel}");
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
fn a_bad_file_reports_file_and_line_and_keeps_the_scene() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bad = dir.path().join("broken.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n").expect("write");
    let (mut h, _) = spawn(
        cornell(),
        ThreadConfig {
            solver: coarse_config(),
            play: false,
            ..Default::default()
        },
    );
    let deadline = Instant::now() + Duration::from_secs(120);
    let before = first_snapshot(&h, deadline, |_| true);
    send(&h, Command::LoadPath(bad.clone()), deadline);
    send(&h, Command::Step, deadline);
    let after = first_snapshot(&h, deadline, |s| s.stats.steps == 1);
    let mut errors = Vec::new();
    while let Some(e) = h.try_event() {
        errors.push(e);
    }
    let want = format!("{}:4", bad.display());
    assert!(
        errors
            .iter()
            .any(|e| matches!(e, Event::Error(m) if m.contains(&want))),
        "no error naming {want}: {errors:?}"
    );
    assert_eq!(after.scene_name, "cornell");
    assert_eq!(after.scene_rev, before.scene_rev);
    assert_eq!(after.geometry.id, before.geometry.id);
    assert!(h.shutdown(Duration::from_secs(30)));
}

#[test]
fn ply_export_holds_the_snapshot() {
    let (mut h, _) = spawn(
        cornell(),
        ThreadConfig {
            solver: coarse_config(),
            max_shots: Some(10),
            ..Default::default()
        },
    );
    let deadline = Instant::now() + Duration::from_secs(120);
    let s = first_snapshot(&h, deadline, |s| s.stats.limit_reached);
    h.shutdown(Duration::from_secs(30));
    let bytes = nusselt_viewer::export::ply_bytes(&s, true, 2.0);
    let end = b"end_header\n";
    let at = bytes
        .windows(end.len())
        .position(|w| w == end)
        .expect("header end")
        + end.len();
    let header = std::str::from_utf8(&bytes[..at]).expect("ascii header");
    let count = |what: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {what} ")))
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no element {what}"))
    };
    let (nv, nf) = (count("vertex"), count("face"));
    assert_eq!(nf * 3, s.geometry.indices.len());
    assert_eq!(at + nv * 27 + nf * 13, bytes.len());
    // Every corner's radiance (with ambient) is in its vertex record, and 8-bit sRGB matches.
    let f = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes"));
    for (k, &v) in s.geometry.source_vertex.iter().enumerate().step_by(97) {
        let o = at + v as usize * 27;
        for c in 0..3 {
            let want = s.radiance[k][c] + s.correction[k][c];
            assert_eq!(f(o + 12 + 4 * c), want);
            assert_eq!(bytes[o + 24 + c], nusselt_viewer::export::srgb8(want, 2.0));
            assert_eq!(f(o + 4 * c), s.geometry.positions[k][c]);
        }
    }
    // Faces index valid vertices.
    let faces = &bytes[at + nv * 27..];
    for rec in faces.chunks_exact(13) {
        assert_eq!(rec[0], 3);
        for i in 0..3 {
            let v = u32::from_le_bytes(rec[1 + 4 * i..5 + 4 * i].try_into().expect("4"));
            assert!((v as usize) < nv);
        }
    }
}

#[test]
fn it_starts_dark_brightens_and_the_ambient_term_decays() {
    let (mut h, _) = spawn(
        cornell(),
        ThreadConfig {
            solver: coarse_config(),
            play: false,
            stop_unshot: 1e-3,
            ..Default::default()
        },
    );
    let deadline = Instant::now() + Duration::from_secs(120);
    let dark = first_snapshot(&h, deadline, |_| true);
    assert_eq!(dark.stats.steps, 0);
    // Only the light's corners are lit before the first shot.
    let lit = dark
        .radiance
        .iter()
        .filter(|c| c.iter().any(|&x| x > 0.0))
        .count();
    assert!(
        lit > 0 && lit < dark.radiance.len() / 10,
        "{lit} lit vertices at shot 0"
    );
    send(&h, Command::Play, deadline);
    let done = first_snapshot(&h, deadline, |s| s.stats.converged);
    h.shutdown(Duration::from_secs(30));
    let energy = |s: &Snapshot| -> f64 { s.radiance.iter().flatten().map(|&x| f64::from(x)).sum() };
    assert!(energy(&done) > 1.5 * energy(&dark));
    let (first, last) = (
        done.history.first().expect("h"),
        done.history.last().expect("h"),
    );
    assert!(
        last.ambient < 0.05 * first.ambient,
        "ambient {} -> {}",
        first.ambient,
        last.ambient
    );
    assert!(last.residual <= 1e-3 && first.residual > last.residual);
}

#[test]
fn a_surface_made_a_light_and_back_converges_to_the_original() {
    let stop = 1e-7;
    let (mut h, _) = spawn(
        cornell(),
        ThreadConfig {
            solver: coarse_config(),
            stop_unshot: stop,
            ..Default::default()
        },
    );
    let deadline = Instant::now() + Duration::from_secs(240);
    let scene = cornell();
    let green = scene
        .materials
        .iter()
        .position(|m| m.name == "green")
        .expect("green");
    let kd = scene.materials[green].reflectance.to_array();
    let edit = |ke: [f64; 3]| Command::SetMaterial {
        material: MaterialId(green as u32),
        reflectance: kd,
        emission: ke,
    };
    first_snapshot(&h, deadline, |s| s.stats.steps >= 10);
    send(&h, edit([3.0, 3.0, 3.0]), deadline);
    let lit = first_snapshot(&h, deadline, |s| {
        s.materials[green].is_emitter() && s.stats.steps >= 40
    });
    send(&h, edit([0.0; 3]), deadline);
    let done = first_snapshot(&h, deadline, |s| {
        !s.materials[green].is_emitter() && s.stats.converged
    });
    h.shutdown(Duration::from_secs(30));
    assert!(done.stats.steps > lit.stats.steps);
    let mut fresh = ProgressiveSolver::new(cornell(), coarse_config()).expect("solver");
    fresh.run(
        &StopCriteria {
            residual: stop,
            ..Default::default()
        },
        &std::sync::atomic::AtomicBool::new(false),
        &mut |_| {},
    );
    let want = done
        .geometry
        .expand(&fresh.mesh().vertex_values(fresh.radiosity()));
    let rel = rel_l2(&done.radiance, &want, &done.geometry);
    eprintln!(
        "light and back: {} shots; vs fresh {rel:.2e}",
        done.stats.steps
    );
    assert!(
        rel < 5e-3,
        "made a light and back: differs from the original by {rel}"
    );
}

#[test]
fn a_sun_added_while_running_converges_to_a_fresh_solve() {
    // The Cornell box open at the front (its front has no wall): a sun from the camera's
    // side shines in. Added mid-run, it converges from the current state to the fresh solve.
    let stop = 1e-7;
    let sun = nusselt_core::scene::Light::Sun {
        direction: glam::DVec3::new(0.2, 0.3, -1.0).normalize_or_zero(),
        irradiance: glam::DVec3::splat(20.0),
        angular_radius: 0.0,
    };
    let mut h = spawn_shooting(stop);
    let deadline = Instant::now() + Duration::from_secs(240);
    let before = first_snapshot(&h, deadline, |s| s.stats.steps >= 20);
    send(&h, Command::SetLights(vec![sun]), deadline);
    let converged = first_snapshot(&h, deadline, |s| {
        check_finite(s);
        s.lights.len() == 1 && s.stats.converged
    });
    assert!(
        converged.stats.steps > before.stats.steps,
        "the light must not restart the solve from dark"
    );
    h.shutdown(Duration::from_secs(30));

    let mut scene = cornell();
    scene.lights.push(sun);
    let (rel, fresh) = against_fresh_solve(&converged, scene, stop);
    assert!(
        fresh.problem().external.punctual.iter().any(|h| h.x > 0.0),
        "the sun reaches into the box"
    );
    assert!(rel < 5e-3, "sun added vs fresh solve differ by {rel}");
}
