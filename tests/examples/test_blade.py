"""The built-in rotating blade (issue #15 item 6) against beam theory and its own definition."""

from __future__ import annotations

import numpy as np
import pytest

from pymorembs.errors import UserError
from pymorembs.examples import build_example
from pymorembs.io.native import read_body_h5
from pymorembs.job.cli import main
from pymorembs.preparation import Frame, prepare
from pymorembs.reduction.modal import eigenmodes

E, RHO, B, H, L = 2.1e11, 7850.0, 0.04, 0.01, 1.0
BETA1 = 1.875104068711961  # first root of cos(b) cosh(b) = -1


def euler_bernoulli_hz(inertia: float, length: float = L) -> float:
    """First clamped-free bending frequency of a uniform beam (Hz)."""
    return BETA1**2 / (2 * np.pi * length**2) * np.sqrt(E * inertia / (RHO * B * H))


def frequencies(body, count: int = 4) -> np.ndarray:
    values, _ = eigenmodes(prepare(body, Frame("none")).system, count, 1.0)
    return np.sqrt(values) / (2 * np.pi)


@pytest.fixture(scope="module")
def blade():
    return build_example("blade")


def test_geometry_mass_and_clamping(blade):
    assert blade.total_mass() == pytest.approx(RHO * L * B * H, rel=1e-12)
    np.testing.assert_allclose(blade.node_position(1), [1.0, 0.0, 0.0])
    np.testing.assert_allclose(blade.node_position(2), [0.0, 0.0, 0.0])
    low, high = blade.coordinates.min(axis=0), blade.coordinates.max(axis=0)
    np.testing.assert_allclose(low, [0.0, -B / 2, -H / 2], atol=1e-15)
    np.testing.assert_allclose(high, [L, B / 2, H / 2], atol=1e-15)
    root = np.flatnonzero(np.abs(blade.coordinates[:, 0]) < 1e-12)
    fixed_nodes = np.unique(blade.dofs.nodes[blade.fixed])
    np.testing.assert_array_equal(np.sort(fixed_nodes), np.sort(blade.node_ids[root]))
    assert blade.fixed.size == 3 * root.size


def test_bending_frequencies_within_one_percent_of_beam_theory(blade):
    f = frequencies(blade)
    flap, edge = euler_bernoulli_hz(B * H**3 / 12), euler_bernoulli_hz(H * B**3 / 12)
    assert f[0] == pytest.approx(flap, rel=1e-2)
    assert f[1] == pytest.approx(edge, rel=1e-2)
    assert f[2] == pytest.approx(6.2669 * flap, rel=1e-2)  # second flapwise, (4.6941 / 1.8751)²


def test_hub_radius_moves_the_blade_only():
    body = build_example("blade", hub_radius=0.5, elements=8)
    near = build_example("blade", elements=8)
    shift = np.array([0.5, 0.0, 0.0])
    np.testing.assert_allclose(body.coordinates, near.coordinates + shift, atol=1e-15)
    difference = abs(body.stiffness - near.stiffness).max()
    assert difference <= 1e-9 * abs(near.stiffness).max()  # rounding of the shifted geometry
    np.testing.assert_allclose(frequencies(body), frequencies(near), rtol=1e-6)


def test_bad_options_are_user_errors():
    with pytest.raises(UserError, match="blade: hub_radius must be >= 0"):
        build_example("blade", hub_radius=-1.0)
    with pytest.raises(UserError, match="blade: elements must be a whole number >= 4"):
        build_example("blade", elements=2)
    with pytest.raises(UserError, match="example blade has no option 'dofs'"):
        build_example("blade", dofs=1000)


def test_cli_writes_the_blade(tmp_path, capsys):
    assert (
        main(["example", "blade", "--hub-radius", "0.2", "--elements", "6", "--out", str(tmp_path)])
        == 0
    )
    body = read_body_h5(tmp_path / "model.h5")
    assert body.name == "blade" and body.coordinates[:, 0].min() == pytest.approx(0.2)
    assert "blade:" in capsys.readouterr().out
