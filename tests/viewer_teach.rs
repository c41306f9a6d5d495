//! Teaching mode end to end: `nusselt view --teach step|hemicube|nusselt|matrix --screenshot`
//! under Xvfb with lavapipe (as `viewer_e2e.rs`), checked against the plain view: the Teach
//! panel is there (the right of the window differs from the plain view's); the hemicube
//! view draws the item buffer (both the red and the green wall appear on the right of the
//! window, where the plain view shows only the green one); the matrix view colours the
//! scene by the shooter's column (heat-scale yellow, which the lit scene never is); the
//! Nusselt view draws the projection's cyan outline; the compare view draws the lit
//! shooting image beside the still mostly dark gathering one; the mesh view draws two
//! different meshes of the lit box. The
//! numbers the views show are tested against the solver in the unit tests of
//! `viewer::teach::{step, hemicube, nusselt, matrix}`.
//!
//! Skips with a printed reason where there is no Xvfb or no Vulkan driver, except in CI.

mod common;
use common::display::{Picture, display, run_viewer_with, vulkan_driver_present};
use common::skip;

/// Mean absolute difference (0…1) over the columns [x0, x1) as fractions of the width.
fn difference(a: &Picture, b: &Picture, x0: f64, x1: f64) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let (c0, c1) = (
        (x0 * a.width as f64) as usize,
        (x1 * a.width as f64) as usize,
    );
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in 0..a.height {
        for x in c0..c1 {
            let (p, q) = (a.rgb[y * a.width + x], b.rgb[y * a.width + x]);
            sum += (0..3).map(|c| (p[c] - q[c]).abs()).sum::<f64>() / 3.0;
            n += 1.0;
        }
    }
    sum / n
}

/// Mean brightness (0…1) of the window region [x0, x1) × [y0, y1) (fractions).
fn brightness(p: &Picture, (x0, x1): (f64, f64), (y0, y1): (f64, f64)) -> f64 {
    let cols = (x0 * p.width as f64) as usize..(x1 * p.width as f64) as usize;
    let rows = (y0 * p.height as f64) as usize..(y1 * p.height as f64) as usize;
    let n = (cols.len() * rows.len()) as f64;
    rows.flat_map(|y| cols.clone().map(move |x| (x, y)))
        .map(|(x, y)| p.rgb[y * p.width + x].iter().sum::<f64>() / 3.0)
        .sum::<f64>()
        / n
}

/// Pixels in the columns [x0, x1) that are clearly red, and clearly green.
fn red_and_green(p: &Picture, x0: f64, x1: f64) -> (usize, usize) {
    let (c0, c1) = (
        (x0 * p.width as f64) as usize,
        (x1 * p.width as f64) as usize,
    );
    let (mut red, mut green) = (0, 0);
    for y in 0..p.height {
        for x in c0..c1 {
            let [r, g, b] = p.rgb[y * p.width + x];
            if r > 0.35 && r > 2.0 * g && r > 2.0 * b {
                red += 1;
            }
            if g > 0.25 && g > 1.3 * r && g > 1.3 * b {
                green += 1;
            }
        }
    }
    (red, green)
}

