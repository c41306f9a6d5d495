//! Hierarchical radiosity with clustering (`--solver hierarchical`), and wavelet radiosity
//! with flatlets on the same hierarchy (`--solver wavelet`, [`flatlet`]).
//!
//! Hanrahan, Salzman & Aupperle (1991), "A rapid hierarchical radiosity algorithm": the
//! transport between two surfaces is represented at the coarsest pair of levels whose
//! estimated transfer `B_j · F_ij` is below a tolerance, so an `n`-element scene needs
//! O(n) links instead of the n² (or patches × elements) of a full matrix. Clusters (Smits,
//! Arvo & Greenberg 1994; Sillion 1995) put a volume hierarchy over the surfaces so that
//! distant groups exchange light through one link; a receiving cluster keeps the light by
//! direction and each element reads it at its own normal ([`directional`]). The hierarchy
//! ([`tree`]) has the mesh's
//! elements as leaves, so the display, the vertex interpolation and every comparison work
//! on the same elements as the other solvers.
//!
//! One step is one iteration: refine the links against the current radiosity (BF
//! refinement, [`link`]), *gather* `H_i = Σ_j K_ij B_j` over each node's links, then
//! *push-pull*: each leaf gets `B = E + ρ Σ_{ancestors} H`, and each inner node the area
//! average of its children. The first iteration links the root to itself and refines with
//! `B = E`; later ones refine where the light has grown. The iteration is Jacobi's on the
//! hierarchical system, so the residual falls like `ρ^k`.
//!
//! Error: that of the links kept (bounded by the tolerance, [`HierarchicalOptions::link_tolerance`]
//! times the scene's mean emitted radiosity, per link), of the visibility (4 rays, or one where a link carries at most `ε/2`), and of
//! constant elements. The estimates err low more often than high, and summed over
//! hundreds of links they lost light: the closed furnace box was 1–5 % off `E/(1 − ρ)` at
//! 864–2,400 elements, the gallery's statue 18 % too dark. Each element's gathered light
//! is therefore rescaled so that the kernels it reads sum to its covered hemisphere
//! ([`conserve`]): exact in a closed scene, weighed against the rays' noise in an open one.
//! The residual reported is the change of the last iteration,
//! `Σ|B_new − B_old| A / Σ|E| A` (the residual of the hierarchical system at the old
//! solution), not the residual of the full-matrix system the other solvers report.
//! Receivers below 1/16,384 of the scene's area ([`REFERENCE_RECEIVERS`]) get a threshold
//! that grows as they shrink (a gradual minimum area, HSA's `A_ε`), so the links stop
//! growing with the element count: their error weighs by their area in the power and image
//! error.
//! Measured (`render --pass vertex --reference`, release, this 2-core machine): the Cornell
//! box at the default tolerance 2.05 % from the path-traced reference (2.66 % before the
//! rescaling; shooting 1.78 %), wavelet 1.45 % (1.90 %); the 100 k-triangle gallery 7.2 %
//! (8.3 %; shooting 5.5 %), its statue's mean 0.997 of the reference's (0.824), wavelet
//! 5.5 % and 1.001 (6.4 %, 0.894). docs/BENCHMARKS.md has the times. One-ray links
//! ([`link::Link::provisional`]; another machine, an Intel Xeon, 2026-12-06): Cornell 1.94 →
//! 1.99 %, gallery 8.00 → 8.33 %, for a solve 5.3 → 4.7 s and 27.3 → 19.9 s (the atrium's
//! 81 → 53 s).
//!
//! [`HierarchicalOptions::link_tolerance`]: super::HierarchicalOptions::link_tolerance

pub mod conserve;
pub mod direct;
pub mod directional;
pub mod flatlet;
pub mod link;
pub mod remainder;
pub mod tree;

mod solver_impl;

use std::sync::atomic::AtomicBool;

use rayon::prelude::*;

use super::{Problem, Solver, channel_sum};
use crate::scene::Rgb;
use flatlet::BlockLink;
use link::{Link, Linker};
use tree::{Hierarchy, NONE};

