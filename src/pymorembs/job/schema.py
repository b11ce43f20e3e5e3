"""Reduction jobs from TOML files.

A job names a model, a damping model, a reference frame, inputs and outputs, a frequency band and
one or more reductions to compare. Every key is checked: an unknown or misspelled key is an
error that suggests the nearest valid key, never silently ignored. See ``examples/*.toml`` and
``docs/jobs.md`` for the full list (the method options come from :mod:`pymorembs.methods`).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import tomllib
import typing
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from pymorembs import Damping, Frame, Port, UserError
from pymorembs.analysis import (
    DEFAULT_CHECKS,
    LARGE_MOTION_CASES,
    REFERENCE_KINDS,
    LargeMotionSettings,
)
from pymorembs.examples import ExampleOptions
from pymorembs.export import BODY_OUTPUTS, DEFAULT_EXPORTS, EXPORT_KINDS, OutputKind
from pymorembs.io import FORMATS
from pymorembs.kinds import DampingKind, FrameType, InterfaceKind, ReferenceKind, choices
from pymorembs.methods import (
    METHODS,
    RENAMED_OPTIONS,
    OptionError,
    ReductionOptions,
    method_options,
    renamed_message,
)
from pymorembs.preparation import INERTIA_LOAD_CASES, StressSpec

MODEL_FILE_KEYS = (
    "file", "stiffness", "mass", "damping", "dofs", "nodes", "constraints", "fixed", "mapping",
    "inp",
)  # fmt: skip
#: The keys of ``[model]`` that name a matrix inside a model file (Nastran).
MATRIX_NAME_KEYS = ("stiffness_name", "mass_name", "damping_name")
MODEL_FORMATS = FORMATS
INTERFACE_KINDS = InterfaceKind.names()
_NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")
#: Files of the job folder a reduction (a sub-folder of that name) must not shadow.
RESERVED_NAMES = frozenset(("summary.json", "error.png", "decay.png", "time.png", "report.html"))


#: The key of a dataclass field's metadata that says how a job file writes the field.
IN_FILE = "job_file"


@dataclass(frozen=True)
class InFile:
    """How a job file writes a field of a table's dataclass, where the field's name, annotation
    and default do not say it (read by :func:`pymorembs.job.shape.job_schema`).

    Attributes
    ----------
    key : str or None
        The key in the file (None: the field's name).
    type : str or None
        The type as the schema shows it (None: the field's annotation).
    required : bool or None
        The file must give it (None: the field has no default).
    keys : tuple of str
        The field holds these keys of the file (each of ``type``), e.g. the model's files.
    inline : bool
        The field is a dataclass whose fields are keys of the same table.
    absent : bool
        No key of the file: derived by the parser, or the table's kind and its parameters
        (:data:`~pymorembs.job.shape.KIND_TABLES`).
    """

    key: str | None = None
    type: str | None = None
    required: bool | None = None
    keys: tuple[str, ...] = ()
    inline: bool = False
    absent: bool = False


def in_file(**how: Any) -> dict[str, InFile]:
    """The metadata of a field that a job file writes as ``how`` says (:class:`InFile`)."""
    return {IN_FILE: InFile(**how)}


@dataclass(frozen=True)
class ModelSpec:
    """Where the body comes from.

    Either a built-in ``example`` (with its ``options``, an
    :class:`~pymorembs.examples.ExampleOptions`: ``dofs`` and ``interface`` of ``rack-solid``
    ...), or model files (``files``: ``file`` for one-file formats, ``stiffness`` and
    ``mass`` with their companions otherwise) in a ``format`` (None: detected from the content),
    with ``names`` of the matrices inside a file where the format has names (Nastran).
    """

    example: str | None = field(default=None, metadata=in_file(type="str"))
    format: str | None = field(default=None, metadata=in_file(type="str"))
    files: dict[str, Path] = field(
        default_factory=dict, metadata=in_file(keys=MODEL_FILE_KEYS, type="str")
    )
    names: dict[str, str] = field(
        default_factory=dict, metadata=in_file(keys=MATRIX_NAME_KEYS, type="str")
    )
    options: ExampleOptions = field(default_factory=ExampleOptions, metadata=in_file(inline=True))

    def __post_init__(self) -> None:
        if not isinstance(self.options, ExampleOptions):  # by name, as the app's form gives them
            options = ExampleOptions.of(self.example or "", self.options)
            object.__setattr__(self, "options", options)


@dataclass(frozen=True)
class InterfaceNodeSpec:
    """An ``[[interface]]`` table: a node to add and the nodes it couples to (section 2.2)."""

    node: int
    position: tuple[float, float, float]
    kind: InterfaceKind = field(metadata=in_file(absent=True))
    ids: tuple[int, ...] | None = field(default=None, metadata=in_file(key="nodes"))
    cylinder: tuple | None = field(
        default=None, metadata=in_file(type="table: point, direction, radius, tolerance")
    )
    box: tuple | None = field(default=None, metadata=in_file(type="table: min, max"))
    parameters: dict[str, float] = field(default_factory=dict, metadata=in_file(absent=True))


#: The accuracy limit of a reduction whose method has no error target of its own: the largest
#: relative error ε (paper eq. 27) over the ports and over the inertia loads its body may have.
DEFAULT_ACCURACY_LIMIT = 1e-2
#: Methods whose ``tolerance`` is a target for ε itself (SOAGA: the estimated maximum relative
#: error); it is then their accuracy limit. The ``tolerance`` of ``gramian`` and ``pod`` is a
#: ratio of singular values, not an error: they get :data:`DEFAULT_ACCURACY_LIMIT`.
ERROR_TARGET_METHODS = ("soaga",)


@dataclass(frozen=True)
class ReductionSpec:
    """One reduction of a job: a unique name and the options object of its method.

    ``options`` is the checked options object of the method
    (:func:`~pymorembs.methods.method_options`, the one check of the ``[[reduction]]`` table's
    values), built once by the parser and handed as it is to the method
    (:func:`~pymorembs.reduction.method_projection`); :attr:`method` and :attr:`order` are its
    own. ``written``: the option keys the table wrote (besides ``name``, ``method``, ``order``
    and ``export_inaccurate``), what the summary records of the job. ``export_inaccurate``:
    write the body files even when the reduction misses its accuracy limit
    (:attr:`accuracy_limit`).
    """

    name: str = field(metadata=in_file(required=False))  # the file's default: the method
    options: ReductionOptions = field(metadata=in_file(key="method", type="str", required=True))
    export_inaccurate: bool = False
    written: tuple[str, ...] = field(default=(), metadata=in_file(absent=True))

    @property
    def method(self) -> str:
        """The method's name (``options.method``)."""
        return self.options.method

    @property
    def order(self) -> int | None:
        """The ``order`` option (None: the method has none, or it was not given)."""
        return self.options.order

    def written_options(self) -> dict[str, Any]:
        """The options the table wrote, by key, as the options object holds them."""
        return {key: getattr(self.options, key) for key in self.written}

    @property
    def accuracy_limit(self) -> tuple[float, str]:
        """The largest max ε (ports and inertia loads) the reduction's body may have, and where
        the limit comes from: ``"tolerance"`` (the method's error target,
        :data:`ERROR_TARGET_METHODS`) or ``"default"`` (:data:`DEFAULT_ACCURACY_LIMIT`)."""
        tolerance = getattr(self.options, "tolerance", None)
        if self.method in ERROR_TARGET_METHODS and tolerance is not None:
            return float(tolerance), "tolerance"
        return DEFAULT_ACCURACY_LIMIT, "default"


@dataclass(frozen=True)
class BandSpec:
    """``[band]``: the frequency band of the error curves and what they are measured against.

    ``points`` log-spaced frequencies from ``f_min_hz`` to ``f_max_hz`` (Hz, plus 0 Hz);
    ``reference`` one of :class:`~pymorembs.kinds.ReferenceKind`; ``check_points``: the
    frequencies where a surrogate reference is checked against the full model.
    """

    f_max_hz: float
    f_min_hz: float = 0.0
    points: int = 400
    reference: ReferenceKind = ReferenceKind.AUTO
    check_points: int = DEFAULT_CHECKS

    def __post_init__(self) -> None:
        object.__setattr__(self, "reference", ReferenceKind(self.reference))


@dataclass(frozen=True)
class ExportSpec:
    """``[export]``: which files to write and for which nodes (SID frame, Exudyn markers).

    ``outputs``: kinds of the export registry (:data:`~pymorembs.export.OutputKind`, a name is
    taken too); ``nodes`` None: the nodes of the inputs and outputs.
    """

    outputs: tuple[OutputKind, ...] = tuple(map(OutputKind, DEFAULT_EXPORTS))
    nodes: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "outputs", tuple(map(OutputKind, self.outputs)))


@dataclass(frozen=True)
class TimeDomainSpec:
    """``[time_domain]``: the load cases of paper section 5.1 and how to integrate them.

    The body is clamped at ``clamp_node``; a force ``force_n`` (N, along x y z) acts at
    ``load_node`` as a step and as ``force_n * sin(2 pi harmonic_hz t)``; the displacement of
    ``load_node`` is compared between the full FE model and each reduced model.
    """

    clamp_node: int
    load_node: int
    force_n: tuple[float, float, float] = (-100.0, -100.0, -100.0)
    harmonic_hz: float = 10.0
    cases: tuple[str, ...] = ("step", "harmonic")
    duration_s: float = 0.2
    step_s: float = 5e-5
    rho_inf: float | None = None
    exudyn: bool = False


@dataclass(frozen=True)
class InertiaLoadSpec:
    """``[inertia_loads]``: the frame's d'Alembert loads as inputs of every reduction.

    ``enabled`` None: on when the job exports a body for a multibody code
    (:data:`~pymorembs.export.registry.BODY_OUTPUTS`), off otherwise. ``cases``: the load cases
    (:data:`~pymorembs.preparation.INERTIA_LOAD_CASES`).
    """

    enabled: bool | None = None
    cases: tuple[str, ...] = INERTIA_LOAD_CASES

    def active(self, exports: tuple[str, ...]) -> bool:
        """Whether the loads are inputs for a job writing ``exports``."""
        if self.enabled is None:
            return any(kind in BODY_OUTPUTS for kind in exports)
        return self.enabled


@dataclass(frozen=True)
class StiffeningSpec:
    """``[stiffening]``: geometric stiffening of the exported bodies (SID_NOTES §4.6).

    ``source`` ``"mesh"`` (the model's solid elements), ``"matrices"`` (``matrices``: load case ->
    Matrix Market file, ``kind`` ``"geometric"`` for ``K_G`` or ``"prestressed"`` for
    ``K_pre``) or ``"none"``.
    """

    source: str = "none"
    matrices: tuple[tuple[str, Path], ...] = ()
    kind: str = "geometric"


@dataclass(frozen=True)
class Job:
    """A parsed reduction job; a field that holds a dataclass is a table of the file."""

    path: Path = field(metadata=in_file(absent=True))
    model: ModelSpec
    interfaces: tuple[InterfaceNodeSpec, ...]
    damping: Damping | None
    frame: Frame
    inputs: tuple[Port, ...]
    outputs: tuple[Port, ...]
    band: BandSpec
    reductions: tuple[ReductionSpec, ...]
    title: str = ""
    export: ExportSpec = ExportSpec()
    time_domain: TimeDomainSpec | None = None
    inertia_loads: InertiaLoadSpec = InertiaLoadSpec()
    large_motion: LargeMotionSettings | None = None
    stiffening: StiffeningSpec = StiffeningSpec()
    stress: StressSpec | None = None

    @property
    def band_hz(self) -> tuple[float, float]:
        """``(f_min_hz, f_max_hz)`` of ``[band]`` (Hz)."""
        return (self.band.f_min_hz, self.band.f_max_hz)

    @property
    def points(self) -> int:
        """``[band] points``."""
        return self.band.points

    @property
    def reference(self) -> ReferenceKind:
        """``[band] reference``."""
        return self.band.reference

    @property
    def check_points(self) -> int:
        """``[band] check_points``."""
        return self.band.check_points

    def stage_count(self) -> int:
        """The progress stages of a run of the job (``pymorembs reduce`` and the app's run): the
        model, the reference, one per reduction, the time domain and the large motion (each when
        the job asks for it)."""
        checks = (self.time_domain is not None) + (self.large_motion is not None)
        return 2 + len(self.reductions) + checks


class _Table:
    """A TOML table read key by key; :meth:`done` rejects the keys nobody asked for."""

    def __init__(self, data: Any, where: str, path: Path) -> None:
        if not isinstance(data, dict):
            raise UserError(f"{path}: {where} must be a table")
        self.data, self.where, self.path = data, where, path
        self.known: set[str] = set()

    def error(self, key: str, problem: str) -> UserError:
        return UserError(f"{self.path}: {self.where}.{key}: {problem}")

    def get(self, key: str, default: Any = None, required: bool = False) -> Any:
        self.known.add(key)
        if key not in self.data:
            if required:
                typo = difflib.get_close_matches(key, [k for k in self.data if k not in self.known])
                if typo:  # a misspelled required key: name the misspelling
                    raise UserError(
                        f"{self.path}: {self.where}: unknown key '{typo[0]}'; did you mean '{key}'?"
                    )
                raise UserError(f"{self.path}: {self.where}: missing key '{key}'")
            return default
        return self.data[key]

    def number(
        self,
        key: str,
        default: float | None = None,
        required: bool = False,
        minimum: float | None = None,
    ) -> float | None:
        value = self.get(key, default, required)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(key, f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise self.error(key, f"must be a finite number, got {value!r}")
        if minimum is not None and value < minimum:
            raise self.error(key, f"must be >= {minimum}, got {value!r}")
        return float(value)

    def integer(
        self, key: str, default: int | None = None, required: bool = False, minimum: int = 1
    ) -> int | None:
        value = self.get(key, default, required)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"must be a whole number, got {value!r}")
        if value < minimum:
            raise self.error(key, f"must be >= {minimum}, got {value!r}")
        return int(value)

    def string(self, key: str, default: str | None = None, required: bool = False) -> str | None:
        value = self.get(key, default, required)
        if value is not None and not isinstance(value, str):
            raise self.error(key, f"must be a string, got {value!r}")
        return value

    def done(self, extra: tuple[str, ...] = ()) -> None:
        allowed = self.known | set(extra)
        for key in self.data:
            if key not in allowed:
                hint = difflib.get_close_matches(key, sorted(allowed), n=1)
                suggestion = (
                    f"; did you mean '{hint[0]}'?"
                    if hint
                    else (f"; valid keys: {', '.join(sorted(allowed))}" if allowed else "")
                )
                raise UserError(f"{self.path}: {self.where}: unknown key '{key}'{suggestion}")


def load_job(path: str | Path) -> Job:
    """Read and check a job file. All problems are :class:`UserError` naming file and key."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # with a byte order mark (Windows editors)
    except FileNotFoundError:
        raise UserError(f"{path}: job file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{path}: cannot read job file ({exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(_toml_message(path, str(exc))) from None
    return parse_job(data, path)


def _toml_message(path: Path, message: str) -> str:
    """``file:line: invalid TOML: problem (column c)`` from tomllib's message."""
    found = re.search(r"\(at line (\d+), column (\d+)\)", message)
    if found is None:
        found_end = re.search(r"\(at end of document\)", message)
        problem = message.replace("(at end of document)", "").strip()
        where = f"{path}: " if found_end is None else f"{path}: at the end: "
        return f"{where}invalid TOML: {problem}"
    problem = (message[: found.start()] + message[found.end() :]).strip()
    return f"{path}:{found.group(1)}: invalid TOML: {problem} (column {found.group(2)})"


def parse_job(data: dict[str, Any], path: Path) -> Job:
    """Check a job given as a dictionary (the parsed TOML) read from ``path``."""
    top = _Table(data, "job", path)
    base = path.parent
    title = top.string("title", "") or ""
    model = _model(_Table(top.get("model", required=True), "[model]", path), base)
    interfaces = _interfaces(top.get("interface", []), path)
    damping = _damping(top.get("damping"), path)
    frame = _frame(_Table(top.get("frame", required=True), "[frame]", path))
    inputs_data = top.get("inputs")
    inputs = () if inputs_data is None else _ports(inputs_data, "inputs", path)
    outputs_data = top.get("outputs")
    outputs = inputs if outputs_data is None else _ports(outputs_data, "outputs", path)
    if outputs and not inputs:
        raise UserError(f"{path}: [[outputs]] without [[inputs]]: give the inputs too")
    band = _Table(top.get("band", required=True), "[band]", path)
    f_min = band.number("f_min_hz", 0.0, minimum=0.0)
    f_max = band.number("f_max_hz", required=True)
    points = band.integer("points", 400, minimum=200)
    reference = band.string("reference", ReferenceKind.AUTO.value)
    if reference not in REFERENCE_KINDS:
        kinds = ", ".join(map(repr, REFERENCE_KINDS))
        raise band.error("reference", f"must be one of {kinds}, got {reference!r}")
    check_points = band.integer("check_points", DEFAULT_CHECKS, minimum=0)
    band.done()
    if not f_max > f_min:
        raise UserError(
            f"{path}: [band]: f_max_hz ({f_max}) must be greater than f_min_hz ({f_min})"
        )
    reductions = _reductions(top.get("reduction", required=True), path)
    export = _export(top.get("export"), path)
    time_domain = _time_domain(top.get("time_domain"), path)
    inertia = _inertia_loads(top.get("inertia_loads"), path)
    large_motion = _large_motion(top.get("large_motion"), path)
    stiffening = _stiffening(top.get("stiffening"), path)
    stress = _stress(top.get("stress"), path)
    top.done()
    return Job(
        path,
        model,
        interfaces,
        damping,
        frame,
        inputs,
        outputs,
        BandSpec(f_max, f_min, points, reference, check_points),
        reductions,
        title,
        export,
        time_domain,
        inertia,
        large_motion,
        stiffening,
        stress,
    )


def _inertia_loads(data: Any, path: Path) -> InertiaLoadSpec:
    if data is None:
        return InertiaLoadSpec()
    table = _Table(data, "[inertia_loads]", path)
    enabled = table.get("enabled")
    if enabled is not None and not isinstance(enabled, bool):
        raise table.error("enabled", f"must be true or false, got {enabled!r}")
    cases = table.get("cases", list(INERTIA_LOAD_CASES))
    if not isinstance(cases, list) or not cases or not all(isinstance(c, str) for c in cases):
        raise table.error("cases", f"must be a list of load cases like {list(INERTIA_LOAD_CASES)}")
    for case in cases:
        if case not in INERTIA_LOAD_CASES:
            hint = difflib.get_close_matches(case, INERTIA_LOAD_CASES, n=1)
            more = (
                f"; did you mean '{hint[0]}'?"
                if hint
                else f" (one of {', '.join(INERTIA_LOAD_CASES)})"
            )
            raise table.error("cases", f"unknown load case {case!r}{more}")
    table.done()
    return InertiaLoadSpec(enabled, tuple(dict.fromkeys(cases)))


def _model(table: _Table, base: Path) -> ModelSpec:
    example = table.string("example")
    if example is not None:
        options = {option.name: _example_option(table, option) for option in fields(ExampleOptions)}
        table.done()
        return ModelSpec(example=example, options=ExampleOptions(**options))
    fmt = table.string("format")
    if fmt is not None and fmt not in MODEL_FORMATS:
        hint = difflib.get_close_matches(fmt, MODEL_FORMATS, n=1)
        more = f"; did you mean '{hint[0]}'?" if hint else f" (one of {', '.join(MODEL_FORMATS)})"
        raise table.error("format", f"unknown format {fmt!r}{more}")
    files = {key: table.string(key) for key in MODEL_FILE_KEYS}
    files = {key: base / value for key, value in files.items() if value is not None}
    names = {key: table.string(key) for key in MATRIX_NAME_KEYS}
    names = {key: value for key, value in names.items() if value is not None}
    table.done()
    if not files:
        raise UserError(
            f"{table.path}: [model]: give 'example', or a model 'file', or 'stiffness' and 'mass'"
        )
    if "file" not in files and not ("stiffness" in files and "mass" in files):
        raise UserError(f"{table.path}: [model]: matrix files need both 'stiffness' and 'mass'")
    return ModelSpec(format=fmt, files=files, names=names)


def _example_option(table: _Table, option: dataclasses.Field) -> Any:
    """One option of a built-in example from ``[model]``, checked as its field declares it."""
    minimum = option.metadata.get("minimum")
    types = typing.get_args(typing.get_type_hints(ExampleOptions)[option.name])
    if int in types:
        return table.integer(option.name, minimum=minimum)
    if float in types:
        return table.number(option.name, minimum=minimum)
    return table.string(option.name)


def _interfaces(data: Any, path: Path) -> tuple[InterfaceNodeSpec, ...]:
    if not isinstance(data, list):
        raise UserError(f"{path}: interface: expected one or more [[interface]] tables")
    specs = []
    for k, item in enumerate(data, start=1):
        table = _Table(item, f"[[interface]] #{k}", path)
        node = table.integer("node", required=True, minimum=-(2**62))
        position = _vector(table, "position", required=True)
        name = table.string("kind", required=True)
        kind = InterfaceKind.lookup(name)
        if kind is None:
            raise table.error("kind", f"must be one of {', '.join(INTERFACE_KINDS)}, got {name!r}")
        ids = table.get("nodes")
        if ids is not None and (
            not isinstance(ids, list)
            or not ids
            or not all(isinstance(i, int) and not isinstance(i, bool) for i in ids)
        ):
            raise table.error("nodes", f"must be a list of node ids, got {ids!r}")
        cylinder = box = None
        table.known.update(("cylinder", "box"))  # selections: always valid keys
        if "cylinder" in table.data:
            sub = _Table(table.get("cylinder"), f"[[interface]] #{k}.cylinder", path)
            cylinder = (
                _vector(sub, "point", required=True),
                _vector(sub, "direction", required=True),
                sub.number("radius", required=True, minimum=0.0),
            )
            tolerance = sub.number("tolerance", minimum=0.0)
            if tolerance is not None:
                cylinder = (*cylinder, tolerance)
            sub.done()
        if "box" in table.data:
            sub = _Table(table.get("box"), f"[[interface]] #{k}.box", path)
            box = (_vector(sub, "min", required=True), _vector(sub, "max", required=True))
            sub.done()
        parameters = {}
        for key in kind.keys:
            value = table.number(key, minimum=0.0)
            if value is not None:
                parameters[key] = value
        table.done()  # unknown keys first: a misspelled key is the likely cause of what follows
        if ids is None and cylinder is None and box is None:
            raise UserError(
                f"{path}: [[interface]] #{k}: give 'nodes', 'cylinder' or 'box' "
                "to select the coupled nodes"
            )
        if kind is InterfaceKind.SPRINGS and "stiffness" not in parameters:
            raise UserError(f"{path}: [[interface]] #{k}: springs need 'stiffness' (N/m)")
        specs.append(
            InterfaceNodeSpec(
                node, position, kind, None if ids is None else tuple(ids), cylinder, box, parameters
            )
        )
    return tuple(specs)


def _vector(table: _Table, key: str, required: bool = False) -> tuple[float, float, float] | None:
    value = table.get(key, required=required)
    if value is None:
        return None
    if not (
        isinstance(value, list)
        and len(value) == 3
        and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in value
        )
    ):
        raise table.error(key, f"must be 3 finite numbers [x, y, z], got {value!r}")
    return (float(value[0]), float(value[1]), float(value[2]))


