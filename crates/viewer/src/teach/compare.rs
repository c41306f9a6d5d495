//! Shooting vs gathering, side by side (`--teach compare`): the lecture's two ways of
//! solving the same patch system `B_p = E_p + ρ_p Σ_q F_pq B_q`, at the same cost per step.
//!
//! - **Progressive shooting** (Cohen, Chen, Wallace & Greenberg 1988): the patch `i` with
//!   the most unshot power `ΔB_i A_i` sends it to every patch, `B_q += ρ_q ΔB_i F_qi` (column
//!   `i` of the matrix), shown with the classic ambient term `ρ_q · R · Σ ΔB_i A_i / Σ A_i`,
//!   `R = 1/(1 − ρ̄)`.
//! - **Gauss-Seidel gathering**: one patch `p` per step, in order, gathers from every
//!   patch, `B_p = E_p + ρ_p Σ_q F_pq B_q` (row `p`), using the values already updated this
//!   sweep.
//!
//! Each step of either reads `n` form factors of the same matrix, so after `k` steps both
//! have done the same work. The matrix is the one the project's solvers use,
//! `F_pi = Σ_{j∈p} A_j F_ji / A_p` from the element rows ([`RowCache::row`], as
//! `solver::gathering`), so its converged solution is theirs at patch level. Both start
//! from `B = E` and are measured, area-weighted, against that solution (Gauss-Seidel to
//! 1e-12), so the error is the iteration's alone, not the mesh's. The images show one
//! colour per patch.
//!
//! The rows are computed first (one per idle turn of the solver thread, so commands stay
//! responsive), since the reference needs all of them; the steps then only read them.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use nusselt_core::mesh::PatchId;
use nusselt_core::scene::{Camera, Rgb};
use nusselt_core::solver::{Problem, RowCache};

use super::super::snapshot::Geometry;
use super::item_image::ItemImage;
use super::matrix::MAX_PATCHES;

/// Side of each of the two images, in pixels.
pub const IMAGE_SIDE: usize = 288;

/// Steps the curve keeps (beyond, every other point is dropped).
const CURVE_CAPACITY: usize = 8192;

/// Both methods are done when their errors fall below this (the reference's own accuracy
/// is far below it).
pub const DONE_ERROR: f64 = 1e-6;

/// What the Teach panel asks of the comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CompareCommand {
    /// Start (computing the rows first), with `steps` steps to take once they are ready
    /// (a scripted screenshot); or stop and drop it.
    On {
        steps: usize,
    },
    Off,
    /// One step of each method.
    Step,
    Play(bool),
    /// Steps per second while playing.
    Rate(f32),
    /// Back to `B = E`.
    Reset,
}

/// The errors after a number of steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComparePoint {
    pub steps: usize,
    /// Shooting, `B` alone.
    pub shooting: f64,
    /// Shooting as displayed, `B + ρ·ambient`.
    pub shooting_ambient: f64,
    pub gathering: f64,
}

/// What the view shows (published with the snapshot).
#[derive(Debug)]
pub struct CompareDetail {
    pub patches: usize,
    /// Rows computed so far (the steps start when all `patches` are).
    pub rows_done: usize,
    pub steps: usize,
    /// Per patch, linear radiance: shooting's `B`, its display with the ambient term, and
    /// gathering's `B`.
    pub shooting: Vec<[f32; 3]>,
    pub shooting_ambient: Vec<[f32; 3]>,
    pub gathering: Vec<[f32; 3]>,
    pub ambient: Rgb,
    /// Fraction of the emitted power not yet shot.
    pub unshot_fraction: f64,
    pub last_shooter: Option<u32>,
    pub last_gatherer: Option<u32>,
    pub curve: Arc<Vec<ComparePoint>>,
    pub image: Arc<ItemImage>,
    pub playing: bool,
    pub rate: f32,
}

impl CompareDetail {
    /// Full Gauss-Seidel sweeps done.
    pub fn sweeps(&self) -> f64 {
        self.steps as f64 / self.patches.max(1) as f64
    }
}

/// The comparison being run (on the solver thread).
pub struct CompareWork {
    /// The mesh it is for (`Geometry::id`).
    pub geometry_id: u64,
    n: usize,
    /// `F_pq` (receiver `p`, source `q`), row-major.
    f: Vec<f64>,
    rows_done: usize,
    area: Vec<f64>,
    emission: Vec<Rgb>,
    rho: Vec<Rgb>,
    reference: Option<Vec<Rgb>>,
    shoot_b: Vec<Rgb>,
    unshot: Vec<Rgb>,
    gather_b: Vec<Rgb>,
    steps: usize,
    last_shooter: Option<usize>,
    last_gatherer: Option<usize>,
    curve: Arc<Vec<ComparePoint>>,
    image: Arc<ItemImage>,
    /// Steps still to take (single steps and a scripted start).
    pending: usize,
    playing: bool,
    rate: f32,
    next_due: Instant,
    /// Something changed since the last [`detail`](Self::detail).
    pub changed: bool,
}

fn channel_sum(c: Rgb) -> f64 {
    c.x + c.y + c.z
}