/// Receivers smaller than the scene's area over this many get a threshold that grows as
/// they shrink (`link::Linker::receiver_eps`), so that the links stop growing with the
/// element count past about this many elements.
pub const REFERENCE_RECEIVERS: f64 = 16384.0;

/// The factor on the tolerance of the first refinement after the direct light is given
/// ([`HierarchicalSolver::set_direct`]). That refinement links by all the light already
/// spread, the work of two refinements from dark; at 4× the tolerance its links come in
/// half the time, so a first gathered image is on screen sooner, and the next refinement,
/// at the tolerance, splits the links that carry more than it. Measured on the Crytek
/// atrium handed over from shooting (`nusselt bench --only live --live-seconds 100`,
/// 2-core AMD EPYC, 2026-12-07, one run each, factors 1, 2, 4 and 8): the first gathered
/// image at about 50, 45, 35 and 35 s, 0.4 %, 0.9 %, 1.4 % and 2.0 % from the converged
/// one; converged at 56.4–58.4, 68.7, 60.3 and 62.0 s (the machine's own spread is a few
/// seconds).
pub const COARSE_FIRST: f64 = 4.0;

/// The basis radiosity is represented in over each node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Basis {
    /// Constant per node, scalar links: hierarchical radiosity (the Haar wavelet case).
    Haar,
    /// Flatlets F2: constant per piece, 4 × 4 blocks between planar nodes ([`flatlet`]).
    Flatlet,
}

pub struct HierarchicalSolver {
    problem: Problem,
    basis: Basis,
    /// Flatlet blocks, sorted by receiver like `links` (empty for [`Basis::Haar`]).
    blocks: Vec<BlockLink>,
    block_start: Vec<u32>,
    tree: Hierarchy,
    /// Sorted by receiver (then sender); `link_start[i]..link_start[i + 1]` are node `i`'s.
    links: Vec<Link>,
    link_start: Vec<u32>,
    /// Radiosity per node (area average of its elements).
    node_b: Vec<Rgb>,
    /// The node radiosities the first refinement links by where they are not `node_b`:
    /// the emission's, for a solve continued from shot light ([`Self::continue_from`]).
    first_links_by: Option<Vec<Rgb>>,
    radiosity: Vec<Rgb>,
    /// Per element, the irradiance over π the emitting surfaces' emission gives it, taken
    /// as computed ([`Self::set_direct`]); empty while the emission is sent over links.
    direct: Vec<Rgb>,
    /// The shots' state the links go on from, sending only the unshot light
    /// ([`remainder`]); `None` while the links carry all reflected light.
    shot_base: Option<remainder::ShotBase>,
    /// The next refinement is the first with the direct light given, to a coarser tolerance.
    coarse_first: bool,
    /// The first step shoots the lights' rows first ([`Self::lights_by_rows`]).
    light_rows_pending: bool,
    /// Last iteration's change per element (the residual).
    change: Vec<Rgb>,
    /// Per element, the covered fraction of its hemisphere ([`conserve`]; measured once).
    coverage: Option<conserve::Coverage>,
    /// Per element, the factor on its gathered light ([`conserve::gain`]; with the links).
    gain: Vec<f64>,
    /// Per patch (an element's are its patch's).
    emission: Vec<Rgb>,
    reflectance: Vec<Rgb>,
    emitted: f64,
    residual: f64,
    steps: usize,
    /// Links made by refinement so far (kept or later split).
    links_made: usize,
    residual_at_refine: f64,
    /// Refinement stopped short at the memory budget (`Problem::cache_bytes`).
    link_budget_reached: bool,
    refine_seconds: f64,
    gather_seconds: f64,
    /// The regional transport of the display correction, built on first display
    /// ([`super::ambient`]).
    regional: std::sync::OnceLock<super::ambient::RegionalAmbient>,
}

impl HierarchicalSolver {
    pub fn new(problem: Problem) -> Self {
        Self::with_basis(problem, Basis::Haar)
    }

