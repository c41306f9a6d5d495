//! Textures on faces: texture coordinates at a point of a face, and the two queries the
//! solver and the renderers make, the mean texture over a patch ([`Scene::texture_mean`])
//! and the texel at a point ([`Scene::texel`]).
//!
//! A face's `vt` coordinates are interpolated linearly over each triangle of its
//! triangulation ([`polygon::triangulate`], the same one everywhere), so a polygon whose
//! texture coordinates are not an affine image of its vertices is mapped piecewise; a patch
//! is cut along those triangles before its mean is taken, so each piece is mapped affinely
//! and its texture-space mean is its area mean.

use glam::{DVec2, DVec3};

use super::texture::{Texture, TextureId};
use super::{Face, Material, Rgb, Scene, UvTransform};
use crate::geometry::polygon;

/// The mean of a face's textures over a patch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureMean {
    /// Mean linear texel colour over the patch, to multiply `Kd` by (1 1 1 for a material
    /// with only an alpha map).
    pub rgb: Rgb,
    /// Fraction of the patch's area whose alpha (`map_d`, else the diffuse map's alpha) is
    /// ≥ 0.5.
    pub coverage: f64,
}

/// Barycentric coordinates of `p` projected along `n` onto the plane of triangle (a, b, c);
/// `None` for a degenerate triangle.
fn barycentric(p: DVec3, [a, b, c]: [DVec3; 3], n: DVec3) -> Option<DVec3> {
    let d = (b - a).cross(c - a).dot(n);
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    let wa = (c - b).cross(p - b).dot(n) / d;
    let wb = (a - c).cross(p - c).dot(n) / d;
    Some(DVec3::new(wa, wb, 1.0 - wa - wb))
}

fn interpolate(w: DVec3, uv: [DVec2; 3]) -> DVec2 {
    uv[0] * w.x + uv[1] * w.y + uv[2] * w.z
}

impl Face {
    /// The face's triangles, as indices into `vertices` (itself when it is a triangle).
    fn triangles(&self) -> Vec<[usize; 3]> {
        if self.vertices.len() == 3 {
            vec![[0, 1, 2]]
        } else {
            polygon::triangulate(&self.vertices)
        }
    }

    /// The vertex uvs when there is one per vertex.
    fn vertex_uvs(&self) -> Option<&[DVec2]> {
        self.uvs
            .as_deref()
            .filter(|uv| uv.len() == self.vertices.len())
    }

    /// Texture coordinates at point `p` of the face: interpolated linearly in the triangle
    /// of the face's triangulation that contains `p`'s projection onto the face (the one it
    /// is least outside of, extrapolated, when it lies outside the face). `None` without
    /// `vt` coordinates.
    pub fn uv_at(&self, p: DVec3) -> Option<DVec2> {
        let uvs = self.vertex_uvs()?;
        let n = polygon::newell(&self.vertices);
        let mut best: Option<(f64, DVec3, [usize; 3])> = None;
        for t in self.triangles() {
            let Some(w) = barycentric(p, t.map(|i| self.vertices[i]), n) else {
                continue;
            };
            let inside = w.min_element();
            if best.is_none_or(|b| inside > b.0) {
                best = Some((inside, w, t));
            }
            if inside >= 0.0 {
                break;
            }
        }
        let (_, w, t) = best?;
        Some(interpolate(w, t.map(|i| uvs[i])))
    }

    /// The polygon `corners` (on the face) as triangles in texture space with their areas:
    /// cut along the face's triangles so each piece maps affinely. `None` without uvs.
    fn uv_pieces(&self, corners: &[DVec3]) -> Option<Vec<(f64, [DVec2; 3])>> {
        let uvs = self.vertex_uvs()?;
        let n = polygon::newell(&self.vertices);
        let whole = polygon::area(corners);
        let mut pieces = Vec::new();
        let mut covered = 0.0;
        for t in self.triangles() {
            let tri = t.map(|i| self.vertices[i]);
            let tri_uv = t.map(|i| uvs[i]);
            let part = if self.vertices.len() == 3 {
                corners.to_vec()
            } else {
                clip_to_triangle(corners, tri, n)
            };
            for k in 1..part.len().saturating_sub(1) {
                let p = [part[0], part[k], part[k + 1]];
                let area = polygon::area(&p);
                let Some(uv) = p
                    .iter()
                    .map(|&q| barycentric(q, tri, n).map(|w| interpolate(w, tri_uv)))
                    .collect::<Option<Vec<_>>>()
                else {
                    continue;
                };
                covered += area;
                pieces.push((area, [uv[0], uv[1], uv[2]]));
            }
        }
        if covered < 0.5 * whole {
            // Mostly off the face (bad input): map the corners themselves.
            let uv: Vec<DVec2> = corners.iter().filter_map(|&q| self.uv_at(q)).collect();
            pieces = (1..uv.len().saturating_sub(1))
                .map(|k| {
                    let area = polygon::area(&[corners[0], corners[k], corners[k + 1]]);
                    (area, [uv[0], uv[k], uv[k + 1]])
                })
                .collect();
        }
        Some(pieces)
    }
}

