"""Checks of a model before anything expensive is computed.

Run for every job (the job layer adds the checks of what the job asks: its nodes exist, its
orders fit the model; ``pymorembs info`` runs :func:`validate_body`):

:func:`validate_body` -- on the body as read (interfaces added), O(nnz):

* matrix sizes agree with the dof table, entries are finite, node ids are unique (also enforced
  by :class:`~pymorembs.body.ElasticBody`);
* ``M``, ``K`` and ``D`` are symmetric within :data:`SYMMETRY_TOL` of their largest entry (the
  worst pair is named by node and direction, with its relative size);
* ``M`` and ``K`` have no negative diagonal entry and no negative 2x2 principal minor
  (``a_ij^2 <= a_ii a_jj``): both prove a matrix indefinite;
* ``M`` is no stiffness matrix: not proportional to ``K``, and it has mass in every rigid
  translation that ``K`` lets move freely;
* no dependent dof of a constraint equation is also fixed;
* the mass matrix, the dof map and the coordinates fit the stiffness matrix
  (:mod:`~pymorembs.preparation.consistency`: rigid-body mass, M's pattern within K's, the map
  proved by the rigid-body fields, the coordinates' length unit, the material of a solid mesh,
  the centre of gravity and inertia within the node cloud); ``facts["consistency"]``.

:func:`validate_prepared` -- on the system of the independent dofs (after frame and
elimination, whose structural rigid-body check runs in :func:`~pymorembs.preparation.prepare`):

* no independent dof without mass and stiffness (dangling) or without stiffness (free);
* with ``deep=True`` (the default of a job run):

  - 30 Lanczos steps on ``M`` (matrix-vector products only): a negative Rayleigh quotient
    proves ``M`` indefinite;
  - one sparse factorization of ``K + sigma M`` with ``sigma`` = :data:`SHIFT` (held body) or
    :data:`FREE_SHIFT` (free body) times ``sigma_typ = median(diag K / diag M)``, with PARDISO
    where installed: its inertia proves ``K + sigma M`` positive definite (SuperLU gives the
    inertia only when its pivoting stayed symmetric). Where PARDISO factorizes ``K`` of a held
    body, ``K`` itself is tried first (``sigma = 0``): when every pivot is positive and none was
    perturbed that proves it positive definite, and a job's later factorizations of ``K`` take
    this factor (:func:`_definite_stiffness`); otherwise the shifted matrix is factorized;
  - four steps of block inverse iteration with that factor and a Rayleigh-Ritz step: the
    lowest eigenvalues of ``(K, M)``. A held body (tangent frame, the model's supports) must
    have none near zero (:data:`MECHANISM_TOL`), a free body (Buckens) exactly six; a
    mechanism is named by the node and direction where it moves most and, if no stiffness
    joins it to the rest, by the nodes of that separate part.

Errors: a mistake in the input is a :class:`~pymorembs.errors.UserError` (exit code 2); an
indefinite mass or stiffness matrix a :class:`~pymorembs.errors.NumericalError` (exit code 3).
The deep check costs about one sparse factorization.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from pymorembs.body import DIRECTIONS, ElasticBody
from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.rounding import COMPUTATION_EPS, relative_rounding
from pymorembs.preparation.consistency import check_consistency

if TYPE_CHECKING:  # pragma: no cover
    from pymorembs.preparation import PreparedModel

#: Largest accepted ``|a_ij - a_ji|`` relative to the largest ``|a_ij|`` of the matrix.
SYMMETRY_TOL = 1e-8
#: A diagonal entry below ``-NEGATIVE_DIAGONAL_TOL * max |diag|`` makes a matrix indefinite.
NEGATIVE_DIAGONAL_TOL = 1e-12
#: Relative excess of ``a_ij^2`` over ``a_ii a_jj`` above which a 2x2 minor is negative.
MINOR_TOL = 1e-8
#: ``||M - c K||_F <= SAME_MATRIX_TOL ||M||_F`` (best ``c``): the mass matrix is a stiffness.
SAME_MATRIX_TOL = 1e-9
#: ``|r^T A r| <= RIGID_ENERGY_TOL sum |diag A|`` over a rigid translation ``r``: ``A`` does
#: not resist (K) or carry mass in (M) that translation (a real M: its total mass, of the order
#: of the diagonal; a free-free K: rounding, also of a file of 8 digits).
RIGID_ENERGY_TOL = 1e-6
#: ``sigma_typ = median(diag K / diag M)`` is a typical element-level ``omega^2``. A held body is
#: factorized as ``K + SHIFT * sigma_typ * M`` (positive definite for PSD K and M, also with a
#: mechanism), a free body as ``K + sigma_typ * M``.
SHIFT = 1e-12
#: The shift of a free body (Buckens frame), larger: rounding in very stiff parts (light stiff
#: beams, E = 1e18) moves its rigid-body modes off zero by up to ~1e-13 sigma_typ.
FREE_SHIFT = 1e-10
#: Rigid-body modes of a free body.
RIGID_MODES = 6
#: An eigenvalue of ``(K, M)`` below ``MECHANISM_TOL * sigma_typ`` is a mechanism. Rounding puts
#: a true mechanism at ~1e-16 sigma_typ; the lowest physical mode of the rack models lies at
#: 1e-10 to 1e-9 sigma_typ (a 10 m steel tube on a 1 mm mesh: ~1e-13).
MECHANISM_TOL = 1e-14
#: An eigenvalue of ``(K, M)`` below ``-NEGATIVE_EIGENVALUE_TOL * sigma_typ`` is no rounding.
NEGATIVE_EIGENVALUE_TOL = 1e-12
#: For a file whose entries are rounded (``eps`` of :func:`~pymorembs.linalg.rounding.
#: relative_rounding` above the computation's), the shift and the two tolerances above are at
#: least ``ROUNDING_FACTOR * eps``: such rounding moves eigenvalues by that much of sigma_typ.
ROUNDING_FACTOR = 100.0
#: Lanczos steps of the search for a negative Rayleigh quotient of ``M``.
LANCZOS_STEPS = 30
#: Block size and steps of the inverse iteration that looks for mechanisms.
INVERSE_BLOCK = 4
INVERSE_STEPS = 4
#: Names of the rigid-body directions for messages.
_MOTION = {
    "ux": "translation x",
    "uy": "translation y",
    "uz": "translation z",
    "rx": "rotation about x",
    "ry": "rotation about y",
    "rz": "rotation about z",
}


@dataclass
class ValidationReport:
    """What the checks found.

    Attributes
    ----------
    checks : list of str
        Names of the checks that ran and passed.
    facts : dict
        Numbers found on the way (worst relative asymmetry per matrix, inertia, lowest
        eigenvalues, the shift ``sigma``), JSON-ready.
    warnings : list of str
        Facts the user should know that do not stop the run.
    seconds : float
        Wall time of the checks, s.
    """

    checks: list[str] = field(default_factory=list)
    facts: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def merge(self, other: ValidationReport) -> ValidationReport:
        """Both reports in one (``other`` after ``self``)."""
        return ValidationReport(
            self.checks + other.checks,
            {**self.facts, **other.facts},
            self.warnings + other.warnings,
            self.seconds + other.seconds,
        )

    def as_dict(self) -> dict[str, Any]:
        """The report as a JSON-ready dictionary."""
        return {
            "checks": list(self.checks),
            "facts": dict(self.facts),
            "warnings": list(self.warnings),
            "seconds": self.seconds,
        }


def _label(body: ElasticBody, index: int) -> str:
    """``node 12 uz`` for an equation index."""
    return f"node {int(body.dofs.nodes[index])} {DIRECTIONS[int(body.dofs.directions[index])]}"


def worst_asymmetry(matrix: sp.spmatrix) -> tuple[float, int, int]:
    """The largest ``|a_ij - a_ji|`` relative to ``max |a|``, and its (row, column).

    O(nnz): one sparse transpose and subtraction. Returns ``(0.0, -1, -1)`` for a symmetric or
    empty matrix.
    """
    a = sp.csr_matrix(matrix)
    scale = float(np.max(np.abs(a.data))) if a.nnz else 0.0
    if scale == 0.0:
        return 0.0, -1, -1
    diff = sp.coo_matrix(a - a.T)
    if diff.nnz == 0:
        return 0.0, -1, -1
    k = int(np.argmax(np.abs(diff.data)))
    return float(abs(diff.data[k]) / scale), int(diff.row[k]), int(diff.col[k])


def worst_principal_minor(
    matrix: sp.spmatrix, tol: float = MINOR_TOL
) -> tuple[int, int, float, float] | None:
    """The stored entry that most violates ``a_ij^2 <= a_ii a_jj``, or None.

    Every 2x2 principal minor of a positive semidefinite matrix is >= 0, so a violation proves
    the matrix indefinite. O(nnz). Returns ``(i, j, a_ij, sqrt(a_ii a_jj))``; violations
    below ``tol`` relative to ``a_ij^2`` are rounding and ignored.
    """
    upper = sp.coo_matrix(sp.triu(matrix, k=1))
    if upper.nnz == 0:
        return None
    diagonal = sp.csr_matrix(matrix).diagonal()
    square = upper.data**2
    product = diagonal[upper.row] * diagonal[upper.col]
    excess = np.zeros_like(square)
    stored = square > 0
    excess[stored] = (square[stored] - product[stored]) / square[stored]
    k = int(np.argmax(excess))
    if excess[k] <= tol:
        return None
    bound = float(np.sqrt(max(product[k], 0.0)))
    return int(upper.row[k]), int(upper.col[k]), float(upper.data[k]), bound


def validate_body(body: ElasticBody) -> ValidationReport:
    """O(nnz) checks of a body as read.

    Parameters
    ----------
    body : ElasticBody
        The body (with its interface nodes added).

    Returns
    -------
    ValidationReport

    Raises
    ------
    UserError
        Sizes that disagree with the dof table, a non-symmetric matrix, a constraint equation
        naming a fixed dependent dof, a mass matrix that is a stiffness matrix.
    NumericalError
        A negative diagonal entry of ``M`` or ``K`` (the matrix is indefinite).
    """
    start = time.perf_counter()
    report = ValidationReport()
    model = "[model]: "
    n = body.n_dof
    matrices = {"mass": body.mass, "stiffness": body.stiffness}
    if body.damping_matrix is not None:
        matrices["damping"] = body.damping_matrix
    for name, matrix in matrices.items():
        if matrix.shape != (n, n):  # ElasticBody refuses this already; kept for other callers
            raise UserError(f"{model}{name} matrix has shape {matrix.shape}, dof table has {n}")
        if not np.all(np.isfinite(sp.csr_matrix(matrix).data)):
            raise UserError(f"{model}{name} matrix has NaN or infinite entries")
    report.checks.append("sizes and finite entries")
    if np.unique(body.node_ids).size != body.node_ids.size:
        raise UserError(f"{model}node ids are not unique")
    report.checks.append("unique node ids")

    asymmetry = {}
    for name, matrix in matrices.items():
        value, row, col = worst_asymmetry(matrix)
        asymmetry[name] = value
        if value > SYMMETRY_TOL:
            a = sp.csr_matrix(matrix)
            raise UserError(
                f"{model}the {name} matrix is not symmetric: entry ({_label(body, row)}, "
                f"{_label(body, col)}) = {a[row, col]:.6g} but its mirror = {a[col, row]:.6g} "
                f"(difference {value:.1e} of the largest entry); export the full symmetric "
                "matrix (both triangles agree, or one triangle only)"
            )
    report.facts["relative_asymmetry"] = asymmetry
    report.checks.append("symmetric matrices")

    for name in ("mass", "stiffness"):
        diagonal = getattr(body, name).diagonal()
        if diagonal.size == 0:
            continue
        worst = int(np.argmin(diagonal))
        tol = NEGATIVE_DIAGONAL_TOL * float(np.max(np.abs(diagonal)))
        if diagonal[worst] < -tol:
            count = int(np.count_nonzero(diagonal < -tol))
            raise NumericalError(
                f"{model}the {name} matrix is indefinite: {count} negative diagonal "
                f"entr{'ies' if count > 1 else 'y'}, the most negative at {_label(body, worst)} "
                f"({diagonal[worst]:.6g}); check the exported matrix and its units"
            )
    report.checks.append("non-negative diagonals of M and K")
    for name in ("mass", "stiffness"):
        worst = worst_principal_minor(getattr(body, name))
        if worst is not None:
            row, col, value, bound = worst
            raise NumericalError(
                f"{model}the {name} matrix is not positive semidefinite: |entry "
                f"({_label(body, row)}, {_label(body, col)})| = {abs(value):.6g} exceeds "
                f"sqrt(product of the diagonal entries) = {bound:.6g} (a 2x2 principal minor "
                "is negative); check the exported matrix"
            )
    report.checks.append("2x2 principal minors of M and K")
    _check_mass_is_a_mass(body, model)
    report.checks.append("M is no stiffness matrix (not proportional to K, moves rigidly)")

    constraints = body.constraints
    if constraints is not None and len(constraints):
        both = np.intersect1d(constraints.dependent, body.fixed)
        if both.size:
            raise UserError(
                f"{model}{_label(body, int(both[0]))} is both fixed and the dependent dof of a "
                "constraint equation; remove one of the two"
            )
        if constraints.matrix.shape[1] != n:
            raise UserError(f"{model}constraint equations do not match the dof table")
    report.checks.append("constraint equations")
    _check_consistency(body, report)

    report.seconds = time.perf_counter() - start
    return report


def _check_consistency(body: ElasticBody, report: ValidationReport) -> None:
    """:func:`~pymorembs.preparation.consistency.check_consistency` into the report: its facts as
    ``facts["consistency"]``, its warnings with the report's."""
    consistency = check_consistency(body)
    report.facts["consistency"] = consistency
    report.warnings.extend(consistency["warnings"])
    report.checks.append(
        f"consistency of M, the dof map and the coordinates with K ({consistency['map']['status']})"
    )


