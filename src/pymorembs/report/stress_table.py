"""The report's table of stress modes: the largest von Mises stress of the first shapes.

For a body with solid elements the report lists, per reduction, the largest nodal von Mises
stress of each of its first :data:`STRESS_SHAPES_EACH` shape functions and the node where it is
(:func:`stress_mode_maxima`; the nodal stresses of :mod:`pymorembs.export.stress_modes`, per unit
modal coordinate), so that a reader sees where each mode strains the part without opening the
VTU or the recovery file. A body without solid elements gets the note why instead.
"""

from __future__ import annotations

import html
from collections.abc import Mapping
from typing import Any

import numpy as np

from pymorembs.export.stress_modes import stress_modes_note
from pymorembs.preparation import PreparedModel
from pymorembs.reduction.projection import ReducedModel
from pymorembs.stress import stress_operator, von_mises

__all__ = ["STRESS_SHAPES_EACH", "stress_mode_maxima", "stress_modes_table"]

#: Shape functions of each reduction the table lists at most.
STRESS_SHAPES_EACH = 6


def stress_mode_maxima(
    prepared: PreparedModel,
    reductions: Mapping[str, ReducedModel],
    count: int = STRESS_SHAPES_EACH,
) -> dict[str, Any]:
    """The largest nodal von Mises stress of the first shapes of every reduction.

    Parameters
    ----------
    prepared : PreparedModel
        The body (its solid mesh) and the map of the bases to all its dofs (eq. 18).
    reductions : mapping of str to ReducedModel
        The reductions by name.
    count : int
        Shapes of each reduction.

    Returns
    -------
    dict
        ``rows``: one per shape, ``{"reduction", "shape" (1-based), "frequency_hz",
        "max_von_mises" (model stress unit per unit modal coordinate), "node"}``; ``note``: why
        there are no rows (a body without solid elements), else None.
    """
    note = stress_modes_note(prepared.body)
    if note is not None:
        return {"rows": [], "note": note}
    operator = stress_operator(prepared.body, location="nodes")
    rows = []
    for name, model in reductions.items():
        keep = min(int(count), model.projection.order)
        if keep <= 0:
            continue
        basis = prepared.expand(model.projection.V[:, :keep])
        mises = von_mises(operator(basis), axis=1)  # (n_nodes, keep)
        for k in range(keep):
            at = int(np.argmax(mises[:, k]))
            rows.append({"reduction": str(name), "shape": k + 1,
                         "frequency_hz": float(model.eigenfrequencies_hz[k]),
                         "max_von_mises": float(mises[at, k]),
                         "node": int(operator.node_ids[at])})  # fmt: skip
    return {"rows": rows, "note": None}


def stress_modes_table(maxima: Mapping[str, Any]) -> str:
    """The HTML of :func:`stress_mode_maxima`: a table, or the note."""
    if maxima.get("note"):
        return f"<p>{html.escape(str(maxima['note']))}.</p>"
    head = ("<tr><th class=\"text\">reduction</th><th>shape</th><th>f [Hz]</th>"
            "<th>largest von Mises per unit q</th><th>at node</th></tr>")  # fmt: skip
    lines = [
        "<p>The largest von Mises stress of the first shape functions, nodal values (model "
        "stress unit per unit modal coordinate; all of them in the VTU and the recovery file, "
        "<code>stress_recovery</code>).</p>",
        "<table>",
        head,
    ]
    for row in maxima.get("rows", []):
        lines.append(
            f'<tr><td class="text">{html.escape(row["reduction"])}</td><td>{row["shape"]}</td>'
            f"<td>{row['frequency_hz']:.4g}</td><td>{row['max_von_mises']:.4g}</td>"
            f"<td>{row['node']}</td></tr>"
        )
    lines.append("</table>")
    return "\n".join(lines)
