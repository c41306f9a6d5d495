//! `nusselt render` / `nusselt reference` through the command line: outputs, camera
//! convention, logs and the JSON summary.

use std::path::Path;
use std::process::Command;

use nusselt_core::render::Image;

fn nusselt(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(args)
        .output()
        .expect("run nusselt");
    assert!(
        out.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8")
}

fn mean_rgb(img: &Image, x0: u32, x1: u32) -> [f64; 3] {
    let mut s = [0.0; 3];
    let mut n = 0.0;
    for y in img.height / 4..img.height * 3 / 4 {
        for x in x0..x1 {
            let p = img.get(x, y);
            s[0] += p.x;
            s[1] += p.y;
            s[2] += p.z;
            n += 1.0;
        }
    }
    s.map(|v| v / n)
}

// Long by design: one render writes every output (image, log, element CSV, JSON), and each
// output is checked in turn against that same run (a split would render once per output).
#[test]
fn cornell_render_has_the_red_wall_on_the_left_and_writes_every_output() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let p = |name: &str| d.join(name).to_str().expect("utf-8").to_string();
    let summary = nusselt(&[
        "render",
        "--builtin",
        "cornell",
        "--element-size",
        "40",
        "--patch-size",
        "80",
        "--width",
        "48",
        "--height",
        "48",
        "--spp",
        "4",
        "--out",
        &p("c.pfm"),
        "--log",
        &p("conv.csv"),
        "--elements-csv",
        &p("el.csv"),
        "--json",
        "--quiet",
    ]);
    let json: serde_json::Value = serde_json::from_str(summary.trim()).expect("one JSON line");
    for key in [
        "elements",
        "vertices",
        "shots",
        "solve_seconds",
        "render_seconds",
        "unshot_fraction",
    ] {
        assert!(json[key].is_number(), "summary lacks {key}: {json}");
    }
    assert!(json["error"].is_null());
    assert!(json["unshot_fraction"].as_f64().expect("number") <= 1e-4);
    // The default solver is auto; on a small scene it shoots, and says why.
    assert_eq!(json["solver"], "shooting");
    let why = json["solver_auto"].as_str().expect("auto's reason");
    assert!(
        why.starts_with("shooting: ") && why.contains("elements"),
        "{why}"
    );

    let img = Image::load_pfm(Path::new(&p("c.pfm"))).expect("pfm");
    assert_eq!((img.width, img.height), (48, 48));
    let left = mean_rgb(&img, 2, 10);
    let right = mean_rgb(&img, 38, 46);
    assert!(
        left[0] > 2.0 * left[1],
        "left edge should be the red wall: {left:?}"
    );
    assert!(
        right[1] > 2.0 * right[0],
        "right edge should be the green wall: {right:?}"
    );

    let log = std::fs::read_to_string(p("conv.csv")).expect("log");
    let mut lines = log.lines();
    assert_eq!(lines.next(), Some("shot,seconds,unshot_fraction,ambient"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().expect("number")).collect())
        .collect();
    assert_eq!(rows.len() as u64, json["shots"].as_u64().expect("shots"));
    assert!(
        rows.windows(2).all(|w| w[1][0] == w[0][0] + 1.0),
        "one row per shot"
    );
    assert!(rows.last().expect("rows")[2] <= 1e-4);

    let el = std::fs::read_to_string(p("el.csv")).expect("elements csv");
    assert_eq!(el.lines().next(), Some("patch,area,cx,cy,cz,r,g,b"));
    assert_eq!(
        el.lines().count() as u64 - 1,
        json["elements"].as_u64().expect("elements")
    );
    // Patch = index of the input face in file order: the light is the last of 19 faces.
    let max_patch = el
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .next()
                .expect("patch")
                .parse::<usize>()
                .expect("int")
        })
        .max();
    assert_eq!(max_patch, Some(18));

    // Other formats by extension.
    for ext in ["png", "exr"] {
        nusselt(&[
            "render",
            "--builtin",
            "cornell",
            "--element-size",
            "60",
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "1",
            "--out",
            &p(&format!("c.{ext}")),
            "--quiet",
        ]);
        assert!(
            std::fs::metadata(p(&format!("c.{ext}")))
                .expect("written")
                .len()
                > 100
        );
    }
}

