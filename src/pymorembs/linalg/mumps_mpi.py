"""A distributed sparse direct solver: MUMPS over MPI, as the optional backend ``"mumps-mpi"``.

One body whose factors do not fit one machine is factorized by several MPI processes (*ranks*),
each holding a share of the factors. pymorembs itself runs on rank 0 (the *host*): it reads the
model, projects, checks and writes as always, and only its factorizations and solves are spread
over the ranks. The other ranks run :func:`serve_solver_ranks`: they wait for the host's
commands and take part in MUMPS's collective calls, and end when the host ends::

    PYMOREMBS_SOLVER=mumps-mpi mpiexec -n 4 pymorembs reduce job.toml

Without ``mpiexec`` the backend runs MUMPS on one process (useful for tests and comparisons).

How a factorization goes (:class:`MumpsFactor`)
-----------------------------------------------
- The host splits the upper triangle (symmetric) or the whole matrix (nonsymmetric) into
  row blocks of about equal numbers of nonzeros and sends block ``r`` to rank ``r``: MUMPS's
  distributed assembled input (``ICNTL(18) = 3``), so no worker holds more than its share of
  the matrix.
- MUMPS analyses the pattern on the host (ordering: MUMPS's automatic choice, ``ICNTL(7) = 7``,
  among AMD, AMF, QAMD and PORD: Debian's ``libmumps`` has no METIS or SCOTCH), then
  factorizes ``A = L D L^T`` (``SYM = 2``: real symmetric indefinite with ``dmumps``, complex
  symmetric -- not Hermitian -- with ``zmumps``) or ``A = L U`` (``SYM = 0``), every rank
  holding its fronts. A factorization that runs out of its estimated workspace
  (:data:`WORKSPACE_CODES`) is repeated with twice the relaxation ``ICNTL(14)``, up to
  :data:`MEMORY_RETRIES` times.
- Solves take a block of ``k`` right-hand sides on the host (``ICNTL(20) = 0``), are done by
  all ranks together, and return the solution on the host (``ICNTL(21) = 0``): one collective
  solve per block, whatever ``k``.

Commands travel as one message from the host to each rank (:func:`_command`). A factor garbage
collected on the host is not freed at once (a finalizer may run in the middle of another
collective call): its instance is queued and freed by all ranks with the next command.

The MUMPS libraries are Debian's (``libmumps-dev`` 5.5.1: ``libdmumps.so``, ``libzmumps.so``)
and are called through :mod:`ctypes` with the ``DMUMPS_STRUC_C`` layout of MUMPS 5.5
(:class:`MumpsStruct`; checked at run time by the version string MUMPS writes into it). MPI
comes from ``mpi4py`` (imported only when this backend is used). Install: ``make mpi``.

Forked worker processes of the host (the parallel frequency response) cannot take part in MPI
calls; a factorization asked for in one uses the default local backend instead.
"""

from __future__ import annotations

import atexit
import ctypes
import ctypes.util
import itertools
import os
import threading
import time
import weakref
from functools import cache
from typing import Any

import numpy as np
import scipy.sparse as sp

from pymorembs.errors import NumericalError, UserError
from pymorembs.linalg.backends import (
    SOLVER_ENV,
    SparseFactor,
    available_backends,
    factorize,
    register_backend,
)

#: The value of ``PYMOREMBS_SOLVER`` that selects this backend.
BACKEND = "mumps-mpi"
#: MUMPS version whose C structure :class:`MumpsStruct` mirrors (major.minor).
MUMPS_SERIES = "5.5"
#: Factorizations that ran out of workspace are repeated this often with twice ``ICNTL(14)``.
MEMORY_RETRIES = 3
#: Environment variables an MPI launcher sets with the number of ranks (Open MPI, MPICH/PMI).
LAUNCHER_SIZE_ENV = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE")
#: Environment variables with the rank of this process.
LAUNCHER_RANK_ENV = ("OMPI_COMM_WORLD_RANK", "PMI_RANK")

#: MPI tag of the host's commands to the other ranks.
COMMAND_TAG = 7
#: Seconds between two looks for the host's next command, and the same after a second of quiet.
POLL_S, IDLE_POLL_S = 1e-4, 0.02

