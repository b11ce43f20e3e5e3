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
outside. :func:`build_exudyn_model` hands them to ``VObjectFFRFreducedOrder(triangleMesh=...)``
-- what Exudyn's FEM route does with ``FEMinterface.GetSurfaceTriangles()``
(``ObjectFFRFreducedOrderInterface``) -- so Exudyn's renderer draws the deforming body. Only
triangles are drawn: a beam model (line segments only) shows no surface. Quadratic faces are
split through their mid-side nodes into flat triangles (Exudyn's route draws a hexahedron face
by its corners).

Exudyn 1.12.258 renamed ``physicsMass``, ``physicsInertia`` and ``physicsCenterOfMass`` to
``mass``, ``inertia`` and ``centerOfMass``; the archive keeps the documented ``physics*`` names
and :func:`build_exudyn_model` passes them under the new ones.

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
so :func:`build_exudyn_model` applies them through the object's ``forceUserFunction``. A body with a
surface holds ``surfaceTriangles`` (n_t × 3, mesh node indices); ``meshNodeIds`` then names each
surface node's own id.

Simulation
----------
:func:`build_exudyn_model` assembles a ready Exudyn system with the body, loads at its nodes,
displacement sensors at every frame node and either the reference frame fixed to ground
(``clamp="frame"``, for tangent-frame bodies) or a rigid joint at one node with the frame free
(``clamp="joint"``, e.g. for Buckens bodies); :func:`simulate_exudyn` integrates it in time with
Exudyn's implicit generalized-alpha solver, without console output and without files.
"""

from __future__ import annotations

import contextlib
import os
import time
import warnings
import zipfile
import zlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from pymorembs.arrays import sorted_unique
from pymorembs.errors import NumericalError, UserError
from pymorembs.export.deterministic import write_npz
from pymorembs.export.invariants import StiffeningTerms, levi_civita, skew
from pymorembs.export.nodal import node_fields

if TYPE_CHECKING:
    from pymorembs.body import ElasticBody
    from pymorembs.export.invariants import BodyInvariants

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "SATELLITE_DIRECTIONS",
    "ExudynModel",
    "ExudynResult",
    "SurfaceMesh",
    "build_exudyn_model",
    "exudyn_arrays",
    "ffrf_inertia_matrices",
    "load_exudyn_body",
    "simulate_exudyn",
    "stiffening_force",
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
_TEXT_KEYS = ("format", "bodyName")
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
}
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
    _check_arrays(arrays, "exudyn export")
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


def _check_arrays(arrays: Mapping[str, np.ndarray], where: str) -> None:
    """Raise :class:`UserError` unless ``arrays`` is a complete, consistent body."""
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
    if float(arrays["physicsMass"]) <= 0 or float(arrays["satelliteLength"]) <= 0:
        raise UserError(f"{where}: physicsMass and satelliteLength must be positive")


# ------------------------------------------------------------------------------ the file
def write_exudyn_body(
    path: str | os.PathLike[str],
    inv: BodyInvariants | Mapping[str, np.ndarray],
    satellite_length: float | None = None,
    surface: SurfaceMesh | None = None,
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

    Returns
    -------
    Path
        The written file.
    """
    if isinstance(inv, Mapping):
        arrays = {key: np.asarray(value) for key, value in inv.items()}
        _check_arrays(arrays, f"exudyn body {path}")
    else:
        arrays = exudyn_arrays(inv, satellite_length, surface)
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
    _check_arrays(arrays, where)
    return arrays


# ------------------------------------------------------------------------------ Exudyn model
#: A load: constant force (3,) in N in ground coordinates, or a function t (s) -> force (3,).
Force = Sequence[float] | np.ndarray | Callable[[float], Sequence[float] | np.ndarray]


