//! `render --pass`: which second pass makes the image from the solution, and `auto` (the
//! default): the most accurate pass whose cost fits.
//!
//! Why these two: on the Cornell box the direct pass (exact direct light per pixel) is the
//! most accurate (1.39 % against the path-traced reference at the default mesh,
//! `docs/BENCHMARKS.md`), then the vertex pass (1.69 %); the final gather at its default 64
//! rays is noisier than either (6.0 %), so `auto` never picks it. The vertex pass costs a
//! fraction of a second at any size and is the fallback.
//!
//! The direct pass's cost is counted, not timed, so that the same command on the same input
//! makes the same image on an idle machine and a loaded one (a clock made the VeachAjar
//! model 16.0 % or 23.2 % from its reference, by the machine's load): its preparation
//! computes a form-factor row per light patch (light patches × elements form factors), then
//! a probe renders 1/16 of the pixels (a quarter of the width and height, same camera and
//! samples) and its work in light evaluations ([`render::direct::DirectLight::work`]) is
//! scaled by 16. The two counts become seconds at fixed rates, the slowest measured on the
//! 2-core machine the figures come from (`render --time-budget 1000`, 256², release,
//! 2026-12-05): preparation 0.6–2.0 M light form factors a second (gallery, Cornell box,
//! VeachAjar), pixels 1.5–3.8 M light evaluations a second (Dabrovic atrium, bijoutier,
//! Cornell variants, water Cornell box, gallery, VeachAjar); the direct pass is taken when
//! the total is at most [`DEFAULT_TIME_BUDGET`] seconds. So the estimate errs long, by up
//! to 2.5× on the fastest scenes; the probe's larger pixels straddle more edges and get
//! more edge samples, another small overestimate.
//!
//! With `--time-budget S` (or `--seconds S`, the whole command) the user asks for time:
//! then the probe is timed and the direct pass taken when the run so far plus the probe's
//! time scaled to the image fits S, as a deadline must; the preparation is not started
//! when its counted cost passes what is left, nor the probe when a smaller scout's time
//! says the probe alone cannot fit (the atrium: preparation 11 s, probe 150 s, pass 40 min).

use std::time::Instant;

use anyhow::{Result, bail};

use nusselt_core::render::{self, Image, Pass, RenderSettings};
use nusselt_core::scene::Rgb;
use nusselt_core::solver::Problem;

/// Seconds the counted limits stand for (what the direct pass may take by default).
pub const DEFAULT_TIME_BUDGET: f64 = 10.0;
/// Light form factors a second of the direct pass's preparation computes: the slowest
/// rate measured (module docs), so that the estimate errs long.
const PREP_PER_SECOND: f64 = 5e5;
/// Light evaluations a second of the direct pass's pixels makes: the slowest rate
/// measured (module docs).
const PIXEL_PER_SECOND: f64 = 1.5e6;
/// The probe renders 1/`PROBE_SCALE`² of the pixels.
const PROBE_SCALE: u32 = 4;
/// With a time budget, a scout of 1/`SCOUT_SCALE`² of the pixels is timed first, and the
/// probe runs only if the scout says the probe itself fits ([`timed`]).
const SCOUT_SCALE: u32 = 16;

/// What `--pass` and `--time-budget` ask for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PassChoice {
    Fixed(Pass),
    /// The most accurate pass whose counted cost is within the limits (`budget: None`), or
    /// that fits in `budget` seconds of the whole run, timed.
    Auto {
        budget: Option<f64>,
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
        return Ok(PassChoice::Auto { budget });
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
                budget: Some(budget.map_or(s, |b| b.min(s))),
            },
            (choice, _) => choice,
        }
    }
}

/// The pass chosen, and for `auto` the direct pass's estimated seconds, the budget when
/// one was given, the counted work, and why.
pub struct Chosen {
    pub pass: Pass,
    pub estimate: Option<f64>,
    pub budget: Option<f64>,
    /// Counted: the preparation's form factors and the pixels' light evaluations (the
    /// latter estimated from the probe; `None` where no probe ran).
    pub work: Option<(f64, Option<f64>)>,
    reason: Option<String>,
}

impl Chosen {
    fn fixed(pass: Pass) -> Chosen {
        Chosen {
            pass,
            estimate: None,
            budget: None,
            work: None,
            reason: None,
        }
    }

