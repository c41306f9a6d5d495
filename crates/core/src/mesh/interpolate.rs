//! Per-vertex display values from per-element radiosity: which elements share a vertex,
//! the weights of each vertex's value, and T-vertices.
//!
//! Display vertices are shared only by elements of one *display group*
//! ([`super::surfaces`]: a plane of one material, or a smooth curved surface): radiance is
//! interpolated across those elements, never across a crease or a material change. Where a
//! vertex of one patch lies inside an edge of a neighbouring element (a T-vertex), its value
//! is set to the interpolation along that edge so the shading has no cracks (Baum, Mann,
//! Smith, Winget 1991).

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::{ElementId, Mesh, TVertex};
use crate::scene::Rgb;

impl Mesh {
    /// Per-vertex values from per-element values (one value per element, its centroid's).
    ///
    /// A vertex inside a surface takes the value at the vertex of the area-weighted
    /// least-squares plane through the centroids of the elements of that surface meeting at
    /// it (on a regular grid, their plain average). A vertex on a surface's boundary — a
    /// corner, a contact line — has elements on one side only, where an average is the value
    /// half an element inwards, an O(h) bias exactly where radiosity changes fastest; there
    /// the plane is fitted through two rings of elements and extrapolated (O(h²)). Results
    /// are clamped to be non-negative. A linear field is reproduced exactly. T-vertices are interpolated along the
    /// edge they lie on, so shading has no cracks.
    pub fn vertex_values(&self, element_values: &[Rgb]) -> Vec<Rgb> {
        debug_assert_eq!(element_values.len(), self.elements.len());
        use rayon::prelude::*;
        // In parallel: a snapshot of a few hundred thousand vertices is taken several
        // times a second while the solver waits for it.
        let mut out: Vec<Rgb> = (0..self.vertices.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|v| {
                let (a, b) = (
                    self.vertex_weight_start[v] as usize,
                    self.vertex_weight_start[v + 1] as usize,
                );
                let value: Rgb = self.vertex_weights[a..b]
                    .iter()
                    .map(|&(e, w)| element_values[e as usize] * w)
                    .sum();
                value.max(Rgb::ZERO)
            })
            .collect();
        // Nested T-vertices settle in a few passes.
        for _ in 0..3 {
            for tv in &self.t_vertices {
                out[tv.vertex as usize] =
                    out[tv.a as usize] * (1.0 - tv.t) + out[tv.b as usize] * tv.t;
            }
        }
        out
    }

