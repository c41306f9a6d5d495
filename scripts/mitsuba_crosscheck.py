#!/usr/bin/env python3
"""Cross-check Nusselt's path-traced Cornell box reference against Mitsuba 3.

Builds the Mitsuba scene from assets/cornell.obj + cornell.mtl (one shape per face,
one-sided diffuse BSDFs, the light as a front-only area emitter), renders it with the
`path` integrator (unbounded depth, box filter) as two independent half-spp images,
and compares the average with the reference PFM.

Usage: python3 scripts/mitsuba_crosscheck.py --spp 512 \
           --reference benches/data/cornell_256_ref.pfm [--variant llvm_ad_rgb]
Not a project dependency: `pip install mitsuba` (llvm_ad_rgb needs libllvm19).
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def read_pfm(path):
    with open(path, "rb") as f:
        if f.readline().strip() != b"PF":
            raise ValueError("not an RGB PFM")
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.fromfile(f, dtype="<f4" if scale < 0 else ">f4")
    return data.reshape(h, w, 3)[::-1].astype(np.float64)  # row 0 = top


def write_pfm(path, img):
    h, w, _ = img.shape
    with open(path, "wb") as f:
        f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
        np.ascontiguousarray(img[::-1], dtype="<f4").tofile(f)


def parse_scene(obj_path, mtl_path):
    mats, cur = {}, None
    for line in open(mtl_path):
        t = line.split()
        if not t or t[0].startswith("#"):
            continue
        if t[0] == "newmtl":
            cur = t[1]
            mats[cur] = {}
        elif t[0] in ("Kd", "Ke"):
            mats[cur][t[0]] = [float(x) for x in t[1:4]]
    verts, faces, obj, mat = [], [], None, None
    for line in open(obj_path):
        t = line.split()
        if not t or t[0].startswith("#"):
            continue
        if t[0] == "v":
            verts.append([float(x) for x in t[1:4]])
        elif t[0] == "o":
            obj = t[1]
        elif t[0] == "usemtl":
            mat = t[1]
        elif t[0] == "f":
            idx = [int(x.split("/")[0]) - 1 for x in t[1:]]
            faces.append((obj, mat, [verts[i] for i in idx]))
    return mats, faces


def build_scene(mi, mats, faces, tmpdir, seed_sampler_spp):
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": -1}}
    scene["sensor"] = {
        "type": "perspective",
        "fov_axis": "y",
        "fov": 39.3077,
        # Nusselt: image right = forward x up = -x here. Mitsuba's camera x axis is
        # up x forward (= +x), and its film x runs opposite to it, so look_at as-is
        # puts +x (red wall) on the left; checked on the rendered image below.
        "to_world": mi.ScalarTransform4f().look_at(
            origin=[278, 273, -800], target=[278, 273, 0], up=[0, 1, 0]),
        "sampler": {"type": "independent", "sample_count": seed_sampler_spp},
        "film": {"type": "hdrfilm", "width": 256, "height": 256,
                 "pixel_format": "rgb", "component_format": "float32",
                 "rfilter": {"type": "box"}},
    }
    for k, (obj, mat, poly) in enumerate(faces):
        path = os.path.join(tmpdir, "face%03d.obj" % k)
        with open(path, "w") as f:
            for v in poly:
                f.write("v %r %r %r\n" % tuple(v))
            for i in range(1, len(poly) - 1):  # fan, keeps the CCW winding
                f.write("f 1 %d %d\n" % (i + 1, i + 2))
        m = mats[mat]
        shape = {"type": "obj", "filename": path, "face_normals": True,
                 "bsdf": {"type": "diffuse",
                          "reflectance": {"type": "rgb", "value": m["Kd"]}}}
        if "Ke" in m and any(m["Ke"]):
            shape["emitter"] = {"type": "area",
                                "radiance": {"type": "rgb", "value": m["Ke"]}}
        scene["%s_%03d" % (obj, k)] = shape
    return scene


def region_map(mi, scene):
    """Per-pixel region from one primary ray through each pixel centre."""
    labels = np.full((256, 256), -1, dtype=np.int32)
    aov = mi.load_dict({"type": "aov", "aovs": "p:position,n:geo_normal"})
    img = np.array(mi.render(scene, integrator=aov, spp=16, seed=7))
    # channels: r,g,b(unused: aov has no radiance) then p.xyz, n.xyz
    p, n = img[..., -6:-3], img[..., -3:]
    eps = 2.0
    labels[(np.abs(p[..., 1]) < eps) & (n[..., 1] > 0.99)] = 0                 # floor
    labels[(np.abs(p[..., 2] - 559.2) < eps) & (n[..., 2] < -0.99)] = 1        # back wall
    labels[(p[..., 0] > 540) & (n[..., 0] < -0.99)] = 2                        # red wall
    labels[(np.abs(p[..., 0]) < eps) & (n[..., 0] > 0.99)] = 3                 # green wall
    labels[(np.abs(p[..., 1] - 548.8) < eps) & (n[..., 1] < -0.99)] = 4        # ceiling
    return labels


REGIONS = ["floor", "back wall", "red wall", "green wall", "ceiling"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=512, help="total spp (two half-spp seeds)")
    ap.add_argument("--reference", default=os.path.join(ROOT, "benches/data/cornell_256_ref.pfm"))
    ap.add_argument("--variant", default=None, help="default: llvm_ad_rgb if usable, else scalar_rgb")
    ap.add_argument("--save", default=None, help="write the Mitsuba image as PFM here")
    a = ap.parse_args()

    import mitsuba as mi
    variant = a.variant
    if variant is None:
        variant = "llvm_ad_rgb" if "llvm_ad_rgb" in mi.variants() else "scalar_rgb"
    mi.set_variant(variant)
    print("mitsuba %s, variant %s" % (mi.__version__, variant))

    mats, faces = parse_scene(os.path.join(ROOT, "assets/cornell.obj"),
                              os.path.join(ROOT, "assets/cornell.mtl"))
    half = max(1, a.spp // 2)
    with tempfile.TemporaryDirectory() as tmp:
        scene = mi.load_dict(build_scene(mi, mats, faces, tmp, half))
        t0 = time.time()
        A = np.array(mi.render(scene, spp=half, seed=1), dtype=np.float64)[..., :3]
        B = np.array(mi.render(scene, spp=half, seed=2), dtype=np.float64)[..., :3]
        dt = time.time() - t0
        labels = region_map(mi, scene)
    I = 0.5 * (A + B)
    print("rendered 2 x %d spp in %.1f s" % (half, dt))
    if a.save:
        write_pfm(a.save, I)

    R = read_pfm(a.reference)
    # Orientation: the red wall (large x) must be on the left in both images.
    for name, im in (("nusselt", R), ("mitsuba", I)):
        l, r = im[128, :64].mean(0), im[128, -64:].mean(0)
        print("%s: left third rgb %s, right third rgb %s -> red on %s" % (
            name, np.round(l, 3), np.round(r, 3),
            "LEFT" if l[0] / max(l[1], 1e-9) > r[0] / max(r[1], 1e-9) else "RIGHT"))

    s = R.sum(-1)
    bright = s > 5.0
    near = bright.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= np.roll(np.roll(bright, dy, 0), dx, 1)
    mask = ~near & (s > 0)
    print("pixels compared: %d of %d (excluded %d light/adjacent, %d black)" % (
        mask.sum(), mask.size, near.sum(), ((s <= 0) & ~near).sum()))

    Rn = np.sqrt((R[mask] ** 2).sum())
    err = np.sqrt(((I - R)[mask] ** 2).sum()) / Rn
    # var(mean of two halves) per pixel = E|A-B|^2 / 4
    noise = np.sqrt(((A - B)[mask] ** 2).sum() / 4.0) / Rn
    bias = np.sqrt(max(err ** 2 - noise ** 2, 0.0))
    print("relative RMS error  %.4f" % err)
    print("Mitsuba noise (est) %.4f" % noise)
    print("bias = sqrt(err^2 - noise^2) %.4f" % bias)
    print("per-region mean (Mitsuba / Nusselt), RGB and luminance-ish sum:")
    for k, name in enumerate(REGIONS):
        m = mask & (labels == k)
        if not m.any():
            print("  %-10s  (no pixels)" % name)
            continue
        mi_, nu = I[m].mean(0), R[m].mean(0)
        print("  %-10s n=%5d  ratio rgb %s  sum %.4f" % (
            name, m.sum(), np.round(mi_ / nu, 4), mi_.sum() / nu.sum()))
    mall = mask
    print("  %-10s n=%5d  sum ratio %.4f" % ("all", mall.sum(), I[mall].sum() / R[mall].sum()))


if __name__ == "__main__":
    sys.exit(main())
