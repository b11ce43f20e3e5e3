"""Do the mass matrix, the dof map and the coordinates belong to the stiffness matrix?

Cheap checks of a body as read (a few sparse products with up to nine vectors, no
factorization), run by :func:`~pymorembs.preparation.validation.validate_body` for ``pymorembs
info`` and before every job. They catch what the checks of single matrices cannot: a mass
matrix in another dof order, a dof table shifted by a node, coordinates in mm with matrices in
SI units. A wrong map or a unit mix is a :class:`~pymorembs.errors.UserError` (exit 2) with one
line naming the likely cause; what is unusual but possible is a note; what cannot be proved is
said so (``map not proved``).

1. **Rigid-body mass** ``A = R^T M R`` (6 x 6, ``R`` the rigid-body fields about the centroid of
   the nodes). Every element whose shape functions hold rigid motion (solids, shells, beams,
   point masses) gives the mass matrix of a rigid body: translational block ``m I``, coupling
   block ``m skew(c)`` (``c`` the centre of gravity), an inertia tensor about ``c`` that is
   positive semidefinite and obeys the triangle inequality of principal moments. Unequal
   translational masses or a non-skew coupling are either directional masses (scalar or point
   masses in some directions, supports that remove some directions of a node) or a wrong map.
   The two differ node by node: the inertia force of a node under a rigid translation
   ``W_n[e, d] = (M t_d)_(n, e)`` is ``w_n I`` for every node of an assembled isotropic model
   (the integral of the node's shape function times the density), so directional masses make
   a few nodes anisotropic, a mass matrix in another dof order nearly all. More than
   :data:`WRONG_FRACTION` of the judged nodes anisotropic: a wrong map (exit 2); fewer: a note.
   Nodes next to supports and superelements (scalar coordinates; condensed boundary masses
   are not node-wise isotropic) are not judged node by node.
2. **M's pattern lies within K's**: every element with mass has stiffness between the same
   dofs, so an entry ``M_ij != 0`` where ``K`` stores nothing is a wrong order of ``M``. Not
   counted: rows of fixed dofs, of dofs without stiffness (nodes held by constraint equations),
   of scalar coordinates (a Craig-Bampton superelement couples them by mass only) and entries
   at the rounding level of their diagonal. More than :data:`PATTERN_WRONG_SHARE` of ``M``'s
   off-diagonal weight outside: exit 2. Judged on at most :data:`PATTERN_ROWS` rows.
3. **The dof map is proved by the rigid-body fields** row by row: ``(K r_j)_i`` must cancel to
   the rounding of the row's terms, ``|K r_j|_i <= CHECK_FACTOR (eps (|K| |r_j|)_i + delta
   (|K| 1_t)_i)`` with ``eps`` the rounding of the stored entries and ``delta`` that of the
   coordinates; the relative residual of a row is ``max_j |K r_j|_i / (|K| |r_j|)_i``. A row
   beside a support (a node with fixed or removed dofs: CalculiX ``*BOUNDARY``, Nastran a-set,
   Ansys with its clamp) carries the reaction and is excused when its node lies within
   :data:`REACH_FACTOR` times its own element reach of a support node; a row that a rigid
   translation leaves a force in is held by a spring to ground (or a support the files do not
   show) and is excused as well. What remains are rows that only the rotations fail. Three
   outcomes:

   - **map proved**: no such row, and at least :data:`MIN_PROOF_ROWS` rows fit all six fields
     (the excused rows are counted in the reason).
   - **map not proved** (a warning, the run goes on): some rows fail the rotations. A
     prestressed stiffness does that in legitimate models: the geometric stiffness of a stress
     ``sigma`` is ``sigma / E`` times an elastic stiffness and only the rotation of the stress
     is left over, so its relative residual stays below the strain ``sigma / E`` (< 1e-2 for
     any metal below yield; the blade and rack-beams with the geometric stiffness of a 1 %
     strain leave 7e-6). Springs between separated nodes that resist rigid rotation (scalar
     springs, bushings without offsets, rotational springs to ground) do it in a few rows with
     any residual up to 1.
   - **this map does not fit K** (exit 2) only where the evidence is unambiguous: more than
     :data:`WRONG_FRACTION` of the judged rows, away from the supports, keep
     :data:`WRONG_RESIDUAL` (0.1) or more of their terms -- ten times what any prestress
     leaves, while a node shifted against ``K`` leaves 0.1 to 1 (the CalculiX solids of the
     tests: median 0.16 to 0.27, 80 to 95 % of the rows) and a mass or stiffness matrix in
     another order fails the translations in most rows; or at :data:`MIN_DISPLACED_NODES` or
     more nodes both a translational and a rotational row keep that much while the
     translations fit: a node displaced against ``K``, whose force and moment balance both
     break. A spring acts on translations only or on rotations only of a node, a prestress
     leaves less, so this is a shifted map (rack-beams shifted by a node: 8 nodes at 0.5 to 1)
     and never a spring. A model made of springs that resist rigid rotation in most of its
     rows, or held by springs to ground of a tenth of its elements' stiffness at most of its
     nodes, cannot be told from a wrong map and is refused too (neither is a body for a
     multibody simulation).

   A reader of an FE program's element assembly (CalculiX, the Ansys ``.full`` with its
   archive) hands over what only it knows, the nodes next to the supports by their elements
   (:attr:`~pymorembs.body.ElasticBody.nodes_near_supports`): then exactly their rows are
   excused, and a row elsewhere that only the rotations fail refutes the map (exit 2), for
   such a stiffness holds no prestress and no spring that resists rigid rotation.

   Without coordinates, rotational fields or :data:`MIN_PROOF_ROWS` fitting rows the map is
   not proved. A real mechanism leaves all six fields in the null space (the map is proved); a
   wrong map of a free body does not (:func:`mechanism_or_map` tells ``info``).
4. **The coordinates' length unit**: with rotational dofs, the rotation fields weigh
   translations by the coordinates and rotations by 1, so only coordinates in K's length unit
   fit; the scales of :data:`~pymorembs.units.COORDINATE_SCALES` are tried with the same
   products. Without rotational dofs the rigid fields are scale-free: a mesh of solid elements
   gives the density ``mass / volume`` and ``E / rho``, which must be a material in some unit
   system (:func:`~pymorembs.units.material_systems`). A scale that fits where the given one
   does not: exit 2, "the coordinates look like mm while K and M are in m-kg-s-N ...".
   Without a mesh only the implied numbers of :mod:`pymorembs.units` remain (mass over the
   bounding box's volume), which a truss, a lattice of springs or a thin-walled part leave
   far below any material: a scale that makes them fit is a warning, never an error.
5. **Centre of gravity and inertia fit the node cloud**: ``c`` within the nodes' box widened by
   :data:`CG_MARGIN` times its largest side; the largest principal moment about ``c`` at most
   :data:`INERTIA_FACTOR` times ``m |extent|^2`` (point masses on the nodes give at most
   ``m |extent|^2``; rotary inertia of sections and point masses with offsets add a little).
   No lower bound can be proved (all mass may sit at the centre of gravity). Superelements
   (their nodes are the boundary only) are not judged.

Thresholds. Entries rounded to ``eps`` (``0.5 10^(1 - d)`` for ``d`` digits, at least
:data:`~pymorembs.linalg.rounding.COMPUTATION_EPS`) change a sum of terms by at most ``eps``
times the sum of their absolute values; :data:`CHECK_FACTOR` = 100 covers the computation's own
rounding over rows of up to 10^4 terms. Exact exports cancel to 1e-16..1e-13 of that scale, a
10-digit punch to 1e-10, single precision to 1e-8; a prestress leaves less than its strain
(item 3), a wrong map 0.1 to 1 -- the tests compare them on genuine files.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.body import DIRECTIONS, ElasticBody
from pymorembs.errors import UserError
from pymorembs.linalg.rounding import COMPUTATION_EPS, relative_rounding, significant_digits
from pymorembs.sparse_rows import abs_products
from pymorembs.units import (
    COORDINATE_SCALES,
    implied_numbers,
    length_unit_name,
    material_systems,
    units_of_numbers,
)

#: Multiple of the rounding bound a cancelling sum may reach (see the module docstring).
CHECK_FACTOR = 100.0
#: Relative level below which a cancellation always counts as rounding: matrices an FE program
#: computed by condensation (superelements, Guyan) lose digits to the condition number of the
#: eliminated part (a Craig-Bampton export of NX in binary doubles: rigid-body residuals up to
#: 2.5e-10, translational masses equal to 2e-12), while a wrong map or unit leaves 1e-4 to 1.
COMPUTED_FLOOR = 1e-8
#: Share of judged nodes (rigid-body mass) or rows (dof map) beyond which a wrong map is the
#: explanation: directional masses, supports and springs touch a minority of a model.
WRONG_FRACTION = 0.5
#: Share of the off-diagonal weight of ``M`` outside the pattern of ``K`` that proves another
#: order of ``M``: 0 for an assembled model; another order puts most of it outside.
PATTERN_WRONG_SHARE = 0.1
#: Rows of ``M`` on which its pattern is compared with ``K``'s (evenly spread).
PATTERN_ROWS = 20_000
#: Relative residual of a row far above what a prestress leaves (at most its strain, below
#: 1e-2 for any metal below yield) and below what a wrong map leaves (0.1 to 1): the third
#: band of item 3 counts the rows beyond it.
WRONG_RESIDUAL = 0.1
#: Nodes displaced against ``K`` (:func:`_displaced_nodes`) that prove a wrong map.
MIN_DISPLACED_NODES = 2
#: Fewest rows that must fit the six fields for the map to count as proved.
MIN_PROOF_ROWS = 6
#: A row next to a support is excused within this multiple of its node's element reach.
REACH_FACTOR = 1.5
#: The centre of gravity may lie outside the nodes' box by this share of its largest side.
CG_MARGIN = 0.5
#: Largest principal moment about the centre of gravity in units of ``m |extent|^2``.
INERTIA_FACTOR = 10.0
#: Wording of the direction codes.
_AXES = "xyz"


@dataclass(frozen=True)
class Rounding:
    """How precisely the body's numbers are stored.

    Attributes
    ----------
    entries : float
        Relative rounding of the entries of ``K`` and ``M``
        (:func:`~pymorembs.linalg.rounding.relative_rounding`).
    coordinates : float
        Absolute rounding of the coordinates (length unit): ``0.5 10^(1 - d)`` times the
        largest coordinate for ``d`` significant digits, else the computation's rounding.
    """

    entries: float
    coordinates: float

    @property
    def relative(self) -> float:
        """Relative size a cancelling sum may keep: :data:`CHECK_FACTOR` times ``entries``,
        at least :data:`COMPUTED_FLOOR`."""
        return max(CHECK_FACTOR * self.entries, COMPUTED_FLOOR)

    @property
    def length(self) -> float:
        """Length a position may be off: :data:`CHECK_FACTOR` times ``coordinates``."""
        return CHECK_FACTOR * self.coordinates


@dataclass(frozen=True)
class MapProof:
    """Whether the rigid-body fields prove the dof map (see the module docstring, item 3).

    Attributes
    ----------
    proved : bool
    residual : float or None
        Largest relative residual ``|K r|_i / (|K| |r|)_i`` over the rows that fit, or None.
    rows : int
        Rows judged (not fixed, reached by a field).
    near_supports : int
        Rows excused: next to a support, or held by a spring to ground (a translation leaves
        a force).
    unexplained : int
        Rows that the rotations fail (the translations fit) away from every support.
    reason : str
        One sentence for ``info`` and ``summary.json``.
    unexplained_residual : float or None
        Largest relative residual of the unexplained rows, or None.
    """

    proved: bool
    residual: float | None
    rows: int
    near_supports: int
    unexplained: int
    reason: str
    unexplained_residual: float | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {
            "status": "map proved" if self.proved else "map not proved",
            "residual": self.residual,
            "rows": self.rows,
            "rows_near_supports": self.near_supports,
            "rows_unexplained": self.unexplained,
            "unexplained_residual": self.unexplained_residual,
            "reason": self.reason,
        }


def check_consistency(body: ElasticBody) -> dict[str, Any]:
    """All checks of the module docstring on a body as read.

    Parameters
    ----------
    body : ElasticBody

    Returns
    -------
    dict
        JSON-ready facts: ``map`` (:meth:`MapProof.as_dict`), ``rigid_mass``,
        ``mass_pattern``, ``material``, ``notes`` (facts worth knowing, no mistake),
        ``warnings`` (possible mistakes that do not stop the run), ``seconds``.

    Raises
    ------
    UserError
        A mass matrix in another dof order, a dof map or coordinates that do not fit ``K``,
        coordinates in another length unit than the matrices (one line, ``[model]: ...``).
    """
    start = time.perf_counter()
    rounding = body_rounding(body)
    notes: list[str] = []
    warnings: list[str] = []
    facts: dict[str, Any] = {}
    facts["mass_pattern"] = check_mass_pattern(body, rounding)
    facts["rigid_mass"] = check_rigid_mass(body, rounding, notes, warnings)
    proof = check_map(body, rounding)
    facts["map"] = proof.as_dict()
    if not proof.proved and proof.unexplained:
        warnings.append(f"map not proved: {proof.reason}")
    facts["material"] = check_material(body, proof, warnings)
    check_node_cloud(body, facts["rigid_mass"])
    facts["notes"] = notes
    facts["warnings"] = warnings
    facts["seconds"] = time.perf_counter() - start
    return facts


def body_rounding(body: ElasticBody) -> Rounding:
    """The :class:`Rounding` of a body's entries and coordinates."""
    eps, _ = relative_rounding(body.stiffness, body.mass, body.precision)
    largest = float(np.abs(body.coordinates).max(initial=0.0))
    digits = significant_digits(body.coordinates) if body.has_coordinates else None
    relative = 0.5 * 10.0 ** (1 - digits) if digits is not None else COMPUTATION_EPS
    return Rounding(eps, relative * largest)


