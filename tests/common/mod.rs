//! Helpers shared by the test files (not a test target of its own): the one rule for tests
//! that need a GPU or a display, and the form-factor case files.
#![allow(dead_code)] // Each test file uses its own subset.

pub mod display;

use glam::DVec3;
#[path = "../../crates/core/tests/common/mod.rs"]
mod core_common;
#[allow(unused_imports)] // Not every test file uses the core helpers.
pub use core_common::*;

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
pub fn gpu_hemicube() -> Option<nusselt_gpu::GpuHemicube> {
    match nusselt_gpu::GpuHemicube::new() {
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
