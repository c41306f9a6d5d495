//! Command-line interface (clap). This is the binary's edge: errors are `anyhow`.
//!
//! The subcommands and flags are a contract used by tests, benchmarks and outside checks:
//! extend them, don't rename them.

pub mod bench;
mod bench_cornell;
mod bench_doc;
mod bench_hierarchical;
mod bench_images;
mod bench_live;
mod bench_meshing;
mod bench_specular;
mod bench_sponza;
mod bench_targets;
mod export;
mod formfactor;
mod method;
mod pass;
mod plot;
mod reference;
mod render;
mod render_report;
mod view;

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand};

use nusselt_core::scene::file::{MeshEntry, SolverEntry};
use nusselt_core::scene::{Light, LoadOptions, Scene, SceneFile, is_scene_file};

#[derive(Parser, Debug)]
#[command(
    name = "nusselt",
    version,
    about = "Diffuse global illumination by the radiosity method"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Solve a scene by progressive radiosity and render an image of the solution.
    Render(render::RenderArgs),
    /// Render an unbiased path-traced reference image of a scene.
    Reference(reference::ReferenceArgs),
    /// Evaluate form-factor cases from a JSON file; one JSON line per case.
    Formfactor(formfactor::FormfactorArgs),
    /// Image error of any PFM image against a reference, with the render's pixel mask.
    Compare(reference::CompareArgs),
    /// Open the live viewer (the default command: `nusselt` = `nusselt view --builtin cornell`).
    View(view::ViewCmdArgs),
    /// Every solver on scenes with known answers: error and residual against time (CSV).
    Bench(bench::BenchArgs),
}

/// Which scene to load: a model file or a built-in.
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// OBJ file (with its MTL files next to it), glTF 2.0 file (`.gltf` or `.glb`), or a
    /// scene file (`.json`: a model, its
    /// lights, camera and material edits; see the README).
    pub scene: Option<PathBuf>,
    /// Built-in scene: cornell, cornell-specular (a mirror and a glass block), cornell-glossy
    /// (a glossy metal and a glass block), furnace, cube (ceiling-lit unit cube, 12
    /// triangles), tworooms (two rooms and a door ajar) or gallery (a room with a
    /// 100,500-triangle statue).
    #[arg(long, conflicts_with = "scene")]
    pub builtin: Option<String>,
    /// Treat every face as two-sided (reflects and emits on both sides).
    #[arg(long)]
    pub two_sided: bool,
    /// Uniform reflectance of the furnace and cube scenes.
    #[arg(long, allow_negative_numbers = true)]
    pub rho: Option<f64>,
    /// A uniform sky of radiance R,G,B (W m⁻² sr⁻¹) from every direction in which a ray
    /// leaves the model.
    #[arg(long, value_name = "R,G,B", allow_hyphen_values = true)]
    pub sky: Option<String>,
    /// A sun arriving from direction X,Y,Z with irradiance R,G,B (W m⁻²) on a surface
    /// facing it, optionally the angular radius of its disc in degrees (a soft shadow);
    /// repeat for several.
    #[arg(long, value_name = "X,Y,Z,R,G,B[,DEG]", allow_hyphen_values = true)]
    pub sun: Vec<String>,
    /// An isotropic point light at X,Y,Z of intensity R,G,B (W sr⁻¹); repeat for several.
    #[arg(long, value_name = "X,Y,Z,R,G,B", allow_hyphen_values = true)]
    pub point: Vec<String>,
    /// A square area light of side SIZE centred at X,Y,Z facing NX,NY,NZ, of radiance
    /// R,G,B (an emitting face like the model's own); repeat for several.
    #[arg(
        long,
        value_name = "X,Y,Z,NX,NY,NZ,SIZE,R,G,B",
        allow_hyphen_values = true
    )]
    pub area: Vec<String>,
    /// Refuse a model that nothing lights instead of adding default lights (a sky and a
    /// sun where rays leave it, else an area light under its ceiling).
    #[arg(long)]
    pub no_default_lights: bool,
}

/// The text of a caught panic's payload.
pub(crate) fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

impl SceneArgs {
    /// The scene as the user named it (for messages).
    pub fn describe(&self) -> String {
        match (&self.scene, &self.builtin) {
            (Some(p), _) => p.display().to_string(),
            (None, Some(b)) => format!("--builtin {b}"),
            (None, None) => "no scene".into(),
        }
    }

    /// The lights given by `--sky`, `--sun` and `--point`, checked.
    pub fn lights(&self) -> Result<Vec<Light>> {
        let mut lights = Vec::new();
        if let Some(sky) = &self.sky {
            lights.push(Light::parse_sky(sky)?);
        }
        for sun in &self.sun {
            lights.push(Light::parse_sun(sun)?);
        }
        for point in &self.point {
            lights.push(Light::parse_point(point)?);
        }
        Ok(lights)
    }

