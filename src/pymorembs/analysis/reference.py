"""The reference frequency response against which reduced models are judged (eq. 27).

The error ``eps(f) = ||H - H_bar||_F / ||H||_F`` needs the full model's response ``H`` on the
error grid: one complex sparse factorization per frequency. At 35,000 dofs that is about 1.3 s
(PARDISO) per frequency, 400 frequencies take minutes -- far more than the reduction itself
(about 5 s). Two kinds of reference are therefore offered:

``"full"``
    ``H`` of the full model at every grid frequency (:func:`transfer_function`). Exact, and the
    default up to :data:`FULL_MAX_ORDER` dofs.
``"surrogate"``
    ``H_ref`` of a *reference model*: an adaptive second-order Krylov model (SOAGA, with its
    error estimator driven to :data:`SURROGATE_TOLERANCE`) of much higher accuracy than the
    reductions being judged. It costs a few real factorizations at expansion points in the
    band, and the grid is evaluated on the small model. The surrogate is then *checked against
    the full model*, and the full response replaces it at every checked frequency:

    * at 0 Hz when the grid starts there (the static error is exact; a real factorization);
    * at ``checks`` frequencies chosen where the reference model is weakest: the maximum of its
      own estimator, the largest peak of the response, then the grid frequencies farthest from
      every expansion point and every earlier check (greedy max-min distance);
    * for every reduction, at the frequency of its largest error, until that maximum lies on a
      checked frequency (:meth:`ReferenceResponse.settled`): the reported maximum error of each
      reduction is always measured against the full model.

    A job checks the reductions' maxima first and then completes the checks
    (:meth:`ReferenceResponse.completed`): the estimator's maximum and the peak are always
    checked, and the frequencies already checked count towards ``checks`` and are avoided by
    the max-min choice -- the same coverage of the band with fewer full solves (on a job with
    three reductions typically two: each a complex factorization, or about 20 s of iterative
    solves at 300,000 dofs).

    The relative deviation ``||H - H_ref|| / ||H||`` at the checks is the reference's measured
    accuracy; errors far above it are resolved (``|eps_surrogate - eps| <= deviation`` to first
    order), errors near it are not, and the summary says which.

By the triangle inequality, with ``delta(f) = ||H - H_ref||_F / ||H||_F`` the reference's own
relative error, ``|eps_surrogate(f) - eps(f)| <= delta (1 + eps) / (1 - delta)``: the surrogate
curve is the true one to within about the reference's error.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

import numpy as np

from pymorembs.analysis.error import relative_error
from pymorembs.analysis.shifted_checks import shifted_response
from pymorembs.analysis.transfer import transfer_function
from pymorembs.errors import UserError
from pymorembs.kinds import ReferenceKind
from pymorembs.linalg.shared_factors import active_shared_factors
from pymorembs.system import SecondOrderSystem

#: What the error of eq. 27 is measured against (``[band] reference``).
REFERENCE_KINDS = ReferenceKind.names()
#: Frequencies above 0 Hz where a surrogate reference is checked against the full model, at
#: least (``[band] check_points``; a job's checks at the maxima of its error curves count).
DEFAULT_CHECKS = 4

#: ``reference = "auto"`` uses the full model up to this many (independent) dofs: a sweep of
#: 400 frequencies takes well under a minute there (rack-beams, 3,996 dofs: about 10 s).
FULL_MAX_ORDER = 6000
#: The reference model's estimated maximum relative error (its SOAGA tolerance).
SURROGATE_TOLERANCE = 1e-12
#: Deflation tolerance of the reference model's basis.
SURROGATE_DEFLATION = 1e-12
#: Largest reference model (columns); also at most half the full order.
SURROGATE_MAX_ORDER = 600
#: Candidate expansion points of the reference model, equidistant over the band.
SURROGATE_CANDIDATES = 12
#: At most this many rounds of :meth:`ReferenceResponse.settled` per reduction.
SETTLE_ROUNDS = 4
#: A surrogate whose measured deviation exceeds this gets a warning in the summary.
DEVIATION_WARNING = 1e-6
#: Checks at f > 0 first computed from a real factor the job holds
#: (:mod:`~pymorembs.analysis.shifted_checks`), a complex factorization only where that answer
#: cannot be certified -- from :data:`ITERATIVE_MIN_ORDER` dofs on. Below it a complex
#: factorization is cheap and the iterative solves are no faster (rack-solid at 6,066 dofs);
#: from about 12,000 dofs on they are (docs/performance.md, "Checks without a complex
#: factorization"), and on the 275k-dof tet10 bracket they replace complex factorizations of
#: about 40 s each.
ITERATIVE_CHECKS = True
#: ... from this order on.
ITERATIVE_MIN_ORDER = 10_000


@dataclass(frozen=True, eq=False)
class ReferenceResponse:
    """Response ``H`` on the error grid, exact or a checked surrogate (an immutable value).

    Checking more frequencies against the full model gives a new reference
    (:meth:`checked`, :meth:`settled`, :meth:`settled_all`); the arrays are read-only views.

    Attributes
    ----------
    frequencies_hz : ndarray, shape (n_f,)
        The error grid in Hz.
    response : ndarray, complex, shape (n_f, n_outputs, n_inputs)
        The reference response; the full model's wherever ``exact`` is set.
    kind : {"full", "surrogate"}
    exact : ndarray of bool, shape (n_f,)
        Where ``response`` is the full model's.
    system : SecondOrderSystem
        The full model, for the checks.
    workers, scheduler
        Parallel processes or Dask scheduler of the checks' sweeps.
    deviation : mapping of float -> float
        Surrogate only: checked frequency (Hz) -> ``||H - H_ref||_F / ||H||_F`` there.
    parameters : mapping
        Surrogate only: order, estimated error and expansion points of the reference model.
    seconds : float
        Wall time spent on the reference (model, grid and checks).
    basis : ndarray, shape (n, order) or None
        Surrogate: the reference model's basis, the coarse space of the checks computed from
        a real factor (:mod:`~pymorembs.analysis.shifted_checks`).
    estimate_curve : (ndarray, ndarray) or None
        Surrogate: the reference model's own error estimator, frequencies (Hz) and values,
        where :meth:`completed` looks for its weakest frequency.
    """

    frequencies_hz: np.ndarray
    response: np.ndarray
    kind: str
    exact: np.ndarray
    system: SecondOrderSystem
    workers: int | None = 1
    scheduler: str | None = None
    deviation: Mapping[float, float] = field(default_factory=dict)
    parameters: Mapping[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    basis: np.ndarray | None = None
    estimate_curve: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        for name in ("frequencies_hz", "response", "exact"):
            view = np.asarray(getattr(self, name)).view()
            view.flags.writeable = False  # the caller's array stays as it was
            object.__setattr__(self, name, view)
        object.__setattr__(self, "deviation", MappingProxyType(dict(self.deviation)))
        object.__setattr__(self, "parameters", MappingProxyType(dict(self.parameters)))

    @property
    def accuracy(self) -> float:
        """Relative accuracy of the reference (0: full): the largest deviation of the surrogate
        from the full model measured at the checks, and no less than the tolerance its error
        estimator was driven to (:data:`SURROGATE_TOLERANCE`): between the checks it is only
        known to that (rack-beams: 2.8e-14 at the checks, 3.4e-13 elsewhere)."""
        measured = max(self.deviation.values(), default=0.0)
        return max(measured, SURROGATE_TOLERANCE) if self.kind == "surrogate" else measured

    def checked(self, frequencies_hz: np.ndarray | list[float]) -> ReferenceResponse:
        """The reference with the full response at these grid frequencies (Hz) as well.

        Frequencies already exact are skipped (then ``self`` is returned); each other one
        costs one sparse factorization (shared out to the workers). The relative deviation
        found is recorded, and the time spent added to ``seconds``.
        """
        wanted = np.asarray(frequencies_hz, dtype=float).ravel()
        index = np.unique([int(np.argmin(np.abs(self.frequencies_hz - f))) for f in wanted])
        index = index[~self.exact[index]] if index.size else index
        if index.size == 0:
            return self
        tick = time.perf_counter()
        full, iterative = self._full_responses(self.frequencies_hz[index])
        deviation = dict(self.deviation)
        for i, value in zip(index, self._deviation(full, self.response[index]), strict=True):
            deviation[float(self.frequencies_hz[i])] = float(value)
        response, exact = self.response.copy(), self.exact.copy()
        response[index] = full
        exact[index] = True
        parameters = dict(self.parameters)
        if iterative:
            parameters["checks_from_real_factors"] = (
                parameters.get("checks_from_real_factors", 0) + iterative
            )
        return replace(
            self,
            response=response,
            exact=exact,
            deviation=deviation,
            parameters=parameters,
            seconds=self.seconds + time.perf_counter() - tick,
        )

    def completed(self, count: int) -> ReferenceResponse:
        """The reference checked where its model is weakest, at ``count`` frequencies above
        0 Hz at least (a full reference is returned as it is).

        The maximum of the reference model's estimator (``count >= 1``) and the largest peak of
        the response (``count >= 2``) are checked unless they are already; the frequencies
        checked before (a job's settle checks) count towards ``count``, and the rest are the
        grid frequencies farthest from every expansion point and every checked frequency
        (:func:`check_frequencies`).
        """
        return self.checked(self._weakest(count)) if self.kind == "surrogate" else self

    def _weakest(self, count: int) -> list[float]:
        """The frequencies (Hz) :meth:`completed` checks."""
        done = self.frequencies_hz[self.exact]
        return check_frequencies(
            self.frequencies_hz,
            list(self.parameters.get("expansion_points_hz", [])),
            self.estimate_curve,
            count,
            np.linalg.norm(self.response, axis=(1, 2)),
            checked=[float(f) for f in done if f > 0.0],
        )

    def _full_responses(self, frequencies_hz: np.ndarray) -> tuple[np.ndarray, int]:
        """The full model's response at these frequencies (Hz), and how many of them came
        from a real factor the job holds (the others: one complex factorization each)."""
        out = np.empty(
            (frequencies_hz.size, self.system.observed_matrix.shape[0], self.system.n_inputs),
            dtype=complex,
        )
        direct = []
        for k, f in enumerate(frequencies_hz):
            found = self._from_real_factor(float(f))
            if found is None:
                direct.append(k)
            else:
                out[k] = found
        if direct:
            out[direct] = transfer_function(
                self.system,
                frequencies_hz[direct],
                workers=self.workers if len(direct) > 1 else 1,
                scheduler=self.scheduler,
                label="frequency response (full model, checks)",
            )
        return out, frequencies_hz.size - len(direct)

    def _from_real_factor(self, frequency_hz: float) -> np.ndarray | None:
        """``H`` at one frequency from the nearest real factor of ``K - tau M`` of an open
        :func:`~pymorembs.linalg.shared_factorizations` (certified, or None)."""
        system = self.system
        shared = active_shared_factors()
        if (
            not ITERATIVE_CHECKS
            or system.order < ITERATIVE_MIN_ORDER
            or shared is None
            or self.basis is None
            or frequency_hz == 0.0
            or system.rigid_modes is not None
        ):
            return None
        shifts = shared.real_shifts(system.stiffness, system.mass)
        if not shifts:
            return None
        terms, scale = system.dynamic_terms(2j * np.pi * frequency_hz)
        sigma = -np.real(terms[1][0])  # Z / c = K - sigma M (+ s D / c)
        _, factor = min(shifts, key=lambda pair: abs(pair[0] - sigma))
        x, _ = shifted_response(terms, system.input_matrix, factor, self.basis)
        if x is None:
            return None
        return np.asarray(system.observed_matrix @ x) / scale

    def _blocks(self) -> list[slice]:
        """Row blocks judged each on its own: the outputs, and the stress outputs (if any)."""
        split = self.system.n_outputs
        return [slice(0, split)] + ([slice(split, None)] if self.system.n_stress else [])

    def _deviation(self, full: np.ndarray, surrogate: np.ndarray) -> np.ndarray:
        """``||H - H_ref||_F / ||H||_F`` per frequency; with stress outputs the larger of the
        outputs' and the stresses' (each relative to its own block, whatever the units)."""
        curves = [relative_error(full[:, rows], surrogate[:, rows]) for rows in self._blocks()]
        return np.max(curves, axis=0)

    def errors(self, reduced: np.ndarray) -> np.ndarray:
        """``eps(f)`` of eq. 27 of a reduced response against this reference, shape (n_f,),
        over the outputs ``C`` (stress outputs: :meth:`stress_errors`)."""
        rows = self._blocks()[0]
        return relative_error(self.response[:, rows], reduced[:, rows])

    def stress_errors(self, reduced: np.ndarray) -> np.ndarray | None:
        """``eps_s(f)`` of eq. 27 over the stress outputs under all inputs, shape (n_f,); None
        without stress outputs."""
        if self.system.n_stress == 0:
            return None
        rows = self._blocks()[1]
        return relative_error(self.response[:, rows], reduced[:, rows])

    def settled(self, reduced: np.ndarray) -> ReferenceResponse:
        """The reference on which the maximum of ``eps(f)`` of ``reduced`` is measured against
        the full model (then ``errors(reduced)`` is the settled curve), and that of
        ``stress_errors(reduced)`` if there are stress outputs.

        The frequency of the largest error is checked (:meth:`checked`) until the maximum lies
        on an exact frequency, at most :data:`SETTLE_ROUNDS` times. A full reference is
        returned as it is.
        """
        reference = self
        for _ in range(SETTLE_ROUNDS):
            blocks = reference._blocks()
            curves = [relative_error(reference.response[:, r], reduced[:, r]) for r in blocks]
            tops = {int(np.argmax(np.where(np.isfinite(eps), eps, np.inf))) for eps in curves}
            open_ = [top for top in sorted(tops) if not reference.exact[top]]
            if not open_:
                break
            reference = reference.checked(reference.frequencies_hz[open_])
        return reference

    def settled_all(self, responses: Sequence[np.ndarray]) -> ReferenceResponse:
        """The reference that settles several reduced responses at once (all judged against
        the same reference).

        Each response is settled (:meth:`settled`); as the checks one response asks for change
        the reference the others were judged against, the round is repeated until no response
        asks for a new check. The result keeps every check (a job's cache of full-model
        frequencies).
        """
        reference = self
        while True:
            before = int(np.count_nonzero(reference.exact))
            for response in responses:
                reference = reference.settled(response)
            if int(np.count_nonzero(reference.exact)) == before:
                return reference

    def resolved(self, eps: np.ndarray) -> bool:
        """Whether a reduction's maximum error stands 10 times above the reference's accuracy."""
        return bool(np.max(eps, initial=0.0) >= 10.0 * self.accuracy)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready description for the summary."""
        out: dict[str, Any] = {"kind": self.kind, "seconds": self.seconds}
        if self.kind == "surrogate":
            out.update(self.parameters)
            out["exact_frequencies"] = int(np.count_nonzero(self.exact))
            out["checks_hz"] = sorted(self.deviation)
            out["deviation"] = [self.deviation[f] for f in sorted(self.deviation)]
            out["accuracy"] = self.accuracy
        return out


def choose_kind(kind: str, order: int) -> str:
    """``"full"`` or ``"surrogate"`` for a requested ``kind`` and a model of ``order`` dofs."""
    if kind not in REFERENCE_KINDS:
        raise UserError(f"reference must be one of {', '.join(REFERENCE_KINDS)}, got {kind!r}")
    if kind == "auto":
        return "full" if order <= FULL_MAX_ORDER else "surrogate"
    return kind


def reference_response(
    system: SecondOrderSystem,
    frequencies_hz: np.ndarray,
    kind: str = "auto",
    checks: int = DEFAULT_CHECKS,
    workers: int | None = 1,
    scheduler: str | None = None,
    candidates_hz: Sequence[float] | None = None,
) -> ReferenceResponse:
    """The reference response of a full sparse system on the error grid.

    Parameters
    ----------
    system : SecondOrderSystem
        The full (sparse) system.
    frequencies_hz : ndarray, shape (n_f,)
        The error grid in Hz (:func:`~pymorembs.frequencies.frequency_grid`).
    kind : {"auto", "full", "surrogate"}
        See the module docstring; ``"auto"``: full up to :data:`FULL_MAX_ORDER` dofs.
    checks : int
        Surrogate: frequencies checked against the full model up front (0 Hz comes on top);
        0 to check only 0 Hz now and the rest later (:meth:`ReferenceResponse.completed`).
    workers, scheduler
        Parallel processes or Dask scheduler of the full-model sweeps
        (:func:`~pymorembs.analysis.transfer.transfer_function`).
    candidates_hz : sequence of float, optional
        Surrogate: expansion points (Hz) the reference model should choose from, e.g. those of
        the reductions it will judge, so that a job factorizes each shift once
        (:func:`~pymorembs.linalg.shared_factorizations`); those in the band are taken, and
        the default equidistant candidates are added while there are fewer than
        :data:`SURROGATE_CANDIDATES`.

    Returns
    -------
    ReferenceResponse
    """
    tick = time.perf_counter()
    frequencies_hz = np.asarray(frequencies_hz, dtype=float).ravel()
    kind = choose_kind(kind, system.order)
    if checks < 0:
        raise UserError(f"check_points must be at least 0, got {checks}")
    if kind == "full":
        response = transfer_function(
            system,
            frequencies_hz,
            workers=workers,
            scheduler=scheduler,
            label="frequency response (full model)",
        )
        exact = np.ones(frequencies_hz.size, dtype=bool)
        return ReferenceResponse(
            frequencies_hz, response, "full", exact, system, workers, scheduler,
            seconds=time.perf_counter() - tick,
        )  # fmt: skip
    model, parameters, estimate_curve, basis = _reference_model(
        system, frequencies_hz, candidates_hz
    )
    response = transfer_function(model, frequencies_hz, label="frequency response (reference)")
    reference = ReferenceResponse(
        frequencies_hz,
        response,
        "surrogate",
        np.zeros(frequencies_hz.size, dtype=bool),
        system,
        workers,
        scheduler,
        parameters=parameters,
        basis=basis,
        estimate_curve=estimate_curve,
    )
    wanted = [0.0] if frequencies_hz[0] == 0.0 else []
    reference = reference.checked(wanted + reference._weakest(checks))
    return replace(reference, seconds=time.perf_counter() - tick)


def _reference_model(
    system: SecondOrderSystem,
    frequencies_hz: np.ndarray,
    candidates_hz: Sequence[float] | None = None,
) -> tuple[SecondOrderSystem, dict[str, Any], tuple[np.ndarray, np.ndarray] | None, np.ndarray]:
    """The reference model by SOAGA; its reduced system, facts, estimator curve and basis."""
    from pymorembs.reduction.projection import reduced_model
    from pymorembs.reduction.soaga import candidate_points, soaga_reduction

    band = (float(frequencies_hz.min()), float(frequencies_hz.max()))
    given = [float(f) for f in candidates_hz or () if band[0] <= f <= band[1]]
    if len(set(given)) < SURROGATE_CANDIDATES:
        given += candidate_points(*band, None, SURROGATE_CANDIDATES)
    projection = soaga_reduction(
        replace(system, stress_targeted=system.n_stress > 0),  # stresses to the same tolerance
        band,
        candidates_hz=sorted(set(given)),
        tolerance=SURROGATE_TOLERANCE,
        max_order=max(1, min(SURROGATE_MAX_ORDER, system.order // 2)),
        tol=SURROGATE_DEFLATION,
        label="reference model (soaga)",
        tolerance_label="internal SOAGA tolerance of the surrogate reference",
    )
    model = reduced_model(system, projection)
    points = [float(f) for f in projection.parameters.get("expansion_points_hz", [])]
    parameters = {
        "order": int(projection.order),
        "estimate": None if projection.error_estimate is None else float(projection.error_estimate),
        "expansion_points_hz": points,
        "factorizations": projection.parameters.get("factorizations"),
        "stop": projection.parameters.get("stop"),
    }
    return model.system, parameters, projection.error_curve, projection.V


def check_frequencies(
    frequencies_hz: np.ndarray,
    expansion_points_hz: list[float],
    estimate_curve: tuple[np.ndarray, np.ndarray] | None,
    count: int,
    magnitude: np.ndarray | None = None,
    checked: Sequence[float] = (),
) -> list[float]:
    """Grid frequencies (Hz) where a Krylov reference model is weakest, ``count`` of them
    with those in ``checked`` (frequencies checked already, which are not chosen again).

    First the maximum of the model's own error estimator (snapped to the grid); then the
    largest peak of the response magnitude ``magnitude`` (``||H_ref(f)||_F`` on the grid): at a
    lightly damped resonance the shifted matrix is nearly singular and every solve, reduced or
    full, is least accurate (rack-solid at 10,000 dofs, with ``longdouble`` residuals: 7.6e-11
    at its 42 Hz peak, 1e-12 elsewhere, and even the refined full solves were off by 4.4e-11
    there); then greedily the grid frequency farthest (in Hz) from every expansion point
    and every frequency checked or chosen before: moment matching is exact at the points and
    weakest between them. The estimator's maximum and the peak are chosen (for ``count`` of
    at least 1 and 2) unless they are in ``checked``, however many that holds.
    """
    chosen: list[float] = []
    checked = [float(f) for f in checked]
    if count == 0:
        return chosen
    firsts = []
    if estimate_curve is not None and np.size(estimate_curve[1]):
        f_est, est = (np.asarray(a, dtype=float) for a in estimate_curve)
        top = f_est[int(np.nanargmax(est))]
        firsts.append(float(frequencies_hz[int(np.argmin(np.abs(frequencies_hz - top)))]))
    if magnitude is not None and count > len(firsts):
        firsts.append(float(frequencies_hz[int(np.nanargmax(magnitude))]))
    for first in firsts:
        if first not in chosen and first not in checked:
            chosen.append(first)
    taken = [*expansion_points_hz, *checked, *chosen]
    while len(set(chosen) | set(checked)) < min(count, frequencies_hz.size):
        if taken:
            distance = np.min(np.abs(frequencies_hz[:, None] - np.asarray(taken)[None, :]), axis=1)
        else:
            distance = np.ones(frequencies_hz.size)
        pick = float(frequencies_hz[int(np.argmax(distance))])
        if pick in chosen or pick in checked:  # every grid frequency taken
            break
        chosen.append(pick)
        taken.append(pick)
    return chosen
