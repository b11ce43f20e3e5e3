"""Which function runs which method: a checked options object of the method registry
(:mod:`pymorembs.methods`) to the projection of its method.

The registry declares and checks the options; the functions here take the checked object as it
is (nothing is checked twice, nothing converted back) and hold each method's policy, e.g. the
first stage of the two-step Gramian reduction (:func:`~pymorembs.reduction.gramian.first_stage`).
"""

from __future__ import annotations

from collections.abc import Callable

from pymorembs.methods import ReductionOptions
from pymorembs.reduction.gramian import first_stage, gramian_from_options, pod_from_options
from pymorembs.reduction.krylov import krylov_from_options
from pymorembs.reduction.modal_family import craig_bampton_from_options, modal_from_options
from pymorembs.reduction.projection import Projection
from pymorembs.reduction.rational_gramian import rational_gramian_from_options
from pymorembs.reduction.soaga import soaga_from_options
from pymorembs.system import SecondOrderSystem

#: Method name -> the function of its checked options: ``(system, options, band_hz)``.
METHOD_FUNCTIONS: dict[str, Callable[..., Projection]] = {
    "modal": modal_from_options,
    "craig-bampton": craig_bampton_from_options,
    "krylov": krylov_from_options,
    "soaga": soaga_from_options,
    "gramian": gramian_from_options,
    "pod": pod_from_options,
}


def method_projection(
    system: SecondOrderSystem, options: ReductionOptions, band_hz: tuple[float, float]
) -> Projection:
    """The projection of the method of ``options`` on ``system``.

    Parameters
    ----------
    system : SecondOrderSystem
        The prepared system (``PreparedModel.reduction_system``). Its stress outputs join the
        outputs the method aims at when they are targeted
        (:meth:`~pymorembs.system.SecondOrderSystem.targeted`); SOAGA takes them as they are
        and holds its estimator to them.
    options : ReductionOptions
        A checked options object (:func:`~pymorembs.methods.method_options`), passed on as it
        is.
    band_hz : (float, float)
        The band (Hz) of the band-aware methods (``soaga``, ``gramian``, ``pod``).

    Returns
    -------
    Projection
    """
    if options.method != "soaga":
        system = system.targeted()
    if options.method == "gramian":
        if first_stage(options.first_stage, system.order) == "rational-krylov":
            return rational_gramian_from_options(system, options, band_hz)
    return METHOD_FUNCTIONS[options.method](system, options, band_hz)
