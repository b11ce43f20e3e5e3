"""An L-shaped steel bracket with two pin holes, meshed by gmsh into quadratic tetrahedra, as a
CalculiX input deck (C3D10, SI units).

Run with a Python that has ``gmsh`` and ``numpy`` (gmsh from PyPI, kept out of the project's
environment, e.g. ``python3 -m venv /tmp/gmshv && /tmp/gmshv/bin/pip install gmsh numpy``)::

    /tmp/gmshv/bin/python bench/bracket_part.py --dofs 283000 --out /work/data/bracket300k

The geometry: a horizontal leg 120 x 60 x 10 mm (x, y, z) and a vertical leg 10 x 60 x 100 mm
standing on it at x = 0, fused; a pin hole of 16 mm diameter through each leg (axis z at
x = 90 mm, y = 30 mm through the horizontal leg; axis x at y = 30 mm, z = 70 mm through the
vertical one). Steel: E = 210 GPa, nu = 0.3, rho = 7850 kg/m^3. The mesh size follows from the
wanted number of dofs (3 per node); the mesh is made once more with a corrected size if the first
one misses it by more than 5 %.

Written into ``--out``:

``bracket.inp``
    The model (``*NODE``, ``*ELEMENT, TYPE=C3D10``, node sets ``HOLE_A`` and ``HOLE_B`` of the
    nodes on the two hole surfaces, ``*MATERIAL``, ``*SOLID SECTION``) and the step
    ``*FREQUENCY, SOLVER=MATRIXSTORAGE``: ``ccx -i bracket`` exports ``bracket.sti``,
    ``bracket.mas``, ``bracket.dof`` (free-free, no supports).
``bracket_modes.inp``
    The same model with the step ``*FREQUENCY`` of ``--modes`` eigenvalues (CalculiX's default
    solver), free-free: ``ccx -i bracket_modes`` writes the frequencies into
    ``bracket_modes.dat``.
``mesh.json``
    Nodes, elements, dofs and the mesh size used.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import gmsh
import numpy as np

#: Dimensions (m).
LEG_LENGTH = 0.120
WIDTH = 0.060
THICKNESS = 0.010
HEIGHT = 0.100
HOLE_DIAMETER = 0.016
#: Steel (Pa, -, kg/m^3).
YOUNG = 210e9
POISSON = 0.3
DENSITY = 7850.0
#: Dofs of the mesh per unit volume / size**-3, a first guess the second meshing corrects.
DOFS_PER_VOLUME_SIZE3 = 25.0
#: gmsh's 10-node tetrahedron to CalculiX's C3D10: the last two mid-side nodes swap.
GMSH_TO_C3D10 = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]


def build_geometry() -> tuple[list[int], list[int]]:
    """The bracket in gmsh's OpenCASCADE kernel.

    Returns
    -------
    hole_a, hole_b : list of int
        Surface tags of the horizontal leg's hole and of the vertical leg's hole.
    """
    occ = gmsh.model.occ
    base = occ.addBox(0, 0, 0, LEG_LENGTH, WIDTH, THICKNESS)
    wall = occ.addBox(0, 0, 0, THICKNESS, WIDTH, HEIGHT)
    fused, _ = occ.fuse([(3, base)], [(3, wall)])
    radius = HOLE_DIAMETER / 2
    pin_a = occ.addCylinder(0.090, WIDTH / 2, -0.001, 0, 0, THICKNESS + 0.002, radius)
    pin_b = occ.addCylinder(-0.001, WIDTH / 2, 0.070, THICKNESS + 0.002, 0, 0, radius)
    occ.cut(fused, [(3, pin_a), (3, pin_b)])
    occ.synchronize()
    hole_a, hole_b = [], []
    for _, tag in gmsh.model.getEntities(2):
        if gmsh.model.getType(2, tag) != "Cylinder":
            continue
        xmin, _, _, xmax, _, _ = gmsh.model.getBoundingBox(2, tag)
        (hole_a if xmin > 0.05 else hole_b).append(tag)
        assert xmax <= LEG_LENGTH
    return hole_a, hole_b


def mesh(size: float) -> None:
    """Second-order tetrahedra of about ``size`` metres (curved mid-side nodes on the holes)."""
    gmsh.model.mesh.clear()
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 12)
    gmsh.option.setNumber("Mesh.ElementOrder", 2)
    gmsh.option.setNumber("Mesh.SecondOrderLinear", 0)
    gmsh.option.setNumber("Mesh.Algorithm3D", 10)
    gmsh.option.setNumber("General.NumThreads", 2)
    gmsh.model.mesh.generate(3)


def mesh_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node labels, coordinates (m) and C3D10 connectivity of the current mesh (used nodes only).

    Returns
    -------
    labels : ndarray, shape (n,)
    coords : ndarray, shape (n, 3)
    elements : ndarray, shape (e, 10)
        Node labels in CalculiX's order, each element with a positive volume.
    """
    tags, coords, _ = gmsh.model.mesh.getNodes()
    coords = np.asarray(coords).reshape(-1, 3)
    types, _, node_tags = gmsh.model.mesh.getElements(3)
    (tet10,) = [k for k, t in enumerate(types) if t == 11]
    elements = np.asarray(node_tags[tet10], dtype=np.int64).reshape(-1, 10)[:, GMSH_TO_C3D10]
    used = np.unique(elements)
    position = np.zeros(int(max(tags.max(), used.max())) + 1, dtype=np.int64)
    position[np.asarray(tags, dtype=np.int64)] = np.arange(len(tags))
    corner = coords[position[elements[:, :4]]]
    volume = np.einsum(
        "ij,ij->i",
        np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0]),
        corner[:, 3] - corner[:, 0],
    )
    flip = volume < 0
    # Swap corners 2 and 3 with their mid-side nodes: 5<->7 (edges 1-2, 1-3), 9<->10.
    elements[np.ix_(flip, [1, 2, 4, 6, 8, 9])] = elements[np.ix_(flip, [2, 1, 6, 4, 9, 8])]
    return used, coords[position[used]], elements


