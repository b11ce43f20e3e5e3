"""Small models for the tests, built independently of the code under test."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from pymorembs.body import ConstraintEquations, Damping, DofTable, ElasticBody


def spring_lattice(
    n_nodes: int = 12,
    seed: int = 0,
    constraints: bool = True,
    offsets: bool = False,
    damping: Damping | None = None,
) -> ElasticBody:
    """A chain of point masses in 3-D (3 translational dofs each) joined by central springs.

    Node ids are 10, 20, 30, ... (not contiguous). The nodes wind along x on a helix of radius
    0.1 m with three nodes per turn, 0.05 m apart in x, moved randomly by a tenth of the radius
    (general 3-D positions); masses of 0.5 to 2 kg and springs of 4e5 to 1.2e6 N/m give SI
    numbers of a light material (mass / box volume ~ 1000 kg/m^3, lowest frequency ~ 10 Hz
    for 12 nodes). Each node
    is joined to the next three by an axial spring ``k e e^T`` (``e`` the unit vector between
    them), so the lattice is rigid (every node after the first three is held by three bars to
    three others), and the springs resist no rigid motion. Springs to ground at the x, y, z of
    nodes 10, 20 and 30 hold it, so the stiffness matrix is positive definite; their rows are
    support rows. Each node has the same mass in its three directions, nodes 20 and 30 a
    little consistent-mass coupling (``0.05 I``): the rigid-body fields see a rigid body's
    mass. With ``constraints``, the dofs of the last node are dependent: a linear combination
    of dofs of two other nodes (plus offsets if asked).
    """
    rng = np.random.default_rng(seed)
    n = 3 * n_nodes
    ids = 10 * np.arange(1, n_nodes + 1)
    turn = 2 * np.pi / 3 * np.arange(n_nodes)
    coords = 0.1 * np.column_stack([0.5 * np.arange(n_nodes), np.cos(turn), np.sin(turn)])
    coords += 0.01 * rng.normal(size=(n_nodes, 3))
    k = np.zeros((n, n))
    for i in range(n_nodes - 1):
        for j in range(i + 1, min(i + 4, n_nodes)):
            e = (coords[j] - coords[i]) / np.linalg.norm(coords[j] - coords[i])
            spring = 4e5 * rng.uniform(1.0, 3.0) * np.outer(e, e)
            blk_i, blk_j = slice(3 * i, 3 * i + 3), slice(3 * j, 3 * j + 3)
            k[blk_i, blk_i] += spring
            k[blk_j, blk_j] += spring
            k[blk_i, blk_j] -= spring
            k[blk_j, blk_i] -= spring
    k[:9, :9] += 1e6 * np.eye(9)  # anchors: nodes 10, 20, 30 to ground
    m = np.diag(np.repeat(rng.uniform(0.5, 2.0, size=n_nodes), 3))
    m[3:6, 6:9] = m[6:9, 3:6] = 0.05 * np.eye(3)  # a little consistent-mass coupling
    dofs = DofTable(np.repeat(ids, 3), np.tile([0, 1, 2], n_nodes))
    equations = None
    if constraints:
        dependent = np.arange(n - 3, n)
        g = np.zeros((3, n))
        g[:, 3 * (n_nodes - 2) : 3 * (n_nodes - 1)] = np.eye(3)  # follows the previous node
        g[:, 3 * 2 : 3 * 3] = 0.3 * rng.normal(size=(3, 3))  # and partly node 30
        offset = rng.normal(size=3) * 1e-3 if offsets else np.zeros(3)
        equations = ConstraintEquations(dependent, sp.csr_matrix(g), offset)
    return ElasticBody(
        node_ids=ids,
        coordinates=coords,
        dofs=dofs,
        mass=sp.csr_matrix(m),
        stiffness=sp.csr_matrix(k),
        constraints=equations,
        damping=damping or Damping(),
        name="lattice",
    )


@pytest.fixture
def lattice() -> ElasticBody:
    return spring_lattice()


def space_truss(nx: int = 4, ny: int = 3, nz: int = 2, spacing: float = 0.1) -> ElasticBody:
    """A 3-D truss of steel bars on a grid (3 translational dofs per node), free in space.

    Bars join each node to its neighbours along the axes and the face and space diagonals, so
    the truss is stiff but has exactly six rigid-body modes. Node ids are ``1 + index``.
    """
    grid = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1)
    coords = spacing * grid.reshape(-1, 3).astype(float)
    n_nodes = coords.shape[0]
    index = np.arange(n_nodes).reshape(nx, ny, nz)
    bars = []
    for di in (0, 1):
        for dj in (-1, 0, 1):
            for dk in (-1, 0, 1):
                if (di, dj, dk) <= (0, 0, 0):
                    continue
                for i in range(nx - di):
                    for j in range(max(0, -dj), ny - max(0, dj)):
                        for k in range(max(0, -dk), nz - max(0, dk)):
                            bars.append((index[i, j, k], index[i + di, j + dj, k + dk]))
    ea, rho_a = 2.1e11 * 1e-4, 7850 * 1e-4
    n = 3 * n_nodes
    k_mat, m_mat = np.zeros((n, n)), np.zeros((n, n))
    for a, b in bars:
        d = coords[b] - coords[a]
        length = np.linalg.norm(d)
        e = d / length
        block = ea / length * np.outer(e, e)
        ia, ib = slice(3 * a, 3 * a + 3), slice(3 * b, 3 * b + 3)
        k_mat[ia, ia] += block
        k_mat[ib, ib] += block
        k_mat[ia, ib] -= block
        k_mat[ib, ia] -= block
        lumped = 0.5 * rho_a * length * np.eye(3)
        m_mat[ia, ia] += lumped
        m_mat[ib, ib] += lumped
    dofs = DofTable(np.repeat(np.arange(1, n_nodes + 1), 3), np.tile([0, 1, 2], n_nodes))
    return ElasticBody(
        np.arange(1, n_nodes + 1),
        coords,
        dofs,
        sp.csr_matrix(m_mat),
        sp.csr_matrix(k_mat),
        name="truss",
    )


@pytest.fixture(autouse=True, scope="session")
def _one_blas_thread():
    """BLAS on one thread, as the command line runs it (``PYMOREMBS_BLAS_THREADS``, default 1).

    The heavy work is sparse; threaded level-1 BLAS on small vectors (ARPACK, norms) is several
    times slower on two cores, and the tests would measure that instead.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


