use super::build::subdivide;
use super::*;
use crate::scene::{LoadOptions, Rgb, Scene};

fn cornell() -> Scene {
    Scene::builtin("cornell", &LoadOptions::default()).expect("cornell")
}

#[test]
fn elements_tile_their_patches() {
    let scene = cornell();
    let mesh = Mesh::build(&scene, &MeshSpec::element(30.0)).expect("mesh");
    for p in &mesh.patches {
        let sum: f64 = mesh.elements[p.elements.start as usize..p.elements.end as usize]
            .iter()
            .map(|e| e.area)
            .sum();
        assert!(
            (sum - p.area).abs() < 1e-5 * p.area,
            "patch {} {} vs {}",
            p.face,
            sum,
            p.area
        );
        for e in &mesh.elements[p.elements.start as usize..p.elements.end as usize] {
            let edge = e.corners().iter().zip(e.corners().iter().cycle().skip(1));
            for (a, b) in edge {
                assert!((*a - *b).length() <= 30.0 * 1.01 + 1e-9 || p.polygon.len() != 4);
            }
        }
    }
}

#[test]
fn triangles_subdivide_with_right_area() {
    let mut out = Vec::new();
    let tri = [
        DVec3::ZERO,
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::new(0.0, 3.0, 0.0),
    ];
    // Area 4.5, at most half a 1.5² square per element: a 2 × 2 grid of 1.125 each.
    subdivide(&tri, 1.5, &mut |c| out.push(polygon::area(c)));
    assert_eq!(out.len(), 4);
    assert!((out.iter().sum::<f64>() - 4.5).abs() < 1e-12);
}

/// A thin strip keeps its grid (one row of cells along it); a convex quad with one corner
/// pulled 1,000 sizes out, whose grid would be 1,000 × 1,000 cells over an area of a few
/// hundred, is cut as triangles to about its area's count.
#[test]
fn a_sliver_quad_is_cut_by_its_area_and_a_strip_by_its_length() {
    let strip = [
        DVec3::ZERO,
        DVec3::new(100.0, 0.0, 0.0),
        DVec3::new(100.0, 0.1, 0.0),
        DVec3::new(0.0, 0.1, 0.0),
    ];
    let mut count = 0;
    subdivide(&strip, 1.0, &mut |_| count += 1);
    assert_eq!(count, 100);
    let sliver = [
        DVec3::ZERO,
        DVec3::new(0.2, 0.0, 0.0),
        DVec3::new(1000.0, 0.5, 0.0),
        DVec3::new(0.0, 0.2, 0.0),
    ];
    assert!(polygon::is_convex(&sliver));
    let area = polygon::area(&sliver);
    let mut pieces = Vec::new();
    subdivide(&sliver, 1.0, &mut |c| pieces.push(polygon::area(c)));
    assert!((pieces.iter().sum::<f64>() - area).abs() < 1e-9 * area);
    assert!(
        (pieces.len() as f64) < 4.0 * (area / 0.5 + 1.0),
        "{} pieces for an area of {area}",
        pieces.len()
    );
}

#[test]
fn vertices_are_not_shared_across_creases_or_materials() {
    let scene = cornell();
    let mesh = Mesh::build(&scene, &MeshSpec::element(50.0)).expect("mesh");
    // The floor-to-back-wall corner point appears once per surface.
    let corner = DVec3::new(0.0, 0.0, 559.2);
    let copies = mesh
        .vertices
        .iter()
        .filter(|v| (**v - corner).length() < 1e-6)
        .count();
    assert_eq!(
        copies, 3,
        "floor, back wall and right wall each keep their own vertex"
    );
}

