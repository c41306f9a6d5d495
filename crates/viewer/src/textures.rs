//! The scene's diffuse maps made ready for the GPU, off the UI thread: one layer of a 2-D
//! texture array per map, all resized to one square power-of-two size, with a box-filtered
//! mip chain, as linear `Rgba16Float` texels (the core's [`Texture`] holds linear values,
//! so the GPU must not decode them as sRGB again).
//!
//! Layers are resized, not packed into an atlas: the sampler repeats in normalised
//! coordinates, so a stretched layer wraps exactly like the original image, which an atlas
//! tile would not. The layer size is the largest map's longer side (a power of two, at
//! most [`MAX_LAYER_SIZE`]), halved until the whole array fits [`GPU_BUDGET`].

use glam::DVec2;
use rayon::prelude::*;

use std::sync::{Arc, Mutex};

use nusselt_core::scene::{Material, Scene, texture::Texture};

/// Largest side of a layer.
pub const MAX_LAYER_SIZE: u32 = 1024;
/// Most layers (wgpu's default `max_texture_array_layers`); maps beyond it are drawn
/// untextured.
pub const MAX_LAYERS: usize = 256;
/// Most bytes the texture array may take on the GPU, mips included.
pub const GPU_BUDGET: usize = 256 << 20;
/// Bytes per texel of `Rgba16Float`.
pub const TEXEL_BYTES: usize = 8;

/// Per texture of [`Scene::textures`], its layer in the array: the textures some material
/// uses as its diffuse map, in texture order, up to [`MAX_LAYERS`]. Alpha-only maps get
/// none (they do not change the colour).
pub fn diffuse_layers(scene: &Scene) -> Vec<Option<u32>> {
    layers_of(scene.textures.len(), &scene.materials)
}

/// [`diffuse_layers`] of `textures` maps used by `materials`.
fn layers_of(textures: usize, materials: &[Material]) -> Vec<Option<u32>> {
    let mut used = vec![false; textures];
    for m in materials {
        if let Some(id) = m.diffuse_map
            && let Some(u) = used.get_mut(id.0 as usize)
        {
            *u = true;
        }
    }
    let mut next = 0u32;
    used.iter()
        .map(|&u| {
            (u && (next as usize) < MAX_LAYERS).then(|| {
                next += 1;
                next - 1
            })
        })
        .collect()
}

/// The texture array's contents.
#[derive(Debug)]
pub struct TextureLayers {
    /// Side of every layer at mip level 0.
    pub size: u32,
    pub layers: u32,
    /// Mip levels (size, size/2, …, 1).
    pub mip_levels: u32,
    /// Per mip level, all layers' texels one after another (top row first), as `f16` bits;
    /// taken by the upload ([`TextureLayers::take_mips`]), so the CPU copy (257 MB for the
    /// Crytek atrium) is not kept beside the GPU's.
    mips: Mutex<Vec<Vec<u16>>>,
}

impl TextureLayers {
    /// The scene's diffuse maps as layers; `None` when it has none.
    pub fn build(scene: &Scene) -> Option<TextureLayers> {
        Self::build_from(&scene.textures, &scene.materials)
    }

    /// [`TextureLayers::build`] from a scene's texture maps and materials (what a thread
    /// of its own needs of the scene).
    pub fn build_from(textures: &[Arc<Texture>], materials: &[Material]) -> Option<TextureLayers> {
        let layer_of = layers_of(textures.len(), materials);
        let maps: Vec<&Texture> = textures
            .iter()
            .zip(&layer_of)
            .filter(|(_, l)| l.is_some())
            .map(|(t, _)| t.as_ref())
            .collect();
        if maps.is_empty() {
            return None;
        }
        let size = layer_size(&maps);
        let alphas = alpha_sources(textures, materials, &layer_of);
        // Each layer's `f32` chain is turned into `f16` as soon as it is made, and each
        // level moved into the array as it is gathered: the `f32` copy of the whole array
        // (twice the `f16` one: 514 MB for the Crytek atrium) never exists at once.
        let mut per_layer: Vec<Vec<Vec<u16>>> = maps
            .par_iter()
            .zip(&alphas)
            .map(|(t, a)| {
                mip_chain(resample(&level0(t, *a), t.width, t.height, size), size)
                    .into_iter()
                    .map(|level| {
                        level
                            .iter()
                            .flatten()
                            .map(|&c| half::f16::from_f32(c).to_bits())
                            .collect()
                    })
                    .collect()
            })
            .collect();
        let mip_levels = per_layer[0].len() as u32;
        let mips: Vec<Vec<u16>> = (0..mip_levels as usize)
            .map(|k| {
                let mut level = Vec::with_capacity(per_layer.iter().map(|l| l[k].len()).sum());
                for layer in &mut per_layer {
                    level.extend_from_slice(&std::mem::take(&mut layer[k]));
                }
                level
            })
            .collect();
        Some(TextureLayers {
            size,
            layers: maps.len() as u32,
            mip_levels,
            mips: Mutex::new(mips),
        })
    }

