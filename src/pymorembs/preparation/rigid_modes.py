"""Rigid-body motions a prepared body can still perform (a mechanism of the chosen frame).

A tangent frame fixes the dofs of one node. At a node of a solid model, which has only ux uy uz,
that fixes the translations but leaves the three rotations about the node free: the stiffness of
the independent dofs is singular, and every solve with it silently returns garbage (LU with
pivoting is backward stable, so a residual check cannot notice). This module finds such motions
before anything is factorized.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pymorembs.body import ElasticBody
from pymorembs.linalg.rounding import relative_rounding
from pymorembs.preparation.elimination import Elimination
from pymorembs.system import SecondOrderSystem

NAMES = (
    "translation x",
    "translation y",
    "translation z",
    "rotation about x",
    "rotation about y",
    "rotation about z",
)
#: A combination of rigid modes is kinematically admissible below this residual.
KINEMATIC_TOL = 1e-9
#: ... and carries no strain energy when ``|K r| / (|K| |r|)`` is below this, or below
#: :data:`ROUNDED_ENERGY_FACTOR` times the relative rounding of a file's entries
#: (:func:`~pymorembs.linalg.rounding.relative_rounding`).
ENERGY_TOL = 1e-10
ROUNDED_ENERGY_FACTOR = 100.0


@dataclass(frozen=True, eq=False)
class AdmissibleFields:
    """The rigid-body motions the fixed dofs and constraints of a prepared body admit.

    Attributes
    ----------
    fields : ndarray, shape (n_independent, a)
        Orthonormal combinations of the rigid-body fields (on the independent dofs) that vanish
        on the fixed dofs and satisfy the constraint equations (``T r_i = r``).
    coefficients : ndarray, shape (p, a)
        The combinations, in terms of the ``p`` rigid-body fields the dof table has.
    names : tuple of str
        Names of those ``p`` fields (:data:`NAMES`).
    """

    fields: np.ndarray
    coefficients: np.ndarray
    names: tuple[str, ...]

    def labels(self, combination: np.ndarray) -> list[str]:
        """A name per column of ``fields @ combination``: its axes, or all six names."""
        weights_all = self.coefficients @ combination
        if weights_all.shape[1] == len(self.names) == len(NAMES):
            return list(NAMES)
        basis, _ = np.linalg.qr(weights_all)
        labels = []
        for k in range(basis.shape[1]):
            weights = np.abs(basis[:, k])
            axes = [self.names[j] for j in np.flatnonzero(weights > 0.3 * weights.max())]
            labels.append(" + ".join(axes))
        return labels


def admissible_rigid_fields(body: ElasticBody, elimination: Elimination) -> AdmissibleFields:
    """The rigid-body fields (about the coordinate origin: a tangent frame's node) that survive
    fixed dofs and constraints, without looking at the stiffness (see :class:`AdmissibleFields`).
    """
    rigid = body.rigid_body_modes()
    norms = np.linalg.norm(rigid, axis=0)
    present = norms > 0
    rigid = rigid[:, present] / norms[present]
    names = tuple(name for name, keep in zip(NAMES, present, strict=True) if keep)
    on_independent = rigid[elimination.independent]
    # a fixed dof that nothing couples to (an empty row and column, e.g. a rotation of a grid
    # that only solid elements use, fixed as Nastran's AUTOSPC does) holds nothing back
    coupled = (_touched(body.stiffness) | _touched(body.mass))[elimination.fixed]
    unfixed = np.ones(body.n_dof, dtype=bool)
    unfixed[elimination.fixed] = False  # the constraint equations, on the dofs that are not fixed
    admissibility = np.vstack(
        [
            rigid[elimination.fixed[coupled]],
            (elimination.transform @ on_independent - rigid)[unfixed],
        ]
    )
    k = rigid.shape[1]
    if admissibility.shape[0] < k:  # pad to a square system: the null space stays the same
        admissibility = np.vstack([admissibility, np.zeros((k - admissibility.shape[0], k))])
    triangle = np.linalg.qr(admissibility, mode="r")  # k x k: no n x n factor is ever formed
    _, sigma, vt = np.linalg.svd(triangle)
    null = vt[sigma < KINEMATIC_TOL].T
    return AdmissibleFields(on_independent @ null, null, names)


def _touched(matrix) -> np.ndarray:
    """Boolean mask of the equations with an entry in their row or column."""
    coo = matrix.tocoo()
    mask = np.zeros(matrix.shape[0], dtype=bool)
    mask[coo.row[coo.data != 0]] = True
    mask[coo.col[coo.data != 0]] = True
    return mask


def free_rigid_body_modes(
    body: ElasticBody, elimination: Elimination, system: SecondOrderSystem
) -> list[str]:
    """Names of the rigid-body motions that survive fixed dofs and constraints, unresisted.

    See :func:`free_rigid_body_motions`, which also returns the motions.
    """
    return free_rigid_body_motions(body, elimination, system)[0]


def free_rigid_body_motions(
    body: ElasticBody, elimination: Elimination, system: SecondOrderSystem
) -> tuple[list[str], np.ndarray]:
    """The rigid-body motions that survive fixed dofs and constraints, unresisted.

    A combination ``r = R a`` of the six rigid-body fields survives when it vanishes on the
    fixed dofs and satisfies the constraint equations, ``T r_i = r``
    (:func:`admissible_rigid_fields`); it is free when the stiffness of the independent dofs
    does no work on it, ``K* r_i = 0`` (springs to ground would resist it).

    Returns
    -------
    labels : list of str
        One per free motion: the axis when the motion is along one, else its components.
    motions : ndarray, shape (n_independent, r)
        The free motions on the independent dofs (orthonormal combinations of the rigid fields).
    """
    admissible = admissible_rigid_fields(body, elimination)
    none = ([], np.zeros((elimination.n_independent, 0)))
    motions = admissible.fields
    if motions.shape[1] == 0:
        return none
    stiffness = system.stiffness
    scale = float(abs(stiffness).sum(axis=1).max()) or 1.0
    work = np.linalg.norm(stiffness @ motions, axis=0) / (scale * np.linalg.norm(motions, axis=0))
    # entries rounded to a few digits (a 10-digit punch) break K r = 0 at their rounding level
    eps, _ = relative_rounding(body.stiffness, body.mass, body.precision)
    free = work < max(ENERGY_TOL, ROUNDED_ENERGY_FACTOR * eps)
    if not free.any():
        return none
    combination, _ = np.linalg.qr(np.eye(motions.shape[1])[:, free])
    return admissible.labels(combination), motions @ combination
