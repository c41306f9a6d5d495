//! Point-to-polygon form factor by Lambert's contour formula.
//!
//! For a differential receiver at `p` with unit normal `n` and an unoccluded planar polygon
//! with vertices `v_k` (unit directions `u_k` from `p`):
//! `F = (1/2π) Σ_k γ_k · n · (u_k × u_{k+1}) / |u_k × u_{k+1}|`, with γ_k the angle between
//! `u_k` and `u_{k+1}` (Lambert 1760; Baum, Rushmeier, Winget 1989, "Improving radiosity
//! solutions through the use of analytically determined form-factors"). It is exact for a
//! point, including a point right next to the polygon, where the point-to-point estimate
//! `A cosθ cosθ' / (π r²)` diverges. The part of the polygon behind the receiver's tangent
//! plane is clipped away first. Error: float round-off only (≈1e-15 relative) for a point;
//! used at an element's centroid it is the midpoint rule over the receiving element.

use glam::DVec3;

use crate::geometry::polygon;

/// Form factor from a differential area at `p` (unit normal `n`) to `poly`, seen from the
/// polygon's front (counter-clockwise side). Returns 0 when `p` is behind the polygon.
///
/// A point 1 below the centre of a unit square facing it: four 0.5 × 0.5 rectangles with a
/// corner overhead, each `(1/2π)[A/√(1+A²) atan(B/√(1+A²)) + B/√(1+B²) atan(A/√(1+B²))]`
/// with `A = B = 0.5` (Howell's catalogue, B-3):
///
/// ```
/// use glam::DVec3;
/// use nusselt_core::formfactor::contour::point_to_polygon;
///
/// // Facing down (−z): counter-clockwise seen from below.
/// let square = [
///     DVec3::new(0.0, 0.0, 1.0),
///     DVec3::new(0.0, 1.0, 1.0),
///     DVec3::new(1.0, 1.0, 1.0),
///     DVec3::new(1.0, 0.0, 1.0),
/// ];
/// let f = point_to_polygon(DVec3::new(0.5, 0.5, 0.0), DVec3::Z, &square);
///
/// let (a, b) = (0.5f64, 0.5f64);
/// let (sa, sb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
/// let corner = (a / sa * (b / sa).atan() + b / sb * (a / sb).atan()) / (2.0 * std::f64::consts::PI);
/// assert!((f - 4.0 * corner).abs() < 1e-14, "{f} vs {}", 4.0 * corner);
///
/// // Behind the square, or facing away from it: nothing.
/// assert_eq!(point_to_polygon(DVec3::new(0.5, 0.5, 2.0), DVec3::NEG_Z, &square), 0.0);
/// assert_eq!(point_to_polygon(DVec3::new(0.5, 0.5, 0.0), DVec3::NEG_Z, &square), 0.0);
/// ```
pub fn point_to_polygon(p: DVec3, n: DVec3, poly: &[DVec3]) -> f64 {
    match polygon::normal(poly) {
        Some(pn) => point_to_polygon_with_normal(p, n, poly, pn),
        None => 0.0,
    }
}

/// [`point_to_polygon`] with the polygon's unit normal `pn` given (the solver's hot path).
pub fn point_to_polygon_with_normal(p: DVec3, n: DVec3, poly: &[DVec3], pn: DVec3) -> f64 {
    // The source emits from its front only.
    if (p - poly[0]).dot(pn) <= 0.0 {
        return 0.0;
    }
    let all_above = poly.iter().all(|v| (*v - p).dot(n) >= 0.0);
    if all_above {
        lambert(p, n, poly)
    } else {
        let clipped = polygon::clip_to_halfspace(poly, p, n);
        if clipped.len() < 3 {
            0.0
        } else {
            lambert(p, n, &clipped)
        }
    }
}

/// The contour sum itself; `poly` must lie in the closed half-space above `p`.
pub fn lambert(p: DVec3, n: DVec3, poly: &[DVec3]) -> f64 {
    // Unit directions, each computed once; on the stack for up to 8 vertices.
    let k = poly.len();
    if k <= 8 {
        let mut buf = [DVec3::ZERO; 8];
        contour_sum(p, n, poly, &mut buf[..k])
    } else {
        contour_sum(p, n, poly, &mut vec![DVec3::ZERO; k])
    }
}

fn contour_sum(p: DVec3, n: DVec3, poly: &[DVec3], units: &mut [DVec3]) -> f64 {
    let k = poly.len();
    for (u, v) in units.iter_mut().zip(poly) {
        *u = (*v - p).normalize_or_zero();
    }
    let mut sum = 0.0;
    for i in 0..k {
        let (a, b) = (units[i], units[(i + 1) % k]);
        let c = a.cross(b);
        let s = c.length();
        if s > 1e-300 {
            sum += s.atan2(a.dot(b)) * n.dot(c) / s;
        }
    }
    // Counter-clockwise seen from the front, viewed from the front: the sum is negative.
    (-sum / (2.0 * std::f64::consts::PI)).max(0.0)
}