#: MUMPS error codes (``INFOG(1)``) that mean the matrix is singular or its factors overflow.
SINGULAR_CODES = {-10: "numerically singular matrix", -6: "structurally singular matrix"}
#: Orderings by MUMPS's code (``INFOG(7)``); Debian's ``libmumps`` has no METIS or SCOTCH.
ORDERINGS = {0: "AMD", 1: "given", 2: "AMF", 3: "SCOTCH", 4: "PORD", 5: "METIS", 6: "QAMD"}
#: ``INFOG(1)`` codes of a workspace too small (retried with a larger ``ICNTL(14)``).
WORKSPACE_CODES = (-8, -9, -14, -15)


class MumpsStruct(ctypes.Structure):
    """``DMUMPS_STRUC_C`` / ``ZMUMPS_STRUC_C`` of MUMPS 5.5 (32-bit ``MUMPS_INT``); both have
    the same layout (8,360 bytes), the value pointers point to ``double`` or ``double complex``.
    Array fields count from 0 here (``icntl[13]`` is the manual's ``ICNTL(14)``)."""

    _fields_ = [
        ("sym", ctypes.c_int),
        ("par", ctypes.c_int),
        ("job", ctypes.c_int),
        ("comm_fortran", ctypes.c_int),
        ("icntl", ctypes.c_int * 60),
        ("keep", ctypes.c_int * 500),
        ("cntl", ctypes.c_double * 15),
        ("dkeep", ctypes.c_double * 230),
        ("keep8", ctypes.c_int64 * 150),
        ("n", ctypes.c_int),
        ("nblk", ctypes.c_int),
        ("nz_alloc", ctypes.c_int),
        ("nz", ctypes.c_int),
        ("nnz", ctypes.c_int64),
        ("irn", ctypes.c_void_p),
        ("jcn", ctypes.c_void_p),
        ("a", ctypes.c_void_p),
        ("nz_loc", ctypes.c_int),
        ("nnz_loc", ctypes.c_int64),
        ("irn_loc", ctypes.c_void_p),
        ("jcn_loc", ctypes.c_void_p),
        ("a_loc", ctypes.c_void_p),
        ("nelt", ctypes.c_int),
        ("eltptr", ctypes.c_void_p),
        ("eltvar", ctypes.c_void_p),
        ("a_elt", ctypes.c_void_p),
        ("blkptr", ctypes.c_void_p),
        ("blkvar", ctypes.c_void_p),
        ("perm_in", ctypes.c_void_p),
        ("sym_perm", ctypes.c_void_p),
        ("uns_perm", ctypes.c_void_p),
        ("colsca", ctypes.c_void_p),
        ("rowsca", ctypes.c_void_p),
        ("colsca_from_mumps", ctypes.c_int),
        ("rowsca_from_mumps", ctypes.c_int),
        ("rhs", ctypes.c_void_p),
        ("redrhs", ctypes.c_void_p),
        ("rhs_sparse", ctypes.c_void_p),
        ("sol_loc", ctypes.c_void_p),
        ("rhs_loc", ctypes.c_void_p),
        ("irhs_sparse", ctypes.c_void_p),
        ("irhs_ptr", ctypes.c_void_p),
        ("isol_loc", ctypes.c_void_p),
        ("irhs_loc", ctypes.c_void_p),
        ("nrhs", ctypes.c_int),
        ("lrhs", ctypes.c_int),
        ("lredrhs", ctypes.c_int),
        ("nz_rhs", ctypes.c_int),
        ("lsol_loc", ctypes.c_int),
        ("nloc_rhs", ctypes.c_int),
        ("lrhs_loc", ctypes.c_int),
        ("schur_mloc", ctypes.c_int),
        ("schur_nloc", ctypes.c_int),
        ("schur_lld", ctypes.c_int),
        ("mblock", ctypes.c_int),
        ("nblock", ctypes.c_int),
        ("nprow", ctypes.c_int),
        ("npcol", ctypes.c_int),
        ("info", ctypes.c_int * 80),
        ("infog", ctypes.c_int * 80),
        ("rinfo", ctypes.c_double * 40),
        ("rinfog", ctypes.c_double * 40),
        ("deficiency", ctypes.c_int),
        ("pivnul_list", ctypes.c_void_p),
        ("mapping", ctypes.c_void_p),
        ("size_schur", ctypes.c_int),
        ("listvar_schur", ctypes.c_void_p),
        ("schur", ctypes.c_void_p),
        ("instance_number", ctypes.c_int),
        ("wk_user", ctypes.c_void_p),
        ("version_number", ctypes.c_char * 32),
        ("ooc_tmpdir", ctypes.c_char * 256),
        ("ooc_prefix", ctypes.c_char * 64),
        ("write_problem", ctypes.c_char * 256),
        ("lwk_user", ctypes.c_int),
        ("save_dir", ctypes.c_char * 256),
        ("save_prefix", ctypes.c_char * 256),
        ("metis_options", ctypes.c_int * 40),
    ]


