"""Independent reference computations for the Nastran reader tests (no pymorembs code).

* :func:`f06_cycles` reads the CYCLES column of a ``R E A L   E I G E N V A L U E S`` table of an
  f06 (the frequencies Nastran published);
* :func:`dmig_entries` parses the DMIG cards of a punch with plain Python (large field, as
  ``PARAM,EXTOUT,DMIGPCH`` writes them);
* :func:`dense_frequencies` solves ``K x = w^2 M x`` densely after exact static condensation of
  the null space of ``M`` (massless directions), optionally after removing given rigid-body
  fields from ``K`` by an M-orthogonal projection.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import scipy.linalg as la
from threadpoolctl import threadpool_limits

_ROW = re.compile(r"^\s+(\d+)\s+(\d+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s*$")


def f06_cycles(path: Path, marker: str = "R E A L   E I G E N V A L U E S", skip: int = 0) -> list:
    """The CYCLES column (Hz) of the ``skip``-th table after a line containing ``marker``."""
    lines = path.read_text(errors="replace").splitlines()
    starts = [i for i, line in enumerate(lines) if marker in line]
    out = []
    for line in lines[starts[skip] + 1 :]:
        match = _ROW.match(line)
        if match:
            out.append(float(match.group(5)))
        elif out:
            break
    return out


def dmig_entries(path: Path, name: str) -> dict[tuple[int, int, int, int], float]:
    """``{(row grid, row comp, col grid, col comp): value}`` of a large-field DMIG matrix."""
    out: dict[tuple[int, int, int, int], float] = {}
    column = None
    for line in path.read_text().splitlines():
        if line.startswith("DMIG*"):
            words = line[8:].split()
            column = (int(words[1]), int(words[2])) if words[0] == name else None
        elif line.startswith("DMIG"):
            column = None
        elif line.startswith("*") and column is not None:
            grid, comp = int(line[8:24]), int(line[24:40])
            out[(grid, comp, *column)] = float(line[40:56].replace("D", "E"))
    return out


def dense_matrix(entries: dict, keys: list[tuple[int, int]]) -> np.ndarray:
    """The full symmetric matrix of one-triangle entries over ``keys`` (grid, comp)."""
    index = {key: i for i, key in enumerate(keys)}
    a = np.zeros((len(keys), len(keys)))
    for (g, c, gj, cj), value in entries.items():
        i, j = index[(g, c)], index[(gj, cj)]
        a[i, j] = a[j, i] = value
    return a


def dense_frequencies(
    k: np.ndarray, m: np.ndarray, rigid: np.ndarray | None = None, tol: float = 1e-9
) -> np.ndarray:
    """Frequencies (Hz, ascending) of ``k, m`` with the null space of ``m`` condensed exactly.

    ``rigid`` (n, r): fields removed from ``k`` first (``P^T K P`` with the M-orthogonal
    projector ``P = I - R (R^T M R)^-1 R^T M``), which gives ``r`` exact zero frequencies.
    """
    with threadpool_limits(
        limits=1, user_api="blas"
    ):  # small dense problems: one thread is fastest
        return _dense_frequencies(k, m, rigid, tol)


def _dense_frequencies(k, m, rigid, tol) -> np.ndarray:
    k = 0.5 * (k + k.T)
    if rigid is not None:
        p = np.eye(k.shape[0]) - rigid @ np.linalg.solve(rigid.T @ m @ rigid, rigid.T @ m)
        k = p.T @ k @ p
        k = 0.5 * (k + k.T)
    values, vectors = np.linalg.eigh(0.5 * (m + m.T))
    massive = values > tol * values.max()
    kt = vectors.T @ k @ vectors
    krr = kt[np.ix_(massive, massive)]
    if (~massive).any():
        krz = kt[np.ix_(massive, ~massive)]
        kzz = kt[np.ix_(~massive, ~massive)]
        krr = krr - krz @ np.linalg.lstsq(kzz, krz.T, rcond=None)[0]
    w2 = la.eigh(0.5 * (krr + krr.T), np.diag(values[massive]), eigvals_only=True)
    return np.sign(w2) * np.sqrt(np.abs(w2)) / (2 * np.pi)
