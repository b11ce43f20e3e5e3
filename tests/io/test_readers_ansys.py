"""Readers for Ansys exports: the binary .full file, its archive (.cdb) and MMF + mapping files.

Genuine files (``tests/data/pymapdl_reader_hexbeam``, MIT, from ansys/pymapdl-reader): the
``file.full`` of a clamped 1 x 1 x 5 beam of 40 SOLID186 (Ansys MAPDL 15.0, 963 equations, 63
constrained), the archive ``HexBeam.cdb`` of the same mesh and the modal result ``file.rst``.
The published reference: "First four natural frequencies 1283.200, 1283.200, 5781.975,
6919.399 Hz" (``doc_user_guide_loading_km.rst``, computed by the docs with scipy on the same
file). Variants of the genuine ``.full`` with records re-encoded in the compressed forms of Ansys
19+ are built here and first checked with ansys-mapdl-reader itself (peer check: the variant is a
file the library reads to the same matrices), because no genuine compressed ``.full`` file with a
licence could be obtained.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.errors import UserError
from pymorembs.io.ansys import RIGID_BODY_TOLERANCE, read_ansys_full, read_ansys_mmf
from pymorembs.io.ansys_cdb import read_cdb
from pymorembs.preparation.consistency import body_rounding, check_map

reader = pytest.importorskip("ansys.mapdl.reader")

DATA = Path(__file__).parents[1] / "data" / "pymapdl_reader_hexbeam"
FULL = DATA / "file.full"
CDB = DATA / "HexBeam.cdb"
RST = DATA / "file.rst"
PUBLISHED_HZ = [1283.200, 1283.200, 5781.975, 6919.399]  # doc_user_guide_loading_km.rst


def _one_line_error(excinfo: pytest.ExceptionInfo[UserError], path: Path, line: int | None = None):
    """The message is one line that starts with the file (and line)."""
    message = str(excinfo.value)
    assert "\n" not in message
    prefix = f"{path}:{line}: " if line is not None else f"{path}"
    assert message.startswith(prefix), message
    return message


# ============================================================================ raw .full records
# An independent walk over the records of a .full file (layout: Ansys fddesc.inc -- [n, flags,
# n words, n]) used to check the reader and to build the compressed variants.
HEADER_AT = 103  # the .full header follows the 100-word standard header record


@dataclass
class Record:
    start: int  # word position in the file
    flags: int  # the second header word
    data: np.ndarray  # the stored words


def records_of(words: np.ndarray, end: int) -> list[Record]:
    """All records from the start of the file up to word ``end`` (the file is a chain of them)."""
    out, p = [], 0
    while p < end:
        n = int(words[p])
        assert words[p + 2 + n] == n
        out.append(Record(p, int(words[p + 1]), words[p + 2 : p + 2 + n].copy()))
        p += n + 3
    assert p == end
    return out


def header_pointers() -> dict[str, int]:
    """Index of the low word of every 64-bit pointer in the .full header (ptrXXXl)."""
    from ansys.mapdl.reader.full import SYMBOLIC_FULL_HEADER_KEYS

    keys = SYMBOLIC_FULL_HEADER_KEYS
    return {k[:-1]: keys.index(k) for k in keys if k.startswith("ptr") and k.endswith("l")}


def header_item(key: str) -> int:
    from ansys.mapdl.reader.full import SYMBOLIC_FULL_HEADER_KEYS

    return SYMBOLIC_FULL_HEADER_KEYS.index(key)


def long_of(header: np.ndarray, low: int) -> int:
    return (int(header[low + 1]) << 32) | (int(header[low]) & 0xFFFFFFFF)


def parse_matrix(words: np.ndarray, pointer: int, neqn: int) -> sp.csr_matrix:
    """One matrix block (per equation an int32 row-index record and a float64 value record)."""
    rows, cols, values = [], [], []
    p = pointer
    for j in range(neqn):
        n = int(words[p])
        rows.append(words[p + 2 : p + 2 + n] - 1)
        q = p + n + 3
        values.append(words[q + 2 : q + 2 + 2 * n].view("<f8"))
        cols.append(np.full(n, j))
        p = q + 2 * n + 3
    r, c, v = (np.concatenate(x) for x in (rows, cols, values))
    upper = sp.csr_matrix((v, (np.minimum(r, c), np.maximum(r, c))), shape=(neqn, neqn))
    return sp.csr_matrix(upper + sp.triu(upper, 1).T)


# ------------------------------------------------------------------ encoders (Ansys 19+ forms)
BIT_SPARSE, WINDOWED, ZLIB, SHORT, INTEGER = 1 << 3, 1 << 4, 1 << 5, 1 << 6, 1 << 7


def bit_sparse(values: np.ndarray) -> np.ndarray:
    """``size, bit code, values whose bit is set`` (at most 32 items)."""
    assert values.size <= 32
    code = sum(1 << i for i in np.flatnonzero(values))
    return np.concatenate([[values.size, np.uint32(code).view(np.int32)], values[values != 0]])


def windowed(values: np.ndarray, isolated: bool = True) -> np.ndarray:
    """``size, number of windows``, then per run of non-zero items an isolated value
    (``index > 0, value``), a constant window (``-start, -length, value``) or a window of values
    (``-start, length, values``)."""
    out, windows, i, n = [], 0, 0, values.size
    while i < n:
        if values[i] == 0:
            i += 1
            continue
        j = i
        while j < n and values[j] != 0:
            j += 1
        run = values[i:j]
        if isolated and run.size == 1 and i > 0:
            out += [i, int(run[0])]
        elif run.size > 1 and np.all(run == run[0]):
            out += [-i, -run.size, int(run[0])]
        else:
            out += [-i, run.size, *run.tolist()]
        windows += 1
        i = j
    return np.array([n, windows, *out], dtype=np.int32)


def constant_window(values: np.ndarray) -> np.ndarray:
    """The one-window form of a constant record: 5 words (the dofs-per-node record of 20.1)."""
    assert np.all(values == values[0])
    return np.array([values.size, 1, 0, -values.size, values[0]], dtype=np.int32)


def zlib_words(values: np.ndarray) -> np.ndarray:
    """A zlib-compressed record: the deflated bytes, padded to whole words."""
    import zlib

    packed = zlib.compress(values.astype("<i4").tobytes())
    return np.frombuffer(packed + bytes(-len(packed) % 4), dtype="<i4")


def rewrite_full(
    source: Path, target: Path, encode: dict[str, tuple[object, int]], header_edit=None
) -> Path:
    """A copy of a .full file with records re-encoded and all header pointers moved.

    ``encode`` maps a record name (``header``, ``dof``, ``equivalence``, ``ndof``, ``const``,
    ``stiffness0`` = first index record of the stiffness block) to ``(encoder, flag bits)``.
    """
    words = np.fromfile(source, dtype="<i4")
    header = words[HEADER_AT + 2 : HEADER_AT + 2 + int(words[HEADER_AT])].copy()
    pointers = header_pointers()
    end = long_of(header, pointers["ptrEND"])
    chain = records_of(words, end)
    position = {r.start: k for k, r in enumerate(chain)}
    ptr_dof = position[long_of(header, pointers["ptrDOF"])]
    names = {"header": 1, "dof": 2, "equivalence": 3, "ndof": ptr_dof, "const": ptr_dof + 1}
    names["stiffness0"] = position[long_of(header, pointers["ptrSTF"])]
    if header_edit is not None:
        header_edit(header)
    chain[1].data = header
    payloads = []
    for k, record in enumerate(chain):
        data, flags = record.data, record.flags
        for name, (encoder, bits) in encode.items():
            if names[name] == k:
                data = np.asarray(encoder(data), dtype=np.int32)
                flags = (flags & 0x00FFFFFF) | ((((flags >> 24) & 0xFF) | bits) << 24)
                flags = np.uint32(flags & 0xFFFFFFFF).view(np.int32)
        payloads.append((data, flags))
    new_start, p = {}, 0
    for record, (data, _) in zip(chain, payloads, strict=True):
        new_start[record.start] = p
        p += data.size + 3
    moved = header.copy()
    for key, low in pointers.items():
        old = long_of(header, low)
        new = p if key == "ptrEND" else new_start.get(old, 0) if old else 0
        moved[low] = np.uint32(new & 0xFFFFFFFF).view(np.int32)
        moved[low + 1] = new >> 32
    if names["header"] not in {names[n] for n in encode}:
        payloads[1] = (moved, payloads[1][1])
    else:
        encoder, _ = encode["header"]
        payloads[1] = (np.asarray(encoder(moved), dtype=np.int32), payloads[1][1])
    out = []
    for data, flags in payloads:
        out.append(np.array([data.size, flags], dtype=np.int32))
        out.append(data.astype(np.int32))
        out.append(np.array([data.size], dtype=np.int32))
    out.append(words[end:])
    np.concatenate(out).astype("<i4").tofile(target)
    return target


def library_model(path: Path):
    """dof_ref, K and M as ansys-mapdl-reader reads them (the peer)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        full = reader.read_binary(str(path))
        dof_ref, k, m = full.load_km(sort=False)
    return dof_ref, k, m, full.const


