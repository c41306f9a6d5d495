//! `render --pass`: which second pass makes the image from the solution, and `auto` (the
//! default): the most accurate pass whose estimated time fits what is left of the time the
//! user gives (`--time-budget`, whole run, default [`DEFAULT_TIME_BUDGET`]).
//!
//! Why these two: on the Cornell box the direct pass (exact direct light per pixel) is the
//! most accurate (1.39 % against the path-traced reference at the default mesh,
//! `docs/BENCHMARKS.md`), then the vertex pass (1.69 %); the final gather at its default 64
//! rays is noisier than either (6.0 %), so `auto` never picks it. The vertex pass costs a fraction of a second at
//! any size and is the fallback. The direct pass's cost grows with the pixels and the light
//! faces, so it is measured, not guessed: its per-solution work (indirect vertex radiance,
//! display BVH, lights) is done once, then a probe renders 1/16 of the pixels (a quarter of
//! the width and height, same camera and samples) and its time is scaled by 16. Known error
//! of the estimate: the probe's pixels are larger, so more of them straddle edges and get
//! edge samples; it overestimates a little, so a run chosen to fit does fit, and one near
//! the limit may get the vertex pass.

use std::time::Instant;

use anyhow::{Result, bail};

use nusselt_core::render::{self, Image, Pass, RenderSettings};
use nusselt_core::scene::Rgb;
use nusselt_core::solver::Problem;

/// Seconds a whole `render` run may take (load to image) when `--time-budget` is not given.
pub const DEFAULT_TIME_BUDGET: f64 = 10.0;
/// The probe renders 1/`PROBE_SCALE`² of the pixels.
const PROBE_SCALE: u32 = 4;

/// What `--pass` and `--time-budget` ask for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PassChoice {
    Fixed(Pass),
    /// The most accurate pass that fits in `budget` seconds of the whole run.
    Auto {
        budget: f64,
    },
}

/// Reads `--pass` and `--time-budget` (checked before any work).
pub fn parse_pass(name: &str, budget: Option<f64>) -> Result<PassChoice> {
    if let Some(b) = budget
        && !(b.is_finite() && b > 0.0)
    {
        bail!("--time-budget must be a positive number of seconds, got {b}");
    }
    if name == "auto" {
        return Ok(PassChoice::Auto {
            budget: budget.unwrap_or(DEFAULT_TIME_BUDGET),
        });
    }
    let Some(fixed) = Pass::parse(name) else {
        bail!("unknown --pass '{name}' (expected auto, vertex, direct or gather)");
    };
    if budget.is_some() {
        bail!("--time-budget chooses the pass of --pass auto; it does nothing with --pass {name}");
    }
    Ok(PassChoice::Fixed(fixed))
}

impl PassChoice {
    /// `auto`'s budget no longer than `seconds`, the whole command's time, when given.
    pub fn within(self, seconds: Option<f64>) -> PassChoice {
        match (self, seconds) {
            (PassChoice::Auto { budget }, Some(s)) => PassChoice::Auto {
                budget: budget.min(s),
            },
            (choice, _) => choice,
        }
    }
}

/// The pass chosen, and for `auto` the direct pass's estimated seconds and the budget.
pub struct Chosen {
    pub pass: Pass,
    pub estimate: Option<f64>,
    pub budget: Option<f64>,
}

impl Chosen {
    /// One line for the user: what was chosen and why.
    pub fn describe(&self) -> Option<String> {
        let budget = self.budget?;
        let Some(estimate) = self.estimate else {
            return Some(format!(
                "pass: vertex (the solve used the whole {budget} s budget; --time-budget or --pass direct for the direct pass)"
            ));
        };
        Some(match self.pass {
            Pass::Direct => format!(
                "pass: direct (about {estimate:.1} s, within the {budget} s budget; --pass vertex is faster)"
            ),
            _ => format!(
                "pass: vertex (the direct pass would take about {estimate:.1} s, past the {budget} s budget; --time-budget or --pass direct to have it)"
            ),
        })
    }
}

/// Renders the image `choice` asks for after the solve (`started`: the run's start;
/// `gather_rays`: for `--pass gather`): for `auto`, the direct pass's per-solution work is
/// done once, a probe of 1/16 of the pixels is timed, and the direct pass is taken when the
/// run so far plus the probe's time scaled to the image fits the budget; when the run so
/// far has used the budget already, the vertex pass without a probe.
pub fn render_chosen(
    choice: PassChoice,
    started: Instant,
    problem: &Problem,
    radiance: &[Rgb],
    settings: &RenderSettings,
    gather_rays: u32,
) -> (Chosen, Image) {
    let budget = match choice {
        PassChoice::Fixed(pass) => {
            let image = pass.render(problem, radiance, settings, gather_rays);
            let chosen = Chosen {
                pass,
                estimate: None,
                budget: None,
            };
            return (chosen, image);
        }
        PassChoice::Auto { budget } => budget,
    };
    // Preparing the direct pass computes every light patch's form-factor row: minutes on a
    // large mesh, so not even tried once the budget is spent.
    if started.elapsed().as_secs_f64() >= budget {
        let image = Pass::Vertex.render(problem, radiance, settings, gather_rays);
        let chosen = Chosen {
            pass: Pass::Vertex,
            estimate: None,
            budget: Some(budget),
        };
        return (chosen, image);
    }
    let direct = render::direct::Prepared::new(problem, radiance);
    let probe = RenderSettings {
        width: settings.width.div_ceil(PROBE_SCALE),
        height: settings.height.div_ceil(PROBE_SCALE),
        ..*settings
    };
    let probe_start = Instant::now();
    direct.render(&probe);
    let scale = (settings.width as f64 * settings.height as f64)
        / (probe.width as f64 * probe.height as f64);
    let estimate = probe_start.elapsed().as_secs_f64() * scale;
    let fits = started.elapsed().as_secs_f64() + estimate <= budget;
    let (pass, image) = if fits {
        (Pass::Direct, direct.render(settings))
    } else {
        drop(direct);
        let image = Pass::Vertex.render(problem, radiance, settings, gather_rays);
        (Pass::Vertex, image)
    };
    let chosen = Chosen {
        pass,
        estimate: Some(estimate),
        budget: Some(budget),
    };
    (chosen, image)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_and_budget_are_read_together() {
        assert_eq!(
            parse_pass("auto", None).expect("auto"),
            PassChoice::Auto {
                budget: DEFAULT_TIME_BUDGET
            }
        );
        assert_eq!(
            parse_pass("auto", Some(2.5)).expect("auto"),
            PassChoice::Auto { budget: 2.5 }
        );
        assert_eq!(
            parse_pass("direct", None).expect("direct"),
            PassChoice::Fixed(Pass::Direct)
        );
        for (name, budget, message) in [
            ("photon", None, "unknown --pass 'photon'"),
            ("vertex", Some(3.0), "does nothing with --pass vertex"),
            ("auto", Some(0.0), "--time-budget must be a positive"),
            ("auto", Some(f64::NAN), "--time-budget must be a positive"),
        ] {
            let e = parse_pass(name, budget).expect_err(name).to_string();
            assert!(e.contains(message), "{name} {budget:?}: {e}");
        }
    }
}
