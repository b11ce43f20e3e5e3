"""The routes of the app's HTTP API: one table of (method, path) -> handler.

A handler is a function of the :class:`~pymorembs.job.app.application.App` and the
:class:`Request` (query, JSON body, the name after a path prefix); what it returns is sent as
JSON, or as a file (:class:`FileReply`) or bytes (:class:`BytesReply`). Errors are
``{"error": "one line"}``: a :class:`~pymorembs.errors.PymorembsError` or a malformed request
with status 400, :class:`NotFound` with 404, a bug of the server with 500
(:class:`~pymorembs.job.app.server.Handler`). ``docs/app.md`` lists the same routes (a test
holds the two together).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pymorembs.errors import PymorembsError
from pymorembs.examples import EXAMPLES, OPTIONS
from pymorembs.export import DEFAULT_EXPORTS, EXPORT_KINDS
from pymorembs.job.app.application import App
from pymorembs.job.shape import job_schema
from pymorembs.methods import METHODS, option_fields
from pymorembs.report import viewer_script

#: The page's own files (``page.html``, its scripts and style).
STATIC = Path(__file__).parent / "static"
#: The end of a path that stands for any name after its prefix (``/files/<name>``).
NAME = "<name>"


class NotFound(Exception):
    """No such file: answered with status 404 and the message."""


@dataclass(frozen=True)
class Request:
    """What a handler gets of a request.

    Attributes
    ----------
    query : dict
        The query string's values by key (the last one of a repeated key).
    body : dict
        The POST body (a JSON object; ``{}`` for GET).
    name : str
        The rest of the path after a prefix route's prefix (``/files/<name>``), unquoted.
    """

    query: dict[str, str] = field(default_factory=dict)
    body: dict[str, Any] = field(default_factory=dict)
    name: str = ""


@dataclass(frozen=True)
class FileReply:
    """A file to send (``download``: as an attachment)."""

    path: Path
    download: bool = False


@dataclass(frozen=True)
class BytesReply:
    """Bytes to send with their content type."""

    data: bytes
    kind: str


@dataclass(frozen=True)
class Route:
    """One route: ``method`` and ``path`` (a path ending in ``<name>`` is a prefix), the
    ``handler`` and what it answers (``what``, one line of the route list)."""

    method: str
    path: str
    handler: Callable[[App, Request], Any]
    what: str


def _page(app: App, request: Request) -> FileReply:
    return FileReply(STATIC / "page.html")


def _viewer(app: App, request: Request) -> BytesReply:
    return BytesReply(viewer_script().encode(), "text/javascript")


def _static(app: App, request: Request) -> FileReply:
    return FileReply(STATIC / Path(request.name).name)


def _run_file(app: App, request: Request) -> FileReply:
    try:
        return FileReply(app.results.file(request.name), download=True)
    except PymorembsError as exc:
        raise NotFound(str(exc)) from None


def stress_history(app: App, request: Request) -> dict[str, Any]:
    """The history at the hot spot of ``point`` or nearest to the scene node ``node``
    (:meth:`~pymorembs.job.app.results.RunResults.stress_history`)."""
    node = request.query.get("node")
    return app.results.stress_history(
        request.query.get("point"),
        None if node is None else int(node),
        request.query.get("components") == "1",
    )


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


ROUTES = (
    Route("GET", "/", _page, "the page"),
    Route("GET", "/index.html", _page, "the page"),
    Route("GET", f"/static/{NAME}", _static, "the page's scripts (ES modules) and style"),
    Route("GET", "/viewer.js", _viewer,
          "the 3D viewer of the HTML report (:func:`~pymorembs.report.viewer_script`)"),
    Route("GET", "/api/schema", lambda app, r: job_schema(),
          "every table of a job, its keys and every list of kinds "
          "(:func:`~pymorembs.job.shape.job_schema`): the page's forms"),
    Route("GET", "/api/methods", lambda app, r: methods(),
          "every method's options, from the method registry"),
    Route("GET", "/api/examples", lambda app, r: examples(),
          "the built-in models and their options"),
    Route("GET", "/api/exports", lambda app, r: exports(),
          "the files a job can write, and the default ones (``[export]``)"),
    Route("GET", "/api/state", lambda app, r: app.state(),
          "the job, its TOML text and check, the model, the run, the view's decorations"),
    Route("POST", "/api/open", lambda app, r: app.open(r.body),
          '``{"example": name, "options": {...}}`` or ``{"path": file}`` (with ``"format"``)'),
    Route("GET", "/api/scene", lambda app, r: app.model.scene_json(),
          "the opened body for the 3D view (:func:`~pymorembs.report.body_scene`)"),
    Route("GET", "/api/facts", lambda app, r: app.model.facts(),
          "dofs, nodes, the lowest eigenfrequencies (computed once)"),
    Route("POST", "/api/pick", lambda app, r: app.pick(r.body),
          '``{"triangle": t}`` or ``{"node": row}``: the smooth surface patch there and its '
          "selection for ``[[interface]]``"),
    Route("POST", "/api/select", lambda app, r: app.select(r.body),
          '``{"cylinder": {...}, "box": {...}, "nodes": [...]}``: node rows'),
    Route("POST", "/api/job", lambda app, r: app.edit(r.body.get("job")),
          '``{"job": {...}}``: the new job; its TOML and check'),
    Route("POST", "/api/run", lambda app, r: app.start(),
          "run the job (``pymorembs reduce`` in a child process)"),
    Route("GET", "/api/status", lambda app, r: app.runs.status(), "progress of the run"),
    Route("POST", "/api/cancel", lambda app, r: app.runs.cancel(), "end the run"),
    Route("GET", "/api/results", lambda app, r: app.results.table(),
          "error curves, estimators, eigenfrequencies of every reduction"),
    Route("GET", "/api/shape",
          lambda app, r: app.results.shape(r.query["reduction"], int(r.query.get("k", 0))),
          "``?reduction=name&k=3``: shape function k on the scene's nodes"),
    Route("GET", "/api/hot_spots", lambda app, r: app.results.hot_spots(),
          "the hot spots of the last run's stress histories and their nearest scene nodes"),
    Route("GET", "/api/stress_history", lambda app, r: stress_history(app, r),
          "``?point=label`` or ``?node=row`` (the nearest hot spot), ``&components=1``: the "
          "stress at a hot spot over time, every body of every time check"),
    Route("GET", "/api/mac", lambda app, r: app.results.mac(r.query["a"], r.query["b"]),
          "``?a=name&b=name``: mass-weighted MAC between the two bases"),
    Route("POST", "/api/save", lambda app, r: app.editor.save(r.body),
          '``{"path": "job.toml"}``: write the job file'),
    Route("GET", f"/files/{NAME}", _run_file, "a file of the last run's output folder"),
)  # fmt: skip


def find_route(method: str, path: str) -> tuple[Route, str] | None:
    """The route of ``method`` and ``path`` and the name after its prefix ('' for a route
    without one); None when there is none."""
    for route in ROUTES:
        if route.method != method:
            continue
        if route.path == path:
            return route, ""
        prefix = route.path.removesuffix(NAME)
        if prefix != route.path and path.startswith(prefix):
            return route, path[len(prefix) :]
    return None


def route_list(routes: tuple[Route, ...] = ROUTES) -> str:
    """The routes as the reStructuredText table of this module's docstring."""
    width = max(len(route.method) + len(route.path) for route in routes) + 7
    rule = "=" * width + "  " + "=" * 60
    rows = [f"``{r.method:<4} {r.path}``".ljust(width) + "  " + r.what for r in routes]
    return "\n".join([rule, *rows, rule])


__doc__ = f"{__doc__}\nThe routes:\n\n{route_list()}\n"