def _load(prefix: str) -> ctypes.CDLL:
    """``lib<prefix>mumps`` of the system (the development link or the runtime's soname)."""
    names = [ctypes.util.find_library(f"{prefix}mumps"), f"lib{prefix}mumps-{MUMPS_SERIES}.so"]
    errors = []
    for name in filter(None, names):
        try:
            library = ctypes.CDLL(name)
        except OSError as exc:
            errors.append(str(exc))
            continue
        function = getattr(library, f"{prefix}mumps_c")
        function.argtypes = [ctypes.POINTER(MumpsStruct)]
        function.restype = None
        return library
    raise OSError(f"lib{prefix}mumps not found ({'; '.join(errors) or 'no library'})")


@cache
def _libraries() -> dict[bool, Any]:
    """The MUMPS entry points by ``complex``: ``dmumps_c`` (float64), ``zmumps_c`` (complex128)."""
    return {False: _load("d").dmumps_c, True: _load("z").zmumps_c}


@cache
def _mpi() -> Any:
    """mpi4py's ``MPI`` module (initializes MPI on first use; ImportError without mpi4py)."""
    from mpi4py import MPI

    return MPI


def launched_ranks() -> int:
    """Number of ranks the MPI launcher started (1 without ``mpiexec``), from its environment,
    without initializing MPI."""
    for name in LAUNCHER_SIZE_ENV:
        value = os.environ.get(name, "")
        if value.isdigit():
            return int(value)
    return 1


def _launched_rank() -> int:
    for name in LAUNCHER_RANK_ENV:
        value = os.environ.get(name, "")
        if value.isdigit():
            return int(value)
    return 0


class _Instance:
    """One MUMPS instance on this rank; every method is a collective call of all ranks."""

    def __init__(self, complex_: bool, symmetric: bool) -> None:
        self.call = _libraries()[complex_]
        self.dtype = np.dtype(np.complex128 if complex_ else np.float64)
        self.struct = MumpsStruct()
        self.struct.sym = 2 if symmetric else 0
        self.struct.par = 1  # the host works on the factors too
        self.struct.comm_fortran = _mpi().COMM_WORLD.py2f()
        self._job(-1)
        version = self.struct.version_number.decode(errors="replace")
        if not version.startswith(MUMPS_SERIES):
            self.struct.job = -2
            self.call(ctypes.byref(self.struct))
            raise OSError(f"MUMPS {version!r} found, this backend is written for {MUMPS_SERIES}")
        icntl = self.struct.icntl
        icntl[0], icntl[1], icntl[2], icntl[3] = -1, -1, -1, 0  # no output
        icntl[4] = 0  # assembled matrix
        icntl[6] = 7  # ordering: MUMPS's automatic choice
        icntl[17] = 3  # distributed matrix: each rank gives its entries
        icntl[19] = 0  # dense right-hand sides on the host
        icntl[20] = 0  # solution on the host
        self.arrays: tuple[np.ndarray, ...] = ()
        self.ended = False

    def _job(self, job: int) -> int:
        self.struct.job = job
        self.call(ctypes.byref(self.struct))
        return int(self.struct.infog[0])

    def factor(self, n: int, rows: np.ndarray, cols: np.ndarray, values: np.ndarray) -> int:
        """Analysis and factorization of this rank's entries (1-based ``rows``, ``cols``);
        returns ``INFOG(1)``."""
        rows = np.ascontiguousarray(rows, dtype=np.int32)
        cols = np.ascontiguousarray(cols, dtype=np.int32)
        values = np.ascontiguousarray(values, dtype=self.dtype)
        self.arrays = (rows, cols, values)  # MUMPS reads them until the factorization is done
        self.struct.n = n
        self.struct.nnz_loc = rows.size
        self.struct.nz_loc = rows.size if rows.size < 2**31 else 0
        self.struct.irn_loc = rows.ctypes.data
        self.struct.jcn_loc = cols.ctypes.data
        self.struct.a_loc = values.ctypes.data
        code = self._job(1)
        if code < 0:
            return code
        code = self._job(2)
        for _ in range(MEMORY_RETRIES):
            if code not in WORKSPACE_CODES:
                break
            self.struct.icntl[13] = 2 * max(self.struct.icntl[13], 20)
            code = self._job(2)
        self.arrays = ()
        self.struct.irn_loc = self.struct.jcn_loc = self.struct.a_loc = None
        return code

    def solve(self, block: np.ndarray | None) -> int:
        """Solve for the columns of ``block`` (n, k) in place, Fortran order, on the host;
        ``None`` on the other ranks (``k`` is the host's). Returns ``INFOG(1)``."""
        if block is not None:
            self.struct.nrhs = block.shape[1]
            self.struct.lrhs = block.shape[0]
            self.struct.rhs = block.ctypes.data
        code = self._job(3)
        self.struct.rhs = None
        return code

    def end(self) -> None:
        if not self.ended:
            self.ended = True
            self._job(-2)

    def statistics(self) -> dict[str, float]:
        """This rank's share: the reals of the space that holds its factors (``INFO(9)``) and the
        memory of factorization and solve, MB (``INFO(22)``, ``INFO(26)``)."""
        info = self.struct.info
        entries = info[8] if info[8] >= 0 else -info[8] * 1_000_000  # INFO(9)
        return {
            "factor_space": float(entries),
            "factorization_mb": float(info[21]),  # INFO(22), MB = 10^6 bytes
            "solve_mb": float(info[25]),  # INFO(26)
        }


