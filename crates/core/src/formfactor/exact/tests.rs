#[test]
fn a_point_inside_a_closed_box_sees_no_light() {
    // Floor point under a box resting on the floor (the box's faces are the blockers):
    // every ray to the light leaves through the box's top or sides.
    let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let light = vec![
        v(1.0 / 3.0, 1.0, 1.0 / 3.0),
        v(2.0 / 3.0, 1.0, 1.0 / 3.0),
        v(2.0 / 3.0, 1.0, 2.0 / 3.0),
        v(1.0 / 3.0, 1.0, 2.0 / 3.0),
    ];
    let c = [
        v(0.15, 0.0, 0.15),
        v(0.45, 0.0, 0.15),
        v(0.45, 0.3, 0.15),
        v(0.15, 0.3, 0.15),
        v(0.15, 0.0, 0.45),
        v(0.45, 0.0, 0.45),
        v(0.45, 0.3, 0.45),
        v(0.15, 0.3, 0.45),
    ];
    let quads = [
        [0, 1, 5, 4],
        [3, 7, 6, 2],
        [0, 3, 2, 1],
        [4, 5, 6, 7],
        [0, 4, 7, 3],
        [1, 2, 6, 5],
    ];
    let mut tris = Vec::new();
    for q in quads {
        tris.push(vec![c[q[0]], c[q[1]], c[q[2]]]);
        tris.push(vec![c[q[0]], c[q[2]], c[q[3]]]);
    }
    for (x, z) in [(0.425, 0.425), (0.3, 0.3), (0.175, 0.35), (0.44, 0.2)] {
        let f = point_to_visible_polygon(v(x, 1e-6, z), DVec3::Y, &light, &tris);
        assert!(f.abs() < 1e-9, "({x}, {z}): {f}");
        // Top and sides alone must hide it too (the bottom is below the point).
        let f = point_to_visible_polygon(v(x, 1e-6, z), DVec3::Y, &light, &tris[2..]);
        assert!(f.abs() < 1e-9, "({x}, {z}) without the bottom: {f}");
    }
}
use super::*;

fn square(z: f64, up: bool) -> Vec<DVec3> {
    let mut s = vec![
        DVec3::new(0.0, 0.0, z),
        DVec3::new(1.0, 0.0, z),
        DVec3::new(1.0, 1.0, z),
        DVec3::new(0.0, 1.0, z),
    ];
    if !up {
        s.reverse();
    }
    s
}

#[test]
fn parallel_unit_squares() {
    let f = polygon_to_polygon(&square(0.0, true), &square(1.0, false));
    assert!((f - 0.199_824_895_698_387_38).abs() < 1e-13, "{f}");
}

#[test]
fn a_point_sees_exactly_half_of_a_source_behind_a_half_blocker() {
    let src = square(1.0, false);
    let p = DVec3::new(0.5, 0.5, 0.0);
    let open = point_to_visible_polygon(p, DVec3::Z, &src, &[]);
    assert!((open - contour::point_to_polygon(p, DVec3::Z, &src)).abs() < 1e-15);
    // A blocker over x < 0.5 at mid-height hides x < 0.5 of the source: by symmetry half.
    let blocker = vec![
        DVec3::new(-1.0, -1.0, 0.5),
        DVec3::new(0.5, -1.0, 0.5),
        DVec3::new(0.5, 2.0, 0.5),
        DVec3::new(-1.0, 2.0, 0.5),
    ];
    let half = point_to_visible_polygon(p, DVec3::Z, &src, std::slice::from_ref(&blocker));
    assert!(
        (half - open / 2.0).abs() < 1e-14,
        "{half} vs {}",
        open / 2.0
    );
    // The same blocker twice hides nothing more.
    let twice = point_to_visible_polygon(p, DVec3::Z, &src, &[blocker.clone(), blocker]);
    assert!((twice - half).abs() < 1e-14);
}

/// Issue 11, scale 1e4: a box edge's shadow that only touches a piece of the light
/// leaves a point-like hole (three vertices within 2e-12 of each other). It hides
/// nothing; its edges have no outward side, and subtracting them returned the piece
/// twice over (areas 265,115 + 24,101 + 241,013 for a piece of 265,115).
#[test]
fn a_point_like_shadow_hides_nothing() {
    let v = DVec3::new;
    let piece = vec![
        v(5000.0, 10000.0, 3333.33333333),
        v(5318.137882918239, 10000.0, 3333.33333333),
        v(5318.137882918239, 10000.0, 4166.666666665),
        v(5000.0, 10000.0, 4166.666666665),
    ];
    let hole = vec![
        v(5318.137882918239, 10000.0, 3409.091097102341),
        v(5318.137882918239, 10000.000000000002, 3409.091097102341),
        v(5318.1378829182395, 10000.000000000002, 3409.091097102341),
    ];
    for sn in [DVec3::NEG_Y, DVec3::Y] {
        let out = subtract_convex(&piece, &hole, sn);
        let area: f64 = out.iter().map(|q| polygon::area(q)).sum();
        let whole = polygon::area(&piece);
        assert!(
            (area - whole).abs() <= 1e-9 * whole,
            "sn {sn}: {} pieces of total area {area}, the piece is {whole}",
            out.len()
        );
    }
    // A real hole still comes out: the middle third of the piece's width.
    let (x0, x1) = (
        5000.0 + 318.137882918239 / 3.0,
        5000.0 + 2.0 * 318.137882918239 / 3.0,
    );
    let hole = vec![
        v(x0, 10000.0, 3500.0),
        v(x0, 10000.0, 4000.0),
        v(x1, 10000.0, 4000.0),
        v(x1, 10000.0, 3500.0),
    ];
    let sn = polygon::normal(&piece).expect("piece normal");
    let hole = if polygon::normal(&hole).expect("hole normal").dot(sn) > 0.0 {
        hole
    } else {
        hole.into_iter().rev().collect()
    };
    let area: f64 = subtract_convex(&piece, &hole, sn)
        .iter()
        .map(|q| polygon::area(q))
        .sum();
    let expected = polygon::area(&piece) - polygon::area(&hole);
    assert!(
        (area - expected).abs() <= 1e-9 * expected,
        "{area} vs {expected}"
    );
}
