//! The second passes by name (`render --pass`): which image is made from a solution.
//!
//! - [`Pass::Vertex`]: radiosity interpolated over the mesh ([`super::render_solution`]);
//!   error: the mesh's (shadow edges smeared over an element).
//! - [`Pass::Direct`]: the lights' direct light per pixel, exact; the indirect rest from the
//!   solution ([`super::direct`]); error: the indirect part's mesh error.
//! - [`Pass::Gather`]: direct per pixel plus one bounce gathered from the solution
//!   ([`super::gather`]); error: the gather's noise, 1/√rays.

use super::{Image, RenderSettings, SolutionView, direct, display_bvh, gather, render_solution};
use crate::scene::Rgb;
use crate::solver::Problem;

/// A second pass (`render --pass`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pass {
    /// Radiosity interpolated over the mesh.
    Vertex,
    /// The lights' direct light per pixel, the indirect rest from the solution.
    Direct,
    /// Direct per pixel plus one bounce gathered from the solution.
    Gather,
}

impl Pass {
    pub const ALL: [Pass; 3] = [Pass::Vertex, Pass::Direct, Pass::Gather];

    /// The name `render --pass` takes.
    pub fn name(self) -> &'static str {
        match self {
            Pass::Vertex => "vertex",
            Pass::Direct => "direct",
            Pass::Gather => "gather",
        }
    }

    /// The pass of a `render --pass` name.
    pub fn parse(name: &str) -> Option<Pass> {
        Pass::ALL.into_iter().find(|p| p.name() == name)
    }

    /// The image of per-element `radiance` on `problem`'s mesh (`gather_rays`: rays per
    /// pixel of the gather, unused by the other passes), seen through the scene's mirrors
    /// and glass if it has any.
    pub fn render(
        self,
        problem: &Problem,
        radiance: &[Rgb],
        settings: &RenderSettings,
        gather_rays: u32,
    ) -> Image {
        match self {
            Pass::Direct => direct::render_solution(problem, radiance, settings),
            Pass::Gather => gather::render_solution(problem, radiance, settings, gather_rays),
            Pass::Vertex => {
                let values = super::per_unit_texture(
                    &problem.scene,
                    &problem.mesh,
                    problem.element_texture(),
                    radiance,
                );
                let vertex = problem.mesh.vertex_values(&values);
                let bvh = display_bvh(&problem.scene, &problem.mesh);
                let view = SolutionView {
                    scene: &problem.scene,
                    mesh: &problem.mesh,
                    vertex_radiance: &vertex,
                    bvh: &bvh,
                    texture: problem.element_texture(),
                };
                render_solution(&view, settings)
            }
        }
    }
}
