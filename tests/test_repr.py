"""Issue #27 item 7: what a user prints is a short line of facts, not array dumps -- ``repr`` of
every value the API hands out is one line of a few hundred characters naming kind, sizes,
method, order, band, frame and ports; the main ones show the same facts as a table in a
notebook (``_repr_html_``)."""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import pymorembs as pm

#: The longest repr accepted (characters): a few lines of a terminal.
LIMIT = 500


@pytest.fixture(scope="module")
def rack():
    return pm.example("rack-beams")


@pytest.fixture(scope="module")
def reduced(rack):
    damping = {"kind": "modal", "ratio": 0.02}
    prepared = pm.prepare(rack, "tangent", node=2, inputs=[(1, "ux uy uz"), (2, "ux")],
                          inertia_loads=["ax", "az"], damping=damping)  # fmt: skip
    return pm.reduce(prepared, "krylov", expansion_points_hz=[0.0, 500.0], order=12)


@pytest.fixture(scope="module")
def curve(reduced):
    return reduced.error((0, 1000), points=20)


def short(value: object) -> str:
    text = repr(value)
    assert "\n" not in text and len(text) <= LIMIT, text
    assert "array(" not in text and "..." not in text.replace(" ... ", ""), text
    return text


def test_the_body_is_one_line_of_its_facts(rack):
    text = short(rack)
    assert text.startswith("<ElasticBody 'rack-beams': ")
    assert "nodes 666" in text and "dofs 3996 (666 nodes x ux uy uz rx ry rz)" in text
    assert "dependent 48" in text and "fixed 0" in text and "damping none" in text
    assert "elements 660 x beam2" in text and "660 lines" in text
    assert short(rack.dofs) == "<DofTable: dofs 3996 (666 nodes x ux uy uz rx ry rz)>"
    assert "dependent dofs 48" in short(rack.constraints)
    assert "660 x beam2" in short(rack.mesh) and "lines 660" in short(rack.surface)
    damped = rack.with_damping(pm.Damping("rayleigh", alpha=2.0, beta=1e-5))
    assert "damping rayleigh, alpha 2 1/s, beta 1e-05 s" in short(damped)
    with_matrix = dataclasses.replace(damped, damping_matrix=rack.mass)
    assert "beta 1e-05 s + damping matrix" in short(with_matrix)


def test_the_reduction_chain_is_printed_in_lines_of_facts(reduced):
    prepared = reduced.prepared
    text = short(prepared)
    assert text.startswith("<PreparedModel 'rack-beams': frame tangent at node 2")
    assert "independent dofs 3942 of 3996" in text
    assert "inputs = outputs 4 (1:ux uy uz, 2:ux)" in text and "inertia loads ax az" in text
    assert "damping modal, ratio 0.02" in text
    assert "order 3942 (sparse" in short(prepared.system)
    assert "independent 3942, dependent 48, fixed 6" in short(prepared.elimination)
    assert "cases ax az" in short(prepared.inertia)

    text = short(reduced)
    assert text.startswith("<ReducedBody 'krylov': method krylov (")
    assert "expansion_points_hz=[0.0, 500.0]" in text and "order=12" in text
    assert "order 12," in text and "frame tangent at node 2" in text
    low, high = reduced.eigenfrequencies_hz.min(), reduced.eigenfrequencies_hz.max()
    assert f"eigenfrequencies {low:.4g} ... {high:.4g} Hz" in text and f"{low:.4g}" == "41.57"
    assert "inputs = outputs 6 (1:ux uy uz, 2:ux, inertia:ax az)" in text
    assert "loss factor 0.04, modal ratio 0.02" in text
    assert short(reduced.model).startswith("<ReducedModel 'krylov': order 12, eigenfrequencies")
    assert "order 12 (dense)" in short(reduced.system)
    assert "basis 3942 x 12, V = W" in short(reduced.projection)
    assert "elastic coordinates 12, frame nodes 1 2" in short(reduced.invariants([1, 2]))


def test_the_error_curve_names_band_maximum_and_where(curve):
    text = short(curve)
    worst = curve.frequencies_hz[np.argmax(curve.relative)]
    assert text.startswith("<ErrorCurve: band 0 ... 1000 Hz, 21 frequencies")
    assert f"max {curve.max:.3e} at {worst:.4g} Hz" in text
    assert f"max inertia loads {curve.max_inertia:.3e}" in text and "reference full" in text


def test_a_time_response_and_a_soaga_projection_are_short(reduced):
    response = reduced.simulate([pm.LoadCase("step", "step", [0, 0, -100])], clamp_node=2,
                                load_node=1, duration_s=0.005, step_s=1e-4)  # fmt: skip
    assert "cases step, steps 51 x 0.0001 s to 0.005 s" in short(response)
    soaga = pm.reduce(reduced.prepared, "soaga", band_hz=(0, 1000), tolerance=1e-3)
    text = short(soaga.projection)
    assert f"error estimate {soaga.projection.error_estimate:.3g}" in text
    assert "estimator curve" in text


@pytest.mark.parametrize("which", ["body", "prepared", "reduced", "model", "error"])
def test_a_notebook_shows_the_same_facts_as_a_table(rack, reduced, curve, which):
    value = {
        "body": dataclasses.replace(rack, name="<rack & co>"),
        "prepared": reduced.prepared,
        "reduced": reduced,
        "model": reduced.model,
        "error": curve,
    }[which]
    table = ET.fromstring(value._repr_html_())  # well-formed, names escaped
    rows = [(row.find("th").text, row.find("td").text) for row in table.iter("tr")]
    assert rows == value.summary() and len(rows) >= 4
    assert table.find("caption/b").text == repr(value)[1:].split(":")[0]