def _damping(data: Any, path: Path) -> Damping | None:
    if data is None:
        return None
    table = _Table(data, "[damping]", path)
    kind = table.string("kind", required=True)
    if kind not in DampingKind.names():
        raise table.error("kind", f"must be {choices(DampingKind)}, got {kind!r}")
    alpha = beta = ratio = 0.0
    if kind == "rayleigh":
        alpha = table.number("alpha", 0.0, minimum=0.0)
        beta = table.number("beta", 0.0, minimum=0.0)
    elif kind == "modal":
        ratio = table.number("ratio", required=True, minimum=0.0)
    table.done()
    try:
        return Damping(kind, alpha, beta, ratio)
    except UserError as exc:
        raise UserError(f"{path}: [damping]: {exc}") from None


def _export(data: Any, path: Path) -> ExportSpec:
    if data is None:
        return ExportSpec()
    table = _Table(data, "[export]", path)
    outputs = table.get("outputs", list(DEFAULT_EXPORTS))
    if not isinstance(outputs, list) or not all(isinstance(o, str) for o in outputs):
        raise table.error("outputs", f"must be a list of names like {list(EXPORT_KINDS)}")
    for name in outputs:
        if name not in EXPORT_KINDS:
            hint = difflib.get_close_matches(name, EXPORT_KINDS, n=1)
            more = (
                f"; did you mean '{hint[0]}'?" if hint else f" (one of {', '.join(EXPORT_KINDS)})"
            )
            raise table.error("outputs", f"unknown output {name!r}{more}")
    nodes = table.get("nodes")
    if nodes is not None and (
        not isinstance(nodes, list)
        or not nodes
        or not all(isinstance(i, int) and not isinstance(i, bool) for i in nodes)
    ):
        raise table.error("nodes", f"must be a list of node ids, got {nodes!r}")
    table.done()
    return ExportSpec(
        tuple(dict.fromkeys(outputs)), None if nodes is None else tuple(dict.fromkeys(nodes))
    )


