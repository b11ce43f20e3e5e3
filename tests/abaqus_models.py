"""Helpers of the Abaqus reader tests: small models with exact matrices, and the genuine files.

The synthetic models are assembled here from first principles (linear tetrahedra, pymorembs'
beam element) so that their stiffness has exactly the rigid-body null space a real export has;
the files are written in the layouts Abaqus writes.
"""

from __future__ import annotations

import hashlib
import itertools
import lzma
from pathlib import Path

import numpy as np

DATA = Path(__file__).parent / "data"

#: SHA-256 of the original bytes of the genuine files stored xz-compressed (see SOURCE.md).
SHA256 = {
    "exudyn_abaqus_blocks/blockC3D4_STIF1.mtx": (
        "86e0fb1a7210a4f5ecc227bb97ea41a663690d8914cf2483cc74465d445fb25b"
    ),
    "exudyn_abaqus_blocks/blockC3D20R_STIF1.mtx": (
        "5d73d50353b46206e30ac911de92ff74330b5435c635765fe58d0484266d9657"
    ),
    "juliafem_abaqus_tetra_beam/STIF1_coord_style.mtx": (
        "57e0c11972744d10ed68e2fed04156f8af385eac454b880e5a598c4f391bb125"
    ),
    "juliafem_abaqus_tetra_beam/MASS1_coord_style.mtx": (
        "46d859d4f20d63096cb09066641b831fe92297c2877f50311732e3d12f55a5a1"
    ),
    "abaqus_mtx_parser/recovery/interface-beam-sub.mtx": (
        "ffd6f64b794b2b03c6eba205ce7bd4c7cdbd8ea21d0b9b884af7aea04657d97a"
    ),
}


def genuine(relative: str, directory: Path) -> Path:
    """Path of a genuine file of ``tests/data``; a compressed one is unpacked into ``directory``.

    The unpacked bytes are checked against :data:`SHA256`, so the file read is the original.
    """
    plain = DATA / relative
    if plain.exists():
        return plain
    target = directory / relative
    if not target.exists():
        data = lzma.decompress((DATA / f"{relative}.xz").read_bytes())
        assert hashlib.sha256(data).hexdigest() == SHA256[relative], relative
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    return target


def read_coordinate_file(path: Path, n: int) -> np.ndarray:
    """A ``row col value`` file as a dense matrix, parsed with plain numpy (independent)."""
    data = np.loadtxt(path, ndmin=2)
    matrix = np.zeros((n, n))
    rows, cols = data[:, 0].astype(int) - 1, data[:, 1].astype(int) - 1
    matrix[rows, cols] = data[:, 2]
    return matrix


