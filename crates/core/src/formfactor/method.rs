//! Which method computes form factors, and the tunables they share.

/// Which method computes form factors. Parsed from its [`name`](Self::name) by
/// [`FromStr`](std::str::FromStr) alone (every command-line flag naming a method goes
/// through it; the viewer's menu lists [`ALL`](Self::ALL)), so there is one parser and one
/// list. The core does not depend on clap.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FormFactorMethod {
    /// Exact point-to-polygon contour formula × stratified visibility.
    Contour,
    /// Exact polygon-to-polygon double contour integral (cases); as a solver row, the
    /// element's own polygon against the patch, × stratified visibility.
    Exact,
    /// Item-buffer hemicube at the shooter's centroid.
    Hemicube,
    /// Cosine-weighted rays from the shooter against the scene.
    Raycast,
    /// Random point pairs on both polygons, with visibility.
    Montecarlo,
    /// Analytic for lights and near or small receivers, hemicube for the rest.
    Hybrid,
    /// The item-buffer hemicube rasterised by a GPU through wgpu (`nusselt-gpu`); needs a
    /// [`ItemBufferRaster`](super::hemicube::ItemBufferRaster) in the [`RowContext`](super::RowContext).
    GpuHemicube,
}

impl FormFactorMethod {
    pub const ALL: &'static [FormFactorMethod] = &[
        FormFactorMethod::Contour,
        FormFactorMethod::Exact,
        FormFactorMethod::Hemicube,
        FormFactorMethod::Raycast,
        FormFactorMethod::Montecarlo,
        FormFactorMethod::Hybrid,
        FormFactorMethod::GpuHemicube,
    ];

    pub fn name(self) -> &'static str {
        match self {
            FormFactorMethod::Contour => "contour",
            FormFactorMethod::Exact => "exact",
            FormFactorMethod::Hemicube => "hemicube",
            FormFactorMethod::Raycast => "raycast",
            FormFactorMethod::Montecarlo => "montecarlo",
            FormFactorMethod::Hybrid => "hybrid",
            FormFactorMethod::GpuHemicube => "gpu-hemicube",
        }
    }

    /// The names, comma-separated (for messages).
    pub fn names() -> String {
        Self::ALL
            .iter()
            .map(|m| m.name())
            .collect::<Vec<_>>()
            .join(", ")
    }
}

impl std::fmt::Display for FormFactorMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown method name.
#[derive(Debug, thiserror::Error)]
#[error("unknown form-factor method '{0}' (available: {names})", names = FormFactorMethod::names())]
pub struct UnknownMethod(pub String);

impl std::str::FromStr for FormFactorMethod {
    type Err = UnknownMethod;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| UnknownMethod(s.to_string()))
    }
}

/// Tunables shared by all methods.
#[derive(Clone, Debug)]
pub struct FormFactorParams {
    /// Shadow rays per receiver–patch pair (rounded to a square, stratified); for
    /// `montecarlo` rows, point pairs per receiving element.
    pub visibility_rays: u32,
    /// Probe with 4 rays first for non-emitting shooters (see [`visibility_fraction`](super::visibility_fraction)).
    pub probe_visibility: bool,
    pub seed: u64,
    /// Hemicube resolution: pixels across the top face (the sides are half as tall).
    pub hemicube_res: u32,
    /// Rotate each hemicube by a random angle about the normal (breaks aliasing patterns).
    pub hemicube_rotate: bool,
    /// Rays per `raycast` row (from the shooting patch), and samples per case for the
    /// sampling methods (`raycast` rays, `montecarlo` point pairs).
    pub rays: u32,
    /// Refinement levels of the adaptive cubature over A1 for `exact` cases with occluders
    /// (the integrand has kinks along penumbra boundaries, so its 1e-10 tolerance is not
    /// reached there; each level quarters the cells near the kinks).
    pub cubature_depth: u32,
    /// `hybrid`: a receiver closer than `hybrid_k · √(A_shooter/π)` is computed analytically.
    pub hybrid_k: f64,
    /// `hybrid`: a receiver expected to cover fewer hemicube pixels than this is computed
    /// analytically too (aliasing of small or far patches).
    pub hybrid_min_pixels: f64,
    /// `contour`: for shooters that get every ray (lights; all with `probe_visibility` off),
    /// at most this many blockers cutting a point's pyramid have their shadows clipped away
    /// exactly ([`point_to_visible_polygon`](super::exact::point_to_visible_polygon)); more, and weighted shadow rays decide.
    /// 0 always samples.
    pub exact_blockers: usize,
}

impl Default for FormFactorParams {
    fn default() -> Self {
        Self {
            visibility_rays: 16,
            probe_visibility: true,
            seed: 1,
            hemicube_res: 256,
            hemicube_rotate: true,
            rays: 1 << 16,
            cubature_depth: 5,
            hybrid_k: 5.0,
            hybrid_min_pixels: 64.0,
            exact_blockers: 12,
        }
    }
}
