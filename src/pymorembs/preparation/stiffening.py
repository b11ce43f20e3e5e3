"""Geometric stiffening of the elastic body under the loads of the moving frame (SID_NOTES §4.6).

A rotating or accelerated body is prestressed by its own inertia loads: the centrifugal load of
a spinning blade puts it in tension, which stiffens bending (a blade's first flapwise frequency
at the speed of its non-rotating frequency rises by about 48 %). For every unit load case ``L``
of the frame motion (the d'Alembert loads of :mod:`pymorembs.preparation.inertia_loads`, SID_NOTES
§4.6: ``ax .. az``, ``alx .. alz``, ``wxx .. wxz``) and for unit forces (and moments) at the
frame nodes of the exported body, the geometric stiffness ``K_G(sigma_L)`` of the prestress is
formed on the independent dofs; the exported body gets its projection ``K0_L = V^T K_G V``
(linear in the load: a frame motion with accelerations ``a`` and angular velocity products
``Omega`` stiffens the body by ``sum_L c_L K0_L``).

Sources (``[stiffening] source``):

``"mesh"``
    The body's own elements (:class:`~pymorembs.body.ElementMesh`: the built-in models, or the
    solid elements and material read with an Abaqus ``.inp``, Nastran bulk data or Ansys
    ``.cdb``, :mod:`pymorembs.io.solid_mesh`): ``u_L = K^+ f_L`` with the support of the
    frame (the same static solve as the basis: fixed frame dofs, or inertia relief in the
    Buckens frame), the stresses of ``u_L`` at the Gauss points and the initial-stress matrix
    of every element.
``"matrices"``
    One Matrix Market file per load case, in the model's equation order: ``K_G`` itself, or
    the stiffness of a prestressed run (``kind = "prestressed"``: ``K_G = K_pre - K``). Forces
    at the frame nodes then have no stiffening (no matrices for them).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from pymorembs.body import ElasticBody
from pymorembs.elements.beam import batch_geometric_matrices
from pymorembs.elements.solid import (
    SOLID_KINDS,
    part,
    solid_geometric_matrices,
    solid_stresses,
)
from pymorembs.errors import UserError
from pymorembs.io.matrix_market import read_matrix_market
from pymorembs.io.solid_mesh import mesh_problem
from pymorembs.preparation.inertia_loads import (
    INERTIA_LOAD_CASES,
    acceleration_fields,
    static_solver,
)

if TYPE_CHECKING:  # pymorembs.preparation re-exports this module's functions
    from pymorembs.preparation import PreparedModel

__all__ = [
    "STIFFENING_KINDS",
    "STIFFENING_SOURCES",
    "Stiffening",
    "geometric_stiffness",
    "stiffening_from_matrices",
    "stiffening_from_mesh",
    "with_stiffening",
]

_CHUNK = 4096  # solid elements per batch of the geometric stiffness
#: ``[stiffening] source``.
STIFFENING_SOURCES = ("mesh", "matrices", "none")
#: ``[stiffening] kind`` of user matrices.
STIFFENING_KINDS = ("geometric", "prestressed")


@dataclass(frozen=True, eq=False)
class Stiffening:
    """Geometric stiffness matrices of unit loads on the independent dofs.

    Attributes
    ----------
    source : str
        ``"mesh"`` or ``"matrices"``.
    cases : dict of str -> sparse matrix, shape (n_i, n_i)
        Load case (:data:`~pymorembs.preparation.inertia_loads.INERTIA_LOAD_CASES`) -> ``K_G``.
    nodes : dict of (node id, direction code) -> sparse matrix, shape (n_i, n_i)
        Unit force (directions 0-2) or moment (3-5) at a frame node -> ``K_G``.
    """

    source: str
    cases: dict[str, sp.csr_matrix]
    nodes: dict[tuple[int, int], sp.csr_matrix] = field(default_factory=dict)

    def __repr__(self) -> str:
        return (f"<Stiffening {self.source!r}: load cases {' '.join(self.cases) or 'none'}, "
                f"frame node loads {len(self.nodes)}>")  # fmt: skip

    def projected(
        self, basis: np.ndarray
    ) -> tuple[dict[str, np.ndarray], dict[tuple[int, int], np.ndarray]]:
        """``V^T K_G V`` of every case and node load, each (nq, nq), for a basis (n_i, nq)."""

        def project(matrix: sp.csr_matrix) -> np.ndarray:
            out = basis.T @ (matrix @ basis)
            return 0.5 * (out + out.T)

        return (
            {case: project(m) for case, m in self.cases.items()},
            {key: project(m) for key, m in self.nodes.items()},
        )


def geometric_stiffness(body: ElasticBody, displacement: np.ndarray) -> sp.csr_matrix:
    """``K_G`` (n_dof, n_dof) of the body's elements prestressed by ``displacement``.

    Parameters
    ----------
    body : ElasticBody
        With ``mesh`` (its elements and material): solids (the stresses at the Gauss points of
        their kind, :mod:`pymorembs.elements.solid`) or two-node beams (their axial forces,
        :func:`pymorembs.elements.beam.batch_geometric_matrices`).
    displacement : ndarray, shape (n_dof,)
        A displacement field over all equations of the body (model length unit).
    """
    mesh = body.mesh
    if mesh is None:
        raise UserError('stiffening: the model has no elements (source = "mesh")')
    connectivity = mesh.connectivity
    n = body.n_dof
    nodes = body.coordinates[body.node_rows(connectivity)]  # (n_el, nodes per element, 3)
    u_all = np.asarray(displacement, dtype=float)
    if mesh.element in SOLID_KINDS:
        kind = mesh.element
        equations = np.stack([_equations(body, connectivity, d) for d in range(3)], axis=-1)
        total = sp.csr_matrix((n, n))
        for start in range(0, connectivity.shape[0], _CHUNK):  # memory ~ the matrix
            eq, xyz = equations[start : start + _CHUNK], nodes[start : start + _CHUNK]
            young, poisson = part(mesh.young, start, _CHUNK), part(mesh.poisson, start, _CHUNK)
            stresses = solid_stresses(kind, xyz, u_all[eq], young, poisson)
            g = solid_geometric_matrices(kind, xyz, stresses)
            r = np.broadcast_to(eq[:, :, None, :], (*g.shape, 3))
            c = np.broadcast_to(eq[:, None, :, :], (*g.shape, 3))
            values = np.broadcast_to(g[..., None], (*g.shape, 3))
            total = total + sp.csr_matrix((values.ravel(), (r.ravel(), c.ravel())), shape=(n, n))
        return total
    else:  # beam2: ux uy uz rx ry rz of node 1, then node 2
        equations = np.stack([_equations(body, connectivity, d) for d in range(6)], axis=-1)
        equations = equations.reshape(-1, 12)
        up = None if mesh.up is None else np.asarray(mesh.up, dtype=float)
        k_g = batch_geometric_matrices(nodes[:, 0], nodes[:, 1], mesh.section, u_all[equations], up)
        r = np.broadcast_to(equations[:, :, None], k_g.shape)
        c = np.broadcast_to(equations[:, None, :], k_g.shape)
        values = k_g
    return sp.csr_matrix((values.ravel(), (r.ravel(), c.ravel())), shape=(n, n))


def _equations(body: ElasticBody, nodes: np.ndarray, direction: int) -> np.ndarray:
    """Equation index of ``(node, direction)`` for an array of node ids (all must exist)."""
    found = body.dofs.positions(nodes, direction)
    if np.any(found < 0):
        bad = nodes.ravel()[np.flatnonzero((found < 0).ravel())[0]]
        raise UserError(f"stiffening: element node {bad} has no dof {direction} in the dof table")
    return found


def _load_cases(prepared: PreparedModel, cases: Sequence[str]) -> dict[str, np.ndarray]:
    """The unit d'Alembert loads ``-M a_L`` on all dofs (SID_NOTES §4.6)."""
    body = prepared.body
    fields = acceleration_fields(body, tuple(cases))
    loads = -(body.mass @ fields)
    return {case: loads[:, j] for j, case in enumerate(cases)}


