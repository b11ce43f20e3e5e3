"""Constraint elimination, tangent frame and ports (eqs. 9-18) against Lagrange multipliers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from conftest import spring_lattice
from pymorembs.analysis.transfer import transfer_function
from pymorembs.body import ConstraintEquations, DofTable, ElasticBody
from pymorembs.errors import UserError
from pymorembs.preparation import Frame, Port, prepare, tangent_frame

PORTS = [Port.parse(120, "ux uz"), Port.parse(50, "uy"), Port.parse(110, "ux")]  # 120: dependent


def lagrange_response(body, frequency_hz, load, offsets):
    """Solve [[K - w^2 M, A^T], [A, 0]] [q; lam] = [load; b] with all constraints as rows of A."""
    n = body.n_dof
    rows, rhs = [], []
    c = body.constraints
    for k, d in enumerate(c.dependent):  # q_d - G q = g
        row = -c.matrix[k].toarray().ravel()
        row[d] += 1.0
        rows.append(row)
        rhs.append(c.offset[k] if offsets else 0.0)
    for f in body.fixed:  # q_c = 0
        row = np.zeros(n)
        row[f] = 1.0
        rows.append(row)
        rhs.append(0.0)
    a = np.array(rows)
    w = 2 * np.pi * frequency_hz
    dyn = body.stiffness.toarray() - w**2 * body.mass.toarray()
    kkt = np.block([[dyn, a.T], [a, np.zeros((a.shape[0], a.shape[0]))]])
    loads = np.atleast_2d(load.T).T
    full_rhs = np.vstack([loads, np.tile(np.array(rhs)[:, None], (1, loads.shape[1]))])
    return np.linalg.solve(kkt, full_rhs)[:n]


def selection(body, ports):
    idx = [body.dofs.index(p.node, d) for p in ports for d in p.directions]
    s = np.zeros((body.n_dof, len(idx)))
    s[idx, np.arange(len(idx))] = 1.0
    return s


@pytest.mark.parametrize("frequency_hz", [0.0, 7.0, 41.0, 130.0])
def test_elimination_matches_lagrange_multipliers(frequency_hz):
    body = tangent_frame(spring_lattice(), 20)
    prepared = prepare(body, Frame("none"), PORTS, PORTS)
    h = transfer_function(prepared.system, [frequency_hz])[0]
    b = selection(body, PORTS)
    q = lagrange_response(body, frequency_hz, b, offsets=False)
    h_ref = b.T @ q
    assert np.allclose(h, h_ref, rtol=1e-9, atol=1e-12 * np.abs(h_ref).max())


def test_static_offsets_match_lagrange_multipliers():
    body = tangent_frame(spring_lattice(offsets=True), 20)
    prepared = prepare(body, Frame("none"), PORTS, PORTS)
    system, elim = prepared.system, prepared.elimination
    load = np.zeros(body.n_dof)
    load[body.dofs.index(120, "ux")] = 3.0  # a force on a dependent dof
    load[body.dofs.index(60, "uy")] = -1.5
    # eliminated: K* q_i = T^T load + f*,  q = T q_i + t  (eqs. 11, 16, 17, 18)
    q_i = np.linalg.solve(
        system.stiffness.toarray(), elim.inputs(load[:, None]).ravel() + system.static_load
    )
    q = elim.transform @ q_i + elim.offset
    q_ref = lagrange_response(body, 0.0, load, offsets=True).ravel()
    assert np.allclose(q, q_ref, rtol=1e-9, atol=1e-12 * np.abs(q_ref).max())
    assert np.abs(elim.offset).max() > 0


def test_chained_constraints_are_resolved():
    base = spring_lattice(constraints=False)
    n = base.n_dof
    # q(ux of node 120) = 2 q(ux of 110) + 0.1 ;  q(ux of 110) = -q(uy of 50) + 0.2
    a, b, c = (base.dofs.index(120, "ux"), base.dofs.index(110, "ux"), base.dofs.index(50, "uy"))
    g = sp.lil_matrix((2, n))
    g[0, b] = 2.0
    g[1, c] = -1.0
    body = replace(base, constraints=ConstraintEquations([a, b], g.tocsr(), [0.1, 0.2]))
    elim = prepare(body, Frame("none")).elimination
    q_i = np.random.default_rng(1).normal(size=elim.n_independent)
    q = elim.transform @ q_i + elim.offset
    assert q[b] == pytest.approx(-q[c] + 0.2)
    assert q[a] == pytest.approx(2 * q[b] + 0.1)


def test_tangent_frame_translates_and_fixes():
    body = spring_lattice()
    framed = tangent_frame(body, 40)
    assert np.allclose(framed.node_position(40), 0.0)
    assert np.allclose(framed.coordinates + body.node_position(40), body.coordinates)
    assert set(framed.fixed) == set(body.dofs.of_node(40))
    prepared = prepare(body, Frame("tangent", 40), PORTS)
    basis = np.random.default_rng(0).normal(size=(prepared.system.order, 4))
    expanded = prepared.expand(basis)  # eq. 18
    assert np.all(expanded[body.dofs.of_node(40)] == 0.0)  # Phi(R_0) = 0
    dep = body.constraints.dependent
    assert np.allclose(
        expanded[dep], body.constraints.matrix[:, prepared.elimination.independent] @ basis
    )


def test_port_on_fixed_dof_gives_zero_column_and_a_note_or_warning():
    """A force at the frame node moves the frame only: a note. An output asked there (not the
    mirror of the inputs) is identically zero: a warning."""
    ports = [Port.parse(40, "ux"), Port.parse(50, "ux")]
    prepared = prepare(spring_lattice(), Frame("tangent", 40), ports)
    assert np.all(prepared.system.input_matrix[:, 0] == 0)
    assert prepared.warnings == ()
    assert prepared.notes == (
        "input 40:ux acts on fixed dofs of the frame: no elastic transfer (it moves the "
        "reference frame only)",
    )
    prepared = prepare(spring_lattice(), Frame("tangent", 40), ports, ports)
    assert prepared.warnings == () and len(prepared.notes) == 2
    prepared = prepare(spring_lattice(), Frame("tangent", 40), ports[1:], ports)
    assert np.all(prepared.system.output_matrix[0] == 0) and prepared.notes == ()
    assert prepared.warnings == (
        "output 40:ux acts on fixed dofs of the frame: no elastic transfer (it moves the "
        "reference frame only)",
    )


@pytest.mark.parametrize(
    ("frame", "ports", "message"),
    [
        (Frame("tangent", 999), PORTS, "node 999"),
        (Frame("tangent", 20), [Port.parse(77, "ux")], "node 77"),
        (Frame("tangent", 20), [Port.parse(50, "rx")], "no dof rx"),
        (Frame("tangent", 20), [Port.parse(50, "ux"), Port.parse(50, "ux uy")], "twice"),
    ],
)
def test_bad_preparation_is_a_user_error(frame, ports, message):
    with pytest.raises(UserError, match=message):
        prepare(spring_lattice(), frame, ports)


def test_unknown_frame_type_is_a_user_error():
    """The frame's kind is a FrameType: an unknown name fails where the Frame is made."""
    with pytest.raises(UserError, match="frame type"):
        prepare(spring_lattice(), Frame("spinning", 20), PORTS)


