"""Input validation before anything expensive (``pymorembs.preparation.validation``).

Each bad model is built here by one deliberate change of a good one; each check must name the
place (node and direction) of the problem.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse as sp

from conftest import space_truss, spring_lattice
from pymorembs.body import ConstraintEquations, DofTable, ElasticBody
from pymorembs.errors import NumericalError, UserError
from pymorembs.examples import build_example
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.preparation.validation import (
    validate_body,
    validate_prepared,
    worst_asymmetry,
    worst_principal_minor,
)

PORT = [Port.parse(60, "ux")]


def test_a_good_body_passes_every_check():
    body = spring_lattice()
    report = validate_body(body)
    assert report.facts["relative_asymmetry"] == {"mass": 0.0, "stiffness": 0.0}
    prepared = prepare(body, Frame("tangent", 10), PORT, PORT)
    deep = validate_prepared(prepared)
    assert deep.facts["inertia"]["negative"] == 0
    assert deep.facts["inertia"]["positive"] == prepared.system.order
    assert "no mechanism (lowest eigenvalues)" in deep.checks
    # the lowest eigenvalue agrees with a dense solution of (K, M)
    import scipy.linalg as sla

    exact = sla.eigh(
        prepared.system.stiffness.toarray(), prepared.system.mass.toarray(), eigvals_only=True
    )
    lowest = deep.facts["lowest_eigenvalues"][0]  # Rayleigh-Ritz: an upper bound
    assert exact[0] * (1 - 1e-12) <= lowest <= exact[0] * (1 + 1e-6)


def test_positive_definite_stiffness_is_factorized_once_for_the_job(monkeypatch):
    """With PARDISO a held body's K is factorized itself (no shift) when it is positive
    definite, and a job's later factorizations of K take that factor."""
    from pymorembs.linalg import backends, shared_factorizations
    from pymorembs.linalg.factorization import Factorization

    if "pardiso" not in backends.available_backends():
        pytest.skip("PARDISO is not installed")
    monkeypatch.setenv("PYMOREMBS_SOLVER", "pardiso")
    prepared = prepare(spring_lattice(), Frame("tangent", 10), PORT, PORT)
    stiffness = prepared.system.stiffness
    with shared_factorizations() as shared:
        deep = validate_prepared(prepared)
        assert deep.facts["sigma"] == 0.0 and shared.made == 1
        static = Factorization(stiffness, label="K")
        assert static.reused and shared.reused == 1
        rhs = np.linspace(1.0, 2.0, stiffness.shape[0])
        x = static.solve(rhs)
    assert np.linalg.norm(stiffness @ x - rhs) <= 1e-12 * np.linalg.norm(rhs)
    assert deep.facts["inertia"] == {"positive": prepared.system.order, "negative": 0}
    import scipy.linalg as sla

    exact = sla.eigh(stiffness.toarray(), prepared.system.mass.toarray(), eigvals_only=True)
    lowest = deep.facts["lowest_eigenvalues"][0]
    assert exact[0] * (1 - 1e-12) <= lowest <= exact[0] * (1 + 1e-6)
    # a mechanism: K is singular, the shifted factorization finds and names it as before
    loose = prepare(_loose(spring_lattice(), joined=True), Frame("tangent", 10), PORT, PORT)
    with shared_factorizations() as shared, pytest.raises(UserError, match="3 mechanisms"):
        validate_prepared(loose)
    assert len(shared) == 0  # nothing kept of a matrix that failed the check


def test_asymmetric_stiffness_names_the_worst_entry():
    body = spring_lattice(constraints=False)
    k = body.stiffness.tolil()
    i, j = body.dofs.index(50, "uy"), body.dofs.index(60, "ux")
    k[i, j] = k[i, j] + 1e-3 * abs(body.stiffness).max()
    k[j, i] = k[j, i] + 1e-12 * abs(body.stiffness).max()  # a rounding-sized difference elsewhere
    bad = replace(body, stiffness=k.tocsr())
    value, row, col = worst_asymmetry(bad.stiffness)
    assert {row, col} == {i, j}
    assert value == pytest.approx(1e-3, rel=1e-6)
    with pytest.raises(UserError) as info:
        validate_body(bad)
    message = str(info.value)
    assert "stiffness matrix is not symmetric" in message
    assert "node 50 uy" in message and "node 60 ux" in message and "1.0e-03" in message


