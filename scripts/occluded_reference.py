#!/usr/bin/env python3
"""Independent reference values for tests/data/formfactors_occluded.json (writes the file).

Usage: scripts/occluded_reference.py [--samples N] [--check]
  (needs numpy; only for regenerating the file: the tests read the committed numbers)
  --check   recompute and compare with the committed file instead of writing it.

Nothing here calls nusselt or shares its code. Every case is a unit square A1 (or a point)
and axis-aligned rectangles, so each reference has an independent derivation:

closed form   catalogue formulas (Howell's C-11 parallel rectangles, C-14 perpendicular
              rectangles with a common edge, B-3 point to a parallel rectangle at a corner)
              and form-factor algebra (superposition, symmetry) -- where the blockers split
              A1 or A2 into rectangles that are either fully seen or fully hidden.
quadrature    parallel A1 and A2 with blockers parallel to them: the 4-D integral reduces
              exactly to 2-D. With u = x1 - x2, v = y1 - y2 the kernel depends on (u, v)
              only, K = c^2 / (pi (c^2 + u^2 + v^2)^2), and a blocker at height h (a fraction
              of c) hides the ray iff x1 - h u and y1 - h v lie in its x and y ranges. So
                  F = integral over [-1,1]^2 of K(u, v) M(u, v) du dv,
              M = sum over blocker subsets S of (-1)^|S| Lx_S(u) Ly_S(v) (inclusion-exclusion),
              Lx_S(u) = length of [0,1] n [u,1+u] n (every blocker of S's x range + h u):
              piecewise linear in u. Gauss-Legendre (40 nodes) on the panels between M's
              breakpoints is exact to rounding; the case with no blockers reproduces C-11 to
              1e-15 (checked below).
pointwise     a second reduction for the same cases: from a point (x1, y1) the blockers'
              shadows on A2's plane are rectangles, the visible part is A2 minus their union
              (inclusion-exclusion again) and each rectangle's point form factor is the B-3
              corner formula; integrated over A1 by panel Gauss-Legendre between the kinks.
Monte Carlo   for every case, as a check of all of the above: uniform pairs (x1 on A1, x2 on
              A2), the estimator A2 * K * V, with its standard error from the sample variance.

Each case records "reference_method", a "note" with the derivation, the cross-checks'
values ("checks") and the Monte Carlo value with its standard error.
"""
import argparse
import itertools
import json
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "tests", "data", "formfactors_occluded.json")

UNIT_A1 = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
UNIT_A2_TOP = [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]]


def rect_z(x0, x1, y0, y1, z):
    return [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]]


# ---------------------------------------------------------------- closed forms (catalogue)


def c11_parallel(a, b, c):
    """Howell C-11: directly opposed parallel a x b rectangles at distance c."""
    x, y = a / c, b / c
    return (2.0 / (math.pi * x * y)) * (
        0.5 * math.log((1 + x * x) * (1 + y * y) / (1 + x * x + y * y))
        + x * math.sqrt(1 + y * y) * math.atan(x / math.sqrt(1 + y * y))
        + y * math.sqrt(1 + x * x) * math.atan(y / math.sqrt(1 + x * x))
        - x * math.atan(x)
        - y * math.atan(y)
    )


def c14_perpendicular(w, h, l):
    """Howell C-14: from A1 (w x l) to A2 (h x l), perpendicular, sharing the edge of length l."""
    W, H = w / l, h / l
    s = W * W + H * H
    log_term = 0.25 * (
        math.log((1 + W * W) * (1 + H * H) / (1 + s))
        + W * W * math.log(W * W * (1 + s) / ((1 + W * W) * s))
        + H * H * math.log(H * H * (1 + s) / ((1 + H * H) * s))
    )
    return (1.0 / (math.pi * W)) * (
        W * math.atan(1 / W) + H * math.atan(1 / H) - math.sqrt(s) * math.atan(1 / math.sqrt(s)) + log_term
    )


