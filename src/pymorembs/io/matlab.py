"""Read a body from a MATLAB ``.mat`` file with ``M``, ``K`` and optionally ``D``, ``B``, ``C``.

This is the form in which the model-reduction community publishes second-order benchmarks
(``M x'' + E x' + K x = B u``, ``y = C x``) and in which MATLAB users keep FE matrices::

    save('model.mat', 'M', 'K', 'B', 'C')            % v5/v7 (compressed since v7)
    save('model.mat', 'M', 'K', 'D', 'B', 'C', '-v7.3')  % HDF5-based, for files > 2 GB

Storage (:func:`read_mat_variables`): v4 and v5/v7 files are read with ``scipy.io.loadmat``;
v7.3 files are HDF5 files (a 512-byte MATLAB header, then HDF5) read with ``h5py``: a variable
is a dataset with the attribute ``MATLAB_class``, stored with its dimensions reversed (MATLAB is
column-major), so a dense matrix is transposed back; a sparse matrix is a group with the
attribute ``MATLAB_sparse`` (the number of rows) and the datasets ``jc`` (column pointers),
``ir`` (row indices) and ``data`` (values; ``ir`` and ``data`` are absent when the matrix has no
nonzero), i.e. compressed sparse columns; complex values are a compound type ``(real, imag)``.
Only the variables the body needs are loaded.

Which variable is what (names compared case-insensitively; ``stiffness``, ``mass`` and
``damping`` override the rules, as ``--stiffness-name``, ``--mass-name`` and
``--damping-name`` do on the command line):

* stiffness ``K`` (or ``stiffness``) and mass ``M`` (or ``mass``): required, square, real,
  symmetric (to :data:`~pymorembs.io.matrix_market.SYMMETRY_TOLERANCE`), of equal size ``n``;
* damping: ``D`` or ``E`` (the MORwiki name) when it is ``n x n`` (a ``D`` of another size is
  the feedthrough of a state-space model and is ignored); else ``C`` of the structural
  convention ``M, C, K`` (MATLAB's ``mechss``) when ``C`` is ``n x n`` and either there is no
  input matrix ``B`` or the outputs come as ``F``. ``C`` of size ``n x n`` next to ``B`` without
  ``F`` is ambiguous and refused: name the damping (``damping='C'``) or say there is none
  (``damping='none'``);
* inputs ``B`` (``n x p``) and outputs ``C`` (``r x n``; ``F`` when ``C`` is the damping)
  become the body's :class:`~pymorembs.body.ModelPorts`; a velocity output ``G`` is not
  supported and noted as ignored.

Without ``dofs`` the equations are scalar coordinates ``q`` numbered ``1 .. n`` (no node, no
position: ``has_coordinates`` is false); with ``dofs`` (``dofs.csv``, header
``node,direction``) they are nodal dofs, and ``nodes`` (``nodes.csv``) gives the coordinates.

Every mistake raises :class:`~pymorembs.errors.UserError` with one line ``file: problem``; no
exception of SciPy or h5py escapes.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from pymorembs.body import SCALAR, DofTable, ElasticBody, ModelPorts
from pymorembs.errors import UserError, located_error
from pymorembs.io.checks import reason
from pymorembs.io.mat5 import Mat5Entry, is_v5, load_v5, scan_v5
from pymorembs.io.matrix_market import check_symmetric, read_dofs_csv
from pymorembs.io.node_files import read_node_file

__all__ = ["MatVariable", "mat_variables", "read_mat_variables", "read_matlab"]

PathLike = str | os.PathLike[str]

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_HDF5_OFFSET = 512  # v7.3 files: the MATLAB header is an HDF5 user block of 512 bytes
_DENSE_LIMIT = 1 << 31  # bytes: a larger dense variable must be stored sparse
_NUMERIC = {
    "double",
    "single",
    "int8",
    "uint8",
    "int16",
    "uint16",
    "int32",
    "uint32",
    "int64",
    "uint64",
    "logical",
}
_STIFFNESS_NAMES = ("K", "stiffness")
_MASS_NAMES = ("M", "mass")
_DAMPING_NAMES = ("D", "E", "damping")
_NO_DAMPING = "none"


@dataclass(frozen=True)
class MatVariable:
    """One variable of a MAT-file, as listed before loading.

    ``shape`` is MATLAB's (rows, columns, ...); ``kind`` is the MATLAB class (``double``,
    ``single``, ``int32``, ``logical``, ``char``, ``cell``, ``struct``, ...) or ``sparse``.
    """

    name: str
    shape: tuple[int, ...]
    kind: str

    def describe(self) -> str:
        """e.g. ``"K (12x12 sparse)"``."""
        return f"{self.name} ({'x'.join(str(s) for s in self.shape)} {self.kind})"


# ============================================================================ storage
def _version(path: Path) -> str:
    """``"hdf5"`` (v7.3), ``"v5"`` (level 5: v6, v7) or ``"v4"`` (no text header)."""
    try:
        if not path.is_file():
            if path.is_dir():
                raise located_error(path, None, "is a directory, expected a MATLAB .mat file")
            raise located_error(path, None, "file not found (expected a MATLAB .mat file)")
        with open(path, "rb") as f:
            head = f.read(_HDF5_OFFSET + 8)
    except OSError as err:
        raise located_error(path, None, f"cannot read: {err.strerror or err}") from None
    if not head:
        raise located_error(path, None, "empty file (expected a MATLAB .mat file)")
    if head[_HDF5_OFFSET:] == _HDF5_SIGNATURE or head.startswith(_HDF5_SIGNATURE):
        return "hdf5"
    if is_v5(head):
        return "v5"
    if 0 in head[:4]:  # the type code of a v4 matrix header (scipy's rule)
        return "v4"
    raise located_error(path, None, "not a MATLAB .mat file (no v5 or v7.3 header, not a v4 file)")


def _v5_entries(path: Path) -> dict[str, Mat5Entry]:
    try:
        data = path.read_bytes()
    except OSError as err:
        raise located_error(path, None, f"cannot read: {err.strerror or err}") from None
    return {entry.name: entry for entry in scan_v5(path, data)}


def mat_variables(path: PathLike) -> list[MatVariable]:
    """The variables of a MAT-file (name, MATLAB shape, class) without loading their data.

    Raises
    ------
    UserError
        Not a MAT-file (or a damaged one), an HDF5 file without MATLAB variables.
    """
    path = Path(path)
    version = _version(path)
    if version == "hdf5":
        return _hdf5_inventory(path)
    if version == "v5":
        return [MatVariable(e.name, e.shape, e.kind) for e in _v5_entries(path).values()]
    from scipy.io import whosmat

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            listed = whosmat(str(path))
    except Exception as err:  # scipy raises many kinds for a file that is not a MAT-file
        raise located_error(
            path, None, f"not a readable MATLAB .mat file ({reason(err)})"
        ) from None
    return [
        MatVariable(str(n), tuple(int(s) for s in shape), str(kind)) for n, shape, kind in listed
    ]


def read_mat_variables(
    path: PathLike, names: list[str] | None = None
) -> dict[str, np.ndarray | sp.csc_matrix]:
    """Load variables of a MAT-file: numeric arrays (MATLAB shape) and sparse matrices (CSC).

    Parameters
    ----------
    path : path-like
        A v4, v5/v7 or v7.3 MAT-file.
    names : list of str, optional
        The variables to load (default: all numeric and sparse ones).

    Returns
    -------
    dict
        name -> ``ndarray`` (dense, at least 2-D, real or complex) or ``scipy.sparse.csc_matrix``.

    Raises
    ------
    UserError
        An unreadable file, a variable that is missing or not numeric (struct, cell, char,
        object), a dense variable of more than 2 GiB, a damaged sparse matrix.
    """
    path = Path(path)
    inventory = {v.name: v for v in mat_variables(path)}
    if names is None:
        names = [n for n, v in inventory.items() if v.kind in _NUMERIC or v.kind == "sparse"]
    for name in names:
        if name not in inventory:
            raise located_error(path, None, f"no variable named {name!r}")
        _check_loadable(path, inventory[name])
    if not names:
        return {}
    version = _version(path)
    if version == "hdf5":
        return _hdf5_load(path, names)
    if version == "v5":
        entries = _v5_entries(path)
        return {name: _at_least_2d(load_v5(path, entries[name])) for name in names}
    return _v4_load(path, names)


def _at_least_2d(value: np.ndarray | sp.csc_matrix) -> np.ndarray | sp.csc_matrix:
    return value if sp.issparse(value) else np.atleast_2d(value)


def _v4_load(path: Path, names: list[str]) -> dict[str, np.ndarray | sp.csc_matrix]:
    """Level-4 files through scipy (its v4 reader is written in Python)."""
    from scipy.io import loadmat

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = loadmat(str(path), variable_names=list(names), squeeze_me=False)
    except Exception as err:
        raise located_error(path, None, f"cannot read the .mat file ({reason(err)})") from None
    out: dict[str, np.ndarray | sp.csc_matrix] = {}
    for name in names:
        value = loaded.get(name)
        if sp.issparse(value):
            out[name] = sp.csc_matrix(value)
        elif isinstance(value, np.ndarray) and value.dtype.kind in "biufc":
            out[name] = np.atleast_2d(value)
        else:
            raise located_error(path, None, f"variable {name!r} is not a numeric matrix")
    return out


def _check_loadable(path: Path, variable: MatVariable) -> None:
    if variable.kind not in _NUMERIC and variable.kind != "sparse":
        raise located_error(
            path, None, f"variable {variable.describe()} is a {variable.kind}, not a matrix"
        )
    if variable.kind != "sparse":
        size = int(np.prod(variable.shape, dtype=np.float64)) * 16
        if size > _DENSE_LIMIT:
            raise located_error(
                path,
                None,
                f"variable {variable.describe()} is dense and needs {size / 2**30:.1f} GiB; "
                "save it as a sparse matrix (sparse(...))",
            )


def _hdf5(path: Path):
    try:
        import h5py
    except ImportError as err:  # pragma: no cover - a declared dependency
        raise located_error(path, None, f"reading v7.3 .mat files needs h5py ({err})") from None
    try:
        return h5py.File(path, "r")
    except Exception as err:
        raise located_error(path, None, f"not a readable HDF5 file ({reason(err)})") from None


def _text(value: object) -> str:
    if isinstance(value, bytes | np.bytes_):
        return value.decode("latin-1")
    return str(value)


def _hdf5_inventory(path: Path) -> list[MatVariable]:
    variables = []
    with _hdf5(path) as f:
        try:
            for key in f:
                if key.startswith("#"):  # #refs#, #subsystem#: MATLAB's internal groups
                    continue
                item = f[key]
                attrs = item.attrs
                kind = _text(attrs.get("MATLAB_class", b""))
                if not kind:
                    continue
                if "MATLAB_sparse" in attrs:
                    jc = item.get("jc")
                    columns = int(jc.shape[0]) - 1 if jc is not None and jc.ndim == 1 else -1
                    variables.append(
                        MatVariable(key, (int(attrs["MATLAB_sparse"]), columns), "sparse")
                    )
                elif hasattr(item, "shape"):
                    shape = tuple(int(s) for s in item.shape[::-1])
                    if attrs.get("MATLAB_empty", 0):
                        shape = tuple(int(s) for s in np.ravel(item[()]))[::-1] or (0, 0)
                    variables.append(MatVariable(key, shape, kind))
                else:
                    variables.append(MatVariable(key, (1, 1), kind))
        except Exception as err:
            raise located_error(path, None, f"cannot read the HDF5 file ({reason(err)})") from None
    if not variables:
        raise located_error(
            path,
            None,
            "an HDF5 file without MATLAB variables (no MATLAB_class attributes): not a MATLAB "
            "7.3 .mat file",
        )
    return variables


def _hdf5_load(path: Path, names: list[str]) -> dict[str, np.ndarray | sp.csc_matrix]:
    out: dict[str, np.ndarray | sp.csc_matrix] = {}
    with _hdf5(path) as f:
        for name in names:
            try:
                item = f[name]
                if "MATLAB_sparse" in item.attrs:
                    out[name] = _hdf5_sparse(path, name, item)
                elif item.attrs.get("MATLAB_empty", 0):
                    dims = tuple(int(s) for s in np.ravel(item[()]))[::-1]
                    out[name] = np.zeros(dims if len(dims) >= 2 else (0, 0))
                else:
                    out[name] = np.atleast_2d(np.transpose(_values(item[()])))
            except UserError:
                raise
            except Exception as err:
                raise located_error(
                    path, None, f"cannot read variable {name!r} ({reason(err)})"
                ) from None
    return out


def _values(data: np.ndarray) -> np.ndarray:
    """Numeric values; a compound ``(real, imag)`` array becomes complex."""
    data = np.asarray(data)
    if data.dtype.names:
        if set(data.dtype.names) != {"real", "imag"}:
            raise ValueError(f"compound values with fields {data.dtype.names}")
        return data["real"] + 1j * data["imag"]
    if data.dtype.kind not in "biuf":
        raise ValueError(f"values of type {data.dtype}")
    return data


def _hdf5_sparse(path: Path, name: str, group) -> sp.csc_matrix:
    """A MATLAB sparse matrix stored as ``jc``, ``ir``, ``data`` (compressed sparse columns)."""
    rows = int(group.attrs["MATLAB_sparse"])
    jc = np.asarray(group["jc"][()], dtype=np.int64).ravel()
    ir = np.asarray(group["ir"][()], dtype=np.int64).ravel() if "ir" in group else np.zeros(0)
    values = _values(group["data"][()]).ravel() if "data" in group else np.zeros(0)
    nnz = ir.size
    bad = (
        jc.size < 1
        or jc[0] != 0
        or jc[-1] != nnz
        or values.size != nnz
        or np.any(np.diff(jc) < 0)
        or (nnz and (ir.min() < 0 or ir.max() >= rows))
    )
    if bad:
        raise located_error(path, None, f"variable {name!r}: damaged sparse matrix (jc, ir, data)")
    return sp.csc_matrix((values, ir.astype(np.int64), jc), shape=(rows, jc.size - 1))


# ============================================================================ the body
def read_matlab(
    path: PathLike,
    stiffness: str | None = None,
    mass: str | None = None,
    damping: str | None = None,
    dofs: PathLike | None = None,
    nodes: PathLike | None = None,
    name: str | None = None,
) -> ElasticBody:
    """Read a body from a MATLAB ``.mat`` file (rules in the module docstring).

    Parameters
    ----------
    path : path-like
        The ``.mat`` file (v4, v5/v7 or v7.3).
    stiffness, mass, damping : str, optional
        Variable names of ``K``, ``M`` and the damping matrix (``"none"``: the file holds no
        damping matrix; its ``C`` is then the output matrix). Default: found by the rules.
    dofs : path-like, optional
        ``dofs.csv``: the dof of every equation. Without it the equations are scalar
        coordinates ``q`` numbered 1..n.
    nodes : path-like, optional
        ``nodes.csv`` with the coordinates of the nodes of ``dofs`` (needs ``dofs``).
    name : str, optional
        Label of the body; default: the file name without extension.

    Returns
    -------
    ElasticBody
        ``K``, ``M`` (and the damping matrix) as given; ``ports`` hold ``B`` and ``C`` when the
        file has them; ``notes`` say which variable was taken for what.

    Raises
    ------
    UserError
        No stiffness or mass matrix (the message lists the variables), an ambiguous name, a
        struct/cell/char where a matrix is needed, complex, non-square, non-symmetric or
        non-finite matrices, matrices of different sizes, ``B`` or ``C`` of the wrong shape,
        a ``dofs.csv`` of another length; one line starting with the file name.
    """
    path = Path(path)
    inventory = mat_variables(path)
    roles = _assign(path, inventory, stiffness, mass, damping)
    values = read_mat_variables(path, [v for v in roles.values() if v is not None])

    def matrix(role: str) -> sp.csr_matrix | None:
        variable = roles.get(role)
        return None if variable is None else _real_matrix(path, variable, values[variable])

    k_matrix, m_matrix = matrix("stiffness"), matrix("mass")
    n = k_matrix.shape[0]
    if k_matrix.shape[1] != n:
        raise located_error(
            path,
            None,
            f"variable {roles['stiffness']} (stiffness) is {n} x {k_matrix.shape[1]}, not square",
        )
    if n == 0:
        raise located_error(
            path, None, f"variable {roles['stiffness']} (stiffness) is empty: no dofs"
        )
    for role in ("stiffness", "mass", "damping"):
        a = k_matrix if role == "stiffness" else m_matrix if role == "mass" else matrix(role)
        if a is None:
            continue
        if a.shape != (n, n):
            raise located_error(
                path,
                None,
                f"variable {roles[role]} ({role}) is {a.shape[0]} x {a.shape[1]}; K is {n} x {n}",
            )
        check_symmetric(a, f"{path}: variable {roles[role]} ({role})")
    d_matrix = matrix("damping")
    ports = _ports(path, roles, values, n)
    table, node_ids, coordinates, has_coordinates, table_note = _dof_table(path, n, dofs, nodes)
    notes = [table_note, _roles_note(path, roles, inventory)]
    try:
        return ElasticBody(
            node_ids=node_ids,
            coordinates=coordinates,
            dofs=table,
            mass=m_matrix,
            stiffness=k_matrix,
            damping_matrix=d_matrix,
            name=path.stem if name is None else name,
            has_coordinates=has_coordinates,
            notes=tuple(notes),
            ports=ports,
        )
    except UserError as err:
        raise located_error(path, None, str(err)) from None


def _find(variables: list[MatVariable], names: tuple[str, ...], what: str, path: Path):
    """The variable whose name is one of ``names`` (case-insensitive); None if there is none."""
    wanted = {n.lower() for n in names}
    hits = [v for v in variables if v.name.lower() in wanted]
    if len(hits) > 1:
        listed = " and ".join(v.name for v in hits)
        raise located_error(
            path,
            None,
            f"variables {listed} could both be the {what}; name it (--{what}-name)",
        )
    return hits[0] if hits else None


def _named(variables: list[MatVariable], given: str, what: str, path: Path) -> MatVariable:
    """The variable the user named (exact name first, then case-insensitive)."""
    exact = [v for v in variables if v.name == given]
    if exact:
        return exact[0]
    found = _find(variables, (given,), what, path)
    if found is None:
        raise located_error(
            path,
            None,
            f"no variable named {given!r} for the {what}; the file holds {_listing(variables)}",
        )
    return found


def _listing(variables: list[MatVariable]) -> str:
    shown = ", ".join(v.describe() for v in variables[:12])
    more = f" and {len(variables) - 12} more" if len(variables) > 12 else ""
    return (shown + more) if variables else "no variables"


def _assign(
    path: Path,
    variables: list[MatVariable],
    stiffness: str | None,
    mass: str | None,
    damping: str | None,
) -> dict[str, str | None]:
    """Variable name of each role: stiffness, mass, damping, inputs, outputs (rules: module)."""
    roles: dict[str, str | None] = {}
    for role, given, names in (
        ("stiffness", stiffness, _STIFFNESS_NAMES),
        ("mass", mass, _MASS_NAMES),
    ):
        found = (
            _named(variables, given, role, path) if given else _find(variables, names, role, path)
        )
        if found is None:
            first_order = _find(variables, ("A",), "system matrix", path)
            hint = (
                " (it looks like a first-order system A, B, C, E; pymorembs reads second-order "
                "models M, K)"
                if first_order is not None
                else ""
            )
            raise located_error(
                path,
                None,
                f"no {role} matrix: the file holds {_listing(variables)}{hint}; name it with "
                f"--{role}-name",
            )
        roles[role] = found.name
    by_name = {v.name: v for v in variables}
    n = by_name[roles["stiffness"]].shape[0]
    square = [v for v in variables if v.shape == (n, n) and v.name not in roles.values()]

    def pick(names: tuple[str, ...], among: list[MatVariable], what: str):
        found = _find(among, names, what, path)
        return None if found is None else found.name

    b = pick(("B",), variables, "input matrix")
    c_var = _find(variables, ("C",), "output matrix", path)
    f = pick(("F",), variables, "output matrix")
    if damping is not None and damping.strip().lower() == _NO_DAMPING:
        roles["damping"] = None
    elif damping:
        roles["damping"] = _named(variables, damping, "damping", path).name
    else:
        roles["damping"] = pick(_DAMPING_NAMES, square, "damping")
        if roles["damping"] is None and c_var is not None and c_var.shape == (n, n):
            if b is not None and f is None:
                raise located_error(
                    path,
                    None,
                    f"variable C is {n} x {n} next to B: it may be the damping matrix (M, C, K) "
                    "or the output matrix; name the damping (--damping-name C) or say there is "
                    "none (--damping-name none)",
                )
            roles["damping"] = c_var.name
    roles["inputs"] = b
    c_is_damping = c_var is not None and roles["damping"] == c_var.name
    roles["outputs"] = f if c_is_damping or c_var is None else c_var.name
    return roles


def _real_matrix(path: Path, variable: str, value: np.ndarray | sp.spmatrix) -> sp.csr_matrix:
    """A real, finite, 2-D matrix as CSR."""
    if sp.issparse(value):
        a = sp.csr_matrix(value)
    else:
        array = np.asarray(value)
        if array.ndim != 2:
            raise located_error(
                path, None, f"variable {variable} has {array.ndim} dimensions, not 2"
            )
        a = sp.csr_matrix(array)
    if np.iscomplexobj(a.data):
        if np.any(a.data.imag != 0):
            raise located_error(
                path,
                None,
                f"variable {variable} is complex; mass, stiffness, damping, B and C must be "
                "real (structural damping as an imaginary stiffness is not supported)",
            )
        a = sp.csr_matrix(a.real)
    a = sp.csr_matrix(a, dtype=np.float64)
    if not np.all(np.isfinite(a.data)):
        raise located_error(path, None, f"variable {variable} has NaN or infinite entries")
    a.eliminate_zeros()
    a.sort_indices()
    return a


def _ports(path: Path, roles: dict[str, str | None], values: dict, n: int) -> ModelPorts | None:
    """``B`` (n x p) and ``C`` (r x n) as the body's ports."""
    inputs = outputs = None
    if roles.get("inputs"):
        inputs = _real_matrix(path, roles["inputs"], values[roles["inputs"]])
        if inputs.shape[0] != n:
            flipped = (
                " (stored transposed? B needs one row per equation)" if inputs.shape[1] == n else ""
            )
            raise located_error(
                path,
                None,
                f"input matrix {roles['inputs']} is {inputs.shape[0]} x {inputs.shape[1]}, "
                f"expected {n} rows{flipped}",
            )
    if roles.get("outputs"):
        outputs = _real_matrix(path, roles["outputs"], values[roles["outputs"]])
        if outputs.shape[1] != n:
            flipped = (
                " (stored transposed? C needs one column per equation)"
                if outputs.shape[0] == n
                else ""
            )
            raise located_error(
                path,
                None,
                f"output matrix {roles['outputs']} is {outputs.shape[0]} x {outputs.shape[1]}, "
                f"expected {n} columns{flipped}",
            )
        if inputs is None:
            raise located_error(
                path,
                None,
                f"output matrix {roles['outputs']} without an input matrix B; give B too",
            )
    if inputs is None:
        return None
    try:
        return ModelPorts(inputs=inputs, outputs=outputs)
    except UserError as err:
        raise located_error(path, None, str(err)) from None


