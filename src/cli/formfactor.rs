//! `nusselt formfactor CASES.json --method M`: one JSON line per case.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;

use super::method::{MethodArgs, parse_method};
use nusselt_core::cases;
use nusselt_core::formfactor::FormFactorParams;

#[derive(Args, Debug)]
pub struct FormfactorArgs {
    /// JSON array of cases (A1/A2 polygons or point + point_normal, optional occluders).
    pub cases: PathBuf,
    /// Method: contour, exact, hemicube, raycast, montecarlo, hybrid or gpu-hemicube.
    #[arg(long, default_value = "contour")]
    pub method: String,
    /// Shadow rays per visibility estimate (contour and hybrid, when a case has occluders).
    #[arg(long, default_value_t = 256)]
    pub vis_rays: u32,
    /// Samples per case for raycast (rays) and montecarlo (point pairs).
    #[arg(long, default_value_t = 1 << 16)]
    pub rays: u32,
    /// Refinement levels of the cubature over A1 for exact with occluders.
    #[arg(long, default_value_t = FormFactorParams::default().cubature_depth)]
    pub cubature_depth: u32,
    #[command(flatten)]
    pub method_args: MethodArgs,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(args: &FormfactorArgs) -> Result<()> {
    let method = parse_method("--method", &args.method)?;
    super::check_count("--rays", args.rays, super::MAX_RAYS)?;
    super::check_count("--vis-rays", args.vis_rays, super::MAX_VIS_RAYS)?;
    args.method_args.check()?;
    let list = cases::load(&args.cases)?;
    let params = FormFactorParams {
        visibility_rays: args.vis_rays,
        probe_visibility: false,
        seed: args.seed,
        rays: args.rays,
        cubature_depth: args.cubature_depth.min(12),
        ..args.method_args.params()
    };
    let raster = super::method::raster_for(method)?;
    let mut stdout = std::io::stdout().lock();
    for case in &list {
        let start = Instant::now();
        let value = cases::evaluate_with(case, method, &params, raster.as_deref())
            .with_context(|| format!("{}: case '{}'", args.cases.display(), case.name))?;
        let seconds = start.elapsed().as_secs_f64();
        let line = serde_json::json!({"name": case.name, "method": method.name(), "value": value, "seconds": seconds});
        if writeln!(stdout, "{line}").is_err() {
            break; // The reader went away (e.g. `| head`): nothing more to say.
        }
    }
    Ok(())
}
