"""The app's state: the opened model, the job being edited, its runs and their results.

:class:`App` composes the four objects the routes (:mod:`~pymorembs.job.app.routes`) work on
and does what takes more than one of them: open a model or a job file (model and editor
together), the page's state, a pick or selection (a new node id beside the job's), and a run
of the edited job.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pymorembs as pm
from pymorembs.errors import UserError
from pymorembs.examples import EXAMPLES
from pymorembs.job.app.editor import JobEditor, default_job, job_file_draft
from pymorembs.job.app.opened_model import OpenedModel
from pymorembs.job.app.results import RunResults
from pymorembs.job.app.runs import RunController
from pymorembs.job.run import load_model
from pymorembs.job.schema import ModelSpec, load_job

#: The model a new page opens when none is given.
DEFAULT_EXAMPLE = {"example": "rack-solid", "options": {"dofs": 35000, "interface": "none"}}


class App:
    """What the page works on; ``workdir`` is the runs' folder (:class:`RunController`).

    Attributes
    ----------
    model : OpenedModel
        The opened body, its scene and facts, picking, the view's decorations.
    editor : JobEditor
        The job being edited: draft, TOML text, the parser's message, the parsed job.
    runs : RunController
        The runs of the job (one at a time) in :attr:`workdir`.
    results : RunResults
        The results of the last finished run.
    """

    def __init__(self, workdir: Path | None = None) -> None:
        self.lock = threading.RLock()  # held while model and job change together
        self.model = OpenedModel()
        self.editor = JobEditor(default_job(DEFAULT_EXAMPLE))
        self.runs = RunController(workdir)
        self.results = RunResults(self.model, self.runs)

    @property
    def workdir(self) -> Path:
        """The folder the runs write into."""
        return self.runs.workdir

    def open(self, request: dict[str, Any]) -> dict[str, Any]:
        """Open a built-in example or a model file (any format ``pymorembs.read`` knows) or a
        job file (its model, and the job into the editor)."""
        draft = None
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
                body = load_model(load_job(path).model)
                draft = job_file_draft(path)
            else:
                fmt = request.get("format") or None
                body = pm.read(path, format=fmt)
                model = {"file": str(path.resolve())}
                if fmt is not None:
                    model["format"] = fmt
        else:
            raise UserError("open: give 'example' or 'path'")
        with self.lock:
            self.model.show(body)
            self.editor.edit(draft if draft is not None else default_job(model))
        return self.state()

    def edit(self, draft: Any) -> dict[str, Any]:
        """Replace the job being edited (the page sends it after every change)."""
        self.editor.edit(draft)
        return self.state()

    def pick(self, request: dict[str, Any]) -> dict[str, Any]:
        """The surface patch at a picked triangle or node (:meth:`OpenedModel.pick`), a new
        node id proposed beside the job's interface nodes."""
        return self.model.pick(request, self.editor.interface_ids())

    def select(self, request: dict[str, Any]) -> dict[str, Any]:
        """The nodes of a selection by numbers (:meth:`OpenedModel.select`), a new node id
        proposed beside the job's interface nodes."""
        return self.model.select(request, self.editor.interface_ids())

    def state(self) -> dict[str, Any]:
        """The job, its TOML text and check, the opened model's sizes, the run's status and
        the view's decorations of the job."""
        editor = self.editor
        with editor.lock:
            draft, text, error, job = editor.draft, editor.text, editor.error, editor.job
        run = self.runs.run
        return {
            "job": draft,
            "toml": text,
            "error": error,
            "model": self.model.summary(),
            "run": None if run is None else run.as_dict(),
            "workdir": str(self.workdir),
            "decorations": self.model.decorations(job, draft),
        }

    def start(self) -> dict[str, Any]:
        """Run the job being edited, if it is valid (one run at a time)."""
        with self.lock:
            return self.runs.start(self.editor.valid)