# ============================================================================ M within K
def check_mass_pattern(body: ElasticBody, rounding: Rounding) -> dict[str, Any]:
    """Item 2 of the module docstring: the share of ``M`` outside the pattern of ``K``.

    Returns
    -------
    dict
        ``rows`` judged, ``entries_outside`` and ``share_outside`` (of the off-diagonal weight
        of ``M`` on those rows).

    Raises
    ------
    UserError
        More than :data:`PATTERN_WRONG_SHARE` of the weight lies outside.
    """
    m, k = sp.csr_matrix(body.mass), sp.csr_matrix(body.stiffness)
    n = body.n_dof
    usable = np.diff(k.indptr) > 0
    usable &= ~body.dofs.scalar
    usable[body.fixed] = False
    rows = np.flatnonzero(usable)
    if rows.size > PATTERN_ROWS:
        rows = rows[np.linspace(0, rows.size - 1, PATTERN_ROWS).astype(np.int64)]
    if rows.size == 0:
        return {"rows": 0, "entries_outside": 0, "share_outside": None}
    mm = sp.coo_matrix(m[rows])
    diagonal = np.abs(m.diagonal())
    columns = mm.col
    row_dof = rows[mm.row]
    keep = (columns != row_dof) & usable[columns] & (mm.data != 0)
    noise = rounding.relative * np.sqrt(diagonal[row_dof] * diagonal[columns])
    keep &= np.abs(mm.data) > noise
    weight = float(np.abs(mm.data[keep]).sum())
    kk = sp.csr_matrix(k[rows])
    kk.sort_indices()
    stored = kk.indices.astype(np.int64) + n * np.repeat(np.arange(rows.size), np.diff(kk.indptr))
    wanted = mm.col.astype(np.int64) + n * mm.row.astype(np.int64)
    at = np.minimum(np.searchsorted(stored, wanted), max(stored.size - 1, 0))
    inside = stored[at] == wanted if stored.size else np.zeros(wanted.size, dtype=bool)
    outside = keep & ~inside
    share = float(np.abs(mm.data[outside]).sum()) / weight if weight > 0 else 0.0
    result = {"rows": int(rows.size), "entries_outside": int(outside.sum()), "share_outside": share}
    if share > PATTERN_WRONG_SHARE:
        first = int(np.flatnonzero(outside)[0])
        raise UserError(
            f"[model]: the mass matrix does not fit the stiffness matrix's dof order: "
            f"{share:.0%} of its off-diagonal weight couples dofs that K does not couple "
            f"({outside.sum()} entries on {rows.size} rows, first ({_label(body, row_dof[first])}"
            f", {_label(body, int(columns[first]))})); a mass matrix in another dof order "
            "(e.g. direction-major where K is node-major)? Export both in the same order"
        )
    return result


