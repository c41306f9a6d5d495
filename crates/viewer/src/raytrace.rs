//! The ray-traced view: the viewport's camera rendered with the second pass (`render --pass
//! direct`: the lights' direct part per pixel with exact shadows, the indirect rest from
//! the radiosity solution, `render::direct`), refined progressively, one sample per pixel
//! per pass, on its own thread so the UI never waits.
//!
//! The solver thread publishes what a render needs ([`RenderInput`]: scene, mesh and the
//! element radiance) with the snapshot while the view is on; the app submits it with the
//! current camera; a new camera or a new solution replaces the job between passes (a pass
//! takes about a second at most on two cores), and a new solution rebuilds the visibility
//! structures and the lights' rows once.

use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Instant;

use nusselt_core::mesh::Mesh;
use nusselt_core::render::direct::{DirectLight, indirect_vertex_radiance};
use nusselt_core::render::{self, RenderSettings, SolutionView};
use nusselt_core::scene::{Camera, Rgb, Scene};
use nusselt_core::solver::{Problem, SolverConfig};

use super::solver_thread::{Latest, Waker};

/// Samples per pixel after which a view is finished.
pub const MAX_SPP: u32 = 256;

/// Longest side of the rendered image, in pixels (larger viewports are upscaled).
pub const MAX_SIDE: u32 = 720;

/// What a render needs of a solution (published by the solver thread).
pub struct RenderInput {
    /// The solver thread's publish sequence it was taken at.
    pub seq: u64,
    pub scene: Scene,
    pub config: SolverConfig,
    pub mesh: Mesh,
    /// Radiance per element, with the solver's display correction.
    pub radiance: Vec<Rgb>,
}

impl std::fmt::Debug for RenderInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RenderInput(seq {})", self.seq)
    }
}

/// One progressive image.
#[derive(Debug)]
pub struct RayImage {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    /// Mean linear radiance per pixel, row-major from the top.
    pub pixels: Vec<Rgb>,
    pub spp: u32,
    /// The [`RenderInput::seq`] rendered.
    pub input_seq: u64,
    /// Seconds since the job started.
    pub seconds: f64,
}

/// A render asked for.
#[derive(Clone)]
pub struct RayJob {
    pub input: Arc<RenderInput>,
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
}

impl RayJob {
    fn same_view(&self, other: &RayJob) -> bool {
        Arc::ptr_eq(&self.input, &other.input)
            && self.camera == other.camera
            && (self.width, self.height) == (other.width, other.height)
    }
}

/// What the app tells the render thread.
#[derive(Default)]
struct Mailbox {
    /// The next job (latest wins).
    job: Option<RayJob>,
    /// Stop rendering the current job.
    stop: bool,
    quit: bool,
}

type Slot = Arc<(Mutex<Mailbox>, Condvar)>;

fn mailbox(slot: &Slot) -> std::sync::MutexGuard<'_, Mailbox> {
    slot.0.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The render thread and its mailboxes.
pub struct RayTracer {
    slot: Slot,
    latest: Arc<Latest<Arc<RayImage>>>,
    /// The job being rendered (to skip submitting the same view again).
    current: Option<RayJob>,
    handle: Option<JoinHandle<()>>,
}

impl RayTracer {
    /// Starts the thread; `waker` is called after each pass.
    pub fn spawn(waker: Waker) -> std::io::Result<RayTracer> {
        let slot: Slot = Arc::new((Mutex::new(Mailbox::default()), Condvar::new()));
        let latest = Arc::new(Latest::default());
        let (s, l) = (slot.clone(), latest.clone());
        let handle = std::thread::Builder::new()
            .name("nusselt-raytrace".into())
            .spawn(move || run(&s, &l, &waker))?;
        Ok(RayTracer {
            slot,
            latest,
            current: None,
            handle: Some(handle),
        })
    }

    /// Renders `job` from now on (the current one stops after its pass); nothing happens
    /// when it is the view already being rendered.
    pub fn submit(&mut self, job: RayJob) {
        if self.current.as_ref().is_some_and(|c| c.same_view(&job)) {
            return;
        }
        self.current = Some(job.clone());
        mailbox(&self.slot).job = Some(job);
        self.slot.1.notify_one();
    }

    /// Stops rendering (the view was turned off).
    pub fn stop(&mut self) {
        self.current = None;
        let mut m = mailbox(&self.slot);
        m.job = None;
        m.stop = true;
    }

    /// The newest image, if a pass finished since the last call.
    pub fn take(&self) -> Option<Arc<RayImage>> {
        self.latest.take()
    }
}