    /// Bytes of the array on the GPU (all layers and mips).
    pub fn gpu_bytes(&self) -> usize {
        array_bytes(self.size, self.layers as usize)
    }

    /// The texels, per mip level, for the one upload of this array; empty afterwards.
    pub fn take_mips(&self) -> Vec<Vec<u16>> {
        std::mem::take(&mut *self.mips.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// A copy of the texels not yet taken (for tests and checks).
    pub fn mips(&self) -> Vec<Vec<u16>> {
        self.mips.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

/// Bytes of `layers` layers of side `size` with their mips.
fn array_bytes(size: u32, layers: usize) -> usize {
    let mut texels = 0usize;
    let mut s = size as usize;
    loop {
        texels += s * s;
        if s == 1 {
            break;
        }
        s /= 2;
    }
    texels * TEXEL_BYTES * layers
}

/// The layer side for these maps (see the module docs).
fn layer_size(maps: &[&Texture]) -> u32 {
    let longest = maps
        .iter()
        .map(|t| t.width.max(t.height))
        .max()
        .unwrap_or(1);
    let mut size = longest.next_power_of_two().min(MAX_LAYER_SIZE);
    while size > 1 && array_bytes(size, maps.len()) > GPU_BUDGET {
        size /= 2;
    }
    size
}

/// Per layer, the alpha map (`map_d`) of a material that uses the layer's texture as its
/// diffuse map: the layer's alpha is read from it, so the shader can discard the holes of
/// a cut-out (the first such material's map when several differ).
fn alpha_sources<'a>(
    textures: &'a [Arc<Texture>],
    materials: &[Material],
    layer_of: &[Option<u32>],
) -> Vec<Option<&'a Texture>> {
    let mut out = vec![None; layer_of.iter().flatten().count()];
    for m in materials {
        if let (Some(d), Some(a)) = (m.diffuse_map, m.alpha_map)
            && let Some(Some(layer)) = layer_of.get(d.0 as usize)
            && let Some(t) = textures.get(a.0 as usize)
        {
            out[*layer as usize].get_or_insert(t.as_ref());
        }
    }
    out
}

/// The texture's full-resolution texels, top row first, with the alpha of `alpha` (read at
/// the same texture coordinates) when given. The core's bilinear sample at a texel's
/// centre is that texel exactly.
fn level0(t: &Texture, alpha: Option<&Texture>) -> Vec<[f32; 4]> {
    let (w, h) = (t.width, t.height);
    let mut out = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h {
        for x in 0..w {
            let uv = DVec2::new(
                (x as f64 + 0.5) / w as f64,
                1.0 - (y as f64 + 0.5) / h as f64,
            );
            let mut texel = t.sample(uv);
            if let Some(a) = alpha {
                texel[3] = a.sample(uv)[3];
            }
            out.push(texel.map(|c| c as f32));
        }
    }
    out
}

/// One row of `n` values resampled to `m`, repeating: a box filter when shrinking (each
/// output texel is the mean of the input it covers), linear when enlarging.
fn resample_row(src: &[[f32; 4]], m: usize, out: &mut Vec<[f32; 4]>) {
    let n = src.len();
    if m == n {
        out.extend_from_slice(src);
        return;
    }
    let add = |acc: &mut [f32; 4], c: [f32; 4], w: f32| {
        for k in 0..4 {
            acc[k] += c[k] * w;
        }
    };
    let scale = n as f64 / m as f64;
    for i in 0..m {
        let mut acc = [0.0f32; 4];
        if m < n {
            let (a, b) = (i as f64 * scale, (i + 1) as f64 * scale);
            let mut x = a.floor();
            while x < b {
                let w = (b.min(x + 1.0) - a.max(x)) / scale;
                add(&mut acc, src[(x as usize).min(n - 1)], w as f32);
                x += 1.0;
            }
        } else {
            let x = (i as f64 + 0.5) * scale - 0.5;
            let x0 = x.floor();
            let f = (x - x0) as f32;
            let at = |k: f64| src[(k as i64).rem_euclid(n as i64) as usize];
            add(&mut acc, at(x0), 1.0 - f);
            add(&mut acc, at(x0 + 1.0), f);
        }
        out.push(acc);
    }
}

/// A `w` × `h` image resampled to `size` × `size`, rows then columns.
fn resample(src: &[[f32; 4]], w: u32, h: u32, size: u32) -> Vec<[f32; 4]> {
    let (w, h, s) = (w as usize, h as usize, size as usize);
    let mut rows = Vec::with_capacity(s * h);
    for r in src.chunks_exact(w) {
        resample_row(r, s, &mut rows);
    }
    let mut out = vec![[0.0f32; 4]; s * s];
    let mut column = Vec::with_capacity(h);
    let mut resized = Vec::with_capacity(s);
    for x in 0..s {
        column.clear();
        column.extend((0..h).map(|y| rows[y * s + x]));
        resized.clear();
        resample_row(&column, s, &mut resized);
        for (y, c) in resized.iter().enumerate() {
            out[y * s + x] = *c;
        }
    }
    out
}

/// A square power-of-two image and its 2 × 2 box halvings down to 1 × 1.
fn mip_chain(base: Vec<[f32; 4]>, size: u32) -> Vec<Vec<[f32; 4]>> {
    let mut levels = vec![base];
    let mut s = size as usize;
    while s > 1 {
        let prev = levels.last().expect("level 0");
        let h = s / 2;
        let next = (0..h * h)
            .map(|i| {
                let (x, y) = (2 * (i % h), 2 * (i / h));
                let t = [
                    prev[y * s + x],
                    prev[y * s + x + 1],
                    prev[(y + 1) * s + x],
                    prev[(y + 1) * s + x + 1],
                ];
                std::array::from_fn(|c| 0.25 * (t[0][c] + t[1][c] + t[2][c] + t[3][c]))
            })
            .collect();
        levels.push(next);
        s = h;
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mean(t: &[[f32; 4]]) -> [f64; 4] {
        let mut m = [0.0; 4];
        for c in t {
            for k in 0..4 {
                m[k] += c[k] as f64 / t.len() as f64;
            }
        }
        m
    }

    #[test]
    fn level0_reads_the_texels_back() {
        let texels: Vec<[f32; 4]> = (0..12).map(|i| [i as f32 / 12.0, 0.5, 0.0, 1.0]).collect();
        let t = Texture::from_linear(4, 3, texels.clone());
        for (a, b) in level0(&t, None).iter().zip(&texels) {
            for k in 0..4 {
                assert!((a[k] - b[k]).abs() < 1e-6, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn resizing_keeps_the_mean_and_mips_end_at_it() {
        // A 6 × 3 ramp, shrunk across and stretched down to 4 × 4: the box filter keeps the
        // mean of every row exactly; linear enlarging with wrap keeps a column's mean too.
        let src: Vec<[f32; 4]> = (0..18)
            .map(|i| [(i % 6) as f32, (i / 6) as f32, 1.0, 1.0])
            .collect();
        let out = resample(&src, 6, 3, 4);
        assert_eq!(out.len(), 16);
        let (a, b) = (mean(&src), mean(&out));
        for k in 0..4 {
            assert!(
                (a[k] - b[k]).abs() < 1e-5,
                "channel {k}: {} vs {}",
                a[k],
                b[k]
            );
        }
        let chain = mip_chain(out, 4);
        assert_eq!(chain.len(), 3);
        assert_eq!(chain[2].len(), 1);
        for k in 0..4 {
            assert!((chain[2][0][k] as f64 - a[k]).abs() < 1e-5);
        }
    }

    #[test]
    fn the_layer_size_fits_the_budget() {
        let big = Texture::from_linear(4096, 1, vec![[0.5; 4]; 4096]);
        let small = Texture::from_linear(100, 60, Vec::new());
        assert_eq!(layer_size(&[&small]), 128);
        assert_eq!(layer_size(&[&big]), MAX_LAYER_SIZE);
        let many: Vec<&Texture> = std::iter::repeat_n(&big, 40).collect();
        let s = layer_size(&many);
        assert!(array_bytes(s, 40) <= GPU_BUDGET && array_bytes(2 * s, 40) > GPU_BUDGET);
        assert_eq!(array_bytes(2, 1), (4 + 1) * TEXEL_BYTES);
    }
}
