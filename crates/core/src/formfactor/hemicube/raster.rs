//! The hemicube's rasteriser: each polygon is mapped to a face's coordinates, clipped to
//! the face's frustum and the near plane (Sutherland–Hodgman), and scan-converted into the
//! face's item buffer with a 1/depth test, nearest polygon winning each pixel centre.

use super::Local;

/// One face's buffers.
pub(super) struct Face {
    pub(super) ids: Vec<u32>,
    /// 1/depth (larger is nearer); 0 = empty.
    pub(super) inv_depth: Vec<f64>,
    pub(super) rows: usize,
}

/// Face coordinates (X, Y, D) of a local point on face `f` (0 top, 1–4 sides): screen =
/// (X/D, Y/D). Each face's map is a signed permutation (lengths are kept).
pub fn to_face(f: usize, p: &Local) -> [f64; 3] {
    let [u, v, w] = *p;
    match f {
        0 => [u, v, w],
        1 => [v, w, u],
        2 => [-v, w, -u],
        3 => [-u, w, v],
        _ => [u, w, -v],
    }
}

/// Sutherland–Hodgman against `a·X + b·Y + c·D ≥ 0` in face coordinates.
fn clip(poly: &[[f64; 3]], plane: [f64; 3], out: &mut Vec<[f64; 3]>) {
    out.clear();
    let k = poly.len();
    let dist = |p: &[f64; 3]| plane[0] * p[0] + plane[1] * p[1] + plane[2] * p[2];
    for i in 0..k {
        let (a, b) = (poly[i], poly[(i + 1) % k]);
        let (da, db) = (dist(&a), dist(&b));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            out.push([
                a[0] + (b[0] - a[0]) * t,
                a[1] + (b[1] - a[1]) * t,
                a[2] + (b[2] - a[2]) * t,
            ]);
        }
    }
}

/// Draws polygon `local` (the patch's frame) into face `f` of a `res`-pixel hemicube:
/// projected, clipped to the face's frustum and the near plane, then scan-converted with
/// its 1/D interpolated per pixel (depth test: the nearest `id` wins).
pub(super) fn draw_face(
    face: &mut Face,
    f: usize,
    res: usize,
    near: f64,
    local: &[Local],
    id: u32,
) {
    let ylo = if f == 0 { -1.0 } else { 0.0 };
    let pts: Vec<[f64; 3]> = local.iter().map(|p| to_face(f, p)).collect();
    // Frustum planes (a, b, c): a X + b Y + c D ≥ 0.
    let planes = [
        [1.0, 0.0, 1.0],  // X ≥ −D
        [-1.0, 0.0, 1.0], // X ≤ D
        [0.0, -1.0, 1.0], // Y ≤ D
        [0.0, 1.0, -ylo], // Y ≥ ylo·D
    ];
    if outside(&pts, near, &planes) {
        return;
    }
    let Some((n, c)) = polygon_plane(&pts) else {
        return; // Edge-on: covers no area.
    };
    let Some(clipped) = clip_to_frustum(pts, near, &planes) else {
        return;
    };
    // Pixel coordinates: px = (sx + 1)/2 · res, py = (sy − ylo) · res/2.
    let scale = res as f64 * 0.5;
    let screen: Vec<(f64, f64)> = clipped
        .iter()
        .map(|p| ((p[0] / p[2] + 1.0) * scale, (p[1] / p[2] - ylo) * scale))
        .collect();
    let Some(edges) = edge_functions(&screen) else {
        return;
    };
    let (mut ymin, mut ymax) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in &screen {
        ymin = ymin.min(s.1);
        ymax = ymax.max(s.1);
    }
    let y0 = ((ymin - 0.5).ceil().max(0.0)) as usize;
    let y1 = ((ymax - 0.5).floor()).min(face.rows as f64 - 1.0);
    if y1 < 0.0 {
        return;
    }
    // 1/D as a function of pixel coordinates.
    let inv_c = 1.0 / c;
    let depth = |sx: f64, sy: f64| (n[0] * sx + n[1] * sy + n[2]) * inv_c;
    for py in y0..=y1 as usize {
        let yc = py as f64 + 0.5;
        let Some((x0, x1)) = span(&edges, yc, res) else {
            continue;
        };
        let sy = yc / scale + ylo;
        let row = py * res;
        for px in x0..=x1 {
            let sx = (px as f64 + 0.5) / scale - 1.0;
            let z = depth(sx, sy);
            let i = row + px;
            if z > face.inv_depth[i] {
                face.inv_depth[i] = z;
                face.ids[i] = id;
            }
        }
    }
}

