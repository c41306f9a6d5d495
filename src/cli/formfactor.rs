//! `nusselt formfactor CASES.json --method M`: one JSON line per case.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Result, anyhow};
use clap::Args;

use crate::formfactor::{FormFactorMethod, FormFactorParams, cases};

#[derive(Args, Debug)]
pub struct FormfactorArgs {
    /// JSON array of cases (A1/A2 polygons or point + point_normal, optional occluders).
    pub cases: PathBuf,
    /// Method: contour.
    #[arg(long, default_value = "contour")]
    pub method: String,
    /// Shadow rays per visibility estimate (used when a case has occluders).
    #[arg(long, default_value_t = 256)]
    pub vis_rays: u32,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(args: &FormfactorArgs) -> Result<()> {
    let method = FormFactorMethod::parse(&args.method).ok_or_else(|| {
        let names: Vec<_> = FormFactorMethod::ALL.iter().map(|m| m.name()).collect();
        anyhow!(
            "unknown --method '{}' (available: {})",
            args.method,
            names.join(", ")
        )
    })?;
    let list = cases::load(&args.cases)?;
    let params = FormFactorParams {
        visibility_rays: args.vis_rays,
        probe_visibility: false,
        seed: args.seed,
    };
    for case in &list {
        let start = Instant::now();
        let value = cases::evaluate(case, method, &params);
        let seconds = start.elapsed().as_secs_f64();
        println!(
            "{}",
            serde_json::json!({"name": case.name, "method": method.name(), "value": value, "seconds": seconds})
        );
    }
    Ok(())
}
