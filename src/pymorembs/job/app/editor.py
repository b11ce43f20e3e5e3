"""The job the page edits: its draft, its TOML text, the parsed :class:`Job` and their checks.

The page's state *is* the job: the same tables and keys as the TOML file (``[model]``,
``[[interface]]``, ``[frame]``, ``[[inputs]]``, ``[band]``, ``[[reduction]]``, ``[export]``),
held as JSON -- the *draft*, the page's edit buffer, which may be incomplete while the user
types. :func:`job_text` writes it as TOML in the order of ``docs/jobs.md``;
:func:`check_job_text` parses that text with the job parser of ``pymorembs reduce``, so what the
page shows, saves and runs is one file, checked by the same code.

:class:`JobEditor` does that once per edit and holds the outcome -- the draft, its text, the
parser's message and, when valid, the typed :class:`~pymorembs.job.schema.Job` -- for every
reader of the job (the page's state, save, run, the 3D view's decorations, the next free node
id), none of which parses again.
"""

from __future__ import annotations

import json
import math
import threading
import tomllib
from pathlib import Path
from typing import Any

from pymorembs.errors import PymorembsError, UserError
from pymorembs.export import DEFAULT_EXPORTS
from pymorembs.io.atomic import write_text
from pymorembs.job.schema import MODEL_FILE_KEYS, Job, parse_job

#: Tables in the order of the job reference; keys not listed follow in their own order.
TABLE_ORDER = (
    "model", "damping", "interface", "frame", "inputs", "outputs", "band", "reduction", "export",
    "inertia_loads", "stiffening", "stress", "time_domain", "large_motion",
)  # fmt: skip


def _value(value: Any) -> str:
    """One TOML value: string, bool, number, list or inline table."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise UserError(f"job: {value!r} is not a finite number")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + " }"
    raise UserError(f"job: cannot write {value!r} in a job file")


def _key(key: str) -> str:
    bare = key.replace("_", "").replace("-", "").isalnum() and key.isascii()
    return key if bare else json.dumps(key)


def _table(lines: list[str], header: str, table: dict[str, Any]) -> None:
    lines.append("")
    lines.append(header)
    for key, value in table.items():
        if value is not None:
            lines.append(f"{_key(key)} = {_value(value)}")


def job_text(job: dict[str, Any]) -> str:
    """The TOML text of a job given as a dictionary (the parsed form of a job file).

    Scalars at the top come first, then the tables in :data:`TABLE_ORDER`; a list of tables is
    written as ``[[name]]`` tables, a table inside a table inline (``cylinder = { ... }``).
    Entries whose value is None are left out.
    """
    lines: list[str] = []
    for key, value in job.items():
        if value is not None and not isinstance(value, dict) and not _is_tables(value):
            lines.append(f"{_key(key)} = {_value(value)}")
    keys = [k for k in TABLE_ORDER if k in job] + [k for k in job if k not in TABLE_ORDER]
    for key in keys:
        value = job[key]
        if isinstance(value, dict):
            _table(lines, f"[{_key(key)}]", value)
        elif _is_tables(value):
            for item in value:
                _table(lines, f"[[{_key(key)}]]", item)
    return "\n".join(lines).lstrip("\n") + "\n"


def _is_tables(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def check_job_text(text: str, path: Path) -> Job:
    """Parse a job's TOML text as ``pymorembs reduce`` would read it from ``path``.

    Raises
    ------
    UserError
        The parser's message (file, table and key), as on the command line.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: invalid TOML: {exc}") from None
    return parse_job(data, path)


def default_job(model: dict[str, Any]) -> dict[str, Any]:
    """A new job on a model: Buckens frame, band 0-1000 Hz, no reductions yet."""
    return {
        "title": "",
        "model": model,
        "interface": [],
        "frame": {"type": "buckens"},
        "inputs": [],
        "band": {"f_min_hz": 0.0, "f_max_hz": 1000.0, "points": 200},
        "reduction": [],
        "export": {"outputs": ["npz"]},
    }


