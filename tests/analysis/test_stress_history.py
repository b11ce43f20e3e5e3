"""Stresses over time at hot spots (issue #29 item 4): histories, peaks, ranges, deviations.

References written in the tests: closed-form uniaxial and shear histories; the trapezoidal rule
on the first-order form of the full and the reduced model (dense, ``test_time_domain``) and the
exact response of the full model by modal superposition (closed-form damped oscillators), each
with the stress operator applied to the displacement fields; the stresses of the element's own
kinematics (``solid_stresses``); von Mises and principal stresses from their textbook formulas.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from test_time_domain import oscillator_response, trapezoidal_states
from threadpoolctl import threadpool_limits

from pymorembs.analysis.stress_history import (
    StressHistory,
    compare_histories,
    hot_spot_labels,
    stress_history,
)
from pymorembs.analysis.time_domain import LoadCase, compare_stresses, full_stress_rows, simulate
from pymorembs.body import Damping
from pymorembs.elements.solid import solid_stresses
from pymorembs.errors import UserError
from pymorembs.examples.blade import TIP_NODE, blade
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.projection import reduced_model
from pymorembs.report.time_plots import plot_stress_histories
from pymorembs.stress import stress_operator

#: Rayleigh damping of the blade: 0.7 % at its first mode (216 Hz), overdamped above ~3 MHz.
ALPHA, BETA = 20.0, 1e-7
CASES = [
    LoadCase("step", "step", np.array([0.0, 0.0, -100.0])),
    LoadCase("harmonic", "harmonic", np.array([0.0, -60.0, -100.0]), frequency_hz=100.0),
]
DURATION_S, STEP_S = 0.02, 2e-5  # 1000 steps; omega_1 h = 0.027


@pytest.fixture(autouse=True)
def one_thread():
    with threadpool_limits(1):
        yield


# -------------------------------------------------------------------------- closed forms
def uniaxial(values: np.ndarray, component: int = 0) -> np.ndarray:
    out = np.zeros((values.size, 6))
    out[:, component] = values
    return out


def test_uniaxial_and_shear_peaks_and_ranges():
    t = np.linspace(0.0, 1.0, 401)
    tension = 3.0 + 2.0 * np.sin(2 * np.pi * t)  # 1 .. 5, always in tension
    swing = -4.0 * np.sin(2 * np.pi * t)  # -4 .. 4: von Mises 0 .. 4
    shear = 1.5 * np.cos(2 * np.pi * t)  # principal stresses +-|tau|, von Mises sqrt(3) |tau|
    values = np.hstack([uniaxial(tension), uniaxial(swing, 2), uniaxial(shear, 4)])
    history = StressHistory(t, values, ("a", "b", "c"))
    a, b, c = history.hot_spots()
    assert (a.point, a.peak_von_mises, a.range_von_mises) == ("a", 5.0, pytest.approx(4.0))
    assert a.range_abs_max_principal == pytest.approx(4.0)
    assert (b.peak_von_mises, b.range_von_mises) == (pytest.approx(4.0), pytest.approx(4.0))
    assert b.range_abs_max_principal == pytest.approx(8.0)  # signed: compression counts
    assert c.peak_von_mises == pytest.approx(np.sqrt(3.0) * 1.5)
    # pure shear: principal stresses +tau and -tau of equal size, a tie either may win
    assert 1.5 - 1e-9 <= c.range_abs_max_principal <= 3.0 + 1e-9
    assert history.components.shape == (401, 3, 6)
    with pytest.raises(UserError, match="needs shape"):
        StressHistory(t, values[:, :10], ("a", "b"))


def test_a_scaled_history_deviates_by_its_scale():
    t = np.linspace(0.0, 1.0, 101)
    reference = StressHistory(
        t, np.hstack([uniaxial(np.sin(7 * t)), uniaxial(2 * np.cos(3 * t), 1)]), ("p", "q")
    )
    scaled = replace(reference, values=1.01 * reference.values)
    result = compare_histories(scaled, reference)
    peak = 2.0  # of von Mises, at q (t = 0)
    assert result.reference_peak_von_mises == pytest.approx(peak)
    assert result.max_rel_deviation == pytest.approx(0.01 * 2.0 / peak)
    assert result.hot_spots[0].max_rel_deviation == pytest.approx(0.01)  # own peak
    assert result.hot_spots[1].max_rel_deviation == pytest.approx(0.01)
    assert compare_histories(reference, reference).max_rel_deviation == 0.0
    with pytest.raises(UserError, match="hot spots"):
        compare_histories(replace(reference, points=("p", "r")), reference)


# -------------------------------------------------------------- the blade in the time domain
@pytest.fixture(scope="module")
def blade_model():
    """The short blade (0.2 m, 4 x 2 x 2 hex20, 360 free dofs, 216 Hz) clamped at its root,
    loaded at its tip; hot spots: the integration points of the two root elements at the
    upper face."""
    body = blade(length=0.2, elements=4).with_damping(Damping("rayleigh", alpha=ALPHA, beta=BETA))
    tip = Port.parse(TIP_NODE, "ux uy uz")
    prepared = prepare(body, Frame("none"), inputs=[tip], outputs=[tip])
    root = body.coordinates[body.node_rows(body.mesh.connectivity)][:, :, 0].max(axis=1) < 0.06
    upper = body.coordinates[body.node_rows(body.mesh.connectivity)][:, :, 2].min(axis=1) > -1e-9
    elements = body.mesh.element_ids[root & upper]
    operator = stress_operator(prepared.body, elements=elements)
    return body, prepared, operator


def dense(matrix) -> np.ndarray:
    return matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix)


def textbook_figures(components: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Von Mises and the signed absolute maximum principal stress of (n_t, p, 6) components."""
    xx, yy, zz, xy, xz, yz = np.moveaxis(components, -1, 0)
    vm = np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2)
                 + 3.0 * (xy**2 + xz**2 + yz**2))  # fmt: skip
    tensor = np.stack([xx, xy, xz, xy, yy, yz, xz, yz, zz], axis=-1).reshape(*xx.shape, 3, 3)
    principal = np.linalg.eigvalsh(tensor)
    low, high = principal[..., 0], principal[..., -1]
    return vm, np.where(-low > high, low, high)


