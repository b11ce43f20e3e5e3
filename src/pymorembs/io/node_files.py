"""Node coordinates from any file an FE program writes them to, for the ``nodes`` option of every
matrix format.

:func:`read_node_file` tells the kind of a file from its content (:func:`node_file_kind`) and
reads its nodes:

``csv``
    ``nodes.csv``: first content line ``id,x,y,z`` (:func:`pymorembs.io.matrix_market.
    read_nodes_csv`).
``ansys``
    An Ansys archive (``CDWRITE,DB``): an ``NBLOCK`` line in its first 64 MiB
    (:func:`pymorembs.io.ansys_cdb.read_cdb`).
``abaqus``
    An Abaqus or CalculiX input deck: its first content line (blank lines and ``**`` comments
    skipped) is a keyword line ``*...`` (:func:`pymorembs.io.abaqus_inp.read_inp`; parts and
    instances placed).
``nastran``
    Anything else: Nastran bulk data (an input deck, an include file, a punch, an ``.f06`` with
    the bulk data echo), whose ``GRID`` cards are converted to the basic system
    (:func:`pymorembs.io.nastran_bulk.read_bulk`); a file without them is refused there.

A matrix reader looks the nodes of its equations up with :meth:`NodeFile.rows`; the readers of
the formats that come with their own node file (the Abaqus ``.inp``, the Ansys ``.cdb``, the
Nastran bulk data) also keep what else it holds (elements, displacement systems) from
:attr:`NodeFile.inp`, :attr:`NodeFile.archive` or :attr:`NodeFile.bulk`. Coordinates from the
file of another FE program are taken as global Cartesian coordinates of the nodes with the same
numbers.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from pymorembs.errors import located_error
from pymorembs.io.abaqus_inp import InpModel, read_inp
from pymorembs.io.ansys_cdb import AnsysArchive, looks_like_cdb, read_cdb
from pymorembs.io.line_blocks import UTF8_BOM
from pymorembs.io.matrix_market import read_nodes_csv
from pymorembs.io.nastran_bulk import BulkData, read_bulk
from pymorembs.io.reader_support import is_nodes_csv

__all__ = ["NODE_FILE_KINDS", "NodeFile", "node_file_kind", "read_node_file"]

PathLike = str | os.PathLike[str]

#: The kinds of node files :func:`read_node_file` reads.
NODE_FILE_KINDS = ("csv", "abaqus", "ansys", "nastran")
_HEAD_BYTES = 1 << 16


@dataclass(frozen=True, eq=False)
class NodeFile:
    """The nodes of a node file and what else the reader found in it.

    Attributes
    ----------
    path : Path
        The file.
    kind : str
        One of :data:`NODE_FILE_KINDS`.
    ids : ndarray of int, shape (n_nodes,)
        Node ids (for an Abaqus deck with parts: the ids of :class:`~pymorembs.io.abaqus_inp.
        InpModel`).
    coordinates : ndarray, shape (n_nodes, 3)
        Global Cartesian coordinates.
    inp, archive, bulk : optional
        The Abaqus deck, Ansys archive or Nastran bulk data read (for the kind's own readers).
    """

    path: Path
    kind: Literal["csv", "abaqus", "ansys", "nastran"]
    ids: np.ndarray
    coordinates: np.ndarray
    inp: InpModel | None = None
    archive: AnsysArchive | None = None
    bulk: BulkData | None = None

    def describe(self) -> str:
        """Where the coordinates come from, e.g. ``"the *NODE data of job.inp"``."""
        name = self.path.name
        where = {
            "csv": name,
            "abaqus": f"the *NODE data of {name}",
            "ansys": f"the NBLOCK of {name}",
            "nastran": f"the GRID cards of {name}",
        }[self.kind]
        return where

    def rows(self, ids: np.ndarray) -> np.ndarray:
        """Row in :attr:`ids` of each of ``ids`` (any shape), -1 where the file lacks the node."""
        ids = np.asarray(ids, dtype=np.int64)
        if not self.ids.size:
            return np.full(ids.shape, -1, dtype=np.int64)
        order = np.argsort(self.ids, kind="stable")
        pos = np.minimum(np.searchsorted(self.ids[order], ids), self.ids.size - 1)
        return np.where(self.ids[order][pos] == ids, order[pos], -1)


def node_file_kind(path: PathLike) -> Literal["csv", "abaqus", "ansys", "nastran"]:
    """The kind of a node file, told from its content (module docstring); ``"nastran"`` for
    anything else, whose reader then says what the file lacks."""
    path = Path(path)
    if is_nodes_csv(path):
        return "csv"
    if looks_like_cdb(path):
        return "ansys"
    try:
        with open(path, "rb") as stream:
            head = stream.read(_HEAD_BYTES).removeprefix(UTF8_BOM)
    except OSError:
        return "nastran"  # its reader names the problem
    for line in head.decode("latin-1").splitlines():
        text = line.strip()
        if not text or text.startswith("**"):
            continue
        return "abaqus" if text.startswith("*") else "nastran"
    return "nastran"


def read_node_file(path: PathLike) -> NodeFile:
    """The nodes of a ``nodes.csv``, Abaqus/CalculiX deck, Ansys archive or Nastran bulk data.

    Parameters
    ----------
    path : path-like
        The file (its kind is told from the content: :func:`node_file_kind`).

    Returns
    -------
    NodeFile

    Raises
    ------
    UserError
        The file cannot be read or holds no nodes; one line ``file[:line]: problem`` from the
        kind's reader.
    """
    path = Path(path)
    kind = node_file_kind(path) if path.is_file() else "csv"  # (its reader: "file not found")
    if kind == "csv":
        ids, xyz = read_nodes_csv(path)
        return NodeFile(path, kind, ids, xyz)
    if kind == "ansys":
        archive = read_cdb(path)
        return NodeFile(path, kind, archive.node_ids, archive.coordinates, archive=archive)
    if kind == "abaqus":
        model = read_inp(path)
        return NodeFile(path, kind, model.node_ids, model.coordinates, inp=model)
    bulk = read_bulk(path)
    if not bulk.grid["ids"].size:
        raise located_error(
            path,
            None,
            "no node coordinates: neither a nodes.csv (first line id,x,y,z), an Abaqus or "
            "CalculiX input deck (*NODE), an Ansys archive (NBLOCK, written by CDWRITE,DB) nor "
            f"Nastran bulk data with GRID cards ({bulk.describe()})",
        )
    return NodeFile(path, kind, bulk.grid["ids"], bulk.basic_coordinates(), bulk=bulk)
