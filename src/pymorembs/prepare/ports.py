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
    directions : tuple of int
        Direction codes 0..5 (ux uy uz rx ry rz).
    """

    node: int
    directions: tuple[int, ...]

    @classmethod
    def parse(cls, node: int, directions: str | list[str]) -> Port:
        return cls(int(node), tuple(parse_directions(directions)))

    def labels(self) -> list[str]:
        return [f"{self.node}:{DIRECTIONS[d]}" for d in self.directions]


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
