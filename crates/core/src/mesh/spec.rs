//! What a mesh is asked to be: the sizes (or the element budget they come from) and
//! whether the lights' shadow outlines become element edges. One value, so the meshing of
//! a scene, a re-mesh at another size and an adaptive refinement of it are all built from
//! the same settings ([`super::Mesh::build`], [`super::Mesh::build_refined`]) and none can
//! drop the discontinuity flag on the way.

/// The settings of a mesh ([`crate::solver::SolverConfig::mesh`]; a scene file's `mesh`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeshSpec {
    /// Element edge length (scene units); `None` = from [`MeshSpec::max_elements`], or
    /// [`super::default_element_size`].
    pub element_size: Option<f64>,
    /// Patch (shooter) edge length; `None` = [`super::default_patch_size`] of the element
    /// size. Never smaller than the element size.
    pub patch_size: Option<f64>,
    /// Element budget for the element size when `element_size` is `None`; `None` =
    /// [`super::default_element_size`].
    pub max_elements: Option<usize>,
    /// A priori discontinuity meshing: the lights' shadow outlines become element edges
    /// (`--discontinuity`, [`super::discontinuity`]).
    pub discontinuity: bool,
}

impl MeshSpec {
    /// Elements of `element_size`, patches of [`super::default_patch_size`] of it.
    pub fn element(element_size: f64) -> Self {
        Self {
            element_size: Some(element_size),
            ..Self::default()
        }
    }

    /// Explicit element and patch sizes.
    pub fn sized(element_size: f64, patch_size: f64) -> Self {
        Self {
            element_size: Some(element_size),
            patch_size: Some(patch_size),
            ..Self::default()
        }
    }

    /// The patch size used with elements of `element_size`: the one asked for, else
    /// [`super::default_patch_size`], and never below `element_size`.
    pub fn patch_for(&self, element_size: f64) -> f64 {
        self.patch_size
            .unwrap_or_else(|| super::default_patch_size(element_size))
            .max(element_size)
    }
}