def test_tangent_frame_at_a_node_without_rotations_is_a_mechanism():
    from conftest import space_truss

    truss = space_truss()
    with pytest.raises(UserError, match="3 rigid-body motions free") as info:
        prepare(truss, Frame("tangent", 1), [Port.parse(5, "ux")])
    assert "rotation about" in str(info.value)
    with pytest.raises(UserError, match="6 rigid-body motions free"):
        prepare(truss, Frame("none"), [Port.parse(5, "ux")])
    # three nodes not on a line hold it; a free body is fine where rigid modes are allowed
    held = truss.with_fixed(np.concatenate([truss.dofs.of_node(n) for n in (1, 2, 4)]))
    prepare(held, Frame("none"), [Port.parse(5, "ux")])
    prepare(truss, Frame("none"), allow_rigid_body_modes=True)


def test_frame_with_rotational_dofs_and_ground_springs_are_not_mechanisms():
    from pymorembs.examples import build_example

    rack = build_example("rack-beams")
    prepare(rack, Frame("tangent", 2), [Port.parse(1, "ux")])  # 6 dofs at node 2: held
    with pytest.raises(UserError, match="6 rigid-body motions free"):
        prepare(rack, Frame("none"), [Port.parse(1, "ux")])
    prepare(spring_lattice(), Frame("none"), PORTS)  # anchored by springs to ground


def test_cyclic_constraints_are_found_whatever_the_coefficients():
    base = spring_lattice(constraints=False)
    a, b = base.dofs.index(110, "ux"), base.dofs.index(120, "ux")
    c = base.dofs.index(50, "uy")
    g = sp.lil_matrix((2, base.n_dof))
    g[0, b] = 49.0
    g[1, a] = 1.0 / 49.0  # nearly singular I - G_dd: not caught by a pivot test
    g[1, c] = 1.0
    body = replace(base, constraints=ConstraintEquations([a, b], g.tocsr(), [0.0, 0.0]))
    with pytest.raises(UserError, match="cyclic"):
        prepare(body, Frame("none"))


def test_long_constraint_tables_with_a_chain_stay_sparse():
    """15,000 tie constraints plus one chained entry: no dense n_d x n solve (was 5 GB)."""
    import time

    n = 30_000
    nodes = np.arange(1, n + 1)
    dofs = DofTable(nodes, np.zeros(n))
    k = sp.diags([np.full(n - 1, -1.0), np.full(n, 2.0), np.full(n - 1, -1.0)], [-1, 0, 1])
    body0 = ElasticBody(nodes, np.zeros((n, 3)), dofs, sp.identity(n).tocsr(), k.tocsr())
    dependent = np.arange(1, n, 2)  # odd dofs follow their even neighbour
    g = sp.lil_matrix((dependent.size, n))
    g[np.arange(dependent.size), dependent - 1] = 1.0
    g[5, dependent[7]] = 0.5  # one chain: dependent 5 also follows dependent 7
    body = replace(
        body0, constraints=ConstraintEquations(dependent, g.tocsr(), np.zeros(dependent.size))
    )
    start = time.perf_counter()
    elim = prepare(body, Frame("none"), allow_rigid_body_modes=True).elimination
    assert time.perf_counter() - start < 5.0
    q_i = np.random.default_rng(2).normal(size=elim.n_independent)
    q = elim.transform @ q_i
    assert q[dependent[5]] == pytest.approx(q[dependent[5] - 1] + 0.5 * q[dependent[7]])