def b3_corner(a, b, c):
    """Howell B-3: point to a parallel a x b rectangle, the point under one corner at distance c.
    Signed in a and b (odd in each), so that rectangles are sums of corner terms."""
    A, B = a / c, b / c
    sa, sb = math.sqrt(1 + A * A), math.sqrt(1 + B * B)
    return (A / sa * math.atan(B / sa) + B / sb * math.atan(A / sb)) / (2 * math.pi)


def point_to_rect(px, py, c, x0, x1, y0, y1):
    """Point at (px, py), normal towards the parallel plane at distance c, to [x0,x1]x[y0,y1]."""
    if x1 <= x0 or y1 <= y0:
        return 0.0
    f = lambda x, y: b3_corner(x - px, y - py, c)  # noqa: E731
    return f(x1, y1) - f(x0, y1) - f(x1, y0) + f(x0, y0)


# ---------------------------------------------------------------- quadrature reductions

GL_X, GL_W = np.polynomial.legendre.leggauss(40)


def panels(lo, hi, breaks):
    pts = sorted({lo, hi, *[b for b in breaks if lo < b < hi]})
    return list(zip(pts[:-1], pts[1:]))


def crossings(lines, lo, hi):
    """Where any two of the lines alpha + beta*t cross inside (lo, hi)."""
    out = []
    for (a1, b1), (a2, b2) in itertools.combinations(lines, 2):
        if abs(b1 - b2) > 1e-15:
            t = (a2 - a1) / (b1 - b2)
            if lo < t < hi:
                out.append(t)
    return out


def interval_length(ends, t):
    """Length of the intersection of intervals [alpha_lo + beta_lo t, alpha_hi + beta_hi t]."""
    lo = max(a + b * t for (a, b), _ in ends)
    hi = min(a + b * t for _, (a, b) in ends)
    return np.maximum(hi - lo, 0.0)


def blocker_ranges(blockers, axis):
    """(lo, hi, h) per blocker: its range on `axis` (0 = x, 1 = y) and its height (z)."""
    out = []
    for b in blockers:
        zs = {p[2] for p in b}
        assert len(zs) == 1, "parallel blockers only"
        vals = [p[axis] for p in b]
        out.append((min(vals), max(vals), zs.pop()))
    return out


def uv_quadrature(blockers):
    """F from the unit square at z=0 to the unit square at z=1, blockers parallel (2-D, (u, v))."""
    rx, ry = blocker_ranges(blockers, 0), blocker_ranges(blockers, 1)
    subsets = [s for r in range(len(blockers) + 1) for s in itertools.combinations(range(len(blockers)), r)]

    def ends(ranges, s):
        # x1 in [0,1], x2 = x1 - u in [0,1], and for each blocker x1 - h u in [lo, hi].
        e = [((0.0, 0.0), (1.0, 0.0)), ((0.0, 1.0), (1.0, 1.0))]
        e += [((ranges[k][0], ranges[k][2]), (ranges[k][1], ranges[k][2])) for k in s]
        return e

    def breaks(ranges):
        lines = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        for lo, hi, h in ranges:
            lines += [(lo, h), (hi, h)]
        return crossings(lines, -1.0, 1.0) + [0.0]

    total = 0.0
    for u0, u1 in panels(-1.0, 1.0, breaks(rx)):
        u = 0.5 * (u1 - u0) * GL_X + 0.5 * (u1 + u0)
        wu = 0.5 * (u1 - u0) * GL_W
        for v0, v1 in panels(-1.0, 1.0, breaks(ry)):
            v = 0.5 * (v1 - v0) * GL_X + 0.5 * (v1 + v0)
            wv = 0.5 * (v1 - v0) * GL_W
            U, V = np.meshgrid(u, v, indexing="ij")
            K = 1.0 / (math.pi * (1.0 + U * U + V * V) ** 2)
            M = np.zeros_like(U)
            for s in subsets:
                lx = np.array([interval_length(ends(rx, s), t) for t in u])
                ly = np.array([interval_length(ends(ry, s), t) for t in v])
                M += (-1) ** len(s) * np.outer(lx, ly)
            total += float(np.einsum("i,j,ij->", wu, wv, K * M))
    return total