def _check_mass_is_a_mass(body: ElasticBody, model: str) -> None:
    """A :class:`UserError` when the mass matrix is really a stiffness matrix. O(nnz).

    Two signs, neither possible for a mass matrix: ``M`` is proportional to ``K`` (within
    :data:`SAME_MATRIX_TOL`; e.g. the stiffness file given twice), or a rigid translation
    ``r`` (1 on every dof of one direction) that ``K`` lets move freely (``r^T K r`` at
    rounding level, :data:`RIGID_ENERGY_TOL` of ``sum |diag|`` over those dofs) has no kinetic
    energy either (``r^T M r``, the body's total mass in that direction, as small).
    """
    m, k = sp.csr_matrix(body.mass), sp.csr_matrix(body.stiffness)
    k_norm2 = float(k.multiply(k).sum())
    if k_norm2 > 0 and m.nnz:
        scale = float(m.multiply(k).sum()) / k_norm2  # least squares M ~ scale K
        gap = sp.csr_matrix(m - scale * k)
        m_norm = float(np.sqrt(m.multiply(m).sum()))
        if np.sqrt(float(gap.multiply(gap).sum())) <= SAME_MATRIX_TOL * m_norm:
            times = "" if scale == 1.0 else f" times {scale:.6g}"
            raise UserError(
                f"{model}the mass matrix is the stiffness matrix{times}: the stiffness file "
                "given as the mass file? (every eigenfrequency would be the same)"
            )
    directions = body.dofs.directions
    m_diag, k_diag = m.diagonal(), k.diagonal()
    for code in range(3):
        r = (directions == code).astype(float)
        m_scale = float(np.abs(m_diag) @ r)
        k_scale = float(np.abs(k_diag) @ r)
        if m_scale == 0 or k_scale == 0:
            continue
        free = abs(float(r @ (k @ r))) <= RIGID_ENERGY_TOL * k_scale
        massless = abs(float(r @ (m @ r))) <= RIGID_ENERGY_TOL * m_scale
        if free and massless:
            raise UserError(
                f"{model}the mass matrix gives a rigid translation in {'xyz'[code]} no mass "
                f"(r^T M r = {float(r @ (m @ r)):.3g} against {m_scale:.3g} on its diagonal), "
                "like the stiffness matrix: is the mass file really the stiffness file?"
            )


