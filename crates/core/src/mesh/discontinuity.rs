//! A priori discontinuity meshing of the lights' shadows (Heckbert 1992; Lischinski,
//! Tampieri & Greenberg 1992), for `--discontinuity`: before the mesh is cut into patches
//! and elements, every large planar unit is cut along the lines where a light starts or
//! stops being hidden by a blocker face, so element edges lie on the boundaries of the
//! umbrae and penumbrae instead of across them.
//!
//! For a light vertex `v` in front of receiver `P` and a face `Q` that faces `v` and lies
//! wholly between `v` and `P`'s plane, `Q` projected centrally from `v` onto the plane is
//! the region that `v` cannot see; its sides are the vertex-edge (VE) events of `v` with
//! `Q`'s edges. For a light edge `ab`, the region some point of `ab` cannot see is the
//! convex hull of `a`'s and `b`'s regions; the hull's sides that join the two are the
//! edge-vertex (EV) events of `ab` with `Q`'s vertices (planes through `ab` that touch
//! `Q`). Point lights cut the vertex-edge events of their one vertex, suns the outline of
//! `Q` projected along their direction (a soft sun's penumbra is not outlined). Both are
//! cut: together they are the first-order (D1) discontinuities of a convex
//! light and one convex blocker, the penumbra's outer boundary and the umbra's among them. Edge-edge events between
//! several blockers (quadric surfaces in general) and higher-order ones are not found here,
//! and faces that straddle `v`'s height are skipped. Contact lines, the zeroth order, are
//! `footprint.rs`. The lines are inserted as the boundaries of convex pieces
//! (`super::footprint`'s cut), and each piece is meshed on its own, so an element edge
//! follows every line; where pieces meet, their elements need not share vertices (the
//! display interpolates per vertex position, as across any two units).
//!
//! Known error: the radiance is still constant per element; what changes is where the
//! element boundaries are. Cuts are capped per unit ([`MAX_CUTS`]) so triangulated models
//! with thousands of small blockers do not shatter a floor.

use glam::DVec3;

use super::cluster::convex_hull_2d;
use super::footprint::{Piece, cut, overlaps};
use crate::geometry::polygon;
use crate::geometry::sampling::basis;
use crate::scene::{Light, Scene};

/// Most shadow outlines cut into one unit.
pub const MAX_CUTS: usize = 96;

/// Blockers smaller than this fraction of a patch's area cast no cut (their shadows are
/// smaller than the elements).
const MIN_BLOCKER: f64 = 0.25;

/// Where the scene's lights that are not faces cast shadows from: point lights (and spots)
/// from their position, suns along their direction (a soft sun's central one: its
/// penumbra's own outline is not cut).
#[derive(Default)]
struct PunctualLights {
    points: Vec<DVec3>,
    /// Unit directions towards each sun.
    suns: Vec<DVec3>,
}

impl PunctualLights {
    fn of(scene: &Scene) -> Self {
        let mut out = Self::default();
        for light in scene.lights.iter().filter(|l| l.is_on()) {
            match light {
                Light::Point { position, .. } => out.points.push(*position),
                Light::Sun { direction, .. } => {
                    out.suns.extend(direction.try_normalize());
                }
                Light::Sky { .. } => {}
            }
        }
        out
    }

    fn is_empty(&self) -> bool {
        self.points.is_empty() && self.suns.is_empty()
    }

    /// The shadows of blocker `q` (normal `nq`) on the plane through `origin` (normal `n`).
    fn shadows(&self, q: &[DVec3], nq: DVec3, origin: DVec3, n: DVec3) -> Vec<Vec<DVec3>> {
        let from_points = self.points.iter().filter_map(|&v| {
            let hv = (v - origin).dot(n);
            (hv > 0.0)
                .then(|| shadow(v, hv, q, nq, origin, n))
                .flatten()
        });
        let from_suns = self
            .suns
            .iter()
            .filter_map(|&d| parallel_shadow(d, q, nq, origin, n));
        from_points.chain(from_suns).collect()
    }
}