def _time_domain(data: Any, path: Path) -> TimeDomainSpec | None:
    if data is None:
        return None
    table = _Table(data, "[time_domain]", path)
    clamp = table.integer("clamp_node", required=True, minimum=-(2**62))
    load = table.integer("load_node", required=True, minimum=-(2**62))
    force = _vector(table, "force_n") or (-100.0, -100.0, -100.0)
    harmonic = table.number("harmonic_hz", 10.0, minimum=0.0)
    cases = table.get("cases", ["step", "harmonic"])
    if (
        not isinstance(cases, list)
        or not cases
        or not all(c in ("step", "harmonic") for c in cases)
        or len(set(cases)) != len(cases)
    ):
        raise table.error("cases", f"must be a list of 'step' and/or 'harmonic', got {cases!r}")
    duration = table.number("duration_s", 0.2)
    step = table.number("step_s", 5e-5)
    rho_inf = table.number("rho_inf", minimum=0.0)
    exudyn = table.get("exudyn", False)
    table.done()
    if not isinstance(exudyn, bool):
        raise table.error("exudyn", f"must be true or false, got {exudyn!r}")
    if not duration > 0 or not step > 0:
        raise UserError(f"{path}: [time_domain]: duration_s and step_s must be positive")
    if duration / step > 1e6:
        raise UserError(
            f"{path}: [time_domain]: {duration / step:.3g} steps; use at most 1e6 "
            "(a larger step_s or a shorter duration_s)"
        )
    if step > duration:
        raise table.error("step_s", f"({step}) is longer than duration_s ({duration})")
    if rho_inf is not None and rho_inf > 1:
        raise table.error("rho_inf", f"must lie in [0, 1], got {rho_inf}")
    if clamp == load:
        raise UserError(f"{path}: [time_domain]: clamp_node and load_node are the same node")
    return TimeDomainSpec(
        clamp, load, force, harmonic, tuple(cases), duration, step, rho_inf, exudyn
    )


