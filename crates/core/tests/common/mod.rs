//! Helpers shared by the core's test files (not a test target of its own): the form-factor
//! case files of the repository's `tests/data` and solver checks. The binary's tests include
//! this file too (`tests/common/mod.rs`).
#![allow(dead_code)] // Each test file uses its own subset.

use std::path::{Path, PathBuf};

use glam::DVec3;
use nusselt_core::cases::{self, Case};

/// The repository's root (the folder of the workspace's `Cargo.lock`), whichever crate's
/// tests ask.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|p| p.join("Cargo.lock").exists())
        .expect("the workspace root above CARGO_MANIFEST_DIR")
        .to_path_buf()
}

/// A case file of tests/data.
pub fn load(name: &str) -> Vec<Case> {
    let p = repo_root().join("tests/data").join(name);
    cases::load(&p).expect("case file")
}

/// The reference catalogue (tests/data/formfactors.json).
pub fn catalogue() -> Vec<Case> {
    load("formfactors.json")
}

/// Shots in which progressive shooting must reach `unshot` (Southwell's bound): each shot
/// takes the patch with the most unshot power, at least U/n of the total U over n patches,
/// and at most ρ_max of it comes back, so U shrinks by a factor (1 − (1 − ρ_max)/n) a shot
/// or faster: k ≤ n·ln(1/unshot)/(1 − ρ_max). Scenes converge far sooner; the bound only
/// ends a run that does not converge, in the same number of shots on any machine.
pub fn shot_bound(s: &nusselt_core::solver::ProgressiveSolver, unshot: f64) -> usize {
    let problem = s.problem();
    let rho_max = (0..s.mesh().elements.len())
        .map(|e| problem.element_rho(e).max_element())
        .fold(0.0, f64::max)
        .min(0.999);
    let n = s.mesh().patches.len() as f64;
    (n * (1.0 / unshot).ln() / (1.0 - rho_max)).ceil() as usize
}

/// Shoots to `unshot`, failing with what was reached if [`shot_bound`] shots do not get
/// there. No wall-clock limit: a slow or loaded machine takes longer, never fails. Returns
/// the seconds taken (reported, not asserted).
pub fn converge_to(s: &mut nusselt_core::solver::ProgressiveSolver, unshot: f64) -> f64 {
    let max_shots = shot_bound(s, unshot);
    let start = std::time::Instant::now();
    s.run(
        &nusselt_core::solver::StopCriteria {
            residual: unshot,
            max_steps: Some(max_shots),
            max_seconds: None,
            tolerance: None,
        },
        &std::sync::atomic::AtomicBool::new(false),
        &mut |_| {},
    );
    let secs = start.elapsed().as_secs_f64();
    eprintln!(
        "{}: {} faces, {} patches, {} elements, {} shots, unshot {:.3e} in {secs:.1} s",
        s.scene().name,
        s.scene().faces.len(),
        s.mesh().patches.len(),
        s.mesh().elements.len(),
        s.shots(),
        s.unshot_fraction()
    );
    assert!(
        s.unshot_fraction() <= unshot,
        "{}: not converged to unshot {unshot} in {max_shots} shots (Southwell's bound): {} \
         shots, {} patches, {} elements, unshot {:.3e}",
        s.scene().name,
        s.shots(),
        s.mesh().patches.len(),
        s.mesh().elements.len(),
        s.unshot_fraction()
    );
    secs
}

/// Every element radiance (with and without the ambient term), every incident value and
/// every display-vertex value is finite and non-negative.
pub fn assert_sane(s: &nusselt_core::solver::ProgressiveSolver) {
    let name = &s.scene().name;
    for ambient in [false, true] {
        let shown = if ambient {
            s.display_radiance()
        } else {
            s.radiosity().to_vec()
        };
        for (j, b) in shown.iter().enumerate() {
            assert!(
                b.is_finite() && b.min_element() >= 0.0,
                "{name}: element {j} radiance {b} (ambient {ambient})"
            );
        }
    }
    for (j, h) in s.incident().iter().enumerate() {
        assert!(
            h.is_finite() && h.min_element() >= 0.0,
            "{name}: element {j} incident {h}"
        );
    }
    let vertex_radiance = s.mesh().vertex_values(&s.display_radiance());
    for (v, b) in vertex_radiance.iter().enumerate() {
        assert!(
            b.is_finite() && b.min_element() >= 0.0,
            "{name}: vertex {v} radiance {b:?}"
        );
    }
}

/// Unshot power Σ ΔB·A over patches, per channel.
pub fn unshot_power(s: &nusselt_core::solver::ProgressiveSolver) -> DVec3 {
    s.unshot()
        .iter()
        .zip(&s.mesh().patches)
        .map(|(u, p)| *u * p.area)
        .sum()
}
