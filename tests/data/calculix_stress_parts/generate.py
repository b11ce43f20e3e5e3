"""Write the CalculiX decks of the stress checks: two small steel parts meshed with gmsh.

Run in this folder with gmsh's Python module on the path (``pip install gmsh``), then ccx
(README.md). Units SI (m, N, Pa). Each part is clamped at x = 0 (``*BOUNDARY``) and has a rigid
interface at its far end: the nodes of the face x = L coupled to a reference node with
``*COUPLING`` + ``*KINEMATIC`` (translations 1-3; the reference node carries moments too).

Parts (``PARTS``):

``plate``
    A bar 0.10 x 0.03 x 0.012 with a hole of radius 0.006 through its thickness at x = 0.05,
    quadratic tetrahedra C3D10 (gmsh, free mesh).
``bar``
    A bar 0.08 x 0.02 x 0.016 of 6 x 2 x 2 serendipity hexahedra, written twice: C3D20
    (``bar``) and C3D20R (``barr``).

Decks per part ``P``:

``P.inp``
    Mesh, material, clamp and a ``*FREQUENCY, SOLVER=MATRIXSTORAGE`` step: ccx writes ``P.sti``,
    ``P.mas``, ``P.dof`` (no coupling there: the reader takes only the clamp; pymorembs adds its
    own rigid interface node).
``P_static.inp``
    The same mesh with the reference node and the coupling, six ``*STATIC`` steps: a unit force
    in x, y, z and a unit moment about x, y, z at the reference node; ``*EL PRINT`` of ``S``,
    ``E`` and ``COORD`` at the integration points of the elements of the set ``PRINT`` (a few
    elements, listed in the deck) into ``P_static.dat``; ``*EL FILE`` of ``S`` into
    ``P_static.frd``: the stresses extrapolated to the nodes and averaged there by CalculiX.
"""

from __future__ import annotations

import gmsh
import numpy as np

E, NU, RHO = 2.1e11, 0.3, 7850.0
REFERENCE = 99999  # the reference node of the coupling
ABAQUS_TET10_EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
ABAQUS_HEX20_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
                      (0, 4), (1, 5), (2, 6), (3, 7)]  # fmt: skip


def abaqus_order(nodes: np.ndarray, xyz: dict[int, np.ndarray], corners: int, edges) -> list[int]:
    """The element's nodes in Abaqus/CalculiX order: corners as gmsh lists them (the same
    convention), each mid-edge node found by its position at the middle of its edge."""
    corner, mids = list(nodes[:corners]), list(nodes[corners:])
    out = list(corner)
    for a, b in edges:
        middle = 0.5 * (xyz[corner[a]] + xyz[corner[b]])
        distance = [np.linalg.norm(xyz[m] - middle) for m in mids]
        k = int(np.argmin(distance))
        assert distance[k] < 1e-9
        out.append(mids.pop(k))
    return out


def mesh_plate() -> tuple[dict[int, np.ndarray], list[list[int]], float]:
    gmsh.model.add("plate")
    box = gmsh.model.occ.addBox(0, 0, 0, 0.10, 0.03, 0.012)
    hole = gmsh.model.occ.addCylinder(0.05, 0.015, -0.01, 0, 0, 0.032, 0.006)
    gmsh.model.occ.cut([(3, box)], [(3, hole)])
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.01)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.004)
    gmsh.option.setNumber("Mesh.ElementOrder", 2)
    gmsh.option.setNumber("Mesh.SecondOrderLinear", 1)  # straight edges: mid-nodes at the middle
    gmsh.model.mesh.generate(3)
    return *collect(11, 4, ABAQUS_TET10_EDGES), 0.10


def mesh_bar() -> tuple[dict[int, np.ndarray], list[list[int]], float]:
    gmsh.model.add("bar")
    box = gmsh.model.occ.addBox(0, 0, 0, 0.08, 0.02, 0.016)
    gmsh.model.occ.synchronize()
    for _, curve in gmsh.model.getEntities(1):
        lo = gmsh.model.getBoundingBox(1, curve)
        length = max(lo[3] - lo[0], lo[4] - lo[1], lo[5] - lo[2])
        gmsh.model.mesh.setTransfiniteCurve(curve, 7 if length > 0.05 else 3)
    for _, surface in gmsh.model.getEntities(2):
        gmsh.model.mesh.setTransfiniteSurface(surface)
        gmsh.model.mesh.setRecombine(2, surface)
    gmsh.model.mesh.setTransfiniteVolume(box)
    gmsh.model.mesh.setRecombine(3, box)
    gmsh.option.setNumber("Mesh.ElementOrder", 2)
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", 1)
    gmsh.model.mesh.generate(3)
    return *collect(17, 8, ABAQUS_HEX20_EDGES), 0.08


