//! `render --export-gltf`: the solved mesh, lit, as glTF 2.0 (`nusselt_core::export::gltf`).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};

use nusselt_core::export::{BakedMesh, GltfFormat, GltfInput, write_gltf};
use nusselt_core::scene::Rgb;
use nusselt_core::solver::Problem;

/// The flag's checks, made before any work: a `.glb` or `.gltf` path in a folder that exists.
pub fn check_gltf_out(path: &Path) -> Result<()> {
    GltfFormat::from_path(path).context("--export-gltf")?;
    super::check_output("--export-gltf", path)
}

/// Writes `problem`'s mesh lit by `radiance` (per element, as displayed) to `path`, with
/// `COLOR_0` at `exposure`; prints one line (path, vertices, triangles, bytes, seconds)
/// unless `quiet`.
pub fn export_gltf(
    problem: &Problem,
    radiance: &[Rgb],
    path: &Path,
    exposure: f64,
    quiet: bool,
) -> Result<()> {
    let start = Instant::now();
    let mesh = BakedMesh::from_solution(problem, radiance);
    let input = GltfInput {
        mesh: &mesh,
        materials: &problem.scene.materials,
        textures: &problem.scene.textures,
        exposure,
        name: &problem.scene.name,
    };
    let stats = write_gltf(path, &input).context("--export-gltf")?;
    if !quiet {
        eprintln!(
            "exported {}: {} vertices, {} triangles, {} bytes in {:.2} s",
            path.display(),
            stats.vertices,
            stats.triangles,
            stats.bytes,
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
