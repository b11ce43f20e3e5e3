"""Stresses of the full model against CalculiX's on the same meshes (issue #29 item 1).

The parts of tests/data/calculix_stress_parts (README there): a plate with a hole of C3D10 and
a bar of C3D20 and of C3D20R, clamped at x = 0, a rigid interface at the far end, six static
unit loads at its reference node (forces x, y, z, moments about x, y, z). CalculiX printed the
stresses ``S``, strains ``E`` and coordinates of the integration points of a few elements
(``*EL PRINT``) and the nodal stresses it extrapolates and averages (``*EL FILE``, ``.frd``).

pymorembs's route is that of a job: read the matrix export with its deck (``pm.read``), add
a rigid interface node at CalculiX's reference node coupled to the same face nodes, solve the
six loads on the full model (``static_response``), apply the stress operator.

Tolerances (relative to the largest component of the load case, over all printed points and
components; measured figures in docs/stresses.md): integration points ``S`` and ``E`` 1e-6
(CalculiX prints 7 significant digits), coordinates 1e-8 m; nodes (``location="nodes"``)
against the ``.frd`` 5e-5 (it prints 6).
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from calculix_output import read_el_print, read_frd_stresses

import pymorembs as pm
from pymorembs.preparation import Frame, Port, add_interface_node, prepare
from pymorembs.preparation.interface import InterfaceSpec

DATA = Path(__file__).parents[1] / "data" / "calculix_stress_parts"
PARTS = ("bar", "barr", "plate")
KINDS = {"bar": "hex20", "barr": "hex20r", "plate": "tet10"}


@cache
def full_model_route(part: str):
    """The prepared body with its rigid interface and the six static responses (n_dof, 6)."""
    body = pm.read(DATA / f"{part}.sti.gz")
    deck = (DATA / f"{part}_static.inp").read_text()
    found = re.search(r"\*NODE, NSET=REF\n(\d+), ([^,]+), ([^,]+), ([^\n]+)", deck)
    assert found is not None
    node, position = int(found.group(1)), tuple(float(found.group(k)) for k in (2, 3, 4))
    tip = deck.split("*NSET, NSET=TIP\n")[1].split("*")[0].replace(",", " ").split()
    coupled = add_interface_node(body, InterfaceSpec(node, position, tuple(map(int, tip))))
    prepared = prepare(coupled, Frame("none"), inputs=[Port(node, "ux uy uz rx ry rz")])
    return prepared.body, prepared.expand(prepared.static_response)


def worst_difference(mine: np.ndarray, theirs: np.ndarray) -> float:
    return float(np.abs(mine - theirs).max() / np.abs(theirs).max())


@pytest.mark.parametrize("part", PARTS)
def test_integration_points_match_calculix(part):
    body, responses = full_model_route(part)
    assert body.mesh.element == KINDS[part]
    printed = read_el_print(DATA / f"{part}_static.dat")
    assert [len(printed[key]) for key in ("S", "E", "COORD")] == [6, 6, 6]
    elements = np.unique(printed["S"][0][:, 0]).astype(int)
    for quantity, key, tolerance in (("stress", "S", 1e-6), ("strain", "E", 1e-6)):
        op = pm.stress_operator(body, quantity=quantity, elements=elements)
        where = {
            pair: k for k, pair in enumerate(zip(op.element_ids, op.point_numbers, strict=True))
        }
        values = op(responses)
        for step, block in enumerate(printed[key]):
            rows = [where[(int(e), int(p))] for e, p in block[:, :2]]
            assert len(rows) == op.n_points
            assert worst_difference(values[rows, :, step], block[:, 2:]) < tolerance
    coordinates = printed["COORD"][0]
    rows = [where[(int(e), int(p))] for e, p in coordinates[:, :2]]
    assert np.abs(op.coordinates[rows] - coordinates[:, 2:]).max() < 1e-8


@pytest.mark.parametrize("part", PARTS)
def test_nodal_stresses_match_calculix(part):
    body, responses = full_model_route(part)
    op = pm.stress_operator(body, location="nodes")
    values = op(responses)
    steps = read_frd_stresses(DATA / f"{part}_static.frd.gz")
    assert len(steps) == 6
    for step, nodal in enumerate(steps):
        nodes = np.array(sorted(nodal))
        rows = np.searchsorted(op.node_ids, nodes)
        assert np.array_equal(op.node_ids[rows], nodes)
        theirs = np.array([nodal[n] for n in nodes])
        assert worst_difference(values[rows, :, step], theirs) < 5e-5


def test_the_deck_numbers_name_the_points():
    body, _ = full_model_route("bar")
    assert body.mesh.element_ids.tolist() == (1000 + 3 * np.arange(24)).tolist()
