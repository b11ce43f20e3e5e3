"""The results of the last finished run, read from its own output folder.

:class:`RunResults` reads ``summary.json`` (a :class:`~pymorembs.job.summary.JobSummary`),
``*/error.csv``, ``*/error_estimate.csv`` and ``*/reduced.npz`` of the run's folder: the table
and curves of every reduction, a shape function on the opened model's scene (with its von Mises
stress at the scene's nodes for a body with solid elements), the mass-weighted
MAC between two bases and the files written. The bases and the run body's mass matrix are read
and built once per run.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

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


class RunResults:
    """What the page shows of the last finished run of ``runs`` on the body of ``model``."""

    def __init__(self, model: OpenedModel, runs: RunController) -> None:
        self.model = model
        self.runs = runs
        self._bases: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        self._body: tuple[str, ElasticBody] | None = None  # (run folder, its body)
        # (run folder, the nodal stress operator on the scene's nodes; None without solids)
        self._stress: tuple[str, StressOperator | None] | None = None

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
