"""Node selections of ``[[interface]]`` tables: a picked patch as the job's keys, and the
job's keys as the arguments of :func:`~pymorembs.preparation.interface.select_nodes`.

:func:`hole_selection` turns a picked region of the surface (the wall of a hole, a face) into
the job's own node selection: a cylinder and a box when they select exactly the region's
nodes, else the list of node ids. :func:`selected_nodes` reads a selection the way
``[[interface]]`` writes it (``cylinder``, ``box``, ``nodes``) from the page's JSON, which need
not be a valid job yet.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.preparation.interface import select_nodes


def free_node_id(body: ElasticBody, taken: list[int] | tuple[int, ...] = ()) -> int:
    """The smallest positive node id that neither the body nor ``taken`` uses."""
    used = set(body.node_ids.tolist()) | {int(t) for t in taken}
    candidate = 1
    while candidate in used:
        candidate += 1
    return candidate


def _rounded(values: np.ndarray, size: float) -> list[float]:
    """Values rounded to a billionth of ``size`` (the model's extent): readable, and exact
    enough for a selection whose tolerance is a millionth of it."""
    digits = 9 - math.floor(math.log10(size))
    return [round(float(v), digits) + 0.0 for v in np.asarray(values, dtype=float)]


def hole_selection(body: ElasticBody, nodes: np.ndarray) -> dict[str, Any]:
    """The job's selection of a set of surface nodes, and where their interface node goes.

    A round hole (the nodes lie on a cylinder) is written as ``cylinder = { point, direction,
    radius, tolerance }`` with a ``box`` around the nodes, the way ``docs/jobs.md`` selects a
    hole's surface; any other set (a flat face, an irregular patch) as ``nodes = [ids]``. The
    cylinder is kept only when :func:`~pymorembs.preparation.interface.select_nodes` gives back
    exactly ``nodes`` with the rounded numbers written.

    Returns
    -------
    dict
        ``selection``: the keys for the ``[[interface]]`` table (``cylinder`` and ``box``, or
        ``nodes``); ``position``: [x, y, z] of the interface node (on the axis, halfway along
        the hole; else the nodes' centroid); ``kind``: ``"cylinder"`` or ``"nodes"``;
        ``radius`` (None for ``"nodes"``).
    """
    ids = np.unique(np.asarray(nodes, dtype=np.int64))
    if ids.size == 0:
        raise UserError("interface: no nodes selected")
    x = body.coordinates[body.node_rows(ids)]
    centroid = x.mean(axis=0)
    size = float(np.ptp(body.coordinates, axis=0).max()) or 1.0
    fallback = {
        "selection": {"nodes": [int(i) for i in ids]},
        "position": _rounded(centroid, size),
        "kind": "nodes",
        "radius": None,
    }
    if ids.size < 6:
        return fallback
    # The axis: the direction along which the points vary the most but stay on a circle
    # around it; try each principal direction and keep the best circle.
    rel = x - centroid
    _, _, vt = np.linalg.svd(rel, full_matrices=False)
    best = None
    for axis in vt:
        e1, e2 = vt[[k for k in range(3) if not np.allclose(vt[k], axis)][:2]]
        u, v = rel @ e1, rel @ e2
        matrix = np.column_stack([u, v, np.ones_like(u)])
        coef, *_ = np.linalg.lstsq(matrix, u**2 + v**2, rcond=None)
        cu, cv = coef[0] / 2.0, coef[1] / 2.0
        radius = math.sqrt(max(coef[2] + cu**2 + cv**2, 0.0))
        spread = np.abs(np.hypot(u - cu, v - cv) - radius).max()
        if radius > 0 and (best is None or spread < best[0]):
            along = rel @ axis
            middle = centroid + cu * e1 + cv * e2 + 0.5 * (along.max() + along.min()) * axis
            best = (spread, axis, middle, radius)
    if best is None or best[0] > 1e-3 * best[3]:
        return fallback
    spread, axis, middle, radius = best
    axis = axis * np.sign(axis[np.argmax(np.abs(axis))])
    tolerance = float(f"{max(spread * 2.0, 1e-6 * size):.2g}")
    pad = 2.0 * tolerance
    cylinder = {
        "point": _rounded(middle, size),
        "direction": [round(float(a), 6) + 0.0 for a in axis],
        "radius": _rounded([radius], size)[0],
        "tolerance": tolerance,
    }
    box = {"min": _rounded(x.min(axis=0) - pad, size), "max": _rounded(x.max(axis=0) + pad, size)}
    try:
        again = select_nodes(
            body,
            cylinder=(cylinder["point"], cylinder["direction"], cylinder["radius"], tolerance),
            box=(box["min"], box["max"]),
        )
    except UserError:
        return fallback
    if not np.array_equal(np.sort(again), ids):
        return fallback
    return {
        "selection": {"cylinder": cylinder, "box": box},
        "position": cylinder["point"],
        "kind": "cylinder",
        "radius": cylinder["radius"],
    }


def selected_nodes(body: ElasticBody, selection: dict[str, Any]) -> np.ndarray:
    """Node ids of a selection by numbers: ``cylinder``, ``box`` and/or ``nodes`` (the keys of
    ``[[interface]]``; all criteria apply).

    Raises
    ------
    UserError
        No criterion, or one that selects no node (:func:`select_nodes`).
    KeyError, TypeError, ValueError
        A criterion that is not written as the job writes it (the page's draft).
    """
    cylinder = selection.get("cylinder")
    box = selection.get("box")
    ids = selection.get("nodes")
    return select_nodes(
        body,
        ids=None if not ids else [int(i) for i in ids],
        cylinder=None if not cylinder else _cylinder(cylinder),
        box=None if not box else (box["min"], box["max"]),
    )


def _cylinder(data: dict[str, Any]) -> tuple:
    values = (data["point"], data["direction"], float(data["radius"]))
    tolerance = data.get("tolerance")
    return values if tolerance in (None, "") else (*values, float(tolerance))
