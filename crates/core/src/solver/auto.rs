//! `--solver auto`: the solver chosen for a meshed scene and the run asked for, with the
//! reason in one line (printed by `render`, shown in the viewer's panel).
//!
//! Measured on this project's 2-core machine (README "Large scenes"): the Cornell box at
//! 20,000 elements converges by shooting to 1 % image error in about 15 s, while on the
//! 263 k-triangle Crytek atrium (227 k elements) shooting leaves 7.6 % unshot after 60 s
//! and hierarchical radiosity converges (residual 4.5e-5) in 82 s: each shot costs a row
//! of form factors to every element, so shooting's cost follows the triangles, while the
//! hierarchy's links follow the light. Shooting stays the choice wherever an image is
//! wanted before the end (the viewer, a `--seconds` limit): it improves with every shot,
//! where the hierarchy shows nothing before its refinement ends. The viewer then hands such
//! a scene over to the hierarchy once most of the light is spread ([`super::handoff`]).
//!
//! Below 100,000 elements what decides is how far the light spreads: a shot costs a row of
//! form factors to every element, and where a sky or many lit surfaces spread the light
//! every patch has to shoot, so converging costs at least patches × elements form factors.
//! Measured with default flags (`render --solver S --pass vertex --json`, release,
//! 2026-12-05; solve seconds to a residual of 1e-4, shooting / hierarchical): VeachAjar
//! (1.6e7 pairs) 3.2 / 4.2, the water Cornell box (1.7e7) 7.5 / 2.7, the Cornell box
//! (2.2e7) 5.8 / 3.7 but 1.78 % / 2.05 % from its reference, the bijoutier shop (8.2e7)
//! 24.2 / 5.1, the Dabrovic atrium (3.3e8) over 150 / 9.1, the Šibenik cathedral (7.1e8)
//! 300 / 16. Hence [`HIERARCHICAL_FROM_PAIRS`].

use super::{OptionSet, Problem, SolverKind};

/// Elements above which a run without a time limit is solved hierarchically.
pub const HIERARCHICAL_FROM_ELEMENTS: usize = 100_000;

/// Patch × element pairs (the form factors of every patch shooting once) above which a run
/// without a time limit is solved hierarchically, at any element count (module docs).
pub const HIERARCHICAL_FROM_PAIRS: f64 = 5e7;

/// What the run asks of the solver, besides the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RunShape {
    /// An image is wanted while solving (the viewer) or by a deadline (`--seconds`).
    pub progressive_image: bool,
    /// The solver options given (`--link-tolerance`, `--formfactor`, …): auto chooses a
    /// solver that reads them all (a hierarchy for `--link-tolerance`, shooting for a
    /// form-factor method), as if the user had named it.
    pub given: OptionSet,
}

/// The solvers `auto` chooses between.
pub const CANDIDATES: [SolverKind; 2] = [SolverKind::Shooting, SolverKind::Hierarchical];

/// Refuses options that neither of auto's [`CANDIDATES`] reads both with, as a message
/// naming the first such flag (`--omega` belongs to `sor`, which auto never picks).
pub fn check_given(given: OptionSet) -> Result<(), String> {
    if CANDIDATES.iter().any(|k| k.reads_all(given)) {
        return Ok(());
    }
    if let Some(unread) = given
        .iter()
        .find(|o| !CANDIDATES.iter().any(|k| k.reads(*o)))
    {
        return Err(super::registry::unread_message(
            unread,
            "auto (shooting or hierarchical)",
        ));
    }
    let flags: Vec<&str> = given.iter().map(|o| o.flag()).collect();
    Err(format!(
        "{} are settings of different solvers (none reads them all): choose one with --solver",
        flags.join(" and ")
    ))
}

