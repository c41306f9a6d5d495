//! A display for the viewer's end-to-end tests (the current one, or a fresh Xvfb), the
//! Vulkan driver check, and PNG pictures to measure.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn which(program: &str) -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(program))
            .find(|p| p.is_file())
    })
}

pub fn vulkan_driver_present() -> bool {
    ["/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d"]
        .iter()
        .filter_map(|d| std::fs::read_dir(d).ok())
        .flatten()
        .any(|e| e.is_ok_and(|e| e.path().extension().is_some_and(|x| x == "json")))
}

pub struct Display {
    pub name: String,
    server: Option<Child>,
}

impl Drop for Display {
    fn drop(&mut self) {
        if let Some(c) = self.server.as_mut() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// The current display, or a fresh Xvfb.
pub fn display() -> Result<Display, String> {
    if let Ok(d) = std::env::var("DISPLAY")
        && !d.is_empty()
    {
        return Ok(Display {
            name: d,
            server: None,
        });
    }
    let xvfb = which("Xvfb").ok_or("DISPLAY is unset and Xvfb is not installed")?;
    // `-displayfd 1`: Xvfb picks a free display number itself (taking its lock file
    // atomically) and writes it to stdout once it accepts connections. Choosing the number
    // here instead raced with the other test processes: two could pick the same one, the
    // loser's Xvfb exited and it went on using the winner's server, which vanished when
    // the winner's test ended. `-noreset`: no server reset when the last client leaves.
    let mut child = Command::new(&xvfb)
        .args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "1280x800x24",
            "-nolisten",
            "tcp",
            "-noreset",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("cannot start Xvfb: {e}"))?;
    let stdout = child.stdout.take().ok_or("Xvfb has no stdout")?;
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    std::thread::Builder::new()
        .name("xvfb-displayfd".into())
        .spawn(move || {
            use std::io::BufRead;
            let mut line = String::new();
            let _ = std::io::BufReader::new(stdout).read_line(&mut line);
            let _ = tx.send(line);
        })
        .map_err(|e| format!("cannot read Xvfb's display number: {e}"))?;
    let number = rx
        .recv_timeout(Duration::from_secs(30))
        .ok()
        .and_then(|line| line.trim().parse::<u32>().ok());
    match number {
        Some(n) => Ok(Display {
            name: format!(":{n}"),
            server: Some(child),
        }),
        None => {
            let _ = child.kill();
            let _ = child.wait();
            Err("Xvfb did not start (no display number on -displayfd within 30 s)".into())
        }
    }
}

pub struct Picture {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[f64; 3]>,
}

impl Picture {
    pub fn load(path: &Path) -> Picture {
        let img = image::open(path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .to_rgb8();
        let (w, h) = img.dimensions();
        Picture {
            width: w as usize,
            height: h as usize,
            rgb: img
                .pixels()
                .map(|p| p.0.map(|c| f64::from(c) / 255.0))
                .collect(),
        }
    }

    /// Mean colour of columns [x0, x1) as fractions of the width.
    pub fn mean(&self, x0: f64, x1: f64) -> [f64; 3] {
        let (a, b) = (
            (x0 * self.width as f64) as usize,
            (x1 * self.width as f64) as usize,
        );
        let mut sum = [0.0; 3];
        let mut n = 0.0f64;
        for y in 0..self.height {
            for x in a..b {
                let p = self.rgb[y * self.width + x];
                for c in 0..3 {
                    sum[c] += p[c];
                }
                n += 1.0;
            }
        }
        sum.map(|s| s / n.max(1.0))
    }
}

/// Runs the viewer on the Cornell box with `args` (element size, when to take the
/// screenshot, a window size other than 900x600); returns the window and viewport PNGs, named after `tag`.
pub fn run_viewer_with(
    display: &Display,
    dir: &Path,
    tag: &str,
    args: &[&str],
) -> (PathBuf, PathBuf) {
    let window = dir.join(format!("window_{tag}.png"));
    let viewport = dir.join(format!("viewport_{tag}.png"));
    let runtime = dir.join("runtime");
    std::fs::create_dir_all(&runtime).expect("runtime dir");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&runtime, std::fs::Permissions::from_mode(0o700)).expect("chmod");
    }
    let start = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(["view", "--builtin", "cornell"])
        .args(args)
        // 900x600 unless `args` says otherwise.
        .args(if args.contains(&"--window") {
            &[][..]
        } else {
            &["--window", "900x600"][..]
        })
        .args(["--no-highlight", "--no-ambient", "--screenshot"])
        .arg(&window)
        .arg("--viewport-png")
        .arg(&viewport)
        .args(["--screenshot-timeout", "240"])
        .env("DISPLAY", &display.name)
        .env("XDG_RUNTIME_DIR", &runtime)
        .env("XDG_DATA_HOME", dir.join("data"))
        .env("XDG_CONFIG_HOME", dir.join("config"))
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run nusselt");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "nusselt view failed ({}):\n{stderr}",
        out.status
    );
    eprintln!(
        "{tag}: {:.1} s; {}",
        start.elapsed().as_secs_f64(),
        stderr
            .lines()
            .filter(|l| l.starts_with("saved"))
            .collect::<Vec<_>>()
            .join("; ")
    );
    (window, viewport)
}
