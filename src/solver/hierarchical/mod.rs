//! Hierarchical radiosity with clustering (`--solver hierarchical`).
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
//! Error: that of the links kept (bounded by the tolerance, [`SolverConfig::link_tolerance`]
//! times the scene's mean emitted radiosity, per link), of the 4-ray visibility, and of
//! constant elements. The residual reported is the change of the last iteration,
//! `Σ|B_new − B_old| A / Σ|E| A` (the residual of the hierarchical system at the old
//! solution), not the residual of the full-matrix system the other solvers report.
//! Measured (docs/BENCHMARKS.md): the Cornell box at the default tolerance 2.95 % from the
//! path-traced reference in 4.2 s (shooting 1.78 % in 6.7 s); at 104 k elements converged
//! in 14 s where shooting has 35 % unshot after 60 s; slow on facet-heavy models (each
//! facet gathers through hundreds of links).
//!
//! [`SolverConfig::link_tolerance`]: super::SolverConfig::link_tolerance

pub mod directional;
pub mod link;
pub mod tree;

use std::sync::atomic::AtomicBool;

use rayon::prelude::*;

use super::{Problem, RowCache, Solver, SolverError, channel_sum};
use crate::scene::{MaterialId, Rgb};
use link::{Link, Linker};
use tree::{Hierarchy, NONE};

/// Receivers smaller than the scene's area over this many get a threshold that grows as
/// they shrink (`link::Linker::receiver_eps`), so that the links stop growing with the
/// element count past about this many elements.
pub const REFERENCE_RECEIVERS: f64 = 16384.0;

pub struct HierarchicalSolver {
    problem: Problem,
    tree: Hierarchy,
    /// Sorted by receiver (then sender); `link_start[i]..link_start[i + 1]` are node `i`'s.
    links: Vec<Link>,
    link_start: Vec<u32>,
    /// The cluster nodes (pre-order) and each node's index among them ([`NONE`] if planar).
    clusters: Vec<u32>,
    cluster_slot: Vec<u32>,
    /// Radiosity per node (area average of its elements).
    node_b: Vec<Rgb>,
    radiosity: Vec<Rgb>,
    /// Last iteration's change per element (the residual).
    change: Vec<Rgb>,
    /// Per patch (an element's are its patch's).
    emission: Vec<Rgb>,
    reflectance: Vec<Rgb>,
    emitted: f64,
    residual: f64,
    steps: usize,
    /// Links made by refinement so far (kept or later split).
    links_made: usize,
    residual_at_refine: f64,
    /// Refinement stopped short at the memory budget (`SolverConfig::row_cache_bytes`).
    link_budget_reached: bool,
    refine_seconds: f64,
    gather_seconds: f64,
}

impl HierarchicalSolver {
    pub fn new(problem: Problem) -> Self {
        let tree = Hierarchy::build(&problem.mesh);
        let clusters: Vec<u32> = (0..tree.nodes.len() as u32)
            .filter(|&n| tree.nodes[n as usize].is_cluster())
            .collect();
        let mut cluster_slot = vec![NONE; tree.nodes.len()];
        for (k, &n) in clusters.iter().enumerate() {
            cluster_slot[n as usize] = k as u32;
        }
        let mut s = Self {
            problem,
            tree,
            links: Vec::new(),
            link_start: Vec::new(),
            clusters,
            cluster_slot,
            node_b: Vec::new(),
            radiosity: Vec::new(),
            change: Vec::new(),
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
        };
        s.reset();
        s
    }

    pub fn link_count(&self) -> usize {
        self.links.len()
    }

    pub fn node_count(&self) -> usize {
        self.tree.nodes.len()
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
        self.problem.config.link_tolerance * sum / area.max(f64::MIN_POSITIVE)
    }