def validate_prepared(prepared: PreparedModel, deep: bool = True) -> ValidationReport:
    """Checks of the system of the independent dofs, before any reduction.

    Parameters
    ----------
    prepared : PreparedModel
        The body in its frame, eliminated.
    deep : bool
        Also factorize ``K + sigma M`` once (inertia) and, for a held body, look for a mechanism
        among the lowest eigenvalues of ``(K, M)`` (a few shift-invert Lanczos steps).

    Returns
    -------
    ValidationReport

    Raises
    ------
    UserError
        A dangling dof, a dof without stiffness or a mechanism of a held body.
    NumericalError
        ``K + sigma M`` is indefinite (``M`` or ``K`` is not positive semidefinite) or
        singular.
    """
    start = time.perf_counter()
    report = ValidationReport()
    system = prepared.system
    body = prepared.body
    independent = prepared.elimination.independent
    n = system.order
    free_body = system.rigid_modes is not None  # Buckens: rigid-body modes are expected
    where = "[frame]: "

    stiffness = sp.csr_matrix(system.stiffness)
    mass = sp.csr_matrix(system.mass)
    k_rows = np.asarray(abs(stiffness).sum(axis=1)).ravel()
    m_rows = np.asarray(abs(mass).sum(axis=1)).ravel()
    dangling = np.flatnonzero((k_rows == 0) & (m_rows == 0))
    if dangling.size:
        raise UserError(
            f"{where}{_label(body, int(independent[dangling[0]]))} has neither mass nor "
            f"stiffness ({dangling.size} such dof{'s' if dangling.size > 1 else ''}): a node "
            "without elements; remove it or fix it"
        )
    loose = np.flatnonzero(k_rows == 0)
    if loose.size:
        first = int(independent[loose[0]])
        direction = DIRECTIONS[int(body.dofs.directions[first])]
        raise UserError(
            f"{where}{_MOTION[direction]} at node {int(body.dofs.nodes[first])} is free: the dof "
            f"has no stiffness ({loose.size} such dof{'s' if loose.size > 1 else ''}; a node "
            "without elements, or rotational dofs of solid elements); fix it or connect it"
        )
    report.checks.append("every independent dof has stiffness")

    if deep and n > 1:
        _inertia_and_mechanisms(prepared, mass, stiffness, free_body, where, report)
    report.seconds = time.perf_counter() - start
    return report


