"""The results of the last finished run, read from its own output folder.

:class:`RunResults` reads ``summary.json`` (a :class:`~pymorembs.job.summary.JobSummary`),
``*/error.csv``, ``*/error_estimate.csv`` and ``*/reduced.npz`` of the run's folder: the table
and curves of every reduction, a shape function on the opened model's scene (with its von Mises
stress at the scene's nodes for a body with solid elements), the mass-weighted
MAC between two bases and the files written. The bases and the run body's mass matrix are read
and built once per run. With hot spots and time checks, ``stress_history.npz``
(:data:`~pymorembs.analysis.HISTORY_FILE`): the hot spots on the scene and the stress history at
one of them, every body of every time check.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from pymorembs.analysis import HISTORY_FILE, StressHistory, histories_from_arrays
from pymorembs.analysis import mac as modal_assurance
from pymorembs.body import ElasticBody
from pymorembs.errors import UserError
from pymorembs.export import nodes_operator, von_mises_at
from pymorembs.job.app.opened_model import OpenedModel
from pymorembs.job.app.runner import Run
from pymorembs.job.app.runs import RunController
from pymorembs.job.run import add_interfaces, load_job_model
from pymorembs.job.summary import JobSummary
from pymorembs.stress import StressOperator

#: What the results give of each reduction's summary entry.
RESULT_KEYS = (
    "name", "method", "order", "max_rel_error", "static_rel_error", "error_estimate",
    "error_bound", "eigenfrequencies_hz", "time_s", "files", "accuracy",
)  # fmt: skip
#: The arrays of ``reduced.npz`` the shape view and the MAC read.
BASIS_KEYS = ("V", "dof_nodes", "dof_directions", "eigenfrequencies_hz")
#: What the page says of a run without stress histories (not an error).
NO_HISTORY = (
    "no stress history in this run: it needs hot spots ([stress]) and a time check "
    "([time_domain] or [large_motion])"
)


class RunResults:
    """What the page shows of the last finished run of ``runs`` on the body of ``model``."""

    def __init__(self, model: OpenedModel, runs: RunController) -> None:
        self.model = model
        self.runs = runs
        self._bases: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        self._body: tuple[str, ElasticBody] | None = None  # (run folder, its body)
        # (run folder, the nodal stress operator on the scene's nodes; None without solids)
        self._stress: tuple[str, StressOperator | None] | None = None
        # (run folder, its stress histories by check, case and body, the hot spots' positions)
        self._histories: tuple[str, dict[str, dict[str, dict]], np.ndarray] | None = None

    def _summary(self) -> tuple[Run, JobSummary]:
        run = self.runs.finished()
        data = json.loads((run.out / "summary.json").read_text(encoding="utf-8"))
        return run, JobSummary.from_json(data)

    def table(self) -> dict[str, Any]:
        """Per reduction: order, errors, estimate and bound, eigenfrequencies, the eps curve
        (and the estimator's, and over the stresses), read from the run's ``summary.json`` and
        ``error*.csv``."""
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
            if reduction.stress:  # the column after the inertia loads' (error.csv)
                curve["stress"] = table[:, 2 + bool(reduction.inertia_loads)].tolist()
            estimate = folder / "error_estimate.csv"
            if estimate.exists():
                est = np.loadtxt(estimate, delimiter=",", skiprows=1, ndmin=2)
                curve["estimate"] = {"frequency_hz": est[:, 0].tolist(),
                                     "relative": est[:, 1].tolist()}  # fmt: skip
            row = {key: entry.get(key) for key in RESULT_KEYS}
            row["curve"] = curve
            inertia = reduction.inertia_loads
            row["max_rel_error_inertia"] = None if inertia is None else inertia.max_rel_error
            stress = reduction.stress
            row["max_rel_error_stress"] = None if stress is None else stress.max_rel_error
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
                basis = {k: data[k] for k in BASIS_KEYS}
            self._bases = {k: v for k, v in self._bases.items() if k[0] == key[0]}  # this run's
            self._bases[key] = basis
        return self._bases[key]

    def shape(self, name: str, k: int) -> dict[str, Any]:
        """Column ``k`` of a reduction's basis as translations of the scene's nodes (largest
        translation 1), with the reduced model's eigenfrequency of that direction and, for a
        body with solid elements, its von Mises stress at the scene's nodes (``von_mises``,
        model stress unit per unit modal coordinate; None without solids)."""
        self.model.opened()
        basis = self._basis(name)
        V = basis["V"]
        if not 0 <= k < V.shape[1]:
            raise UserError(f"reduction '{name}' has shape functions 0..{V.shape[1] - 1}")
        ids = self.model.scene_ids
        values = np.zeros((ids.size, 3))
        nodes, directions = basis["dof_nodes"], basis["dof_directions"]
        known = np.isin(nodes, ids) & (directions < 3)
        values[self.model.scene_rows(nodes[known]), directions[known]] = V[known, k]
        largest = np.abs(values).max()
        if largest > 0:
            values /= largest
        operator = self._scene_stress(nodes, directions)
        stress = None if operator is None else von_mises_at(operator, V[:, k : k + 1], ids)
        return {
            "values": values.ravel().round(6).tolist(),
            "von_mises": None if stress is None else [float(f"{v:.4g}") for v in stress[:, 0]],
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
        mass = self._run_body(A["dof_nodes"], A["dof_directions"]).mass
        return {
            "matrix": modal_assurance(A["V"], B["V"], mass).round(4).tolist(),
            "weighting": "mass",
            "a_hz": A["eigenfrequencies_hz"].tolist(),
            "b_hz": B["eigenfrequencies_hz"].tolist(),
        }

    def _scene_stress(self, nodes: np.ndarray, directions: np.ndarray) -> StressOperator | None:
        """The nodal stress operator of the last run's body on the scene's nodes (None for a
        body without solid elements), built once per run."""
        run, _ = self._summary()
        if self._stress is None or self._stress[0] != str(run.out):
            body = self._run_body(nodes, directions)
            self._stress = (str(run.out), nodes_operator(body, self.model.scene_ids))
        return self._stress[1]

    def _run_body(self, nodes: np.ndarray, directions: np.ndarray) -> ElasticBody:
        """The last run's body (the model with the job's interface nodes, on the dofs of its
        ``reduced.npz``: its sparse mass matrix, its mesh), built once per run."""
        run, _ = self._summary()
        if self._body is not None and self._body[0] == str(run.out):
            return self._body[1]
        job = self.runs.job_of(run)
        body = add_interfaces(self.model.opened(), job)
        if not _same_dofs(body, nodes, directions):  # another model opened since the run
            body = load_job_model(job)
        if not _same_dofs(body, nodes, directions):
            raise UserError("the run's bases are not on the dofs of its model")
        self._body = (str(run.out), body)
        return body

    def _stress_histories(self) -> tuple[dict[str, dict[str, dict]], np.ndarray] | None:
        """The last run's stress histories (by check, case and body) and the hot spots'
        positions (n_p, 3), read once per run; None when the run wrote none."""
        run, _ = self._summary()
        if self._histories is None or self._histories[0] != str(run.out):
            path = run.out / HISTORY_FILE
            if not path.is_file():
                return None
            with np.load(path) as data:
                arrays = {key: data[key] for key in data.files}
            self._histories = (str(run.out), histories_from_arrays(arrays), arrays["coordinates"])
        return self._histories[1], self._histories[2]

    def hot_spots(self) -> dict[str, Any]:
        """The hot spots of the last run's stress histories: ``points`` (labels),
        ``positions`` (model length unit), ``rows`` (the nearest scene node of each, for a
        marker) and ``checks`` (check -> its cases); ``available`` False and a ``note`` when
        the run wrote no histories."""
        found = self._stress_histories()
        if found is None:
            return {"available": False, "note": NO_HISTORY, "points": [], "rows": []}
        checks, positions = found
        return {
            "available": True,
            "note": "",
            "points": list(_points(checks)),
            "positions": positions.tolist(),
            "rows": self._nearest_scene_rows(positions).tolist(),
            "checks": {check: list(cases) for check, cases in checks.items()},
        }

    def stress_history(
        self, point: str | None = None, node: int | None = None, components: bool = False
    ) -> dict[str, Any]:
        """The stress history at one hot spot: ``point`` (its label) or the hot spot nearest
        to the scene's node ``node`` (its row). Per check and case the times (s) and per body
        its von Mises stress over time with peak and range (model stress unit), and with
        ``components`` the six components (times x 6, ``xx yy zz xy xz yz``); without
        histories ``available`` False and a ``note``."""
        found = self._stress_histories()
        if found is None:
            return {"available": False, "note": NO_HISTORY}
        checks, positions = found
        points = _points(checks)
        if point is not None:
            if point not in points:
                raise UserError(f"no hot spot {point!r} in the last run ({len(points)} points)")
            k = points.index(point)
        elif node is not None:
            ids = self.model.scene_ids
            if not 0 <= node < ids.size:
                raise UserError(f"no node {node} in the view (it has {ids.size})")
            at = self._scene_positions()[node]
            k = int(np.argmin(np.linalg.norm(positions - at, axis=1)))
        else:
            raise UserError("stress history: give a hot spot (point=label) or a node (node=row)")
        return {
            "available": True,
            "point": points[k],
            "position": positions[k].tolist(),
            "histories": [
                {
                    "check": check,
                    "case": case,
                    "times": next(iter(bodies.values())).times.tolist(),
                    "bodies": [_body_history(name, h, k, components) for name, h in bodies.items()],
                }
                for check, cases in checks.items()
                for case, bodies in cases.items()
            ],
        }

    def _scene_positions(self) -> np.ndarray:
        """The positions of the scene's nodes (n, 3), model length unit."""
        body = self.model.opened()
        return body.coordinates[body.node_rows(self.model.scene_ids)]

    def _nearest_scene_rows(self, positions: np.ndarray) -> np.ndarray:
        """The scene node nearest to each of ``positions`` (n_p, 3): its row."""
        scene = self._scene_positions()
        if scene.shape[0] == 0:
            return np.zeros(0, dtype=np.int64)
        return np.array([int(np.argmin(np.linalg.norm(scene - p, axis=1))) for p in positions])

    def file(self, name: str) -> Path:
        """A file of the last finished run's output folder (never outside it)."""
        run = self.runs.finished()
        path = (run.out / name).resolve()
        if run.out.resolve() not in path.parents or not path.is_file():
            raise UserError(f"no file {name!r} in the run's output")
        return path


def _same_dofs(body: ElasticBody, nodes: np.ndarray, directions: np.ndarray) -> bool:
    return np.array_equal(body.dofs.nodes, nodes) and np.array_equal(
        body.dofs.directions, directions
    )


def _points(checks: dict[str, dict[str, dict]]) -> tuple[str, ...]:
    """The hot spots' labels of the histories (every history has the same)."""
    for cases in checks.values():
        for bodies in cases.values():
            for history in bodies.values():
                return history.points
    return ()


def _body_history(name: str, history: StressHistory, k: int, components: bool) -> dict[str, Any]:
    """One body's history at hot spot ``k``: von Mises over time, its peak and range (as the
    summary's entries, :meth:`StressHistory.hot_spots`) and the components if asked for."""
    spot = history.hot_spots()[k]
    entry = {
        "name": name,
        "von_mises": history.von_mises[:, k].tolist(),
        "peak_von_mises": spot.peak_von_mises,
        "range_von_mises": spot.range_von_mises,
        "range_abs_max_principal": spot.range_abs_max_principal,
    }
    if components:
        entry["stress"] = history.components[:, k, :].tolist()
    return entry
