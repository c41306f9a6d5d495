//! Form factors: how much of the light leaving one surface arrives at another.
//!
//! The solver needs, for a shooting patch `i`, a *row*: for every receiving element `j` the
//! form factor `F_ji` from (a point of) `j` to the whole of `i`, so that
//! `ΔB_j = ρ_j ΔB_i F_ji` (Cohen, Chen, Wallace, Greenberg 1988). The default method,
//! `contour`, evaluates Lambert's exact point-to-polygon formula at the element's centroid
//! and deals with blockers in three tiers: triangles outside the pair's shaft (Haines &
//! Wallace 1994) cannot block, so most pairs need no ray at all; for a light source (or with
//! probing off), when up to `exact_blockers` (12) triangles cut the point's own pyramid to
//! the patch, their shadows are subtracted from the patch polygon and Lambert's formula
//! integrates the visible rest exactly ([`exact::point_to_visible_polygon`]); otherwise the
//! visible fraction of stratified shadow rays is used (a 4-ray probe first for non-emitters),
//! each ray weighted by its point-to-point form factor (Wallace, Elmquist, Haines 1989).
//! Known error: the probe can miss a blocker smaller than its ray spacing; the sampled tier
//! has stratified noise O(N^-3/4) in penumbrae; the centroid rule integrates over the
//! receiving element with O(h²) error.

pub mod contour;
pub mod exact;
pub mod hemicube;
pub mod hybrid;
pub mod lights;
mod method;
pub mod montecarlo;
pub mod raycast;
pub mod row;
pub mod visibility;

pub use method::{FormFactorMethod, FormFactorParams, UnknownMethod};
pub use row::{RowContext, compute_row};
pub use visibility::{PolygonSampler, occluded_point_to_polygon, visibility_fraction};