// Long by design: one test starts the viewer under Xvfb once per teaching view and checks
// each screenshot in turn; split, every part would need the same display and set-up.
#[test]
fn teach_screenshots_show_each_view() {
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
    let common = ["--element-size", "40", "--window", "1200x700"];
    let with = |extra: &[&'static str]| -> Vec<&str> {
        common
            .iter()
            .copied()
            .chain(extra.iter().copied())
            .collect()
    };
    let (plain, _) = run_viewer_with(
        &display,
        dir.path(),
        "plain",
        &with(&["--after-shots", "3"]),
    );
    let (step, _) = run_viewer_with(
        &display,
        dir.path(),
        "step",
        &with(&["--teach", "step", "--after-shots", "3"]),
    );
    let (cube, _) = run_viewer_with(
        &display,
        dir.path(),
        "hemicube",
        &with(&["--teach", "hemicube", "--after-shots", "1"]),
    );
    let (matrix_window, matrix_viewport) = run_viewer_with(
        &display,
        dir.path(),
        "matrix",
        &with(&["--teach", "matrix", "--after-shots", "2"]),
    );
    let (nusselt, _) = run_viewer_with(
        &display,
        dir.path(),
        "nusselt",
        &with(&["--teach", "nusselt", "--after-shots", "1"]),
    );
    let (compare, _) = run_viewer_with(
        &display,
        dir.path(),
        "compare",
        &with(&["--teach", "compare", "--after-shots", "20"]),
    );
    let (mesh, _) = run_viewer_with(&display, dir.path(), "mesh", &with(&["--teach", "mesh"]));
    let (_, plain_viewport) = run_viewer_with(
        &display,
        dir.path(),
        "plain_viewport",
        &with(&["--after-shots", "2"]),
    );
    let (plain, step, cube) = (
        Picture::load(&plain),
        Picture::load(&step),
        Picture::load(&cube),
    );
    // The Teach panel takes the right of the window.
    let d_step = difference(&step, &plain, 0.75, 1.0);
    let d_cube = difference(&cube, &plain, 0.75, 1.0);
    eprintln!("right quarter vs the plain view: step {d_step:.3}, hemicube {d_cube:.3}");
    assert!(
        d_step > 0.05,
        "step mode looks like the plain view: {d_step}"
    );
    assert!(
        d_cube > 0.05,
        "the hemicube view looks like the plain view: {d_cube}"
    );
    let (pr, pg) = red_and_green(&plain, 0.75, 1.0);
    let (cr, cg) = red_and_green(&cube, 0.75, 1.0);
    eprintln!("red/green pixels on the right: plain {pr}/{pg}, hemicube {cr}/{cg}");
    assert!(pr < 50, "the plain view has red on its right: {pr}");
    assert!(
        cr > 200 && cg > 200,
        "the item buffer does not show both walls: {cr} red, {cg} green"
    );
    // The matrix view: its panel, and the scene coloured by the shooter's column on the
    // heat scale (saturated yellow where F_ij is large), which the lit scene never is.
    let d_matrix = difference(&Picture::load(&matrix_window), &plain, 0.75, 1.0);
    let yellow = |p: &Picture| {
        let n = p
            .rgb
            .iter()
            .filter(|[r, g, b]| *r > 0.85 && *g > 0.75 && *b < 0.5)
            .count();
        n as f64 / p.rgb.len() as f64
    };
    let (ym, yp) = (
        yellow(&Picture::load(&matrix_viewport)),
        yellow(&Picture::load(&plain_viewport)),
    );
    eprintln!(
        "matrix: right quarter differs by {d_matrix:.3}; yellow viewport {ym:.3} vs plain {yp:.3}"
    );
    assert!(
        d_matrix > 0.05,
        "the matrix view looks like the plain view: {d_matrix}"
    );
    // The Nusselt view: the projection's cyan outline on the disk.
    let cyan = |p: &Picture| {
        let c0 = p.width * 3 / 4;
        (0..p.height)
            .flat_map(|y| (c0..p.width).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let [r, g, b] = p.rgb[y * p.width + x];
                r < 0.3 && g > 0.7 && b > 0.8
            })
            .count()
    };
    let (cn, cp) = (cyan(&Picture::load(&nusselt)), cyan(&plain));
    eprintln!("nusselt: {cn} cyan pixels on the right (plain {cp})");
    assert!(
        cn > 50 && cp == 0,
        "no projection outline: {cn} vs plain {cp}"
    );
    assert!(
        ym > 0.03 && yp < 0.005,
        "no column colours: {ym} vs plain {yp}"
    );
    // Compare and mesh draw two images side by side where the viewport was (1200×700:
    // the left image spans about 26–45 % of the width, the right one 48–67 %, the top
    // 9–40 % of the height). After 20 of 133 steps shooting has lit the box; gathering
    // has updated 20 patches of the floor.
    let (left, right, rows) = ((0.27, 0.44), (0.49, 0.66), (0.10, 0.38));
    let compare = Picture::load(&compare);
    let (shoot, gather) = (
        brightness(&compare, left, rows),
        brightness(&compare, right, rows),
    );
    eprintln!("compare: shooting image {shoot:.3}, gathering image {gather:.3}");
    assert!(
        shoot > 0.15 && shoot > 2.0 * gather,
        "shooting should be lit and gathering mostly dark: {shoot} vs {gather}"
    );
    let mesh = Picture::load(&mesh);
    let (uniform, adaptive) = (
        brightness(&mesh, left, rows),
        brightness(&mesh, right, rows),
    );
    let meshes_differ = difference_in(&mesh, left, right, rows);
    eprintln!("mesh: uniform {uniform:.3}, adaptive {adaptive:.3}, differ by {meshes_differ:.3}");
    assert!(uniform > 0.15 && adaptive > 0.15, "{uniform} {adaptive}");
    assert!(
        meshes_differ > 0.02,
        "the two meshes look the same: {meshes_differ}"
    );
}

/// Mean absolute difference between two equally wide column ranges of one picture.
fn difference_in(p: &Picture, a: (f64, f64), b: (f64, f64), (y0, y1): (f64, f64)) -> f64 {
    let w = ((a.1 - a.0) * p.width as f64) as usize;
    let (xa, xb) = (
        (a.0 * p.width as f64) as usize,
        (b.0 * p.width as f64) as usize,
    );
    let rows = (y0 * p.height as f64) as usize..(y1 * p.height as f64) as usize;
    let n = (w * rows.len()) as f64;
    rows.flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (c, d) = (p.rgb[y * p.width + xa + x], p.rgb[y * p.width + xb + x]);
            (0..3).map(|k| (c[k] - d[k]).abs()).sum::<f64>() / 3.0
        })
        .sum::<f64>()
        / n
}
