//! The Nusselt analogue in 3-D: the unit hemisphere over the point, the patch (drawn scaled
//! about the point so it fits: the same projection), rays from the point to its corners,
//! its central projection on the hemisphere, and that projection dropped onto the base
//! disk. Drag to turn the view. Orthographic, painted with egui shapes.

use eframe::egui;
use glam::DVec3;

use super::nusselt::NusseltDetail;

/// The patch is drawn scaled about the point so that its nearest corner is this far away
/// (in hemisphere radii): far enough to stand clear of the hemisphere.
const PATCH_DISTANCE: f64 = 1.5;

/// Edge subdivisions of the projected outlines.
const STEPS: usize = 24;

/// Turns the view: yaw about the normal and pitch above the disk, in radians.
#[derive(Clone, Copy, Debug)]
pub struct View3d {
    pub yaw: f32,
    pub pitch: f32,
}

impl Default for View3d {
    fn default() -> Self {
        View3d {
            yaw: 0.6,
            pitch: 0.7,
        }
    }
}

/// Screen offset (x right, y down, in radii) of a point in the patch frame (z = normal),
/// seen from `v`: orthographic, the far side of the disk higher on the screen.
fn project(v: &View3d, p: DVec3) -> egui::Vec2 {
    let (sy, cy) = (f64::from(v.yaw).sin(), f64::from(v.yaw).cos());
    let (sp, cp) = (f64::from(v.pitch).sin(), f64::from(v.pitch).cos());
    let x = cy * p.x - sy * p.y;
    let depth = sy * p.x + cy * p.y;
    let up = cp * p.z + sp * depth;
    egui::vec2(x as f32, -up as f32)
}

/// A filled region from a star-shaped outline (a fan from its mean), and the outline.
fn fan(painter: &egui::Painter, pts: &[egui::Pos2], fill: egui::Color32, stroke: egui::Stroke) {
    if pts.len() < 3 {
        return;
    }
    let n = pts.len() as f32;
    let c = pts.iter().fold(egui::Vec2::ZERO, |a, p| a + p.to_vec2()) / n;
    let mut mesh = egui::Mesh::default();
    mesh.colored_vertex(c.to_pos2(), fill);
    for p in pts {
        mesh.colored_vertex(*p, fill);
    }
    let k = pts.len() as u32;
    for i in 0..k {
        mesh.add_triangle(0, 1 + i, 1 + (i + 1) % k);
    }
    painter.add(egui::Shape::mesh(mesh));
    painter.add(egui::Shape::closed_line(pts.to_vec(), stroke));
}

/// Draws the analogue for `d` in a square of `side` points; dragging turns `view`.
pub(super) fn draw(ui: &mut egui::Ui, d: &NusseltDetail, view: &mut View3d, side: f32) {
    let (rect, response) = ui.allocate_exact_size(egui::vec2(side, side), egui::Sense::drag());
    if response.dragged() {
        let delta = response.drag_delta();
        view.yaw += delta.x * 0.01;
        view.pitch = (view.pitch + delta.y * 0.01).clamp(0.05, 1.5);
    }
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 4.0, egui::Color32::from_gray(24));
    let (patch, scale) = scaled_patch(d);
    let (origin, radius) = fit(view, &patch, rect, side);
    let at = |p: DVec3| origin + project(view, p) * radius;
    draw_hemisphere(&painter, &at);
    draw_projections(&painter, &at, &patch);
    painter.text(
        rect.left_top() + egui::vec2(6.0, 4.0),
        egui::Align2::LEFT_TOP,
        format!("patch drawn ×{scale:.3} about the point (same projection); drag to turn"),
        egui::FontId::proportional(11.0),
        egui::Color32::from_gray(200),
    );
}

/// The patch in the point's frame, scaled about the point so that its nearest corner lies
/// at [`PATCH_DISTANCE`]; and the scale.
fn scaled_patch(d: &NusseltDetail) -> (Vec<DVec3>, f64) {
    let corners: Vec<DVec3> = d
        .patch_local
        .iter()
        .map(|c| DVec3::from_array(*c))
        .collect();
    let nearest = corners
        .iter()
        .map(|c| c.length())
        .fold(f64::INFINITY, f64::min);
    let scale = if nearest.is_finite() && nearest > 0.0 {
        PATCH_DISTANCE / nearest
    } else {
        1.0
    };
    (corners.iter().map(|c| *c * scale).collect(), scale)
}

/// Where the point is drawn and how many screen points a unit is, so that the hemisphere
/// and the patch fit into the square (their screen bounds, centred).
fn fit(view: &View3d, patch: &[DVec3], rect: egui::Rect, side: f32) -> (egui::Pos2, f32) {
    let (mut lo, mut hi) = (egui::Vec2::splat(f32::MAX), egui::Vec2::splat(f32::MIN));
    let ring = (0..36).map(|k| {
        let a = k as f64 / 36.0 * std::f64::consts::TAU;
        DVec3::new(a.cos(), a.sin(), 0.0)
    });
    for p in ring.chain([DVec3::Z]).chain(patch.iter().copied()) {
        let q = project(view, p);
        lo = lo.min(q);
        hi = hi.max(q);
    }
    let size = (hi - lo).max(egui::Vec2::splat(1e-3));
    let radius = ((side - 16.0) / size.x).min((side - 36.0) / size.y);
    let origin = rect.center() + egui::vec2(0.0, 10.0) - (lo + hi) * 0.5 * radius;
    (origin, radius)
}

