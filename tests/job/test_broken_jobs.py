"""The corpus of deliberately broken job files (``tests/broken/jobs/*.toml``).

Each job is a realistic mistake. Run through the command line (``pymorembs reduce JOB --out
DIR``), each must exit with its code (2: the user's mistake, 3: a numerical failure), print
exactly one line on stderr that matches its pattern and names the job file, show no traceback,
and write nothing: the output folder stays absent and no staging folder is left behind.

The jobs reference small models that the fixture writes next to the copied job files:
``lattice/`` (the spring lattice of ``conftest``: 12 nodes, 36 dofs, node 120 dependent),
``lattice-fixed/`` (node 20 supported), ``lattice-loose/`` (plus two nodes joined only to each
other: a mechanism), ``lattice-unconnected/`` (plus a node with mass and no stiffness),
``lattice-negative-mass/`` (a sign error in M), ``lattice-dangling/`` (plain files whose
``constraints.csv`` names a node that does not exist) and ``truss/`` (a solid-like truss,
translations only).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from conftest import space_truss, spring_lattice
from pymorembs.body import DofTable, ElasticBody
from pymorembs.io.matrix_market import write_matrix_files
from pymorembs.io.native import write_body_h5
from pymorembs.job.cli import main

JOBS = Path(__file__).parents[1] / "broken" / "jobs"

#: (job file stem, exit code, regular expression the one stderr line must match)
CASES = [
    ("misspelled_key", 2, r"\[band\]: unknown key 'f_max'; did you mean 'f_max_hz'\?"),
    ("unknown_method", 2, r"\[\[reduction\]\] #2\.method: unknown method 'krilov'; did you mean "
     r"'krylov'\?"),
    ("order_larger_than_model", 2, r"\[\[reduction\]\] #1\.order: 500 is not below the 30 "
     r"independent dofs"),
    ("band_reversed", 2, r"\[band\]: f_max_hz \(100\.0\) must be greater than f_min_hz \(500\.0\)"),
    ("negative_frequency", 2, r"\[band\]\.f_min_hz: must be >= 0\.0, got -10"),
    ("negative_expansion_point", 2, r"expansion_points_hz: must be a list of finite frequencies "
     r">= 0"),
    ("missing_model_file", 2, r"results/model\.h5: file not found"),
    ("unknown_node", 2, r"\[\[inputs\]\] #1: node 77 has no dofs in the model"),
    ("unknown_frame_node", 2, r"\[frame\]: node 999 does not exist"),
    ("unknown_direction", 2, r"\[\[inputs\]\] #1: node 60 has no dof rz"),
    ("input_on_fixed_dof", 2, r"\[\[inputs\]\] #1: node 20 ux is a fixed dof of the model"),
    ("inputs_only_on_frame_node", 2, r"\[\[inputs\]\]: every input acts on a fixed dof of the "
     r"frame"),
    ("tangent_frame_leaves_rotations", 2, r"\[frame\]: the tangent frame at node 1 leaves 3 "
     r"rigid-body motions free \(rotation about x; rotation about y; rotation about z\)"),
    ("loose_part", 2, r"\[frame\]: the held body still has \d mechanisms? .*translation [xyz] at "
     r"node 1[34]0 is free"),
    ("unconnected_dof", 2, r"\[frame\]: translation x at node 130 is free: the dof has no "
     r"stiffness \(3 such dofs"),
    ("indefinite_mass", 3, r"\[model\]: the mass matrix is indefinite: 1 negative diagonal entry, "
     r"the most negative at node 50 uy"),
    ("name_escapes_output_folder", 2, r"\[\[reduction\]\] #2\.name: '\.\./krylov' is not a valid "
     r"name"),
    ("absolute_output_name", 2, r"\[\[reduction\]\] #2\.name: '/tmp/krylov' is not a valid name"),
    ("name_shadows_summary", 2, r"\[\[reduction\]\] #2\.name: 'summary\.json' is the name of a "
     r"file of the job's output folder"),
    ("invalid_toml", 2, r"invalid_toml\.toml:7: invalid TOML: Invalid value \(column 7\)"),
    ("wrong_type", 2, r"\[\[reduction\]\] #1\.order: must be a whole number, got '6'"),
    ("unknown_export_format", 2, r"\[export\]\.outputs: unknown output 'hdf5'"),
    ("duplicate_reduction_names", 2, r"\[\[reduction\]\] #2\.name: 'modal-6' is used by another "
     r"reduction"),
    ("damping_ratio_percent", 2, r"\[damping\]: modal damping ratio must lie in \(0, 1\), got 2"),
    ("unknown_example", 2, r"unknown example 'rack-bems'; available: blade, rack-beams"),
    ("missing_band", 2, r"job: missing key 'band'"),
    ("time_domain_with_modal_damping", 2, r"\[time_domain\]: modal damping is a loss factor"),
    ("dangling_constraint", 2, r"\[model\]: .*lattice-dangling/constraints\.csv:2: node 999 has "
     r"no dofs in the model"),
    ("input_on_massless_mechanism", 2, r"\[\[inputs\]\]: input 150:ux loads a direction without "
     r"mass and stiffness \(node 150 ux\)"),
    ("coupled_massless_mechanism", 3, r"\[model\]: the stiffness matrix is not positive "
     r"semidefinite: a massless direction without stiffness of its own \(nodes 150, 160 ux\) is "
     r"coupled to node 50 ux"),
]  # fmt: skip


def _models(folder: Path) -> None:
    """Write the small models the broken jobs reference into ``folder``."""
    lattice = spring_lattice()
    (folder / "lattice").mkdir()
    write_body_h5(lattice, folder / "lattice" / "model.h5")

    fixed = lattice.with_fixed(lattice.dofs.of_node(20))
    (folder / "lattice-fixed").mkdir()
    write_body_h5(fixed, folder / "lattice-fixed" / "model.h5")

    (folder / "lattice-loose").mkdir()
    write_body_h5(_with_extra_nodes(lattice, joined=True), folder / "lattice-loose" / "model.h5")

    (folder / "lattice-unconnected").mkdir()
    write_body_h5(
        _with_extra_nodes(lattice, joined=False), folder / "lattice-unconnected" / "model.h5"
    )

    mass = lattice.mass.tolil()
    index = lattice.dofs.index(50, "uy")
    mass[index, index] = -mass[index, index]
    (folder / "lattice-negative-mass").mkdir()
    write_body_h5(
        replace(lattice, mass=mass.tocsr()), folder / "lattice-negative-mass" / "model.h5"
    )

    write_matrix_files(space_truss(), folder / "truss")

    for name, coupled in (("lattice-massless", False), ("lattice-massless-coupled", True)):
        (folder / name).mkdir()
        write_body_h5(_with_massless_pair(lattice, coupled), folder / name / "model.h5")

    dangling = folder / "lattice-dangling"
    write_matrix_files(lattice, dangling)
    lines = (dangling / "constraints.csv").read_text().splitlines()
    assert lines[1].startswith("120,ux,0.0,30,")
    lines[1] = lines[1].replace(",30,", ",999,", 1)  # a node that does not exist
    (dangling / "constraints.csv").write_text("\n".join(lines) + "\n")


def _with_extra_nodes(body: ElasticBody, joined: bool) -> ElasticBody:
    """The body plus node 130 (and 140 if ``joined``, tied to 130 by a stiff 3-D spring).

    Neither touches the rest of the body: with ``joined`` the pair can translate together (a
    mechanism whose stiffness rows are not zero); without, node 130 has mass and no stiffness.
    """
    ids = [130, 140] if joined else [130]
    n_new = 3 * len(ids)
    extra_k = np.zeros((n_new, n_new))
    if joined:
        spring = 1e5 * np.eye(3)
        extra_k = np.block([[spring, -spring], [-spring, spring]])
    k = sp.block_diag([body.stiffness, sp.csr_matrix(extra_k)], format="csr")
    m = sp.block_diag([body.mass, sp.identity(n_new)], format="csr")
    dofs = DofTable(
        np.concatenate([body.dofs.nodes, np.repeat(ids, 3)]),
        np.concatenate([body.dofs.directions, np.tile([0, 1, 2], len(ids))]),
    )
    coordinates = np.vstack([body.coordinates, [[20.0, 0.0, 0.0], [21.0, 0.0, 0.0]][: len(ids)]])
    constraints = body.constraints
    g = sp.hstack([constraints.matrix, sp.csr_matrix((len(constraints), n_new))])
    return replace(
        body,
        node_ids=np.concatenate([body.node_ids, ids]),
        coordinates=coordinates,
        dofs=dofs,
        mass=m,
        stiffness=k,
        constraints=replace(constraints, matrix=sp.csr_matrix(g)),
    )


def _with_massless_pair(body: ElasticBody, coupled: bool) -> ElasticBody:
    """The body plus nodes 150 and 160 (ux only, no mass): nothing touches them, or
    (``coupled``) a spring joins them to each other and a stiffness term joins node 150 to node
    50 ux without a diagonal entry to balance it (its 2x2 minors stay positive)."""
    n = body.n_dof
    extra = np.zeros((2, 2))
    k = sp.block_diag([body.stiffness, sp.csr_matrix(extra)], format="lil")
    if coupled:
        k[n:, n:] = 1e5 * np.array([[1.0, -1.0], [-1.0, 1.0]])
        i = body.dofs.index(50, "ux")
        k[n, i] = k[i, n] = 0.1 * np.sqrt(1e5 * k[i, i])
    constraints = body.constraints
    return replace(
        body,
        node_ids=np.concatenate([body.node_ids, [150, 160]]),
        coordinates=np.vstack([body.coordinates, [[20.0, 0.0, 0.0], [21.0, 0.0, 0.0]]]),
        dofs=DofTable(
            np.concatenate([body.dofs.nodes, [150, 160]]),
            np.concatenate([body.dofs.directions, [0, 0]]),
        ),
        mass=sp.block_diag([body.mass, sp.csr_matrix((2, 2))], format="csr"),
        stiffness=sp.csr_matrix(k),
        constraints=replace(
            constraints,
            matrix=sp.hstack([constraints.matrix, sp.csr_matrix((len(constraints), 2))]),
        ),
    )


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("broken")
    for job in JOBS.glob("*.toml"):
        shutil.copy(job, folder / job.name)
    _models(folder)
    return folder


def test_the_corpus_is_complete():
    """Every job file has a case and every case a job file; at least 15 mistakes."""
    files = sorted(p.stem for p in JOBS.glob("*.toml"))
    assert files == sorted(name for name, _, _ in CASES)
    assert len(files) >= 15
    for path in JOBS.glob("*.toml"):
        assert path.read_text().startswith("# Broken on purpose: "), path.name


@pytest.mark.parametrize(("name", "code", "pattern"), CASES, ids=[c[0] for c in CASES])
def test_broken_job(name, code, pattern, corpus, capsys):
    job = corpus / f"{name}.toml"
    out = corpus / f"out-{name}"
    before = {p.name for p in corpus.iterdir()}
    result = main(["reduce", str(job), "--out", str(out)])
    captured = capsys.readouterr()
    err = captured.err
    assert result == code, err
    assert err.count("\n") == 1, err
    assert "Traceback" not in err
    line = err.rstrip("\n")
    assert line.startswith(f"pymorembs: error: {job}")  # names the job file first
    assert re.search(pattern, line), line
    assert not out.exists()
    assert {p.name for p in corpus.iterdir()} == before  # no staging folder, nothing else


@pytest.mark.slow
def test_the_command_itself_exits_with_the_code(corpus):
    """The installed console script, as a user runs it (one case per exit code)."""
    script = Path(sys.executable).with_name("pymorembs")
    for name, code in (("misspelled_key", 2), ("indefinite_mass", 3)):
        out = corpus / f"out-cli-{name}"
        done = subprocess.run(
            [str(script), "reduce", str(corpus / f"{name}.toml"), "--out", str(out)],
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert done.returncode == code, done.stderr
        assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
        assert not out.exists()
