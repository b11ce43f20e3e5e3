"""The viewer's scene (pymorembs.report.scene) against the body it was made of."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.preparation import Frame
from pymorembs.preparation.interface import InterfaceSpec, add_interface_node
from pymorembs.report.scene import attached_nodes, body_scene, viewer_script


@pytest.fixture(scope="module")
def blade():
    return build_example("blade", elements=4)


@pytest.fixture(scope="module")
def beams():
    return build_example("rack-beams")


def coordinates_of(body, ids):
    """Coordinates of node ids, looked up one by one."""
    row = {int(n): i for i, n in enumerate(body.node_ids)}
    return np.array([body.coordinates[row[int(n)]] for n in ids])


def test_triangles_and_positions_are_the_bodys_surface(blade):
    scene = body_scene(blade)
    ids = np.array(scene["node_ids"])
    triangles = np.array(scene["triangles"]).reshape(-1, 3)
    assert triangles.min() >= 0 and triangles.max() < ids.size
    assert np.array_equal(ids[triangles], blade.surface.triangles)
    # Only the surface's nodes, not the blade's interior ones.
    assert set(ids.tolist()) == set(blade.surface.node_ids.tolist())
    assert ids.size < blade.n_nodes
    positions = np.array(scene["positions"]).reshape(-1, 3)
    size = np.linalg.norm(np.ptp(blade.coordinates[np.isin(blade.node_ids, ids)], axis=0))
    assert scene["size"] == pytest.approx(size)
    assert np.allclose(positions, coordinates_of(blade, ids), rtol=0, atol=1e-6 * size)
    assert scene["lines"] == [] and scene["shapes"] == [] and scene["frame"] is None


def test_shapes_are_the_basis_translations_node_by_node(beams):
    """rack-beams has six dofs per node: the shapes take ux uy uz only, 0 where a dof lacks."""
    rng = np.random.default_rng(1)
    basis = rng.standard_normal((beams.n_dof, 3))
    basis[:, 2] *= 1e-7  # a small scale: rounding is relative to each shape's peak
    body = replace(beams, name="x")
    scene = body_scene(body, basis=basis, shape_names=["a", "b", "c"], frame=Frame("tangent", 2))
    ids = scene["node_ids"]
    assert [s["name"] for s in scene["shapes"]] == ["a", "b", "c"]
    for k, shape in enumerate(scene["shapes"]):
        expected = np.zeros((len(ids), 3))
        for row, node in enumerate(ids):
            for direction in range(3):
                of_node = beams.dofs.of_node(node)
                index = [i for i in of_node if beams.dofs.directions[i] == direction]
                if index:
                    expected[row, direction] = basis[index[0], k]
        values = np.array(shape["values"]).reshape(-1, 3)
        peak = np.abs(expected).max()
        assert np.allclose(values, expected, rtol=0, atol=6e-4 * peak)
        assert not np.allclose(values, 0)
    lines = np.array(scene["lines"]).reshape(-1, 2)
    assert np.array_equal(np.array(ids)[lines], beams.surface.lines)
    assert scene["triangles"] == []
    assert 2 in ids  # the frame node is kept though no line uses it
    assert scene["frame"]["origin"] == pytest.approx(list(coordinates_of(beams, [2])[0]))
    assert scene["frame"]["axes"] == np.eye(3).tolist()


def test_interfaces_point_at_their_nodes(beams):
    coupled = [int(n) for n in beams.node_ids[10:20]]
    spec = InterfaceSpec(node=1, position=(0.0, 0.0, 0.0), coupled=tuple(coupled))
    scene = body_scene(beams, interfaces=[spec, ("bolt", 2, coupled[:3])])
    ids = np.array(scene["node_ids"])
    first, second = scene["interfaces"]
    assert first["name"] == "interface 1 (rigid)" and ids[first["node"]] == 1
    assert ids[first["coupled"]].tolist() == coupled
    assert second["name"] == "bolt" and ids[second["node"]] == 2
    with pytest.raises(UserError, match="node 424242"):
        body_scene(beams, interfaces=[("x", 424242, coupled)])


def test_a_body_without_surface_is_all_its_nodes(blade):
    bare = replace(blade, surface=None)
    scene = body_scene(bare)
    assert scene["node_ids"] == blade.node_ids.tolist()
    assert scene["triangles"] == [] and scene["lines"] == []
    assert any("points" in note for note in scene["notes"])


def test_caps_and_json(blade):
    basis = np.random.default_rng(2).standard_normal((blade.n_dof, 7))
    scene = body_scene(blade, basis=basis, max_shapes=5)
    assert len(scene["shapes"]) == 5 and scene["shapes_total"] == 7
    assert "5 of 7 shapes" in scene["notes"][-1]
    n = len(scene["node_ids"])
    assert len(body_scene(blade, basis=basis, max_values=2 * 3 * n + 1)["shapes"]) == 2
    text = json.dumps(scene, allow_nan=False, separators=(",", ":"))
    values = json.dumps(scene["shapes"][0]["values"], separators=(",", ":"))
    assert len(values) / (3 * n) < 8  # 4 significant digits print short
    assert json.loads(text) == scene


def test_buckens_frame_at_the_centre_of_gravity(blade):
    # The uniform blade's centre of gravity is the centre of its box (mass from M, not geometry).
    free = replace(blade, fixed=np.zeros(0, dtype=np.int64))
    scene = body_scene(free, frame=Frame("buckens"))
    middle = (blade.coordinates.min(axis=0) + blade.coordinates.max(axis=0)) / 2
    assert scene["frame"]["origin"] == pytest.approx(middle.tolist(), abs=1e-9)
    assert body_scene(free, frame=Frame("none"))["frame"] is None


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"basis": np.zeros((5, 2))}, "expected"),
        ({"basis": "zeros", "shape_names": ["a"]}, "1 shape names for 2 shapes"),
        ({"shape_names": ["a"]}, "without a basis"),
        ({"frame": ([0, 0], None)}, "origin of 3 numbers"),
        ({"frame": {"origin": [0, 0, 0], "axes": np.zeros((3, 3))}}, "zero length"),
        ({"frame": Frame("tangent", 424242)}, "not a node"),
    ],
)
def test_bad_arguments(blade, kwargs, message):
    if isinstance(kwargs.get("basis"), str):
        kwargs = {**kwargs, "basis": np.zeros((blade.n_dof, 2))}
    with pytest.raises(UserError, match=message):
        body_scene(blade, **kwargs)


def test_the_viewer_script_is_there():
    script = viewer_script()
    assert "PymorembsViewer" in script and "</script" not in script.lower()


def test_the_models_own_interface_nodes_are_found():
    """rack-beams: the plate nodes 1 and 2, each on the four rod ends of its plate (z = 4 mm
    and 204 mm); rack-solid: node 2 on the nodes of its hole's wall (radius 15 mm)."""
    beams = build_example("rack-beams")
    found = {node: set(coupled.tolist()) for _, node, coupled in attached_nodes(beams)}
    assert set(found) == {1, 2}
    for node, z in ((1, 0.004), (2, 0.204)):
        ends = beams.node_ids[np.isclose(beams.coordinates[:, 2], z)]
        assert found[node] == set(ends.tolist()) and len(ends) == 4
    solid = build_example("rack-solid", dofs=8000)
    ((name, node, coupled),) = attached_nodes(solid)
    radius = np.hypot(solid.coordinates[:, 0], solid.coordinates[:, 1])
    wall = (np.abs(radius - 0.015) < 1e-9) & (solid.coordinates[:, 2] >= 0.204 - 1e-9)
    assert node == 2 and "node 2" in name
    assert set(coupled.tolist()) == set(solid.node_ids[wall].tolist())


@pytest.mark.parametrize("kind", ["rigid", "distributing", "beams", "springs"])
def test_an_added_interface_node_is_found_with_its_coupled_nodes(blade, kind):
    tip = blade.node_ids[np.isclose(blade.coordinates[:, 0], 1.0)]
    spec = InterfaceSpec(
        node=9, position=(1.01, 0.0, 0.0), coupled=tuple(int(n) for n in tip), kind=kind,
        stiffness=1e6,
    )  # fmt: skip
    body = add_interface_node(blade, spec)
    assert attached_nodes(blade) == []
    ((_, node, coupled),) = attached_nodes(body)
    assert node == 9 and sorted(coupled.tolist()) == sorted(tip.tolist())
