//! Which input faces belong together: welded topology, planar surfaces, smooth groups and
//! shooter clusters.
//!
//! A modelling program exports a wall as two triangles, a floor as a grid of quads and a
//! sphere as thousands of facets. Meshing each input face on its own puts element
//! boundaries along the triangulation, turns every tiny facet into a shooter and shades a
//! sphere flat. Here faces are grouped once, in time linear in the number of faces (hash
//! maps keyed by welded vertices and quantised planes, union–find; no pairwise search):
//! - a *planar surface* is a set of edge-adjacent faces of one material in one plane; when
//!   its outline is one convex polygon it is meshed as that polygon;
//! - a *display group* joins faces whose radiance is interpolated across their shared
//!   vertices: coplanar faces of one material (adjacent or not, so T-junctions still
//!   interpolate) and edge-adjacent faces of one material meeting at less than
//!   [`SMOOTH_ANGLE_DEG`] (a curved surface shades round, a box keeps its creases);
//! - small faces of one display group are *clustered* into shooters of about one patch.

use std::collections::VecDeque;

use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::{FxHashMap, FxHashSet};

use crate::geometry::polygon;
use crate::scene::Scene;

/// Edge-adjacent faces of one material meeting at a smaller angle than this are one smooth
/// surface (Blender's auto-smooth default).
pub const SMOOTH_ANGLE_DEG: f64 = 30.0;

/// Two faces are coplanar when their normals differ by less than this (radians, ~0.06°).
const COPLANAR_ANGLE: f64 = 1e-3;

/// Faces grouped for meshing and display.
pub(crate) struct Topology {
    pub normal: Vec<DVec3>,
    pub area: Vec<f64>,
    pub centroid: Vec<DVec3>,
    /// Welded vertex ids per face (same order as the face's vertices).
    pub welded: Vec<Vec<u32>>,
    /// Edge-adjacent faces (CSR).
    adjacency_start: Vec<u32>,
    adjacency: Vec<u32>,
    /// Planar surface of each face (edge-adjacent, coplanar, same material).
    pub planar: Vec<u32>,
    pub planar_count: usize,
    /// Display group of each face.
    pub display: Vec<u32>,
    /// Faces that repeat another face of the same material and plane: the same vertices
    /// (a duplicate) or lying wholly inside it (a coplanar overlap). Meshing them would
    /// count their area twice; they are left out of the mesh (not of the blockers).
    /// Partial overlaps are not detected.
    pub redundant: Vec<bool>,
}

/// Coplanar groups larger than this are not searched for faces lying inside others (the
/// search is quadratic in the group).
const MAX_OVERLAP_GROUP: usize = 64;

struct UnionFind(Vec<u32>);

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind((0..n as u32).collect())
    }
    fn find(&mut self, mut a: u32) -> u32 {
        while self.0[a as usize] != a {
            let up = self.0[self.0[a as usize] as usize];
            self.0[a as usize] = up;
            a = up;
        }
        a
    }
    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    /// Dense labels 0..count in order of first appearance.
    fn labels(&mut self) -> (Vec<u32>, usize) {
        let n = self.0.len();
        let mut label = vec![u32::MAX; n];
        let mut out = Vec::with_capacity(n);
        let mut count = 0;
        for i in 0..n as u32 {
            let r = self.find(i) as usize;
            if label[r] == u32::MAX {
                label[r] = count;
                count += 1;
            }
            out.push(label[r]);
        }
        (out, count as usize)
    }
}

/// Welded vertex ids per face: positions within ~1e-7 of the scene's size (`diag`) are one
/// vertex.
fn weld(scene: &Scene, diag: f64) -> Vec<Vec<u32>> {
    let weld = 1e-7 * diag;
    let corners = scene.faces.iter().map(|f| f.vertices.len()).sum();
    let mut ids: FxHashMap<(i64, i64, i64), u32> =
        FxHashMap::with_capacity_and_hasher(corners, Default::default());
    let mut welded = Vec::with_capacity(scene.faces.len());
    for f in &scene.faces {
        let w: Vec<u32> = f
            .vertices
            .iter()
            .map(|p| {
                let q = (*p / weld).round();
                let next = ids.len() as u32;
                *ids.entry((q.x as i64, q.y as i64, q.z as i64))
                    .or_insert(next)
            })
            .collect();
        welded.push(w);
    }
    welded
}

