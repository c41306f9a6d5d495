//! Linear RGB images, their files (PFM, OpenEXR, PNG) and the image error measure.
//!
//! Row 0 is the top of the image in memory. PFM stores rows bottom-to-top (as the format
//! says); EXR stores linear values top-to-bottom; PNG is `exposure × radiance`, clamped,
//! then encoded with the sRGB transfer curve. Every file is written atomically
//! ([`atomic_write`]): a crash or a full disk never leaves a half-written image behind.
//!
//! The 8-bit helpers ([`srgb8`], [`Rgba8Image`] with [`crop`](Rgba8Image::crop) and
//! [`save_png`](Rgba8Image::save_png), [`atomic_write`]) are shared with the viewer's
//! screenshots and exports.

use std::io::Write;
use std::path::{Path, PathBuf};

use glam::DVec3;
use image::{ExtendedColorType, ImageEncoder as _};

#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at the top, linear radiance.
    pub pixels: Vec<DVec3>,
}

#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("cannot write {path}: {message}")]
    Write { path: String, message: String },
    #[error("cannot read {path}: {message}")]
    Read { path: String, message: String },
    #[error("unknown image extension in '{0}' (use .pfm, .exr or .png)")]
    Extension(String),
    #[error("images differ in size: {0}×{1} vs {2}×{3}")]
    Size(u32, u32, u32, u32),
}

impl Image {
    pub fn new(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![DVec3::ZERO; width as usize * height as usize],
        }
    }

    pub fn get(&self, x: u32, y: u32) -> DVec3 {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Writes by extension: `.pfm`, `.exr` (linear) or `.png` (exposure + sRGB).
    pub fn save(&self, path: &Path, exposure: f64) -> Result<(), ImageError> {
        let ext = check_extension(path)?;
        let err = |message: String| ImageError::Write {
            path: path.display().to_string(),
            message,
        };
        match ext.as_str() {
            "pfm" => {
                let mut bytes = format!("PF\n{} {}\n-1.0\n", self.width, self.height).into_bytes();
                for y in (0..self.height).rev() {
                    for x in 0..self.width {
                        for c in self.get(x, y).to_array() {
                            bytes.extend_from_slice(&(c as f32).to_le_bytes());
                        }
                    }
                }
                atomic_write(path, &bytes).map_err(|e| err(e.to_string()))
            }
            "exr" => {
                let w = self.width as usize;
                atomic_write_with(path, |tmp| {
                    exr::prelude::write_rgb_file(tmp, w, self.height as usize, |x, y| {
                        let p = self.pixels[y * w + x];
                        (p.x as f32, p.y as f32, p.z as f32)
                    })
                    .map_err(std::io::Error::other)
                })
                .map_err(|e| err(e.to_string()))
            }
            "png" => {
                let mut rgb = Vec::with_capacity(self.pixels.len() * 3);
                for p in &self.pixels {
                    let v = *p * exposure;
                    rgb.extend([srgb8(v.x), srgb8(v.y), srgb8(v.z)]);
                }
                let bytes = encode_png(&rgb, self.width, self.height, ExtendedColorType::Rgb8)
                    .map_err(err)?;
                atomic_write(path, &bytes).map_err(|e| err(e.to_string()))
            }
            _ => Err(ImageError::Extension(path.display().to_string())),
        }
    }

    /// Reads a PFM file (colour `PF` or grey `Pf`, either byte order).
    pub fn load_pfm(path: &Path) -> Result<Image, ImageError> {
        let bad = |m: &str| ImageError::Read {
            path: path.display().to_string(),
            message: m.to_string(),
        };
        let data = std::fs::read(path).map_err(|e| bad(&e.to_string()))?;
        let mut fields = Vec::new();
        let mut pos = 0;
        while fields.len() < 4 {
            while pos < data.len() && data[pos].is_ascii_whitespace() {
                pos += 1;
            }
            let start = pos;
            while pos < data.len() && !data[pos].is_ascii_whitespace() {
                pos += 1;
            }
            if start == pos {
                return Err(bad("truncated PFM header"));
            }
            fields.push(String::from_utf8_lossy(&data[start..pos]).into_owned());
        }
        pos += 1; // the single whitespace byte after the scale
        let channels = match fields[0].as_str() {
            "PF" => 3,
            "Pf" => 1,
            _ => return Err(bad("not a PFM file (no PF/Pf magic)")),
        };
        let width: u32 = fields[1].parse().map_err(|_| bad("bad width"))?;
        let height: u32 = fields[2].parse().map_err(|_| bad("bad height"))?;
        let scale: f64 = fields[3].parse().map_err(|_| bad("bad scale"))?;
        let little = scale < 0.0;
        let need = width as usize * height as usize * channels * 4;
        if width == 0 || height == 0 || data.len() < pos + need {
            return Err(bad("truncated PFM data"));
        }
        let mut img = Image::new(width, height);
        let mut at = pos;
        for y in (0..height).rev() {
            for x in 0..width {
                let mut c = [0f64; 3];
                for ck in c.iter_mut().take(channels) {
                    let b = [data[at], data[at + 1], data[at + 2], data[at + 3]];
                    at += 4;
                    *ck = if little {
                        f32::from_le_bytes(b)
                    } else {
                        f32::from_be_bytes(b)
                    } as f64;
                }
                if channels == 1 {
                    c = [c[0]; 3];
                }
                img.pixels[(y * width + x) as usize] = DVec3::from_array(c);
            }
        }
        Ok(img)
    }
}