# ============================================================================ synthetic models
def cube(size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The 8 corners of a cube (corner k has bits x, y, z) and its 6 Kuhn tetrahedra."""
    xyz = np.array([[(k >> a) & 1 for a in range(3)] for k in range(8)], dtype=float) * size
    tets = []
    for perm in itertools.permutations(range(3)):
        path = [0]
        for axis in perm:
            path.append(path[-1] | (1 << axis))
        tets.append(path)
    return xyz, np.array(tets)


def tet_stiffness(xyz: np.ndarray, E: float = 2.1e11, nu: float = 0.3) -> np.ndarray:
    """Stiffness (12 x 12) of a linear tetrahedron, dofs ux uy uz of its nodes in turn."""
    a = np.hstack([np.ones((4, 1)), xyz])
    volume = abs(np.linalg.det(a)) / 6.0
    grad = np.linalg.inv(a)[1:]  # (3, 4): gradient of each shape function
    b = np.zeros((6, 12))
    for i in range(4):
        gx, gy, gz = grad[:, i]
        b[:, 3 * i : 3 * i + 3] = [[gx, 0, 0], [0, gy, 0], [0, 0, gz], [gy, gx, 0], [0, gz, gy],
                                   [gz, 0, gx]]  # fmt: skip
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    d = np.zeros((6, 6))
    d[:3, :3] = lam
    d[np.arange(6), np.arange(6)] += [2 * mu] * 3 + [mu] * 3
    return volume * b.T @ d @ b


def solid_matrices(
    xyz: np.ndarray, tets: np.ndarray, rho: float = 7850.0
) -> tuple[np.ndarray, np.ndarray]:
    """Assembled stiffness and lumped mass (3 dofs per node, nodes in the order of ``xyz``).

    ``K`` is made exactly symmetric (the mean of both triangles), as a written file is.
    """
    n = 3 * xyz.shape[0]
    k, m = np.zeros((n, n)), np.zeros(n)
    for tet in tets:
        eq = (3 * tet[:, None] + np.arange(3)).ravel()
        k[np.ix_(eq, eq)] += tet_stiffness(xyz[tet])
        volume = abs(np.linalg.det(np.hstack([np.ones((4, 1)), xyz[tet]]))) / 6.0
        m[eq] += rho * volume / 4.0
    return 0.5 * (k + k.T), np.diag(m)  # exactly symmetric, as Abaqus writes it


def coordinate_text(matrix: np.ndarray) -> str:
    """FORMAT=COORDINATE: ``row col value``, both triangles, equations from 1, exact values."""
    rows, cols = np.nonzero(matrix)
    return "".join(
        f"{i + 1} {j + 1}  {float(matrix[i, j])!r}\n"
        for i, j in zip(rows.tolist(), cols.tolist(), strict=True)
    )


def matrix_input_text(matrix: np.ndarray, keys: list[tuple[int, int]]) -> str:
    """FORMAT=MATRIX INPUT: ``node,dof, node,dof, value``, lower triangle by columns."""
    lines = []
    n = matrix.shape[0]
    for j in range(n):
        for i in range(j, n):
            if matrix[i, j] != 0.0:
                (ni, di), (nj, dj) = keys[i], keys[j]
                lines.append(f"{ni},{di}, {nj},{dj},  {float(matrix[i, j])!r}")
    return "\n".join(lines) + "\n"


def node_lines(labels: list[int] | np.ndarray, xyz: np.ndarray) -> list[str]:
    return [
        f"{int(label):7d}, {x!r}, {y!r}, {z!r}"
        for label, (x, y, z) in zip(labels, xyz.tolist(), strict=True)
    ]


def element_lines(connectivity: np.ndarray, first: int = 1) -> list[str]:
    return [
        f"{first + k}, " + ", ".join(str(int(v)) for v in row) for k, row in enumerate(connectivity)
    ]


def rotate(xyz: np.ndarray, a: np.ndarray, b: np.ndarray, degrees: float) -> np.ndarray:
    """Points rotated by ``degrees`` about the axis a -> b (right hand), computed independently."""
    k = (b - a) / np.linalg.norm(b - a)
    t = np.radians(degrees)
    p = xyz - a
    return a + p * np.cos(t) + np.cross(k, p) * np.sin(t) + np.outer(p @ k, k) * (1.0 - np.cos(t))


def substructure_text(
    nodes: list[int],
    dof_lines: list[str],
    matrices: dict[str, np.ndarray],
    unsym: bool = False,
) -> str:
    """A ``*SUBSTRUCTURE MATRIX OUTPUT`` file: node list, dof lines, ``*MATRIX`` blocks.

    Values are written four to a line, comma separated, the lower triangle row by row (the
    full matrix row by row for ``TYPE=STIFFNESS`` with ``unsym``), as Abaqus writes them.
    """
    head = f"*USER ELEMENT, NODES={len(nodes):10d}, LINEAR" + (", UNSYM" if unsym else "")
    lines = ["**", "** GENERATION OF SUBSTRUCTURE Z1", head, "** ELEMENT NODES"]
    lines.append("** " + ", ".join(f"{node:10d}" for node in nodes))
    lines += dof_lines
    for kind, matrix in matrices.items():
        lines.append(f"*MATRIX,TYPE={kind}")
        n = matrix.shape[0]
        for i in range(n):
            row = matrix[i] if unsym and kind == "STIFFNESS" else matrix[i, : i + 1]
            values = [f"{float(v)!r:>20}" for v in row]
            for start in range(0, len(values), 4):
                lines.append(", ".join(values[start : start + 4]))
    return "\n".join(lines) + "\n"
