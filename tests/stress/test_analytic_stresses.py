"""Stresses of finite-element solutions against closed forms (issue #29 item 1).

Meshes built in Python (box_meshes.py); the stiffness assembled from the same elements, the
static solution by a sparse direct solve. References:

- a cantilever under a tip force (Euler-Bernoulli, exact for the bending stress of the elastic
  solution away from the ends): ``sigma_xx = -P (L - x) (y - h/2) / I``;
- Kirsch's infinite plate with a circular hole under uniaxial tension ``sigma_0`` in x, plane
  stress: a quarter annulus ``a <= r <= 8 a``, thin (``t = a / 10``), with Kirsch's
  displacements imposed at ``r = 8 a`` and symmetry on the other cuts, so the exact solution is
  Kirsch's field itself: ``sigma_xx = 3 sigma_0`` at the top of the hole, ``sigma_yy =
  -sigma_0`` at its side.

Tolerances (relative to the largest stress of the section, or to ``sigma_0``; the measured
figures are in docs/stresses.md): cantilever at x = 0.3, 0.5, 0.7 L, hex20 1e-4 at the nodes
and 5e-3 at the integration points, hex20r 5e-4, tet10 2e-2; Kirsch's factor 3 within 1 % at
the hole's top, the whole field within 5 % (hex20) and 7 % (tet10) of sigma_0 at the nodes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from box_meshes import box_mesh, solid_body

import pymorembs as pm
from pymorembs.preparation import Frame, Port, add_interface_node, prepare
from pymorembs.preparation.interface import InterfaceSpec

E, NU = 2.1e11, 0.3


# ----------------------------------------------------------------------------- cantilever
@pytest.mark.parametrize(
    ("kind", "nodes_tolerance", "points_tolerance"),
    [("hex20", 1e-4, 5e-3), ("tet10", 2e-2, 2e-2), ("hex20r", 5e-4, 5e-4)],
)
def test_cantilever_bending_stress(kind, nodes_tolerance, points_tolerance):
    length, height, width, force = 1.0, 0.1, 0.05, 1000.0
    counts = (20, 4, 2)
    points, connectivity = box_mesh(kind, counts, (length, height, width))
    body = solid_body(kind, points, connectivity, E, NU)
    x = body.coordinates[:, 0]
    clamp = np.flatnonzero(np.isclose(x, 0.0))
    body = replace(body, fixed=(3 * clamp[:, None] + np.arange(3)).ravel())
    tip = tuple(body.node_ids[np.isclose(x, length)])
    node = 10**6  # a rigid interface node at the tip's centre, as a job couples a joint
    coupled = add_interface_node(body, InterfaceSpec(node, (length, height / 2, width / 2), tip))
    prepared = prepare(coupled, Frame("none"), inputs=[Port(node, "uy")])
    u = force * prepared.expand(prepared.static_response)[:, 0]
    inertia = width * height**3 / 12
    for location, tolerance in (("nodes", nodes_tolerance), ("integration", points_tolerance)):
        op = pm.stress_operator(prepared.body, location=location)
        sxx, at = op(u)[:, 0], op.coordinates
        for section in (0.3, 0.5, 0.7):
            band = np.abs(at[:, 0] - section) <= (1e-9 if location == "nodes" else 0.025)
            expected = -force * (length - at[band, 0]) * (at[band, 1] - height / 2) / inertia
            error = np.abs(sxx[band] - expected).max() / np.abs(expected).max()
            assert error < tolerance, (location, section, error)


# ---------------------------------------------------------------------------------- Kirsch
A, SIGMA0 = 1.0, 1.0
MU, KAPPA = E / (2 * (1 + NU)), (3 - NU) / (1 + NU)  # plane stress


def kirsch_displacement(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r, t = np.hypot(x, y), np.arctan2(y, x)
    c = SIGMA0 * A / (8 * MU)
    ux = c * (r / A * (KAPPA + 1) * np.cos(t)
              + 2 * A / r * ((1 + KAPPA) * np.cos(t) + np.cos(3 * t))
              - 2 * (A / r) ** 3 * np.cos(3 * t))  # fmt: skip
    uy = c * (r / A * (KAPPA - 3) * np.sin(t)
              + 2 * A / r * ((1 - KAPPA) * np.sin(t) + np.sin(3 * t))
              - 2 * (A / r) ** 3 * np.sin(3 * t))  # fmt: skip
    return ux, uy


def kirsch_stress(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``(sigma_xx, sigma_yy, sigma_xy)`` stacked on the first axis."""
    r, t = np.hypot(x, y), np.arctan2(y, x)
    q2, q4 = (A / r) ** 2, (A / r) ** 4
    sxx = 1 - q2 * (1.5 * np.cos(2 * t) + np.cos(4 * t)) + 1.5 * q4 * np.cos(4 * t)
    syy = -q2 * (0.5 * np.cos(2 * t) - np.cos(4 * t)) - 1.5 * q4 * np.cos(4 * t)
    sxy = -q2 * (0.5 * np.sin(2 * t) + np.sin(4 * t)) + 1.5 * q4 * np.sin(4 * t)
    return SIGMA0 * np.array([sxx, syy, sxy])