    /// Refines the links against the current radiosity. `false` if cancelled.
    fn refine(&mut self, cancel: &AtomicBool) -> bool {
        let Some(root) = self.tree.root() else {
            return false;
        };
        let eps = self.threshold();
        let linker = Linker {
            mesh: &self.problem.mesh,
            bvh: &self.problem.bvh,
            tree: &self.tree,
            epsilon: self.problem.epsilon,
            seed: self.problem.config.formfactor.seed,
            reference_area: self.tree.nodes[root as usize].area / REFERENCE_RECEIVERS,
        };
        // The links to split become the frontier; the rest stay where they are.
        let mut links = std::mem::take(&mut self.links);
        let (frontier, removed): (Vec<(u32, u32)>, Vec<Link>) =
            if self.steps == 0 && links.is_empty() {
                (vec![(root, root)], Vec::new())
            } else {
                let b = &self.node_b;
                let split: Vec<bool> = links
                    .par_iter()
                    .map(|l| linker.needs_split(l, b[l.sender as usize].max_element(), eps))
                    .collect();
                let removed: Vec<Link> = links
                    .iter()
                    .zip(&split)
                    .filter(|(_, s)| **s)
                    .map(|(l, _)| *l)
                    .collect();
                let mut k = 0;
                links.retain(|_| {
                    k += 1;
                    !split[k - 1]
                });
                (
                    removed.iter().map(|l| (l.receiver, l.sender)).collect(),
                    removed,
                )
            };
        if frontier.is_empty() {
            self.links = links;
            return true;
        }
        let budget = self.problem.config.row_cache_bytes / std::mem::size_of::<Link>();
        let max_links = budget.saturating_sub(links.len());
        let Some((new_links, capped)) =
            linker.refine(frontier, &self.node_b, eps, max_links, cancel)
        else {
            // Cancelled: the links as they were (sorted again, `link_start` still fits).
            links.extend(removed);
            links.par_sort_unstable_by_key(|l| (l.receiver, l.sender));
            self.links = links;
            return false;
        };
        drop(removed);
        self.link_budget_reached |= capped;
        self.links_made += new_links.len();
        links.reserve_exact(new_links.len());
        links.extend(new_links);
        links.shrink_to_fit();
        links.par_sort_unstable_by_key(|l| (l.receiver, l.sender));
        let mut start = vec![0u32; self.tree.nodes.len() + 1];
        for l in &links {
            start[l.receiver as usize + 1] += 1;
        }
        for k in 1..start.len() {
            start[k] += start[k - 1];
        }
        self.links = links;
        self.link_start = start;
        true
    }

    /// Gather, push to the leaves, pull up; sets the residual.
    fn gather_push_pull(&mut self) {
        let links = &self.links;
        let start = &self.link_start;
        let b = &self.node_b;
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
        let clusters = &self.clusters;
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
        let slot = &self.cluster_slot;
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
        let mut residual = 0.0;
        for (e, el) in self.problem.mesh.elements.iter().enumerate() {
            let leaf = self.tree.leaf[e] as usize;
            let p = el.patch.0 as usize;
            let new = self.emission[p] + self.reflectance[p] * down[leaf];
            debug_assert!(new.is_finite());
            self.change[e] = new - self.radiosity[e];
            residual += channel_sum(self.change[e]) * el.area;
            self.radiosity[e] = new;
        }
        self.residual = residual / self.emitted.max(f64::MIN_POSITIVE);
        self.pull();
    }

