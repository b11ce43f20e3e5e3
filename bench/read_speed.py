"""Read speed: every text reader of pymorembs against a plain C-speed parse of the same numbers.

From the built-in ``rack-solid`` (about ``--dofs`` dofs) one export per text format is written
into ``bench/.cache/read-speed-<dofs>-v<layout>/`` (kept for later runs; delete it to write
again), in the layout the FE program writes:

``matrix-market``
    pymorembs' own directory (``write_matrix_files``): ``K.mtx``, ``M.mtx`` (coordinate, general
    or symmetric, shortest round-trip values), ``dofs.csv``, ``nodes.csv``, ``constraints.csv``.
``ansys-mmf``
    APDL Math ``*EXPORT,...,MMF``: ``K.mtx``, ``M.mtx`` (coordinate real symmetric, lower
    triangle, ``%.15E`` values), the ``HBMAT`` mapping file ``model.mapping`` and ``nodes.csv``.
``abaqus-matrix-input``
    ``*MATRIX OUTPUT, FORMAT=MATRIX INPUT``: ``rack_STIF1.mtx``, ``rack_MASS1.mtx`` with
    ``node,dof, node,dof, value`` lines, one triangle, plus ``rack.inp`` with the ``*NODE`` block.
``abaqus-coordinate``
    ``*MATRIX OUTPUT, FORMAT=COORDINATE`` as Abaqus/CAE 2021 writes it (the Exudyn test data of
    the corpus): ``row col  value`` with both triangles, each off-diagonal pair on consecutive
    lines, ``% .15e`` values; plus ``dofs.csv`` and ``rack.inp``.
``nastran-dmig``
    MSC ``PARAM,EXTOUT,DMIGPCH`` punch (the mAEWing1 punch of the corpus): ``KAAX``/``MAAX`` in
    large field ``DMIG*`` cards, upper triangle column by column, 10 significant digits with
    ``D`` exponents; plus ``grids.bdf`` with ``GRID*`` cards.
``nastran-op4``
    ASCII ``OUTPUT4`` in sparse BIGMAT format (the MSC layout of the corpus' ``se_test_n11.op4``,
    with the negative row count and two-word string headers of BIGMAT): ``KAAX``/``MAAX``, full
    columns, ``1P,3E22.15``; plus ``dofs.csv`` and ``nodes.csv``.

Every measurement runs in a fresh process: the pymorembs reader (``read_matrix_directory``,
``read_ansys_mmf``, ``read_abaqus``, ``read_dmig``, ``read_op4``), and the baseline, a plain
C-speed parse of the same numbers (``scipy.io.mmread`` for Matrix Market files, a symmetric
one read as stored, without scipy's mirroring in Python, which costs more than the parse; NumPy's
``loadtxt`` for CSV, Abaqus and mapping lines; ``np.frombuffer`` fixed-width fields and
``astype`` for the DMIG cards; ``np.fromstring`` for the OP4 values, after splitting numbers
that touch). Reported: wall time (and the ratio of CPU times, all threads counted, which other
load on the machine disturbs less), peak memory of the process above its memory before the read
(``VmHWM`` after ``clear_refs``), the matrices' own size (CSR bytes of K and M as the body holds
them) and the ratios. Targets: time ratio <= 2, memory ratio <= 2.

Each pair is measured in two memory conditions (``--memory``), because the first touch of memory
can cost more than the parse. ``warm``: right before it reads, the child touches and frees twice
the files' size of memory, so both reader and baseline get pages the machine has just used, as
on a machine where memory is simply there. ``cold``: the child waits :data:`COLD_WAIT_S` first.
On a virtual machine that reports freed memory to its host (``virtio_balloon`` free page
reporting, as on the machines of this project), every page is then new to the host as well, and
the first touch of 1 GiB takes seconds instead of a tenth of one; a reader that has to build a
larger result than the baseline keeps (the full symmetric matrix against the stored triangle)
pays for it in proportion. Without a pause, the condition of a child would depend on what the
one before it freed, and the baseline, which always ran right after the reader, got the reader's
pages warm. The results name the first-touch cost measured in the same run.

Usage::

    .venv/bin/python bench/read_speed.py --dofs 35000 300000 [--formats ...] [--repeat 2]
        [--memory warm cold]
    .venv/bin/python bench/read_speed.py --quick      # 7,500 dofs, about a minute
"""