def collect(element_type: int, corners: int, edges) -> tuple[dict[int, np.ndarray], list]:
    tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = {int(t): np.asarray(c) for t, c in zip(tags, coords.reshape(-1, 3), strict=True)}
    _, nodes = gmsh.model.mesh.getElementsByType(element_type)
    per = len(edges) + corners
    elements = [abaqus_order(e, xyz, corners, edges) for e in nodes.reshape(-1, per).astype(int)]
    used = sorted({n for e in elements for n in e})
    return {n: xyz[n] for n in used}, elements


def write_decks(name: str, element: str, xyz, elements, length: float) -> None:
    nodes = np.array(sorted(xyz))
    points = np.array([xyz[n] for n in nodes])
    clamp = nodes[np.abs(points[:, 0]) < 1e-9]
    tip = nodes[np.abs(points[:, 0] - length) < 1e-9]
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    reference = (length + 0.01, centre[1] + 0.002, centre[2] - 0.001)
    numbers = 1000 + 3 * np.arange(len(elements))  # element numbers with gaps
    chosen = np.linspace(0, len(elements) - 1, 8 if element == "C3D10" else 4)
    printed = numbers[chosen.round().astype(int)]

    def lines(values, per=8):
        values = list(values)
        return "".join(
            ", ".join(str(v) for v in values[k : k + per]) + "\n"
            for k in range(0, len(values), per)
        )

    mesh = ["*NODE, NSET=NALL\n"]
    mesh += [
        f"{n}, {p[0]:.15g}, {p[1]:.15g}, {p[2]:.15g}\n" for n, p in zip(nodes, points, strict=True)
    ]
    mesh.append(f"*ELEMENT, TYPE={element}, ELSET=EALL\n")
    for number, e in zip(numbers, elements, strict=True):
        entries = [str(v) for v in (number, *e)]  # at most 16 entries a line, "," continues
        rows = [", ".join(entries[k : k + 16]) for k in range(0, len(entries), 16)]
        mesh.append(",\n".join(rows) + "\n")
    mesh.append("*NSET, NSET=CLAMP\n" + lines(clamp))
    mesh.append("*NSET, NSET=TIP\n" + lines(tip))
    mesh.append("*ELSET, ELSET=PRINT\n" + lines(printed))
    mesh.append(f"*MATERIAL, NAME=STEEL\n*ELASTIC\n{E:g}, {NU:g}\n*DENSITY\n{RHO:g}\n")
    mesh.append("*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n")
    mesh.append("*BOUNDARY\nCLAMP, 1, 3\n")
    text = "".join(mesh)
    with open(f"{name}.inp", "w") as f:
        f.write(text + "*STEP\n*FREQUENCY, SOLVER=MATRIXSTORAGE\n*END STEP\n")
    coupling = (
        f"*NODE, NSET=REF\n{REFERENCE}, {reference[0]:.15g}, {reference[1]:.15g}, "
        f"{reference[2]:.15g}\n"
        "*SURFACE, TYPE=NODE, NAME=TIPS\nTIP\n"
        f"*COUPLING, REF NODE={REFERENCE}, SURFACE=TIPS, CONSTRAINT NAME=INTERFACE\n"
        "*KINEMATIC\n1, 3\n"
    )
    steps = []
    for dof in range(1, 7):
        steps.append(
            f"*STEP\n*STATIC\n*CLOAD, OP=NEW\n{REFERENCE}, {dof}, 1.\n"
            "*EL FILE\nS\n*EL PRINT, ELSET=PRINT\nS, E, COORD\n*END STEP\n"
        )
    with open(f"{name}_static.inp", "w") as f:
        f.write(text + coupling + "".join(steps))


PARTS = {"plate": (mesh_plate, ["C3D10"]), "bar": (mesh_bar, ["C3D20", "C3D20R"])}

if __name__ == "__main__":
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    for part, (make, types) in PARTS.items():
        xyz, elements, length = make()
        for element in types:
            name = part if element != "C3D20R" else part + "r"
            write_decks(name, element, xyz, elements, length)
    gmsh.finalize()