    /// Wavelet radiosity in `basis` (hierarchical radiosity for [`Basis::Haar`]).
    pub fn with_basis(problem: Problem, basis: Basis) -> Self {
        let tree = Hierarchy::build(&problem.mesh);
        let mut s = Self {
            problem,
            basis,
            blocks: Vec::new(),
            block_start: Vec::new(),
            tree,
            links: Vec::new(),
            link_start: Vec::new(),
            node_b: Vec::new(),
            first_links_by: None,
            radiosity: Vec::new(),
            direct: Vec::new(),
            shot_base: None,
            coarse_first: false,
            light_rows_pending: false,
            change: Vec::new(),
            coverage: None,
            gain: Vec::new(),
            emission: Vec::new(),
            reflectance: Vec::new(),
            emitted: 0.0,
            residual: 1.0,
            steps: 0,
            links_made: 0,
            residual_at_refine: f64::INFINITY,
            link_budget_reached: false,
            refine_seconds: 0.0,
            gather_seconds: 0.0,
            regional: std::sync::OnceLock::new(),
        };
        s.reset();
        s
    }

    pub fn link_count(&self) -> usize {
        self.links.len()
    }

    /// Flatlet blocks ([`Basis::Flatlet`]; none for Haar).
    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    pub fn node_count(&self) -> usize {
        self.tree.nodes.len()
    }

    /// The scalar links into `node`, sorted by sender (none before the first step).
    pub fn links_into(&self, node: u32) -> &[Link] {
        let n = node as usize;
        match (self.link_start.get(n), self.link_start.get(n + 1)) {
            (Some(&a), Some(&b)) => &self.links[a as usize..b as usize],
            _ => &[],
        }
    }

    pub fn hierarchy(&self) -> &Hierarchy {
        &self.tree
    }

    /// The BF threshold: the tolerance times the area-mean of the brightest emission channel.
    fn threshold(&self) -> f64 {
        let mesh = &self.problem.mesh;
        let (mut sum, mut area) = (0.0, 0.0);
        for e in &mesh.elements {
            sum += self.emission[e.patch.0 as usize].max_element() * e.area;
            area += e.area;
        }
        self.problem.config.hierarchical.link_tolerance * sum / area.max(f64::MIN_POSITIVE)
    }

