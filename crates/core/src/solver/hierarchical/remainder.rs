//! Going on from a shooting solver's state by sending only the light not yet shot over
//! links.
//!
//! Progressive shooting keeps, after any number of shots, `B_s = E + ρ F (B_s − U)`: the
//! light each patch has shot (`B_s − U`, its radiosity less its unshot radiance `U`) has
//! reached every element through a row of form factors. The true solution
//! `B = E + ρ F B` therefore differs from `B_s` by `e = ρ F (e + U)`: with `x = e + U`,
//!
//! ```text
//! x = U + ρ F x,    B = B_s + (x − U) = B_s + ρ F x.
//! ```
//!
//! That is a radiosity problem whose source is the unshot light: the hierarchy solves it
//! over its links and adds the result to the shots' radiosity
//! ([`HierarchicalSolver::continue_from_shots`]). What the shots delivered keeps the rows'
//! accuracy (the form-factor method's, with its visibility samples), and only `x` carries
//! the links' error. On the Crytek atrium, handed over at 20 % unshot, `x` is about a
//! third of the reflected light, so the links' error on the converged image shrinks by as
//! much. Without this, the hierarchy re-solved all reflected light over its links from the
//! shots' radiosity as a first guess, and its converged image of the atrium was 6–10 %
//! (relative RMS per pixel) from the shots' one, in broad smooth regions where each
//! coarse link spreads its estimate: the viewer's image jumped by that much at the first
//! gather, and no image before it was within 5 % of the converged one.

use super::HierarchicalSolver;
use crate::scene::Rgb;

/// A shooting solver's state, per element, that the links go on from.
#[derive(Clone, Debug, Default)]
pub struct ShotBase {
    /// `B_s`: the shots' radiosity; each gather adds the links' light reflected to it.
    pub held: Vec<Rgb>,
    /// `B_s − U`: the light already shot, which the links do not send again (a node sends
    /// its radiosity less this: `x`).
    pub shot: Vec<Rgb>,
}

impl HierarchicalSolver {
    /// Goes on from a shooting solver's state (module docs): `radiosity` per element and
    /// `unshot` per patch. The radiosity is the shots' until the first gather; the
    /// residual starts at the unshot fraction, which is also what the display correction
    /// estimates the missing light from. Links are made by the unshot light, at the coarser
    /// tolerance of a first refinement with the direct light given ([`super::COARSE_FIRST`]).
    /// An edit of materials or lights, or a reset, ends this: the radiosity is then sent
    /// over links whole again, from the emission.
    ///
    /// # Panics
    /// If `radiosity` does not have one value per element or `unshot` one per patch.
    pub fn continue_from_shots(&mut self, radiosity: &[Rgb], unshot: &[Rgb]) {
        self.continue_from(radiosity, unshot);
        // `continue_from` set the change to each element's patch's unshot radiance.
        let shot = (radiosity.iter().zip(&self.change))
            .map(|(b, u)| *b - *u)
            .collect();
        self.shot_base = Some(ShotBase {
            held: radiosity.to_vec(),
            shot,
        });
        self.direct = Vec::new();
        self.first_links_by = None;
        self.coarse_first = true;
        self.pull();
    }

    /// Whether the links carry only the light not yet shot ([`Self::continue_from_shots`]).
    pub fn goes_on_from_shots(&self) -> bool {
        self.shot_base.is_some()
    }
}
