#!/usr/bin/env bash
# Formatting, lints and tests: run before every commit.
set -euo pipefail
cd "$(dirname "$0")"
cargo fmt --all -- --check
cargo clippy --workspace --all-targets -- -D warnings
RUSTDOCFLAGS="-D rustdoc::broken_intra_doc_links" cargo doc --workspace --no-deps --quiet
cargo bench --workspace --bench '*' --no-run --quiet
if command -v cargo-nextest >/dev/null 2>&1; then
    cargo nextest run --no-fail-fast
else
    cargo test --no-fail-fast
fi
cargo test --doc
