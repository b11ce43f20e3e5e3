"""The stress recovery file of a reduction (``<name>.stress.h5``): stress and strain modes.

For fatigue and strength tools: with the modal coordinates ``q(t)`` of a multibody run (the
coordinates of the exported SID, Neweul-M² or Exudyn body, in their order), the stress at every
integration point and node is ``sum_j q_j(t) stress[j]``; with unit loads, the static columns
give the quasi-static stress of each input. One HDF5 file, readable with h5py alone; the layout
is documented in ``docs/recovery.md`` (the names below are its datasets and attributes)::

    /                      attributes format = "pymorembs-stress-recovery", version = 1, name,
                           body, method, written_by, components ("xx yy zz xy xz yz"),
                           strain (the operator's strain convention), units, note
    /columns               labels (k,): "1" ... "m" (modal coordinates), then the inputs of the
                           static columns ("1:ux", "inertia:ax"); attribute n_shapes = m;
                           eigenfrequencies_hz (m,)
    /integration_points    element_ids, point_numbers (n_ip,); coordinates (n_ip, 3);
                           stress, strain (k, n_ip, 6)
    /nodes                 node_ids (n_n,); coordinates (n_n, 3); stress, strain (k, n_n, 6)

Every dataset carries a Fletcher-32 checksum (as the reduced body's file,
:mod:`pymorembs.io.reduced_file`); the values are chunked one column at a time and not
compressed (they compress by a fifth only). A body without solid elements gets a file with
the groups and ``k`` columns but no points (``n_ip = n_n = 0``) and its reason in ``note``. The
values are formed a block of columns at a time
(:class:`~pymorembs.export.stress_modes.StressModes`), so memory stays at the operators plus a
block; the file is written atomically.
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from pymorembs.export.stress_modes import StressModes
from pymorembs.io.atomic import atomic_path
from pymorembs.io.native import put_array
from pymorembs.stress import COMPONENTS, StressOperator

__all__ = ["FORMAT", "STRAIN", "UNITS", "VERSION", "write_stress_recovery"]

#: Value of the root attribute ``format``.
FORMAT = "pymorembs-stress-recovery"
#: Layout version written.
VERSION = 1
#: The ``units`` attribute: what the numbers are in.
UNITS = (
    "the FE model's consistent units: coordinates in its length unit, stresses in its stress "
    "unit (force / length^2, Pa in SI), strains dimensionless; a shape column per unit modal "
    "coordinate (q of the exported bodies, mass-normalised basis), a static column per unit "
    "input (force, moment or frame acceleration)"
)
#: The ``strain`` attribute: how shear strains are given (:mod:`pymorembs.stress`).
STRAIN = "tensor components: eps_xy = gamma_xy / 2 (as CalculiX prints E)"
#: Points per HDF5 chunk of a values dataset (a chunk: one column, these points, 6 components).
CHUNK_POINTS = 65536
_GROUPS = {"integration": "integration_points", "nodes": "nodes"}


def write_stress_recovery(
    path: str | os.PathLike[str],
    modes: StressModes | None,
    *,
    name: str,
    body_name: str,
    method: str,
    labels: tuple[str, ...],
    n_shapes: int,
    eigenfrequencies_hz: np.ndarray,
    note: str | None = None,
) -> Path:
    """Write the recovery file of one reduction (layout in the module docstring), atomically.

    Parameters
    ----------
    path : path-like
        Target file (``<name>.stress.h5``).
    modes : StressModes or None
        The stress modes (:func:`~pymorembs.export.stress_modes.stress_modes`); None for a body
        without solid elements (a file without points, ``note`` saying why).
    name, body_name, method : str
        The reduction, its body and its method (provenance).
    labels : tuple of str
        The column labels (``modes.labels`` when there are modes).
    n_shapes : int
        How many columns are shape functions.
    eigenfrequencies_hz : ndarray, shape (n_shapes,)
        Of the reduced model, one per shape function.
    note : str, optional
        Why there are no points.

    Returns
    -------
    Path
    """
    from pymorembs import __version__  # the package imports this module

    target = Path(path)
    with atomic_path(target) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["version"] = VERSION
        f.attrs["name"] = str(name)
        f.attrs["body"] = str(body_name)
        f.attrs["method"] = str(method)
        f.attrs["written_by"] = f"pymorembs {__version__}"
        f.attrs["components"] = " ".join(COMPONENTS)
        f.attrs["units"] = UNITS
        f.attrs["note"] = note or ""
        columns = f.create_group("columns")
        columns.attrs["n_shapes"] = int(n_shapes)
        columns.create_dataset("labels", data=list(labels), dtype=h5py.string_dtype())
        put_array(columns, "eigenfrequencies_hz", np.asarray(eigenfrequencies_hz), np.float64)
        f.attrs["strain"] = STRAIN
        for location, group_name in _GROUPS.items():
            group = f.create_group(group_name)
            if modes is None:
                _put_points(group, None, location)
                for quantity in ("stress", "strain"):
                    _values_dataset(group, quantity, len(labels), 0)
                continue
            for quantity in ("stress", "strain"):
                operator = modes.operator(location, quantity)
                if quantity == "stress":
                    _put_points(group, operator, location)
                dataset = _values_dataset(group, quantity, modes.count, operator.n_points)
                for part, values in modes.blocks(operator):
                    dataset[part[0] : part[-1] + 1] = values
    return target


def _put_points(group: h5py.Group, operator: StressOperator | None, location: str) -> None:
    """The points of ``operator`` (none for None): ids, numbers and coordinates."""
    empty = np.zeros(0, dtype=np.int64)
    if location == "integration":
        put_array(group, "element_ids", empty if operator is None else operator.element_ids,
                  np.int64)  # fmt: skip
        put_array(group, "point_numbers", empty if operator is None else operator.point_numbers,
                  np.int64)  # fmt: skip
    else:
        put_array(group, "node_ids", empty if operator is None else operator.node_ids, np.int64)
    coordinates = np.zeros((0, 3)) if operator is None else operator.coordinates
    put_array(group, "coordinates", coordinates, np.float64)


def _values_dataset(group: h5py.Group, key: str, count: int, points: int) -> h5py.Dataset:
    """An empty (count, points, 6) float dataset with a checksum, chunked by column (no
    chunks, hence no checksum, for a dataset without numbers). Not compressed: stresses
    compress by a fifth at four times the writing time."""
    if count * points == 0:
        return group.create_dataset(key, shape=(count, points, 6), dtype=np.float64)
    rows = min(points, CHUNK_POINTS)
    return group.create_dataset(
        key, shape=(count, points, 6), dtype=np.float64, chunks=(1, rows, 6), fletcher32=True
    )
