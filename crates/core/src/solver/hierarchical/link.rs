//! Links of hierarchical radiosity: the transfer estimate between two nodes, the BF
//! refinement oracle, and visibility by shadow rays.
//!
//! A link `i ← j` carries the kernel `K_ij` = the area average over `i` of
//! `∫_j cosθ_i cosθ_j V / (π r²) dA_j`, so the radiosity `i` gathers is `K_ij B_j`.
//! Estimates (the error each leaves is what the oracle bounds):
//! - a leaf sender (one element): Lambert's exact point-to-polygon value at the receiver's
//!   centroid (leaf receiver) or at 4 stratified element centroids of the receiver;
//! - a planar inner sender: the disc formula `A cosθ_i cosθ_j / (π r² + A)` (Wallace,
//!   Elmquist & Haines 1989) from the same points;
//! - a cluster sender: a point emitter of its projected area towards the receiver,
//!   `min(P(ω) cosθ_i / (π r²), 1)` with `P(ω) = Σ A max(n·ω, 0)` over its planar groups
//!   in second-order harmonics ([`super::directional`]). The isotropic `A/4` of Sillion
//!   (1995), with the disc formula's `+ A/4` under `π r²`, left a ball in a furnace 8 % and
//!   the walls 6 % short of the light they gather: a piece of a convex surface facing the
//!   receiver shows it up to 4× more than `A/4`.
//!
//! Visibility is the fraction of 4 shadow rays between area-sampled points of the two nodes
//! that arrive (16 for a partly hidden pair with a leaf on one end), or of one ray where the
//! link's transfer `B_j K_ij` is at most `ε/2`: one ray's standard error (1/2 of the
//! transfer) is then within 4 rays' at the largest transfer kept (1/4 of `ε`), so the
//! error bound per link stays that of 4 rays, at a quarter of the rays. Such a link is
//! provisional ([`Link::provisional`]): decided again, with its full rays, once its
//! sender's radiosity grows past that. Most links qualify: those from senders still dark
//! (`B_j = 0`, in the first iterations most of a large scene) and many made by a split.
//! A receiving cluster keeps 4 rays: a ray from a random point of a cluster is often
//! blocked by the cluster's own faces, so one ray would leave a whole group dark or lit.
//! A one-ray link from a cluster aims at a sender point chosen by its kernel among 16
//! (`Linker::visibility_ray`): aimed at an area-uniform point, half its rays ended on faces
//! turned away and the atrium came out 10 % too bright after the conservation gain.
//!
//! The oracle (Hanrahan, Salzman & Aupperle 1991, "BF refinement") keeps a link when
//! `B_j · bound_ij ≤ ε`, where `bound` is the unoccluded estimate, or where the estimate is
//! unreliable (one node's bounding sphere crosses the other's plane, or the nodes are
//! closer than their sizes) the cosine-free `A/(π r² + A)`; otherwise it splits the larger
//! node. A cluster receives through links that carry normal-incidence irradiance from the
//! sender's direction, read per element by its normal ([`super::directional`]); the oracle
//! charges those the harmonics' error and splits the receiver first. Two leaves are
//! always linked. Known error: a kept link is off by at most about `ε` in radiosity per
//! link times the number of links into a receiver, plus the visibility sampling error
//! (a standard error of at most 1/4 of a partly hidden link's transfer with 4 rays, and of
//! at most `ε/4` for a one-ray link, whose transfer is at most `ε/2`).

use std::f64::consts::PI;
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

mod estimate;

use super::flatlet::{BlockDecision, BlockLink};
use super::tree::{Hierarchy, Node};
use crate::geometry::Bvh;
use crate::mesh::Mesh;
use crate::scene::Rgb;

/// One link: `receiver` gathers `kernel × B(sender)`.
#[derive(Clone, Copy, Debug)]
pub struct Link {
    pub receiver: u32,
    pub sender: u32,
    /// `K_ij` with visibility.
    pub kernel: f32,
    /// The oracle's bound on the unoccluded kernel (see the module docs); negative for a
    /// provisional link ([`Link::provisional`]).
    bound: f32,
}