@dataclass(eq=False)
class ExudynModel:
    """An assembled Exudyn system with one exported body.

    Attributes
    ----------
    system_container : exudyn.SystemContainer
    mbs : exudyn.MainSystem
        The assembled system.
    body : dict of str to ndarray
        The arrays of the body (:func:`exudyn_arrays`).
    clamp : str
        ``"frame"`` or ``"joint"``.
    joint_node : int or None
        Node id of the rigid joint (``clamp="joint"``).
    object_index, rigid_node, modal_node : int
        Indices of the ``ObjectFFRFreducedOrder``, its rigid-body node and its modal node.
    position_markers : dict of int to int
        Node id -> ``MarkerSuperElementPosition`` at the node.
    rigid_markers : dict of int to int
        Node id -> ``MarkerSuperElementRigid`` on the node's satellites (nodes with rotations).
    sensors : dict of int to int
        Node id -> sensor of the node's displacement in ground coordinates (m).
    frame_sensors : dict of str to int
        ``"angular_velocity"`` (ground coordinates, rad/s) and ``"rotation"`` (the rotation
        matrix, row-major) of the reference frame, ``"coordinates"``: the elastic coordinates.
    """

    system_container: Any
    mbs: Any
    body: dict[str, np.ndarray]
    clamp: str
    joint_node: int | None
    object_index: int
    rigid_node: int
    modal_node: int
    position_markers: dict[int, int] = field(default_factory=dict)
    rigid_markers: dict[int, int] = field(default_factory=dict)
    sensors: dict[int, int] = field(default_factory=dict)
    frame_sensors: dict[str, int] = field(default_factory=dict)


class ExudynResult(NamedTuple):
    """Result of :func:`simulate_exudyn`.

    Attributes
    ----------
    times : ndarray, shape (n_t,)
        Output times (s), from 0 to the end time.
    displacements : dict of int to ndarray (n_t, 3)
        Node id -> displacement of the node in ground coordinates (m): reference-frame motion plus
        elastic deformation.
    wall_time_s : float
        Wall-clock time of the time integration (s).
    angular_velocity : ndarray, shape (n_t, 3)
        Of the reference frame, ground coordinates (rad/s).
    rotation : ndarray, shape (n_t, 3, 3)
        Orientation of the reference frame (body-frame to ground coordinates).
    coordinates : ndarray, shape (n_t, nq)
        The elastic coordinates ``q``; the elastic deflection of a node in the body frame is
        its rows of ``modeBasis`` times ``q``.
    """

    times: np.ndarray
    displacements: dict[int, np.ndarray]
    wall_time_s: float
    angular_velocity: np.ndarray | None = None
    rotation: np.ndarray | None = None
    coordinates: np.ndarray | None = None


@contextlib.contextmanager
def _quiet_exudyn() -> Iterator[None]:
    """Silence Exudyn's console output (``exudyn.config.printToConsole``) for a block."""
    import exudyn

    old = exudyn.config.printToConsole
    exudyn.config.printToConsole = False
    try:
        yield
    finally:
        exudyn.config.printToConsole = old


