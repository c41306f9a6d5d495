//! The built-in `gallery`: a large generated scene for scale benchmarks. A 6 × 3 ×
//! 5 m room lit by a ceiling panel, a table, two cabinets, and on a plinth a tessellated
//! statue: a bumpy sphere of `2 · STATUE_U · STATUE_V` triangles (100,000), so that the
//! input has more than 100 k triangles, most of them small, curved and of one material,
//! like a scanned model. Generated as OBJ text and loaded through the same validation as
//! any user file; the generator is this code, not a stored model.

use std::f64::consts::PI;
use std::fmt::Write;

use glam::DVec3;

/// Statue grid: around (u) and from pole to pole (v).
pub const STATUE_U: usize = 250;
pub const STATUE_V: usize = 202;

pub const MTL: &str = "newmtl wall\nKd 0.75 0.75 0.72\n\
newmtl floor\nKd 0.45 0.32 0.22\n\
newmtl light\nKd 0.8 0.8 0.8\nKe 12 11 9\n\
newmtl wood\nKd 0.3 0.2 0.12\n\
newmtl cabinet\nKd 0.2 0.35 0.6\n\
newmtl plinth\nKd 0.6 0.6 0.6\n\
newmtl statue\nKd 0.7 0.68 0.62\n";

struct Obj {
    text: String,
    vertices: usize,
}

impl Obj {
    fn vertex(&mut self, p: DVec3) -> usize {
        let _ = writeln!(self.text, "v {:.6} {:.6} {:.6}", p.x, p.y, p.z);
        self.vertices += 1;
        self.vertices
    }
    fn face(&mut self, ids: &[usize]) {
        self.text.push('f');
        for i in ids {
            let _ = write!(self.text, " {i}");
        }
        self.text.push('\n');
    }
    fn material(&mut self, name: &str) {
        let _ = writeln!(self.text, "usemtl {name}");
    }
    /// A quad, counter-clockwise seen from the side it faces.
    fn quad(&mut self, corners: [DVec3; 4]) {
        let ids = corners.map(|c| self.vertex(c));
        self.face(&ids);
    }
    /// An axis-aligned box seen from outside, without its bottom face (it stands on
    /// something).
    fn cuboid(&mut self, lo: DVec3, hi: DVec3) {
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let (a, b) = (lo, hi);
        self.quad([
            p(a.x, b.y, a.z),
            p(a.x, b.y, b.z),
            p(b.x, b.y, b.z),
            p(b.x, b.y, a.z),
        ]); // top
        self.quad([
            p(a.x, a.y, b.z),
            p(b.x, a.y, b.z),
            p(b.x, b.y, b.z),
            p(a.x, b.y, b.z),
        ]); // +z
        self.quad([
            p(b.x, a.y, a.z),
            p(a.x, a.y, a.z),
            p(a.x, b.y, a.z),
            p(b.x, b.y, a.z),
        ]); // -z
        self.quad([
            p(b.x, a.y, b.z),
            p(b.x, a.y, a.z),
            p(b.x, b.y, a.z),
            p(b.x, b.y, b.z),
        ]); // +x
        self.quad([
            p(a.x, a.y, a.z),
            p(a.x, a.y, b.z),
            p(a.x, b.y, b.z),
            p(a.x, b.y, a.z),
        ]); // -x
    }
}

