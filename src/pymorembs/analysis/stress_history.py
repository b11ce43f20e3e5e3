"""Stress histories at hot spots: peak, range, and the deviation of one history from another.

The time-domain checks (paper section 5.1) give the stress at the hot spots of the full model,
``sigma(t) = C_sigma q(t)``, and of each reduced body, ``C_sigma V q_r(t)``; the large-motion
checks give that of each body in Exudyn from its elastic coordinates. ``C_sigma`` is the sparse
:class:`~pymorembs.stress.StressOperator` of the hot spots: six components per point, in the
order xx, yy, zz, xy, xz, yz, in the model's stress unit (Pa for SI models).

Per hot spot (:class:`HotSpotStress`) a history gives

* the peak of the von Mises stress over time, and its range ``max_t - min_t``;
* the range ``max_t - min_t`` of the **absolute maximum principal stress**: at each time the
  principal stress of the largest magnitude, with its sign (tension positive) -- the quantity
  of a stress-life fatigue count on a point loaded in tension or in compression alike.

A candidate history is compared with a reference (:func:`compare_histories`) by the largest
deviation over time and the six components, ``max |sigma_cand - sigma_ref|``, relative to the
reference's peak von Mises stress: over all hot spots relative to the peak over all hot spots,
and per hot spot relative to that point's own peak.

The histories themselves go into a run's folder as :data:`HISTORY_FILE` (a ``.npz`` archive of
plain arrays, :func:`history_arrays`; read back by :func:`histories_from_arrays`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from pymorembs.errors import UserError
from pymorembs.stress import COMPONENTS, StressOperator, von_mises

__all__ = [
    "HISTORY_FILE",
    "STRESS_COVERS",
    "HotSpotStress",
    "StressComparison",
    "StressHistory",
    "compare_histories",
    "histories_from_arrays",
    "history_arrays",
    "hot_spot_entries",
    "hot_spot_labels",
    "stress_history",
    "stress_settings",
]

#: What the stress figures of a comparison cover (the ``covers`` text of ``summary.json``).
STRESS_COVERS = (
    "the six stress components at the hot spots over the whole history (model stress unit); "
    "max_rel_deviation: max over time, hot spots and components of |sigma - sigma_ref| over the "
    "reference's peak von Mises stress over all hot spots (per hot spot: over its own peak); "
    "range: max - min over time of the von Mises stress and of the absolute maximum principal "
    "stress (the principal stress of largest magnitude, signed)"
)
#: The file of a run's stress histories at the hot spots (:func:`history_arrays`).
HISTORY_FILE = "stress_history.npz"
#: Stress histories by check (``time_domain``, ``large_motion``), load case or motion and body.
CheckHistories = Mapping[str, Mapping[str, Mapping[str, "StressHistory"]]]
#: Index pairs (i, j) of the symmetric tensor of each component of :data:`COMPONENTS`.
TENSOR_INDEX = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def hot_spot_labels(operator: StressOperator) -> tuple[str, ...]:
    """One label per point of ``operator`` (its row labels without the component, e.g.
    ``"e1234.ip3"``, ``"n17"``)."""
    return tuple(label.rsplit(":", 1)[0] for label in operator.labels()[:: len(COMPONENTS)])


@dataclass(frozen=True)
class HotSpotStress:
    """Peak and range of the stress at one hot spot over a history, model stress unit.

    Attributes
    ----------
    point : str
        The hot spot's label (:func:`hot_spot_labels`).
    peak_von_mises : float
        ``max_t sigma_vM(t)``.
    range_von_mises : float
        ``max_t sigma_vM(t) - min_t sigma_vM(t)``.
    range_abs_max_principal : float
        ``max_t - min_t`` of the absolute maximum principal stress (module docstring).
    max_rel_deviation : float or None
        Against a reference history: ``max_t,component |sigma - sigma_ref|`` over the
        reference's peak von Mises stress at this point; None for the reference itself.
    """

    point: str
    peak_von_mises: float
    range_von_mises: float
    range_abs_max_principal: float
    max_rel_deviation: float | None = None

    def to_json(self) -> dict[str, Any]:
        """The entry as ``summary.json`` holds it (``max_rel_deviation`` only when set)."""
        entry = {
            "point": self.point,
            "peak_von_mises": self.peak_von_mises,
            "range_von_mises": self.range_von_mises,
            "range_abs_max_principal": self.range_abs_max_principal,
        }
        if self.max_rel_deviation is not None:
            entry["max_rel_deviation"] = self.max_rel_deviation
        return entry


@dataclass(frozen=True, eq=False)
class StressHistory:
    """The six stress components at hot spots over time.

    Attributes
    ----------
    times : ndarray, shape (n_t,)
        s.
    values : ndarray, shape (n_t, 6 n_points)
        Point-major rows of the stress operator (components xx, yy, zz, xy, xz, yz), model
        stress unit.
    points : tuple of str
        The hot spots' labels (``n_points``).
    """

    times: np.ndarray
    values: np.ndarray
    points: tuple[str, ...]

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=float)
        if values.shape != (np.size(self.times), len(COMPONENTS) * len(self.points)):
            raise UserError(
                f"a stress history of {len(self.points)} hot spots over {np.size(self.times)} "
                f"times needs shape ({np.size(self.times)}, {6 * len(self.points)}), got "
                f"{values.shape}"
            )
        object.__setattr__(self, "values", values)

    @property
    def components(self) -> np.ndarray:
        """The components per hot spot, shape (n_t, n_points, 6)."""
        return self.values.reshape(self.values.shape[0], len(self.points), len(COMPONENTS))

    @cached_property
    def von_mises(self) -> np.ndarray:
        """The von Mises stress, shape (n_t, n_points)."""
        return von_mises(self.components, axis=-1)

    @cached_property
    def abs_max_principal(self) -> np.ndarray:
        """The absolute maximum principal stress (signed), shape (n_t, n_points)."""
        components = self.components
        tensor = np.empty((*components.shape[:2], 3, 3))
        for k, (i, j) in enumerate(TENSOR_INDEX):
            tensor[..., i, j] = tensor[..., j, i] = components[..., k]
        principal = np.linalg.eigvalsh(tensor)  # ascending
        low, high = principal[..., 0], principal[..., -1]
        return np.where(np.abs(low) > np.abs(high), low, high)

    def hot_spots(self) -> list[HotSpotStress]:
        """Peak and ranges at every hot spot (no deviation)."""
        vm, principal = self.von_mises, self.abs_max_principal
        return [
            HotSpotStress(
                point,
                float(vm[:, k].max()),
                float(np.ptp(vm[:, k])),
                float(np.ptp(principal[:, k])),
            )
            for k, point in enumerate(self.points)
        ]


@dataclass(frozen=True)
class StressComparison:
    """A stress history against a reference history at the same hot spots and times.

    Attributes
    ----------
    max_rel_deviation : float
        ``max_t,points,components |sigma - sigma_ref|`` over the reference's peak von Mises
        stress over all hot spots.
    von_mises_max_rel_deviation : float
        ``max_t,points |sigma_vM - sigma_vM,ref|`` over the same peak.
    worst_point : str
        The hot spot of the largest deviation relative to its own peak.
    reference_peak_von_mises : float
        The reference's peak von Mises stress over all hot spots, model stress unit.
    hot_spots : list of HotSpotStress
        Per hot spot this history's peak and ranges, and its deviation relative to the
        reference's peak at that point.
    """

    max_rel_deviation: float
    von_mises_max_rel_deviation: float
    worst_point: str
    reference_peak_von_mises: float
    hot_spots: list[HotSpotStress]

    def to_json(self) -> dict[str, Any]:
        """The entry as ``summary.json`` holds it."""
        return {
            "max_rel_deviation": self.max_rel_deviation,
            "von_mises_max_rel_deviation": self.von_mises_max_rel_deviation,
            "worst_point": self.worst_point,
            "reference_peak_von_mises": self.reference_peak_von_mises,
            "hot_spots": [spot.to_json() for spot in self.hot_spots],
        }


def _ratio(deviation: np.ndarray, peak: np.ndarray | float) -> np.ndarray:
    """``deviation / peak``; 0 where both vanish, inf where only the peak does."""
    peak = np.broadcast_to(np.asarray(peak, dtype=float), np.shape(deviation))
    out = np.where(deviation > 0, np.inf, 0.0)
    return np.divide(deviation, peak, out=out, where=peak > 0)


def compare_histories(candidate: StressHistory, reference: StressHistory) -> StressComparison:
    """``candidate``'s deviation from ``reference`` (class :class:`StressComparison`).

    Raises
    ------
    UserError
        The histories have other hot spots or other times.
    """
    if candidate.points != reference.points:
        raise UserError("the stress histories to compare are at different hot spots")
    if candidate.times.shape != reference.times.shape or not np.allclose(
        candidate.times, reference.times
    ):
        raise UserError("the stress histories to compare have different time grids")
    difference = np.abs(candidate.components - reference.components).max(axis=(0, 2))
    peaks = reference.von_mises.max(axis=0)
    peak = float(peaks.max(initial=0.0))
    per_point = _ratio(difference, peaks)
    vm_difference = float(np.abs(candidate.von_mises - reference.von_mises).max(initial=0.0))
    spots = [
        HotSpotStress(
            spot.point,
            spot.peak_von_mises,
            spot.range_von_mises,
            spot.range_abs_max_principal,
            float(per_point[k]),
        )
        for k, spot in enumerate(candidate.hot_spots())
    ]
    return StressComparison(
        max_rel_deviation=float(_ratio(difference.max(initial=0.0), peak)),
        von_mises_max_rel_deviation=float(_ratio(np.asarray(vm_difference), peak)),
        worst_point=reference.points[int(np.argmax(per_point))] if reference.points else "",
        reference_peak_von_mises=peak,
        hot_spots=spots,
    )


def stress_settings(operator: StressOperator, reference: str) -> dict[str, Any]:
    """The ``stress`` entry of a check in ``summary.json``: the hot spots' labels, the
    operator's quantity and location, what the histories are compared with (``reference``)
    and :data:`STRESS_COVERS`."""
    return {
        "points": list(hot_spot_labels(operator)),
        "quantity": operator.quantity,
        "location": operator.location,
        "reference": reference,
        "covers": STRESS_COVERS,
    }


def hot_spot_entries(history: StressHistory | None) -> dict[str, Any]:
    """``{"stress_hot_spots": [...]}``: the peak and ranges per hot spot of a reference history
    as ``summary.json`` holds them; empty without a history."""
    if history is None:
        return {}
    return {"stress_hot_spots": [spot.to_json() for spot in history.hot_spots()]}


def stress_history(
    times: np.ndarray, coordinates: np.ndarray, stress_modes: np.ndarray, points: Sequence[str]
) -> StressHistory:
    """The history ``C_sigma V q(t)`` from a body's coordinates over time.

    Parameters
    ----------
    times : ndarray, shape (n_t,)
    coordinates : ndarray, shape (n_t, n)
        The coordinates ``q(t)`` of the body (e.g. Exudyn's elastic coordinates).
    stress_modes : ndarray, shape (6 n_points, n)
        ``C_sigma V``: the stress of each shape function at the hot spots.
    points : sequence of str
    """
    return StressHistory(np.asarray(times), np.asarray(coordinates) @ stress_modes.T, tuple(points))


def history_arrays(checks: CheckHistories, coordinates: np.ndarray) -> dict[str, np.ndarray]:
    """The members of :data:`HISTORY_FILE`: plain arrays (no pickles), keys below.

    ``points`` (n_p,) the hot spots' labels; ``coordinates`` (n_p, 3) their positions (model
    length unit); ``components`` (6,) ``xx yy zz xy xz yz``; then per check and per load case
    or motion ``<check>/<case>/``: ``times`` (n_t,) s, ``bodies`` (n_b,) the bodies' names, and
    per body ``k`` (its index in ``bodies``) ``<k>/stress`` (n_t, n_p, 6) and
    ``<k>/von_mises`` (n_t, n_p), model stress unit.

    Parameters
    ----------
    checks : dict of check -> (dict of case -> (dict of body name -> StressHistory))
        Every history at the same hot spots; within a case on the same times.
    coordinates : ndarray, shape (n_p, 3)
    """
    points: tuple[str, ...] | None = None
    arrays: dict[str, np.ndarray] = {}
    for check, cases in checks.items():
        for case, bodies in cases.items():
            prefix = f"{check}/{case}"
            arrays[f"{prefix}/bodies"] = np.array(list(bodies), dtype=str)
            for k, history in enumerate(bodies.values()):
                points = history.points if points is None else points
                if history.points != points:
                    raise UserError("the stress histories to write are at different hot spots")
                arrays.setdefault(f"{prefix}/times", history.times)
                arrays[f"{prefix}/{k}/stress"] = history.components
                arrays[f"{prefix}/{k}/von_mises"] = history.von_mises
    return {
        "points": np.array(points or (), dtype=str),
        "coordinates": np.asarray(coordinates, dtype=float).reshape(-1, 3),
        "components": np.array(COMPONENTS, dtype=str),
        **arrays,
    }


def histories_from_arrays(arrays: Mapping[str, np.ndarray]) -> dict[str, dict[str, dict]]:
    """The histories of :func:`history_arrays`' members (e.g. an opened :data:`HISTORY_FILE`):
    by check, case and body name a :class:`StressHistory`."""
    points = tuple(str(p) for p in arrays["points"])
    checks: dict[str, dict[str, dict]] = {}
    for key in arrays:
        if not key.endswith("/bodies"):
            continue
        prefix = key.removesuffix("/bodies")
        check, case = prefix.split("/", 1)
        times = np.asarray(arrays[f"{prefix}/times"])
        checks.setdefault(check, {})[case] = {
            str(name): StressHistory(
                times, np.asarray(arrays[f"{prefix}/{k}/stress"]).reshape(times.size, -1), points
            )
            for k, name in enumerate(arrays[key])
        }
    return checks