from __future__ import annotations

import argparse
import io
import itertools
import json
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from _common import (
    CACHE,
    available_memory_bytes,
    emit,
    fmt_s,
    machine_facts,
    markdown_table,
    peak_memory_mb,
    reset_peak_memory,
    rss_mb,
    run_child,
    update_results,
)

#: Memory conditions of a measurement (module docstring).
MEMORY = ("warm", "cold")
#: Version of the export layouts: bump it when a writer below changes, so old caches are not used.
LAYOUT = 2
FORMATS = (
    "matrix-market",
    "ansys-mmf",
    "abaqus-matrix-input",
    "abaqus-coordinate",
    "nastran-dmig",
    "nastran-op4",
)
QUICK_DOFS = 7500
_LINES_PER_WRITE = 1 << 18


# =========================================================================== the exports
def export_dir(dofs: int) -> Path:
    return CACHE / f"read-speed-{dofs}-v{LAYOUT}"


def write_exports(dofs: int, directory: Path) -> dict:
    """Build rack-solid and write every export (see the module docstring) into ``directory``."""
    from pymorembs.examples import build_example
    from pymorembs.io.matrix_market import write_matrix_files

    tick = time.perf_counter()
    body = build_example("rack-solid", dofs=dofs)
    build_s = time.perf_counter() - tick
    if directory.exists():
        shutil.rmtree(directory)
    directory.mkdir(parents=True)
    k, m = sp.csr_matrix(body.stiffness), sp.csr_matrix(body.mass)
    nodes, codes = body.dofs.nodes, body.dofs.directions
    timings = {}

    def timed(name: str, write: Callable[[Path], None]) -> None:
        tick = time.perf_counter()
        target = directory / name
        target.mkdir()
        write(target)
        timings[name] = round(time.perf_counter() - tick, 1)
        print(f"  {name}: written in {timings[name]} s", flush=True)

    timed("matrix-market", lambda d: write_matrix_files(body, d))

    def ansys(d: Path) -> None:
        for name, a in (("K.mtx", k), ("M.mtx", m)):
            _write_ansys_mmf(d / name, a)
        labels = np.array(["UX", "UY", "UZ", "ROTX", "ROTY", "ROTZ"])[codes]
        _write_lines(
            d / "model.mapping",
            ["Matrix Eqn   Node   DOF"],
            (
                f"{eq:>10} {node:>10}  {label}"
                for eq, node, label in zip(
                    range(1, nodes.size + 1), nodes.tolist(), labels.tolist(), strict=True
                )
            ),
        )
        _write_nodes_csv(d / "nodes.csv", body)

    timed("ansys-mmf", ansys)

    def abaqus_matrix_input(d: Path) -> None:
        for name, a in (("rack_STIF1.mtx", k), ("rack_MASS1.mtx", m)):
            low = sp.tril(a, format="coo")
            _write_lines(
                d / name,
                [],
                (
                    f"{n1},{c1 + 1}, {n2},{c2 + 1}, {v: .15e}"
                    for n1, c1, n2, c2, v in zip(
                        nodes[low.row].tolist(),
                        codes[low.row].tolist(),
                        nodes[low.col].tolist(),
                        codes[low.col].tolist(),
                        low.data.tolist(),
                        strict=True,
                    )
                ),
            )
        _write_inp(d / "rack.inp", body)

    timed("abaqus-matrix-input", abaqus_matrix_input)

    def abaqus_coordinate(d: Path) -> None:
        for name, a in (("rack_STIF1.mtx", k), ("rack_MASS1.mtx", m)):
            _write_lines(d / name, [], _coordinate_pairs(a))
        _write_dofs_csv(d / "dofs.csv", body)
        _write_inp(d / "rack.inp", body)

    timed("abaqus-coordinate", abaqus_coordinate)

    def dmig(d: Path) -> None:
        with open(d / "rack.pch", "w", encoding="ascii") as out:
            for name, a in (("KAAX", k), ("MAAX", m)):
                _write_dmig(out, name, a, nodes, codes)
        _write_grids(d / "grids.bdf", body)

    timed("nastran-dmig", dmig)

    def op4(d: Path) -> None:
        with open(d / "rack.op4", "w", encoding="ascii") as out:
            for name, a in (("KAAX", k), ("MAAX", m)):
                _write_op4_bigmat(out, name, a)
        _write_dofs_csv(d / "dofs.csv", body)
        _write_nodes_csv(d / "nodes.csv", body)

    timed("nastran-op4", op4)
    facts = {
        "dofs": dofs,
        "n": body.n_dof,
        "nodes": body.n_nodes,
        "nnz_k": int(k.nnz),
        "nnz_m": int(m.nnz),
        "build_s": round(build_s, 1),
        "write_s": timings,
    }
    (directory / "export.json").write_text(json.dumps(facts, indent=1))
    return facts