    /// The link maker on this solver's geometry; `None` for an empty hierarchy.
    fn linker(&self) -> Option<Linker<'_>> {
        linker(&self.problem, &self.tree, self.basis)
    }

    /// Whether a provisional link's transfer has outgrown its one ray since the links
    /// were made.
    fn provisional_outgrown(&self) -> bool {
        let Some(linker) = self.linker() else {
            return false;
        };
        let (b, eps) = (&self.node_b, self.threshold());
        (self.links.par_iter())
            .any(|l| linker.outgrew_ray(l, b[l.sender as usize].max_element(), eps))
    }

    /// Refines the links against the current radiosity (`full`), or only decides again the
    /// provisional links whose sender is lit. `false` if cancelled.
    fn refine(&mut self, cancel: &AtomicBool, full: bool) -> bool {
        let Some(root) = self.tree.root() else {
            return false;
        };
        let eps = self.threshold() * if self.coarse_first { COARSE_FIRST } else { 1.0 };
        let Some(linker) = linker(&self.problem, &self.tree, self.basis) else {
            return false;
        };
        // The links to split, and provisional ones whose sender is lit, become the
        // frontier; the rest stay where they are.
        let mut links = std::mem::take(&mut self.links);
        let mut blocks = std::mem::take(&mut self.blocks);
        let first = self.steps == 0 && links.is_empty() && blocks.is_empty();
        let (removed, removed_blocks) = if first {
            (Vec::new(), Vec::new())
        } else {
            let b = &self.node_b;
            (
                take_where(&mut links, |l| {
                    let b_sender = b[l.sender as usize].max_element();
                    if full {
                        linker.needs_decision(l, b_sender, eps)
                    } else {
                        linker.outgrew_ray(l, b_sender, eps)
                    }
                }),
                take_where(&mut blocks, |k| full && linker.block_needs_split(k, b, eps)),
            )
        };
        let frontier: Vec<(u32, u32)> = if first {
            vec![(root, root)]
        } else {
            let pairs = removed.iter().map(|l| (l.receiver, l.sender));
            pairs
                .chain(removed_blocks.iter().map(|k| (k.receiver, k.sender)))
                .collect()
        };
        if frontier.is_empty() {
            self.links = links;
            self.blocks = blocks;
            return true;
        }
        let budget = self.problem.cache_bytes() / std::mem::size_of::<Link>();
        let held = links.len() + blocks.len() * std::mem::size_of::<BlockLink>() / 16;
        let max_links = budget.saturating_sub(held);
        let Some((new_links, new_blocks, capped)) = linker.refine(
            frontier,
            self.first_links_by.as_deref().unwrap_or(&self.node_b),
            eps,
            max_links,
            cancel,
        ) else {
            // Cancelled: the links as they were.
            blocks.extend(removed_blocks);
            self.set_links(merge_sorted(links, removed), blocks);
            return false;
        };
        drop((removed, removed_blocks));
        self.first_links_by = None;
        self.coarse_first = false;
        self.link_budget_reached |= capped;
        self.links_made += new_links.len() + new_blocks.len();
        let mut new_links = new_links;
        new_links.par_sort_unstable_by_key(|l| (l.receiver, l.sender));
        let links = merge_sorted(links, new_links);
        blocks.reserve_exact(new_blocks.len());
        blocks.extend(new_blocks);
        self.set_links(links, blocks);
        true
    }

    /// Stores links (sorted by receiver and sender) and blocks (sorted here), with their
    /// start per node.
    fn set_links(&mut self, links: Vec<Link>, mut blocks: Vec<BlockLink>) {
        debug_assert!(links.is_sorted_by_key(|l| (l.receiver, l.sender)));
        blocks.shrink_to_fit();
        blocks.par_sort_unstable_by_key(|l| (l.receiver, l.sender));
        let n = self.tree.nodes.len();
        self.link_start = starts(n, links.iter().map(|l| l.receiver));
        self.block_start = starts(n, blocks.iter().map(|l| l.receiver));
        self.links = links;
        self.blocks = blocks;
    }

    /// The irradiance per node that node radiosities `b` send over the links and blocks,
    /// pushed down (each node's includes its ancestors'; clusters' read at the normal).
    fn pushed(&self, b: &[Rgb]) -> Vec<Rgb> {
        let links = &self.links;
        let start = &self.link_start;
        let nodes = &self.tree.nodes;
        // Planar receivers gather a scalar; clusters a directional irradiance.
        let mut down: Vec<Rgb> = (0..nodes.len())
            .into_par_iter()
            .map(|i| {
                if nodes[i].is_cluster() {
                    return Rgb::ZERO;
                }
                links[start[i] as usize..start[i + 1] as usize]
                    .iter()
                    .map(|l| b[l.sender as usize] * l.kernel as f64)
                    .sum()
            })
            .collect();
        // Flatlet blocks deliver to their receiver's pieces.
        if !self.blocks.is_empty() {
            let blocks = &self.blocks;
            let bs = &self.block_start;
            let tree = &self.tree;
            let pieces: Vec<([u32; flatlet::PIECES], usize, [Rgb; flatlet::PIECES])> = (0..nodes
                .len())
                .into_par_iter()
                .filter(|&i| bs[i] < bs[i + 1])
                .map(|i| {
                    let mut total = [Rgb::ZERO; flatlet::PIECES];
                    let mut ids = ([0u32; flatlet::PIECES], 0);
                    for k in &blocks[bs[i] as usize..bs[i + 1] as usize] {
                        let (p, n, g) = flatlet::block_gather(tree, k, b);
                        ids = (p, n);
                        for (t, g) in total.iter_mut().zip(g) {
                            *t += g;
                        }
                    }
                    (ids.0, ids.1, total)
                })
                .collect();
            for (ids, n, g) in pieces {
                for (&p, g) in ids[..n].iter().zip(g) {
                    down[p as usize] += g;
                }
            }
        }
        let clusters = &self.tree.clusters;
        let mut sh: Vec<directional::Sh9> = clusters
            .par_iter()
            .map(|&i| {
                let i = i as usize;
                let mut sh = [Rgb::ZERO; 9];
                for l in &links[start[i] as usize..start[i + 1] as usize] {
                    let d = (nodes[l.sender as usize].centroid - nodes[i].centroid)
                        .try_normalize()
                        .unwrap_or(glam::DVec3::Z);
                    directional::add(&mut sh, d, b[l.sender as usize] * l.kernel as f64);
                }
                sh
            })
            .collect();
        // Push: accumulated irradiance, parents first (pre-order). A cluster's harmonics
        // add up down the cluster levels and are read once at each planar group's normal
        // (its elements' normals agree within `tree::PLANAR_COS`).
        let slot = &self.tree.cluster_slot;
        for n in 0..down.len() {
            let p = self.tree.parent[n];
            if p == NONE {
                continue;
            }
            let p = p as usize;
            down[n] = down[n] + down[p];
            if slot[p] == NONE {
                continue;
            }
            let parent_sh = sh[slot[p] as usize];
            if slot[n] != NONE {
                for (a, b) in sh[slot[n] as usize].iter_mut().zip(parent_sh) {
                    *a += b;
                }
            } else {
                down[n] += directional::irradiance(&parent_sh, nodes[n].normal);
            }
        }
        down
    }

    /// Gather, push to the leaves, pull up; sets the residual.
    fn gather_push_pull(&mut self) {
        let down = self.pushed(&self.node_b);
        let mut residual = 0.0;
        for (e, el) in self.problem.mesh.elements.iter().enumerate() {
            let leaf = self.tree.leaf[e] as usize;
            let p = el.patch.0 as usize;
            let mut gathered = down[leaf] * self.gain.get(e).copied().unwrap_or(1.0);
            let new = if let Some(base) = &self.shot_base {
                base.held[e] + self.reflectance[p] * gathered
            } else {
                if let Some(d) = self.direct.get(e) {
                    gathered += *d;
                }
                self.problem.element_source(e) + self.reflectance[p] * gathered
            };
            debug_assert!(new.is_finite());
            self.change[e] = new - self.radiosity[e];
            residual += channel_sum(self.change[e]) * el.area;
            self.radiosity[e] = new;
        }
        self.residual = residual / self.emitted.max(f64::MIN_POSITIVE);
        self.pull();
    }

    /// Node radiosities from the elements' (area averages, children before parents): what
    /// each node sends over its links, less the emission where its light is given
    /// ([`Self::set_direct`]), or less the light already shot ([`remainder`]).
    fn pull(&mut self) {
        let nodes = &self.tree.nodes;
        if self.node_b.len() != nodes.len() {
            self.node_b = vec![Rgb::ZERO; nodes.len()];
        }
        let mesh = &self.problem.mesh;
        for n in (0..nodes.len()).rev() {
            let node = &nodes[n];
            self.node_b[n] = if node.is_leaf() {
                let e = self.tree.order[node.first as usize] as usize;
                if let Some(base) = &self.shot_base {
                    self.radiosity[e] - base.shot[e]
                } else if self.direct.is_empty() {
                    self.radiosity[e]
                } else {
                    let emission = self.problem.material_of(mesh.elements[e].patch).emission;
                    self.radiosity[e] - emission
                }
            } else {
                let [a, c] = node.children.map(|c| c as usize);
                if node.area > 0.0 {
                    (self.node_b[a] * nodes[a].area + self.node_b[c] * nodes[c].area) / node.area
                } else {
                    (self.node_b[a] + self.node_b[c]) * 0.5
                }
            };
        }
    }

    /// Scales each element's gathered light so the kernels it reads sum to its covered
    /// fraction ([`conserve`]); after the links change.
    fn update_gain(&mut self) {
        if self.coverage.is_none() {
            let p = &self.problem;
            self.coverage = Some(conserve::Coverage::measure(&p.mesh, &p.bvh, p.epsilon));
        }
        let sums = self.pushed(&vec![Rgb::ONE; self.tree.nodes.len()]);
        let sums: Vec<f64> = (self.tree.leaf.iter())
            .map(|&l| {
                let s = sums[l as usize];
                (s.x + s.y + s.z) / 3.0
            })
            .collect();
        if let Some(coverage) = self.coverage.as_ref() {
            self.gain = coverage.gains(&sums);
        }
    }

    /// Memory of the links and the hierarchy, in bytes.
    pub fn bytes(&self) -> usize {
        self.links.capacity() * std::mem::size_of::<Link>()
            + self.link_start.len() * 4
            + self.blocks.capacity() * std::mem::size_of::<BlockLink>()
            + self.block_start.len() * 4
            + self.tree.bytes()
            + self.node_b.len() * 24
            + self.direct.capacity() * 24
            + self
                .shot_base
                .as_ref()
                .map_or(0, |b| (b.held.capacity() + b.shot.capacity()) * 24)
            + self.tree.clusters.len() * std::mem::size_of::<directional::Sh9>()
    }
}

