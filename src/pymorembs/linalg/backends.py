"""Sparse direct solvers behind one small interface: MKL PARDISO where installed, SuperLU always.

``factorize(matrix, symmetric)`` returns a :class:`SparseFactor` whose ``solve`` takes one
right-hand side (n,) or a block (n, k) in one call. Two backends:

``"superlu"``
    SciPy's SuperLU (``scipy.sparse.linalg.splu``), always available. Symmetric matrices use
    minimum degree ordering of ``A^T + A`` with diagonal pivoting (:data:`SUPERLU_OPTIONS`);
    complex matrices are factorized in complex arithmetic.
``"pardiso"``
    Intel MKL PARDISO, a dependency of pymorembs where MKL publishes wheels (x86-64 Linux and
    Windows: ``pypardiso`` and ``mkl``; elsewhere SuperLU is used). pypardiso's solver class
    handles real matrices only, so pymorembs uses it just to locate and load ``mkl_rt`` and
    calls MKL's ``pardiso`` itself, with one handle (``pt``, ``iparm``) per factor -- no shared
    global solver -- released by ``phase = -1`` when the factor is garbage collected. Matrix
    types: real symmetric indefinite (``mtype = -2``, Bunch-Kaufman LDL^T of the upper triangle)
    for real shifts, complex symmetric (``mtype = 6``) for complex ones, real or complex
    nonsymmetric (11, 13) otherwise; METIS nested-dissection ordering; zero-based CSR indices,
    so the arrays are passed without copies.

Choice of the backend
---------------------
``PYMOREMBS_SOLVER`` = ``superlu`` | ``pardiso`` | ``mumps-mpi`` | ``auto`` (default ``auto``:
PARDISO when it is installed and works and the matrix has at least :data:`AUTO_MIN_NNZ`
nonzeros, complex ones :data:`AUTO_MIN_NNZ_COMPLEX`, else SuperLU; without PARDISO, the first
factorization of a large matrix, :data:`NOTE_MIN_NNZ`, writes one line on stderr,
:func:`fast_solver_note`; ``auto`` never chooses ``mumps-mpi``, the distributed MUMPS over MPI
of :mod:`pymorembs.linalg.mumps_mpi`). A PARDISO factorization that had to perturb pivots (the
matrix is singular or nearly so) is replaced by SuperLU's, which either factorizes exactly or
reports the singularity.

All shifts ``K - omega^2 M + i omega D`` of a model share one sparsity pattern, so its analysis
(METIS ordering and symbolic factorization) is done once: the symmetric factors of one pattern
are kept in one PARDISO handle (a *family*, :class:`_Family`, up to
:data:`FACTORS_PER_FAMILY` numeric factors, ``maxfct``/``mnum``), and every factorization after
the first runs PARDISO's numeric phase only, about a third of a complete factorization.
``PYMOREMBS_PARDISO_FAMILIES=0`` gives every factor its own
handle (the ordering of a pattern, :data:`MAX_ORDERINGS` of them, is still reused).

Storage of PARDISO's factors
----------------------------
``PYMOREMBS_PARDISO_STORAGE`` = ``auto`` | ``in-core`` | ``out-of-core`` (default ``in-core``).
``in-core`` keeps the double-precision factors in memory. ``out-of-core`` writes them to files
(``iparm[59] = 2``) in a fresh directory under ``PYMOREMBS_PARDISO_OOC_DIR`` (default: the
system's temporary directory), removed with the factor's handle; memory then holds only
PARDISO's working front. ``auto`` is in-core while the factors fit: it hands PARDISO
``iparm[59] = 1`` with ``MKL_PARDISO_OOC_MAX_CORE_SIZE`` set to :data:`AUTO_CORE_FRACTION` of
the memory available at the analysis (``MemAvailable``), so PARDISO itself goes out of core for
factors that would not fit. :attr:`PardisoFactor.out_of_core` says what PARDISO chose (it
wrote factor files). Factors that may go out of core (``auto``, ``out-of-core``) each get a handle
of their own: several factors of one handle (``maxfct`` > 1) out of core gave a wrong solve now
and then (one run in about eight of ``tests/linalg/test_factor_storage.py``), so only in-core
factors share the analysis of their pattern.

Single-precision factors (``iparm[27] = 1``, half the memory) are only offered to measurements
(``PardisoFactor(..., storage="single")``): refinement would restore double accuracy only where
``cond(A) * 6e-8`` is well below 1, and the shifted stiffness of a solid FE model is far from
that (``bench/two_million.py --single``); the factor measures the error of one solve with a
known solution and refuses factors off by more than :data:`SINGLE_MAX_ERROR`.

Threads: ``PYMOREMBS_SOLVER_THREADS`` (default: the cores this process may use) for the
factorization, set thread-locally around each PARDISO call, so a ``threadpool_limits(1,
"blas")`` around the whole job (as the command line does) does not throttle it. Solves of a
factor with its own handle run on one thread (2 threads were never faster on 2 cores, and up to
2x slower when the other core is busy); on a shared handle every call uses the family's thread
count, because a one-thread solve between a two-thread factorization and the release of that
factor (phase 0) made the next numeric factorization in the handle crash (MKL 2026.2). Worker
processes that run factorizations in parallel should set the variable to 1.

Complex shifts use the complex symmetric factorization (``mtype = 6``): it is several times
faster than SuperLU's complex LU and than the real equivalent forms of size 2n, whose factors
are also three to seven times larger (measurements: ``bench/RESULTS.md``).

"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import os
import platform
import shutil
import sys
import tempfile
import threading
import time
import weakref
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from pymorembs.errors import NumericalError, UserError
from pymorembs.parallel import available_memory_bytes

#: Environment variable that selects the backend: ``superlu``, ``pardiso`` or ``auto``.
SOLVER_ENV = "PYMOREMBS_SOLVER"
#: Environment variable with the number of PARDISO (MKL OpenMP) threads.
THREADS_ENV = "PYMOREMBS_SOLVER_THREADS"
#: Environment variable: ``0`` gives every PARDISO factor its own handle (no shared analysis).
FAMILIES_ENV = "PYMOREMBS_PARDISO_FAMILIES"
#: Environment variable: how PARDISO stores its factors (module docstring).
STORAGE_ENV = "PYMOREMBS_PARDISO_STORAGE"
#: Values of :data:`STORAGE_ENV`.
STORAGES = ("auto", "in-core", "out-of-core")
#: Environment variable: the directory under which out-of-core factors are written.
OOC_DIR_ENV = "PYMOREMBS_PARDISO_OOC_DIR"
#: With ``auto``, factors stay in core up to this fraction of the memory available at the
#: analysis; larger ones go out of core (PARDISO's ``iparm[59] = 1``).
AUTO_CORE_FRACTION = 0.5
#: Single-precision factors whose solve of a known system is off by more than this are refused
#: (:class:`~pymorembs.errors.NumericalError`): refinement would need many steps, or diverge.
SINGLE_MAX_ERROR = 1e-3
BACKENDS = ("superlu", "pardiso")
#: With ``auto``, matrices with fewer stored nonzeros go to SuperLU even when PARDISO is there:
#: loading MKL costs a fraction of a second once per process, which PARDISO's faster
#: factorizations pay back only from about this size (``bench/solvers.py``, small models).
AUTO_MIN_NNZ = 250_000
#: :data:`AUTO_MIN_NNZ` of complex matrices: SciPy's complex SuperLU takes many times its real
#: factorization of the same pattern, so PARDISO pays back its loading much earlier.
AUTO_MIN_NNZ_COMPLEX = 100_000
#: Without PARDISO (``auto``), a real matrix with this many stored nonzeros or more, or a complex
#: one with :data:`AUTO_MIN_NNZ_COMPLEX`, makes :func:`factorize` write
#: :func:`fast_solver_note` on stderr, once per process: from there on SuperLU costs seconds per
#: factorization where PARDISO needs a fraction of it (``bench/solvers.py``).
NOTE_MIN_NNZ = 1_000_000
#: (system, machine) pairs of :mod:`platform` for which MKL publishes wheels (PyPI, ``mkl``).
MKL_PLATFORMS = (("Linux", "x86_64"), ("Windows", "AMD64"))

#: SuperLU settings for symmetric matrices (all of pymorembs' are): minimum degree ordering of
#: ``A^T + A`` and diagonal pivots unless one is below 1 % of its column. On the 35,000-dof
#: rack-solid (``K - omega^2 M`` at 500 Hz, indefinite) this factorizes in 2.0 s with 23 M
#: nonzeros in L + U instead of 28.7 s and 116 M with SciPy's default (COLAMD, partial
#: pivoting), at the same residual; refinement and the backward-error check guard every solve.
SUPERLU_OPTIONS: dict[str, Any] = {
    "permc_spec": "MMD_AT_PLUS_A",
    "diag_pivot_thresh": 0.01,
    "options": {"SymmetricMode": True},
}

#: PARDISO error codes (MKL reference, ``error`` argument).
PARDISO_ERRORS = {
    -1: "input inconsistent",
    -2: "not enough memory",
    -3: "reordering problem",
    -4: "zero pivot",
    -5: "unclassified internal error",
    -6: "reordering failed",
    -7: "diagonal matrix is singular",
    -8: "32-bit integer overflow",
    -9: "not enough memory for out-of-core",
    -10: "cannot open out-of-core files",
    -11: "out-of-core read/write error",
    -12: "wrong pardiso_64 call",
}


class SparseFactor:
    """A factorization of a sparse square matrix ``A``, shape (n, n).

    Attributes
    ----------
    backend : str
        ``"superlu"`` or ``"pardiso"``.
    shape : tuple of int
    dtype : numpy dtype
        ``float64`` or ``complex128``.
    symmetric : bool
        Whether ``A`` was factorized as symmetric (only its upper triangle is used by PARDISO).
    seconds : float
        Wall time of the factorization, s (with the conversion of the matrix).
    """

    backend = ""

    def __init__(self, shape: tuple[int, int], dtype: np.dtype, symmetric: bool) -> None:
        self.shape = shape
        self.dtype = np.dtype(dtype)
        self.symmetric = symmetric
        self.seconds = 0.0

    @property
    def nnz_factor(self) -> int:
        """Nonzeros of the factors (L + U, or L of ``L D L^T``)."""
        raise NotImplementedError

    @property
    def memory_bytes(self) -> int:
        """Memory held by the factors, bytes (estimate)."""
        return self.nnz_factor * (self.dtype.itemsize + 4)

    @property
    def held_bytes(self) -> int:
        """Memory this factor alone holds, bytes: what dropping it would free (the budget of
        :func:`~pymorembs.linalg.shared_factorizations`); :attr:`memory_bytes` unless a
        backend says otherwise."""
        return self.memory_bytes

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``A X = rhs`` for a vector (n,) or a block (n, k), in one call.

        A complex right-hand side with a real factor is solved as one real block of 2k columns.
        Returns an array of the shape of ``rhs`` and the dtype ``result_type(A, rhs)``.
        """
        rhs = np.asarray(rhs)
        if rhs.shape[:1] != self.shape[:1]:
            raise ValueError(f"right-hand side of shape {rhs.shape} for a {self.shape} matrix")
        if rhs.size == 0:
            return np.zeros(rhs.shape, dtype=np.result_type(rhs.dtype, self.dtype))
        if np.iscomplexobj(rhs) and self.dtype.kind != "c":
            block = rhs.reshape(rhs.shape[0], -1)
            k = block.shape[1]
            both = self._solve(np.column_stack([block.real, block.imag]).astype(float))
            return (both[:, :k] + 1j * both[:, k:]).reshape(rhs.shape)
        return self._solve(rhs.astype(self.dtype, copy=False))

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class SuperLUFactor(SparseFactor):
    """SciPy SuperLU (``splu``); the settings of :data:`SUPERLU_OPTIONS` if symmetric."""

    backend = "superlu"

    def __init__(self, matrix: sp.spmatrix, symmetric: bool) -> None:
        start = time.perf_counter()
        matrix = sp.csc_matrix(matrix)
        super().__init__(matrix.shape, matrix.dtype, symmetric)
        try:
            self._lu = spla.splu(matrix, **(SUPERLU_OPTIONS if symmetric else {}))
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise NumericalError(f"the matrix is singular (SuperLU: {exc})") from None
        self.seconds = time.perf_counter() - start

    @property
    def nnz_factor(self) -> int:
        # SuperLU's own count (L includes its unit diagonal): no copy of the factors
        return int(self._lu.nnz)

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        return self._lu.solve(rhs)


