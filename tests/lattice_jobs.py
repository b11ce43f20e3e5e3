"""Job files on the small spring lattice of ``conftest.spring_lattice`` written as ``model.h5``.

The frame is tangent at node 10, the inputs are forces ux, uy at node 60, the band is 0-200 Hz;
the tests add their ``[[reduction]]`` tables.
"""

from __future__ import annotations

SOAGA = 'name = "soaga"\nmethod = "soaga"\ntolerance = 1e-8'


def lattice_job(*reductions: str, points: int | None = None) -> str:
    """The job text with one ``[[reduction]]`` table per entry of ``reductions`` (its lines)."""
    band = "[band]\nf_max_hz = 200\n" + ("" if points is None else f"points = {points}\n")
    tables = "".join(f"\n[[reduction]]\n{reduction}\n" for reduction in reductions)
    return (
        '[model]\nfile = "model.h5"\n\n[frame]\ntype = "tangent"\nnode = 10\n\n'
        f'[[inputs]]\nnode = 60\ndirections = "ux uy"\n\n{band}{tables}'
    )
