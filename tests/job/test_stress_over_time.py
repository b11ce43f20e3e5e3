"""Issue #29 item 4 end to end: a job with ``[stress]`` gives the stress histories at its hot
spots in ``[time_domain]`` (full FE model against each reduced body) and in ``[large_motion]``
(each body in Exudyn against the modal reference body), in ``summary.json``, the figures and the
report.

The figures are checked against histories computed here: the full model's stresses by an
independent trapezoidal rule on the first-order form of the clamped model (sparse LU), with the
job's own hot spots applied to the displacement fields.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from conftest import blade_job
from pymorembs.analysis import HISTORY_FILE, histories_from_arrays
from pymorembs.analysis.time_domain import LoadCase, clamped_full_model
from pymorembs.job.cli import main
from pymorembs.job.run import prepare_and_validate, run_job
from pymorembs.job.schema import load_job, parse_job
from pymorembs.stress import stress_operator, von_mises

#: The blade (8 x 2 x 2 hex20) held at its root (fixed dofs) and, through a rigid interface
#: node at its tip, by the tangent frame there; loaded at the centre of its span (node 1131).
TIME_JOB = """
[model]
example = "blade"
elements = 8
[[interface]]
node = 9
position = [1.0, 0.0, 0.0]
kind = "rigid"
box = {{ min = [0.999, -1.0, -1.0], max = [1.001, 1.0, 1.0] }}
[damping]
kind = "rayleigh"
beta = 1e-6
[frame]
type = "tangent"
node = 9
[[inputs]]
node = 1131
directions = "ux uy uz"
[band]
f_max_hz = 1000
points = 200
[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0]
moments = 4
export_inaccurate = true  # ε up to 1000 Hz is not the point here: the stresses over time are
[stress]
elements = [{elements}]
[export]
outputs = ["npz", "report"]
[time_domain]
clamp_node = 9
load_node = 1131
duration_s = 0.01
step_s = 2e-5
rho_inf = 1.0
"""
ROOT_ELEMENTS = (1, 2)


@pytest.mark.slow
def test_time_domain_stress_histories_of_a_job(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text(TIME_JOB.format(elements=", ".join(map(str, ROOT_ELEMENTS))))
    out = tmp_path / "out"
    assert main(["reduce", str(job), "--out", str(out), "--quiet"]) == 0
    data = json.loads((out / "summary.json").read_text())
    entry = data["time_domain"]
    assert entry["stress"]["reference"].startswith("the full FE model")
    assert (out / "time_stress.png").stat().st_size > 10_000
    assert "time_stress.png" in data["files"]
    assert "stress: max rel. deviation" in (out / "report.html").read_text()

    # the full model's history, independently: trapezoidal rule on (q, v), sparse
    body, _, _ = prepare_and_validate(load_job(job), deep=False)  # the blade with node 9
    clamped = clamped_full_model(body, clamp_node=9, load_node=1131)
    system = clamped.system
    operator = stress_operator(clamped.body, elements=list(ROOT_ELEMENTS))
    assert entry["stress"]["points"] == [p.split(":")[0] for p in operator.labels()[::6]]
    m, k, d = system.mass, system.stiffness, system.damping
    b, n = system.input_matrix, system.order
    h, n_steps = 2e-5, 500
    e = sp.block_diag([sp.identity(n), m], format="csc")
    a = sp.bmat([[None, sp.identity(n)], [-k, -d]], format="csc")
    left, right = spla.splu(sp.csc_matrix(e - h / 2 * a)), sp.csr_matrix(e + h / 2 * a)
    assert HISTORY_FILE in data["files"]
    with np.load(out / HISTORY_FILE) as arrays:  # the histories themselves, in the run folder
        written = histories_from_arrays(arrays)
        assert list(arrays["points"]) == entry["stress"]["points"]
        assert np.allclose(arrays["coordinates"], operator.coordinates, rtol=0, atol=1e-12)
    assert list(written) == ["time_domain"]
    for case in entry["cases"]:
        load = LoadCase(case["name"], case["kind"], np.array([-100.0] * 3), frequency_hz=10.0)
        z = np.zeros(2 * n)
        vm = [np.zeros(operator.n_points)]
        for step in range(n_steps):
            force = b @ load.force(np.array([(step + 0.5) * h]))[0]
            z = left.solve(right @ z + h * np.concatenate([np.zeros(n), force]))
            vm.append(von_mises(operator(clamped.expand(z[:n, None])[:, 0])))
        vm = np.array(vm)  # (n_t, points)
        bodies = written["time_domain"][case["name"]]
        assert list(bodies) == ["full", "krylov"]
        assert np.allclose(bodies["full"].times, h * np.arange(n_steps + 1), rtol=0, atol=1e-12)
        assert np.allclose(bodies["full"].von_mises, vm, rtol=0, atol=1e-6 * vm.max())
        spots = case["stress_hot_spots"]
        assert len(spots) == operator.n_points
        near = 1e-6 * vm.max()  # round-off of two solvers on a stiff clamped-clamped model
        for spot, column in zip(spots, vm.T, strict=True):
            assert spot["peak_von_mises"] == pytest.approx(column.max(), abs=near)
            assert spot["range_von_mises"] == pytest.approx(np.ptp(column), abs=near)
        (row,) = case["reductions"]
        stress = row["stress"]
        assert stress["reference_peak_von_mises"] == pytest.approx(vm.max(), abs=near)
        assert 0 < stress["max_rel_deviation"] < 0.2  # measured 0.06 (step): 12 columns
        assert stress["worst_point"] in entry["stress"]["points"]
        peaks = bodies["krylov"].von_mises.max(axis=0)
        assert [spot["peak_von_mises"] for spot in stress["hot_spots"]] == list(peaks)
        # each reduction's own entry holds the same row
        reduction = data["reductions"][0]
        assert reduction["time_domain"][case["name"]]["stress"] == stress


@pytest.mark.slow
def test_large_motion_stress_histories_of_a_job(tmp_path):
    """The job's hot spots in the large motion: each body against the modal reference body
    (measured: Krylov-24 within 9e-4 of modal-24, whose own convergence against modal-12 is
    3.7e-3; the deflections agree to 3e-5)."""
    pytest.importorskip("exudyn")
    tables = blade_job(
        damping={"kind": "rayleigh", "beta": 1e-5},
        inputs=[{"node": 1, "directions": "ux uy uz"}],
        band={"f_max_hz": 200.0, "points": 200},
        reduction=[
            {
                "name": "krylov",
                "method": "krylov",
                "expansion_points_hz": [0.0],
                "order": 24,
                "export_inaccurate": True,
            }
        ],
        stress={"elements": [1, 2]},
        export={"outputs": ["exudyn", "report"]},
        large_motion={
            "joint_node": 2,
            "cases": ["spin-up"],
            "duration_s": 0.2,
            "spin_rad_s": 12.0,
            "reference_order": 24,
        },
    )
    tables["model"]["elements"] = 8
    out = tmp_path / "out"
    run_job(parse_job(tables, tmp_path / "job.toml"), out)
    data = json.loads((out / "summary.json").read_text())
    entry = data["large_motion"]
    assert "modal reference body of order 24" in entry["stress"]["reference"]
    assert len(entry["stress"]["points"]) == 2 * 27
    (case,) = entry["cases"]
    assert 0 < case["reference_convergence"]["stress_max_rel_deviation"] < 0.05
    (row,) = case["reductions"]
    assert 0 < row["stress"]["max_rel_deviation"] < 0.01
    assert data["reductions"][0]["large_motion"]["spin-up"]["stress"] == row["stress"]
    assert "large_motion_stress.png" in data["files"]
    with np.load(out / HISTORY_FILE) as arrays:  # the histories behind the figures
        (bodies,) = histories_from_arrays(arrays)["large_motion"].values()
    assert list(bodies) == ["reference", "krylov"]
    peaks = bodies["reference"].von_mises.max(axis=0)
    assert [spot["peak_von_mises"] for spot in case["stress_hot_spots"]] == list(peaks)
    assert (out / "large_motion_stress.png").stat().st_size > 10_000
    assert "stress: max rel. deviation" in (out / "report.html").read_text()