def test_rounding_sized_asymmetry_is_accepted():
    body = spring_lattice(constraints=False)
    k = body.stiffness.tolil()
    i, j = body.dofs.index(50, "uy"), body.dofs.index(60, "ux")
    k[i, j] = k[i, j] * (1 + 1e-13)
    report = validate_body(replace(body, stiffness=k.tocsr()))
    assert 0 < report.facts["relative_asymmetry"]["stiffness"] < 1e-12


def test_negative_mass_diagonal_is_a_numerical_error():
    body = spring_lattice()
    m = body.mass.tolil()
    i = body.dofs.index(70, "uz")
    m[i, i] = -0.5
    with pytest.raises(NumericalError, match="mass matrix is indefinite: 1 negative diagonal entry"
                       r", the most negative at node 70 uz"):  # fmt: skip
        validate_body(replace(body, mass=m.tocsr()))


def test_negative_principal_minor_proves_an_indefinite_mass():
    body = spring_lattice(constraints=False)
    m = body.mass.tolil()
    i, j = body.dofs.index(40, "ux"), body.dofs.index(50, "ux")
    coupling = 2.0 * np.sqrt(m[i, i] * m[j, j])  # diagonal fine, |m_ij| too large
    m[i, j] = m[j, i] = coupling
    bad = replace(body, mass=m.tocsr())
    assert worst_principal_minor(bad.mass)[:2] == (i, j)
    assert worst_principal_minor(body.mass) is None
    with pytest.raises(NumericalError, match=r"node 40 ux.*node 50 ux"):
        validate_body(bad)


def test_indefinite_mass_found_by_lanczos_when_minors_pass():
    """A mass matrix whose 2x2 minors are fine but which is indefinite (a 3x3 block)."""
    body = spring_lattice(constraints=False)
    m = body.mass.toarray()
    idx = [body.dofs.index(80, d) for d in ("ux", "uy", "uz")]
    block = np.full((3, 3), -0.9)
    np.fill_diagonal(block, 1.0)  # eigenvalues 1.9, 1.9, -0.8: 2x2 minors 1 - 0.81 > 0
    m[np.ix_(idx, idx)] = block
    bad = replace(body, mass=sp.csr_matrix(m))
    validate_body(bad)  # the O(nnz) checks cannot see it
    prepared = prepare(bad, Frame("tangent", 10), PORT, PORT)
    with pytest.raises(NumericalError, match=r"mass matrix is indefinite.*node 80"):
        validate_prepared(prepared)


@pytest.mark.parametrize("backend", ["pardiso", "superlu"])
def test_indefinite_stiffness_is_found(backend, monkeypatch):
    """With PARDISO by the inertia of K + sigma M; with SuperLU (no inertia when its pivoting
    was not symmetric) by the negative eigenvalue the inverse iteration finds."""
    from pymorembs.linalg import backends

    if backend not in backends.available_backends():
        pytest.skip("PARDISO is not installed")
    monkeypatch.setattr(backends, "available_backends", lambda: [backend])
    monkeypatch.setenv("PYMOREMBS_SOLVER", backend)
    body = spring_lattice(constraints=False)
    k = body.stiffness.toarray()
    idx = [body.dofs.index(90, d) for d in ("ux", "uy", "uz")]
    scale = k[idx[0], idx[0]]
    k[np.ix_(idx, idx)] -= 3.0 * scale * np.ones((3, 3)) / 3 * 1.5  # a negative spring
    bad = replace(body, stiffness=sp.csr_matrix(k))
    prepared = prepare(bad, Frame("tangent", 10), PORT, PORT, allow_rigid_body_modes=True)
    pattern = (
        r"K \+ sigma M has \d+ negative eigenvalue"
        if backend == "pardiso"
        else r"negative eigenvalue|stiffness matrix is not positive semidefinite: \(K, M\) has"
    )
    with pytest.raises(NumericalError, match=pattern):
        validate_prepared(prepared)


