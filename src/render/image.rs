//! Linear RGB images, their files (PFM, OpenEXR, PNG) and the image error measure.
//!
//! Row 0 is the top of the image in memory. PFM stores rows bottom-to-top (as the format
//! says); EXR stores linear values top-to-bottom; PNG is `exposure × radiance`, clamped,
//! then encoded with the sRGB transfer curve.

use std::io::Write;
use std::path::Path;

use glam::DVec3;

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
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
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
                write_atomic(path, &bytes).map_err(|e| err(e.to_string()))
            }
            "exr" => {
                let w = self.width as usize;
                exr::prelude::write_rgb_file(path, w, self.height as usize, |x, y| {
                    let p = self.pixels[y * w + x];
                    (p.x as f32, p.y as f32, p.z as f32)
                })
                .map_err(|e| err(e.to_string()))
            }
            "png" => {
                let mut buf = image::RgbImage::new(self.width, self.height);
                for (i, p) in buf.pixels_mut().enumerate() {
                    let v = self.pixels[i] * exposure;
                    *p = image::Rgb([srgb8(v.x), srgb8(v.y), srgb8(v.z)]);
                }
                buf.save(path).map_err(|e| err(e.to_string()))
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

fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let tmp = path.with_extension("tmp~");
    {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
    }
    std::fs::rename(&tmp, path)
}

/// Linear value to 8-bit sRGB.
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
    }
}