def _write_lines(path: Path, head: list[str], lines: Iterable[str]) -> None:
    """Write ``head`` and ``lines`` (without line ends) in blocks."""
    with open(path, "w", encoding="ascii") as out:
        for line in head:
            out.write(line + "\n")
        block: list[str] = []
        for line in lines:
            block.append(line)
            if len(block) == _LINES_PER_WRITE:
                out.write("\n".join(block) + "\n")
                block.clear()
        if block:
            out.write("\n".join(block) + "\n")


def _write_ansys_mmf(path: Path, a: sp.csr_matrix) -> None:
    low = sp.tril(a, format="coo")
    _write_lines(
        path,
        ["%%MatrixMarket matrix coordinate real symmetric", f"{a.shape[0]} {a.shape[1]} {low.nnz}"],
        (
            f"{i} {j} {v:.15E}"
            for i, j, v in zip(
                (low.row + 1).tolist(), (low.col + 1).tolist(), low.data.tolist(), strict=True
            )
        ),
    )


def _coordinate_pairs(a: sp.csr_matrix) -> Iterable[str]:
    """``row col  value`` lines: the upper triangle of the pattern of ``a`` and ``a^T`` row by
    row, each off-diagonal entry followed by its mirror (as in the Abaqus/CAE 2021 files of the
    corpus)."""
    pattern = sp.triu(abs(a) + abs(a.T), format="csr")
    pattern.sort_indices()
    rows = np.repeat(np.arange(a.shape[0]), np.diff(pattern.indptr))
    for i, j, v, w in zip(
        (rows + 1).tolist(),
        (pattern.indices + 1).tolist(),
        _aligned(a, pattern).tolist(),
        _aligned(sp.csr_matrix(a.T), pattern).tolist(),
        strict=True,
    ):
        yield f"{i} {j} {v: .15e}"
        if i != j:
            yield f"{j} {i} {w: .15e}"


def _aligned(values: sp.csr_matrix, pattern: sp.csr_matrix) -> np.ndarray:
    """The entries of ``values`` at the positions of ``pattern`` (zero where absent)."""
    values = sp.csr_matrix(values)
    values.sort_indices()
    out = np.zeros(pattern.nnz)
    keys = np.repeat(np.arange(pattern.shape[0]), np.diff(pattern.indptr)) * pattern.shape[1]
    keys = keys + pattern.indices
    have = np.repeat(np.arange(values.shape[0]), np.diff(values.indptr)) * values.shape[1]
    have = have + values.indices
    position = np.searchsorted(have, keys)
    found = position < have.size
    found[found] = have[position[found]] == keys[found]
    out[found] = values.data[position[found]]
    return out


