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
    // Quick rejection: every vertex outside one plane (or in front of the near plane).
    if pts.iter().all(|p| p[2] < near) {
        return;
    }
    for pl in &planes {
        if pts
            .iter()
            .all(|p| pl[0] * p[0] + pl[1] * p[1] + pl[2] * p[2] < 0.0)
        {
            return;
        }
    }
    // Plane of the polygon in face coordinates: n·P = c; then 1/D = n·(sx, sy, 1)/c.
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
    if nlen == 0.0 || c.abs() <= 1e-12 * nlen * dist0 {
        return; // Edge-on: covers no area.
    }
    let mut a: Vec<[f64; 3]> = pts;
    let mut b = Vec::with_capacity(k + 8);
    // Near plane: D ≥ near.
    {
        let mut tmp = Vec::with_capacity(k + 2);
        let shifted: Vec<[f64; 3]> = a.iter().map(|p| [p[0], p[1], p[2] - near]).collect();
        clip(&shifted, [0.0, 0.0, 1.0], &mut tmp);
        a = tmp.iter().map(|p| [p[0], p[1], p[2] + near]).collect();
    }
    for pl in &planes {
        if a.len() < 3 {
            return;
        }
        clip(&a, *pl, &mut b);
        std::mem::swap(&mut a, &mut b);
    }
    if a.len() < 3 {
        return;
    }
    // Pixel coordinates: px = (sx + 1)/2 · res, py = (sy − ylo) · res/2.
    let scale = res as f64 * 0.5;
    let screen: Vec<(f64, f64)> = a
        .iter()
        .map(|p| ((p[0] / p[2] + 1.0) * scale, (p[1] / p[2] - ylo) * scale))
        .collect();
    let m = screen.len();
    let mut area2 = 0.0;
    for i in 0..m {
        let (p, q) = (screen[i], screen[(i + 1) % m]);
        area2 += p.0 * q.1 - q.0 * p.1;
    }
    if area2 == 0.0 {
        return;
    }
    let orient = area2.signum();
    // Edge functions E(x, y) = A x + B y + C ≥ 0 inside.
    let edges: Vec<(f64, f64, f64)> = (0..m)
        .map(|i| {
            let (p, q) = (screen[i], screen[(i + 1) % m]);
            let ea = -(q.1 - p.1) * orient;
            let eb = (q.0 - p.0) * orient;
            (ea, eb, -(ea * p.0 + eb * p.1))
        })
        .collect();
    let (mut ymin, mut ymax) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in &screen {
        ymin = ymin.min(s.1);
        ymax = ymax.max(s.1);
    }
    let rows = face.rows;
    let y0 = ((ymin - 0.5).ceil().max(0.0)) as usize;
    let y1 = ((ymax - 0.5).floor()).min(rows as f64 - 1.0);
    if y1 < 0.0 {
        return;
    }
    let y1 = y1 as usize;
    // 1/D as a function of pixel coordinates.
    let inv_c = 1.0 / c;
    for py in y0..=y1 {
        let yc = py as f64 + 0.5;
        let (mut xl, mut xr) = (0.0f64, res as f64);
        let mut empty = false;
        for &(ea, eb, ec) in &edges {
            let rest = eb * yc + ec;
            if ea > 0.0 {
                xl = xl.max(-rest / ea);
            } else if ea < 0.0 {
                xr = xr.min(-rest / ea);
            } else if rest < 0.0 {
                empty = true;
                break;
            }
        }
        if empty || xl > xr {
            continue;
        }
        let x0 = (xl - 0.5).ceil().max(0.0) as usize;
        let x1 = (xr - 0.5).floor().min(res as f64 - 1.0);
        if x1 < 0.0 {
            continue;
        }
        let x1 = x1 as usize;
        let sy = yc / scale + ylo;
        let row = py * res;
        for px in x0..=x1 {
            let sx = (px as f64 + 0.5) / scale - 1.0;
            let z = (n[0] * sx + n[1] * sy + n[2]) * inv_c;
            let i = row + px;
            if z > face.inv_depth[i] {
                face.inv_depth[i] = z;
                face.ids[i] = id;
            }
        }
    }
}