class PardisoFactor(SparseFactor):
    """MKL PARDISO through ctypes, one handle per factor (see the module docstring).

    Parameters
    ----------
    matrix : sparse matrix, shape (n, n), real or complex
    symmetric : bool
        Factorize ``A`` as symmetric (``mtype`` -2 or 6) from its upper triangle.
    threads : int, optional
        PARDISO threads; default from :func:`solver_threads`.
    storage : {"auto", "in-core", "out-of-core", "single"}, optional
        How the factors are stored; default from :func:`pardiso_storage` (module docstring;
        ``"single"``: single-precision factors, for measurements).
    share_analysis : bool
        Join the family of the pattern (module docstring); False: an own handle, whose solves
        run on one thread (for many one-vector solves, as ARPACK's).

    Attributes
    ----------
    out_of_core : bool
        PARDISO keeps these factors (of its handle) in files.
    memory_report : dict of str to int
        PARDISO's own memory figures, KiB: ``analysis_peak`` (``iparm[14]``), ``permanent``
        (``iparm[15]``), ``factors_in_core`` (``iparm[16]``: factorization and solution in
        core) and ``out_of_core_minimum`` (``iparm[62]``).
    """

    backend = "pardiso"

    def __init__(
        self,
        matrix: sp.spmatrix,
        symmetric: bool,
        threads: int | None = None,
        storage: str | None = None,
        share_analysis: bool = True,
    ) -> None:
        start = time.perf_counter()
        self._share_analysis = share_analysis
        self.storage = pardiso_storage() if storage is None else storage
        if self.storage not in (*STORAGES, "single"):
            raise ValueError(f"unknown storage {self.storage!r}")
        if not isinstance(matrix, sp.csr_matrix):  # (a CSR matrix is used as is: no copy)
            matrix = sp.csr_matrix(matrix)
        complex_ = np.iscomplexobj(matrix.data)
        dtype = np.complex128 if complex_ else np.float64
        super().__init__(matrix.shape, dtype, symmetric)
        key = None
        if symmetric:
            matrix, key = _upper_triangle(matrix)
        elif not matrix.has_canonical_format:
            matrix = matrix.copy()  # not the caller's matrix
            matrix.sum_duplicates()
        if not np.all(np.isfinite(matrix.data)):
            raise NumericalError("the matrix has entries that are not finite")
        if not symmetric and np.any(np.diff(matrix.indptr) == 0):
            raise NumericalError("the matrix is singular (an empty row)")
        self._data = np.ascontiguousarray(matrix.data, dtype=_stored_dtype(dtype, self.storage))
        self._indptr = np.ascontiguousarray(matrix.indptr, dtype=np.int32)
        self._indices = np.ascontiguousarray(matrix.indices, dtype=np.int32)
        self.mtype = (6 if complex_ else -2) if symmetric else (13 if complex_ else 11)
        self.threads = solver_threads() if threads is None else int(threads)
        self._family: _Family | None = None
        self._maxfct, self._mnum = 1, 1
        if symmetric and key is None:
            key = _pattern_key(self._indptr, self._indices)
        try:
            phase = self._factorize(key, index64=False)
        except _PardisoError as exc:
            if exc.code != -8:
                raise
            # the factors have more than 2**31 entries: PARDISO's 64-bit interface, new handle
            if getattr(self, "_finalizer", None) is not None:
                self._finalizer()
            _FAMILIES.pop((key, self.mtype, self.threads, self.storage), None)
            phase = self._factorize(key, index64=True)
        self.seconds = time.perf_counter() - start
        if phase == 12 and key is not None and key not in _ORDERINGS:
            _remember_ordering(key, self._perm)
        #: PARDISO's 64-bit integer interface (``pardiso_64``) is used: factors beyond 2**31.
        self.index64 = self._iparm.dtype == np.int64
        #: Pivots PARDISO replaced by ``eps * |A|`` (a symptom of (near) singularity).
        self.perturbed_pivots = int(self._iparm[13])
        #: Inertia (positive, negative eigenvalues) of a real symmetric matrix.
        self.inertia = (int(self._iparm[21]), int(self._iparm[22]))
        self.out_of_core = self._files.written()
        self.memory_report = {
            "analysis_peak": int(self._iparm[14]),
            "permanent": int(self._iparm[15]),
            "factors_in_core": int(self._iparm[16]),
            "out_of_core_minimum": int(self._iparm[62]),
        }
        #: Relative error of one solve with these factors, measured on a known solution
        #: (single precision only; None otherwise).
        self.single_error = None
        if self.storage == "single" and not self.perturbed_pivots:
            self.single_error = self._measured_error(matrix)
            if self.single_error > SINGLE_MAX_ERROR:
                raise NumericalError(
                    f"single-precision factors of the matrix are too inaccurate (a solve is "
                    f"off by {self.single_error:.1e})"
                )

    def _measured_error(self, upper: sp.csr_matrix) -> float:
        """Relative error of a solve for ``x = 1 + i`` (``upper``: the matrix or, symmetric,
        its upper triangle; the product in double precision)."""
        x = np.ones(self.shape[0], dtype=self.dtype) * (1 + 1j if self.dtype.kind == "c" else 1)
        product = upper @ x
        if self.symmetric:  # the strictly lower triangle is the transpose of the upper one
            product += upper.T @ x - upper.diagonal() * x
        error = self._solve(product) - x
        return float(np.linalg.norm(error) / np.linalg.norm(x))

    def _factorize(self, key: str | None, index64: bool) -> int:
        """Set up the handle (the family's, else an own one) and factorize; the phase run."""
        n = self.shape[0]
        family = (
            _family(
                key, n, self.mtype, self._indptr, self._indices, self.threads, self.storage, index64
            )
            if self._share_analysis
            else None
        )
        slot = family.acquire() if family is not None else None
        if slot is not None:
            # the analysis of this pattern is done (shared by all shifts): numeric phase only
            self._family, self._mnum, self._maxfct = family, slot, family.maxfct
            self._pt, self._perm = family.pt, family.perm
            self._indptr, self._indices = family.indptr, family.indices
            self._files = family.files
            self._iparm = family.iparm.copy()
            self._finalizer = weakref.finalize(self, family.release, slot, self._data)
            phase = 22
        else:
            # own handle; the fill-reducing ordering of a symmetric pattern is still reused
            self._family, self._mnum, self._maxfct = None, 1, 1
            integer = np.int64 if index64 else np.int32
            self._indptr = self._indptr.astype(integer, copy=False)
            self._indices = self._indices.astype(integer, copy=False)
            self._pt = np.zeros(64, dtype=np.int64)
            self._iparm = _iparm(self.mtype, self.storage, index64)
            self._files = _FactorFiles.create(self.storage)
            known = _ORDERINGS.get(key) if key is not None else None
            self._perm = (np.zeros(n) if known is None else known).astype(integer)
            self._iparm[4] = 2 if known is None else 1  # return the ordering / use the given one
            self._finalizer = weakref.finalize(
                self, _release, self._pt, self.mtype, 1, self.storage, self._files, index64
            )
            phase = 12
        self._call(phase, np.zeros((n, 1), dtype=self._data.dtype, order="F"))
        return phase

    @property
    def nnz_factor(self) -> int:
        return int(self._iparm[17])

    @property
    def memory_bytes(self) -> int:
        """Memory the factor holds or needs in core, bytes (PARDISO's count): permanent memory
        plus that of factorization and solution (out of core: PARDISO's minimum working memory
        instead of the factors)."""
        working = self._iparm[62] if self.out_of_core else self._iparm[16]
        return 1024 * int(max(self._iparm[14], self._iparm[15] + working))

    @property
    def held_bytes(self) -> int:
        """Memory this factor alone holds, bytes. In a family PARDISO's counts are those of
        the whole handle, every factor stored in it so far (docs/performance.md, "Memory"); a
        member holds its own numeric factor, estimated as ``nnz_factor`` entries of the stored
        type plus a 4-byte index each. An own handle: :attr:`memory_bytes`."""
        if self._family is None:
            return self.memory_bytes
        return self.nnz_factor * (self._data.dtype.itemsize + 4)

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        block = np.asfortranarray(rhs.reshape(rhs.shape[0], -1), dtype=self._data.dtype)
        # out of core, every solve reads the factors from disk: on all the family's threads
        x = self._call(33, block, threads=self.threads if self.out_of_core else 1)
        if not np.all(np.isfinite(x)):
            raise NumericalError("the matrix is singular (PARDISO returned non-finite values)")
        return np.ascontiguousarray(x, dtype=self.dtype).reshape(rhs.shape)

    def _call(self, phase: int, rhs: np.ndarray, threads: int | None = None) -> np.ndarray:
        x = np.zeros_like(rhs, order="F")
        arrays = (self._data, self._indptr, self._indices, self._perm, self._iparm)
        if self._family is not None:
            # every call on a shared handle with the same number of threads: a solve on one
            # thread between a factorization and phase 0 on two made the next phase 22 crash
            with self._family.lock, self._files.environment():
                _pardiso(self._pt, self._maxfct, self._mnum, self.mtype, phase, *arrays, rhs, x,
                         self._family.threads)  # fmt: skip
            return x
        with self._files.environment():
            _pardiso(self._pt, self._maxfct, self._mnum, self.mtype, phase, *arrays, rhs, x,
                     self.threads if threads is None else threads)  # fmt: skip
        return x