def _write_dmig(out, name: str, a: sp.csr_matrix, nodes: np.ndarray, codes: np.ndarray) -> None:
    """Large-field DMIG cards (symmetric form 6, real double, upper triangle by columns)."""
    upper = sp.triu(a, format="csc")
    upper.sort_indices()
    columns = np.flatnonzero(np.diff(upper.indptr))
    out.write(f"DMIG    {name:<8}{0:>8}{6:>8}{2:>8}{0:>8}{'':8}{'':8}{columns.size:>8}\n")
    block: list[str] = []
    for j in columns.tolist():
        start, stop = upper.indptr[j], upper.indptr[j + 1]
        block.append(f"DMIG*   {name:<16}{nodes[j]:>16}{codes[j] + 1:>16}")
        rows = upper.indices[start:stop]
        for g, c, v in zip(
            nodes[rows].tolist(),
            (codes[rows] + 1).tolist(),
            upper.data[start:stop].tolist(),
            strict=True,
        ):
            block.append(f"*       {g:>16}{c:>16}{_nastran_d(v)}")
        if len(block) >= _LINES_PER_WRITE:
            out.write("\n".join(block) + "\n")
            block.clear()
    if block:
        out.write("\n".join(block) + "\n")


def _nastran_d(value: float) -> str:
    """16 characters, 10 significant digits, D exponent (``-2.053437033D+06``)."""
    return f"{value:16.9E}".replace("E", "D")


def _write_op4_bigmat(out, name: str, a: sp.csr_matrix) -> None:
    """ASCII OUTPUT4, sparse BIGMAT: one string per run of consecutive rows of a column."""
    c = a.tocsc()
    c.sort_indices()
    n = a.shape[0]
    out.write(f"{n:8d}{-n:8d}{6:8d}{1:8d}{name:<8s}1P,3E22.15\n")
    block: list[str] = []
    for j in range(n):
        start, stop = c.indptr[j], c.indptr[j + 1]
        if start == stop:
            continue
        rows = c.indices[start:stop]
        values = c.data[start:stop]
        breaks = np.flatnonzero(np.diff(rows) != 1) + 1
        edges = [0, *breaks.tolist(), rows.size]
        words = sum(2 + (b - e) for e, b in itertools.pairwise(edges))
        block.append(f"{j + 1:8d}{0:8d}{words:8d}")
        for first, last in itertools.pairwise(edges):
            block.append(f"{last - first + 1:8d}{rows[first] + 1:8d}")
            run = values[first:last].tolist()
            for k in range(0, len(run), 3):
                block.append("".join(f"{v:22.15E}" for v in run[k : k + 3]))
        if len(block) >= _LINES_PER_WRITE:
            out.write("\n".join(block) + "\n")
            block.clear()
    block.append(f"{n + 1:8d}{1:8d}{1:8d}")
    block.append(f"{1.0:22.15E}")
    out.write("\n".join(block) + "\n")


def _write_dofs_csv(path: Path, body) -> None:
    from pymorembs.body import DIRECTIONS

    _write_lines(
        path,
        ["node,direction"],
        (
            f"{node},{DIRECTIONS[code]}"
            for node, code in zip(
                body.dofs.nodes.tolist(), body.dofs.directions.tolist(), strict=True
            )
        ),
    )


def _write_nodes_csv(path: Path, body) -> None:
    _write_lines(
        path,
        ["id,x,y,z"],
        (
            f"{node},{x!r},{y!r},{z!r}"
            for node, (x, y, z) in zip(
                body.node_ids.tolist(), body.coordinates.tolist(), strict=True
            )
        ),
    )


def _write_inp(path: Path, body) -> None:
    _write_lines(
        path,
        ["*HEADING", "rack-solid (pymorembs bench/read_speed.py)", "*NODE, NSET=ALL"],
        (
            f"{node}, {x:.15g}, {y:.15g}, {z:.15g}"
            for node, (x, y, z) in zip(
                body.node_ids.tolist(), body.coordinates.tolist(), strict=True
            )
        ),
    )


