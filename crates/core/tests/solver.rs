//! Furnace and power-balance identities of the progressive solver.

use std::sync::atomic::AtomicBool;

use glam::DVec3;
use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{
    FormFactorConfig, ProgressiveSolver, ShootingOptions, SolverConfig, StopCriteria,
};

fn furnace(rho: f64, size: f64) -> ProgressiveSolver {
    furnace_with(rho, size, false)
}

/// The furnace with 1/`size` elements per side and 0.5-wide patches. Plain shooting
/// (`overshoot` false) and the classic global ambient term are what the identities below
/// are about (the regional term matches them only to its sampling error: tests/ambient.rs).
fn furnace_with(rho: f64, size: f64, overshoot: bool) -> ProgressiveSolver {
    let scene = Scene::builtin(
        "furnace",
        &LoadOptions {
            rho: Some(rho),
            ..Default::default()
        },
    )
    .expect("furnace scene");
    ProgressiveSolver::new(
        scene,
        SolverConfig {
            mesh: MeshSpec::sized(size, 0.5),
            shooting: ShootingOptions {
                overshoot,
                regional_ambient: false,
            },
            ..Default::default()
        },
    )
    .expect("solver")
}

fn max_rel_error(values: &[DVec3], exact: f64) -> f64 {
    values
        .iter()
        .map(|v| (*v - DVec3::splat(exact)).abs().max_element() / exact)
        .fold(0.0, f64::max)
}

#[test]
fn furnace_converges_to_e_over_one_minus_rho() {
    let never = AtomicBool::new(false);
    for rho in [0.5, 0.9, 0.99, 0.999] {
        let mut s = furnace(rho, 0.25);
        let exact = 1.0 / (1.0 - rho);
        // In a uniform closed furnace the ambient term is exact on average at every step:
        // Σ A (B + ρ·ambient) = Σ A B + ρ/(1 − ρ) Σ A ΔB = Σ A E/(1 − ρ).
        let check_average = |s: &ProgressiveSolver, when: &str| {
            let elements = &s.mesh().elements;
            let area: f64 = elements.iter().map(|e| e.area).sum();
            let avg = s
                .display_radiance()
                .iter()
                .zip(elements)
                .map(|(b, e)| b.x * e.area)
                .sum::<f64>()
                / area;
            assert!(
                (avg - exact).abs() < 1e-6 * exact,
                "rho {rho} {when}: average {avg} vs {exact}"
            );
        };
        // Before any shot the ambient term alone gives the exact answer everywhere.
        assert!(
            max_rel_error(&s.display_radiance(), exact) < 1e-9,
            "rho {rho} at start"
        );
        check_average(&s, "at start");
        // About one shot per patch.
        let sweep = s.mesh().patches.len();
        let first_sweep = StopCriteria {
            max_steps: Some(sweep),
            ..Default::default()
        };
        s.run(&first_sweep, &never, &mut |_| {});
        check_average(&s, "after a sweep");
        let early = max_rel_error(&s.display_radiance(), exact);
        let raw = max_rel_error(s.radiosity(), exact);
        eprintln!(
            "rho {rho}: after {sweep} shots ambient-corrected error {early:.2e}, raw {raw:.2e}"
        );
        assert!(
            early < raw,
            "the ambient term must bring the display closer"
        );
        let converge = StopCriteria {
            residual: 1e-4 * (1.0 - rho),
            ..Default::default()
        };
        s.run(&converge, &never, &mut |_| {});
        let err = max_rel_error(s.radiosity(), exact);
        eprintln!(
            "rho {rho}: {} shots, max element error {err:.2e}",
            s.shots()
        );
        assert!(err < 1e-3, "rho {rho}: error {err}");
    }
}

const BOX_OBJ: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
usemtl lamp\nf 1 5 6 2\nusemtl a\nf 4 3 7 8\nf 1 2 3 4\nusemtl b\nf 5 8 7 6\nf 1 4 8 5\nusemtl c\nf 2 6 7 3\n";

/// A closed cube where only the floor emits.
fn partial_emission_box(mtl: &str) -> ProgressiveSolver {
    let scene = Scene::from_obj_str(
        "box.obj",
        BOX_OBJ,
        &[("m.mtl", mtl)],
        &LoadOptions::default(),
    )
    .expect("scene");
    let mut s = ProgressiveSolver::new(
        scene,
        SolverConfig {
            mesh: MeshSpec::element(0.1),
            ..Default::default()
        },
    )
    .expect("solver");
    s.run(
        &StopCriteria {
            residual: 1e-7,
            ..Default::default()
        },
        &AtomicBool::new(false),
        &mut |_| {},
    );
    s
}

