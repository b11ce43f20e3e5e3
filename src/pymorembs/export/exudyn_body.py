"""The reduced elastic body for Exudyn's ``ObjectFFRFreducedOrder`` (SID_NOTES §5).

Exudyn (J. Gerstmayr et al.) models a modally reduced flexible body in the floating frame of
reference by ``ObjectFFRFreducedOrder``: a rigid-body node for the reference frame, a
``NodeGenericODE2`` for the elastic coordinates ``q`` (nq) and, with ``computeFFRFterms=True``,
the FFRF mass matrix and quadratic velocity vector evaluated in C++ from the total mass, the
inertia tensor, the centre of mass and six "inertia-like" matrices. Exudyn's own helper
(``exudyn.FEM.ObjectFFRFreducedOrderInterface``) forms these from the full FE mass matrix of a
mesh with translational dofs only. This module forms them from the reduced mass invariants of
:mod:`pymorembs.export.invariants` instead (SID_NOTES §5 table). That needs no FE matrices, works
for beam and shell models with rotational dofs, and keeps their rotary inertia in all first-order
terms (``m``, ``c``, ``J0``, ``Ct``, ``Cr``, ``Me``); the second-order terms (from ``S`` and
``PP``) are as exact as the invariants' ``second_order_mass`` (exact for solids and lumped masses,
without rotary inertia for beams):

=====================  ===========  =========================================================
Exudyn parameter       shape        from the invariants (``P = Ctᵀ``, ``S_k = S[k]``)
=====================  ===========  =========================================================
physicsMass            ()           ``m``
physicsCenterOfMass    (3,)         ``∫c dm / m``
physicsInertia         (3, 3)       ``J0`` (tensor about the body-frame origin)
massMatrixReduced      (nq, nq)     ``Me``; ``stiffnessMatrixReduced`` = ``Ke``,
                                    ``dampingMatrixReduced`` = ``De``
mPhitTPsi              (3, nq)      ``P``
mPhitTPsiTilde         (3, 3nq)     block k = ``skew(P[:, k])``
mXRefTildePsi          (3, nq)      ``-Crᵀ``
mXRefTildePsiTilde     (3, 3nq)     block k = ``-C4_k = tr(S_k) I - S_kᵀ``
mPsiTildePsi           (3nq, nq)    row ``3k+a``, column l: ``Kr[a, k, l] = ∫(Φ_l × Φ_k)_a dm``
mPsiTildePsiTilde      (3nq, 3nq)   block (k, l) = ``-C6_kl``, entry (a, b):
                                    ``δ_ab Σ_c PP[c, c, k, l] - PP[b, a, k, l]``
=====================  ===========  =========================================================

"Block k" is Exudyn's per-mode layout (columns ``3k .. 3k+2``), the layout of
``exudyn.rigidBodyUtilities.ComputeSkewMatrix`` applied to the mode basis; it differs from the
axis-major layout of ``Gr``/``Ge`` in a SID file (SID_NOTES §0). Exudyn's definitions are
``Φ_tᵀ M Ψ``, ``Φ_tᵀ M Ψ̃``, ``X̃ᵀ M Ψ``, ``X̃ᵀ M Ψ̃``, ``Ψ̃ᵀ M Ψ`` and ``Ψ̃ᵀ M Ψ̃`` with the
full mass matrix ``M`` (``exudyn/FEM.py``, ``ObjectFFRFreducedOrderInterface.__init__``); the
tests compare both routes on a solid model and find them equal to round-off.

Mode basis and mesh nodes
-------------------------
Exudyn reconstructs node positions from ``referencePositions`` and the translational
``modeBasis`` (rows node-major ``[ux0, uy0, uz0, ux1, ...]``); the mass terms above do not depend
on it. The exported "mesh" therefore holds the frame nodes of the invariants (``inv.nodes``),
each followed -- if it has rotational dofs -- by six massless *satellite points*
on a rigid cross around it: positions ``c_p ± L e_a`` (order +x, -x, +y, -y, +z, -z) with the
mode rows ``φ_p + ψ_p × (±L e_a)`` of a linearised rigid link. Their mean is the node itself
(position and displacement), and a ``MarkerSuperElementRigid`` with equal weights on the six of
them gives the node's position and its elastic rotation (``ψ_p q`` to first order), so a rigid
joint can act at the node. ``L`` is the radius of gyration of the body about its centre of
gravity unless given; it does not enter the dynamics.

Surface
-------
With a :class:`SurfaceMesh` (:func:`surface_mesh`: the body's surface triangles,
:class:`~pymorembs.surface.Surface`) the nodes of the triangles follow, each with its position
and its translational rows of the basis (a frame node on the surface keeps its one mesh node),
and ``surfaceTriangles`` holds the triangles as mesh node indices, counter-clockwise seen from
outside. :func:`~pymorembs.analysis.exudyn_model.build_exudyn_model` hands them to
``VObjectFFRFreducedOrder(triangleMesh=...)`` -- what Exudyn's FEM route does with
``FEMinterface.GetSurfaceTriangles()`` (``ObjectFFRFreducedOrderInterface``) -- so Exudyn's
renderer draws the deforming body. Only
triangles are drawn: a beam model (line segments only) shows no surface. Quadratic faces are
split through their mid-side nodes into flat triangles (Exudyn's route draws a hexahedron face
by its corners).

File
----
:func:`write_exudyn_body` stores the arrays of :func:`exudyn_arrays` in a ``.npz`` archive (no
pickled objects; ``numpy.load(..., allow_pickle=False)`` reads it). Besides the Exudyn parameters
above the archive holds ``format`` (``"pymorembs-exudyn-body"``), ``formatVersion`` (1),
``bodyName``, ``eigenfrequenciesHz`` (nq,), ``nodeIds`` (p,), ``nodeMeshIndices`` (p,),
``satelliteMeshIndices`` (p, 6; -1 for a node without rotational dofs), ``meshNodeIds`` (n_mesh,;
the node each mesh node belongs to: a satellite's frame node), ``satelliteLength`` () in m and
``satelliteDirections`` (6, 3). Lengths in m, masses in kg, times in s (those of the FE model). A
body with geometric stiffening (SID_NOTES §4.6) also holds ``K0`` of the centrifugal load cases
(``stiffeningOmega``, 6 × nq × nq, wxx wyy wzz wxy wyz wxz), of the frame's translational and
angular accelerations (``stiffeningAcceleration``, ``stiffeningAngularAcceleration``, 3 × nq × nq
each) and, if any stiffens the body, of unit forces at the frame nodes (``stiffeningNodeForces``, p
× 3 × nq × nq, body directions x, y, z); Exudyn's ``ObjectFFRFreducedOrder`` has no input for them,
so :func:`~pymorembs.analysis.exudyn_model.stiffening_force` applies them through the object's
``forceUserFunction``. A body with a surface holds ``surfaceTriangles`` (n_t × 3, mesh node
indices); ``meshNodeIds`` then names each surface node's own id.

Stress modes
------------
A body with solid elements (:func:`~pymorembs.export.stress_modes.stress_modes`) also holds
``outputVariableModeBasis`` (n_mesh × 6 nq) and ``outputVariableTypeModeBasis`` (the text
``"StressLocal"``): Exudyn's own ``ObjectFFRFreducedOrder`` parameters, with which
``GetObjectOutputSuperElement(..., StressLocal, meshNode)``, its sensors and its renderer's
contour plot give the stress ``sum_j q_j X[i, 6 j : 6 j + 6]`` of mesh node ``i``
(:func:`~pymorembs.export.stress_modes.exudyn_stress_basis`). The row of a mesh node is the
averaged nodal stress of its node per unit modal coordinate, components in Exudyn's order
``xx yy zz yz xz xy`` (``exudyn.physics.VonMisesStress`` reads that order), in the model's stress
unit; a satellite point and a node of no solid element (a reference node of a rigid coupling)
have rows of 0. Exudyn holds one output variable per body: the archive holds the stresses, the
strains are in the recovery file (:mod:`pymorembs.export.recovery`).

This module writes and reads the archive and runs nothing; the body in a ready Exudyn system,
integrated in time, is :mod:`pymorembs.analysis.exudyn_model`.
"""

