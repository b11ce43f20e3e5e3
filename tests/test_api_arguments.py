"""Issue #27 item 7: every option that takes a list takes a list, a tuple or a NumPy array, and
every number a Python or NumPy number; a wrong type or shape is one line naming the option.

The reference is the same call with plain Python lists and numbers: the options objects must be
equal (and hold plain Python values), the reduced bodies the same."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import pymorembs as pm
from pymorembs.methods import OptionError

#: Per method: the options as plain Python values, and the same as NumPy / tuple values.
AS_PYTHON_AND_AS_NUMPY = [
    (
        "modal",
        {"order": 5, "frm_hz": [100.0, 300.0], "shift_hz": 2.0, "candidates": 30},
        {"order": np.int32(5), "frm_hz": np.array([100.0, 300.0]), "shift_hz": np.float32(2.0),
         "candidates": np.int64(30)},
    ),
    (
        "modal",
        {"order": 5, "frm_hz": [100.0], "select": "best"},
        {"order": np.array(5), "frm_hz": np.float64(100.0), "select": np.str_("best")},
    ),
    (
        "craig-bampton",
        {"fixed_modes": 4, "shift_hz": 1.0, "max_frequency_hz": 5000.0},
        {"fixed_modes": np.uint8(4), "shift_hz": np.array(1.0),
         "max_frequency_hz": np.float32(5000.0)},
    ),
    (
        "krylov",
        {"expansion_points_hz": [0.0, 500.0], "moments": [3, 2], "two_sided": True,
         "deflation_tolerance": 1e-9},
        {"expansion_points_hz": np.array([0.0, 500.0]), "moments": np.array([3, 2]),
         "two_sided": np.bool_(True), "deflation_tolerance": np.float64(1e-9)},
    ),
    (
        "krylov",
        {"expansion_points_hz": [0.0, 500.0], "order": 12, "moments": 4},
        {"expansion_points_hz": (0, 500), "order": np.int64(12), "moments": np.int16(4)},
    ),
    (
        "krylov",
        {"expansion_points_hz": [250.0], "order": 12},
        {"expansion_points_hz": np.float64(250.0), "order": np.array(12)},
    ),
    (
        "soaga",
        {"tolerance": 1e-6, "order": 40, "candidates_hz": [0.0, 250.0, 500.0], "n_candidates": 3},
        {"tolerance": np.float64(1e-6), "order": np.int64(40),
         "candidates_hz": np.linspace(0.0, 500.0, 3), "n_candidates": np.int8(3)},
    ),
    (
        "gramian",
        {"order": 6, "first_stage": "krylov", "expansion_points_hz": [0.0, 300.0],
         "moments": [2, 2], "first_order": 20},
        {"order": np.int64(6), "first_stage": np.str_("krylov"),
         "expansion_points_hz": np.array([0, 300]), "moments": (np.int64(2), np.int32(2)),
         "first_order": np.int64(20)},
    ),
    (
        "gramian",
        {"tolerance": 1e-8, "first_stage": "rational-krylov", "convergence_tolerance": 1e-7},
        {"tolerance": np.float64(1e-8), "first_stage": "rational-krylov",
         "convergence_tolerance": np.array(1e-7)},
    ),
    (
        "pod",
        {"order": 8, "snapshots": 12, "tolerance": 1e-9},
        {"order": np.int64(8), "snapshots": np.int32(12), "tolerance": np.float64(1e-9)},
    ),
]  # fmt: skip


def plain_python(value: object) -> bool:
    """Whether a checked option holds only plain Python values (no NumPy type inside)."""
    if isinstance(value, tuple | list):
        return all(plain_python(item) for item in value)
    return value is None or type(value) in (bool, int, float, str)


@pytest.mark.parametrize(("method", "as_python", "as_numpy"), AS_PYTHON_AND_AS_NUMPY)
def test_numpy_values_give_the_options_of_python_values(method, as_python, as_numpy):
    expected = pm.method_options(method, as_python)
    checked = pm.method_options(method, as_numpy)
    assert checked == expected
    for field in dataclasses.fields(checked):
        value = getattr(checked, field.name)
        assert plain_python(value), (field.name, value)


@pytest.mark.parametrize(
    ("method", "options", "message"),
    [
        ("krylov", {"expansion_points_hz": np.zeros((2, 2)), "order": 8},
         r"expansion_points_hz: must be a list of finite frequencies >= 0 in Hz, got an array "
         r"of shape \(2, 2\)"),
        ("krylov", {"expansion_points_hz": np.array([0.0, np.nan]), "order": 8},
         "expansion_points_hz: must be a list of finite frequencies >= 0 in Hz, got an entry nan"),
        ("krylov", {"expansion_points_hz": np.array([], dtype=float), "order": 8},
         "expansion_points_hz: must be a list of .* got an empty list"),
        ("krylov", {"expansion_points_hz": "0, 500", "order": 8},
         "expansion_points_hz: must be a list of finite frequencies"),
        ("krylov", {"expansion_points_hz": [0, -5.0], "order": 8},
         "expansion_points_hz: must be a list of finite frequencies >= 0 in Hz, got -5.0"),
        ("krylov", {"expansion_points_hz": [0, 500], "moments": np.array([2.0, 3.0])},
         "moments: must be a whole number >= 1 or one per expansion point, got an entry 2.0"),
        ("krylov", {"expansion_points_hz": [0, 500], "moments": np.array([2, 3, 4])},
         "moments: 3 values for 2 expansion points"),
        ("krylov", {"expansion_points_hz": [0, 500], "moments": np.ones((2, 1), dtype=int)},
         r"moments: .* got an array of shape \(2, 1\)"),
        ("krylov", {"expansion_points_hz": [0, 500], "order": 8, "two_sided": 1},
         "two_sided: must be true or false, got 1"),
        ("krylov", {"expansion_points_hz": [0, 500], "order": np.float64(8.0)},
         "order: must be a whole number, got 8.0"),
        ("krylov", {"expansion_points_hz": [0, 500], "order": np.array([8])},
         r"order: must be a whole number, got an array of shape \(1,\)"),
        ("modal", {"order": 5, "frm_hz": np.array([[100.0]])},
         r"frm_hz: must be a list of finite frequencies >= 0 in Hz, got an array of shape"),
        ("modal", {"order": 5, "shift_hz": np.array([1.0, 2.0])},
         r"shift_hz: must be a number, got an array of shape \(2,\)"),
        ("modal", {"order": 5, "select": np.array(["best"])},
         "select: must be 'lowest' or 'best' .*got an array"),
        ("soaga", {"tolerance": 1e-6, "candidates_hz": [[0, 100]]},
         r"candidates_hz: must be a list of finite frequencies .* got an entry \[0, 100\]"),
        ("gramian", {"order": 4, "first_stage": "krylov", "expansion_points_hz": [0, 300],
                     "moments": [2, 2, 2]},
         "moments: 3 values for 2 expansion points"),
        ("pod", {"order": 4, "snapshots": np.float32(12)},
         "snapshots: must be a whole number, got 12.0"),
    ],
)  # fmt: skip
def test_a_wrong_shape_or_type_is_one_line_naming_the_option(method, options, message):
    with pytest.raises(OptionError, match=message) as caught:
        pm.method_options(method, options)
    assert "\n" not in str(caught.value)


@pytest.fixture(scope="module")
def rack():
    return pm.example("rack-beams")


@pytest.fixture(scope="module")
def reduced(rack):
    prepared = pm.prepare(rack, "tangent", node=2, inputs=[(1, "ux uy uz")])
    return pm.reduce(prepared, "krylov", expansion_points_hz=[0.0, 500.0], order=12)


def test_the_api_takes_arrays_where_it_takes_lists(rack, reduced, tmp_path):
    """prepare, reduce, error and the exports with NumPy arguments: the same body as with lists."""
    prepared = pm.prepare(rack, "tangent", node=np.int64(2),
                          inputs=np.array([(1, "ux uy uz")], dtype=object),
                          inertia_loads=np.array(["ax", "az"]))  # fmt: skip
    assert prepared.frame == pm.Frame("tangent", 2) and prepared.inertia.cases == ("ax", "az")
    same = pm.prepare(rack, "tangent", node=2, inputs=[(1, np.array(["ux", "uy", "uz"]))])
    assert same.system.input_labels == reduced.prepared.system.input_labels
    again = pm.reduce(same, "krylov", expansion_points_hz=np.array([0.0, 500.0]),
                      order=np.int64(12), band_hz=np.array([0, 1000]))  # fmt: skip
    np.testing.assert_array_equal(again.eigenfrequencies_hz, reduced.eigenfrequencies_hz)
    curve = reduced.error(np.array([0.0, 1000.0]), points=np.int64(6), workers=np.int32(1))
    reference = reduced.error((0, 1000), points=6)
    np.testing.assert_array_equal(curve.relative, reference.relative)
    a = reduced.to_sid(tmp_path / "a.SID_FEM", nodes=np.array([1, 2]))
    b = reduced.to_sid(tmp_path / "b.SID_FEM", nodes=(1, 2))
    assert a.read_bytes() == b.read_bytes()
    written = reduced.to_matrices(tmp_path / "m", formats="mtx")
    assert written and all(path.suffix == ".mtx" for path in written)
    info = pm.facts(rack, modes=np.int64(2))  # 6 rigid-body modes, then the 2 asked for
    assert np.count_nonzero(np.asarray(info["eigenfrequencies_hz"]) > 0) == 2


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda body, r: pm.prepare(body, "tangent", node=2, inputs=(1, "ux")),
         r"inputs: give a list of ports, e.g. inputs=\[\(1, 'ux uy uz'\)\]"),
        (lambda body, r: pm.prepare(body, "tangent", node=2, inputs=[(1.5, "ux")]),
         "inputs node: must be a whole number, got 1.5"),
        (lambda body, r: pm.prepare(body, "tangent", node=2.0, inputs=[(1, "ux")]),
         "node: must be a whole number, got 2.0"),
        (lambda body, r: pm.prepare(body, 2, inputs=[(1, "ux")]),
         "frame: must be a Frame or 'tangent', 'buckens' or 'none', got 2"),
        (lambda body, r: pm.prepare(body, "tangent", node=2, inputs=[(1, "ux")],
                                    inertia_loads="ax"),
         r"inertia_loads: give a list of load cases, e.g. \['ax'\]"),
        (lambda body, r: pm.prepare(body, "tangent", node=2, inputs=[(1, "ux")],
                                    inertia_loads=np.ones((2, 2))),
         "inertia_loads: must be true, false or a list of load cases"),
        (lambda body, r: pm.reduce(r.prepared, "soaga", band_hz=(0, 500, 1000), tolerance=1e-4),
         r"band_hz: must be \(f_min, f_max\) in Hz, got 3 values"),
        (lambda body, r: pm.reduce(r.prepared, "soaga", band_hz=np.array([500, 0]),
                                   tolerance=1e-4),
         r"band_hz: must be \(f_min, f_max\) in Hz with f_min < f_max, got \(500, 0\)"),
        (lambda body, r: r.error(1000.0),
         r"band_hz: must be \(f_min, f_max\) in Hz, got 1000.0"),
        (lambda body, r: r.error((0, 1000), points=20.0),
         "points: must be a whole number, got 20.0"),
        (lambda body, r: r.to_sid("x.SID_FEM", nodes=[1.5, 2]),
         r"nodes: must be node ids \(whole numbers\), got an entry 1.5"),
        (lambda body, r: r.to_exudyn("x.npz", nodes=np.array([[1, 2]])),
         r"nodes: must be node ids \(whole numbers\), got an array of shape \(1, 2\)"),
        (lambda body, r: r.to_matrices("m", formats=np.array([1, 2])),
         "formats: must be a list of 'npz', 'mtx', 'mat', got an array"),
        (lambda body, r: r.simulate(pm.LoadCase("s", "step", [0, 0, 1]), clamp_node=2,
                                    load_node=1),
         "load_cases: must be a list of LoadCase"),
        (lambda body, r: r.simulate([pm.LoadCase("s", "step", [0, 0, 1])], clamp_node=2,
                                    load_node=np.array([1])),
         r"load_node: must be a whole number, got an array of shape \(1,\)"),
        (lambda body, r: pm.facts(body, modes=2.5), "modes: must be a whole number, got 2.5"),
    ],
)  # fmt: skip
def test_a_wrong_argument_of_the_api_is_one_line_naming_it(
    rack, reduced, call, message, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)  # the calls name relative files: nothing lands in the checkout
    with pytest.raises(pm.UserError, match=message) as caught:
        call(rack, reduced)
    assert "\n" not in str(caught.value)