def job_file_draft(path: Path) -> dict[str, Any]:
    """A job file as the editor's draft: its model files made absolute (the saved job runs from
    any folder), ``npz`` added to ``[export] outputs`` (the page reads the bases from
    ``reduced.npz``)."""
    data = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    model = dict(data.get("model", {}))
    for key in MODEL_FILE_KEYS:
        if isinstance(model.get(key), str):
            model[key] = str((path.parent / model[key]).resolve())
    data["model"] = model
    export = dict(data.get("export", {}))
    outputs = list(export.get("outputs", DEFAULT_EXPORTS))
    if "npz" not in outputs:
        export["outputs"] = ["npz", *outputs]
        data["export"] = export
    return data


def _without_empty(job: dict[str, Any]) -> dict[str, Any]:
    """The job without empty lists of tables and empty strings (not written)."""
    return {k: v for k, v in job.items() if v not in ([], "", None)}


class JobEditor:
    """The job being edited: the page's draft, parsed once per edit.

    Attributes
    ----------
    draft : dict
        The job as the page sent it (the tables and keys of the TOML file; may be invalid).
    text : str
        Its TOML text ('' when it cannot be written, e.g. a number that is not finite).
    error : str
        The parser's message in one line ('' when the job is valid).
    job : Job or None
        The parsed job when it is valid (read as ``job.toml`` of the current folder).
    """

    def __init__(self, draft: dict[str, Any]) -> None:
        self.lock = threading.Lock()
        self.draft: dict[str, Any] = {}
        self.text = ""
        self.error = ""
        self.job: Job | None = None
        self.edit(draft)

    def edit(self, draft: Any) -> None:
        """Hold a new draft: write its text and parse it (the one parse of this edit).

        Raises
        ------
        UserError
            ``draft`` is not an object (a JSON object from the page).
        """
        if not isinstance(draft, dict):
            raise UserError("job: expected an object")
        job: Job | None = None
        try:
            text, error = job_text(_without_empty(draft)), ""
        except UserError as exc:
            text, error = "", str(exc)
        if not error:
            try:
                job = check_job_text(text, Path("job.toml"))
            except PymorembsError as exc:
                error = " ".join(str(exc).split())
        with self.lock:
            self.draft, self.text, self.error, self.job = draft, text, error, job

    def valid(self) -> tuple[str, Job]:
        """The job's text and parsed job.

        Raises
        ------
        UserError
            The job is not valid yet (the parser's message).
        """
        with self.lock:
            text, error, job = self.text, self.error, self.job
        if job is None:
            raise UserError(f"the job is not valid yet: {error}")
        return text, job

    def interface_ids(self) -> list[int]:
        """The node ids of the job's ``[[interface]]`` tables: the parsed job's when it is valid,
        else the whole numbers of the draft's tables."""
        with self.lock:
            job, draft = self.job, self.draft
        if job is not None:
            return [spec.node for spec in job.interfaces]
        items = draft.get("interface")
        if not isinstance(items, list):
            return []
        nodes = [item.get("node") for item in items if isinstance(item, dict)]
        return [n for n in nodes if isinstance(n, int) and not isinstance(n, bool)]

    def save(self, request: dict[str, Any]) -> dict[str, Any]:
        """Write the job's TOML text to ``request["path"]`` (a ``.toml`` file), if it is valid."""
        text, _ = self.valid()
        path = Path(str(request.get("path", ""))).expanduser()
        if path.suffix.lower() != ".toml":
            raise UserError(f"save: {path}: a job file ends in .toml")
        if path.is_dir():
            raise UserError(f"save: {path} is a folder")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:  # a file in the way, no permission
            raise UserError(f"save: {path}: cannot create its folder ({exc.strerror})") from None
        write_text(path, text)
        return {"path": str(path.resolve()), "toml": text}