impl Link {
    /// A link whose kernel is final (`bound` ≥ 0).
    pub fn new(receiver: u32, sender: u32, kernel: f32, bound: f32) -> Link {
        Link {
            receiver,
            sender,
            kernel,
            bound: bound.abs(),
        }
    }

    /// Whether the link's visibility is one ray, made while its transfer was at most half
    /// the threshold: it is decided again once the sender's radiosity grows past that.
    pub fn provisional(&self) -> bool {
        self.bound.is_sign_negative()
    }

    /// The oracle's bound on the unoccluded kernel.
    pub fn bound(&self) -> f32 {
        self.bound.abs()
    }
}

/// Shadow rays per link (more for a partly hidden pair with a leaf end).
pub const RAYS: u32 = 4;
pub const RAYS_PARTIAL: u32 = 16;
/// Sender points a one-ray visibility chooses its target among where a cluster is at either
/// end (`Linker::visibility_ray`): seen from below, a cube of equal elements turns one face
/// of six to a receiver, and 16 elements drawn uniformly all miss it with probability
/// (5/6)¹⁶ ≈ 5 %.
const CANDIDATES: u32 = 16;
/// The fraction of the threshold under which a link's transfer is estimated from one
/// shadow ray (module docs).
const ONE_RAY: f64 = 0.5;
/// Points of a receiver (element centroids, stratified by area) the kernel is estimated at.
const RECEIVER_POINTS: u32 = 4;
/// Points of a planar inner sender its transfer is summed from.
const SENDER_POINTS: u32 = 4;
/// Slack for planes of groups whose elements are within `PLANAR_COS` of each other.
const PLANE_SLACK: f64 = 0.05;

/// A flatlet block's memory in scalar links (for the link budget).
const BLOCK_COST: usize = std::mem::size_of::<BlockLink>() / std::mem::size_of::<Link>() + 1;

/// Pairs decided at once in [`Linker::refine`] (bounds the pairs held waiting).
const FRONTIER_BATCH: usize = 1 << 18;

/// What [`Linker::expand`] makes of a batch of pairs.
#[derive(Default)]
struct Expanded {
    links: Vec<Link>,
    blocks: Vec<BlockLink>,
    next: Vec<Pair>,
}

/// A receiver and a sender node.
type Pair = (u32, u32);

/// What the oracle decided for a pair.
pub(super) enum Decision {
    /// No light can pass (same plane, or behind): no link.
    Drop,
    /// Keep the link (kernel with visibility, the oracle's bound per unit radiosity).
    Accept {
        kernel: f64,
        bound: f64,
    },
    /// Keep the link while its transfer stays under half the threshold (kernel with a
    /// one-ray visibility).
    Provisional {
        kernel: f64,
        bound: f64,
    },
    SplitReceiver,
    SplitSender,
    SplitBoth,
}

/// The geometry links are made on.
pub struct Linker<'a> {
    pub mesh: &'a Mesh,
    pub bvh: &'a Bvh,
    pub tree: &'a Hierarchy,
    pub epsilon: f64,
    pub seed: u64,
    /// Receivers smaller than this get a threshold raised by `reference_area / area`
    /// (see `Linker::receiver_eps`).
    pub reference_area: f64,
    /// Planar pairs linked by flatlet blocks ([`super::flatlet`]) instead of scalar links
    /// (whose kernels are always final: blocks have no provisional state).
    pub flatlets: bool,
}

