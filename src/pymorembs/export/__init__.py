"""The reduced body in the formats multibody codes read (paper section 4).

* :mod:`~pymorembs.export.invariants`: the mass invariants of the reduced body (SID_NOTES §4).
* :mod:`~pymorembs.export.sid`: Standard Input Data (``.SID_FEM``) writer, reader and checks.
* :mod:`~pymorembs.export.neweul`: the SID invariants as a MATLAB file for Neweul-M².
* :mod:`~pymorembs.export.exudyn_body`: a body for Exudyn's ``ObjectFFRFreducedOrder``.
* :mod:`~pymorembs.export.vtu`: the surface with the shape functions as a VTU file (ParaView).
* :mod:`~pymorembs.export.nodal`: vectors over the dofs as fields over the nodes.
* :mod:`~pymorembs.export.matrices`: reduced matrices for MATLAB, and the pyMOR adapter.
* :mod:`~pymorembs.export.outputs`: the files a job asks for (``[export] outputs``).

The package writes files and runs nothing: an exported Exudyn body in an Exudyn system is
:mod:`pymorembs.analysis.exudyn_model`.

A public subpackage (``docs/api.md``, "The public surface"): the names below are its interface.
"""

from pymorembs.export.exudyn_body import exudyn_arrays, write_exudyn_body
from pymorembs.export.invariants import BodyInvariants
from pymorembs.export.neweul import write_neweul
from pymorembs.export.outputs import (
    BODY_OUTPUTS,
    body_invariants,
    check_before_writing,
    write_outputs,
)
from pymorembs.export.sid import check_sid, read_sid, write_sid

__all__ = [
    "BODY_OUTPUTS",
    "BodyInvariants",
    "body_invariants",
    "check_before_writing",
    "check_sid",
    "exudyn_arrays",
    "read_sid",
    "write_exudyn_body",
    "write_neweul",
    "write_outputs",
    "write_sid",
]