#[test]
fn power_balances_with_partial_emission_and_uniform_rho() {
    // With one reflectance everywhere: Σ E A = Σ (1 − ρ) B A.
    let rho = 0.7;
    let mtl = format!(
        "newmtl lamp\nKd {rho} {rho} {rho}\nKe 2 1 0.5\nnewmtl a\nKd {rho} {rho} {rho}\nnewmtl b\nKd {rho} {rho} {rho}\nnewmtl c\nKd {rho} {rho} {rho}\n"
    );
    let s = partial_emission_box(&mtl);
    let mut emitted = DVec3::ZERO;
    let mut absorbed = DVec3::ZERO;
    let lamp = s
        .scene()
        .materials
        .iter()
        .position(|m| m.name == "lamp")
        .expect("lamp");
    for (e, b) in s.mesh().elements.iter().zip(s.radiosity()) {
        let m = s.mesh().patch(e.patch).material.0 as usize;
        if m == lamp {
            emitted += DVec3::new(2.0, 1.0, 0.5) * e.area;
        }
        absorbed += (1.0 - rho) * *b * e.area;
    }
    let rel = ((emitted - absorbed) / emitted).abs().max_element();
    eprintln!("uniform rho: emitted {emitted:?} absorbed {absorbed:?} rel {rel:.2e}");
    assert!(rel < 1e-3, "power balance off by {rel}");
}

#[test]
fn power_balances_with_mixed_reflectances() {
    // In general the absorbed power is Σ (1 − ρ) H A with H the incident radiance.
    let mtl = "newmtl lamp\nKd 0.3 0.3 0.3\nKe 2 1 0.5\nnewmtl a\nKd 0.8 0.5 0.2\nnewmtl b\nKd 0.6 0.7 0.9\nnewmtl c\nKd 0.1 0.9 0.5\n";
    let s = partial_emission_box(mtl);
    let (emitted, absorbed) = s.power_balance();
    let rel = ((emitted - absorbed) / emitted).abs().max_element();
    eprintln!("mixed rho: emitted {emitted:?} absorbed {absorbed:?} rel {rel:.2e}");
    assert!(rel < 1e-3, "power balance off by {rel}");
}

fn cornell_solver(seed: u64) -> ProgressiveSolver {
    let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
    let config = SolverConfig {
        mesh: MeshSpec::sized(60.0, 120.0),
        formfactor: FormFactorConfig {
            params: nusselt_core::formfactor::FormFactorParams {
                seed,
                ..Default::default()
            },
            ..Default::default()
        },
        ..Default::default()
    };
    ProgressiveSolver::new(scene, config).expect("solver")
}

#[test]
fn a_solve_is_deterministic_for_a_seed() {
    let never = AtomicBool::new(false);
    let stop = StopCriteria {
        max_steps: Some(40),
        ..Default::default()
    };
    let mut a = cornell_solver(3);
    let mut b = cornell_solver(3);
    let mut c = cornell_solver(4);
    for s in [&mut a, &mut b, &mut c] {
        s.run(&stop, &never, &mut |_| {});
    }
    assert_eq!(a.radiosity(), b.radiosity());
    assert_ne!(
        a.radiosity(),
        c.radiosity(),
        "another seed samples visibility differently"
    );
}

#[test]
fn a_cancelled_shot_changes_nothing() {
    let mut s = cornell_solver(1);
    let before = s.radiosity().to_vec();
    let cancel = AtomicBool::new(true);
    assert_eq!(s.shoot(&cancel), None);
    assert_eq!(s.shots(), 0);
    assert_eq!(s.radiosity(), &before[..]);
    assert!(s.shoot(&AtomicBool::new(false)).is_some());
    assert_eq!(s.shots(), 1);
}

#[test]
fn an_edit_then_convergence_matches_a_fresh_solve() {
    let never = AtomicBool::new(false);
    let stop = StopCriteria {
        residual: 1e-6,
        ..Default::default()
    };
    let mut edited = cornell_solver(1);
    edited.run(
        &StopCriteria {
            max_steps: Some(30),
            ..Default::default()
        },
        &never,
        &mut |_| {},
    );
    let red = edited
        .scene()
        .materials
        .iter()
        .position(|m| m.name == "red")
        .map(|i| nusselt_core::scene::MaterialId(i as u32))
        .expect("red");
    // The red wall becomes a dim blue light and more reflective, mid-solve.
    let (rho, ke) = (DVec3::new(0.8, 0.2, 0.1), DVec3::new(0.0, 0.0, 2.0));
    edited.set_material(red, rho, ke).expect("edit");
    edited.run(&stop, &never, &mut |_| {});
    let mut fresh = cornell_solver(1);
    fresh
        .set_material(red, rho, ke)
        .expect("edit before solving");
    fresh.reset();
    fresh.run(&stop, &never, &mut |_| {});
    let (num, den) = edited
        .radiosity()
        .iter()
        .zip(fresh.radiosity())
        .zip(&fresh.mesh().elements)
        .fold((0.0, 0.0), |(n, d), ((a, b), e)| {
            (
                n + (*a - *b).length_squared() * e.area,
                d + b.length_squared() * e.area,
            )
        });
    let rel = (num / den).sqrt();
    assert!(rel < 5e-3, "edited vs fresh solve differ by {rel}");
}

