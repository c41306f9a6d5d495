//! Cut-outs: triangles whose texture's alpha makes parts of them holes (leaves, chains and
//! banners modelled as single sheets). A ray that hits such a triangle where the alpha map
//! is transparent passes on, in every query of the [`crate::geometry::Bvh`]: the solve's
//! visibility, the lights' shadow rays, the eye rays of every pass and the path tracer.
//!
//! The test reads the nearest texel of the full-resolution mask (no filtering: a ray is a
//! point sample), so a hole is found to within half a texel of its edge.

use glam::Vec2;

/// Which texels of a texture are opaque (alpha ≥ the cut-out threshold), one bit each.
#[derive(Clone, Debug, PartialEq)]
pub struct AlphaMask {
    width: u32,
    height: u32,
    bits: Vec<u64>,
}

impl AlphaMask {
    /// A mask of `width × height` texels, top row first; `opaque(x, y)` says which are.
    pub fn new(width: u32, height: u32, opaque: impl Fn(u32, u32) -> bool) -> AlphaMask {
        let (width, height) = (width.max(1), height.max(1));
        let n = width as usize * height as usize;
        let mut bits = vec![0u64; n.div_ceil(64)];
        for y in 0..height {
            for x in 0..width {
                if opaque(x, y) {
                    let i = y as usize * width as usize + x as usize;
                    bits[i / 64] |= 1 << (i % 64);
                }
            }
        }
        AlphaMask {
            width,
            height,
            bits,
        }
    }

    /// Whether texture coordinate `uv` is opaque: the nearest texel, repeating, `v` = 0 at
    /// the bottom row (as [`crate::scene::texture::Texture::sample`] reads). A non-finite
    /// `uv` reads as opaque.
    pub fn opaque(&self, uv: Vec2) -> bool {
        if !uv.is_finite() {
            return true;
        }
        let u = uv.x.rem_euclid(1.0);
        let v = uv.y.rem_euclid(1.0);
        let x = ((u * self.width as f32) as u32).min(self.width - 1);
        let y = (((1.0 - v) * self.height as f32) as u32).min(self.height - 1);
        let i = y as usize * self.width as usize + x as usize;
        self.bits[i / 64] >> (i % 64) & 1 == 1
    }

    /// Memory held, in bytes.
    pub fn bytes(&self) -> usize {
        self.bits.len() * std::mem::size_of::<u64>()
    }
}

/// A triangle's cut-out: which mask (an index into the masks given to
/// [`crate::geometry::Bvh::build_with_masks`]) and the mask's texture coordinates at its three
/// vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutOut {
    pub mask: u32,
    pub uv: [Vec2; 3],
}

impl CutOut {
    /// The texture coordinate at barycentrics `(u, v)` (the weights of vertices 1 and 2).
    pub fn uv_at(&self, u: f32, v: f32) -> Vec2 {
        self.uv[0] + (self.uv[1] - self.uv[0]) * u + (self.uv[2] - self.uv[0]) * v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_checkerboard_mask_reads_back_by_texture_coordinate() {
        // 4 × 2 texels, opaque where x + y is even; the top row is v in (0.5, 1).
        let m = AlphaMask::new(4, 2, |x, y| (x + y) % 2 == 0);
        assert!(m.opaque(Vec2::new(0.1, 0.9))); // x 0, y 0
        assert!(!m.opaque(Vec2::new(0.3, 0.9))); // x 1, y 0
        assert!(!m.opaque(Vec2::new(0.1, 0.1))); // x 0, y 1
        assert!(m.opaque(Vec2::new(0.3, 0.1))); // x 1, y 1
        // Repeats, negative coordinates included.
        assert!(m.opaque(Vec2::new(1.1, 1.9)));
        assert!(!m.opaque(Vec2::new(-0.7, 0.9)));
        assert!(m.opaque(Vec2::new(f32::NAN, 0.5)));
    }

    #[test]
    fn barycentric_coordinates_interpolate_the_vertex_uvs() {
        let c = CutOut {
            mask: 0,
            uv: [Vec2::ZERO, Vec2::new(1.0, 0.0), Vec2::new(0.0, 2.0)],
        };
        assert_eq!(c.uv_at(0.25, 0.5), Vec2::new(0.25, 1.0));
    }
}