impl CompareWork {
    /// Refused (with the message for the user) past [`MAX_PATCHES`].
    pub fn new(
        problem: &Problem,
        geometry: &Geometry,
        camera: &Camera,
        steps: usize,
    ) -> Result<CompareWork, String> {
        let n = problem.mesh.patches.len();
        if n > MAX_PATCHES {
            return Err(format!(
                "the shooting-vs-gathering view takes at most {MAX_PATCHES} patches, this mesh \
                 has {n}: use a larger element size"
            ));
        }
        let emission = problem.patch_emission();
        let image = ItemImage::trace(
            geometry.bvh(),
            &geometry.triangle_element,
            camera,
            IMAGE_SIDE,
            IMAGE_SIDE,
        );
        Ok(CompareWork {
            geometry_id: geometry.id,
            n,
            f: vec![0.0; n * n],
            rows_done: 0,
            area: problem.mesh.patches.iter().map(|p| p.area).collect(),
            rho: problem.patch_reflectance(),
            shoot_b: emission.clone(),
            unshot: emission.clone(),
            gather_b: emission.clone(),
            emission,
            reference: None,
            steps: 0,
            last_shooter: None,
            last_gatherer: None,
            curve: Arc::new(Vec::new()),
            image: Arc::new(image),
            pending: steps,
            playing: false,
            rate: 10.0,
            next_due: Instant::now(),
            changed: true,
        })
    }

    pub fn apply(&mut self, command: CompareCommand) {
        match command {
            CompareCommand::Step => self.pending += 1,
            CompareCommand::Play(on) => {
                self.playing = on;
                self.next_due = Instant::now();
            }
            CompareCommand::Rate(r) => self.rate = r.clamp(0.5, 10_000.0),
            CompareCommand::Reset => self.reset(),
            CompareCommand::On { .. } | CompareCommand::Off => {}
        }
        self.changed = true;
    }

    fn reset(&mut self) {
        self.shoot_b = self.emission.clone();
        self.unshot = self.emission.clone();
        self.gather_b = self.emission.clone();
        self.steps = 0;
        self.pending = 0;
        self.playing = false;
        self.last_shooter = None;
        self.last_gatherer = None;
        self.curve = Arc::new(Vec::new());
        self.record();
    }

    /// Whether the rows (and the reference) are ready.
    pub fn prepared(&self) -> bool {
        self.reference.is_some()
    }

    /// Whether both methods have converged.
    pub fn done(&self) -> bool {
        self.curve
            .last()
            .is_some_and(|p| p.shooting.max(p.gathering) < DONE_ERROR)
    }

    /// Whether there is work to do now (a row, or a step that is due).
    pub fn pending(&self, now: Instant) -> bool {
        if !self.prepared() {
            return true;
        }
        !self.done() && (self.pending > 0 || (self.playing && now >= self.next_due))
    }

    /// How long until the next step is due while playing (for the thread's wait).
    pub fn wait(&self, now: Instant) -> Option<Duration> {
        (self.prepared() && self.playing && !self.done())
            .then(|| self.next_due.saturating_duration_since(now))
    }

    /// Computes one more row, or takes the steps that are due. `false` when cancelled.
    pub fn work(&mut self, problem: &Problem, cancel: &AtomicBool) -> bool {
        if !self.prepared() {
            return self.next_row(problem, cancel);
        }
        let now = Instant::now();
        let mut taken = 0;
        while self.pending > 0 && !self.done() {
            self.step();
            self.pending -= 1;
            taken += 1;
        }
        if self.playing {
            let period = Duration::from_secs_f64(1.0 / f64::from(self.rate));
            // Fast rates take several steps a turn; a late turn does not catch up.
            while now >= self.next_due && taken < 1000 && !self.done() {
                self.step();
                taken += 1;
                self.next_due += period;
            }
            if now >= self.next_due {
                self.next_due = now + period;
            }
            if self.done() {
                self.playing = false;
            }
        }
        if taken > 0 {
            self.changed = true;
        }
        true
    }

    fn next_row(&mut self, problem: &Problem, cancel: &AtomicBool) -> bool {
        let i = self.rows_done;
        if i < self.n {
            // The element row of source i is column i of the patch matrix.
            let Some(row) = RowCache::default().row(problem, PatchId(i as u32), cancel) else {
                return false;
            };
            let mesh = &problem.mesh;
            for (e, f_ji) in mesh.elements.iter().zip(row.iter()) {
                let p = e.patch.0 as usize;
                self.f[p * self.n + i] += f64::from(*f_ji) * e.area / self.area[p];
            }
            self.rows_done += 1;
            self.changed = true;
        }
        if self.rows_done == self.n {
            self.reference = Some(self.converged());
            self.record();
        }
        true
    }

    /// Gauss-Seidel to a relative change below 1e-12 (at most 100,000 sweeps).
    fn converged(&self) -> Vec<Rgb> {
        let mut b = self.emission.clone();
        for _ in 0..100_000 {
            let mut change: f64 = 0.0;
            let mut size: f64 = 0.0;
            for p in 0..self.n {
                let new = self.gathered(p, &b);
                change += channel_sum((new - b[p]).abs()) * self.area[p];
                size += channel_sum(new) * self.area[p];
                b[p] = new;
            }
            if change <= 1e-12 * size {
                break;
            }
        }
        b
    }