    /// Precomputes the weights used by [`Mesh::vertex_values`].
    pub(super) fn build_vertex_weights(&mut self) {
        use rayon::prelude::*;
        let nv = self.vertices.len();
        let mut count = vec![0u32; nv + 1];
        for e in &self.elements {
            for &v in e.vertex_ids() {
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..nv {
            count[i + 1] += count[i];
        }
        let mut at = count.clone();
        let mut adjacent = vec![0u32; count[nv] as usize];
        for (ei, e) in self.elements.iter().enumerate() {
            for &v in e.vertex_ids() {
                adjacent[at[v as usize] as usize] = ei as u32;
                at[v as usize] += 1;
            }
        }
        let elems_of =
            |v: u32| &adjacent[count[v as usize] as usize..count[v as usize + 1] as usize];
        // The vertices' fits are independent: in parallel over fixed chunks, joined in
        // vertex order (the same weights whatever the thread count).
        const CHUNK: usize = 4096;
        let weights_of = |v: u32, ring: &mut Vec<u32>, out: &mut Vec<(u32, f64)>| {
            let p = self.vertices[v as usize];
            let first = elems_of(v);
            let total: f64 = first.iter().map(|&e| self.elements[e as usize].area).sum();
            if first.is_empty() || total <= 0.0 {
                return;
            }
            let h = (total / first.len() as f64).sqrt();
            let offset = first
                .iter()
                .map(|&e| {
                    let el = &self.elements[e as usize];
                    (el.centroid - p) * el.area
                })
                .sum::<DVec3>()
                / total;
            let average = |weights: &mut Vec<(u32, f64)>| {
                for &e in first {
                    weights.push((e, self.elements[e as usize].area / total));
                }
            };
            // A least-squares plane through the centroids: over the elements at the vertex
            // when they surround it (the plain average on a regular grid), over two rings of
            // elements on a boundary (or where one ring is too thin to fit), extrapolating.
            let n = self.elements[first[0] as usize].normal;
            let (t1, t2) = n.any_orthonormal_pair();
            let phi = |e: u32| {
                let d = (self.elements[e as usize].centroid - p) / h;
                DVec3::new(1.0, d.dot(t1), d.dot(t2))
            };
            let fit = |ring: &[u32]| -> Option<DVec3> {
                let mut m = glam::DMat3::ZERO;
                for &e in ring {
                    let f = phi(e);
                    let a = self.elements[e as usize].area;
                    m += glam::DMat3::from_cols(f * f.x, f * f.y, f * f.z) * a;
                }
                let scale = m.x_axis.x.max(f64::MIN_POSITIVE);
                (ring.len() >= 3 && (m.determinant() / scale.powi(3)).abs() > 1e-6)
                    .then(|| m.inverse() * DVec3::X)
            };
            let mut solution = if offset.length() < 0.2 * h {
                fit(first).map(|z| (z, first.to_vec()))
            } else {
                None
            };
            if solution.is_none() {
                ring.clear();
                for &e in first {
                    for &u in self.elements[e as usize].vertex_ids() {
                        ring.extend_from_slice(elems_of(u));
                    }
                }
                ring.sort_unstable();
                ring.dedup();
                solution = fit(ring).map(|z| (z, ring.clone()));
            }
            match solution {
                Some((z, ring)) => {
                    for e in ring {
                        let w = self.elements[e as usize].area * z.dot(phi(e));
                        debug_assert!(w.is_finite());
                        out.push((e, w));
                    }
                }
                None => average(out),
            }
        };
        // Per chunk: each vertex's weight count, and the weights.
        type Chunk = (Vec<u32>, Vec<(u32, f64)>);
        let chunks: Vec<Chunk> = (0..nv.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let (mut lengths, mut out, mut ring) = (Vec::new(), Vec::new(), Vec::new());
                for v in c * CHUNK..nv.min((c + 1) * CHUNK) {
                    let before = out.len();
                    weights_of(v as u32, &mut ring, &mut out);
                    lengths.push((out.len() - before) as u32);
                }
                (lengths, out)
            })
            .collect();
        let mut start = Vec::with_capacity(nv + 1);
        let mut weights = Vec::with_capacity(chunks.iter().map(|c| c.1.len()).sum());
        let mut offset = 0u32;
        for (lengths, out) in chunks {
            for n in lengths {
                start.push(offset);
                offset += n;
            }
            weights.extend(out);
        }
        start.push(weights.len() as u32);
        self.vertex_weight_start = start;
        self.vertex_weights = weights;
    }

    /// Display vertices: element corners welded within each display group
    /// (`element_group[e]`), display triangles, then the T-vertices.
    pub(super) fn build_vertices(&mut self, element_group: &[u32]) {
        let diag = self.bounds().diagonal().max(1e-300);
        let eps = 1e-6 * diag;
        let quant = |p: DVec3| {
            let q = (p / eps).round();
            (q.x as i64, q.y as i64, q.z as i64)
        };
        let corners = (self.elements.iter())
            .map(|e| e.corner_count as usize)
            .sum();
        let mut index: FxHashMap<(u32, Cell), u32> =
            FxHashMap::with_capacity_and_hasher(corners, Default::default());
        let mut vertex_group: Vec<u32> = Vec::with_capacity(corners);
        self.vertices.reserve(corners);
        self.triangles.reserve(2 * self.elements.len());
        self.triangle_element.reserve(2 * self.elements.len());
        for (ei, &group) in element_group.iter().enumerate() {
            for k in 0..self.elements[ei].corner_count as usize {
                let p = self.elements[ei].corners[k];
                let id = *index.entry((group, quant(p))).or_insert_with(|| {
                    self.vertices.push(p);
                    vertex_group.push(group);
                    self.vertices.len() as u32 - 1
                });
                self.elements[ei].vertices[k] = id;
            }
            let v = self.elements[ei].vertices;
            let eid = ElementId(ei as u32);
            self.triangles.push([v[0], v[1], v[2]]);
            self.triangle_element.push(eid);
            if self.elements[ei].corner_count == 4 {
                self.triangles.push([v[0], v[2], v[3]]);
                self.triangle_element.push(eid);
            }
        }
        self.find_t_vertices(element_group, &vertex_group, eps);
    }

    /// The vertices lying inside an edge of an element of their display group (within
    /// `eps`), found through a grid of cells of [`Mesh::t_vertex_cell`]. A vertex inside
    /// several edges takes the first in element and edge order. The elements are searched
    /// in parallel in fixed chunks, each listing its hits in that order, so the first hit
    /// of each vertex does not depend on the thread count.
    fn find_t_vertices(&mut self, element_group: &[u32], vertex_group: &[u32], eps: f64) {
        use rayon::prelude::*;
        const CHUNK: usize = 2048;
        let grid = VertexGrid::new(&self.vertices, self.t_vertex_cell(eps));
        let search = TSearch {
            vertices: &self.vertices,
            vertex_group,
            grid: &grid,
            eps,
        };
        let hits: Vec<Vec<TVertex>> = self
            .elements
            .par_chunks(CHUNK)
            .zip(element_group.par_chunks(CHUNK))
            .map(|(elements, groups)| search.hits(elements, groups))
            .collect();
        let mut first: Vec<Option<TVertex>> = vec![None; self.vertices.len()];
        for tv in hits.into_iter().flatten() {
            first[tv.vertex as usize].get_or_insert(tv);
        }
        self.t_vertices = first.into_iter().flatten().collect();
    }

    /// The cell size of the T-vertex search grid: a typical element's size (the median
    /// area's side), not the nominal element size: faces smaller than an element stay
    /// whole, and a model of many tiny faces would otherwise put thousands of vertices in
    /// one cell (1 M triangles: 240 s). Coarser where most edges are far longer than the
    /// typical element (a few tiny faces beside large ones): the walks along the edges then
    /// visit at most about 16 cells an edge in all, instead of millions each.
    fn t_vertex_cell(&self, eps: f64) -> f64 {
        let mut areas: Vec<f64> = self.elements.iter().map(|e| e.area).collect();
        let typical = if areas.is_empty() {
            self.element_size
        } else {
            let mid = areas.len() / 2;
            let (_, median, _) = areas.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
            median.sqrt()
        };
        let (mut edge_length, mut edges) = (0.0, 0usize);
        for e in &self.elements {
            let n = e.corner_count as usize;
            for k in 0..n {
                edge_length += (e.corners[(k + 1) % n] - e.corners[k]).length();
                edges += 1;
            }
        }
        let mut cell = typical.min(self.element_size).max(eps);
        while edge_length / (0.5 * cell) > 16.0 * edges as f64 && cell.is_finite() {
            cell *= 2.0;
        }
        cell
    }

    /// Number of T-vertices found (for tests and statistics).
    pub fn t_vertex_count(&self) -> usize {
        self.t_vertices.len()
    }
}

/// What the T-vertex search reads.
struct TSearch<'a> {
    vertices: &'a [DVec3],
    vertex_group: &'a [u32],
    grid: &'a VertexGrid,
    eps: f64,
}