def test_stress_history_of_full_and_reduced_blade_against_an_independent_integration(
    blade_model, tmp_path
):
    """Full model ``C_sigma T q(t)`` and Krylov body ``C_sigma V q_r(t)`` (rho_inf = 1) against
    the trapezoidal rule on the first-order form of each (dense, written in the tests) with the
    operator applied to the displacement fields; peak and ranges against the textbook formulas
    on those histories."""
    _, prepared, operator = blade_model
    points = hot_spot_labels(operator)
    assert len(points) == operator.n_points == 2 * 27 and points[0].startswith("e")
    full_system = prepared.system
    model = reduced_model(full_system, krylov_reduction(full_system, [0.0], 4))
    basis = prepared.expand(model.projection.V)
    rows = full_stress_rows(prepared, operator.matrix)
    full = simulate(full_system, CASES, DURATION_S, STEP_S, 1.0, rows, points)
    reduced = simulate(model.system, CASES, DURATION_S, STEP_S, 1.0,
                       np.asarray(operator.matrix @ basis), points)  # fmt: skip
    n_steps = full.times.size - 1
    for response, system, to_dofs in ((full, full_system, prepared.expand),
                                      (reduced, model.system, lambda q: basis @ q)):  # fmt: skip
        matrices = [dense(x) for x in (system.mass, system.stiffness, system.damping)]
        for case in CASES:
            q = trapezoidal_states(*matrices, dense(system.input_matrix), case, STEP_S, n_steps)
            components = np.moveaxis(operator(to_dofs(q.T)), -1, 0)  # (n_t, p, 6)
            history = response.stresses[case.name]
            peak = np.abs(components).max()
            assert np.abs(history.components - components).max() < 1e-9 * peak
            vm, signed = textbook_figures(components)
            for k, spot in enumerate(history.hot_spots()):
                assert spot.point == points[k]
                assert spot.peak_von_mises == pytest.approx(vm[:, k].max(), rel=1e-9)
                assert spot.range_von_mises == pytest.approx(np.ptp(vm[:, k]), rel=1e-9)
                assert spot.range_abs_max_principal == pytest.approx(np.ptp(signed[:, k]),
                                                                     rel=1e-9)  # fmt: skip
    # the reduced body's deviation: the largest component deviation over the full peak von Mises
    result = compare_stresses(full, reduced)
    for case in CASES:
        sigma_full = full.stresses[case.name].components
        sigma_red = reduced.stresses[case.name].components
        expected = np.abs(sigma_red - sigma_full).max() / textbook_figures(sigma_full)[0].max()
        assert result[case.name].max_rel_deviation == pytest.approx(expected, rel=1e-12)
        assert 1e-5 < expected < 0.1  # a 12-column Krylov body: close, not exact
    figure = plot_stress_histories(
        {"full": full.stresses, "krylov": reduced.stresses}, tmp_path / "stress.png"
    )
    assert figure.stat().st_size > 10_000


