//! A soak of the viewer's solver thread: 10,000 random commands of every kind (open, re-mesh,
//! material and light edits, area lights, solvers, form-factor methods, adaptive refinement,
//! teaching views, scene saves) on a coarse Cornell box under a memory budget. Nothing may
//! panic, the thread answers every few hundred commands within a bound, and the process's
//! resident memory stays flat and inside the budget.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;
use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::geometry::Rng;
use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{AreaLight, Light, LoadOptions, MaterialId, Scene};
use nusselt_core::solver::{SolverConfig, SolverKind};
use nusselt_viewer::solver_thread::{Command, SolverHandle, ThreadConfig};
use nusselt_viewer::teach::TeachCommand;

const COMMANDS: usize = 10_000;
/// The solver's memory budget: far above what a 60 mm Cornell box needs (a few MB), so a
/// run that grows towards it is leaking.
const BUDGET: usize = 256 << 20;
/// A command is answered when a `Step` sent after it brings a snapshot within this time.
const ANSWER_BOUND: Duration = Duration::from_secs(30);

fn cornell() -> Scene {
    Scene::builtin("cornell", &LoadOptions::default()).expect("cornell")
}

/// Resident memory of this process (Linux `/proc/self/status`), in bytes.
fn resident_bytes() -> usize {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let kb: usize = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .expect("VmRSS");
    kb << 10
}

fn random_light(rng: &mut Rng) -> Light {
    let r = rng.next_f64();
    match rng.next_u32() % 3 {
        0 => Light::Sky {
            radiance: DVec3::splat(r),
        },
        1 => Light::Sun {
            direction: DVec3::new(r - 0.5, 1.0, 0.3),
            irradiance: DVec3::splat(2.0 * r),
            angular_radius: 0.0,
        },
        _ => Light::Point {
            position: DVec3::new(278.0, 300.0 + 200.0 * r, 280.0),
            intensity: DVec3::splat(1e4 * r),
            cone: None,
        },
    }
}

fn random_area_lights(rng: &mut Rng) -> Vec<AreaLight> {
    let n = rng.next_u32() % 3;
    (0..n)
        .map(|_| {
            let (x, z, s) = (
                100.0 + 300.0 * rng.next_f64(),
                100.0 + 300.0 * rng.next_f64(),
                60.0,
            );
            AreaLight {
                corners: vec![
                    DVec3::new(x, 500.0, z),
                    DVec3::new(x + s, 500.0, z),
                    DVec3::new(x + s, 500.0, z + s),
                    DVec3::new(x, 500.0, z + s),
                ],
                radiance: DVec3::splat(5.0 * rng.next_f64()),
            }
        })
        .collect()
}

fn random_command(rng: &mut Rng, dir: &std::path::Path) -> Command {
    let r = rng.next_f64();
    match rng.next_u32() % 20 {
        0 | 1 => Command::Play,
        2 => Command::Pause,
        3 | 4 => Command::Step,
        5 => Command::Reset,
        6 if r < 0.1 => Command::Remesh(f64::NAN),
        6 => Command::Remesh(50.0 + 100.0 * r),
        7 | 8 => Command::SetMaterial {
            material: MaterialId(rng.next_u32() % 5),
            reflectance: [r * 0.99, rng.next_f64() * 0.99, 0.5],
            emission: [0.0; 3],
        },
        9 => Command::ResetMaterials,
        10 | 11 => Command::SetLights((0..rng.next_u32() % 3).map(|_| random_light(rng)).collect()),
        12 => Command::SetAreaLights(random_area_lights(rng)),
        13 => Command::SetMethod(
            FormFactorMethod::ALL[rng.next_u32() as usize % FormFactorMethod::ALL.len()],
        ),
        14 => Command::SetSolver(match (r * 7.0) as usize {
            0 => SolverKind::Shooting,
            1 => SolverKind::Jacobi,
            2 => SolverKind::GaussSeidel,
            3 => SolverKind::Sor(None),
            4 => SolverKind::Cg,
            5 => SolverKind::Hierarchical,
            _ => SolverKind::Wavelet,
        }),
        15 => Command::Adapt((r < 0.7).then_some(0.3 + r)),
        16 => Command::Teach(match rng.next_u32() % 5 {
            0 => TeachCommand::RecordSteps(r < 0.5),
            1 => TeachCommand::Back,
            2 => TeachCommand::Matrix(r < 0.5),
            3 => TeachCommand::Mesh((r < 0.5).then_some(80.0)),
            _ => TeachCommand::Hemicube(None),
        }),
        17 if r < 0.02 => Command::LoadScene(Box::new(cornell())),
        17 => Command::SetStopThreshold(1e-3),
        18 if r < 0.05 => Command::SaveScene {
            path: dir.join("soak.scene.json"),
            camera: None,
        },
        _ => Command::Step,
    }
}

