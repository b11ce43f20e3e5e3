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
from pymorembs.reduction.soaga import candidate_points, soaga_from_options
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

#: The methods given the stress outputs as a block of their own, not appended to ``C``:
#: SOAGA holds its estimator to them; the Gramians take the union of the dominant eigenspaces
#: of the ports' and the stresses' Gramian sums, each held to the tolerance by itself
#: (:func:`~pymorembs.reduction.gramian.block_union`); Krylov takes its spaces from ``B`` and
#: the ports' ``C`` alone (an output Krylov space of six rows per hot spot is not worth its
#: columns, and an oblique ``W`` from it is unstable: docs/jobs.md, "Stresses at hot spots").
STRESS_BLOCK_AS_IS = frozenset({"soaga", "gramian", "krylov"})


def aims_at_stresses(options: ReductionOptions) -> bool:
    """Whether the method of ``options`` shapes its basis by targeted stress outputs.

    SOAGA (its stopping estimate), the Gramians (the stresses' own block), the POD (its
    snapshots' outputs) and the modal method that selects by approximate Hankel singular values
    (eq. 26, which weigh ``C``) do; Krylov (its spaces from ``B`` and the ports' ``C``), the
    lowest modes and Craig-Bampton do not: a job's ``[stress] target`` leaves their basis as it
    is, and the summary says so.
    """
    if options.method in ("soaga", "gramian", "pod"):
        return True
    return options.method == "modal" and getattr(options, "select", "lowest") == "best"


def expansion_candidates(options: ReductionOptions, band_hz: tuple[float, float]) -> list[float]:
    """The frequencies (Hz) at which the method of ``options`` may factorize ``K - omega^2 M``:
    Krylov's expansion points, SOAGA's candidates; empty for the other methods.

    A job's error reference takes them as its own candidates, so that its factorizations serve
    the reductions too (:func:`~pymorembs.linalg.shared_factorizations`).
    """
    if options.method == "krylov":
        return [float(f) for f in options.expansion_points_hz]
    if options.method == "soaga":
        return candidate_points(*band_hz, options.candidates_hz, options.n_candidates)
    return []


def method_projection(
    system: SecondOrderSystem, options: ReductionOptions, band_hz: tuple[float, float]
) -> Projection:
    """The projection of the method of ``options`` on ``system``.

    Parameters
    ----------
    system : SecondOrderSystem
        The prepared system (``PreparedModel.reduction_system``). When its stress outputs are
        targeted, the methods of :data:`STRESS_BLOCK_AS_IS` take them as they are; the others
        see them joined to the outputs they aim at
        (:meth:`~pymorembs.system.SecondOrderSystem.targeted`).
    options : ReductionOptions
        A checked options object (:func:`~pymorembs.methods.method_options`), passed on as it
        is.
    band_hz : (float, float)
        The band (Hz) of the band-aware methods (``soaga``, ``gramian``, ``pod``).

    Returns
    -------
    Projection
    """
    if options.method not in STRESS_BLOCK_AS_IS:
        system = system.targeted()
    if options.method == "gramian":
        if first_stage(options.first_stage, system.order) == "rational-krylov":
            return rational_gramian_from_options(system, options, band_hz)
    return METHOD_FUNCTIONS[options.method](system, options, band_hz)
