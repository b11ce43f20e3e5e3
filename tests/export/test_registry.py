"""The export registry (issue #28 item 3): one entry per kind of ``[export] outputs``, used by
``write_outputs``, ``ReducedBody.to_*``, the job schema and the job reference."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import pymorembs as pm
from pymorembs.export import (
    BODY_OUTPUTS,
    DEFAULT_EXPORTS,
    EXPORT_KINDS,
    EXPORTS,
    MATRIX_OUTPUTS,
    exports_table,
    write_outputs,
)
from pymorembs.job import schema


@pytest.fixture(scope="module")
def reduced() -> pm.ReducedBody:
    prepared = pm.prepare(pm.example("rack-beams"), frame=pm.Frame("tangent", node=2),
                          inputs=[(1, "ux uy uz")])  # fmt: skip
    return pm.reduce(prepared, "krylov", expansion_points_hz=[0], order=6)


@pytest.fixture(scope="module")
def written(reduced, tmp_path_factory) -> tuple[Path, list[str]]:
    """Every kind written by ``write_outputs`` into one folder, and the names it returned."""
    folder = tmp_path_factory.mktemp("every-kind")
    names = write_outputs(reduced.model, reduced.prepared, reduced.name, EXPORT_KINDS, [1, 2],
                          folder)  # fmt: skip
    return folder, names


def test_write_outputs_writes_the_files_each_kind_names(reduced, written):
    folder, names = written
    expected = []
    for kind in EXPORTS.values():
        if kind.write is not None:  # the report is the job's
            expected += kind.file_names(reduced.name)
    assert sorted(p.name for p in folder.iterdir()) == sorted(names) == sorted(expected)
    # the bodies for multibody codes after the other files (the order of summary.json)
    assert names == [
        "reduced.npz", "M.mtx", "K.mtx", "D.mtx", "B.mtx", "C.mtx", "reduced.mat",
        "krylov.vtu", "krylov.stress.h5", "krylov.SID_FEM", "krylov_neweul.mat",
        "krylov_exudyn.npz",
    ]  # fmt: skip


def test_the_api_writes_the_files_of_write_outputs(reduced, written, tmp_path):
    folder, _ = written
    for kind, path in (
        ("sid", reduced.to_sid(tmp_path / "a.SID_FEM", nodes=[1, 2])),
        ("neweul", reduced.to_neweul(tmp_path / "a.mat", nodes=[1, 2])),
        ("exudyn", reduced.to_exudyn(tmp_path / "a.npz", nodes=[1, 2])),
        ("vtu", reduced.to_vtu(tmp_path / "a.vtu")),
    ):
        (name,) = EXPORTS[kind].file_names(reduced.name)
        assert path.read_bytes() == (folder / name).read_bytes(), kind
    matrices = reduced.to_matrices(tmp_path / "m", formats=MATRIX_OUTPUTS)
    assert [p.name for p in matrices] == [
        name for kind in MATRIX_OUTPUTS for name in EXPORTS[kind].file_names(reduced.name)
    ]
    for path in matrices:
        assert path.read_bytes() == (folder / path.name).read_bytes(), path.name


def test_every_kind_is_described_once():
    assert EXPORT_KINDS == tuple(EXPORTS) and len(set(EXPORT_KINDS)) == len(EXPORT_KINDS)
    assert set(DEFAULT_EXPORTS) <= set(EXPORTS) and DEFAULT_EXPORTS
    assert BODY_OUTPUTS == ("sid", "neweul", "exudyn")
    for name, kind in EXPORTS.items():
        assert kind.name == name and kind.files and kind.description, name
        assert kind.group in ("matrices", "shapes", "body", "job"), name
        if kind.options is not None:
            assert dataclasses.is_dataclass(kind.options), name
            assert kind.options.__dataclass_params__.frozen, name
    assert [name for name, kind in EXPORTS.items() if kind.write is None] == ["report"]


def test_the_job_schema_takes_its_kinds_from_the_registry():
    assert schema.EXPORT_KINDS is EXPORT_KINDS and schema.DEFAULT_EXPORTS is DEFAULT_EXPORTS
    assert schema.ExportSpec().outputs == DEFAULT_EXPORTS


def test_the_job_reference_holds_the_generated_exports_table():
    text = (Path(__file__).parents[2] / "docs" / "jobs.md").read_text(encoding="utf-8")
    block = text.split("<!-- exports-table:start -->\n")[1].split("<!-- exports-table:end -->")[0]
    assert block == exports_table(), "regenerate the table in docs/jobs.md (see its section)"
    for name in EXPORTS:
        assert f"| `{name}`" in block