def _pardiso(
    pt: np.ndarray,
    maxfct: int,
    mnum: int,
    mtype: int,
    phase: int,
    data: np.ndarray,
    indptr: np.ndarray,
    indices: np.ndarray,
    perm: np.ndarray | None,
    iparm: np.ndarray,
    rhs: np.ndarray,
    x: np.ndarray,
    threads: int,
) -> None:
    """One call of MKL's ``pardiso`` (handle ``pt``, factor ``mnum`` of ``maxfct``), with
    ``threads`` MKL threads; raises :class:`NumericalError` on an error code.

    The integer width follows ``iparm``: with an ``int64`` one (and ``int64`` index arrays) the
    call goes to ``pardiso_64``, whose factors may exceed 2**31 entries."""
    integer = ctypes.c_int64 if iparm.dtype == np.int64 else ctypes.c_int32
    function = _mkl().pardiso_64 if integer is ctypes.c_int64 else _mkl().pardiso
    index = ctypes.POINTER(integer)
    error = integer(0)
    with _threads(threads):
        function(
            pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
            ctypes.byref(integer(maxfct)),
            ctypes.byref(integer(mnum)),
            ctypes.byref(integer(mtype)),
            ctypes.byref(integer(phase)),
            ctypes.byref(integer(indptr.size - 1)),
            data.ctypes.data_as(ctypes.c_void_p),
            indptr.ctypes.data_as(index),
            indices.ctypes.data_as(index),
            None if perm is None else perm.ctypes.data_as(index),
            ctypes.byref(integer(rhs.shape[1])),  # nrhs
            iparm.ctypes.data_as(index),
            ctypes.byref(integer(0)),  # msglvl
            rhs.ctypes.data_as(ctypes.c_void_p),
            x.ctypes.data_as(ctypes.c_void_p),
            ctypes.byref(error),
        )
    if error.value:
        what = PARDISO_ERRORS.get(error.value, "unknown error")
        if error.value in (-4, -7):
            raise NumericalError(f"the matrix is singular (PARDISO {error.value}: {what})")
        raise _PardisoError(f"PARDISO failed with error {error.value} ({what})", error.value)