impl Drop for RayTracer {
    fn drop(&mut self) {
        mailbox(&self.slot).quit = true;
        self.slot.1.notify_one();
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// A new job, a stop or quit ends the current job between passes.
fn interrupted(slot: &Slot) -> bool {
    let m = mailbox(slot);
    m.job.is_some() || m.stop || m.quit
}

/// Waits for a job; `None` when told to quit.
fn next_job(slot: &Slot) -> Option<RayJob> {
    let mut m = mailbox(slot);
    loop {
        if m.quit {
            return None;
        }
        if let Some(job) = m.job.take() {
            m.stop = false;
            return Some(job);
        }
        m = slot.1.wait(m).unwrap_or_else(PoisonError::into_inner);
    }
}

fn run(slot: &Slot, latest: &Latest<Arc<RayImage>>, waker: &Waker) {
    let mut pending = next_job(slot);
    while let Some(first) = pending.take() {
        // A solution: its problem (the solver's visibility structure), the indirect part
        // per vertex, the display BVH and the lights, built once.
        let input = first.input.clone();
        let problem = match Problem::with_mesh(
            input.scene.clone(),
            input.config.clone(),
            input.mesh.clone(),
        ) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("viewer: ray-traced view: {e}");
                pending = next_job(slot);
                continue;
            }
        };
        let vertex = indirect_vertex_radiance(&problem, &input.radiance);
        let bvh = render::display_bvh(&problem.scene, &problem.mesh);
        let view = SolutionView {
            scene: &problem.scene,
            mesh: &problem.mesh,
            vertex_radiance: &vertex,
            bvh: &bvh,
            texture: problem.element_texture(),
        };
        let lights = DirectLight::new(&problem);
        let mut job = first;
        loop {
            let start = Instant::now();
            let mut sum = vec![Rgb::ZERO; (job.width * job.height) as usize];
            for pass in 0..MAX_SPP {
                if interrupted(slot) {
                    break;
                }
                let settings = RenderSettings {
                    width: job.width,
                    height: job.height,
                    spp: 1,
                    camera: job.camera,
                    seed: u64::from(pass) + 1,
                    edge_spp: 0,
                };
                let image = render::direct::render(&view, &lights, &settings);
                for (s, p) in sum.iter_mut().zip(&image.pixels) {
                    *s += *p;
                }
                let spp = pass + 1;
                latest.publish(Arc::new(RayImage {
                    camera: job.camera,
                    width: job.width,
                    height: job.height,
                    pixels: sum.iter().map(|s| *s / f64::from(spp)).collect(),
                    spp,
                    input_seq: input.seq,
                    seconds: start.elapsed().as_secs_f64(),
                }));
                waker();
            }
            let Some(next) = next_job(slot) else {
                return;
            };
            if Arc::ptr_eq(&next.input, &input) {
                job = next;
            } else {
                pending = Some(next);
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use nusselt_core::mesh::MeshSpec;
    use std::time::Duration;

    use super::*;
    use nusselt_core::scene::LoadOptions;

    /// The view converges to what `render --pass direct` computes for the same solution
    /// and camera (the same shading, so the difference is the two estimates' sampling
    /// noise: after 16 passes against 16 spp, a few percent of the mean per pixel at
    /// most, far less on average).
    #[test]
    fn passes_converge_to_the_direct_pass() {
        let scene = Scene::builtin("cornell", &LoadOptions::default()).expect("cornell");
        let config = SolverConfig {
            mesh: MeshSpec::element(100.0),
            ..SolverConfig::default()
        };
        let problem = Problem::new(scene.clone(), config.clone()).expect("problem");
        let radiance = vec![Rgb::splat(0.2); problem.mesh.elements.len()];
        let camera = Camera::cornell();
        let reference = render::direct::render_solution(
            &problem,
            &radiance,
            &RenderSettings {
                width: 32,
                height: 32,
                spp: 16,
                camera,
                seed: 99,
                edge_spp: 0,
            },
        );
        let mut tracer = RayTracer::spawn(Box::new(|| {})).expect("thread");
        tracer.submit(RayJob {
            input: Arc::new(RenderInput {
                seq: 7,
                scene,
                config,
                mesh: problem.mesh.clone(),
                radiance,
            }),
            camera,
            width: 32,
            height: 32,
        });
        let deadline = Instant::now() + Duration::from_secs(120);
        let image = loop {
            assert!(Instant::now() < deadline, "no 16-pass image");
            if let Some(i) = tracer.take()
                && i.spp >= 16
            {
                break i;
            }
            std::thread::sleep(Duration::from_millis(5));
        };
        assert_eq!((image.width, image.height, image.input_seq), (32, 32, 7));
        let mean = |p: &[Rgb]| p.iter().map(|c| c.x + c.y + c.z).sum::<f64>() / p.len() as f64;
        let diff: f64 = image
            .pixels
            .iter()
            .zip(&reference.pixels)
            .map(|(a, b)| (*a - *b).abs().element_sum())
            .sum::<f64>()
            / image.pixels.len() as f64;
        let m = mean(&reference.pixels);
        assert!(m > 0.0);
        assert!(diff < 0.05 * m, "mean difference {diff} vs mean {m}");
        tracer.stop();
    }
}
