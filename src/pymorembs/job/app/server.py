"""The local web server of ``pymorembs app``: the page, its files and a small JSON API.

Standard library only (:mod:`http.server`, one thread per request), bound to 127.0.0.1. The
framework was chosen by measurement (``docs/app.md``). Long work never runs on a request
thread: a job runs in a child process (:mod:`~pymorembs.job.app.runner`), the eigenfrequencies
of the opened model in a background thread.

API (JSON in and out; errors are ``{"error": "one line"}`` with status 400, 500 for a bug of
the server). Only requests addressed to 127.0.0.1 or localhost are answered, and POST bodies
must be JSON objects: another web site open in the same browser cannot drive the app.

=======================  ==================================================================
``GET  /api/schema``      every table of a job, its keys and every list of kinds
                          (:func:`~pymorembs.job.shape.job_schema`): the page's forms
``GET  /api/methods``     every method's options, from the method registry (the form)
``GET  /api/examples``    the built-in models and their options
``GET  /api/exports``     the files a job can write, and the default ones (``[export]``)
``GET  /api/state``       the job, its TOML text and check, the model, the run
``POST /api/open``        ``{"example": name, "options": {...}}`` or ``{"path": file}``
                          (with ``"format"``: the reader, default told from the content)
``GET  /api/scene``       the opened body for the 3D view (:func:`body_scene`)
``GET  /api/facts``       dofs, nodes, the lowest eigenfrequencies (computed once)
``POST /api/pick``        ``{"triangle": t}`` or ``{"node": row}``: the smooth surface patch
                          there (a hole's wall) and its selection for ``[[interface]]``
``POST /api/select``      ``{"cylinder": {...}, "box": {...}, "nodes": [...]}``: node rows
``POST /api/job``         ``{"job": {...}}``: the new job; its TOML and check
``POST /api/run``         run the job (``pymorembs reduce`` in a child process)
``GET  /api/status``      progress of the run
``POST /api/cancel``      end the run
``GET  /api/results``     error curves, estimators, eigenfrequencies of every reduction
``GET  /api/shape``       ``?reduction=name&k=3``: shape function k on the scene's nodes
``GET  /api/mac``         ``?a=name&b=name``: mass-weighted MAC between the two bases
``POST /api/save``        ``{"path": "job.toml"}``: write the job file
``GET  /files/<name>``    a file of the last run's output folder (export)
=======================  ==================================================================
"""

from __future__ import annotations

import json
import mimetypes
import tempfile
import threading
import tomllib
import traceback
from collections.abc import Callable
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, unquote, urlparse

import numpy as np

import pymorembs as pm
from pymorembs.analysis import mac as modal_assurance
from pymorembs.body import ElasticBody
from pymorembs.errors import PymorembsError, UserError
from pymorembs.examples import EXAMPLES, OPTIONS
from pymorembs.export import DEFAULT_EXPORTS, EXPORT_KINDS
from pymorembs.io.atomic import write_text
from pymorembs.job.app.editor import check_job_text, free_node_id, hole_selection, job_text
from pymorembs.job.app.runner import Run, start_run
from pymorembs.job.run import add_interfaces, load_job_model, load_model
from pymorembs.job.schema import MODEL_FILE_KEYS, ModelSpec, load_job
from pymorembs.job.shape import job_schema
from pymorembs.job.summary import JobSummary
from pymorembs.methods import METHODS, option_fields
from pymorembs.preparation import centre_of_gravity
from pymorembs.report import body_scene, viewer_script
from pymorembs.surface import smooth_patch

STATIC = Path(__file__).parent / "static"
#: What the results give of each reduction's summary entry.
RESULT_KEYS = (
    "name", "method", "order", "max_rel_error", "static_rel_error", "error_estimate",
    "error_bound", "eigenfrequencies_hz", "time_s", "files", "accuracy",
)  # fmt: skip
#: The arrays of ``reduced.npz`` the shape view and the MAC read.
BASIS_KEYS = ("V", "dof_nodes", "dof_directions", "eigenfrequencies_hz")
#: The model a new page opens when none is given.
DEFAULT_EXAMPLE = {"example": "rack-solid", "options": {"dofs": 35000, "interface": "none"}}


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