@pytest.fixture(params=["superlu", "pardiso"])
def each_solver(request, monkeypatch) -> str:
    """Runs a test once with each sparse solver backend (``PYMOREMBS_SOLVER``).

    Small matrices go to SuperLU under ``auto`` and large ones to PARDISO where it is installed,
    so a test on a small model would never reach PARDISO, and one on a large model never
    SuperLU, the fallback where MKL has no wheels. PARDISO's run is skipped where it is not
    available.
    """
    from pymorembs.linalg.backends import available_backends

    if request.param not in available_backends():
        pytest.skip(f"{request.param} is not available here")
    monkeypatch.setenv("PYMOREMBS_SOLVER", request.param)
    return request.param


def blade_job(**tables) -> dict:
    """A small job on the built-in blade (frame "none", one modal reduction) plus ``tables``."""
    return {
        "model": {"example": "blade"},
        "frame": {"type": "none"},
        "inputs": [{"node": 1, "directions": "ux"}],
        "band": {"f_max_hz": 100.0},
        "reduction": [{"name": "m", "method": "modal", "order": 4}],
        **tables,
    }


# --- the end of the test process -----------------------------------------------------------------

_EXIT_STATUS: list[int] = []


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    _EXIT_STATUS.append(int(exitstatus))


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config: pytest.Config) -> None:
    """End the process with pytest's status, without the interpreter's teardown of the native
    libraries: one full run passed every test and then died at exit in a segmentation fault
    ("Value still in symbol table!", from LLVM) with llvmlite and MKL's runtimes loaded side by
    side. The results are reported by then; only the exit code is protected."""
    if _EXIT_STATUS:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_EXIT_STATUS[-1])
