"""The solid elements and isotropic material of an imported FE model, for geometric stiffening.

Readers that see the elements of a model (the Abaqus ``.inp``, the Nastran bulk data, the Ansys
``.cdb``) hand them here as :class:`SolidBlock` s; :func:`element_mesh` makes the body's
:class:`~pymorembs.body.ElementMesh` of them, or says in one sentence why it cannot (no solid
elements, an element type without kinematics here, several element kinds or materials). The
reader keeps the body readable either way: :func:`attach_mesh` puts the mesh on the body, or
the sentence into its notes, where ``[stiffening] source = "mesh"`` finds it
(:func:`mesh_problem`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pymorembs.body import ElasticBody, ElementMesh
from pymorembs.errors import UserError

__all__ = [
    "NO_MESH",
    "SolidBlock",
    "attach_mesh",
    "element_mesh",
    "mesh_problem",
]

#: The note of a body whose elements give no mesh starts with this.
NO_MESH = "no element mesh for geometric stiffening: "


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
    """

    kind: str
    connectivity: np.ndarray
    young: float
    poisson: float
    where: str


def element_mesh(blocks: list[SolidBlock]) -> ElementMesh:
    """One :class:`~pymorembs.body.ElementMesh` of the blocks.

    Raises
    ------
    UserError
        No blocks, blocks of different kinds or materials (a body holds one element kind and
        one material for its stiffening), or a material that is not elastic.
    """
    if not blocks:
        raise UserError("the model has no solid elements")
    kinds = sorted({b.kind for b in blocks})
    if len(kinds) > 1:
        raise UserError(
            f"the solid elements are of several kinds ({', '.join(kinds)}); the stiffening of a "
            "body from its elements takes one kind"
        )
    materials = sorted({(b.young, b.poisson) for b in blocks})
    if len(materials) > 1:
        listed = ", ".join(f"E = {e:g}, nu = {nu:g}" for e, nu in materials)
        raise UserError(
            f"the solid elements have several materials ({listed}); the stiffening of a body "
            "from its elements takes one material"
        )
    connectivity = np.concatenate([b.connectivity for b in blocks])
    young, poisson = materials[0]
    return ElementMesh(kinds[0], connectivity, young, poisson)


def attach_mesh(body: ElasticBody, blocks: list[SolidBlock] | str) -> ElasticBody:
    """The body with the mesh of ``blocks``, or with a note saying why it has none.

    ``blocks`` may already be that reason (a reader that found the elements unusable). A mesh
    whose nodes lack translational dofs in the body is not attached either (noted).
    """
    if isinstance(blocks, str):
        problem = blocks
    else:
        try:
            return replace(body, mesh=element_mesh(blocks))
        except UserError as err:
            problem = str(err)
    return replace(body, mesh=None, notes=(*body.notes, NO_MESH + problem))


def mesh_problem(body: ElasticBody) -> str | None:
    """The reason noted by :func:`attach_mesh` why the body has no mesh, or None."""
    for note in body.notes:
        if note.startswith(NO_MESH):
            return note[len(NO_MESH) :]
    return None