class App:
    """What the page works on: the opened body, the job being edited and its last run.

    Parameters
    ----------
    workdir : Path, optional
        Where runs write (``job.toml``, ``run-1/``, ...); default a new temporary folder.
    """

    def __init__(self, workdir: Path | None = None) -> None:
        self.workdir = Path(workdir or tempfile.mkdtemp(prefix="pymorembs-app-")).resolve()
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.lock = threading.RLock()
        self.body: ElasticBody | None = None
        self.scene: dict[str, Any] | None = None
        self._scene_ids = np.zeros(0, dtype=np.int64)
        self.job: dict[str, Any] = default_job(DEFAULT_EXAMPLE)
        self.run: Run | None = None
        self.runs = 0
        self._facts: dict[str, Any] | None = None
        self._facts_thread: threading.Thread | None = None
        self._bases: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        self._mass: tuple[str, Any] | None = None  # (run folder, mass matrix of its body)
        self._cog: tuple[ElasticBody, np.ndarray] | None = None

    # -- the model ---------------------------------------------------------------------------
    def open(self, request: dict[str, Any]) -> dict[str, Any]:
        """Open a built-in example or a model file (any format ``pymorembs.read`` knows) or a
        job file (its model, and the job into the editor)."""
        job = None
        if "example" in request:
            name = str(request["example"])
            if name not in EXAMPLES:
                raise UserError(f"unknown example {name!r}; available: {', '.join(EXAMPLES)}")
            options = {k: v for k, v in dict(request.get("options") or {}).items()
                       if v not in (None, "")}  # fmt: skip
            body = load_model(ModelSpec(example=name, options=options))
            model = {"example": name, **options}
        elif "path" in request:
            path = Path(str(request["path"])).expanduser()
            if not path.exists():
                raise UserError(f"{path}: no such file")
            if path.suffix.lower() == ".toml":
                parsed = load_job(path)
                body = load_model(parsed.model)
                job = _job_dict(path)
                model = job["model"]
                export = dict(job.get("export", {}))
                outputs = list(export.get("outputs", DEFAULT_EXPORTS))
                if "npz" not in outputs:  # the page reads the bases from reduced.npz
                    export["outputs"] = ["npz", *outputs]
                    job["export"] = export
            else:
                fmt = request.get("format") or None
                body = pm.read(path, format=fmt)
                model = {"file": str(path.resolve())}
                if fmt is not None:
                    model["format"] = fmt
        else:
            raise UserError("open: give 'example' or 'path'")
        scene = body_scene(body)
        with self.lock:
            self.body = body
            self.scene = scene
            self._scene_ids = np.asarray(scene["node_ids"], dtype=np.int64)
            self._facts = None
            self._facts_thread = None
            self.job = job if job is not None else default_job(model)
        return self.state()

    def scene_json(self) -> dict[str, Any]:
        """The opened body for ``viewer.js`` (:func:`pymorembs.report.scene.body_scene`)."""
        self._body()
        return self.scene

    def scene_rows(self, ids: np.ndarray) -> np.ndarray:
        """Indices into the scene's nodes of those of ``ids`` that the scene has."""
        scene = self._scene_ids
        if scene.size == 0:
            return np.zeros(0, dtype=np.int64)
        order = np.argsort(scene, kind="stable")
        ids = np.asarray(ids, dtype=np.int64)
        found = order[np.minimum(np.searchsorted(scene, ids, sorter=order), scene.size - 1)]
        return found[scene[found] == ids]

    def facts(self) -> dict[str, Any]:
        """The facts of ``pymorembs info`` (computed once per model, off the request thread)."""
        body = self._body()
        with self.lock:
            if self._facts is None and self._facts_thread is None:
                self._facts_thread = threading.Thread(
                    target=self._compute_facts, args=(body,), daemon=True
                )
                self._facts_thread.start()
            thread = self._facts_thread
        if thread is not None:
            thread.join()
        with self.lock:
            return self._facts or {"error": "the model's facts could not be computed"}

    def _compute_facts(self, body: ElasticBody) -> None:
        try:
            facts = pm.facts(body, modes=10)
            keep = ("name", "n_dof", "n_nodes", "n_independent", "n_dependent", "n_fixed",
                    "rigid_body_modes", "eigenfrequencies_hz", "total_mass", "units")  # fmt: skip
            out = {k: facts[k] for k in keep if k in facts}
        except PymorembsError as exc:
            out = {"error": " ".join(str(exc).split())}
        out["surface"] = None if body.surface is None else body.surface.source
        with self.lock:
            if self.body is body:
                self._facts = out

    def _body(self) -> ElasticBody:
        if self.body is None:
            raise UserError("no model is open")
        return self.body

    # -- picking -------------------------------------------------------------------------------
    def pick(self, request: dict[str, Any]) -> dict[str, Any]:
        """The smooth surface patch at a picked triangle (or node) and its job selection."""
        body = self._body()
        surface = body.surface
        angle = float(request.get("max_angle_deg", 30.0))
        if surface is None or surface.triangles.shape[0] == 0:
            raise UserError("this model has no surface to pick on; give a cylinder or a box")
        if request.get("triangle") is not None:
            seed = int(request["triangle"])
        elif request.get("node") is not None:
            row = int(request["node"])
            if not 0 <= row < self._scene_ids.size:
                raise UserError(f"pick: no node {row} in the view (it has {self._scene_ids.size})")
            node = int(self._scene_ids[row])
            touching = np.flatnonzero((surface.triangles == node).any(axis=1))
            if touching.size == 0:
                raise UserError(f"node {node} is not on the surface")
            seed = int(touching[0])
        else:
            raise UserError("pick: give 'triangle' or 'node'")
        region = smooth_patch(surface, body.node_ids, body.coordinates, seed, angle)
        nodes = np.unique(surface.triangles[region])
        return {**self._selected(nodes), **hole_selection(body, nodes)}

    def select(self, request: dict[str, Any]) -> dict[str, Any]:
        """Nodes of a selection given by numbers (as in ``[[interface]]``)."""
        return self._selected(_selection(self._body(), request))

    def decorations(self) -> dict[str, Any]:
        """What the 3D view draws of the job being edited (``viewer.setDecorations``).

        Returns
        -------
        dict
            ``frame``: ``{"origin": [3], "axes": [[3], [3], [3]]}`` (model length unit, the
            model's axes) or None: a tangent frame at its node (a node of the model or an
            interface node of the job, at its ``position``), a Buckens frame at the model's
            centre of gravity, none for ``type = "none"``; ``interfaces``: per ``[[interface]]``
            ``{"name", "node": index into the scene's nodes or None, "position": [3],
            "coupled": [indices into the scene's nodes]}``; ``notes``: what could not be drawn
            (a selection that gives no nodes, a frame node nobody has), one line each.
        """
        body = self.body
        out: dict[str, Any] = {"frame": None, "interfaces": [], "notes": []}
        if body is None:
            return out
        placed: dict[int, list[float]] = {}
        interfaces = self.job.get("interface") or []
        if not isinstance(interfaces, list):
            out["notes"].append("[[interface]] is not drawn: expected a list of tables")
            interfaces = []
        for k, item in enumerate(interfaces, start=1):
            try:
                node = int(item["node"])
                position = [float(x) for x in item["position"]]
                if len(position) != 3 or not np.all(np.isfinite(position)):
                    raise ValueError("position must be 3 finite numbers")
                coupled = _selection(body, item)
            except (PymorembsError, KeyError, TypeError, ValueError) as exc:
                out["notes"].append(f"[[interface]] #{k} is not drawn: {_one_line(exc)}")
                continue
            row = self.scene_rows(np.array([node]))
            out["interfaces"].append({
                "name": f"interface {node} ({item.get('kind', 'rigid')})",
                "node": int(row[0]) if row.size else None,
                "position": position,
                "coupled": self.scene_rows(coupled).tolist(),
            })  # fmt: skip
            placed[node] = position
        frame = self.job.get("frame") or {}
        if not isinstance(frame, dict):
            out["notes"].append("[frame] is not drawn: it must be a table")
            frame = {}
        kind = frame.get("type")
        origin = None
        try:
            if kind == "tangent":
                node = int(frame["node"])
                if node in placed:
                    origin = placed[node]
                elif node in body.node_index:
                    origin = body.node_position(node).tolist()
                else:
                    out["notes"].append(f"[frame] node {node} is neither a node of the model "
                                        "nor an interface node: no triad")  # fmt: skip
            elif kind == "buckens":
                origin = self._centre_of_gravity(body).tolist()
        except (PymorembsError, KeyError, TypeError, ValueError) as exc:
            out["notes"].append(f"[frame] is not drawn: {_one_line(exc)}")
        if origin is not None:
            out["frame"] = {"origin": origin, "axes": np.eye(3).tolist()}
        return out

    def _centre_of_gravity(self, body: ElasticBody) -> np.ndarray:
        with self.lock:
            if self._cog is None or self._cog[0] is not body:
                self._cog = (body, centre_of_gravity(body))
            return self._cog[1]

    def _selected(self, nodes: np.ndarray) -> dict[str, Any]:
        body = self._body()
        return {
            "count": int(nodes.size),
            "rows": self.scene_rows(nodes).tolist(),
            "ids": [int(n) for n in nodes],
            "free_id": free_node_id(body, _interface_ids(self.job)),
        }

    # -- the job -------------------------------------------------------------------------------
    def set_job(self, job: dict[str, Any]) -> dict[str, Any]:
        """Replace the job being edited (the page sends it after every change)."""
        if not isinstance(job, dict):
            raise UserError("job: expected an object")
        with self.lock:
            self.job = job
        return self.state()

    def checked(self) -> tuple[str, str]:
        """The job's TOML text and the parser's message ('' when the job is valid)."""
        try:
            text = job_text(_without_empty(self.job))
        except UserError as exc:
            return "", str(exc)
        try:
            check_job_text(text, Path("job.toml"))
        except PymorembsError as exc:
            return text, " ".join(str(exc).split())
        return text, ""

    def state(self) -> dict[str, Any]:
        """The job, its TOML text and check, the opened model's sizes, the run's status."""
        text, error = self.checked()
        body = self.body
        return {
            "job": self.job,
            "toml": text,
            "error": error,
            "model": None
            if body is None
            else {
                "name": body.name,
                "n_dof": body.n_dof,
                "n_nodes": body.n_nodes,
                "surface": body.surface is not None,
            },
            "run": None if self.run is None else self.run.as_dict(),
            "workdir": str(self.workdir),
            "decorations": self.decorations(),
        }

    def save(self, request: dict[str, Any]) -> dict[str, Any]:
        """Write the job's TOML text to ``request["path"]`` (a ``.toml`` file), if it is valid."""
        text, error = self.checked()
        if error:
            raise UserError(f"the job is not valid yet: {error}")
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

    # -- running -------------------------------------------------------------------------------
    def start(self) -> dict[str, Any]:
        """Write the job into the work folder and run it (one run at a time)."""
        with self.lock:
            if self.run is not None and self.run.state == "running":
                raise UserError("a run is going on; cancel it first")
            if self.run is not None and self.run.alive:
                raise UserError("the cancelled run is still ending; run again in a moment")
            text, error = self.checked()
            if error:
                raise UserError(f"the job is not valid yet: {error}")
            self.runs += 1
            job = self.workdir / f"job-{self.runs}.toml"
            write_text(job, text)
            stages = check_job_text(text, job).stage_count()
            self._bases.clear()
            self.run = start_run(job, self.workdir / f"run-{self.runs}", stages)
            return self.run.as_dict()

    def status(self) -> dict[str, Any]:
        """The run's progress (``{"state": "idle"}`` before the first run)."""
        return {"state": "idle"} if self.run is None else self.run.as_dict()

    def cancel(self) -> dict[str, Any]:
        """End the run going on, if any."""
        if self.run is not None:
            self.run.cancel()
        return self.status()

    def _summary(self) -> tuple[Run, JobSummary]:
        run = self.run
        if run is None or run.state != "done":
            raise UserError("no finished run yet")
        data = json.loads((run.out / "summary.json").read_text(encoding="utf-8"))
        return run, JobSummary.from_json(data)

    def results(self) -> dict[str, Any]:
        """Per reduction: order, errors, estimate and bound, eigenfrequencies, the eps curve
        (and the estimator's), read from the run's ``summary.json`` and ``error*.csv``."""
        run, summary = self._summary()
        rows = []
        for reduction in summary.reductions:
            entry = reduction.to_json()
            folder = run.out / reduction.name
            table = np.loadtxt(folder / "error.csv", delimiter=",", skiprows=1, ndmin=2)
            curve: dict[str, Any] = {"frequency_hz": table[:, 0].tolist(),
                                     "relative": table[:, 1].tolist()}  # fmt: skip
            if reduction.inertia_loads:
                curve["inertia"] = table[:, 2].tolist()
            estimate = folder / "error_estimate.csv"
            if estimate.exists():
                est = np.loadtxt(estimate, delimiter=",", skiprows=1, ndmin=2)
                curve["estimate"] = {"frequency_hz": est[:, 0].tolist(),
                                     "relative": est[:, 1].tolist()}  # fmt: skip
            row = {key: entry.get(key) for key in RESULT_KEYS}
            row["curve"] = curve
            inertia = reduction.inertia_loads
            row["max_rel_error_inertia"] = None if inertia is None else inertia.max_rel_error
            rows.append(row)
        return {
            "reductions": rows,
            "band_hz": list(summary.band_hz),
            "reference": summary.reference.get("kind"),
            "warnings": summary.warnings,
            "accuracy": summary.accuracy,
            "out": str(run.out),
            "job": str(run.job),
        }

    def _basis(self, name: str) -> dict[str, np.ndarray]:
        run, summary = self._summary()
        if name not in [r.name for r in summary.reductions]:
            raise UserError(f"no reduction named {name!r} in the last run")
        key = (str(run.out), name)
        if key not in self._bases:
            path = run.out / name / "reduced.npz"
            if not path.exists():
                raise UserError(f"reduction '{name}' wrote no reduced.npz (add 'npz' to outputs)")
            with np.load(path) as data:
                self._bases[key] = {k: data[k] for k in BASIS_KEYS}
        return self._bases[key]

    def shape(self, name: str, k: int) -> dict[str, Any]:
        """Column ``k`` of a reduction's basis as translations of the scene's nodes (largest
        translation 1), with the reduced model's eigenfrequency of that direction."""
        self._body()
        basis = self._basis(name)
        V = basis["V"]
        if not 0 <= k < V.shape[1]:
            raise UserError(f"reduction '{name}' has shape functions 0..{V.shape[1] - 1}")
        ids = self._scene_ids
        values = np.zeros((ids.size, 3))
        nodes, directions = basis["dof_nodes"], basis["dof_directions"]
        known = np.isin(nodes, ids) & (directions < 3)
        values[self.scene_rows(nodes[known]), directions[known]] = V[known, k]
        largest = np.abs(values).max()
        if largest > 0:
            values /= largest
        return {
            "values": values.ravel().round(6).tolist(),
            "frequency_hz": float(basis["eigenfrequencies_hz"][k]),
            "count": int(V.shape[1]),
        }

    def mac(self, a: str, b: str) -> dict[str, Any]:
        """The mass-weighted modal assurance criterion between the columns of two bases,
        ``(v_i^T M w_j)^2 / ((v_i^T M v_i)(w_j^T M w_j))`` with the sparse mass matrix of the
        run's body (:func:`pymorembs.analysis.mac`)."""
        A, B = self._basis(a), self._basis(b)
        if not (
            np.array_equal(A["dof_nodes"], B["dof_nodes"])
            and np.array_equal(A["dof_directions"], B["dof_directions"])
        ):
            raise UserError("the two bases are not on the same dofs")
        mass = self._run_mass(A["dof_nodes"], A["dof_directions"])
        return {
            "matrix": modal_assurance(A["V"], B["V"], mass).round(4).tolist(),
            "weighting": "mass",
            "a_hz": A["eigenfrequencies_hz"].tolist(),
            "b_hz": B["eigenfrequencies_hz"].tolist(),
        }

    def _run_mass(self, nodes: np.ndarray, directions: np.ndarray) -> Any:
        """The sparse mass matrix of the last run's body (the model with the job's interface
        nodes, on the dofs of its ``reduced.npz``), built once per run."""
        run, _ = self._summary()
        if self._mass is not None and self._mass[0] == str(run.out):
            mass = self._mass[1]
        else:
            job = load_job(run.job)
            body = add_interfaces(self._body(), job)
            if not _same_dofs(body, nodes, directions):  # another model opened since the run
                body = load_job_model(job)
            if not _same_dofs(body, nodes, directions):
                raise UserError("the run's bases are not on the dofs of its model")
            mass = body.mass
            self._mass = (str(run.out), mass)
        return mass

    def file(self, name: str) -> Path:
        """A file of the last finished run's output folder (never outside it)."""
        run = self.run
        if run is None or run.state != "done":
            raise UserError("no finished run yet")
        path = (run.out / name).resolve()
        if run.out.resolve() not in path.parents or not path.is_file():
            raise UserError(f"no file {name!r} in the run's output")
        return path


