//! An OBJ, its MTL and a texture image, as files (the loader resolves `map_Kd`/`map_d`
//! paths on disk and decodes the image) → load → mesh → 3 shots → an 8 × 8 render.
//!
//! Input: OBJ text, NUL, MTL text, NUL, image bytes, written as `s.obj`, `m.mtl` and
//! `t.png` (any `mtllib`, `map_Kd` or `map_d` naming another file finds it missing: a
//! warning or an error, both fine). Seed with OBJs whose MTL names `t.png`.
#![no_main]

#[path = "common.rs"]
mod common;

use libfuzzer_sys::fuzz_target;
use nusselt::scene::{LoadOptions, Scene};

fuzz_target!(|data: &[u8]| {
    let mut parts = data.splitn(3, |b| *b == 0);
    let (Some(obj), Some(mtl), Some(image)) = (parts.next(), parts.next(), parts.next()) else {
        return;
    };
    let dir = common::scratch();
    let written = std::fs::write(dir.join("s.obj"), obj)
        .and_then(|()| std::fs::write(dir.join("m.mtl"), mtl))
        .and_then(|()| std::fs::write(dir.join("t.png"), image));
    if written.is_err() {
        return;
    }
    if let Ok(scene) = Scene::load_obj(&dir.join("s.obj"), &LoadOptions::default()) {
        common::solve_and_render(scene);
    }
});
