"""The outer surface of a body's elements: what a viewer draws of the body.

A :class:`Surface` holds triangles and line segments over the body's node ids. It is built
from element connectivity by :func:`outer_surface`: for solids, the faces that belong to one
element only (the faces inside the body are shared by two); shells are their own faces (one
set of triangles for both sides; a shell on a solid's face is not drawn twice); beams and other
line elements are segments. Quadratic faces are split into triangles through their
mid-side nodes, so that every surface node carries the motion a shape function gives it and a
curved hole stays round. Triangles are oriented outward (their normal points away from the
element they belong to), whatever the node order of the elements.

A body without elements (a bare matrix export) has no surface; a viewer then shows its nodes as
points.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from pymorembs.arrays import missing_from, sorted_unique
from pymorembs.display import one_line
from pymorembs.errors import UserError

__all__ = ["SURFACE_ELEMENTS", "Surface", "outer_surface", "smooth_patch"]

# Faces of each element kind as loops of local node numbers (0-based). Quadratic faces list
# corner, mid-side, corner, ... in turn. Node orders of Abaqus (C3D4, C3D10, C3D8, C3D20, C3D6,
# C3D15, C3D5, S3, STRI65, S4, S8R); Nastran (CTETRA, CPYRAM, CTRIA3/6, CQUAD4/8) and Ansys
# (SOLID185/186/187, SHELL181/281) share them, CHEXA and CPENTA with 20 / 15 grids list their
# edges in another order (the reader reorders them). pyramid13 is Nastran's CPYRAM with all
# edge grids.
_FACES: dict[str, tuple[tuple[int, ...], ...]] = {
    "tet4": ((0, 2, 1), (0, 1, 3), (1, 2, 3), (2, 0, 3)),
    "tet10": ((0, 6, 2, 5, 1, 4), (0, 4, 1, 8, 3, 7), (1, 5, 2, 9, 3, 8), (2, 6, 0, 7, 3, 9)),
    "hex8": ((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)),
    "hex20": (
        (0, 11, 3, 10, 2, 9, 1, 8),
        (4, 12, 5, 13, 6, 14, 7, 15),
        (0, 8, 1, 17, 5, 12, 4, 16),
        (1, 9, 2, 18, 6, 13, 5, 17),
        (2, 10, 3, 19, 7, 14, 6, 18),
        (3, 11, 0, 16, 4, 15, 7, 19),
    ),
    "wedge6": ((0, 2, 1), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)),
    "wedge15": (
        (0, 8, 2, 7, 1, 6),
        (3, 9, 4, 10, 5, 11),
        (0, 6, 1, 13, 4, 9, 3, 12),
        (1, 7, 2, 14, 5, 10, 4, 13),
        (2, 8, 0, 12, 3, 11, 5, 14),
    ),
    "pyramid5": ((0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)),
    # corners, the base's edges (1-2, 2-3, 3-4, 4-1), the edges to the apex (1-5 .. 4-5)
    "pyramid13": (
        (0, 8, 3, 7, 2, 6, 1, 5),
        (0, 5, 1, 10, 4, 9),
        (1, 6, 2, 11, 4, 10),
        (2, 7, 3, 12, 4, 11),
        (3, 8, 0, 9, 4, 12),
    ),
    "tri3": ((0, 1, 2),),
    "tri6": ((0, 3, 1, 4, 2, 5),),
    "quad4": ((0, 1, 2, 3),),
    "quad8": ((0, 4, 1, 5, 2, 6, 3, 7),),
}
_SHELLS = frozenset({"tri3", "tri6", "quad4", "quad8"})
# Line elements: segments of local node numbers (a quadratic beam lists end, middle, end).
_LINES: dict[str, tuple[tuple[int, int], ...]] = {
    "line2": ((0, 1),),
    "line3": ((0, 1), (1, 2)),
}
_ALIASES = {"hex20r": "hex20", "beam2": "line2"}
#: Element kinds :func:`outer_surface` knows, with their number of nodes.
SURFACE_ELEMENTS: dict[str, int] = {
    kind: 1 + max(max(loop) for loop in loops) for kind, loops in {**_FACES, **_LINES}.items()
}
SURFACE_ELEMENTS.update({alias: SURFACE_ELEMENTS[kind] for alias, kind in _ALIASES.items()})
# Triangles of a face loop of 3, 4, 6 (quadratic triangle) or 8 (quadratic quad) nodes,
# as positions in the loop, each counter-clockwise when the loop is.
_LOOP_TRIANGLES = {
    3: ((0, 1, 2),),
    4: ((0, 1, 2), (0, 2, 3)),
    6: ((0, 1, 5), (2, 3, 1), (4, 5, 3), (1, 3, 5)),
    8: ((0, 1, 7), (2, 3, 1), (4, 5, 3), (6, 7, 5), (1, 3, 5), (1, 5, 7)),
}


@dataclass(frozen=True, eq=False)
class Surface:
    """What a viewer draws of a body: outer triangles and line segments over its node ids.

    Attributes
    ----------
    triangles : ndarray of int, shape (n_triangles, 3)
        Node ids of each triangle, counter-clockwise seen from outside the body.
    lines : ndarray of int, shape (n_lines, 2)
        Node ids of each segment (beams, bars, springs drawn as lines).
    source : str
        What the surface was built from, e.g. ``"outer faces of 1,024 hex20 elements"``.
    """

    triangles: np.ndarray
    lines: np.ndarray
    source: str = ""

    def __post_init__(self) -> None:
        for name, width in (("triangles", 3), ("lines", 2)):
            value = np.asarray(getattr(self, name), dtype=np.int64).reshape(-1, width)
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def __repr__(self) -> str:
        rows = [("triangles", str(self.triangles.shape[0])), ("lines", str(self.lines.shape[0]))]
        return one_line(f"Surface {self.source!r}", rows)

    @property
    def node_ids(self) -> np.ndarray:
        """Sorted ids of the nodes the surface uses, shape (n,)."""
        return sorted_unique(np.concatenate([self.triangles.ravel(), self.lines.ravel()]))

    def check_nodes(self, node_ids: np.ndarray) -> None:
        """Raise :class:`UserError` if the surface uses a node that ``node_ids`` lacks."""
        missing = missing_from(self.node_ids, np.asarray(node_ids, dtype=np.int64))
        if missing.size:
            raise UserError(
                f"surface: {missing.size} node(s) of the elements are not nodes of the body, "
                f"first {int(missing[0])}"
            )


def outer_surface(
    blocks: Iterable[tuple[str, np.ndarray]],
    node_ids: np.ndarray,
    coordinates: np.ndarray,
) -> Surface:
    """The outer surface of element blocks.

    Parameters
    ----------
    blocks : iterable of (kind, connectivity)
        Element kind (a key of :data:`SURFACE_ELEMENTS`) and the node ids of each element,
        shape (n_el, nodes per element). Solids of all blocks are taken together, so a face
        shared by elements of two blocks is inside; a shell face on the corners of a solid face
        or of another shell face is drawn once (by the solid, or by the first shell).
    node_ids : ndarray of int, shape (n_nodes,)
        The body's node ids.
    coordinates : ndarray, shape (n_nodes, 3)
        Their positions (orient the triangles outward).

    Returns
    -------
    Surface
        Raises :class:`UserError` for an unknown kind, a connectivity of the wrong width or a
        node id that is not in ``node_ids``.
    """
    node_ids = np.asarray(node_ids, dtype=np.int64)
    coordinates = np.asarray(coordinates, dtype=float)
    order = np.argsort(node_ids, kind="stable")
    solid_loops: list[tuple[np.ndarray, np.ndarray]] = []  # (face loops, centroid of element)
    shell_loops: list[np.ndarray] = []
    lines: list[np.ndarray] = []
    counts: dict[str, int] = {}
    for kind, connectivity in blocks:
        kind = _ALIASES.get(kind, kind)
        if kind not in _FACES and kind not in _LINES:
            raise UserError(
                f"surface: unknown element kind {kind!r}; known: {', '.join(SURFACE_ELEMENTS)}"
            )
        elements = np.asarray(connectivity, dtype=np.int64)
        width = SURFACE_ELEMENTS[kind]
        if elements.ndim != 2 or elements.shape[1] != width:
            raise UserError(
                f"surface: {kind} elements need {width} node ids each, got shape {elements.shape}"
            )
        if elements.size == 0:
            continue
        counts[kind] = counts.get(kind, 0) + elements.shape[0]
        rows = _rows(elements, node_ids, order)
        if kind in _LINES:
            lines.extend(elements[:, list(segment)] for segment in _LINES[kind])
            continue
        for face in _FACES[kind]:
            loop = rows[:, list(face)]
            if kind in _SHELLS:
                shell_loops.append(loop)
            else:
                solid_loops.append((loop, coordinates[rows].mean(axis=1)))
    shells = _single_shell_faces(shell_loops, solid_loops)
    triangles = [_triangles(loop, None, coordinates) for loop in shells]
    triangles += _outer_solid_faces(solid_loops, coordinates)
    tri = np.concatenate(triangles) if triangles else np.zeros((0, 3), np.int64)
    seg = np.concatenate(lines) if lines else np.zeros((0, 2), np.int64)
    return Surface(node_ids[tri], seg, _source(counts))


def _source(counts: dict[str, int]) -> str:
    """``outer faces of 8 hex8 elements; 4 quad4 shell elements; 2 line2 line elements``."""
    parts = []
    for group, word in ((set(_FACES) - _SHELLS, "elements"), (_SHELLS, "shell elements"),
                        (set(_LINES), "line elements")):  # fmt: skip
        listed = [f"{n:,} {k}" for k, n in counts.items() if k in group]
        if listed:
            parts.append(f"{', '.join(listed)} {word}")
    if not parts:
        return "no elements"
    return ("outer faces of " if counts.keys() - _SHELLS - set(_LINES) else "") + "; ".join(parts)


def smooth_patch(
    surface: Surface,
    node_ids: np.ndarray,
    coordinates: np.ndarray,
    seed: int,
    max_angle_deg: float = 30.0,
) -> np.ndarray:
    """The smooth region of a surface around one triangle: e.g. the wall of a hole.

    Triangles that share an edge belong to one region when their normals differ by less than
    ``max_angle_deg``; the sharp edges of a part (the rim of a hole, a plate's corners) bound
    the regions. The wall of a round hole is one region: its facets turn by a few degrees each.

    Parameters
    ----------
    surface : Surface
    node_ids : ndarray of int, shape (n_nodes,)
        The body's node ids.
    coordinates : ndarray, shape (n_nodes, 3)
        Their positions.
    seed : int
        Row of the triangle in ``surface.triangles`` the region grows from.
    max_angle_deg : float
        Largest angle (degrees) between the normals of neighbouring triangles of one region.

    Returns
    -------
    ndarray of int
        Rows of the region's triangles in ``surface.triangles``, sorted.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    triangles = surface.triangles
    if not 0 <= int(seed) < triangles.shape[0]:
        raise UserError(f"surface: no triangle {seed} (the surface has {triangles.shape[0]})")
    node_ids = np.asarray(node_ids, dtype=np.int64)
    order = np.argsort(node_ids, kind="stable")
    rows = _rows(triangles, node_ids, order)
    p = np.asarray(coordinates, dtype=float)[rows]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(normal, axis=1)
    normal = normal / np.where(length > 0, length, 1.0)[:, None]
    edges = np.sort(rows[:, [[0, 1], [1, 2], [2, 0]]], axis=2).reshape(-1, 2)
    owner = np.repeat(np.arange(rows.shape[0]), 3)
    _, edge, count = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    edge = edge.ravel()
    by_edge = np.argsort(edge, kind="stable")
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    pairs = count == 2  # an edge of two triangles (more: a non-manifold seam, left apart)
    a = owner[by_edge[first[pairs]]]
    b = owner[by_edge[first[pairs] + 1]]
    smooth = np.einsum("ij,ij->i", normal[a], normal[b]) >= np.cos(np.radians(max_angle_deg))
    n = rows.shape[0]
    graph = coo_matrix((np.ones(int(smooth.sum())), (a[smooth], b[smooth])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    return np.flatnonzero(label == label[int(seed)])


def _rows(elements: np.ndarray, node_ids: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Rows of the node ids of ``elements`` in ``node_ids``; UserError for an unknown id."""
    if node_ids.size == 0 and elements.size:
        raise UserError(
            f"surface: element node {int(elements.flat[0])} is not a node of the body (it has none)"
        )
    position = np.searchsorted(node_ids, elements, sorter=order)
    position = np.minimum(position, node_ids.size - 1)
    rows = order[position]
    unknown = node_ids[rows] != elements
    if unknown.any():
        raise UserError(
            f"surface: element node {int(elements[unknown][0])} is not a node of the body"
        )
    return rows


def _face_keys(loop: np.ndarray) -> np.ndarray:
    """The name of each face loop: its sorted corner rows (quadratic loops: every other node),
    padded with -1 to 4, shape (n_faces, 4)."""
    corners = loop[:, ::2] if loop.shape[1] in (6, 8) else loop
    key = np.full((loop.shape[0], 4), -1, dtype=np.int64)
    key[:, : corners.shape[1]] = np.sort(corners, axis=1)
    return key


def _single_shell_faces(
    shells: list[np.ndarray], solids: list[tuple[np.ndarray, np.ndarray]]
) -> list[np.ndarray]:
    """The shell face loops without repeats: a face on the corners of a solid's face (the solid
    draws it, or it lies inside) or of an earlier shell (a membrane laid over a shell) is left
    out."""
    if not shells:
        return []
    keys = [_face_keys(loop) for loop in shells]
    taken = np.concatenate([_face_keys(loop) for loop, _ in solids] or [np.zeros((0, 4), int)])
    every = np.concatenate([taken, *keys])
    _, first, inverse = np.unique(every, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    keep = (np.arange(every.shape[0]) == first[inverse])[taken.shape[0] :]
    out, start = [], 0
    for loop in shells:
        part = keep[start : start + loop.shape[0]]
        start += loop.shape[0]
        if part.any():
            out.append(loop[part])
    return out


def _outer_solid_faces(
    loops: list[tuple[np.ndarray, np.ndarray]], coordinates: np.ndarray
) -> list[np.ndarray]:
    """Triangles (rows) of the solid faces that belong to one element only, oriented outward."""
    if not loops:
        return []
    # A face is named by its sorted corner rows (quadratic loops: every other node), padded to 4.
    keys = [_face_keys(loop) for loop, _ in loops]
    _, inverse, count = np.unique(
        np.concatenate(keys), axis=0, return_inverse=True, return_counts=True
    )
    once = count[inverse.ravel()] == 1
    out, start = [], 0
    for (loop, centroid), key in zip(loops, keys, strict=True):
        keep = once[start : start + key.shape[0]]
        start += key.shape[0]
        if keep.any():
            out.append(_triangles(loop[keep], centroid[keep], coordinates))
    return out


def _triangles(loop: np.ndarray, inside: np.ndarray | None, coordinates: np.ndarray) -> np.ndarray:
    """Triangles (rows) of face loops, flipped where their normal points towards ``inside``."""
    tri = loop[:, np.array(_LOOP_TRIANGLES[loop.shape[1]])]  # (n_faces, n_tri, 3)
    if inside is not None:
        p = coordinates[loop]
        # Twice the face's area vector (sum over its loop), robust for warped quads.
        normal = np.cross(p, np.roll(p, -1, axis=1)).sum(axis=1)
        outward = np.einsum("ij,ij->i", normal, p.mean(axis=1) - inside) >= 0
        tri = np.where(outward[:, None, None], tri, tri[:, :, ::-1])
    return tri.reshape(-1, 3)