def _body_arrays(body_data: BodyInvariants | Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    if isinstance(body_data, Mapping):
        arrays = {key: np.asarray(value) for key, value in body_data.items()}
        _check_arrays(arrays, "exudyn body")
        return arrays
    return exudyn_arrays(body_data)


def _damping_matrix(arrays: Mapping[str, np.ndarray], damping: Any) -> np.ndarray | None:
    if isinstance(damping, str):
        if damping == "exported":
            d = arrays["dampingMatrixReduced"]
            return d if np.any(d) else None
        if damping == "none":
            return None
    else:
        try:
            alpha, beta = (float(x) for x in damping)
        except (TypeError, ValueError):
            alpha = beta = float("nan")
        if np.isfinite(alpha) and np.isfinite(beta) and alpha >= 0 and beta >= 0:
            d = alpha * arrays["massMatrixReduced"] + beta * arrays["stiffnessMatrixReduced"]
            return d if np.any(d) else None
    raise UserError(
        f"exudyn model: damping must be 'exported', 'none' or (alpha 1/s, beta s) >= 0, "
        f"got {damping!r}"
    )


def _matrix_container(matrix: np.ndarray) -> Any:
    import exudyn

    container = exudyn.MatrixContainer()
    container.SetWithDenseMatrix(np.ascontiguousarray(matrix, dtype=float), useDenseMatrix=True)
    return container


def build_exudyn_model(
    body_data: BodyInvariants | Mapping[str, np.ndarray],
    *,
    clamp: str = "frame",
    joint_node: int | None = None,
    loads: Sequence[tuple[int, Force]] = (),
    damping: str | tuple[float, float] = "exported",
    gravity: Sequence[float] | None = None,
    hinge_axis: Sequence[float] | None = None,
    torques: Sequence[Force] = (),
    initial_angular_velocity: Sequence[float] | None = None,
    initial_coordinates: Sequence[float] | None = None,
) -> ExudynModel:
    """Build a ready Exudyn system with the exported body.

    The body is an ``ObjectFFRFreducedOrder`` (``computeFFRFterms=True``: the FFRF mass matrix and
    quadratic velocity terms are evaluated by Exudyn) on a ``NodeRigidBodyEP`` for the reference
    frame, placed at the ground origin with the identity orientation (ground coordinates =
    body-frame coordinates at t = 0), and a ``NodeGenericODE2`` for the elastic coordinates.

    Parameters
    ----------
    body_data : dict or BodyInvariants
        The arrays of :func:`exudyn_arrays` / :func:`load_exudyn_body`, or the invariants.
    clamp : {"frame", "joint"}
        ``"frame"``: the reference frame is fixed to ground by a ``GenericJoint`` on the rigid
        node (tangent-frame bodies: the frame node is clamped, the body deforms about it).
        ``"joint"``: the frame is free; a ``GenericJoint`` (all six axes locked) fixes the
        ``MarkerSuperElementRigid`` of ``joint_node`` to ground (e.g. Buckens bodies).
    joint_node : int, optional
        Node id of the joint; needed for ``clamp="joint"``; the node must have rotational dofs.
    loads : sequence of (node id, force)
        Forces at frame nodes in ground coordinates (N): a constant vector (3,) or a function of
        time ``t`` (s) returning one (a Python user function, evaluated every step).
    damping : "exported", "none" or (alpha, beta)
        Modal damping: the exported ``De``, none, or Rayleigh ``alpha Me + beta Ke`` (1/s, s).
    gravity : (3,) float, optional
        Gravitational acceleration in ground coordinates (m/s²), applied through Exudyn's
        ``LoadMassProportional`` (which uses ``m``, the centre of mass and ``mPhitTPsi``).
    hinge_axis : (3,) float, optional
        Make the joint of ``clamp`` a revolute joint: rotation about this axis (ground
        coordinates, through the joint point) stays free.
    torques : sequence of torque
        Torques (N m, ground coordinates; constant or functions of time) on the reference frame.
    initial_angular_velocity : (3,) float, optional
        Angular velocity of the reference frame at t = 0 (rad/s; must agree with the joint).
    initial_coordinates : (nq,) float, optional
        Elastic coordinates at t = 0.

    A body with ``stiffening*`` entries (geometric stiffening, SID_NOTES §4.6) gets the
    generalised force ``-sum_L c_L K0_L q`` on its elastic coordinates through the object's
    ``forceUserFunction``: the centrifugal cases weighted by the products of the frame's angular
    velocity, the acceleration cases by the frame's acceleration less ``gravity`` and by its
    angular acceleration, the node-force cases by the forces of ``loads`` (all in body
    coordinates; the frame's accelerations are those of the current iterate of the implicit
    solver). Joint reactions and ``torques`` on the frame node stiffen
    nothing: a tangent frame's support already carries them in the load cases.

    Returns
    -------
    ExudynModel

    Raises
    ------
    UserError
        Unknown clamp, node or damping, a joint node without rotations, or a bad load.
    """
    import exudyn
    import exudyn.itemInterface as eii

    arrays = _body_arrays(body_data)
    node_ids = [int(n) for n in arrays["nodeIds"]]
    mesh_of = dict(zip(node_ids, (int(i) for i in arrays["nodeMeshIndices"]), strict=True))
    satellites_of = {
        n: [int(i) for i in row]
        for n, row in zip(node_ids, arrays["satelliteMeshIndices"], strict=True)
        if row[0] >= 0
    }
    _check_clamp(clamp, joint_node, node_ids, satellites_of)
    damping_matrix = _damping_matrix(arrays, damping)
    forces = [_checked_force(node, force, node_ids) for node, force in loads]
    frame_torques = [_checked_vector(torque, "torque", "N m") for torque in torques]
    hinge = None
    if hinge_axis is not None:
        hinge = np.asarray(_checked_vector(hinge_axis, "hinge axis", "-"), dtype=float)
        if not np.linalg.norm(hinge) > 0:
            raise UserError("exudyn model: the hinge axis must not be zero")
        hinge = hinge / np.linalg.norm(hinge)
    g = None if gravity is None else np.asarray(gravity, dtype=float)
    if g is not None and (g.shape != (3,) or not np.all(np.isfinite(g))):
        raise UserError(f"exudyn model: gravity must be 3 finite numbers (m/s²), got {gravity!r}")
    nq = arrays["massMatrixReduced"].shape[0]
    triangles = arrays.get("surfaceTriangles")
    if triangles is not None:
        triangles = np.asarray(triangles, dtype=np.int64).tolist()

    with _quiet_exudyn():
        sc = exudyn.SystemContainer()
        mbs = sc.AddSystem()
        spin = np.zeros(3) if initial_angular_velocity is None else initial_angular_velocity
        spin = np.asarray(_checked_vector(spin, "initial angular velocity", "rad/s"))
        start = np.zeros(nq) if initial_coordinates is None else initial_coordinates
        start = np.asarray(start, dtype=float).ravel()
        if start.shape != (nq,) or not np.all(np.isfinite(start)):
            raise UserError(f"exudyn model: initial_coordinates must be {nq} finite numbers")
        rigid = mbs.AddNode(
            eii.NodeRigidBodyEP(
                referenceCoordinates=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
                # Euler parameters at p = (1, 0, 0, 0): dp/dt = (0, omega / 2)
                initialVelocities=[0.0, 0.0, 0.0, 0.0, *(0.5 * spin).tolist()],
            )
        )
        modal = mbs.AddNode(
            eii.NodeGenericODE2(
                numberOfODE2Coordinates=nq,
                referenceCoordinates=[0.0] * nq,
                initialCoordinates=start.tolist(),
                initialCoordinates_t=[0.0] * nq,
            )
        )
        extra = {}
        if any(key.startswith("stiffening") for key in arrays):
            extra["forceUserFunction"] = stiffening_force(arrays, rigid, g, forces)
        obj = mbs.AddObject(
            eii.ObjectFFRFreducedOrder(
                name=str(arrays["bodyName"]),
                nodeNumbers=[rigid, modal],
                massMatrixReduced=_matrix_container(arrays["massMatrixReduced"]),
                stiffnessMatrixReduced=_matrix_container(arrays["stiffnessMatrixReduced"]),
                dampingMatrixReduced=(
                    [] if damping_matrix is None else _matrix_container(damping_matrix)
                ),
                modeBasis=arrays["modeBasis"],
                referencePositions=arrays["referencePositions"],
                # physicsMass/-Inertia/-CenterOfMass are named mass/inertia/centerOfMass since
                # Exudyn 1.12.258
                mass=float(arrays["physicsMass"]),
                inertia=arrays["physicsInertia"],
                centerOfMass=arrays["physicsCenterOfMass"],
                mPsiTildePsi=arrays["mPsiTildePsi"],
                mPsiTildePsiTilde=arrays["mPsiTildePsiTilde"],
                mPhitTPsi=arrays["mPhitTPsi"],
                mPhitTPsiTilde=arrays["mPhitTPsiTilde"],
                mXRefTildePsi=arrays["mXRefTildePsi"],
                mXRefTildePsiTilde=arrays["mXRefTildePsiTilde"],
                computeFFRFterms=True,
                # Exudyn's renderer draws the deforming surface as its FEM route does
                # (ObjectFFRFreducedOrderInterface: triangleMesh = the surface triangles)
                visualization=eii.VObjectFFRFreducedOrder(
                    show=triangles is not None, triangleMesh=[] if triangles is None else triangles
                ),
                **extra,
            )
        )
        model = ExudynModel(sc, mbs, arrays, clamp, joint_node, obj, rigid, modal)
        for n in node_ids:
            model.position_markers[n] = mbs.AddMarker(
                eii.MarkerSuperElementPosition(
                    bodyNumber=obj, meshNodeNumbers=[mesh_of[n]], weightingFactors=[1.0]
                )
            )
            model.sensors[n] = mbs.AddSensor(
                eii.SensorSuperElement(
                    bodyNumber=obj,
                    meshNodeNumber=mesh_of[n],
                    outputVariableType=exudyn.OutputVariableType.Displacement,
                    writeToFile=False,
                    storeInternal=True,
                )
            )
        for n, satellites in satellites_of.items():
            model.rigid_markers[n] = mbs.AddMarker(
                eii.MarkerSuperElementRigid(
                    bodyNumber=obj, meshNodeNumbers=satellites, weightingFactors=[1.0 / 6.0] * 6
                )
            )

        ground = mbs.AddObject(eii.ObjectGround())
        if clamp == "frame":
            body_marker = mbs.AddMarker(eii.MarkerNodeRigid(nodeNumber=rigid))
            ground_position = np.zeros(3)
        else:
            body_marker = model.rigid_markers[int(joint_node)]
            first = 3 * mesh_of[int(joint_node)]
            ground_position = arrays["referencePositions"][first : first + 3]
        ground_marker = mbs.AddMarker(
            eii.MarkerBodyRigid(
                bodyNumber=ground, localPosition=[float(x) for x in ground_position]
            )
        )
        joint = {"constrainedAxes": [1, 1, 1, 1, 1, 1]}
        if hinge is not None:  # joint frames with z along the hinge: rotation about z free
            frame = _frame_with_z(hinge).tolist()
            joint = {"constrainedAxes": [1, 1, 1, 1, 1, 0], "rotationMarker0": frame,
                     "rotationMarker1": frame}  # fmt: skip
        with warnings.catch_warnings():  # rotationMarker0/1: deprecated, supported until 2031
            warnings.simplefilter("ignore", DeprecationWarning)
            mbs.AddObject(
                eii.GenericJoint(
                    markerNumbers=[ground_marker, body_marker],
                    visualization=eii.VGenericJoint(show=False),
                    **joint,
                )
            )
        for node, force in forces:
            mbs.AddLoad(_force_load(eii, model.position_markers[node], force))
        if frame_torques:
            frame_marker = mbs.AddMarker(eii.MarkerNodeRigid(nodeNumber=rigid))
            for torque in frame_torques:
                mbs.AddLoad(_force_load(eii, frame_marker, torque, kind="torque"))
        for key, node, variable in (
            ("angular_velocity", rigid, exudyn.OutputVariableType.AngularVelocity),
            ("rotation", rigid, exudyn.OutputVariableType.RotationMatrix),
            ("coordinates", modal, exudyn.OutputVariableType.Coordinates),
        ):
            model.frame_sensors[key] = mbs.AddSensor(
                eii.SensorNode(
                    nodeNumber=node,
                    outputVariableType=variable,
                    writeToFile=False,
                    storeInternal=True,
                )
            )
        if g is not None:
            mass_marker = mbs.AddMarker(eii.MarkerBodyMass(bodyNumber=obj))
            mbs.AddLoad(eii.LoadMassProportional(markerNumber=mass_marker, loadVector=list(g)))
        mbs.Assemble()
    return model


def _check_clamp(
    clamp: str, joint_node: int | None, node_ids: list[int], satellites_of: dict
) -> None:
    if clamp == "frame":
        if joint_node is not None:
            raise UserError("exudyn model: joint_node is only used with clamp='joint'")
        return
    if clamp != "joint":
        raise UserError(f"exudyn model: clamp must be 'frame' or 'joint', got {clamp!r}")
    if joint_node is None:
        raise UserError("exudyn model: clamp='joint' needs joint_node")
    if int(joint_node) not in node_ids:
        raise UserError(
            f"exudyn model: joint node {joint_node} is not a frame node of the body "
            f"(nodes: {node_ids})"
        )
    if int(joint_node) not in satellites_of:
        raise UserError(
            f"exudyn model: joint node {joint_node} has no rotational dofs, so a rigid joint "
            "cannot act on it; export a node with rotations (e.g. an RBE2 interface node)"
        )


def _euler_parameter_rotation(p: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3), body to ground, of the Euler parameters ``p = (p0, p1, p2, p3)``."""
    p0, p1, p2, p3 = p
    return 2.0 * np.array(
        [
            [p0 * p0 + p1 * p1 - 0.5, p1 * p2 - p0 * p3, p1 * p3 + p0 * p2],
            [p1 * p2 + p0 * p3, p0 * p0 + p2 * p2 - 0.5, p2 * p3 - p0 * p1],
            [p1 * p3 - p0 * p2, p2 * p3 + p0 * p1, p0 * p0 + p3 * p3 - 0.5],
        ]
    )


def stiffening_force(
    arrays: Mapping[str, np.ndarray],
    rigid: int,
    gravity: Sequence[float] | None = None,
    forces: Sequence[tuple[int, Any]] = (),
) -> Callable[..., list[float]]:
    """``forceUserFunction`` of the geometric stiffening (SID_NOTES §4.6) of an exported body.

    For a body placed in one's own Exudyn system: pass the result as ``forceUserFunction`` of
    its ``ObjectFFRFreducedOrder`` (:func:`build_exudyn_model` does).

    Parameters
    ----------
    arrays : dict
        The body (:func:`load_exudyn_body`) with its ``stiffening*`` entries.
    rigid : int
        Exudyn node number of the body's reference node (``NodeRigidBodyEP``).
    gravity : (3,) float, optional
        Gravitational acceleration in ground coordinates (m/s²) as applied to the body.
    forces : sequence of (node id, force)
        The forces applied at frame nodes, in ground coordinates (N): constant (3,) or a
        function of time returning one.

    The generalised force on the elastic coordinates is ``-(sum_m Omega_m K0_m + sum_a c_a K0_a
    + sum_a alpha_a K0_al,a + sum_(n,a) f_na K0_na) q``, all in body coordinates: ``Omega_m``
    the six products of the frame's angular velocity ``2 G(p) dp/dt`` (order of
    :data:`CENTRIFUGAL_CASES`); ``c = A^T (r'' - g)`` the frame's acceleration less gravity (the
    load case ``ax`` is the d'Alembert load of a unit frame acceleration, and gravity ``g`` loads
    the body as a frame acceleration ``-g`` does); ``alpha = A^T alpha_ground`` the angular
    acceleration; ``f_n = A^T F_n(t)`` the forces applied at frame nodes. The accelerations are
    the reference node's of the current iterate (Exudyn's ``Current`` configuration), so the
    implicit solver iterates them to convergence with the rest of the step. The object's
    coordinates are the reference node's (3 positions, 4 Euler parameters as displacements from
    (1, 0, 0, 0)) followed by the elastic coordinates.
    """
    import exudyn

    nq = arrays["massMatrixReduced"].shape[0]

    def flat(key: str) -> np.ndarray | None:
        value = arrays.get(key)
        if value is None or not np.any(value):
            return None
        return np.asarray(value, dtype=float).reshape(-1, nq * nq)

    omega_k0 = flat("stiffeningOmega")
    acceleration_k0 = flat("stiffeningAcceleration")
    angular_k0 = flat("stiffeningAngularAcceleration")
    node_k0 = flat("stiffeningNodeForces")
    index_of = {int(n): i for i, n in enumerate(arrays["nodeIds"])}
    node_terms = []
    if node_k0 is not None:
        node_terms = [
            (node_k0[3 * index_of[int(n)] : 3 * index_of[int(n)] + 3], f) for n, f in forces
        ]
    g = np.zeros(3) if gravity is None else np.asarray(gravity, dtype=float)
    current = exudyn.ConfigurationType.Current
    kinds = exudyn.OutputVariableType

    def force(mbs: Any, t: float, index: int, q: Any, q_t: Any) -> list[float]:
        q, q_t = np.asarray(q), np.asarray(q_t)
        p = np.array([1.0, 0.0, 0.0, 0.0]) + q[3:7]
        p0, p1, p2, p3 = p
        gp = np.array([[-p1, p0, p3, -p2], [-p2, -p3, p0, p1], [-p3, p2, -p1, p0]])
        rotation = _euler_parameter_rotation(p)
        weights = np.zeros(nq * nq)
        if omega_k0 is not None:
            wx, wy, wz = 2.0 * gp @ q_t[3:7]
            weights += np.array([wx * wx, wy * wy, wz * wz, wx * wy, wy * wz, wx * wz]) @ omega_k0
        if acceleration_k0 is not None:
            a = np.asarray(mbs.GetNodeOutput(rigid, kinds.Acceleration, configuration=current))
            weights += (rotation.T @ (a - g)) @ acceleration_k0
        if angular_k0 is not None:
            alpha = mbs.GetNodeOutput(rigid, kinds.AngularAcceleration, configuration=current)
            weights += (rotation.T @ np.asarray(alpha)) @ angular_k0
        for k0, f in node_terms:
            weights += (rotation.T @ np.asarray(f(t) if callable(f) else f, dtype=float)) @ k0
        out = np.zeros(q.size)
        out[7:] = -(weights.reshape(nq, nq) @ q[7:])
        return out.tolist()

    return force


def _frame_with_z(axis: np.ndarray) -> np.ndarray:
    """A rotation matrix whose third column is the unit vector ``axis``."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(axis, x), axis])


