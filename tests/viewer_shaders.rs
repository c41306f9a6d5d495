//! Every WGSL file in shaders/ parses and validates with naga (no GPU needed), and the
//! viewport shader's uniform block has the layout of `viewer::render::Uniforms`.

use std::path::Path;

fn validate(path: &Path) -> naga::Module {
    let text = std::fs::read_to_string(path).expect("read shader");
    let module = naga::front::wgsl::parse_str(&text).unwrap_or_else(|e| {
        panic!(
            "{}",
            e.emit_to_string_with_path(&text, &path.display().to_string())
        )
    });
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}: {}", path.display(), e.emit_to_string(&text)));
    module
}

#[test]
fn every_shader_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).expect("shaders/") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "wgsl") {
            validate(&path);
            count += 1;
        }
    }
    assert!(count >= 1, "no shaders found in {}", dir.display());
}

/// The shader file is the embedded source, has the entry points, and its uniform struct has
/// the size of the Rust struct uploaded into it.
fn check_shader(
    file: &str,
    embedded: &str,
    entry_points: &[&str],
    uniform: &str,
    rust_size: usize,
) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("shaders")
        .join(file);
    let module = validate(&path);
    assert_eq!(embedded, std::fs::read_to_string(&path).expect("read"));
    let names: Vec<&str> = module
        .entry_points
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    for want in entry_points {
        assert!(names.contains(want), "{want} missing: {names:?}");
    }
    let (_, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(uniform))
        .unwrap_or_else(|| panic!("{uniform} struct missing"));
    let naga::TypeInner::Struct { span, .. } = &ty.inner else {
        panic!("{uniform} is not a struct");
    };
    assert_eq!(
        *span as usize, rust_size,
        "{uniform}: block size differs between WGSL and Rust"
    );
}

#[test]
fn viewport_shader_matches_the_rust_side() {
    check_shader(
        "viewport.wgsl",
        nusselt_viewer::render::SHADER_SOURCE,
        &["vs_mesh", "fs_mesh", "vs_line", "fs_line"],
        "Uniforms",
        std::mem::size_of::<nusselt_viewer::render::Uniforms>(),
    );
}

#[test]
fn hemicube_shader_matches_the_rust_side() {
    check_shader(
        "hemicube.wgsl",
        nusselt_gpu::hemicube::SHADER_SOURCE,
        &["vs_main", "fs_main"],
        "Face",
        std::mem::size_of::<nusselt_gpu::hemicube::FaceUniform>(),
    );
}

#[test]
fn a_broken_shader_is_rejected() {
    // The check above can fail: a type error must not validate.
    let bad = "@fragment fn f() -> @location(0) vec4<f32> { return vec3<f32>(1.0); }";
    let parsed = naga::front::wgsl::parse_str(bad);
    let valid = parsed.map(|m| {
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&m)
        .is_ok()
    });
    assert!(!matches!(valid, Ok(true)));
}

/// The viewport shader reads the diffuse maps as render.rs binds them: a filterable float
/// 2-D array at binding 1 and a filtering sampler at binding 2 of group 0, and its mesh
/// vertex input has the eight locations render.rs's five vertex buffers fill.
#[test]
fn viewport_shader_binds_the_texture_array() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("shaders")
        .join("viewport.wgsl");
    let module = validate(&path);
    let at = |binding: u32| {
        let (_, var) = module
            .global_variables
            .iter()
            .find(|(_, v)| {
                v.binding
                    .as_ref()
                    .is_some_and(|b| b.group == 0 && b.binding == binding)
            })
            .unwrap_or_else(|| panic!("nothing at binding {binding}"));
        module.types[var.ty].inner.clone()
    };
    assert!(
        matches!(
            at(1),
            naga::TypeInner::Image {
                dim: naga::ImageDimension::D2,
                arrayed: true,
                class: naga::ImageClass::Sampled {
                    kind: naga::ScalarKind::Float,
                    multi: false
                },
            }
        ),
        "{:?}",
        at(1)
    );
    assert!(matches!(
        at(2),
        naga::TypeInner::Sampler { comparison: false }
    ));
    let vs = module
        .entry_points
        .iter()
        .find(|e| e.name == "vs_mesh")
        .expect("vs_mesh");
    let arg = &vs.function.arguments[0];
    let naga::TypeInner::Struct { members, .. } = &module.types[arg.ty].inner else {
        panic!("vs_mesh takes a struct");
    };
    let mut locations: Vec<u32> = members
        .iter()
        .filter_map(|m| match m.binding {
            Some(naga::Binding::Location { location, .. }) => Some(location),
            _ => None,
        })
        .collect();
    locations.sort_unstable();
    assert_eq!(locations, (0..8).collect::<Vec<u32>>());
    assert_eq!(nusselt_viewer::render::TEXTURING_STRIDE, 24);
}
