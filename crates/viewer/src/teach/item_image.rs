//! Small images drawn on the CPU for the teaching views that show two solutions side by
//! side (`compare`, `mesh`): an item buffer (the element each pixel sees, one ray per
//! pixel centre) traced once per mesh and camera, then coloured by any per-element value
//! as often as the values change, which costs a lookup per pixel. Element edges are the
//! pixels whose neighbour sees another element, so the mesh shows without a line renderer.

use nusselt_core::geometry::{Bvh, Ray};
use nusselt_core::scene::Camera;

/// No element: the ray left the scene.
pub const NOTHING: u32 = u32::MAX;

/// The element seen through each pixel.
#[derive(Debug, Clone)]
pub struct ItemImage {
    pub width: usize,
    pub height: usize,
    /// Row-major, [`NOTHING`] where no surface is hit.
    pub element: Vec<u32>,
}

impl ItemImage {
    /// One ray through each pixel centre of `camera` into `bvh`, whose triangle ids map to
    /// elements through `triangle_element`.
    pub fn trace(
        bvh: &Bvh,
        triangle_element: &[u32],
        camera: &Camera,
        width: usize,
        height: usize,
    ) -> ItemImage {
        let mut element = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let dir =
                    camera.ray_dir(x as f64 + 0.5, y as f64 + 0.5, width as u32, height as u32);
                let hit = bvh.closest_hit(&Ray::new(camera.eye, dir), 0.0, f64::INFINITY);
                element.push(
                    hit.and_then(|h| triangle_element.get(h.id as usize).copied())
                        .unwrap_or(NOTHING),
                );
            }
        }
        ItemImage {
            width,
            height,
            element,
        }
    }

    /// Whether pixel `k` lies on an element edge: its right or lower neighbour sees
    /// another element (or nothing).
    pub fn on_edge(&self, k: usize) -> bool {
        let here = self.element[k];
        if here == NOTHING {
            return false;
        }
        let (x, y) = (k % self.width, k / self.width);
        (x + 1 < self.width && self.element[k + 1] != here)
            || (y + 1 < self.height && self.element[k + self.width] != here)
    }

    /// RGBA8 pixels: `colour` of the element seen (sRGB bytes), background black, and
    /// element edges in `edge` when given.
    pub fn paint(&self, colour: impl Fn(u32) -> [u8; 3], edge: Option<[u8; 3]>) -> Vec<[u8; 3]> {
        (0..self.element.len())
            .map(|k| match (self.element[k], edge) {
                (NOTHING, _) => [0, 0, 0],
                (_, Some(e)) if self.on_edge(k) => e,
                (j, _) => colour(j),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use nusselt_core::geometry::bvh::TriangleInput;

    /// Two triangles forming a square seen head-on fill the middle of the image; the
    /// diagonal between them is an edge, the background is not.
    #[test]
    fn a_square_of_two_elements_is_seen_with_its_diagonal() {
        let v = [
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ];
        let bvh = Bvh::build(&[
            TriangleInput {
                vertices: [v[0], v[1], v[2]],
                id: 0,
                cull_back: false,
                cut: None,
            },
            TriangleInput {
                vertices: [v[0], v[2], v[3]],
                id: 1,
                cull_back: false,
                cut: None,
            },
        ]);
        let camera = Camera {
            eye: DVec3::new(0.0, 0.0, 4.0),
            target: DVec3::ZERO,
            vfov_deg: 60.0,
        };
        let img = ItemImage::trace(&bvh, &[7, 9], &camera, 32, 32);
        let centre = img.element[16 * 32 + 16];
        assert!(centre == 7 || centre == 9);
        assert_eq!(img.element[0], NOTHING, "the corner sees past the square");
        let sevens = img.element.iter().filter(|&&e| e == 7).count();
        let nines = img.element.iter().filter(|&&e| e == 9).count();
        assert!(sevens > 50 && nines > 50 && sevens.abs_diff(nines) < 40);
        // Along the diagonal (one pixel of it at least per row in the square) edges are
        // found; the background is never an edge.
        let edges = (0..img.element.len()).filter(|&k| img.on_edge(k)).count();
        assert!(edges >= 10, "{edges}");
        assert!(!img.on_edge(0));
        let px = img.paint(|e| [e as u8, 0, 0], Some([255, 255, 255]));
        assert_eq!(px[0], [0, 0, 0]);
        assert!(px.contains(&[7, 0, 0]) && px.contains(&[9, 0, 0]));
    }
}
