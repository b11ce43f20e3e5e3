"""The tangent reference frame (paper section 2.1).

A tangent frame identifies the floating reference frame with the body frame at one node
(``R_0 = 0``): the coordinates are translated to that node, and the node's motion is suppressed
(``Phi(R_0) = 0``), so every shape function, and thus every column of V and W, vanishes there.

For a node with independent dofs this fixes them (eq. 10). A node whose dofs are dependent --
e.g. an RBE3-like interface node, which follows the area it is coupled to -- cannot simply be
fixed; instead ``q_node = T_node q_i + t_node = 0`` is imposed by making as many well-chosen
independent dofs dependent (column-pivoted QR of ``T_node``), so that the node's own constraint
equations then evaluate to zero.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from pymorembs.body import ConstraintEquations, ElasticBody
from pymorembs.errors import UserError
from pymorembs.preparation.elimination import eliminate


def tangent_frame(body: ElasticBody, node: int) -> ElasticBody:
    """The body with its coordinates measured from ``node`` and that node held.

    Parameters
    ----------
    body : ElasticBody
    node : int
        Node id of the reference node.
    """
    origin = body.node_position(node)
    indices = body.dofs.of_node(node)
    if indices.size == 0:
        raise UserError(f"frame node {node} has no dofs in the model")
    moved = body.translated(origin)
    dependent = np.isin(indices, body.constraints.dependent)
    if np.any(dependent) and not np.all(dependent):
        raise UserError(f"frame node {node} has both dependent and independent dofs")
    if not np.any(dependent):
        return moved.with_fixed(indices)
    return _hold_dependent(moved, node, indices)


def _hold_dependent(body: ElasticBody, node: int, indices: np.ndarray) -> ElasticBody:
    """Impose ``q = 0`` on the dependent dofs ``indices`` by new constraint equations."""
    elimination = eliminate(body)
    rows = sp.csr_matrix(elimination.transform[indices])  # q_node = A q_i + t_node
    offset = elimination.offset[indices]
    columns = np.unique(rows.indices)
    dense = rows[:, columns].toarray()
    _, r, pivots = sla.qr(dense, mode="economic", pivoting=True)
    rank = int(np.count_nonzero(np.abs(np.diag(r)) > 1e-10 * abs(r[0, 0]))) if r.size else 0
    if rank < len(indices):
        raise UserError(
            f"frame node {node}: its dofs depend on too few independent dofs to be held "
            f"(rank {rank} of {len(indices)})"
        )
    chosen = pivots[: len(indices)]
    rest = np.setdiff1d(np.arange(columns.size), chosen)
    inverse = np.linalg.inv(dense[:, chosen])
    # A_c q_c + A_r q_r + t = 0  ->  q_c = -A_c^-1 A_r q_r - A_c^-1 t
    coefficients = -inverse @ dense[:, rest]
    dependent = elimination.independent[columns[chosen]]
    targets = elimination.independent[columns[rest]]
    k, m = coefficients.shape
    matrix = sp.csr_matrix(
        (coefficients.ravel(), (np.repeat(np.arange(k), m), np.tile(targets, k))),
        shape=(k, body.n_dof),
    )
    old = body.constraints
    return replace(
        body,
        constraints=ConstraintEquations(
            np.concatenate([old.dependent, dependent]),
            sp.vstack([old.matrix, matrix]),
            np.concatenate([old.offset, -inverse @ offset]),
        ),
    )
