"""The reduction methods and their options, written once (the method registry).

Each method family of the paper's section 3 (Fehr and Eberhard 2011, cited in
:mod:`pymorembs`) has one frozen dataclass of options with its defaults; the Python API
(:func:`pymorembs.reduce`), the job file (``[[reduction]]`` tables, :mod:`pymorembs.job.schema`),
the method functions of :mod:`pymorembs.reduction` called directly (``krylov_reduction(system,
...)``) and the job reference (:func:`options_table`) all use them. Building an options object
checks it, and nothing else checks an option: a bad value raises :class:`OptionError`, which
names the option. The registry only declares; the methods run the checked object
(:func:`pymorembs.reduction.method_projection`), their policies (the two-step Gramian's first
stage) live with them in :mod:`pymorembs.reduction`.

=================  ==========================================================================
method             what it keeps (paper section)
=================  ==========================================================================
``modal``          the lowest (or the dominant, eq. 26) eigenmodes, with frequency-response
                   modes on request (3.1)
``craig-bampton``  fixed-interface modes and the static constraint modes of the input dofs
``krylov``         moments of the transfer function at expansion points (eqs. 19-22, 3.1)
``soaga``          adaptive second-order global Arnoldi with an error estimator (3.1)
``gramian``        the dominant directions of frequency-weighted Gramians (eqs. 23-26, 3.2)
``pod``            Gramians approximated from frequency-response snapshots (3.2)
=================  ==========================================================================

Frequencies are in Hz throughout (``s = i 2 pi f``).
"""

from __future__ import annotations

import dataclasses
import difflib
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from pymorembs.arguments import (
    OptionError,
    described,
    flag,
    frequencies,
    number,
    plain,
    whole,
    whole_list,
)

__all__ = [
    "METHODS",
    "RENAMED_OPTIONS",
    "CraigBamptonOptions",
    "GramianOptions",
    "KrylovOptions",
    "ModalOptions",
    "OptionError",
    "PodOptions",
    "ReductionOptions",
    "SoagaOptions",
    "method_options",
    "option_fields",
    "options_table",
    "renamed_message",
]

#: Old option name -> its name now (one name per idea); the old name is refused with a pointer.
RENAMED_OPTIONS: dict[str, str] = {"tol": "deflation_tolerance"}


def _choice(key: str, value: Any, choices: tuple[str, ...], what: str = "") -> str:
    value = plain(value)
    if not isinstance(value, str) or value not in choices:
        quoted = ", ".join(f"'{c}'" for c in choices[:-1]) + f" or '{choices[-1]}'"
        raise OptionError(key, f"must be {quoted}{what}, got {described(value)}")
    return value


def _given(value: Any) -> bool:
    """Whether a list option with the default ``()`` was given (an array, list or non-empty
    tuple; an array is never compared elementwise with the default)."""
    return not (isinstance(value, tuple) and value == ())


def _moments(value: Any, points: tuple[float, ...] | None) -> int | tuple[int, ...] | None:
    """Moments per expansion point: one whole number for all points, or one per point."""
    single = plain(value)
    if single is None:
        return None
    what = "a whole number >= 1 or one per expansion point"
    if isinstance(single, int) and not isinstance(single, bool):
        return whole("moments", single, minimum=1)
    values = whole_list("moments", value, what, minimum=1)
    if points is not None and len(values) != len(points):
        raise OptionError("moments", f"{len(values)} values for {len(points)} expansion points")
    return values


def _points(key: str, value: Any) -> tuple[float, ...]:
    """Expansion points (Hz): a non-empty list of finite frequencies >= 0, none repeated (a
    repeated point adds a factorization and no direction)."""
    points = frequencies(key, value)
    if len(set(points)) != len(points):
        raise OptionError(key, f"points repeat: {list(points)}")
    return points


def _relative(key: str, value: Any, meaning: str) -> float | None:
    value = number(key, value)
    if value is not None and not 0 < value < 1:
        raise OptionError(key, f"must lie in (0, 1) ({meaning}), got {value}")
    return value


def _positive(key: str, value: Any) -> float | None:
    """A number > 0 (a stopping tolerance), or None."""
    value = number(key, value)
    if value is not None and not value > 0:
        raise OptionError(key, f"must be > 0, got {value!r}")
    return value


