"""A reduced model as the writers of the export registry read it, and the checks before writing.

:class:`ExportSource` holds one reduced model with its prepared model and name, and makes what
several writers share once: the arrays of ``reduced.npz`` and ``reduced.mat``, the basis on all
dofs (eq. 18), the static responses, the stress modes (VTU, Exudyn, recovery file) and the mass
invariants of the body for a set of frame nodes (SID, Neweul-M² and Exudyn read the same
invariants). :func:`check_before_writing` refuses a model that is not fit to
be written; :func:`body_invariants` refuses a body of a two-sided projection.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import numpy as np

from pymorembs.errors import NumericalError, UserError
from pymorembs.export.invariants import BodyInvariants, StiffeningTerms, compute_invariants
from pymorembs.export.matrices import reduced_arrays
from pymorembs.export.stress_modes import StressModes, stress_modes, stress_modes_note
from pymorembs.export.vtu import static_fields
from pymorembs.preparation import PreparedModel
from pymorembs.reduction.projection import ReducedModel
from pymorembs.system import check_damping


def body_invariants(
    model: ReducedModel, prepared: PreparedModel, nodes: Sequence[int], name: str
) -> BodyInvariants:
    """The mass invariants of a reduced body (SID_NOTES section 4) for its frame ``nodes``."""
    if not model.projection.one_sided:
        raise UserError(
            f"reduction '{name}': SID, Neweul-M² and Exudyn bodies need a one-sided (Galerkin) "
            "projection; drop two_sided or write only matrices"
        )
    basis = prepared.expand(model.projection.V)  # eq. 18: all dofs
    stiffening = None
    if prepared.stiffening is not None:
        cases, loads = prepared.stiffening.projected(model.projection.V)
        stiffening = StiffeningTerms(cases, loads, prepared.stiffening.source)
    return compute_invariants(
        prepared.body,
        basis,
        model.system.mass,
        model.system.stiffness,
        model.damping_matrix,
        nodes,
        frequencies_hz=model.eigenfrequencies_hz,
        name=name,
        stiffening=stiffening,
    )


def check_before_writing(model: ReducedModel, name: str) -> None:
    """Refuse a reduced model that is not fit to be written.

    Checks (:meth:`~pymorembs.system.SecondOrderSystem.check_reduced`): finite ``V``, ``M``,
    ``K``, ``D``, ``B``, ``C``; symmetric ``M``, ``K``, ``D``; positive definite ``M``;
    positive semidefinite ``K`` and the viscous damping written for simulation
    (:attr:`ReducedModel.damping_matrix`, which includes a modal damping ratio). An oblique
    (two-sided) model has non-symmetric 2x2 blocks for complex pairs; it is checked for finite
    entries here, its stability when it is formed
    (:func:`~pymorembs.reduction.projection.reduced_model`).

    Raises
    ------
    NumericalError
        Naming the reduction and the failed check; nothing has been written.
    """
    try:
        if not np.all(np.isfinite(model.projection.V)):
            raise NumericalError("the basis V has NaN or infinite entries")
        if model.projection.one_sided:
            model.system.check_reduced()
            check_damping(np.asarray(model.damping_matrix), "reduced damping matrix (written)")
        else:  # W^T K V of complex pairs is block diagonal, not symmetric: checked when formed
            system = model.system
            for label, matrix in (
                ("mass", system.mass),
                ("stiffness", system.stiffness),
                ("damping", model.damping_matrix),
                ("input", system.input_matrix),
                ("output", system.output_matrix),
            ):
                if not np.all(np.isfinite(np.asarray(matrix))):
                    raise NumericalError(f"reduced {label} matrix has NaN or infinite entries")
    except NumericalError as exc:
        raise NumericalError(f"reduction '{name}': {exc}; nothing was written") from None


class ExportSource:
    """One reduced model as the export writers read it; what they share is made once.

    Parameters
    ----------
    model : ReducedModel
        The checked reduced model (:func:`check_before_writing`).
    prepared : PreparedModel
        The prepared model it was reduced from.
    name : str
        The reduction's name (in file names and the SID header).
    """

    def __init__(self, model: ReducedModel, prepared: PreparedModel, name: str) -> None:
        self.model = model
        self.prepared = prepared
        self.name = name
        self._invariants: dict[tuple[int, ...], BodyInvariants] = {}

    @cached_property
    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays of ``reduced.npz`` and ``reduced.mat`` (:func:`reduced_arrays`)."""
        return reduced_arrays(self.model, self.prepared)

    @cached_property
    def basis(self) -> np.ndarray:
        """The basis ``V`` on all dofs of the prepared body (eq. 18), shape (n_dof, order)."""
        return self.prepared.expand(self.model.projection.V)

    @cached_property
    def static(self) -> dict[str, np.ndarray]:
        """The static response to every input on all dofs (:func:`static_fields`)."""
        return static_fields(self.prepared)

    @cached_property
    def stress_modes(self) -> StressModes | None:
        """The stress and strain modes of the basis and the static responses
        (:func:`~pymorembs.export.stress_modes.stress_modes`); None for a body without solid
        elements (:attr:`stress_note` says so)."""
        if self.stress_note is not None:
            return None
        return stress_modes(self.prepared.body, self.basis, self.static)

    @property
    def stress_note(self) -> str | None:
        """Why the body has no stress modes (:func:`stress_modes_note`), or None."""
        return stress_modes_note(self.prepared.body)

    def invariants(self, nodes: Sequence[int]) -> BodyInvariants:
        """The mass invariants of the body with these frame nodes (:func:`body_invariants`),
        computed once per set of nodes."""
        key = tuple(nodes)
        if key not in self._invariants:
            self._invariants[key] = body_invariants(self.model, self.prepared, key, self.name)
        return self._invariants[key]


__all__ = ["ExportSource", "body_invariants", "check_before_writing"]