# ============================================================================ rigid mass
def check_rigid_mass(
    body: ElasticBody, rounding: Rounding, notes: list[str], warnings: list[str]
) -> dict[str, Any]:
    """Item 1 of the module docstring: the rigid-body mass matrix ``R^T M R``.

    Returns
    -------
    dict
        ``masses`` seen by the translations x, y, z (model mass unit), ``rigid`` (the 6 x 6 is
        that of a rigid body), and with it ``centre_of_gravity`` (length) and
        ``principal_inertia`` (mass length^2, ascending; NaN-free only with coordinates).

    Raises
    ------
    UserError
        Unequal translational masses or centres of gravity and anisotropic nodal masses at more
        than :data:`WRONG_FRACTION` of the judged nodes (a mass matrix in another dof order).
    """
    directions = body.dofs.directions
    present = [d for d in range(3) if np.any(directions == d)]
    result: dict[str, Any] = {"masses": None, "rigid": None}
    if len(present) < 3:
        axes = ", ".join(_AXES[d] for d in present) or "none"
        result["translations"] = axes
        return result  # a 1-D or 2-D model: nothing to compare
    m = sp.csr_matrix(body.mass)
    centre = _centroid(body)
    fields = body.rigid_body_modes(centre)
    inertia = fields.T @ (m @ fields)
    scale = np.abs(fields).T @ abs_products(m, fields)
    block = inertia[:3, :3]
    masses = np.diag(block).copy()
    result["masses"] = masses.tolist()
    mean = float(masses.mean())
    deviation = np.abs(block - mean * np.eye(3))
    unequal = bool(np.any(deviation > rounding.relative * scale[:3, :3].max()))
    located = _located(body)
    off_centre = False
    if located:
        coupling = inertia[3:, :3]
        allowed = rounding.relative * scale[3:, :3].max() + rounding.length * scale[:3, :3].max()
        off_centre = bool(np.abs(coupling + coupling.T).max() > allowed)
    if not unequal and not off_centre:
        result["rigid"] = True
        if located and mean > 0:
            _rigid_body_inertia(inertia, centre, mean, rounding.relative, scale, result, warnings)
        return result
    result["rigid"] = False
    anisotropic, judged, first = _anisotropic_nodes(body, m @ fields[:, :3], rounding.relative)
    result["anisotropic_nodes"] = anisotropic
    result["judged_nodes"] = judged
    seen = ", ".join(f"{v:.4g}" for v in masses)
    if judged and anisotropic > WRONG_FRACTION * judged:
        what = (
            f"the rigid translations in x, y, z see the masses {seen}"
            if unequal
            else "the rigid translations see the same mass but different centres of gravity "
            f"({_directional_centres(body, m, centre)})"
        )
        raise UserError(
            f"[model]: the mass matrix does not fit the dof table: {what}, and the mass of a "
            f"node differs between its directions at {anisotropic} of {judged} nodes; a mass "
            "matrix in another dof order than the stiffness matrix (e.g. direction-major where "
            "K is node-major)? Export both in the same order"
        )
    if anisotropic:
        where = f" at {anisotropic} of {judged} nodes (first node {first})"
    elif body.fixed.size:
        where = (
            f" on nodes next to the supports ({body.fixed.size} fixed dofs, whose mass the "
            "rigid translations do not move)"
        )
    else:
        where = " on nodes next to supports or of a superelement"
    notes.append(
        f"directional masses: the rigid translations in x, y, z see the masses {seen} (model "
        f"mass unit); the difference sits{where}: point or scalar masses in some directions, "
        "or supports that remove some directions"
    )
    return result


