//! Timings of a viewer run for `--frame-log` and docs/VIEWER.md: one row per frame, the
//! start-up figures, and how long a material edit takes to reach the screen.

use std::time::Instant;

use super::snapshot::Snapshot;

/// One frame of the frame log.
#[derive(Clone, Copy, Debug)]
pub struct FrameRow {
    /// Since the window's first frame.
    pub t_ms: f64,
    /// Since the previous frame started.
    pub interval_ms: f64,
    /// Time spent in `App::logic` + `App::ui` this frame.
    pub ui_ms: f64,
    /// eframe's CPU time of the previous frame (ui, tessellation, painting, presenting).
    pub cpu_ms: f64,
    pub shots: usize,
    pub elements: usize,
    pub new_snapshot: bool,
}

/// Timings gathered by the app for `--frame-log`.
#[derive(Debug, Default)]
pub struct FrameLog {
    pub rows: Vec<FrameRow>,
    /// Process start → first frame.
    pub first_frame_ms: Option<f64>,
    /// First frame → first frame that draws a solution (emitters lit).
    pub first_light_ms: Option<f64>,
    /// First frame → first frame that draws a solution after one shot.
    pub first_shot_ms: Option<f64>,
    /// Edit sent → first frame that draws it.
    pub edit_latency_ms: Vec<f64>,
    /// Edit sent → the solver thread published a snapshot with it.
    pub edit_publish_ms: Vec<f64>,
    /// Of the last snapshot drawn: drawn vertices and display triangles (radiance, 12 bytes
    /// a vertex, is what a new snapshot uploads).
    pub mesh_size: Option<(usize, usize)>,
}

fn percentile(values: &[f64], p: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let k = ((p / 100.0) * (v.len() - 1) as f64).round() as usize;
    v[k.min(v.len() - 1)]
}

impl FrameLog {
    /// CSV rows then `#` summary lines.
    pub fn to_text(&self) -> String {
        let mut s =
            String::from("frame,t_ms,interval_ms,ui_ms,cpu_ms,shots,elements,new_snapshot\n");
        for (i, r) in self.rows.iter().enumerate() {
            s.push_str(&format!(
                "{i},{:.3},{:.3},{:.3},{:.3},{},{},{}\n",
                r.t_ms, r.interval_ms, r.ui_ms, r.cpu_ms, r.shots, r.elements, r.new_snapshot as u8
            ));
        }
        s.push_str(&self.summary());
        s
    }

    /// Summary lines (also printed to stderr at exit).
    pub fn summary(&self) -> String {
        // Frames while the solver was running (shots increasing), the first 10 skipped
        // (start-up: shader compilation, first uploads).
        let solving: Vec<&FrameRow> = self
            .rows
            .windows(2)
            .skip(10)
            .filter(|w| w[1].shots > w[0].shots)
            .map(|w| &w[1])
            .collect();
        let col = |f: fn(&FrameRow) -> f64| solving.iter().map(|r| f(r)).collect::<Vec<f64>>();
        let ui = col(|r| r.ui_ms);
        let cpu = col(|r| r.cpu_ms);
        let interval = col(|r| r.interval_ms);
        let opt = |x: Option<f64>| x.map_or("n/a".to_string(), |v| format!("{v:.1}"));
        let mut s = format!(
            "# frames {} (while solving, after the first 10: {})\n",
            self.rows.len(),
            solving.len()
        );
        s.push_str(&format!(
            "# ui_ms p50 {:.2} p99 {:.2} max {:.2}\n# cpu_ms p50 {:.2} p99 {:.2} max {:.2}\n# interval_ms p50 {:.2} p99 {:.2} max {:.2}\n",
            percentile(&ui, 50.0),
            percentile(&ui, 99.0),
            percentile(&ui, 100.0),
            percentile(&cpu, 50.0),
            percentile(&cpu, 99.0),
            percentile(&cpu, 100.0),
            percentile(&interval, 50.0),
            percentile(&interval, 99.0),
            percentile(&interval, 100.0),
        ));
        s.push_str(&format!(
            "# process start -> first frame ms {}\n# first frame -> emitters drawn ms {}\n# first frame -> first shot drawn ms {}\n",
            opt(self.first_frame_ms),
            opt(self.first_light_ms),
            opt(self.first_shot_ms)
        ));
        if let Some((vertices, triangles)) = self.mesh_size {
            s.push_str(&format!(
                "# radiance upload per new snapshot: {} bytes ({vertices} drawn vertices, {triangles} triangles; per triangle corner it would be {} bytes)\n",
                vertices * 12,
                triangles * 3 * 12
            ));
        }
        for (l, p) in self.edit_latency_ms.iter().zip(&self.edit_publish_ms) {
            s.push_str(&format!(
                "# edit sent -> published by the solver thread ms {p:.1}, -> drawn ms {l:.1}\n"
            ));
        }
        s
    }
}

/// An edit sent and not yet seen drawn.
struct PendingEdit {
    sent: Instant,
    material: u32,
    kd: [f64; 3],
    ke: [f64; 3],
}

/// Edits sent and not yet drawn; each is timed until the first snapshot that shows it.
#[derive(Default)]
pub struct EditLatency {
    pending: Vec<PendingEdit>,
}

impl EditLatency {
    /// Most edits kept waiting (older ones are dropped from the figure).
    const CAPACITY: usize = 64;

    pub fn sent(&mut self, material: u32, kd: [f64; 3], ke: [f64; 3]) {
        self.pending.push(PendingEdit {
            sent: Instant::now(),
            material,
            kd,
            ke,
        });
        if self.pending.len() > Self::CAPACITY {
            self.pending.remove(0);
        }
    }

    /// Every edit sent has been drawn.
    pub fn is_empty(&self) -> bool {
        self.pending.is_empty()
    }

    /// An edit of `material` is still on its way.
    pub fn waits_for(&self, material: u32) -> bool {
        self.pending.iter().any(|e| e.material == material)
    }

    /// Records the latency of every pending edit that `s` shows (it is about to be drawn).
    pub fn on_snapshot(&mut self, s: &Snapshot, log: &mut FrameLog) {
        let now = Instant::now();
        self.pending.retain(|e| {
            let drawn = s
                .materials
                .get(e.material as usize)
                .is_some_and(|m| m.reflectance.to_array() == e.kd && m.emission.to_array() == e.ke);
            if drawn {
                log.edit_latency_ms.push((now - e.sent).as_secs_f64() * 1e3);
                log.edit_publish_ms.push(
                    s.edit_published
                        .unwrap_or(s.published)
                        .saturating_duration_since(e.sent)
                        .as_secs_f64()
                        * 1e3,
                );
            }
            !drawn
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 50.0), 51.0);
        assert_eq!(percentile(&v, 99.0), 99.0);
        assert!(percentile(&[], 50.0).is_nan());
    }
}
