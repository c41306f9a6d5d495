//! The crate graph is the architecture: the core's normal dependencies, followed to the
//! bottom through `cargo metadata`'s resolved graph, hold no GUI, GPU or CLI crate, and the
//! GPU crate holds no GUI crate, so an engine can embed the solver without them.

use std::collections::{BTreeSet, HashMap};
use std::process::Command;

use serde_json::Value;

/// Package names reachable from `root` through normal (not dev or build) dependencies.
fn normal_closure(metadata: &Value, root: &str) -> BTreeSet<String> {
    let packages: HashMap<&str, &str> = metadata["packages"]
        .as_array()
        .expect("packages")
        .iter()
        .map(|p| (p["id"].as_str().unwrap(), p["name"].as_str().unwrap()))
        .collect();
    let nodes: HashMap<&str, &Value> = metadata["resolve"]["nodes"]
        .as_array()
        .expect("resolve.nodes")
        .iter()
        .map(|n| (n["id"].as_str().unwrap(), n))
        .collect();
    let start = packages
        .iter()
        .find(|(_, name)| **name == root)
        .map(|(id, _)| *id)
        .unwrap_or_else(|| panic!("no package {root}"));
    let (mut seen, mut todo) = (BTreeSet::new(), vec![start]);
    while let Some(id) = todo.pop() {
        if !seen.insert(id) {
            continue;
        }
        for dep in nodes[id]["deps"].as_array().expect("deps") {
            let normal = dep["dep_kinds"]
                .as_array()
                .expect("dep_kinds")
                .iter()
                .any(|k| k["kind"].is_null());
            if normal {
                todo.push(dep["pkg"].as_str().unwrap());
            }
        }
    }
    seen.iter().map(|id| packages[id].to_string()).collect()
}

fn metadata() -> Value {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(["metadata", "--format-version", "1"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("metadata JSON")
}

#[test]
fn the_core_depends_on_no_gui_gpu_or_cli_crate() {
    let metadata = metadata();
    let core = normal_closure(&metadata, "nusselt-core");
    assert!(core.contains("glam") && core.contains("rayon"), "{core:?}");
    let banned = [
        "egui",
        "eframe",
        "egui-wgpu",
        "wgpu",
        "winit",
        "clap",
        "indicatif",
        "plotters",
        "rfd",
    ];
    let found: Vec<_> = banned.iter().filter(|b| core.contains(**b)).collect();
    assert!(found.is_empty(), "nusselt-core pulls in {found:?}");
    let gpu = normal_closure(&metadata, "nusselt-gpu");
    assert!(gpu.contains("wgpu"), "{gpu:?}");
    let found: Vec<_> = ["egui", "eframe", "winit", "clap"]
        .iter()
        .filter(|b| gpu.contains(**b))
        .collect();
    assert!(found.is_empty(), "nusselt-gpu pulls in {found:?}");
}