def surface_nodes(surfaces: list[int]) -> np.ndarray:
    """Labels of the mesh nodes on the given surfaces (their edges included)."""
    found = [
        np.asarray(gmsh.model.mesh.getNodes(2, tag, includeBoundary=True)[0], dtype=np.int64)
        for tag in surfaces
    ]
    return np.unique(np.concatenate(found))


def node_set(name: str, labels: np.ndarray) -> str:
    rows = [", ".join(str(v) for v in labels[i : i + 16]) for i in range(0, len(labels), 16)]
    return f"*NSET, NSET={name}\n" + "\n".join(rows) + "\n"


def write_decks(out: Path, labels, coords, elements, sets: dict[str, np.ndarray], modes: int):
    """``bracket.inp`` (matrix storage) and ``bracket_modes.inp`` (``*FREQUENCY``)."""
    lines = ["*HEADING", "L-shaped steel bracket with two pin holes (gmsh, C3D10, SI units)"]
    lines.append("*NODE, NSET=NALL")
    lines += [
        f"{n}, {x:.17g}, {y:.17g}, {z:.17g}" for n, (x, y, z) in zip(labels, coords, strict=True)
    ]
    lines.append("*ELEMENT, TYPE=C3D10, ELSET=EALL")
    numbers = np.column_stack([np.arange(1, len(elements) + 1), elements])
    lines += [
        ", ".join(map(str, row[:9])) + ",\n" + ", ".join(map(str, row[9:])) for row in numbers
    ]
    model = "\n".join(lines) + "\n"
    model += "".join(node_set(name, nodes) for name, nodes in sets.items())
    model += (
        "*MATERIAL, NAME=STEEL\n*ELASTIC\n"
        f"{YOUNG:.6g}, {POISSON}\n*DENSITY\n{DENSITY}\n"
        "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n"
    )
    (out / "bracket.inp").write_text(model + "*STEP\n*FREQUENCY, SOLVER=MATRIXSTORAGE\n*END STEP\n")
    (out / "bracket_modes.inp").write_text(model + f"*STEP\n*FREQUENCY\n{modes}\n*END STEP\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--dofs", type=int, default=283_000, help="about this many dofs")
    parser.add_argument("--out", type=Path, required=True, help="directory of the decks")
    parser.add_argument("--modes", type=int, default=20, help="eigenvalues of bracket_modes.inp")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    gmsh.initialize(["gmsh", "-v", "2"])
    try:
        gmsh.model.add("bracket")
        hole_a, hole_b = build_geometry()
        volume = sum(gmsh.model.occ.getMass(3, t) for _, t in gmsh.model.getEntities(3))
        size = (DOFS_PER_VOLUME_SIZE3 * volume / args.dofs) ** (1 / 3)
        for _ in range(3):
            mesh(size)
            labels, coords, elements = mesh_arrays()
            dofs = 3 * len(labels)
            print(f"size {size * 1e3:.3f} mm: {len(elements)} C3D10, {dofs} dofs", flush=True)
            if abs(dofs / args.dofs - 1) <= 0.05:
                break
            size *= (dofs / args.dofs) ** (1 / 3)
        sets = {"HOLE_A": surface_nodes(hole_a), "HOLE_B": surface_nodes(hole_b)}
        write_decks(args.out, labels, coords, elements, sets, args.modes)
        facts = {
            "nodes": len(labels),
            "elements": len(elements),
            "dofs": dofs,
            "mesh_size_m": size,
            "volume_m3": volume,
            "hole_nodes": {k: len(v) for k, v in sets.items()},
            "gmsh": gmsh.__version__,
        }
        (args.out / "mesh.json").write_text(json.dumps(facts, indent=1) + "\n")
        print(json.dumps(facts))
    finally:
        gmsh.finalize()
    return 0


if __name__ == "__main__":
    sys.exit(main())