def test_dependent_and_fixed_at_once_is_refused():
    body = spring_lattice()
    both = body.with_fixed(body.constraints.dependent[:1])
    with pytest.raises(UserError, match="node 120 ux is both fixed and the dependent dof"):
        validate_body(both)


def test_duplicate_node_ids_and_nan_are_refused_on_construction():
    body = spring_lattice(constraints=False)
    ids = body.node_ids.copy()
    ids[3] = ids[2]
    with pytest.raises(UserError, match="node id 30 appears more than once"):
        replace(body, node_ids=ids)
    m = body.mass.tolil()
    m[0, 0] = np.nan
    with pytest.raises(UserError, match="NaN"):
        replace(body, mass=m.tocsr())


def _loose(body: ElasticBody, joined: bool) -> ElasticBody:
    """Two extra nodes joined to each other only (``joined``), or one with mass only."""
    ids = [130, 140] if joined else [130]
    n_new = 3 * len(ids)
    extra = np.zeros((n_new, n_new))
    if joined:
        extra = 1e5 * np.block([[np.eye(3), -np.eye(3)], [-np.eye(3), np.eye(3)]])
    constraints = body.constraints
    return replace(
        body,
        node_ids=np.concatenate([body.node_ids, ids]),
        coordinates=np.vstack([body.coordinates, np.ones((len(ids), 3)) * [20.0, 1.0, 0.0]]),
        dofs=DofTable(
            np.concatenate([body.dofs.nodes, np.repeat(ids, 3)]),
            np.concatenate([body.dofs.directions, np.tile([0, 1, 2], len(ids))]),
        ),
        mass=sp.block_diag([body.mass, sp.identity(n_new)], format="csr"),
        stiffness=sp.block_diag([body.stiffness, sp.csr_matrix(extra)], format="csr"),
        constraints=ConstraintEquations(
            constraints.dependent,
            sp.hstack([constraints.matrix, sp.csr_matrix((len(constraints), n_new))]),
            constraints.offset,
        ),
    )


def test_a_loose_part_of_a_held_body_is_a_named_mechanism():
    body = _loose(spring_lattice(), joined=True)
    prepared = prepare(body, Frame("tangent", 10), PORT, PORT)  # no rigid-body mode of all
    validate_prepared(prepared, deep=False)  # its rows are not zero: only the deep check sees it
    with pytest.raises(UserError) as info:
        validate_prepared(prepared)
    message = str(info.value)
    assert "the held body still has 3 mechanisms" in message
    assert "node 130 is free" in message or "node 140 is free" in message
    assert "nodes 130, 140 (2 nodes) are not joined to the rest of the body (2 separate parts)" in (
        message
    )


def test_a_dof_without_stiffness_is_named():
    body = _loose(spring_lattice(), joined=False)
    prepared = prepare(body, Frame("tangent", 10), PORT, PORT)
    with pytest.raises(UserError, match="translation x at node 130 is free: the dof has no "
                       r"stiffness \(3 such dofs"):  # fmt: skip
        validate_prepared(prepared, deep=False)


def test_a_dof_without_mass_and_stiffness_is_removed_and_the_rest_named():
    """The dangling dof is removed like Nastran's AUTOSPC (issue #27, item 3); the dofs of
    that node with mass but without stiffness are still named."""
    body = _loose(spring_lattice(), joined=False)
    m = body.mass.tolil()
    i = body.dofs.index(130, "uy")
    m[i, i] = 0.0
    prepared = prepare(replace(body, mass=m.tocsr()), Frame("tangent", 10), PORT, PORT)
    assert "node 130 uy: no mass and no stiffness (removed like Nastran's AUTOSPC)" in (
        prepared.notes
    )
    with pytest.raises(UserError, match="translation x at node 130 is free: the dof has no "
                       r"stiffness \(2 such dofs"):  # fmt: skip
        validate_prepared(prepared, deep=False)


def test_free_body_has_exactly_six_rigid_body_modes():
    truss = space_truss()
    prepared = prepare(truss, Frame("buckens"), [Port.parse(1, "ux")], [Port.parse(1, "ux")])
    report = validate_prepared(prepared)
    assert report.facts["zero_eigenvalues"] == 6
    assert "six rigid-body modes, no mechanism" in report.checks