/// The pairs of faces sharing a welded edge, both ways, sorted. The undirected edges are
/// sorted with the faces using them (no map of lists): a face's edges in order, then
/// grouped by edge.
fn edge_pairs(welded: &[Vec<u32>]) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32, u32)> = Vec::with_capacity(welded.iter().map(Vec::len).sum());
    for (fi, w) in welded.iter().enumerate() {
        for k in 0..w.len() {
            let (a, b) = (w[k], w[(k + 1) % w.len()]);
            if a != b {
                edges.push((a.min(b), a.max(b), fi as u32));
            }
        }
    }
    edges.par_sort_unstable();
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for list in edges.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
        // A non-manifold edge (more than two faces) joins nothing: ambiguous.
        if list.len() == 2 && list[0].2 != list[1].2 {
            pairs.push((list[0].2, list[1].2));
            pairs.push((list[1].2, list[0].2));
        }
    }
    pairs.par_sort_unstable();
    pairs.dedup();
    pairs
}

/// The faces of a scene with their plane data, for grouping them.
struct Faces<'a> {
    scene: &'a Scene,
    normal: &'a [DVec3],
    area: &'a [f64],
    centroid: &'a [DVec3],
    /// The scene's diagonal (tolerances are relative to it).
    diag: f64,
}

impl Faces<'_> {
    /// Edge-adjacent faces joined into planar surfaces (coplanar, same material) and into
    /// display groups (same material, meeting at less than [`SMOOTH_ANGLE_DEG`]).
    fn join_adjacent(&self, pairs: &[(u32, u32)]) -> (UnionFind, UnionFind) {
        let (faces, normal, centroid) = (&self.scene.faces, self.normal, self.centroid);
        let n = faces.len();
        let same_plane = |a: usize, b: usize| {
            faces[a].material == faces[b].material
                && normal[a].dot(normal[b]) > (COPLANAR_ANGLE).cos()
                && (normal[a].dot(centroid[b] - centroid[a])).abs() < 1e-6 * self.diag
        };
        let mut planar_uf = UnionFind::new(n);
        let mut display_uf = UnionFind::new(n);
        let cos_smooth = SMOOTH_ANGLE_DEG.to_radians().cos();
        for &(a, b) in pairs {
            let (a, b) = (a as usize, b as usize);
            if a > b {
                continue;
            }
            if same_plane(a, b) {
                planar_uf.union(a as u32, b as u32);
            }
            if faces[a].material == faces[b].material && normal[a].dot(normal[b]) > cos_smooth {
                display_uf.union(a as u32, b as u32);
            }
        }
        (planar_uf, display_uf)
    }

    /// The faces of each quantised plane and material. Coplanar faces of one material
    /// share display vertices even when they only meet at T-junctions (no shared welded
    /// edge), so each plane's faces are joined in `display_uf`.
    fn planes(&self, display_uf: &mut UnionFind) -> FxHashMap<(u32, [i64; 4]), Vec<u32>> {
        let (normal, centroid) = (self.normal, self.centroid);
        let mut planes: FxHashMap<(u32, [i64; 4]), Vec<u32>> = FxHashMap::default();
        for (fi, f) in self.scene.faces.iter().enumerate() {
            if normal[fi] == DVec3::ZERO {
                continue;
            }
            let nq = (normal[fi] * 1e4).round();
            let d = (normal[fi].dot(centroid[fi]) / (1e-5 * self.diag)).round();
            let key = (
                f.material.0,
                [nq.x as i64, nq.y as i64, nq.z as i64, d as i64],
            );
            let members = planes.entry(key).or_default();
            if let Some(&g) = members.first() {
                display_uf.union(g, fi as u32);
            }
            members.push(fi as u32);
        }
        planes
    }

    /// [`Topology::redundant`]: duplicates (same welded vertices, material and
    /// orientation), then, in each plane of `planes` of at most [`MAX_OVERLAP_GROUP`]
    /// faces, faces lying inside a larger convex face.
    fn redundant(
        &self,
        welded: &[Vec<u32>],
        planes: &FxHashMap<(u32, [i64; 4]), Vec<u32>>,
    ) -> Vec<bool> {
        let (faces, normal, area) = (&self.scene.faces, self.normal, self.area);
        let mut redundant = vec![false; faces.len()];
        // Per face, its sorted vertex ids and quantised normal, all in one buffer.
        let mut keys: Vec<u32> = Vec::with_capacity(welded.iter().map(|w| w.len() + 3).sum());
        let mut ends = Vec::with_capacity(welded.len());
        for (fi, w) in welded.iter().enumerate() {
            let start = keys.len();
            keys.extend_from_slice(w);
            keys[start..].sort_unstable();
            let q = (normal[fi] * 1e4).round();
            keys.extend([q.x as i64 as u32, q.y as i64 as u32, q.z as i64 as u32]);
            ends.push(keys.len());
        }
        let mut seen: FxHashSet<(u32, &[u32])> = FxHashSet::default();
        let mut start = 0;
        for (fi, &end) in ends.iter().enumerate() {
            // Same vertex set, material and orientation as an earlier face: a duplicate.
            redundant[fi] = !seen.insert((faces[fi].material.0, &keys[start..end]));
            start = end;
        }
        for members in planes.values() {
            if members.len() < 2 || members.len() > MAX_OVERLAP_GROUP {
                continue;
            }
            for &inner in members {
                let fi = inner as usize;
                if redundant[fi] {
                    continue;
                }
                let inside_other = members.iter().any(|&outer| {
                    let fo = outer as usize;
                    fo != fi
                        && !redundant[fo]
                        && area[fo] > area[fi]
                        && polygon::is_convex(&faces[fo].vertices)
                        && faces[fi].vertices.iter().all(|p| {
                            inside_convex(&faces[fo].vertices, normal[fo], *p, 1e-9 * self.diag)
                        })
                });
                redundant[fi] = inside_other;
            }
        }
        redundant
    }
}

