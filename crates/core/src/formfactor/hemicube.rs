//! The hemicube (Cohen & Greenberg 1985, "The hemi-cube: a radiosity solution for complex
//! environments"): an item buffer on the five faces of a half cube around a point, each pixel
//! holding the id of the nearest polygon seen through it (z-buffer), weighted by its
//! precomputed delta form factor — top face (x, y, 1): `ΔA / (π (x² + y² + 1)²)`, side face at
//! height z: `z ΔA / (π (y² + z² + 1)²)` — so that `F(point → polygon) ≈ Σ` over its pixels.
//!
//! This is a CPU rasteriser: polygons are clipped in homogeneous coordinates against the near
//! plane and the face's frustum, then scan-converted (pixel centres) with `1/depth` interpolated;
//! each hemicube may be rotated by a random angle about the normal (Wallace et al. 1989 and
//! Baum et al. 1989 note the aliasing a fixed orientation gives).
//!
//! Known error: (1) aliasing — a polygon covering few pixels is rounded to whole pixels, so a
//! small or far receiver is over- or under-estimated by up to one pixel's delta per boundary
//! pixel (the reference catalogue notes a 0.05-wide square at distance 1–2 missed entirely
//! 40 % of the time at 32×32; median error 7 % at 128, 2 % at 256); (2) the point
//! approximation — the shooter is a point at its centroid, wrong for receivers closer than a
//! few shooter radii; (3) the delta form factors are the midpoint rule, so they sum to
//! `1 − O(res⁻²)` (measured in the tests).

use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use self::raster::{Face, draw_face};
use super::RowContext;
use crate::geometry::Rng;
use crate::geometry::sampling::{basis, hash_seed};
use crate::mesh::PatchId;

mod raster;

pub use self::raster::to_face;

/// Id of pixels that see nothing, or a polygon that only blocks.
pub const NONE: u32 = u32::MAX;

/// Id of a polygon that is not drawn at all (for [`ItemBufferRaster`]).
pub const SKIP: u32 = u32::MAX - 1;

/// Where a hemicube sits: `axes[2]` is the normal, `axes[0..2]` span the top face's x and y
/// (see [`hemicube_axes`]); geometry nearer than `near` along a face's axis is clipped.
#[derive(Clone, Copy, Debug)]
pub struct HemicubeView {
    pub origin: DVec3,
    pub axes: [DVec3; 3],
    pub near: f64,
}

/// A hemicube's item buffer rasterised elsewhere — the GPU one is `nusselt_gpu::GpuHemicube`,
/// outside the core so that the core never depends on wgpu. It must draw exactly what
/// [`Hemicube`] draws: the same five faces, pixel centres, nearest polygon wins, and the
/// same face layout for [`DeltaTable::deltas`].
pub trait ItemBufferRaster: Send + Sync + std::fmt::Debug {
    /// What rasterises (e.g. the GPU adapter's name).
    fn describe(&self) -> String;

    /// Draws the convex polygons returned by `polygons` (world coordinates; called again only
    /// when `key` differs from the previous call's) at `view`, polygon `k` with id `ids[k]`
    /// ([`NONE`] blocks, [`SKIP`] is not drawn), and returns for every id below `n` the sum of
    /// the delta form factors of its pixels in `table`.
    fn form_factors(
        &self,
        key: u64,
        polygons: &dyn Fn() -> Vec<Vec<DVec3>>,
        view: &HemicubeView,
        table: &DeltaTable,
        ids: &[u32],
        n: usize,
    ) -> Result<Vec<f64>, RasterError>;
}

/// A rasteriser failed (device lost, out of memory, …).
#[derive(Debug, thiserror::Error)]
#[error("hemicube rasteriser: {0}")]
pub struct RasterError(pub String);

/// The hemicube frame: tangent and bitangent rotated by `angle` about `normal`, then `normal`.
pub fn hemicube_axes(normal: DVec3, angle: f64) -> [DVec3; 3] {
    let (t, b) = basis(normal);
    let (s, c) = angle.sin_cos();
    [t * c + b * s, b * c - t * s, normal]
}

/// Delta form factors for one resolution.
#[derive(Clone, Debug)]
pub struct DeltaTable {
    res: usize,
    half: usize,
    top: Vec<f64>,
    side: Vec<f64>,
}

