"""Write the CalculiX decks of this folder: a steel block of 2 x 1 x 1 C3D20 elements.

``python generate.py`` writes ``free.inp`` and ``fixed.inp`` (a ``*FREQUENCY,
SOLVER=MATRIXSTORAGE`` step: CalculiX writes the stiffness, mass and dof files) and
``free_modes.inp``, ``fixed_modes.inp`` (the same model with a ``*FREQUENCY`` step: the
eigenfrequencies CalculiX prints in the ``.dat`` file).
"""

from pathlib import Path

ELEMENTS = (2, 1, 1)  # along x, y, z
SIZE = (0.2, 0.05, 0.04)  # m
#: Corner and mid-side nodes of a C3D20 element (CalculiX/Abaqus order), as offsets in a
#: grid of half elements.
C3D20 = (
    (0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0), (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2),
    (1, 0, 0), (2, 1, 0), (1, 2, 0), (0, 1, 0), (1, 0, 2), (2, 1, 2), (1, 2, 2), (0, 1, 2),
    (0, 0, 1), (2, 0, 1), (2, 2, 1), (0, 2, 1),
)  # fmt: skip


def nodes() -> dict[tuple[int, int, int], int]:
    """Label of every node of the grid of half elements (labels 103, 106, ...: with gaps)."""
    labels = {}
    nx, ny, nz = ELEMENTS
    for k in range(2 * nz + 1):
        for j in range(2 * ny + 1):
            for i in range(2 * nx + 1):
                if i % 2 + j % 2 + k % 2 <= 1:  # no face or body centres in C3D20
                    labels[i, j, k] = 100 + 3 * (len(labels) + 1)
    return labels


def deck(title: str, step: list[str], supported: bool) -> str:
    labels = nodes()
    lines = ["*HEADING", title, "*NODE, NSET=NALL"]
    for (i, j, k), label in reversed(labels.items()):  # not in label order
        x, y, z = (n * s / (2 * e) for n, s, e in zip((i, j, k), SIZE, ELEMENTS, strict=True))
        lines.append(f"{label}, {x:.6g}, {y:.6g}, {z:.6g}")
    lines.append("*ELEMENT, TYPE=C3D20, ELSET=EALL")
    number = 0
    for ek in range(ELEMENTS[2]):
        for ej in range(ELEMENTS[1]):
            for ei in range(ELEMENTS[0]):
                number += 1
                at = [labels[2 * ei + a, 2 * ej + b, 2 * ek + c] for a, b, c in C3D20]
                lines.append(f"{number}, " + ", ".join(map(str, at[:15])) + ",")
                lines.append(", ".join(map(str, at[15:])))
    clamped = [label for (i, _, _), label in labels.items() if i == 0]
    lines.append("*NSET, NSET=NFIX")
    for start in range(0, len(clamped), 8):
        lines.append(", ".join(map(str, clamped[start : start + 8])) + ",")
    lines += [
        "*MATERIAL, NAME=STEEL",
        "*ELASTIC",
        "210000e6, 0.3",
        "*DENSITY",
        "7850.",
        "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL",
    ]
    if supported:  # the end x = 0 held in x, one of its nodes in y and z, another in z
        lines += ["*BOUNDARY", "NFIX, 1", f"{labels[0, 0, 0]}, 2, 3", f"{labels[0, 1, 0]}, 3"]
    lines += ["*STEP", *step, "*END STEP"]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    here = Path(__file__).parent
    for name, supported in (("free", False), ("fixed", True)):
        matrices = ["*FREQUENCY, SOLVER=MATRIXSTORAGE"]
        modes = ["*FREQUENCY", "12, 1."]  # 12 modes, shift at 1 Hz (a free body is singular)
        (here / f"{name}.inp").write_text(deck(f"{name}: matrices", matrices, supported))
        (here / f"{name}_modes.inp").write_text(deck(f"{name}: modes", modes, supported))
