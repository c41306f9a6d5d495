#!/usr/bin/env python3
"""Writes assets/tworooms.obj and .mtl: two 4 x 2.5 x 4 m rooms side by side, joined by a
door left ajar (a 0.1 m x 2 m gap in a 0.1 m thick wall), the light (1 x 1 m, radiance 10)
in the ceiling of the left room. The right room is lit only through the gap: the scene of
the case where a global ambient term shows the unlit room far too bright mid-solve.

Faces are one-sided with normals into the rooms (counter-clockwise seen from inside)."""
import os

H, D = 2.5, 4.0            # height (y), depth (z)
XA0, XA1 = 0.0, 4.0        # left room (lit)
XB0, XB1 = 4.1, 8.1        # right room
Z0, Z1, DOOR_H = 1.0, 1.1, 2.0   # the gap in the wall x in [4, 4.1]
L0, L1 = 1.5, 2.5          # the light square in the left ceiling (x and z)

verts, faces = [], []


def quad(mat, a, b, c, d):
    """A quad a-b-c-d, counter-clockwise seen from the side it faces."""
    base = len(verts)
    verts.extend([a, b, c, d])
    faces.append((mat, [base + 1, base + 2, base + 3, base + 4]))


def floor(x0, x1, z0, z1, mat="floor"):  # normal +y
    quad(mat, (x0, 0, z0), (x0, 0, z1), (x1, 0, z1), (x1, 0, z0))


def ceiling(x0, x1, z0, z1, mat="wall"):  # normal -y
    quad(mat, (x0, H, z0), (x1, H, z0), (x1, H, z1), (x0, H, z1))


def wall_x(x, z0, z1, y0, y1, normal):  # plane x, normal +1 or -1
    if normal > 0:
        quad("wall", (x, y0, z0), (x, y1, z0), (x, y1, z1), (x, y0, z1))
    else:
        quad("wall", (x, y0, z0), (x, y0, z1), (x, y1, z1), (x, y1, z0))


def wall_z(z, x0, x1, y0, y1, normal):  # plane z, normal +1 or -1
    if normal > 0:
        quad("wall", (x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z))
    else:
        quad("wall", (x0, y0, z), (x0, y1, z), (x1, y1, z), (x1, y0, z))


for x0, x1 in [(XA0, XA1), (XB0, XB1)]:
    floor(x0, x1, 0, D)
    wall_z(0, x0, x1, 0, H, +1)
    wall_z(D, x0, x1, 0, H, -1)
# Left room: the ceiling around the light, the light, the outer wall.
ceiling(XA0, XA1, 0, L0)
ceiling(XA0, XA1, L1, D)
ceiling(XA0, L0, L0, L1)
ceiling(L1, XA1, L0, L1)
ceiling(L0, L1, L0, L1, mat="light")
wall_x(XA0, 0, D, 0, H, +1)
# Right room: ceiling and outer wall.
ceiling(XB0, XB1, 0, D)
wall_x(XB1, 0, D, 0, H, -1)
# The shared wall, both sides, with the gap z in [Z0, Z1], y in [0, DOOR_H].
for x, n in [(XA1, -1), (XB0, +1)]:
    wall_x(x, 0, Z0, 0, H, n)
    wall_x(x, Z1, D, 0, H, n)
    wall_x(x, Z0, Z1, DOOR_H, H, n)
# The gap's jambs, lintel and threshold (inside the wall's thickness).
wall_z(Z0, XA1, XB0, 0, DOOR_H, +1)
wall_z(Z1, XA1, XB0, 0, DOOR_H, -1)
quad("wall", (XA1, DOOR_H, Z0), (XB0, DOOR_H, Z0), (XB0, DOOR_H, Z1), (XA1, DOOR_H, Z1))
floor(XA1, XB0, Z0, Z1)

root = os.path.join(os.path.dirname(__file__), "..", "assets")
with open(os.path.join(root, "tworooms.obj"), "w") as f:
    f.write("# Two rooms joined by a door left ajar (scripts/tworooms.py): the light in the\n")
    f.write("# left room's ceiling, the right room lit only through a 0.1 m gap. Units: metres.\n")
    f.write("mtllib tworooms.mtl\n")
    for v in verts:
        f.write("v %g %g %g\n" % v)
    mat = None
    for m, idx in faces:
        if m != mat:
            f.write("usemtl %s\n" % m)
            mat = m
        f.write("f %s\n" % " ".join(map(str, idx)))
with open(os.path.join(root, "tworooms.mtl"), "w") as f:
    f.write("newmtl wall\nKd 0.75 0.75 0.75\n\n")
    f.write("newmtl floor\nKd 0.5 0.45 0.4\n\n")
    f.write("newmtl light\nKd 0.78 0.78 0.78\nKe 10 10 10\n")
print(len(verts), "vertices,", len(faces), "faces")