impl DeltaTable {
    /// `res` pixels across the top face (rounded up to even, at least 2); the sides are
    /// `res/2` pixels tall.
    pub fn new(res: u32) -> Self {
        let res = (res.max(2) as usize).div_ceil(2) * 2;
        let half = res / 2;
        let d = 2.0 / res as f64;
        let da = d * d;
        let pi = std::f64::consts::PI;
        let mut top = Vec::with_capacity(res * res);
        for j in 0..res {
            let y = -1.0 + (j as f64 + 0.5) * d;
            for i in 0..res {
                let x = -1.0 + (i as f64 + 0.5) * d;
                let q = x * x + y * y + 1.0;
                top.push(da / (pi * q * q));
            }
        }
        let mut side = Vec::with_capacity(res * half);
        for j in 0..half {
            let z = (j as f64 + 0.5) * d;
            for i in 0..res {
                let y = -1.0 + (i as f64 + 0.5) * d;
                let q = y * y + z * z + 1.0;
                side.push(z * da / (pi * q * q));
            }
        }
        Self {
            res,
            half,
            top,
            side,
        }
    }

    pub fn res(&self) -> usize {
        self.res
    }

    /// Delta form factors of face `f`, row-major from its first row: face 0 is the top
    /// (`res × res`, row `j` at `y = −1 + (j + ½)·2/res`), faces 1–4 the sides (`res/2` rows
    /// of `res`, row `j` at height `z = (j + ½)·2/res`).
    pub fn deltas(&self, f: usize) -> &[f64] {
        if f == 0 { &self.top } else { &self.side }
    }

    /// Adds the delta form factor of each pixel of face `f` (item buffer `ids`, layout of
    /// [`deltas`](Self::deltas)) to `out[id]`; ids ≥ `out.len()` and [`NONE`] are skipped.
    pub fn accumulate_face(&self, f: usize, ids: &[u32], out: &mut [f64]) {
        for (id, d) in ids.iter().zip(self.deltas(f)) {
            if let Some(o) = out.get_mut(*id as usize) {
                *o += d;
            }
        }
    }

    /// Sum over the whole hemicube (1 in the limit).
    pub fn sum(&self) -> f64 {
        self.top.iter().sum::<f64>() + 4.0 * self.side.iter().sum::<f64>()
    }

    /// Solid angle of a pixel at the centre of the top face (steradians).
    pub fn pixel_solid_angle(&self) -> f64 {
        let d = 2.0 / self.res as f64;
        d * d
    }

    /// [`pixel_solid_angle`](Self::pixel_solid_angle) of a table of resolution `res`,
    /// without building it.
    pub fn pixel_solid_angle_at(res: u32) -> f64 {
        let res = (res.max(2) as usize).div_ceil(2) * 2;
        let d = 2.0 / res as f64;
        d * d
    }
}

/// A hemicube at a point: draw polygons, then read the form factor of each id.
pub struct Hemicube<'t> {
    table: &'t DeltaTable,
    origin: DVec3,
    axes: [DVec3; 3],
    near: f64,
    faces: Vec<Face>,
}

/// A polygon's vertices in hemicube-local coordinates (u, v, w): w along the normal.
pub type Local = [f64; 3];

impl<'t> Hemicube<'t> {
    /// A hemicube at `origin` looking along unit `normal`, rotated by `angle` about it;
    /// geometry nearer than `near` along a face's axis is clipped.
    pub fn new(table: &'t DeltaTable, origin: DVec3, normal: DVec3, angle: f64, near: f64) -> Self {
        let axes = hemicube_axes(normal, angle);
        let res = table.res;
        let faces = (0..5)
            .map(|f| {
                let rows = if f == 0 { res } else { table.half };
                Face {
                    ids: vec![NONE; res * rows],
                    inv_depth: vec![0.0; res * rows],
                    rows,
                }
            })
            .collect();
        Self {
            table,
            origin,
            axes,
            near: near.max(1e-300),
            faces,
        }
    }

    /// Local coordinates of a point.
    pub fn local(&self, p: DVec3) -> Local {
        let d = p - self.origin;
        [
            d.dot(self.axes[0]),
            d.dot(self.axes[1]),
            d.dot(self.axes[2]),
        ]
    }

    /// Draws a convex polygon with `id` on every face (depth-tested).
    pub fn draw(&mut self, poly: &[DVec3], id: u32) {
        let local: Vec<Local> = poly.iter().map(|p| self.local(*p)).collect();
        self.draw_local(&local, id);
    }

    /// [`draw`](Self::draw) with the vertices already in local coordinates.
    pub fn draw_local(&mut self, local: &[Local], id: u32) {
        if local.iter().all(|p| p[2] <= 0.0) {
            return; // Entirely below the horizon.
        }
        let (res, near) = (self.table.res, self.near);
        for (f, face) in self.faces.iter_mut().enumerate() {
            draw_face(face, f, res, near, local, id);
        }
    }