def _checked_vector(value: Force, what: str, unit: str) -> Any:
    """A constant vector (3,) as ndarray, or a function of time returning one (checked at 0)."""
    if callable(value):
        try:
            probe = np.asarray(value(0.0), dtype=float)
        except Exception as exc:
            raise UserError(f"exudyn model: the {what} (a function of time) fails: {exc}") from None
        if probe.shape != (3,):
            raise UserError(
                f"exudyn model: the {what} (a function of time) returns shape {probe.shape}, "
                "expected (3,)"
            )
        return value
    try:
        vector = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        vector = np.full(0, np.nan)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise UserError(f"exudyn model: the {what} must be 3 finite numbers ({unit})")
    return vector


def _checked_force(node: int, force: Force, node_ids: list[int]) -> tuple[int, Any]:
    """``(node id, force)`` with a constant force as ndarray (3,); checks node and shape."""
    if int(node) not in node_ids:
        raise UserError(
            f"exudyn model: load at node {node}, which is not a frame node of the body "
            f"(nodes: {node_ids})"
        )
    return int(node), _checked_vector(force, f"load at node {node}", "N")


def _force_load(eii: Any, marker: int, force: Any, kind: str = "force") -> Any:
    """A ``LoadForceVector`` (or ``LoadTorqueVector``) in ground directions: constant, or a
    Python user function of t."""
    load = eii.LoadForceVector if kind == "force" else eii.LoadTorqueVector
    if not callable(force):
        return load(markerNumber=marker, loadVector=[float(x) for x in force])

    def user_function(mbs: Any, t: float, load_vector: Any) -> list[float]:
        return [float(x) for x in np.asarray(force(t), dtype=float)]

    return load(
        markerNumber=marker, loadVector=[0.0, 0.0, 0.0], loadVectorUserFunction=user_function
    )


