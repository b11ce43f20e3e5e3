"""The outer surface of element meshes (pymorembs.surface) against geometry done by hand."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mesh_checks import enclosed_volume, is_closed_and_consistent
from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.io.native import read_body_h5, write_body_h5
from pymorembs.surface import Surface, outer_surface

# Unit cube, corners in the Abaqus C3D8 order.
CUBE = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)
# Mid-edge nodes of the C3D20 order: edges 1-2, 2-3, 3-4, 4-1, 5-6, 6-7, 7-8, 8-5, 1-5 ... 4-8.
HEX20_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
               (0, 4), (1, 5), (2, 6), (3, 7)]  # fmt: skip


def points_of(surface: Surface, node_ids: np.ndarray, coordinates: np.ndarray) -> np.ndarray:
    """Corner coordinates of every triangle, shape (n, 3, 3)."""
    order = np.argsort(node_ids)
    return coordinates[order[np.searchsorted(node_ids, surface.triangles, sorter=order)]]


def test_a_hex20_cube_is_36_triangles_over_its_20_nodes_enclosing_volume_one():
    coordinates = np.vstack([CUBE, [(CUBE[a] + CUBE[b]) / 2 for a, b in HEX20_EDGES]])
    ids = np.arange(101, 121)
    surface = outer_surface([("hex20", ids[None])], ids, coordinates)
    assert surface.triangles.shape == (36, 3)
    assert np.array_equal(surface.node_ids, ids)
    assert is_closed_and_consistent(surface.triangles)
    assert enclosed_volume(points_of(surface, ids, coordinates)) == pytest.approx(1.0, rel=1e-14)


def test_two_hex8_share_a_face_that_is_inside_even_when_one_is_left_handed():
    coordinates = np.vstack([CUBE, CUBE[4:] + np.array([0.0, 0.0, 1.0])])
    ids = np.arange(1, 13)
    lower = ids[:8]
    upper = ids[[4, 5, 6, 7, 8, 9, 10, 11]][[1, 0, 3, 2, 5, 4, 7, 6]]  # mirrored node order
    surface = outer_surface([("hex8", np.array([lower, upper]))], ids, coordinates)
    assert surface.triangles.shape == (20, 3)  # 10 outer quads
    assert is_closed_and_consistent(surface.triangles)
    assert enclosed_volume(points_of(surface, ids, coordinates)) == pytest.approx(2.0, rel=1e-14)


def test_a_tet10_with_curved_free_edges_is_closed_and_outward():
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
    coordinates = np.vstack([corners, [(corners[a] + corners[b]) / 2 for a, b in edges]])
    ids = np.arange(10)
    surface = outer_surface([("tet10", ids[None])], ids, coordinates)
    assert surface.triangles.shape == (16, 3)
    assert is_closed_and_consistent(surface.triangles)
    assert enclosed_volume(points_of(surface, ids, coordinates)) == pytest.approx(1 / 6, rel=1e-14)


def test_shells_are_their_own_faces_and_beams_are_segments():
    ids = np.arange(1, 10)
    coordinates = np.c_[np.arange(9.0), np.zeros(9), np.zeros(9)]
    surface = outer_surface(
        [("quad8", ids[None, :8]), ("line3", np.array([[7, 8, 9]])), ("beam2", [[1, 9]])],
        ids,
        coordinates,
    )
    assert surface.triangles.shape == (6, 3)
    assert surface.lines.tolist() == [[7, 8], [8, 9], [1, 9]]
    assert "quad8" in surface.source and "line3" in surface.source


def test_rack_solid_skin_is_closed_and_encloses_the_volume_its_mass_matrix_holds():
    body = build_example("rack-solid")
    surface = body.surface
    assert surface is not None and is_closed_and_consistent(surface.triangles)
    ux = (body.dofs.directions == 0).astype(float)
    volume = ux @ (body.mass @ ux) / 7850.0  # total mass / density
    # Flat triangles cut the curved hole walls a little: the skin holds slightly less.
    enclosed = enclosed_volume(points_of(surface, body.node_ids, body.coordinates))
    assert 0.99 * volume < enclosed < volume


def test_the_surface_travels_through_the_native_file(tmp_path):
    body = build_example("rack-beams")
    assert body.surface is not None and body.surface.lines.shape[0] > 0
    write_body_h5(body, tmp_path / "model.h5")
    back = read_body_h5(tmp_path / "model.h5")
    assert np.array_equal(back.surface.lines, body.surface.lines)
    assert np.array_equal(back.surface.triangles, body.surface.triangles)
    assert back.surface.source == body.surface.source


@pytest.mark.parametrize(
    ("blocks", "message"),
    [
        ([("hex27", np.zeros((1, 27), int))], "unknown element kind 'hex27'"),
        ([("tet4", np.zeros((1, 3), int))], "tet4 elements need 4 node ids"),
        ([("tet4", np.array([[1, 2, 3, 99]]))], "element node 99 is not a node"),
    ],
)
def test_bad_elements_are_refused_in_one_line(blocks, message):
    with pytest.raises(UserError, match=message):
        outer_surface(blocks, np.array([1, 2, 3, 4]), np.zeros((4, 3)))


def test_a_body_refuses_a_surface_over_nodes_it_does_not_have():
    body = build_example("rack-beams")
    with pytest.raises(UserError, match="not nodes of the body"):
        replace(body, surface=Surface(np.array([[1, 2, 123456]]), np.zeros((0, 2))))