def shadow(lo, hi, h, p):
    """Shadow on z=1 of the range [lo, hi] at height h seen from coordinate p at z=0."""
    return p + (lo - p) / h, p + (hi - p) / h


def point_visible(px, py, blockers):
    """Point (px, py, 0), normal +z, to the unit square at z=1 minus the blockers' shadows."""
    rx, ry = blocker_ranges(blockers, 0), blocker_ranges(blockers, 1)
    total = 0.0
    for r in range(len(blockers) + 1):
        for s in itertools.combinations(range(len(blockers)), r):
            x0, x1, y0, y1 = 0.0, 1.0, 0.0, 1.0
            for k in s:
                a, b = shadow(rx[k][0], rx[k][1], rx[k][2], px)
                c, d = shadow(ry[k][0], ry[k][1], ry[k][2], py)
                x0, x1, y0, y1 = max(x0, a), min(x1, b), max(y0, c), min(y1, d)
            total += (-1) ** r * point_to_rect(px, py, 1.0, x0, x1, y0, y1)
    return total


def pointwise_quadrature(blockers):
    """The same F as uv_quadrature, integrating point_visible over A1 (2-D, (x1, y1))."""

    def breaks(ranges):
        # Shadow ends p (1 - 1/h) + e/h against 0, 1 and each other.
        lines = [(0.0, 0.0), (1.0, 0.0)]
        for lo, hi, h in ranges:
            lines += [(lo / h, 1 - 1 / h), (hi / h, 1 - 1 / h)]
        return crossings(lines, 0.0, 1.0)

    rx, ry = blocker_ranges(blockers, 0), blocker_ranges(blockers, 1)
    total = 0.0
    for x0, x1 in panels(0.0, 1.0, breaks(rx)):
        for y0, y1 in panels(0.0, 1.0, breaks(ry)):
            for xi, wi in zip(GL_X, GL_W):
                px = 0.5 * (x1 - x0) * xi + 0.5 * (x1 + x0)
                for yj, wj in zip(GL_X, GL_W):
                    py = 0.5 * (y1 - y0) * yj + 0.5 * (y1 + y0)
                    total += 0.25 * (x1 - x0) * (y1 - y0) * wi * wj * point_visible(px, py, blockers)
    return total


# ---------------------------------------------------------------- Monte Carlo


def axis_rect(poly):
    """An axis-aligned rectangle as (axis, offset, (lo, hi) on the other two axes in order)."""
    p = np.array(poly, dtype=float)
    axis = int(np.argmin(p.max(0) - p.min(0)))
    assert p[:, axis].max() - p[:, axis].min() == 0.0
    others = [a for a in range(3) if a != axis]
    return axis, p[0, axis], [(p[:, a].min(), p[:, a].max()) for a in others], others


def sample_rect(poly, n, rng):
    axis, off, bounds, others = axis_rect(poly)
    out = np.empty((n, 3))
    out[:, axis] = off
    for (lo, hi), a in zip(bounds, others):
        out[:, a] = rng.uniform(lo, hi, n)
    area = (bounds[0][1] - bounds[0][0]) * (bounds[1][1] - bounds[1][0])
    return out, area


def normal_towards(poly, other_point):
    axis, off, _, _ = axis_rect(poly)
    n = np.zeros(3)
    n[axis] = 1.0 if other_point[axis] > off else -1.0
    return n


