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
//!
//! Known fault, so not used where the scene has a sky, sun or point light
//! ([`crate::solver::handoff::hand_over`]): on the Dabrović atrium under the default sky
//! and sun (6,000 elements, handed over at 18.6 % unshot, a debug test not kept) the
//! answer converged to an area-mean radiosity of 0.381 where shooting to 1e-3 gives 0.393
//! and the hierarchy from dark, or from the shots with all reflected light linked, 0.3935.
//! The first eleven shots there were the sunlit outer walls, whose rows deliver nothing
//! (their light leaves the model), so the shots' radiosity was the source alone and the
//! unshot light 527 of 2,838 units of power; the links then gathered 44 units of the
//! 548 they sent at convergence, and 21 came back as radiosity, where the hierarchy from
//! dark added 114 to the source (214 gathered of 2,952 sent). Neither links made
//! at the unshot fraction times the tolerance (0.3816), nor the shot light spread per
//! patch, nor the conservation gain left out (0.3807) closed it; why is not found yet.

use super::HierarchicalSolver;
use crate::scene::Rgb;

/// A shooting solver's state, per element, that the links go on from.
#[derive(Clone, Debug, Default)]
pub struct ShotBase {
    /// `B_s`: the shots' radiosity; each gather adds the links' light reflected to it.
    pub held: Vec<Rgb>,
    /// `B_s − U` per patch, spread evenly over its elements as its rows sent it: the light
    /// already shot, which the links do not send again (a node sends its radiosity less
    /// this: `x`).
    pub shot: Vec<Rgb>,
}

impl HierarchicalSolver {
    /// Goes on from a shooting solver's state (module docs): `radiosity` per element and
    /// `unshot` per patch. The radiosity is the shots' until the first gather; the
    /// residual starts at the unshot fraction, which is also what the display correction
    /// estimates the missing light from. Links are made by the unshot light at the
    /// tolerance: unlike a first refinement with the direct light given, which links by all
    /// the light spread and is made coarser first ([`super::COARSE_FIRST`]), this one has
    /// little light to link by. Measured on the Crytek atrium (`nusselt bench --only live
    /// --live-model ../shared/models/crytek_sponza/sponza.obj --live-seconds 75`, 2-core
    /// AMD EPYC, 2026-12-08, the factor from an environment variable in a build not kept,
    /// alternated runs): at 4× the tolerance the first gather came between 30 and 40 s,
    /// 1.8 % from the converged image, and the residual reached 1e-3 at 60.0 and 56.6 s;
    /// at the tolerance the first gather came between 40 and 50 s, 0.6 % off, and the
    /// residual 1e-3 at 57.9 and 50.0 s. The image shown until then is the shots', 4.4 %
    /// off, either way.
    /// An edit of materials or lights, or a reset, ends this: the radiosity is then sent
    /// over links whole again, from the emission.
    ///
    /// # Panics
    /// If `radiosity` does not have one value per element or `unshot` one per patch.
    pub fn continue_from_shots(&mut self, radiosity: &[Rgb], unshot: &[Rgb]) {
        self.continue_from(radiosity, unshot);
        // What each patch has shot: its area-mean radiosity less its unshot radiance,
        // spread evenly over it as its rows sent it.
        let mesh = &self.problem.mesh;
        let shot_per_patch = mesh.patch_means(radiosity);
        let shot = (mesh.elements.iter())
            .map(|e| {
                let p = e.patch.0 as usize;
                shot_per_patch[p] - unshot[p]
            })
            .collect();
        self.shot_base = Some(ShotBase {
            held: radiosity.to_vec(),
            shot,
        });
        self.direct = Vec::new();
        self.first_links_by = None;
        self.coarse_first = false;
        self.pull();
    }
}
