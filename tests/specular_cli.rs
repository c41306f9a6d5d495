//! `nusselt render` on a scene with a mirror and glass: the eye pass is used without a flag
//! and says so; a scene without them says it is not.

use std::process::Command;

use nusselt_core::render::Image;

fn render_json(builtin: &str, out: &str) -> serde_json::Value {
    let o = Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args([
            "render",
            "--builtin",
            builtin,
            "--element-size",
            "60",
            "--width",
            "16",
            "--height",
            "16",
            "--spp",
            "4",
            "--pass",
            "direct",
            "--out",
            out,
            "--json",
            "--quiet",
        ])
        .output()
        .expect("run nusselt");
    assert!(
        o.status.success(),
        "{builtin}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_str(String::from_utf8_lossy(&o.stdout).trim()).expect("json")
}

#[test]
fn render_traces_mirrors_and_glass_without_a_flag() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("cs.pfm");
    let out = path.to_str().expect("utf-8");
    let json = render_json("cornell-specular", out);
    assert_eq!(json["specular"], serde_json::Value::Bool(true), "{json}");
    let image = Image::load_pfm(&path).expect("image");
    assert!(
        image
            .pixels
            .iter()
            .all(|p| p.is_finite() && p.min_element() >= 0.0)
    );
    assert!(image.pixels.iter().any(|p| p.max_element() > 0.0));
    let json = render_json("cornell", out);
    assert_eq!(json["specular"], serde_json::Value::Bool(false), "{json}");
}
