"""The floor ratio's unit (bench/floor_ratio.py): every factorized matrix is timed again."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.linalg.factorization import Factorization

# bench/_common.py by its path: bench/ itself must not go on sys.path (its distributed.py would
# shadow the dask package for the rest of the session)
_PATH = Path(__file__).resolve().parents[1] / "bench" / "_common.py"
_SPEC = importlib.util.spec_from_file_location("bench_common", _PATH)
bench_common = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(bench_common)
FactorizationCounter = bench_common.FactorizationCounter
assemble = bench_common.assemble
time_backends = bench_common.time_backends


def _matrices(n: int = 40) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    main = 2.0 * np.ones(n)
    off = -np.ones(n - 1)
    k = sp.diags([off, main, off], [-1, 0, 1], format="csr")
    return k, sp.identity(n, format="csr")


def test_counter_keeps_the_terms_of_every_factorization():
    k, m = _matrices()
    shifts = (0.0, 0.3, 1.7)
    with FactorizationCounter() as counter:
        for sigma in shifts:
            Factorization([(1.0, k), (-sigma, m)], check=False)
    assert counter.count("real") == 3 and counter.count("complex") == 0
    kept = counter.terms["real"]
    assert len(kept) == 3 and counter.first_terms["real"] is kept[0]
    for terms, sigma in zip(kept, shifts, strict=True):
        # the very matrix of that call, assembled again (independent dense reference)
        expected = k.toarray() - sigma * m.toarray()
        np.testing.assert_array_equal(assemble(terms).toarray(), expected)


def test_time_backends_can_time_one_backend_only():
    k, _ = _matrices()
    every = time_backends(sp.csc_matrix(k))
    assert len(every) > 1
    name = next(iter(every))
    one = time_backends(sp.csc_matrix(k), only=name)
    assert list(one) == [name] and isinstance(one[name], float)
