//! The element hierarchy of hierarchical radiosity: binary trees over planar groups of
//! elements, joined by a volume hierarchy of clusters.
//!
//! A *planar group* is the elements of one surface side whose elements share its plane
//! (normals within [`PLANAR_COS`]): its tree splits the elements at the median of their
//! centroids along the longest axis, two levels standing for one quadtree level of Hanrahan,
//! Salzman & Aupperle (1991). Elements of a patch that is not planar (clustered facets of a
//! curved model) are each a group of one. The groups are joined top-down by a midpoint-split
//! volume hierarchy (Smits, Arvo & Greenberg 1994; Sillion 1995): its inner nodes are
//! *clusters*, which send as isotropic emitters and receive a directional irradiance
//! ([`super::directional`]), so initial linking is one root-to-root link refined top-down, O(s log s) in the number of
//! groups instead of O(s²).
//!
//! Nodes are stored in pre-order (a parent before its children) and every node's elements
//! are one contiguous range of [`Hierarchy::order`], so a top-down pass is a forward loop,
//! a bottom-up pass a backward one, and two nodes overlap exactly when their ranges do.

use glam::DVec3;

use super::directional;
use crate::mesh::Mesh;

/// Elements whose normals are within this cosine of their surface's are one planar group.
pub const PLANAR_COS: f64 = 0.9995;

/// No child (a leaf).
pub const NONE: u32 = u32::MAX;

#[derive(Clone, Debug)]
pub struct Node {
    /// Start of the node's elements in [`Hierarchy::order`].
    pub first: u32,
    pub count: u32,
    /// Children, [`NONE`] for a leaf (one element).
    pub children: [u32; 2],
    pub area: f64,
    /// Area-weighted centroid.
    pub centroid: DVec3,
    /// Unit normal of a planar node; zero for a cluster.
    pub normal: DVec3,
    /// Radius of a sphere about `centroid` holding every element corner.
    pub radius: f64,
}

impl Node {
    pub fn is_leaf(&self) -> bool {
        self.children[0] == NONE
    }
    pub fn is_cluster(&self) -> bool {
        self.normal == DVec3::ZERO
    }
    /// Whether the element ranges of `self` and `other` intersect (one holds the other).
    pub fn overlaps(&self, other: &Node) -> bool {
        self.first < other.first + other.count && other.first < self.first + self.count
    }
}

pub struct Hierarchy {
    pub nodes: Vec<Node>,
    /// Element ids in node order.
    pub order: Vec<u32>,
    /// `area_prefix[k]` = total area of `order[..k]` (for area-weighted sampling).
    pub area_prefix: Vec<f64>,
    /// The leaf node of each element.
    pub leaf: Vec<u32>,
    /// The parent of each node ([`NONE`] for the root).
    pub parent: Vec<u32>,
    pub planar_groups: usize,
    /// The cluster nodes (pre-order) and each node's index among them ([`NONE`] if planar).
    pub clusters: Vec<u32>,
    pub cluster_slot: Vec<u32>,
    /// Per cluster: its projected area as a function of direction, `Σ A max(n·ω, 0)` over
    /// its planar groups, in harmonics ([`directional::clamped_cosine_sum`]).
    pub projected: Vec<directional::Sh9Scalar>,
    /// Each element's centroid, normal and area in node order (`samples[k]` is element
    /// `order[k]`'s), for drawing candidates from a cluster's elements.
    pub samples: Vec<ElementSample>,
}

/// An element's centroid, normal and area, one cache line each: the links' visibility
/// rays weigh 16 random elements of a cluster per ray, and reading them from the mesh (three
/// lines of a 180-byte element, behind the `order` lookup) was about 15 % of the Crytek
/// atrium's refinement, waiting on memory.
#[derive(Clone, Copy, Debug)]
#[repr(align(64))]
pub struct ElementSample {
    pub centroid: DVec3,
    pub normal: DVec3,
    pub area: f64,
}

/// One planar group (or a single element of a curved patch).
struct Group {
    elements: Vec<u32>,
    normal: DVec3,
    centroid: DVec3,
}

