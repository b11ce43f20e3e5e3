"""The reduced body in the formats multibody codes read (paper section 4).

* :mod:`~pymorembs.export.invariants`: the mass invariants of the reduced body (SID_NOTES §4).
* :mod:`~pymorembs.export.sid`: Standard Input Data (``.SID_FEM``) writer, reader and checks.
* :mod:`~pymorembs.export.neweul`: the SID invariants as a MATLAB file for Neweul-M².
* :mod:`~pymorembs.export.exudyn_body`: a body for Exudyn's ``ObjectFFRFreducedOrder``.
* :mod:`~pymorembs.export.vtu`: the surface with the shape functions as a VTU file (ParaView).
* :mod:`~pymorembs.export.stress_modes`: the stress and strain modes of a reduced body, for
  every writer; :mod:`~pymorembs.export.recovery`: their HDF5 recovery file.
* :mod:`~pymorembs.export.nodal`: vectors over the dofs as fields over the nodes.
* :mod:`~pymorembs.export.matrices`: reduced matrices for MATLAB, and the pyMOR adapter.
* :mod:`~pymorembs.export.registry`: the export registry, one entry per kind of ``[export]
  outputs`` (writer, options, file names, description).
* :mod:`~pymorembs.export.source`: a reduced model as the writers read it; the checks before
  writing.
* :mod:`~pymorembs.export.outputs`: the files a job asks for (``[export] outputs``).

The package writes files and runs nothing: an exported Exudyn body in an Exudyn system is
:mod:`pymorembs.analysis.exudyn_model`.

A public subpackage (``docs/api.md``, "The public surface"): the names below are its interface.
"""

from pymorembs.export.deterministic import write_npz
from pymorembs.export.exudyn_body import exudyn_arrays, write_exudyn_body
from pymorembs.export.invariants import BodyInvariants
from pymorembs.export.neweul import write_neweul
from pymorembs.export.outputs import write_outputs
from pymorembs.export.recovery import write_stress_recovery
from pymorembs.export.registry import (
    BODY_OUTPUTS,
    DEFAULT_EXPORTS,
    EXPORT_KINDS,
    EXPORTS,
    MATRIX_OUTPUTS,
    BodyOptions,
    ExportKind,
    OutputKind,
    exports_table,
)
from pymorembs.export.sid import check_sid, read_sid, write_sid
from pymorembs.export.source import ExportSource, body_invariants, check_before_writing
from pymorembs.export.stress_modes import (
    StressModes,
    nodes_operator,
    stress_modes,
    stress_modes_note,
    von_mises_at,
)

__all__ = [
    "BODY_OUTPUTS",
    "DEFAULT_EXPORTS",
    "EXPORTS",
    "EXPORT_KINDS",
    "MATRIX_OUTPUTS",
    "BodyInvariants",
    "BodyOptions",
    "ExportKind",
    "ExportSource",
    "OutputKind",
    "StressModes",
    "body_invariants",
    "check_before_writing",
    "check_sid",
    "exports_table",
    "exudyn_arrays",
    "nodes_operator",
    "read_sid",
    "stress_modes",
    "stress_modes_note",
    "von_mises_at",
    "write_exudyn_body",
    "write_neweul",
    "write_npz",
    "write_outputs",
    "write_sid",
    "write_stress_recovery",
]