# ============================================================================ .full
@pytest.fixture(scope="module")
def full_body():
    return read_ansys_full(FULL)


def test_hexbeam_published_frequencies_and_independent_parse(full_body):
    """K and M equal an independent parse of the records; eigsh gives the published values."""
    body = full_body
    assert body.n_dof == 963 and body.name == "file" and not body.has_coordinates
    words = np.fromfile(FULL, dtype="<i4")
    header = words[HEADER_AT + 2 : HEADER_AT + 102]
    pointers = header_pointers()
    ptr_dof = long_of(header, pointers["ptrDOF"])
    const = words[ptr_dof + 2 + 321 + 3 : ptr_dof + 2 + 321 + 3 + 963]
    constrained = const < 0
    for key, matrix in (("ptrSTF", body.stiffness), ("ptrMAS", body.mass)):
        parsed = parse_matrix(words, long_of(header, pointers[key]), 963)
        keep = ~constrained
        expected = sp.diags(keep.astype(float)) @ parsed @ sp.diags(keep.astype(float))
        assert abs(matrix - expected).max() == 0.0
        assert abs(matrix - matrix.T).max() == 0.0
    free = np.flatnonzero(~constrained)
    np.testing.assert_array_equal(np.setdiff1d(np.arange(963), body.fixed), free)
    k = body.stiffness[free][:, free].tocsc()
    m = body.mass[free][:, free].tocsc()
    values = spla.eigsh(k, k=6, M=m, sigma=0.0, which="LM", return_eigenvectors=False)
    hz = np.sort(np.sqrt(values))[:4] / (2 * np.pi)
    np.testing.assert_allclose(hz, PUBLISHED_HZ, rtol=1e-6)  # printed with 7 digits
    assert any("63 dofs constrained in Ansys are fixed dofs" in note for note in body.notes)
    assert "321 nodes x ux uy uz" in body.notes[0] and "Ansys MAPDL 15.0" in body.notes[0]


def test_full_fixed_dofs_and_dof_table(full_body):
    """Constrained dofs become fixed dofs with empty rows; the dof table matches the library."""
    body = full_body
    dof_ref, _, _, const = library_model(FULL)
    np.testing.assert_array_equal(body.dofs.nodes, dof_ref[:, 0])
    np.testing.assert_array_equal(body.dofs.directions, dof_ref[:, 1])  # UX UY UZ only
    constrained = {(int(n), int(d)) for n, d in const}
    fixed = {(int(body.dofs.nodes[i]), int(body.dofs.directions[i])) for i in body.fixed}
    assert fixed == constrained and len(fixed) == 63
    assert body.stiffness[body.fixed].nnz == 0 and body.mass[body.fixed].nnz == 0
    assert body.damping_matrix is None
    assert np.all(body.coordinates == 0.0)


