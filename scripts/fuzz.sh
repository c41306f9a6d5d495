#!/usr/bin/env bash
# Runs every cargo-fuzz target of fuzz/ for SECONDS each (default 600), seeded from the
# repository's own inputs, and prints each target's executions and crashes.
#   bash scripts/fuzz.sh [SECONDS]
# Needs `cargo install cargo-fuzz`; the stable toolchain builds with RUSTC_BOOTSTRAP=1 and
# no sanitizer (safe Rust: panics are what we look for). The first build compiles every
# dependency with coverage instrumentation (about an hour on a 2-core machine).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-600}
root=$PWD
seed() { # target, then files
    local t=$1; shift
    mkdir -p "fuzz/corpus/$t"
    for f in "$@"; do [ -f "$f" ] && cp "$f" "fuzz/corpus/$t/$(echo "$f" | tr / _)"; done
}
# obj_solve and mtl_texture: OBJ NUL MTL [NUL image].
mkdir -p fuzz/corpus/obj_solve fuzz/corpus/mtl_texture
for f in tests/data/hard/*.obj tests/data/models/*.obj tests/data/bad/*.obj assets/*.obj; do
    m=${f%.obj}.mtl; [ -f "$m" ] || m=/dev/null
    name=$(echo "$f" | tr / _)
    { sed 's/^mtllib .*/mtllib m.mtl/' "$f"; printf '\0'; cat "$m"; } > "fuzz/corpus/obj_solve/$name"
done
{ sed 's/^mtllib .*/mtllib m.mtl/' tests/data/cutout/leaf_canopy.obj; printf '\0'
  sed 's/leaves_mask.png/t.png/' tests/data/cutout/leaf_canopy.mtl; printf '\0'
  cat tests/data/cutout/leaves_mask.png; } > fuzz/corpus/mtl_texture/leaf_canopy
seed gltf_solve ../shared/models/gltf/*/*.glb ../shared/models/gltf/*/*.gltf
mkdir -p fuzz/corpus/scene_file
printf '{"builtin": "cornell", "lights": [{"type": "sun", "direction": [0.3, 1, 0.2], "irradiance": [2, 2, 2]}], "mesh": {"element_size": 80}}' \
    > fuzz/corpus/scene_file/cornell_sun.json
cd fuzz
for t in obj_solve mtl_texture gltf_solve scene_file; do
    echo "== $t: $seconds s"
    RUSTC_BOOTSTRAP=1 cargo fuzz run "$t" -s none -- -max_total_time="$seconds" -timeout=60 \
        -print_final_stats=1 2>&1 | grep -E "stat::number_of_executed_units|SUMMARY|panicked|Done" || true
    ls "artifacts/$t" 2>/dev/null | sed "s|^|crash: artifacts/$t/|" || true
done
cd "$root"