/// The file types [`Image::save`] writes, by extension (lower case).
pub const IMAGE_EXTENSIONS: [&str; 3] = ["pfm", "exr", "png"];

/// The extension of `path` (lower case) when [`Image::save`] can write it, else the error
/// `save` would give: to check an output path before doing the work that fills it.
pub fn check_extension(path: &Path) -> Result<String, ImageError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if IMAGE_EXTENSIONS.contains(&ext.as_str()) {
        Ok(ext)
    } else {
        Err(ImageError::Extension(path.display().to_string()))
    }
}

/// Writes `bytes` to `path` atomically: into a temporary file in the same folder, synced,
/// then renamed over `path`. On failure the temporary file is removed and `path` is left
/// as it was.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    atomic_write_with(path, |tmp| {
        let mut f = std::fs::File::create(tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })
}

/// [`atomic_write`] for writers that want a path: `write` fills the temporary file.
fn atomic_write_with(
    path: &Path,
    write: impl FnOnce(&Path) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    // Hidden, per process, and ending in the target's extension (encoders may look at it).
    let tmp = dir.join(format!(".{}.tmp.{name}", std::process::id()));
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn encode_png(
    pixels: &[u8],
    width: u32,
    height: u32,
    color: ExtendedColorType,
) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(pixels, width, height, color)
        .map_err(|e| e.to_string())?;
    Ok(bytes)
}

/// A rectangle of pixels: `x`, `y` of its top-left corner (row 0 at the top) and its size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

impl PixelRect {
    /// The pixels of a rectangle given in logical points (`min`, `max` corners, as a UI
    /// lays out) on a screen of `pixels_per_point`: corners truncated to whole pixels (as
    /// egui's `ColorImage::region` does); negative or non-finite coordinates become 0.
    pub fn from_points(min: [f32; 2], max: [f32; 2], pixels_per_point: f32) -> PixelRect {
        let px = |v: f32| {
            let p = v * pixels_per_point;
            if p.is_finite() && p > 0.0 {
                p as u32
            } else {
                0
            }
        };
        let (x0, y0, x1, y1) = (px(min[0]), px(min[1]), px(max[0]), px(max[1]));
        PixelRect {
            x: x0,
            y: y0,
            width: x1.saturating_sub(x0),
            height: y1.saturating_sub(y0),
        }
    }
}

/// An 8-bit RGBA image, row-major, row 0 at the top (what a window screenshot gives).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rgba8Image {
    pub width: u32,
    pub height: u32,
    /// `4 × width × height` bytes.
    pub pixels: Vec<u8>,
}

impl Rgba8Image {
    /// The part of the image inside `rect`, clipped to the image (an empty image when they
    /// do not overlap): never panics on a rectangle that reaches past the edge.
    pub fn crop(&self, rect: PixelRect) -> Rgba8Image {
        let x0 = rect.x.min(self.width);
        let y0 = rect.y.min(self.height);
        let x1 = rect.x.saturating_add(rect.width).min(self.width);
        let y1 = rect.y.saturating_add(rect.height).min(self.height);
        let (w, h) = (x1 - x0, y1 - y0);
        let stride = self.width as usize * 4;
        let mut pixels = Vec::with_capacity(w as usize * h as usize * 4);
        for y in y0..y1 {
            let row = y as usize * stride;
            pixels.extend_from_slice(&self.pixels[row + x0 as usize * 4..row + x1 as usize * 4]);
        }
        Rgba8Image {
            width: w,
            height: h,
            pixels,
        }
    }