/// Sends, retrying while the channel is full (the test may wait; the UI never does).
fn send(h: &SolverHandle, mut c: Command) {
    let deadline = Instant::now() + ANSWER_BOUND;
    loop {
        match h.send(c) {
            Ok(()) => return,
            Err(back) => {
                assert!(
                    Instant::now() < deadline,
                    "channel full for {ANSWER_BOUND:?}"
                );
                c = back;
                std::thread::sleep(Duration::from_micros(200));
            }
        }
    }
}

/// A `Step` answered by a new snapshot within [`ANSWER_BOUND`].
fn assert_answers(h: &mut SolverHandle, last_seq: &mut u64, at: usize) {
    send(h, Command::Step);
    let deadline = Instant::now() + ANSWER_BOUND;
    loop {
        if let Some(s) = h.take_snapshot() {
            assert!(s.radiance.iter().flatten().all(|x| x.is_finite()));
            if s.seq > *last_seq {
                *last_seq = s.seq;
                return;
            }
        }
        while h.try_event().is_some() {}
        assert!(h.is_alive(), "solver thread died by command {at}");
        assert!(
            Instant::now() < deadline,
            "no snapshot within {ANSWER_BOUND:?} after command {at}"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn ten_thousand_random_commands_keep_the_thread_answering_and_memory_flat() {
    let dir = tempfile::tempdir().expect("tempdir");
    let baseline = resident_bytes();
    let wakes = Arc::new(AtomicUsize::new(0));
    let w = wakes.clone();
    let mut h = SolverHandle::spawn(
        cornell(),
        ThreadConfig {
            solver: SolverConfig {
                mesh: MeshSpec::sized(60.0, 120.0),
                memory_bytes: BUDGET,
                ..Default::default()
            },
            ..Default::default()
        },
        Box::new(move || {
            w.fetch_add(1, Ordering::Relaxed);
        }),
    )
    .expect("spawn");
    let mut rng = Rng::new(29, 4);
    let mut last_seq = 0;
    let mut samples: Vec<usize> = Vec::new();
    let start = Instant::now();
    for i in 0..COMMANDS {
        send(&h, random_command(&mut rng, dir.path()));
        while h.try_event().is_some() {}
        if let Some(s) = h.take_snapshot() {
            last_seq = last_seq.max(s.seq);
        }
        if i % 250 == 249 {
            assert_answers(&mut h, &mut last_seq, i);
            samples.push(resident_bytes());
        }
    }
    let peak = samples.iter().copied().max().unwrap_or(0);
    let quarter = samples.len() / 4;
    let mean = |s: &[usize]| s.iter().sum::<usize>() as f64 / s.len().max(1) as f64;
    let (early, late) = (
        mean(&samples[quarter..2 * quarter]),
        mean(&samples[3 * quarter..]),
    );
    eprintln!(
        "{COMMANDS} commands in {:.1} s; resident: baseline {} MiB, second quarter {:.0} MiB, \
         last quarter {:.0} MiB, peak {} MiB (budget {} MiB); {} wakes",
        start.elapsed().as_secs_f64(),
        baseline >> 20,
        early / f64::from(1 << 20),
        late / f64::from(1 << 20),
        peak >> 20,
        BUDGET >> 20,
        wakes.load(Ordering::Relaxed)
    );
    assert!(
        peak <= baseline + BUDGET,
        "resident {peak} B over the baseline {baseline} B plus the budget {BUDGET} B"
    );
    // Flat: a leak of one coarse mesh (~0.5 MB) per re-mesh or load would add ~250 MB over
    // the ~500 of each kind sent between the second and the last quarter; allocator
    // fragmentation is a few per cent.
    assert!(
        late <= 1.25 * early + (32 << 20) as f64,
        "resident memory grew from {early} B to {late} B"
    );
    assert!(
        h.shutdown(Duration::from_secs(30)),
        "the thread did not quit"
    );
}
