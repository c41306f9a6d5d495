//! Planar polygons: normal, area, planarity, triangulation and clipping.
//!
//! A polygon is a slice of vertices, counter-clockwise seen from its front; its normal
//! (Newell's method) points to the front.

use glam::DVec3;

/// Newell's normal: length = twice the area, direction = front side.
pub fn newell(poly: &[DVec3]) -> DVec3 {
    let n = poly.len();
    let mut acc = DVec3::ZERO;
    // Subtracting the first vertex keeps precision for polygons far from the origin.
    let o = poly.first().copied().unwrap_or(DVec3::ZERO);
    for i in 0..n {
        let a = poly[i] - o;
        let b = poly[(i + 1) % n] - o;
        acc += a.cross(b);
    }
    acc
}

/// Unit normal, or `None` for a degenerate polygon.
pub fn normal(poly: &[DVec3]) -> Option<DVec3> {
    newell(poly).try_normalize()
}

pub fn area(poly: &[DVec3]) -> f64 {
    newell(poly).length() * 0.5
}

/// Area-weighted centroid of a planar polygon.
pub fn centroid(poly: &[DVec3]) -> DVec3 {
    let n = normal(poly).unwrap_or(DVec3::Z);
    let o = poly[0];
    let mut c = DVec3::ZERO;
    let mut total = 0.0;
    for i in 1..poly.len().saturating_sub(1) {
        let a = (poly[i] - o).cross(poly[i + 1] - o).dot(n) * 0.5;
        c += (o + poly[i] + poly[i + 1]) / 3.0 * a;
        total += a;
    }
    if total.abs() > 0.0 {
        c / total
    } else {
        poly.iter().copied().sum::<DVec3>() / poly.len().max(1) as f64
    }
}

/// Largest distance of a vertex from the polygon's best-fit plane.
pub fn planarity_error(poly: &[DVec3]) -> f64 {
    let Some(n) = normal(poly) else { return 0.0 };
    let c = poly.iter().copied().sum::<DVec3>() / poly.len() as f64;
    poly.iter()
        .map(|p| (p - c).dot(n).abs())
        .fold(0.0, f64::max)
}

/// True when every corner turns the same way (a convex polygon, collinear corners allowed).
pub fn is_convex(poly: &[DVec3]) -> bool {
    let Some(n) = normal(poly) else { return false };
    let k = poly.len();
    (0..k).all(|i| {
        let a = poly[i];
        let b = poly[(i + 1) % k];
        let c = poly[(i + 2) % k];
        (b - a).cross(c - b).dot(n) >= -1e-12 * (b - a).length() * (c - b).length()
    })
}

/// Triangulates a simple planar polygon by ear clipping; returns index triples.
/// Works for concave polygons; a degenerate polygon gives no triangles.
pub fn triangulate(poly: &[DVec3]) -> Vec<[usize; 3]> {
    let Some(n) = normal(poly) else {
        return Vec::new();
    };
    let mut idx: Vec<usize> = (0..poly.len()).collect();
    let mut out = Vec::with_capacity(poly.len().saturating_sub(2));
    let mut guard = 0;
    while idx.len() > 3 && guard < 10 * poly.len() * poly.len() {
        guard += 1;
        let m = idx.len();
        let mut clipped = false;
        for i in 0..m {
            let (ia, ib, ic) = (idx[(i + m - 1) % m], idx[i], idx[(i + 1) % m]);
            let (a, b, c) = (poly[ia], poly[ib], poly[ic]);
            if (b - a).cross(c - b).dot(n) <= 0.0 {
                continue;
            }
            let inside = idx
                .iter()
                .any(|&j| j != ia && j != ib && j != ic && point_in_triangle(poly[j], a, b, c, n));
            if !inside {
                out.push([ia, ib, ic]);
                idx.remove(i);
                clipped = true;
                break;
            }
        }
        if !clipped {
            // Numerically stuck (nearly collinear run): fall back to a fan.
            for i in 1..idx.len() - 1 {
                out.push([idx[0], idx[i], idx[i + 1]]);
            }
            return out;
        }
    }
    if idx.len() == 3 {
        out.push([idx[0], idx[1], idx[2]]);
    }
    out
}