def _anisotropic_nodes(
    body: ElasticBody, forces: np.ndarray, relative: float
) -> tuple[int, int, int | None]:
    """Nodes whose rigid-translation inertia ``W_n`` is not ``w_n I``: (count, judged, first).

    ``forces = M T`` (n_dof, 3). Judged: nodes with ux uy uz and mass, away from supports
    (not coupled by ``M`` to a node with fixed or missing translations); none in a
    superelement (scalar coordinates).
    """
    if np.any(body.dofs.scalar):
        return 0, 0, None
    nodes = np.unique(body.dofs.nodes)
    rows = body.dofs.positions(nodes[:, None], np.arange(3)[None, :])
    complete = np.all(rows >= 0, axis=1)
    support = np.zeros(body.n_dof)
    support[_support_dofs(body)] = 1.0
    m = sp.csr_matrix(body.mass)
    near = abs_products(m, support) > 0
    rows = rows[complete]
    nodes = nodes[complete]
    ok = ~np.any(near[rows], axis=1)
    weights = forces[rows]  # (nodes, e, d)
    magnitude = abs_products(m, (body.dofs.directions < 3).astype(float))[rows].sum(axis=1)
    trace = np.trace(weights, axis1=1, axis2=2) / 3.0
    spread = np.linalg.norm(weights - trace[:, None, None] * np.eye(3), axis=(1, 2))
    judged = ok & (magnitude > 0)
    bad = judged & (spread > relative * magnitude)
    first = int(nodes[np.argmax(bad)]) if bad.any() else None
    return int(bad.sum()), int(judged.sum()), first