def _dof_table(
    path: Path, n: int, dofs: PathLike | None, nodes: PathLike | None
) -> tuple[DofTable, np.ndarray, np.ndarray, bool, str]:
    """The dof table: scalar coordinates 1..n, or dofs.csv (with nodes.csv for coordinates)."""
    if dofs is None:
        if nodes is not None:
            raise located_error(
                Path(nodes), None, "node coordinates need the dof table (dofs.csv) too"
            )
        table = DofTable(np.arange(1, n + 1), np.full(n, SCALAR))
        note = (
            f"dof table: {n} scalar coordinates (q) numbered 1..{n}; {path.name} has no dof "
            "labels (give dofs.csv to make them nodal)"
        )
        return table, np.zeros(0, dtype=np.int64), np.zeros((0, 3)), False, note
    dofs_path = Path(dofs)
    table, _ = read_dofs_csv(dofs_path)
    if len(table) != n:
        raise located_error(
            dofs_path, None, f"{len(table)} dofs but the matrices of {path} are {n} x {n}"
        )
    geometric = ~table.scalar
    if nodes is None:
        _, first = np.unique(table.nodes[geometric], return_index=True)
        node_ids = table.nodes[geometric][np.sort(first)]
        note = f"dof table: {table.describe()} from {dofs_path.name}; no coordinates"
        return table, node_ids, np.zeros((node_ids.size, 3)), False, note
    node_file = read_node_file(nodes)
    nodes_path, node_ids, coordinates = node_file.path, node_file.ids, node_file.coordinates
    missing = np.setdiff1d(table.nodes[geometric], node_ids)
    if missing.size:
        raise located_error(
            nodes_path, None, f"node {int(missing[0])} of {dofs_path} is not listed"
        )
    note = (
        f"dof table: {table.describe()} from {dofs_path.name}, coordinates from "
        f"{node_file.describe()}"
    )
    return table, node_ids, coordinates, True, note


def _roles_note(path: Path, roles: dict[str, str | None], variables: list[MatVariable]) -> str:
    used = {v for v in roles.values() if v}
    parts = [f"{roles[r]} = {r}" for r in ("stiffness", "mass", "damping") if roles.get(r)]
    if roles.get("inputs"):
        parts.append(f"{roles['inputs']} = inputs")
    if roles.get("outputs"):
        parts.append(f"{roles['outputs']} = outputs")
    ignored = [v.name for v in variables if v.name not in used]
    text = f"variables of {path.name}: {', '.join(parts)}"
    if ignored:
        text += f"; not used: {', '.join(ignored[:10])}{' ...' if len(ignored) > 10 else ''}"
    return text