def simulate_exudyn(
    model: ExudynModel,
    duration_s: float,
    step_s: float,
    nodes: Sequence[int] | None = None,
    *,
    spectral_radius: float = 0.9,
) -> ExudynResult:
    """Integrate the model in time with Exudyn's implicit generalized-alpha solver.

    Constant step size ``step_s`` (the end time is ``duration_s`` rounded to whole steps);
    Newton iterations to Exudyn's default tolerances. Every call starts again from the model's
    initial state (at rest). No console output, no solution, sensor or solver-information files.

    Parameters
    ----------
    model : ExudynModel
        From :func:`build_exudyn_model`.
    duration_s, step_s : float
        End time and step size (s).
    nodes : sequence of int, optional
        Node ids whose displacement to return; default: all frame nodes.
    spectral_radius : float
        Spectral radius at infinity of generalized-alpha (1: no numerical damping).

    Returns
    -------
    ExudynResult
        Times (s) and node displacements in ground coordinates (m) at every step, wall time (s).

    Raises
    ------
    UserError
        Bad times or an unknown node.
    NumericalError
        The solver fails.
    """
    import exudyn

    if not (np.isfinite(duration_s) and np.isfinite(step_s) and 0 < step_s <= duration_s):
        raise UserError(
            f"exudyn simulation: need 0 < step_s <= duration_s, got {step_s!r}, {duration_s!r}"
        )
    wanted = list(model.sensors) if nodes is None else [int(n) for n in nodes]
    unknown = [n for n in wanted if n not in model.sensors]
    if unknown:
        raise UserError(f"exudyn simulation: node {unknown[0]} is not a frame node of the body")
    n_steps = round(duration_s / step_s)
    settings = exudyn.SimulationSettings()
    ti = settings.timeIntegration
    ti.endTime = n_steps * step_s
    ti.numberOfSteps = n_steps
    ti.automaticStepSize = False
    ti.adaptiveStep = False
    ti.verboseMode = 0
    ti.verboseModeFile = 0
    ti.generalizedAlpha.spectralRadius = float(spectral_radius)
    settings.solution.file.write = False
    settings.solution.restart.write = False
    settings.solution.sensors.active = True
    settings.solution.sensors.writePeriod = step_s
    settings.show.computationTime = False
    settings.show.globalTimers = False
    settings.show.statistics = False
    with _quiet_exudyn():
        start = time.perf_counter()
        try:
            ok = model.mbs.SolveDynamic(settings, storeSolver=False)
        except exudyn.SolverError as exc:
            raise NumericalError(
                f"exudyn simulation: the time integration failed ({exc})"
            ) from None
        wall = time.perf_counter() - start
    if not ok:
        raise NumericalError("exudyn simulation: the time integration failed")
    displacements = {}
    times = np.zeros(0)
    for n in wanted:
        data = np.asarray(model.mbs.GetSensorStoredData(model.sensors[n]))
        times, displacements[n] = data[:, 0], data[:, 1:4]
    frame = {
        key: np.asarray(model.mbs.GetSensorStoredData(sensor))[:, 1:]
        for key, sensor in model.frame_sensors.items()
    }
    rotation = frame.get("rotation")
    return ExudynResult(
        times,
        displacements,
        wall,
        frame.get("angular_velocity"),
        None if rotation is None else rotation.reshape(-1, 3, 3),
        frame.get("coordinates"),
    )