/// The links of two lists sorted by receiver and sender, in one sorted list of exactly
/// their length: `a` grown once and merged into from its end (a few new links merged into
/// millions: no sort of the whole, and no second list of them all).
fn merge_sorted(mut a: Vec<Link>, b: Vec<Link>) -> Vec<Link> {
    let key = |l: &Link| (l.receiver, l.sender);
    let n = a.len();
    a.reserve_exact(b.len());
    a.extend_from_slice(&b);
    // Fill from the back: slot `k` takes the larger of `a[i - 1]` and `b[j - 1]`; `k`
    // never passes below `i`, so no item of `a` is overwritten before it is read.
    let (mut i, mut j, mut k) = (n, b.len(), a.len());
    while j > 0 {
        k -= 1;
        if i > 0 && key(&a[i - 1]) > key(&b[j - 1]) {
            a[k] = a[i - 1];
            i -= 1;
        } else {
            a[k] = b[j - 1];
            j -= 1;
        }
    }
    a.shrink_to_fit();
    a
}

#[cfg(test)]
#[test]
fn merged_links_are_sorted_and_complete() {
    let l = |r: u32, s: u32| Link::new(r, s, 0.0, 0.0);
    let keys = |v: &[Link]| v.iter().map(|l| (l.receiver, l.sender)).collect::<Vec<_>>();
    let a = vec![l(0, 1), l(2, 0), l(2, 5), l(7, 7)];
    let b = vec![l(0, 0), l(2, 3), l(9, 9)];
    let m = merge_sorted(a.clone(), b.clone());
    let mut expected = keys(&a);
    expected.extend(keys(&b));
    expected.sort();
    assert_eq!(keys(&m), expected);
    assert_eq!(keys(&merge_sorted(a.clone(), Vec::new())), keys(&a));
    assert_eq!(keys(&merge_sorted(Vec::new(), b.clone())), keys(&b));
}

