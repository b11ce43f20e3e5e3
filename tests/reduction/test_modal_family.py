"""Best modes, modes with frequency response modes and Craig-Bampton against dense computations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from conftest import space_truss, spring_lattice
from pymorembs.analysis.error import relative_error
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import Damping
from pymorembs.errors import UserError
from pymorembs.frequencies import frequency_grid
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.modal import modal_reduction
from pymorembs.reduction.modal_family import (
    DEFAULT_DAMPING_RATIO,
    best_modes,
    boundary_dofs_of_inputs,
    craig_bampton,
    modes_with_frm,
)
from pymorembs.reduction.projection import Projection, reduced_model
from pymorembs.system import SecondOrderSystem

INPUTS = [Port.parse(70, "ux uy"), Port.parse(40, "uz")]
OUTPUTS = [Port.parse(50, "ux uy uz")]


def system_of(damping=None, outputs=OUTPUTS, n_nodes=40):
    body = spring_lattice(n_nodes=n_nodes, damping=damping)
    return prepare(body, Frame("tangent", 10), INPUTS, outputs).system


def dense(matrix):
    return matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix)


def chain(n, seed=0, stiffness=1.0, start=0):
    """Fixed-free spring-mass chain: spring ``j`` joins mass ``j - 1`` (ground for j = 0) to
    mass ``j``. Returns dense K, M (n x n), random springs and masses around the given scale."""
    rng = np.random.default_rng(seed)
    springs = stiffness * rng.uniform(0.5, 2.0, size=n)
    masses = rng.uniform(0.5, 2.0, size=n)
    k = np.diag(springs + np.append(springs[1:], 0.0))
    k -= np.diag(springs[1:], 1) + np.diag(springs[1:], -1)
    return k, np.diag(masses)


def chain_system(n=30, inputs=(-1,), outputs=(-1,)):
    k, m = chain(n)
    eye = np.eye(n)
    return SecondOrderSystem(
        mass=sp.csr_matrix(m),
        stiffness=sp.csr_matrix(k),
        damping=None,
        input_matrix=eye[:, list(inputs)],
        output_matrix=eye[list(outputs)],
    )


def response_error(system, projection, frequencies):
    model = reduced_model(system, projection)
    return relative_error(
        transfer_function(system, frequencies), transfer_function(model.system, frequencies)
    )


# --------------------------------------------------------------------------------------------
# best modes
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("damping", "ratio"),
    [
        (None, lambda omega: np.full_like(omega, DEFAULT_DAMPING_RATIO)),
        (Damping("modal", ratio=0.02), lambda omega: np.full_like(omega, 0.02)),
        # Rayleigh: D = alpha M + beta K gives xi_i = (alpha / omega_i + beta omega_i) / 2
        (Damping("rayleigh", alpha=40.0, beta=1e-6), lambda w: 0.5 * (40.0 / w + 1e-6 * w)),
    ],
)
def test_best_modes_rank_by_approximate_hsv(damping, ratio):
    system = system_of(damping, n_nodes=12)
    order = 6
    projection = best_modes(system, order)
    count = projection.parameters["candidates"]
    assert count == min(max(3 * order, order + 20), system.order - 1)
    # independent: all modes densely, eq. 26 by hand on the same candidates
    values, phi = sla.eigh(dense(system.stiffness), dense(system.mass))
    values, phi = values[:count], phi[:, :count]
    omega = np.sqrt(values)
    b_tilde, c_tilde = phi.T @ system.input_matrix, system.output_matrix @ phi
    sigma = (
        np.linalg.norm(c_tilde, axis=0)
        * np.linalg.norm(b_tilde, axis=1)
        / (4 * omega * ratio(omega))
    )
    expected = np.sort(np.argsort(-sigma)[:order])
    assert projection.parameters["mode_indices"] == expected.tolist()
    assert np.allclose(projection.parameters["approximate_hsv"], np.sort(sigma)[::-1], rtol=1e-7)
    assert np.allclose(
        projection.parameters["mode_frequencies_hz"], omega[expected] / (2 * np.pi), rtol=1e-9
    )
    # V holds exactly these modes (up to sign)
    overlap = phi[:, expected].T @ dense(system.mass) @ projection.V
    assert np.allclose(np.abs(overlap), np.eye(order), atol=1e-8)
    assert projection.one_sided


def test_rayleigh_damping_changes_the_choice():
    """With a strong mass-proportional part the lowest modes are damped most: eq. 26 with the
    modal xi_i then prefers higher modes than with a constant ratio."""
    plain = best_modes(system_of(n_nodes=12), 6)
    damped = best_modes(system_of(Damping("rayleigh", alpha=400.0), n_nodes=12), 6)
    assert damped.parameters["damping_source"] == "viscous"
    assert plain.parameters["damping_source"] == "default"
    assert damped.parameters["mode_indices"] != plain.parameters["mode_indices"]
    assert sum(damped.parameters["mode_indices"]) > sum(plain.parameters["mode_indices"])


def two_chains(coupling=1e-2):
    """A soft chain (all its modes lowest) weakly coupled to a stiff one that carries the ports:
    the lowest modes hardly take part in the transfer behaviour."""
    k_soft, m_soft = chain(10, seed=1, stiffness=1.0)
    k_stiff, m_stiff = chain(10, seed=2, stiffness=1e4)
    k = sla.block_diag(k_soft, k_stiff)
    m = sla.block_diag(m_soft, m_stiff)
    a, b = 9, 19  # free ends
    k[[a, b], [a, b]] += coupling
    k[a, b] -= coupling
    k[b, a] -= coupling
    eye = np.eye(20)
    return SecondOrderSystem(
        mass=sp.csr_matrix(m),
        stiffness=sp.csr_matrix(k),
        damping=None,
        input_matrix=eye[:, [19]],
        output_matrix=eye[[19, 14]],
        loss_factor=0.04,
        modal_damping_ratio=0.02,
    )


def test_best_modes_beat_the_lowest_modes():
    system = two_chains()
    frequencies = np.sqrt(sla.eigh(dense(system.stiffness), dense(system.mass), eigvals_only=True))
    frequencies = frequencies / (2 * np.pi)
    assert frequencies[9] < frequencies[10] / 2  # the soft chain's ten modes come first
    order = 6
    best = best_modes(system, order, candidates=19)
    assert min(best.parameters["mode_indices"]) >= 10  # all from the stiff chain
    grid = frequency_grid(0.0, frequencies[12], 300)
    eps_best = response_error(system, best, grid)
    eps_lowest = response_error(system, modal_reduction(system, order), grid)
    assert eps_lowest.max() > 0.9  # the lowest modes miss the response entirely
    assert eps_best.max() < 0.2 * eps_lowest.max()
    assert np.all(eps_best < eps_lowest)


def test_best_modes_of_repeated_eigenvalues_do_not_depend_on_the_solver_basis():
    """Two identical chains loaded and read at both free ends alike: every eigenvalue is double,
    and only the symmetric mode of each pair takes part. Eq. 26 on the solver's arbitrary basis
    of a pair would split it; the cluster rotation keeps exactly the best symmetric modes."""
    k1, m1 = chain(10, seed=3)
    eye = np.eye(20)
    ends = eye[:, [9]] + eye[:, [19]]
    system = SecondOrderSystem(
        mass=sp.csr_matrix(sla.block_diag(m1, m1)),
        stiffness=sp.csr_matrix(sla.block_diag(k1, k1)),
        damping=None,
        input_matrix=ends,
        output_matrix=ends.T,
    )
    values, phi = sla.eigh(k1, m1)
    symmetric = np.vstack([phi, phi]) / np.sqrt(2)  # mass-normalised in the doubled system
    b_tilde = symmetric.T @ ends
    sigma = (b_tilde[:, 0] ** 2) / (4 * np.sqrt(values) * DEFAULT_DAMPING_RATIO)
    order = 4
    top = np.argsort(-sigma)[:order]
    expected = symmetric[:, top]
    for _ in range(3):  # the eigensolver starts at random
        projection = best_modes(system, order, candidates=19)
        v = projection.V
        inside = expected @ (expected.T @ (dense(system.mass) @ v))
        assert np.linalg.norm(v - inside) <= 1e-8 * np.linalg.norm(v)
        assert projection.parameters["repeated_eigenvalue_clusters"] == 9  # 19 candidates
        assert projection.parameters["negligible_modes_chosen"] == 0
        assert np.allclose(
            projection.parameters["approximate_hsv"][:order], np.sort(sigma)[::-1][:order]
        )


def test_best_modes_options():
    system = system_of(n_nodes=8)
    with pytest.raises(UserError, match="candidates"):
        best_modes(system, 5, candidates=3)
    with pytest.raises(UserError, match="modes requested"):
        best_modes(system, system.order)
    with pytest.raises(UserError, match="inputs and outputs"):
        best_modes(replace(system, output_matrix=np.zeros((0, system.order)), output_labels=()), 3)
    # a constant ratio only scales the values: same choice, values in inverse proportion
    a = best_modes(system, 4, damping_ratio=0.01)
    b = best_modes(system, 4, damping_ratio=0.05)
    assert a.parameters["mode_indices"] == b.parameters["mode_indices"]
    assert np.allclose(
        np.array(a.parameters["approximate_hsv"]) / 5, b.parameters["approximate_hsv"]
    )


# --------------------------------------------------------------------------------------------
# eigenmodes + frequency response modes
# --------------------------------------------------------------------------------------------


def test_static_frm_makes_the_static_response_exact():
    system = system_of()
    zero = np.array([0.0])
    projection = modes_with_frm(system, 10, 0.0, modes="lowest")
    assert projection.order == 13  # 10 modes + 3 inputs
    assert projection.parameters["frm_directions"] == [3]
    assert np.allclose(projection.V.T @ projection.V, np.eye(13), atol=1e-12)
    assert response_error(system, projection, zero)[0] <= 1e-10
    assert response_error(system, modal_reduction(system, 10), zero)[0] > 1e-6


def test_frm_interpolates_at_its_frequency():
    """The exact response (K - w^2 M)^-1 B lies in span(V): a Galerkin projection reproduces
    H at that frequency (no damping)."""
    system = system_of()
    projection = modes_with_frm(system, 10, [0.0, 3.0], modes="best")
    assert projection.order == 16
    assert projection.parameters["eigenmodes"] == 10
    assert len(projection.parameters["approximate_hsv"]) == projection.parameters["candidates"]
    eps = response_error(system, projection, np.array([0.0, 3.0, 1.7]))
    assert eps[0] <= 1e-10 and eps[1] <= 1e-10
    assert eps[2] > 1e-8  # elsewhere only approximate


def test_dependent_frm_are_deflated():
    system = system_of()
    once = modes_with_frm(system, 8, [0.0], modes="lowest")
    twice = modes_with_frm(system, 8, [0.0, 0.0], modes="lowest")
    assert once.order == twice.order == 11
    assert twice.parameters["frm_directions"] == [3, 0]
    assert twice.parameters["frm_deflated"] == [0, 3]
    # the same input twice: B has rank 3
    doubled = replace(
        system, input_matrix=np.hstack([system.input_matrix, -system.input_matrix]), input_labels=()
    )
    projection = modes_with_frm(doubled, 8, [0.0], modes="lowest")
    assert projection.order == 11
    assert projection.parameters["frm_deflated"] == [3]


def test_frm_in_the_span_of_the_modes_is_deflated():
    """A load M phi_j on mode j: K^-1 M phi_j = phi_j / omega_j^2 adds nothing to the modes."""
    system = system_of()
    _, phi = sla.eigh(dense(system.stiffness), dense(system.mass), subset_by_index=(0, 7))
    loads = np.column_stack([dense(system.mass) @ phi[:, 2], system.input_matrix[:, 0]])
    modal_load = replace(system, input_matrix=loads, input_labels=())
    projection = modes_with_frm(modal_load, 8, [0.0], modes="lowest")
    assert projection.order == 9
    assert projection.parameters["frm_deflated"] == [1]


def test_static_frm_of_a_free_body_uses_inertia_relief():
    ports = [Port.parse(7, "ux uz"), Port.parse(20, "uy")]
    system = prepare(space_truss(), Frame("buckens"), ports, ports).system
    zero = np.array([0.0])
    projection = modes_with_frm(system, 6, 0.0, modes="lowest")
    assert projection.order == 9
    assert response_error(system, projection, zero)[0] <= 1e-10
    assert response_error(system, modal_reduction(system, 6), zero)[0] > 1e-6


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"frm_hz": []}, "at least one"),
        ({"frm_hz": [-1.0]}, ">= 0"),
        ({"frm_hz": [np.nan]}, "finite"),
        ({"frm_hz": 0.0, "modes": "highest"}, "'best' or 'lowest'"),
    ],
)
def test_bad_frm_options(kwargs, message):
    with pytest.raises(UserError, match=message):
        modes_with_frm(system_of(n_nodes=8), 4, **kwargs)


# --------------------------------------------------------------------------------------------
# Craig-Bampton
# --------------------------------------------------------------------------------------------


def ritz_values(system, v):
    k, m = dense(system.stiffness), dense(system.mass)
    return sla.eigh(v.T @ k @ v, v.T @ m @ v, eigvals_only=True)


def test_craig_bampton_eigenvalues_converge_from_above():
    n = 30
    system = chain_system(n)
    exact = sla.eigh(dense(system.stiffness), dense(system.mass), eigvals_only=True)
    previous = None
    for k in (0, 1, 3, 6, 12, 27, 28, n - 1):  # Guyan, Lanczos, and dense interior modes
        projection = craig_bampton(system, [n - 1], k)
        assert projection.order == k + 1
        reduced = ritz_values(system, projection.V)
        assert np.all(reduced >= exact[: k + 1] * (1 - 1e-12))  # Rayleigh-Ritz: from above
        if previous is not None:  # nested spaces: every eigenvalue decreases
            assert np.all(reduced[: previous.size] <= previous * (1 + 1e-12))
        previous = reduced
    assert np.allclose(previous, exact, rtol=1e-10, atol=0)
    # the same through reduced_model
    model = reduced_model(system, craig_bampton(system, [n - 1], n - 1))
    assert np.allclose((2 * np.pi * model.eigenfrequencies_hz) ** 2, exact, rtol=1e-10, atol=0)


def test_craig_bampton_fixed_interface_modes_of_a_chain():
    """Lowest reduced eigenvalue of the chain with its free end held = first fixed mode."""
    n = 30
    system = chain_system(n)
    projection = craig_bampton(system, [n - 1], 5)
    k, m = dense(system.stiffness), dense(system.mass)
    held = sla.eigh(k[:-1, :-1], m[:-1, :-1], eigvals_only=True)[:5]
    assert np.allclose(
        (2 * np.pi * np.array(projection.parameters["fixed_interface_frequencies_hz"])) ** 2,
        held,
        rtol=1e-9,
    )
    phi = projection.V[:, 1:]
    assert np.all(phi[-1] == 0)  # boundary held
    assert np.allclose(phi.T @ m @ phi, np.eye(5), atol=1e-10)


@pytest.mark.parametrize("n_fixed", [0, 4])
def test_craig_bampton_constraint_modes_and_static_response(n_fixed):
    system = system_of(n_nodes=30)
    boundary = boundary_dofs_of_inputs(system)
    assert boundary.size == 3
    projection = craig_bampton(system, boundary, n_fixed)
    assert projection.order == 3 + n_fixed
    k = dense(system.stiffness)
    interior = np.setdiff1d(np.arange(system.order), boundary)
    psi = projection.V[:, :3]
    assert np.array_equal(psi[boundary], np.eye(3))
    residual = k[np.ix_(interior, interior)] @ psi[interior] + k[np.ix_(interior, boundary)]
    scale = np.linalg.norm(k[np.ix_(interior, interior)]) * np.linalg.norm(psi[interior])
    assert np.linalg.norm(residual) <= 1e-13 * scale
    # loads on the boundary only: the static response is exact
    zero = np.array([0.0])
    assert response_error(system, projection, zero)[0] <= 1e-10
    # independent: full static deflection under the boundary loads vs the projected one
    v = projection.V
    full = np.linalg.solve(k, system.input_matrix)
    red = v @ np.linalg.solve(v.T @ k @ v, v.T @ system.input_matrix)
    assert np.linalg.norm(red - full) <= 1e-10 * np.linalg.norm(full)


def test_craig_bampton_static_response_of_a_chain():
    n = 30
    system = chain_system(n, inputs=(-1,), outputs=(5, 17, -1))
    k = dense(system.stiffness)
    v = craig_bampton(system, [n - 1], 3).V
    full = np.linalg.solve(k, system.input_matrix)
    red = v @ np.linalg.solve(v.T @ k @ v, v.T @ system.input_matrix)
    assert np.linalg.norm(red - full) <= 1e-10 * np.linalg.norm(full)
    # a load inside is not exact
    inside = replace(system, input_matrix=np.eye(n)[:, [10]], input_labels=())
    full = np.linalg.solve(k, inside.input_matrix)
    red = v @ np.linalg.solve(v.T @ k @ v, v.T @ inside.input_matrix)
    assert np.linalg.norm(red - full) > 1e-6 * np.linalg.norm(full)


def test_boundary_dofs_of_inputs():
    system = chain_system(30, inputs=(17, 5, 5))
    assert boundary_dofs_of_inputs(system).tolist() == [5, 17]


def test_craig_bampton_of_a_free_body():
    truss = space_truss()
    ports = [Port.parse(7, "ux uz"), Port.parse(20, "uy")]
    system = prepare(truss, Frame("buckens"), ports, ports).system
    assert system.order == truss.n_dof  # no fixed dofs: dof j of node i is 3 (i - 1) + j
    boundary = np.concatenate([3 * (node - 1) + np.arange(3) for node in (1, 12, 24)])
    projection = craig_bampton(system, boundary, 5)
    assert projection.parameters["rigid_directions_removed"] == 6
    assert projection.order == 9 + 5 - 6
    model = reduced_model(system, projection)
    exact = sla.eigh(dense(system.stiffness), dense(system.mass), eigvals_only=True)[6:]
    reduced = (2 * np.pi * model.eigenfrequencies_hz) ** 2
    assert np.all(reduced >= exact[: reduced.size] * (1 - 1e-9))
    with pytest.raises(UserError, match="do not hold"):
        craig_bampton(system, 3 * (7 - 1) + np.arange(3), 2)
    with pytest.raises(UserError, match="explicitly"):
        boundary_dofs_of_inputs(system)


@pytest.mark.parametrize(
    ("boundary", "modes", "message"),
    [
        ([], 2, "at least one"),
        ([0, 0], 2, "repeat"),
        ([30], 2, r"\[0, 30\)"),
        ([29], 30, r"\[0, 29\]"),
        ([1.5], 2, "integer"),
    ],
)
def test_bad_craig_bampton_options(boundary, modes, message):
    with pytest.raises(UserError, match=message):
        craig_bampton(chain_system(30), boundary, modes)


def test_projection_type():
    projection = craig_bampton(chain_system(10), [9], 2)
    assert isinstance(projection, Projection) and projection.W is projection.V