impl Hierarchy {
    /// Builds the hierarchy over every element of `mesh`. An empty mesh gives no nodes.
    pub fn build(mesh: &Mesh) -> Hierarchy {
        let groups = planar_groups(mesh);
        let mut h = Hierarchy {
            nodes: Vec::with_capacity(2 * mesh.elements.len()),
            order: Vec::with_capacity(mesh.elements.len()),
            area_prefix: Vec::new(),
            leaf: vec![NONE; mesh.elements.len()],
            parent: Vec::with_capacity(2 * mesh.elements.len()),
            planar_groups: groups.len(),
            clusters: Vec::new(),
            cluster_slot: Vec::new(),
            projected: Vec::new(),
            samples: Vec::new(),
        };
        if !groups.is_empty() {
            let mut ids: Vec<u32> = (0..groups.len() as u32).collect();
            h.build_clusters(mesh, &groups, &mut ids, NONE);
        }
        let mut sum = 0.0;
        h.area_prefix.reserve(h.order.len() + 1);
        h.area_prefix.push(0.0);
        for &e in &h.order {
            sum += mesh.elements[e as usize].area;
            h.area_prefix.push(sum);
        }
        h.samples = (h.order.iter())
            .map(|&e| {
                let e = &mesh.elements[e as usize];
                ElementSample {
                    centroid: e.centroid,
                    normal: e.normal,
                    area: e.area,
                }
            })
            .collect();
        h.clusters = (0..h.nodes.len() as u32)
            .filter(|&n| h.nodes[n as usize].is_cluster())
            .collect();
        h.cluster_slot = vec![NONE; h.nodes.len()];
        for (k, &n) in h.clusters.iter().enumerate() {
            h.cluster_slot[n as usize] = k as u32;
        }
        // Children after parents in pre-order: sum bottom-up.
        h.projected = vec![[0.0; 9]; h.clusters.len()];
        for k in (0..h.clusters.len()).rev() {
            let node = &h.nodes[h.clusters[k] as usize];
            let mut sh = [0.0; 9];
            for c in node.children {
                let child = &h.nodes[c as usize];
                match h.cluster_slot[c as usize] {
                    NONE => directional::add_scalar(&mut sh, child.normal, child.area),
                    slot => {
                        for (a, b) in sh.iter_mut().zip(h.projected[slot as usize]) {
                            *a += b;
                        }
                    }
                }
            }
            h.projected[k] = sh;
        }
        h
    }

    /// A cluster's projected area towards unit direction `w` (towards the viewer);
    /// `None` for a planar node.
    pub fn projected_area(&self, node: u32, w: DVec3) -> Option<f64> {
        match self.cluster_slot[node as usize] {
            NONE => None,
            slot => Some(directional::clamped_cosine_sum(
                &self.projected[slot as usize],
                w,
            )),
        }
    }

    pub fn root(&self) -> Option<u32> {
        (!self.nodes.is_empty()).then_some(0)
    }