#[test]
fn two_sided_faces_emit_and_reflect_on_their_backs() {
    // A light facing up above a floor facing up: only a two-sided light reaches the floor,
    // and the floor's back side then stays dark unless it is two-sided too.
    let obj = "mtllib m.mtl\nusemtl floor\nv 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 4 3 2\n\
usemtl lamp\nv 0.4 1 0.4\nv 0.6 1 0.4\nv 0.6 1 0.6\nv 0.4 1 0.6\nf 5 8 7 6\n";
    let mtl = "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 1 1 1\n";
    let floor_light = |two_sided: bool| {
        let opts = LoadOptions {
            two_sided,
            ..Default::default()
        };
        let scene = Scene::from_obj_str("t.obj", obj, &[("m.mtl", mtl)], &opts).expect("scene");
        let mut s = ProgressiveSolver::new(
            scene,
            SolverConfig {
                mesh: MeshSpec::sized(0.25, 0.5),
                ..Default::default()
            },
        )
        .expect("solver");
        s.run(
            &StopCriteria::default(),
            &AtomicBool::new(false),
            &mut |_| {},
        );
        let mesh = s.mesh();
        let floor_front: f64 = mesh
            .elements
            .iter()
            .zip(s.radiosity())
            .filter(|(e, _)| {
                let p = mesh.patch(e.patch);
                p.face == 0 && !p.back
            })
            .map(|(_, b)| b.x)
            .sum();
        floor_front
    };
    assert_eq!(
        floor_light(false),
        0.0,
        "a one-sided light facing away lights nothing"
    );
    assert!(
        floor_light(true) > 0.01,
        "a two-sided light reaches the floor"
    );
}

/// Overshooting (Feda & Purgathofer 1992) sends each patch's expected future light with its
/// shots; in the furnace that estimate (the ambient term) is exact on average, so the
/// number of sweeps (shots per patch) grows far slower with ρ than plain shooting's
/// ln(1e-4)/ln(ρ) (13 at ρ = 0.5, 87 at 0.9, 9,200 at 0.999). Bound: a fifth of plain
/// shooting's sweeps, at least 10 (measured here: 2.9, 4.6 and 636 sweeps). Overshooting
/// switched off fails at 0.9 and 0.999; a bug in its sign or bookkeeping diverges, stalls
/// (a patch re-picked with nothing to shoot), or ends at the wrong answer.
#[test]
fn overshooting_converges_the_furnace_in_far_fewer_sweeps() {
    let never = AtomicBool::new(false);
    for rho in [0.5, 0.9, 0.999] {
        let mut s = furnace_with(rho, 0.25, true);
        let patches = s.mesh().patches.len();
        let stop = StopCriteria {
            residual: 1e-4,
            max_steps: Some(1000 * patches),
            ..Default::default()
        };
        s.run(&stop, &never, &mut |_| {});
        let exact = 1.0 / (1.0 - rho);
        let err = max_rel_error(s.radiosity(), exact);
        eprintln!(
            "rho {rho}: {} shots for {patches} patches, error {err:.2e}",
            s.shots()
        );
        assert!(
            s.unshot_fraction() <= 1e-4,
            "rho {rho}: {} left",
            s.unshot_fraction()
        );
        let plain_sweeps = (1e-4f64).ln() / rho.ln();
        let bound = (plain_sweeps / 5.0).max(10.0) * patches as f64;
        assert!(
            s.shots() as f64 <= bound,
            "rho {rho}: {} shots, bound {bound}",
            s.shots()
        );
        // What is missing relative to the answer is about the unshot fraction (1e-4; the
        // unshot power and the answer's power both carry the gain 1/(1 − ρ)), on top of
        // the rows' row-sum error that the plain-shooting test allows (1e-3).
        assert!(err < 1e-3 + 1e-4, "rho {rho}: error {err}");
        for b in s.radiosity() {
            assert!(b.min_element() >= 0.0);
        }
    }
}
