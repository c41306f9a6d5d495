//! Prints a digest of the default mesh of a scene (every field of every patch, element,
//! vertex, T-vertex and vertex weight, floats to the bit) and of its per-element texture
//! means, with the counts: two builds mesh a scene identically when their digests agree.
//! `cargo run --release -p nusselt-core --example mesh_digest -- MODEL|builtin:NAME [--discontinuity]`

use std::fmt::Write as _;
use std::hash::{DefaultHasher, Hasher};
use std::path::Path;

use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{Problem, SolverConfig};

/// `fmt::Write` into a hasher, so a large `Debug` output is hashed without being stored.
struct HashWriter(DefaultHasher);

impl std::fmt::Write for HashWriter {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        self.0.write(s.as_bytes());
        Ok(())
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let what = args
        .first()
        .ok_or("usage: mesh_digest MODEL|builtin:NAME")?;
    let opts = LoadOptions::default();
    let scene = match what.strip_prefix("builtin:") {
        Some(name) => Scene::builtin(name, &opts)?,
        None => Scene::load(Path::new(what), &opts)?,
    };
    let mut config = SolverConfig::default();
    config.mesh.discontinuity = args.iter().any(|a| a == "--discontinuity");
    let problem = Problem::new(scene, config)?;
    let mut mesh = problem.mesh.clone();
    mesh.id = 0;
    let mut h = HashWriter(DefaultHasher::new());
    write!(h, "{mesh:?}")?;
    let mesh_digest = h.0.finish();
    let mut t = DefaultHasher::new();
    for (e, rgb) in problem.element_texture().iter().enumerate() {
        for c in rgb.to_array() {
            t.write_u64(c.to_bits());
        }
        t.write_u64(problem.element_coverage(e).to_bits());
    }
    println!(
        "elements {} patches {} vertices {} t_vertices {} mesh {:016x} textures {:016x} setup {:?}",
        mesh.elements.len(),
        mesh.patches.len(),
        mesh.vertices.len(),
        mesh.t_vertex_count(),
        mesh_digest,
        t.finish(),
        problem.setup_seconds
    );
    Ok(())
}
