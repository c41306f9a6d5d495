//! What the benches share: the rays of the BVH benches, so that `core`'s `bvh` group and
//! `bvh_compare` time the same work.

use glam::DVec3;
use nusselt_core::geometry::Rng;
use nusselt_core::mesh::Mesh;

/// `n` random segments between points just off the mesh's elements (seeded: the same
/// segments on every run).
pub fn segments(mesh: &Mesh, n: usize) -> Vec<(DVec3, DVec3)> {
    let mut rng = Rng::new(5, 0);
    let pick = |rng: &mut Rng| {
        let e = &mesh.elements[(rng.next_f64() * mesh.elements.len() as f64) as usize];
        e.centroid + e.normal * 1e-3
    };
    (0..n).map(|_| (pick(&mut rng), pick(&mut rng))).collect()
}
