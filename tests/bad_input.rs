//! Every malformed file under tests/data/bad/ gives a clear message (naming the file and,
//! where there is one, the line) and never panics or half-loads.

use std::path::PathBuf;
use std::process::Command;

use nusselt_core::scene::{LoadOptions, Scene};

fn bad(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/bad")
        .join(name)
}

/// (file, substrings the error message must contain).
const ERRORS: &[(&str, &[&str])] = &[
    ("empty.obj", &["empty.obj", "no faces"]),
    ("only_comments.obj", &["only_comments.obj", "no faces"]),
    (
        "bad_number.obj",
        &["bad_number.obj:3", "'abc' is not a number"],
    ),
    (
        "nan_vertex.obj",
        &["nan_vertex.obj:3", "not a finite number"],
    ),
    (
        "inf_vertex.obj",
        &["inf_vertex.obj:4", "not a finite number"],
    ),
    (
        "short_vertex.obj",
        &["short_vertex.obj:2", "'v' needs 3 to 4 numbers, found 2"],
    ),
    (
        "index_out_of_range.obj",
        &["index_out_of_range.obj:5", "vertex index 7 is out of range"],
    ),
    (
        "index_zero.obj",
        &["index_zero.obj:5", "vertex index 0 is out of range"],
    ),
    (
        "negative_index_out_of_range.obj",
        &["negative_index_out_of_range.obj:5", "index -5"],
    ),
    (
        "face_two_vertices.obj",
        &["face_two_vertices.obj:4", "at least 3 vertices, found 2"],
    ),
    (
        "bad_face_token.obj",
        &["bad_face_token.obj:5", "bad vertex index 'x'"],
    ),
    (
        "normal_index_out_of_range.obj",
        &[
            "normal_index_out_of_range.obj:6",
            "normal index 4 is out of range",
        ],
    ),
    (
        "missing_mtl.obj",
        &["missing_mtl.obj:1", "does_not_exist.mtl"],
    ),
    (
        "kd_one_number.obj",
        &[
            "kd_one_number.mtl:2",
            "'Kd' needs 3 numbers (r g b), found 1",
            "Kd 0.5 0.5 0.5",
        ],
    ),
    (
        "kd_negative.obj",
        &["kd_negative.mtl:2", "must not be negative"],
    ),
    (
        "ke_negative.obj",
        &["ke_negative.mtl:3", "'Ke' values must not be negative"],
    ),
    ("kd_nan.obj", &["kd_nan.mtl:2", "not a finite number"]),
    (
        "kd_before_newmtl.obj",
        &["kd_before_newmtl.mtl:1", "before any 'newmtl'"],
    ),
    ("ke_spectral.obj", &["ke_spectral.mtl:2", "not supported"]),
    (
        "all_zero_area.obj",
        &["all_zero_area.obj", "no usable faces", "2 zero-area"],
    ),
    (
        "usemtl_without_name.obj",
        &["usemtl_without_name.obj:2", "needs a material name"],
    ),
    (
        "mtllib_without_name.obj",
        &["mtllib_without_name.obj:1", "needs a file name"],
    ),
    ("binary.obj", &["binary.obj", "not a text file"]),
    ("does_not_exist.obj", &["does_not_exist.obj", "cannot read"]),
];

/// (file, substrings one of the warnings must contain): these load with a warning.
const WARNINGS: &[(&str, &[&str])] = &[
    (
        "reflectance_above_one.obj",
        &["bright.mtl", "clamped to 0.95 in 'white' (line 2)"],
    ),
    ("zero_area_dropped.obj", &["dropped 2 zero-area face(s)"]),
    ("non_planar_split.obj", &["split 1 non-planar face(s)"]),
];