#: Serializes the host's commands: one command and its collective calls at a time.
_LOCK = threading.RLock()
#: Instances of factors collected on the host, freed with the next command.
_PENDING: list[int] = []
_KEYS = itertools.count(1)
_HOST: dict[str, Any] = {"pid": None, "stopped": False}


def _host_comm() -> Any:
    """COMM_WORLD on the host (rank 0); registers the stop of the other ranks at exit."""
    comm = _mpi().COMM_WORLD
    if _HOST["pid"] is None:
        if comm.rank != 0:
            raise UserError(f"{SOLVER_ENV}={BACKEND}: rank {comm.rank} asked to factorize")
        _HOST["pid"] = os.getpid()
        atexit.register(stop_solver_ranks)
    return comm


def _command(comm: Any, operation: str, *arguments: Any) -> None:
    """Send one command (with the instances to free first) to every rank; the host too frees."""
    frees = _PENDING[:]
    del _PENDING[:]
    for rank in range(1, comm.size):
        comm.send((operation, frees, arguments), dest=rank, tag=COMMAND_TAG)
    for key in frees:
        instance = _INSTANCES.pop(key, None)
        if instance is not None:
            instance.end()


#: This rank's live instances by key (on the host: those of live :class:`MumpsFactor`).
_INSTANCES: dict[int, _Instance] = {}


def _row_blocks(indptr: np.ndarray, ranks: int) -> np.ndarray:
    """Row bounds (ranks + 1,) of ``ranks`` contiguous blocks of about equal nonzeros."""
    nnz = int(indptr[-1])
    targets = np.linspace(0, nnz, ranks + 1)
    bounds = np.searchsorted(indptr, targets, side="left")
    bounds[0], bounds[-1] = 0, indptr.size - 1
    return np.maximum.accumulate(bounds)


def _triplets(matrix: sp.csr_matrix, first: int, last: int) -> tuple[np.ndarray, ...]:
    """1-based (rows, cols, values) of rows ``first:last`` of a CSR matrix."""
    start, stop = int(matrix.indptr[first]), int(matrix.indptr[last])
    counts = np.diff(matrix.indptr[first : last + 1])
    rows = np.repeat(np.arange(first + 1, last + 1, dtype=np.int32), counts)
    cols = (matrix.indices[start:stop] + 1).astype(np.int32)
    return rows, cols, matrix.data[start:stop]


def _send_arrays(comm: Any, rank: int, arrays: tuple[np.ndarray, ...]) -> None:
    comm.send([(a.dtype.str, a.size) for a in arrays], dest=rank, tag=1)
    for array in arrays:
        comm.Send(np.ascontiguousarray(array), dest=rank, tag=2)


