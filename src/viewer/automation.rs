//! Reproducible viewer runs: `--screenshot` (wait, capture exactly what is on screen, save,
//! close), `--edit` (material edits sent at a given shot, as a user would), and
//! `--frame-log` (per-frame timings and the latency figures of docs/VIEWER.md).
//!
//! Screenshots go through `egui::Context::request_screenshot` (egui 0.37's form of
//! `ViewportCommand::Screenshot` + `Event::Screenshot`): the image arrives a frame or two
//! later, is saved, and then `ViewportCommand::Close` ends the run. eframe's
//! `EFRAME_SCREENSHOT_TO` does not work with the wgpu backend.

use std::path::PathBuf;
use std::time::{Duration, Instant};

/// When to take the screenshot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScreenshotWhen {
    /// After this many shots (the solver stops there, so the image is of exactly N shots;
    /// earlier if it converges first).
    Shots(usize),
    /// This long after the window opened (the solver keeps running).
    Seconds(f64),
    /// When the solve has converged.
    Converged,
}

#[derive(Clone, Debug)]
pub struct ScreenshotPlan {
    pub path: PathBuf,
    pub when: ScreenshotWhen,
    /// Give up (and exit with an error) after this long.
    pub timeout: Duration,
}

/// What an `--edit` changes.
#[derive(Clone, Debug, PartialEq)]
pub enum EditTarget {
    /// A material by name.
    Material(String),
    /// The material of a patch (by id); the patch is also selected.
    Patch(u32),
}

/// `--edit TARGET:kd=r,g,b[:ke=r,g,b]`, TARGET = material name or `#patch`.
#[derive(Clone, Debug, PartialEq)]
pub struct EditSpec {
    pub target: EditTarget,
    pub kd: Option<[f64; 3]>,
    pub ke: Option<[f64; 3]>,
}

impl EditSpec {
    pub fn parse(text: &str) -> Result<EditSpec, String> {
        let mut parts = text.split(':');
        let target = parts.next().unwrap_or_default().trim();
        if target.is_empty() {
            return Err(format!("'{text}': expected TARGET:kd=r,g,b[:ke=r,g,b]"));
        }
        let target = match target.strip_prefix('#') {
            Some(id) => EditTarget::Patch(
                id.parse()
                    .map_err(|_| format!("'{text}': '#{id}' is not a patch number"))?,
            ),
            None => EditTarget::Material(target.to_string()),
        };
        let (mut kd, mut ke) = (None, None);
        for part in parts {
            let (key, value) = part
                .split_once('=')
                .ok_or_else(|| format!("'{text}': '{part}' should be kd=r,g,b or ke=r,g,b"))?;
            let v = parse_rgb(value).map_err(|e| format!("'{text}': {key}: {e}"))?;
            match key.trim() {
                "kd" => kd = Some(v),
                "ke" => ke = Some(v),
                other => return Err(format!("'{text}': unknown key '{other}' (kd or ke)")),
            }
        }
        if kd.is_none() && ke.is_none() {
            return Err(format!("'{text}': give kd=r,g,b and/or ke=r,g,b"));
        }
        Ok(EditSpec { target, kd, ke })
    }
}

/// Parses `r,g,b` (three finite numbers >= 0).
pub fn parse_rgb(text: &str) -> Result<[f64; 3], String> {
    let v: Vec<&str> = text.split(',').collect();
    if v.len() != 3 {
        return Err(format!("expected three numbers r,g,b, got '{text}'"));
    }
    let mut out = [0.0; 3];
    for (o, s) in out.iter_mut().zip(&v) {
        *o = parse_channel(s)?;
    }
    Ok(out)
}

/// One colour channel: a finite number >= 0.
pub fn parse_channel(text: &str) -> Result<f64, String> {
    let x: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("'{}' is not a number", text.trim()))?;
    if !x.is_finite() || x < 0.0 {
        return Err(format!("{x} must be a finite number >= 0"));
    }
    Ok(x)
}

/// Everything a scripted run does.
#[derive(Clone, Debug, Default)]
pub struct Automation {
    pub screenshot: Option<ScreenshotPlan>,
    pub frame_log: Option<PathBuf>,
    pub edits: Vec<EditSpec>,
    /// Send the edits once this many shots are on screen.
    pub edit_after_shots: usize,
    /// Select this patch at start.
    pub select: Option<u32>,
    /// With the screenshot, also save the viewport alone (the PNG export).
    pub viewport_png: Option<PathBuf>,
    /// With the screenshot, also export the solution as PLY.
    pub export_ply: Option<PathBuf>,
}

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
        for (l, p) in self.edit_latency_ms.iter().zip(&self.edit_publish_ms) {
            s.push_str(&format!(
                "# edit sent -> published by the solver thread ms {p:.1}, -> drawn ms {l:.1}\n"
            ));
        }
        s
    }
}

/// Progress of a scripted screenshot.
#[derive(Debug, Default)]
pub enum ShotState {
    #[default]
    Waiting,
    /// The condition held in frame `frames` ago; wait a frame more so it is on screen.
    Ready(u32),
    Requested(Instant),
    Done,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_specs_parse_and_reject() {
        assert_eq!(
            EditSpec::parse("red:kd=0.1,0.2,0.3"),
            Ok(EditSpec {
                target: EditTarget::Material("red".into()),
                kd: Some([0.1, 0.2, 0.3]),
                ke: None
            })
        );
        let e = EditSpec::parse("#12:ke=5,5,5:kd=0,0,0").expect("parse");
        assert_eq!(e.target, EditTarget::Patch(12));
        assert_eq!(e.ke, Some([5.0; 3]));
        for bad in [
            "",
            "red",
            "red:kd=1,2",
            "red:kd=a,b,c",
            "red:kd=-1,0,0",
            "red:kd=nan,0,0",
            "red:xx=1,1,1",
            "#x:kd=0,0,0",
        ] {
            assert!(EditSpec::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn percentiles() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 50.0), 51.0);
        assert_eq!(percentile(&v, 99.0), 99.0);
        assert!(percentile(&[], 50.0).is_nan());
    }
}
