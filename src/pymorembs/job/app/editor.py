"""The job the page edits: a job file as a dictionary, its TOML text and its checks.

The page's state *is* the job: the same tables and keys as the TOML file (``[model]``,
``[[interface]]``, ``[frame]``, ``[[inputs]]``, ``[band]``, ``[[reduction]]``, ``[export]``),
held as JSON. :func:`job_text` writes it as TOML in the order of ``docs/jobs.md``;
:func:`check_job_text` parses that text with the job parser of ``pymorembs reduce``, so what the
page shows, saves and runs is one file, checked by the same code.

:func:`hole_selection` turns a picked region of the surface (the wall of a hole, a face) into
the job's own node selection: a cylinder and a box when they select exactly the region's
nodes, else the list of node ids.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.job.schema import Job, parse_job
from pymorembs.preparation.interface import select_nodes

#: Tables in the order of the job reference; keys not listed follow in their own order.
TABLE_ORDER = (
    "model", "damping", "interface", "frame", "inputs", "outputs", "band", "reduction", "export",
    "inertia_loads", "stiffening", "time_domain", "large_motion",
)  # fmt: skip


def _value(value: Any) -> str:
    """One TOML value: string, bool, number, list or inline table."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise UserError(f"job: {value!r} is not a finite number")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    raise UserError(f"job: cannot write {value!r} in a job file")


def _key(key: str) -> str:
    bare = key.replace("_", "").replace("-", "").isalnum() and key.isascii()
    return key if bare else json.dumps(key)


def _table(lines: list[str], header: str, table: dict[str, Any]) -> None:
    lines.append("")
    lines.append(header)
    for key, value in table.items():
        if value is not None:
            lines.append(f"{_key(key)} = {_value(value)}")


def job_text(job: dict[str, Any]) -> str:
    """The TOML text of a job given as a dictionary (the parsed form of a job file).

    Scalars at the top come first, then the tables in :data:`TABLE_ORDER`; a list of tables is
    written as ``[[name]]`` tables, a table inside a table inline (``cylinder = { ... }``).
    Entries whose value is None are left out.
    """
    lines: list[str] = []
    for key, value in job.items():
        if value is not None and not isinstance(value, dict) and not _is_tables(value):
            lines.append(f"{_key(key)} = {_value(value)}")
    keys = [k for k in TABLE_ORDER if k in job] + [k for k in job if k not in TABLE_ORDER]
    for key in keys:
        value = job[key]
        if isinstance(value, dict):
            _table(lines, f"[{_key(key)}]", value)
        elif _is_tables(value):
            for item in value:
                _table(lines, f"[[{_key(key)}]]", item)
    return "\n".join(lines).lstrip("\n") + "\n"


def _is_tables(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def check_job_text(text: str, path: Path) -> Job:
    """Parse a job's TOML text as ``pymorembs reduce`` would read it from ``path``.

    Raises
    ------
    UserError
        The parser's message (file, table and key), as on the command line.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: invalid TOML: {exc}") from None
    return parse_job(data, path)


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