impl TSearch<'_> {
    /// The vertices lying inside an edge of `elements` (of display groups `groups`), in
    /// element and edge order (a vertex once per edge).
    fn hits(&self, elements: &[super::Element], groups: &[u32]) -> Vec<TVertex> {
        let (vertices, eps) = (self.vertices, self.eps);
        let mut out = Vec::new();
        let mut scratch = Scratch::default();
        for (e, &group) in elements.iter().zip(groups) {
            let n = e.corner_count as usize;
            for k in 0..n {
                let (a, b) = (e.vertices[k], e.vertices[(k + 1) % n]);
                let (pa, pb) = (vertices[a as usize], vertices[b as usize]);
                let d = pb - pa;
                let len2 = d.length_squared();
                if len2 <= 0.0 {
                    continue;
                }
                self.grid
                    .near_edge(pa, pb, eps, vertices.len(), &mut scratch);
                for &v in &scratch.candidates {
                    if v == a || v == b || self.vertex_group[v as usize] != group {
                        continue;
                    }
                    let p = vertices[v as usize];
                    let t = (p - pa).dot(d) / len2;
                    if t <= 1e-9 || t >= 1.0 - 1e-9 {
                        continue;
                    }
                    if (pa + d * t - p).length() < eps * 10.0 {
                        out.push(TVertex { vertex: v, a, b, t });
                    }
                }
            }
        }
        out
    }
}

