"""The tangent reference frame (paper section 2.1).

A tangent frame identifies the floating reference frame with the body frame at one node
(``R_0 = 0``): the coordinates are translated to that node, and the node's dofs are fixed
(``Phi(R_0) = 0``), so every shape function, and thus every column of V and W, vanishes there.
"""

from __future__ import annotations

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError


def tangent_frame(body: ElasticBody, node: int) -> ElasticBody:
    """The body with its coordinates measured from ``node`` and that node's dofs fixed.

    Parameters
    ----------
    body : ElasticBody
    node : int
        Node id of the reference node. It must carry independent dofs: a node whose dofs are
        dependent (tied by constraint equations) cannot be the frame node -- use the node it is
        tied to.
    """
    origin = body.node_position(node)
    indices = body.dofs.of_node(node)
    if indices.size == 0:
        raise UserError(f"frame node {node} has no dofs in the model")
    tied = set(indices.tolist()) & set(body.constraints.dependent.tolist())
    if tied:
        raise UserError(
            f"frame node {node} has dependent dofs ({body.dofs.label(min(tied))}); "
            "place the tangent frame at the node they are tied to"
        )
    return body.translated(origin).with_fixed(indices)