def _write_grids(path: Path, body) -> None:
    """``GRID*`` large-field cards (basic system), 16-character coordinates."""

    def cards():
        for node, (x, y, z) in zip(body.node_ids.tolist(), body.coordinates.tolist(), strict=True):
            yield f"GRID*   {node:>16}{0:>16}{x:16.9E}{y:16.9E}"
            yield f"*       {z:16.9E}{0:>16}"

    _write_lines(path, ["$ grids of rack-solid (pymorembs bench/read_speed.py)"], cards())


# =========================================================================== readers and baselines
def _read(fmt: str, d: Path):
    """The pymorembs reader of ``fmt`` on the export directory ``d``."""
    if fmt == "matrix-market":
        from pymorembs.io.matrix_market import read_matrix_directory

        return lambda: read_matrix_directory(d)
    if fmt == "ansys-mmf":
        from pymorembs.io.ansys import read_ansys_mmf

        return lambda: read_ansys_mmf(
            d / "K.mtx", d / "M.mtx", d / "model.mapping", nodes=d / "nodes.csv"
        )
    if fmt == "abaqus-matrix-input":
        from pymorembs.io.abaqus import read_abaqus

        return lambda: read_abaqus(d / "rack_STIF1.mtx", d / "rack_MASS1.mtx", inp=d / "rack.inp")
    if fmt == "abaqus-coordinate":
        from pymorembs.io.abaqus import read_abaqus

        return lambda: read_abaqus(
            d / "rack_STIF1.mtx", d / "rack_MASS1.mtx", inp=d / "rack.inp", dofs=d / "dofs.csv"
        )
    if fmt == "nastran-dmig":
        from pymorembs.io.nastran_dmig import read_dmig

        return lambda: read_dmig(d / "rack.pch", nodes=d / "grids.bdf")
    if fmt == "nastran-op4":
        from pymorembs.io.nastran_op4 import read_op4

        return lambda: read_op4(d / "rack.op4", dofs=d / "dofs.csv", nodes=d / "nodes.csv")
    raise ValueError(fmt)


def _baseline(fmt: str, d: Path):
    """A plain C-speed parse of the numbers of ``fmt``'s files (no checks, no assembly)."""
    import scipy.io

    def csv(path: Path, kinds: tuple) -> np.ndarray:
        dtype = [(f"f{k}", kind) for k, kind in enumerate(kinds)]
        return np.loadtxt(path, delimiter=",", skiprows=1, dtype=dtype, ndmin=1)

    def inp_nodes(path: Path) -> np.ndarray:
        return np.loadtxt(path, delimiter=",", skiprows=3, ndmin=2)

    if fmt == "matrix-market":
        return lambda: [
            scipy.io.mmread(d / "K.mtx"),
            scipy.io.mmread(d / "M.mtx"),
            csv(d / "dofs.csv", (np.int64, "U2")),
            csv(d / "nodes.csv", (np.int64, float, float, float)),
            csv(d / "constraints.csv", (np.int64, "U2", float, np.int64, "U2", float)),
        ]
    if fmt == "ansys-mmf":
        return lambda: [
            _mmread_as_stored(d / "K.mtx"),
            _mmread_as_stored(d / "M.mtx"),
            np.loadtxt(
                d / "model.mapping", skiprows=1, dtype=[("e", int), ("n", int), ("d", "U4")]
            ),
            csv(d / "nodes.csv", (np.int64, float, float, float)),
        ]
    if fmt == "abaqus-matrix-input":
        kinds = (np.int64, np.int64, np.int64, np.int64, float)
        return lambda: (
            [
                np.loadtxt(
                    d / name, delimiter=",", dtype=[(f"f{k}", t) for k, t in enumerate(kinds)]
                )
                for name in ("rack_STIF1.mtx", "rack_MASS1.mtx")
            ]
            + [inp_nodes(d / "rack.inp")]
        )
    if fmt == "abaqus-coordinate":
        kinds = (np.int64, np.int64, float)
        return lambda: (
            [
                np.loadtxt(d / name, dtype=[(f"f{k}", t) for k, t in enumerate(kinds)])
                for name in ("rack_STIF1.mtx", "rack_MASS1.mtx")
            ]
            + [csv(d / "dofs.csv", (np.int64, "U2")), inp_nodes(d / "rack.inp")]
        )
    if fmt == "nastran-dmig":
        return lambda: [_dmig_fields(d / "rack.pch"), _grid_fields(d / "grids.bdf")]
    if fmt == "nastran-op4":
        return lambda: [
            _op4_numbers(d / "rack.op4"),
            csv(d / "dofs.csv", (np.int64, "U2")),
            csv(d / "nodes.csv", (np.int64, float, float, float)),
        ]
    raise ValueError(fmt)


