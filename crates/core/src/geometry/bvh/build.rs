//! Building the hierarchy: recursive binned surface-area-heuristic splits (`BINS` bins per
//! axis, leaves of at most `MAX_LEAF` triangles), nodes written depth-first. Large subtrees
//! are built on two threads; their nodes are joined in the order a serial build writes them,
//! so the tree is the same at any thread count.

use super::*;

/// Subtrees of at least this many triangles build their two halves in parallel.
pub(super) const PARALLEL_MIN: usize = 8192;

/// The nodes over `idx` (reordered so each leaf's triangles are contiguous).
pub(super) fn build_tree(
    idx: &mut [u32],
    boxes: &[Aabb],
    centers: &[DVec3],
    parallel_min: usize,
) -> Vec<Node> {
    let mut nodes = Vec::with_capacity(idx.len());
    let inputs = Inputs {
        boxes,
        centers,
        parallel_min,
    };
    build_rec(&mut nodes, idx, 0, &inputs);
    nodes
}

struct Inputs<'a> {
    boxes: &'a [Aabb],
    centers: &'a [DVec3],
    parallel_min: usize,
}

/// Appends the subtree over `idx` (which starts at `offset` in the whole index list) to
/// `nodes` and returns its root's index.
fn build_rec(nodes: &mut Vec<Node>, idx: &mut [u32], offset: usize, inputs: &Inputs) -> u32 {
    let (boxes, centers) = (inputs.boxes, inputs.centers);
    let me = nodes.len() as u32;
    let mut bounds = Aabb::EMPTY;
    let mut cbounds = Aabb::EMPTY;
    for &i in idx.iter() {
        bounds.grow(boxes[i as usize].min);
        bounds.grow(boxes[i as usize].max);
        cbounds.grow(centers[i as usize]);
    }
    let count = idx.len();
    nodes.push(Node {
        min: bounds.min.as_vec3(),
        max: bounds.max.as_vec3(),
        first_or_right: offset as u32,
        count: count as u32,
    });
    if count <= MAX_LEAF {
        return me;
    }
    let mid = match sah_split(idx, boxes, centers, &bounds, &cbounds) {
        Some(m) => m,
        None => {
            if count <= 16 {
                return me;
            }
            // All centres coincide or SAH says no: split in the middle of the list.
            count / 2
        }
    };
    let (left, right) = idx.split_at_mut(mid);
    let right = if count >= inputs.parallel_min {
        let ((), mut right_nodes) = rayon::join(
            || {
                build_rec(nodes, left, offset, inputs);
            },
            || {
                let mut v = Vec::with_capacity(right.len());
                build_rec(&mut v, right, offset + mid, inputs);
                v
            },
        );
        // The right subtree's interior nodes point at their right children within it.
        let base = nodes.len() as u32;
        for n in right_nodes.iter_mut().filter(|n| n.count == 0) {
            n.first_or_right += base;
        }
        nodes.append(&mut right_nodes);
        base
    } else {
        build_rec(nodes, left, offset, inputs);
        build_rec(nodes, right, offset + mid, inputs)
    };
    let n = &mut nodes[me as usize];
    n.count = 0;
    n.first_or_right = right;
    me
}

fn area(b: &Aabb) -> f64 {
    if b.is_empty() {
        return 0.0;
    }
    let d = b.max - b.min;
    d.x * d.y + d.y * d.z + d.z * d.x
}

/// The split of `idx` (reordered) with the lowest binned SAH cost: the index of the first
/// triangle on the right, or `None` where a leaf is cheaper or no split separates them.
fn sah_split(
    idx: &mut [u32],
    boxes: &[Aabb],
    centers: &[DVec3],
    bounds: &Aabb,
    cbounds: &Aabb,
) -> Option<usize> {
    let count = idx.len();
    let extent = cbounds.max - cbounds.min;
    let mut best = (f64::INFINITY, 0usize, 0usize);
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        let scale = BINS as f64 / extent[axis];
        let bin_of = |c: DVec3| (((c[axis] - cbounds.min[axis]) * scale) as usize).min(BINS - 1);
        for &i in idx.iter() {
            let b = bin_of(centers[i as usize]);
            bins[b].0.grow(boxes[i as usize].min);
            bins[b].0.grow(boxes[i as usize].max);
            bins[b].1 += 1;
        }
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for b in (1..BINS).rev() {
            if !bins[b].0.is_empty() {
                acc.grow(bins[b].0.min);
                acc.grow(bins[b].0.max);
            }
            n += bins[b].1;
            right_area[b] = area(&acc);
            right_count[b] = n;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for b in 0..BINS - 1 {
            if !bins[b].0.is_empty() {
                acc.grow(bins[b].0.min);
                acc.grow(bins[b].0.max);
            }
            n += bins[b].1;
            let cost = area(&acc) * n as f64 + right_area[b + 1] * right_count[b + 1] as f64;
            if n > 0 && right_count[b + 1] > 0 && cost < best.0 {
                best = (cost, axis, b);
            }
        }
    }
    if !best.0.is_finite() {
        return None;
    }
    let leaf_cost = area(bounds) * count as f64;
    if count <= MAX_LEAF * 4 && best.0 + area(bounds) * 0.5 >= leaf_cost {
        return None;
    }
    let (axis, split_bin) = (best.1, best.2);
    let scale = BINS as f64 / extent[axis];
    let slice = idx;
    let mut i = 0;
    let mut j = slice.len();
    while i < j {
        let c = centers[slice[i] as usize];
        let b = (((c[axis] - cbounds.min[axis]) * scale) as usize).min(BINS - 1);
        if b <= split_bin {
            i += 1;
        } else {
            j -= 1;
            slice.swap(i, j);
        }
    }
    if i == 0 || i == slice.len() {
        None
    } else {
        Some(i)
    }
}