/// The OBJ text of the gallery (materials in [`MTL`], library `gallery.mtl`).
pub fn obj() -> String {
    let mut o = Obj {
        text: String::with_capacity(8 << 20),
        vertices: 0,
    };
    o.text.push_str("mtllib gallery.mtl\n");
    let p = DVec3::new;
    let (w, h, d) = (6.0, 3.0, 5.0);
    // Room, faces pointing inwards.
    o.material("floor");
    o.quad([
        p(0.0, 0.0, 0.0),
        p(0.0, 0.0, d),
        p(w, 0.0, d),
        p(w, 0.0, 0.0),
    ]);
    o.material("wall");
    o.quad([p(0.0, h, 0.0), p(w, h, 0.0), p(w, h, d), p(0.0, h, d)]); // ceiling
    o.quad([
        p(0.0, 0.0, 0.0),
        p(w, 0.0, 0.0),
        p(w, h, 0.0),
        p(0.0, h, 0.0),
    ]); // back
    o.quad([p(0.0, 0.0, d), p(0.0, h, d), p(w, h, d), p(w, 0.0, d)]); // front
    o.quad([
        p(0.0, 0.0, 0.0),
        p(0.0, h, 0.0),
        p(0.0, h, d),
        p(0.0, 0.0, d),
    ]); // left
    o.quad([p(w, 0.0, 0.0), p(w, 0.0, d), p(w, h, d), p(w, h, 0.0)]); // right
    // Ceiling panel just below the ceiling, facing down.
    o.material("light");
    let y = h - 0.01;
    o.quad([
        p(2.5, y, 2.0),
        p(3.5, y, 2.0),
        p(3.5, y, 3.0),
        p(2.5, y, 3.0),
    ]);
    // Table: top and four legs.
    o.material("wood");
    o.cuboid(p(0.6, 0.72, 0.8), p(2.2, 0.78, 1.8));
    for (x, z) in [(0.65, 0.85), (2.1, 0.85), (0.65, 1.7), (2.1, 1.7)] {
        o.cuboid(p(x, 0.0, z), p(x + 0.05, 0.72, z + 0.05));
    }
    // Cabinets against the back and right walls.
    o.material("cabinet");
    o.cuboid(p(3.8, 0.0, 0.02), p(5.6, 1.6, 0.5));
    o.cuboid(p(5.45, 0.0, 3.2), p(5.98, 1.1, 4.6));
    // Plinth and statue.
    o.material("plinth");
    let centre = p(3.6, 0.0, 2.9);
    o.cuboid(centre + p(-0.35, 0.0, -0.35), centre + p(0.35, 0.9, 0.35));
    o.material("statue");
    statue(&mut o, centre + p(0.0, 0.9 + 0.45, 0.0), 0.42);
    o.text
}

/// A bumpy sphere of radius about `r` around `c`: `2 · STATUE_U · (STATUE_V − 1)` triangles
/// plus the pole fans.
fn statue(o: &mut Obj, c: DVec3, r: f64) {
    let point = |u: usize, v: usize| {
        let theta = 2.0 * PI * u as f64 / STATUE_U as f64;
        let phi = PI * v as f64 / STATUE_V as f64;
        let bump = 1.0 + 0.12 * (5.0 * theta).sin() * (4.0 * phi).sin() + 0.05 * (17.0 * phi).cos();
        c + DVec3::new(phi.sin() * theta.cos(), phi.cos(), phi.sin() * theta.sin()) * (r * bump)
    };
    let top = o.vertex(point(0, 0));
    let mut rows = Vec::with_capacity(STATUE_V - 1);
    for v in 1..STATUE_V {
        let row: Vec<usize> = (0..STATUE_U).map(|u| o.vertex(point(u, v))).collect();
        rows.push(row);
    }
    let bottom = o.vertex(point(0, STATUE_V));
    let n = STATUE_U;
    // Counter-clockwise seen from outside.
    for u in 0..n {
        o.face(&[top, rows[0][(u + 1) % n], rows[0][u]]);
    }
    for v in 0..rows.len() - 1 {
        for u in 0..n {
            let (a, b) = (rows[v][u], rows[v][(u + 1) % n]);
            let (c2, d2) = (rows[v + 1][u], rows[v + 1][(u + 1) % n]);
            o.face(&[a, b, d2]);
            o.face(&[a, d2, c2]);
        }
    }
    let last = rows.len() - 1;
    for u in 0..n {
        o.face(&[bottom, rows[last][u], rows[last][(u + 1) % n]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::polygon;
    use crate::scene::{LoadOptions, Scene};

    /// Over 100 k input triangles, every statue facet facing away from the statue's centre
    /// and every room face facing into the room (a flipped winding makes a black statue or
    /// a room lit from outside).
    #[test]
    fn gallery_is_large_and_faces_the_right_way() {
        let scene = Scene::builtin("gallery", &LoadOptions::default()).expect("gallery");
        let statue = scene
            .materials
            .iter()
            .position(|m| m.name == "statue")
            .expect("statue material");
        let centre = DVec3::new(3.6, 0.9 + 0.45, 2.9);
        let room_centre = DVec3::new(3.0, 1.5, 2.5);
        let mut statue_faces = 0;
        for f in &scene.faces {
            let n = polygon::normal(&f.vertices).expect("non-degenerate face");
            let c = polygon::centroid(&f.vertices);
            if f.material.0 as usize == statue {
                statue_faces += 1;
                assert!(n.dot(c - centre) > 0.0, "statue facet at {c} faces inwards");
            }
        }
        assert!(statue_faces >= 100_000, "{statue_faces} statue triangles");
        assert!(scene.faces.len() > 100_000);
        // The six room faces (the first six faces) face the room's centre.
        for f in &scene.faces[..6] {
            let n = polygon::normal(&f.vertices).expect("room face");
            assert!(n.dot(room_centre - polygon::centroid(&f.vertices)) > 0.0);
        }
    }
}