#[test]
fn t_vertices_are_interpolated_along_the_coarse_edge() {
    // Two coplanar patches of one material with different subdivisions.
    let obj = "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\nf 1 2 3 4\nf 2 5 6 3\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 7 8 9\n";
    let mtl = "newmtl w\nKd 0.5 0.5 0.5\nnewmtl l\nKe 1 1 1\n";
    let scene = Scene::from_obj_str("t.obj", obj, &[("m.mtl", mtl)], &LoadOptions::default())
        .expect("scene");
    let mut mesh = Mesh::build(&scene, &MeshSpec::element(0.5)).expect("mesh");
    // Make the second patch finer by rebuilding it alone is awkward; instead check that
    // conforming patches have no T-vertices and a finer neighbour does.
    assert_eq!(mesh.t_vertex_count(), 0);
    let obj2 = obj.replace("v 2 0 0\nv 2 1 0", "v 1.5 0 0\nv 1.5 1 0");
    let scene2 = Scene::from_obj_str("t.obj", &obj2, &[("m.mtl", mtl)], &LoadOptions::default())
        .expect("scene");
    mesh = Mesh::build(&scene2, &MeshSpec::element(0.34)).expect("mesh");
    // The two quads (1 and 0.5 wide) share an edge and a plane: one surface, meshed as
    // one 1.5 × 1 grid, so no T-vertex, and a linear field is reproduced at every vertex
    // (a wrong weight, or a vertex shared across the light, breaks it).
    assert_eq!(mesh.t_vertex_count(), 0);
    let field = |p: DVec3| 1.0 + 0.3 * p.x + 0.7 * p.y;
    let linear_error = |mesh: &Mesh| {
        let values: Vec<Rgb> = mesh
            .elements
            .iter()
            .map(|e| Rgb::splat(field(e.centroid)))
            .collect();
        let vv = mesh.vertex_values(&values);
        mesh.vertices
            .iter()
            .zip(&vv)
            .filter(|(p, _)| p.z == 0.0)
            .map(|(p, v)| (v.x - field(*p)).abs())
            .fold(0.0, f64::max)
    };
    assert!(linear_error(&mesh) < 1e-9, "{}", linear_error(&mesh));
    let obj3 = "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 1 0.5 0\nv 1.1 0.5 0\nv 1.1 1 0\nf 1 2 5 3 4\nf 5 6 7 3\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 8 9 10\n";
    let scene3 = Scene::from_obj_str("t.obj", obj3, &[("m.mtl", mtl)], &LoadOptions::default())
        .expect("scene");
    let mesh3 = Mesh::build(&scene3, &MeshSpec::element(0.2)).expect("mesh");
    // A pentagon and a quad sharing the vertex (1, 0.5) and the edge to (1, 1): finely
    // meshed, a linear field is still reproduced at every vertex.
    assert!(linear_error(&mesh3) < 1e-9, "{}", linear_error(&mesh3));
    // A true T-vertex: a single quad next to two stacked quads (the upper one narrower,
    // so that the two do not merge into one convex surface without the vertex).
    let obj4 = "mtllib m.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 0.5 0\nv 1 0.5 0\nv 1.5 1 0\nv 1.5 0.5 0\nf 1 2 3 4\nf 2 5 6 9 7\nf 7 9 8 3\nusemtl l\nv 0 0 3\nv 0 1 3\nv 1 1 3\nf 10 11 12\n";
    let scene4 = Scene::from_obj_str("t.obj", obj4, &[("m.mtl", mtl)], &LoadOptions::default())
        .expect("scene");
    let mesh4 = Mesh::build(&scene4, &MeshSpec::element(10.0)).expect("mesh");
    assert_eq!(mesh4.t_vertex_count(), 1);
    let values: Vec<Rgb> = mesh4
        .elements
        .iter()
        .map(|e| {
            Rgb::splat(if e.centroid.x < 1.0 {
                0.0
            } else {
                e.centroid.y
            })
        })
        .collect();
    let vv = mesh4.vertex_values(&values);
    let t = mesh4
        .vertices
        .iter()
        .position(|p| (*p - DVec3::new(1.0, 0.5, 0.0)).length() < 1e-9)
        .expect("T-vertex");
    let a = mesh4
        .vertices
        .iter()
        .position(|p| (*p - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-9)
        .expect("a");
    let b = mesh4
        .vertices
        .iter()
        .position(|p| (*p - DVec3::new(1.0, 1.0, 0.0)).length() < 1e-9)
        .expect("b");
    assert!(
        (vv[t] - (vv[a] + vv[b]) * 0.5).length() < 1e-12,
        "{:?} {:?} {:?}",
        vv[t],
        vv[a],
        vv[b]
    );
}

#[test]
fn vertex_values_reproduce_a_linear_field_up_to_the_boundary() {
    // Every wall of the Cornell box with radiance linear in position: interior vertices
    // (averages) and boundary vertices (least-squares extrapolation) must both be exact.
    // Averaging alone would be off by half an element's gradient at the boundary.
    let scene = cornell();
    let mesh = Mesh::build(&scene, &MeshSpec::element(30.0)).expect("mesh");
    let field = |p: DVec3| 1.0 + 0.002 * p.x + 0.001 * p.y + 0.0015 * p.z;
    let values: Vec<Rgb> = mesh
        .elements
        .iter()
        .map(|e| Rgb::splat(field(e.centroid)))
        .collect();
    let vv = mesh.vertex_values(&values);
    let mut worst: f64 = 0.0;
    for (p, v) in mesh.vertices.iter().zip(&vv) {
        worst = worst.max((v.x - field(*p)).abs() / field(*p));
    }
    // Not 1e-15: the published walls are a few mm off planar, so some centroids lie off
    // the fitted plane. Plain averaging is off by ~1 % at the boundary here.
    assert!(worst < 1e-5, "worst relative error {worst}");
}

#[test]
fn too_small_element_size_is_refused() {
    let scene = cornell();
    assert!(matches!(
        Mesh::build(&scene, &MeshSpec::element(0.01)),
        Err(MeshError::TooManyElements { .. })
    ));
    assert!(matches!(
        Mesh::build(&scene, &MeshSpec::element(f64::NAN)),
        Err(MeshError::BadElementSize(_))
    ));
}

/// A spec without an element size meshes for the element budget; refined, the levels
/// apply to the patches of that budget mesh (the same sizes, the same base patches).
#[test]
fn a_budget_spec_refines_the_budget_mesh() {
    let scene = cornell();
    let spec = MeshSpec {
        max_elements: Some(500),
        ..MeshSpec::default()
    };
    let base = Mesh::build(&scene, &spec).expect("mesh");
    let same = Mesh::build_refined(&scene, &spec, &[0, 0]).expect("mesh");
    assert_eq!(same.elements.len(), base.elements.len());
    let fine = Mesh::build_refined(&scene, &spec, &[1]).expect("mesh");
    assert_eq!(fine.element_size, base.element_size);
    assert_eq!(fine.base_count(), base.base_count());
    assert!(fine.elements.len() > base.elements.len());
}

/// The blockers' hierarchy built over the faces and relabelled to occluder groups answers
/// every ray as the one built with the groups' ids: same hit, same distance, same id.
#[test]
fn the_relabelled_face_hierarchy_is_the_blockers_hierarchy() {
    use crate::geometry::{Ray, Rng};
    // A floor and a ceiling of two triangles each (one planar group apiece) and a small
    // cube between them (a cluster).
    let mut obj = String::from(
        "v 0 0 0\nv 2 0 0\nv 2 0 2\nv 0 0 2\nv 0 2 0\nv 2 2 0\nv 2 2 2\nv 0 2 2\n\
         f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\n",
    );
    let c = [0.9, 1.1];
    for (x, y, z) in (0..8).map(|k| (c[k & 1], c[(k >> 1) & 1], c[k >> 2])) {
        obj += &format!("v {x} {y} {z}\n");
    }
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        obj += &format!("f {} {} {} {}\n", f[0] + 8, f[1] + 8, f[2] + 8, f[3] + 8);
    }
    let scene =
        Scene::from_obj_str("groups.obj", &obj, &[], &LoadOptions::default()).expect("scene");
    let mesh = Mesh::build(&scene, &MeshSpec::element(0.5)).expect("mesh");
    // Groups are not face indices, so a relabelling left undone would show.
    let moved = (mesh.face_occluder.iter().enumerate()).filter(|&(f, &g)| g != f as u32);
    assert!(moved.count() > 0, "every face is its own group");
    let direct = mesh.blocker_bvh_where(&scene, |_| true);
    let relabelled = mesh.blocker_bvh(&scene);
    let b = scene.bounds();
    let mut rng = Rng::new(7, 0);
    let mut hits = 0;
    for _ in 0..4000 {
        let at = |rng: &mut Rng| {
            b.min
                + (b.max - b.min) * glam::DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64())
        };
        let (from, to) = (at(&mut rng), at(&mut rng));
        let Some(dir) = (to - from).try_normalize() else {
            continue;
        };
        let ray = Ray::new(from, dir);
        let (x, y) = (
            direct.closest_hit(&ray, 0.0, f64::INFINITY),
            relabelled.closest_hit(&ray, 0.0, f64::INFINITY),
        );
        assert_eq!(x.map(|h| (h.t, h.id)), y.map(|h| (h.t, h.id)));
        hits += usize::from(x.is_some());
    }
    assert!(hits > 500, "{hits} hits");
}

/// The size for an excess is where the plain sum `Σ max(0, k A_f / s² − 1)` over the faces
/// (both sides of a two-sided scene) reaches it: the search's running sums over the faces
/// sorted by area give the same sum.
#[test]
fn the_size_for_an_excess_gives_that_excess() {
    use crate::geometry::polygon;
    let scene = cornell();
    let sides = if scene.two_sided { 2.0 } else { 1.0 };
    let plain = |s: f64| -> f64 {
        let per_face = scene.faces.iter().map(|f| {
            let convex_quad = f.vertices.len() == 4 && polygon::is_convex(&f.vertices);
            let k = if convex_quad { 1.0 } else { 2.0 };
            (k * polygon::area(&f.vertices) / (s * s) - 1.0).max(0.0)
        });
        sides * per_face.sum::<f64>()
    };
    for extra in [10.0, 200.0, 5000.0] {
        let s = element_size_for_excess(&scene, extra);
        let got = plain(s);
        assert!((got - extra).abs() <= 1e-6 * extra, "{extra}: {got} at {s}");
    }
}
