//! `nusselt bench --only meshing`: the Cornell box's image error against its element count
//! for the three ways of placing elements: uniform (`--max-elements N`), adaptive
//! (`--adaptive TOL`, two passes from a coarse budget) and discontinuity meshing
//! (`--discontinuity`), each rendered interpolated and with the direct pass, against the
//! path-traced reference. Writes `meshing.csv` and the plot `cornell_meshing.{png,svg}`.

use std::io::Write;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{Context, Result};

use nusselt_core::mesh::MeshSpec;
use nusselt_core::render::{self, Image, RenderSettings};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{SolverConfig, StopCriteria, run_solver};

use super::bench_images::render_elements;
use super::plot::{self, Plot, Series};

/// One measured mesh: kind, label, elements, whole seconds and error interpolated, and with
/// the direct pass.
struct Row {
    kind: &'static str,
    label: String,
    elements: usize,
    vertex: (f64, f64),
    direct: (f64, f64),
}

/// What every mesh is measured against, and how it is rendered.
struct Setup {
    scene: Scene,
    reference: Image,
    mask: Vec<bool>,
    settings: RenderSettings,
}

pub fn meshing(out: &Path, reference_path: &Path) -> Result<()> {
    let reference = Image::load_pfm(reference_path)
        .with_context(|| format!("meshing: the reference {}", reference_path.display()))?;
    let scene = Scene::builtin("cornell", &LoadOptions::default())?;
    let camera = render::view::default_camera(&scene);
    let mask = render::error_mask(&scene, &camera, reference.width, reference.height);
    let settings = RenderSettings {
        width: reference.width,
        height: reference.height,
        spp: 16,
        camera,
        seed: 1,
        edge_spp: nusselt_core::render::DEFAULT_EDGE_SPP,
    };
    let setup = Setup {
        scene,
        reference,
        mask,
        settings,
    };
    let rows = measure_all(&setup)?;
    write_csv_and_table(out, &rows)?;
    write_plot(out, &rows)
}

/// One mesh solved to the default stop, then rendered interpolated and by the direct pass;
/// seconds are whole (start, mesh, solve, render).
fn measure(
    setup: &Setup,
    kind: &'static str,
    label: String,
    config: SolverConfig,
    adaptive: Option<f64>,
) -> Result<Row> {
    let (reference, mask, settings) = (&setup.reference, &setup.mask, &setup.settings);
    eprintln!("meshing: {kind} {label}…");
    let start = Instant::now();
    let mut s = super::bench_images::meshed(&setup.scene, config, adaptive)?;
    run_solver(
        s.as_mut(),
        &StopCriteria::default(),
        &AtomicBool::new(false),
        &mut |_, _| {},
    );
    let solved = start.elapsed().as_secs_f64();
    let radiance = s.display_radiance();
    let bvh = render::display_bvh(&setup.scene, &s.problem().mesh);
    let image = render_elements(s.problem(), &radiance, &bvh, settings.spp);
    let vertex = (
        start.elapsed().as_secs_f64(),
        render::relative_rms(&image, reference, mask)?,
    );
    let t = Instant::now();
    let image = render::direct::render_solution(s.problem(), &radiance, settings);
    let direct = (
        solved + t.elapsed().as_secs_f64(),
        render::relative_rms(&image, reference, mask)?,
    );
    Ok(Row {
        kind,
        label,
        elements: s.problem().mesh.elements.len(),
        vertex,
        direct,
    })
}

/// Uniform and discontinuity meshes at each budget, then adaptive meshes from coarser ones.
fn measure_all(setup: &Setup) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    for budget in [2_500, 5_000, 10_000, 20_000, 40_000] {
        for (kind, discontinuity) in [("uniform", false), ("discontinuity", true)] {
            let config = SolverConfig {
                mesh: MeshSpec {
                    max_elements: Some(budget),
                    discontinuity,
                    ..Default::default()
                },
                ..Default::default()
            };
            rows.push(measure(
                setup,
                kind,
                format!("budget {budget}"),
                config,
                None,
            )?);
        }
    }
    for (budget, tolerance) in [
        (1_250, 0.1),
        (2_500, 0.1),
        (5_000, 0.15),
        (6_000, 0.15),
        (8_000, 0.2),
        (5_000, 0.1),
        (10_000, 0.15),
        (5_000, 0.05),
    ] {
        let config = SolverConfig {
            mesh: MeshSpec {
                max_elements: Some(budget),
                ..Default::default()
            },
            ..Default::default()
        };
        let label = format!("budget {budget}, --adaptive {tolerance}");
        rows.push(measure(setup, "adaptive", label, config, Some(tolerance))?);
    }
    Ok(rows)
}

/// `meshing.csv`, and the same rows as a table on stdout.
fn write_csv_and_table(out: &Path, rows: &[Row]) -> Result<()> {
    let path = out.join("meshing.csv");
    let mut csv = std::io::BufWriter::new(super::bench::csv_file(
        &path,
        "kind,setting,elements,seconds,error,seconds_direct,error_direct",
    )?);
    println!(
        "\n| meshing | setting | elements | s | error | s, direct pass | error, direct pass |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|");
    for r in rows {
        writeln!(
            csv,
            "{},{},{},{:.3},{:.5},{:.3},{:.5}",
            r.kind, r.label, r.elements, r.vertex.0, r.vertex.1, r.direct.0, r.direct.1
        )?;
        println!(
            "| {} | {} | {} | {:.2} | {:.2} % | {:.2} | {:.2} % |",
            r.kind,
            r.label,
            r.elements,
            r.vertex.0,
            100.0 * r.vertex.1,
            r.direct.0,
            100.0 * r.direct.1
        );
    }
    csv.flush()?;
    Ok(())
}

/// `cornell_meshing.{svg,png}`: error against elements, each kind interpolated and with the
/// direct pass.
fn write_plot(out: &Path, rows: &[Row]) -> Result<()> {
    let series = |kind: &str, direct: bool| -> Series {
        Series {
            label: format!("{kind}{}", if direct { " + direct pass" } else { "" }),
            points: rows
                .iter()
                .filter(|r| r.kind == kind)
                .map(|r| {
                    let (_, e) = if direct { r.direct } else { r.vertex };
                    (r.elements as f64, e)
                })
                .collect(),
            markers: kind == "adaptive",
        }
    };
    plot::write(
        &out.join("cornell_meshing"),
        &Plot {
            title: "Cornell box: image error against elements, by meshing",
            x_label: "elements",
            y_label: "relative RMS image error",
            series: ["uniform", "adaptive", "discontinuity"]
                .into_iter()
                .flat_map(|k| [series(k, false), series(k, true)])
                .collect(),
        },
    )?;
    Ok(())
}