def test_stress_history_of_the_full_blade_converges_to_modal_superposition(blade_model):
    """The default scheme (rho_inf = 0.8) against the exact response of the full model (modal
    superposition of closed-form damped oscillators, the operator applied): the harmonic
    case within 4e-3 of the peak von Mises at h = 2e-5 s, 1.5e-3 at h = 1e-5 s -- the stress
    holds more of the stiff modes (that the scheme damps) than the tip displacement does."""
    _, prepared, operator = blade_model
    system, points = prepared.system, hot_spot_labels(operator)
    w2, modes = sla.eigh(system.stiffness.toarray(), system.mass.toarray())
    case = CASES[1]
    for step, tolerance in ((2e-5, 4e-3), (1e-5, 1.5e-3)):
        response = simulate(system, [case], DURATION_S, step,
                            stress_rows=full_stress_rows(prepared, operator.matrix),
                            hot_spots=points)  # fmt: skip
        load = modes.T @ system.input_matrix @ case.force_n
        eta = oscillator_response(w2, ALPHA + BETA * w2, load, response.times, case)
        exact = np.moveaxis(operator(prepared.expand(modes @ eta.T)), -1, 0)
        exact = StressHistory(response.times, exact.reshape(response.times.size, -1), points)
        deviation = compare_histories(response.stresses[case.name], exact).max_rel_deviation
        assert deviation < tolerance


def test_stress_rows_must_fit_the_model(blade_model):
    _, prepared, operator = blade_model
    points = hot_spot_labels(operator)
    with pytest.raises(UserError, match="hot spots"):
        rows = full_stress_rows(prepared, operator.matrix)
        simulate(prepared.system, CASES, DURATION_S, STEP_S, stress_rows=rows, hot_spots=points[:3])
    with pytest.raises(UserError, match="dofs"):
        full_stress_rows(prepared, operator.matrix[:, :-3])


def test_stress_history_from_coordinates_against_the_element_stresses(blade_model):
    """``C_sigma V q`` of a body's coordinates equals the stresses of the field ``V q`` at the
    Gauss points of the element, from the element's own kinematics
    (:func:`pymorembs.elements.solid.solid_stresses`)."""
    body, prepared, operator = blade_model
    model = reduced_model(prepared.system, krylov_reduction(prepared.system, [0.0], 2))
    basis = prepared.expand(model.projection.V)
    q = np.random.default_rng(3).standard_normal((5, model.projection.order))
    history = stress_history(np.arange(5.0), q, np.asarray(operator.matrix @ basis),
                             hot_spot_labels(operator))  # fmt: skip
    element = int(np.flatnonzero(body.mesh.element_ids == operator.element_ids[0])[0])
    rows = body.node_rows(body.mesh.connectivity[element])
    xyz = body.coordinates[rows][None]
    for k in range(q.shape[0]):
        field = (basis @ q[k]).reshape(-1, 3)  # the blade: equation 3 r + i, direction i
        tensors = solid_stresses("hex20", xyz, field[rows][None], body.mesh.young,
                                 body.mesh.poisson)[0]  # fmt: skip
        expected = tensors[:, [0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]]  # xx yy zz xy xz yz
        assert np.allclose(history.components[k, :27], expected, rtol=1e-10,
                           atol=1e-10 * np.abs(expected).max())  # fmt: skip