def _deflation(value: Any) -> float:
    key = "deflation_tolerance"
    tolerance = number(key, value, minimum=1e-15)
    if tolerance > 1e-3:
        raise OptionError(key, f"must be at most 1e-3 (a deflation tolerance), got {tolerance!r}")
    return tolerance


@dataclass(frozen=True)
class ReductionOptions:
    """Options of every method.

    Attributes
    ----------
    max_frequency_hz : float, optional
        Remove the reduced model's eigen-directions above this frequency (Hz), e.g. for an
        explicit integrator (:func:`~pymorembs.reduction.projection.without_stiff_directions`).
    """

    method: ClassVar[str] = ""
    max_frequency_hz: float | None = None

    def __post_init__(self) -> None:
        limit = number("max_frequency_hz", self.max_frequency_hz)
        if limit is not None and not limit > 0:
            raise OptionError("max_frequency_hz", f"must be a frequency > 0 (Hz), got {limit!r}")
        self._set("max_frequency_hz", limit)

    def _set(self, key: str, value: Any) -> None:
        object.__setattr__(self, key, value)

    @property
    def order(self) -> int | None:  # overridden by the methods that have one
        return None

    def given(self) -> dict[str, Any]:
        """The options that differ from their defaults (as a job would write them)."""
        out = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            default = f.default if f.default is not dataclasses.MISSING else object()
            if value != default:
                out[f.name] = list(value) if isinstance(value, tuple) else value
        return out


@dataclass(frozen=True)
class ModalOptions(ReductionOptions):
    """``modal``: eigenmodes (and frequency-response modes).

    Attributes
    ----------
    order : int
        Number of modes (with ``frm_hz``: modes and frequency-response modes together).
    select : {"lowest", "best"}
        The lowest modes, or the ``order`` modes with the largest approximate Hankel singular
        values (eq. 26) among ``candidates``.
    candidates : int, optional
        Modes computed for ``select = "best"`` (default ``max(3 order, order + 20)``).
    frm_hz : tuple of float
        Add the frequency-response modes ``(K - w^2 M)^-1 B`` at these frequencies (Hz).
    shift_hz : float
        Shift-invert about ``sigma = -(2 pi shift_hz)^2`` (Hz).
    """

    method: ClassVar[str] = "modal"
    order: int | None = None
    select: str = "lowest"
    candidates: int | None = None
    frm_hz: tuple[float, ...] = ()
    shift_hz: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.order is None:
            raise OptionError(None, "modal reduction needs 'order'")
        order = whole("order", self.order)
        self._set("order", order)
        self._set("shift_hz", number("shift_hz", self.shift_hz, minimum=0.0))
        self._set("select", _choice("select", self.select, ("lowest", "best"), " (eq. 26)"))
        candidates = whole("candidates", self.candidates)
        if candidates is not None and candidates <= order:
            raise OptionError("candidates", f"must exceed the order {order}, got {candidates}")
        self._set("candidates", candidates)
        self._set("frm_hz", frequencies("frm_hz", self.frm_hz) if _given(self.frm_hz) else ())


@dataclass(frozen=True)
class CraigBamptonOptions(ReductionOptions):
    """``craig-bampton``: fixed-interface modes and static constraint modes of the input dofs.

    Attributes
    ----------
    fixed_modes : int
        Fixed-interface normal modes (0: Guyan reduction). The order follows from them and the
        boundary (the dofs of the port forces); with inertia loads, their static responses with
        the boundary held are added.
    shift_hz : float
        Shift-invert of the fixed-interface eigenproblem (Hz).
    """

    method: ClassVar[str] = "craig-bampton"
    fixed_modes: int | None = None
    shift_hz: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.fixed_modes is None:
            raise OptionError(None, "craig-bampton needs 'fixed_modes'")
        self._set("fixed_modes", whole("fixed_modes", self.fixed_modes, minimum=0))
        self._set("shift_hz", number("shift_hz", self.shift_hz, minimum=0.0))


