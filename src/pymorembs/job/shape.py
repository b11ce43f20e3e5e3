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
from typing import Any

from pymorembs.analysis import LARGE_MOTION_CASES, LargeMotionSettings
from pymorembs.examples import OPTIONS
from pymorembs.export import DEFAULT_EXPORTS, EXPORTS
from pymorembs.io import FORMATS
from pymorembs.job.schema import (
    MODEL_FILE_KEYS,
    BandSpec,
    ExportSpec,
    InertiaLoadSpec,
    StiffeningSpec,
    TimeDomainSpec,
)
from pymorembs.kinds import DampingKind, FrameType, InterfaceKind, Kind, ReferenceKind
from pymorembs.methods import METHODS, option_fields
from pymorembs.preparation import INERTIA_LOAD_CASES

#: The job's tables that are one dataclass each, its fields the table's keys.
DATACLASS_TABLES: dict[str, type] = {
    "band": BandSpec,
    "export": ExportSpec,
    "time_domain": TimeDomainSpec,
    "inertia_loads": InertiaLoadSpec,
    "large_motion": LargeMotionSettings,
    "stiffening": StiffeningSpec,
}
#: The tables whose keys are a kind's name (``key``) and the parameters of that kind.
KIND_TABLES: dict[str, tuple[str, type[Kind]]] = {
    "frame": ("type", FrameType),
    "damping": ("kind", DampingKind),
    "interface": ("kind", InterfaceKind),
}


def key(name: str, type_: str, default: Any = None, required: bool = False) -> dict[str, Any]:
    """One key of a table as the schema shows it (``default`` JSON-ready, None: none)."""
    if isinstance(default, tuple):
        default = list(default)
    return {"name": name, "type": type_, "default": default, "required": required}


def dataclass_keys(cls: type) -> list[dict[str, Any]]:
    """The keys of a table that is the dataclass ``cls``: its fields with type and default."""
    keys = []
    for field in dataclasses.fields(cls):
        if field.default is not dataclasses.MISSING:
            keys.append(key(field.name, str(field.type), field.default))
        elif field.default_factory is not dataclasses.MISSING:
            keys.append(key(field.name, str(field.type), field.default_factory()))
        else:
            keys.append(key(field.name, str(field.type), required=True))
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
    tables["interface"] += [
        key("node", "int", required=True),
        key("position", "tuple[float, float, float]", required=True),
        key("nodes", "tuple[int, ...] | None"),
        key("cylinder", "table: point, direction, radius, tolerance"),
        key("box", "table: min, max"),
    ]
    ports = [key("node", "int", required=True), key("directions", "str", required=True)]
    tables |= {"inputs": ports, "outputs": ports}
    tables["model"] = [key("example", "str"), key("format", "str")]
    tables["model"] += [key(name, "str") for name in MODEL_FILE_KEYS]
    tables["reduction"] = [
        key("name", "str"),
        key("method", "str", required=True),
        key("export_inaccurate", "bool", False),
    ]
    tables["job"] = [key("title", "str", "")]
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