def _receive_arrays(comm: Any) -> list[np.ndarray]:
    arrays = []
    for dtype, size in comm.recv(source=0, tag=1):
        array = np.empty(size, dtype=dtype)
        comm.Recv(array, source=0, tag=2)
        arrays.append(array)
    return arrays


class MumpsFactor(SparseFactor):
    """A MUMPS factorization spread over all MPI ranks (see the module docstring).

    Parameters
    ----------
    matrix : sparse matrix, shape (n, n), float64 or complex128
    symmetric : bool
        ``A = A^T``: ``L D L^T`` of the upper triangle (``SYM = 2``), else ``L U``.

    Attributes
    ----------
    ranks : int
        MPI ranks that hold the factors.
    """

    backend = BACKEND

    def __init__(self, matrix: sp.spmatrix, symmetric: bool) -> None:
        start = time.perf_counter()
        matrix = sp.csr_matrix(sp.triu(matrix, format="csr") if symmetric else matrix)
        matrix.sum_duplicates()
        complex_ = np.iscomplexobj(matrix.data)
        super().__init__(matrix.shape, np.complex128 if complex_ else np.float64, symmetric)
        if not np.all(np.isfinite(matrix.data)):
            raise NumericalError("the matrix has entries that are not finite")
        n = matrix.shape[0]
        with _LOCK:
            comm = _host_comm()
            self.ranks = comm.size
            self.key = next(_KEYS)
            _command(comm, "factor", self.key, complex_, symmetric, n)
            bounds = _row_blocks(matrix.indptr, comm.size)
            for rank in range(1, comm.size):
                _send_arrays(comm, rank, _triplets(matrix, bounds[rank], bounds[rank + 1]))
            instance = _Instance(complex_, symmetric)
            code = instance.factor(n, *_triplets(matrix, bounds[0], bounds[1]))
            if code < 0:
                instance.end()  # the other ranks end theirs on the same global code
                raise NumericalError(_failure(code, instance.struct.infog[1]))
            _INSTANCES[self.key] = instance
        infog = instance.struct.infog
        entries = infog[28]  # INFOG(29): entries of the factors, all ranks
        self._entries = int(entries if entries >= 0 else -entries * 1_000_000)
        self._memory_mb = int(infog[21])  # INFOG(22): MB used by the factorization, all ranks
        #: The fill-reducing ordering MUMPS chose (``INFOG(7)``, :data:`ORDERINGS`).
        self.ordering = ORDERINGS.get(int(infog[6]), str(int(infog[6])))
        self._finalizer = weakref.finalize(self, _PENDING.append, self.key)
        self.seconds = time.perf_counter() - start

    @property
    def nnz_factor(self) -> int:
        return self._entries

    @property
    def memory_bytes(self) -> int:
        """Memory of the factorization on all ranks together, bytes (MUMPS's ``INFOG(22)``)."""
        return self._memory_mb * 1_000_000

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        block = np.array(rhs.reshape(rhs.shape[0], -1), dtype=self.dtype, order="F")
        with _LOCK:
            comm = _host_comm()
            _command(comm, "solve", self.key)
            code = _INSTANCES[self.key].solve(block)
        if code < 0:
            raise NumericalError(_failure(code, 0))
        if not np.all(np.isfinite(block)):
            raise NumericalError("the matrix is singular (MUMPS returned non-finite values)")
        return block.reshape(rhs.shape)


def _failure(code: int, detail: int) -> str:
    """The message of a MUMPS error code ``INFOG(1)`` (with ``INFOG(2)``)."""
    if code in SINGULAR_CODES:
        return f"the matrix is singular (MUMPS: {SINGULAR_CODES[code]})"
    return f"MUMPS failed with INFOG(1) = {code}, INFOG(2) = {detail} (see the MUMPS manual)"


def mumps_factor(matrix: sp.spmatrix, symmetric: bool) -> SparseFactor:
    """The backend's factory: a :class:`MumpsFactor`, or in a forked child of the host (which
    cannot take part in MPI calls) a factor of the local default backend."""
    if _HOST["pid"] is not None and os.getpid() != _HOST["pid"]:
        return factorize(matrix, symmetric, _local_backend())
    return MumpsFactor(matrix, symmetric)