@dataclass(frozen=True)
class KrylovOptions(ReductionOptions):
    """``krylov``: moment matching at expansion points (eqs. 19-22).

    Attributes
    ----------
    expansion_points_hz : tuple of float
        Expansion points (Hz, ``s = i 2 pi f``).
    order : int, optional
        Without ``moments``: blocks are added round-robin over the points, lowest moments first,
        until the basis has ``order`` columns; with ``moments``: a cap.
    moments : int or tuple of int, optional
        Moments (blocks) per point: one number for all or one per point.
    two_sided : bool
        ``W`` from the output Krylov spaces (eq. 22): 2r moments for ``C != B^T``.
    deflation_tolerance : float
        Deflation tolerance of the block Arnoldi process (relative).
    """

    method: ClassVar[str] = "krylov"
    expansion_points_hz: tuple[float, ...] = ()
    order: int | None = None
    moments: int | tuple[int, ...] | None = None
    two_sided: bool = False
    deflation_tolerance: float = 1e-10

    def __post_init__(self) -> None:
        super().__post_init__()
        if not _given(self.expansion_points_hz):
            raise OptionError(None, "missing key 'expansion_points_hz'")
        points = _points("expansion_points_hz", self.expansion_points_hz)
        self._set("expansion_points_hz", points)
        self._set("order", whole("order", self.order))
        self._set("moments", _moments(self.moments, points))
        if self.moments is None and self.order is None:
            raise OptionError(None, "krylov needs 'moments' or 'order'")
        self._set("two_sided", flag("two_sided", self.two_sided))
        self._set("deflation_tolerance", _deflation(self.deflation_tolerance))


@dataclass(frozen=True)
class SoagaOptions(ReductionOptions):
    """``soaga``: second-order adaptive global Arnoldi with its error estimator.

    Attributes
    ----------
    tolerance : float, optional
        Stop when the estimated maximum relative error over the band is below it.
    order : int, optional
        The largest order (at least one of ``tolerance`` and ``order``).
    candidates_hz : tuple of float, optional
        Candidate expansion points (Hz); default ``n_candidates`` equidistant over the band.
    n_candidates : int, optional
        Number of equidistant candidates.
    deflation_tolerance : float
        Deflation tolerance of the Arnoldi blocks (relative).
    """

    method: ClassVar[str] = "soaga"
    tolerance: float | None = None
    order: int | None = None
    candidates_hz: tuple[float, ...] | None = None
    n_candidates: int | None = None
    deflation_tolerance: float = 1e-10

    def __post_init__(self) -> None:
        super().__post_init__()
        self._set("order", whole("order", self.order))
        if self.candidates_hz is not None:
            self._set("candidates_hz", _points("candidates_hz", self.candidates_hz))
        self._set("n_candidates", whole("n_candidates", self.n_candidates))
        tolerance = _relative("tolerance", self.tolerance, "relative error")
        self._set("tolerance", tolerance)
        if self.order is None and tolerance is None:
            raise OptionError(
                None,
                "soaga needs 'order' (the largest order) or 'tolerance' (estimated max relative "
                "error), or both",
            )
        self._set("deflation_tolerance", _deflation(self.deflation_tolerance))


def _indicator(options: ReductionOptions) -> float | None:
    tolerance = _relative("tolerance", options.tolerance, "sigma_n+1 / sigma_1")
    if options.order is None and tolerance is None:
        raise OptionError(
            None,
            f"{options.method} needs 'order' or 'tolerance' (the indicator sigma_n+1 / "
            "sigma_1), or both",
        )
    return tolerance


