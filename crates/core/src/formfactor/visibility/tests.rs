use super::*;
use crate::formfactor::{montecarlo, raycast};

/// Polygons with nothing to sample: no vertices, two, collinear, repeated points.
fn degenerate_polygons() -> Vec<Vec<DVec3>> {
    let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0));
    vec![vec![], vec![a], vec![a, b], vec![a, b, c], vec![b, b, b, b]]
}

fn unit_square_at(z: f64) -> Vec<DVec3> {
    // Facing down (−z), counter-clockwise seen from below.
    vec![
        DVec3::new(0.0, 0.0, z),
        DVec3::new(0.0, 1.0, z),
        DVec3::new(1.0, 1.0, z),
        DVec3::new(1.0, 0.0, z),
    ]
}

#[test]
fn degenerate_polygon_gives_an_empty_sampler_with_a_defined_point() {
    for poly in degenerate_polygons() {
        let s = PolygonSampler::new(&poly);
        assert!(s.is_empty(), "{poly:?}");
        // Used to panic: "index out of bounds: the len is 0 but the index is 0".
        let mean = poly.iter().copied().sum::<DVec3>() / poly.len().max(1) as f64;
        for (u1, u2) in [(0.0, 0.0), (0.5, 0.5), (1.0, 1.0), (f64::NAN, 0.3)] {
            assert_eq!(s.point(u1, u2), mean, "{poly:?}");
        }
    }
    assert!(!PolygonSampler::new(&unit_square_at(1.0)).is_empty());
}

#[test]
fn degenerate_target_is_invisible_to_every_estimator() {
    let bvh = Bvh::default();
    let (x, nx) = (DVec3::new(0.5, 0.5, 0.0), DVec3::Z);
    for poly in degenerate_polygons() {
        let s = PolygonSampler::new(&poly);
        let mut rng = Rng::new(7, 0);
        for probe in [false, true] {
            let v = visibility_fraction(&bvh, x, nx, &s, 4, probe, 1e-9, [u32::MAX; 2], &mut rng);
            assert_eq!(v, 0.0, "{poly:?}");
        }
        let f = occluded_point_to_polygon(
            &bvh,
            x,
            nx,
            &poly,
            &s,
            4,
            false,
            1e-9,
            [u32::MAX; 2],
            &mut rng,
        );
        assert_eq!(f, 0.0, "{poly:?}");
        let receiver = montecarlo::Receiver::Point(x, nx);
        let mc = montecarlo::estimate(&receiver, &s, 1.0, None, [u32::MAX; 2], 1e-9, 64, &mut rng);
        assert_eq!(mc, 0.0, "{poly:?}");
        // As the origin of rays or point pairs too.
        let square = PolygonSampler::new(&unit_square_at(1.0));
        let from_nothing = montecarlo::Receiver::Polygon(&s);
        let mc = montecarlo::estimate(
            &from_nothing,
            &square,
            1.0,
            None,
            [u32::MAX; 2],
            1e-9,
            64,
            &mut rng,
        );
        assert_eq!(mc, 0.0, "{poly:?}");
        let hits = raycast::hit_fraction(&bvh, raycast::Origin::Polygon(s), 0, 64, 1e-9, &mut rng);
        assert_eq!(hits, 0.0, "{poly:?}");
    }
}

/// Issue 11: a shooter whose edge lies in the receiver's tangent plane, but 5e-17 above
/// or below it by round-off (a wall patch starting at the height of a box top), must not
/// be clipped: clipping reorders its vertices and so the sampler's points.
#[test]
fn a_vertex_on_the_tangent_plane_up_to_round_off_is_not_clipped() {
    let wall = vec![
        DVec3::new(1.0, 0.3, 0.5),
        DVec3::new(1.0, 0.3, 0.6),
        DVec3::new(1.0, 0.4, 0.6),
        DVec3::new(1.0, 0.4, 0.5),
    ];
    for y in [0.3, 0.30000000000000004, 0.29999999999999993] {
        let part = part_above(&wall, DVec3::new(0.175, y, 0.275), DVec3::Y);
        assert!(matches!(part, Cow::Borrowed(_)), "receiver at y = {y}");
    }
    // A real tilt below the plane is still clipped.
    let part = part_above(&wall, DVec3::new(0.175, 0.3 + 1e-9, 0.275), DVec3::Y);
    assert!(matches!(part, Cow::Owned(_)));
}

#[test]
fn a_polygon_clipped_to_nothing_is_invisible() {
    let square = unit_square_at(1.0);
    let whole = PolygonSampler::new(&square);
    let x = DVec3::new(0.5, 0.5, 1.0);
    let nx = DVec3::X; // Tangent plane x = 0.5 cuts the square in half.
    let half = part_above(&square, x, nx);
    assert!(matches!(half, Cow::Owned(_)));
    assert!((polygon::area(&half) - 0.5).abs() < 1e-12);
    assert!(!part_sampler(&half, &whole).is_empty());
    // A plane through one edge only: nothing of area is left above it.
    let edge = part_above(&square, DVec3::new(1.0, 0.0, 1.0), DVec3::X);
    assert!(part_sampler(&edge, &whole).is_empty());
    let bvh = Bvh::default();
    let v = visibility_fraction(
        &bvh,
        DVec3::new(1.0, 0.5, 0.0),
        DVec3::X,
        &part_sampler(&edge, &whole),
        4,
        false,
        1e-9,
        [u32::MAX; 2],
        &mut Rng::new(3, 0),
    );
    assert_eq!(v, 0.0);
    // Everything above: the whole polygon's own sampler, not a copy.
    let all = part_above(&square, DVec3::new(0.5, 0.5, 0.0), DVec3::Z);
    assert!(matches!(all, Cow::Borrowed(_)));
    assert!(matches!(part_sampler(&all, &whole), Cow::Borrowed(_)));
}
