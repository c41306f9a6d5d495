//! OBJ/MTL text → load → mesh → a few shots → a tiny render. Nothing may panic; errors
//! returned by the library are fine.
//!
//! Input: the OBJ text, optionally followed by a NUL byte and the text of the MTL library
//! `m.mtl` (any `mtllib` names another file, which is then missing: an error, also fine).
#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use nusselt::scene::{LoadOptions, Scene};

const DEFAULT_MTL: &str = "newmtl light\nKd 0.5 0.5 0.5\nKe 4 4 4\nnewmtl grey\nKd 0.7 0.7 0.7\n";

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = match data.iter().position(|b| *b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, DEFAULT_MTL.as_bytes()),
    };
    let obj = String::from_utf8_lossy(obj);
    let mtl = String::from_utf8_lossy(mtl);
    for two_sided in [false, true] {
        let opts = LoadOptions {
            two_sided,
            ..Default::default()
        };
        if let Ok(scene) = Scene::from_obj_str("fuzz.obj", &obj, &[("m.mtl", &mtl)], &opts) {
            common::solve_and_render(scene);
        }
    }
});
