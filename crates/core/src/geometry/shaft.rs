//! Shaft culling: the convex hull of two convex polygons (or a point and a polygon) as a set
//! of planes, and which scene triangles may cut it (Haines & Wallace 1994, "Shaft culling
//! for efficient ray-cast radiosity").
//!
//! Every segment between a point of `A` and a point of `B` lies in the hull of `A ∪ B`, so a
//! triangle that misses the hull cannot block any of them: a pair whose shaft holds no
//! triangle is fully visible, exactly, with no shadow ray at all, and the shadow rays of a
//! pair that does hold some need only be tested against those few triangles.
//!
//! The test is conservative: a triangle counts as outside only when all of its vertices lie
//! on or beyond one hull plane (within a tolerance), or its box misses the hull's box. A
//! triangle that merely touches the hull's boundary (a wall meeting both patches at an edge)
//! can therefore be reported; then the caller falls back to rays, which is slower, not wrong.

use glam::DVec3;

use super::Aabb;

/// The convex hull of two point sets given as convex planar polygons (a polygon may be a
/// single point), as outward planes `n·x ≤ d` plus a bounding box.
/// Planes kept per shaft; further faces of a very detailed hull are dropped, which only makes
/// the shaft larger (still conservative).
const MAX_PLANES: usize = 40;

#[derive(Clone, Debug)]
pub struct Shaft {
    planes: [(DVec3, f64); MAX_PLANES],
    plane_count: usize,
    bounds: Aabb,
    /// A point counts as outside a plane when `n·x − d ≥ −tolerance`.
    tolerance: f64,
}

impl Shaft {
    /// Hull of `a ∪ b`. `a` and `b` are convex and planar (or a single point);
    /// `tolerance` is in scene units. A degenerate (flat) hull keeps only its box.
    pub fn between(a: &[DVec3], b: &[DVec3], tolerance: f64) -> Shaft {
        let mut bounds = Aabb::from_points(a.iter());
        for p in b {
            bounds.grow(*p);
        }
        let scale = bounds.diagonal().max(f64::MIN_POSITIVE);
        let mut planes = [(DVec3::ZERO, 0.0); MAX_PLANES];
        let mut plane_count = 0;
        let mut consider = |p0: DVec3, p1: DVec3, p2: DVec3| {
            if plane_count == MAX_PLANES {
                return;
            }
            let Some(n) = (p1 - p0).cross(p2 - p0).try_normalize() else {
                return;
            };
            let d = n.dot(p0);
            let (mut lo, mut hi) = (0.0f64, 0.0f64);
            for p in a.iter().chain(b) {
                let s = n.dot(*p) - d;
                lo = lo.min(s);
                hi = hi.max(s);
            }
            let flat = 1e-9 * scale;
            if hi <= flat && lo < -flat {
                planes[plane_count] = (n, d);
                plane_count += 1;
            } else if lo >= -flat && hi > flat {
                planes[plane_count] = (-n, -d);
                plane_count += 1;
            }
            // Points on both sides: not a hull face. All on the plane: a flat hull.
        };
        // Faces of the hull of two convex polygons: the polygons' own planes, and planes
        // through an edge of one and a vertex of the other.
        for (poly, other) in [(a, b), (b, a)] {
            if poly.len() >= 3 {
                // The polygon's own plane (centroid and an edge: well conditioned).
                let c = poly.iter().copied().sum::<DVec3>() / poly.len() as f64;
                consider(c, poly[0], poly[1]);
            }
            if poly.len() >= 2 {
                for k in 0..poly.len() {
                    let (e0, e1) = (poly[k], poly[(k + 1) % poly.len()]);
                    for v in other {
                        consider(e0, e1, *v);
                    }
                }
            }
        }
        Shaft {
            planes,
            plane_count,
            bounds,
            tolerance,
        }
    }

    /// Only the bounding box of `a ∪ b` (no planes): a cheap first cull.
    pub fn bounding_box(a: &[DVec3], b: &[DVec3], tolerance: f64) -> Shaft {
        let mut bounds = Aabb::from_points(a.iter());
        for p in b {
            bounds.grow(*p);
        }
        Shaft {
            planes: [(DVec3::ZERO, 0.0); MAX_PLANES],
            plane_count: 0,
            bounds,
            tolerance,
        }
    }