impl Linker<'_> {
    fn node(&self, i: u32) -> &Node {
        &self.tree.nodes[i as usize]
    }

    /// The threshold for receiver `i`: `eps` in radiosity for receivers of at least the
    /// reference area, and a fixed power error `eps × reference_area` below it (Hanrahan et
    /// al.'s minimum area Aε made gradual, as in "BFA" refinement): past that size a
    /// receiver's error weighs less in the power and image error than its links cost.
    pub(super) fn receiver_eps(&self, i: u32, eps: f64) -> f64 {
        let area = self.node(i).area;
        if area > 0.0 && area < self.reference_area {
            eps * (self.reference_area / area)
        } else {
            eps
        }
    }

    /// Links covering the pairs `(receiver, sender)` of `frontier`, each refined until it
    /// meets the oracle against node radiosities `b` and threshold `eps`. Breadth-first,
    /// each level in parallel; the result is in a deterministic order. Once the links
    /// (made and still to come) would pass `max_links`, every pair left is kept as it is
    /// except where the hierarchy forces a split (a cluster receiver, overlapping nodes);
    /// the flag says so. `None` if `cancel` was set.
    pub fn refine(
        &self,
        frontier: Vec<(u32, u32)>,
        b: &[Rgb],
        eps: f64,
        max_links: usize,
        cancel: &AtomicBool,
    ) -> Option<(Vec<Link>, Vec<BlockLink>, bool)> {
        let mut links = Vec::new();
        let mut blocks = Vec::new();
        let mut capped = false;
        // Pairs still to decide, in batches of at most `FRONTIER_BATCH`: the newest batch
        // first, so the pairs waiting stay few (memory) while each batch runs in parallel.
        let mut pending = 0usize;
        let mut stack = Vec::new();
        if !frontier.is_empty() {
            pending = frontier.len();
            stack.push(frontier);
        }
        while let Some(mut batch) = stack.pop() {
            if cancel.load(Ordering::Relaxed) {
                return None;
            }
            if batch.len() > FRONTIER_BATCH {
                stack.push(batch.split_off(FRONTIER_BATCH));
            }
            pending -= batch.len();
            capped |=
                links.len() + BLOCK_COST * blocks.len() + 2 * (batch.len() + pending) > max_links;
            let eps = if capped { f64::INFINITY } else { eps };
            let parts: Vec<(Vec<Link>, Vec<BlockLink>, Vec<Pair>)> = batch
                .par_chunks(256)
                .map(|chunk| {
                    let mut out = Expanded::default();
                    for &(i, j) in chunk {
                        self.expand(i, j, b, eps, &mut out);
                    }
                    (out.links, out.blocks, out.next)
                })
                .collect();
            drop(batch);
            let mut next = Vec::with_capacity(parts.iter().map(|p| p.2.len()).sum());
            for (kept, kept_blocks, pairs) in parts {
                links.extend(kept);
                blocks.extend(kept_blocks);
                next.extend(pairs);
            }
            if !next.is_empty() {
                pending += next.len();
                stack.push(next);
            }
        }
        Some((links, blocks, capped))
    }

    /// One decision on the pair `i ← j`: a kept link into `kept`, or child pairs into `next`.
    fn expand(&self, i: u32, j: u32, b: &[Rgb], eps: f64, out: &mut Expanded) {
        let Expanded {
            links: kept,
            blocks: kept_blocks,
            next,
        } = out;
        let (ni, nj) = (self.node(i), self.node(j));
        let ci = ni.children;
        let cj = nj.children;
        let planar_pair = !ni.is_cluster() && !nj.is_cluster() && !ni.overlaps(nj);
        let decision = if self.flatlets && planar_pair {
            match self.decide_block(i, j, b, eps) {
                BlockDecision::Drop => return,
                BlockDecision::Keep(block) => {
                    kept_blocks.push(block);
                    return;
                }
                BlockDecision::Split(d) => d,
            }
        } else {
            self.decide(i, j, b[j as usize].max_element(), eps)
        };
        match decision {
            Decision::Drop => {}
            Decision::Accept { kernel, bound } => {
                if kernel > 0.0 || bound > 0.0 {
                    kept.push(Link::new(i, j, kernel as f32, bound as f32));
                }
            }
            Decision::Provisional { kernel, bound } => {
                if kernel > 0.0 || bound > 0.0 {
                    let mut link = Link::new(i, j, kernel as f32, bound as f32);
                    link.bound = -link.bound;
                    kept.push(link);
                }
            }
            Decision::SplitReceiver => next.extend(ci.map(|c| (c, j))),
            Decision::SplitSender => next.extend(cj.map(|c| (i, c))),
            Decision::SplitBoth => {
                for a in ci {
                    for c in cj {
                        next.push((a, c));
                    }
                }
            }
        }
    }

    /// Whether a kept link should now be split, given the sender's radiosity.
    pub fn needs_split(&self, link: &Link, b_sender: f64, eps: f64) -> bool {
        b_sender * link.bound() as f64 > self.receiver_eps(link.receiver, eps)
            && !(self.node(link.receiver).is_leaf() && self.node(link.sender).is_leaf())
    }

    /// Whether a kept link must be decided again: it needs a split, or it is provisional
    /// and its transfer has outgrown one ray ([`Linker::outgrew_ray`]).
    pub fn needs_decision(&self, link: &Link, b_sender: f64, eps: f64) -> bool {
        self.outgrew_ray(link, b_sender, eps) || self.needs_split(link, b_sender, eps)
    }

    /// Whether a provisional link's transfer, at the sender's radiosity now, has passed
    /// the half threshold under which one shadow ray is enough.
    pub fn outgrew_ray(&self, link: &Link, b_sender: f64, eps: f64) -> bool {
        link.provisional()
            && b_sender * link.bound() as f64 > ONE_RAY * self.receiver_eps(link.receiver, eps)
    }

    pub(super) fn decide(&self, i: u32, j: u32, b_j: f64, eps: f64) -> Decision {
        let eps = self.receiver_eps(i, eps);
        let (ni, nj) = (self.node(i), self.node(j));
        if ni.overlaps(nj) {
            return if i == j {
                if ni.is_cluster() {
                    Decision::SplitBoth
                } else {
                    Decision::Drop // a planar node cannot see itself
                }
            } else if ni.count > nj.count {
                Decision::SplitReceiver
            } else {
                Decision::SplitSender
            };
        }
        if ni.is_cluster() {
            return self.decide_cluster_receiver(i, j, b_j, eps);
        }
        let d = nj.centroid - ni.centroid;
        let slack_i = PLANE_SLACK * ni.radius;
        // The sender wholly behind the receiver's plane, or the receiver behind the sender's.
        if ni.normal.dot(d) + nj.radius < -slack_i {
            return Decision::Drop;
        }
        if !nj.is_cluster() {
            let slack_j = PLANE_SLACK * nj.radius;
            if -nj.normal.dot(d) + ni.radius < -slack_j {
                return Decision::Drop;
            }
            // Same plane, same side: nothing passes.
            if ni.normal.dot(nj.normal) > 0.9995
                && ni.normal.dot(d).abs() <= slack_i + slack_j
                && !(ni.is_leaf() && nj.is_leaf())
            {
                return Decision::Drop;
            }
        }
        let (unoccluded, spread) = self.unoccluded(i, j);
        let r2 = d.length_squared();
        let toward_receiver = -d / r2.sqrt().max(f64::MIN_POSITIVE);
        let sender_area = match self.tree.projected_area(j, toward_receiver) {
            Some(p) => p.max(nj.area / 4.0),
            None => nj.area,
        };
        let both_leaves = ni.is_leaf() && nj.is_leaf();
        let crosses_i = ni.normal.dot(d).abs() < nj.radius && !ni.is_leaf();
        let crosses_j = !nj.is_cluster() && nj.normal.dot(d).abs() < ni.radius && !nj.is_leaf();
        let near = r2.sqrt() < ni.radius + nj.radius;
        // The kernel the error is measured on, and the error of the estimate over it: the
        // spread over the receiver's points plus the sender's approximation (second order
        // in its size for the disc formula; first order, up to 4×, for an isotropic cluster).
        let reliable = !(crosses_i || crosses_j || near);
        // Nothing passes where the estimate says so and can be trusted (or cannot be
        // refined further): no link, and no shadow rays spent on one.
        if unoccluded <= 0.0 && (reliable || both_leaves) {
            return Decision::Drop;
        }
        let (kernel, variation) = if !reliable {
            (unoccluded.max(sender_area / (PI * r2 + sender_area)), 1.0)
        } else {
            let size = nj.radius * nj.radius / r2;
            let sender_error = if nj.is_leaf() {
                0.0
            } else if nj.is_cluster() {
                4.0 * unoccluded * size.sqrt()
            } else {
                unoccluded * size
            };
            let k = unoccluded.max(f64::MIN_POSITIVE);
            (k, ((spread + sender_error) / k).min(1.0))
        };
        if b_j * kernel <= ONE_RAY * eps && !self.flatlets {
            return Decision::Provisional {
                kernel: unoccluded * self.visibility_ray(i, j),
                bound: kernel,
            };
        }
        let accept = |visibility: Option<f64>| {
            let v = visibility.unwrap_or_else(|| self.visibility(i, j));
            let partial = v > 0.0 && v < 1.0;
            Decision::Accept {
                kernel: unoccluded * v,
                bound: kernel * if partial { 1.0 } else { variation },
            }
        };
        if both_leaves {
            return accept(None);
        }
        if b_j * kernel <= eps {
            return accept(None);
        }
        if b_j * kernel * variation <= eps {
            // Small enough unless the pair is in penumbra.
            let v = self.visibility_or_partial(i, j);
            if v == 0.0 || v == 1.0 {
                return accept(Some(v));
            }
        }
        self.split_choice(i, j)
    }

    /// Which node of a pair that fails the oracle to split: the larger, never a leaf.
    pub(super) fn split_choice(&self, i: u32, j: u32) -> Decision {
        let (ni, nj) = (self.node(i), self.node(j));
        let split_receiver = if nj.is_leaf() {
            true
        } else if ni.is_leaf() {
            false
        } else {
            ni.radius >= nj.radius
        };
        if split_receiver {
            Decision::SplitReceiver
        } else {
            Decision::SplitSender
        }
    }

    /// The oracle for a receiving cluster, whose links carry normal-incidence irradiance
    /// from the sender's direction ([`super::directional`]): kept when the transfer times
    /// the relative variation over the two nodes plus the harmonics' error is under `eps`
    /// and the pair is not in penumbra.
    fn decide_cluster_receiver(&self, i: u32, j: u32, b_j: f64, eps: f64) -> Decision {
        let (ni, nj) = (self.node(i), self.node(j));
        // Receivers first: a sender split first is paid again under every receiver child.
        let split = Decision::SplitReceiver;
        let d = nj.centroid - ni.centroid;
        let dist = d.length();
        if dist <= ni.radius + nj.radius || dist <= 0.0 {
            return split;
        }
        let dir = d / dist;
        let k = self.normal_incidence(ni.centroid, dir, j);
        if k <= 0.0 {
            return Decision::Drop;
        }
        // An isotropic sender may be up to 4× brighter towards the receiver.
        let kb = if nj.is_cluster() { 4.0 * k } else { k };
        let variation = ((ni.radius + nj.radius) / dist + super::directional::SH_ERROR).min(1.0);
        if b_j * kb * variation > eps {
            return split;
        }
        // Past the threshold a partly hidden pair splits, so one round of rays decides it.
        let split_if_partial = b_j * kb > eps;
        let v = if split_if_partial {
            self.visibility_or_partial(i, j)
        } else {
            self.visibility(i, j)
        };
        let partial = v > 0.0 && v < 1.0;
        if partial && split_if_partial {
            return split;
        }
        Decision::Accept {
            kernel: k * v,
            bound: kb * if partial { 1.0 } else { variation },
        }
    }
}
