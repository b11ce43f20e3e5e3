"""The surface a reader gives the body from every element its file carries (for viewers).

The readers of files with elements (the Abaqus ``.inp``, the Nastran bulk data, the Ansys
``.cdb``) translate each element type they meet into a kind of :mod:`pymorembs.surface` (solids,
shells, beams and rods) or count it as not drawn (springs, rigid elements, point masses ...),
and hand both here as :class:`SurfaceElements`. :func:`attach_surface` puts the outer surface
on the body with one note saying what it was built from and what was left out. This is
independent of the solid mesh for geometric stiffening (:mod:`pymorembs.io.solid_mesh`), which
takes the solid elements only and proves them against ``K``: drawing needs node ids and
coordinates only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pymorembs.arrays import missing_from, sorted_unique
from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.surface import outer_surface

__all__ = ["SurfaceElements", "attach_surface"]


@dataclass(eq=False)
class SurfaceElements:
    """Elements of a file for its surface, and the ones that are not drawn.

    Attributes
    ----------
    blocks : list of (str, ndarray of int)
        A kind of :data:`pymorembs.surface.SURFACE_ELEMENTS` and the node ids of its elements,
        shape (n_el, nodes of the kind), in the node order of :mod:`pymorembs.surface`.
    skipped : dict of str to int
        Number of elements of each type of the file (its own name: ``CBUSH``, ``SPRING2``,
        ``COMBIN14``) that the surface leaves out.
    """

    blocks: list[tuple[str, np.ndarray]] = field(default_factory=list)
    skipped: dict[str, int] = field(default_factory=dict)

    def add(self, kind: str, connectivity: np.ndarray) -> None:
        """Append elements of a surface kind (an empty connectivity is ignored)."""
        connectivity = np.asarray(connectivity, dtype=np.int64)
        if connectivity.size:
            self.blocks.append((kind, connectivity))

    def skip(self, name: str, count: int = 1) -> None:
        """Count ``count`` elements of the file's type ``name`` as not drawn."""
        if count > 0:
            self.skipped[name] = self.skipped.get(name, 0) + int(count)

    @property
    def skipped_text(self) -> str:
        """``not drawn: 2 CBUSH, 1 RBE2`` (largest counts first), or ``""``."""
        if not self.skipped:
            return ""
        items = sorted(self.skipped.items(), key=lambda item: (-item[1], item[0]))
        return "not drawn: " + ", ".join(f"{n:,} {name}" for name, n in items)


def attach_surface(body: ElasticBody, elements: SurfaceElements) -> ElasticBody:
    """The body with the outer surface of ``elements`` and a note ``surface: ... for viewers``.

    Without elements of a known kind the body keeps no surface (a note says which elements were
    not drawn, if any); without coordinates, or with elements on nodes the body lacks (the
    interior grids of a superelement whose matrices hold its boundary only), it stays as it is,
    with a note saying why.
    """
    skipped = elements.skipped_text
    if not elements.blocks:
        if skipped:
            return body.with_notes(f"surface: none, no element of a drawn kind ({skipped})")
        return body
    if not body.has_coordinates:
        return body.with_notes("surface: the file gives no coordinates; nodes cannot be drawn")
    used = sorted_unique(np.concatenate([c.ravel() for _, c in elements.blocks]))
    missing = missing_from(used, np.asarray(body.node_ids, dtype=np.int64))
    if missing.size:
        return body.with_notes(
            f"surface: none, {missing.size:,} of the {used.size:,} nodes of the elements are "
            f"not nodes of the body (first {int(missing[0])}; the matrices hold part of the "
            "mesh, e.g. a superelement's boundary)"
        )
    try:
        surface = outer_surface(elements.blocks, body.node_ids, body.coordinates)
    except UserError as err:
        return body.with_notes(f"surface: none ({err})")
    counts = [f"{surface.triangles.shape[0]:,} triangles"]
    if surface.lines.shape[0]:
        counts.append(f"{surface.lines.shape[0]:,} lines")
    tail = f"; {skipped}" if skipped else ""
    return body.with_surface(surface).with_notes(
        f"surface: {surface.source} ({', '.join(counts)}{tail}) for viewers"
    )