def monte_carlo(case, samples, seed, chunk=1_000_000):
    rng = np.random.default_rng(seed)
    a2 = case["A2"]
    blockers = [axis_rect(b) for b in case.get("occluders", [])]
    s1 = s2 = 0.0
    done = 0
    while done < samples:
        n = min(chunk, samples - done)
        if "point" in case:
            x1 = np.tile(np.array(case["point"], float), (n, 1))
            n1 = np.array(case["point_normal"], float)
        else:
            x1, _ = sample_rect(case["A1"], n, rng)
            n1 = normal_towards(case["A1"], np.mean(np.array(a2, float), 0))
        x2, area2 = sample_rect(a2, n, rng)
        n2 = normal_towards(a2, np.mean(x1, 0)) if "point" in case else normal_towards(a2, np.mean(np.array(case["A1"], float), 0))
        d = x2 - x1
        r2 = np.einsum("ij,ij->i", d, d)
        c1 = np.clip(d @ n1, 0, None)
        c2 = np.clip(-(d @ n2), 0, None)
        f = area2 * c1 * c2 / (math.pi * r2 * r2)
        for axis, off, bounds, others in blockers:
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (off - x1[:, axis]) / d[:, axis]
            hit = (t > 0) & (t < 1)
            for (lo, hi), a in zip(bounds, others):
                q = x1[:, a] + t * d[:, a]
                hit &= (q >= lo) & (q <= hi)
            f = np.where(hit, 0.0, f)
        s1 += float(f.sum())
        s2 += float((f * f).sum())
        done += n
    mean = s1 / samples
    var = max(s2 / samples - mean * mean, 0.0)
    return mean, math.sqrt(var / (samples - 1))


# ---------------------------------------------------------------- the cases

F_C11 = c11_parallel(1, 1, 1)


