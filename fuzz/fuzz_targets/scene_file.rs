//! A scene file (JSON: model or builtin, lights, camera, material edits, mesh and solver
//! settings) → read and checked → the scene it describes → mesh → 3 shots → an 8 × 8
//! render. A `model` path names a missing file (an error, fine) unless it is a built-in.
//! Seed with the scene files the viewer's Save scene writes and README's example.
#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use nusselt::scene::SceneFile;

fuzz_target!(|data: &[u8]| {
    let path = common::scratch().join("fuzz.scene.json");
    if std::fs::write(&path, data).is_err() {
        return;
    }
    let Ok(file) = SceneFile::read(&path) else {
        return;
    };
    if let Ok(scene) = file.load(&path) {
        common::solve_and_render(scene);
    }
});