from __future__ import annotations

import os
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pymorembs.arrays import sorted_unique
from pymorembs.elements.rigid import skew
from pymorembs.errors import UserError
from pymorembs.export.deterministic import write_npz
from pymorembs.export.invariants import StiffeningTerms, levi_civita
from pymorembs.export.nodal import node_fields
from pymorembs.export.stress_modes import StressModes, exudyn_stress_basis

if TYPE_CHECKING:
    from pymorembs.body import ElasticBody
    from pymorembs.export.invariants import BodyInvariants

__all__ = [
    "ACCELERATION_CASES",
    "ANGULAR_ACCELERATION_CASES",
    "CENTRIFUGAL_CASES",
    "FORMAT",
    "FORMAT_VERSION",
    "SATELLITE_DIRECTIONS",
    "STRESS_OUTPUT",
    "SurfaceMesh",
    "check_exudyn_arrays",
    "exudyn_arrays",
    "ffrf_inertia_matrices",
    "load_exudyn_body",
    "surface_mesh",
    "write_exudyn_body",
]

#: Value of the ``format`` entry of an exported body.
FORMAT = "pymorembs-exudyn-body"
#: Version of the archive layout; :func:`load_exudyn_body` reads this version only.
FORMAT_VERSION = 1
#: Unit directions of the six satellite points of a node with rotations, shape (6, 3).
SATELLITE_DIRECTIONS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float
)

