"""The app's shape view of a solid body gives the shape's von Mises stress (issue #29 item 2):
``/api/shape`` against the stress operator applied to the run's ``reduced.npz`` here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_app import call, run_to_the_end, server  # noqa: F401 (the fixture)

from pymorembs import example
from pymorembs.export import nodes_operator, von_mises_at
from pymorembs.stress import stress_operator, von_mises


def test_von_mises_at_nodes_is_the_operators_there_and_none_without_solids():
    blade = example("blade", elements=4)
    vectors = np.random.default_rng(1).normal(size=(blade.n_dof, 2))
    nodes = np.array([1, 2, 999_999, *blade.node_ids[::7]])  # 999999: no such node
    got = von_mises_at(nodes_operator(blade, nodes), vectors, nodes)
    op = stress_operator(blade, location="nodes")
    every = von_mises(op(vectors), axis=1)
    for i, node in enumerate(nodes):
        at = np.flatnonzero(op.node_ids == node)
        assert np.allclose(got[i], every[at[0]] if at.size else 0.0, rtol=1e-12, atol=0)
    assert nodes_operator(example("rack-beams"), np.array([1])) is None


@pytest.mark.slow
def test_the_shape_view_of_a_solid_body_gives_its_von_mises_stress(server):  # noqa: F811
    _, base = server
    status, reply = call(base, "/api/open", {"example": "blade", "options": {"elements": 4}})
    assert status == 200, reply
    job = reply["job"] | {
        "frame": {"type": "none"},
        "inputs": [{"node": 1, "directions": "uy uz"}],
        "band": {"f_min_hz": 0, "f_max_hz": 100, "points": 200},
        "reduction": [{"name": "krylov", "method": "krylov", "expansion_points_hz": [0, 60],
                       "order": 8}],
    }  # fmt: skip
    done = run_to_the_end(base, job)
    status, shape = call(base, "/api/shape?reduction=krylov&k=1")
    assert status == 200, shape
    with np.load(Path(done["out"]) / "krylov" / "reduced.npz") as data:
        V = data["V"]
    scene_ids = np.asarray(call(base, "/api/scene")[1]["node_ids"])
    blade = example("blade", elements=4)  # the run's body: no interfaces added
    op = stress_operator(blade, location="nodes")
    expected = von_mises(op(V[:, 1]))
    rows = np.searchsorted(op.node_ids, scene_ids)
    got = np.asarray(shape["von_mises"])
    assert got.shape == scene_ids.shape
    assert np.allclose(got, expected[rows], rtol=1e-3, atol=0)  # 4 digits in the reply