    /// Draws many convex polygons (local coordinates, with ids), the five faces in parallel.
    pub fn draw_many(&mut self, polys: &[(Vec<Local>, u32)]) {
        let (res, near) = (self.table.res, self.near);
        self.faces.par_iter_mut().enumerate().for_each(|(f, face)| {
            for (local, id) in polys {
                if local.iter().any(|p| p[2] > 0.0) {
                    draw_face(face, f, res, near, local, *id);
                }
            }
        });
    }

    /// Adds each pixel's delta form factor to `out[id]` (ids ≥ `out.len()` and
    /// [`NONE`] are skipped).
    pub fn accumulate(&self, out: &mut [f64]) {
        for (f, face) in self.faces.iter().enumerate() {
            self.table.accumulate_face(f, &face.ids, out);
        }
    }

    /// The item buffer, face after face in the layout of [`DeltaTable::deltas`].
    pub fn item_buffer(&self) -> Vec<u32> {
        self.faces
            .iter()
            .flat_map(|f| f.ids.iter().copied())
            .collect()
    }

    /// Form factor of one id.
    pub fn form_factor(&self, id: u32) -> f64 {
        let mut sum = 0.0;
        for (f, face) in self.faces.iter().enumerate() {
            for (i, d) in face.ids.iter().zip(self.table.deltas(f)) {
                if *i == id {
                    sum += d;
                }
            }
        }
        sum
    }
}

/// The random rotation of the hemicube of one shot (0 when rotation is off).
pub fn shot_angle(ctx: &RowContext, shooter: PatchId) -> f64 {
    if !ctx.params.hemicube_rotate {
        return 0.0;
    }
    let mut rng = Rng::new(hash_seed(&[ctx.params.seed, shooter.0 as u64, 0x4e3c]), 7);
    rng.next_f64() * std::f64::consts::TAU
}

/// `F_ij` from a hemicube at the shooter's centroid to every element `j` (indexed like
/// `mesh.elements`). Elements facing away block (one-sided scenes) or are skipped (their
/// other side is an element of its own in two-sided scenes); the shooter's own elements are
/// not drawn. Returns `None` when cancelled.
pub fn element_values(
    ctx: &RowContext,
    shooter: PatchId,
    table: &DeltaTable,
    cancel: &AtomicBool,
) -> Option<Vec<f64>> {
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    let angle = shot_angle(ctx, shooter);
    let mut cube = Hemicube::new(table, patch.centroid, patch.normal, angle, ctx.epsilon);
    let polys: Vec<(Vec<Local>, u32)> = element_ids(ctx, shooter)
        .into_iter()
        .zip(&mesh.elements)
        .filter(|(id, _)| *id != SKIP)
        .map(|(id, e)| (e.corners().iter().map(|c| cube.local(*c)).collect(), id))
        .collect();
    if cancel.load(Ordering::Relaxed) {
        return None;
    }
    cube.draw_many(&polys);
    let mut values = vec![0.0; mesh.elements.len()];
    cube.accumulate(&mut values);
    Some(values)
}

/// What each element is for a hemicube at the shooter: its own id (faces the shooter),
/// [`NONE`] (faces away in a one-sided scene: blocks) or [`SKIP`] (the shooter's own
/// elements; faces away in a two-sided scene, where its other side is an element of its own).
pub fn element_ids(ctx: &RowContext, shooter: PatchId) -> Vec<u32> {
    let patch = ctx.mesh.patch(shooter);
    ctx.mesh
        .elements
        .iter()
        .enumerate()
        .map(|(j, e)| {
            if e.patch == shooter {
                return SKIP;
            }
            let facing = (patch.centroid - e.centroid).dot(e.normal);
            if facing > ctx.epsilon {
                j as u32
            } else if ctx.scene.two_sided || facing > -ctx.epsilon {
                SKIP
            } else {
                NONE
            }
        })
        .collect()
}

/// `F_ij` from the shooter to every element like [`element_values`], rasterised by
/// `raster` (the GPU hemicube).
pub fn raster_element_values(
    ctx: &RowContext,
    raster: &dyn ItemBufferRaster,
    shooter: PatchId,
    table: &DeltaTable,
) -> Result<Vec<f64>, RasterError> {
    let mesh = ctx.mesh;
    let patch = mesh.patch(shooter);
    let view = HemicubeView {
        origin: patch.centroid,
        axes: hemicube_axes(patch.normal, shot_angle(ctx, shooter)),
        near: ctx.epsilon,
    };
    let ids = element_ids(ctx, shooter);
    let polygons = || mesh.elements.iter().map(|e| e.corners().to_vec()).collect();
    raster.form_factors(mesh.id, &polygons, &view, table, &ids, mesh.elements.len())
}

