"""ElasticBody helpers (top-level module ``pymorembs.body``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from conftest import spring_lattice
from pymorembs.errors import UserError


def test_with_notes_adds_notes_and_shares_everything_else():
    body = spring_lattice()
    noted = body.with_notes("dof table: proved", "units: SI")
    assert noted.notes == (*body.notes, "dof table: proved", "units: SI")
    assert noted.stiffness is body.stiffness and noted.mass is body.mass
    assert noted.dofs is body.dofs and noted.n_dof == body.n_dof
    assert "units: SI" not in body.notes  # the original is untouched (frozen value)


def test_matrices_must_be_finite_even_where_their_sum_overflows():
    """The finiteness check adds the entries first: a sum that overflows does not refuse a
    body whose entries are all finite, and NaN or inf is refused with the matrix named."""
    body = spring_lattice()
    huge = body.stiffness.copy()
    huge.data[:] = 1e308  # finite entries whose sum is inf
    assert np.all(dataclasses.replace(body, stiffness=huge).stiffness.data == 1e308)
    for bad in (np.inf, -np.inf, np.nan):
        mass = body.mass.copy()
        mass.data[-1] = bad
        with pytest.raises(UserError, match="mass matrix has NaN or infinite entries"):
            dataclasses.replace(body, mass=mass)