def test_hexbeam_coordinates_from_the_archive():
    """The .cdb gives the coordinates and the nodes next to the clamp; the consistency check
    proves them away from the clamp."""
    body = read_ansys_full(FULL, nodes=CDB)
    assert body.has_coordinates and body.n_nodes == 321
    archive = reader.Archive(str(CDB), parse_vtk=False)
    np.testing.assert_array_equal(body.node_ids, archive.nnum)
    np.testing.assert_allclose(body.coordinates, archive.nodes, rtol=0, atol=1e-14)
    proof = check_map(body, body_rounding(body))
    assert proof.proved and "leave no force in 810 of 900 rows" in proof.reason, proof
    # the check itself, computed here: K r on the equations of the nodes far from the clamp
    clamped = {int(n) for n in body.dofs.nodes[body.fixed]}
    near = set()
    for element in archive.elem:
        nodes = {int(v) for v in element[10:] if v > 0}
        if nodes & clamped:
            near |= nodes
    rows = ~np.isin(body.dofs.nodes, sorted(near))
    assert rows.sum() == 810
    r = body.rigid_body_modes(body.coordinates.mean(axis=0))
    k = body.stiffness[rows]
    scale = abs(k).sum(axis=1).max()
    residual = np.linalg.norm(k @ r, axis=0) / (scale * np.linalg.norm(r, axis=0))
    assert residual.max() < 1e-14
    # all free rows (as ElasticBody.rigid_body_residuals sees them): the clamp shows
    assert body.rigid_body_residuals().min() > 1e-3