def _same_dofs(body: ElasticBody, nodes: np.ndarray, directions: np.ndarray) -> bool:
    return np.array_equal(body.dofs.nodes, nodes) and np.array_equal(
        body.dofs.directions, directions
    )


def _selection(body: ElasticBody, request: dict[str, Any]) -> np.ndarray:
    """Node ids of a selection by numbers: ``cylinder``, ``box`` and/or ``nodes`` (the keys of
    ``[[interface]]``; all criteria apply)."""
    cylinder = request.get("cylinder")
    box = request.get("box")
    ids = request.get("nodes")
    return pm.select_nodes(
        body,
        ids=None if not ids else [int(i) for i in ids],
        cylinder=None if not cylinder else _cylinder(cylinder),
        box=None if not box else (box["min"], box["max"]),
    )


def _one_line(exc: Exception) -> str:
    text = " ".join(str(exc).split())
    return f"missing {text}" if isinstance(exc, KeyError) else text


def _interface_ids(job: dict[str, Any]) -> list[int]:
    """The node ids of the edited job's ``[[interface]]`` tables (whole numbers only: the job
    being edited need not be valid)."""
    items = job.get("interface")
    if not isinstance(items, list):
        return []
    nodes = [item.get("node") for item in items if isinstance(item, dict)]
    return [n for n in nodes if isinstance(n, int) and not isinstance(n, bool)]