def _stiffening(data: Any, path: Path) -> StiffeningSpec:
    if data is None:
        return StiffeningSpec()
    table = _Table(data, "[stiffening]", path)
    source = table.string("source", "none")
    if source not in ("mesh", "matrices", "none"):
        raise table.error("source", f"must be 'mesh', 'matrices' or 'none', got {source!r}")
    kind = table.string("kind", "geometric")
    if kind not in ("geometric", "prestressed"):
        raise table.error("kind", f"must be 'geometric' or 'prestressed', got {kind!r}")
    files = table.get("matrices", {})
    if not isinstance(files, dict) or not all(isinstance(v, str) for v in files.values()):
        raise table.error("matrices", 'must be a table of load case = "file.mtx"')
    for case in files:
        if case not in INERTIA_LOAD_CASES:
            hint = difflib.get_close_matches(case, INERTIA_LOAD_CASES, n=1)
            more = f"; did you mean '{hint[0]}'?" if hint else ""
            raise table.error("matrices", f"unknown load case {case!r}{more}")
    table.done()
    if source == "matrices" and not files:
        raise table.error("matrices", 'source = "matrices" needs at least one load case file')
    if source != "matrices" and files:
        raise table.error("matrices", f'given, but source is "{source}" (use "matrices")')
    matrices = tuple((case, (path.parent / name).resolve()) for case, name in files.items())
    for case, file in matrices:
        if not file.is_file():
            raise table.error("matrices", f"{case}: file {file} not found")
    return StiffeningSpec(source, matrices, kind)