#: Keys of the archive with their number of dimensions (the body-describing part).
_KEYS_NDIM: dict[str, int] = {
    "format": 0,
    "formatVersion": 0,
    "bodyName": 0,
    "massMatrixReduced": 2,
    "stiffnessMatrixReduced": 2,
    "dampingMatrixReduced": 2,
    "modeBasis": 2,
    "referencePositions": 1,
    "physicsMass": 0,
    "physicsInertia": 2,
    "physicsCenterOfMass": 1,
    "mPsiTildePsi": 2,
    "mPsiTildePsiTilde": 2,
    "mPhitTPsi": 2,
    "mPhitTPsiTilde": 2,
    "mXRefTildePsi": 2,
    "mXRefTildePsiTilde": 2,
    "eigenfrequenciesHz": 1,
    "nodeIds": 1,
    "nodeMeshIndices": 1,
    "satelliteMeshIndices": 2,
    "meshNodeIds": 1,
    "satelliteLength": 0,
    "satelliteDirections": 2,
}
_TEXT_KEYS = ("format", "bodyName", "outputVariableTypeModeBasis")
#: Optional keys: the geometric stiffening ``K0`` of the centrifugal load cases (6, nq, nq), of
#: the translational and of the angular acceleration cases (3, nq, nq each) and of unit forces at
#: the frame nodes (p, 3, nq, nq; node order of ``nodeIds``, body directions x, y, z); the
#: surface triangles as mesh node indices (n_t, 3).
_OPTIONAL_KEYS_NDIM: dict[str, int] = {
    "stiffeningOmega": 3,
    "stiffeningAcceleration": 3,
    "stiffeningAngularAcceleration": 3,
    "stiffeningNodeForces": 4,
    "surfaceTriangles": 2,
    "outputVariableModeBasis": 2,
    "outputVariableTypeModeBasis": 0,
}
#: The output variable of ``outputVariableModeBasis`` (an ``exudyn.OutputVariableType`` name).
STRESS_OUTPUT = "StressLocal"
#: The centrifugal load cases of ``stiffeningOmega``, in the order of the six products of Ω.
CENTRIFUGAL_CASES = ("wxx", "wyy", "wzz", "wxy", "wyz", "wxz")
#: The load cases of ``stiffeningAcceleration`` and ``stiffeningAngularAcceleration``.
ACCELERATION_CASES = ("ax", "ay", "az")
ANGULAR_ACCELERATION_CASES = ("alx", "aly", "alz")
_INTEGER_KEYS = (
    "formatVersion",
    "nodeIds",
    "nodeMeshIndices",
    "satelliteMeshIndices",
    "meshNodeIds",
    "surfaceTriangles",
)