#[test]
fn render_reports_its_error_against_a_reference() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |name: &str| dir.path().join(name).to_str().expect("utf-8").to_string();
    let common = ["--builtin", "cornell", "--width", "24", "--height", "24"];
    nusselt(
        &[
            &["reference"][..],
            &common[..],
            &["--spp", "64", "--out", &p("ref.pfm"), "--quiet"],
        ]
        .concat(),
    );
    let out = nusselt(
        &[
            &["render"][..],
            &common[..],
            &[
                "--element-size",
                "40",
                "--out",
                &p("r.pfm"),
                "--reference",
                &p("ref.pfm"),
                "--json",
                "--quiet",
            ],
        ]
        .concat(),
    );
    let json: serde_json::Value = serde_json::from_str(out.trim()).expect("json");
    let error = json["error"].as_f64().expect("error is reported");
    let compare = |image: &str, reference: &str| {
        let out = nusselt(&[
            "compare",
            "--builtin",
            "cornell",
            "--image",
            image,
            "--reference",
            reference,
        ]);
        let v: serde_json::Value = serde_json::from_str(out.trim()).expect("json");
        v["error"].as_f64().expect("error")
    };
    // `compare` uses the same mask: it reproduces the render's figure, and 0 for itself.
    assert!((compare(&p("r.pfm"), &p("ref.pfm")) - error).abs() < 1e-6 * error);
    assert_eq!(compare(&p("ref.pfm"), &p("ref.pfm")), 0.0);
    // The metric is the relative RMS √(Σ‖I − R‖²/Σ‖R‖²): the reference halved (exact in
    // binary, so the PFM holds it exactly) is 0.5 off whatever pixels the mask keeps.
    let mut scaled = Image::load_pfm(Path::new(&p("ref.pfm"))).expect("reference");
    for px in &mut scaled.pixels {
        *px *= 0.5;
    }
    scaled
        .save(Path::new(&p("scaled.pfm")), 1.0)
        .expect("write");
    let e = compare(&p("scaled.pfm"), &p("ref.pfm"));
    assert!((e - 0.5).abs() < 1e-12, "halved: {e}");
    // Lower bound from the reference's own noise. A second 64-spp reference (another seed)
    // differs from the first by √2 σ (σ: one reference's relative noise). The render does
    // not share the reference's noise, so its error is √(bias² + σ² + its own noise) ≥ σ in
    // expectation; over the ~500 masked pixels that estimate of σ² scatters by about
    // √(2/500) ≈ 6 %, so 0.8 σ is 3 of those below.
    nusselt(
        &[
            &["reference"][..],
            &common[..],
            &[
                "--spp",
                "64",
                "--seed",
                "2",
                "--out",
                &p("ref2.pfm"),
                "--quiet",
            ],
        ]
        .concat(),
    );
    let sigma = compare(&p("ref2.pfm"), &p("ref.pfm")) / 2f64.sqrt();
    eprintln!("render error {error:.4}; one 64-spp reference's noise {sigma:.4}");
    assert!(sigma > 0.0);
    assert!(
        error >= 0.8 * sigma,
        "error {error} below the reference's noise {sigma}"
    );
}

/// `render --json` of a coarse Cornell box at 24² pixels and 4 samples into `out`, with
/// `extra` flags; the summary line.
fn small_cornell(out: &Path, extra: &[&str]) -> serde_json::Value {
    let common = [
        "render",
        "--builtin",
        "cornell",
        "--element-size",
        "60",
        "--width",
        "24",
        "--height",
        "24",
        "--spp",
        "4",
        "--json",
        "--quiet",
        "--out",
    ];
    let out = out.to_str().expect("utf-8");
    let json = nusselt(&[&common[..], &[out], extra].concat());
    serde_json::from_str(json.trim()).expect("json")
}

/// `--pass auto` (the default) takes the direct pass when the time budget leaves room for it
/// and the vertex pass when the run has already used it up (1 ms: the load alone takes
/// longer), and says which in the summary; the image is then that pass's, pixel for pixel.
/// A fixed pass reports no estimate.
#[test]
fn the_auto_pass_follows_the_time_budget() {
    let dir = tempfile::tempdir().expect("tempdir");
    let p = |name: &str| dir.path().join(name).to_str().expect("utf-8").to_string();
    let run = |out: &str, extra: &[&str]| small_cornell(Path::new(out), extra);
    let roomy = run(&p("auto.pfm"), &["--time-budget", "1000"]);
    assert_eq!(roomy["pass"], "direct", "{roomy}");
    assert!(roomy["pass_estimate_seconds"].as_f64().expect("estimate") > 0.0);
    assert_eq!(roomy["time_budget"].as_f64(), Some(1000.0));
    let tight = run(&p("tight.pfm"), &["--time-budget", "0.001"]);
    assert_eq!(tight["pass"], "vertex", "{tight}");
    for (pass, auto) in [("direct", "auto.pfm"), ("vertex", "tight.pfm")] {
        let fixed = run(&p("fixed.pfm"), &["--pass", pass]);
        assert_eq!(fixed["pass"], pass);
        assert!(fixed["pass_estimate_seconds"].is_null(), "{fixed}");
        let a = Image::load_pfm(Path::new(&p(auto))).expect("auto image");
        let b = Image::load_pfm(Path::new(&p("fixed.pfm"))).expect("fixed image");
        assert_eq!(
            a.pixels, b.pixels,
            "--pass auto chose {pass} but drew another image"
        );
    }
}