/// Buffers of [`VertexGrid::near_edge`], kept between calls.
#[derive(Default)]
struct Scratch {
    /// The vertices found.
    candidates: Vec<u32>,
    /// The distinct cells of the points of a walk along an edge.
    chain: Vec<Cell>,
}

type Cell = (i64, i64, i64);

/// The display vertices bucketed by cubic cells: per occupied cell (in order of first
/// appearance) a range of `members`, the vertices in increasing order.
struct VertexGrid {
    cell: f64,
    cells: FxHashMap<Cell, (u32, u32)>,
    members: Vec<u32>,
}

impl VertexGrid {
    fn new(vertices: &[DVec3], cell: f64) -> Self {
        let mut grid = Self {
            cell,
            cells: FxHashMap::default(),
            members: vec![0; vertices.len()],
        };
        let keys: Vec<Cell> = vertices.iter().map(|p| grid.key(*p)).collect();
        // Count per cell, then place each vertex after the cells that appeared before it.
        let mut counts: Vec<u32> = Vec::new();
        let slot: Vec<u32> = keys
            .iter()
            .map(|k| {
                let next = counts.len() as u32;
                let i = grid.cells.entry(*k).or_insert((next, 0)).0;
                if i == next {
                    counts.push(0);
                }
                counts[i as usize] += 1;
                i
            })
            .collect();
        let mut start = Vec::with_capacity(counts.len());
        let mut total = 0u32;
        for c in &counts {
            start.push(total);
            total += c;
        }
        for range in grid.cells.values_mut() {
            let i = range.0 as usize;
            *range = (start[i], start[i] + counts[i]);
        }
        for (v, &i) in slot.iter().enumerate() {
            grid.members[start[i as usize] as usize] = v as u32;
            start[i as usize] += 1;
        }
        grid
    }

    fn key(&self, p: DVec3) -> Cell {
        let q = (p / self.cell).floor();
        (q.x as i64, q.y as i64, q.z as i64)
    }

    /// Appends the vertices of cell `key` to `out`.
    fn extend(&self, key: Cell, out: &mut Vec<u32>) {
        if let Some(&(a, b)) = self.cells.get(&key) {
            out.extend_from_slice(&self.members[a as usize..b as usize]);
        }
    }

