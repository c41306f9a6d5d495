#!/usr/bin/env bash
# Regenerates the measured tables of docs/FORMFACTORS.md: every form-factor method on the
# reference cases (error and seconds per evaluation) and as the solver's row on the Cornell
# box (image error against the converged reference, seconds), plus the hybrid's rule sweep
# and an equal-time comparison. Prints Markdown on stdout.
#
# Usage: scripts/formfactors_doc.sh [path/to/nusselt] > /tmp/tables.md
#   (default binary: target/release/nusselt, or $CARGO_TARGET_DIR/release/nusselt)
#   REF_SPP=N  spp of the Cornell reference if benches/data/cornell_256_ref.pfm is missing
#              (default 32768; it is rendered once and kept).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-${CARGO_TARGET_DIR:-target}/release/nusselt}
[ -x "$bin" ] || cargo build --release
ref=benches/data/cornell_256_ref.pfm
if [ ! -f "$ref" ]; then
    mkdir -p benches/data
    "$bin" reference --builtin cornell --width 256 --height 256 --spp "${REF_SPP:-32768}" \
        --out "$ref" --quiet
fi
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
methods="contour exact hemicube raycast montecarlo hybrid gpu-hemicube"
# gpu-hemicube needs a wgpu adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1).

echo "## Reference cases"
echo
echo "Relative error |F − F_ref|/F_ref (absolute error where F_ref = 0) and seconds per"
echo "evaluation (release build, one thread). Parameters: hemicube 256 pixels across;"
echo "raycast 65 536 rays; montecarlo 65 536 point pairs; contour 256 shadow rays per point"
echo "(occluded cases only); seed 1."
echo
for file in tests/data/formfactors.json tests/data/formfactors_occluded.json; do
    for m in $methods; do
        "$bin" formfactor "$file" --method "$m" > "$out/$(basename "$file" .json)_$m.jsonl"
    done
done
python3 - "$out" $methods <<'PY'
import json, sys, os
out, methods = sys.argv[1], sys.argv[2:]
for stem, title in [("formfactors", "tests/data/formfactors.json (closed forms)"),
                    ("formfactors_occluded", "tests/data/formfactors_occluded.json (exact, adaptive)")]:
    cases = json.load(open(f"tests/data/{stem}.json"))
    ref = {c["name"]: c["exact"] for c in cases}
    rows = {}
    for m in methods:
        for line in open(os.path.join(out, f"{stem}_{m}.jsonl")):
            d = json.loads(line)
            rows.setdefault(d["name"], {})[m] = (d["value"], d["seconds"])
    print(f"### {title}\n")
    print("| case | F_ref | " + " | ".join(methods) + " |")
    print("|---|---:|" + "---:|" * len(methods))
    for c in cases:
        n = c["name"]; r = ref[n]
        cells = []
        for m in methods:
            v, s = rows[n][m]
            e = abs(v - r) / r if r != 0 else abs(v - r)
            cells.append(f"{e:.1e} ({s*1e3:.3g} ms)")
        print(f"| {n} | {r:.6g} | " + " | ".join(cells) + " |")
    print()
PY

render() {
    # shellcheck disable=SC2068
    "$bin" render --builtin cornell --width 256 --height 256 --reference "$ref" --json --quiet \
        --out "$out/r.pfm" $@
}
summary() {
    python3 - "$1" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
print("%.2f %% | %.2f | %.2f | %d" % (100 * d["error"], d["solve_seconds"], d["total_seconds"], d["shots"]))
PY
}

echo "## Cornell box, converged (--unshot 1e-4), 256×256, default mesh"
echo
echo "Image error against the converged reference ($ref) over the render's mask;"
echo "solve seconds and whole-process seconds on this machine (2 cores shared)."
echo
echo "| method | image error | solve s | total s | shots |"
echo "|---|---:|---:|---:|---:|"
for m in $methods; do
    echo "| $m | $(summary "$(render --formfactor "$m")") |"
done
echo