    /// The pyramid from `apex` to a convex planar polygon `base` lying in front of it:
    /// the same hull as `between(&[apex], base)`, built directly.
    pub fn pyramid(apex: DVec3, base: &[DVec3], tolerance: f64) -> Shaft {
        let mut bounds = Aabb::from_points(base.iter());
        bounds.grow(apex);
        let mut planes = [(DVec3::ZERO, 0.0); MAX_PLANES];
        let mut plane_count = 0;
        let k = base.len();
        if k >= 3 {
            let c = base.iter().copied().sum::<DVec3>() / k as f64;
            let mut add = |n: DVec3, p: DVec3, inside: DVec3| {
                if plane_count < MAX_PLANES
                    && let Some(n) = n.try_normalize()
                {
                    let (n, d) = (n, n.dot(p));
                    // Orient outward: the inside point below the plane.
                    planes[plane_count] = if n.dot(inside) - d <= 0.0 {
                        (n, d)
                    } else {
                        (-n, -d)
                    };
                    plane_count += 1;
                }
            };
            // The apex is inside the base plane's half-space; the centroid inside the sides'.
            add((base[1] - base[0]).cross(base[2] - base[0]), base[0], apex);
            for i in 0..k {
                let (e0, e1) = (base[i], base[(i + 1) % k]);
                add((e0 - apex).cross(e1 - apex), apex, c);
            }
        }
        Shaft {
            planes,
            plane_count,
            bounds,
            tolerance,
        }
    }

    fn planes(&self) -> &[(DVec3, f64)] {
        &self.planes[..self.plane_count]
    }

    pub fn bounds(&self) -> &Aabb {
        &self.bounds
    }

    /// True when the triangle certainly misses the hull (conservative: `false` may be wrong).
    #[inline]
    pub fn excludes_triangle(&self, v: [DVec3; 3]) -> bool {
        let t = self.tolerance;
        let lo = v[0].min(v[1]).min(v[2]);
        let hi = v[0].max(v[1]).max(v[2]);
        if lo.cmpge(self.bounds.max - t).any() || hi.cmple(self.bounds.min + t).any() {
            return true;
        }
        self.planes()
            .iter()
            .any(|(n, d)| v.iter().all(|p| n.dot(*p) - d >= -t))
    }

    /// True when the box certainly misses the hull.
    #[inline]
    pub fn excludes_box(&self, min: DVec3, max: DVec3) -> bool {
        let t = self.tolerance;
        for axis in 0..3 {
            if min[axis] >= self.bounds.max[axis] - t || max[axis] <= self.bounds.min[axis] + t {
                return true;
            }
        }
        self.planes().iter().any(|(n, d)| {
            // The box corner deepest inside the plane.
            let p = DVec3::new(
                if n.x > 0.0 { min.x } else { max.x },
                if n.y > 0.0 { min.y } else { max.y },
                if n.z > 0.0 { min.z } else { max.z },
            );
            n.dot(p) - d >= -t
        })
    }

