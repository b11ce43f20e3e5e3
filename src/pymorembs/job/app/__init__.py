"""``pymorembs app``: a local web page that edits, runs and compares reduction jobs.

The page is a job editor (paper Fig. 1 and Fig. 8): open a model, look at it in 3D, pick the
interface nodes on its surface (or give a cylinder or a box), choose frame, inputs, outputs and
the band, add reductions with the options of the method registry; the job file it builds is
shown as it changes, saved on request and run exactly as ``pymorembs reduce`` runs it. The
results -- error curves, estimators, eigenfrequencies, MAC between bases, shape functions --
come from the run's own output folder. See ``docs/app.md``.

* :mod:`~pymorembs.job.app.application` -- :class:`App`, the composition of the four objects
  below (open a model or job file, the page's state, a run of the edited job);
* :mod:`~pymorembs.job.app.opened_model` -- the opened body, its scene and facts, picking, the
  3D view's decorations of the job;
* :mod:`~pymorembs.job.app.editor` -- the job being edited: draft, TOML text, the parsed job;
* :mod:`~pymorembs.job.app.selection` -- node selections (a picked hole as a cylinder and box);
* :mod:`~pymorembs.job.app.runs` -- the runs of the job, one at a time, in the work folder;
* :mod:`~pymorembs.job.app.runner` -- a run of the job in a child process (progress, cancel);
* :mod:`~pymorembs.job.app.results` -- results, shapes and MAC of the last finished run;
* :mod:`~pymorembs.job.app.routes` -- the table of the HTTP API's routes and their handlers;
* :mod:`~pymorembs.job.app.server` -- the HTTP server; ``static/`` the page and its ES modules.
"""

from __future__ import annotations

import shutil
import sys
import threading
import webbrowser
from pathlib import Path

from pymorembs.errors import UserError
from pymorembs.job.app.application import DEFAULT_EXAMPLE, App
from pymorembs.job.app.server import make_server

__all__ = ["DEFAULT_PORT", "App", "make_server", "serve"]

#: The port ``pymorembs app`` listens on unless ``--port`` says otherwise.
DEFAULT_PORT = 8765


def serve(
    model: str | Path | None = None,
    port: int = DEFAULT_PORT,
    open_browser: bool = True,
    workdir: Path | None = None,
    format: str | None = None,
) -> int:
    """Serve the app on http://127.0.0.1:port until interrupted; return the exit code.

    Parameters
    ----------
    model : path, optional
        A model file (any format :func:`pymorembs.read` knows) or a job file (``.toml``) to
        open; default the built-in rack-solid (35,000 dofs, bare mesh, no interface yet).
    port : int
        TCP port on 127.0.0.1.
    open_browser : bool
        Open the page in the default browser.
    workdir : Path, optional
        Where the runs write their job files and results (default: a temporary folder).
    format : str, optional
        The model file's format (``pymorembs.io.formats.FORMATS``); default told from the
        content.

    Raises
    ------
    UserError
        A model path that does not exist or cannot be read, or a port in use; raised before
        the server starts.
    """
    if model is not None and not Path(model).exists():
        raise UserError(f"{model}: no such file")
    app = App(workdir)
    try:
        _serve_app(app, model, port, open_browser, format)
    finally:
        if workdir is None and app.runs.runs == 0:  # leave no empty temporary folder behind
            shutil.rmtree(app.workdir, ignore_errors=True)
    return 0


def _serve_app(
    app: App, model: str | Path | None, port: int, open_browser: bool, format: str | None
) -> None:
    """Serve ``app`` until interrupted (the body of :func:`serve`)."""
    server = make_server(app, port)
    try:
        app.open({"path": str(model), "format": format} if model is not None else DEFAULT_EXAMPLE)
        url = f"http://127.0.0.1:{server.server_address[1]}/"
        print(f"pymorembs app: {url} (runs in {app.workdir}); Ctrl-C ends it", flush=True)
        if open_browser:
            threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
        try:
            server.serve_forever()
        except KeyboardInterrupt:
            sys.stderr.write("pymorembs app: stopped\n")
        finally:
            app.runs.cancel()
    finally:
        server.server_close()
