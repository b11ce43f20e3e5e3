"""Independent checks of a surface mesh, shared by the surface and reader tests."""

from __future__ import annotations

import numpy as np


def enclosed_volume(p: np.ndarray) -> float:
    """Volume inside closed outward triangles ``p`` (t, 3, 3) by the divergence theorem."""
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def is_closed_and_consistent(triangles: np.ndarray) -> bool:
    """Every directed edge once, and its reverse present: a closed, consistently oriented skin."""
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    directed = set(map(tuple, edges.tolist()))
    return len(directed) == len(edges) and all((b, a) in directed for a, b in directed)
