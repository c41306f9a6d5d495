//! Rays, triangles, a bounding-volume hierarchy and seeded sampling.
//!
//! Coordinates are right-handed scene units (millimetres for the Cornell box), +y up.
//! The BVH stores triangles in `f32` for traversal speed, in coordinates normalised by the
//! scene's bounding box (so its rounding does not depend on the unit); queries take and
//! return `f64`.

pub mod alpha_mask;
pub mod bvh;
pub mod polygon;
pub mod sampling;
pub mod shaft;

pub use alpha_mask::{AlphaMask, CutOut};
pub use bvh::{Bvh, Hit};
pub use sampling::Rng;

use glam::DVec3;

/// A ray `origin + t * dir`; `dir` need not be normalised.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: DVec3,
    pub dir: DVec3,
}

impl Ray {
    pub fn new(origin: DVec3, dir: DVec3) -> Self {
        Self { origin, dir }
    }
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + self.dir * t
    }
}

/// Axis-aligned bounding box in `f64`.
#[derive(Clone, Copy, Debug)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };
    pub fn grow(&mut self, p: DVec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a DVec3>) -> Aabb {
        let mut b = Aabb::EMPTY;
        for p in points {
            b.grow(*p);
        }
        b
    }
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }
    pub fn diagonal(&self) -> f64 {
        if self.is_empty() {
            0.0
        } else {
            (self.max - self.min).length()
        }
    }
    pub fn center(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }
}