def _node_loads(prepared: PreparedModel, nodes: Sequence[int]) -> dict[tuple[int, int], np.ndarray]:
    """Unit forces and moments at the frame nodes, on all dofs."""
    body = prepared.body
    out = {}
    for node in nodes:
        for index in body.dofs.of_node(int(node)):
            direction = int(body.dofs.directions[index])
            if direction < 6:
                load = np.zeros(body.n_dof)
                load[index] = 1.0
                out[(int(node), direction)] = load
    return out


def stiffening_from_mesh(
    prepared: PreparedModel,
    cases: Sequence[str] = INERTIA_LOAD_CASES,
    nodes: Sequence[int] = (),
) -> Stiffening:
    """``K_G`` of the load cases and of unit loads at ``nodes`` from the body's elements.

    One static factorization for all loads; ``u = T K^+ T^T f`` with the frame's support
    (:func:`~pymorembs.preparation.inertia_loads.static_solver`), then :func:`geometric_stiffness`,
    then ``T^T K_G T``.
    """
    body, elimination, system = prepared.body, prepared.elimination, prepared.system
    if body.mesh is None:
        why = mesh_problem(body)
        raise UserError(
            '[stiffening]: source = "mesh" needs the elements and material of the model '
            + (
                f"({why})"
                if why is not None
                else "(the built-in models and models read with their .inp or bulk data have them)"
            )
            + '; give matrices instead (source = "matrices")'
        )
    loads = {**_load_cases(prepared, cases), **_node_loads(prepared, nodes)}
    keys = list(loads)
    forces = elimination.inputs(np.column_stack([loads[k] for k in keys]))
    if system.rigid_modes is not None:  # the self-equilibrated part (Buckens frame)
        rigid = system.rigid_modes
        forces = forces - system.mass @ (rigid @ (rigid.T @ forces))
    solution = static_solver(system, "K (static load cases of the stiffening)").solve(forces)
    transform = sp.csr_matrix(elimination.transform)
    matrices = {}
    for j, key in enumerate(keys):
        displacement = transform @ solution[:, j]
        k_g = geometric_stiffness(body, displacement)
        matrices[key] = sp.csr_matrix(transform.T @ k_g @ transform)
    return Stiffening(
        "mesh",
        {k: m for k, m in matrices.items() if isinstance(k, str)},
        {k: m for k, m in matrices.items() if not isinstance(k, str)},
    )