    /// `auto`'s choice after a probe: the direct pass where it `fits`.
    fn decided(
        fits: bool,
        estimate: f64,
        budget: Option<f64>,
        (prep, pixels): (f64, f64),
        reason: String,
    ) -> Chosen {
        Chosen {
            pass: if fits { Pass::Direct } else { Pass::Vertex },
            estimate: Some(estimate),
            budget,
            work: Some((prep, Some(pixels))),
            reason: Some(reason),
        }
    }

    /// One line for the user: what `auto` chose and why.
    pub fn describe(&self) -> Option<String> {
        self.reason.clone()
    }
}

/// Renders the image `choice` asks for after the solve (`started`: the run's start;
/// `gather_rays`: for `--pass gather`); for `auto` by counted work ([`counted`]) or, with
/// a budget in seconds, by time ([`timed`]).
pub fn render_chosen(
    choice: PassChoice,
    started: Instant,
    problem: &Problem,
    radiance: &[Rgb],
    settings: &RenderSettings,
    gather_rays: u32,
) -> (Chosen, Image) {
    match choice {
        PassChoice::Fixed(pass) => {
            let image = pass.render(problem, radiance, settings, gather_rays);
            (Chosen::fixed(pass), image)
        }
        PassChoice::Auto { budget: None } => counted(problem, radiance, settings),
        PassChoice::Auto {
            budget: Some(budget),
        } => timed(budget, started, problem, radiance, settings),
    }
}

/// Form factors the direct pass's preparation computes: a row per light patch.
fn prep_work(problem: &Problem) -> f64 {
    let lights = problem
        .mesh
        .patches
        .iter()
        .filter(|p| problem.scene.materials[p.material.0 as usize].emission != Rgb::ZERO)
        .count();
    lights as f64 * problem.mesh.elements.len() as f64
}

/// The vertex pass, with `reason`.
fn vertex(
    problem: &Problem,
    radiance: &[Rgb],
    settings: &RenderSettings,
    chosen: Chosen,
) -> (Chosen, Image) {
    let image = Pass::Vertex.render(problem, radiance, settings, 0);
    (chosen, image)
}

/// `auto` without a time: the direct pass when its counted work, at the measured rates,
/// takes at most [`DEFAULT_TIME_BUDGET`] seconds; the same choice on any machine.
fn counted(problem: &Problem, radiance: &[Rgb], settings: &RenderSettings) -> (Chosen, Image) {
    let prep = prep_work(problem);
    let prep_seconds = prep / PREP_PER_SECOND;
    if prep_seconds > DEFAULT_TIME_BUDGET {
        let chosen = Chosen {
            pass: Pass::Vertex,
            estimate: Some(prep_seconds),
            budget: None,
            work: Some((prep, None)),
            reason: Some(format!(
                "pass: vertex (the direct pass would first compute {prep:.2e} light form factors, about {prep_seconds:.0} s on the reference machine, past its {DEFAULT_TIME_BUDGET} s; --pass direct to have it)"
            )),
        };
        return vertex(problem, radiance, settings, chosen);
    }
    let direct = render::direct::Prepared::new(problem, radiance);
    let (_, pixels) = run_probe(&direct, settings, PROBE_SCALE);
    let estimate = prep_seconds + pixels / PIXEL_PER_SECOND;
    let fits = estimate <= DEFAULT_TIME_BUDGET;
    let reason = if fits {
        format!(
            "pass: direct ({pixels:.2e} light evaluations, about {estimate:.1} s on the reference machine, within {DEFAULT_TIME_BUDGET} s; --pass vertex is faster)"
        )
    } else {
        format!(
            "pass: vertex (the direct pass would take {pixels:.2e} light evaluations, about {estimate:.0} s on the reference machine, past {DEFAULT_TIME_BUDGET} s; --pass direct to have it)"
        )
    };
    let chosen = Chosen::decided(fits, estimate, None, (prep, pixels), reason);
    finish(direct, chosen, problem, radiance, settings)
}

/// The image of the pass `chosen` names: the prepared direct pass, or the vertex pass.
fn finish(
    direct: render::direct::Prepared,
    chosen: Chosen,
    problem: &Problem,
    radiance: &[Rgb],
    settings: &RenderSettings,
) -> (Chosen, Image) {
    if chosen.pass == Pass::Direct {
        let image = direct.render(settings);
        (chosen, image)
    } else {
        drop(direct);
        vertex(problem, radiance, settings, chosen)
    }
}