def _inertia_and_mechanisms(
    prepared: PreparedModel,
    mass: sp.csr_matrix,
    stiffness: sp.csr_matrix,
    free_body: bool,
    where: str,
    report: ValidationReport,
) -> None:
    """One factorization of ``K + sigma M``: inertia, then the lowest eigenvalues of (K, M)."""
    from pymorembs.linalg.backends import available_backends, factorize

    body = prepared.body
    independent = prepared.elimination.independent
    k_diag, m_diag = stiffness.diagonal(), mass.diagonal()
    massive = m_diag > 0
    if not np.any(massive):
        raise NumericalError(f"{where}the mass matrix of the independent dofs is zero")
    typical = float(np.median(k_diag[massive] / m_diag[massive]))
    if not typical > 0:
        typical = float(np.max(np.abs(k_diag))) / float(np.max(m_diag))
    # a file rounded to a few digits (a 10-digit punch, single precision) moves eigenvalues by
    # up to ROUNDING_FACTOR * eps * sigma_typ: rigid-body modes of a free aircraft at -40
    # (rad/s)^2 (1 Hz); the tolerances grow with it
    eps, _ = relative_rounding(body.stiffness, body.mass, body.precision)
    noise = ROUNDING_FACTOR * eps if eps > COMPUTATION_EPS else 0.0
    sigma = max(FREE_SHIFT if free_body else SHIFT, noise) * typical
    negative_tol = max(NEGATIVE_EIGENVALUE_TOL, noise)
    mechanism_tol = max(MECHANISM_TOL, noise)
    report.facts["sigma_typical"] = typical
    report.facts["sigma"] = sigma
    _mass_rayleigh_check(prepared, mass, where, report)
    factor = None if free_body else _definite_stiffness(stiffness)
    if factor is not None:  # K itself is positive definite: no shift needed
        shifted, sigma = stiffness, 0.0
        report.facts["sigma"] = sigma
    else:
        shifted = sp.csc_matrix(stiffness + sigma * mass)
        backend = "pardiso" if "pardiso" in available_backends() else None  # it reports inertia
        try:
            factor = factorize(shifted, symmetric=True, backend=backend)
        except NumericalError:
            raise NumericalError(
                f"{where}K + sigma M is singular (sigma = {sigma:.3g}): a mechanism without "
                "mass, or a mass or stiffness matrix that is not positive semidefinite"
            ) from None
    report.facts["factorization_backend"] = factor.backend
    report.facts["factorization_s"] = factor.seconds
    inertia = _inertia(factor)
    if inertia is not None:
        report.facts["inertia"] = {"positive": inertia[0], "negative": inertia[1]}
        if inertia[1] > 0:
            raise NumericalError(
                f"{where}K + sigma M has {inertia[1]} negative eigenvalue"
                f"{'s' if inertia[1] > 1 else ''} (sigma = {sigma:.3g}): the mass or stiffness "
                "matrix is not positive semidefinite; check the exported matrices"
            )
        report.checks.append("M and K positive semidefinite (inertia)")
    expected = RIGID_MODES if free_body else 0  # a free body moves in six ways, a held one not
    lam, vectors = _lowest_eigenpairs(
        factor, shifted, mass, sigma, INVERSE_BLOCK + expected, INVERSE_STEPS + bool(expected)
    )
    if lam is None:
        report.warnings.append("the mechanism check could not separate the lowest modes")
        return
    report.facts["lowest_eigenvalues"] = lam.tolist()
    if lam[0] < -negative_tol * typical:  # found even without the inertia
        top = int(independent[int(np.argmax(np.abs(vectors[:, 0])))])
        raise NumericalError(
            f"{where}the stiffness matrix is not positive semidefinite: (K, M) has the "
            f"eigenvalue {lam[0]:.3g}, a motion largest at {_label(body, top)}; check the "
            "exported matrices"
        )
    zero = np.flatnonzero(lam < mechanism_tol * typical)
    report.facts["zero_eigenvalues"] = int(zero.size)
    if free_body and zero.size > expected:
        part = _separate_part(prepared, stiffness, None)
        top = int(np.argmax(np.abs(vectors[:, zero[-1]])))
        index = int(independent[top])
        direction = DIRECTIONS[int(body.dofs.directions[index])]
        detail = part or f"{_MOTION[direction]} at node {int(body.dofs.nodes[index])} is free"
        raise UserError(
            f"{where}the free body has {zero.size} zero eigenfrequencies instead of "
            f"{expected} rigid-body modes: {detail} (a mechanism); connect or fix that part"
        )
    if not free_body and zero.size:
        vector = vectors[:, zero[0]]
        top = int(np.argmax(np.abs(vector)))
        index = int(independent[top])
        direction = DIRECTIONS[int(body.dofs.directions[index])]
        part = _separate_part(prepared, stiffness, top)
        raise UserError(
            f"{where}the held body still has {zero.size} mechanism"
            f"{'s' if zero.size > 1 else ''} (lowest eigenvalue {lam[0]:.3g}, a zero "
            f"eigenfrequency): {_MOTION[direction]} at node {int(body.dofs.nodes[index])} is "
            f"free{'; ' + part if part else ''}; connect or fix that part"
        )
    report.checks.append(
        "six rigid-body modes, no mechanism" if free_body else "no mechanism (lowest eigenvalues)"
    )


