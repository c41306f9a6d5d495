use super::*;
use crate::geometry::bvh::TriangleInput;

/// A UV sphere of radius `r` about `c`: `rings × segments` faces (triangles at the poles,
/// quads between), wound so their normals point outwards.
fn sphere(c: DVec3, r: f64, rings: usize, segments: usize) -> Vec<Vec<DVec3>> {
    let at = |i: usize, j: usize| {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        let ph = std::f64::consts::TAU * (j % segments) as f64 / segments as f64;
        c + r * DVec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin())
    };
    let mut faces = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let mut f = vec![at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)];
            f.dedup_by(|a, b| a.distance(*b) < 1e-12);
            if f.first().unwrap().distance(*f.last().unwrap()) < 1e-12 {
                f.pop();
            }
            // Outward: the normal points away from the centre.
            if polygon::normal(&f).unwrap().dot(f[0] - c) < 0.0 {
                f.reverse();
            }
            faces.push(f);
        }
    }
    faces
}

fn group_of(faces: &[Vec<DVec3>]) -> FacetGroup {
    let emitting: Vec<EmittingFace> = faces
        .iter()
        .map(|v| EmittingFace {
            vertices: v,
            emission: Rgb::ONE,
            occluder: 7,
        })
        .collect();
    FacetGroup::new(&emitting.iter().collect::<Vec<_>>())
}

/// The exact unoccluded factor, facet by facet (contour integrals of every facet).
fn exact_sum(faces: &[Vec<DVec3>], p: DVec3, n: DVec3) -> f64 {
    faces
        .iter()
        .map(|f| {
            formfactor::contour::point_to_polygon_with_normal(p, n, f, polygon::normal(f).unwrap())
                .max(0.0)
        })
        .sum()
}

fn at(p: DVec3, n: DVec3, own: u32) -> Receiver {
    Receiver {
        p,
        n,
        origin: p,
        own,
    }
}

fn unblocked(g: &FacetGroup, p: DVec3, n: DVec3) -> f64 {
    let mut work = 0;
    g.visible_factor(
        &at(p, n, u32::MAX),
        &Bvh::default(),
        &mut Rng::new(1, 0),
        &mut work,
    )
}

/// The group's unblocked factor at `p` (normal `n`) within `tolerance` (relative) of the
/// exact sum over `faces`.
fn assert_exact_sum(g: &FacetGroup, faces: &[Vec<DVec3>], p: DVec3, n: DVec3, tolerance: f64) {
    let exact = exact_sum(faces, p, n);
    let got = unblocked(g, p, n);
    assert!(
        (got / exact - 1.0).abs() < tolerance,
        "at {p}: {got} against {exact}"
    );
}

/// Far from the light the group's factor is the exact one to the point kernel's error
/// (facets at 15–40 sizes away: `(size / r)²` under 0.5 %), and the sphere's analytic
/// `(R / d)²` to the tessellation's (the inscribed polyhedron's smaller area, about 2 %).
#[test]
fn far_from_the_light_the_factor_is_the_exact_sum() {
    let c = DVec3::new(0.0, 5.0, 0.0);
    let faces = sphere(c, 1.0, 12, 24);
    let g = group_of(&faces);
    for (p, n) in [
        (DVec3::ZERO, DVec3::Y),
        (DVec3::new(3.0, 0.0, 1.0), DVec3::Y),
        (DVec3::new(0.0, 5.0, -6.0), DVec3::Z),
    ] {
        assert_exact_sum(&g, &faces, p, n, 5e-3);
    }
    let analytic = 1.0 / 25.0;
    let got = unblocked(&g, DVec3::ZERO, DVec3::Y);
    assert!(
        (got / analytic - 1.0).abs() < 0.03,
        "{got} against {analytic}"
    );
}

/// Close to the light the near facets take their exact factor; the far ones' point kernel
/// errs by `(size / (8 size))²` at most, under 1 % of the sum.
#[test]
fn near_the_light_the_factor_is_still_the_exact_sum() {
    let c = DVec3::new(0.0, 1.5, 0.0);
    let faces = sphere(c, 1.0, 12, 24);
    let g = group_of(&faces);
    for (p, n) in [
        (DVec3::ZERO, DVec3::Y),
        (DVec3::new(0.8, 0.0, 0.3), DVec3::Y),
        (
            DVec3::new(1.2, 0.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0) * std::f64::consts::FRAC_1_SQRT_2,
        ),
    ] {
        assert_exact_sum(&g, &faces, p, n, 0.01);
    }
}

/// A blocker hiding half the sphere (by symmetry) passes half its light on average over
/// seeds: 400 estimates of 16 stratified rays, each within [0, F], give a mean within
/// `3 · F / (2 √(16 · 400))` ≈ 2 % of F of the truth; a blocker hiding all of it passes none.
#[test]
fn blockers_take_their_share() {
    let c = DVec3::new(0.0, 5.0, 0.0);
    let faces = sphere(c, 1.0, 12, 24);
    let g = group_of(&faces);
    let quad = |x0: f64, x1: f64| {
        let v = [
            DVec3::new(x0, 2.5, -3.0),
            DVec3::new(x1, 2.5, -3.0),
            DVec3::new(x1, 2.5, 3.0),
            DVec3::new(x0, 2.5, 3.0),
        ];
        [[v[0], v[1], v[2]], [v[0], v[2], v[3]]].map(|vertices| TriangleInput {
            vertices,
            id: 1,
            cull_back: false,
            cut: None,
        })
    };
    let (p, n) = (DVec3::ZERO, DVec3::Y);
    let full = unblocked(&g, p, n);
    let half = Bvh::build(&quad(-3.0, 0.0));
    let runs = 400;
    let mut work = 0;
    let mean = (0..runs)
        .map(|s| g.visible_factor(&at(p, n, 0), &half, &mut Rng::new(s, 3), &mut work))
        .sum::<f64>()
        / runs as f64;
    assert!(
        (mean / full - 0.5).abs() < 0.02,
        "{mean} against {}",
        full / 2.0
    );
    let all = Bvh::build(&quad(-3.0, 3.0));
    let hidden = g.visible_factor(&at(p, n, 0), &all, &mut Rng::new(1, 3), &mut work);
    assert_eq!(hidden, 0.0);
    // Its cost: a unit per ray and per 16 facets, not a shaft per facet.
    assert!(work < runs * (1 + SHADOW_RAYS as u64 + 600 / 16) * 2);
}

/// Faces sharing a vertex and an emission are one group; another emission, or no shared
/// vertex, another.
#[test]
fn groups_are_connected_faces_of_one_emission() {
    let a = sphere(DVec3::ZERO, 1.0, 4, 6);
    let b = sphere(DVec3::new(5.0, 0.0, 0.0), 1.0, 4, 6);
    let mut faces: Vec<EmittingFace> = a
        .iter()
        .chain(&b)
        .map(|v| EmittingFace {
            vertices: v,
            emission: Rgb::ONE,
            occluder: 0,
        })
        .collect();
    let groups = group_faces(&faces);
    assert_eq!(groups.len(), 2);
    assert_eq!(groups[0], (0..24).collect::<Vec<_>>());
    assert_eq!(groups[1], (24..48).collect::<Vec<_>>());
    // The first sphere's first face in another colour leaves it: a group of its own.
    faces[0].emission = Rgb::new(2.0, 1.0, 1.0);
    let groups = group_faces(&faces);
    assert_eq!(groups.len(), 3);
    assert_eq!(groups[0], vec![0]);
    assert_eq!(groups[1], (1..24).collect::<Vec<_>>());
}