class _AsGeneral(io.RawIOBase):
    """A symmetric Matrix Market file whose banner reads ``general``, so that
    ``scipy.io.mmread`` returns the entries as stored, without its mirroring in Python."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self._file = open(path, "rb", buffering=0)  # closed in close()
        self._first = True

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        size = self._file.readinto(buffer)
        if self._first and size:
            self._first = False
            end = bytes(buffer[: min(size, 200)]).find(b"\n")
            at = bytes(buffer[: max(end, 0)]).lower().find(b"symmetric")
            if at >= 0:
                buffer[at : at + 9] = b"general  "
        return size

    def close(self) -> None:
        self._file.close()
        super().close()


def _mmread_as_stored(path: Path):
    """fast_matrix_market's parse of the stored entries (a symmetric file is not mirrored)."""
    import scipy.io

    with io.BufferedReader(_AsGeneral(path), 1 << 20) as stream:
        return scipy.io.mmread(stream, spmatrix=False)


_CARD = np.dtype([("key", "S8"), ("a", "S16"), ("b", "S16"), ("c", "S16"), ("end", "S1")])


def _dmig_fields(path: Path) -> list[np.ndarray]:
    """The fields of the 56-column DMIG* cards as numbers: each matrix's header line is
    skipped, the cards after it are one fixed-width record array (``np.frombuffer``), D
    exponents become E (``bytes.replace``) and the fields are converted by ``astype``."""
    data = path.read_bytes().replace(b"D+", b"E+").replace(b"D-", b"E-")
    out = []
    start = 0
    while start < len(data):
        first = data.index(b"\n", start) + 1  # after the small-field header line
        stop = data.find(b"\nDMIG    ", first)
        stop = len(data) if stop < 0 else stop + 1
        count = (stop - first) // _CARD.itemsize
        cards = np.frombuffer(data, dtype=_CARD, count=count, offset=first)
        entry = cards["key"] == b"*"
        out += [
            cards["a"][entry].astype(np.int64),
            cards["b"].astype(np.int64),
            cards["c"].astype(float),
        ]
        start = stop
    return out


def _grid_fields(path: Path) -> np.ndarray:
    """Coordinates of the two-line ``GRID*`` cards: fixed-width records and ``astype``."""
    data = path.read_bytes()
    first = data.index(b"\n") + 1
    card = np.dtype(
        [
            ("key", "S8"),
            ("id", "S16"),
            ("cp", "S16"),
            ("x", "S16"),
            ("y", "S16"),
            ("e1", "S1"),
            ("k2", "S8"),
            ("z", "S16"),
            ("cd", "S16"),
            ("e2", "S1"),
        ]
    )
    cards = np.frombuffer(data, dtype=card, offset=first)
    return np.column_stack(
        [cards["id"].astype(np.int64)] + [cards[a].astype(float) for a in ("x", "y", "z")]
    )


def _op4_numbers(path: Path) -> np.ndarray:
    """Every number of an ASCII OP4 file by ``np.fromstring``; numbers that touch
    (``1.0E+00-2.0E+00``) are split first (``bytes.replace``); the header lines are dropped."""
    data = path.read_bytes()
    data = data.replace(b"E-", b"E_").replace(b"-", b" -").replace(b"E_", b"E-")
    numbers = []
    for block in data.split(b"1P,3E22.15\n")[1:]:  # the text after each header line
        numbers.append(np.fromstring(block[: block.rfind(b"\n") + 1], sep=" "))
    return numbers