def test_the_kirsch_displacements_give_the_kirsch_stresses():
    """The two closed forms belong together (central differences, plane-stress Hooke)."""
    x, y, h = np.array([1.3, 0.2, 4.0]), np.array([0.7, 1.1, 2.5]), 1e-6
    dx = (np.array(kirsch_displacement(x + h, y)) - kirsch_displacement(x - h, y)) / (2 * h)
    dy = (np.array(kirsch_displacement(x, y + h)) - kirsch_displacement(x, y - h)) / (2 * h)
    scale = E / (1 - NU**2)
    stress = [scale * (dx[0] + NU * dy[1]), scale * (dy[1] + NU * dx[0]), MU * (dx[1] + dy[0])]
    assert np.allclose(stress, kirsch_stress(x, y), atol=1e-7)


@pytest.mark.parametrize(("kind", "field_tolerance"), [("hex20", 0.05), ("tet10", 0.07)])
def test_plate_with_a_hole_has_kirsch_stresses(kind, field_tolerance):
    outer, thickness, counts = 8.0 * A, 0.1 * A, (12, 12, 1)
    logical, connectivity = box_mesh(kind, counts, (1.0, 1.0, thickness))
    radius = A * (outer / A) ** logical[:, 0]  # graded towards the hole
    angle = 0.5 * np.pi * logical[:, 1]
    points = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), logical[:, 2]])
    body = solid_body(kind, points, connectivity, E, NU)
    u, known = np.zeros(points.shape), np.zeros(points.shape, dtype=bool)
    rim = np.isclose(logical[:, 0], 1.0)
    u[rim, 0], u[rim, 1] = kirsch_displacement(points[rim, 0], points[rim, 1])
    known[rim, :2] = True
    known[np.isclose(logical[:, 1], 0.0), 1] = True  # y = 0: symmetry
    known[np.isclose(logical[:, 1], 1.0), 0] = True  # x = 0: symmetry
    known[np.isclose(logical[:, 2], 0.0), 2] = True  # mid-plane
    u, known = u.ravel(), known.ravel()
    k = body.stiffness.tocsr()
    free, given = np.flatnonzero(~known), np.flatnonzero(known)
    u[free] = spla.spsolve(k[free][:, free].tocsc(), -(k[free][:, given] @ u[given]))
    op = pm.stress_operator(body, location="nodes")
    stress, at = op(u), op.coordinates
    top = np.isclose(at[:, 0], 0.0) & np.isclose(at[:, 1], A)
    side = np.isclose(at[:, 1], 0.0) & np.isclose(at[:, 0], A)
    assert np.allclose(stress[top, 0], 3.0 * SIGMA0, rtol=1e-2)  # Kirsch's factor 3
    assert np.allclose(stress[side, 1], -SIGMA0, rtol=field_tolerance)
    error = np.abs(stress[:, [0, 1, 3]] - kirsch_stress(at[:, 0], at[:, 1]).T).max()
    assert error < field_tolerance * SIGMA0
