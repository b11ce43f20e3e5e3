"""The shape of a job file as data: every table, its keys and every list of kinds.

:func:`job_schema` is what the app serves (``GET /api/schema``) and builds its forms and lists
from, so that no list of kinds is written into the page. It is generated, never written by hand:
the tables from the dataclasses the parser fills (:mod:`pymorembs.job.schema`), the kinds with
their parameters from :mod:`pymorembs.kinds`, the methods from the method registry
(:func:`~pymorembs.methods.option_fields`) and the files from the export registry
(:data:`~pymorembs.export.EXPORTS`).
"""

from __future__ import annotations

import dataclasses
import re
import typing
from enum import Enum
from typing import Any

from pymorembs.analysis import LARGE_MOTION_CASES, LargeMotionSettings
from pymorembs.examples import OPTIONS
from pymorembs.export import DEFAULT_EXPORTS, EXPORTS
from pymorembs.io import FORMATS
from pymorembs.job.schema import (
    IN_FILE,
    BandSpec,
    ExportSpec,
    InertiaLoadSpec,
    InFile,
    InterfaceNodeSpec,
    Job,
    ModelSpec,
    ReductionSpec,
    StiffeningSpec,
    TimeDomainSpec,
)
from pymorembs.kinds import DampingKind, FrameType, InterfaceKind, Kind, ReferenceKind
from pymorembs.methods import METHODS, option_fields
from pymorembs.preparation import INERTIA_LOAD_CASES, Port, StressSpec

#: The job's tables that are one dataclass each, its fields the table's keys (the fields'
#: metadata :data:`~pymorembs.job.schema.IN_FILE` says where the file writes them otherwise).
DATACLASS_TABLES: dict[str, type] = {
    "band": BandSpec,
    "export": ExportSpec,
    "time_domain": TimeDomainSpec,
    "inertia_loads": InertiaLoadSpec,
    "large_motion": LargeMotionSettings,
    "stiffening": StiffeningSpec,
    "stress": StressSpec,
}
#: The tables whose keys are a kind's name (``key``) and the parameters of that kind.
KIND_TABLES: dict[str, tuple[str, type[Kind]]] = {
    "frame": ("type", FrameType),
    "damping": ("kind", DampingKind),
    "interface": ("kind", InterfaceKind),
}
#: The types of the fields of a :class:`~pymorembs.preparation.Port` as a job file writes them:
#: the directions as names (``"ux uy uz"``), not as the codes the port holds.
PORT_TYPES = {"directions": "str"}


def key(name: str, type_: str, default: Any = None, required: bool = False) -> dict[str, Any]:
    """One key of a table as the schema shows it (``default`` JSON-ready, None: none)."""
    if isinstance(default, tuple):
        default = list(default)
    return {"name": name, "type": type_, "default": default, "required": required}


def type_name(cls: type, field: dataclasses.Field) -> str:
    """The type of a field as the schema shows it: its annotation, a kind (a string enum of
    :mod:`pymorembs.kinds` or the export registry) written ``str``, as the job file does."""
    text = str(field.type)
    for enum in enums_in(typing.get_type_hints(cls)[field.name]):
        text = re.sub(rf"\b{enum.__name__}\b", "str", text)
    return text


def enums_in(hint: Any) -> list[type[Enum]]:
    """The enum classes a type hint names (``tuple[OutputKind, ...]``: ``[OutputKind]``)."""
    if isinstance(hint, type) and issubclass(hint, Enum):
        return [hint]
    return [enum for arg in typing.get_args(hint) for enum in enums_in(arg)]


def is_table(hint: Any) -> bool:
    """Whether a field of this type hint is a table of its own (it holds a dataclass)."""
    if dataclasses.is_dataclass(hint):
        return True
    return any(is_table(arg) for arg in typing.get_args(hint))