def _directional_centres(body: ElasticBody, m: sp.csr_matrix, centre: np.ndarray) -> str:
    """``x: (..), y: (..), z: (..)``: the centre of gravity each rigid translation sees."""
    positions = body.dof_positions()
    directions = body.dofs.directions
    parts = []
    for d in range(3):
        t = (directions == d).astype(float)
        row_mass = (m @ t) * t
        total = row_mass.sum()
        centre_d = (row_mass @ positions) / total if total else centre
        parts.append(f"{_AXES[d]}: ({', '.join(f'{v:.4g}' for v in centre_d)})")
    return "; ".join(parts)


def _rigid_body_inertia(
    inertia: np.ndarray,
    centre: np.ndarray,
    mass: float,
    relative: float,
    scale: np.ndarray,
    result: dict[str, Any],
    warnings: list[str],
) -> None:
    """Centre of gravity and principal moments from a rigid 6 x 6; a warning when the inertia
    tensor is no rigid body's (indefinite, or a principal moment above the sum of the others)."""
    coupling = inertia[3:, :3]  # m skew(c): rows rotations, columns translations
    c = np.array([coupling[2, 1], coupling[0, 2], coupling[1, 0]]) / mass
    skew = np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    about_cg = inertia[3:, 3:] - mass * skew.T @ skew
    principal = np.linalg.eigvalsh(0.5 * (about_cg + about_cg.T))
    result["centre_of_gravity"] = (centre + c).tolist()
    result["principal_inertia"] = principal.tolist()
    tol = relative * float(np.trace(scale[3:, 3:]))
    if principal[0] < -tol or principal[2] > principal[0] + principal[1] + tol:
        warnings.append(
            "the rigid-body inertia about the centre of gravity (principal moments "
            f"{', '.join(f'{v:.4g}' for v in principal)}) is no rigid body's (a principal "
            "moment is negative or exceeds the sum of the other two): a point mass's inertia "
            "entered wrongly, or rotational mass entries in another unit than the coordinates?"
        )


# ============================================================================ the dof map
def check_map(body: ElasticBody, rounding: Rounding) -> MapProof:
    """Items 3 and 4 of the module docstring: the rows fit the rigid-body fields.

    Raises
    ------
    UserError
        The rotations fit ``K`` only with scaled coordinates (a unit mix), or the evidence of a
        wrong map is unambiguous (the third band of item 3).
    """
    if not np.any(body.dofs.directions < 3):
        return MapProof(False, None, 0, 0, 0, "no translational dofs (scalar coordinates only)")
    if not _located(body):
        return MapProof(
            False,
            None,
            0,
            0,
            0,
            "no node coordinates: the translations alone cannot tell one node from another",
        )
    products = _RowProducts(body, rounding)
    fit = products.fit(1.0)
    failing, relative, judged = fit.failing, fit.relative, fit.judged
    n_judged = int(judged.sum())
    # a row next to a support carries its reaction; away from the supports, a row that a
    # translation leaves a force in is held by a spring to ground (or a support the files do
    # not show), one that only the rotations fail is unexplained
    if body.nodes_near_supports is None:
        away = failing & ~_near_supports(body, failing)
    else:  # the reader's elements name the rows next to a support
        away = failing & ~np.isin(body.dofs.nodes, body.nodes_near_supports)
    unexplained = away & ~fit.reactions
    n_unexplained = int(unexplained.sum())
    if n_unexplained and products.has_rotations:
        _check_coordinate_scale(body, products, n_unexplained, n_judged)
    if n_unexplained and body.nodes_near_supports is not None:
        _refuse_assembly_map(body, unexplained, relative, n_judged)
    large = away & (relative >= WRONG_RESIDUAL)
    displaced = _displaced_nodes(body, unexplained & large)
    if int(large.sum()) > WRONG_FRACTION * n_judged or displaced.size >= MIN_DISPLACED_NODES:
        _refuse_map(body, large, relative, n_judged, displaced)
    residual = float(relative[judged & ~failing].max()) if (judged & ~failing).any() else None
    fitting = int((judged & ~failing).sum())
    excused = int((failing & ~unexplained).sum())
    reactions = (
        f"; {excused} rows carry reactions of supports or springs to ground" if excused else ""
    )
    if n_unexplained:
        worst = int(np.argmax(np.where(unexplained, relative, -1.0)))
        reason = (
            f"in {n_unexplained} of {n_judged} rows the rigid translations fit but the "
            f"rotations leave a force, away from every support (largest at "
            f"{_label(body, worst)}, relative residual {relative[worst]:.1e}): a prestressed "
            "stiffness (its geometric stiffness leaves less than its strain, < 1e-2), springs "
            "between separated nodes that resist rigid rotation (scalar springs, bushings "
            "without offsets) or rotational springs to ground, or a dof table or coordinates "
            "wrong there"
        )
        worst_residual = float(relative[worst])
        return MapProof(False, residual, n_judged, excused, n_unexplained, reason, worst_residual)
    if fitting < MIN_PROOF_ROWS:
        reason = f"only {fitting} of {n_judged} rows can be checked away from the supports"
        return MapProof(False, residual, n_judged, excused, 0, reason)
    reason = (
        f"the six rigid-body fields leave no force in {fitting} of {n_judged} rows "
        f"(largest relative residual {residual:.1e}){reactions}"
    )
    return MapProof(True, residual, n_judged, excused, 0, reason)


