//! The form-factor case harness, at the CLI edge (used by `nusselt formfactor` and the
//! tests): cases in the JSON format of the reference catalogue: polygons `A1`, `A2`
//! (counter-clockwise seen from the front, fronts facing each other), or a differential
//! receiver `point` + `point_normal`, and optional `occluders` (a list of polygons).

use std::path::Path;

use glam::DVec3;
use serde::Deserialize;

use crate::formfactor::hemicube::{ItemBufferRaster, RasterError};
use crate::formfactor::{
    FormFactorMethod, FormFactorParams, PolygonSampler, contour, exact, hemicube, hybrid,
    montecarlo, occluded_point_to_polygon, raycast,
};
use crate::geometry::bvh::TriangleInput;
use crate::geometry::sampling::hash_seed;
use crate::geometry::{Bvh, Rng, polygon};

#[derive(Clone, Debug, Deserialize)]
pub struct Case {
    pub name: String,
    #[serde(rename = "A1", default)]
    pub a1: Vec<[f64; 3]>,
    #[serde(rename = "A2")]
    pub a2: Vec<[f64; 3]>,
    #[serde(default)]
    pub point: Option<[f64; 3]>,
    #[serde(default)]
    pub point_normal: Option<[f64; 3]>,
    #[serde(default)]
    pub occluders: Vec<Vec<[f64; 3]>>,
    /// The exact value, when the file has one (ignored by evaluation).
    #[serde(default)]
    pub exact: Option<f64>,
}

#[derive(Debug, thiserror::Error)]
pub enum CaseError {
    #[error("cannot read {path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Format { path: String, message: String },
}

fn to_vecs(p: &[[f64; 3]]) -> Vec<DVec3> {
    p.iter().map(|v| DVec3::from_array(*v)).collect()
}