def dataclass_keys(cls: type, types: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """The keys of a table that is the dataclass ``cls``: its fields with type and default.

    A field's :class:`~pymorembs.job.schema.InFile` metadata renames it, gives its type, says
    it is required, stands for several keys, inlines a dataclass's keys (those not keys of the
    table already) or leaves it out; a
    field without it that holds a dataclass is a table of its own and no key. ``types``: the
    types of fields as the schema shows them, by field name, for a class of the library.
    """
    hints = typing.get_type_hints(cls)
    keys = []
    for field in dataclasses.fields(cls):
        how = field.metadata.get(IN_FILE, InFile())
        if how.absent or (IN_FILE not in field.metadata and is_table(hints[field.name])):
            continue
        if how.inline:  # a key it shares with the table (the model's dofs) stays the first
            names = {k["name"] for k in keys}
            keys += [k for k in dataclass_keys(hints[field.name]) if k["name"] not in names]
            continue
        type_ = how.type or (types or {}).get(field.name) or type_name(cls, field)
        if how.keys:
            keys += [key(name, type_) for name in how.keys]
            continue
        if field.default is not dataclasses.MISSING:
            default, required = field.default, False
        elif field.default_factory is not dataclasses.MISSING:
            default, required = field.default_factory(), False
        else:
            default, required = None, True
        required = required if how.required is None else how.required
        keys.append(key(how.key or field.name, type_, default, required))
    return keys


def kind_keys(name: str, kind: type[Kind]) -> list[dict[str, Any]]:
    """The keys of a table chosen by a ``kind``: its name, then every kind's parameters."""
    keys = [key(name, "str", kind.names()[0], required=True)]
    for member in kind:
        for parameter in member.parameters:
            if all(k["name"] != parameter.name for k in keys):
                keys.append(key(parameter.name, parameter.type))  # required: per kind
    return keys


def job_schema() -> dict[str, Any]:
    """Every table of a job file with its keys, and every list of kinds with its parameters.

    Returns
    -------
    dict
        ``tables``: table name -> list of keys (``name``, ``type``, ``default``, ``required``);
        ``kinds``: ``frame``, ``damping``, ``interface``, ``reference`` (kind -> its
        parameters, each ``name``, ``type``, ``unit``, ``meaning``, ``required``), ``export``
        (kind -> ``files``, ``group``, ``description``, ``default``), ``method`` (method -> its
        options, :func:`~pymorembs.methods.option_fields`), ``model_format``, ``example``
        (built-in model -> its options), ``inertia_load_case``, ``large_motion_case``;
        ``default_exports``: the files a job writes when ``[export]`` does not say.
    """
    tables = {name: dataclass_keys(cls) for name, cls in DATACLASS_TABLES.items()}
    tables |= {table: kind_keys(name, kind) for table, (name, kind) in KIND_TABLES.items()}
    tables["interface"] += dataclass_keys(InterfaceNodeSpec)
    ports = dataclass_keys(Port, PORT_TYPES)
    tables |= {"inputs": ports, "outputs": ports}
    tables["model"] = dataclass_keys(ModelSpec)
    tables["reduction"] = dataclass_keys(ReductionSpec)
    tables["job"] = dataclass_keys(Job)
    kinds: dict[str, Any] = {
        "frame": FrameType.to_json(),
        "damping": DampingKind.to_json(),
        "interface": InterfaceKind.to_json(),
        "reference": ReferenceKind.to_json(),
        "export": {
            name: {
                "files": list(kind.files),
                "group": kind.group,
                "description": kind.description,
                "default": kind.default,
            }
            for name, kind in EXPORTS.items()
        },
        "method": {name: option_fields(name) for name in METHODS},
        "model_format": list(FORMATS),
        "example": {name: list(options) for name, options in OPTIONS.items()},
        "inertia_load_case": list(INERTIA_LOAD_CASES),
        "large_motion_case": list(LARGE_MOTION_CASES),
    }
    return {"tables": tables, "kinds": kinds, "default_exports": list(DEFAULT_EXPORTS)}