    /// Encodes the image as PNG and writes it atomically.
    pub fn save_png(&self, path: &Path) -> Result<(), ImageError> {
        let err = |message: String| ImageError::Write {
            path: path.display().to_string(),
            message,
        };
        if self.pixels.len() != self.width as usize * self.height as usize * 4 {
            return Err(err(format!(
                "{} bytes for a {}×{} RGBA image",
                self.pixels.len(),
                self.width,
                self.height
            )));
        }
        let bytes = encode_png(
            &self.pixels,
            self.width,
            self.height,
            ExtendedColorType::Rgba8,
        )
        .map_err(err)?;
        atomic_write(path, &bytes).map_err(|e| err(e.to_string()))
    }
}

/// Linear value (exposure applied) to 8-bit sRGB: clamped to [0, 1], the sRGB transfer
/// curve, rounded. NaN gives 0.
pub fn srgb8(linear: f64) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Relative RMS error √(Σ‖I − R‖²) / √(Σ‖R‖²) over pixels where `mask` is true.
pub fn relative_rms(image: &Image, reference: &Image, mask: &[bool]) -> Result<f64, ImageError> {
    if image.width != reference.width || image.height != reference.height {
        return Err(ImageError::Size(
            image.width,
            image.height,
            reference.width,
            reference.height,
        ));
    }
    let mut num = 0.0;
    let mut den = 0.0;
    for ((a, b), m) in image.pixels.iter().zip(&reference.pixels).zip(mask) {
        if *m {
            num += (*a - *b).length_squared();
            den += b.length_squared();
        }
    }
    Ok(if den > 0.0 { (num / den).sqrt() } else { 0.0 })
}

/// Luminance (linear) below which, at the 95th percentile, an image or a view counts as
/// dark: 0.01 is sRGB 25/255, a nearly black screen.
pub const DARK_LUMINANCE: f64 = 0.01;

/// Luminance a dark image's 95th percentile is brought to (sRGB 188/255).
pub const TARGET_LUMINANCE: f64 = 0.5;

/// Luminance above which, at the 95th percentile, an image or a view counts as burnt out
/// (most of it white at exposure 1: a light of `Ke` 1000 behind a door, lighting a room).
pub const BRIGHT_LUMINANCE: f64 = 2.0;

/// The exposure in stops that a scene needs to be seen, from its luminances (pixels or
/// vertices): `None` when nothing is lit; 0 when the 95th percentile is between
/// [`DARK_LUMINANCE`] and [`BRIGHT_LUMINANCE`]; else what brings it (or, with fewer than 1
/// in 20 lit, the brightest) to [`TARGET_LUMINANCE`], in half stops towards 0, within ±8.
/// Weak lights for the scene's size (glTF lights in photometric units, a millimetre model
/// lit by a 1 W point) otherwise give a black first view, strong ones a white one.
pub fn auto_exposure_stops(mut luminance: Vec<f64>) -> Option<f64> {
    luminance.retain(|l| l.is_finite());
    let max = luminance.iter().copied().fold(0.0, f64::max);
    if max <= 0.0 {
        return None;
    }
    let k = ((luminance.len() as f64 * 0.95) as usize).min(luminance.len() - 1);
    let p95 = *luminance.select_nth_unstable_by(k, f64::total_cmp).1;
    if (DARK_LUMINANCE..=BRIGHT_LUMINANCE).contains(&p95) {
        return Some(0.0);
    }
    let level = if p95 > 0.0 { p95 } else { max };
    Some(
        ((TARGET_LUMINANCE / level).log2() * 2.0)
            .trunc()
            .clamp(-16.0, 16.0)
            / 2.0,
    )
}

