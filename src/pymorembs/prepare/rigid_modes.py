"""Rigid-body motions a prepared body can still perform (a mechanism of the chosen frame).

A tangent frame fixes the dofs of one node. At a node of a solid model, which has only ux uy uz,
that fixes the translations but leaves the three rotations about the node free: the stiffness of
the independent dofs is singular, and every solve with it silently returns garbage (LU with
pivoting is backward stable, so a residual check cannot notice). This module finds such motions
before anything is factorized.
"""

from __future__ import annotations

import numpy as np

from pymorembs.body import ElasticBody
from pymorembs.prepare.elimination import Elimination
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
#: ... and carries no strain energy when ``|K r| / (|K| |r|)`` is below this.
ENERGY_TOL = 1e-10


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

    A combination ``r = R a`` of the six rigid-body fields (about the coordinate origin) survives
    when it vanishes on the fixed dofs and satisfies the constraint equations, ``T r_i = r``; it
    is free when the stiffness of the independent dofs does no work on it, ``K* r_i = 0``
    (springs to ground would resist it).

    Returns
    -------
    labels : list of str
        One per free motion: the axis when the motion is along one, else its components.
    motions : ndarray, shape (n_independent, r)
        The free motions on the independent dofs (orthonormal combinations of the rigid fields).
    """
    rigid = body.rigid_body_modes()
    norms = np.linalg.norm(rigid, axis=0)
    present = norms > 0
    rigid = rigid[:, present] / norms[present]
    names = [name for name, keep in zip(NAMES, present, strict=True) if keep]
    on_independent = rigid[elimination.independent]
    admissibility = np.vstack(
        [
            rigid[elimination.fixed],
            elimination.transform @ on_independent - rigid,
        ]
    )
    k = rigid.shape[1]
    if admissibility.shape[0] < k:  # pad to a square system: the null space stays the same
        admissibility = np.vstack([admissibility, np.zeros((k - admissibility.shape[0], k))])
    triangle = np.linalg.qr(admissibility, mode="r")  # k x k: no n x n factor is ever formed
    _, sigma, vt = np.linalg.svd(triangle)
    null = vt[sigma < KINEMATIC_TOL].T
    none = ([], np.zeros((elimination.n_independent, 0)))
    if null.shape[1] == 0:
        return none
    motions = on_independent @ null
    stiffness = system.stiffness
    scale = float(abs(stiffness).sum(axis=1).max()) or 1.0
    work = np.linalg.norm(stiffness @ motions, axis=0) / (scale * np.linalg.norm(motions, axis=0))
    free = null[:, work < ENERGY_TOL]
    if free.shape[1] == 0:
        return none
    # name each free motion by its axis if it is (nearly) one, else by its components
    labels = []
    basis, _ = np.linalg.qr(free)
    for k in range(basis.shape[1]):
        weights = np.abs(basis[:, k])
        axes = [names[j] for j in np.flatnonzero(weights > 0.3 * weights.max())]
        labels.append(" + ".join(axes))
    if basis.shape[1] == len(names):
        labels = list(names)
    return labels, on_independent @ basis
