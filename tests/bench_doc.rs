//! `nusselt bench --doc`: the figure tables in README.md and docs/*.md match the committed
//! bench CSVs, and a figure edited by hand is caught and rewritten.

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn bench_doc(dir: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nusselt"))
        .args(["bench", "--doc"])
        .args(extra)
        .current_dir(dir)
        .output()
        .expect("run nusselt")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The repository's own documents: every generated region is what its CSV gives, and
/// writing them takes no benchmark run.
#[test]
fn committed_figures_match_the_csvs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let start = Instant::now();
    let out = bench_doc(root, &["--check"]);
    assert!(
        out.status.success(),
        "README.md or docs/*.md drifted from bench/*.csv; run `nusselt bench --doc`:\n{}",
        stderr(&out)
    );
    assert!(
        start.elapsed() < Duration::from_secs(10),
        "CSV to markdown took {:?}",
        start.elapsed()
    );
    let regions = stderr(&out);
    let count: usize = regions
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(count >= 12, "expected the generated regions: {regions}");
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for entry in std::fs::read_dir(from).expect("read_dir") {
        let path = entry.expect("entry").path();
        let ext = path.extension().and_then(|e| e.to_str());
        if matches!(ext, Some("md" | "csv")) {
            std::fs::copy(&path, to.join(path.file_name().expect("name"))).expect("copy");
        }
    }
}

/// A copy of the documents with one generated figure changed: `--check` fails naming the
/// file, `--doc` restores it, and a second `--doc` changes nothing.
#[test]
fn a_hand_edited_figure_is_caught_and_rewritten() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::copy(root.join("README.md"), dir.path().join("README.md")).expect("README");
    copy_tree(&root.join("docs"), &dir.path().join("docs"));
    copy_tree(&root.join("bench"), &dir.path().join("bench"));
    let doc = dir.path().join("docs/BENCHMARKS.md");
    let original = std::fs::read_to_string(&doc).expect("read");
    let row = "| light Ke x2 | 0.499 | 1969 | 0.166 |";
    assert!(original.contains(row), "the live-edit row is generated");
    std::fs::write(
        &doc,
        original.replace(row, "| light Ke x2 | 0.499 | 1969 | 0.100 |"),
    )
    .expect("write");

    let check = bench_doc(dir.path(), &["--check"]);
    assert!(
        !check.status.success(),
        "--check passed on an edited figure"
    );
    assert!(
        stderr(&check).contains("BENCHMARKS.md"),
        "{}",
        stderr(&check)
    );

    assert!(bench_doc(dir.path(), &[]).status.success());
    assert_eq!(std::fs::read_to_string(&doc).expect("read"), original);
    let again = bench_doc(dir.path(), &[]);
    assert!(again.status.success());
    assert!(!stderr(&again).contains("wrote"), "{}", stderr(&again));
}

/// A region naming no table is refused with the file and line.
#[test]
fn an_unknown_table_names_its_line() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir_all(dir.path().join("docs")).expect("docs");
    std::fs::write(
        dir.path().join("README.md"),
        "# x\n\n<!-- bench:table nonesuch -->\n<!-- /bench:table -->\n",
    )
    .expect("write");
    let out = bench_doc(dir.path(), &["--check"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("README.md:3") && stderr(&out).contains("nonesuch"),
        "{}",
        stderr(&out)
    );
}
