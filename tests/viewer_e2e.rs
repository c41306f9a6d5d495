//! End to end: the real binary opens its window under Xvfb with a software Vulkan adapter
//! (Mesa lavapipe), takes scripted screenshots of the Cornell box, and the pictures are
//! checked: red on the left, green on the right, brighter after 200 shots than after 1.
//!
//! Skips with a printed reason where there is no Xvfb or no Vulkan driver, except in CI
//! (`common::in_ci`), where that is a failure.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::skip;

fn which(program: &str) -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|d| d.join(program))
            .find(|p| p.is_file())
    })
}

fn vulkan_driver_present() -> bool {
    ["/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d"]
        .iter()
        .filter_map(|d| std::fs::read_dir(d).ok())
        .flatten()
        .any(|e| e.is_ok_and(|e| e.path().extension().is_some_and(|x| x == "json")))
}

struct Display {
    name: String,
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
fn display() -> Result<Display, String> {
    if let Ok(d) = std::env::var("DISPLAY")
        && !d.is_empty()
    {
        return Ok(Display {
            name: d,
            server: None,
        });
    }
    let xvfb = which("Xvfb").ok_or("DISPLAY is unset and Xvfb is not installed")?;
    for attempt in 0..20u32 {
        let n = 50 + (std::process::id() + attempt * 7) % 400;
        if Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()
            || Path::new(&format!("/tmp/.X{n}-lock")).exists()
        {
            continue;
        }
        let mut child = Command::new(&xvfb)
            .args([
                format!(":{n}").as_str(),
                "-screen",
                "0",
                "1280x800x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot start Xvfb: {e}"))?;
        let deadline = Instant::now() + Duration::from_secs(15);
        while Instant::now() < deadline {
            if Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() {
                return Ok(Display {
                    name: format!(":{n}"),
                    server: Some(child),
                });
            }
            if let Ok(Some(_)) = child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = child.kill();
        let _ = child.wait();
    }
    Err("Xvfb did not start".into())
}

struct Picture {
    width: usize,
    height: usize,
    rgb: Vec<[f64; 3]>,
}

impl Picture {
    fn load(path: &Path) -> Picture {
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
    fn mean(&self, x0: f64, x1: f64) -> [f64; 3] {
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

fn run_viewer(display: &Display, dir: &Path, shots: usize) -> (PathBuf, PathBuf) {
    let n = shots.to_string();
    run_viewer_with(
        display,
        dir,
        &format!("{shots}_shots"),
        &["--element-size", "25", "--after-shots", &n],
    )
}

/// Runs the viewer on the Cornell box with `args` (element size and when to take the
/// screenshot); returns the window and viewport PNGs, named after `tag`.
fn run_viewer_with(display: &Display, dir: &Path, tag: &str, args: &[&str]) -> (PathBuf, PathBuf) {
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
        .args([
            "--window",
            "900x600",
            "--no-highlight",
            "--no-ambient",
            "--screenshot",
        ])
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

#[test]
fn cornell_screenshots_show_red_left_green_right_and_brighten() {
    if !vulkan_driver_present() {
        skip("no Vulkan driver (install mesa-vulkan-drivers for lavapipe)");
        return;
    }
    let display = match display() {
        Ok(d) => d,
        Err(reason) => {
            skip(&reason);
            return;
        }
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let (w1, v1) = run_viewer(&display, dir.path(), 1);
    let (w200, v200) = run_viewer(&display, dir.path(), 200);
    for p in [&w1, &w200] {
        let pic = Picture::load(p);
        // The whole window, side panel included.
        assert!(
            pic.width >= 800 && pic.height >= 500,
            "{}x{}",
            pic.width,
            pic.height
        );
    }
    let early = Picture::load(&v1);
    let late = Picture::load(&v200);
    let lum = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let (l, m, r) = (
        late.mean(0.0, 1.0 / 3.0),
        late.mean(1.0 / 3.0, 2.0 / 3.0),
        late.mean(2.0 / 3.0, 1.0),
    );
    eprintln!("after 200 shots: left {l:.3?} middle {m:.3?} right {r:.3?}");
    // The light is orange, so every wall is warm; compare red/green balance with the middle.
    assert!(l[0] > l[1] && l[0] > l[2], "left third not reddish: {l:?}");
    assert!(
        l[0] / l[1] > 1.3 * m[0] / m[1],
        "left third not redder than the middle: {l:?} vs {m:?}"
    );
    assert!(
        r[1] / r[0] > 1.3 * m[1] / m[0],
        "right third not greener than the middle: {r:?} vs {m:?}"
    );
    assert!(r[1] > r[2], "right third not greenish: {r:?}");
    let (e, a) = (lum(early.mean(0.0, 1.0)), lum(late.mean(0.0, 1.0)));
    eprintln!("mean luminance (sRGB) after 1 shot {e:.4}, after 200 shots {a:.4}");
    assert!(a > 1.2 * e, "not brighter after 200 shots: {e} -> {a}");
}

/// `--solver gauss-seidel`: the gathering solve streams to the window and its converged
/// picture has the Cornell box's colours where shooting's has them (red left, green right).
#[test]
fn a_gauss_seidel_screenshot_is_lit_like_shootings() {
    if !vulkan_driver_present() {
        skip("no Vulkan driver (install mesa-vulkan-drivers for lavapipe)");
        return;
    }
    let display = match display() {
        Ok(d) => d,
        Err(reason) => {
            skip(&reason);
            return;
        }
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let (_, v) = run_viewer_with(
        &display,
        dir.path(),
        "gauss_seidel",
        &["--element-size", "40", "--solver", "gauss-seidel"],
    );
    let pic = Picture::load(&v);
    let lum = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let (l, m, r) = (
        pic.mean(0.0, 1.0 / 3.0),
        pic.mean(1.0 / 3.0, 2.0 / 3.0),
        pic.mean(2.0 / 3.0, 1.0),
    );
    eprintln!("gauss-seidel converged: left {l:.3?} middle {m:.3?} right {r:.3?}");
    assert!(
        l[0] / l[1] > 1.3 * m[0] / m[1],
        "left third not redder than the middle: {l:?} vs {m:?}"
    );
    assert!(
        r[1] / r[0] > 1.3 * m[1] / m[0],
        "right third not greener than the middle: {r:?} vs {m:?}"
    );
    // Lit by interreflection, not only the light: the walls are far from black.
    assert!(lum(m) > 0.1, "middle third too dark: {m:?}");
}
