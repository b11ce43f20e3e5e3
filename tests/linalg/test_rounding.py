"""Exports rounded to a few digits: digit detection, eigenvalue bounds, rigid-body modes.

The reference for each bound is the exact model the rounded one came from: rounding the entries
of a free bent beam to ``d`` digits must move every eigenvalue by less than the first-order bound
of :func:`pymorembs.linalg.rounding.eigenvalue_bounds`, and the rigid-body modes must still be
recognised (by geometry, by the spectrum, and by the Buckens frame).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from test_massless import beam_body, dense_reference, hz

from pymorembs.analysis.spectrum import model_spectrum
from pymorembs.body import ElasticBody
from pymorembs.linalg.rounding import relative_rounding, significant_digits
from pymorembs.preparation import Frame, prepare


def rounded(values: np.ndarray, digits: int) -> np.ndarray:
    """Values rounded to ``digits`` significant decimal digits, through their text form."""
    return np.array([float(f"{v:.{digits - 1}e}") for v in values])


def rounded_body(body: ElasticBody, digits: int) -> ElasticBody:
    k, m = sp.csr_matrix(body.stiffness, copy=True), sp.csr_matrix(body.mass, copy=True)
    k.data, m.data = rounded(k.data, digits), rounded(m.data, digits)
    k = 0.5 * (k + k.T)  # both triangles came from one printed value
    return ElasticBody(
        node_ids=body.node_ids,
        coordinates=body.coordinates,
        dofs=body.dofs,
        mass=sp.csr_matrix(m),
        stiffness=sp.csr_matrix(k),
        fixed=body.fixed,
        has_coordinates=body.has_coordinates,
    )


@pytest.mark.parametrize("digits", [5, 6, 8, 10, 12, 13])
def test_digits_of_rounded_values_are_found(digits):
    rng = np.random.default_rng(digits)
    values = rng.uniform(0.1, 10.0, 3000) * 10.0 ** rng.integers(-5, 8, 3000)
    assert significant_digits(rounded(values, digits)) == digits


def test_full_doubles_round_numbers_and_single_precision():
    rng = np.random.default_rng(1)
    assert significant_digits(rng.normal(size=1000)) is None
    assert significant_digits(np.array([1.0, -2.0, 1000.0, 25.0])) is None  # exact numbers
    single = sp.csr_matrix(rng.normal(size=(20, 20)).astype(np.float32).astype(float))
    assert relative_rounding(single, single) == (2.0**-24, "single precision")
    exact = sp.csr_matrix(rng.normal(size=(20, 20)))
    assert relative_rounding(exact, exact)[1] == "full double precision"


@pytest.mark.parametrize("digits", [7, 10])
def test_bounds_hold_and_rigid_modes_are_found_on_a_rounded_free_beam(digits):
    exact = beam_body(14, clamped=False, bent=True, offset_masses=True)
    body = rounded_body(exact, digits)
    eps, text = relative_rounding(body.stiffness, body.mass)
    assert text == f"{digits} significant digits" and eps == pytest.approx(
        0.5 * 10.0 ** (1 - digits)
    )
    prepared = prepare(body, Frame("none"), allow_rigid_body_modes=True)
    spectrum = model_spectrum(body, prepared, 8)
    assert spectrum.rigid.count == 6 and spectrum.rigid.decided_by == "geometry"
    assert "the spectrum agrees" in spectrum.rigid.explanation
    truth = hz(dense_reference(exact)[6:14])
    assert np.all(np.abs(spectrum.elastic_hz - truth) <= spectrum.elastic_bound_hz)
    assert np.all(spectrum.elastic_bound_hz < 0.05 * truth)  # the bound is not vacuous
    # the Buckens frame accepts the rounded free body (its six rigid-body modes)
    assert prepare(body, Frame("buckens")).system.rigid_modes.shape[1] == 6


def test_a_rounded_clamped_beam_has_no_rigid_body_mode():
    """Its first mode lies 6x below the second, but far outside the rounding bound."""
    body = rounded_body(beam_body(14, clamped=True, bent=True), 10)
    spectrum = model_spectrum(body, prepare(body, Frame("none")), 3)
    assert spectrum.rigid.count == 0 and spectrum.rigid.mechanisms == 0
    assert spectrum.elastic_hz[0] > 0