    /// `E_p + ρ_p Σ_q F_pq B_q`.
    fn gathered(&self, p: usize, b: &[Rgb]) -> Rgb {
        let row = &self.f[p * self.n..(p + 1) * self.n];
        let sum = row
            .iter()
            .zip(b)
            .fold(Rgb::ZERO, |acc, (f, bq)| acc + *bq * *f);
        self.emission[p] + self.rho[p] * sum
    }

    /// One step of each method.
    fn step(&mut self) {
        // Shooting: the most unshot power.
        let shooter = (0..self.n)
            .map(|i| (i, channel_sum(self.unshot[i]) * self.area[i]))
            .filter(|&(_, power)| power > 0.0)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i);
        if let Some(i) = shooter {
            let shot = self.unshot[i];
            self.unshot[i] = Rgb::ZERO;
            for q in 0..self.n {
                let f_qi = self.f[q * self.n + i];
                if f_qi > 0.0 && q != i {
                    let gain = self.rho[q] * shot * f_qi;
                    self.shoot_b[q] += gain;
                    self.unshot[q] += gain;
                }
            }
        }
        self.last_shooter = shooter;
        // Gathering: the next patch in order.
        let p = self.steps % self.n.max(1);
        if self.n > 0 {
            self.gather_b[p] = self.gathered(p, &self.gather_b);
            self.last_gatherer = Some(p);
        }
        self.steps += 1;
        debug_assert!(
            self.shoot_b
                .iter()
                .chain(&self.gather_b)
                .all(|b| b.is_finite())
        );
        self.record();
    }

    /// The classic ambient term `R · Σ ΔB_i A_i / Σ A_i`, `R = 1/(1 − ρ̄)` per channel.
    fn ambient(&self) -> Rgb {
        let total: f64 = self.area.iter().sum();
        if total <= 0.0 {
            return Rgb::ZERO;
        }
        let mut rho = Rgb::ZERO;
        let mut unshot = Rgb::ZERO;
        for p in 0..self.n {
            rho += self.rho[p] * self.area[p];
            unshot += self.unshot[p] * self.area[p];
        }
        let rho = rho / total;
        let r = (Rgb::ONE - rho).max(Rgb::splat(1e-3)).recip();
        r * unshot / total
    }

    fn shown_with_ambient(&self) -> Vec<Rgb> {
        let a = self.ambient();
        self.shoot_b
            .iter()
            .zip(&self.rho)
            .map(|(b, rho)| *b + *rho * a)
            .collect()
    }

    /// Area-weighted relative error against the reference, `Σ A_p |B_p − B*_p| / Σ A_p B*_p`
    /// (channels summed).
    pub fn error(&self, b: &[Rgb]) -> f64 {
        let Some(reference) = &self.reference else {
            return f64::NAN;
        };
        let (mut diff, mut size) = (0.0, 0.0);
        for p in 0..self.n {
            diff += channel_sum((b[p] - reference[p]).abs()) * self.area[p];
            size += channel_sum(reference[p]) * self.area[p];
        }
        diff / size.max(1e-300)
    }

    fn record(&mut self) {
        if self.reference.is_none() {
            return;
        }
        let point = ComparePoint {
            steps: self.steps,
            shooting: self.error(&self.shoot_b),
            shooting_ambient: self.error(&self.shown_with_ambient()),
            gathering: self.error(&self.gather_b),
        };
        let curve = Arc::make_mut(&mut self.curve);
        if curve.len() >= CURVE_CAPACITY {
            let mut keep = false;
            curve.retain(|_| {
                keep = !keep;
                keep
            });
        }
        curve.push(point);
    }

    /// What the view shows now.
    pub fn detail(&mut self) -> CompareDetail {
        self.changed = false;
        let f32s =
            |v: &[Rgb]| -> Vec<[f32; 3]> { v.iter().map(|c| c.as_vec3().to_array()).collect() };
        let emitted: f64 = (0..self.n)
            .map(|p| channel_sum(self.emission[p]) * self.area[p])
            .sum();
        let unshot: f64 = (0..self.n)
            .map(|p| channel_sum(self.unshot[p]) * self.area[p])
            .sum();
        CompareDetail {
            patches: self.n,
            rows_done: self.rows_done,
            steps: self.steps,
            shooting: f32s(&self.shoot_b),
            shooting_ambient: f32s(&self.shown_with_ambient()),
            gathering: f32s(&self.gather_b),
            ambient: self.ambient(),
            unshot_fraction: unshot / emitted.max(1e-300),
            last_shooter: self.last_shooter.map(|p| p as u32),
            last_gatherer: self.last_gatherer.map(|p| p as u32),
            curve: self.curve.clone(),
            image: self.image.clone(),
            playing: self.playing,
            rate: self.rate,
        }
    }
}

#[cfg(test)]
mod tests;