class _PardisoError(NumericalError):
    """A PARDISO error code other than a singular matrix (``code``: MKL's ``error``)."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class _Family:
    """One PARDISO handle for all symmetric matrices of one pattern (``maxfct`` factors).

    PARDISO analyses a sparsity pattern once (phase 11: ordering and symbolic factorization)
    and keeps up to ``maxfct`` numeric factors of matrices with that pattern in the same handle,
    each computed by phase 22 alone (``mnum`` = its slot). All shifts ``K - omega^2 M + i omega
    D`` of a reduction share their pattern, so from the second one on a factorization skips the
    symbolic analysis: on rack-solid at 35,679 dofs 0.23 s instead of 0.37 s with the ordering
    given (0.46 s for the analysis, once). A factor frees its slot (phase 0) when it is garbage
    collected; the handle is released (phase -1) when the family is dropped from
    :data:`_FAMILIES` and its last factor is gone. Calls on one handle are serialised by
    ``lock``, and all run on the family's ``threads`` (solves too).
    """

    def __init__(
        self,
        key: str,
        n: int,
        mtype: int,
        indptr: np.ndarray,
        indices: np.ndarray,
        threads: int,
        storage: str,
        index64: bool = False,
    ) -> None:
        self.key = key
        self.mtype = mtype
        self.threads = threads
        self.storage = storage
        self.maxfct = FACTORS_PER_FAMILY
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = _iparm(mtype, storage, index64)
        self.files = _FactorFiles.create(storage)
        integer = np.int64 if index64 else np.int32
        self.indptr = indptr = indptr.astype(integer, copy=False)
        self.indices = indices = indices.astype(integer, copy=False)
        known = _ORDERINGS.get(key)
        self.perm = (np.zeros(n) if known is None else known).astype(integer)
        self.iparm[4] = 2 if known is None else 1  # return the ordering / use the given one
        self.lock = threading.Lock()
        # slot 1 holds the analysis (phase 11 runs on it); freeing its numeric factor with
        # phase 0 and factorizing into it again crashed MKL (35k rack-solid), so factors use 2..
        self.free = list(range(self.maxfct, 1, -1))
        dtype = _stored_dtype(np.complex128 if mtype in (6, 13) else np.float64, storage)
        # the analysis does not read values; kept with the handle like every array given to it
        self.values = values = np.zeros(indices.size, dtype=dtype)
        weakref.finalize(self, _release, self.pt, mtype, self.maxfct, storage, self.files, index64)
        empty = np.zeros((n, 1), dtype=dtype, order="F")
        with self.files.environment():
            _pardiso(self.pt, self.maxfct, 1, mtype, 11, values, indptr, indices, self.perm,
                     self.iparm, empty, np.zeros_like(empty), self.threads)  # fmt: skip
        if known is None:
            _remember_ordering(key, self.perm)

    def acquire(self) -> int | None:
        """A free factor slot (``mnum``), or None when all ``maxfct`` are taken."""
        with self.lock:
            return self.free.pop() if self.free else None

    def release(self, mnum: int, data: np.ndarray) -> None:
        """Free the numeric factor in slot ``mnum`` (phase 0) and the slot."""
        empty = np.zeros((self.perm.size, 1), dtype=data.dtype, order="F")
        arrays = (data, self.indptr, self.indices, self.perm, self.iparm.copy())
        with self.lock, self.files.environment():
            try:
                _pardiso(self.pt, self.maxfct, mnum, self.mtype, 0, *arrays, empty, empty,
                         self.threads)  # fmt: skip
            except NumericalError:  # nothing to free
                pass
            self.free.append(mnum)


#: Factor families by pattern and matrix type (:class:`_Family`), most recent last.
_FAMILIES: dict[tuple[str, int, int, str], _Family] = {}
#: At most this many families are kept (each holds one symbolic analysis).
MAX_FAMILIES = 4
#: Numeric factors one family holds at most (SOAGA keeps one per expansion point).
FACTORS_PER_FAMILY = 16


def _family(
    key: str | None,
    n: int,
    mtype: int,
    indptr: np.ndarray,
    indices: np.ndarray,
    threads: int,
    storage: str,
    index64: bool = False,
) -> _Family | None:
    """The family of this symmetric pattern (created with its analysis, with 64-bit indices if
    ``index64``); None if not symmetric or switched off (``PYMOREMBS_PARDISO_FAMILIES=0``)."""
    if key is None or mtype not in (-2, 6) or os.environ.get(FAMILIES_ENV, "1").strip() == "0":
        return None
    if storage != "in-core":  # out-of-core factors: one per handle (module docstring)
        return None
    family = _FAMILIES.pop((key, mtype, threads, storage), None)
    if family is None:
        family = _Family(key, n, mtype, indptr, indices, threads, storage, index64)
    _FAMILIES[(key, mtype, threads, storage)] = family  # most recent last
    while len(_FAMILIES) > MAX_FAMILIES:
        _FAMILIES.pop(next(iter(_FAMILIES)))
    return family


def _remember_ordering(key: str, perm: np.ndarray) -> None:
    _ORDERINGS[key] = perm.copy()
    while len(_ORDERINGS) > MAX_ORDERINGS:
        _ORDERINGS.pop(next(iter(_ORDERINGS)))


class _UpperPattern:
    """Where the upper triangle of a canonical CSR pattern is, when it stores every diagonal.

    Kept per pattern (:data:`_UPPER`): the matrices of all shifts of a reduction share their
    ``indptr`` and ``indices`` arrays (:mod:`pymorembs.linalg.pattern`), so the upper triangle
    of the next one is a single gather of its data.
    """

    def __init__(self, matrix: sp.csr_matrix) -> None:
        n = matrix.shape[0]
        index_type = np.int32 if matrix.nnz < 2**31 else np.intp
        try:  # one compiled pass (Numba)
            from pymorembs.linalg.compiled_kernels import upper_positions
        except ImportError:
            upper_positions = None
        if upper_positions is not None:
            keep = np.empty(matrix.nnz, dtype=index_type)
            self.indptr = np.empty(n + 1, dtype=np.int32)
            count, self.complete = upper_positions(matrix.indptr, matrix.indices, keep, self.indptr)
            self.keep = keep[:count]
        else:
            rows = np.repeat(np.arange(n, dtype=np.int32), np.diff(matrix.indptr))
            self.keep = np.flatnonzero(matrix.indices >= rows).astype(index_type)
            self.complete = int(np.count_nonzero(matrix.indices == rows)) == n
            kept = np.bincount(rows[self.keep], minlength=n)
            self.indptr = np.concatenate([[0], np.cumsum(kept)]).astype(np.int32)
        self.indices = matrix.indices[self.keep].astype(np.int32)
        self.key = _pattern_key(self.indptr, self.indices)


_UPPER: dict[tuple[int, int], _UpperPattern] = {}


def _upper_triangle(matrix: sp.csr_matrix) -> tuple[sp.csr_matrix, str | None]:
    """The upper triangle of a square matrix with every diagonal entry stored (zeros too, as
    PARDISO's symmetric types need), canonical CSR; and the :func:`_pattern_key` of its
    pattern if known."""
    if matrix.has_canonical_format:
        key = (id(matrix.indices), id(matrix.indptr))
        known = _UPPER.get(key)
        if known is None:
            known = _UpperPattern(matrix)
            if known.complete:
                _UPPER[key] = known
                weakref.finalize(matrix.indices, _UPPER.pop, key, None)
        if known.complete:
            upper = sp.csr_matrix(matrix.shape, dtype=matrix.dtype)
            upper.data = matrix.data[known.keep]
            upper.indices, upper.indptr = known.indices, known.indptr
            upper.has_canonical_format = True
            return upper, known.key
    n = matrix.shape[0]
    upper = sp.triu(matrix, format="coo")
    diagonal = np.arange(n)
    matrix = sp.csr_matrix(
        (
            np.concatenate([upper.data, np.zeros(n, dtype=upper.data.dtype)]),
            (np.concatenate([upper.row, diagonal]), np.concatenate([upper.col, diagonal])),
        ),
        shape=(n, n),
    )
    matrix.sum_duplicates()
    matrix.sort_indices()
    return matrix, None


#: Fill-reducing orderings of recent symmetric patterns, by :func:`_pattern_key`.
_ORDERINGS: dict[str, np.ndarray] = {}
#: At most this many orderings are kept (each n 32-bit integers).
MAX_ORDERINGS = 16


def _pattern_key(indptr: np.ndarray, indices: np.ndarray) -> str:
    """A digest of a sparsity pattern (about 20 ms for 2.4 M nonzeros)."""
    digest = hashlib.blake2b(indptr.tobytes(), digest_size=16)
    digest.update(indices.tobytes())
    return digest.hexdigest()


def _iparm(mtype: int, storage: str = "in-core", index64: bool = False) -> np.ndarray:
    """PARDISO parameters (``iparm``, zero-based here; MKL's manual counts from 1) for factors
    stored as ``storage`` (:data:`STORAGES`); ``int64`` for the 64-bit interface."""
    iparm = np.zeros(64, dtype=np.int64 if index64 else np.int32)
    iparm[0] = 1  # no defaults: all set here
    iparm[1] = 2  # METIS nested dissection ordering
    iparm[7] = 0  # iterative refinement: automatic (2 steps when pivots were perturbed)
    symmetric = mtype in (-2, 6)
    iparm[9] = 13  # pivots below 1e-13 |A| are perturbed (``factorize`` then uses SuperLU)
    iparm[10] = 0 if symmetric else 1  # scaling
    iparm[12] = 0 if symmetric else 1  # weighted matching
    iparm[17] = -1  # report the nonzeros of the factors
    iparm[20] = 1  # Bunch-Kaufman 1x1 and 2x2 pivots (symmetric indefinite)
    iparm[27] = 1 if storage == "single" else 0  # precision of the factors (and of a, b, x)
    iparm[34] = 1  # zero-based indices
    # 0: in core; 1: out of core when the factors exceed MKL_PARDISO_OOC_MAX_CORE_SIZE; 2: always
    iparm[59] = {"auto": 1, "out-of-core": 2}.get(storage, 0)
    return iparm


def _release(
    pt: np.ndarray,
    mtype: int,
    maxfct: int,
    storage: str,
    files: _FactorFiles,
    index64: bool = False,
) -> None:
    """Free PARDISO's memory of one handle (``phase = -1``) and its out-of-core files."""
    if pt.any():
        dummy = np.zeros((1, 1))
        index = np.zeros(2, dtype=np.int64 if index64 else np.int32)
        try:
            with files.environment():
                _pardiso(pt, maxfct, 1, mtype, -1, dummy.ravel(), index, index, None,
                         _iparm(mtype, storage, index64), dummy, dummy.copy(), 1)  # fmt: skip
        except NumericalError:
            pass
        pt[:] = 0
    files.remove()


def _stored_dtype(dtype: type | np.dtype, storage: str) -> np.dtype:
    """The dtype of the values PARDISO gets: single precision for ``storage == "single"``."""
    dtype = np.dtype(dtype)
    if storage != "single":
        return dtype
    return np.dtype(np.complex64 if dtype.kind == "c" else np.float32)


class _FactorFiles:
    """Where one PARDISO handle may write its factors out of core: a fresh directory (under
    ``PYMOREMBS_PARDISO_OOC_DIR`` or the temporary directory), handed to MKL through its
    environment variables around every call of the handle; none for in-core storage."""

    def __init__(self, directory: str | None, core_mb: int) -> None:
        self.directory = directory
        self.core_mb = core_mb

    @classmethod
    def create(cls, storage: str) -> _FactorFiles:
        if storage not in ("auto", "out-of-core"):
            return cls(None, 0)
        root = os.environ.get(OOC_DIR_ENV, "").strip() or None
        try:
            directory = tempfile.mkdtemp(prefix="pymorembs-pardiso-", dir=root)
        except OSError as exc:
            raise UserError(
                f"{OOC_DIR_ENV}: cannot create a directory in {root!r}: {exc}"
            ) from None
        core = AUTO_CORE_FRACTION * available_memory_bytes()
        core_mb = int(min(core, 2**50) / 2**20)  # (infinite where MemAvailable is not known)
        return cls(directory, max(core_mb, 1))

    @contextlib.contextmanager
    def environment(self):
        """MKL's out-of-core settings for one call (nothing for in-core storage)."""
        if self.directory is None:
            yield
            return
        settings = {
            "MKL_PARDISO_OOC_PATH": self.directory,  # (a directory: MKL names the files)
            "MKL_PARDISO_OOC_MAX_CORE_SIZE": str(self.core_mb),
            "MKL_PARDISO_OOC_KEEP_FILE": "0",
        }
        previous = {name: os.environ.get(name) for name in settings}
        os.environ.update(settings)
        try:
            yield
        finally:
            for name, value in previous.items():
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value

    def written(self) -> bool:
        """Whether PARDISO has written factors here (it went out of core)."""
        return self.directory is not None and any(os.scandir(self.directory))

    def remove(self) -> None:
        """Delete the directory and whatever PARDISO left in it."""
        if self.directory is not None:
            shutil.rmtree(self.directory, ignore_errors=True)
            self.directory = None


class _threads:
    """Context: MKL runs with ``count`` threads in this thread (``mkl_set_num_threads_local``)."""

    def __init__(self, count: int) -> None:
        self.count = count

    def __enter__(self) -> None:
        self.previous = _mkl().MKL_Set_Num_Threads_Local(ctypes.c_int(self.count))

    def __exit__(self, *exc: object) -> None:
        _mkl().MKL_Set_Num_Threads_Local(ctypes.c_int(self.previous))


@cache
def _mkl() -> ctypes.CDLL:
    """MKL's runtime library as pypardiso finds it (ImportError/OSError if it is not there)."""
    from pypardiso import PyPardisoSolver

    library = PyPardisoSolver().libmkl
    library.pardiso.restype = None
    library.pardiso_64.restype = None
    library.MKL_Set_Num_Threads_Local.restype = ctypes.c_int
    library.MKL_Set_Num_Threads_Local.argtypes = [ctypes.c_int]
    return library


def pardiso_storage() -> str:
    """How PARDISO stores its factors: ``PYMOREMBS_PARDISO_STORAGE``, default ``in-core``."""
    value = os.environ.get(STORAGE_ENV, "in-core").strip().lower() or "in-core"
    if value not in STORAGES:
        raise UserError(f"{STORAGE_ENV} must be {', '.join(STORAGES)}, got {value!r}")
    return value


def solver_threads() -> int:
    """PARDISO threads: ``PYMOREMBS_SOLVER_THREADS``, else the cores this process may use."""
    value = os.environ.get(THREADS_ENV, "").strip()
    if value:
        if not value.isdigit() or int(value) < 1:
            raise UserError(f"{THREADS_ENV} must be a whole number >= 1, got {value!r}")
        return int(value)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@cache
def _pardiso_works() -> bool:
    """PARDISO is installed and solves a small symmetric indefinite system correctly."""
    try:
        matrix = sp.csr_matrix(np.array([[2.0, 1.0, 0.0], [1.0, -3.0, 1.0], [0.0, 1.0, 4.0]]))
        factor = PardisoFactor(matrix, symmetric=True, threads=1, storage="in-core")
        x = factor.solve(np.array([3.0, -1.0, 5.0]))
    except (ImportError, OSError, AttributeError, NumericalError):
        return False
    return bool(np.allclose(x, 1.0, rtol=1e-12, atol=0.0))


def fast_solver_hint() -> str:
    """How to get PARDISO here: the install command, or why there is none for this platform."""
    system, machine = platform.system(), platform.machine()
    if (system, machine) in MKL_PLATFORMS:
        return "install it with: pip install 'pymorembs[fast]'"
    return f"MKL publishes no wheels for {system} {machine} (only x86-64 Linux and Windows)"


def fast_solver_note() -> str:
    """The one line written when a large matrix is factorized by SuperLU for want of PARDISO."""
    return (
        "pymorembs: note: the fast sparse solver (MKL PARDISO) is not available, so SciPy's "
        f"SuperLU factorizes this large model, several times slower; {fast_solver_hint()} "
        "(docs/performance.md, Sparse solvers)"
    )


@cache
def _write_fast_solver_note() -> None:
    """:func:`fast_solver_note` on stderr, once per process."""
    sys.stderr.write(fast_solver_note() + "\n")
    sys.stderr.flush()


def available_backends() -> list[str]:
    """Backends that work here: ``["superlu"]``, plus ``"pardiso"`` if MKL PARDISO does."""
    return ["superlu", "pardiso"] if _pardiso_works() else ["superlu"]


def default_backend() -> str:
    """The preferred backend: ``PYMOREMBS_SOLVER`` if set, else the fastest available.

    ``auto`` (the default) is PARDISO when it works -- it factorizes the 35,000-dof rack-solid
    2-3 times faster than SuperLU (module docstring) -- else SuperLU; :func:`factorize` then
    still uses SuperLU for small matrices (:data:`AUTO_MIN_NNZ`). Asking for
    ``pardiso`` when it is not installed is a :class:`~pymorembs.errors.UserError`.
    """
    value = _requested()
    if value == "auto":
        return "pardiso" if _pardiso_works() else "superlu"
    if value not in BACKENDS:
        if value in OPTIONAL_BACKENDS:
            return _optional_backend(value)[0]
        names = ", ".join([*BACKENDS, *OPTIONAL_BACKENDS])
        raise UserError(f"{SOLVER_ENV} must be {names} or auto, got {value!r}")
    if value == "pardiso" and not _pardiso_works():
        raise UserError(
            f"{SOLVER_ENV}=pardiso, but MKL PARDISO is not available ({fast_solver_hint()})"
        )
    return value


def _requested() -> str:
    return os.environ.get(SOLVER_ENV, "auto").strip().lower() or "auto"


#: A backend's factorization: ``factory(matrix, symmetric)`` -> :class:`SparseFactor`.
Factory = Callable[[sp.spmatrix, bool], SparseFactor]

_FACTORIES: dict[str, Factory] = {
    "superlu": SuperLUFactor,
    "pardiso": PardisoFactor,
}


def chosen_backend(matrix: sp.spmatrix) -> str:
    """The backend :func:`factorize` uses for ``matrix`` when none is given: the default
    (:func:`default_backend`), but with ``auto`` SuperLU for matrices below
    :data:`AUTO_MIN_NNZ` stored nonzeros (:data:`AUTO_MIN_NNZ_COMPLEX` complex), without
    loading MKL (a fraction of a second on first use)."""
    complex_ = np.iscomplexobj(matrix.data)
    if _requested() == "auto" and matrix.nnz < (AUTO_MIN_NNZ_COMPLEX if complex_ else AUTO_MIN_NNZ):
        return "superlu"
    return default_backend()


def factorize(
    matrix: sp.spmatrix, symmetric: bool, backend: str | None = None, share_analysis: bool = True
) -> SparseFactor:
    """Factorize a sparse square matrix with the given (or the default) backend.

    Parameters
    ----------
    matrix : sparse matrix, shape (n, n), float64 or complex128
    symmetric : bool
        ``A = A^T`` (not Hermitian: complex symmetric, as ``K - omega^2 M + i omega D``);
        PARDISO then reads the upper triangle only.
    backend : {"superlu", "pardiso"}, optional
        Default :func:`default_backend`.
    share_analysis : bool
        PARDISO: in the family of the pattern (default), or an own handle (``PardisoFactor``).

    Returns
    -------
    SparseFactor
        With PARDISO, a matrix for which PARDISO had to perturb pivots (below ``1e-13 |A|``:
        singular or nearly so) is factorized by SuperLU instead, which pivots without
        perturbation; ``backend`` then says ``"superlu"``.

    Raises
    ------
    NumericalError
        The matrix is singular (an exactly zero pivot in SuperLU, a PARDISO failure).
    """
    automatic = backend is None and _requested() == "auto"
    complex_ = np.iscomplexobj(matrix.data)
    name = chosen_backend(matrix) if backend is None else backend
    large = matrix.nnz >= (AUTO_MIN_NNZ_COMPLEX if complex_ else NOTE_MIN_NNZ)
    if automatic and large and not _pardiso_works():
        _write_fast_solver_note()
    factory = _optional_backend(name)[1] if name in OPTIONAL_BACKENDS else _FACTORIES.get(name)
    if factory is None:
        raise UserError(f"unknown solver backend {name!r}; choose from {', '.join(BACKENDS)}")
    if name == "pardiso" and not _pardiso_works():
        raise UserError(f"the PARDISO backend is not available ({fast_solver_hint()})")
    if matrix.shape[0] != matrix.shape[1]:
        raise ValueError(f"cannot factorize a matrix of shape {matrix.shape}")
    if not complex_:
        matrix = matrix.astype(np.float64, copy=False)
    if name == "pardiso":
        factor = PardisoFactor(matrix, symmetric, share_analysis=share_analysis)
    else:
        factor = factory(matrix, symmetric)
    if getattr(factor, "perturbed_pivots", 0):
        # PARDISO's static pivoting replaced pivots below 1e-13 |A|: the matrix is singular or
        # nearly so. SuperLU's threshold pivoting factorizes it exactly or reports it singular.
        del factor
        factor = SuperLUFactor(matrix, symmetric)
    return factor


#: Backends defined in other modules, which register themselves (:func:`register_backend`): the
#: distributed ``mumps-mpi`` of :mod:`pymorembs.linalg.mumps_mpi`. Name -> (factory, whether it
#: works here, how to install it). ``auto`` never chooses one.
OPTIONAL_BACKENDS: dict[str, tuple[Factory, Callable[[], bool], str]] = {}


def register_backend(
    name: str,
    factory: Factory,
    works: Callable[[], bool],
    install: str,
) -> None:
    """Make ``name`` a value of ``PYMOREMBS_SOLVER`` and of :func:`factorize`'s ``backend``.

    Parameters
    ----------
    name : str
    factory : callable
        ``factory(matrix, symmetric)`` -> :class:`SparseFactor`.
    works : callable
        ``works()`` -> whether the backend is installed and works (called when it is asked for).
    install : str
        How to install it, for the message when it is asked for but does not work.
    """
    OPTIONAL_BACKENDS[name] = (factory, works, install)


def _optional_backend(name: str) -> tuple[str, Factory]:
    """The name and factory of a registered backend; a UserError if it does not work here."""
    factory, works, install = OPTIONAL_BACKENDS[name]
    if not works():
        raise UserError(f"{SOLVER_ENV}={name}: the backend is not available here ({install})")
    return name, factory