def _definite_stiffness(stiffness: sp.csr_matrix) -> Any:
    """``K`` of a held body factorized by PARDISO when it is positive definite (every pivot
    positive, none perturbed), else None (then ``K + sigma M`` is factorized).

    Where PARDISO is the backend :func:`~pymorembs.linalg.backends.factorize` chooses for ``K``
    and a job's :func:`~pymorembs.linalg.shared_factorizations` is open, the factor is kept there
    under the key of ``K``: the static solves of the inertia loads, the reference's 0 Hz and
    every expansion point at 0 Hz take it instead of factorizing ``K`` again (with a shift
    ``K + 1e-12 sigma_typ M`` no other step could use it).
    """
    from pymorembs.linalg.backends import PardisoFactor, chosen_backend
    from pymorembs.linalg.shared_factors import active_shared_factors

    if chosen_backend(stiffness) != "pardiso":
        return None
    terms = [(1.0, stiffness)]
    shared = active_shared_factors()
    key = shared.key(terms, True, None) if shared is not None else None
    found = shared.get(key) if shared is not None else None
    try:
        factor = found if found is not None else PardisoFactor(stiffness, True)
    except NumericalError:  # singular: the shifted factorization names the problem
        return None
    if factor.perturbed_pivots or tuple(factor.inertia) != (stiffness.shape[0], 0):
        return None
    if shared is not None and found is None:
        shared.put(key, terms, factor)
    return factor