def _stress(data: Any, path: Path) -> StressSpec | None:
    """``[stress]``: the hot spots whose stresses are outputs (:class:`StressSpec`)."""
    if data is None:
        return None
    table = _Table(data, "[stress]", path)
    ids = {}
    for key in ("nodes", "elements"):
        value = table.get(key, [])
        if not isinstance(value, list) or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in value
        ):
            raise table.error(key, f"must be a list of {key[:-1]} ids, got {value!r}")
        ids[key] = tuple(value)
    sets = table.get("sets", [])
    if not isinstance(sets, list) or not all(isinstance(v, str) and v.strip() for v in sets):
        raise table.error("sets", f"must be a list of node set names, got {sets!r}")
    for key, value in (*ids.items(), ("sets", sets)):
        if key in data and not value:  # an empty list would silently mean "find them"
            raise table.error(key, "an empty list: give at least one, or leave the key out")
    box = table.get("box")
    if box is not None:
        if not isinstance(box, list) or len(box) != 2:
            raise table.error("box", f"must be [[x, y, z], [x, y, z]] (lower, upper), got {box!r}")
        corners = _Table({"lower": box[0], "upper": box[1]}, "[stress].box", path)
        box = (_vector(corners, "lower"), _vector(corners, "upper"))
    count = table.integer("count", StressSpec.count)
    location = table.string("location", StressSpec.location)
    target = table.get("target", False)
    if not isinstance(target, bool):
        raise table.error("target", f"must be true or false, got {target!r}")
    table.done()
    try:
        return StressSpec(ids["nodes"], ids["elements"], box, count, location, target, tuple(sets))
    except UserError as exc:
        raise UserError(f"{path}: {exc}") from None