    /// Memory held, in bytes.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * (std::mem::size_of::<Node>() + 8)
            + self.clusters.len() * (4 + std::mem::size_of::<directional::Sh9Scalar>())
            + self.order.len() * 4
            + self.area_prefix.len() * 8
            + self.leaf.len() * 4
            + self.samples.len() * std::mem::size_of::<ElementSample>()
    }

    /// The element of `node` at area fraction `u` in [0, 1).
    pub fn element_at(&self, node: &Node, u: f64) -> u32 {
        let lo = node.first as usize;
        let hi = lo + node.count as usize;
        let target = self.area_prefix[lo] + u * (self.area_prefix[hi] - self.area_prefix[lo]);
        // First k in lo..hi with prefix[k + 1] > target.
        let slice = &self.area_prefix[lo + 1..=hi];
        let k = slice
            .partition_point(|&p| p <= target)
            .min(node.count as usize - 1);
        self.order[lo + k]
    }

    fn push(&mut self, node: Node, parent: u32) -> u32 {
        self.nodes.push(node);
        self.parent.push(parent);
        (self.nodes.len() - 1) as u32
    }

    /// A volume hierarchy over `ids` (groups), split at the middle of the longest axis.
    fn build_clusters(
        &mut self,
        mesh: &Mesh,
        groups: &[Group],
        ids: &mut [u32],
        parent: u32,
    ) -> u32 {
        if ids.len() == 1 {
            let g = &groups[ids[0] as usize];
            let mut elements = g.elements.clone();
            return self.build_planar(mesh, &mut elements, g.normal, parent);
        }
        let (lo, hi) = bounds(ids.iter().map(|&g| groups[g as usize].centroid));
        let axis = longest_axis(hi - lo);
        // Spatial midpoint split (clusters are regions of space: a light far from an object
        // must not share a cluster with half of it); the median if one side would be empty.
        let middle = 0.5 * (lo[axis] + hi[axis]);
        let key = |g: &u32| groups[*g as usize].centroid[axis];
        ids.sort_unstable_by(|a, b| key(a).total_cmp(&key(b)).then(a.cmp(b)));
        let mut mid = ids.partition_point(|g| key(g) < middle);
        if mid == 0 || mid == ids.len() {
            mid = ids.len() / 2;
        }
        let first = self.order.len() as u32;
        let me = self.push(placeholder(first), parent);
        let (left, right) = ids.split_at_mut(mid);
        let a = self.build_clusters(mesh, groups, left, me);
        let b = self.build_clusters(mesh, groups, right, me);
        self.finish_inner(mesh, me, [a, b], DVec3::ZERO);
        me
    }

    /// A binary tree over the elements of one planar group.
    fn build_planar(
        &mut self,
        mesh: &Mesh,
        elements: &mut [u32],
        normal: DVec3,
        parent: u32,
    ) -> u32 {
        let first = self.order.len() as u32;
        if elements.len() == 1 {
            let e = elements[0];
            let el = &mesh.elements[e as usize];
            self.order.push(e);
            let radius = el
                .corners()
                .iter()
                .map(|c| (*c - el.centroid).length())
                .fold(0.0, f64::max);
            // A leaf keeps its own normal: it is exact for the element.
            let node = Node {
                first,
                count: 1,
                children: [NONE; 2],
                area: el.area,
                centroid: el.centroid,
                normal: el.normal,
                radius,
            };
            let me = self.push(node, parent);
            self.leaf[e as usize] = me;
            return me;
        }
        let (lo, hi) = bounds(elements.iter().map(|&e| mesh.elements[e as usize].centroid));
        let axis = longest_axis(hi - lo);
        let mid = elements.len() / 2;
        elements.select_nth_unstable_by(mid, |a, b| {
            let (ca, cb) = (
                mesh.elements[*a as usize].centroid,
                mesh.elements[*b as usize].centroid,
            );
            ca[axis].total_cmp(&cb[axis]).then(a.cmp(b))
        });
        let me = self.push(placeholder(first), parent);
        let (left, right) = elements.split_at_mut(mid);
        let a = self.build_planar(mesh, left, normal, me);
        let b = self.build_planar(mesh, right, normal, me);
        self.finish_inner(mesh, me, [a, b], normal);
        me
    }

    /// Fills an inner node from its children (which follow it in `order`).
    fn finish_inner(&mut self, mesh: &Mesh, me: u32, children: [u32; 2], normal: DVec3) {
        let (a, b) = (
            &self.nodes[children[0] as usize],
            &self.nodes[children[1] as usize],
        );
        let area = a.area + b.area;
        let centroid = if area > 0.0 {
            (a.centroid * a.area + b.centroid * b.area) / area
        } else {
            (a.centroid + b.centroid) * 0.5
        };
        let first = self.nodes[me as usize].first;
        let count = a.count + b.count;
        // The exact radius over the corners (a bound from the children's spheres grows
        // with depth).
        let radius = self.order[first as usize..(first + count) as usize]
            .iter()
            .flat_map(|&e| mesh.elements[e as usize].corners().iter())
            .map(|c| (*c - centroid).length())
            .fold(0.0, f64::max);
        let node = &mut self.nodes[me as usize];
        node.count = count;
        node.children = children;
        node.area = area;
        node.centroid = centroid;
        node.normal = normal;
        node.radius = radius;
    }
}

fn placeholder(first: u32) -> Node {
    Node {
        first,
        count: 0,
        children: [NONE; 2],
        area: 0.0,
        centroid: DVec3::ZERO,
        normal: DVec3::ZERO,
        radius: 0.0,
    }
}

fn bounds(points: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    points.fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    )
}

fn longest_axis(extent: DVec3) -> usize {
    if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    }
}