# ------------------------------------------------------------------------------ the arrays
def ffrf_inertia_matrices(inv: BodyInvariants) -> dict[str, np.ndarray]:
    """Exudyn's six FFRF inertia matrices from the mass invariants (SID_NOTES §5).

    Parameters
    ----------
    inv : BodyInvariants
        Uses ``Ct`` (nq, 3) in kg, ``Cr`` (nq, 3) and ``S`` (nq, 3, 3) in kg·m and ``PP``
        (3, 3, nq, nq) in kg (per unit of ``q`` in the length unit).

    Returns
    -------
    dict
        ``mPhitTPsi`` (3, nq), ``mPhitTPsiTilde`` (3, 3nq), ``mXRefTildePsi`` (3, nq),
        ``mXRefTildePsiTilde`` (3, 3nq), ``mPsiTildePsi`` (3nq, nq) and ``mPsiTildePsiTilde``
        (3nq, 3nq), in Exudyn's per-mode block layout (see the module docstring).
    """
    ct, cr = np.asarray(inv.Ct, dtype=float), np.asarray(inv.Cr, dtype=float)
    s, pp = np.asarray(inv.S, dtype=float), np.asarray(inv.PP, dtype=float)
    nq = ct.shape[0]
    p = ct.T  # P = ∫Φ dm (3, nq)
    # -C4_k = tr(S_k) I - S_kᵀ, stored (k, a, b) then laid out as blocks k of (3, 3)
    trace_s = np.einsum("kaa->k", s)
    minus_c4 = trace_s[:, None, None] * np.eye(3) - s.transpose(0, 2, 1)
    # Kr[a, k, l] = ∫(Φ_l × Φ_k)_a dm = Σ_bc ε_abc PP[c, b, k, l]
    kr = np.einsum("abc,cbkl->akl", levi_civita(), pp)
    # -C6_kl[a, b] = δ_ab Σ_c PP[c, c, k, l] - PP[b, a, k, l], stored (k, a, l, b)
    trace_pp = np.einsum("cckl->kl", pp)
    minus_c6 = np.einsum("kl,ab->kalb", trace_pp, np.eye(3)) - pp.transpose(2, 1, 3, 0)
    return {
        "mPhitTPsi": p.copy(),
        "mPhitTPsiTilde": skew(p.T).transpose(1, 0, 2).reshape(3, 3 * nq),
        "mXRefTildePsi": -cr.T.copy(),
        "mXRefTildePsiTilde": minus_c4.transpose(1, 0, 2).reshape(3, 3 * nq),
        "mPsiTildePsi": kr.transpose(1, 0, 2).reshape(3 * nq, nq),
        "mPsiTildePsiTilde": minus_c6.reshape(3 * nq, 3 * nq),
    }


def _radius_of_gyration(inv: BodyInvariants) -> float:
    """``sqrt(tr(J_G) / (2 m))`` (m): a length scale of the body about its centre of gravity."""
    mass = float(inv.mass)
    centre = np.asarray(inv.first_moment, dtype=float) / mass
    j_g = np.asarray(inv.inertia, dtype=float) - mass * (
        centre @ centre * np.eye(3) - np.outer(centre, centre)
    )
    return float(np.sqrt(max(np.trace(j_g), 0.0) / (2.0 * mass)))


