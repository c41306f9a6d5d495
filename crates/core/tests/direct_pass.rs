//! The second pass's direct light per pixel (`render --pass direct`) against closed-form
//! form factors: a floor under a square light, a smaller square blocker between them.
//! Nothing but the floor reflects (light and blocker are black), so every floor pixel is
//! exactly `ρ E F_visible(x)`, whatever the mesh: the pass must reproduce it where constant
//! elements cannot.

use std::f64::consts::PI;
use std::sync::atomic::AtomicBool;

use glam::DVec3;
use nusselt_core::mesh::MeshSpec;
use nusselt_core::render::{Camera, RenderSettings};
use nusselt_core::scene::{LoadOptions, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, StopCriteria};

const OBJ: &str = "mtllib room.mtl
v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1
v 0.25 1 0.25\nv 0.75 1 0.25\nv 0.75 1 0.75\nv 0.25 1 0.75
v 0.4 0.5 0.4\nv 0.6 0.5 0.4\nv 0.6 0.5 0.6\nv 0.4 0.5 0.6
usemtl floor\nf 1 4 3 2
usemtl light\nf 5 6 7 8
usemtl blocker\nf 9 10 11 12\n";
const MTL: &str = "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 10 10 10
newmtl blocker\nKd 0 0 0\n";

