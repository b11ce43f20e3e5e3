"""The Buckens frame for free bodies (paper section 2.1): CG, inertia relief, M-orthogonality."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from conftest import space_truss
from pymorembs.analysis.error import relative_error
from pymorembs.analysis.transfer import transfer_function
from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.preparation import Frame, Port, centre_of_gravity, prepare
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.modal import modal_reduction
from pymorembs.reduction.projection import reduced_model

RACK_PORTS = [Port.parse(1, "ux uy uz"), Port.parse(2, "ux uy uz rx")]


@pytest.fixture(scope="module")
def rack():
    return build_example("rack-beams")


def test_centre_of_gravity_of_the_truss_is_its_geometric_centre():
    truss = space_truss()  # lumped, symmetric masses: the CG is the grid centre
    assert np.allclose(centre_of_gravity(truss), [0.15, 0.1, 0.05], atol=1e-14)
    shifted = truss.translated(np.array([1.0, -2.0, 3.0]))
    assert np.allclose(centre_of_gravity(shifted), [-0.85, 2.1, -2.95], atol=1e-13)


def test_centre_of_gravity_of_the_rack(rack):
    # plates at their reference nodes, rods uniform: CG by hand from the part masses
    z_upper = rack.node_position(2)[2]
    rods = 0.0789 / 4  # per rod (kg), centred at the rod mid-height
    rod_mid = (rack.node_position(1001)[2] + rack.node_position(1166)[2]) / 2
    masses = np.array([0.2010, 1.1067, 4 * rods])
    heights = np.array([0.0, z_upper, rod_mid])
    expected = masses @ heights / masses.sum()
    assert centre_of_gravity(rack) == pytest.approx([0, 0, expected], abs=2e-4)


def test_inertia_relief_static_response_against_a_bordered_system():
    truss = space_truss()
    ports = [Port.parse(7, "ux uz"), Port.parse(20, "uy")]
    prepared = prepare(truss, Frame("buckens"), ports, ports)
    system = prepared.system
    h0 = transfer_function(system, [0.0])[0].real
    # independent: [[K, M R], [R^T M, 0]] [x; lam] = [f_e; 0] with R from the geometry
    k, m = system.stiffness.toarray(), system.mass.toarray()
    r = prepared.body.rigid_body_modes()
    r = r @ np.linalg.inv(np.linalg.cholesky(r.T @ m @ r)).T
    b = np.zeros((truss.n_dof, 3))
    b[
        [truss.dofs.index(7, "ux"), truss.dofs.index(7, "uz"), truss.dofs.index(20, "uy")],
        [0, 1, 2],
    ] = 1.0
    b_e = b - m @ r @ (r.T @ b)
    bordered = np.block([[k, m @ r], [r.T @ m, np.zeros((6, 6))]])
    x = np.linalg.solve(bordered, np.vstack([b_e, np.zeros((6, 3))]))[: truss.n_dof]
    c_e = b.T - (b.T @ r) @ (m @ r).T
    assert np.allclose(h0, c_e @ x, rtol=1e-9, atol=1e-12 * np.abs(c_e @ x).max())
    # the elastic transfer function is continuous at 0 Hz (no rigid-body pole)
    h_small = transfer_function(system, [1e-3])[0]
    assert np.linalg.norm(h_small - h0) < 1e-6 * np.linalg.norm(h0)


@pytest.mark.slow  # 4-10 s: in the slow set (make test stays within its budget)
def test_modal_reduction_of_the_free_rack_gives_its_elastic_modes(rack):
    prepared = prepare(rack, Frame("buckens"), RACK_PORTS)
    system = prepared.system
    model = reduced_model(system, modal_reduction(system, 6))
    # dense reference in flexibility form, accurate for the lowest modes (the direct form
    # factors the ill-conditioned M and spreads the 5-fold 460 Hz eigenvalue by 3e-7)
    shift = 1e3
    k, m = system.stiffness.toarray(), system.mass.toarray()
    n = k.shape[0]
    mu = sla.eigh(m, k + shift * m, eigvals_only=True, subset_by_index=[n - 12, n - 1])[::-1]
    elastic = np.sqrt(1.0 / mu[6:] - shift) / (2 * np.pi)
    assert np.allclose(model.eigenfrequencies_hz, elastic, rtol=1e-8)
    assert model.eigenfrequencies_hz[0] == pytest.approx(105.34, abs=0.01)


@pytest.mark.parametrize("method", ["krylov", "modal"])
def test_buckens_bases_are_mass_orthogonal_to_the_rigid_body_modes(rack, method):
    prepared = prepare(rack, Frame("buckens"), RACK_PORTS)
    system = prepared.system
    projection = (
        krylov_reduction(system, [0.0, 300.0, 900.0], moments=3)
        if method == "krylov"
        else modal_reduction(system, 20)
    )
    model = reduced_model(system, projection)
    v_all = prepared.expand(model.projection.V)  # eq. 18: all dofs of the FE model
    rigid = prepared.body.rigid_body_modes()
    rigid = rigid / np.sqrt(np.einsum("ij,ij->j", rigid, prepared.body.mass @ rigid))
    v_all = v_all / np.sqrt(np.einsum("ij,ij->j", v_all, prepared.body.mass @ v_all))
    assert np.abs(rigid.T @ (prepared.body.mass @ v_all)).max() < 1e-10


def test_krylov_on_the_free_rack_is_accurate_and_statically_exact(rack):
    prepared = prepare(rack, Frame("buckens"), RACK_PORTS)
    system = prepared.system
    model = reduced_model(system, krylov_reduction(system, [0.0, 400.0, 900.0], moments=4))
    f = np.array([0.0, 10.0, 100.0, 500.0, 1000.0])
    eps = relative_error(transfer_function(system, f), transfer_function(model.system, f))
    assert eps[0] < 1e-10
    assert eps.max() < 1e-4


def test_buckens_needs_a_free_body(rack):
    with pytest.raises(UserError, match="fixed dofs"):
        prepare(rack.with_fixed(rack.dofs.of_node(1)), Frame("buckens"), RACK_PORTS)
    from conftest import spring_lattice  # anchored by springs: no rigid-body modes

    with pytest.raises(UserError, match="six rigid-body modes"):
        prepare(spring_lattice(), Frame("buckens"), [Port.parse(50, "ux")])


def test_buckens_reduction_of_rack_solid_is_mass_orthogonal_to_rigid_modes():
    """Issue #3: rack-solid (light stiff beams at node 2), Buckens frame, V^T M R = 0."""
    body = build_example("rack-solid", dofs=8_000)
    ports = [Port.parse(1, "ux uy uz"), Port.parse(2, "ux uy uz")]
    prepared = prepare(body, Frame("buckens"), ports)
    model = reduced_model(
        prepared.system, krylov_reduction(prepared.system, [0.0, 500.0, 1000.0], moments=3)
    )
    v_all = prepared.expand(model.projection.V)
    rigid = prepared.body.rigid_body_modes()
    mass = prepared.body.mass
    rigid = rigid / np.sqrt(np.einsum("ij,ij->j", rigid, mass @ rigid))
    v_all = v_all / np.sqrt(np.einsum("ij,ij->j", v_all, mass @ v_all))
    assert np.abs(rigid.T @ (mass @ v_all)).max() < 1e-10
    f = np.array([0.0, 200.0, 700.0])
    eps = relative_error(transfer_function(prepared.system, f), transfer_function(model.system, f))
    assert eps.max() < 1e-6