def _not_json(constant: str) -> None:
    raise ValueError(f"{constant} is not a number in JSON")


def _cylinder(data: dict[str, Any]) -> tuple:
    values = (data["point"], data["direction"], float(data["radius"]))
    tolerance = data.get("tolerance")
    return values if tolerance in (None, "") else (*values, float(tolerance))


def _without_empty(job: dict[str, Any]) -> dict[str, Any]:
    """The job without empty lists of tables and empty strings (not written)."""
    return {k: v for k, v in job.items() if v not in ([], "", None)}


def _job_dict(path: Path) -> dict[str, Any]:
    """A job file as the editor's dictionary, its model files made absolute."""
    data = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    model = dict(data.get("model", {}))
    for key in MODEL_FILE_KEYS:
        if isinstance(model.get(key), str):
            model[key] = str((path.parent / model[key]).resolve())
    data["model"] = model
    return data


def methods() -> dict[str, Any]:
    """Every method's options as the page's forms show them (:func:`option_fields`)."""
    return {name: option_fields(name) for name in METHODS}


def exports() -> dict[str, list[str]]:
    """The files a job can write (``[export] outputs``: ``kinds``) and those it writes when
    it does not say (``default``), from the export registry (:mod:`pymorembs.export.registry`)."""
    return {"kinds": list(EXPORT_KINDS), "default": list(DEFAULT_EXPORTS)}


