//! Helpers shared by the test files (not a test target of its own): the one rule for tests
//! that need a GPU or a display, and the form-factor case files.
#![allow(dead_code)] // Each test file uses its own subset.

pub mod display;

use std::path::PathBuf;

use glam::DVec3;
use nusselt::cli::cases::{self, Case};

/// A case file of tests/data.
pub fn load(name: &str) -> Vec<Case> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    cases::load(&p).expect("case file")
}

/// The reference catalogue (tests/data/formfactors.json).
pub fn catalogue() -> Vec<Case> {
    load("formfactors.json")
}

/// One JSON value per line of a command's standard output.
pub fn json_lines(stdout: Vec<u8>) -> Vec<serde_json::Value> {
    String::from_utf8(stdout)
        .expect("utf-8")
        .lines()
        .map(|l| serde_json::from_str(l).expect("json line"))
        .collect()
}

/// Whether this run is CI: `CI` set to anything but empty, `false` or `0` (`.ci/run` exports
/// `CI=true`; GitHub and GitLab set `CI=true` too). The one place the tests decide this.
pub fn in_ci() -> bool {
    ci_value(std::env::var_os("CI").as_deref().and_then(|v| v.to_str()))
}

/// [`in_ci`] for a given value of `CI`.
pub fn ci_value(v: Option<&str>) -> bool {
    v.is_some_and(|v| !v.is_empty() && !v.eq_ignore_ascii_case("false") && v != "0")
}

/// A test cannot run here (no GPU adapter, no display, ...). Outside CI it prints
/// `SKIPPED: <reason>` and the caller returns; in CI, where the setup installs lavapipe and
/// Xvfb, a skip would hide a broken setup, so it fails with the reason.
pub fn skip(reason: &str) {
    assert!(
        !in_ci(),
        "CI must run this test, but it cannot: {reason} (CI={:?})",
        std::env::var_os("CI").unwrap_or_default()
    );
    eprintln!("SKIPPED: {reason} (set CI=true to make this a failure)");
}

/// The GPU hemicube, or `None` after [`skip`] (a failure in CI) with the adapter's error.
pub fn gpu_hemicube() -> Option<nusselt::gpu::GpuHemicube> {
    match nusselt::gpu::GpuHemicube::new() {
        Ok(g) => {
            eprintln!("GPU adapter: {}", g.adapter());
            Some(g)
        }
        Err(e) => {
            skip(&format!("no GPU adapter for the GPU hemicube: {e}"));
            None
        }
    }
}

/// A bound on |hemicube − exact| for one hemicube at `p` (any normal, any rotation) seeing
/// `polygons` (the receiver and the occluders), from the pixel size Δ = 2/res alone:
///
/// * a pixel that no projected edge crosses lies wholly inside or outside every polygon's
///   image, so its centre classifies it right; it errs only by the midpoint rule of its delta
///   form factor ρ: `Δ⁴/24 · (|ρ_xx| + |ρ_yy|) ≤ Δ⁴/24 · 8/π` per pixel, `4Δ²/π` over the 12
///   face units of the hemicube;
/// * the others lie along projected edges. An edge projects onto at most the 5 faces, as a
///   straight piece on each, and a piece of face length L crosses at most `√2 L/Δ + 3`
///   pixels. At face distance r from `p` (1 ≤ r ≤ √3) a change dθ of direction moves the
///   image by at most r² dθ, and a pixel there has `ΔF ≤ Δ²/(π r⁴)` (top: Δ²/(π r⁴); sides:
///   z Δ²/(π r⁴), z ≤ 1). So an edge subtending θ at `p` misclassifies at most
///   `√2 Δ θ/π + 15 Δ²/π` of form factor, wherever it lies;
/// * the near plane clips along the horizon, the bottom pixel rows of the sides: at most
///   `4 res · (Δ/2) · Δ²/π = 4Δ²/π`.
pub fn hemicube_bound(res: u32, p: DVec3, polygons: &[&[DVec3]]) -> f64 {
    use std::f64::consts::{PI, SQRT_2};
    let res = res.div_ceil(2) * 2; // As DeltaTable rounds it.
    let d = 2.0 / res as f64;
    let (mut theta, mut edges) = (0.0, 0.0);
    for poly in polygons {
        for (k, a) in poly.iter().enumerate() {
            let b = poly[(k + 1) % poly.len()];
            theta += (*a - p).angle_between(b - p);
            edges += 1.0;
        }
    }
    SQRT_2 * d * theta / PI + (15.0 * edges + 8.0) * d * d / PI
}

/// Shoots to `unshot` within `budget_s` wall seconds; fails with what was reached otherwise.
/// Returns the seconds taken.
pub fn converge_within(
    s: &mut nusselt::solver::ProgressiveSolver,
    unshot: f64,
    budget_s: f64,
) -> f64 {
    let start = std::time::Instant::now();
    s.run(
        &nusselt::solver::StopCriteria {
            unshot,
            max_shots: None,
            max_seconds: Some(budget_s),
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
        "{}: not converged to unshot {unshot} within {budget_s} s: {} shots, {} patches, {} \
         elements, unshot {:.3e}",
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
pub fn assert_sane(s: &nusselt::solver::ProgressiveSolver) {
    let name = &s.scene().name;
    for ambient in [false, true] {
        for (j, b) in s.element_radiance(ambient).iter().enumerate() {
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
    let vertex_radiance = s.mesh().vertex_values(&s.element_radiance(true));
    for (v, b) in vertex_radiance.iter().enumerate() {
        assert!(
            b.is_finite() && b.min_element() >= 0.0,
            "{name}: vertex {v} radiance {b:?}"
        );
    }
}

/// Unshot power Σ ΔB·A over patches, per channel.
pub fn unshot_power(s: &nusselt::solver::ProgressiveSolver) -> DVec3 {
    s.unshot()
        .iter()
        .zip(&s.mesh().patches)
        .map(|(u, p)| *u * p.area)
        .sum()
}