/// The base disk and the hemisphere's wireframe (meridians and two parallels); `at` puts
/// a point of the frame on the screen.
fn draw_hemisphere(painter: &egui::Painter, at: &impl Fn(DVec3) -> egui::Pos2) {
    let thin = egui::Stroke::new(1.0, egui::Color32::from_gray(110));
    let circle = |z: f64, r: f64| -> Vec<egui::Pos2> {
        (0..72)
            .map(|k| {
                let a = k as f64 / 72.0 * std::f64::consts::TAU;
                at(DVec3::new(r * a.cos(), r * a.sin(), z))
            })
            .collect()
    };
    painter.add(egui::Shape::convex_polygon(
        circle(0.0, 1.0),
        egui::Color32::from_gray(45),
        egui::Stroke::new(1.5, egui::Color32::GRAY),
    ));
    for lat in [30f64, 60.0] {
        let t = lat.to_radians();
        painter.add(egui::Shape::closed_line(circle(t.sin(), t.cos()), thin));
    }
    for m in 0..8 {
        let a = m as f64 / 8.0 * std::f64::consts::TAU;
        let pts: Vec<egui::Pos2> = (0..=18)
            .map(|k| {
                let t = k as f64 / 18.0 * std::f64::consts::FRAC_PI_2;
                at(DVec3::new(t.cos() * a.cos(), t.cos() * a.sin(), t.sin()))
            })
            .collect();
        painter.add(egui::Shape::line(pts, thin));
    }
}

/// The patch's outline subdivided ([`STEPS`] points an edge) and projected centrally onto
/// the hemisphere, clamped to the horizon.
fn outline_on_sphere(patch: &[DVec3]) -> Vec<DVec3> {
    let n = patch.len();
    let mut on_sphere = Vec::with_capacity(n * STEPS);
    for k in 0..n {
        let (a, b) = (patch[k], patch[(k + 1) % n]);
        for s in 0..STEPS {
            let h = a.lerp(b, s as f64 / STEPS as f64).normalize_or_zero();
            let h = if h.z < 0.0 {
                DVec3::new(h.x, h.y, 0.0).normalize_or_zero()
            } else {
                h
            };
            on_sphere.push(h);
        }
    }
    on_sphere
}

/// The patch, its projection on the hemisphere and that projection dropped onto the disk,
/// with the rays from the point to the corners and the drop lines.
fn draw_projections(painter: &egui::Painter, at: &impl Fn(DVec3) -> egui::Pos2, patch: &[DVec3]) {
    let n = patch.len();
    let on_sphere = outline_on_sphere(patch);
    let cyan = egui::Color32::from_rgb(0, 220, 255);
    let yellow = egui::Color32::from_rgb(255, 210, 60);
    let disk: Vec<egui::Pos2> = on_sphere
        .iter()
        .map(|h| at(DVec3::new(h.x, h.y, 0.0)))
        .collect();
    fan(
        painter,
        &disk,
        egui::Color32::from_rgba_unmultiplied(0, 220, 255, 90),
        egui::Stroke::new(2.0, cyan),
    );
    // Drop lines from the hemisphere to the disk at the patch's corners.
    for k in 0..n {
        let h = on_sphere[k * STEPS];
        painter.line_segment(
            [at(h), at(DVec3::new(h.x, h.y, 0.0))],
            egui::Stroke::new(1.0, cyan),
        );
    }
    let sphere: Vec<egui::Pos2> = on_sphere.iter().map(|h| at(*h)).collect();
    fan(
        painter,
        &sphere,
        egui::Color32::from_rgba_unmultiplied(255, 210, 60, 110),
        egui::Stroke::new(2.0, yellow),
    );
    // Rays from the point to the patch's corners, and the patch.
    for c in patch {
        painter.line_segment(
            [at(DVec3::ZERO), at(*c)],
            egui::Stroke::new(1.0, egui::Color32::from_gray(170)),
        );
    }
    let patch_pts: Vec<egui::Pos2> = patch.iter().map(|c| at(*c)).collect();
    fan(
        painter,
        &patch_pts,
        egui::Color32::from_rgba_unmultiplied(230, 230, 230, 70),
        egui::Stroke::new(2.0, egui::Color32::WHITE),
    );
    painter.circle_filled(at(DVec3::ZERO), 3.0, egui::Color32::RED);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Seen from straight above (pitch π/2) the drawing is the disk as the 2-D panel draws
    /// it (x right, y up) and the pole is at the centre; from the side (pitch 0) the normal
    /// points up the screen.
    #[test]
    fn from_above_the_view_is_the_disk() {
        let above = View3d {
            yaw: 0.0,
            pitch: std::f32::consts::FRAC_PI_2,
        };
        let s = project(&above, DVec3::new(0.5, 0.25, 0.0));
        assert!(
            (s.x - 0.5).abs() < 1e-6 && (s.y + 0.25).abs() < 1e-6,
            "{s:?}"
        );
        assert!(project(&above, DVec3::Z).length() < 1e-6);
        let side = View3d {
            yaw: 0.0,
            pitch: 0.0,
        };
        let up = project(&side, DVec3::Z);
        assert!((up.y + 1.0).abs() < 1e-6 && up.x.abs() < 1e-6);
    }
}