#[test]
fn every_bad_file_has_its_message() {
    assert!(ERRORS.len() >= 20);
    for (file, parts) in ERRORS {
        let result =
            std::panic::catch_unwind(|| Scene::load_obj(&bad(file), &LoadOptions::default()));
        let loaded = result.unwrap_or_else(|_| panic!("{file}: loading panicked"));
        let message = match loaded {
            Ok(_) => panic!("{file}: loaded but should have failed"),
            Err(e) => e.to_string(),
        };
        for part in *parts {
            assert!(
                message.contains(part),
                "{file}: message {message:?} lacks {part:?}"
            );
        }
    }
}

#[test]
fn an_unlit_model_gets_default_lights_unless_refused() {
    let mut scene = Scene::load_obj(&bad("no_emitter.obj"), &LoadOptions::default())
        .expect("an unlit model loads");
    let e = scene
        .check_lit()
        .expect_err("nothing lights it")
        .to_string();
    assert!(
        e.contains("no_emitter.obj") && e.contains("no emitter"),
        "{e}"
    );
    let message = scene.add_default_lights().expect("lights added");
    assert!(message.contains("--no-default-lights"), "{message}");
    assert!(scene.check_lit().is_ok());
}

#[test]
fn recoverable_problems_load_with_warnings() {
    for (file, parts) in WARNINGS {
        let scene = Scene::load_obj(&bad(file), &LoadOptions::default())
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let all = scene.warnings.join("\n");
        for part in *parts {
            assert!(all.contains(part), "{file}: warnings {all:?} lack {part:?}");
        }
    }
    let s =
        Scene::load_obj(&bad("reflectance_above_one.obj"), &LoadOptions::default()).expect("loads");
    assert!(
        s.materials
            .iter()
            .all(|m| m.reflectance.max_element() <= 0.999)
    );
    let s = Scene::load_obj(&bad("non_planar_split.obj"), &LoadOptions::default()).expect("loads");
    assert_eq!(s.faces.len(), 2, "a non-planar quad becomes two triangles");
}

fn nusselt(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(args)
        .output()
        .expect("run nusselt");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

// Long by design: a table of bad inputs, each with the message it must produce.
#[test]
fn the_cli_reports_bad_input_without_panicking() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("x.png");
    let out = out.to_str().expect("utf-8 path");
    let kd = bad("kd_one_number.obj");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["render", kd.to_str().expect("path"), "--out", out],
            "kd_one_number.mtl:2",
        ),
        (
            vec!["render", "--builtin", "nope", "--out", out],
            "unknown built-in scene 'nope'",
        ),
        (
            vec![
                "render",
                "--builtin",
                "cornell",
                "--out",
                out,
                "--camera",
                "1,2,3",
            ],
            "expected 7 numbers",
        ),
        (
            vec![
                "render",
                "--builtin",
                "cornell",
                "--out",
                out,
                "--element-size",
                "-1",
            ],
            "element size must be a positive",
        ),
        (
            vec![
                "render",
                "--builtin",
                "cornell",
                "--out",
                out,
                "--element-size",
                "0.001",
            ],
            "or larger, or --max-memory",
        ),
        (
            vec![
                "render",
                "--builtin",
                "cornell",
                "--out",
                "/tmp/x.bmp",
                "--shots",
                "1",
            ],
            "unknown image extension",
        ),
        (
            vec![
                "render",
                "--builtin",
                "cornell",
                "--out",
                out,
                "--reference",
                "/nonexistent.pfm",
            ],
            "cannot read /nonexistent.pfm",
        ),
        (
            vec![
                "render",
                "--builtin",
                "cornell",
                "--out",
                out,
                "--formfactor",
                "magic",
            ],
            "unknown --formfactor 'magic'",
        ),
        (
            vec![
                "render",
                "--builtin",
                "furnace",
                "--rho",
                "-2",
                "--out",
                out,
            ],
            "--rho must be",
        ),
        (
            vec!["formfactor", "/nonexistent.json"],
            "cannot read /nonexistent.json",
        ),
    ];
    for (args, expected) in cases {
        let (ok, stderr) = nusselt(&args);
        assert!(!ok, "{args:?} should fail");
        assert!(
            stderr.contains(expected),
            "{args:?}: stderr {stderr:?} lacks {expected:?}"
        );
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    }
}