    /// Node radiosities from the elements' (area averages, children before parents).
    fn pull(&mut self) {
        let nodes = &self.tree.nodes;
        if self.node_b.len() != nodes.len() {
            self.node_b = vec![Rgb::ZERO; nodes.len()];
        }
        for n in (0..nodes.len()).rev() {
            let node = &nodes[n];
            self.node_b[n] = if node.is_leaf() {
                self.radiosity[self.tree.order[node.first as usize] as usize]
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

    /// Memory of the links and the hierarchy, in bytes.
    pub fn bytes(&self) -> usize {
        self.links.capacity() * std::mem::size_of::<Link>()
            + self.link_start.len() * 4
            + self.tree.bytes()
            + self.node_b.len() * 24
            + self.cluster_slot.len() * 4
            + self.clusters.len() * (4 + std::mem::size_of::<directional::Sh9>())
    }
}

impl Solver for HierarchicalSolver {
    fn name(&self) -> &'static str {
        "hierarchical"
    }
    fn problem(&self) -> &Problem {
        &self.problem
    }
    fn step(&mut self, cancel: &AtomicBool) -> bool {
        if self.tree.root().is_none() || self.residual == 0.0 {
            return false;
        }
        let t0 = std::time::Instant::now();
        // Links follow the light: refine while the solution still changes much (the
        // first steps), then only once the residual has fallen 8× since the last refine.
        if self.steps < 2 || self.residual * 8.0 <= self.residual_at_refine {
            if !self.refine(cancel) {
                return false;
            }
            self.residual_at_refine = self.residual;
        }
        let t1 = std::time::Instant::now();
        self.gather_push_pull();
        self.refine_seconds += (t1 - t0).as_secs_f64();
        self.gather_seconds += t1.elapsed().as_secs_f64();
        self.steps += 1;
        true
    }
    fn steps(&self) -> usize {
        self.steps
    }
    fn radiosity(&self) -> &[Rgb] {
        &self.radiosity
    }
    fn residual(&self) -> f64 {
        self.residual
    }
    /// No display correction: until the first iteration only the lights show.
    fn element_radiance(&self, _with_ambient: bool) -> Vec<Rgb> {
        self.radiosity.clone()
    }
    /// Keeps the links and continues from the current solution (later iterations refine
    /// where the new materials need it).
    fn set_material(
        &mut self,
        id: MaterialId,
        reflectance: Rgb,
        emission: Rgb,
    ) -> Result<(), SolverError> {
        self.problem
            .set_material(id.0 as usize, reflectance, emission)?;
        self.emission = self.problem.patch_emission();
        self.reflectance = self.problem.patch_reflectance();
        self.emitted = self.problem.emitted_power();
        self.residual = if self.emitted > 0.0 { 1.0 } else { 0.0 };
        self.residual_at_refine = f64::INFINITY;
        Ok(())
    }
    /// Back to the emission alone; the links are kept.
    fn reset(&mut self) {
        self.emission = self.problem.patch_emission();
        self.reflectance = self.problem.patch_reflectance();
        self.radiosity = self.problem.element_emission();
        self.change = vec![Rgb::ZERO; self.radiosity.len()];
        self.emitted = self.problem.emitted_power();
        self.residual = if self.emitted > 0.0 { 1.0 } else { 0.0 };
        self.steps = 0;
        self.residual_at_refine = f64::INFINITY;
        self.pull();
    }
    fn matrix_bytes(&self) -> usize {
        self.bytes()
    }
    /// `max|change| / (1 − ρ_max)` over each element's radiosity (as for the gathering
    /// solvers; the change of a Jacobi iteration is its residual). Infinite before the
    /// first iteration.
    fn error_estimate(&self) -> f64 {
        if self.steps == 0 {
            return f64::INFINITY;
        }
        let r_max = self
            .change
            .iter()
            .map(|c| c.abs().max_element())
            .fold(0.0, f64::max);
        let rho_max = self
            .reflectance
            .iter()
            .map(|r| r.max_element())
            .fold(0.0, f64::max);
        super::residual_error_estimate(
            &self.problem,
            &self.radiosity,
            &self.radiosity,
            r_max,
            rho_max,
        )
    }
    fn report(&self) -> String {
        format!(
            "{} links ({} made), {} nodes ({} planar groups), {:.1} MB; refine {:.2} s, gather {:.2} s",
            self.links.len(),
            self.links_made,
            self.tree.nodes.len(),
            self.tree.planar_groups,
            self.bytes() as f64 / 1e6,
            self.refine_seconds,
            self.gather_seconds
        ) + if self.link_budget_reached {
            "; link budget reached (--max-memory): coarser than the tolerance"
        } else {
            ""
        }
    }
    fn into_parts(self: Box<Self>) -> (Problem, RowCache) {
        (self.problem, RowCache::default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{LoadOptions, Scene};
    use crate::solver::SolverConfig;
    use glam::DVec3;

    /// Σ of the kernels a leaf gathers through (its own links and its ancestors').
    fn kernel_sums(s: &HierarchicalSolver) -> Vec<f64> {
        let per_node: Vec<f64> = (0..s.tree.nodes.len())
            .map(|i| {
                s.links[s.link_start[i] as usize..s.link_start[i + 1] as usize]
                    .iter()
                    .map(|l| l.kernel as f64)
                    .sum()
            })
            .collect();
        let mut down = per_node;
        for n in 0..down.len() {
            let p = s.tree.parent[n];
            if p != NONE {
                down[n] += down[p as usize];
            }
        }
        s.tree.leaf.iter().map(|&l| down[l as usize]).collect()
    }

    fn solver(builtin: &str, config: SolverConfig) -> HierarchicalSolver {
        let scene = Scene::builtin(builtin, &LoadOptions::default()).expect("scene");
        HierarchicalSolver::new(Problem::new(scene, config).expect("problem"))
    }

    fn solve(s: &mut HierarchicalSolver, residual: f64) {
        let cancel = AtomicBool::new(false);
        while s.residual() > residual && s.steps() < 200 {
            assert!(s.step(&cancel), "stopped at residual {}", s.residual());
        }
    }

    /// In a closed convex box every point sees the whole box: the kernels a leaf gathers
    /// through must sum to 1, and each link's kernel must match the exact average, over the
    /// receiver's elements, of Lambert's point-to-polygon value summed over the sender's
    /// elements (an independent evaluation of the same integral). The oracle keeps each
    /// link's error times the sender's radiosity under ε (= the tolerance here: emission 1
    /// everywhere); it measures the spread from 4 points, so a few links may pass it.
    /// A kernel bug (a missing cosine, the wrong node's area, a cluster at full area) moves
    /// most links by far more.
    #[test]
    fn kernels_of_a_closed_box_match_the_exact_integral() {
        let tolerance = 0.005;
        let config = SolverConfig {
            link_tolerance: tolerance,
            ..SolverConfig::default()
        };
        let mut s = solver("furnace", config);
        solve(&mut s, 1e-3);
        let mesh = &s.problem.mesh;
        let elements = |n: u32| {
            let node = &s.tree.nodes[n as usize];
            &s.tree.order[node.first as usize..(node.first + node.count) as usize]
        };
        let (mut outside, mut worst) = (0usize, 0.0f64);
        // Links into clusters carry normal-incidence irradiance (tested below).
        assert!(
            s.links
                .iter()
                .all(|l| !s.tree.nodes[l.receiver as usize].is_cluster())
        );
        for l in &s.links {
            let receivers = elements(l.receiver);
            let mut exact = 0.0;
            for &r in receivers {
                let er = &mesh.elements[r as usize];
                for &e in elements(l.sender) {
                    let es = &mesh.elements[e as usize];
                    exact += crate::formfactor::contour::point_to_polygon_with_normal(
                        er.centroid,
                        er.normal,
                        es.corners(),
                        es.normal,
                    );
                }
            }
            exact /= receivers.len() as f64;
            let err = (l.kernel as f64 - exact).abs();
            worst = worst.max(err);
            outside += usize::from(err > tolerance);
        }
        eprintln!(
            "{} of {} links outside, worst {worst}",
            outside,
            s.links.len()
        );
        assert!(
            outside * 100 <= s.links.len(),
            "{outside} of {} links off by more than {tolerance}",
            s.links.len()
        );
        assert!(worst <= 4.0 * tolerance, "a link off by {worst}");
        let sums = kernel_sums(&s);
        let mean = sums.iter().sum::<f64>() / sums.len() as f64;
        assert!((mean - 1.0).abs() < 0.01, "mean row sum {mean}");
    }

    /// On the same mesh, hierarchical radiosity approaches the full-matrix answer (shooting
    /// to a residual of 1e-6) as the link tolerance falls: first order in the tolerance,
    /// so a tolerance 10× smaller must at least halve the error.
    #[test]
    fn converges_to_the_full_solution_as_the_tolerance_falls() {
        // Patches of one element: the full solution is the element-to-element system that
        // the hierarchy's leaves approximate (larger patches shoot their average radiosity,
        // a different discretisation, 1.7 % away on this mesh).
        let base = SolverConfig {
            element_size: Some(50.0),
            patch_size: Some(50.0),
            ..SolverConfig::default()
        };
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("scene");
        let mut full = crate::solver::SolverKind::Shooting
            .build(Problem::new(scene, base.clone()).expect("problem"))
            .expect("shooting");
        let cancel = AtomicBool::new(false);
        while full.residual() > 1e-6 {
            assert!(full.step(&cancel));
        }
        let mesh = &full.problem().mesh;
        let error = |tolerance: f64| {
            let mut s = solver(
                "cornell",
                SolverConfig {
                    link_tolerance: tolerance,
                    ..base.clone()
                },
            );
            solve(&mut s, 1e-6);
            let (mut diff, mut sum) = (0.0, 0.0);
            for ((e, a), b) in mesh
                .elements
                .iter()
                .zip(s.radiosity())
                .zip(full.radiosity())
            {
                diff += channel_sum(*a - *b) * e.area;
                sum += channel_sum(*b) * e.area;
            }
            diff / sum
        };
        let coarse = error(0.02);
        let fine = error(0.002);
        eprintln!("error {coarse} at 0.02, {fine} at 0.002");
        assert!(
            fine <= 0.5 * coarse,
            "error {coarse} at 0.02, {fine} at 0.002"
        );
        assert!(fine < 0.03, "error {fine} at 0.002");
    }

    /// A memory budget smaller than the tolerance needs: refinement stops at it (the rest
    /// of the links kept coarser), the report says so, and the solve still converges to a
    /// finite, non-negative answer.
    #[test]
    fn the_link_budget_holds() {
        let budget_links = 20_000;
        let config = SolverConfig {
            element_size: Some(50.0),
            row_cache_bytes: budget_links * std::mem::size_of::<Link>(),
            ..SolverConfig::default()
        };
        let mut s = solver("cornell", config);
        solve(&mut s, 1e-4);
        assert!(s.report().contains("link budget reached"), "{}", s.report());
        // Past the budget only forced splits (cluster receivers, overlapping nodes) remain,
        // at most a few per node.
        assert!(
            s.link_count() <= budget_links + 4 * s.node_count(),
            "{} links",
            s.link_count()
        );
        assert!(
            s.radiosity()
                .iter()
                .all(|b| b.is_finite() && b.min_element() >= 0.0)
        );
    }

    /// A small cube far from a square light is one cluster: it receives through links
    /// carrying directional irradiance, and each face reads its own: the face towards the
    /// light within the harmonics' error of Lambert's exact value, the face away nearly
    /// dark, the sides in between (the light has no reflectance, so this is one bounce).
    #[test]
    fn a_distant_cluster_receives_by_direction() {
        let obj = "mtllib m.mtl\nusemtl light\nv -0.5 -0.5 10\nv -0.5 0.5 10\nv 0.5 0.5 10\nv 0.5 -0.5 10\nf 1 2 3 4\nusemtl cube\nv -0.05 -0.05 -0.05\nv 0.05 -0.05 -0.05\nv 0.05 0.05 -0.05\nv -0.05 0.05 -0.05\nv -0.05 -0.05 0.05\nv 0.05 -0.05 0.05\nv 0.05 0.05 0.05\nv -0.05 0.05 0.05\nf 5 8 7 6\nf 9 10 11 12\nf 5 6 10 9\nf 8 12 11 7\nf 5 9 12 8\nf 6 7 11 10\n";
        let mtl = "newmtl light\nKd 0 0 0\nKe 1 1 1\nnewmtl cube\nKd 0.5 0.5 0.5\n";
        let scene = Scene::from_obj_str("c.obj", obj, &[("m.mtl", mtl)], &LoadOptions::default())
            .expect("scene");
        let config = SolverConfig {
            element_size: Some(0.05),
            link_tolerance: 0.01,
            ..SolverConfig::default()
        };
        let mut s = HierarchicalSolver::new(Problem::new(scene, config).expect("problem"));
        solve(&mut s, 1e-6);
        let cluster_links = s
            .links
            .iter()
            .filter(|l| s.tree.nodes[l.receiver as usize].is_cluster())
            .count();
        assert!(cluster_links > 0, "no cluster received: {}", s.report());
        let light = [
            DVec3::new(-0.5, -0.5, 10.0),
            DVec3::new(-0.5, 0.5, 10.0),
            DVec3::new(0.5, 0.5, 10.0),
            DVec3::new(0.5, -0.5, 10.0),
        ];
        // Normal-incidence kernel at the cube: the light's form factor from a point facing it.
        let k = crate::formfactor::contour::point_to_polygon(DVec3::ZERO, DVec3::Z, &light);
        let mesh = &s.problem.mesh;
        for (e, b) in mesh.elements.iter().zip(s.radiosity()) {
            if e.centroid.z > 5.0 {
                continue; // the light
            }
            let exact =
                0.5 * crate::formfactor::contour::point_to_polygon(e.centroid, e.normal, &light);
            let allowed = 0.5
                * k
                * match e.normal.z {
                    z if z > 0.9 => directional::SH_ERROR + 0.05,
                    z if z < -0.9 => 0.0625 + 0.05,
                    _ => 0.5,
                };
            assert!(
                (b.x - exact).abs() <= allowed,
                "normal {:?}: {} vs exact {exact} (allowed {allowed})",
                e.normal,
                b.x
            );
        }
    }
}