impl Topology {
    pub fn new(scene: &Scene) -> Topology {
        let faces = &scene.faces;
        let n = faces.len();
        let diag = scene.bounds().diagonal().max(1e-300);
        let welded = weld(scene, diag);
        let normal: Vec<DVec3> = faces
            .par_iter()
            .map(|f| polygon::normal(&f.vertices).unwrap_or(DVec3::ZERO))
            .collect();
        let area: Vec<f64> = faces
            .par_iter()
            .map(|f| polygon::area(&f.vertices))
            .collect();
        let centroid: Vec<DVec3> = faces
            .par_iter()
            .map(|f| polygon::centroid(&f.vertices))
            .collect();
        let pairs = edge_pairs(&welded);
        let mut adjacency_start = vec![0u32; n + 1];
        for &(a, _) in &pairs {
            adjacency_start[a as usize + 1] += 1;
        }
        for i in 0..n {
            adjacency_start[i + 1] += adjacency_start[i];
        }
        let adjacency: Vec<u32> = pairs.iter().map(|&(_, b)| b).collect();
        let faces_of = Faces {
            scene,
            normal: &normal,
            area: &area,
            centroid: &centroid,
            diag,
        };
        let (mut planar_uf, mut display_uf) = faces_of.join_adjacent(&pairs);
        let planes = faces_of.planes(&mut display_uf);
        let redundant = faces_of.redundant(&welded, &planes);
        let (planar, planar_count) = planar_uf.labels();
        let (display, _) = display_uf.labels();
        Topology {
            normal,
            area,
            centroid,
            welded,
            adjacency_start,
            adjacency,
            planar,
            planar_count,
            display,
            redundant,
        }
    }

    pub fn neighbours(&self, face: usize) -> &[u32] {
        &self.adjacency
            [self.adjacency_start[face] as usize..self.adjacency_start[face + 1] as usize]
    }

    /// Faces of each planar surface, redundant faces left out (empty surfaces dropped).
    pub fn planar_members(&self) -> Vec<Vec<u32>> {
        let mut out = vec![Vec::new(); self.planar_count];
        for (f, &s) in self.planar.iter().enumerate() {
            if !self.redundant[f] {
                out[s as usize].push(f as u32);
            }
        }
        out.retain(|m| !m.is_empty());
        out
    }