/// Quick rejection: every vertex behind the near plane, or every vertex outside one plane.
fn outside(pts: &[[f64; 3]], near: f64, planes: &[[f64; 3]; 4]) -> bool {
    pts.iter().all(|p| p[2] < near)
        || planes.iter().any(|pl| {
            pts.iter()
                .all(|p| pl[0] * p[0] + pl[1] * p[1] + pl[2] * p[2] < 0.0)
        })
}

/// The polygon's plane in face coordinates, `n·P = c` (Newell's normal, unnormalised), so
/// that `1/D = n·(sx, sy, 1)/c`; `None` when the polygon is seen edge-on.
fn polygon_plane(pts: &[[f64; 3]]) -> Option<([f64; 3], f64)> {
    let mut n = [0.0f64; 3];
    let k = pts.len();
    for i in 0..k {
        let (a, b) = (pts[i], pts[(i + 1) % k]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    let c = n[0] * pts[0][0] + n[1] * pts[0][1] + n[2] * pts[0][2];
    let nlen = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let dist0 = (pts[0][0].powi(2) + pts[0][1].powi(2) + pts[0][2].powi(2)).sqrt();
    (nlen != 0.0 && c.abs() > 1e-12 * nlen * dist0).then_some((n, c))
}

/// `pts` clipped to `D ≥ near` and the four frustum planes; `None` when less than a
/// triangle is left.
fn clip_to_frustum(pts: Vec<[f64; 3]>, near: f64, planes: &[[f64; 3]; 4]) -> Option<Vec<[f64; 3]>> {
    let k = pts.len();
    let mut b = Vec::with_capacity(k + 8);
    let mut tmp = Vec::with_capacity(k + 2);
    let shifted: Vec<[f64; 3]> = pts.iter().map(|p| [p[0], p[1], p[2] - near]).collect();
    clip(&shifted, [0.0, 0.0, 1.0], &mut tmp);
    let mut a: Vec<[f64; 3]> = tmp.iter().map(|p| [p[0], p[1], p[2] + near]).collect();
    for pl in planes {
        if a.len() < 3 {
            return None;
        }
        clip(&a, *pl, &mut b);
        std::mem::swap(&mut a, &mut b);
    }
    (a.len() >= 3).then_some(a)
}

/// The edge functions `E(x, y) = A x + B y + C`, non-negative inside the screen polygon
/// whatever its orientation; `None` for a polygon of no area.
fn edge_functions(screen: &[(f64, f64)]) -> Option<Vec<(f64, f64, f64)>> {
    let m = screen.len();
    let mut area2 = 0.0;
    for i in 0..m {
        let (p, q) = (screen[i], screen[(i + 1) % m]);
        area2 += p.0 * q.1 - q.0 * p.1;
    }
    if area2 == 0.0 {
        return None;
    }
    let orient = area2.signum();
    Some(
        (0..m)
            .map(|i| {
                let (p, q) = (screen[i], screen[(i + 1) % m]);
                let ea = -(q.1 - p.1) * orient;
                let eb = (q.0 - p.0) * orient;
                (ea, eb, -(ea * p.0 + eb * p.1))
            })
            .collect(),
    )
}

/// The pixels `x0..=x1` of the row at height `yc` whose centres are inside every edge;
/// `None` when there are none.
fn span(edges: &[(f64, f64, f64)], yc: f64, res: usize) -> Option<(usize, usize)> {
    let (mut xl, mut xr) = (0.0f64, res as f64);
    for &(ea, eb, ec) in edges {
        let rest = eb * yc + ec;
        if ea > 0.0 {
            xl = xl.max(-rest / ea);
        } else if ea < 0.0 {
            xr = xr.min(-rest / ea);
        } else if rest < 0.0 {
            return None;
        }
    }
    if xl > xr {
        return None;
    }
    let x0 = (xl - 0.5).ceil().max(0.0) as usize;
    let x1 = (xr - 0.5).floor().min(res as f64 - 1.0);
    (x1 >= 0.0).then_some((x0, x1 as usize))
}