@dataclass(frozen=True, eq=False)
class SurfaceMesh:
    """The body's surface triangles with what Exudyn needs to draw them deforming.

    Attributes
    ----------
    node_ids : ndarray of int, shape (n_s,)
        The nodes the triangles use, sorted.
    positions : ndarray, shape (n_s, 3)
        Their undeformed positions in the body frame (model length unit).
    modes : ndarray, shape (n_s, 3, nq)
        Their translational rows of the basis ``Φ`` (ux, uy, uz; a missing dof gives 0).
    triangles : ndarray of int, shape (n_t, 3)
        Node ids of each triangle, counter-clockwise seen from outside
        (:class:`~pymorembs.surface.Surface`).
    """

    node_ids: np.ndarray
    positions: np.ndarray
    modes: np.ndarray
    triangles: np.ndarray


def surface_mesh(body: ElasticBody, basis: np.ndarray) -> SurfaceMesh | None:
    """The surface triangles of ``body`` with their nodes' positions and rows of ``basis``.

    Parameters
    ----------
    body : ElasticBody
        The prepared body (coordinates in the reference frame); its ``surface``.
    basis : ndarray, shape (n_dof, nq)
        The basis on all dofs of ``body`` (eq. 18), the one of the invariants.

    Returns
    -------
    SurfaceMesh or None
        None for a body without surface triangles (no elements, or line elements only).
    """
    if body.surface is None or body.surface.triangles.size == 0:
        return None
    triangles = body.surface.triangles
    ids = sorted_unique(triangles.ravel())
    fields = node_fields(body, basis, ids)
    positions = body.coordinates[body.node_rows(ids)]
    return SurfaceMesh(ids, positions, fields.translations, triangles)


