"""Sparse linear algebra: factorizations, products, the massless part of a mass matrix.

A public subpackage for the few names below (``docs/api.md``, "The public surface"): the
massless split of a mass matrix (:func:`mass_split`) and the sparse solver backends
(:func:`available_backends`, :func:`default_backend`, chosen by ``PYMOREMBS_SOLVER``), the
factors one job shares between its steps (:func:`shared_factorizations`), and the service of
the other MPI ranks of the distributed backend (:func:`serve_solver_ranks`).
"""

from pymorembs.linalg.backends import available_backends, default_backend
from pymorembs.linalg.mass_split import MassSplit, mass_split
from pymorembs.linalg.mumps_mpi import serve_solver_ranks
from pymorembs.linalg.shared_factors import SharedFactors, shared_factorizations

__all__ = [
    "MassSplit",
    "SharedFactors",
    "available_backends",
    "default_backend",
    "mass_split",
    "serve_solver_ranks",
    "shared_factorizations",
]