@dataclass(frozen=True)
class GramianOptions(ReductionOptions):
    """``gramian``: dominant eigenspace of the frequency-weighted position Gramians (eqs. 23-26).

    Attributes
    ----------
    order : int, optional
        Reduced order; at least one of ``order`` and ``tolerance``.
    tolerance : float, optional
        Automatic order: the smallest n with ``sigma_n+1 / sigma_1 <= tolerance``.
    first_stage : {"soaga", "krylov", "rational-krylov", "none"}, optional
        The medium model of the two-step reduction (section 3.2). Default: ``"soaga"`` above
        :data:`~pymorembs.reduction.gramian.MAX_DENSE_ORDER` dofs, else none.
        ``"rational-krylov"``: no medium model, the Gramians of the large model by a rational
        Krylov (Galerkin) solver.
    first_order : int, optional
        Order of the medium model (SOAGA default 132, Krylov as its ``order``), or the largest
        dimension of the rational Krylov space (default 300).
    first_tolerance : float, optional
        The SOAGA first stage's estimated error target (default 1e-10).
    convergence_tolerance : float, optional
        Rational Krylov: stop when trace and leading singular value of the Gramians change by
        less than this (relative, default 1e-8).
    expansion_points_hz, moments
        Of the Krylov first stage (as for ``krylov``).
    """

    method: ClassVar[str] = "gramian"
    order: int | None = None
    tolerance: float | None = None
    first_stage: str | None = None
    first_order: int | None = None
    first_tolerance: float | None = None
    convergence_tolerance: float | None = None
    expansion_points_hz: tuple[float, ...] | None = None
    moments: int | tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        self._set("order", whole("order", self.order))
        self._set("tolerance", _indicator(self))
        if self.first_stage is not None:
            stages = ("soaga", "krylov", "rational-krylov", "none")
            self._set("first_stage", _choice("first_stage", self.first_stage, stages))
        self._set("first_order", whole("first_order", self.first_order))
        self._set("first_tolerance", _positive("first_tolerance", self.first_tolerance))
        self._set(
            "convergence_tolerance", _positive("convergence_tolerance", self.convergence_tolerance)
        )
        rational = self.first_stage == "rational-krylov"
        if rational and self.first_tolerance is not None:
            raise OptionError(
                "first_tolerance",
                "is the SOAGA first stage's error target; the rational Krylov solver stops by "
                "'convergence_tolerance'",
            )
        if not rational and self.convergence_tolerance is not None:
            raise OptionError("convergence_tolerance", "belongs to first_stage = 'rational-krylov'")
        if self.first_stage == "krylov" and self.expansion_points_hz is None:
            raise OptionError(None, "missing key 'expansion_points_hz'")
        if self.first_stage == "krylov" and self.moments is None and self.first_order is None:
            raise OptionError(None, "the krylov first stage needs 'moments' or 'first_order'")
        points = None
        if self.expansion_points_hz is not None:
            points = _points("expansion_points_hz", self.expansion_points_hz)
            self._set("expansion_points_hz", points)
        self._set("moments", _moments(self.moments, points))


@dataclass(frozen=True)
class PodOptions(ReductionOptions):
    """``pod``: Gramians approximated from frequency-response snapshots of the full model.

    Attributes
    ----------
    order, tolerance
        As for ``gramian`` (at least one).
    snapshots : int
        Frequency responses over the band (Gauss-Legendre nodes), at least 4.
    """

    method: ClassVar[str] = "pod"
    order: int | None = None
    tolerance: float | None = None
    snapshots: int = 40

    def __post_init__(self) -> None:
        super().__post_init__()
        self._set("order", whole("order", self.order))
        self._set("tolerance", _indicator(self))
        self._set("snapshots", whole("snapshots", self.snapshots, minimum=4))


#: Method name -> its options class.
METHODS: dict[str, type[ReductionOptions]] = {
    cls.method: cls
    for cls in (
        ModalOptions,
        CraigBamptonOptions,
        KrylovOptions,
        SoagaOptions,
        GramianOptions,
        PodOptions,
    )
}


def method_options(method: str, values: Mapping[str, Any] | None = None) -> ReductionOptions:
    """The checked options of ``method`` from a mapping of option names to values.

    Raises
    ------
    OptionError
        Unknown method or option (with the nearest valid name), or a bad value.
    """
    if method not in METHODS:
        hint = difflib.get_close_matches(str(method), list(METHODS), n=1)
        more = f"; did you mean '{hint[0]}'?" if hint else ""
        raise OptionError(
            "method", f"unknown method {method!r}{more} (available: {', '.join(METHODS)})"
        )
    cls = METHODS[method]
    known = [f.name for f in dataclasses.fields(cls)]
    values = dict(values or {})
    for key in values:
        if key not in known and RENAMED_OPTIONS.get(key) in known:
            raise OptionError(key, renamed_message(key))
        if key not in known:
            hint = difflib.get_close_matches(key, known, n=1)
            more = f"; did you mean '{hint[0]}'?" if hint else ""
            raise OptionError(key, f"unknown option of {method}{more}")
    return cls(**values)


def renamed_message(key: str) -> str:
    """What to say about an option given by its old name (:data:`RENAMED_OPTIONS`)."""
    new = RENAMED_OPTIONS[key]
    return f"was renamed to '{new}'; write {new} = ... instead"


