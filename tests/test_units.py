"""Unit-system detection (``pymorembs.units``) on the built-in models, in SI and converted."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pymorembs.examples import build_example
from pymorembs.job.cli import main
from pymorembs.preparation import Frame, Port, prepare
from pymorembs.reduction.modal import eigenmodes
from pymorembs.units import SYSTEMS, convert_body, detect_units, frequency_warnings


@pytest.fixture(scope="module")
def beams():
    return build_example("rack-beams")


@pytest.fixture(scope="module")
def solid():
    return build_example("rack-solid", dofs=10000)


def lowest_hz(body, count=3):
    ports = [Port.parse(1, "ux")]
    prepared = prepare(body, Frame("tangent", 2), ports, ports)
    values, _ = eigenmodes(prepared.system, count)
    return np.sqrt(values) / (2 * np.pi)


@pytest.mark.parametrize("model", ["beams", "solid"])
def test_si_models_are_detected_as_si(model, request):
    guess = detect_units(request.getfixturevalue(model))
    assert guess.name == "m-kg-s-N"
    assert guess.plausible and guess.ambiguous == () and guess.warnings == ()
    assert 300 < guess.implied_density < 8000  # steel, partly filled box, kg/m^3


@pytest.mark.parametrize("target", [s.name for s in SYSTEMS[1:]])
@pytest.mark.parametrize("model", ["beams", "solid"])
def test_converted_models_are_detected(model, target, request):
    body = request.getfixturevalue(model)
    converted = convert_body(body, "m-kg-s-N", target)
    guess = detect_units(converted)
    assert guess.name == target
    assert guess.plausible


def test_mm_t_s_conversion_is_exact(beams):
    """lengths x 1e3, masses x 1e-3 (t), translational K in N/mm (x 1e-3), rotational K in
    N mm/rad (x 1e3), rotary inertia in t mm^2 (x 1e3); the same eigenfrequencies (seconds)."""
    mm = convert_body(beams, "m-kg-s-N", "mm-t-s-N")
    assert np.allclose(mm.coordinates, 1e3 * beams.coordinates, rtol=0, atol=1e-12)
    assert mm.total_mass() == pytest.approx(1e-3 * beams.total_mass(), rel=1e-14)
    d = beams.dofs.directions
    i = int(np.flatnonzero(d == 0)[10])  # a translational dof
    r = int(np.flatnonzero(d == 5)[10])  # a rotational dof
    assert mm.stiffness[i, i] == pytest.approx(1e-3 * beams.stiffness[i, i], rel=1e-14)
    assert mm.stiffness[r, r] == pytest.approx(1e3 * beams.stiffness[r, r], rel=1e-14)
    assert mm.mass[r, r] == pytest.approx(1e3 * beams.mass[r, r], rel=1e-14)
    assert mm.stiffness[i, r] == pytest.approx(beams.stiffness[i, r], rel=1e-14)
    assert np.allclose(lowest_hz(mm), lowest_hz(beams), rtol=1e-7)  # cond(K) ~ 5e11
    assert lowest_hz(beams)[0] == pytest.approx(41.57, abs=0.01)


def test_milliseconds_divide_the_frequencies_by_1000(beams):
    ms = convert_body(beams, "m-kg-s-N", "mm-kg-ms-kN")
    assert np.allclose(lowest_hz(ms), 1e-3 * lowest_hz(beams), rtol=1e-9)
    guess = detect_units(ms)
    assert guess.system.frequency_unit == "kHz"


def test_implausible_numbers_give_one_warning(beams):
    heavy = replace(beams, mass=beams.mass * 1e8)  # a density of 3e11 kg/m^3
    guess = detect_units(heavy)
    assert not guess.plausible
    assert len(guess.warnings) == 1
    assert "fit no usual unit system" in guess.warnings[0]
    assert "\n" not in guess.warnings[0]


def test_frequency_warnings(beams):
    si = detect_units(beams)
    assert frequency_warnings(si, (0.0, 1000.0), np.array([41.6, 100.9, 460.4])) == []
    far_above = frequency_warnings(si, (0.0, 1e6), np.array([41.6, 100.9, 460.4]))
    assert len(far_above) == 1 and "more than 100 times every eigenfrequency" in far_above[0]
    far_below = frequency_warnings(si, (0.0, 0.1), np.array([41.6, 100.9]))
    assert len(far_below) == 1 and "below 1/100 of the lowest eigenfrequency" in far_below[0]
    ms = detect_units(convert_body(beams, "m-kg-s-N", "mm-kg-ms-kN"))
    hint = frequency_warnings(ms, (0.0, 1000.0), np.array([0.0416, 0.1009, 0.4604]))
    assert len(hint) == 1 and "mm-kg-ms-kN" in hint[0] and "kHz" in hint[0]


def test_info_and_summary_state_the_unit_system(tmp_path, capsys):
    assert main(["example", "rack-beams", "--out", str(tmp_path / "rack")]) == 0
    capsys.readouterr()
    assert main(["info", str(tmp_path / "rack" / "model.h5"), "--modes", "2"]) == 0
    out = capsys.readouterr().out
    assert "unit system       m-kg-s-N (m, kg, s, N; frequencies in Hz)" in out
    assert main(["info", str(tmp_path / "rack" / "model.h5"), "--modes", "2", "--json"]) == 0
    facts = json.loads(capsys.readouterr().out)
    assert facts["units"]["system"] == "m-kg-s-N" and facts["units"]["plausible"] is True


def straight_beam(n_nodes, direction, section):
    """A 1 m steel beam in SI on the line through the origin along ``direction``."""
    from pymorembs.body import DofTable, ElasticBody
    from pymorembs.elements.beam import assemble_beams

    ids = np.arange(1, n_nodes + 1)
    xyz = np.outer(np.linspace(0.0, 1.0, n_nodes), direction / np.linalg.norm(direction))
    elements = np.column_stack([ids[:-1], ids[1:]])
    k, m = assemble_beams(
        ids, xyz, elements, section, lambda node: 6 * (node - 1) + np.arange(6), n_dof=6 * n_nodes
    )
    dofs = DofTable(np.repeat(ids, 6), np.tile(np.arange(6), n_nodes))
    return ElasticBody(node_ids=ids, coordinates=xyz, dofs=dofs, mass=m, stiffness=k, name="beam")


@pytest.mark.parametrize("n_nodes", [3, 21, 101])
@pytest.mark.parametrize("direction", [(1.0, 0.0, 0.0), (0.3, -0.5, 0.8)])
def test_collinear_steel_beam_in_si_is_si(n_nodes, direction):
    """Issue #16: a 1 m steel beam (nodes on a line) "fit no usual unit system". A 50 mm square
    section: its box gets the section from the rotary inertia about the axis, so the implied
    density is steel's (7,850 kg/m^3, within 10 %: the translational mass diagonal of the
    consistent mass is slightly above rho A L / 3)."""
    from pymorembs.elements.beam import BeamSection

    section = BeamSection.rectangular(0.05, 0.05, E=2.1e11, nu=0.3, rho=7850.0)
    body = straight_beam(n_nodes, np.array(direction), section)
    guess = detect_units(body)
    assert guess.name == "m-kg-s-N" and guess.plausible and guess.warnings == ()
    assert guess.implied_density == pytest.approx(7850.0, rel=0.1)
    for system in SYSTEMS[1:]:
        assert detect_units(convert_body(body, "m-kg-s-N", system.name)).name == system.name


def test_planar_and_rotation_free_line_models_are_judged():
    """A plane frame of beams, and a line of nodes without rotational dofs (a chain of bars):
    no rotary inertia to read the section from, the node spacing stands for it."""
    from dataclasses import replace as with_

    import scipy.sparse as sp

    from pymorembs.body import DofTable
    from pymorembs.elements.beam import BeamSection

    section = BeamSection.rectangular(0.05, 0.05, E=2.1e11, nu=0.3, rho=7850.0)
    body = straight_beam(21, np.array([1.0, 0.0, 0.0]), section)
    keep = np.flatnonzero(body.dofs.directions < 3)
    bars = with_(
        body,
        dofs=DofTable(body.dofs.nodes[keep], body.dofs.directions[keep]),
        mass=sp.csr_matrix(body.mass[keep][:, keep]),
        stiffness=sp.csr_matrix(body.stiffness[keep][:, keep]),
    )
    guess = detect_units(bars)
    assert guess.name == "m-kg-s-N" and guess.plausible and guess.warnings == ()
    # a flat frame: two such beams side by side in the x-y plane, 0.5 m apart
    frame = with_(
        body,
        node_ids=np.concatenate([body.node_ids, body.node_ids + 100]),
        coordinates=np.vstack([body.coordinates, body.coordinates + np.array([0.0, 0.5, 0.0])]),
        dofs=DofTable(
            np.concatenate([body.dofs.nodes, body.dofs.nodes + 100]),
            np.concatenate([body.dofs.directions, body.dofs.directions]),
        ),
        mass=sp.block_diag([body.mass, body.mass], format="csr"),
        stiffness=sp.block_diag([body.stiffness, body.stiffness], format="csr"),
    )
    guess = detect_units(frame)
    assert guess.name == "m-kg-s-N" and guess.plausible and guess.warnings == ()


@pytest.mark.parametrize(
    ("band", "suspect"),
    [
        ((0.0, 2 * np.pi * 1000), "f_max_hz = 6283.19 is 2 pi x 1000"),
        ((0.0, 6283.0), "f_max_hz = 6283 is 2 pi x 1000"),
        ((0.0, 628.3), "f_max_hz = 628.3 is 2 pi x 100"),
        ((2 * np.pi * 10, 3141.59), "f_min_hz = 62.8319 is 2 pi x 10, f_max_hz = 3141.59"),
    ],
)
def test_a_band_in_rad_per_s_warns(band, suspect):
    """Issue #16: a band in rad/s ran silently. 2 pi times a round number warns, once."""
    from pymorembs.units import band_unit_warnings

    [line] = band_unit_warnings(band)
    assert suspect in line and "rad/s" in line and "\n" not in line


@pytest.mark.parametrize("f_max", [100, 200, 250, 314, 400, 1000, 1500, 2000, 2500, 20000, 40, 150])
def test_round_bands_do_not_warn(f_max):
    """Round limits, and 314 (only three digits of 100 pi), are Hz as written."""
    from pymorembs.units import band_unit_warnings

    assert band_unit_warnings((0.0, float(f_max))) == []


def test_shipped_example_jobs_do_not_warn_about_the_band():
    from pathlib import Path

    from pymorembs.job.schema import load_job
    from pymorembs.units import band_unit_warnings

    jobs = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.toml"))
    assert len(jobs) >= 4
    for path in jobs:
        assert band_unit_warnings(load_job(path).band_hz) == [], path