def _matrix_bytes(body) -> int:
    return sum(
        a.data.nbytes + a.indices.nbytes + a.indptr.nbytes for a in (body.stiffness, body.mass)
    )


def measure(fmt: str, role: str, d: Path, memory: str) -> dict:
    """Time and peak memory of the reader or the baseline of ``fmt`` (in this process); with
    ``memory == "warm"`` right after :func:`warm_memory`, with ``"cold"`` after a pause of
    :data:`COLD_WAIT_S`."""
    call = _read(fmt, d) if role == "reader" else _baseline(fmt, d)
    if memory == "warm":
        warm_memory(_warm_bytes(d))
    else:
        time.sleep(COLD_WAIT_S)
    reset_peak_memory()
    before = rss_mb()
    tick, cpu = time.perf_counter(), time.process_time()
    result = call()
    seconds, cpu = time.perf_counter() - tick, time.process_time() - cpu
    peak = peak_memory_mb()
    out = {"seconds": seconds, "cpu_s": cpu, "peak_mb": peak - before, "rss_before_mb": before}
    if role == "reader":
        out.update(matrix_mb=_matrix_bytes(result) / 2**20, n=result.n_dof)
    return out


# =========================================================================== memory conditions
#: Seconds a child waits before it reads in the ``cold`` condition: longer than the delay after
#: which a Linux guest reports freed memory to its host (2 s for ``virtio_balloon``).
COLD_WAIT_S = 5.0