def examples() -> dict[str, Any]:
    """The built-in models and the options each takes."""
    return {name: list(OPTIONS[name]) for name in EXAMPLES}


class Handler(BaseHTTPRequestHandler):
    """Requests of the page; ``self.server.app`` is the :class:`App`."""

    server_version = "pymorembs-app"

    def log_message(self, format: str, *args: Any) -> None:  # quiet: the page polls
        pass

    @property
    def app(self) -> App:
        return self.server.app  # type: ignore[attr-defined]

    def _send(self, status: int, body: bytes, kind: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        try:
            self.wfile.write(body)
        except (BrokenPipeError, ConnectionResetError):  # the page went away meanwhile
            pass

    def _json(self, data: Any, status: int = 200) -> None:
        body = json.dumps(data, allow_nan=False, separators=(",", ":")).encode()
        self._send(status, body, "application/json")

    def _handle(self, action: Callable[[], Any]) -> None:
        try:
            self._json(action())
        except PymorembsError as exc:
            self._json({"error": " ".join(str(exc).split())}, HTTPStatus.BAD_REQUEST)
        except (KeyError, TypeError, ValueError) as exc:
            self._json({"error": f"bad request: {exc}"}, HTTPStatus.BAD_REQUEST)
        except Exception as exc:  # a bug, not the user's mistake: an answer, the traceback here
            traceback.print_exc()
            self._json(
                {"error": f"internal error: {_one_line(exc)}"}, HTTPStatus.INTERNAL_SERVER_ERROR
            )

    def _request(self) -> dict[str, Any]:
        """The POST body: a JSON object (an empty body is ``{}``).

        Raises
        ------
        UserError
            A body that is not a JSON object: invalid JSON or UTF-8, ``NaN`` or ``Infinity``
            (not JSON; the state could not be sent back), an array, a string, a number.
        """
        try:
            length = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            raise UserError("bad request: Content-Length is not a number") from None
        data = self.rfile.read(length) if length > 0 else b""
        try:
            request = json.loads(data or b"{}", parse_constant=_not_json)
        except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, NaN
            raise UserError(f"bad JSON: {_one_line(exc)}") from None
        if not isinstance(request, dict):
            raise UserError(f"bad JSON: expected an object, got {type(request).__name__}")
        return request

    def _refused(self, post: bool) -> bool:
        """Refuse requests another web site could make through the user's browser: a foreign
        ``Host`` (DNS rebinding), and for POST any body but JSON (a cross-site form or a
        simple request; JSON needs a CORS preflight, which this server never grants)."""
        port = self.server.server_address[1]
        if self.headers.get("Host") not in (f"127.0.0.1:{port}", f"localhost:{port}"):
            self._json({"error": "requests only from this machine's page"}, HTTPStatus.FORBIDDEN)
            return True
        kind = (self.headers.get("Content-Type") or "").split(";")[0].strip()
        if post and kind != "application/json":
            self._json({"error": "send JSON"}, HTTPStatus.UNSUPPORTED_MEDIA_TYPE)
            return True
        return False

    def do_GET(self) -> None:
        if self._refused(post=False):
            return
        url = urlparse(self.path)
        query = {k: v[-1] for k, v in parse_qs(url.query).items()}
        route = url.path
        if route in ("/", "/index.html"):
            return self._file(STATIC / "page.html")
        if route.startswith("/static/"):
            name = Path(unquote(route[len("/static/") :])).name
            return self._file(STATIC / name)
        if route == "/viewer.js":
            return self._send(200, viewer_script().encode(), "text/javascript")
        if route.startswith("/files/"):
            try:
                path = self.app.file(unquote(route[len("/files/") :]))
            except PymorembsError as exc:
                return self._json({"error": str(exc)}, HTTPStatus.NOT_FOUND)
            return self._file(path, download=True)
        app = self.app
        actions = {
            "/api/schema": job_schema,
            "/api/methods": methods,
            "/api/examples": examples,
            "/api/exports": exports,
            "/api/state": app.state,
            "/api/scene": app.scene_json,
            "/api/facts": app.facts,
            "/api/status": app.status,
            "/api/results": app.results,
            "/api/shape": lambda: app.shape(query["reduction"], int(query.get("k", 0))),
            "/api/mac": lambda: app.mac(query["a"], query["b"]),
        }
        if route not in actions:
            return self._json({"error": f"no such page {route}"}, HTTPStatus.NOT_FOUND)
        self._handle(actions[route])

    def do_POST(self) -> None:
        if self._refused(post=True):
            return
        try:
            request = self._request()
        except UserError as exc:
            return self._json({"error": str(exc)}, HTTPStatus.BAD_REQUEST)
        app = self.app
        actions = {
            "/api/open": lambda: app.open(request),
            "/api/pick": lambda: app.pick(request),
            "/api/select": lambda: app.select(request),
            "/api/job": lambda: app.set_job(request.get("job")),
            "/api/run": app.start,
            "/api/cancel": app.cancel,
            "/api/save": lambda: app.save(request),
        }
        route = urlparse(self.path).path
        if route not in actions:
            return self._json({"error": f"no such action {route}"}, HTTPStatus.NOT_FOUND)
        self._handle(actions[route])

    def _file(self, path: Path, download: bool = False) -> None:
        if not path.is_file():
            return self._json({"error": f"no file {path.name}"}, HTTPStatus.NOT_FOUND)
        kind = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
        if path.suffix == ".js":
            kind = "text/javascript"
        self.send_response(200)
        data = path.read_bytes()
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Cache-Control", "no-store")
        if download:
            self.send_header("Content-Disposition", f'attachment; filename="{path.name}"')
        self.end_headers()
        self.wfile.write(data)


def make_server(app: App, port: int) -> ThreadingHTTPServer:
    """The server of ``app`` on 127.0.0.1:``port`` (0: a free port), not yet serving.

    Raises
    ------
    UserError
        The port is in use or cannot be bound.
    """
    try:
        server = ThreadingHTTPServer(("127.0.0.1", int(port)), Handler)
    except OSError as exc:
        if exc.errno in (98, 48, 10048):  # EADDRINUSE on Linux, macOS, Windows
            raise UserError(
                f"port {port} is in use (another pymorembs app?); choose another with --port"
            ) from None
        raise UserError(f"cannot listen on 127.0.0.1:{port}: {exc.strerror}") from None
    server.daemon_threads = True
    server.app = app  # type: ignore[attr-defined]
    return server