def _large_motion(data: Any, path: Path) -> LargeMotionSettings | None:
    if data is None:
        return None
    table = _Table(data, "[large_motion]", path)
    joint = table.integer("joint_node", required=True, minimum=-(2**62))
    cases = table.get("cases", list(LARGE_MOTION_CASES))
    if (
        not isinstance(cases, list)
        or not cases
        or not all(c in LARGE_MOTION_CASES for c in cases)
        or len(set(cases)) != len(cases)
    ):
        raise table.error("cases", f"must be a list of 'pendulum' and/or 'spin-up', got {cases!r}")
    duration = table.number("duration_s", 1.0)
    step = table.number("step_s")
    spin = table.number("spin_rad_s")
    axis = _vector(table, "spin_axis")
    spin_up = table.number("spin_up_s")
    gravity = table.number("gravity_m_s2", 9.81, minimum=0.0)
    order = table.integer("reference_order", 120, minimum=2)
    rho_inf = table.number("rho_inf", 0.9, minimum=0.0)
    table.done()
    for key, value in (("duration_s", duration), ("step_s", step), ("spin_rad_s", spin),
                       ("spin_up_s", spin_up)):  # fmt: skip
        if value is not None and not value > 0:
            raise table.error(key, f"must be > 0, got {value!r}")
    if step is not None and duration / step > 1e6:
        raise table.error("step_s", f"gives {duration / step:.3g} steps; use at most 1e6")
    if spin_up is not None and spin_up > duration:
        raise table.error("spin_up_s", f"({spin_up}) is longer than duration_s ({duration})")
    if axis is not None and not any(axis):
        raise table.error("spin_axis", "must not be the zero vector")
    if rho_inf > 1:
        raise table.error("rho_inf", f"must lie in [0, 1], got {rho_inf}")
    if "pendulum" in cases and not gravity > 0:
        raise table.error("gravity_m_s2", "must be > 0 for the pendulum")
    return LargeMotionSettings(
        joint_node=joint,
        cases=tuple(cases),
        duration_s=duration,
        step_s=step,
        spin_rad_s=spin,
        spin_axis=axis if axis is not None else LargeMotionSettings.spin_axis,
        spin_up_s=spin_up,
        gravity_m_s2=gravity,
        reference_order=order,
        rho_inf=rho_inf,
    )