/// Form factor from a point to a rectangle in a parallel plane at height 1, with one
/// corner straight above the point and sides `a`, `b` (signed: odd in each).
fn corner(a: f64, b: f64) -> f64 {
    let (sa, sb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
    (a / sa * (b / sa).atan() + b / sb * (a / sb).atan()) / (2.0 * PI)
}

/// Point at the origin of its plane, rectangle `[x1, x2] × [z1, z2]` at height `h`.
fn rect(x1: f64, x2: f64, z1: f64, z2: f64, h: f64) -> f64 {
    let c = |x: f64, z: f64| corner(x / h, z / h);
    c(x2, z2) - c(x1, z2) - c(x2, z1) + c(x1, z1)
}

/// The pixel values of a narrow view straight down at `(x, 0, z)`: the 4 × 4 pixels cover
/// 4e-5 of the floor, over which `F` changes by about 1e-4 of itself (its relative gradient
/// near the light's corner is ~2 per unit), hence the 5e-4 below.
fn pixels_at(s: &ProgressiveSolver, x: f64, z: f64) -> Vec<f64> {
    let settings = RenderSettings {
        width: 4,
        height: 4,
        spp: 4,
        camera: Camera {
            eye: DVec3::new(x + 1e-4, 0.05, z),
            target: DVec3::new(x, 0.0, z),
            vfov_deg: 0.05,
        },
        seed: 3,
        edge_spp: 0,
    };
    let image =
        nusselt_core::render::direct::render_solution(s.problem(), s.radiosity(), &settings);
    image.pixels.iter().map(|p| p.x).collect()
}

/// The floor room solved: after the light's shot nothing else carries light.
fn solved() -> ProgressiveSolver {
    solved_obj(OBJ)
}

/// A room of `obj` (materials `MTL`) solved to a residual of 1e-9.
fn solved_obj(obj: &str) -> ProgressiveSolver {
    let scene = Scene::from_obj_str(
        "room.obj",
        obj,
        &[("room.mtl", MTL)],
        &LoadOptions::default(),
    )
    .expect("scene");
    let config = SolverConfig {
        mesh: MeshSpec::sized(0.1, 0.25),
        ..Default::default()
    };
    let mut s = ProgressiveSolver::new(scene, config).expect("solver");
    let stop = StopCriteria {
        residual: 1e-9,
        ..Default::default()
    };
    s.run(&stop, &AtomicBool::new(false), &mut |_| {});
    s
}

/// `F_visible` at floor point `(x, z)`: the light `[0.25, 0.75]²` at height 1 minus the part
/// the blocker `[0.4, 0.6]²` at height 0.5 hides, its central projection from the point
/// onto the light's plane, `[0.8 − x, 1.2 − x] × [0.8 − z, 1.2 − z]`, clipped to the light.
fn visible(x: f64, z: f64) -> f64 {
    let light = rect(0.25 - x, 0.75 - x, 0.25 - z, 0.75 - z, 1.0);
    let (x1, x2) = ((0.8 - x).max(0.25), (1.2 - x).min(0.75));
    let (z1, z2) = ((0.8 - z).max(0.25), (1.2 - z).min(0.75));
    if x1 >= x2 || z1 >= z2 {
        return light;
    }
    light - rect(x1 - x, x2 - x, z1 - z, z2 - z, 1.0)
}

/// A view of the floor's quarter `[0.05, 0.45]²` from under the blocker, 32² pixels of
/// 1/80 of the room each, from the open floor into the blocker's penumbra: each pixel is
/// the pass's estimate of the mean of `ρ E F_visible` over its footprint, where most
/// pixels take the direct light from a plane through their four quadrants
/// (`direct::render`) and the steepest sample every point. The exact mean comes from a
/// 32 × 32 grid of closed-form values per pixel. Toward the blocker's corner `F` changes
/// by up to ~20 % across a pixel, where 16 jittered samples of a ramp miss its mean by
/// up to V/(m²√12) ≈ 0.36 % (m = 4); elsewhere a few hundredths of a percent. Hence 4e-3.
#[test]
fn pixels_of_a_penumbra_match_the_mean_of_the_closed_form() {
    let s = solved();
    let (rho, e) = (0.5, 10.0);
    let (w, h) = (32u32, 32u32);
    let camera = Camera {
        eye: DVec3::new(0.25, 0.45, 0.25),
        target: DVec3::new(0.25 + 1e-4, 0.0, 0.25),
        vfov_deg: 2.0 * (0.2f64 / 0.45).atan().to_degrees(),
    };
    let settings = RenderSettings {
        width: w,
        height: h,
        spp: 16,
        camera,
        seed: 5,
        edge_spp: 0,
    };
    let image =
        nusselt_core::render::direct::render_solution(s.problem(), s.radiosity(), &settings);
    let floor = |sx: f64, sy: f64| {
        let d = camera.ray_dir(sx, sy, w, h);
        let t = camera.eye.y / -d.y;
        let p = camera.eye + d * t;
        rho * e * visible(p.x, p.z)
    };
    let mut worst: (f64, u32, u32) = (0.0, 0, 0);
    for y in 0..h {
        for x in 0..w {
            const GRID: u32 = 32;
            let exact = (0..GRID * GRID)
                .map(|g| {
                    let sx = x as f64 + ((g % GRID) as f64 + 0.5) / GRID as f64;
                    let sy = y as f64 + ((g / GRID) as f64 + 0.5) / GRID as f64;
                    floor(sx, sy)
                })
                .sum::<f64>()
                / (GRID * GRID) as f64;
            let got = image.pixels[(y * w + x) as usize].x;
            let off = (got - exact).abs() / exact;
            eprint!("{:5.2} ", (got - exact) / exact * 100.0);
            if x == w - 1 {
                eprintln!();
            }
            if off > worst.0 {
                worst = (off, x, y);
            }
        }
    }
    assert!(
        worst.0 <= 4e-3,
        "pixel ({}, {}) is {:.3} % off the closed form",
        worst.1,
        worst.2,
        worst.0 * 100.0
    );
}

#[test]
fn direct_light_per_pixel_matches_the_closed_form_with_and_without_shadow() {
    let s = solved();
    let (rho, e) = (0.5, 10.0);
    // Under the middle: the light minus the blocker's shadow on the light's plane (the
    // blocker, at half the height, hides [0.3, 0.7]² of it), both centred above the point.
    let centre = rect(-0.25, 0.25, -0.25, 0.25, 1.0) - rect(-0.2, 0.2, -0.2, 0.2, 1.0);
    // Near a corner: the light seen from (0.1, 0.1) is [0.15, 0.65]² relative to it; the
    // blocker, at half the height, hides [0.6, 1.0]² on the light's plane, its corner
    // [0.6, 0.65]².
    let side = rect(0.15, 0.65, 0.15, 0.65, 1.0) - rect(0.6, 0.65, 0.6, 0.65, 1.0);
    for ((x, z), f) in [((0.5, 0.5), centre), ((0.1, 0.1), side)] {
        let expected = rho * e * f;
        for p in pixels_at(&s, x, z) {
            assert!(
                (p - expected).abs() <= 5e-4 * expected,
                "at ({x}, {z}): {p} vs {expected}"
            );
        }
    }
}

/// The light `[0.25, 0.75]²` cut into a 5 × 5 grid of quads over the open floor: 25
/// connected faces of one emission, lit as one light (`render/direct/many.rs`: point
/// kernels per facet, the exact factor within 8 facet sizes, rays drawn by kernel). With
/// nothing in the way every ray arrives, so each pixel is `ρ E F` to the kernels' error:
/// the facets (0.14 across) are within 8 sizes of the floor points (1.13) except, seen from
/// near a wall, the far side's, whose point kernels err by up to `(size / r)²` ≈ 1.5 % of
/// their small share, hence 1e-3 of the sum. Without the exact near facets, or without
/// the group, the test fails.
#[test]
fn a_light_of_many_faces_gives_the_closed_form() {
    let n = 5;
    let mut obj = String::from("mtllib room.mtl\nv 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\n");
    for i in 0..=n {
        for j in 0..=n {
            let (x, z) = (
                0.25 + 0.5 * i as f64 / n as f64,
                0.25 + 0.5 * j as f64 / n as f64,
            );
            obj += &format!("v {x} 1 {z}\n");
        }
    }
    obj += "usemtl floor\nf 1 4 3 2\nusemtl light\n";
    let at = |i: usize, j: usize| 5 + i * (n + 1) + j;
    for i in 0..n {
        for j in 0..n {
            // Wound to face down, as the single light quad above.
            obj += &format!(
                "f {} {} {} {}\n",
                at(i, j),
                at(i + 1, j),
                at(i + 1, j + 1),
                at(i, j + 1)
            );
        }
    }
    let s = solved_obj(&obj);
    let (rho, e) = (0.5, 10.0);
    for (x, z) in [(0.5, 0.5), (0.1, 0.1), (0.9, 0.3)] {
        let expected = rho * e * rect(0.25 - x, 0.75 - x, 0.25 - z, 0.75 - z, 1.0);
        for p in pixels_at(&s, x, z) {
            assert!(
                (p - expected).abs() <= 1e-3 * expected,
                "at ({x}, {z}): {p} vs {expected}"
            );
        }
    }
}
