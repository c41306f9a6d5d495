//! Clusters of small faces: the polygons a cluster is meshed as, and the planar proxy
//! patch that shoots for them (its mean plane, convex hull and prism for shaft culling).

use glam::DVec3;
use rustc_hash::{FxHashMap, FxHashSet};

use super::surfaces::Topology;
use super::{Element, Patch};
use crate::geometry::polygon;
use crate::scene::Scene;

/// The polygons a cluster of faces is meshed as: each small planar surface whose faces
/// all fell in the cluster as its outline (no element edge along its triangulation), every
/// other face as itself. Order follows the faces.
pub(super) fn cluster_parts(
    scene: &Scene,
    topo: &Topology,
    small_outline: &FxHashMap<u32, (Vec<DVec3>, usize)>,
    faces: &[u32],
) -> Vec<(Vec<DVec3>, usize)> {
    let mut count: FxHashMap<u32, usize> = FxHashMap::default();
    for &f in faces {
        *count.entry(topo.planar[f as usize]).or_default() += 1;
    }
    let mut done: FxHashSet<u32> = FxHashSet::default();
    let mut parts = Vec::new();
    for &f in faces {
        let surface = topo.planar[f as usize];
        match small_outline.get(&surface) {
            Some((outline, members)) if count[&surface] == *members => {
                if done.insert(surface) {
                    parts.push((outline.clone(), f as usize));
                }
            }
            _ => parts.push((scene.faces[f as usize].vertices.clone(), f as usize)),
        }
    }
    parts
}

/// A patch shooting for several small faces: a planar proxy polygon of the cluster's area
/// in its mean plane (the convex hull of the corners projected on that plane, shrunk about
/// its centroid to the cluster's area) and, for shaft culling, the hull lifted to the
/// highest and lowest corner (a prism holding every element).
pub(super) fn cluster_patch(
    scene: &Scene,
    face: usize,
    occluder: u32,
    back: bool,
    elements: &[Element],
    first: u32,
) -> Patch {
    let area: f64 = elements.iter().map(|e| e.area).sum();
    let centroid = elements.iter().map(|e| e.centroid * e.area).sum::<DVec3>() / area;
    let mean: DVec3 = elements.iter().map(|e| e.normal * e.area).sum();
    let normal = mean
        .try_normalize()
        .unwrap_or_else(|| elements[0].normal.try_normalize().unwrap_or(DVec3::Z));
    let (t1, t2) = normal.any_orthonormal_pair();
    let mut points: Vec<(f64, f64)> = Vec::new();
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for e in elements {
        for c in e.corners() {
            let d = *c - centroid;
            points.push((d.dot(t1), d.dot(t2)));
            lo = lo.min(d.dot(normal));
            hi = hi.max(d.dot(normal));
        }
    }
    let hull = convex_hull_2d(&mut points);
    let lift = |(u, v): (f64, f64), h: f64| centroid + t1 * u + t2 * v + normal * h;
    let outline: Vec<DVec3> = hull.iter().map(|&p| lift(p, 0.0)).collect();
    let hull_area = polygon::area(&outline);
    let mut polygon: Vec<DVec3> = if hull.len() >= 3 && hull_area > 0.0 {
        let c2 = polygon::centroid(&outline);
        let k = (area / hull_area).sqrt().min(1.0);
        outline.iter().map(|p| c2 + (*p - c2) * k).collect()
    } else {
        elements[0].corners().to_vec()
    };
    if polygon::normal(&polygon).is_some_and(|n| n.dot(normal) < 0.0) {
        polygon.reverse();
    }
    // The hull starts at its lexicographically smallest point, which round-off decides
    // among points of equal coordinates (another unit, another start): start at a vertex
    // that does not depend on it, so the shooter's samplers do not either.
    let start = polygon::canonical_start(&polygon);
    polygon.rotate_left(start);
    let mut bounds: Vec<DVec3> = hull.iter().map(|&p| lift(p, lo)).collect();
    bounds.extend(hull.iter().map(|&p| lift(p, hi)));
    if bounds.is_empty() {
        bounds = polygon.clone();
    }
    Patch {
        face,
        source_face: scene.faces[face].source_face,
        occluder,
        material: scene.faces[face].material,
        area,
        centroid,
        radius: bounds
            .iter()
            .map(|v| (*v - centroid).length())
            .fold(0.0, f64::max),
        largest_element_area: elements.iter().map(|e| e.area).fold(0.0, f64::max),
        polygon,
        bounds,
        normal,
        elements: first..first + elements.len() as u32,
        back,
    }
}

/// Counter-clockwise convex hull (Andrew's monotone chain); collinear points dropped.
pub(super) fn convex_hull_2d(points: &mut [(f64, f64)]) -> Vec<(f64, f64)> {
    points.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    if points.len() < 3 {
        return points.to_vec();
    }
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let mut hull: Vec<(f64, f64)> = Vec::with_capacity(points.len() * 2);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &(f64, f64)>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}
