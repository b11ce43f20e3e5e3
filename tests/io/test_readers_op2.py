"""Nastran OP2 files through pyNastran: the genuine Simcenter 2412 file, damaged files.

The genuine file holds KGG (no MGG although the deck asked for it), element matrices KELM/MELM,
and the geometry tables EQEXIN and BGPDT. Its dof table and coordinates are checked against the
GRID cards of the input deck, parsed here with plain Python, and by the rigid-body check.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pymorembs.errors import UserError
from pymorembs.io.nastran_op2 import read_op2
from pymorembs.io.pynastran_compat import numpy_with_in1d, op2_class

pytest.importorskip("pyNastran")

DATA = Path(__file__).parents[1] / "data" / "pynastran" / "op2_kgg_kelm"
OP2 = DATA / "static_solid_shell_bar_kelm.op2"


def deck_grids() -> dict[int, tuple[float, float, float]]:
    """GRID cards (small field) of the input deck and its include, parsed here."""
    grids = {}
    for name in ("static_solid_shell_bar_kelm.bdf", "geom.inc"):
        for line in (DATA / name).read_text().splitlines():
            if line.startswith("GRID"):
                fields = [line[8 * k : 8 * k + 8].strip() for k in range(1, 6)]
                grids[int(fields[0])] = tuple(float(f or 0) for f in fields[2:5])
    return grids


def test_op2_without_mass_says_what_it_holds() -> None:
    with pytest.raises(UserError) as err:
        read_op2(OP2)
    assert str(err.value) == (
        f"{OP2}: holds KGG (stiffness, 150 x 150) but no mass matrix (no MGG); the file also "
        "holds KELM (300 x 21), MELM (300 x 21); export the mass matrix too or name it with "
        "--mass-name (MELM and MDICT hold element mass matrices; pymorembs does not assemble "
        "them into MGG)"
    )


def test_op2_dof_table_and_coordinates() -> None:
    """KGG read with itself as the 'mass' to check the g-set table from EQEXIN and BGPDT."""
    body = read_op2(OP2, mass="KGG")
    assert body.dofs.describe() == "25 nodes x ux uy uz rx ry rz"
    assert body.dofs.nodes.tolist() == [g for g in range(1, 26) for _ in range(6)]
    assert body.stiffness.nnz == 2677  # 2679 stored entries, 2 of them zero
    grids = deck_grids()
    assert sorted(grids) == list(range(1, 26))
    np.testing.assert_array_equal(body.coordinates, [grids[g] for g in body.node_ids])
    assert np.nanmax(body.rigid_body_residuals()) < 1e-14
    assert "coordinates from the BGPDT table (basic system)" in body.notes
    assert len(body.fixed) == 35  # rotations of grids joined by solid elements only
    deck = read_op2(OP2, mass="KGG", nodes=DATA / "static_solid_shell_bar_kelm.bdf")
    np.testing.assert_array_equal(deck.coordinates, body.coordinates)


def test_op2_damaged_files(tmp_path: Path) -> None:
    data = OP2.read_bytes()
    for size in (60, len(data) // 2):
        cut = tmp_path / "cut.op2"
        cut.write_bytes(data[:size])
        with pytest.raises(UserError) as err:
            read_op2(cut)
        message = str(err.value)
        assert "\n" not in message and message.startswith(f"{cut}: ")
    with pytest.raises(UserError, match="file not found"):
        read_op2(tmp_path / "none.op2")


def test_numpy_in1d_shim() -> None:
    """pyNastran's OP2 reader imports with this NumPy; the shim is NumPy's old in1d."""
    assert op2_class().__name__ == "OP2"
    a, b = np.array([[1, 2], [3, 4]]), np.array([2, 3])
    with numpy_with_in1d():
        np.testing.assert_array_equal(np.in1d(a, b), [False, True, True, False])  # noqa: NPY201
        np.testing.assert_array_equal(np.in1d(a, b, invert=True), [True, False, False, True])  # noqa: NPY201


def test_reading_an_op2_file_leaves_numpy_as_it_was() -> None:
    """Issue #28: the shim lives for the calls into pyNastran only, not for the process: after
    a read (and a read that ends in an error) NumPy has ``in1d`` only if it has its own."""
    own = np.lib.NumpyVersion(np.__version__) < "2.4.0"  # NumPy 2.4 removed in1d
    read_op2(OP2, mass="KGG")
    assert hasattr(np, "in1d") == own
    with pytest.raises(UserError):
        read_op2(OP2)
    assert hasattr(np, "in1d") == own