/// Point-to-point (disc) estimate `A cosθ cosθ' / (π r²)`, for comparison only.
pub fn point_to_point(p: DVec3, n: DVec3, q: DVec3, nq: DVec3, area: f64) -> f64 {
    let d = q - p;
    let r2 = d.length_squared();
    if r2 <= 0.0 {
        return 0.0;
    }
    let cos_p = n.dot(d) / r2.sqrt();
    let cos_q = -nq.dot(d) / r2.sqrt();
    if cos_p <= 0.0 || cos_q <= 0.0 {
        return 0.0;
    }
    area * cos_p * cos_q / (std::f64::consts::PI * r2)
}

/// Form factor from polygon `a1` to `a2` by integrating the contour formula over `a1`
/// with an `n × n` midpoint rule per triangle of `a1`'s subdivision.
pub fn polygon_to_polygon(a1: &[DVec3], a2: &[DVec3], n: usize) -> f64 {
    let Some(n1) = polygon::normal(a1) else {
        return 0.0;
    };
    let area = polygon::area(a1);
    let mut sum = 0.0;
    for t in polygon::triangulate(a1) {
        let (a, b, c) = (a1[t[0]], a1[t[1]], a1[t[2]]);
        let ta = polygon::area(&[a, b, c]);
        let n = n.max(1);
        let at = |i: f64, j: f64| a + (b - a) * (i / n as f64) + (c - a) * (j / n as f64);
        let small = ta / (n * n) as f64;
        for j in 0..n {
            for i in 0..n - j {
                let (fi, fj) = (i as f64, j as f64);
                let up = (at(fi, fj) + at(fi + 1.0, fj) + at(fi, fj + 1.0)) / 3.0;
                sum += point_to_polygon(up, n1, a2) * small;
                if i + j + 1 < n {
                    let down = (at(fi + 1.0, fj) + at(fi + 1.0, fj + 1.0) + at(fi, fj + 1.0)) / 3.0;
                    sum += point_to_polygon(down, n1, a2) * small;
                }
            }
        }
    }
    sum / area
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn lambert_matches_closed_forms() {
        let sq = unit_square_at(1.0);
        let centre = point_to_polygon(DVec3::new(0.5, 0.5, 0.0), DVec3::Z, &sq);
        let corner = point_to_polygon(DVec3::ZERO, DVec3::Z, &sq);
        assert!((centre - 0.239_456_2).abs() < 1e-6, "{centre}");
        assert!((corner - 0.138_532_0).abs() < 1e-6, "{corner}");
        // Behind the source, or facing away: nothing.
        assert_eq!(
            point_to_polygon(DVec3::new(0.5, 0.5, 2.0), DVec3::NEG_Z, &sq),
            0.0
        );
        assert_eq!(
            point_to_polygon(DVec3::new(0.5, 0.5, 0.0), DVec3::NEG_Z, &sq),
            0.0
        );
    }

    #[test]
    fn clipped_polygon_counts_only_the_visible_part() {
        // A large wall perpendicular to the receiver, half of it below the tangent plane.
        let wall = vec![
            DVec3::new(1.0, -5.0, -5.0),
            DVec3::new(1.0, -5.0, 5.0),
            DVec3::new(1.0, 5.0, 5.0),
            DVec3::new(1.0, 5.0, -5.0),
        ];
        let f = point_to_polygon(DVec3::ZERO, DVec3::Z, &wall);
        // Differential element to a perpendicular 5 × 10 plate at distance 1 (Howell B-2),
        // twice the 5 × 5 half: (1/2π)[atan B − atan(B/√(1+A²))/√(1+A²)], A = B = 5.
        let s = (1.0f64 + 25.0).sqrt();
        let half = (5.0f64.atan() - (5.0 / s).atan() / s) / (2.0 * std::f64::consts::PI);
        assert!((f - 2.0 * half).abs() < 1e-12, "{f} vs {}", 2.0 * half);
    }

    #[test]
    fn point_to_point_blows_up_near_contact_where_contour_does_not() {
        let sq = unit_square_at(0.05);
        let p = DVec3::new(0.5, 0.5, 0.0);
        let exact = point_to_polygon(p, DVec3::Z, &sq);
        let disc = point_to_point(p, DVec3::Z, DVec3::new(0.5, 0.5, 0.05), DVec3::NEG_Z, 1.0);
        assert!(exact < 1.0 && exact > 0.9);
        assert!(disc > 100.0);
    }
}
