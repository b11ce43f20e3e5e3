"""Issue #27 item 7: ``ReducedBody.save(path)`` and ``pm.load(path)`` -- a versioned HDF5 file,
no pickle, that holds everything to evaluate, re-export and compare the body.

The loaded body is checked against the body that was saved: the same eigenfrequencies, the same
error curve over a band against the full model (which the file must hold for that), and the same
bytes of every exported file (the writers are deterministic). A damaged, truncated, newer or
foreign file is one line. The layout documented in docs/api.md is checked against a file, read
with h5py alone."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp

import pymorembs as pm
from conftest import space_truss
from pymorembs.io.native import write_body_h5
from pymorembs.job.cli import main

ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def tangent():
    """rack-beams held at node 2: modal damping, inertia loads, geometric stiffening of the mesh
    (also of a unit force at node 1), Krylov with stiff directions removed."""
    prepared = pm.prepare(pm.example("rack-beams"), "tangent", node=2, inputs=[(1, "ux uy uz")],
                          inertia_loads=["ax", "wzz"], stiffening="mesh", stiffening_nodes=[1],
                          damping=pm.Damping("modal", ratio=0.02))  # fmt: skip
    return pm.reduce(prepared, "krylov", expansion_points_hz=[0.0, 500.0], order=24,
                     max_frequency_hz=3000.0, name="rack")  # fmt: skip


@pytest.fixture(scope="module")
def free(tmp_path_factory):
    """A free truss in the Buckens frame: Rayleigh damping, outputs elsewhere than the inputs,
    stiffening from a matrix file, reduced by two-sided Krylov (an oblique projection: W is not
    V) and by SOAGA (an error estimator curve)."""
    body = space_truss()
    k_g = tmp_path_factory.mktemp("kg") / "KG.mtx"
    scipy.io.mmwrite(k_g, sp.csr_matrix(body.stiffness) * 1e-3)
    prepared = pm.prepare(body, "buckens", inputs=[(1, "ux uy uz")],
                          outputs=[(24, "ux uy uz"), (1, "ux")], inertia_loads=["ax", "wzz"],
                          stiffening={"wzz": k_g},
                          damping={"kind": "rayleigh", "alpha": 2.0, "beta": 1e-5})  # fmt: skip
    oblique = pm.reduce(prepared, "krylov", expansion_points_hz=[0, 1000], moments=[2, 2],
                        two_sided=True)  # fmt: skip
    soaga = pm.reduce(prepared, "soaga", band_hz=(0, 2000), tolerance=1e-6)
    return oblique, soaga


def same_system(a: pm.SecondOrderSystem, b: pm.SecondOrderSystem) -> None:
    for key in ("mass", "stiffness", "damping", "input_matrix", "output_matrix", "static_load",
                "rigid_modes"):  # fmt: skip
        x, y = getattr(a, key), getattr(b, key)
        assert (x is None) == (y is None), key
        if x is not None:
            assert sp.issparse(x) == sp.issparse(y), key
            x, y = (m.toarray() if sp.issparse(m) else np.asarray(m) for m in (x, y))
            np.testing.assert_array_equal(x, y, err_msg=key)
    assert (a.input_labels, a.output_labels) == (b.input_labels, b.output_labels)
    assert (a.loss_factor, a.modal_damping_ratio) == (b.loss_factor, b.modal_damping_ratio)


def same_model(a: pm.ReducedModel, b: pm.ReducedModel) -> None:
    np.testing.assert_array_equal(a.eigenfrequencies_hz, b.eigenfrequencies_hz)
    np.testing.assert_array_equal(a.projection.V, b.projection.V)
    np.testing.assert_array_equal(a.projection.W, b.projection.W)
    assert a.projection.one_sided == b.projection.one_sided
    assert a.projection.parameters == b.projection.parameters
    assert (a.projection.error_estimate, a.projection.error_bound) == (
        b.projection.error_estimate, b.projection.error_bound)  # fmt: skip
    same_system(a.system, b.system)


def round_trip(reduced: pm.ReducedBody, path: Path) -> pm.ReducedBody:
    assert reduced.save(path) == path
    loaded = pm.load(path)
    assert isinstance(loaded, pm.ReducedBody)
    assert repr(loaded) == repr(reduced) and loaded.name == reduced.name
    assert loaded.options == reduced.options
    same_model(loaded.model, reduced.model)
    same_system(loaded.prepared.system, reduced.prepared.system)
    same_system(loaded.prepared.reduction_system, reduced.prepared.reduction_system)
    assert loaded.prepared.frame == reduced.prepared.frame
    assert loaded.prepared.warnings == reduced.prepared.warnings
    assert loaded.prepared.notes == reduced.prepared.notes
    return loaded


@pytest.mark.slow
def test_a_saved_tangent_body_evaluates_and_exports_as_the_original(tangent, tmp_path):
    loaded = round_trip(tangent, tmp_path / "rack.h5")
    assert loaded.before_removal is not None
    same_model(loaded.before_removal, tangent.before_removal)
    assert loaded.prepared.body.damping == pm.Damping("modal", ratio=0.02)
    # the error curve against the full model, ports and inertia loads
    mine, theirs = loaded.error((0, 1000), points=8), tangent.error((0, 1000), points=8)
    assert mine.max > 0 and mine.max_inertia > 0
    np.testing.assert_array_equal(mine.relative, theirs.relative)
    np.testing.assert_array_equal(mine.inertia, theirs.inertia)
    # the exported bodies, byte for byte (stiffening terms and inertia loads go into the SID)
    a = tangent.to_sid(tmp_path / "a.SID_FEM", nodes=[1, 2]).read_bytes()
    assert loaded.to_sid(tmp_path / "b.SID_FEM", nodes=[1, 2]).read_bytes() == a
    assert b"Geo_Stiff= yes" in a
    a = tangent.to_exudyn(tmp_path / "a.npz", nodes=[1, 2]).read_bytes()
    assert loaded.to_exudyn(tmp_path / "b.npz", nodes=[1, 2]).read_bytes() == a


@pytest.mark.slow
def test_the_other_exports_of_a_loaded_body_are_the_originals(tangent, tmp_path):
    loaded = pm.load(tangent.save(tmp_path / "rack.h5"))
    a = tangent.to_neweul(tmp_path / "a.mat", nodes=[1, 2]).read_bytes()
    assert loaded.to_neweul(tmp_path / "b.mat", nodes=[1, 2]).read_bytes() == a
    assert (tangent.to_vtu(tmp_path / "a.vtu").read_bytes()
            == loaded.to_vtu(tmp_path / "b.vtu").read_bytes())  # fmt: skip
    pairs = zip(tangent.to_matrices(tmp_path / "ma", formats=("npz", "mtx", "mat")),
                loaded.to_matrices(tmp_path / "mb", formats=("npz", "mtx", "mat")),
                strict=True)  # fmt: skip
    for a, b in pairs:
        assert a.name == b.name and a.read_bytes() == b.read_bytes(), a.name


def test_a_saved_free_body_keeps_its_oblique_basis_estimator_and_stiffening(free, tmp_path):
    oblique, soaga = free
    assert not oblique.projection.one_sided and soaga.projection.error_curve is not None
    loaded = round_trip(oblique, tmp_path / "oblique.h5")
    assert not loaded.projection.one_sided
    assert loaded.prepared.frame == pm.Frame("buckens")
    assert loaded.prepared.system.rigid_modes.shape == (72, 6)
    np.testing.assert_array_equal(loaded.error((0, 2000), 12).relative,
                                  oblique.error((0, 2000), 12).relative)  # fmt: skip
    loaded = round_trip(soaga, tmp_path / "soaga.h5")
    for a, b in zip(loaded.projection.error_curve, soaga.projection.error_curve, strict=True):
        np.testing.assert_array_equal(a, b)
    original = loaded.prepared.stiffening
    assert original.source == "matrices" and list(original.cases) == ["wzz"]
    np.testing.assert_array_equal(original.cases["wzz"].toarray(),
                                  soaga.prepared.stiffening.cases["wzz"].toarray())  # fmt: skip
    a = soaga.to_sid(tmp_path / "a.SID_FEM", nodes=[1, 24]).read_bytes()
    assert loaded.to_sid(tmp_path / "b.SID_FEM", nodes=[1, 24]).read_bytes() == a


@pytest.fixture(scope="module")
def saved(tangent, tmp_path_factory):
    return tangent.save(tmp_path_factory.mktemp("saved") / "rack.h5")


def one_line_error(path: Path, pattern: str, call=pm.load) -> None:
    with pytest.raises(pm.UserError, match=pattern) as caught:
        call(path)
    assert "\n" not in str(caught.value) and str(caught.value).startswith(str(path))


def test_a_truncated_file_is_one_line(saved, tmp_path):
    data = saved.read_bytes()
    for cut in (len(data) // 2, len(data) - 100, 1000):
        path = tmp_path / f"cut{cut}.h5"
        path.write_bytes(data[:cut])
        one_line_error(path, "cannot read|not an HDF5 file")


def damaged(path: Path, dataset: str, out: Path) -> Path:
    """A copy of ``path`` with one bit flipped in the middle of a dataset's stored bytes."""
    with h5py.File(path, "r") as f:
        chunk = f[dataset].id.get_chunk_info(0)
    data = bytearray(path.read_bytes())
    data[chunk.byte_offset + chunk.size // 2] ^= 0x10
    out.write_bytes(bytes(data))
    return out


def test_damaged_data_is_refused_by_its_checksum(saved, tmp_path):
    """One bit changed in the basis V, or in K of a model file (the same writer): read wrong
    before, refused now."""
    path = damaged(saved, "reduced/projection/V", tmp_path / "damaged.h5")
    one_line_error(path, "cannot read the body: the file is damaged: an array fails its checksum")
    model = write_body_h5(pm.example("rack-beams"), tmp_path / "model.h5")
    path = damaged(model, "stiffness/data", tmp_path / "damaged-model.h5")
    one_line_error(path, "the file is damaged: an array fails its checksum", call=pm.read)


def edited(saved: Path, tmp_path: Path, edit) -> Path:
    path = tmp_path / "edited.h5"
    shutil.copy(saved, path)
    with h5py.File(path, "r+") as f:
        edit(f)
    return path


@pytest.mark.parametrize(
    ("edit", "pattern"),
    [
        (lambda f: f.attrs.__setitem__("version", 2),
         r"format version 2 is newer than this pymorembs reads \(version 1\); update pymorembs"),
        (lambda f: f.attrs.__setitem__("format", "something-else"),
         "without the format marker 'pymorembs-reduced-body'; not a reduced body saved by "
         "ReducedBody.save"),
        (lambda f: f.__delitem__("reduced"), "/reduced is missing"),
        (lambda f: f.__delitem__("prepared/elimination/transform"),
         "/prepared/elimination/transform is missing"),
        (lambda f: f["reduced/system"].__delitem__("input_labels"),
         "/reduced/system/input_labels is missing or not a list of texts"),
        (lambda f: f["options"].attrs.__setitem__("method", "krylow"),
         "/options: method: unknown method 'krylow'; did you mean 'krylov'"),
    ],
)  # fmt: skip
def test_a_foreign_newer_or_incomplete_file_is_one_line(saved, tmp_path, edit, pattern):
    one_line_error(edited(saved, tmp_path, edit), pattern)


def test_each_kind_of_file_points_to_its_reader(saved, tmp_path, capsys):
    one_line_error(saved, "a reduced body saved by ReducedBody.save, not an FE model; open it "
                          r"with pymorembs.load\(path\)", call=pm.read)  # fmt: skip
    model = write_body_h5(pm.example("rack-beams"), tmp_path / "model.h5")
    one_line_error(model, r"an FE model \(a pymorembs body file\), not a saved reduced body; "
                          r"read it with pymorembs.read\(path\)")  # fmt: skip
    (tmp_path / "text.h5").write_text("not hdf5\n")
    one_line_error(tmp_path / "text.h5", "not an HDF5 file")
    one_line_error(tmp_path / "missing.h5", "file not found")
    assert main(["info", str(saved)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "open it with pymorembs.load(path)" in err
    matrices = saved.parent / "matrices"
    pm.load(saved).to_matrices(matrices, formats=["npz"])
    one_line_error(matrices / "reduced.npz", "not an FE model.*pymorembs.load", call=pm.read)


def test_the_documented_layout_is_the_file(saved, free, tmp_path):
    """Every path of docs/api.md's table is in a saved file with the shape the table gives (the
    optional ones in one of three files, but for the body's own optional parts), and reading the
    file with h5py alone gives the body's matrices."""
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    section = text.split("\n### The saved file\n", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| `(/[^`<]*)` \| ([^|]*) \| ([^|]*) \|$", section, flags=re.MULTILINE)
    assert len(rows) >= 50
    others = [free[0].save(tmp_path / "oblique.h5"), free[1].save(tmp_path / "soaga.h5")]
    reduced = pm.load(saved)
    sizes = {"n": 3996, "n_i": 3942, "m": 11, "p₀": 3, "r₀": 3, "k": 2, "p": 5, "r": 5,
             "n_nodes": 666, "n_d": 48, "n_c": 6}  # fmt: skip
    assert reduced.order == sizes["m"] and reduced.prepared.body.n_dof == sizes["n"]
    with h5py.File(saved, "r") as f:
        for path, shape, meaning in rows:
            if path not in f:
                assert meaning.startswith("optional"), path
                if not path.startswith("/body/"):
                    assert any(path in h5py.File(other, "r") for other in others), path
                continue
            found = re.search(r"\(([^)]*)\)", shape)
            node = f[path]
            if found:
                want = tuple(sizes.get(s.strip(), s.strip()) for s in found.group(1).split(","))
                got = tuple(node.attrs["shape"]) if isinstance(node, h5py.Group) else node.shape
                if all(isinstance(s, int) for s in want):
                    assert got == want, (path, got, want)
        np.testing.assert_array_equal(f["reduced/system/stiffness"][()], reduced.system.stiffness)
        np.testing.assert_array_equal(f["reduced/projection/V"][()], reduced.projection.V)
        labels = tuple(f["reduced/system/input_labels"].asstr()[()])
        assert labels == reduced.system.input_labels == ("1:ux", "1:uy", "1:uz", "inertia:ax",
                                                         "inertia:wzz")  # fmt: skip
        group = f["prepared/system/stiffness"]
        k = sp.csr_matrix((group["data"][()], group["indices"][()], group["indptr"][()]),
                          shape=tuple(group.attrs["shape"]))  # fmt: skip
        assert (k != reduced.prepared.system.stiffness).nnz == 0
        assert f.attrs["format"] == "pymorembs-reduced-body" and f.attrs["version"] == 1