def test_free_body_with_a_seventh_zero_mode_names_the_mechanism():
    truss = space_truss()
    loose = _loose(replace(truss, constraints=ConstraintEquations.empty(truss.n_dof)), joined=True)
    prepared = prepare(loose, Frame("buckens"), [Port.parse(1, "ux")], [Port.parse(1, "ux")])
    with pytest.raises(UserError) as info:
        validate_prepared(prepared)
    message = str(info.value)
    assert "the free body has 9 zero eigenfrequencies instead of 6 rigid-body modes" in message
    assert "nodes 130, 140 (2 nodes) are not joined to the rest of the body" in message


def test_rack_beams_tangent_and_buckens_pass_with_their_known_lowest_modes():
    body = build_example("rack-beams")
    ports = [Port.parse(1, "ux uy uz")]
    held = validate_prepared(prepare(body, Frame("tangent", 2), ports, ports))
    lowest_hz = np.sqrt(held.facts["lowest_eigenvalues"][0]) / (2 * np.pi)
    assert lowest_hz == pytest.approx(41.57, abs=0.01)  # README: 41.57 Hz with node 2 clamped
    free = validate_prepared(prepare(body, Frame("buckens"), ports, ports))
    assert free.facts["zero_eigenvalues"] == 6
    first_elastic = np.sqrt(free.facts["lowest_eigenvalues"][6]) / (2 * np.pi)
    assert first_elastic == pytest.approx(105.3, abs=0.1)


def test_job_level_checks(tmp_path):
    from pymorembs.io.native import write_body_h5
    from pymorembs.job.schema import load_job

    body = spring_lattice()
    write_body_h5(body.with_fixed(body.dofs.of_node(20)), tmp_path / "model.h5")
    text = """
[model]
file = "model.h5"
[frame]
node = 10
[[inputs]]
node = {node}
directions = "ux"
[band]
f_max_hz = 100
[[reduction]]
method = "modal"
order = {order}
"""
    job_path = tmp_path / "job.toml"

    def check(node: int, order: int) -> None:
        job_path.write_text(text.format(node=node, order=order))
        job = load_job(job_path)
        from pymorembs.job.run import prepare_and_validate

        prepare_and_validate(job, deep=False)

    check(60, 5)  # fine
    with pytest.raises(UserError, match=r"job\.toml: \[\[inputs\]\] #1: node 20 ux is a fixed"):
        check(20, 5)
    with pytest.raises(UserError, match=r"#1\.order: 27 is not below the 27 independent dofs"):
        check(60, 27)
    with pytest.raises(UserError, match="every input acts on a fixed dof of the frame"):
        check(10, 5)


def test_a_stiffness_matrix_given_as_the_mass_is_refused():
    """Issue #16: the stiffness file given as the mass file ran to exit 0. The same matrix (or a
    multiple) is refused, and so is a free body whose "mass" matrix, like its stiffness, gives
    a rigid translation no energy (an independent stiffness-like matrix: springs between
    random node pairs, written here)."""
    from pymorembs.preparation.validation import validate_body

    lattice = spring_lattice()
    for factor in (1.0, 3.0):
        with pytest.raises(UserError, match="the mass matrix is the stiffness matrix"):
            validate_body(replace(lattice, mass=factor * lattice.stiffness))
    truss = space_truss()
    n_nodes = truss.node_ids.size
    rng = np.random.default_rng(1)
    pairs = rng.integers(0, n_nodes, size=(3 * n_nodes, 2))
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    springs = np.zeros((truss.n_dof, truss.n_dof))
    for a, b in pairs:
        d = np.zeros(n_nodes)
        d[a], d[b] = 1.0, -1.0
        springs += rng.uniform(1.0, 2.0) * np.kron(np.outer(d, d), np.eye(3))
    assert np.allclose(springs @ np.tile(np.eye(3), (n_nodes, 1)), 0.0)  # no rigid energy
    with pytest.raises(UserError, match=r"rigid translation in x no mass .*really the stiffness"):
        validate_body(replace(truss, mass=sp.csr_matrix(springs)))
    validate_body(truss)  # its own mass passes
    validate_body(lattice)
