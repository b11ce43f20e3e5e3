"""Inputs and outputs of the elastic body by node and direction (paper section 2.3).

A port is one node and a list of directions; each (node, direction) becomes a column of the input
matrix ``B_e`` with a 1 at the dof's equation (``B_e(q_global_input(j), j) = 1``), or a row of the
output matrix ``C_e``. Ports are looked up in the dof table, so node ids are those of the FE
program.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from pymorembs.body import DIRECTIONS, ElasticBody, parse_directions
from pymorembs.errors import UserError


@dataclass(frozen=True)
class Port:
    """One node with the directions of its forces (inputs) or displacements (outputs).

    Parameters
    ----------
    node : int
        Node id as in the FE model.
    directions : tuple of int, or str
        Direction codes 0..6 (ux uy uz rx ry rz q), or their names as :func:`Port.parse`
        takes them (``"ux uy uz"``, ``["ux", "uy"]``, ``"translations"``); stored as codes.

    Raises
    ------
    UserError
        A node that is not a whole number, no direction, an unknown or repeated direction.
    """

    node: int
    directions: tuple[int, ...]

    def __post_init__(self) -> None:
        node = self.node
        if isinstance(node, bool) or not _is_number(node) or not float(node).is_integer():
            raise UserError(f"Port: the node must be a node id (a whole number), got {node!r}")
        directions = self.directions
        if isinstance(directions, str) or any(isinstance(d, str) for d in directions):
            codes = parse_directions(directions)
        else:
            codes = [int(d) for d in directions]
            if not codes or len(set(codes)) != len(codes):
                raise UserError(f"Port {node}: no direction or a direction repeated in {codes}")
            if any(c < 0 or c >= len(DIRECTIONS) for c in codes):
                raise UserError(
                    f"Port {node}: direction codes are 0..{len(DIRECTIONS) - 1} "
                    f"({' '.join(DIRECTIONS)}), got {codes}"
                )
        object.__setattr__(self, "node", int(node))
        object.__setattr__(self, "directions", tuple(codes))

    @classmethod
    def parse(cls, node: int, directions: str | list[str]) -> Port:
        return cls(int(node), tuple(parse_directions(directions)))

    def labels(self) -> list[str]:
        return [f"{self.node}:{DIRECTIONS[d]}" for d in self.directions]


def _is_number(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating)


def selection_matrix(body: ElasticBody, ports: list[Port]) -> tuple[sp.csr_matrix, list[str]]:
    """Selection matrix of all dofs, shape (n_dof, p), and the labels of its columns.

    Transpose it for an output matrix. A (node, direction) listed twice is a user error.
    """
    indices: list[int] = []
    labels: list[str] = []
    for port in ports:
        for code, label in zip(port.directions, port.labels(), strict=True):
            if label in labels:
                raise UserError(f"port {label} is listed twice")
            indices.append(body.dofs.index(port.node, code))
            labels.append(label)
    if not indices:
        raise UserError("no input or output given")
    idx = np.array(indices, dtype=np.int64)
    matrix = sp.csr_matrix(
        (np.ones(idx.size), (idx, np.arange(idx.size))), shape=(body.n_dof, idx.size)
    )
    return matrix, labels