fn point_in_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3, n: DVec3) -> bool {
    let s1 = (b - a).cross(p - a).dot(n);
    let s2 = (c - b).cross(p - b).dot(n);
    let s3 = (a - c).cross(p - c).dot(n);
    s1 >= 0.0 && s2 >= 0.0 && s3 >= 0.0
}

/// A generic direction (1, √2, √3)/√6: no edge of axis-aligned or otherwise regular geometry
/// is perpendicular to it, so two vertices of a polygon practically never tie along it.
const CANONICAL_AXIS: DVec3 = DVec3::new(
    0.408_248_290_463_863,
    0.577_350_269_189_625_8,
    0.707_106_781_186_547_5,
);

/// Index of the vertex of `poly` farthest along a fixed generic direction (the first of
/// exact ties; 0 for an empty polygon): the same vertex whichever one the list starts at
/// and whatever the unit, since it depends only on differences of vertices. Rotating a
/// polygon built by an algorithm whose starting vertex depends on round-off (a convex hull
/// starting at its lexicographically smallest point) to start there makes its list, and so
/// everything that samples it in list order, independent of that round-off.
pub fn canonical_start(poly: &[DVec3]) -> usize {
    let Some(&first) = poly.first() else {
        return 0;
    };
    let mut best = (f64::NEG_INFINITY, 0);
    for (k, v) in poly.iter().enumerate() {
        let key = (*v - first).dot(CANONICAL_AXIS);
        if key > best.0 {
            best = (key, k);
        }
    }
    best.1
}

/// Clips a polygon to the half-space `(x - origin) · n >= 0` (Sutherland–Hodgman).
pub fn clip_to_halfspace(poly: &[DVec3], origin: DVec3, n: DVec3) -> Vec<DVec3> {
    let k = poly.len();
    let mut out = Vec::with_capacity(k + 2);
    for i in 0..k {
        let a = poly[i];
        let b = poly[(i + 1) % k];
        let da = (a - origin).dot(n);
        let db = (b - origin).dot(n);
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            out.push(a + (b - a) * t);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_properties() {
        let sq = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        assert!((area(&sq) - 1.0).abs() < 1e-15);
        assert_eq!(normal(&sq), Some(DVec3::Z));
        assert!((centroid(&sq) - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-15);
        assert!(is_convex(&sq));
        assert_eq!(triangulate(&sq).len(), 2);
    }

    #[test]
    fn concave_polygon_triangulates_with_right_area() {
        // An L shape of area 3.
        let l = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        assert!(!is_convex(&l));
        let tris = triangulate(&l);
        assert_eq!(tris.len(), 4);
        let total: f64 = tris
            .iter()
            .map(|t| area(&[l[t[0]], l[t[1]], l[t[2]]]))
            .sum();
        assert!((total - 3.0).abs() < 1e-12);
    }

    #[test]
    fn the_canonical_start_does_not_depend_on_the_listing() {
        let pentagon: Vec<DVec3> = (0..5)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 5.0 + 0.3;
                DVec3::new(a.cos(), 0.2 * a.sin(), a.sin())
            })
            .collect();
        let c = canonical_start(&pentagon);
        for start in 0..5 {
            let rotated: Vec<DVec3> = pentagon[start..]
                .iter()
                .chain(&pentagon[..start])
                .copied()
                .collect();
            let k = canonical_start(&rotated);
            assert_eq!(rotated[k], pentagon[c], "listed from vertex {start}");
            // The same polygon in another unit and place.
            let moved: Vec<DVec3> = rotated.iter().map(|v| *v * 1e-3 + DVec3::X).collect();
            assert_eq!(
                canonical_start(&moved),
                k,
                "listed from vertex {start}, moved"
            );
        }
        assert_eq!(canonical_start(&[]), 0);
    }

    #[test]
    fn clipping_halves_a_square() {
        let sq = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        let half = clip_to_halfspace(&sq, DVec3::new(0.5, 0.0, 0.0), DVec3::X);
        assert!((area(&half) - 0.5).abs() < 1e-15);
    }
}