/// Reads a case file (a JSON array of cases) and checks each case's polygons.
pub fn load(path: &Path) -> Result<Vec<Case>, CaseError> {
    let text = std::fs::read_to_string(path).map_err(|source| CaseError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let p = path.display().to_string();
    let cases: Vec<Case> = serde_json::from_str(&text).map_err(|e| CaseError::Format {
        path: p.clone(),
        message: format!("line {}: {e}", e.line()),
    })?;
    for c in &cases {
        let bad = |m: &str| CaseError::Format {
            path: p.clone(),
            message: format!("case '{}': {m}", c.name),
        };
        let finite = |poly: &[[f64; 3]]| poly.iter().flatten().all(|x| x.is_finite());
        if c.a2.len() < 3 || polygon::normal(&to_vecs(&c.a2)).is_none() || !finite(&c.a2) {
            return Err(bad(
                "A2 must be a polygon of at least 3 finite, non-collinear vertices",
            ));
        }
        if c.point.is_none()
            && (c.a1.len() < 3 || polygon::normal(&to_vecs(&c.a1)).is_none() || !finite(&c.a1))
        {
            return Err(bad("A1 must be a polygon (or give point and point_normal)"));
        }
        if c.point.is_some()
            && c.point_normal
                .and_then(|n| DVec3::from_array(n).try_normalize())
                .is_none()
        {
            return Err(bad("point_normal must be a non-zero vector"));
        }
        if c.occluders.iter().any(|o| o.len() < 3 || !finite(o)) {
            return Err(bad(
                "each occluder must be a polygon of at least 3 finite vertices",
            ));
        }
    }
    Ok(cases)
}

/// Evaluates one case with one method: F from A1 (or the point) to A2.
///
/// Point methods (`hemicube`) are averaged over A1 with a fixed 6×6 Gauss–Legendre rule per
/// triangle of A1 ([`integrate_fixed`]); `raycast` and `montecarlo` spread their
/// `params.rays` samples over A1 uniformly; `exact` uses the double contour integral (with
/// occluders: the exact point-to-visible-polygon value integrated adaptively over A1).
pub fn evaluate(case: &Case, method: FormFactorMethod, params: &FormFactorParams) -> f64 {
    match evaluate_with(case, method, params, None) {
        Ok(v) => v,
        // Without a rasteriser `gpu-hemicube` is computed by the CPU hemicube, which cannot fail.
        Err(_) => evaluate(case, FormFactorMethod::Hemicube, params),
    }
}

/// [`evaluate`], with `raster` drawing the hemicubes of `gpu-hemicube` (without one it is
/// the CPU hemicube).
pub fn evaluate_with(
    case: &Case,
    method: FormFactorMethod,
    params: &FormFactorParams,
    raster: Option<&dyn ItemBufferRaster>,
) -> Result<f64, RasterError> {
    let g = CaseGeometry::new(case, params);
    let mut rng = Rng::new(params.seed, 0);
    let value = match method {
        FormFactorMethod::Contour => g.contour(params, &mut rng),
        FormFactorMethod::Exact => g.exact(params),
        FormFactorMethod::Hemicube => {
            hemicube_case(g.point, &g.a1, &g.a2, &g.occluders, params, None, &mut rng)?
        }
        FormFactorMethod::GpuHemicube => hemicube_case(
            g.point,
            &g.a1,
            &g.a2,
            &g.occluders,
            params,
            raster,
            &mut rng,
        )?,
        FormFactorMethod::Raycast => g.raycast(params, &mut rng),
        FormFactorMethod::Montecarlo => g.montecarlo(params, &mut rng),
        FormFactorMethod::Hybrid => {
            if g.hybrid_is_analytic(params) {
                evaluate(case, FormFactorMethod::Contour, params)
            } else {
                evaluate(case, FormFactorMethod::Hemicube, params)
            }
        }
    };
    Ok(value)
}

/// A case's polygons, blockers and the sampling settings its estimators share.
struct CaseGeometry {
    a1: Vec<DVec3>,
    a2: Vec<DVec3>,
    occluders: Vec<Vec<DVec3>>,
    bvh: Bvh,
    /// The receiving point and its normal, when the case is point-to-polygon.
    point: Option<(DVec3, DVec3)>,
    sampler: PolygonSampler,
    /// Shadow rays per side of the visibility grid.
    m: u32,
    eps: f64,
    /// Like the solver's contour rows: few blockers have their shadows clipped away
    /// exactly, many are sampled with weighted shadow rays.
    few_blockers: bool,
}

impl CaseGeometry {
    fn new(case: &Case, params: &FormFactorParams) -> Self {
        let a2 = to_vecs(&case.a2);
        let occluders: Vec<Vec<DVec3>> = case.occluders.iter().map(|o| to_vecs(o)).collect();
        let bvh = occluder_bvh(&occluders);
        let scale = polygon::area(&a2).sqrt();
        let point = match (case.point, case.point_normal) {
            (Some(p), Some(n)) => Some((
                DVec3::from_array(p),
                DVec3::from_array(n).try_normalize().unwrap_or(DVec3::Z),
            )),
            _ => None,
        };
        Self {
            a1: to_vecs(&case.a1),
            sampler: PolygonSampler::new(&a2),
            few_blockers: bvh.triangle_count() <= params.exact_blockers,
            m: ((params.visibility_rays.max(1) as f64).sqrt().round() as u32).max(1),
            eps: 1e-9 * scale.max(1e-12),
            a2,
            occluders,
            bvh,
            point,
        }
    }

    /// The contour integral's point-to-polygon value at `p` (normal `n`), blockers clipped
    /// or sampled.
    fn point_value(&self, p: DVec3, n: DVec3, rng: &mut Rng) -> f64 {
        let (a2, occluders) = (&self.a2, &self.occluders);
        if occluders.is_empty() {
            contour::point_to_polygon(p, n, a2)
        } else if self.few_blockers {
            exact::point_to_visible_polygon(p, n, a2, occluders)
        } else {
            let (sampler, m, eps) = (&self.sampler, self.m, self.eps);
            let no_skip = [u32::MAX; 2];
            occluded_point_to_polygon(&self.bvh, p, n, a2, sampler, m, false, eps, no_skip, rng)
        }
    }

    fn contour(&self, params: &FormFactorParams, rng: &mut Rng) -> f64 {
        if let Some((p, n)) = self.point {
            return self.point_value(p, n, rng);
        }
        // Clipped shadows have kinks, sampled visibility is noisy: refine a bounded number
        // of levels, not to 1e-10.
        let depth = if self.occluders.is_empty() {
            14
        } else if self.few_blockers {
            params.cubature_depth
        } else {
            2
        };
        integrate_over(&self.a1, depth, &mut |p, n| self.point_value(p, n, rng))
    }

    fn exact(&self, params: &FormFactorParams) -> f64 {
        let (a2, occluders) = (&self.a2, &self.occluders);
        if let Some((p, n)) = self.point {
            return exact::point_to_visible_polygon(p, n, a2, occluders);
        }
        if occluders.is_empty() {
            return exact::polygon_to_polygon(&self.a1, a2);
        }
        integrate_over_with_floor(&self.a1, params.cubature_depth, 1e-13, &mut |p, n| {
            exact::point_to_visible_polygon(p, n, a2, occluders)
        })
    }

    fn raycast(&self, params: &FormFactorParams, rng: &mut Rng) -> f64 {
        let mut tris = triangles(&self.a2, 0);
        for o in &self.occluders {
            tris.extend(triangles(o, 1));
        }
        let scene = Bvh::build(&tris);
        let from = match self.point {
            Some((p, n)) => raycast::Origin::Point(p, n),
            None => raycast::Origin::Polygon(PolygonSampler::new(&self.a1)),
        };
        raycast::hit_fraction(&scene, from, 0, params.rays as u64, self.eps, rng)
    }

    fn montecarlo(&self, params: &FormFactorParams, rng: &mut Rng) -> f64 {
        let a1_sampler;
        let receiver = match self.point {
            Some((p, n)) => montecarlo::Receiver::Point(p, n),
            None => {
                a1_sampler = PolygonSampler::new(&self.a1);
                montecarlo::Receiver::Polygon(&a1_sampler)
            }
        };
        let blockers = (!self.occluders.is_empty()).then_some(&self.bvh);
        montecarlo::estimate(
            &receiver,
            &self.sampler,
            polygon::area(&self.a2),
            blockers,
            [u32::MAX; 2],
            self.eps,
            params.rays as u64,
            rng,
        )
    }

    /// Whether the hybrid method takes the analytic (contour) form factor for this case
    /// rather than the hemicube.
    fn hybrid_is_analytic(&self, params: &FormFactorParams) -> bool {
        let (c1, area1) = match self.point {
            Some((p, _)) => (p, 0.0),
            None => (polygon::centroid(&self.a1), polygon::area(&self.a1)),
        };
        let a2 = &self.a2;
        let omega = hemicube::DeltaTable::pixel_solid_angle_at(params.hemicube_res);
        // The hemicube sits on A1 (the "shooter"); A2 is what it sees.
        let n2 = polygon::normal(a2).unwrap_or(DVec3::Z);
        let (c2, area2) = (polygon::centroid(a2), polygon::area(a2));
        hybrid::analytic(params, omega, false, c1, area1, c2, n2, area2)
    }
}

fn triangles(poly: &[DVec3], id: u32) -> Vec<TriangleInput> {
    polygon::triangulate(poly)
        .into_iter()
        .map(|t| TriangleInput {
            vertices: [poly[t[0]], poly[t[1]], poly[t[2]]],
            id,
            cull_back: false,
            cut: None,
        })
        .collect()
}

fn hemicube_case(
    point: Option<(DVec3, DVec3)>,
    a1: &[DVec3],
    a2: &[DVec3],
    occluders: &[Vec<DVec3>],
    params: &FormFactorParams,
    raster: Option<&dyn ItemBufferRaster>,
    rng: &mut Rng,
) -> Result<f64, RasterError> {
    let table = hemicube::DeltaTable::new(params.hemicube_res);
    let scale = crate::geometry::Aabb::from_points(a2.iter()).diagonal();
    let near = 1e-9 * scale.max(1e-12);
    let a2_pieces = convex_pieces(a2);
    let occ_pieces: Vec<Vec<DVec3>> = occluders.iter().flat_map(|o| convex_pieces(o)).collect();
    // For a rasteriser: A2's pieces draw id 0, the occluders block.
    let all: Vec<Vec<DVec3>> = a2_pieces.iter().chain(&occ_pieces).cloned().collect();
    let ids: Vec<u32> = (0..all.len())
        .map(|k| {
            if k < a2_pieces.len() {
                0
            } else {
                hemicube::NONE
            }
        })
        .collect();
    let key = hash_seed(
        &all.iter()
            .flatten()
            .flat_map(|p| p.to_array().map(f64::to_bits))
            .collect::<Vec<u64>>(),
    );
    let mut failure = None;
    let mut at = |p: DVec3, n: DVec3| {
        let angle = if params.hemicube_rotate {
            rng.next_f64() * std::f64::consts::TAU
        } else {
            0.0
        };
        if let Some(r) = raster {
            let view = hemicube::HemicubeView {
                origin: p,
                axes: hemicube::hemicube_axes(n, angle),
                near,
            };
            return match r.form_factors(key, &|| all.clone(), &view, &table, &ids, 1) {
                Ok(v) => v[0],
                Err(e) => {
                    failure.get_or_insert(e);
                    0.0
                }
            };
        }
        let mut cube = hemicube::Hemicube::new(&table, p, n, angle, near);
        for piece in &a2_pieces {
            cube.draw(piece, 0);
        }
        for piece in &occ_pieces {
            cube.draw(piece, hemicube::NONE);
        }
        cube.form_factor(0)
    };
    let value = match point {
        Some((p, n)) => at(p, n),
        None => integrate_fixed(a1, &mut at),
    };
    match failure {
        Some(e) => Err(e),
        None => Ok(value),
    }
}

fn convex_pieces(poly: &[DVec3]) -> Vec<Vec<DVec3>> {
    if polygon::is_convex(poly) {
        return vec![poly.to_vec()];
    }
    triangles(poly, 0)
        .into_iter()
        .map(|t| t.vertices.to_vec())
        .collect()
}

/// Area-average of `f` over `a1` with one 6×6 Gauss–Legendre cell per triangle (Duffy map):
/// 36 evaluations per triangle, for the point methods that are too costly to refine.
pub fn integrate_fixed(a1: &[DVec3], f: &mut dyn FnMut(DVec3, DVec3) -> f64) -> f64 {
    let n = polygon::normal(a1).unwrap_or(DVec3::Z);
    let total_area = polygon::area(a1);
    if total_area <= 0.0 {
        return 0.0;
    }
    let mut sum = 0.0;
    for t in polygon::triangulate(a1) {
        let (a, b, c) = (a1[t[0]], a1[t[1]], a1[t[2]]);
        let jac = 2.0 * polygon::area(&[a, b, c]);
        let mut g = |u: f64, v: f64| f(a + (b - a) * u + (c - b) * (u * v), n) * u * jac;
        sum += cell(&mut g, 0.0, 0.0, 1.0);
    }
    sum / total_area
}

fn occluder_bvh(occluders: &[Vec<DVec3>]) -> Bvh {
    let mut tris = Vec::new();
    for (i, o) in occluders.iter().enumerate() {
        for t in polygon::triangulate(o) {
            tris.push(TriangleInput {
                vertices: [o[t[0]], o[t[1]], o[t[2]]],
                id: i as u32,
                cull_back: false,
                cut: None,
            });
        }
    }
    Bvh::build(&tris)
}

/// Gauss–Legendre nodes and weights on [0, 1], 6 points.
const GL: [(f64, f64); 6] = [
    (0.033_765_242_898_423_98, 0.085_662_246_189_585_17),
    (0.169_395_306_766_867_74, 0.180_380_786_524_069_3),
    (0.380_690_406_958_401_56, 0.233_956_967_286_345_5),
    (0.619_309_593_041_598_4, 0.233_956_967_286_345_5),
    (0.830_604_693_233_132_3, 0.180_380_786_524_069_3),
    (0.966_234_757_101_576, 0.085_662_246_189_585_17),
];

/// Area-average of `f` over polygon `a1` by adaptive Gauss–Legendre cubature, at most
/// `max_depth` levels of refinement (Duffy map of
/// each triangle to the unit square; a cell is split while its 6×6 rule and the sum over its
/// four children differ by more than `1e-10 × (first estimate) × (cell area)`, so the
/// accepted cells' differences add up to at most 1e-10 of the integral).
pub fn integrate_over(a1: &[DVec3], max_depth: u32, f: &mut dyn FnMut(DVec3, DVec3) -> f64) -> f64 {
    integrate_over_with_floor(a1, max_depth, 0.0, f)
}

/// [`integrate_over`] that also accepts a cell whose refinement changes the area-average by
/// less than `floor` (absolute), so an integrand that is zero on a cell stops refining.
pub fn integrate_over_with_floor(
    a1: &[DVec3],
    max_depth: u32,
    floor: f64,
    f: &mut dyn FnMut(DVec3, DVec3) -> f64,
) -> f64 {
    let n = polygon::normal(a1).unwrap_or(DVec3::Z);
    let total_area = polygon::area(a1);
    let mut sum = 0.0;
    for t in polygon::triangulate(a1) {
        let (a, b, c) = (a1[t[0]], a1[t[1]], a1[t[2]]);
        let jac = 2.0 * polygon::area(&[a, b, c]);
        // Duffy: (u, v) ∈ [0,1]² → a + u(b − a) + uv(c − b), Jacobian u·jac.
        let mut g = |u: f64, v: f64| f(a + (b - a) * u + (c - b) * (u * v), n) * u * jac;
        let first = cell(&mut g, 0.0, 0.0, 1.0);
        let tol = (1e-10 * first.abs()).max(floor * jac).max(1e-300);
        sum += adapt(&mut g, 0.0, 0.0, 1.0, first, tol, max_depth);
    }
    sum / total_area
}

fn cell(g: &mut dyn FnMut(f64, f64) -> f64, u0: f64, v0: f64, h: f64) -> f64 {
    let mut s = 0.0;
    for (x, wx) in GL {
        for (y, wy) in GL {
            s += wx * wy * g(u0 + x * h, v0 + y * h);
        }
    }
    s * h * h
}

fn adapt(
    g: &mut dyn FnMut(f64, f64) -> f64,
    u0: f64,
    v0: f64,
    h: f64,
    whole: f64,
    tol: f64,
    depth: u32,
) -> f64 {
    let hh = h * 0.5;
    let offs = [(0.0, 0.0), (hh, 0.0), (0.0, hh), (hh, hh)];
    let parts = offs.map(|(du, dv)| cell(g, u0 + du, v0 + dv, hh));
    let split: f64 = parts.iter().sum();
    if depth == 0 || (split - whole).abs() <= tol * h * h {
        return split;
    }
    offs.iter()
        .zip(parts)
        .map(|((du, dv), p)| adapt(g, u0 + du, v0 + dv, hh, p, tol, depth - 1))
        .sum()
}