def exudyn_arrays(
    inv: BodyInvariants,
    satellite_length: float | None = None,
    surface: SurfaceMesh | None = None,
    stress: StressModes | None = None,
) -> dict[str, np.ndarray]:
    """Everything ``ObjectFFRFreducedOrder`` needs, from the reduced invariants.

    Parameters
    ----------
    inv : BodyInvariants
        The reduced body (:func:`pymorembs.export.invariants.compute_invariants`).
    satellite_length : float, optional
        Arm ``L`` (m) of the satellite points of nodes with rotational dofs; default: the radius
        of gyration of the body about its centre of gravity.
    surface : SurfaceMesh, optional
        The body's surface (:func:`surface_mesh`, same basis as ``inv``): its nodes join the
        mesh after the frame nodes and their satellites (a frame node keeps its one mesh
        node), and ``surfaceTriangles`` holds the triangles as mesh node indices for Exudyn's
        ``triangleMesh``.

    Returns
    -------
    dict of str to ndarray
        The keys of the module docstring (Exudyn parameters, node maps, ``format``...).

    Raises
    ------
    UserError
        The body has no mass, no elastic coordinates or no frame nodes, ``satellite_length``
        is not a positive number, or the surface's basis has another number of columns.
    """
    mass = float(inv.mass)
    me = np.asarray(inv.Me, dtype=float)
    nq = me.shape[0]
    if not (np.isfinite(mass) and mass > 0):
        raise UserError(f"exudyn export: the body mass must be positive, got {mass!r}")
    if nq == 0:
        raise UserError("exudyn export: the body has no elastic coordinates")
    if not inv.nodes:
        raise UserError("exudyn export: the body has no frame nodes to attach markers or loads")
    if satellite_length is None:
        satellite_length = _radius_of_gyration(inv) or 1.0
    length = float(satellite_length)
    if not (np.isfinite(length) and length > 0):
        raise UserError(f"exudyn export: satellite_length must be > 0 m, got {satellite_length!r}")

    positions, rows, owners = [], [], []
    node_mesh = np.zeros(len(inv.nodes), dtype=np.int64)
    satellites = np.full((len(inv.nodes), 6), -1, dtype=np.int64)
    for i, frame in enumerate(inv.nodes):
        c_p = np.asarray(frame.position, dtype=float)
        phi = np.asarray(frame.phi, dtype=float)
        node_mesh[i] = len(owners)
        positions.append(c_p[None, :])
        rows.append(phi[None, :, :])
        owners.append(int(frame.node_id))
        if frame.psi is not None:
            arms = length * SATELLITE_DIRECTIONS  # (6, 3)
            psi = np.asarray(frame.psi, dtype=float)
            # φ_p + ψ_p × d for every arm d and mode k: (6, 3, nq)
            links = phi[None] + np.cross(psi.T[None, :, :], arms[:, None, :]).transpose(0, 2, 1)
            satellites[i] = len(owners) + np.arange(6)
            positions.append(c_p + arms)
            rows.append(links)
            owners.extend([int(frame.node_id)] * 6)
    triangles = None
    if surface is not None:
        modes = np.asarray(surface.modes, dtype=float)
        if modes.ndim != 3 or modes.shape[1:] != (3, nq):
            raise UserError(
                f"exudyn export: the surface's mode rows have shape {modes.shape}, expected "
                f"(n, 3, {nq})"
            )
        ids = np.asarray(surface.node_ids, dtype=np.int64)  # sorted
        frame_ids = np.array([int(frame.node_id) for frame in inv.nodes], dtype=np.int64)
        new = ~np.isin(ids, frame_ids)  # a frame node keeps its one mesh node
        mesh_index = np.empty(ids.size, dtype=np.int64)
        mesh_index[new] = len(owners) + np.arange(int(new.sum()))
        is_frame = np.flatnonzero(~new)
        order = np.argsort(frame_ids)
        mesh_index[is_frame] = node_mesh[
            order[np.searchsorted(frame_ids, ids[is_frame], sorter=order)]
        ]
        positions.append(np.asarray(surface.positions, dtype=float)[new])
        rows.append(modes[new])
        owners.extend(ids[new].tolist())
        triangles = mesh_index[np.searchsorted(ids, np.asarray(surface.triangles, np.int64))]
    arrays: dict[str, np.ndarray] = {
        "format": np.array(FORMAT),
        "formatVersion": np.array(FORMAT_VERSION, dtype=np.int64),
        "bodyName": np.array(str(inv.name)),
        "massMatrixReduced": me.copy(),
        "stiffnessMatrixReduced": np.asarray(inv.Ke, dtype=float).copy(),
        "dampingMatrixReduced": np.asarray(inv.De, dtype=float).copy(),
        "modeBasis": np.concatenate(rows).reshape(-1, nq),
        "referencePositions": np.concatenate(positions).ravel(),
        "physicsMass": np.array(mass),
        "physicsInertia": np.asarray(inv.inertia, dtype=float).copy(),
        "physicsCenterOfMass": np.asarray(inv.first_moment, dtype=float) / mass,
        **ffrf_inertia_matrices(inv),
        "eigenfrequenciesHz": np.asarray(inv.frequencies_hz, dtype=float).copy(),
        "nodeIds": np.array([int(f.node_id) for f in inv.nodes], dtype=np.int64),
        "nodeMeshIndices": node_mesh,
        "satelliteMeshIndices": satellites,
        "meshNodeIds": np.array(owners, dtype=np.int64),
        "satelliteLength": np.array(length),
        "satelliteDirections": SATELLITE_DIRECTIONS.copy(),
    }
    if inv.stiffening is not None:
        arrays.update(_stiffening_arrays(inv.stiffening, arrays["nodeIds"], nq))
    if triangles is not None:
        arrays["surfaceTriangles"] = triangles
    if stress is not None:
        if stress.n_shapes != nq:
            raise UserError(
                f"exudyn export: stress modes of {stress.n_shapes} shape functions for {nq} modes"
            )
        arrays["outputVariableModeBasis"] = exudyn_stress_basis(stress, arrays["meshNodeIds"])
        arrays["outputVariableTypeModeBasis"] = np.array(STRESS_OUTPUT)
    check_exudyn_arrays(arrays, "exudyn export")
    return arrays


