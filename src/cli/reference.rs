//! `nusselt reference` (the path-traced reference image) and `nusselt compare` (an image's
//! error against a reference, with the render's pixel mask).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Args;

use super::render::{bar, check_image_out};
use super::{SceneArgs, ViewArgs};
use nusselt_core::render::{self, Image};

#[derive(Args, Debug)]
pub struct ReferenceArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub view: ViewArgs,
    /// Output image (.pfm recommended).
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[arg(long, allow_negative_numbers = true, default_value_t = 1.0)]
    pub exposure: f64,
    #[arg(long)]
    pub quiet: bool,
}

pub fn run_reference(args: &ReferenceArgs) -> Result<()> {
    check_image_out(&args.out)?;
    if !(args.exposure.is_finite() && args.exposure > 0.0) {
        bail!("--exposure must be a positive number");
    }
    let scene = args.scene.load()?;
    let settings = args.view.settings(&scene, args.seed)?;
    let start = Instant::now();
    let pb = bar(
        args.quiet,
        settings.height as u64,
        "path tracing {bar:40} {pos}/{len} rows [{elapsed} / ~{duration}]",
    );
    let image =
        render::pathtrace::reference(&scene, &settings, &|rows| pb.set_position(rows as u64));
    pb.finish_and_clear();
    image.save(&args.out, args.exposure)?;
    if !args.quiet {
        eprintln!(
            "{} spp at {}×{} in {:.1} s; wrote {}",
            settings.spp,
            settings.width,
            settings.height,
            start.elapsed().as_secs_f64(),
            args.out.display()
        );
    }
    Ok(())
}

#[derive(Args, Debug)]
pub struct CompareArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Camera (as for render); the image size comes from the images.
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// The image to judge (PFM).
    #[arg(long)]
    pub image: PathBuf,
    /// The reference (PFM).
    #[arg(long)]
    pub reference: PathBuf,
}

/// Prints `{"error": …, "pixels": …}`: the relative RMS over the pixels that see neither a
/// light nor the background (the mask `render --reference` uses).
pub fn run_compare(args: &CompareArgs) -> Result<()> {
    let scene = args.scene.load()?;
    let image = Image::load_pfm(&args.image)?;
    let reference = Image::load_pfm(&args.reference)?;
    let camera = match &args.camera {
        Some(text) => nusselt_core::scene::Camera::parse(text).context("--camera")?,
        None => nusselt_core::render::view::default_camera(&scene),
    };
    let mask = render::error_mask(&scene, &camera, reference.width, reference.height);
    let error = render::relative_rms(&image, &reference, &mask)?;
    let pixels = mask.iter().filter(|m| **m).count();
    println!("{}", serde_json::json!({"error": error, "pixels": pixels}));
    Ok(())
}
