"""The app's route table (issue #28 item 5): one table of (method, path) -> handler, the same
routes in the module's docstring and in docs/app.md, and the job parsed once per edit."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import pymorembs.job.app.routes as routes
from pymorembs.job.app import App
from pymorembs.job.app.routes import NAME, ROUTES, find_route

ROOT = Path(__file__).resolve().parents[2]
STATIC = ROOT / "src" / "pymorembs" / "job" / "app" / "static"


def table_routes() -> set[tuple[str, str]]:
    return {(route.method, route.path) for route in ROUTES}


def documented_routes(text: str) -> set[tuple[str, str]]:
    """The ``METHOD /path`` in backticks of a text, their query strings left out."""
    found = re.findall(r"`(GET|POST) +(/[^`?\s]*)[^`]*`", text)
    return {(method, path) for method, path in found}


def test_each_route_is_in_the_table_once():
    assert len(table_routes()) == len(ROUTES)
    assert all(route.what and route.path.startswith("/") for route in ROUTES)


def test_the_docstring_lists_the_routes_of_the_table():
    assert documented_routes(routes.__doc__) == table_routes()


def test_docs_app_lists_the_routes_of_the_table():
    text = (ROOT / "docs" / "app.md").read_text(encoding="utf-8")
    section = text.split("\n## The API behind the page\n", 1)[1].split("\n## ", 1)[0]
    assert documented_routes(section) == table_routes()


def test_the_check_of_documented_routes_finds_what_it_is_for():
    text = "| `GET /api/state`, `POST /api/job` | x | `GET /api/mac?a=&b=` `GET  /files/<name>`"
    assert documented_routes(text) == {
        ("GET", "/api/state"),
        ("POST", "/api/job"),
        ("GET", "/api/mac"),
        ("GET", "/files/<name>"),
    }


@pytest.mark.parametrize(
    ("method", "path", "found", "name"),
    [
        ("GET", "/api/state", "/api/state", ""),
        ("POST", "/api/job", "/api/job", ""),
        ("GET", "/files/modal/reduced.npz", f"/files/{NAME}", "modal/reduced.npz"),
        ("GET", "/static/main.js", f"/static/{NAME}", "main.js"),
        ("POST", "/api/state", None, ""),
        ("GET", "/api/job", None, ""),
        ("GET", "/api/nothing", None, ""),
    ],
)
def test_a_request_finds_its_route(method, path, found, name):
    route = find_route(method, path)
    if found is None:
        assert route is None
    else:
        assert route[0].path == found and route[1] == name


def test_the_page_loads_its_script_as_es_modules():
    """page.html loads main.js as a module; every static script is a module of its own."""
    page = (STATIC / "page.html").read_text(encoding="utf-8")
    assert '<script type="module" src="/static/main.js"></script>' in page
    scripts = sorted(path.name for path in STATIC.glob("*.js"))
    assert "app.js" not in scripts and "main.js" in scripts
    for name in scripts:
        text = (STATIC / name).read_text(encoding="utf-8")
        assert re.search(r"^(import|export) ", text, flags=re.M), name


def test_the_job_is_parsed_once_per_edit(tmp_path, monkeypatch):
    """The editor parses the page's job once per edit; the state, a pick, a save and the
    decorations read what it holds (issue #28 item 5: no parse per state)."""
    import pymorembs.job.app.editor as editor

    parsed = []
    parse_job = editor.parse_job

    def counted(data, path):
        parsed.append(path)
        return parse_job(data, path)

    monkeypatch.setattr(editor, "parse_job", counted)
    app = App(tmp_path / "work")
    parsed.clear()  # the new page's job
    state = app.open({"example": "rack-beams"})
    assert len(parsed) == 1 and state["error"] != ""  # no reduction yet
    job = state["job"] | {
        "frame": {"type": "tangent", "node": 2},
        "reduction": [{"name": "m", "method": "modal", "order": 4}],
    }
    assert app.edit(job)["error"] == "" and len(parsed) == 2
    for _ in range(3):
        assert app.state()["decorations"]["frame"] is not None
    assert app.select({"nodes": [1]})["count"] == 1
    app.editor.save({"path": str(tmp_path / "saved.toml")})
    assert len(parsed) == 2
    assert app.editor.job is not None and app.editor.job.frame.node == 2


def test_the_scripts_are_served_as_javascript(tmp_path):
    """A browser runs an ES module only when its MIME type is JavaScript."""
    import threading
    import urllib.request

    from pymorembs.job.app import make_server

    http = make_server(App(tmp_path / "work"), 0)
    threading.Thread(target=http.serve_forever, daemon=True).start()
    try:
        base = f"http://127.0.0.1:{http.server_address[1]}"
        for path in sorted(STATIC.glob("*.js")):
            with urllib.request.urlopen(f"{base}/static/{path.name}", timeout=30) as response:
                assert response.headers["Content-Type"] == "text/javascript"
                assert response.read() == path.read_bytes()
    finally:
        http.shutdown()
        http.server_close()
