//! What `nusselt render` reports once the image is written: the JSON summary line
//! (`--json`) or the lines on stderr.

use nusselt_core::formfactor::FormFactorMethod;
use nusselt_core::scene::{Camera, Rgb};
use nusselt_core::solver::{Problem, Solver, StopCriteria};

use super::pass::Chosen;
use super::render::RenderArgs;

/// What the report needs from the solver, kept when the solver's working memory (links,
/// rows, hierarchy) goes before the render builds its own.
pub(super) struct Solved {
    /// Per element: the display radiance, or the radiosity alone with `--no-ambient`.
    pub radiance: Vec<Rgb>,
    pub steps: usize,
    pub residual: f64,
    pub name: &'static str,
    pub report: String,
    pub matrix_bytes: usize,
    /// Mesh and BVH set-up, by stage.
    pub setup_seconds: Vec<(&'static str, f64)>,
}

impl Solved {
    /// The problem and what the report needs; the solver (and its rows) is dropped.
    pub fn take(solver: Box<dyn Solver>, no_ambient: bool) -> (Problem, Solved) {
        let radiance = if no_ambient {
            solver.radiosity().to_vec()
        } else {
            solver.display_radiance()
        };
        let solved = Solved {
            radiance,
            steps: solver.steps(),
            residual: solver.residual(),
            name: solver.name(),
            report: solver.report(),
            matrix_bytes: solver.matrix_bytes(),
            setup_seconds: solver.problem().setup_seconds.clone(),
        };
        (solver.into_parts().0, solved)
    }
}

/// One run's figures.
pub(super) struct Report<'a> {
    pub problem: &'a Problem,
    pub solved: &'a Solved,
    pub camera: &'a Camera,
    /// Auto's reason, when auto chose the solver.
    pub auto_reason: Option<String>,
    pub chosen: &'a Chosen,
    pub method: FormFactorMethod,
    /// The GPU adapter of `gpu-hemicube`.
    pub adapter: Option<String>,
    pub load_seconds: f64,
    pub solve_seconds: f64,
    pub render_seconds: f64,
    pub exposure: f64,
    pub total_seconds: f64,
    /// Relative RMS error against `--reference`.
    pub error: Option<f64>,
}

impl Report<'_> {
    /// The `--json` line.
    pub fn summary(&self) -> serde_json::Value {
        let (problem, solved, camera) = (self.problem, self.solved, self.camera);
        let setup: serde_json::Map<String, serde_json::Value> = solved
            .setup_seconds
            .iter()
            .map(|(k, v)| (k.to_string(), serde_json::json!(v)))
            .collect();
        serde_json::json!({
            "elements": problem.mesh.elements.len(),
            "patches": problem.mesh.patches.len(),
            "faces": problem.scene.faces.len(),
            "element_size": problem.mesh.element_size,
            "patch_size": problem.mesh.patch_size,
            "camera": [
                camera.eye.x, camera.eye.y, camera.eye.z,
                camera.target.x, camera.target.y, camera.target.z,
                camera.vfov_deg
            ],
            "vertices": problem.mesh.vertices.len(),
            "shots": solved.steps,
            "solver": solved.name,
            "solver_auto": self.auto_reason,
            "solver_report": solved.report,
            "matrix_bytes": solved.matrix_bytes,
            "load_seconds": self.load_seconds,
            "setup_seconds": setup,
            "solve_seconds": self.solve_seconds,
            "pass": self.chosen.pass.name(),
            "pass_estimate_seconds": self.chosen.estimate,
            "pass_work": self.chosen.work.map(|(prep, pixels)| serde_json::json!({"light_form_factors": prep, "light_evaluations": pixels})),
            "time_budget": self.chosen.budget,
            "render_seconds": self.render_seconds,
            "exposure": self.exposure,
            "total_seconds": self.total_seconds,
            "unshot_fraction": solved.residual,
            "error": self.error,
            "method": self.method.name(),
            "rasteriser": self.adapter,
            // Mirrors and glass traced by the eye pass (render::specular); caustics not included.
            "specular": problem.scene.has_specular(),
        })
    }

    /// The lines on stderr: counts and times, the solver's report, what `--seconds` cut,
    /// the pass chosen, the specular note. `before_solve`: seconds from the start to the
    /// solve (loading).
    pub fn print(&self, args: &RenderArgs, stop: &StopCriteria, before_solve: f64) {
        let (problem, solved) = (self.problem, self.solved);
        eprintln!(
            "{} elements, {} shots, unshot {:.2e}, solve {:.3} s, render {:.3} s{}; wrote {}",
            problem.mesh.elements.len(),
            solved.steps,
            solved.residual,
            self.solve_seconds,
            self.render_seconds,
            self.error
                .map(|e| format!(", image error {:.2} %", e * 100.0))
                .unwrap_or_default(),
            args.out.display()
        );
        if !solved.report.is_empty() {
            eprintln!("{}: {}", solved.name, solved.report);
        }
        if let Some(total) = args.seconds {
            let setup_total: f64 = solved.setup_seconds.iter().map(|(_, v)| v).sum();
            eprintln!(
                "--seconds {total}: load and mesh {:.1} s, solve {:.1} s (stopped at {} with unshot {:.2e}), render {:.1} s",
                before_solve + setup_total,
                self.solve_seconds - setup_total,
                if stop.max_seconds.is_some_and(|m| m <= 0.0) {
                    "once loading and meshing had used the time".to_string()
                } else {
                    format!("{} steps", solved.steps)
                },
                solved.residual,
                self.render_seconds
            );
        }
        if let Some(line) = self.chosen.describe() {
            eprintln!("{line}");
        }
        if problem.scene.has_specular() {
            eprintln!(
                "mirrors and glass traced by the eye pass onto the diffuse solution; light they \
                 throw onto diffuse surfaces (caustics) is not included (docs/SPECULAR.md)"
            );
        }
    }
}