/// Cuts `pieces` along the shadow outlines of the scene's lights (see the module docs).
pub(super) fn split(pieces: Vec<Piece>, scene: &Scene, patch_area: f64) -> Vec<Piece> {
    let lights: Vec<&[DVec3]> = scene
        .faces
        .iter()
        .filter(|f| scene.materials[f.material.0 as usize].is_emitter())
        .map(|f| f.vertices.as_slice())
        .collect();
    let punctual = PunctualLights::of(scene);
    if lights.is_empty() && punctual.is_empty() {
        return pieces;
    }
    let blockers: Vec<(&[DVec3], DVec3)> = scene
        .faces
        .iter()
        .filter(|f| !scene.materials[f.material.0 as usize].is_emitter())
        .filter(|f| polygon::area(&f.vertices) >= MIN_BLOCKER * patch_area)
        .filter_map(|f| Some((f.vertices.as_slice(), polygon::normal(&f.vertices)?)))
        .collect();
    let mut out = Vec::with_capacity(pieces.len());
    for p in pieces {
        let (Some(n), area) = (polygon::normal(&p.poly), polygon::area(&p.poly)) else {
            out.push(p);
            continue;
        };
        let origin = p.poly[0];
        let mut parts = vec![p.poly.clone()];
        let mut cuts = 0;
        let mut outlines = Vec::new();
        for light in &lights {
            for (q, nq) in &blockers {
                // What each light vertex cannot see of the plane (vertex-edge events) …
                let shadows: Vec<Option<Vec<DVec3>>> = light
                    .iter()
                    .map(|&v| {
                        let hv = (v - origin).dot(n);
                        (hv > 0.0)
                            .then(|| shadow(v, hv, q, *nq, origin, n))
                            .flatten()
                    })
                    .collect();
                outlines.extend(shadows.iter().flatten().cloned());
                // … and what the points of each light edge cannot see: the hull of its two
                // ends' shadows, whose sides joining them are edge-vertex events.
                for k in 0..shadows.len() {
                    if let (Some(a), Some(b)) = (&shadows[k], &shadows[(k + 1) % shadows.len()])
                        && let Some(hull) = hull_in_plane(a, b, origin, n)
                    {
                        outlines.push(hull);
                    }
                }
            }
        }
        for (q, nq) in &blockers {
            outlines.extend(punctual.shadows(q, *nq, origin, n));
        }
        for outline in outlines {
            if cuts >= MAX_CUTS {
                break;
            }
            if !overlaps(&p.poly, &outline, n) {
                continue;
            }
            cuts += 1;
            parts = parts
                .into_iter()
                .flat_map(|r| cut(&r, &outline, n, 1e-9 * area))
                .collect();
        }
        out.extend(parts.into_iter().map(|poly| Piece { poly, face: p.face }));
    }
    out
}

/// The convex hull of two convex polygons in the plane through `origin` with normal `n`,
/// counter-clockwise about `n`; `None` when it is degenerate or is one of the two (the other
/// inside it: no new line).
fn hull_in_plane(a: &[DVec3], b: &[DVec3], origin: DVec3, n: DVec3) -> Option<Vec<DVec3>> {
    let (t, s) = basis(n);
    let mut points: Vec<(f64, f64)> = a
        .iter()
        .chain(b)
        .map(|p| ((*p - origin).dot(t), (*p - origin).dot(s)))
        .collect();
    let hull = convex_hull_2d(&mut points);
    if hull.len() < 3 {
        return None;
    }
    let out: Vec<DVec3> = hull.iter().map(|(x, y)| origin + t * *x + s * *y).collect();
    let area = polygon::area(&out);
    let same = |p: &[DVec3]| (polygon::area(p) - area).abs() <= 1e-9 * area;
    (area > 0.0 && !same(a) && !same(b)).then_some(out)
}