def cases():
    out = []

    # A blocker at z = 0.5 over x < 0.5: the ray (x1 -> x2) is hidden iff x1 + x2 < 1.
    blockers = [rect_z(-1, 0.5, -1, 2, 0.5)]
    out.append(dict(
        name="half_blocker_parallel_unit_squares", A1=UNIT_A1, A2=UNIT_A2_TOP, occluders=blockers,
        exact=0.5 * F_C11,
        reference_method="closed form (C-11) and symmetry",
        note="a ray from x1 to x2 crosses z = 0.5 at x = (x1 + x2)/2, so it is hidden iff x1 + x2 < 1; "
        "the map x -> 1 - x on both squares keeps the kernel (it depends on x1 - x2) and swaps "
        "hidden and seen pairs: exactly half of C-11(a = b = c = 1) = %.17g" % F_C11,
        checks={"uv_quadrature": uv_quadrature(blockers), "pointwise_quadrature": pointwise_quadrature(blockers)},
    ))

    blockers = [rect_z(0.3, 0.7, 0.3, 0.7, 0.5)]
    out.append(dict(
        name="centred_small_blocker", A1=UNIT_A1, A2=UNIT_A2_TOP, occluders=blockers,
        exact=uv_quadrature(blockers),
        reference_method="2-D quadrature of the exact reduction (uv_quadrature)",
        note="no closed form (the blocker splits neither square into rectangles); the 4-D integral "
        "reduces exactly to a 2-D one over (x1 - x2, y1 - y2) with a piecewise-bilinear seen-area "
        "weight, integrated by panel Gauss-Legendre (rounding-level error); a second reduction "
        "(B-3 corner formulas over A1, pointwise_quadrature) and Monte Carlo agree",
        checks={"pointwise_quadrature": pointwise_quadrature(blockers)},
    ))

    blockers = [rect_z(0.1, 0.6, 0.1, 0.6, 0.4), rect_z(0.4, 0.9, 0.4, 0.9, 0.6)]
    out.append(dict(
        name="two_overlapping_blockers", A1=UNIT_A1, A2=UNIT_A2_TOP, occluders=blockers,
        exact=uv_quadrature(blockers),
        reference_method="2-D quadrature of the exact reduction (uv_quadrature)",
        note="as centred_small_blocker, with inclusion-exclusion over the two blockers (hidden by "
        "either = by the first + by the second - by both)",
        checks={"pointwise_quadrature": pointwise_quadrature(blockers)},
    ))

    # A1 on z = 0, A2 the wall x = 0; a wall x = 0.5 of height 0.5 stands on A1.
    w = 0.5
    out.append(dict(
        name="perp_shared_edge_low_wall", A1=UNIT_A1,
        A2=[[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]],
        occluders=[[[0.5, -1, 0], [0.5, 2, 0], [0.5, 2, 0.5], [0.5, -1, 0.5]]],
        exact=w * c14_perpendicular(w, 1.0, 1.0),
        reference_method="closed form (C-14) and superposition",
        note="A1 splits at x = 0.5 into a strip 0 <= x1 < 0.5 that sees all of A2 (its rays never "
        "reach x = 0.5) and a strip 0.5 < x1 <= 1 that sees none of it (a ray to height z2 <= 1 "
        "crosses x = 0.5 at z2 (1 - 0.5/x1) <= 0.5); so F = (A_strip/A1) F_C14(w = 0.5, h = 1, "
        "l = 1) = 0.5 * %.17g; the Monte Carlo check has infinite variance here (the kernel is "
        "unbounded at the shared edge), so its standard error is only indicative" % c14_perpendicular(w, 1.0, 1.0),
    ))

    # From (0.5, 0.5, 0) the blocker's shadow on z = 1 is [0,1] x [0,0.7]: the seen part of A2
    # is the rectangle [0,1] x [0.7,1].
    blockers = [rect_z(0.25, 0.75, 0.25, 0.6, 0.5)]
    out.append(dict(
        name="point_under_offset_blocker", A2=UNIT_A2_TOP, point=[0.5, 0.5, 0], point_normal=[0, 0, 1],
        occluders=blockers,
        exact=point_to_rect(0.5, 0.5, 1.0, 0.0, 1.0, 0.7, 1.0),
        reference_method="closed form (B-3) and superposition",
        note="seen from the point, the blocker's shadow on z = 1 (scaled by 2 about (0.5, 0.5)) is "
        "[0,1] x [0,0.7], so the seen part of A2 is the rectangle [0,1] x [0.7,1]: four B-3 corner "
        "terms (point under a corner of a parallel rectangle) with signs",
        checks={"pointwise": point_visible(0.5, 0.5, blockers)},
    ))

    blockers = [rect_z(-1, 2, -1, 2, 0.5)]
    out.append(dict(
        name="full_blocker", A1=UNIT_A1, A2=UNIT_A2_TOP, occluders=blockers,
        exact=0.0,
        reference_method="geometry",
        note="every ray crosses z = 0.5 at ((x1 + x2)/2, (y1 + y2)/2), inside the blocker",
        checks={"uv_quadrature": uv_quadrature(blockers)},
    ))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=100_000_000)
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args()

    # The reductions reproduce the catalogue without blockers.
    assert abs(uv_quadrature([]) - F_C11) < 1e-14, uv_quadrature([])
    assert abs(pointwise_quadrature([]) - F_C11) < 1e-13, pointwise_quadrature([])

    out = cases()
    worst = 0.0
    for k, c in enumerate(out):
        mean, err = monte_carlo(c, args.samples, seed=1000 + k)
        c["monte_carlo"] = {"samples": args.samples, "seed": 1000 + k, "value": mean, "standard_error": err}
        z = abs(mean - c["exact"]) / err if err > 0 else (0.0 if mean == c["exact"] else math.inf)
        for name, v in c.get("checks", {}).items():
            d = abs(v - c["exact"])
            worst = max(worst, d)
            print(f"{c['name']:36} {name:22} {v:.15f} |diff| {d:.1e}")
        print(f"{c['name']:36} {'reference':22} {c['exact']:.15f}  MC {mean:.6f} +- {err:.1e} ({z:.1f} sigma)")
        if z > 4.5:
            sys.exit(f"{c['name']}: Monte Carlo {z:.1f} standard errors away")
        c["reference_method"] += " (scripts/occluded_reference.py)"
    if worst > 1e-12:
        sys.exit(f"independent derivations disagree by {worst:.1e}")

    order = ["name", "A1", "A2", "point", "point_normal", "occluders", "exact", "reference_method", "note",
             "checks", "monte_carlo"]
    out = [{k: c[k] for k in order if k in c} for c in out]
    text = json.dumps(out, indent=1) + "\n"
    if args.check:
        committed = json.load(open(OUT))
        for a, b in zip(committed, out):
            assert a["name"] == b["name"] and abs(a["exact"] - b["exact"]) <= 1e-15, (a["name"], a["exact"], b["exact"])
        print("committed references reproduced")
    else:
        with open(OUT, "w") as f:
            f.write(text)
        print(f"wrote {os.path.relpath(OUT)}")


if __name__ == "__main__":
    main()