/// `poly` clipped to the prism over triangle `tri` (normal `n`).
fn clip_to_triangle(poly: &[DVec3], tri: [DVec3; 3], n: DVec3) -> Vec<DVec3> {
    let mut out = poly.to_vec();
    for i in 0..3 {
        let (a, b) = (tri[i], tri[(i + 1) % 3]);
        out = polygon::clip_to_halfspace(&out, a, n.cross(b - a));
        if out.len() < 3 {
            return Vec::new();
        }
    }
    out
}

/// A map of a material with its uv transform.
struct Map<'a> {
    texture: &'a Texture,
    uv: UvTransform,
}

impl Map<'_> {
    fn mean(&self, uv: [DVec2; 3]) -> [f64; 4] {
        self.texture
            .mean_over_triangle(uv.map(|p| self.uv.apply(p)))
    }

    fn coverage(&self, uv: [DVec2; 3]) -> f64 {
        self.texture
            .coverage_over_triangle(uv.map(|p| self.uv.apply(p)))
    }

    fn sample(&self, uv: DVec2) -> [f64; 4] {
        self.texture.sample(self.uv.apply(uv))
    }
}

fn rgb(t: [f64; 4]) -> Rgb {
    DVec3::new(t[0], t[1], t[2])
}

impl Scene {
    fn map(&self, id: Option<TextureId>, uv: UvTransform) -> Option<Map<'_>> {
        let texture = self.textures.get(id?.0 as usize)?;
        Some(Map { texture, uv })
    }

    /// The face's material and its (diffuse, alpha) maps; `None` when it has neither.
    fn maps(&self, face: usize) -> Option<(&Face, Option<Map<'_>>, Option<Map<'_>>)> {
        let f = self.faces.get(face)?;
        let m: &Material = self.materials.get(f.material.0 as usize)?;
        let diffuse = self.map(m.diffuse_map, m.diffuse_uv);
        let alpha = self.map(m.alpha_map, m.alpha_uv);
        (diffuse.is_some() || alpha.is_some()).then_some((f, diffuse, alpha))
    }

    /// The mean of face `face`'s textures over the polygon `corners` (3 or 4 points on the
    /// face; a quad counts as two triangles weighted by area): the colour to multiply `Kd` by
    /// and the opaque fraction. `None` when the face's material has no map that loaded. A
    /// face without `vt` coordinates gets its textures' means over the whole image.
    pub fn texture_mean(&self, face: usize, corners: &[DVec3]) -> Option<TextureMean> {
        let (f, diffuse, alpha) = self.maps(face)?;
        let cover = alpha.as_ref().or(diffuse.as_ref());
        let pieces = f.uv_pieces(corners).filter(|p| !p.is_empty());
        let Some(pieces) = pieces else {
            return Some(TextureMean {
                rgb: diffuse.as_ref().map_or(Rgb::ONE, |d| rgb(d.texture.mean())),
                coverage: cover.map_or(1.0, |c| c.texture.mean_coverage()),
            });
        };
        let total: f64 = pieces.iter().map(|p| p.0).sum();
        let weight = |a: f64| {
            if total > 0.0 {
                a / total
            } else {
                1.0 / pieces.len() as f64
            }
        };
        let mut mean = TextureMean {
            rgb: if diffuse.is_some() {
                Rgb::ZERO
            } else {
                Rgb::ONE
            },
            coverage: 0.0,
        };
        for &(a, uv) in &pieces {
            if let Some(d) = &diffuse {
                mean.rgb += rgb(d.mean(uv)) * weight(a);
            }
            mean.coverage += cover.map_or(1.0, |c| c.coverage(uv)) * weight(a);
        }
        Some(mean)
    }

    /// The diffuse map's linear colour (to multiply `Kd` by; 1 1 1 with only an alpha map)
    /// and the alpha (`map_d`, else the diffuse map's) at point `p` of face `face`, sampled
    /// bilinearly. `None` when the face's material has no map that loaded; a face without
    /// `vt` coordinates reads its textures' means.
    pub fn texel(&self, face: usize, p: DVec3) -> Option<(Rgb, f64)> {
        let (f, diffuse, alpha) = self.maps(face)?;
        let read = |m: &Map| match f.uv_at(p) {
            Some(uv) => m.sample(uv),
            None => m.texture.mean(),
        };
        let colour = diffuse.as_ref().map(read);
        let a = alpha.as_ref().map(read).or(colour).map_or(1.0, |t| t[3]);
        Some((colour.map_or(Rgb::ONE, rgb), a))
    }
}