/// Without a time, `--pass auto` counts work instead of timing it: the summary carries the
/// counts and an estimate made from them at fixed rates (preparation 5e5 light form factors
/// a second, pixels 1.5e6 light evaluations a second; `src/cli/pass.rs`), no budget, and two
/// runs make the same choice and the same image.
#[test]
fn the_default_auto_pass_counts_work_instead_of_timing_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |out: &str| small_cornell(&dir.path().join(out), &[]);
    let (a, b) = (run("a.pfm"), run("b.pfm"));
    assert_eq!(a["pass"], "direct", "{a}");
    assert!(a["time_budget"].is_null(), "{a}");
    let prep = a["pass_work"]["light_form_factors"].as_f64().expect("prep");
    let pixels = a["pass_work"]["light_evaluations"]
        .as_f64()
        .expect("pixels");
    // A row of every element per light patch: a whole, non-zero number of rows.
    let elements = a["elements"].as_f64().expect("elements");
    assert!(prep >= elements && prep % elements == 0.0, "{a}");
    // At least one light evaluation per camera sample of the image (24² pixels × 4).
    assert!(pixels >= (24 * 24 * 4) as f64, "{a}");
    let estimate = a["pass_estimate_seconds"].as_f64().expect("estimate");
    assert!(
        (estimate - (prep / 5e5 + pixels / 1.5e6)).abs() < 1e-9 * estimate,
        "{a}"
    );
    assert_eq!(a["pass_work"], b["pass_work"], "counts differ between runs");
    let ia = Image::load_pfm(&dir.path().join("a.pfm")).expect("a");
    let ib = Image::load_pfm(&dir.path().join("b.pfm")).expect("b");
    assert_eq!(ia.pixels, ib.pixels);
}

/// A scene file's mesh and solver settings are `render`'s defaults: its element size
/// reaches the mesh, and a flag given overrides it; a bad setting is refused by its path.
#[test]
fn scene_file_settings_are_defaults_that_flags_override() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let scene = d.join("box.json");
    std::fs::write(
        &scene,
        r#"{"builtin": "cornell",
            "mesh": {"element_size": 80, "patch_size": 160},
            "solver": {"name": "shooting", "formfactor": "contour", "unshot": 0.01}}"#,
    )
    .expect("write scene");
    let out = d.join("b.pfm");
    let (scene, out) = (scene.to_str().expect("utf-8"), out.to_str().expect("utf-8"));
    let run = |extra: &[&str]| -> serde_json::Value {
        let mut args = vec![
            "render", scene, "--width", "8", "--height", "8", "--spp", "1", "--pass", "vertex",
            "--out", out, "--json", "--quiet",
        ];
        args.extend_from_slice(extra);
        serde_json::from_str(nusselt(&args).trim()).expect("one JSON line")
    };
    let file = run(&[]);
    assert_eq!(file["element_size"].as_f64(), Some(80.0), "{file}");
    assert_eq!(file["patch_size"].as_f64(), Some(160.0), "{file}");
    assert!(file["unshot_fraction"].as_f64().expect("number") <= 0.01);
    let flag = run(&["--element-size", "40", "--unshot", "1e-4"]);
    assert_eq!(flag["element_size"].as_f64(), Some(40.0), "{flag}");
    let elements = |j: &serde_json::Value| j["elements"].as_u64().expect("elements");
    assert!(elements(&flag) > 2 * elements(&file), "{flag} vs {file}");
    assert!(flag["unshot_fraction"].as_f64().expect("number") <= 1e-4);

    let bad = d.join("bad.json");
    std::fs::write(
        &bad,
        r#"{"builtin": "cornell", "mesh": {"element_size": -3}}"#,
    )
    .expect("write");
    let failed = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(["render", bad.to_str().expect("utf-8"), "--out", out])
        .output()
        .expect("run nusselt");
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(!failed.status.success());
    assert!(
        stderr.contains("bad.json") && stderr.contains("mesh.element_size"),
        "{stderr}"
    );
}