def _refuse_assembly_map(
    body: ElasticBody, unexplained: np.ndarray, relative: np.ndarray, judged: int
) -> None:
    """The :class:`UserError` of a map that a reader's element assembly (no prestress, its
    supports named: ``ElasticBody.nodes_near_supports``) does not fit: rows away from the
    supports that only the rotations fail."""
    worst = int(np.argmax(np.where(unexplained, relative, -1.0)))
    raise UserError(
        f"[model]: this map does not fit K: in {int(unexplained.sum())} of {judged} rows away "
        f"from the supports the rigid rotations of the nodes leave a force (largest at "
        f"{_label(body, worst)}, relative residual {relative[worst]:.1e}), which an element "
        "assembly without prestress never does: the dof table or the node coordinates do not "
        "belong to the matrices (files of different runs?)"
    )


def _displaced_nodes(body: ElasticBody, rows: np.ndarray) -> np.ndarray:
    """Nodes with a translational and a rotational row among ``rows`` (shape (n_dof,), rows
    that only the rotations fail by a large residual): force and moment balance of the
    rotated node both broken, which no spring and no prestress does (item 3)."""
    directions = body.dofs.directions
    moved = np.unique(body.dofs.nodes[rows & (directions < 3)])
    turned = np.unique(body.dofs.nodes[rows & (directions >= 3) & (directions < 6)])
    return np.intersect1d(moved, turned)


def _refuse_map(
    body: ElasticBody,
    large: np.ndarray,
    relative: np.ndarray,
    judged: int,
    displaced: np.ndarray,
) -> None:
    """The :class:`UserError` of a map that does not fit ``K`` (the third band of item 3)."""
    worst = int(np.argmax(np.where(large, relative, -1.0)))
    if displaced.size >= MIN_DISPLACED_NODES:
        evidence = (
            f"at {displaced.size} nodes (first {int(displaced[0])}) the rigid rotations leave "
            f"forces and moments of {WRONG_RESIDUAL:g} or more of their rows while the "
            "translations fit"
        )
    else:
        evidence = (
            f"the rigid-body motions of the nodes leave forces of {WRONG_RESIDUAL:g} or more of "
            f"the row in {int(large.sum())} of {judged} rows away from any support"
        )
    raise UserError(
        f"[model]: this map does not fit K: {evidence}; largest at {_label(body, worst)}, "
        f"relative residual {relative[worst]:.1e}: the dof table or the node coordinates do "
        "not belong to the matrices (a table shifted by a node, another node order?)"
    )


@dataclass(frozen=True)
class _RowFit:
    """Per row (shape (n_dof,)): fails a field, largest relative residual, judged, and fails
    a translation field (a reaction)."""

    failing: np.ndarray
    relative: np.ndarray
    judged: np.ndarray
    reactions: np.ndarray


class _RowProducts:
    """``K`` times the rigid-body fields split into their parts, once for every scale.

    The rotation fields are ``P + Q``: ``P`` on the translational dofs (``theta x (x - c)``,
    proportional to the coordinates), ``Q`` on the rotational dofs (``theta``); coordinates
    scaled by ``s`` give ``s P + Q``. Nine products with ``K`` and nine with ``|K|``.
    """

    def __init__(self, body: ElasticBody, rounding: Rounding) -> None:
        stiffness = sp.csr_matrix(body.stiffness)
        directions = body.dofs.directions
        fields = body.rigid_body_modes(_centroid(body))
        translational = (directions < 3)[:, None]
        rotational = ((directions >= 3) & (directions < 6))[:, None]
        vectors = np.hstack(
            [fields[:, :3], fields[:, 3:] * translational, fields[:, 3:] * rotational]
        )
        self.forces = stiffness @ vectors
        self.sizes = abs_products(stiffness, vectors)
        self.coordinate_terms = abs_products(stiffness, translational[:, 0].astype(float))
        self.rounding = rounding
        self.has_rotations = bool(rotational.any())
        self.free = np.ones(body.n_dof, dtype=bool)
        self.free[body.fixed] = False

    def fit(self, scale: float) -> _RowFit:
        """How the rows fit the fields for coordinates times ``scale``."""
        f, a = self.forces, self.sizes
        residual = np.hstack([f[:, :3], scale * f[:, 3:6] + f[:, 6:]])
        size = np.hstack([a[:, :3], scale * a[:, 3:6] + a[:, 6:]])
        allowed = self.rounding.relative * size
        allowed[:, 3:] += scale * self.rounding.length * self.coordinate_terms[:, None]
        reached = size > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            relative = np.where(reached, np.abs(residual) / np.where(reached, size, 1.0), 0.0)
        judged = reached.any(axis=1) & self.free
        beyond = (np.abs(residual) > allowed) & judged[:, None]
        return _RowFit(beyond.any(axis=1), relative.max(axis=1), judged, beyond[:, :3].any(axis=1))


def _check_coordinate_scale(
    body: ElasticBody, products: _RowProducts, unexplained: int, judged: int
) -> None:
    """A :class:`UserError` when the rotations fit ``K`` with coordinates in another length
    unit (many fewer unexplained rows than as given)."""
    best_scale, best = 1.0, unexplained
    for scale in COORDINATE_SCALES:
        fit = products.fit(scale)
        rotations_only = fit.failing & ~fit.reactions
        count = int((rotations_only & ~_near_supports(body, rotations_only)).sum())
        if count < best:
            best_scale, best = scale, count
    if best_scale != 1.0 and 10 * best < unexplained:
        raise UserError(
            f"[model]: {_unit_mix(body, best_scale)}: the rigid-body rotations fit K only with "
            f"the coordinates times {best_scale:g} ({unexplained} of {judged} rows do not fit "
            "them as given); give the coordinates in the length unit of the matrices"
        )


