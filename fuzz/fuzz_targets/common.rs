//! What every target does with a scene that loaded: mesh it coarsely (relative to its size,
//! as a user's `--element-size` would be), shoot 3 times and render 8 × 8 pixels. Errors
//! returned by the library are fine; a panic, a NaN or a negative radiance is a crash.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use nusselt::mesh::MeshSpec;
use nusselt::render::{self, RenderSettings, SolutionView};
use nusselt::scene::Scene;
use nusselt::solver::{ProgressiveSolver, SolverConfig, StopCriteria};

/// Replaces libFuzzer's panic hook (which aborts at once) with a silent one, so that a
/// panic the library catches and reports as an error is not counted as a crash; a panic
/// that reaches the target still aborts (libfuzzer-sys catches it at the target's edge).
#[allow(dead_code)] // only the targets whose loaders catch panics
pub fn tolerate_caught_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| std::panic::set_hook(Box::new(|_| {})));
}

/// A folder of this process's own for the files a target writes (loaders read files).
#[allow(dead_code)] // obj_solve loads from memory
pub fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nusselt-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    dir
}

pub fn solve_and_render(scene: Scene) {
    let d = scene.bounds().diagonal();
    let config = SolverConfig {
        mesh: MeshSpec::sized(d / 6.0, d / 3.0),
        ..Default::default()
    };
    let Ok(mut s) = ProgressiveSolver::new(scene, config) else {
        return;
    };
    s.run(
        &StopCriteria {
            residual: 0.0,
            max_steps: Some(3),
            max_seconds: None,
            tolerance: None,
        },
        &AtomicBool::new(false),
        &mut |_| {},
    );
    let radiance = s.display_radiance();
    assert!(radiance.iter().all(|b| b.is_finite() && b.min_element() >= 0.0));
    let vertex = s.mesh().vertex_values(&radiance);
    let bvh = render::display_bvh(s.scene(), s.mesh());
    let view = SolutionView {
        scene: s.scene(),
        mesh: s.mesh(),
        vertex_radiance: &vertex,
        bvh: &bvh,
        texture: s.problem().element_texture(),
    };
    let img = render::render_solution(
        &view,
        &RenderSettings {
            width: 8,
            height: 8,
            spp: 1,
            camera: render::view::default_camera(s.scene()),
            seed: 1,
            edge_spp: 0,
        },
    );
    assert!(img.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
}
