//! The form-factor method flags shared by `render`, `view` and `formfactor`: the method's
//! name and the hemicube and hybrid parameters.

use std::sync::Arc;

use anyhow::{Context, Result, anyhow, bail};
use clap::Args;

use nusselt_core::formfactor::hemicube::ItemBufferRaster;
use nusselt_core::formfactor::{FormFactorMethod, FormFactorParams};

/// Parameters of the hemicube and hybrid methods, shared by `render` and `formfactor`.
#[derive(Args, Debug, Clone)]
pub struct MethodArgs {
    /// Hemicube resolution: pixels across the top face (hemicube, hybrid).
    #[arg(long, default_value_t = 256)]
    pub hemicube_res: u32,
    /// Keep every hemicube in the same orientation (no random rotation about the normal).
    #[arg(long)]
    pub no_hemicube_rotate: bool,
    /// Hybrid: receivers within K radii of the shooter are computed analytically.
    #[arg(long, allow_negative_numbers = true, default_value_t = FormFactorParams::default().hybrid_k)]
    pub hybrid_k: f64,
    /// Hybrid: receivers expected to cover fewer hemicube pixels than this are analytic.
    #[arg(long, allow_negative_numbers = true, default_value_t = FormFactorParams::default().hybrid_min_pixels)]
    pub hybrid_min_pixels: f64,
    /// Contour: up to this many blockers between a point and a patch have their shadows
    /// clipped away exactly; more are sampled with shadow rays (0: always sample).
    #[arg(long, default_value_t = FormFactorParams::default().exact_blockers)]
    pub exact_blockers: usize,
}

impl MethodArgs {
    pub fn check(&self) -> Result<()> {
        if !(2..=8192).contains(&self.hemicube_res) {
            bail!("--hemicube-res must be in 2..=8192");
        }
        if !(self.hybrid_k.is_finite() && self.hybrid_k >= 0.0) {
            bail!("--hybrid-k must be a number >= 0");
        }
        if !(self.hybrid_min_pixels.is_finite() && self.hybrid_min_pixels >= 0.0) {
            bail!("--hybrid-min-pixels must be a number >= 0");
        }
        Ok(())
    }

    /// Default parameters with these fields set.
    pub fn params(&self) -> FormFactorParams {
        FormFactorParams {
            hemicube_res: self.hemicube_res,
            hemicube_rotate: !self.no_hemicube_rotate,
            hybrid_k: self.hybrid_k,
            hybrid_min_pixels: self.hybrid_min_pixels,
            exact_blockers: self.exact_blockers,
            ..Default::default()
        }
    }
}

/// The GPU hemicube when `method` needs it (opening the device), else `None`.
pub fn raster_for(method: FormFactorMethod) -> Result<Option<Arc<dyn ItemBufferRaster>>> {
    if method != FormFactorMethod::GpuHemicube {
        return Ok(None);
    }
    let gpu = nusselt_gpu::GpuHemicube::new().context("--formfactor gpu-hemicube")?;
    Ok(Some(Arc::new(gpu)))
}

/// Parses a method name with the library's parser; the message names the flag.
pub fn parse_method(flag: &str, name: &str) -> Result<FormFactorMethod> {
    name.parse::<FormFactorMethod>().map_err(|_| {
        anyhow!(
            "unknown {flag} '{name}' (available: {})",
            FormFactorMethod::names()
        )
    })
}
