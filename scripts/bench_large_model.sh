#!/usr/bin/env bash
# Issue 11 benchmark: the 100,000-triangle model (a terrain room, 100,352 triangles, written
# by scripts/make_models.py --terrain, the same construction as tests/models.rs's
# write_terrain) loaded, meshed and solved to --unshot 1e-3 with default flags, timed, with
# peak memory. Not a test: the debug-build test (tests/models.rs,
# large_terrain_model_converges) uses 20,000 triangles.
#
#   scripts/bench_large_model.sh [N] [BINARY]
#
# N: terrain cells per side (default 224: 2·224² = 100,352 triangles); BINARY: the nusselt
# binary (default target/release/nusselt, built if missing).
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-224}
bin=${2:-target/release/nusselt}
if [ ! -x "$bin" ]; then
    cargo build --release --bin nusselt
fi
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
python3 scripts/make_models.py --terrain "$n" "$dir/terrain.obj"
echo "terrain: $(grep -c '^f' "$dir/terrain.obj") faces ($((2 * n * n)) terrain triangles)"
/usr/bin/time -v "$bin" render "$dir/terrain.obj" --out "$dir/terrain.pfm" --unshot 1e-3 \
    --json --quiet 2>"$dir/time.txt" | tee "$dir/summary.json"
grep -E "Elapsed|Maximum resident" "$dir/time.txt"
