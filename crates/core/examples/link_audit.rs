//! Checks a hierarchical solve's link kernels against rays, by kind of link: for random
//! elements of one material, cosine-weighted rays from the element against a hierarchy of
//! the mesh's display triangles; a ray that meets an element's front is credited to the link
//! (into the element or one of its ancestors) whose sender holds that element, so each
//! link's share of the rays is the kernel it should have. Also splits what the links into
//! planar inner nodes miss by whether the two nodes' bounding spheres overlap.
//! `cargo run --release -p nusselt-core --example link_audit -- MODEL [MATERIAL] [STEPS]`
//! (default `bricks`, 7 iterations; 200 elements, 2,048 rays each).

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use nusselt_core::geometry::sampling::cosine_hemisphere;
use nusselt_core::geometry::{Ray, Rng};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::hierarchical::HierarchicalSolver;
use nusselt_core::solver::hierarchical::tree::Node;
use nusselt_core::solver::{Problem, Solver, SolverConfig};

const ELEMENTS: usize = 200;
const RAYS: usize = 2048;

/// Per kind of link: kernel sum, rays' estimate, links (all per element once divided).
type Tally = BTreeMap<&'static str, (f64, f64, usize)>;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: link_audit MODEL [MATERIAL] [STEPS]";
    let model = args.first().ok_or(usage)?;
    let material = args.get(1).map_or("bricks", String::as_str);
    let steps: usize = args.get(2).map_or(Ok(7), |s| s.parse())?;
    let scene = Scene::load(Path::new(model), &LoadOptions::default())?;
    let mut solver = HierarchicalSolver::new(Problem::new(scene, SolverConfig::default())?);
    let cancel = AtomicBool::new(false);
    for _ in 0..steps {
        solver.step(&cancel);
    }
    let (problem, tree) = (solver.problem(), solver.hierarchy());
    let mesh = &problem.mesh;
    // Display triangles know their element, and carry the scene's cut-outs as the solve's
    // blockers do.
    let bvh = mesh.display_bvh(&problem.scene, false);
    let element_of = |triangle: u32| mesh.triangle_element[triangle as usize].0 as usize;
    let of_material: Vec<usize> = (0..mesh.elements.len())
        .filter(|&k| {
            let patch = &mesh.patches[mesh.elements[k].patch.0 as usize];
            problem.scene.materials[patch.material.0 as usize].name == material
        })
        .collect();
    if of_material.is_empty() {
        return Err(format!("no element of material '{material}'").into());
    }
    let mut rng = Rng::new(12345, 1);
    let mut tally = Tally::new();
    let (mut front, mut back, mut unlinked) = (0.0, 0.0, 0.0);
    let (mut near_missing, mut far_missing) = (0.0, 0.0);
    for _ in 0..ELEMENTS {
        let k = of_material[(rng.next_f64() * of_material.len() as f64) as usize];
        let e = &mesh.elements[k];
        let mut chain = Vec::new();
        let mut a = tree.leaf[k];
        while a != u32::MAX {
            chain.push(a);
            a = tree.parent[a as usize];
        }
        let into: Vec<_> = (chain.iter()).flat_map(|&a| solver.links_into(a)).collect();
        let mut hits = vec![0usize; into.len()];
        for _ in 0..RAYS {
            let x = e.point_at(rng.next_f64(), rng.next_f64());
            let d = cosine_hemisphere(e.normal, rng.next_f64(), rng.next_f64());
            let Some(h) = bvh.closest_hit(
                &Ray::new(x + e.normal * problem.epsilon, d),
                0.0,
                f64::INFINITY,
            ) else {
                continue;
            };
            let hit = element_of(h.id);
            if mesh.elements[hit].normal.dot(d) >= 0.0 {
                back += 1.0;
                continue;
            }
            front += 1.0;
            let at = tree.nodes[tree.leaf[hit] as usize].first;
            let mut credited = false;
            for (m, l) in into.iter().enumerate() {
                let s = &tree.nodes[l.sender as usize];
                if (s.first..s.first + s.count).contains(&at) {
                    hits[m] += 1;
                    credited = true;
                }
            }
            if !credited {
                unlinked += 1.0;
            }
        }
        for (l, &h) in into.iter().zip(&hits) {
            let (ni, nj) = (
                &tree.nodes[l.receiver as usize],
                &tree.nodes[l.sender as usize],
            );
            let mut kernel = l.kernel as f64;
            if ni.is_cluster() {
                // Read by the element at its normal (the harmonics, to first order).
                let dir = (nj.centroid - ni.centroid).normalize_or_zero();
                kernel *= e.normal.dot(dir).max(0.0);
            }
            let rays = h as f64 / RAYS as f64;
            let entry = tally.entry(kind(ni, nj)).or_default();
            *entry = (entry.0 + kernel, entry.1 + rays, entry.2 + 1);
            if !ni.is_cluster() && !ni.is_leaf() {
                let near = (nj.centroid - ni.centroid).length() < ni.radius + nj.radius;
                *(if near {
                    &mut near_missing
                } else {
                    &mut far_missing
                }) += rays - kernel;
            }
        }
    }
    let n = ELEMENTS as f64;
    let hemisphere = n * RAYS as f64;
    println!(
        "{} elements of {material}; per element, {ELEMENTS} of them:",
        of_material.len()
    );
    println!(
        "rays meet a front on {:.3} of the hemisphere, a back on {:.3}; fronts in no link's sender {:.3}",
        front / hemisphere,
        back / hemisphere,
        unlinked / hemisphere
    );
    println!("| receiver <- sender | links | kernel | rays |");
    let (mut k_all, mut r_all) = (0.0, 0.0);
    for (kind, (k, r, c)) in &tally {
        println!(
            "| {kind} | {:.1} | {:.4} | {:.4} |",
            *c as f64 / n,
            k / n,
            r / n
        );
        k_all += k;
        r_all += r;
    }
    println!("| all | | {:.4} | {:.4} |", k_all / n, r_all / n);
    println!(
        "missing from links into planar inner nodes: {:.4} where the bounding spheres overlap, {:.4} elsewhere",
        near_missing / n,
        far_missing / n
    );
    Ok(())
}

fn kind(receiver: &Node, sender: &Node) -> &'static str {
    let of = |n: &Node| match (n.is_cluster(), n.is_leaf()) {
        (true, _) => 0,
        (false, true) => 1,
        (false, false) => 2,
    };
    const KINDS: [[&str; 3]; 3] = [
        [
            "cluster <- cluster",
            "cluster <- leaf",
            "cluster <- planar inner",
        ],
        ["leaf <- cluster", "leaf <- leaf", "leaf <- planar inner"],
        [
            "planar inner <- cluster",
            "planar inner <- leaf",
            "planar inner <- planar inner",
        ],
    ];
    KINDS[of(receiver)][of(sender)]
}
