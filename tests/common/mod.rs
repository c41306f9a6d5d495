//! Helpers shared by the test files (not a test target of its own): the one rule for tests
//! that need a GPU or a display, and the form-factor case files.
#![allow(dead_code)] // Each test file uses its own subset.

use std::path::PathBuf;

use nusselt::formfactor::cases::{self, Case};

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