def _separate_part(
    prepared: PreparedModel, stiffness: sp.csr_matrix, dof: int | None
) -> str | None:
    """Name a part of the body that no stiffness joins to the rest, if there is one.

    The parts are the connected components of the node graph of ``K*`` (two nodes are joined
    when a stiffness term couples any of their independent dofs; constraint equations are
    already folded into ``K*``), O(nnz). ``dof`` given: the part that contains it, unless
    it is the largest; else the smallest part. None if the body is one part.
    """
    from scipy.sparse.csgraph import connected_components

    dof_nodes = prepared.body.dofs.nodes[prepared.elimination.independent]
    node_ids, node_of_dof = np.unique(dof_nodes, return_inverse=True)
    incidence = sp.csr_matrix(
        (np.ones(dof_nodes.size), (np.arange(dof_nodes.size), node_of_dof)),
        shape=(dof_nodes.size, node_ids.size),
    )
    graph = incidence.T @ (abs(stiffness) @ incidence)  # nodes joined by any stiffness term
    count, labels = connected_components(graph, directed=False)
    if count < 2:
        return None
    sizes = np.bincount(labels)
    if dof is not None:
        label = int(labels[node_of_dof[dof]])
        if sizes[label] == sizes.max():
            return None
    else:
        label = int(np.argmin(sizes))
    nodes = node_ids[labels == label]
    listed = ", ".join(str(int(n)) for n in nodes[:5]) + (", ..." if nodes.size > 5 else "")
    return (
        f"node{'s' if nodes.size > 1 else ''} {listed} ({nodes.size} node"
        f"{'s' if nodes.size > 1 else ''}) {'are' if nodes.size > 1 else 'is'} not joined to "
        f"the rest of the body ({count} separate parts)"
    )


