"""The reduction methods of paper section 3 and the reduced model they give.

A public subpackage (``docs/api.md``, "The public surface"). A method is usually chosen by name
through :func:`pymorembs.reduce` (options checked by :mod:`pymorembs.methods`, run by
:func:`method_projection`); the method functions below take a prepared system directly, check
their options by the same options classes (``soaga_reduction`` and ``rational_krylov_gramians``,
wider interfaces, check their own arguments), and give a :class:`Projection` (``V``, ``W`` and
how they were made); below them the algorithms take checked values. :func:`first_stage` is
the Gramian method's choice of its first stage. :func:`reduced_model` projects, diagonalises
and checks it (:class:`ReducedModel`); :func:`without_stiff_directions` and
:func:`explicit_step_s` concern the highest frequencies of the reduced model.
"""

from pymorembs.reduction.dispatch import (
    aims_at_stresses,
    expansion_candidates,
    method_projection,
)
from pymorembs.reduction.gramian import first_stage, gramian_reduction, pod_reduction
from pymorembs.reduction.krylov import krylov_reduction
from pymorembs.reduction.modal import modal_reduction
from pymorembs.reduction.modal_family import best_modes, craig_bampton, modes_with_frm
from pymorembs.reduction.projection import (
    Projection,
    ReducedModel,
    explicit_step_s,
    reduced_model,
    without_stiff_directions,
)
from pymorembs.reduction.rational_gramian import rational_gramian_reduction
from pymorembs.reduction.soaga import soaga_reduction

__all__ = [
    "Projection",
    "ReducedModel",
    "aims_at_stresses",
    "best_modes",
    "craig_bampton",
    "expansion_candidates",
    "explicit_step_s",
    "first_stage",
    "gramian_reduction",
    "krylov_reduction",
    "method_projection",
    "modal_reduction",
    "modes_with_frm",
    "pod_reduction",
    "rational_gramian_reduction",
    "reduced_model",
    "soaga_reduction",
    "without_stiff_directions",
]
