"""Reading speed of the Nastran text readers: bulk data GRIDs and a DMIG punch.

With ``--plate N`` also a flat N x N plate of CQUAD4 cards (small field): the time to read it
and to give its surface (:func:`pymorembs.io.nastran_bulk.bulk_surface_elements`, then
:func:`pymorembs.surface.outer_surface`), the cost of the shells the bulk reader keeps for the
surface (issue 17).

Writes (to a temporary folder) a bulk data file with ``--grids`` GRID cards in small, large and
free field, and the DMIG punch (large field, D exponents, as ``PARAM,EXTOUT,DMIGPCH`` writes it)
of a chain of ``--grids`` / 10 grids x 6 dofs, then times
:func:`pymorembs.io.nastran_bulk.read_bulk` (with the conversion to basic coordinates) and
:func:`pymorembs.io.nastran_dmig.read_dmig`. The
baseline is a plain numpy parse of the same numbers (the fixed-width fields cut out of the lines
and converted at once), the C-speed floor for a text format.

Usage (from the repository root)::

    .venv/bin/python bench/nastran_read.py --grids 1000000

Measured on 2 cores shared with other jobs (load average 5, so the times are up to twice
those of an idle machine), 2026-12-01, ``--grids 1000000``::

    bulk small field: 1000000 GRIDs, 47 MiB: read 3.71 s, basic coordinates 0.07 s
    bulk large field: 1000000 GRIDs, 93 MiB: read 4.30 s, basic coordinates 0.09 s
    bulk free  field: 1000000 GRIDs, 41 MiB: read 8.26 s, basic coordinates 0.08 s
    DMIG punch: 600000 dofs, 1799994 entries, 163 MiB: read 16.67 s (numpy floor 2.21 s)

(on an idle moment: small field 2.5 s, free field 5.0 s). The DMIG time is that of the reader
before issue #14 (CPU time 6-9 s for both in alternating runs); the new notes (significant
digits) add about 1 s.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from pymorembs.io.nastran_bulk import bulk_surface_elements, read_bulk  # noqa: E402
from pymorembs.io.nastran_dmig import read_dmig  # noqa: E402
from pymorembs.surface import outer_surface  # noqa: E402


def write_grids(path: Path, xyz: np.ndarray, style: str) -> None:
    with open(path, "w") as f:
        for i, (x, y, z) in enumerate(xyz.tolist(), 1):
            if style == "small":
                f.write(f"GRID    {i:<8}        {x:<8.3f}{y:<8.3f}{z:<8.3f}\n")
            elif style == "large":
                f.write(f"GRID*   {i:>16}{'':16}{x:>16.9E}{y:>16.9E}\n*       {z:>16.9E}\n")
            else:
                f.write(f"GRID,{i},,{x:.6f},{y:.6f},{z:.6f}\n")


def write_punch(path: Path, grids: int) -> int:
    """A chain of grids (6 dofs each): each column couples to its grid and the previous one."""
    n = 6 * grids
    entries = 0
    with open(path, "w") as f:
        for name, scale in (("KAAX", 1.0e6), ("MAAX", 1.0)):
            f.write(f"DMIG    {name:<8}{0:>8}{6:>8}{2:>8}{0:>8}{'':16}{n:>8}\n")
            for g in range(1, grids + 1):
                for c in range(1, 7):
                    f.write(f"DMIG*   {name:<16}{g:>16}{c:>16}\n")
                    rows = [(g - 1, c), (g, c)] if g > 1 and name == "KAAX" else [(g, c)]
                    for rg, rc in rows:
                        value = scale * (2.0 if rg == g else -1.0) * (1 + 0.1 * c)
                        f.write(f"*       {rg:>16}{rc:>16}{value:>16.9E}".replace("E", "D") + "\n")
                        entries += 1
    return entries


def write_plate(path: Path, n: int) -> None:
    """GRIDs of an (n + 1) x (n + 1) grid in the plane z = 0 and n x n CQUAD4 between them."""
    with open(path, "w") as f:
        for j in range(n + 1):
            for i in range(n + 1):
                f.write(
                    f"GRID    {j * (n + 1) + i + 1:<8}        {i * 0.01:<8.3f}{j * 0.01:<8.3f}\n"
                )
        element = 0
        for j in range(n):
            for i in range(n):
                a = j * (n + 1) + i + 1
                element += 1
                f.write(
                    f"CQUAD4  {element:<8}1       {a:<8}{a + 1:<8}{a + n + 2:<8}{a + n + 1:<8}\n"
                )


def baseline(path: Path, width: int, columns: list[slice]) -> float:
    """Seconds to cut the fixed-width columns of every line out and convert them with numpy."""
    start = time.perf_counter()
    lines = path.read_bytes().splitlines()
    u = np.array(lines, dtype=f"S{width}").view(np.uint8).reshape(len(lines), width)
    for cut in columns:
        block = np.ascontiguousarray(u[:, cut])
        block[block == ord("D")] = ord("E")
        block[(block == 0)] = ord(" ")
        try:
            block.view(f"S{cut.stop - cut.start}").ravel().astype(np.float64)
        except ValueError:
            pass  # header lines: the floor is the conversion itself
    return time.perf_counter() - start


def timed(function, *args, **kwargs) -> tuple[float, object]:
    start = time.perf_counter()
    out = function(*args, **kwargs)
    return time.perf_counter() - start, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grids", type=int, default=1_000_000)
    parser.add_argument("--plate", type=int, default=0, help="also an N x N CQUAD4 plate")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    xyz = rng.random((args.grids, 3)) * 100
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        for style in ("small", "large", "free"):
            path = folder / f"{style}.bdf"
            write_grids(path, xyz, style)
            seconds, bulk = timed(read_bulk, path)
            convert, _ = timed(bulk.basic_coordinates)
            size = path.stat().st_size / 2**20
            print(
                f"bulk {style:5s} field: {args.grids} GRIDs, {size:.0f} MiB: read {seconds:.2f} s, "
                f"basic coordinates {convert:.2f} s"
            )
        punch = folder / "model.pch"
        grids = max(args.grids // 10, 1)
        entries = write_punch(punch, grids)
        seconds, body = timed(read_dmig, punch)
        floor = baseline(punch, 72, [slice(40, 56)])
        size = punch.stat().st_size / 2**20
        print(
            f"DMIG punch: {body.n_dof} dofs, {entries} entries, {size:.0f} MiB: read "
            f"{seconds:.2f} s (numpy floor for the values {floor:.2f} s)"
        )
        if args.plate:
            plate = folder / "plate.bdf"
            write_plate(plate, args.plate)
            seconds, bulk = timed(read_bulk, plate)
            found, elements = timed(bulk_surface_elements, bulk)
            ids = bulk.grid["ids"]
            xyz = bulk.basic_coordinates(bulk.grid_rows(ids))
            drawn, surface = timed(outer_surface, elements.blocks, ids, xyz)
            print(
                f"plate: {ids.size} GRIDs, {args.plate**2} CQUAD4, "
                f"{plate.stat().st_size / 2**20:.0f} MiB: read {seconds:.2f} s, surface elements "
                f"{found:.2f} s, outer surface {drawn:.2f} s ({surface.triangles.shape[0]} "
                "triangles)"
            )


if __name__ == "__main__":
    main()
