#!/usr/bin/env bash
# Image error against the committed 32k-spp reference vs whole-process seconds, for a few
# element/patch sizes and stopping points (Cornell box, 256×256). Prints a Markdown table.
# Usage: scripts/error_vs_time.sh [path/to/nusselt]   (default: target/release/nusselt)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/nusselt}
[ -x "$bin" ] || cargo build --release
ref=benches/data/cornell_256_ref.pfm
out=$(mktemp -d)
echo "| element | patch | stop | elements | shots | image error | seconds (whole process) | CPU seconds |"
echo "|---:|---:|---|---:|---:|---:|---:|---:|"
run() {
    local es=$1 ps=$2 stop=$3
    local start end json
    start=$(date +%s.%N)
    # shellcheck disable=SC2086
    json=$(/usr/bin/time -f "%U %S" -o "$out/cpu" "$bin" render --builtin cornell --out "$out/r.pfm" --reference "$ref" --json --quiet \
        --element-size "$es" --patch-size "$ps" $stop)
    end=$(date +%s.%N)
    python3 - "$json" "$es" "$ps" "$stop" "$start" "$end" "$(cat "$out/cpu")" <<'PY'
import json, sys
d = json.loads(sys.argv[1]); es, ps, stop = sys.argv[2:5]; t = float(sys.argv[6]) - float(sys.argv[5])
cpu = sum(map(float, sys.argv[7].split()))
print(f"| {es} | {ps} | {stop} | {d['elements']} | {d['shots']} | {100*d['error']:.2f} % | {t:.2f} | {cpu:.2f} |")
PY
}
run 40 80 "--unshot 1e-4"
run 30 60 "--unshot 1e-4"
run 24 48 "--unshot 1e-4"
run 16 48 "--unshot 1e-4"
run 14 48 "--unshot 1e-4"
run 16 32 "--unshot 1e-4"
run 12 40 "--unshot 1e-2"
run 12 40 "--unshot 1e-4"
run 8 32 "--unshot 1e-4"
run 12 40 "--shots 500"
run 12 40 "--shots 2000"
rm -rf "$out"
