"""A 30 x 10 x 10 mm block of 3 x 1 x 1 C3D20 elements (steel, mm-t-s-N), clamped at x = 0."""

import sys

nx, ny, nz, L = 3, 1, 1, 30.0
h = L / nx
# grid of all positions at half spacing; keep the nodes of hex20 (not face/body centres)
pts = {}


def nid(i, j, k):
    key = (i, j, k)
    if key not in pts:
        pts[key] = len(pts) + 1
    return pts[key]


corner = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2)]
mid = [
    (1, 0, 0),
    (2, 1, 0),
    (1, 2, 0),
    (0, 1, 0),
    (1, 0, 2),
    (2, 1, 2),
    (1, 2, 2),
    (0, 1, 2),
    (0, 0, 1),
    (2, 0, 1),
    (2, 2, 1),
    (0, 2, 1),
]
elements = []
for e in range(nx):
    for a in range(ny):
        for b in range(nz):
            base = (2 * e, 2 * a, 2 * b)
            elements.append(
                [nid(base[0] + c[0], base[1] + c[1], base[2] + c[2]) for c in corner + mid]
            )
free = sys.argv[1] == "free"
with open(sys.argv[2], "w") as f:
    f.write("*HEADING\nC3D20 block 30 x 10 x 10 mm, steel in mm-t-s-N\n*NODE, NSET=NALL\n")
    for (i, j, k), n in sorted(pts.items(), key=lambda t: t[1]):
        f.write(f"{n}, {i * h / 2:.6g}, {j * h / 2:.6g}, {k * h / 2:.6g}\n")
    f.write("*ELEMENT, TYPE=C3D20, ELSET=EALL\n")
    for k, el in enumerate(elements, 1):
        f.write(
            f"{k}, " + ", ".join(map(str, el[:15])) + ",\n" + ", ".join(map(str, el[15:])) + "\n"
        )
    fixed = [n for (i, j, k), n in pts.items() if i == 0]
    f.write("*NSET, NSET=FIX\n" + ",\n".join(map(str, fixed)) + "\n")
    f.write("*MATERIAL, NAME=STEEL\n*ELASTIC\n210000., 0.3\n*DENSITY\n7.85E-9\n")
    f.write("*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n")
    f.write("*STEP\n*FREQUENCY, SOLVER=MATRIXSTORAGE\n10\n")
    if not free:
        f.write("*BOUNDARY\nFIX, 1, 3\n")
    f.write("*END STEP\n")