def stiffening_from_matrices(
    prepared: PreparedModel, files: Mapping[str, str | Path], kind: str = "geometric"
) -> Stiffening:
    """``K_G`` of the load cases from Matrix Market files (model equation order, all dofs).

    ``kind = "prestressed"``: the files hold the stiffness of the prestressed model and
    ``K_G = K_pre - K``.
    """
    if kind not in STIFFENING_KINDS:
        raise UserError(f"[stiffening]: kind must be one of {', '.join(STIFFENING_KINDS)}")
    body, elimination = prepared.body, prepared.elimination
    transform = sp.csr_matrix(elimination.transform)
    matrices = {}
    for case, path in files.items():
        if case not in INERTIA_LOAD_CASES:
            raise UserError(
                f"[stiffening] matrices: unknown load case {case!r}; use "
                + ", ".join(INERTIA_LOAD_CASES)
            )
        matrix = sp.csr_matrix(read_matrix_market(path), dtype=float)
        if matrix.shape != (body.n_dof, body.n_dof):
            raise UserError(
                f"{path}: {matrix.shape[0]} x {matrix.shape[1]} matrix, but the model has "
                f"{body.n_dof} equations (K_G of load case {case} in the model's equation order)"
            )
        if kind == "prestressed":
            matrix = matrix - sp.csr_matrix(body.stiffness)
        matrices[case] = sp.csr_matrix(transform.T @ matrix @ transform)
    return Stiffening("matrices", matrices)


def with_stiffening(prepared: PreparedModel, stiffening: Stiffening) -> PreparedModel:
    """The prepared model carrying its geometric stiffening."""
    return replace(prepared, stiffening=stiffening)
