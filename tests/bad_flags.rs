//! Command-line flags and scene values that used to get through: each is refused with a
//! message naming the flag or the value, before any work, and nothing panics or hangs.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use nusselt_core::mesh::MeshSpec;
use nusselt_core::scene::{LoadOptions, MaterialId, Rgb, Scene};
use nusselt_core::solver::{ProgressiveSolver, SolverConfig, SolverError, StopCriteria};

/// Runs the binary; returns (success, stderr). Killed (and the test failed) after `limit`,
/// so a check that regresses into an endless solve fails instead of hanging CI.
fn nusselt_within(args: &[&str], limit: Duration) -> (bool, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run nusselt");
    let start = Instant::now();
    loop {
        if child.try_wait().expect("wait").is_some() {
            break;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("nusselt {args:?} still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().expect("output");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Asserts that `args` fail with `expected` in the message, without a panic, within `limit`.
fn refused_within(args: &[&str], expected: &str, limit: Duration) {
    let (ok, stderr) = nusselt_within(args, limit);
    assert!(!ok, "{args:?} should fail");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    assert!(
        stderr.contains(expected),
        "{args:?}: stderr {stderr:?} lacks {expected:?}"
    );
}

fn refused(args: &[&str], expected: &str) {
    refused_within(args, expected, Duration::from_secs(120));
}

/// A floor lit by a ceiling light of radiance `ke` (grey), as OBJ + MTL in `dir`.
fn lit_floor(dir: &Path, ke: &str) -> PathBuf {
    let obj = dir.join("lit.obj");
    std::fs::write(
        &obj,
        "mtllib lit.mtl\n\
         v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\n\
         v 0.25 1 0.25\nv 0.75 1 0.25\nv 0.75 1 0.75\nv 0.25 1 0.75\n\
         usemtl floor\nf 1 4 3 2\n\
         usemtl light\nf 5 6 7 8\n",
    )
    .expect("write obj");
    std::fs::write(
        dir.join("lit.mtl"),
        format!("newmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe {ke} {ke} {ke}\n"),
    )
    .expect("write mtl");
    obj
}

#[test]
fn screenshot_waits_are_bounded_instead_of_panicking() {
    // 1e20 s is past u64 seconds: Duration::from_secs_f64 panicked on it.
    let dir = tempfile::tempdir().expect("tempdir");
    let shot = dir.path().join("s.png");
    let shot = shot.to_str().expect("utf-8");
    for t in ["1e20", "inf", "0", "-1", "86401"] {
        let flag = format!("--screenshot-timeout={t}");
        refused(
            &["view", "--screenshot", shot, &flag],
            "--screenshot-timeout must be a number of seconds in (0, 86400]",
        );
    }
    refused(
        &["view", "--screenshot", shot, "--after-seconds", "1e20"],
        "--after-seconds must be in 0..=86400",
    );
}

#[test]
fn image_sizes_and_sample_counts_have_upper_bounds() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.png");
    let out = out.to_str().expect("utf-8");
    let base = [
        "render",
        "--builtin",
        "cornell",
        "--out",
        out,
        "--shots",
        "1",
    ];
    let with =
        |extra: &[&'static str]| -> Vec<&str> { base.iter().chain(extra).copied().collect() };
    let cases: [(&[&str], &str); 9] = [
        (
            &["--width", "8193"],
            "--width must be in 1..=8192, got 8193",
        ),
        (
            &["--height", "16384"],
            "--height must be in 1..=8192, got 16384",
        ),
        (&["--width", "0"], "--width must be in 1..=8192, got 0"),
        (&["--spp", "1048577"], "--spp must be in 1..=1048576"),
        (&["--spp", "0"], "--spp must be in 1..=1048576, got 0"),
        (&["--rays", "67108865"], "--rays must be in 1..=67108864"),
        (&["--rays", "0"], "--rays must be in 1..=67108864, got 0"),
        (
            &["--vis-rays", "1048577"],
            "--vis-rays must be in 1..=1048576",
        ),
        (
            &["--vis-rays", "0"],
            "--vis-rays must be in 1..=1048576, got 0",
        ),
    ];
    for (extra, expected) in cases {
        refused(&with(extra), expected);
    }
    // The path tracer shares the image flags.
    refused(
        &[
            "reference",
            "--builtin",
            "cornell",
            "--out",
            out,
            "--spp",
            "2000000",
        ],
        "--spp must be in 1..=1048576",
    );
    // The largest accepted values pass the check (and fail only later, on purpose, here
    // on a scene that does not exist) — the bounds are inclusive.
    refused(
        &[
            "render",
            "/nonexistent/scene.obj",
            "--out",
            out,
            "--rays",
            "67108864",
            "--vis-rays",
            "1048576",
        ],
        "/nonexistent/scene.obj",
    );
    // formfactor's sample counts.
    let cases_file = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/formfactors.json");
    let cases_file = cases_file.to_str().expect("utf-8");
    refused(
        &["formfactor", cases_file, "--rays", "67108865"],
        "--rays must be in 1..=67108864",
    );
    refused(
        &["formfactor", cases_file, "--vis-rays", "0"],
        "--vis-rays must be in 1..=1048576, got 0",
    );
}

#[test]
fn patch_size_must_be_a_positive_number() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.png");
    let out = out.to_str().expect("utf-8");
    for p in ["NaN", "0", "-0.1", "inf"] {
        refused(
            &[
                "render",
                "--builtin",
                "cornell",
                "--out",
                out,
                "--shots",
                "1",
                "--patch-size",
                p,
            ],
            "--patch-size must be a positive number",
        );
    }
}

#[test]
fn output_paths_are_checked_before_the_scene_is_even_read() {
    // The scene does not exist: if the output were checked after loading (or after the
    // solve, as before), the message would be about the scene.
    let dir = tempfile::tempdir().expect("tempdir");
    let missing = "/nonexistent/scene.obj";
    let bmp = dir.path().join("x.bmp");
    let bmp = bmp.to_str().expect("utf-8");
    for cmd in ["render", "reference"] {
        refused(&[cmd, missing, "--out", bmp], "unknown image extension");
        refused(
            &[cmd, missing, "--out", "/nonexistent/folder/x.png"],
            "the folder /nonexistent/folder does not exist",
        );
    }
    let png = dir.path().join("x.png");
    let png = png.to_str().expect("utf-8");
    refused(
        &[
            "render",
            missing,
            "--out",
            png,
            "--log",
            "/nonexistent/folder/log.csv",
        ],
        "--log /nonexistent/folder/log.csv: the folder /nonexistent/folder does not exist",
    );
    refused(
        &[
            "render",
            missing,
            "--out",
            png,
            "--elements-csv",
            "/nonexistent/folder/e.csv",
        ],
        "--elements-csv /nonexistent/folder/e.csv",
    );
    refused(
        &["view", missing, "--screenshot", "/nonexistent/folder/s.png"],
        "--screenshot /nonexistent/folder/s.png",
    );
}

#[test]
fn overflowing_emission_is_refused_and_render_ends() {
    // Ke = 1e308 per channel: Σ Ke × area overflows to infinity, the unshot fraction was
    // inf/inf = NaN, `NaN <= target` never held, and a render without --shots/--seconds
    // never ended. The limit makes a regression fail instead of hang.
    let dir = tempfile::tempdir().expect("tempdir");
    let obj = lit_floor(dir.path(), "1e308");
    let out = dir.path().join("x.png");
    refused_within(
        &[
            "render",
            obj.to_str().expect("utf-8"),
            "--out",
            out.to_str().expect("utf-8"),
        ],
        "the emitted power",
        Duration::from_secs(60),
    );
    assert!(!out.exists(), "no image for a refused scene");
}

#[test]
fn the_solver_refuses_power_that_would_overflow_and_keeps_its_state() {
    let dir = tempfile::tempdir().expect("tempdir");
    let opts = LoadOptions::default();
    // Finite Ke whose power overflows only through interreflection: 1e306 × 3 channels ×
    // 0.25 m² is 7.5e305, finite, but the floor's ρ = 0.999 multiplies what a solve
    // carries by 1000.
    let hot = lit_floor(dir.path(), "1e306");
    std::fs::write(
        dir.path().join("lit.mtl"),
        "newmtl floor\nKd 0.999 0.999 0.999\nnewmtl light\nKd 0 0 0\nKe 1e306 1e306 1e306\n",
    )
    .expect("write mtl");
    let scene = Scene::load_obj(&hot, &opts).expect("loads: every value is finite");
    let config = || SolverConfig {
        mesh: MeshSpec::element(0.25),
        ..Default::default()
    };
    match ProgressiveSolver::new(scene, config()) {
        Err(SolverError::PowerOverflow { emitted }) => {
            assert!(emitted.is_finite() && emitted > 1e305, "{emitted}");
        }
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a solve whose power overflows was accepted"),
    }

    // An ordinary scene, then an edit that would overflow: refused, nothing changes.
    let obj = lit_floor(dir.path(), "10");
    let scene = Scene::load_obj(&obj, &opts).expect("load");
    let light = MaterialId(
        scene
            .materials
            .iter()
            .position(|m| m.name == "light")
            .expect("light") as u32,
    );
    let mut solver = ProgressiveSolver::new(scene, config()).expect("solver");
    let never = AtomicBool::new(false);
    solver.shoot(&never).expect("one shot");
    let before_radiosity = solver.radiosity().to_vec();
    let before_fraction = solver.unshot_fraction();
    let err = solver
        .set_material(light, Rgb::ZERO, Rgb::splat(1e308))
        .expect_err("overflowing emission");
    assert!(err.to_string().contains("emitted power"), "{err}");
    assert_eq!(solver.radiosity(), &before_radiosity[..]);
    assert_eq!(solver.unshot_fraction(), before_fraction);
    let m = &solver.scene().materials[light.0 as usize];
    assert_eq!(m.emission, Rgb::splat(10.0));
    // A large but safe edit still goes through, and the solve to a target ends.
    solver
        .set_material(light, Rgb::ZERO, Rgb::splat(1e200))
        .expect("large but finite power");
    solver.run(
        &StopCriteria {
            residual: 1e-3,
            max_steps: Some(10_000),
            max_seconds: None,
            tolerance: None,
        },
        &never,
        &mut |r| assert!(r.unshot_fraction.is_finite(), "{r:?}"),
    );
    assert!(
        solver.unshot_fraction() <= 1e-3,
        "{}",
        solver.unshot_fraction()
    );
}

/// `--solver`, `--omega` and `--max-memory` are refused with a message naming the flag or
/// the size, before any long work: an unknown solver name, ω outside (0, 2) (SOR diverges
/// there), and a matrix larger than the memory allowed (never an out-of-memory kill).
#[test]
fn solver_flags_are_checked() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.png");
    let out = out.to_str().expect("utf-8");
    let base = ["render", "--builtin", "cornell", "--out", out, "--quiet"];
    let with = |extra: &[&'static str]| -> Vec<&str> {
        base.iter().copied().chain(extra.iter().copied()).collect()
    };
    refused(&with(&["--solver", "newton"]), "unknown --solver 'newton'");
    refused(&with(&["--solver", "sor", "--omega", "2.5"]), "--omega");
    refused(&with(&["--solver", "sor", "--omega", "0"]), "--omega");
    refused(
        &with(&["--solver", "gauss-seidel", "--max-memory", "1"]),
        "--max-memory",
    );
    refused(&with(&["--max-memory", "0"]), "--max-memory");
    refused(
        &with(&["--solver", "cg", "--omega", "1.5"]),
        "--omega is a setting of --solver sor; --solver cg does not use it",
    );
    refused(
        &with(&["--omega", "1.5"]),
        "--solver auto (shooting or hierarchical) does not use it",
    );
    refused(
        &with(&["--solver", "shooting", "--omega", "1.5"]),
        "--solver shooting does not use it",
    );
    // Settings a solver would ignore are refused, naming the flag (the registry's rows).
    refused(
        &with(&["--solver", "hierarchical", "--formfactor", "hemicube"]),
        "--formfactor is a setting of --solver shooting and jacobi",
    );
    refused(
        &with(&["--solver", "wavelet", "--no-overshoot"]),
        "--no-overshoot is a setting of --solver shooting; --solver wavelet does not use it",
    );
    refused(
        &with(&["--solver", "cg", "--ambient", "global"]),
        "--ambient is a setting of --solver shooting",
    );
    refused(
        &with(&["--formfactor", "hemicube", "--link-tolerance", "0.01"]),
        "settings of different solvers",
    );
    refused(
        &with(&["--solver", "hierarchical", "--link-tolerance", "0"]),
        "--link-tolerance must be a positive number",
    );
    // Under the default (auto), --link-tolerance chooses the hierarchy; a solver that has no
    // links refuses it.
    refused(
        &with(&["--solver", "shooting", "--link-tolerance", "0.01"]),
        "--link-tolerance is a setting of --solver hierarchical and wavelet; --solver shooting does not use it",
    );
    refused(&with(&["--tolerance", "0"]), "--tolerance");
    refused(&with(&["--tolerance", "nan"]), "--tolerance");
    refused(&with(&["--ambient", "local"]), "unknown --ambient 'local'");
    refused(&with(&["--pass", "photon"]), "unknown --pass 'photon'");
    refused(
        &with(&["--time-budget", "-2"]),
        "--time-budget must be a positive number",
    );
    refused(
        &with(&["--pass", "direct", "--time-budget", "5"]),
        "--time-budget chooses the pass of --pass auto",
    );
    refused(
        &with(&["--pass", "gather", "--gather-rays", "0"]),
        "--gather-rays must be between 1 and 65536",
    );
    refused(
        &with(&["--adaptive", "-1"]),
        "--adaptive must be a positive number",
    );
    refused(
        &with(&["--adaptive", "0.1", "--adaptive-passes", "9"]),
        "--adaptive-passes",
    );
}

/// `nusselt view --solver/--omega`: the same names as `render`, ω only with sor and in
/// (0, 2), refused before a window opens (no display is needed to see the refusal).
#[test]
fn view_solver_flags_are_checked() {
    let dir = tempfile::tempdir().expect("tempdir");
    let shot = dir.path().join("s.png");
    let shot = shot.to_str().expect("utf-8");
    let base = ["view", "--screenshot", shot];
    let with = |extra: &[&'static str]| -> Vec<&str> {
        base.iter().copied().chain(extra.iter().copied()).collect()
    };
    refused(&with(&["--solver", "newton"]), "unknown --solver 'newton'");
    refused(
        &with(&["--solver", "jacobi", "--omega", "1.5"]),
        "--omega is a setting of --solver sor; --solver jacobi does not use it",
    );
    refused(&with(&["--omega", "1.5"]), "--solver shooting");
    refused(
        &with(&["--solver", "sor", "--omega", "2.5"]),
        "--omega must be in (0, 2)",
    ); // Teaching views: an unknown one is refused, and the message lists them.
    refused(
        &with(&["--teach", "lecture"]),
        "unknown --teach 'lecture' (the views: step, hemicube",
    );
    refused(&with(&["--projector"]), "--teach");
}

#[test]
fn bad_lights_are_refused_before_any_work() {
    let fast = Duration::from_secs(20);
    for (flag, value, expected) in [
        (
            "--sun",
            "0,0,0,1,1,1",
            "--sun 0,0,0,1,1,1: the direction X,Y,Z must not be zero",
        ),
        ("--sun", "0,1,0,1,-1,1", "non-negative"),
        ("--point", "0,1,0,1,1", "expected 6 numbers, got 5"),
        ("--sky", "1,nan,1", "not a finite number"),
    ] {
        refused_within(
            &[
                "render",
                "--builtin",
                "gallery",
                flag,
                value,
                "--out",
                "/tmp/x.png",
            ],
            expected,
            fast,
        );
    }
}

#[test]
fn an_unlit_model_is_refused_only_when_asked() {
    let dir = tempfile::tempdir().expect("temp dir");
    let obj = dir.path().join("dark.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 1 0 1\nf 1 3 2\n").expect("obj");
    let obj = obj.to_str().expect("utf-8 path");
    refused(
        &["render", obj, "--no-default-lights", "--out", "/tmp/x.png"],
        "no emitter",
    );
    let out = dir.path().join("dark.png");
    let (ok, stderr) = nusselt_within(
        &[
            "render",
            obj,
            "--width",
            "16",
            "--height",
            "16",
            "--out",
            out.to_str().unwrap(),
        ],
        Duration::from_secs(120),
    );
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("no light in the model: added a sky"),
        "{stderr}"
    );
}

/// A memory budget too small for the mesh asked for is refused in seconds (before meshing a
/// million elements), naming the budget and the flags that would fit.
#[test]
fn a_mesh_over_the_memory_budget_is_refused_in_seconds() {
    let out = std::env::temp_dir().join("nusselt-never-written.png");
    let args = [
        "render",
        "--builtin",
        "cornell",
        "--element-size",
        "1.4",
        "--max-memory",
        "512",
        "--out",
        out.to_str().expect("utf-8 temp dir"),
    ];
    for expected in ["memory budget of 512 MiB", "--element-size 2.", "or more"] {
        refused_within(&args, expected, Duration::from_secs(10));
    }
}