def warm_memory(size: int) -> None:
    """Touch ``size`` bytes of new memory and free them again.

    Right after this, the pages the process gets from the kernel are pages the machine has
    just used. On a virtual machine whose guest reports freed memory to its host (free page
    reporting), a page used for the first time otherwise costs the host a fault as well: there
    the first touch of 1 GiB can take seconds (see the ``first touch`` facts).
    """
    block = np.ones(max(size, 8) // 8)
    del block


def _warm_bytes(d: Path) -> int:
    """Memory warmed before a read: twice the files' size (at least 1 GiB), at most half of
    the available memory."""
    files = sum(p.stat().st_size for p in d.iterdir())
    return int(min(max(2 * files, 2**30), available_memory_bytes() / 2))


def first_touch_facts() -> dict[str, str]:
    """Seconds to touch 1 GiB of new memory in a fresh process after a pause (cold) and once
    more right after freeing it (warm): how much this machine charges for memory used for the
    first time."""
    code = (
        "import time, numpy as np\n"
        f"time.sleep({COLD_WAIT_S})\n"
        "out = []\n"
        "for _ in range(2):\n"
        "    t = time.perf_counter(); a = np.ones(2**27); out.append(time.perf_counter() - t)\n"
        "    del a\n"
        "print(' '.join(f'{x:.2f}' for x in out))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    cold, warm = [*done.stdout.split(), "?", "?"][:2]
    return {"first touch of 1 GiB in a fresh process (s)": f"{cold} cold, {warm} warm"}


# =========================================================================== driver
def _files_mb(fmt: str, d: Path) -> float:
    return sum(p.stat().st_size for p in (d / fmt).iterdir()) / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=int, nargs="+", default=[35000, 300000])
    parser.add_argument("--formats", nargs="+", choices=FORMATS, default=list(FORMATS))
    parser.add_argument("--quick", action="store_true", help=f"{QUICK_DOFS} dofs only")
    parser.add_argument(
        "--repeat", type=int, default=1, help="runs of reader and baseline (best time counts)"
    )
    parser.add_argument("--timeout", type=float, default=3600.0, help="per run, seconds")
    parser.add_argument(
        "--memory",
        nargs="+",
        choices=MEMORY,
        default=list(MEMORY),
        help="memory conditions (module docstring)",
    )
    parser.add_argument("--no-results", action="store_true", help="do not write RESULTS.md")
    parser.add_argument(
        "--child", nargs=4, metavar=("ROLE", "FORMAT", "DIR", "MEMORY"), help=argparse.SUPPRESS
    )
    args = parser.parse_args()
    if args.child:
        role, fmt, directory, memory = args.child
        if role == "export":
            emit(write_exports(int(fmt), Path(directory)))
        else:
            emit(measure(fmt, role, Path(directory) / fmt, memory))
        return

    sizes = [QUICK_DOFS] if args.quick else sorted(args.dofs)
    rows, failed = [], False
    for dofs in sizes:
        d = export_dir(dofs)
        if not (d / "export.json").exists():
            print(f"{dofs} dofs: building rack-solid and writing the exports ...", flush=True)
            r = run_child([__file__, "--child", "export", str(dofs), str(d), "-"], timeout=None)
            if "failed" in r:
                print("  " + r["failed"])
                failed = True
                continue
        facts = json.loads((d / "export.json").read_text())
        print(f"{dofs} dofs: n = {facts['n']}, nnz K {facts['nnz_k']}, M {facts['nnz_m']}")
        for fmt, memory in itertools.product(args.formats, args.memory):
            best: dict[str, dict] = {}
            for _ in range(args.repeat):
                for role in ("reader", "baseline"):
                    argv = [__file__, "--child", role, fmt, str(d), memory]
                    r = run_child(argv, timeout=args.timeout)
                    if "failed" in r or r["seconds"] < best.get(role, {}).get("seconds", np.inf):
                        best[role] = r
            reader, baseline = best["reader"], best["baseline"]
            if "failed" in reader or "failed" in baseline:
                failed = True
                reason = reader.get("failed") or baseline.get("failed")
                print(f"  {fmt} ({memory}): {reason}")
                rows.append([facts["n"], fmt, memory, f"{_files_mb(fmt, d):.0f}", "failed", reason])
                continue
            time_ratio = reader["seconds"] / baseline["seconds"]
            cpu_ratio = reader["cpu_s"] / baseline["cpu_s"]
            memory_ratio = reader["peak_mb"] / reader["matrix_mb"]
            ok = "yes" if time_ratio <= 2 and memory_ratio <= 2 else "**no**"
            row = [
                facts["n"],
                fmt,
                memory,
                f"{_files_mb(fmt, d):.0f}",
                fmt_s(reader["seconds"]),
                fmt_s(baseline["seconds"]),
                f"{time_ratio:.2f}",
                f"{cpu_ratio:.2f}",
                f"{reader['peak_mb']:.0f}",
                f"{reader['matrix_mb']:.0f}",
                f"{memory_ratio:.2f}",
                f"{baseline['peak_mb']:.0f}",
                ok,
            ]
            print("  " + " | ".join(map(str, row[1:])), flush=True)
            rows.append(row)
    headers = [
        "dofs",
        "format",
        "memory",
        "files [MB]",
        "pymorembs [s]",
        "baseline [s]",
        "time ratio",
        "CPU time ratio",
        "reader peak [MB]",
        "K+M CSR [MB]",
        "memory ratio",
        "baseline peak [MB]",
        "targets met",
    ]
    table = markdown_table(headers, rows)
    print(table)
    machine = machine_facts() | first_touch_facts()
    print("\n".join(f"- {key}: {value}" for key, value in machine.items()))
    if not args.no_results:
        body = (
            "rack-solid exports in each text format (layouts: `bench/read_speed.py` docstring); "
            "pymorembs reader against a plain C-speed parse of the same numbers, each in a "
            f"fresh process, best of {args.repeat} (wall time; the CPU time ratio, all threads "
            "counted, is less sensitive to other load on the machine). Memory `warm`: the "
            "child touches and frees twice the files' size of memory right before it reads; "
            f"`cold`: it waits {COLD_WAIT_S:g} s first, so that a virtual machine with free page "
            "reporting has handed its freed memory back to the host (the first-touch facts "
            "below say what that costs here). Peak memory: `VmHWM` "
            "above the process's memory before the read (interpreter and imports excluded); "
            "memory ratio = reader peak / CSR bytes of K and M as the body holds them. "
            "Targets: both ratios <= 2.\n\n" + table
        )
        name = "Read speed" + (", quick" if args.quick else "")
        print(f"written: {update_results(name, body, machine)}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