/// The link maker on `problem`'s geometry and `tree`; `None` for an empty hierarchy.
fn linker<'a>(problem: &'a Problem, tree: &'a Hierarchy, basis: Basis) -> Option<Linker<'a>> {
    let root = tree.root()?;
    Some(Linker {
        mesh: &problem.mesh,
        bvh: &problem.bvh,
        tree,
        epsilon: problem.epsilon,
        seed: problem.config.formfactor.params.seed,
        reference_area: tree.nodes[root as usize].area / REFERENCE_RECEIVERS,
        flatlets: basis == Basis::Flatlet,
    })
}

/// Removes and returns the items for which `split` holds (evaluated in parallel).
fn take_where<T: Copy + Send + Sync>(
    items: &mut Vec<T>,
    split: impl Fn(&T) -> bool + Sync,
) -> Vec<T> {
    let flags: Vec<bool> = items.par_iter().map(&split).collect();
    let taken = items
        .iter()
        .zip(&flags)
        .filter(|(_, f)| **f)
        .map(|(x, _)| *x)
        .collect();
    let mut k = 0;
    items.retain(|_| {
        k += 1;
        !flags[k - 1]
    });
    taken
}

/// `start[i]..start[i + 1]` = the range of node `i` in a list sorted by receiver.
fn starts(nodes: usize, receivers: impl Iterator<Item = u32>) -> Vec<u32> {
    let mut start = vec![0u32; nodes + 1];
    for r in receivers {
        start[r as usize + 1] += 1;
    }
    for k in 1..start.len() {
        start[k] += start[k - 1];
    }
    start
}

#[cfg(test)]
mod tests;
