"""The summary of a job run, a typed value written as ``summary.json`` by its one ``to_json``.

:func:`~pymorembs.job.run.run_job` builds a :class:`JobSummary`; the command line prints its
table from it, the app reads it back (:meth:`JobSummary.from_json` of ``summary.json``) and the
HTML report is written from its :meth:`~JobSummary.to_json`. ``docs/jobs.md`` ("summary.json")
documents every key. The entries that lower layers compute and describe themselves (the model's
sizes, the units, the validation, the reference, the provenance, the rows of the time-domain
and large-motion checks) stay their JSON dictionaries here.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Self

#: The ``covers`` text of a reduction's errors over the inertia loads.
INERTIA_COVERS = (
    "the inertia loads of the frame motion to the port outputs and their collocated outputs, "
    "and the port inputs to those"
)
#: The ``covers`` text of a reduction's errors over the stress outputs.
STRESS_COVERS = (
    "the six stress components at every hot spot under every input (port forces and inertia "
    "loads), against the full model's, eq. 27 over that block"
)
#: What a reduction's ``max_rel_error`` covers.
PORTS_COVER = "ports: the port outputs to the port inputs"
#: The keys of the checks that add an entry to the summary and rows to every reduction.
CHECK_KEYS = ("time_domain", "large_motion")


class FlatEntry:
    """An entry of ``summary.json`` whose keys are its dataclass fields, values plain JSON."""

    def to_json(self) -> dict[str, Any]:
        """The entry as ``summary.json`` holds it."""
        return dict(vars(self))

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Self:
        """The entry read back from ``summary.json``."""
        return cls(**data)


@dataclass(frozen=True)
class Accuracy(FlatEntry):
    """A reduction's ``accuracy`` entry: does it meet its limit, are its body files written.

    Attributes
    ----------
    met : bool
        ``max <= limit``.
    limit : float
        The largest max ε the reduction may have (dimensionless).
    limit_from : {"tolerance", "default"}
        Where the limit comes from.
    max : float
        The largest ε over the ports, the inertia loads and the stress outputs.
    ports : float
        The largest ε over the ports.
    inertia_loads : float or None
        The largest ε over the inertia loads (None: they are not inputs).
    export_inaccurate : bool
        The job's flag: write the body files even when the limit is missed.
    exported : bool
        The body files are written (met, or allowed by the flag).
    stress : float or None
        The largest ε over the stress outputs at the hot spots (None: no ``[stress]``).
    """

    met: bool
    limit: float
    limit_from: str
    max: float
    ports: float
    inertia_loads: float | None
    export_inaccurate: bool
    exported: bool
    stress: float | None = None

    def to_json(self) -> dict[str, Any]:
        """The entry as ``summary.json`` holds it (``stress`` only with stress outputs)."""
        entry = dict(vars(self))
        if self.stress is None:
            del entry["stress"]
        return entry


@dataclass(frozen=True)
class InertiaErrors(FlatEntry):
    """A reduction's errors over the inertia loads of the frame motion (its ``inertia_loads``).

    ``max_rel_error`` and ``static_rel_error`` (at 0 Hz; None: the band does not start there)
    are ε of eq. 27 (dimensionless); ``covers`` says over which transfer paths.
    """

    max_rel_error: float
    static_rel_error: float | None
    covers: str = INERTIA_COVERS


@dataclass(frozen=True)
class StressErrors(FlatEntry):
    """A reduction's errors over the stress outputs at the hot spots (its ``stress``).

    ``max_rel_error`` and ``static_rel_error`` (at 0 Hz; None: the band does not start there)
    are ε of eq. 27 over the stress block (dimensionless); ``estimate`` SOAGA's estimate of its
    maximum (None: another method); ``targeted`` whether the reduction aimed at the stresses;
    ``covers`` says over which transfer paths.
    """

    max_rel_error: float
    static_rel_error: float | None
    estimate: float | None
    targeted: bool
    covers: str = STRESS_COVERS


@dataclass(frozen=True)
class ReductionSummary:
    """One reduction of the job as ``summary.json`` lists it (``reductions``).

    Errors are ε of eq. 27 (dimensionless), frequencies in Hz, times in s; ``files`` relative
    to the job's output folder; ``checks`` the rows of the time-domain and large-motion checks
    (:data:`CHECK_KEYS`) by check and case name.
    """

    name: str
    method: str
    order: int
    max_rel_error: float
    static_rel_error: float | None
    error_estimate: float | None
    error_bound: float | None
    reference_resolved: Any
    time_s: float
    parameters: dict[str, Any]
    eigenfrequencies_hz: list[float]
    highest_frequency_hz: float
    explicit_step_s: float | None
    files: list[str]
    accuracy: Accuracy
    inertia_loads: InertiaErrors | None = None
    checks: dict[str, dict[str, Any]] = field(default_factory=dict)
    stress: StressErrors | None = None
    error_covers: str = PORTS_COVER

    def to_json(self) -> dict[str, Any]:
        """The entry as ``summary.json`` holds it, its keys in their order."""
        entry: dict[str, Any] = {
            "name": self.name,
            "method": self.method,
            "order": self.order,
            "max_rel_error": self.max_rel_error,
            "static_rel_error": self.static_rel_error,
            "error_estimate": self.error_estimate,
            "error_bound": self.error_bound,
            "reference_resolved": self.reference_resolved,
            "error_covers": self.error_covers,
            "time_s": self.time_s,
            "parameters": self.parameters,
            "eigenfrequencies_hz": self.eigenfrequencies_hz,
            "highest_frequency_hz": self.highest_frequency_hz,
            "explicit_step_s": self.explicit_step_s,
            "files": self.files,
        }
        if self.inertia_loads is not None:
            entry["inertia_loads"] = self.inertia_loads.to_json()
        if self.stress is not None:
            entry["stress"] = self.stress.to_json()
        entry["accuracy"] = self.accuracy.to_json()
        return entry | self.checks

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ReductionSummary:
        """The entry read back from ``summary.json``."""
        values = {key: value for key, value in data.items() if key not in CHECK_KEYS}
        inertia = values.pop("inertia_loads", None)
        stress = values.pop("stress", None)
        return cls(
            **values | {"accuracy": Accuracy.from_json(values["accuracy"])},
            inertia_loads=None if inertia is None else InertiaErrors.from_json(inertia),
            stress=None if stress is None else StressErrors.from_json(stress),
            checks={key: data[key] for key in CHECK_KEYS if key in data},
        )

    def with_check(self, key: str, rows: dict[str, Any]) -> ReductionSummary:
        """The entry with its ``rows`` (by case name) of the check ``key``."""
        return replace(self, checks=self.checks | {key: rows})


@dataclass(frozen=True)
class JobSummary:
    """The summary of a job run (``summary.json``); see ``docs/jobs.md`` for every key.

    ``checks``: the entries of the time-domain and large-motion checks the job ran
    (:data:`CHECK_KEYS`); ``title``: the job's title ("" none, then not written).
    """

    pymorembs_version: str
    job: str
    model: dict[str, Any]
    units: dict[str, Any]
    validation: dict[str, Any]
    band_hz: tuple[float, float]
    n_frequencies: int
    reference: dict[str, Any]
    reductions: tuple[ReductionSummary, ...]
    warnings: list[str]
    notes: list[str]
    timings_s: dict[str, float]
    files: list[str]
    provenance: dict[str, Any]
    checks: dict[str, dict[str, Any]] = field(default_factory=dict)
    title: str = ""

    @property
    def accuracy(self) -> dict[str, Any]:
        """The job's ``accuracy`` entry: whether every reduction met its limit, and which did
        not (``not_met``) and of those which wrote no body files (``not_exported``)."""
        missed = [r for r in self.reductions if not r.accuracy.met]
        return {
            "met": not missed,
            "not_met": [r.name for r in missed],
            "not_exported": [r.name for r in missed if not r.accuracy.exported],
        }

    @property
    def inertia_loads(self) -> dict[str, Any] | None:
        """The model's inertia loads (None: not inputs of the reductions)."""
        return self.model.get("inertia_loads")

    def to_json(self) -> dict[str, Any]:
        """The summary as ``summary.json`` holds it, its keys in their order."""
        return {
            "pymorembs_version": self.pymorembs_version,
            "job": self.job,
            "model": self.model,
            "units": self.units,
            "validation": self.validation,
            "band_hz": list(self.band_hz),
            "n_frequencies": self.n_frequencies,
            "reference": self.reference,
            "reductions": [r.to_json() for r in self.reductions],
            "warnings": self.warnings,
            "notes": self.notes,
            "timings_s": self.timings_s,
            "accuracy": self.accuracy,
            "files": self.files,
            "provenance": self.provenance,
            **self.checks,
            **({"title": self.title} if self.title else {}),
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> JobSummary:
        """The summary read back from ``summary.json``."""
        values = {key: value for key, value in data.items() if key not in CHECK_KEYS}
        del values["accuracy"]  # derived from the reductions
        return cls(
            **values
            | {
                "band_hz": (data["band_hz"][0], data["band_hz"][1]),
                "reductions": tuple(ReductionSummary.from_json(r) for r in data["reductions"]),
            },
            checks={key: data[key] for key in CHECK_KEYS if key in data},
        )
