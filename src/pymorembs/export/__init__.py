"""The reduced body in the formats multibody codes read (paper section 4).

* :mod:`~pymorembs.export.invariants`: the mass invariants of the reduced body (SID_NOTES §4).
* :mod:`~pymorembs.export.sid`: Standard Input Data (``.SID_FEM``) writer, reader and checks.
* :mod:`~pymorembs.export.neweul`: the SID invariants as a MATLAB file for Neweul-M².
* :mod:`~pymorembs.export.exudyn_body`: a body for Exudyn's ``ObjectFFRFreducedOrder``.
* :mod:`~pymorembs.export.vtu`: the surface with the shape functions as a VTU file (ParaView).
* :mod:`~pymorembs.export.nodal`: vectors over the dofs as fields over the nodes.
* :mod:`~pymorembs.export.matrices`: reduced matrices for MATLAB, and the pyMOR adapter.
* :mod:`~pymorembs.export.outputs`: the files a job asks for (``[export] outputs``).
"""