/// The solver `auto` stands for on `problem`, and why.
pub fn choose(problem: &Problem, run: RunShape) -> (SolverKind, String) {
    let n = problem.mesh.elements.len();
    if !run.given.is_empty()
        && let Some(kind) = CANDIDATES.iter().find(|k| k.reads_all(run.given))
        && !CANDIDATES.iter().all(|k| k.reads_all(run.given))
    {
        let flags: Vec<&str> = run.given.iter().map(|o| o.flag()).collect();
        return (
            *kind,
            format!("{}: {} is its setting", kind.name(), flags.join(" and ")),
        );
    }
    let patches = problem.mesh.patches.len();
    let pairs = n as f64 * patches as f64;
    if n <= HIERARCHICAL_FROM_ELEMENTS && pairs <= HIERARCHICAL_FROM_PAIRS {
        return (
            SolverKind::Shooting,
            format!(
                "shooting: {n} elements (at most {HIERARCHICAL_FROM_ELEMENTS}) and {patches} patches, where progressive refinement converges in seconds and shows every shot"
            ),
        );
    }
    if run.progressive_image {
        return (
            SolverKind::Shooting,
            format!(
                "shooting: {n} elements, but an image is wanted before the end (viewer or --seconds) and shooting improves with every shot; hierarchical shows nothing before its refinement ends"
            ),
        );
    }
    if n <= HIERARCHICAL_FROM_ELEMENTS {
        return (
            SolverKind::Hierarchical,
            format!(
                "hierarchical: {n} elements × {patches} patches = {pairs:.1e} form factors for every patch to shoot once (more than {HIERARCHICAL_FROM_PAIRS:.0e}): its links follow the light"
            ),
        );
    }
    (
        SolverKind::Hierarchical,
        format!(
            "hierarchical: {n} elements (more than {HIERARCHICAL_FROM_ELEMENTS}): its links follow the light, where every shot would cost a row of {n} form factors"
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSpec;
    use crate::scene::{LoadOptions, Scene};
    use crate::solver::{SolverConfig, SolverOption};

    fn cornell(max_elements: usize) -> Problem {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec {
                max_elements: Some(max_elements),
                ..Default::default()
            },
            ..Default::default()
        };
        Problem::new(scene, config).expect("problem")
    }

    #[test]
    fn small_scenes_shoot_and_large_ones_build_a_hierarchy_unless_watched() {
        let small = cornell(2_000);
        let (kind, why) = choose(&small, RunShape::default());
        assert_eq!(kind, SolverKind::Shooting, "{why}");
        assert!(
            why.contains(&small.mesh.elements.len().to_string()),
            "{why}"
        );
        // Under the element limit but with more pairs than the limit: 40 k elements in
        // about 2,500 patches of 16 elements.
        let spread = cornell(40_000);
        let pairs = spread.mesh.elements.len() as f64 * spread.mesh.patches.len() as f64;
        assert!(spread.mesh.elements.len() <= HIERARCHICAL_FROM_ELEMENTS);
        assert!(pairs > HIERARCHICAL_FROM_PAIRS, "{pairs}");
        let (kind, why) = choose(&spread, RunShape::default());
        assert_eq!(kind, SolverKind::Hierarchical, "{why}");
        assert!(why.contains("patches"), "{why}");
        let large = cornell(2 * HIERARCHICAL_FROM_ELEMENTS);
        assert!(large.mesh.elements.len() > HIERARCHICAL_FROM_ELEMENTS);
        assert_eq!(
            choose(&large, RunShape::default()).0,
            SolverKind::Hierarchical
        );
        let watched = RunShape {
            progressive_image: true,
            ..Default::default()
        };
        assert_eq!(choose(&large, watched).0, SolverKind::Shooting);
        let asked = RunShape {
            given: OptionSet::of(&[SolverOption::LinkTolerance]),
            ..Default::default()
        };
        assert_eq!(choose(&small, asked).0, SolverKind::Hierarchical);
        // A form-factor method is read by shooting only: a large scene then shoots.
        let method = RunShape {
            given: OptionSet::of(&[SolverOption::FormFactor]),
            ..Default::default()
        };
        let (kind, why) = choose(&large, method);
        assert_eq!(kind, SolverKind::Shooting, "{why}");
        assert!(why.contains("--formfactor"), "{why}");
        // Options no candidate reads with the others are refused, naming the flag.
        let err = check_given(OptionSet::of(&[
            SolverOption::FormFactor,
            SolverOption::LinkTolerance,
        ]))
        .unwrap_err();
        assert!(err.contains("--formfactor"), "{err}");
        assert!(check_given(OptionSet::of(&[SolverOption::Omega])).is_err());
    }
}