    /// The outline of a planar surface made of several faces, when it is one convex polygon
    /// whose area is the faces' total (no holes, overlaps or folds); collinear corners
    /// removed. `None` otherwise: the surface is then meshed face by face.
    pub fn convex_outline(&self, scene: &Scene, members: &[u32]) -> Option<Vec<DVec3>> {
        const MAX_CORNERS: usize = 64;
        let mut directed: FxHashMap<(u32, u32), u32> = FxHashMap::default();
        let mut position: FxHashMap<u32, DVec3> = FxHashMap::default();
        for &f in members {
            let w = &self.welded[f as usize];
            let v = &scene.faces[f as usize].vertices;
            for k in 0..w.len() {
                *directed.entry((w[k], w[(k + 1) % w.len()])).or_default() += 1;
                position.insert(w[k], v[k]);
            }
        }
        let mut next: FxHashMap<u32, u32> = FxHashMap::default();
        for (&(a, b), &count) in &directed {
            if count != 1 || directed.contains_key(&(b, a)) {
                if count != 1 && !directed.contains_key(&(b, a)) {
                    return None; // a doubled boundary edge: overlapping faces
                }
                continue;
            }
            if next.insert(a, b).is_some() {
                return None; // two boundary edges leave one vertex: not one simple loop
            }
        }
        let &start = next.keys().min()?;
        let mut loop_ids = vec![start];
        let mut at = start;
        while let Some(&b) = next.get(&at) {
            if b == start {
                break;
            }
            if loop_ids.len() > next.len() {
                return None;
            }
            loop_ids.push(b);
            at = b;
        }
        if loop_ids.len() != next.len() {
            return None; // several loops (a hole) or an open chain
        }
        let mut outline: Vec<DVec3> = loop_ids.iter().map(|i| position[i]).collect();
        let n = self.normal[members[0] as usize];
        // Drop collinear corners (the input's triangulation leaves them on straight edges).
        let mut changed = true;
        while changed && outline.len() > 3 {
            changed = false;
            for i in 0..outline.len() {
                let k = outline.len();
                let (a, b, c) = (outline[(i + k - 1) % k], outline[i], outline[(i + 1) % k]);
                let cross = (b - a).cross(c - b).dot(n);
                if cross.abs() <= 1e-9 * (b - a).length() * (c - b).length() {
                    outline.remove(i);
                    changed = true;
                    break;
                }
            }
        }
        if outline.len() > MAX_CORNERS || !polygon::is_convex(&outline) {
            return None;
        }
        let total: f64 = members.iter().map(|&f| self.area[f as usize]).sum();
        let n_outline = polygon::normal(&outline)?;
        if n_outline.dot(n) < 0.999 || (polygon::area(&outline) - total).abs() > 1e-6 * total {
            return None;
        }
        Some(outline)
    }

    /// Groups `faces` (small faces of one material) into shooter clusters: breadth-first over
    /// shared edges within a display group, faces within `max_angle` of the seed's normal and
    /// `radius` of its centroid, until `max_area`. Returns the clusters in seed order.
    pub fn clusters(&self, faces: &[u32], max_area: f64, radius: f64) -> Vec<Vec<u32>> {
        let cos_max = SMOOTH_ANGLE_DEG.to_radians().cos();
        let mut eligible = vec![false; self.area.len()];
        for &f in faces {
            eligible[f as usize] = true;
        }
        let mut out = Vec::new();
        let mut queue = VecDeque::new();
        for &seed in faces {
            if !eligible[seed as usize] {
                continue;
            }
            eligible[seed as usize] = false;
            let s = seed as usize;
            let mut cluster = vec![seed];
            let mut total = self.area[s];
            queue.clear();
            queue.extend(self.neighbours(s).iter().copied());
            while let Some(f) = queue.pop_front() {
                if total >= max_area {
                    break;
                }
                let fu = f as usize;
                if !eligible[fu]
                    || self.display[fu] != self.display[s]
                    || self.normal[fu].dot(self.normal[s]) < cos_max
                    || (self.centroid[fu] - self.centroid[s]).length() > radius
                    || total + self.area[fu] > max_area * 1.25
                {
                    continue;
                }
                eligible[fu] = false;
                total += self.area[fu];
                cluster.push(f);
                queue.extend(self.neighbours(fu).iter().copied());
            }
            out.push(cluster);
        }
        out
    }
}