def _mass_rayleigh_check(
    prepared: PreparedModel, mass: sp.csr_matrix, where: str, report: ValidationReport
) -> None:
    """A few Lanczos steps towards the smallest eigenvalue of ``M`` (matrix-vector products).

    A Ritz vector with a negative Rayleigh quotient ``x^T M x / x^T x`` proves ``M``
    indefinite; not finding one within the steps is no proof of the opposite (the inertia of
    ``K + sigma M`` barely sees ``M`` for a small ``sigma``).
    """
    n = mass.shape[0]
    if n < 3:
        return
    scale = float(np.max(np.abs(mass.diagonal()))) or 1.0
    x = _lanczos_smallest(mass, LANCZOS_STEPS)
    quotient = float(x @ (mass @ x)) / float(x @ x)
    report.facts["mass_rayleigh_min"] = quotient
    if quotient < -NEGATIVE_DIAGONAL_TOL * 1e2 * scale:
        top = int(prepared.elimination.independent[int(np.argmax(np.abs(x)))])
        raise NumericalError(
            f"{where}the mass matrix is indefinite: a motion largest at "
            f"{_label(prepared.body, top)} has negative kinetic energy (Rayleigh quotient "
            f"{quotient:.3g}, largest diagonal {scale:.3g}); check the exported mass matrix"
        )
    report.checks.append("M: no negative Rayleigh quotient (Lanczos)")


