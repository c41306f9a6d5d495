#!/usr/bin/env bash
# Rebuilds the committed Cornell reference (benches/data/cornell_256_ref.pfm): the average of
# `nusselt reference --builtin cornell --spp 4096 --seed S` for S = 1..8 (32,768 spp), and
# prints its own noise estimate: the image error of each 4096-spp part against the average
# (a part's noise; the average's is about that / sqrt(8)).
#   bash scripts/make_reference.sh [path/to/nusselt] [out.pfm]   (hours on 2 cores)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/nusselt}
out=${2:-benches/data/cornell_256_ref.pfm}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
parts=()
for s in 1 2 3 4 5 6 7 8; do
    "$bin" reference --builtin cornell --spp 4096 --seed "$s" --out "$tmp/part$s.pfm" --quiet
    parts+=("$tmp/part$s.pfm")
done
python3 scripts/average_pfm.py "$out" "${parts[@]}"
for p in "${parts[@]}"; do
    "$bin" compare --builtin cornell --image "$p" --reference "$out"
done