/// Relative luminance (Rec. 709) of each pixel.
pub fn luminance(image: &Image) -> Vec<f64> {
    image
        .pixels
        .iter()
        .map(|p| 0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_round_trips_with_rows_bottom_to_top() {
        let mut img = Image::new(3, 2);
        img.pixels[0] = DVec3::new(1.0, 2.0, 3.0); // top-left
        img.pixels[5] = DVec3::new(0.5, 0.25, 0.125); // bottom-right
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("a.pfm");
        img.save(&p, 1.0).expect("save");
        let bytes = std::fs::read(&p).expect("read");
        // The first stored pixel is the bottom-left one.
        let header = b"PF\n3 2\n-1.0\n".len();
        assert_eq!(
            f32::from_le_bytes(bytes[header..header + 4].try_into().expect("4")),
            0.0
        );
        assert_eq!(Image::load_pfm(&p).expect("load"), img);
    }

    #[test]
    fn relative_rms_is_zero_for_equal_and_scales() {
        let mut a = Image::new(2, 1);
        a.pixels = vec![DVec3::ONE, DVec3::splat(2.0)];
        let mut b = a.clone();
        let mask = [true, true];
        assert_eq!(relative_rms(&a, &b, &mask).expect("same size"), 0.0);
        b.pixels.iter_mut().for_each(|p| *p *= 1.1);
        let e = relative_rms(&a, &b, &mask).expect("same size");
        assert!((e - 0.1 / 1.1).abs() < 1e-12);
        assert!(relative_rms(&a, &Image::new(1, 1), &mask).is_err());
    }

    #[test]
    fn srgb_curve_endpoints() {
        assert_eq!(srgb8(0.0), 0);
        assert_eq!(srgb8(1.0), 255);
        assert_eq!(srgb8(0.5), 188);
        // IEC 61966-2-1: linear 0.18 (18 % grey) encodes to 0.4614 → 118; the linear
        // segment below 0.0031308: 0.001 → 12.92 × 0.001 × 255 = 3.29 → 3.
        assert_eq!(srgb8(0.18), 118);
        assert_eq!(srgb8(0.001), 3);
        assert_eq!(srgb8(-1.0), 0);
        assert_eq!(srgb8(7.0), 255);
        assert_eq!(srgb8(f64::NAN), 0);
    }

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("a.png");
        std::fs::write(&p, b"old").expect("write");
        atomic_write(&p, b"new").expect("atomic");
        assert_eq!(std::fs::read(&p).expect("read"), b"new");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .expect("dir")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.png")]);
        // A folder that does not exist: an error, and nothing left behind.
        assert!(atomic_write(&dir.path().join("no/such/x.png"), b"x").is_err());
        // A failed encoder leaves the old file and no temporary.
        let failed = atomic_write_with(&p, |tmp| {
            std::fs::write(tmp, b"half")?;
            Err(std::io::Error::other("encoder failed"))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read(&p).expect("read"), b"new");
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 1);
    }

    #[test]
    fn crop_takes_the_rectangle_and_clips_at_the_edges() {
        // 3 × 2 image whose pixel (x, y) holds [x, y, 7, 255].
        let (w, h) = (3u32, 2u32);
        let pixels = (0..h)
            .flat_map(|y| (0..w).flat_map(move |x| [x as u8, y as u8, 7, 255]))
            .collect();
        let img = Rgba8Image {
            width: w,
            height: h,
            pixels,
        };
        let rect = PixelRect {
            x: 1,
            y: 1,
            width: 2,
            height: 1,
        };
        let c = img.crop(rect);
        assert_eq!((c.width, c.height), (2, 1));
        assert_eq!(c.pixels, vec![1, 1, 7, 255, 2, 1, 7, 255]);
        // Reaching past the right and bottom edges: clipped, no panic.
        let past = img.crop(PixelRect {
            x: 2,
            y: 0,
            width: 10,
            height: 10,
        });
        assert_eq!((past.width, past.height), (1, 2));
        assert_eq!(past.pixels, vec![2, 0, 7, 255, 2, 1, 7, 255]);
        // Outside altogether: empty.
        let none = img.crop(PixelRect {
            x: 5,
            y: 5,
            width: 1,
            height: 1,
        });
        assert_eq!((none.width, none.height, none.pixels.len()), (0, 0, 0));
        // Logical points on a 2× screen: truncated corners, like egui's region.
        let r = PixelRect::from_points([0.5, 0.0], [1.4, 1.0], 2.0);
        assert_eq!(
            r,
            PixelRect {
                x: 1,
                y: 0,
                width: 1,
                height: 2
            }
        );
        assert_eq!(
            PixelRect::from_points([-3.0, f32::NAN], [1.0, 1.0], 1.0).x,
            0
        );
    }

    #[test]
    fn png_round_trips_through_the_decoder() {
        let dir = tempfile::tempdir().expect("tempdir");
        let p = dir.path().join("c.png");
        let img = Rgba8Image {
            width: 2,
            height: 1,
            pixels: vec![255, 0, 0, 255, 0, 0, 255, 128],
        };
        img.save_png(&p).expect("save");
        let back = image::open(&p).expect("decode").to_rgba8();
        assert_eq!((back.width(), back.height()), (2, 1));
        assert_eq!(back.into_raw(), img.pixels);
        let bad = Rgba8Image {
            width: 2,
            height: 2,
            pixels: vec![0; 4],
        };
        assert!(bad.save_png(&p).is_err());
        // The linear image's PNG: exposure, then the sRGB curve.
        let mut lin = Image::new(1, 1);
        lin.pixels[0] = DVec3::new(0.09, 0.5, 2.0);
        let q = dir.path().join("l.png");
        lin.save(&q, 2.0).expect("save");
        let px = image::open(&q).expect("decode").to_rgb8().into_raw();
        assert_eq!(px, vec![srgb8(0.18), 255, 255]);
        // EXR goes through a temporary too and reads back.
        let e = dir.path().join("l.exr");
        lin.save(&e, 1.0).expect("exr");
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 3);
    }
}
