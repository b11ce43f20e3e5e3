"""Short summaries of the values a user prints: one-line ``repr`` and notebook tables.

The values of pymorembs hold large arrays (matrices, bases); their ``repr`` would print them.
Each value class lists instead a few rows of facts -- (label, text) pairs such as
``("dofs", "3996 (666 nodes x ux uy uz rx ry rz)")`` -- which :func:`one_line` joins into its
``repr`` and :func:`html_table` turns into the table a notebook shows (``_repr_html_``), so the
two always say the same.
"""

from __future__ import annotations

import html
from collections.abc import Sequence

import numpy as np

__all__ = ["frequency_range", "html_table", "one_line", "port_labels", "port_rows"]

Rows = Sequence[tuple[str, str]]


def one_line(title: str, rows: Rows) -> str:
    """``<title: label text, label text, ...>``, e.g. ``<ReducedBody 'krylov': order 12, ...>``."""
    facts = ", ".join(f"{label} {text}" for label, text in rows)
    return f"<{title}: {facts}>" if facts else f"<{title}>"


def html_table(title: str, rows: Rows) -> str:
    """The rows as a small two-column HTML table with the title as its caption."""
    body = "".join(
        f"<tr><th style='text-align:left'>{html.escape(label)}</th>"
        f"<td style='text-align:left'>{html.escape(text)}</td></tr>"
        for label, text in rows
    )
    caption = f"<caption style='text-align:left'><b>{html.escape(title)}</b></caption>"
    return f"<table>{caption}{body}</table>"


def port_labels(labels: Sequence[str], limit: int = 4) -> str:
    """Port labels grouped by node, e.g. ``"6: 1:ux uy uz, 2:ux uy uz"``; after ``limit``
    groups the rest is counted (``"+ 10 more"``)."""
    groups: list[tuple[str, list[str]]] = []
    for label in labels:
        node, sep, direction = str(label).rpartition(":")
        if sep and groups and groups[-1][0] == node:
            groups[-1][1].append(direction)
        elif sep:
            groups.append((node, [direction]))
        else:
            groups.append((str(label), []))
    parts = [f"{head}:{' '.join(tail)}" if tail else head for head, tail in groups[:limit]]
    rest = sum(max(len(tail), 1) for _, tail in groups[limit:])
    if rest:
        parts.append(f"+ {rest} more")
    return f"{len(labels)}" + (f" ({', '.join(parts)})" if parts else "")


def port_rows(inputs: Sequence[str], outputs: Sequence[str]) -> list[tuple[str, str]]:
    """Rows of the inputs and outputs, one row when they are the same dofs."""
    if tuple(inputs) == tuple(outputs):
        return [("inputs = outputs", port_labels(inputs))]
    return [("inputs", port_labels(inputs)), ("outputs", port_labels(outputs))]


def frequency_range(frequencies_hz: np.ndarray) -> str:
    """``"41.57 ... 1.203e+04 Hz"`` (lowest and highest, 4 significant digits)."""
    values = np.asarray(frequencies_hz, dtype=float).ravel()
    if values.size == 0:
        return "none"
    low, high = float(values.min()), float(values.max())
    return f"{low:.4g} Hz" if low == high else f"{low:.4g} ... {high:.4g} Hz"
