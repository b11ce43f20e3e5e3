"""The files a reduced body can be written as, each kind written once (the export registry).

The counterpart of the method registry (:mod:`pymorembs.methods`): every kind of ``[export]
outputs`` is one :class:`ExportKind` in :data:`EXPORTS` with its writer, the dataclass of its
options (None without options), the names of the files it writes and a one-line description;
:data:`OutputKind`, the enum of the kinds' names, is made from it.
The job file (:mod:`pymorembs.job.schema`), :func:`~pymorembs.export.outputs.write_outputs`, the
``ReducedBody.to_*`` methods of the Python API, the job reference (:func:`exports_table`, in
``docs/jobs.md``) and the app's list of kinds all read it.

File names may hold ``{name}``, the reduction's name. The files of a reduction go into its folder
(``<name>/`` of the job's output folder); those of the ``job`` group (``report``) into the job's
folder. The bodies for multibody codes (group ``body``) need a one-sided (Galerkin) projection, so
that the reduced matrices are ``V^T M V`` and ``V^T K V`` of a real displacement basis.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io

from pymorembs.export.deterministic import write_npz
from pymorembs.export.exudyn_body import surface_mesh, write_exudyn_body
from pymorembs.export.matrices import write_reduced_mat
from pymorembs.export.neweul import write_neweul
from pymorembs.export.recovery import write_stress_recovery
from pymorembs.export.sid import write_sid
from pymorembs.export.source import ExportSource
from pymorembs.export.vtu import require_coordinates, write_vtu
from pymorembs.io.atomic import atomic_path

#: ``write(source, options, paths)``: the files of one kind at ``paths`` (one per file name).
Writer = Callable[[ExportSource, Any, tuple[Path, ...]], None]

#: The reduced matrices of ``mtx``, one Matrix Market file each.
MTX_MATRICES = ("M", "K", "D", "B", "C")


@dataclass(frozen=True)
class BodyOptions:
    """Options of a body for a multibody code (``sid``, ``neweul``, ``exudyn``).

    Attributes
    ----------
    nodes : tuple of int
        The frame nodes of the body (SID node frames, Exudyn markers): ``[export] nodes`` of a
        job or ``nodes`` of ``ReducedBody.to_sid``; by default the nodes of the inputs and
        outputs.
    """

    nodes: tuple[int, ...] = ()


@dataclass(frozen=True)
class ExportKind:
    """One kind of ``[export] outputs``: what it writes and how.

    Attributes
    ----------
    name : str
        The kind as a job names it (``"sid"``).
    group : {"matrices", "shapes", "body", "job"}
        ``matrices``: the reduced matrices (``ReducedBody.to_matrices``); ``shapes``: the shape
        functions for a viewer; ``body``: a body for a multibody code, from the mass invariants
        for the frame nodes; ``job``: one file for the whole job.
    files : tuple of str
        The names of the files it writes, ``{name}`` standing for the reduction's name.
    description : str
        What the files hold, one line (Markdown).
    write : callable or None
        ``write(source, options, paths)`` writes the files at ``paths`` (one per name of
        ``files``) from an :class:`~pymorembs.export.source.ExportSource`, with an instance of
        ``options`` (None without options). None for the job's report, which the job writes
        from its summary (:func:`pymorembs.report.write_report`).
    options : type or None
        The frozen dataclass of its options (:class:`BodyOptions`); None without options.
    default : bool
        Written when a job does not say (no ``outputs`` in ``[export]``).
    """

    name: str
    group: str
    files: tuple[str, ...]
    description: str
    write: Writer | None
    options: type[BodyOptions] | None = None
    default: bool = False

    def file_names(self, name: str) -> tuple[str, ...]:
        """The names of its files for the reduction ``name``."""
        return tuple(file.format(name=name) for file in self.files)


def _write_npz(source: ExportSource, options: None, paths: tuple[Path, ...]) -> None:
    write_npz(paths[0], source.arrays, compress=True)


def _write_mtx(source: ExportSource, options: None, paths: tuple[Path, ...]) -> None:
    for key, path in zip(MTX_MATRICES, paths, strict=True):
        with atomic_path(path) as tmp:
            scipy.io.mmwrite(str(tmp), np.asarray(source.arrays[key]), precision=17)


def _write_mat(source: ExportSource, options: None, paths: tuple[Path, ...]) -> None:
    write_reduced_mat(paths[0], source.arrays)


def _write_vtu(source: ExportSource, options: None, paths: tuple[Path, ...]) -> None:
    require_coordinates(source.prepared.body, paths[0])  # before the static solve
    body = source.prepared.body
    write_vtu(paths[0], body, source.basis, static=source.static, stress=source.stress_modes)


def _write_stress_recovery(source: ExportSource, options: None, paths: tuple[Path, ...]) -> None:
    modes = source.stress_modes
    labels = modes.labels if modes is not None else (
        *(str(k) for k in range(1, source.model.projection.order + 1)),
        *source.prepared.reduction_system.input_labels,
    )  # fmt: skip
    write_stress_recovery(
        paths[0],
        modes,
        name=source.name,
        body_name=source.prepared.body.name,
        method=source.model.projection.method,
        labels=tuple(labels),
        n_shapes=source.model.projection.order,
        eigenfrequencies_hz=source.model.eigenfrequencies_hz,
        note=source.stress_note,
    )


def _write_sid(source: ExportSource, options: BodyOptions, paths: tuple[Path, ...]) -> None:
    comment = f"SID generated by pymorembs, reduction {source.name}"
    write_sid(paths[0], source.invariants(options.nodes), comment=comment)


def _write_neweul(source: ExportSource, options: BodyOptions, paths: tuple[Path, ...]) -> None:
    write_neweul(paths[0], source.invariants(options.nodes))


def _write_exudyn(source: ExportSource, options: BodyOptions, paths: tuple[Path, ...]) -> None:
    surface = surface_mesh(source.prepared.body, source.basis)
    write_exudyn_body(
        paths[0], source.invariants(options.nodes), surface=surface, stress=source.stress_modes
    )


#: Kind name -> its entry, in the order the job reference and the app list them.
EXPORTS: dict[str, ExportKind] = {
    kind.name: kind
    for kind in (
        ExportKind(
            "npz",
            "matrices",
            ("reduced.npz",),
            "the reduced `M K D B C`, the basis `V` on all dofs (eq. 18), the eigenfrequencies, "
            "the dof table and the port labels (NumPy)",
            _write_npz,
            default=True,
        ),
        ExportKind(
            "mtx",
            "matrices",
            tuple(f"{key}.mtx" for key in MTX_MATRICES),
            "the reduced matrices as Matrix Market files",
            _write_mtx,
            default=True,
        ),
        ExportKind(
            "mat",
            "matrices",
            ("reduced.mat",),
            "the arrays of `reduced.npz` for MATLAB",
            _write_mat,
        ),
        ExportKind(
            "sid",
            "body",
            ("{name}.SID_FEM",),
            "Standard Input Data for Simpack and other SID readers",
            _write_sid,
            BodyOptions,
        ),
        ExportKind(
            "neweul",
            "body",
            ("{name}_neweul.mat",),
            "the SID invariants as MATLAB arrays for Neweul-M²",
            _write_neweul,
            BodyOptions,
        ),
        ExportKind(
            "exudyn",
            "body",
            ("{name}_exudyn.npz",),
            "the data of an Exudyn `ObjectFFRFreducedOrder`, with the surface triangles its "
            "renderer draws and the stress modes of its `StressLocal` output (solid bodies)",
            _write_exudyn,
            BodyOptions,
        ),
        ExportKind(
            "vtu",
            "shapes",
            ("{name}.vtu",),
            "the surface with every shape function and the static response to every input, "
            "with their nodal stress, strain and von Mises stress (solid bodies), for ParaView",
            _write_vtu,
        ),
        ExportKind(
            "stress_recovery",
            "shapes",
            ("{name}.stress.h5",),
            "the stress and strain modes of every shape function and static response at the "
            "integration points and nodes (HDF5, `docs/recovery.md`), for fatigue tools",
            _write_stress_recovery,
        ),
        ExportKind(
            "report",
            "job",
            ("report.html",),
            "one HTML page for the whole job: tables, plots and a 3D view of the body and its "
            "shape functions",
            None,
        ),
    )
}

#: The kinds of ``[export] outputs`` as a string enum (``OutputKind.SID == "sid"``), made from
#: :data:`EXPORTS`, their one definition, in its order: a job's ``[export] outputs`` holds them.
OutputKind = StrEnum("OutputKind", [(name.upper(), name) for name in EXPORTS])
OutputKind.__doc__ = "A kind of ``[export] outputs``, one per entry of :data:`EXPORTS`."
#: The kinds of ``[export] outputs``, in the order of :data:`EXPORTS`.
EXPORT_KINDS = tuple(EXPORTS)
#: The kinds a job writes when its ``[export]`` has no ``outputs``.
DEFAULT_EXPORTS = tuple(name for name, kind in EXPORTS.items() if kind.default)
#: The bodies for multibody codes: inertia loads are inputs by default for these.
BODY_OUTPUTS = tuple(name for name, kind in EXPORTS.items() if kind.group == "body")
#: The reduced matrices (the ``formats`` of ``ReducedBody.to_matrices``).
MATRIX_OUTPUTS = tuple(name for name, kind in EXPORTS.items() if kind.group == "matrices")


def exports_table() -> str:
    """The export kinds as a Markdown table (kind, files, options, content), for the job
    reference (``docs/jobs.md``); the default kinds are marked."""
    lines = ["| kind | files | options | content |", "|---|---|---|---|"]
    for name, kind in EXPORTS.items():
        folder = "" if kind.group == "job" else "<name>/"
        files = ", ".join(f"`{folder if i == 0 else ''}{file}`"
                          for i, file in enumerate(kind.file_names("<name>")))  # fmt: skip
        options = "—"
        if kind.options is not None:
            options = ", ".join(f"`{f.name}`" for f in dataclasses.fields(kind.options))
        marked = f"`{name}` (default)" if kind.default else f"`{name}`"
        lines.append(f"| {marked} | {files} | {options} | {kind.description} |")
    return "\n".join(lines) + "\n"