echo "## Equal time: error after a fixed solve time (--seconds T)"
echo
echo "Median of 5 runs each (image error, shots in brackets). Around 4 s the"
echo "solve passes from computing new rows to re-shooting cached ones, so a few per cent of"
echo "timing noise moves the shot count (and the error) a lot there."
echo
echo "| T (s) | contour | hemicube | hybrid | gpu-hemicube |"
echo "|---:|---:|---:|---:|---:|"
for t in 1 2 4; do
    row="| $t |"
    for m in contour hemicube hybrid gpu-hemicube; do
        runs=""
        for rep in 1 2 3 4 5; do
            runs="$runs $(render --formfactor "$m" --seconds "$t" | tr -d ' ')"
        done
        row="$row $(python3 - $runs <<'PY'
import json, sys
ds = sorted((json.loads(a) for a in sys.argv[1:]), key=lambda d: d["error"])
d = ds[len(ds) // 2]
print("%.2f %% (%d shots)" % (100 * d["error"], d["shots"]))
PY
) |"
    done
    echo "$row"
done
echo

echo "## Equal work: solve seconds for the first 1000 shots (5 runs each, interleaved)"
echo
echo "| method | runs (s) | median (s) |"
echo "|---|---|---:|"
declare -A work
for rep in 1 2 3 4 5; do
    for m in contour hybrid; do
        work[$m]="${work[$m]:-} $("$bin" render --builtin cornell --width 64 --height 64 --spp 1 --formfactor "$m" --shots 1000 --json --quiet --out "$out/w.pfm" | python3 -c 'import json,sys; print("%.3f" % json.load(sys.stdin)["solve_seconds"])')"
    done
done
for m in contour hybrid; do
    # shellcheck disable=SC2086
    echo "| $m | ${work[$m]} | $(python3 -c 'import statistics,sys; print("%.3f" % statistics.median(map(float, sys.argv[1:])))' ${work[$m]}) |"
done
echo

echo "## Hybrid rule sweep (converged, --unshot 1e-4)"
echo
echo "| --hybrid-k | --hybrid-min-pixels | image error | solve s | total s | shots |"
echo "|---:|---:|---:|---:|---:|---:|"
for k in 2 5; do
    for px in 0 16 64; do
        echo "| $k | $px | $(summary "$(render --formfactor hybrid --hybrid-k "$k" --hybrid-min-pixels "$px")") |"
    done
done
echo

echo "## Hemicube resolution (converged)"
echo
echo "| --hemicube-res | image error | solve s | total s | shots |"
echo "|---:|---:|---:|---:|---:|"
for r in 128 256 512; do
    echo "| $r | $(summary "$(render --formfactor hemicube --hemicube-res "$r")") |"
done
echo

echo "## Raycast rays per shot (converged)"
echo
echo "| --rays | image error | solve s | total s | shots |"
echo "|---:|---:|---:|---:|---:|"
for n in 16384 65536; do
    echo "| $n | $(summary "$(render --formfactor raycast --rays "$n")") |"
done

echo "## GPU hemicube against the CPU hemicube"
echo
echo "Same shots (first 300 of the default Cornell mesh, seed 1); milliseconds per shot"
echo "(solve seconds / shots, including the shot's update) and the image difference between"
echo "the two renders (relative RMS over the mask)."
echo
echo "| --hemicube-res | CPU ms/shot | GPU ms/shot | image difference |"
echo "|---:|---:|---:|---:|"
for r in 128 256 512; do
    c=$(render --formfactor hemicube --hemicube-res "$r" --shots 300 | tr -d ' ')
    cp "$out/r.pfm" "$out/cpu.pfm"
    g=$(render --formfactor gpu-hemicube --hemicube-res "$r" --shots 300 | tr -d ' ')
    diff=$("$bin" compare --builtin cornell --image "$out/r.pfm" --reference "$out/cpu.pfm" 2>/dev/null | python3 -c 'import json,sys; print("%.2e" % json.loads(sys.stdin.read())["error"])')
    echo "| $r | $(python3 -c "import json,sys; d=json.loads(sys.argv[1]); print('%.2f' % (1e3*d['solve_seconds']/d['shots']))" "$c") | $(python3 -c "import json,sys; d=json.loads(sys.argv[1]); print('%.2f' % (1e3*d['solve_seconds']/d['shots']))" "$g") | $diff |"
done
echo
echo "Adapter: $(render --formfactor gpu-hemicube --shots 1 | python3 -c 'import json,sys; print(json.loads(sys.stdin.read())["rasteriser"])')"
