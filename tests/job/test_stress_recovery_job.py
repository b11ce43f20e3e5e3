"""A job that asks for the stress recovery file of a body without solid elements writes it
without points and says why, on stderr and in the summary's notes (issue #29 item 2)."""

from __future__ import annotations

import json

import h5py
import pytest
from test_cli import lattice_files, run, write_job  # noqa: F401 (the fixture)


@pytest.mark.slow  # a whole job: 15 s
def test_a_body_without_solids_gets_a_note_and_a_recovery_file_without_points(
    tmp_path,
    capsys,
    lattice_files,  # noqa: F811
):
    job = write_job(tmp_path, extra='\n[export]\noutputs = ["stress_recovery"]\n')
    code, _, err = run(["reduce", job, "--out", tmp_path / "out"], capsys)
    assert code == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    note = [n for n in summary["notes"] if "has no element mesh" in n]
    assert len(note) == 1 and f"pymorembs: note: {note[0]}" in err.splitlines()
    with h5py.File(tmp_path / "out" / "kry" / "kry.stress.h5", "r") as f:
        assert f.attrs["note"] == note[0]
        assert f["integration_points/stress"].shape[1] == 0