/// The planar groups of `mesh`: per patch, its elements if they all lie within
/// [`PLANAR_COS`] of the patch normal (patches of one surface side joined), else one group
/// per element.
fn planar_groups(mesh: &Mesh) -> Vec<Group> {
    use std::collections::BTreeMap;
    // Surface side: (first face of the surface, back side).
    let mut surfaces: BTreeMap<(usize, bool), Vec<u32>> = BTreeMap::new();
    let mut groups = Vec::new();
    for p in &mesh.patches {
        let range = p.elements.start..p.elements.end;
        let planar = mesh.elements[range.start as usize..range.end as usize]
            .iter()
            .all(|e| e.normal.dot(p.normal) >= PLANAR_COS);
        if planar {
            surfaces.entry((p.face, p.back)).or_default().extend(range);
        } else {
            for e in range {
                let el = &mesh.elements[e as usize];
                groups.push(Group {
                    elements: vec![e],
                    normal: el.normal,
                    centroid: el.centroid,
                });
            }
        }
    }
    for (_, elements) in surfaces {
        let mut area = 0.0;
        let mut centroid = DVec3::ZERO;
        let mut normal = DVec3::ZERO;
        for &e in &elements {
            let el = &mesh.elements[e as usize];
            area += el.area;
            centroid += el.centroid * el.area;
            normal += el.normal * el.area;
        }
        let centroid = if area > 0.0 {
            centroid / area
        } else {
            mesh.elements[elements[0] as usize].centroid
        };
        let normal = normal
            .try_normalize()
            .unwrap_or(mesh.elements[elements[0] as usize].normal);
        groups.push(Group {
            elements,
            normal,
            centroid,
        });
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::MeshSpec;
    use crate::scene::{LoadOptions, Scene};

    #[test]
    fn every_element_is_one_leaf_and_ranges_nest() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let mesh = Mesh::build(&scene, &MeshSpec::element(60.0)).expect("mesh");
        let h = Hierarchy::build(&mesh);
        assert_eq!(h.order.len(), mesh.elements.len());
        let mut seen = vec![false; mesh.elements.len()];
        for &e in &h.order {
            assert!(!seen[e as usize], "element {e} twice");
            seen[e as usize] = true;
        }
        let total: f64 = mesh.elements.iter().map(|e| e.area).sum();
        assert!((h.nodes[0].area - total).abs() < 1e-9 * total);
        for (i, n) in h.nodes.iter().enumerate() {
            if n.is_leaf() {
                assert_eq!(n.count, 1);
                assert_eq!(h.leaf[h.order[n.first as usize] as usize], i as u32);
                continue;
            }
            let [a, b] = n.children.map(|c| &h.nodes[c as usize]);
            assert_eq!(a.first, n.first);
            assert_eq!(b.first, a.first + a.count);
            assert_eq!(a.count + b.count, n.count);
            assert!((a.area + b.area - n.area).abs() <= 1e-9 * n.area);
            // Pre-order: children after the parent, and a planar node's children planar.
            assert!(n.children.iter().all(|&c| c as usize > i));
            if !n.is_cluster() {
                assert!(!a.is_cluster() && !b.is_cluster());
            }
            for &e in &h.order[n.first as usize..(n.first + n.count) as usize] {
                for c in mesh.elements[e as usize].corners() {
                    assert!((*c - n.centroid).length() <= n.radius * (1.0 + 1e-12));
                }
            }
        }
        // The Cornell box: each wall side is one planar group (5 walls, 2 blocks of 5
        // visible faces, a light; the ceiling is cut by the light).
        assert!(h.planar_groups < 30, "{} groups", h.planar_groups);
    }

    #[test]
    fn area_sampling_picks_elements_by_area() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let mesh = Mesh::build(&scene, &MeshSpec::element(60.0)).expect("mesh");
        let h = Hierarchy::build(&mesh);
        let root = &h.nodes[0];
        let n = 20_000;
        let mut hits = vec![0usize; mesh.elements.len()];
        for k in 0..n {
            hits[h.element_at(root, (k as f64 + 0.5) / n as f64) as usize] += 1;
        }
        // Stratified: each element's count is its area share within one stratum each side.
        for (e, el) in mesh.elements.iter().enumerate() {
            let expect = el.area / root.area * n as f64;
            assert!((hits[e] as f64 - expect).abs() <= 1.0 + 1e-9, "{e}");
        }
    }
}