    /// Whether `p` lies inside the hull (by more than the tolerance).
    pub fn contains(&self, p: DVec3) -> bool {
        let t = self.tolerance;
        (0..3).all(|a| p[a] > self.bounds.min[a] + t && p[a] < self.bounds.max[a] - t)
            && self.planes().iter().all(|(n, d)| n.dot(p) - d < -t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(z: f64, size: f64) -> Vec<DVec3> {
        vec![
            DVec3::new(0.0, 0.0, z),
            DVec3::new(size, 0.0, z),
            DVec3::new(size, size, z),
            DVec3::new(0.0, size, z),
        ]
    }

    #[test]
    fn hull_of_two_parallel_squares_is_the_box_between_them() {
        let s = Shaft::between(&square(0.0, 1.0), &square(1.0, 1.0), 1e-9);
        assert!(s.contains(DVec3::new(0.5, 0.5, 0.5)));
        assert!(!s.contains(DVec3::new(1.5, 0.5, 0.5)));
        assert!(!s.contains(DVec3::new(0.5, 0.5, 1.5)));
        // A blocker half-way is inside; one beside the shaft is not.
        let inside = [
            DVec3::new(0.2, 0.2, 0.5),
            DVec3::new(0.8, 0.2, 0.5),
            DVec3::new(0.5, 0.8, 0.5),
        ];
        let beside = inside.map(|p| p + DVec3::new(2.0, 0.0, 0.0));
        assert!(!s.excludes_triangle(inside));
        assert!(s.excludes_triangle(beside));
        // A triangle lying in a side face of the hull (x = 1) cannot block interior segments.
        let on_face = [
            DVec3::new(1.0, 0.1, 0.1),
            DVec3::new(1.0, 0.9, 0.1),
            DVec3::new(1.0, 0.5, 0.9),
        ];
        assert!(s.excludes_triangle(on_face));
    }

    #[test]
    fn pyramid_from_a_point_excludes_what_lies_outside_its_slanted_sides() {
        // Apex above the middle of a unit square at height 1: the hull is a pyramid.
        let apex = [DVec3::new(0.5, 0.5, 1.0)];
        let s = Shaft::between(&apex, &square(0.0, 1.0), 1e-9);
        // Inside the box but outside the slanted side near a base corner's top.
        let p = DVec3::new(0.05, 0.05, 0.9);
        assert!(!s.contains(p));
        assert!(s.contains(DVec3::new(0.5, 0.5, 0.5)));
        let tri = [
            p,
            p + DVec3::new(0.01, 0.0, 0.0),
            p + DVec3::new(0.0, 0.01, 0.0),
        ];
        assert!(s.excludes_triangle(tri));
        assert!(s.excludes_box(p, p + DVec3::splat(0.01)));
        assert!(!s.excludes_box(DVec3::splat(0.4), DVec3::splat(0.6)));
    }

    #[test]
    fn pyramid_matches_the_general_hull() {
        let base = square(0.0, 1.0);
        let mut rng = crate::geometry::Rng::new(3, 0);
        for _ in 0..100 {
            let apex = DVec3::new(rng.next_f64() * 3.0 - 1.0, rng.next_f64() * 3.0 - 1.0, 0.5);
            let (g, p) = (
                Shaft::between(&[apex], &base, 1e-9),
                Shaft::pyramid(apex, &base, 1e-9),
            );
            for _ in 0..50 {
                let q = DVec3::new(
                    rng.next_f64() * 3.0 - 1.0,
                    rng.next_f64() * 3.0 - 1.0,
                    rng.next_f64() * 0.6 - 0.05,
                );
                assert_eq!(g.contains(q), p.contains(q), "{apex:?} {q:?}");
            }
        }
    }

    #[test]
    fn segments_between_the_polygons_stay_inside_for_random_tilted_pairs() {
        let mut rng = crate::geometry::Rng::new(7, 0);
        for _ in 0..200 {
            let mut r = || rng.next_f64();
            let a = vec![
                DVec3::new(r(), r(), 0.0),
                DVec3::new(1.0 + r(), r(), 0.0),
                DVec3::new(1.0 + r(), 1.0 + r(), 0.0),
            ];
            let b = vec![
                DVec3::new(r(), 0.0, 1.0 + r()),
                DVec3::new(r(), 1.0, 1.0 + r()),
                DVec3::new(1.0 + r(), 0.5, 2.0 + r()),
            ];
            let s = Shaft::between(&a, &b, 1e-9);
            let (wa, wb) = (r(), r());
            let pa = a[0] * (1.0 - wa) + (a[1] * (1.0 - wb) + a[2] * wb) * wa;
            let pb = b[0] * (1.0 - wa) + (b[1] * (1.0 - wb) + b[2] * wb) * wa;
            let mid = pa.lerp(pb, r() * 0.8 + 0.1);
            // A tiny triangle around any point of a segment is never excluded.
            let e = 1e-4;
            let tri = [
                mid,
                mid + DVec3::new(e, 0.0, 0.0),
                mid + DVec3::new(0.0, e, e),
            ];
            assert!(!s.excludes_triangle(tri), "{a:?} {b:?} {mid:?}");
        }
    }
}
