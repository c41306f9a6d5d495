#!/usr/bin/env python3
"""Average PFM images of equal size (e.g. reference renders with different seeds).

Usage: scripts/average_pfm.py OUT.pfm IN1.pfm IN2.pfm ...
The committed reference benches/data/cornell_256_ref.pfm is the average of 8 renders of
`nusselt reference --builtin cornell --spp 4096 --seed S` for S = 1..8 (32,768 spp in all).
"""
import struct
import sys
from array import array


def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        if kind != b"PF":
            sys.exit(f"{path}: not an RGB PFM (header {kind!r})")
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = array("f")
        data.frombytes(f.read(w * h * 3 * 4))
        if (scale < 0) != (sys.byteorder == "little"):
            data.byteswap()
        return w, h, data


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out, inputs = sys.argv[1], sys.argv[2:]
    w, h, acc = read_pfm(inputs[0])
    acc = array("d", acc)
    for p in inputs[1:]:
        w2, h2, d = read_pfm(p)
        if (w2, h2) != (w, h):
            sys.exit(f"{p}: size {w2}x{h2} differs from {w}x{h}")
        for i, v in enumerate(d):
            acc[i] += v
    n = len(inputs)
    avg = array("f", (v / n for v in acc))
    if sys.byteorder != "little":
        avg.byteswap()
    with open(out, "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        f.write(avg.tobytes())


if __name__ == "__main__":
    main()
