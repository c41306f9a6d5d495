//! The contour method on the reference catalogue (tests/data/formfactors.json, copied from
//! closed forms: Howell C-11, C-14, C-41, B-3).

use std::path::PathBuf;

use nusselt_core::cases::{self, Case};
use nusselt_core::formfactor::{FormFactorMethod, FormFactorParams};

mod common;
use common::{catalogue, json_lines};

fn touching(c: &Case) -> bool {
    c.a1.iter().any(|p| c.a2.iter().any(|q| p == q))
}

#[test]
fn contour_is_within_1e6_on_every_case() {
    let params = FormFactorParams::default();
    let mut checked = 0;
    for c in catalogue() {
        let exact = c.exact.expect("exact value");
        let value = cases::evaluate(&c, FormFactorMethod::Contour, &params);
        let rel = (value - exact).abs() / exact;
        eprintln!("{:32} {value:.12} exact {exact:.12} rel {rel:.2e}", c.name);
        // Touching cases too: the adaptive cubature resolves the log-singular shared edge.
        assert!(rel <= 1e-6, "{}: {rel}", c.name);
        checked += usize::from(!touching(&c));
    }
    assert_eq!(checked, 9, "non-touching cases in the catalogue");
}

#[test]
fn an_occluder_half_way_blocks_its_share() {
    // Parallel unit squares at distance 1 with a blocker covering half the gap's
    // cross-section at mid-height: F drops, but not to zero.
    let mut c = catalogue().into_iter().next().expect("first case");
    let open = cases::evaluate(&c, FormFactorMethod::Contour, &FormFactorParams::default());
    c.occluders = vec![vec![
        [-1.0, -1.0, 0.5],
        [0.5, -1.0, 0.5],
        [0.5, 2.0, 0.5],
        [-1.0, 2.0, 0.5],
    ]];
    let params = FormFactorParams {
        visibility_rays: 256,
        ..Default::default()
    };
    let blocked = cases::evaluate(&c, FormFactorMethod::Contour, &params);
    // By symmetry (x ↦ 1 − x), blocking x < 0.5 at mid-height removes exactly half: to the
    // cubature's accuracy with the shadow clipped away, within the rays' noise when sampled.
    assert!(
        (blocked - open / 2.0).abs() < 1e-6 * open,
        "{blocked} vs {}",
        open / 2.0
    );
    let sampled_params = FormFactorParams {
        exact_blockers: 0,
        ..params.clone()
    };
    let sampled = cases::evaluate(&c, FormFactorMethod::Contour, &sampled_params);
    assert!(
        (sampled - open / 2.0).abs() < 0.01 * open && sampled != blocked,
        "{sampled} vs {}",
        open / 2.0
    );
    c.occluders = vec![vec![
        [-1.0, -1.0, 0.5],
        [2.0, -1.0, 0.5],
        [2.0, 2.0, 0.5],
        [-1.0, 2.0, 0.5],
    ]];
    // Shadows are subtracted exactly: what is left of the source is rounding (≤ 1e-12).
    let hidden = cases::evaluate(&c, FormFactorMethod::Contour, &params);
    assert!(hidden.abs() <= 1e-12 * open, "{hidden}");
}

#[test]
fn the_cli_prints_one_json_line_per_case() {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/formfactors.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args([
            "formfactor",
            p.to_str().expect("utf-8"),
            "--method",
            "contour",
        ])
        .output()
        .expect("run");
    assert!(out.status.success());
    let lines = json_lines(out.stdout);
    assert_eq!(lines.len(), catalogue().len());
    for (l, c) in lines.iter().zip(catalogue()) {
        assert_eq!(l["name"], c.name.as_str());
        assert_eq!(l["method"], "contour");
        let v = l["value"].as_f64().expect("value");
        assert!((v - c.exact.expect("exact")).abs() / v < 1e-4);
        assert!(l["seconds"].as_f64().expect("seconds") >= 0.0);
    }
}