def _unit_mix(body: ElasticBody, scale: float) -> str:
    """``the coordinates look like mm while K and M are in m-kg-s-N units`` for coordinates
    that fit the matrices when multiplied by ``scale``."""
    density, speed2 = implied_numbers(body)
    guess = units_of_numbers(density / scale**3, speed2 * scale**2)
    if guess.system is None:
        return f"the coordinates are in another length unit than K and M (1 : {scale:g})"
    coordinate_unit = length_unit_name(guess.system.length_m * scale)
    return (
        f"the coordinates look like {coordinate_unit} while K and M are in {guess.system.name} "
        f"units ({guess.system.length}, {guess.system.mass})"
    )


def _support_dofs(body: ElasticBody) -> np.ndarray:
    """Dofs of support nodes: nodes with fixed dofs, with some but not all three translations
    or some but not all three rotations (removed by the exporter)."""
    nodes = np.unique(body.dofs.nodes[~body.dofs.scalar])
    if nodes.size == 0:
        return np.zeros(0, dtype=np.int64)
    translations = body.dofs.positions(nodes[:, None], np.arange(3)[None, :]) >= 0
    rotations = body.dofs.positions(nodes[:, None], np.arange(3, 6)[None, :]) >= 0
    count_t, count_r = translations.sum(axis=1), rotations.sum(axis=1)
    partial = ((count_t > 0) & (count_t < 3)) | ((count_r > 0) & (count_r < 3))
    support = set(nodes[partial].tolist())
    support.update(body.dofs.nodes[body.fixed][~body.dofs.scalar[body.fixed]].tolist())
    return np.flatnonzero(np.isin(body.dofs.nodes, sorted(support)) & ~body.dofs.scalar)


def _support_nodes(body: ElasticBody) -> np.ndarray:
    """Support nodes (:func:`_support_dofs`) and the nodes of the node list without dofs
    (fully held nodes that the exporter removed)."""
    with_dofs = np.unique(body.dofs.nodes[~body.dofs.scalar])
    without = np.setdiff1d(body.node_ids, with_dofs)
    return np.union1d(np.unique(body.dofs.nodes[_support_dofs(body)]), without)


def _near_supports(body: ElasticBody, failing: np.ndarray) -> np.ndarray:
    """Which failing rows lie next to a support: their node is one, or a support node lies
    within :data:`REACH_FACTOR` times the longest distance from the node to a node it is
    coupled to in ``K`` (its elements' reach)."""
    out = np.zeros(failing.size, dtype=bool)
    rows = np.flatnonzero(failing & ~body.dofs.scalar)
    supports = _support_nodes(body)
    if rows.size == 0 or supports.size == 0:
        return out
    from scipy.spatial import cKDTree

    k = sp.csr_matrix(body.stiffness)[rows]
    own = body.dofs.nodes[rows]
    partner = body.dofs.nodes[k.indices]
    geometric = ~body.dofs.scalar[k.indices]
    here = body.coordinates[body.node_rows(np.repeat(own, np.diff(k.indptr)))]
    there = np.zeros_like(here)
    there[geometric] = body.coordinates[body.node_rows(partner[geometric])]
    distance = np.where(geometric, np.linalg.norm(there - here, axis=1), 0.0)
    reach = np.zeros(rows.size)
    starts = k.indptr[:-1][np.diff(k.indptr) > 0]
    reach[np.diff(k.indptr) > 0] = np.maximum.reduceat(distance, starts) if distance.size else 0
    gap, _ = cKDTree(body.coordinates[body.node_rows(supports)]).query(
        body.coordinates[body.node_rows(own)]
    )
    out[rows] = (gap <= REACH_FACTOR * reach) | np.isin(own, supports)
    return out


# ============================================================================ units
def check_material(
    body: ElasticBody, proof: MapProof, warnings: list[str]
) -> dict[str, Any] | None:
    """Item 4 without rotational dofs: mass / volume of the solid elements and ``E / rho``
    are a material in some unit system; without a mesh, the implied numbers of
    :mod:`pymorembs.units` (a warning into ``warnings`` where only another length unit of
    the coordinates makes them fit).

    Returns
    -------
    dict or None
        ``density`` and ``speed_squared`` (model units) and the ``systems`` that fit, for a
        body with a solid mesh; None otherwise.

    Raises
    ------
    UserError
        With a solid mesh: the material fits no system as given (the message names the
        length unit of the coordinates where another one makes it fit).
    """
    mesh = body.mesh
    mass = body.total_mass()
    if mesh is not None and mesh.element != "beam2" and mass > 0:
        from pymorembs.elements.solid import solid_volumes

        nodes = body.coordinates[body.node_rows(mesh.connectivity)]
        volume = float(solid_volumes(mesh.element, nodes).sum())
        young = float(np.median(np.atleast_1d(mesh.young)))
        density = mass / volume
        speed2 = young / density
        systems = material_systems(density, speed2)
        facts = {
            "density": density,
            "speed_squared": speed2,
            "systems": [s.name for s in systems],
            "method": "total mass / volume of the solid elements, median E / density",
        }
        if not systems:
            _scaled_material(density, speed2)
            raise UserError(
                f"[model]: mass / volume of the solid elements is {density:.3g} and E / density "
                f"{speed2:.3g} (model units): a material in no unit system; K, M and the "
                "material of the mesh in different units?"
            )
        return facts
    if body.has_coordinates and not np.any(body.dofs.directions >= 3) and proof.rows:
        density, speed2 = implied_numbers(body)
        if not units_of_numbers(density, speed2).plausible:
            for scale in COORDINATE_SCALES:
                guess = units_of_numbers(density / scale**3, speed2 * scale**2)
                if guess.plausible and not guess.ambiguous and guess.system is not None:
                    warnings.append(
                        f"coordinates in another length unit? As given, mass / bounding-box "
                        f"volume {density:.3g} and the wave speed^2 estimate {speed2:.3g} fit "
                        f"no unit system, with the coordinates times {scale:g} they fit "
                        f"{guess.system.name} (only a hint: a truss or a lattice of springs "
                        "fills little of its box)"
                    )
                    break
    return None


