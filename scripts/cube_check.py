"""Face averages of the ceiling-lit unit cube (`--builtin cube`), default flags against a
fine exact-form-factor solve: the "unit cube" figure of the README.

    python3 scripts/cube_check.py target/release/nusselt [rho]

Prints, per face, the area-weighted mean radiance of both solves and their relative
difference, and the default solve's element count and time."""
import csv, json, subprocess, sys, tempfile, os

def solve(binary, rho, extra, tmp, name):
    out = os.path.join(tmp, name + ".csv")
    cmd = [binary, "render", "--builtin", "cube", "--rho", str(rho), "--out",
           os.path.join(tmp, name + ".pfm"), "--json", "--quiet", "--elements-csv", out] + extra
    summary = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    faces = {}
    for r in csv.DictReader(open(out)):
        c = [float(r[k]) for k in ("cx", "cy", "cz")]
        axis = min(range(3), key=lambda k: min(c[k], 1 - c[k]))
        key = "xyz"[axis] + ("=0" if c[axis] < 0.5 else "=1")
        a = float(r["area"])
        s = faces.setdefault(key, [0.0, 0.0])
        s[0] += a * float(r["r"]); s[1] += a
    return summary, {k: v[0] / v[1] for k, v in faces.items()}

binary = sys.argv[1] if len(sys.argv) > 1 else "target/release/nusselt"
rho = float(sys.argv[2]) if len(sys.argv) > 2 else 0.5
with tempfile.TemporaryDirectory() as tmp:
    d, default = solve(binary, rho, ["--unshot", "1e-4"], tmp, "default")
    f, fine = solve(binary, rho, ["--formfactor", "exact", "--element-size", "0.025",
                                  "--patch-size", "0.1", "--unshot", "1e-7"], tmp, "fine")
print(f"rho {rho}: default {d['elements']} elements, {d['patches']} patches, "
      f"{d['shots']} shots, solve {d['solve_seconds']:.3f} s; fine exact {f['elements']} elements")
worst = 0.0
for k in sorted(fine):
    rel = abs(default[k] - fine[k]) / fine[k]
    worst = max(worst, rel)
    print(f"  face {k}: default {default[k]:.6f}  fine {fine[k]:.6f}  diff {100 * rel:.3f} %")
print(f"  worst face {100 * worst:.3f} %")
