//! The Nusselt analogue's data: the form factor from a point `dA_i` to a patch is the
//! fraction of the unit disk under the hemisphere covered by the patch's projection —
//! projected first onto the unit hemisphere around the point (central projection), then
//! straight down onto its base disk (the `cos θ_i`), divided by the disk's area `π`.
//!
//! Kept: the outline of the projection on the disk, the fraction measured by stratified
//! points on the disk (each lifted to the hemisphere and cast towards the patch), its
//! sampling error, the exact value (`formfactor::contour::point_to_polygon`), and copies of
//! the patch scaled about the point (the same projection), whose exact values are the same.
//! Visibility is left out on purpose: the analogue is about the projection.

use glam::DVec3;

use nusselt_core::formfactor::contour::point_to_polygon;
use nusselt_core::geometry::sampling::basis;
use nusselt_core::mesh::PatchId;
use nusselt_core::solver::Problem;

/// Points per side of the stratified grid over the disk's bounding square.
pub const GRID: usize = 64;
/// Scales of the copies (about the point: each has the same projection).
pub const COPIES: [f64; 3] = [0.5, 1.0, 1.6];

/// Which projection to show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NusseltRequest {
    /// The patch whose centre is the point (`None`: the last shooter, else the first).
    pub from: Option<u32>,
    /// The patch projected (`None`: the one with the largest exact form factor).
    pub to: Option<u32>,
}

/// One projection, ready to draw.
#[derive(Debug)]
pub struct NusseltDetail {
    pub request: NusseltRequest,
    pub from: u32,
    pub to: u32,
    /// The projection's outline on the disk, `(x, y)` in the unit disk (edges subdivided,
    /// so the curved sides of the projection show).
    pub outline: Vec<[f64; 2]>,
    /// The sample points on the disk, and whether each one's lifted ray hits the patch.
    pub samples: Vec<([f64; 2], bool)>,
    /// Covered fraction of the disk: hits / points on the disk.
    pub fraction: f64,
    /// One standard deviation of `fraction` (binomial).
    pub sigma: f64,
    /// `F(dA_i → A_j)` exactly, without visibility.
    pub exact: f64,
    /// `(scale, exact F)` of the copies scaled about the point.
    pub copies: Vec<(f64, f64)>,
    /// The patch's corners relative to the point, in its frame (tangent, bitangent,
    /// normal), for the 3-D drawing.
    pub patch_local: Vec<[f64; 3]>,
}

/// Where the ray from `o` along `d` meets convex polygon `poly` (in front of `o`).
fn hits(o: DVec3, d: DVec3, poly: &[DVec3], normal: DVec3) -> bool {
    let denom = d.dot(normal);
    if poly.is_empty() || denom.abs() < 1e-300 {
        return false;
    }
    let t = (poly[0] - o).dot(normal) / denom;
    if t <= 0.0 {
        return false;
    }
    let q = o + d * t;
    let n = poly.len();
    let mut sign = 0.0;
    for k in 0..n {
        let c = (poly[(k + 1) % n] - poly[k]).cross(q - poly[k]).dot(normal);
        if c != 0.0 {
            if sign != 0.0 && c.signum() != sign {
                return false;
            }
            sign = c.signum();
        }
    }
    true
}