/// The `gpu-hemicube` row: [`row`] with the item buffer from `ctx.raster`. Without a
/// rasteriser, or when it fails (the error is printed once), the CPU hemicube computes it.
pub fn raster_row(
    ctx: &RowContext,
    shooter: PatchId,
    out: &mut [f32],
    cancel: &AtomicBool,
) -> bool {
    let table = DeltaTable::new(ctx.params.hemicube_res);
    let values = match ctx
        .raster
        .map(|r| raster_element_values(ctx, r, shooter, &table))
    {
        Some(Ok(v)) => v,
        Some(Err(e)) => {
            static WARNED: std::sync::Once = std::sync::Once::new();
            WARNED.call_once(|| eprintln!("warning: {e}; falling back to the CPU hemicube"));
            return row(ctx, shooter, out, cancel);
        }
        None => return row(ctx, shooter, out, cancel),
    };
    write_row(ctx, shooter, &values, out);
    !cancel.load(Ordering::Relaxed)
}

/// `out[j] = F_ji = F_ij A_i / A_j` from one hemicube at the shooter's centroid.
pub fn row(ctx: &RowContext, shooter: PatchId, out: &mut [f32], cancel: &AtomicBool) -> bool {
    let table = DeltaTable::new(ctx.params.hemicube_res);
    let Some(values) = element_values(ctx, shooter, &table, cancel) else {
        return false;
    };
    write_row(ctx, shooter, &values, out);
    !cancel.load(Ordering::Relaxed)
}

/// Reciprocity: `out[j] = F_ij A_i / A_j`.
fn write_row(ctx: &RowContext, shooter: PatchId, values: &[f64], out: &mut [f32]) {
    let area = ctx.mesh.patch(shooter).area;
    for ((o, v), e) in out.iter_mut().zip(values).zip(&ctx.mesh.elements) {
        *o = if e.area > 0.0 {
            (v * area / e.area) as f32
        } else {
            0.0
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formfactor::contour;

    #[test]
    fn delta_form_factors_sum_to_one_with_second_order_error() {
        let e64 = (DeltaTable::new(64).sum() - 1.0).abs();
        let e256 = (DeltaTable::new(256).sum() - 1.0).abs();
        eprintln!("|Σ − 1|: {e64:.3e} at 64, {e256:.3e} at 256");
        assert!(e64 < 1e-3, "{e64}");
        // Midpoint rule: 4× the resolution, about 16× smaller.
        assert!(e256 < e64 / 12.0 && e256 < 1e-4, "{e256} vs {e64}");
    }

    #[test]
    fn a_large_square_overhead_matches_lambert() {
        let table = DeltaTable::new(256);
        let sq = [
            DVec3::new(-0.3, -0.4, 1.0),
            DVec3::new(-0.3, 0.9, 1.0),
            DVec3::new(0.8, 0.9, 1.0),
            DVec3::new(0.8, -0.4, 1.0),
        ];
        let exact = contour::point_to_polygon(DVec3::ZERO, DVec3::Z, &sq);
        for angle in [0.0, 0.3, 1.1] {
            let mut h = Hemicube::new(&table, DVec3::ZERO, DVec3::Z, angle, 1e-9);
            h.draw(&sq, 0);
            let f = h.form_factor(0);
            // Boundary pixels: perimeter ≈ 4.8 units / pixel size 2/256, each ≤ its delta.
            assert!(
                (f - exact).abs() < 0.01 * exact,
                "angle {angle}: {f} vs {exact}"
            );
        }
    }

    #[test]
    fn the_nearer_polygon_wins_the_pixels() {
        let table = DeltaTable::new(64);
        let big = |z: f64| {
            [
                DVec3::new(-5.0, -5.0, z),
                DVec3::new(-5.0, 5.0, z),
                DVec3::new(5.0, 5.0, z),
                DVec3::new(5.0, -5.0, z),
            ]
        };
        let mut h = Hemicube::new(&table, DVec3::ZERO, DVec3::Z, 0.0, 1e-9);
        h.draw(&big(2.0), 1);
        h.draw(&big(1.0), 2);
        h.draw(&big(3.0), 3);
        assert_eq!(h.form_factor(1), 0.0);
        assert_eq!(h.form_factor(3), 0.0);
        let f = h.form_factor(2);
        let exact = contour::point_to_polygon(DVec3::ZERO, DVec3::Z, &big(1.0));
        assert!((f - exact).abs() < 0.01, "{f} vs {exact}");
    }
}
