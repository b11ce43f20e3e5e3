"""The solid elements and isotropic material of an imported FE model, for geometric stiffening.

Readers that see the elements of a model (the Abaqus ``.inp``, the Nastran bulk data, the Ansys
``.cdb``) hand them here as :class:`SolidBlock` s; :func:`element_mesh` makes the body's
:class:`~pymorembs.body.ElementMesh` of them, or says in one sentence why it cannot (no solid
elements, an element type without kinematics here, several element kinds). The
reader keeps the body readable either way: :func:`attach_mesh` puts the mesh on the body, or
the sentence into its notes, where ``[stiffening] source = "mesh"`` finds it
(:func:`mesh_problem`). The body's surface for viewers, from every element kind, is
:mod:`pymorembs.io.element_surface`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from pymorembs.body import NO_MESH, ElasticBody, ElementMesh, mesh_problem
from pymorembs.elements.solid import SOLID_KINDS, part, solid_forces
from pymorembs.errors import UserError

__all__ = [
    "MESH_TOLERANCE",
    "NO_MESH",
    "SolidBlock",
    "attach_mesh",
    "describe_material",
    "element_mesh",
    "mesh_problem",
    "stiffness_mismatch",
]

#: Largest relative difference between the elements' stiffness and the model's K accepted
#: (files written with 7 significant digits stay far below it; another material, rule or node
#: order lies far above).
MESH_TOLERANCE = 1e-5


@dataclass(frozen=True, eq=False)
class SolidBlock:
    """Elements of one kind and one isotropic material.

    Attributes
    ----------
    kind : str
        A key of :data:`pymorembs.elements.solid.SOLID_KINDS`.
    connectivity : ndarray of int, shape (n_el, nodes per element)
        Node ids, in the node order of the kind.
    young, poisson : float
        Young's modulus (model stress unit) and Poisson's ratio.
    where : str
        The source, for messages (``"abq_beam.inp: *ELEMENT, TYPE=C3D10 (line 526)"``).
    element_ids : ndarray of int, shape (n_el,), optional
        The element numbers of the file, where it numbers them.
    """

    kind: str
    connectivity: np.ndarray
    young: float
    poisson: float
    where: str
    element_ids: np.ndarray | None = None


def element_mesh(blocks: list[SolidBlock]) -> ElementMesh:
    """One :class:`~pymorembs.body.ElementMesh` of the blocks (one material per element when
    the blocks have several; the file's element numbers when every block has them and no number
    repeats, as in an assembly of parts, else ``1 .. n_el``).

    Raises
    ------
    UserError
        No blocks, blocks of different kinds (a body holds one element kind for its
        stiffening), or a material that is not elastic.
    """
    if not blocks:
        raise UserError("the model has no solid elements")
    kinds = sorted({b.kind for b in blocks})
    if len(kinds) > 1:
        raise UserError(
            f"the solid elements are of several kinds ({', '.join(kinds)}); the stiffening of a "
            "body from its elements takes one kind"
        )
    connectivity = np.concatenate([b.connectivity for b in blocks])
    ids = None  # the file's numbers where every block has them and they are distinct
    if all(b.element_ids is not None for b in blocks):
        ids = np.concatenate([b.element_ids for b in blocks])  # type: ignore[misc]
        if np.unique(ids).size != ids.size:
            ids = None
    if len({(b.young, b.poisson) for b in blocks}) == 1:
        return ElementMesh(
            kinds[0], connectivity, blocks[0].young, blocks[0].poisson, element_ids=ids
        )
    counts = [b.connectivity.shape[0] for b in blocks]
    young = np.repeat([b.young for b in blocks], counts)
    poisson = np.repeat([b.poisson for b in blocks], counts)
    return ElementMesh(kinds[0], connectivity, young, poisson, element_ids=ids)


def describe_material(mesh: ElementMesh) -> str:
    """``E = .., nu = ..`` of a mesh, or the number of its materials and the first of them."""
    young, poisson = np.broadcast_arrays(np.ravel(mesh.young), np.ravel(mesh.poisson))
    pairs = np.unique(np.column_stack([young, poisson]), axis=0)
    if len(pairs) == 1:
        return f"E = {pairs[0, 0]:g}, nu = {pairs[0, 1]:g}"
    listed = "; ".join(f"E = {e:g}, nu = {nu:g}" for e, nu in pairs[:4])
    return f"{len(pairs)} materials ({listed}{'; ...' if len(pairs) > 4 else ''})"


def attach_mesh(body: ElasticBody, blocks: list[SolidBlock] | str) -> ElasticBody:
    """The body with the mesh of ``blocks``, or with a note saying why it has none.

    ``blocks`` may already be that reason (a reader that found the elements unusable). The
    mesh is attached only when the stiffness of its elements and material
    (:func:`~pymorembs.elements.solid.solid_stiffness`) reproduces the body's own ``K`` on the
    free dofs to :data:`MESH_TOLERANCE` (:func:`stiffness_mismatch`): that proves node order,
    integration rule and material belong to the matrices (a material of another run would
    scale every stress, and so ``K_G``, silently). A mesh whose nodes lack translational dofs
    in the body is not attached either (noted).
    """
    if isinstance(blocks, str):
        problem = blocks
    else:
        try:
            mesh = element_mesh(blocks)
            with_mesh = replace(body, mesh=mesh)
            mismatch = stiffness_mismatch(with_mesh)
        except UserError as err:
            problem = str(err)
        else:
            if mismatch <= MESH_TOLERANCE:
                note = (
                    f"element mesh: {mesh.connectivity.shape[0]} {mesh.element} elements, "
                    f"{describe_material(mesh)}; their stiffness reproduces K "
                    f"(relative difference {mismatch:.0e})"
                )
                return replace(with_mesh, notes=(*body.notes, note))
            problem = (
                f"the stiffness of its {mesh.connectivity.shape[0]} {mesh.element} elements with "
                f"{describe_material(mesh)} differs from the model's K by "
                f"{mismatch:.1e} (relative; at most {MESH_TOLERANCE:g} when elements, node "
                "order and material belong to the matrices)"
            )
    return replace(body, mesh=None, notes=(*body.notes, NO_MESH + problem))


def stiffness_mismatch(body: ElasticBody, chunk: int = 2048, seed: int = 0) -> float:
    """How far the stiffness of the body's solid elements is from its ``K``, on the free dofs.

    ``|(K_e v - K v)_f| / |(K v)_f|`` for two random fields ``v`` that vanish at the fixed dofs
    (``f``: the rows of the other dofs), with ``K_e v`` summed element by element (no matrix
    formed: :func:`~pymorembs.elements.solid.solid_forces`). Dependent dofs are treated like
    free ones.

    Parameters
    ----------
    body : ElasticBody
        With a solid ``mesh``.
    chunk : int
        Elements per batch.
    seed : int
        Of the random fields.

    Returns
    -------
    float
        The relative difference (0 for elements that are the whole model's stiffness).
    """
    mesh = body.mesh
    if mesh is None or mesh.element not in SOLID_KINDS:
        raise UserError("stiffness check: the body has no solid elements")
    connectivity = mesh.connectivity
    equations = np.stack([body.dofs.positions(connectivity, d) for d in range(3)], axis=-1).reshape(
        connectivity.shape[0], -1
    )
    if np.any(equations < 0):
        raise UserError("an element node has no translational dofs in the model's dof table")
    xyz = body.coordinates[body.node_rows(connectivity)]
    fields = np.random.default_rng(seed).standard_normal((body.n_dof, 2))
    fields[body.fixed] = 0.0
    product = np.zeros_like(fields)
    n_nodes = connectivity.shape[1]
    for start in range(0, connectivity.shape[0], chunk):
        eq = equations[start : start + chunk]
        young, poisson = part(mesh.young, start, chunk), part(mesh.poisson, start, chunk)
        local_fields = fields[eq].reshape(eq.shape[0], n_nodes, 3, 2)
        local = solid_forces(mesh.element, xyz[start : start + chunk], local_fields, young, poisson)
        for k in range(2):  # the sums of np.add.at, quicker
            product[:, k] += np.bincount(eq.ravel(), local[..., k].ravel(), body.n_dof)
    reference = sp.csr_matrix(body.stiffness) @ fields
    free = np.ones(body.n_dof, dtype=bool)
    free[body.fixed] = False
    scale = np.linalg.norm(reference[free])
    if not scale > 0:
        return float("inf")
    return float(np.linalg.norm((product - reference)[free]) / scale)
