//! OBJ/MTL text → load → mesh → a few shots → a tiny render. Nothing may panic; errors
//! returned by the library are fine.
//!
//! Input: the OBJ text, optionally followed by a NUL byte and the text of the MTL library
//! `m.mtl` (any `mtllib` names another file, which is then missing: an error, also fine).
#![no_main]

use std::sync::atomic::AtomicBool;

use libfuzzer_sys::fuzz_target;
use nusselt::render::{self, RenderSettings, SolutionView};
use nusselt::scene::{LoadOptions, Scene};
use nusselt::solver::{ProgressiveSolver, SolverConfig, StopCriteria};

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
        let Ok(scene) = Scene::from_obj_str("fuzz.obj", &obj, &[("m.mtl", &mtl)], &opts) else {
            return;
        };
        // Coarse sizes relative to the scene, as a user's `--element-size` would be.
        let d = scene.bounds().diagonal();
        let config = SolverConfig {
            element_size: Some(d / 6.0),
            patch_size: Some(d / 3.0),
            ..Default::default()
        };
        let Ok(mut s) = ProgressiveSolver::new(scene, config) else {
            return;
        };
        s.run(
            &StopCriteria {
                unshot: 0.0,
                max_shots: Some(3),
                max_seconds: None,
            },
            &AtomicBool::new(false),
            &mut |_| {},
        );
        let radiance = s.element_radiance(true);
        assert!(radiance.iter().all(|b| b.is_finite() && b.min_element() >= 0.0));
        let vertex = s.mesh().vertex_values(&radiance);
        let bvh = render::display_bvh(s.scene(), s.mesh());
        let view = SolutionView {
            scene: s.scene(),
            mesh: s.mesh(),
            vertex_radiance: &vertex,
            bvh: &bvh,
        };
        let img = render::render_solution(
            &view,
            &RenderSettings {
                width: 8,
                height: 8,
                spp: 1,
                camera: s.scene().default_camera(),
                seed: 1,
            },
        );
        assert!(img.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
    }
});