def options_table() -> str:
    """The options of every method as a Markdown table (method, option, default, meaning), for
    the job reference (``docs/jobs.md``). ``max_frequency_hz`` (every method) comes once."""
    lines = ["| method | option | default | meaning |", "|---|---|---|---|"]
    common = {f.name for f in dataclasses.fields(ReductionOptions)}
    base = _attribute_docs(ReductionOptions)
    for key in sorted(common):
        lines.append(f"| every method | `{key}` | — | {_markdown(base.get(key, ''))} |")
    for name, cls in METHODS.items():
        docs = _attribute_docs(cls)
        for f in dataclasses.fields(cls):
            if f.name in common:
                continue
            if f.name in _REQUIRED.get(name, ()):
                default = "required"
            elif f.default is None or f.default == ():
                default = "—"
            else:
                default = f"`{f.default!r}`".replace("'", '"')
            lines.append(f"| {name} | `{f.name}` | {default} | {_markdown(docs.get(f.name, ''))} |")
    return "\n".join(lines) + "\n"


def option_fields(method: str) -> list[dict[str, Any]]:
    """The options of ``method`` as a form would show them, read from its options dataclass.

    Returns
    -------
    list of dict
        One per option, in the dataclass's order (``max_frequency_hz`` last): ``name``;
        ``kind`` -- ``"int"``, ``"float"``, ``"bool"``, ``"str"``, ``"choice"`` (one of
        ``choices``), ``"floats"`` (a list of numbers) or ``"ints"`` (one whole number or one
        per expansion point); ``default`` (None: none), ``required`` (bool), ``choices`` (list
        of str, for ``"choice"``) and ``meaning`` (the docstring's first sentence, Markdown).

    Raises
    ------
    OptionError
        An unknown method.
    """
    if method not in METHODS:
        method_options(method)  # raises, with the nearest name
    cls = METHODS[method]
    docs = _attribute_docs(cls)
    types = _attribute_types(cls)
    common = {f.name for f in dataclasses.fields(ReductionOptions)}
    fields = [f for f in dataclasses.fields(cls) if f.name not in common]
    fields += [f for f in dataclasses.fields(cls) if f.name in common]
    out = []
    for f in fields:
        annotation = str(f.type)
        choices = types.get(f.name, [])
        if "bool" in annotation:
            kind = "bool"
        elif "tuple[float" in annotation:
            kind = "floats"
        elif "tuple[int" in annotation:
            kind = "ints"
        elif annotation.startswith("int"):
            kind = "int"
        elif annotation.startswith("float"):
            kind = "float"
        else:
            kind = "choice" if choices else "str"
        default = None if f.default is dataclasses.MISSING else f.default
        out.append(
            {
                "name": f.name,
                "kind": kind,
                "default": list(default) if isinstance(default, tuple) else default,
                "required": f.name in _REQUIRED.get(method, ()),
                "choices": choices if kind == "choice" else [],
                "meaning": _markdown(docs.get(f.name, "")),
            }
        )
    return out


def _attribute_types(cls: type) -> dict[str, list[str]]:
    """The choices ``{"a", "b"}`` of each attribute whose docstring type line lists them."""
    found: dict[str, list[str]] = {}
    text = (cls.__doc__ or "").split("Attributes\n    ----------\n", 1)
    for line in text[-1].splitlines() if len(text) == 2 else ():
        if line.startswith("    ") and not line.startswith("        ") and ":" in line:
            names, kind = line.split(":", 1)
            braces = re.search(r"\{([^}]*)\}", kind)
            if braces:
                for name in names.split(","):
                    found[name.strip()] = re.findall(r'"([^"]+)"', braces.group(1))
    return found


def _markdown(text: str) -> str:
    """Docstring markup to Markdown: ``x`` and :role:`~a.b.c` to `x` and `c`."""
    text = re.sub(r":[a-z]+:`~?(?:[\w.]+\.)?([\w]+)`", r"`\1`", text)
    return text.replace("``", "`")


_REQUIRED = {
    "modal": ("order",),
    "craig-bampton": ("fixed_modes",),
    "krylov": ("expansion_points_hz",),
}


def _attribute_docs(cls: type) -> dict[str, str]:
    """First sentence of each attribute of a numpy-style ``Attributes`` section."""
    docs: dict[str, str] = {}
    text = (cls.__doc__ or "").split("Attributes\n    ----------\n", 1)
    if len(text) < 2:
        return docs
    names: list[str] = []
    for line in text[1].splitlines():
        if line.startswith("    ") and not line.startswith("        ") and line.strip():
            names = [n.strip() for n in line.split(":")[0].split(",")]
        elif line.startswith("        ") and names:
            for name in names:
                docs[name] = (docs.get(name, "") + " " + line.strip()).strip()
    inherited = _attribute_docs(ReductionOptions) if cls is not ReductionOptions else {}
    return {**inherited, **docs}