/// A probe: 1/`scale`² of the pixels, same camera and samples.
fn probe_settings(settings: &RenderSettings, scale: u32) -> RenderSettings {
    RenderSettings {
        width: settings.width.div_ceil(scale),
        height: settings.height.div_ceil(scale),
        ..*settings
    }
}

/// Renders 1/`scale`² of the pixels with `direct` ([`probe_settings`]): its seconds and
/// light evaluations, each scaled to the whole image.
fn run_probe(
    direct: &render::direct::Prepared,
    settings: &RenderSettings,
    scale: u32,
) -> (f64, f64) {
    let probe = probe_settings(settings, scale);
    let (work_before, start) = (direct.work(), Instant::now());
    direct.render(&probe);
    let to_image = pixel_scale(settings, &probe);
    let seconds = start.elapsed().as_secs_f64() * to_image;
    (seconds, (direct.work() - work_before) as f64 * to_image)
}

/// Pixels of the image over pixels of the probe.
fn pixel_scale(settings: &RenderSettings, probe: &RenderSettings) -> f64 {
    (settings.width as f64 * settings.height as f64) / (probe.width as f64 * probe.height as f64)
}

/// `auto` with a time: the direct pass when the run so far plus the probe's time scaled to
/// the image fits `budget`. Nothing that could not fit is started: when the preparation's
/// counted cost (at the slowest rate, [`PREP_PER_SECOND`]) passes what is left, the vertex
/// pass without preparing (every light patch's row: minutes on a large mesh); and a scout
/// of 1/[`SCOUT_SCALE`]² of the pixels is timed before the probe, which runs only where the
/// scout says it fits: its 1/16 of the image would otherwise take minutes where the direct
/// pass takes hours (the atrium's two lights are 960 sphere facets, each clipped per
/// sample). So the run passes its budget by at most the scout.
fn timed(
    budget: f64,
    started: Instant,
    problem: &Problem,
    radiance: &[Rgb],
    settings: &RenderSettings,
) -> (Chosen, Image) {
    let prep = prep_work(problem);
    let prep_seconds = prep / PREP_PER_SECOND;
    let left = budget - started.elapsed().as_secs_f64();
    if left <= 0.0 || prep_seconds > left {
        let why = if left <= 0.0 {
            format!("the solve used the whole {budget} s budget")
        } else {
            format!(
                "the direct pass would first compute {prep:.2e} light form factors, up to {prep_seconds:.0} s, past the {left:.1} s left of the {budget} s budget"
            )
        };
        let chosen = Chosen {
            budget: Some(budget),
            work: Some((prep, None)),
            reason: Some(format!(
                "pass: vertex ({why}; --time-budget or --pass direct for the direct pass)"
            )),
            ..Chosen::fixed(Pass::Vertex)
        };
        return vertex(problem, radiance, settings, chosen);
    }
    let direct = render::direct::Prepared::new(problem, radiance);
    // The scout, then the probe unless the scout says the probe alone would pass the
    // budget. The choice is the probe's where it ran (the scout's larger pixels straddle
    // more edges: it errs long).
    let scout = run_probe(&direct, settings, SCOUT_SCALE);
    let probe_seconds = scout.0 / pixel_scale(settings, &probe_settings(settings, PROBE_SCALE));
    let (estimate, pixels) = if started.elapsed().as_secs_f64() + probe_seconds > budget {
        scout
    } else {
        run_probe(&direct, settings, PROBE_SCALE)
    };
    let fits = started.elapsed().as_secs_f64() + estimate <= budget;
    let reason = if fits {
        format!(
            "pass: direct (about {estimate:.1} s, within the {budget} s budget; --pass vertex is faster)"
        )
    } else {
        format!(
            "pass: vertex (the direct pass would take about {estimate:.1} s, past the {budget} s budget; --time-budget or --pass direct to have it)"
        )
    };
    let chosen = Chosen::decided(fits, estimate, Some(budget), (prep, pixels), reason);
    finish(direct, chosen, problem, radiance, settings)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_and_budget_are_read_together() {
        assert_eq!(
            parse_pass("auto", None).expect("auto"),
            PassChoice::Auto { budget: None }
        );
        assert_eq!(
            parse_pass("auto", Some(2.5)).expect("auto"),
            PassChoice::Auto { budget: Some(2.5) }
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