/// `q` projected from `v` (at height `hv` above the plane through `origin` with normal `n`)
/// onto that plane, counter-clockwise about `n`; `None` unless `q` faces `v`, is convex
/// and lies wholly between `v` and the plane (touching the plane allowed).
fn shadow(
    v: DVec3,
    hv: f64,
    q: &[DVec3],
    nq: DVec3,
    origin: DVec3,
    n: DVec3,
) -> Option<Vec<DVec3>> {
    if (v - q[0]).dot(nq) <= 1e-9 * hv || !polygon::is_convex(q) {
        return None;
    }
    let tolerance = 1e-9 * hv;
    if q.iter().all(|x| (*x - origin).dot(n).abs() <= tolerance) {
        return None; // In the receiver's plane: no shadow on it.
    }
    let mut out = Vec::with_capacity(q.len());
    for &x in q {
        let h = (x - origin).dot(n);
        if h < -tolerance || h > hv * (1.0 - 1e-6) {
            return None;
        }
        // Where the ray from v through x meets the plane.
        out.push(v + (x - v) * (hv / (hv - h)));
    }
    let normal = polygon::normal(&out)?;
    if normal.dot(n) < 0.0 {
        out.reverse();
    }
    Some(out)
}

/// `q` projected along the sun direction `d` (unit, towards the sun) onto the plane through
/// `origin` with normal `n`, counter-clockwise about `n`; `None` unless the plane faces the
/// sun, `q` faces it, is convex and lies wholly above the plane (touching allowed).
fn parallel_shadow(
    d: DVec3,
    q: &[DVec3],
    nq: DVec3,
    origin: DVec3,
    n: DVec3,
) -> Option<Vec<DVec3>> {
    let dn = d.dot(n);
    if dn <= 1e-9 || d.dot(nq) <= 1e-9 || !polygon::is_convex(q) {
        return None;
    }
    let scale = q
        .iter()
        .map(|x| (*x - origin).length())
        .fold(0.0, f64::max)
        .max(1e-300);
    let tolerance = 1e-9 * scale;
    let heights: Vec<f64> = q.iter().map(|x| (*x - origin).dot(n)).collect();
    if heights.iter().any(|h| *h < -tolerance) || heights.iter().all(|h| h.abs() <= tolerance) {
        return None;
    }
    let mut out: Vec<DVec3> = q
        .iter()
        .zip(&heights)
        .map(|(x, h)| *x - d * (h / dn))
        .collect();
    let normal = polygon::normal(&out)?;
    if normal.dot(n) < 0.0 {
        out.reverse();
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::LoadOptions;

    /// The scene of `obj` (faces: floor, block, light; `s.mtl` gives them materials) and its
    /// floor (face 0) cut by [`split`] at patch area 1.
    pub(super) fn floor_split(obj: &str) -> (Scene, Vec<Piece>) {
        let mtl =
            "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl block\nKd 0.5 0.5 0.5\nnewmtl light\nKe 1 1 1\n";
        let scene = Scene::from_obj_str("s.obj", obj, &[("s.mtl", mtl)], &LoadOptions::default())
            .expect("scene");
        let floor = Piece {
            poly: scene.faces[0].vertices.clone(),
            face: 0,
        };
        let pieces = split(vec![floor], &scene, 1.0);
        (scene, pieces)
    }

    /// A square blocker halfway between a point-like light and the floor casts a shadow
    /// twice its size: the floor is cut along exactly that outline (a piece of the
    /// shadow's area, centred under the light), and nothing is cut without a light.
    #[test]
    fn a_blocker_cuts_the_floor_along_its_shadow() {
        let obj = "mtllib s.mtl
v -10 0 -10\nv 10 0 -10\nv 10 0 10\nv -10 0 10
v -1 2 -1\nv 1 2 -1\nv 1 2 1\nv -1 2 1
v -0.01 4 -0.01\nv 0.01 4 -0.01\nv 0.01 4 0.01\nv -0.01 4 0.01
usemtl floor\nf 1 4 3 2
usemtl block\nf 5 8 7 6
usemtl light\nf 9 10 11 12\n";
        let (scene, pieces) = floor_split(obj);
        let total: f64 = pieces.iter().map(|p| polygon::area(&p.poly)).sum();
        assert!((total - 400.0).abs() < 1e-6, "area kept: {total}");
        // The umbra of the tiny light: the blocker (2×2 at height 2) doubled, 4×4 = 16.
        let umbra = pieces
            .iter()
            .map(|p| polygon::area(&p.poly))
            .filter(|a| (a - 16.0).abs() < 0.2)
            .count();
        assert!(
            umbra >= 1,
            "{:?}",
            pieces
                .iter()
                .map(|p| polygon::area(&p.poly))
                .collect::<Vec<_>>()
        );
        assert!(pieces.len() >= 5);
        let mut dark = scene.clone();
        for m in &mut dark.materials {
            m.emission = crate::scene::Rgb::ZERO;
        }
        let floor = Piece {
            poly: dark.faces[0].vertices.clone(),
            face: 0,
        };
        assert_eq!(split(vec![floor], &dark, 1.0).len(), 1);
    }

    /// A sun straight above a 2 × 2 blocker at height 2 casts its 2 × 2 shadow under it; a
    /// sun at 45° towards +x moves it by 2 along x; a point light at height 4 doubles it
    /// (as the tiny area light above does): each outline is cut into the floor.
    #[test]
    fn suns_and_point_lights_cut_the_floor_along_their_shadows() {
        let obj = "mtllib s.mtl
v -10 0 -10\nv 10 0 -10\nv 10 0 10\nv -10 0 10
v -1 2 -1\nv 1 2 -1\nv 1 2 1\nv -1 2 1
usemtl floor\nf 1 4 3 2
usemtl block\nf 5 8 7 6\n";
        let mtl = "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl block\nKd 0.5 0.5 0.5\n";
        let base = Scene::from_obj_str("s.obj", obj, &[("s.mtl", mtl)], &LoadOptions::default())
            .expect("scene");
        let (one, half) = (crate::scene::Rgb::ONE, 0.5f64.sqrt());
        let cases = [
            (
                Light::Sun {
                    direction: DVec3::Y,
                    irradiance: one,
                    angular_radius: 0.0,
                },
                DVec3::ZERO,
                4.0,
            ),
            (
                Light::Sun {
                    direction: DVec3::new(half, half, 0.0),
                    irradiance: one,
                    angular_radius: 0.0,
                },
                DVec3::new(-2.0, 0.0, 0.0),
                4.0,
            ),
            (
                Light::Point {
                    position: DVec3::new(0.0, 4.0, 0.0),
                    intensity: one,
                    cone: None,
                },
                DVec3::ZERO,
                16.0,
            ),
        ];
        for (light, centre, area) in cases {
            let mut scene = base.clone();
            scene.lights = vec![light];
            let floor = Piece {
                poly: scene.faces[0].vertices.clone(),
                face: 0,
            };
            let pieces = split(vec![floor], &scene, 1.0);
            let total: f64 = pieces.iter().map(|p| polygon::area(&p.poly)).sum();
            assert!((total - 400.0).abs() < 1e-6, "area kept: {total}");
            let shadow = pieces.iter().find(|p| {
                let lo = p.poly.iter().copied().fold(DVec3::INFINITY, DVec3::min);
                let hi = p.poly.iter().copied().fold(DVec3::NEG_INFINITY, DVec3::max);
                let c = (lo + hi) / 2.0;
                (polygon::area(&p.poly) - area).abs() < 1e-6 && (c - centre).length() < 1e-6
            });
            assert!(
                shadow.is_some(),
                "{light:?}: {:?}",
                pieces
                    .iter()
                    .map(|p| polygon::area(&p.poly))
                    .collect::<Vec<_>>()
            );
        }
    }
}

/// Edge-vertex events: a square light (corners (±0.5, 4, ±0.5)) over a diamond blocker
/// (tips (±1, 2, 0), (0, 2, ±1)) over the floor. The penumbra's outer boundary is the
/// Minkowski sum of the doubled diamond and the mirrored light, an octagon of area 17
/// (a 5 × 5 square less four corner triangles of legs 2). Its slanted sides are shadow
/// edges of single light vertices (vertex-edge); its four short sides, e.g. (2.5, ±0.5),
/// are traced by a diamond tip seen from the points of a light edge (edge-vertex), on no
/// single vertex's shadow. The octagon must be a union of pieces: pieces wholly inside sum
/// to 17 and none straddles it (without the edge-vertex lines pieces crossed the short
/// sides).
#[cfg(test)]
mod edge_vertex_tests {
    use super::tests::floor_split;
    use super::*;

    #[test]
    fn the_penumbras_outer_boundary_is_cut_along_edge_vertex_lines() {
        let obj = "mtllib s.mtl
v -10 0 -10\nv 10 0 -10\nv 10 0 10\nv -10 0 10
v 1 2 0\nv 0 2 1\nv -1 2 0\nv 0 2 -1
v -0.5 4 -0.5\nv 0.5 4 -0.5\nv 0.5 4 0.5\nv -0.5 4 0.5
usemtl floor\nf 1 4 3 2
usemtl block\nf 5 8 7 6
usemtl light\nf 9 10 11 12\n";
        let (_, pieces) = floor_split(obj);
        // The octagon as half-planes |x| ≤ 2.5, |z| ≤ 2.5, |x| + |z| ≤ 3.
        let depth = |p: DVec3| {
            (p.x.abs() - 2.5)
                .max(p.z.abs() - 2.5)
                .max(p.x.abs() + p.z.abs() - 3.0)
        };
        let (mut inside, mut straddling) = (0.0, 0);
        for p in &pieces {
            let deepest = p
                .poly
                .iter()
                .map(|v| depth(*v))
                .fold(f64::INFINITY, f64::min);
            let shallowest = p
                .poly
                .iter()
                .map(|v| depth(*v))
                .fold(f64::NEG_INFINITY, f64::max);
            if shallowest <= 1e-9 {
                inside += polygon::area(&p.poly);
            } else if deepest < -1e-9 {
                straddling += 1;
            }
        }
        assert_eq!(straddling, 0, "pieces cross the penumbra's outer boundary");
        assert!((inside - 17.0).abs() < 1e-6, "inside the octagon: {inside}");
    }
}

#[cfg(test)]
mod cornell_tests {
    use crate::mesh::{Mesh, MeshSpec};
    use crate::scene::{LoadOptions, Scene};

    /// On the Cornell box the shadow outlines add pieces (more patches at the same sizes)
    /// and the meshes cover the same area. Not to round-off: the cut mesh measures 2.8e-7
    /// more (0.5 mm² of 1.9 m²; meshes of two element sizes differ by 5e-9), most likely
    /// slivers between the nearly coincident outlines of the light's four corners counted
    /// twice; the bound below holds that to a thousandth of an element.
    #[test]
    fn the_cornell_mesh_gains_pieces_and_keeps_its_area() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let plain = Mesh::build(&scene, &MeshSpec::sized(40.0, 160.0)).expect("mesh");
        let cut = Mesh::build(
            &scene,
            &MeshSpec {
                discontinuity: true,
                ..MeshSpec::sized(40.0, 160.0)
            },
        )
        .expect("mesh");
        let area = |m: &Mesh| m.elements.iter().map(|e| e.area).sum::<f64>();
        let (a, b) = (area(&plain), area(&cut));
        assert!((a - b).abs() < 1e-3 * 40.0 * 40.0, "{a} vs {b}");
        assert!(
            cut.patches.len() > plain.patches.len(),
            "{} vs {}",
            cut.patches.len(),
            plain.patches.len()
        );
    }
}
