//! Wavelet radiosity with flatlets (Gortler, Schröder, Cohen & Hanrahan 1993, "Wavelet
//! Radiosity", §5): each node's radiosity is represented by box functions over its pieces,
//! and a link between two planar nodes carries the whole block of piece-to-piece kernels.
//!
//! Haar wavelet radiosity is hierarchical radiosity itself (Gortler et al. show that
//! push-pull over box functions is the nonstandard Haar transform), so `--solver
//! hierarchical` is the Haar case. The flatlet basis F2 puts 2 × 2 boxes on each square;
//! on our binary (median-split) surface trees that is a node's grandchildren, up to 4
//! pieces, and a link a 4 × 4 block. A block is kept when every piece pair passes the
//! hierarchical oracle (`Linker::decide`); otherwise the pair is split like a scalar link.
//! Links between clusters, or with a cluster on one end, stay scalar (clusters as in
//! hierarchical radiosity).
//!
//! Cost: a block stores 16 kernels (76 bytes against a link's 16) and costs 16 oracle
//! evaluations; its error is the pieces' (about half a node's size), the same first order
//! as hierarchical radiosity. Measured (docs/BENCHMARKS.md): at equal image error on the
//! Cornell box flatlets hold about half the memory of scalar links in about the same time
//! (2.53 % in 17.9 MB against 2.72 % in 39.6 MB), unlike the polynomial bases Willmott &
//! Heckbert found memory-hungry.

use super::link::{Decision, Linker};
use super::tree::Hierarchy;
use crate::scene::Rgb;

/// Pieces per node (grandchildren of a binary tree: one level of a quadtree).
pub const PIECES: usize = 4;

/// A flatlet block: piece `a` of `receiver` gathers `kernel[a * PIECES + b] × B(piece b of
/// sender)`; pieces are [`pieces`] of each node.
#[derive(Clone, Copy, Debug)]
pub struct BlockLink {
    pub receiver: u32,
    pub sender: u32,
    /// The largest of the piece pairs' oracle bounds, each over its receiver piece's share
    /// of the threshold (so `B_max(sender) × bound > ε` says a piece pair needs a split).
    pub bound: f32,
    pub kernel: [f32; PIECES * PIECES],
}

/// What [`Linker::decide_block`] found for a planar pair.
pub(super) enum BlockDecision {
    Drop,
    Keep(BlockLink),
    Split(Decision),
}

/// The pieces of node `n`: its grandchildren, a child that is a leaf standing for itself;
/// a leaf is its own single piece.
pub fn pieces(tree: &Hierarchy, n: u32) -> ([u32; PIECES], usize) {
    let mut out = [0u32; PIECES];
    let mut len = 0;
    let node = &tree.nodes[n as usize];
    if node.is_leaf() {
        out[0] = n;
        return (out, 1);
    }
    for c in node.children {
        let child = &tree.nodes[c as usize];
        if child.is_leaf() {
            out[len] = c;
            len += 1;
        } else {
            for g in child.children {
                out[len] = g;
                len += 1;
            }
        }
    }
    (out, len)
}

/// What each receiver piece of `block` gathers from the sender's pieces.
pub fn block_gather(
    tree: &Hierarchy,
    block: &BlockLink,
    b: &[Rgb],
) -> ([u32; PIECES], usize, [Rgb; PIECES]) {
    let (pi, ni) = pieces(tree, block.receiver);
    let (pj, nj) = pieces(tree, block.sender);
    let mut out = [Rgb::ZERO; PIECES];
    for (a, o) in out[..ni].iter_mut().enumerate() {
        for (c, &q) in pj[..nj].iter().enumerate() {
            *o += b[q as usize] * block.kernel[a * PIECES + c] as f64;
        }
    }
    (pi, ni, out)
}

impl Linker<'_> {
    /// The oracle for a block between two planar, non-overlapping nodes: every piece pair
    /// decided as a scalar link would be; any split among them splits the pair (the larger
    /// node, as `Linker::decide` chooses).
    pub(super) fn decide_block(&self, i: u32, j: u32, b: &[Rgb], eps: f64) -> BlockDecision {
        let (pi, ni) = pieces(self.tree, i);
        let (pj, nj) = pieces(self.tree, j);
        let mut kernel = [0f32; PIECES * PIECES];
        let mut bound = 0f64;
        let mut any = false;
        for (a, &p) in pi[..ni].iter().enumerate() {
            let share = self.receiver_eps(p, 1.0);
            for (c, &q) in pj[..nj].iter().enumerate() {
                match self.decide(p, q, b[q as usize].max_element(), eps) {
                    Decision::Drop => {}
                    Decision::Accept {
                        kernel: k,
                        bound: kb,
                    } => {
                        kernel[a * PIECES + c] = k as f32;
                        bound = bound.max(kb / share);
                        any |= k > 0.0 || kb > 0.0;
                    }
                    _ => return BlockDecision::Split(self.split_choice(i, j)),
                }
            }
        }
        if !any {
            return BlockDecision::Drop;
        }
        BlockDecision::Keep(BlockLink {
            receiver: i,
            sender: j,
            bound: bound as f32,
            kernel,
        })
    }

    /// Whether a kept block should now be split, given the node radiosities.
    pub fn block_needs_split(&self, block: &BlockLink, b: &[Rgb], eps: f64) -> bool {
        let (pj, nj) = pieces(self.tree, block.sender);
        let b_max = pj[..nj]
            .iter()
            .map(|&q| b[q as usize].max_element())
            .fold(0.0, f64::max);
        b_max * block.bound as f64 > eps
            && !(self.tree.nodes[block.receiver as usize].is_leaf()
                && self.tree.nodes[block.sender as usize].is_leaf())
    }
}