/// The projection of `request` on `problem` (`last`: the last shooter).
pub fn compute(
    problem: &Problem,
    request: NusseltRequest,
    last: Option<PatchId>,
) -> Option<NusseltDetail> {
    let mesh = &problem.mesh;
    let from = super::hemicube::teaching_patch(problem, request.from, last)?;
    let pi = mesh.patches.get(from as usize)?;
    let origin = pi.centroid + pi.normal * problem.epsilon;
    let exact_to = |poly: &[DVec3]| point_to_polygon(origin, pi.normal, poly);
    let to = request
        .to
        .filter(|&t| (t as usize) < mesh.patches.len() && t != from)
        .or_else(|| {
            (0..mesh.patches.len())
                .filter(|&k| k != from as usize)
                .map(|k| (k, exact_to(&mesh.patches[k].polygon)))
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(k, _)| k as u32)
        })?;
    let pj = &mesh.patches[to as usize];
    let (tu, tv) = basis(pi.normal);
    let local = |d: DVec3| [d.dot(tu), d.dot(tv), d.dot(pi.normal)];
    // The outline: each edge subdivided, projected centrally onto the hemisphere (points
    // below the horizon clamped to it), then down onto the disk.
    let mut outline = Vec::new();
    let n = pj.polygon.len();
    for k in 0..n {
        let (a, b) = (pj.polygon[k], pj.polygon[(k + 1) % n]);
        for s in 0..16 {
            let p = a.lerp(b, s as f64 / 16.0);
            let [x, y, z] = local((p - origin).normalize_or_zero());
            let r = (x * x + y * y).sqrt();
            if z < 0.0 && r > 0.0 {
                outline.push([x / r, y / r]);
            } else {
                outline.push([x, y]);
            }
        }
    }
    let mut samples = Vec::with_capacity(GRID * GRID);
    let (mut on_disk, mut hit) = (0usize, 0usize);
    for j in 0..GRID {
        for i in 0..GRID {
            let x = -1.0 + (2.0 * i as f64 + 1.0) / GRID as f64;
            let y = -1.0 + (2.0 * j as f64 + 1.0) / GRID as f64;
            let rr = x * x + y * y;
            if rr >= 1.0 {
                continue;
            }
            let d = tu * x + tv * y + pi.normal * (1.0 - rr).sqrt();
            let h = hits(origin, d, &pj.polygon, pj.normal);
            on_disk += 1;
            hit += usize::from(h);
            samples.push(([x, y], h));
        }
    }
    let fraction = hit as f64 / on_disk.max(1) as f64;
    let sigma = (fraction * (1.0 - fraction) / on_disk.max(1) as f64).sqrt();
    let copies = COPIES
        .iter()
        .map(|&s| {
            let poly: Vec<DVec3> = pj
                .polygon
                .iter()
                .map(|c| origin + (*c - origin) * s)
                .collect();
            (s, exact_to(&poly))
        })
        .collect();
    Some(NusseltDetail {
        request,
        from,
        to,
        outline,
        samples,
        fraction,
        sigma,
        exact: exact_to(&pj.polygon),
        copies,
        patch_local: pj.polygon.iter().map(|c| local(*c - origin)).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nusselt_core::mesh::MeshSpec;
    use nusselt_core::scene::{LoadOptions, Scene};
    use nusselt_core::solver::SolverConfig;

    /// The covered fraction of the disk is the exact form factor within its sampling error
    /// (the analogue holds), for the patch seen most from the light and for a wall patch
    /// seen at a grazing angle; the copies scaled about the point (same projection) have
    /// the same exact value; the outline lies in the unit disk.
    #[test]
    fn the_covered_fraction_is_the_form_factor() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::sized(100.0, 200.0),
            ..Default::default()
        };
        let problem = Problem::new(scene, config).expect("problem");
        let first = NusseltRequest {
            from: None,
            to: None,
        };
        let d = compute(&problem, first, None).expect("a projection");
        let wall = (0..problem.mesh.patches.len() as u32)
            .find(|&k| {
                let p = &problem.mesh.patches[k as usize];
                p.normal.x.abs() > 0.9 && k != d.to
            })
            .expect("a side wall patch");
        let grazing = compute(
            &problem,
            NusseltRequest {
                from: None,
                to: Some(wall),
            },
            None,
        )
        .expect("a projection");
        for d in [&d, &grazing] {
            eprintln!(
                "patch {} -> {}: fraction {:.5} ± {:.5}, exact {:.5}",
                d.from, d.to, d.fraction, d.sigma, d.exact
            );
            assert!(d.exact > 0.0);
            // The midpoint grid is better than random sampling; 4 σ (plus the grid's edge
            // error) is generous for it and still catches a missing cos θ (a factor
            // of up to 2 here) or a solid angle instead of the projected one.
            assert!(
                (d.fraction - d.exact).abs() <= 4.0 * d.sigma + 2e-3,
                "{} vs {}",
                d.fraction,
                d.exact
            );
            for (s, f) in &d.copies {
                assert!(
                    (f - d.exact).abs() <= 1e-9 * d.exact,
                    "copy x{s}: {f} vs {}",
                    d.exact
                );
            }
            assert!(d.outline.iter().all(|[x, y]| x * x + y * y <= 1.0 + 1e-9));
        }
        assert!(
            d.exact > 5.0 * grazing.exact,
            "the grazing wall is not smaller"
        );
    }
}
