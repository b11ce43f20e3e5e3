"""The app's stress at a hot spot over time (issue #29 item 2, "pick a point, see sigma(t)"):
``/api/hot_spots`` and ``/api/stress_history`` against the run folder's ``stress_history.npz``
and the summary's peaks and ranges, the nearest hot spot of a picked node, and a run without
histories (a note, not an error)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from test_app import call, run_to_the_end, server  # noqa: F401 (the fixture)

from pymorembs import example
from pymorembs.analysis import HISTORY_FILE, StressHistory, histories_from_arrays, history_arrays
from pymorembs.errors import UserError
from pymorembs.export import write_npz
from pymorembs.job.app.opened_model import OpenedModel
from pymorembs.job.app.results import NO_HISTORY, RunResults

#: The blade (4 x 2 x 2 hex20) held at its root (fixed dofs) and by a rigid interface node at
#: its tip, loaded at mid-span (node 1137), stresses at the hot spots of its two root elements.
JOB = {
    "interface": [{"node": 9, "position": [1.0, 0.0, 0.0], "kind": "rigid",
                   "box": {"min": [0.999, -1.0, -1.0], "max": [1.001, 1.0, 1.0]}}],
    "damping": {"kind": "rayleigh", "beta": 1e-6},
    "frame": {"type": "tangent", "node": 9},
    "inputs": [{"node": 1137, "directions": "ux uy uz"}],
    "band": {"f_min_hz": 0, "f_max_hz": 200, "points": 200},
    "reduction": [{"name": "krylov", "method": "krylov", "expansion_points_hz": [0], "order": 8,
                   "export_inaccurate": True}],
    "stress": {"elements": [1, 2]},
    "time_domain": {"clamp_node": 9, "load_node": 1137, "duration_s": 0.02, "step_s": 1e-4},
}  # fmt: skip


def results_of(folder: Path, body=None) -> RunResults:
    """The results of a finished run in ``folder`` (no summary read) on the opened ``body``."""
    model = OpenedModel()
    if body is not None:
        model.show(body)
    results = RunResults(model, runs=None)
    results._summary = lambda: (SimpleNamespace(out=folder), None)
    return results


def test_a_run_without_histories_says_so(tmp_path):
    results = results_of(tmp_path)
    assert results.hot_spots() == {"available": False, "note": NO_HISTORY, "points": [],
                                   "rows": []}  # fmt: skip
    assert results.stress_history(point="n1") == {"available": False, "note": NO_HISTORY}


def test_the_file_round_trips_and_a_node_picks_the_nearest_hot_spot(tmp_path):
    blade = example("blade", elements=4)
    rng = np.random.default_rng(3)
    times = np.linspace(0.0, 0.01, 11)
    points = ("n1", "n2", "e1.ip1")
    where = np.array([blade.node_position(1), blade.node_position(2), [0.1, 0.0, 0.0]])
    full, reduced = (StressHistory(times, rng.normal(size=(11, 18)), points) for _ in range(2))
    checks = {"time_domain": {"step": {"full": full, "krylov": reduced}}}
    write_npz(tmp_path / HISTORY_FILE, history_arrays(checks, where))
    with np.load(tmp_path / HISTORY_FILE) as data:
        back = histories_from_arrays({key: data[key] for key in data.files})
    assert list(back["time_domain"]["step"]) == ["full", "krylov"]
    assert np.array_equal(back["time_domain"]["step"]["krylov"].values, reduced.values)

    results = results_of(tmp_path, blade)
    spots = results.hot_spots()
    assert spots["points"] == list(points) and spots["checks"] == {"time_domain": ["step"]}
    scene = blade.coordinates[blade.node_rows(results.model.scene_ids)]
    for position, row in zip(where, spots["rows"], strict=True):  # the nearest scene node
        assert np.linalg.norm(scene[row] - position) == pytest.approx(
            np.linalg.norm(scene - position, axis=1).min(), abs=1e-15
        )
    # a node near the third point (x = 0.1 m) gives it; its history is the file's
    row = int(np.argmin(np.linalg.norm(scene - [0.12, 0.0, 0.0], axis=1)))
    reply = results.stress_history(node=row, components=True)
    assert reply["point"] == "e1.ip1"
    (case,) = reply["histories"]
    assert case["times"] == times.tolist()
    for body, history in zip(case["bodies"], (full, reduced), strict=True):
        assert body["von_mises"] == history.von_mises[:, 2].tolist()
        assert body["stress"] == history.components[:, 2, :].tolist()
        assert body["peak_von_mises"] == history.von_mises[:, 2].max()
    with pytest.raises(UserError, match="no hot spot 'n7'"):
        results.stress_history(point="n7")
    with pytest.raises(UserError, match="no node 99999 in the view"):
        results.stress_history(node=99999)


@pytest.mark.slow
def test_the_served_history_is_the_run_folders_and_the_summarys(server):  # noqa: F811
    _, base = server
    status, reply = call(base, "/api/open", {"example": "blade", "options": {"elements": 4}})
    assert status == 200, reply
    done = run_to_the_end(base, reply["job"] | JOB, seconds=300)
    out = Path(done["out"])
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert HISTORY_FILE in summary["files"]
    entry = summary["time_domain"]

    status, spots = call(base, "/api/hot_spots")
    assert status == 200 and spots["available"], spots
    assert spots["points"] == entry["stress"]["points"]  # 2 elements x 27 points
    assert len(spots["rows"]) == 54 and spots["checks"] == {"time_domain": ["step", "harmonic"]}
    point = spots["points"][7]
    status, served = call(base, f"/api/stress_history?point={point}&components=1")
    assert status == 200 and served["point"] == point
    with np.load(out / HISTORY_FILE) as data:
        written = histories_from_arrays({key: data[key] for key in data.files})["time_domain"]
    k = spots["points"].index(point)
    for history, case in zip(served["histories"], entry["cases"], strict=True):
        assert (history["check"], history["case"]) == ("time_domain", case["name"])
        bodies = written[case["name"]]
        assert history["times"] == bodies["full"].times.tolist()
        for body in history["bodies"]:  # exactly the file's (JSON keeps every digit)
            assert body["von_mises"] == bodies[body["name"]].von_mises[:, k].tolist()
            assert body["stress"] == bodies[body["name"]].components[:, k, :].tolist()
        full, krylov = history["bodies"]
        assert (full["name"], krylov["name"]) == ("full", "krylov")
        # the summary's peak and range of this hot spot: the full model's, and the reduced one's
        (spot,) = [s for s in case["stress_hot_spots"] if s["point"] == point]
        (row,) = case["reductions"]
        (reduced,) = [s for s in row["stress"]["hot_spots"] if s["point"] == point]
        for got, want in ((full, spot), (krylov, reduced)):
            assert got["peak_von_mises"] == want["peak_von_mises"] > 0
            assert got["range_von_mises"] == want["range_von_mises"]
            assert got["range_abs_max_principal"] == want["range_abs_max_principal"]
        assert max(full["von_mises"]) == spot["peak_von_mises"]
    status, refused = call(base, "/api/stress_history?point=n0")
    assert status == 400 and "no hot spot 'n0'" in refused["error"]
