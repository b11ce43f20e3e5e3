"""The Buckens reference frame (paper section 2.1, eq. 6).

The Buckens frame follows the body so that the elastic deformation is as small as possible in
the mass-weighted sense, ``int u . u dm -> min``. Its origin is the centre of gravity of the
undeformed body, and the elastic shape functions must be mass-orthogonal to the six rigid-body
modes. The body is free: nothing is fixed, and the stiffness is singular.
"""

from __future__ import annotations

import numpy as np

from pymorembs.body import ElasticBody
from pymorembs.errors import UserError


def centre_of_gravity(body: ElasticBody) -> np.ndarray:
    """Centre of gravity (shape (3,)) of the undeformed body from its mass matrix.

    With the rigid-body fields ``R`` about the coordinate origin, ``R^T M R`` has the block
    ``T^T M Theta = -m [c]x`` between translations and rotations, from which ``c`` follows.
    """
    rigid = body.rigid_body_modes()
    coupling = rigid[:, :3].T @ (body.mass @ rigid[:, 3:])
    mass = float(np.trace(rigid[:, :3].T @ (body.mass @ rigid[:, :3]))) / 3.0
    if not mass > 0:
        raise UserError("Buckens frame: the body has no translational mass")
    cross = -(coupling - coupling.T) / (2.0 * mass)  # [c]x, antisymmetric part
    return np.array([cross[2, 1], cross[0, 2], cross[1, 0]])


def buckens_frame(body: ElasticBody) -> ElasticBody:
    """The body with coordinates measured from its centre of gravity (nothing fixed).

    The mass-orthogonality of the shape functions to the rigid-body modes is imposed when the
    body is prepared (:func:`pymorembs.preparation.prepare`) and kept by every reduction.
    """
    if body.fixed.size:
        raise UserError(
            f"Buckens frame: the model has {body.fixed.size} fixed dofs; the Buckens frame is "
            "for free bodies (use a tangent frame, or remove the fixed dofs)"
        )
    return body.translated(centre_of_gravity(body))