    /// Puts in `scratch.candidates` the vertices that can lie on the edge `pa`–`pb` (of
    /// `vertex_count` in all), each once: those in the cells of its bounding box, or for a
    /// long edge (a large element beside small ones) in the cells along it, or every vertex
    /// where that walk would visit more cells than there are vertices (an edge millions of
    /// cells long: a fuzzed model at 1e32 scale walked 10^7 steps an edge).
    fn near_edge(
        &self,
        pa: DVec3,
        pb: DVec3,
        eps: f64,
        vertex_count: usize,
        scratch: &mut Scratch,
    ) {
        scratch.candidates.clear();
        let (lo, hi) = (
            self.key(pa.min(pb) - DVec3::splat(eps)),
            self.key(pa.max(pb) + DVec3::splat(eps)),
        );
        let span = |a: i64, b: i64| b.abs_diff(a) as f64 + 1.0;
        let box_cells = span(lo.0, hi.0) * span(lo.1, hi.1) * span(lo.2, hi.2);
        let d = pb - pa;
        let walk = (d.length_squared().sqrt() / (0.5 * self.cell)).ceil();
        if box_cells <= 64.0 {
            for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    for z in lo.2..=hi.2 {
                        self.extend((x, y, z), &mut scratch.candidates);
                    }
                }
            }
        } else if 27.0 * walk > vertex_count as f64 {
            scratch.candidates.extend(0..vertex_count as u32);
        } else {
            self.walk(pa, d, walk as usize, scratch);
        }
    }

    /// The vertices of the cells within one cell (on every axis) of the cells of the points
    /// `pa + d i / steps`, `i` = 0..=steps, each cell once. Along a segment each coordinate,
    /// and so each coordinate of the cell, moves one way only (rounding is monotone): a
    /// cell of the points repeats only consecutively, and a neighbour of a point's cell
    /// already visited is a neighbour of one of the last cells before it, those within two
    /// cells on every axis. Checking them finds the same cells as sorting and deduplicating
    /// all 27 neighbours of every point, at a fraction of the cost.
    fn walk(&self, pa: DVec3, d: DVec3, steps: usize, scratch: &mut Scratch) {
        let Scratch { candidates, chain } = scratch;
        chain.clear();
        for i in 0..=steps {
            let c = self.key(pa + d * (i as f64 / steps.max(1) as f64));
            if chain.last() != Some(&c) {
                chain.push(c);
            }
        }
        let within = |p: &Cell, q: Cell, r: u64| {
            p.0.abs_diff(q.0) <= r && p.1.abs_diff(q.1) <= r && p.2.abs_diff(q.2) <= r
        };
        for (i, &c) in chain.iter().enumerate() {
            let recent = chain[..i]
                .iter()
                .rev()
                .take_while(|p| within(p, c, 2))
                .count();
            let recent = &chain[i - recent..i];
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let n = (c.0 + dx, c.1 + dy, c.2 + dz);
                        if !recent.iter().any(|p| within(p, n, 1)) {
                            self.extend(n, candidates);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Rng;

    /// The walk along an edge visits the cells that sorting and deduplicating the 27
    /// neighbours of every point's cell gives, each once (one vertex per cell of a lattice,
    /// so vertices stand for cells), along segments of every direction and length.
    #[test]
    fn the_walk_visits_each_neighbour_cell_once() {
        let n = 24;
        let vertices: Vec<DVec3> = (0..n * n * n)
            .map(|i| DVec3::new((i % n) as f64, (i / n % n) as f64, (i / (n * n)) as f64) + 0.5)
            .collect();
        let grid = VertexGrid::new(&vertices, 1.0);
        let mut rng = Rng::new(7, 0);
        let mut scratch = Scratch::default();
        for i in 0..600 {
            let mut point =
                || DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 20.0 + 2.0;
            let (pa, mut pb) = (point(), point());
            // Some along a plane or an axis of the grid.
            if i % 3 == 1 {
                pb.y = pa.y;
            } else if i % 3 == 2 {
                (pb.y, pb.z) = (pa.y, pa.z);
            }
            let steps = ((pb - pa).length() / 0.5).ceil() as usize;
            scratch.candidates.clear();
            grid.walk(pa, pb - pa, steps, &mut scratch);
            let mut cells: Vec<Cell> = Vec::new();
            for i in 0..=steps {
                let c = grid.key(pa + (pb - pa) * (i as f64 / steps.max(1) as f64));
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        for dz in -1..=1 {
                            cells.push((c.0 + dx, c.1 + dy, c.2 + dz));
                        }
                    }
                }
            }
            cells.sort_unstable();
            cells.dedup();
            let mut expected: Vec<u32> = Vec::new();
            for c in cells {
                grid.extend(c, &mut expected);
            }
            expected.sort_unstable();
            let mut found = scratch.candidates.clone();
            found.sort_unstable();
            assert_eq!(found, expected, "{pa} {pb}");
        }
    }
}
