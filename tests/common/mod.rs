//! Helpers shared by the form-factor test files (not a test target of its own).
#![allow(dead_code)] // Each test file uses its own subset.

use std::path::PathBuf;

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