def _lowest_eigenpairs(
    factor: Any, shifted: sp.spmatrix, mass: sp.spmatrix, sigma: float, block: int, steps: int
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Approximate lowest eigenpairs of ``(K, M)`` by block inverse iteration with ``K + sigma M``.

    Each step multiplies the block by ``(K + sigma M)^-1 M``, which amplifies a mechanism
    (eigenvalue 0) over the lowest physical mode ``lambda_1`` by ``(lambda_1 + sigma) / sigma``
    (1,600 for rack-solid); a Rayleigh-Ritz step on the block then gives its eigenvalue to
    rounding. Returns ascending eigenvalues of ``(K, M)`` and their vectors, or ``(None, None)``
    if the block lost its mass (a degenerate projected mass matrix).
    """
    n = shifted.shape[0]
    block = min(block, n)
    x = np.random.default_rng(20261122).standard_normal((n, block))  # deterministic
    for _ in range(steps):
        x = factor.solve(mass @ x)
        x, _ = np.linalg.qr(x)
    a = x.T @ (shifted @ x)
    b = x.T @ (mass @ x)
    try:
        values, ritz = sla.eigh(0.5 * (a + a.T), 0.5 * (b + b.T))
    except (np.linalg.LinAlgError, ValueError):
        return None, None
    return values - sigma, x @ ritz


def _lanczos_smallest(matrix: sp.spmatrix, steps: int) -> np.ndarray:
    """The Ritz vector of the smallest Ritz value after ``steps`` Lanczos steps, shape (n,).

    Full reorthogonalisation (``steps`` is small); a deterministic start vector, so the check
    gives the same answer on every run.
    """
    n = matrix.shape[0]
    steps = min(steps, n)
    rows = np.zeros((steps, n))  # the Lanczos vectors as rows: contiguous slices
    q = np.linspace(1.0, 2.0, n)
    q /= np.linalg.norm(q)
    used = steps
    for j in range(steps):
        rows[j] = q
        w = matrix @ q
        w -= rows[: j + 1].T @ (rows[: j + 1] @ w)
        w -= rows[: j + 1].T @ (rows[: j + 1] @ w)  # twice is enough
        norm = float(np.linalg.norm(w))
        if j == steps - 1 or norm == 0.0:
            used = j + 1
            break
        q = w / norm
    basis = rows[:used].T
    projected = basis.T @ (matrix @ basis)
    _, ritz = np.linalg.eigh(0.5 * (projected + projected.T))
    return basis @ ritz[:, 0]


def _inertia(factor: Any) -> tuple[int, int] | None:
    """(positive, negative) eigenvalue counts of a symmetric factorized matrix, if known.

    PARDISO reports them; for SuperLU they are the signs of ``diag(U)`` when the row and column
    permutations agree (symmetric pivoting: ``P A P^T = L U`` with ``U = D L^T``).
    """
    inertia = getattr(factor, "inertia", None)
    if inertia is not None:
        return int(inertia[0]), int(inertia[1])
    lu = getattr(factor, "_lu", None)
    if lu is None or not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    diagonal = lu.U.diagonal()
    return int(np.count_nonzero(diagonal > 0)), int(np.count_nonzero(diagonal < 0))


__all__ = ["ValidationReport", "validate_body", "validate_prepared", "worst_asymmetry"]