def _stiffening_arrays(
    stiffening: StiffeningTerms, node_ids: np.ndarray, nq: int
) -> dict[str, np.ndarray]:
    """The ``stiffening*`` entries: every load case and node force that has a ``K0`` (zeros for
    the cases without), the node forces only if one of them stiffens the body."""
    zero = np.zeros((nq, nq))

    def stacked(cases: tuple[str, ...]) -> np.ndarray:
        return np.stack([stiffening.cases.get(case, zero) for case in cases])

    out = {
        "stiffeningOmega": stacked(CENTRIFUGAL_CASES),
        "stiffeningAcceleration": stacked(ACCELERATION_CASES),
        "stiffeningAngularAcceleration": stacked(ANGULAR_ACCELERATION_CASES),
    }
    forces = np.array(
        [[stiffening.nodes.get((int(n), d), zero) for d in range(3)] for n in node_ids]
    ).reshape(len(node_ids), 3, nq, nq)
    if np.any(forces):
        out["stiffeningNodeForces"] = forces
    return out


def check_exudyn_arrays(arrays: Mapping[str, np.ndarray], where: str) -> None:
    """Raise :class:`UserError` unless ``arrays`` is a complete, consistent body.

    ``where`` starts the message (the file, or what was given the arrays).
    """
    kind = np.asarray(arrays.get("format", "")).astype(str)
    if kind.ndim != 0 or str(kind) != FORMAT:
        raise UserError(f"{where}: not a {FORMAT} archive (format entry {str(kind)!r})")
    version = np.asarray(arrays.get("formatVersion", -1))
    if version.ndim != 0 or version.dtype.kind not in "iu" or int(version) != FORMAT_VERSION:
        raise UserError(
            f"{where}: format version {version} is not supported "
            f"(this pymorembs reads version {FORMAT_VERSION})"
        )
    missing = [key for key in _KEYS_NDIM if key not in arrays]
    if missing:
        raise UserError(f"{where}: missing entr{'ies' if len(missing) > 1 else 'y'} {missing}")
    for key, ndim in {**_KEYS_NDIM, **_OPTIONAL_KEYS_NDIM}.items():
        if key not in arrays:
            continue
        value = np.asarray(arrays[key])
        if value.ndim != ndim:
            raise UserError(f"{where}: entry {key} has {value.ndim} dimensions, not {ndim}")
        kinds = "U" if key in _TEXT_KEYS else "iu" if key in _INTEGER_KEYS else "f"
        if value.dtype.kind not in kinds:
            raise UserError(f"{where}: entry {key} has the wrong type ({value.dtype})")
        if kinds == "f" and not np.all(np.isfinite(value)):
            raise UserError(f"{where}: entry {key} has NaN or infinite values")
    nq = arrays["massMatrixReduced"].shape[0]
    n_mesh = arrays["meshNodeIds"].shape[0]
    p = arrays["nodeIds"].shape[0]
    shapes = {
        "massMatrixReduced": (nq, nq),
        "stiffnessMatrixReduced": (nq, nq),
        "dampingMatrixReduced": (nq, nq),
        "modeBasis": (3 * n_mesh, nq),
        "referencePositions": (3 * n_mesh,),
        "physicsInertia": (3, 3),
        "physicsCenterOfMass": (3,),
        "mPhitTPsi": (3, nq),
        "mPhitTPsiTilde": (3, 3 * nq),
        "mXRefTildePsi": (3, nq),
        "mXRefTildePsiTilde": (3, 3 * nq),
        "mPsiTildePsi": (3 * nq, nq),
        "mPsiTildePsiTilde": (3 * nq, 3 * nq),
        "eigenfrequenciesHz": (nq,),
        "nodeMeshIndices": (p,),
        "satelliteMeshIndices": (p, 6),
        "satelliteDirections": (6, 3),
    }
    optional_shapes = {
        "stiffeningOmega": (6, nq, nq),
        "stiffeningAcceleration": (3, nq, nq),
        "stiffeningAngularAcceleration": (3, nq, nq),
        "stiffeningNodeForces": (p, 3, nq, nq),
        "surfaceTriangles": (arrays.get("surfaceTriangles", np.zeros((0, 3))).shape[0], 3),
        "outputVariableModeBasis": (n_mesh, 6 * nq),
    }
    shapes.update({key: shape for key, shape in optional_shapes.items() if key in arrays})
    for key, shape in shapes.items():
        if arrays[key].shape != shape:
            raise UserError(f"{where}: entry {key} has shape {arrays[key].shape}, expected {shape}")
    if p == 0 or nq == 0:
        raise UserError(f"{where}: the body has no frame nodes or no elastic coordinates")
    index = arrays["nodeMeshIndices"]
    if index.min() < 0 or index.max() >= n_mesh or np.unique(arrays["nodeIds"]).size != p:
        raise UserError(f"{where}: node ids / mesh indices are inconsistent")
    if not np.array_equal(arrays["meshNodeIds"][index], arrays["nodeIds"]):
        raise UserError(f"{where}: nodeMeshIndices do not point at the nodes' own mesh nodes")
    sat = arrays["satelliteMeshIndices"]
    has = sat[:, 0] >= 0
    if np.any((sat >= 0) != has[:, None]) or (sat.max() >= n_mesh):
        raise UserError(f"{where}: satelliteMeshIndices are inconsistent")
    triangles = arrays.get("surfaceTriangles")
    if (
        triangles is not None
        and triangles.size
        and (triangles.min() < 0 or triangles.max() >= n_mesh)
    ):
        raise UserError(f"{where}: surfaceTriangles point outside the mesh")
    if ("outputVariableModeBasis" in arrays) != ("outputVariableTypeModeBasis" in arrays) or str(
        arrays.get("outputVariableTypeModeBasis", STRESS_OUTPUT)
    ) != STRESS_OUTPUT:
        raise UserError(
            f"{where}: outputVariableModeBasis needs outputVariableTypeModeBasis = "
            f"{STRESS_OUTPUT!r} beside it"
        )
    if float(arrays["physicsMass"]) <= 0 or float(arrays["satelliteLength"]) <= 0:
        raise UserError(f"{where}: physicsMass and satelliteLength must be positive")