/// Whether `p` lies in convex polygon `poly` (normal `n`), within `tolerance`.
fn inside_convex(poly: &[DVec3], n: DVec3, p: DVec3, tolerance: f64) -> bool {
    let k = poly.len();
    (0..k).all(|i| {
        let (a, b) = (poly[i], poly[(i + 1) % k]);
        let inward = n.cross(b - a);
        let len = inward.length();
        len > 0.0 && (p - a).dot(inward) / len >= -tolerance
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LoadOptions;

    fn scene(obj: &str) -> Scene {
        let mtl = "newmtl w\nKd 0.5 0.5 0.5\nnewmtl l\nKe 1 1 1\n";
        Scene::from_obj_str("t.obj", obj, &[("m.mtl", mtl)], &LoadOptions::default())
            .expect("scene")
    }

    #[test]
    fn two_triangles_of_a_quad_have_the_quad_as_outline() {
        let s = scene(
            "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 5 6 7\n",
        );
        let t = Topology::new(&s);
        assert_eq!(t.planar[0], t.planar[1]);
        assert_ne!(t.planar[0], t.planar[2]);
        let outline = t.convex_outline(&s, &[0, 1]).expect("convex");
        assert_eq!(outline.len(), 4);
        assert!((polygon::area(&outline) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn an_l_shape_and_a_fold_are_not_one_polygon() {
        // L-shape: three unit squares (non-convex outline).
        let s = scene(
            "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nv 1 1 0\nv 2 1 0\nv 0 2 0\nv 1 2 0\nf 1 2 5 4\nf 2 3 6 5\nf 4 5 8 7\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 9 10 11\n",
        );
        let t = Topology::new(&s);
        assert_eq!(t.planar[0], t.planar[2]);
        assert!(t.convex_outline(&s, &[0, 1, 2]).is_none());
        // A fold (90°) is two planar surfaces but one display group? No: 90° > 30°.
        let s = scene(
            "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1 0 1\nv 1 1 1\nf 1 2 3 4\nf 2 5 6 3\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 7 8 9\n",
        );
        let t = Topology::new(&s);
        assert_ne!(t.planar[0], t.planar[1]);
        assert_ne!(t.display[0], t.display[1]);
    }

    #[test]
    fn duplicates_and_contained_coplanar_faces_are_redundant() {
        // Face 0: unit floor; 1: the same quad again; 2: a small quad lying on it; 3: the
        // same small quad facing down (another side: kept).
        let s = scene(
            "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 0.2 0 0.2\nv 0.4 0 0.2\nv 0.4 0 0.4\nv 0.2 0 0.4\nf 1 4 3 2\nf 1 4 3 2\nf 5 8 7 6\nf 5 6 7 8\nusemtl l\nv 0 2 0\nv 0 2 1\nv 1 2 1\nf 9 10 11\n",
        );
        let t = Topology::new(&s);
        assert_eq!(t.redundant, vec![false, true, true, false, false]);
    }

    #[test]
    fn a_gentle_crease_is_one_display_group() {
        // Two quads meeting at 10°: smooth.
        let z = (10f64).to_radians().tan();
        let obj = format!(
            "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 {z}\nv 2 1 {z}\nf 1 2 3 4\nf 2 5 6 3\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 7 8 9\n"
        );
        let s = scene(&obj);
        let t = Topology::new(&s);
        assert_ne!(t.planar[0], t.planar[1]);
        assert_eq!(t.display[0], t.display[1]);
        let clusters = t.clusters(&[0, 1], 10.0, 10.0);
        assert_eq!(clusters, vec![vec![0, 1]]);
        // Area limit: each alone.
        assert_eq!(t.clusters(&[0, 1], 1.0, 10.0).len(), 2);
    }
}
