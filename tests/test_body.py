"""ElasticBody helpers (top-level module ``pymorembs.body``)."""

from __future__ import annotations

from conftest import spring_lattice


def test_with_notes_adds_notes_and_shares_everything_else():
    body = spring_lattice()
    noted = body.with_notes("dof table: proved", "units: SI")
    assert noted.notes == (*body.notes, "dof table: proved", "units: SI")
    assert noted.stiffness is body.stiffness and noted.mass is body.mass
    assert noted.dofs is body.dofs and noted.n_dof == body.n_dof
    assert "units: SI" not in body.notes  # the original is untouched (frozen value)
