//! glTF JSON or GLB bytes → the glTF importer → mesh → 3 shots → an 8 × 8 render.
//! External buffers and images are looked up in an empty folder (missing: an error, fine).
//! The importer runs the gltf crate under `catch_unwind` (it panics on some malformed
//! files, e.g. an overflow in its GLB header parsing): such a panic, caught and turned into
//! an error, is not a crash here either ([`common::tolerate_caught_panics`]).
//! Seed with the `.glb` and `.gltf` files of `../shared/models/gltf` and the exports of
//! `nusselt render … --export-gltf`.
#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use nusselt::scene::LoadOptions;

fuzz_target!(|data: &[u8]| {
    common::tolerate_caught_panics();
    let dir = common::scratch();
    let opts = LoadOptions::default();
    if let Ok(scene) = nusselt::scene::gltf::from_slice(data, "fuzz.glb", &dir, &opts) {
        common::solve_and_render(scene);
    }
});