    /// The mesh and solver settings of a scene file (none for a model or a built-in):
    /// defaults that the flags override.
    pub fn file_settings(&self) -> Result<(MeshEntry, SolverEntry)> {
        match &self.scene {
            Some(path) if is_scene_file(path) => {
                let file = SceneFile::read(path)?;
                Ok((
                    file.mesh.unwrap_or_default(),
                    file.solver.unwrap_or_default(),
                ))
            }
            _ => Ok(Default::default()),
        }
    }

    pub fn load(&self) -> Result<Scene> {
        let lights = self.lights()?;
        let areas = self
            .area
            .iter()
            .map(|a| nusselt_core::scene::lights::parse_area(a))
            .collect::<Result<Vec<_>, _>>()?;
        let opts = LoadOptions {
            two_sided: self.two_sided,
            rho: self.rho,
        };
        let mut scene = match (&self.scene, &self.builtin) {
            (Some(path), None) if is_scene_file(path) => {
                let mut scene = SceneFile::read(path)?.load(path)?;
                scene.two_sided |= self.two_sided;
                scene
            }
            (Some(path), None) => Scene::load(path, &opts)?,
            (None, Some(name)) => Scene::builtin(name, &opts)?,
            (None, None) => bail!("give a scene: an OBJ or glTF file or --builtin cornell|furnace"),
            (Some(_), Some(_)) => bail!("give either a model file or --builtin, not both"),
        };
        if self.rho.is_some() && scene.name != "furnace" && scene.name != "cube" {
            bail!("--rho applies to the furnace and cube scenes only");
        }
        for w in &scene.warnings {
            eprintln!("warning: {w}");
        }
        scene.lights.extend(lights);
        for (corners, radiance) in areas {
            scene.add_area_light(corners, radiance);
        }
        if self.no_default_lights {
            scene.check_lit()?;
        } else if let Some(message) = scene.add_default_lights() {
            eprintln!("{}: {message}", self.describe());
        }
        Ok(scene)
    }
}

/// Largest `--width`/`--height`: 8192² pixels of linear RGB are already 1.6 GB.
pub const MAX_IMAGE_SIDE: u32 = 8192;
/// Largest `--spp`.
pub const MAX_SPP: u32 = 1 << 20;
/// Largest `--rays` (rays per raycast shot or samples per case).
pub const MAX_RAYS: u32 = 1 << 26;
/// Largest `--vis-rays` (shadow rays per receiver–shooter pair).
pub const MAX_VIS_RAYS: u32 = 1 << 20;

/// Checks that an output file can be created where asked before any work is done: its
/// folder exists (the file itself is written later, atomically or when its data is ready).
pub fn check_output(flag: &str, path: &std::path::Path) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    if !dir.is_dir() {
        bail!(
            "{flag} {}: the folder {} does not exist",
            path.display(),
            dir.display()
        );
    }
    if path.is_dir() {
        bail!("{flag} {}: is a folder, not a file", path.display());
    }
    Ok(())
}

/// Checks a count flag: `1..=max`.
pub fn check_count(flag: &str, value: u32, max: u32) -> Result<()> {
    if !(1..=max).contains(&value) {
        bail!("{flag} must be in 1..={max}, got {value}");
    }
    Ok(())
}

/// Image size and camera.
#[derive(Args, Debug, Clone)]
pub struct ViewArgs {
    /// Image width in pixels (at most 8192).
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    /// Image height in pixels (at most 8192).
    #[arg(long, default_value_t = 256)]
    pub height: u32,
    /// Samples per pixel (stratified, box filter; at most 1048576).
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Camera as ex,ey,ez,tx,ty,tz,vfov_deg (+y up); default: the scene's own or a framing view.
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
}

impl ViewArgs {
    pub fn settings(
        &self,
        scene: &Scene,
        seed: u64,
    ) -> Result<nusselt_core::render::RenderSettings> {
        check_count("--width", self.width, MAX_IMAGE_SIDE)?;
        check_count("--height", self.height, MAX_IMAGE_SIDE)?;
        check_count("--spp", self.spp, MAX_SPP)?;
        let camera = match &self.camera {
            Some(text) => nusselt_core::scene::Camera::parse(text).context("--camera")?,
            None => nusselt_core::render::view::default_camera(scene),
        };
        Ok(nusselt_core::render::RenderSettings {
            width: self.width,
            height: self.height,
            spp: self.spp,
            camera,
            seed,
            edge_spp: 0,
        })
    }
}

/// Runs the command line.
pub fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Render(args)) => render::run_render(&args),
        Some(Command::Reference(args)) => reference::run_reference(&args),
        Some(Command::Formfactor(args)) => formfactor::run(&args),
        Some(Command::Compare(args)) => reference::run_compare(&args),
        Some(Command::View(args)) => view::run(&args),
        Some(Command::Bench(args)) => bench::run(&args),
        None => view::run(&view::ViewCmdArgs::cornell()),
    }
}
