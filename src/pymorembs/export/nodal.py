"""Vectors over the dofs of a body as fields over its nodes (what a viewer colours and moves).

A shape function or a static response is a column over the equations of the body (its dof
table: node id and direction of each row). A viewer wants it per node: a translation vector
``(ux, uy, uz)`` and, for nodes with rotational dofs, a rotation vector ``(rx, ry, rz)``. A
direction the node does not have (a solid node has no rotations, a 2D model no ``uz``) is 0;
scalar coordinates (direction ``q``) belong to no node and are left out.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError

__all__ = ["NodeFields", "node_fields"]


class NodeFields(NamedTuple):
    """Columns over the dofs of a body, per node.

    Attributes
    ----------
    node_ids : ndarray of int, shape (n_nodes,)
        The nodes, in the order of the rows.
    translations : ndarray, shape (n_nodes, 3, k)
        ``ux uy uz`` of each node for each column (0 where the node has no such dof).
    rotations : ndarray, shape (n_nodes, 3, k), or None
        ``rx ry rz`` likewise; None when no node has a rotational dof.
    """

    node_ids: np.ndarray
    translations: np.ndarray
    rotations: np.ndarray | None


def node_fields(
    body: ElasticBody, vectors: np.ndarray, nodes: np.ndarray | None = None
) -> NodeFields:
    """The columns of ``vectors`` as translation (and rotation) fields of the body's nodes.

    Parameters
    ----------
    body : ElasticBody
        Its dof table maps the rows of ``vectors`` to (node, direction).
    vectors : ndarray, shape (n_dof, k)
        Columns over all equations of ``body`` (e.g. a basis expanded by
        :meth:`~pymorembs.preparation.PreparedModel.expand`).
    nodes : ndarray of int, shape (n,), optional
        Node ids to take (default: all nodes of the body, in the order of ``body.node_ids``).

    Returns
    -------
    NodeFields

    Raises
    ------
    UserError
        ``vectors`` does not have one row per equation of the body.
    """
    vectors = np.asarray(vectors, dtype=float)
    if vectors.ndim != 2 or vectors.shape[0] != body.n_dof:
        raise UserError(
            f"node fields: vectors have shape {vectors.shape}, expected ({body.n_dof}, k)"
        )
    ids = body.node_ids if nodes is None else np.asarray(nodes, dtype=np.int64).ravel()
    rows = body.dofs.positions(ids[:, None], np.arange(6)[None, :])  # (n, 6), -1: no such dof
    present = rows >= 0
    values = np.where(present[:, :, None], vectors[np.maximum(rows, 0)], 0.0)  # (n, 6, k)
    rotations = values[:, 3:] if present[:, 3:].any() else None
    return NodeFields(ids, values[:, :3], rotations)