def _local_backend() -> str:
    return available_backends()[-1]


@cache
def mumps_works() -> bool:
    """mpi4py and Debian's MUMPS are installed and solve a small symmetric indefinite system."""
    try:
        matrix = sp.csr_matrix(np.array([[2.0, 1.0, 0.0], [1.0, -3.0, 1.0], [0.0, 1.0, 4.0]]))
        x = MumpsFactor(matrix, symmetric=True).solve(np.array([3.0, -1.0, 5.0]))
    except (ImportError, OSError, AttributeError, NumericalError):
        return False
    return bool(np.allclose(x, 1.0, rtol=1e-12, atol=0.0))


def rank_statistics() -> list[dict[str, float]]:
    """Per rank (host first): peak resident memory (MB) and the sum over its live factors of
    :meth:`_Instance.statistics`; a collective command."""
    with _LOCK:
        comm = _host_comm()
        _command(comm, "statistics")
        return comm.gather(_own_statistics(), root=0)


def _own_statistics() -> dict[str, float]:
    import resource  # Unix only, as MPI here

    totals = {"factor_space": 0.0, "factorization_mb": 0.0, "solve_mb": 0.0}
    for instance in _INSTANCES.values():
        for name, value in instance.statistics().items():
            totals[name] += value
    totals["factors"] = float(len(_INSTANCES))
    totals["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return totals


def stop_solver_ranks() -> None:
    """Free every factor and end the other ranks' service (on the host; at exit by itself)."""
    if _HOST["pid"] != os.getpid() or _HOST["stopped"]:
        return
    with _LOCK:
        _HOST["stopped"] = True
        _PENDING.extend(_INSTANCES)
        _command(_mpi().COMM_WORLD, "stop")


def serve_solver_ranks() -> bool:
    """Under ``mpiexec`` with ``PYMOREMBS_SOLVER=mumps-mpi``: on every rank but 0, serve the
    host's factorizations until it stops, then return True (the caller ends); on rank 0 and
    without a launcher return False at once, without initializing MPI.

    Raises
    ------
    UserError
        Several ranks were launched but the solver is not ``mumps-mpi`` (each rank would run the
        whole job); on rank 0 only, the others return True.
    """
    if launched_ranks() <= 1:
        return False
    if os.environ.get(SOLVER_ENV, "").strip().lower() != BACKEND:
        if _launched_rank() != 0:
            return True
        raise UserError(
            f"pymorembs was started on {launched_ranks()} MPI ranks, which only the distributed "
            f"solver uses: set {SOLVER_ENV}={BACKEND} (or run without mpiexec)"
        )
    comm = _mpi().COMM_WORLD
    if comm.rank == 0:
        _host_comm()  # the others wait for commands: stop them at exit, also if none comes
        return False
    _serve(comm)
    return True


def _next_command(comm: Any) -> tuple[str, list[int], tuple[Any, ...]]:
    """Wait for the host's next command, asleep between polls (a blocking receive of Open MPI
    spins, taking a core from the host while it projects, checks and writes): polls every
    :data:`POLL_S` at first, up to every :data:`IDLE_POLL_S` after a second of quiet."""
    started = time.perf_counter()
    while not comm.Iprobe(source=0, tag=COMMAND_TAG):
        idle = time.perf_counter() - started
        time.sleep(POLL_S if idle < 1.0 else IDLE_POLL_S)
    return comm.recv(source=0, tag=COMMAND_TAG)


def _serve(comm: Any) -> None:
    """The command loop of a rank other than 0."""
    while True:
        operation, frees, arguments = _next_command(comm)
        for key in frees:
            instance = _INSTANCES.pop(key, None)
            if instance is not None:
                instance.end()
        if operation == "stop":
            for instance in _INSTANCES.values():
                instance.end()
            return
        if operation == "factor":
            key, complex_, symmetric, n = arguments
            rows, cols, values = _receive_arrays(comm)
            instance = _Instance(complex_, symmetric)
            if instance.factor(n, rows, cols, values) < 0:
                instance.end()
            else:
                _INSTANCES[key] = instance
        elif operation == "solve":
            _INSTANCES[arguments[0]].solve(None)
        elif operation == "statistics":
            comm.gather(_own_statistics(), root=0)


register_backend(BACKEND, mumps_factor, mumps_works, "install MUMPS and mpi4py: make mpi")