# ------------------------------------------------------------------------------ the file
def write_exudyn_body(
    path: str | os.PathLike[str],
    inv: BodyInvariants | Mapping[str, np.ndarray],
    satellite_length: float | None = None,
    surface: SurfaceMesh | None = None,
    stress: StressModes | None = None,
) -> Path:
    """Write the Exudyn body as an ``.npz`` archive, atomically.

    Parameters
    ----------
    path : path-like
        Target file (written as given, no extension is appended).
    inv : BodyInvariants or dict
        The reduced body, or the arrays of :func:`exudyn_arrays`.
    satellite_length : float, optional
        Passed to :func:`exudyn_arrays` when ``inv`` is a :class:`BodyInvariants`.
    surface : SurfaceMesh, optional
        Likewise: the surface triangles Exudyn draws (:func:`surface_mesh`).
    stress : StressModes, optional
        Likewise: the stress modes of ``StressLocal``.

    Returns
    -------
    Path
        The written file.
    """
    if isinstance(inv, Mapping):
        arrays = {key: np.asarray(value) for key, value in inv.items()}
        check_exudyn_arrays(arrays, f"exudyn body {path}")
    else:
        arrays = exudyn_arrays(inv, satellite_length, surface, stress)
    target = Path(path)
    return write_npz(target, arrays)


def load_exudyn_body(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Read a body written by :func:`write_exudyn_body`.

    Returns
    -------
    dict of str to ndarray
        The arrays of :func:`exudyn_arrays`.

    Raises
    ------
    UserError
        The file is missing, not an ``.npz`` archive, holds pickled objects, is of another format
        or version, or its arrays are incomplete or inconsistent.
    """
    where = f"exudyn body {path}"
    try:
        archive = np.load(Path(path), allow_pickle=False)
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise UserError(f"{where}: a single .npy array, not an .npz archive")
        with archive:
            arrays = {key: archive[key] for key in archive.files}
    except FileNotFoundError:
        raise UserError(f"{where}: file not found") from None
    except IsADirectoryError:
        raise UserError(f"{where}: is a directory") from None
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise UserError(f"{where}: not a readable .npz archive ({exc})") from None
    check_exudyn_arrays(arrays, where)
    return arrays