def _frame(table: _Table) -> Frame:
    kind = table.string("type", FrameType.TANGENT.value)
    if kind == FrameType.TANGENT:
        node = table.integer("node", required=True, minimum=-(2**62))
        table.done()
        return Frame(FrameType.TANGENT, node)
    if kind in FrameType.names():
        table.done()
        return Frame(kind)
    raise table.error("type", f"must be {choices(FrameType)}, got {kind!r}")


def _ports(data: Any, key: str, path: Path) -> tuple[Port, ...]:
    if not isinstance(data, list) or not data:
        raise UserError(f"{path}: {key}: expected one or more [[{key}]] tables")
    ports = []
    for k, item in enumerate(data, start=1):
        table = _Table(item, f"[[{key}]] #{k}", path)
        node = table.integer("node", required=True, minimum=-(2**62))
        directions = table.get("directions", required=True)
        table.done()
        if not isinstance(directions, str | list):
            raise table.error("directions", f"must be a string like 'ux uy uz', got {directions!r}")
        try:
            ports.append(Port.parse(node, directions))
        except UserError as exc:
            raise table.error("directions", str(exc)) from None
    return tuple(ports)


def _reductions(data: Any, path: Path) -> tuple[ReductionSpec, ...]:
    if not isinstance(data, list) or not data:
        raise UserError(f"{path}: expected one or more [[reduction]] tables")
    specs: list[ReductionSpec] = []
    for k, item in enumerate(data, start=1):
        table = _Table(item, f"[[reduction]] #{k}", path)
        method = table.string("method", required=True)
        if method not in METHODS:
            hint = difflib.get_close_matches(method, list(METHODS), n=1)
            more = f"; did you mean '{hint[0]}'?" if hint else ""
            raise table.error(
                "method",
                f"unknown method {method!r}{more} (available: {', '.join(METHODS)})",
            )
        name = table.string("name", method)
        if not _NAME_PATTERN.match(name):
            raise table.error("name", f"{name!r} is not a valid name (letters, digits, _ . + -)")
        if any(spec.name == name for spec in specs):
            raise table.error("name", f"{name!r} is used by another reduction")
        if name.lower() in RESERVED_NAMES:
            raise table.error(
                "name", f"{name!r} is the name of a file of the job's output folder; choose another"
            )
        order = table.integer("order")
        inaccurate = table.get("export_inaccurate", False)
        if not isinstance(inaccurate, bool):
            raise table.error("export_inaccurate", f"must be true or false, got {inaccurate!r}")
        if method == "craig-bampton" and order is not None:
            raise table.error("order", "is set by the inputs (boundary dofs) and 'fixed_modes'")
        known = tuple(f.name for f in dataclasses.fields(METHODS[method]) if f.name != "order")
        options = {key: table.get(key) for key in known if key in table.data}
        for key in table.data:
            if RENAMED_OPTIONS.get(key) in known:  # a job file written for an older version
                raise table.error(key, renamed_message(key))
        table.done(known)
        try:
            checked = method_options(
                method, {**options, **({} if order is None else {"order": order})}
            )
        except OptionError as exc:
            if exc.key is None:
                raise UserError(f"{table.path}: {table.where}: {exc.problem}") from None
            raise table.error(exc.key, exc.problem) from None
        specs.append(ReductionSpec(name, checked, inaccurate, tuple(options)))
    return tuple(specs)