def _scaled_material(density: float, speed2: float) -> None:
    """A :class:`UserError` naming the coordinates' unit when a scale makes the material fit."""
    for scale in COORDINATE_SCALES:
        systems = material_systems(density / scale**3, speed2 * scale**3)
        if systems:
            system = systems[0]
            unit = length_unit_name(system.length_m * scale)
            raise UserError(
                f"[model]: the coordinates look like {unit} while K and M are in {system.name} "
                f"units ({system.length}, {system.mass}): mass / volume of the solid elements "
                f"is {density:.3g} (model units), with the coordinates times {scale:g} a "
                f"density of {density / scale**3 / system.density_factor:.4g} kg/m^3 and E / "
                f"density {speed2 * scale**3 / system.speed_squared_factor:.3g} m^2/s^2; give "
                "the coordinates in the length unit of the matrices"
            )


# ============================================================================ node cloud
def check_node_cloud(body: ElasticBody, rigid_mass: dict[str, Any]) -> None:
    """Item 5 of the module docstring.

    Raises
    ------
    UserError
        The centre of gravity lies far outside the nodes, or the inertia exceeds what any
        mass on (or near) the nodes can have.
    """
    cg = rigid_mass.get("centre_of_gravity")
    if cg is None or np.any(body.dofs.scalar) or not rigid_mass["masses"]:
        return
    mass = float(np.mean(rigid_mass["masses"]))
    points = body.coordinates[body.node_rows(np.unique(body.dofs.nodes))]
    low, high = points.min(axis=0), points.max(axis=0)
    extent = high - low
    size = float(extent.max())
    if mass <= 0 or size <= 0:
        return
    cg = np.asarray(cg)
    margin = CG_MARGIN * size
    if np.any(cg < low - margin) or np.any(cg > high + margin):
        raise UserError(
            f"[model]: the centre of gravity ({', '.join(f'{v:.4g}' for v in cg)}) lies far "
            f"outside the nodes (box {', '.join(f'{v:.4g}' for v in low)} to "
            f"{', '.join(f'{v:.4g}' for v in high)}): the mass matrix does not belong to these "
            "coordinates (another node order or length unit?)"
        )
    largest = float(rigid_mass["principal_inertia"][2])
    bound = INERTIA_FACTOR * mass * float(extent @ extent)
    if largest > bound:
        raise UserError(
            f"[model]: the rigid-body inertia {largest:.4g} exceeds {INERTIA_FACTOR:g} x mass x "
            f"(size of the node cloud)^2 = {bound:.4g}: the rotational mass entries are in "
            "another length unit than the coordinates (e.g. M in mm-t-s-N with coordinates in "
            "m)?"
        )


def mechanism_or_map(consistency: dict[str, Any], rigid: int, mechanisms: int) -> str | None:
    """The error line for ``info`` when the zero-energy modes beyond the geometric rigid-body
    modes are the rigid rotations of a wrong map, not mechanisms; None otherwise.

    A free body whose map is wrong keeps six zero-energy modes (its matrices are unchanged),
    while the geometric fields find only the translations: ``rigid + mechanisms == 6`` with
    ``rigid < 6``, and the rotations leave forces away from every support. A real mechanism
    leaves the six geometric fields in the null space of ``K`` (``rigid == 6``), and a part
    joined by springs that resist rotation, or a held body, has another count.

    Parameters
    ----------
    consistency : dict
        :func:`check_consistency`'s facts.
    rigid, mechanisms : int
        Geometric rigid-body modes and further zero-energy modes of the spectrum.
    """
    proof = consistency.get("map", {})
    if mechanisms <= 0 or rigid >= 6 or rigid + mechanisms != 6:
        return None
    if not proof.get("rows_unexplained"):
        return None
    return (
        f"[model]: this map does not fit K: the spectrum has {mechanisms} zero-energy mode"
        f"{'s' if mechanisms > 1 else ''} besides the rigid-body motions of the nodes, which "
        f"leave forces in K ({proof['reason']}); a wrong dof table or wrong coordinates, not a "
        "mechanism"
    )


# ============================================================================ helpers
def _located(body: ElasticBody) -> bool:
    """The body has coordinates that span more than a point."""
    return bool(
        body.has_coordinates
        and body.n_nodes > 1
        and np.ptp(body.coordinates, axis=0).max(initial=0.0) > 0
    )


def _centroid(body: ElasticBody) -> np.ndarray:
    return body.coordinates.mean(axis=0) if body.n_nodes else np.zeros(3)


def _label(body: ElasticBody, index: int) -> str:
    """``node 12 uz`` for an equation index."""
    return f"node {int(body.dofs.nodes[index])} {DIRECTIONS[int(body.dofs.directions[index])]}"


__all__ = [
    "CHECK_FACTOR",
    "MapProof",
    "Rounding",
    "body_rounding",
    "check_consistency",
    "check_map",
    "check_mass_pattern",
    "check_material",
    "check_node_cloud",
    "check_rigid_mass",
    "mechanism_or_map",
]
