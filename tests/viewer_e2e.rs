//! End to end: the real binary opens its window under Xvfb with a software Vulkan adapter
//! (Mesa lavapipe), takes scripted screenshots of the Cornell box, and the pictures are
//! checked: red on the left, green on the right, brighter after 200 shots than after 1.
//!
//! Skips with a printed reason where there is no Xvfb or no Vulkan driver, except in CI
//! (`common::in_ci`), where that is a failure.

use std::path::{Path, PathBuf};

mod common;
use common::display::{Display, Picture, display, run_viewer_with, vulkan_driver_present};
use common::skip;

fn run_viewer(display: &Display, dir: &Path, shots: usize) -> (PathBuf, PathBuf) {
    let n = shots.to_string();
    run_viewer_with(
        display,
        dir,
        &format!("{shots}_shots"),
        &["--element-size", "25", "--after-shots", &n],
    )
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

/// The ray-traced view (`--ray-traced`, the second pass refined on its own thread) is drawn
/// over the viewport: the screenshot waits for 16 samples per pixel of the converged
/// solution, shows the same lit box as the rasterised view (red left, green right, about
/// as bright: the same solution, the direct part computed per pixel), and differs from it
/// (per-pixel shadows and shading instead of interpolated elements).
#[test]
fn the_ray_traced_view_shows_the_same_box_per_pixel() {
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
    let common = ["--element-size", "40", "--window", "700x500"];
    let (_, plain) = run_viewer_with(&display, dir.path(), "raster", &common);
    let with: Vec<&str> = common.iter().copied().chain(["--ray-traced"]).collect();
    let (_, traced) = run_viewer_with(&display, dir.path(), "ray_traced", &with);
    let (plain, traced) = (Picture::load(&plain), Picture::load(&traced));
    let lum = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    let (l, m, r) = (
        traced.mean(0.0, 1.0 / 3.0),
        traced.mean(1.0 / 3.0, 2.0 / 3.0),
        traced.mean(2.0 / 3.0, 1.0),
    );
    eprintln!("ray-traced: left {l:.3?} middle {m:.3?} right {r:.3?}");
    eprintln!(
        "rasterised: left {:.3?} middle {:.3?} right {:.3?}",
        plain.mean(0.0, 1.0 / 3.0),
        plain.mean(1.0 / 3.0, 2.0 / 3.0),
        plain.mean(2.0 / 3.0, 1.0)
    );
    assert!(l[0] / l[1] > 1.3 * m[0] / m[1], "left not red: {l:?} {m:?}");
    assert!(
        r[1] / r[0] > 1.15 * m[1] / m[0],
        "right not green: {r:?} {m:?}"
    );
    let (lt, lp) = (lum(traced.mean(0.0, 1.0)), lum(plain.mean(0.0, 1.0)));
    let differ = traced
        .rgb
        .iter()
        .zip(&plain.rgb)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).abs()).sum::<f64>() / 3.0)
        .sum::<f64>()
        / traced.rgb.len() as f64;
    eprintln!("mean luminance: ray-traced {lt:.3}, rasterised {lp:.3}; differ by {differ:.4}");
    assert!(
        (lt - lp).abs() < 0.15 * lp,
        "not the same solution: {lt} vs {lp}"
    );
    assert!(differ > 0.003, "the ray-traced view is not drawn: {differ}");
}