def test_archive_parse_equals_ansys_mapdl_reader():
    """read_cdb against the library's Archive on the genuine archives it ships."""
    from ansys.mapdl.reader import examples

    folder = Path(examples.__file__).parent
    for name in ("HexBeam.cdb", "TetBeam.cdb", "sector.cdb"):
        mine, theirs = read_cdb(folder / name), reader.Archive(str(folder / name), parse_vtk=False)
        np.testing.assert_array_equal(mine.node_ids, theirs.nnum)
        np.testing.assert_allclose(mine.coordinates, theirs.nodes, rtol=1e-14, atol=1e-14)
        np.testing.assert_array_equal(mine.angles, theirs.node_angles)
        np.testing.assert_array_equal(mine.element_ids, theirs.enum)
        for k in (0, len(theirs.elem) // 2, len(theirs.elem) - 1):
            expected = [int(v) for v in theirs.elem[k][10:] if v > 0]
            got = mine.element_nodes[mine.element_offsets[k] : mine.element_offsets[k + 1]]
            assert got.tolist() == expected
    # the text is parsed exactly (correct rounding): one coordinate checked by hand
    line = next(t for t in CDB.read_text().splitlines() if t.startswith("      318 "))
    archive = read_cdb(CDB)
    assert archive.coordinates[list(archive.node_ids).index(318)].tolist() == [
        float(line[27 + 21 * j : 27 + 21 * (j + 1)]) for j in range(3)
    ]


def test_wrong_coordinates_are_refused(tmp_path):
    """Two nodes' coordinates swapped in the archive: the rotations fail, the file is refused."""
    lines = CDB.read_text().split("\n")
    first = next(k for k, t in enumerate(lines) if t.startswith("NBLOCK")) + 2
    a, b = first + 100, first + 200
    lines[a], lines[b] = lines[a][:27] + lines[b][27:], lines[b][:27] + lines[a][27:]
    bad = tmp_path / "swapped.cdb"
    bad.write_text("\n".join(lines))
    body = read_ansys_full(FULL, nodes=bad)
    with pytest.raises(UserError, match="this map does not fit K") as info:
        check_map(body, body_rounding(body))
    message = _one_line_error(info, "[model]: ")
    assert "the dof table or the node coordinates do not belong to the matrices" in message


def test_nodes_csv_on_the_clamped_beam_is_proved_by_the_reach_of_the_supports(tmp_path):
    archive = read_cdb(CDB)
    rows = [
        f"{n},{x!r},{y!r},{z!r}"
        for n, (x, y, z) in zip(archive.node_ids, archive.coordinates.tolist(), strict=True)
    ]
    nodes = tmp_path / "nodes.csv"
    nodes.write_text("id,x,y,z\n" + "\n".join(rows[::-1]) + "\n")
    body = read_ansys_full(FULL, nodes=nodes, name="beam")
    assert body.name == "beam" and body.has_coordinates
    np.testing.assert_array_equal(body.node_position(318), [0.75, 0.5, 3.0])
    assert body.nodes_near_supports is None  # no elements: the consistency check judges by reach
    proof = check_map(body, body_rounding(body))
    assert proof.proved and "leave no force in 810 of 900 rows" in proof.reason, proof
    short = tmp_path / "short.csv"
    short.write_text("id,x,y,z\n" + "\n".join(rows[1:]) + "\n")
    with pytest.raises(UserError, match="node 1 ") as info:
        read_ansys_full(FULL, nodes=short)
    _one_line_error(info, short)


def test_rst_is_the_free_free_analysis_of_the_same_matrices():
    """file.rst vs file.full: same K and M (mode shapes satisfy K x = w^2 M x away from the
    clamp to 1e-6), but the .rst is free-free (its modes move the nodes the .full clamps)."""
    import warnings

    body = read_ansys_full(FULL, nodes=CDB)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = reader.read_binary(str(RST))
        frequencies = np.asarray(result.time_values)
        shapes = []
        for mode in range(6):
            nnum, disp = result.nodal_displacement(mode)
            index = {int(n): i for i, n in enumerate(nnum)}
            rows = [index[int(n)] for n in body.dofs.nodes]
            shapes.append(disp[rows, body.dofs.directions])
    np.testing.assert_allclose(frequencies[[0, 2, 5]], [7366.495, 11504.895, 20137.193], rtol=1e-7)
    archive = read_cdb(CDB)
    far = ~np.isin(body.dofs.nodes, archive.neighbours(body.dofs.nodes[body.fixed]))
    clamped = np.zeros(body.n_dof, dtype=bool)
    clamped[body.fixed] = True
    for x, f in zip(shapes, frequencies, strict=True):
        kx, mx = body.stiffness @ x, body.mass @ x
        residual = np.linalg.norm((kx - (2 * np.pi * f) ** 2 * mx)[far]) / np.linalg.norm(kx[far])
        assert residual < 2e-6
        assert np.abs(x[clamped]).max() > 0.5 * np.abs(x).max()  # not clamped in the .rst


@pytest.mark.parametrize(
    "encode",
    [
        pytest.param({"ndof": (constant_window, WINDOWED)}, id="ndof-constant-window"),
        pytest.param({"ndof": (windowed, WINDOWED), "const": (windowed, WINDOWED)}, id="windows"),
        pytest.param({"dof": (bit_sparse, BIT_SPARSE)}, id="dof-bit-sparse"),
        pytest.param(
            {"header": (windowed, WINDOWED), "equivalence": (windowed, WINDOWED)}, id="header"
        ),
    ],
)
def test_compressed_records_read_like_the_library_reads_them(tmp_path, encode, full_body):
    """(a) ansys-mapdl-reader reads the variant to the same model (it is a valid file);
    (b) read_ansys_full reads it to the same body as the original."""
    variant = rewrite_full(FULL, tmp_path / "variant.full", encode)
    assert variant.stat().st_size != FULL.stat().st_size
    dof0, k0, m0, c0 = library_model(FULL)
    dof1, k1, m1, c1 = library_model(variant)
    np.testing.assert_array_equal(dof0, dof1)
    np.testing.assert_array_equal(c0, c1)
    assert abs(k0 - k1).max() == 0.0 and abs(m0 - m1).max() == 0.0
    body = read_ansys_full(variant)
    np.testing.assert_array_equal(body.dofs.nodes, full_body.dofs.nodes)
    np.testing.assert_array_equal(body.dofs.directions, full_body.dofs.directions)
    np.testing.assert_array_equal(body.fixed, full_body.fixed)
    assert abs(body.stiffness - full_body.stiffness).max() == 0.0
    assert abs(body.mass - full_body.mass).max() == 0.0
    assert "compressed records decoded" in body.notes[0]


def test_the_20_1_rotor_case_dofs_per_node_in_five_words(tmp_path):
    """The failure of issue 14: a windowed dofs-per-node record of 5 words is read."""
    variant = rewrite_full(FULL, tmp_path / "v.full", {"ndof": (constant_window, WINDOWED)})
    words = np.fromfile(variant, dtype="<i4")
    header = words[HEADER_AT + 2 : HEADER_AT + 102]
    ptr = long_of(header, header_pointers()["ptrDOF"])
    assert words[ptr] == 5 and list(words[ptr + 2 : ptr + 7]) == [321, 1, 0, -321, 3]
    body = read_ansys_full(variant)
    assert "dofs per node (windowed)" in body.notes[0]


@pytest.mark.parametrize(
    ("encode", "pattern"),
    [
        ({"ndof": (zlib_words, ZLIB)}, "dofs per node: the record is zlib"),
        ({"ndof": (lambda d: d, SHORT)}, "dofs per node: the record holds 16-bit integers"),
        (
            {"stiffness0": (bit_sparse, BIT_SPARSE)},
            "stiffness matrix: compressed records \\(first at equation 1\\)",
        ),
    ],
)
def test_records_the_library_would_misread_are_refused(tmp_path, encode, pattern):
    variant = rewrite_full(FULL, tmp_path / "v.full", encode)
    with pytest.raises(UserError, match=pattern) as info:
        read_ansys_full(variant)
    _one_line_error(info, variant)


# One child process imports ansys-mapdl-reader once and forks a grandchild per file, so that a
# crash of the library on one file is seen as an exit status: one line per file, "crash" or
# the sums of K, M and dof_ref.
LIBRARY_CHILD = """
import os, sys, warnings
warnings.simplefilter("ignore")
from ansys.mapdl.reader import read_binary
for path in sys.argv[1:]:
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read)
        d, k, m = read_binary(path).load_km(sort=False)
        os.write(write, f"{abs(k).sum()!r} {abs(m).sum()!r} {d.sum()}".encode())
        os._exit(0)
    os.close(write)
    _, status = os.waitpid(pid, 0)
    text = os.read(read, 1000).decode()
    print(text if os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0 else "crash")
"""

REFUSED = {
    "compressed-matrix-record": {"stiffness0": (bit_sparse, BIT_SPARSE)},
    "zlib-record": {"ndof": (zlib_words, ZLIB)},
    "window-overrun": {"ndof": (lambda _: np.array([321, 1, 0, -100000, 3]), WINDOWED)},
}


def test_what_is_refused_crashes_or_fools_the_library(tmp_path):
    """Why these files are refused: ansys-mapdl-reader crashes on them or returns another model
    (seen in a child process); read_ansys_full refuses each in one line."""
    import subprocess
    import sys

    variants = [rewrite_full(FULL, tmp_path / f"{k}.full", e) for k, e in REFUSED.items()]
    for variant in variants:
        with pytest.raises(UserError) as info:
            read_ansys_full(variant)
        _one_line_error(info, variant)
    child = subprocess.run(
        [sys.executable, "-c", LIBRARY_CHILD, str(FULL), *map(str, variants)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert child.returncode == 0, child.stderr
    original, *outcomes = child.stdout.split("\n")[: 1 + len(variants)]
    assert original != "crash"
    assert all(outcome != original for outcome in outcomes), outcomes
    assert outcomes[0] == "crash" and outcomes[2] == "crash"  # seen with 0.56.0


@pytest.mark.parametrize(
    ("data", "pattern"),
    [
        ([321, 1, 0, -322, 3], "window 1 \\(322 items from 0\\) overruns"),
        ([321, 2, 0, -320, 3], "window 2 of 2 is missing"),
        ([321, 1, 321, 3], "isolated value at 321 outside 321 items"),
        ([-5, 1, 0, -5, 3], "negative size -5"),
        ([321, 1, -300, 30, 3], "overruns the record"),
    ],
)
def test_damaged_compressed_records(tmp_path, data, pattern):
    """Windows the C reader would write past its buffer are refused before it runs."""
    variant = rewrite_full(
        FULL, tmp_path / "v.full", {"ndof": (lambda _: np.array(data), WINDOWED)}
    )
    with pytest.raises(UserError, match=f"dofs per node: damaged compressed record .*{pattern}"):
        read_ansys_full(variant)


def test_damaged_bit_sparse_record(tmp_path):
    variant = rewrite_full(
        FULL, tmp_path / "v.full", {"dof": (lambda _: np.array([3, 7, 1, 2]), BIT_SPARSE)}
    )
    with pytest.raises(UserError, match="announces 3 values but 2 are stored"):
        read_ansys_full(variant)
    variant = rewrite_full(
        FULL, tmp_path / "w.full", {"dof": (lambda _: np.array([40, 7, 1, 2, 3]), BIT_SPARSE)}
    )
    with pytest.raises(UserError, match="bit-coded record of 40 items; at most 32"):
        read_ansys_full(variant)


def _edit(key: str, value: int):
    def edit(header: np.ndarray) -> None:
        header[header_item(key)] = value

    return edit


@pytest.mark.parametrize(
    ("key", "value", "pattern"),
    [
        (
            "ntermMl",
            0,
            "the file holds no mass matrix, only a stiffness matrix \\(963 equations\\) and a load "
            "vector: it was written by a modal analysis",
        ),
        ("kan", 1, "buckling analysis \\(ANTYPE,BUCKLE\\): its second matrix is the stress"),
        ("lumpm", 1, "lumped mass matrix \\(LUMPM,ON\\) cannot be read"),
        ("keyuns", 1, "the matrices are unsymmetric"),
        ("ncefull", 4, "constraint equations \\(CE, CP or MPC contact\\)"),
    ],
)
def test_files_pymorembs_cannot_use_say_why(tmp_path, key, value, pattern):
    variant = rewrite_full(FULL, tmp_path / "v.full", {}, header_edit=_edit(key, value))
    with pytest.raises(UserError, match=pattern) as info:
        read_ansys_full(variant)
    _one_line_error(info, variant)


def test_static_full_file_says_what_it_holds(tmp_path):
    """Issue item 9: a .full of a static analysis (no mass matrix) says so in one line."""

    def static(header: np.ndarray) -> None:
        header[header_item("ntermMl")] = 0
        header[header_item("kan")] = 0

    variant = rewrite_full(FULL, tmp_path / "static.full", {}, header_edit=static)
    with pytest.raises(UserError) as info:
        read_ansys_full(variant)
    assert str(info.value) == (
        f"{variant}: the file holds no mass matrix, only a stiffness matrix (963 equations) and "
        "a load vector: it was written by a static analysis (ANTYPE,STATIC); write the .full "
        "file from a modal analysis (ANTYPE,MODAL with WRFULL,1)"
    )


def test_static_full_through_pymorembs_info(tmp_path, capsys):
    """The same refusal from the command line: exit code 2, one line, nothing on stdout."""
    from pymorembs.job.cli import main

    def static(header: np.ndarray) -> None:
        header[header_item("ntermMl")] = 0
        header[header_item("kan")] = 0

    variant = rewrite_full(FULL, tmp_path / "static.full", {}, header_edit=static)
    code = main(["info", str(variant)])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith(f"pymorembs: error: {variant}: the file holds no mass matrix")


def test_info_with_the_archive(capsys):
    """pymorembs info on the genuine .full with its .cdb: the published frequencies."""
    import json

    from pymorembs.job.cli import main

    code = main(["info", str(FULL), "--nodes", str(CDB), "--modes", "4", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    hz = json.loads(out)["eigenfrequencies_hz"]
    np.testing.assert_allclose(hz[:4], PUBLISHED_HZ, rtol=1e-6)


@pytest.mark.parametrize("size", [0, 30, 500, 2000, 300_000, 801_592])
def test_full_truncated(tmp_path, size):
    path = tmp_path / "cut.full"
    path.write_bytes(FULL.read_bytes()[:size])
    with pytest.raises(UserError) as excinfo:
        read_ansys_full(path)
    _one_line_error(excinfo, path)


def test_full_corrupt_matrix_block(tmp_path):
    """A damaged record length inside the stiffness block is caught before the C reader."""
    data = bytearray(FULL.read_bytes())
    pointer = 536  # ptrSTF of the example file (words)
    data[4 * pointer : 4 * pointer + 4] = (10**6).to_bytes(4, "little")
    path = tmp_path / "bad.full"
    path.write_bytes(bytes(data))
    with pytest.raises(UserError, match="stiffness matrix: damaged record") as excinfo:
        read_ansys_full(path)
    _one_line_error(excinfo, path)


def test_full_wrong_files(tmp_path):
    text = tmp_path / "notes.full"
    text.write_text("this is a text file, not a matrix file\n" * 20)
    with pytest.raises(UserError, match="not an Ansys binary file") as excinfo:
        read_ansys_full(text)
    _one_line_error(excinfo, text)
    rst = tmp_path / "result.full"
    shutil.copy(RST, rst)
    with pytest.raises(UserError, match=r"Result File, not a \.full file") as excinfo:
        read_ansys_full(rst)
    _one_line_error(excinfo, rst)
    with pytest.raises(UserError, match="file not found") as excinfo:
        read_ansys_full(tmp_path / "missing.full")
    _one_line_error(excinfo, tmp_path / "missing.full")
    with pytest.raises(UserError, match="is a directory"):
        read_ansys_full(tmp_path)
    notes = tmp_path / "nodes.txt"
    notes.write_text("no nodes here\n")
    unknown = r"no node coordinates: neither a nodes\.csv .* Ansys archive"
    with pytest.raises(UserError, match=unknown) as excinfo:
        read_ansys_full(FULL, nodes=notes)
    _one_line_error(excinfo, notes)


def test_full_damping_matrix_code_path(monkeypatch):
    """The damping block is read like K and M; fake one by pointing at the stiffness block."""
    import dataclasses

    import pymorembs.io.ansys as ansys_io

    real_scan = ansys_io._scan_full_file

    def scan_with_damping(path):
        info = real_scan(path)
        return dataclasses.replace(info, damping=(536, 39023))  # ptrSTF, ntermK of the example

    monkeypatch.setattr(ansys_io, "_scan_full_file", scan_with_damping)
    body = read_ansys_full(FULL)
    assert body.damping_matrix is not None
    assert abs(body.damping_matrix - body.stiffness).max() == 0.0


# ============================================================================ .cdb problems
def test_archive_problems(tmp_path):
    text = CDB.read_text()
    cases = {
        "no_nblock.cdb": (text.replace("NBLOCK", "XBLOCK"), None, "no NBLOCK"),
        "format.cdb": (text.replace("(3i9,6e21.13e3)", "(3i9,6f21.13)"), 36, "NBLOCK: format"),
        "field.cdb": (
            text.replace(" 2.5000000000000E-001", " 2.50000000000x0E-001"),
            39,
            "NBLOCK: x '2.50000000000x0E-001' is not a number",
        ),
        "twice.cdb": (
            text.replace("        4        0        0", "        3        0        0", 1),
            40,
            "NBLOCK: node 3 is listed twice \\(first on line 39\\)",
        ),
        "count.cdb": (
            text.replace("NBLOCK,6,SOLID,       321,       321", "NBLOCK,6,SOLID,321,322"),
            35,
            "NBLOCK announces 322 nodes but holds 321",
        ),
        "element.cdb": (
            text.replace("       286       240\n", "       286       999\n", 1),
            359,
            "EBLOCK: element 1 names node 999, which the NBLOCK does not define",
        ),
    }
    for name, (content, line, pattern) in cases.items():
        path = tmp_path / name
        path.write_text(content)
        with pytest.raises(UserError, match=pattern) as info:
            read_cdb(path)
        _one_line_error(info, path, line)
    rotated = tmp_path / "rotated.cdb"
    reals = "".join(f"{v:21.13E}" for v in (0.5, 0.0, 0.0, 30.0))
    line4 = "        4        0        0 5.0000000000000E-001\n"
    rotated.write_text(text.replace(line4, "        4        0        0" + reals + "\n"))
    assert read_cdb(rotated).angles[3].tolist() == [30.0, 0.0, 0.0]
    with pytest.raises(UserError, match="node 4 has a rotated nodal coordinate system") as info:
        read_ansys_full(FULL, nodes=rotated)
    _one_line_error(info, rotated)


# ============================================================================ MMF + mapping
# A free space truss (bars between the nodes of two triangles stacked along z), assembled here:
# node ids 10..60, translations only, plus a massless rotation-free extra: none.
TRUSS_XYZ = {
    10: (0.0, 0.0, 0.0),
    20: (4.0, 0.0, 0.0),
    30: (0.0, 3.0, 0.0),
    40: (0.0, 0.0, 2.0),
    50: (4.0, 0.0, 2.0),
    60: (0.0, 3.0, 2.0),
}
TRUSS_BARS = [(10, 20), (20, 30), (30, 10), (40, 50), (50, 60), (60, 40)]
TRUSS_BARS += [(10, 40), (20, 50), (30, 60), (10, 50), (20, 60), (30, 40)]


def truss() -> tuple[np.ndarray, np.ndarray, list[tuple[int, str]]]:
    """K (EA = 1e6), consistent bar mass M (rho A = 2) and the dofs (node, label)."""
    ids = list(TRUSS_XYZ)
    dofs = [(n, label) for n in ids for label in ("UX", "UY", "UZ")]
    n = len(dofs)
    k, m = np.zeros((n, n)), np.zeros((n, n))
    for a, b in TRUSS_BARS:
        xa, xb = np.array(TRUSS_XYZ[a]), np.array(TRUSS_XYZ[b])
        length = np.linalg.norm(xb - xa)
        e = (xb - xa) / length
        block = 1e6 / length * np.outer(e, e)
        ia, ib = 3 * ids.index(a), 3 * ids.index(b)
        for (i, j), s in (((ia, ia), 1), ((ib, ib), 1), ((ia, ib), -1), ((ib, ia), -1)):
            k[i : i + 3, j : j + 3] += s * block
            m[i : i + 3, j : j + 3] += 2 * length / 6 * (2 if i == j else 1) * np.eye(3)
    return k, m, dofs


def mtx(matrix: np.ndarray) -> str:
    """Matrix Market, symmetric storage (lower triangle)."""
    rows, cols = np.nonzero(np.tril(matrix))
    lines = [
        "%%MatrixMarket matrix coordinate real symmetric",
        f"{matrix.shape[0]} {matrix.shape[0]} {rows.size}",
    ]
    lines += [f"{i + 1} {j + 1} {float(matrix[i, j])!r}" for i, j in zip(rows, cols, strict=True)]
    return "\n".join(lines) + "\n"


def hbmat_mapping(dofs: list[tuple[int, str]]) -> str:
    """The layout HBMAT writes: a header line, then %14d%14d    %-4s."""
    lines = ["    Matrix Eqn          Node    DOF     "]
    lines += [f"{k + 1:14d}{node:14d}    {label:<4s}" for k, (node, label) in enumerate(dofs)]
    return "\n".join(lines) + "\n"


@pytest.fixture
def mmf(tmp_path):
    k, m, dofs = truss()
    files = {
        "stiffness": tmp_path / "K.mtx",
        "mass": tmp_path / "M.mtx",
        "mapping": tmp_path / "truss.mapping",
    }
    files["stiffness"].write_text(mtx(k))
    files["mass"].write_text(mtx(m))
    files["mapping"].write_text(hbmat_mapping(dofs))
    nodes = tmp_path / "nodes.csv"
    nodes.write_text(
        "id,x,y,z\n" + "".join(f"{n},{x},{y},{z}\n" for n, (x, y, z) in TRUSS_XYZ.items())
    )
    return files, nodes


def test_mmf_free_truss_proved_with_and_without_coordinates(mmf, tmp_path):
    files, nodes = mmf
    k, m, dofs = truss()
    body = read_ansys_mmf(**files, nodes=nodes)
    np.testing.assert_array_equal(body.stiffness.toarray(), k)
    np.testing.assert_array_equal(body.mass.toarray(), m)
    assert [
        (int(n), "UX UY UZ".split()[d])
        for n, d in zip(body.dofs.nodes, body.dofs.directions, strict=True)
    ] == dofs
    assert body.name == "truss" and body.fixed.size == 0 and body.has_coordinates
    # the one proof of the map is the consistency check's (the reader writes none)
    proof = check_map(body, body_rounding(body))
    assert proof.proved and f"leave no force in {body.n_dof} of {body.n_dof} rows" in proof.reason
    assert proof.residual <= 1e-12, proof
    # the proof, computed here: K annihilates the six rigid-body fields
    residuals = body.rigid_body_residuals()
    assert residuals.max() < 1e-12
    bare = read_ansys_mmf(**files)
    assert not bare.has_coordinates
    assert "no coordinates (nodes not given): all nodes lie at the origin" in bare.notes
    proof = check_map(bare, body_rounding(bare))  # the translations alone prove no map
    assert not proof.proved and "no node coordinates" in proof.reason
    d = tmp_path / "D.mtx"
    d.write_text(mtx(1e-3 * k))
    damped = read_ansys_mmf(**files, damping=d, name="s")
    np.testing.assert_allclose(damped.damping_matrix.toarray(), 1e-3 * k)


def test_mmf_mapping_in_another_order_is_refused(mmf):
    files, nodes = mmf
    _, _, dofs = truss()
    swapped = list(dofs)
    swapped[0], swapped[1] = swapped[1], swapped[0]  # 10 UX <-> 10 UY
    files["mapping"].write_text(hbmat_mapping(swapped))
    with pytest.raises(
        UserError,
        match=r"the equation order is not proved: K maps the rigid-body "
        r"translation in [xy] to a residual of",
    ) as info:
        read_ansys_mmf(**files)
    _one_line_error(info, files["mapping"])
    # two nodes swapped: the translations cannot see it, the rotations with coordinates do
    swapped = [(20 if n == 30 else 30 if n == 20 else n, label) for n, label in dofs]
    files["mapping"].write_text(hbmat_mapping(swapped))
    bare = read_ansys_mmf(**files)  # read: the translations alone cannot see it ...
    assert not check_map(bare, body_rounding(bare)).proved  # ... so no proof of the map
    with pytest.raises(
        UserError,
        match=r"rotation about .* the node order of the mapping or the "
        r"coordinates of .*nodes\.csv do not belong",
    ):
        read_ansys_mmf(**files, nodes=nodes)


def test_mmf_constrained_model_is_refused_lone_diagonals_are_fixed(mmf):
    files, nodes = mmf
    k, m, dofs = truss()
    free = [i for i, (n, _) in enumerate(dofs) if n != 10]
    files["stiffness"].write_text(mtx(k[np.ix_(free, free)]))
    files["mass"].write_text(mtx(m[np.ix_(free, free)]))
    files["mapping"].write_text(hbmat_mapping([dofs[i] for i in free]))
    with pytest.raises(
        UserError, match="or the model is constrained; export the matrices of the free body"
    ):
        read_ansys_mmf(**files, nodes=nodes)
    # the constrained dofs of node 10 kept the Ansys way: diagonal 1, no couplings, no mass
    k1, m1 = k.copy(), m.copy()
    k1[:3, :] = k1[:, :3] = 0.0
    m1[:3, :] = m1[:, :3] = 0.0
    k1[:3, :3] = np.eye(3)
    files["stiffness"].write_text(mtx(k1))
    files["mass"].write_text(mtx(m1))
    files["mapping"].write_text(hbmat_mapping(dofs))
    with pytest.raises(UserError, match="or the model is constrained"):
        read_ansys_mmf(**files, nodes=nodes)
    # a decoupled massless dof with a diagonal only (and the rest free) becomes a fixed dof
    k2 = np.zeros((19, 19))
    k2[:18, :18], k2[18, 18] = k, 1.0
    m2 = np.zeros((19, 19))
    m2[:18, :18] = m
    files["stiffness"].write_text(mtx(k2))
    files["mass"].write_text(mtx(m2))
    files["mapping"].write_text(hbmat_mapping([*dofs, (70, "UX")]))
    nodes.write_text(nodes.read_text() + "70,9,9,9\n")
    body = read_ansys_mmf(**files, nodes=nodes)
    assert body.fixed.tolist() == [18]
    assert "1 equations with only a diagonal stiffness entry" in body.notes[1]


def test_mmf_mapping_rows_in_any_order(mmf):
    files, _ = mmf
    _, _, dofs = truss()
    rows = [f"{k + 1}, {n}, {label.lower()}" for k, (n, label) in enumerate(dofs)]
    files["mapping"].write_text("! dof mapping\nMatrix Eqn, Node, DOF\n" + "\n".join(rows[::-1]))
    body = read_ansys_mmf(**files)
    assert body.dofs.nodes.tolist() == [n for n, _ in dofs]


MAPPING = "Matrix Eqn   Node   DOF\n\n       1       10     UX\n       2       10     UY\n"
MAPPING += "       3       20     UX\n       4       30   ROTZ\n"


@pytest.mark.parametrize(
    ("text", "line", "pattern"),
    [
        (MAPPING.replace("     UY", "     UQ"), 4, "unknown dof label 'UQ'"),
        (MAPPING.replace("     UY", "   TEMP"), 4, "dof TEMP is not structural"),
        (MAPPING.replace("20     UX", "10     UX"), 5, "dof 10:UX is listed twice"),
        (MAPPING.replace("       3 ", "       2 "), 5, "equation 2 is listed twice"),
        (MAPPING.replace("30   ROTZ", "30   ROTZ  7"), 6, "4 fields, expected 3"),
        (MAPPING + "   five   30   UZ\n", 7, "expected 'equation node dof'"),
        (MAPPING.replace("       4 ", "       0 "), 6, "must be at least 1"),
    ],
)
def test_mmf_bad_mapping_lines(mmf, text, line, pattern):
    files, _ = mmf
    files["mapping"].write_text(text)
    with pytest.raises(UserError, match=pattern) as excinfo:
        read_ansys_mmf(**files)
    _one_line_error(excinfo, files["mapping"], line)


def test_mmf_bad_mapping_size_and_matrices(mmf):
    files, _ = mmf
    k, _, dofs = truss()
    files["mapping"].write_text(hbmat_mapping(dofs[:-1]))
    with pytest.raises(UserError, match=r"matrix is 18 x 18 but .* maps 17 equations") as info:
        read_ansys_mmf(**files)
    _one_line_error(info, files["stiffness"])
    files["mapping"].write_text(hbmat_mapping(dofs).replace("            18 ", "            19 "))
    with pytest.raises(UserError, match="equation 18 is missing") as info:
        read_ansys_mmf(**files)
    _one_line_error(info, files["mapping"])
    files["mapping"].write_text("Matrix Eqn   Node   DOF\n")
    with pytest.raises(UserError, match="no equation rows"):
        read_ansys_mmf(**files)
    files["mapping"].write_text(hbmat_mapping(dofs))
    unsymmetric = k.copy()
    unsymmetric[0, 3] += 1e3
    rows, cols = np.nonzero(unsymmetric)
    general = ["%%MatrixMarket matrix coordinate real general", f"18 18 {rows.size}"]
    general += [
        f"{i + 1} {j + 1} {float(unsymmetric[i, j])!r}" for i, j in zip(rows, cols, strict=True)
    ]
    files["stiffness"].write_text("\n".join(general) + "\n")
    with pytest.raises(UserError, match="not symmetric") as info:
        read_ansys_mmf(**files)
    _one_line_error(info, files["stiffness"])


def test_mmf_missing_node(mmf):
    files, nodes = mmf
    nodes.write_text("id,x,y,z\n10,0,0,0\n20,4,0,0\n")
    with pytest.raises(UserError, match="node 30 and 3 more of") as excinfo:
        read_ansys_mmf(**files, nodes=nodes)
    _one_line_error(excinfo, nodes)


def test_tolerance_is_between_rounding_and_wrong():
    assert 1e-9 < RIGID_BODY_TOLERANCE < 1e-4


@pytest.mark.parametrize(
    ("text", "fast"),
    [
        (MAPPING, True),
        (MAPPING.replace("\n", "\r\n"), True),
        ("       2       10     uy\n       1       10     UX\n", True),  # no header, any order
        (MAPPING.replace("   ROTZ", "   ROTZZZZZZ"), False),  # too long: the strict pass
        (MAPPING.replace("       3 ", "       2 "), False),  # equation twice
        (MAPPING.replace("20     UX", "10     UX"), False),  # dof twice
        (MAPPING.replace("       4 ", "       5 "), False),  # equation 4 missing
        (MAPPING.replace("     UY", "     UQ"), False),
        ("! comment\n" + MAPPING, False),
        (MAPPING.replace("10     UY", "10,    UY"), False),
        (MAPPING.replace("10     UY", "1.5     UY"), False),
        (MAPPING.replace("UY", "U\u00ff"), False),  # non-ASCII never reaches NumPy
    ],
)
def test_mapping_fast_path_equals_the_line_by_line_pass(tmp_path, monkeypatch, text, fast):
    from pymorembs.io import ansys

    path = tmp_path / "model.mapping"
    path.write_bytes(text.encode("utf-8"))
    result = ansys._read_mapping_fast(path)
    assert (result is not None) == fast

    def outcome():
        try:
            table = ansys._read_mapping(path)
        except UserError as err:
            return str(err)
        return table.nodes.tolist(), table.directions.tolist()

    with_fast = outcome()
    monkeypatch.setattr(ansys, "_read_mapping_fast", lambda path: None)
    assert outcome() == with_fast
    if result is not None:
        assert (result.nodes.tolist(), result.directions.tolist()) == with_fast
