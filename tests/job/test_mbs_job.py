"""Issue #5 end to end: a job writes every body output, runs the time-domain checks and the
report, on rack-beams (Buckens frame, clamped at node 2 by a joint, as in paper section 5.1)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import html5lib
import numpy as np
import pytest
import scipy.io

from pymorembs.analysis import transfer_function
from pymorembs.examples import build_example
from pymorembs.export.exudyn_body import load_exudyn_body
from pymorembs.export.sid import check_sid, read_sid, sid_invariants
from pymorembs.job.cli import main
from pymorembs.job.run import prepare_job
from pymorembs.job.schema import load_job
from pymorembs.system import SecondOrderSystem

JOB = """
title = "rack-beams as a multibody body"
[model]
example = "rack-beams"
[damping]
kind = "rayleigh"
beta = 2e-6
[frame]
type = "buckens"
[[inputs]]
node = 1
directions = "ux uy uz"
[[inputs]]
node = 2
directions = "ux uy uz rx ry rz"
[band]
f_min_hz = 0
f_max_hz = 1000
points = 200
[[reduction]]
name = "krylov"
method = "krylov"
expansion_points_hz = [0, 500]
moments = [3, 2]
{extra_reduction}
[export]
outputs = {outputs}
[time_domain]
clamp_node = 2
load_node = 1
duration_s = 0.06
step_s = 1e-4
exudyn = true
"""
ALL = '["sid", "neweul", "exudyn", "vtu", "npz", "mat", "mtx", "report"]'


def run(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


#: The tests on the output of the whole job with every output (about 17 s on 2 cores) are in
#: the slow set (`make test-slow`, which CI runs too).
whole_job = pytest.mark.slow


@pytest.fixture(scope="module")
def mbs_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mbs")
    job = folder / "job.toml"
    job.write_text(JOB.format(outputs=ALL, extra_reduction=""))
    assert main(["reduce", str(job), "--out", str(folder / "out"), "--quiet"]) == 0
    summary = json.loads((folder / "out" / "summary.json").read_text())
    return folder / "out", summary


def direct_mass_properties():
    """Mass, centre of gravity and inertia tensor about it from the full M and the node
    coordinates of rack-beams: rigid-body fields built node by node here, then the
    parallel-axis theorem."""
    body = build_example("rack-beams")
    rigid = np.zeros((body.n_dof, 6))
    for i, node in enumerate(body.node_ids):
        rows = body.dofs.of_node(int(node))
        arms = np.cross(np.eye(3), body.coordinates[i])  # row a: e_a x x
        for row, d in zip(rows, body.dofs.directions[rows], strict=True):
            rigid[row, d] = 1.0
            if d < 3:
                rigid[row, 3:] = arms[:, d]
    total = rigid.T @ (body.mass @ rigid)
    m = total[0, 0]
    cross = -(total[:3, 3:] - total[:3, 3:].T) / (2 * m)  # -m [c]x block
    cg = np.array([cross[2, 1], cross[0, 2], cross[1, 0]])
    inertia = total[3:, 3:] - m * (cg @ cg * np.eye(3) - np.outer(cg, cg))
    return m, cg, inertia


@whole_job
def test_every_output_is_written_and_listed(mbs_run):
    out, summary = mbs_run
    (entry,) = summary["reductions"]
    names = {name.split("/", 1)[1] for name in entry["files"]}
    expected = {
        "krylov.SID_FEM", "krylov_neweul.mat", "krylov_exudyn.npz", "krylov.vtu", "reduced.npz",
        "reduced.mat", "M.mtx", "K.mtx", "D.mtx", "B.mtx", "C.mtx",
    }  # fmt: skip
    assert expected <= names
    for name in entry["files"] + summary["files"]:
        assert (out / name).is_file(), name
    assert {"summary.json", "error.png", "time.png", "report.html"} <= set(summary["files"])


@whole_job
def test_sid_has_the_mass_properties_of_the_fe_model(mbs_run):
    out, _ = mbs_run
    sid = read_sid(out / "krylov" / "krylov.SID_FEM")
    assert check_sid(sid) == []
    values = sid_invariants(sid)
    m, cg, inertia = direct_mass_properties()
    assert abs(values["mass"] - m) <= 1e-10 * m
    # Buckens frame: origin in the centre of gravity, so the first moment vanishes
    assert np.linalg.norm(values["centre_of_gravity"]) <= 1e-10 * np.abs(cg).max()
    np.testing.assert_allclose(
        values["inertia"], inertia, rtol=0, atol=1e-10 * np.abs(inertia).max()
    )
    npz = np.load(out / "krylov" / "reduced.npz")
    np.testing.assert_allclose(values["Me"], npz["M"], atol=1e-10)
    np.testing.assert_allclose(
        values["Ke"], npz["K"], rtol=1e-10, atol=1e-10 * np.abs(npz["K"]).max()
    )
    text = (out / "krylov" / "krylov.SID_FEM").read_text().splitlines()
    assert re.match(r"^\s*\d+\s+\d+\s+:No\. nodes, No\. modes:", text[0])
    assert all("E+" not in line and "E-" not in line for line in text)  # D exponents


@whole_job
def test_sid_body_responds_as_the_full_model_within_the_jobs_error(mbs_run):
    """The body as a multibody code gets it -- the SID file read back, its ``Me``, ``Ke``,
    ``De`` and the mode rows of the port nodes -- against the full prepared model, computed here
    by the sparse sweep: within the job's own maximum error over the ports (eq. 27). The job's
    damping is Rayleigh, so ``De`` is the projected ``D`` and both sides are the same model."""
    out, summary = mbs_run
    sid = read_sid(out / "krylov" / "krylov.SID_FEM")
    rows = np.vstack([sid.nodes[1]["phi"].m0, sid.nodes[2]["phi"].m0, sid.nodes[2]["psi"].m0])
    me, ke, de = (sid.objects[name].m0 for name in ("Me", "Ke", "De"))
    _, prepared = prepare_job(load_job(out.parent / "job.toml"))
    frequencies = np.array([0.0, 137.0, 480.0, 755.0, 1000.0])
    full = transfer_function(prepared.system, frequencies)
    body = transfer_function(SecondOrderSystem(me, ke, de, rows.T, rows), frequencies)
    error = np.linalg.norm(body - full, axis=(1, 2)) / np.linalg.norm(full, axis=(1, 2))
    (entry,) = summary["reductions"]
    assert entry["accuracy"]["max"] < 1e-6
    assert error.max() <= 1.5 * entry["accuracy"]["max"] + 1e-12, error


@whole_job
def test_neweul_and_exudyn_files_hold_the_same_body(mbs_run):
    out, _ = mbs_run
    sid = sid_invariants(read_sid(out / "krylov" / "krylov.SID_FEM"))
    neweul = scipy.io.loadmat(out / "krylov" / "krylov_neweul.mat")
    assert float(neweul["mass"].squeeze()) == pytest.approx(sid["mass"], rel=1e-10)
    np.testing.assert_allclose(neweul["Ke"], sid["Ke"], rtol=1e-10, atol=1e-6)
    exudyn = load_exudyn_body(out / "krylov" / "krylov_exudyn.npz")
    assert float(exudyn["physicsMass"]) == pytest.approx(sid["mass"], rel=1e-10)
    np.testing.assert_allclose(exudyn["physicsInertia"], sid["inertia"], rtol=1e-10, atol=1e-12)


@whole_job
def test_time_domain_entries(mbs_run):
    _, summary = mbs_run
    cases = {case["name"]: case for case in summary["time_domain"]["cases"]}
    assert set(cases) == {"step", "harmonic"}
    for case in cases.values():
        (row,) = case["reductions"]
        assert row["max_rel_deviation"] < 1e-6  # Krylov order 46 vs the full FE model
        assert row["speedup"] > 1
        assert row["exudyn_clamp"] == "joint"
        # Exudyn with the exported Buckens body on a rigid joint: linear for small motion
        assert row["exudyn_small_load_max_rel_deviation"] < 1e-4
    (entry,) = summary["reductions"]
    assert set(entry["time_domain"]) == {"step", "harmonic"}


@whole_job
def test_report_is_valid_html_with_all_plots(mbs_run):
    out, summary = mbs_run
    text = (out / "report.html").read_text()
    document = html5lib.HTMLParser(strict=True).parse(text)
    images = document.findall(".//{http://www.w3.org/1999/xhtml}img")
    assert len(images) == 2  # error (with estimators) and time responses; no decay for Krylov
    for name in summary["reductions"][0]["files"]:
        assert name in text


@pytest.mark.skipif(shutil.which("chromium") is None, reason="chromium not installed")
@whole_job
def test_report_renders_in_headless_chromium(mbs_run, tmp_path):
    """Every embedded image decodes in a real browser (naturalWidth > 0)."""
    out, _ = mbs_run
    text = (out / "report.html").read_text()
    probe = (
        "<script>window.addEventListener('load', () => { const ok = [...document.images]"
        ".filter(i => i.complete && i.naturalWidth > 0).length; document.title = "
        "'decoded ' + ok + ' of ' + document.images.length; });</script></body>"
    )
    page = tmp_path / "probe.html"
    page.write_text(text.replace("</body>", probe))
    result = subprocess.run(
        [
            "chromium",
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--virtual-time-budget=5000",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert "<title>decoded 2 of 2</title>" in result.stdout, result.stderr[-2000:]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("outputs = " + ALL, 'outputs = ["sid", "sdi"]'), "did you mean 'sid'"),
        (('kind = "rayleigh"\nbeta = 2e-6', 'kind = "modal"\nratio = 0.01'), "Rayleigh"),
        (("moments = [3, 2]", "moments = [3, 2]\ntwo_sided = true"), "one-sided"),
        (("clamp_node = 2", "clamp_node = 1"), "same node"),
        (("[export]", "[export]\nnodes = [1, 99999]"), "node 99999 has no dofs"),
        (("load_node = 1", "load_node = 99999"), "node 99999 has no dofs"),
        (("clamp_node = 2", "clamp_node = 1001"), "cannot move"),
    ],
)
def test_bad_mbs_jobs_exit_2(change, message, tmp_path, capsys):
    job = tmp_path / "job.toml"
    job.write_text(JOB.format(outputs=ALL, extra_reduction="").replace(*change))
    code, _, err = run(["reduce", job, "--out", tmp_path / "out"], capsys)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_exudyn_step_response_of_a_tangent_frame_body_matches_our_integration():
    """Done-when of issue #5: the exported reduced rack-beams body in Exudyn, step load
    -100 (1,1,1) N at node 1 for 0.1 s, agrees with our own linear integration to 1 %."""
    from dataclasses import replace

    from threadpoolctl import threadpool_limits

    from pymorembs.analysis.exudyn_model import build_exudyn_model, simulate_exudyn
    from pymorembs.analysis.time_domain import clamped_reduced_system, paper_load_cases, simulate
    from pymorembs.body import Damping
    from pymorembs.export.exudyn_body import exudyn_arrays
    from pymorembs.export.source import body_invariants
    from pymorembs.preparation import Frame, Port, prepare
    from pymorembs.reduction.modal import modal_reduction
    from pymorembs.reduction.projection import reduced_model

    body = replace(build_example("rack-beams"), damping=Damping("rayleigh", beta=2e-6))
    port = Port.parse(1, "ux uy uz")
    with threadpool_limits(1):
        prepared = prepare(body, Frame("tangent", 2), [port], [port])
        model = reduced_model(prepared.system, modal_reduction(prepared.system, 20))
    step = paper_load_cases()[0]
    basis = prepared.expand(model.projection.V)
    system = clamped_reduced_system(
        prepared.body, basis, model.system.mass, model.system.stiffness,
        model.damping_matrix, 2, 1,
    )  # fmt: skip
    ours = simulate(system, [step], duration_s=0.1, step_s=1e-4).outputs["step"]
    arrays = exudyn_arrays(body_invariants(model, prepared, [1, 2], "modal"))
    exudyn = build_exudyn_model(arrays, clamp="frame", loads=[(1, lambda _t: step.force_n)])
    theirs = simulate_exudyn(exudyn, 0.1, 1e-4, nodes=[1], spectral_radius=0.8)
    assert theirs.displacements[1].shape == ours.shape
    deviation = np.abs(theirs.displacements[1] - ours).max() / np.abs(ours).max()
    assert np.abs(ours).max() > 5e-3  # the rack deflects by millimetres
    assert deviation < 0.01
